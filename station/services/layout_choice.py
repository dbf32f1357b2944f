"""Which layout to place: among an optimizer's verified candidates (and layouts placed before), the one predicted to
succeed most often physically.

The optimizer (:func:`station.services.robust.optimize`) takes the physics as exact and keeps the candidate that did
best in its own simulations. On a table the material values are only known within a range (the scenario's, or a
calibration's interval), and a candidate that works across that range is the better one to place. Each option is
scored by :func:`station.services.predict.predict_layout` (placement error and material values drawn from their
intervals, the same seed for every option so that they meet the same draws) and the best is kept; ties keep the
earlier option, so the caller lists what it prefers first. Used by ``station loop`` and the Assemble screen's
re-optimization.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from common.progress import ProgressCallback

__all__ = ["candidate_layouts", "choose_layout", "distinct_layouts"]


def candidate_layouts(payload: dict, limit: int) -> list[dict]:
    """An optimizer's LAYOUT.json data and its verified runners-up that worked in simulation (best local success
    first), as LAYOUT.json data each, at most ``limit`` in all.

    A runner-up gets the optimizer's payload with its own parameters and, where the payload carries the fitted
    model, the model's PSP of it; its ``"candidate"`` says which row of ``verification`` it is.
    """
    rows = [(i, r) for i, r in enumerate(payload.get("verification", []))
            if not r.get("kept") and r.get("local_success_rate", 0) > 0]
    rows.sort(key=lambda item: -float(item[1]["local_success_rate"]))
    runners_up = rows[: max(0, limit - 1)]
    return [payload, *(_with_normalized(payload, np.asarray(r["u"], dtype=float), i) for i, r in runners_up)]


def _with_normalized(payload: dict, u: np.ndarray, index: int) -> dict:
    from design.robust.model_io import layout_model

    data = {k: v for k, v in payload.items() if k not in ("physical_choice", "candidate")}
    data["parameters"] = [{**p, "value": float(p["lower"] + u[i] * (p["upper"] - p["lower"])),
                           "normalized": float(u[i])} for i, p in enumerate(payload["parameters"])]
    data["candidate"] = index
    model = layout_model(payload)
    if model is not None:
        data["predicted_psp"] = float(model.predict(u[None, :])[0])
    return data


def distinct_layouts(options: list[dict], tolerance: float = 1e-6) -> list[dict]:
    """``options`` without repeats (the same parameter values), the first kept."""
    seen: list[np.ndarray] = []
    out = []
    for data in options:
        u = np.array([float(p["value"]) for p in data["parameters"]])
        if any(len(u) == len(v) and np.max(np.abs(u - v)) <= tolerance for v in seen):
            continue
        seen.append(u)
        out.append(data)
    return out


def choose_layout(scenario, options: list[dict], profile=None, *, samples: int = 16, seed: int = 0,
                  workers: int | None = None, scheduler: str | None = None,
                  progress: ProgressCallback | None = None, should_stop: Callable[[], bool] | None = None,
                  on_option: Callable[[int, int], None] | None = None) -> dict:
    """The option predicted to succeed most often physically, with its ``"physical_choice"``: which option it was,
    every option's predicted success and the simulations each had.

    Parameters
    ----------
    scenario : Scenario
    options : list of dict
        LAYOUT.json data, the preferred first (repeats are dropped).
    profile : PhysicsProfile, optional
        Values and intervals to draw from (None: the scenario's own values, no draws).
    samples, seed : int
        Simulations per option, and their seed (the same for every option).
    on_option : callable, optional
        Called with ``(index, count)`` before each option is scored.

    Raises
    ------
    RunStopped
        Stopped; the simulations done are in the cache.
    """
    from design.contraption.layout_io import layout_from_data
    from station.services.predict import predict_layout

    options = distinct_layouts(options)
    if len(options) == 1:
        return options[0]
    scores = []
    for i, data in enumerate(options):
        if on_option is not None:
            on_option(i, len(options))
        x = np.asarray(layout_from_data(data, scenario, file="<candidate layout>").x, dtype=float)
        scores.append(predict_layout(scenario, x, profile=profile, samples=samples, seed=seed, workers=workers,
                                     scheduler=scheduler, progress=progress, should_stop=should_stop).probability)
    best = int(np.argmax(scores))  # the first of equals
    chosen = dict(options[best])
    chosen["physical_choice"] = {"chosen": best, "predicted_physical_success": [float(v) for v in scores],
                                 "samples": samples}
    return chosen
