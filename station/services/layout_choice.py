"""Which layout to place: among an optimizer's verified candidates (and layouts placed before), the one expected to
succeed most often physically.

The optimizer (:func:`station.services.robust.optimize`) takes the physics as exact and keeps the candidate that did
best in its own simulations. On a table the material values are only known within a range (the scenario's, or a
calibration's interval), and a candidate that works across that range is the better one to place. Each option is
scored by :func:`station.services.predict.predict_layout` (placement error and material values drawn from their
intervals, the same seed for every option so that they meet the same draws) and the best is kept; ties keep the
earlier option, so the caller lists what it prefers first. Used by ``station loop`` and the Assemble screen's
re-optimization.

A layout already placed on the table also has a record: its successes in the trials logged with its values. The
prediction is taken as a Beta prior worth ``prediction_weight`` attempts and the record updates it: the expected
success of the next attempt is ``(w p + successes) / (w + attempts)`` (a layout never placed keeps ``p``). So a layout
that just worked 5 times in 5 is not swapped for one only simulated to do a little better, and one that failed
stops being chosen for its simulations' sake. The default weight, :data:`PREDICTION_WEIGHT`, is what the loop's own
records say the predictions are worth (``python -m bench.bench_prediction_weight``: the beta-binomial maximum
likelihood over the bench's layouts).

The options are ranked by the lower quartile of that Beta posterior (:func:`choice_score`), not by its mean: a
success the station is 75 % sure of. Where the means are close, the layout with a record wins over one known only
from its simulations, whose prediction is the best of several noisy ones (16 simulations are +- 0.1) and so tends to
be high (a loop left a layout that had worked 4 times in 5, expected 0.80, for a new one predicted 0.81 that then
failed 4 times in 5); where they are far apart, the higher mean still wins.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass

import numpy as np

from common.progress import Reporter
from design.contraption import layout_io
from design.contraption.physics_profile import PhysicsProfile
from design.robust.model_io import layout_model
from station.errors import ServiceError, station_errors

__all__ = ["CHOICE_QUANTILE", "PREDICTION_EDGE", "PREDICTION_WEIGHT", "candidate_layouts", "choice_score",
           "choose_layout", "describe_choice", "distinct_layouts", "expected_success", "layout_record",
           "layout_records", "same_layout"]

#: What a predicted success is worth, in attempts on the table (the strength of the Beta prior it centres): the
#: weight that best explains the bench loops' records (``bench/bench_prediction_weight.py``; the figures are in the
#: loop's results page).
PREDICTION_WEIGHT = 4.0

#: The quantile of a layout's success posterior the options are ranked by (:func:`choice_score`).
CHOICE_QUANTILE = 0.25

#: Predictions of exactly 0 or 1 would give a degenerate Beta prior; they are held this far inside.
PREDICTION_EDGE = 0.01


@station_errors
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
    data = {k: v for k, v in payload.items() if k not in ("physical_choice", "candidate")}
    data["parameters"] = [{**p, "value": float(p["lower"] + u[i] * (p["upper"] - p["lower"])),
                           "normalized": float(u[i])} for i, p in enumerate(payload["parameters"])]
    data["candidate"] = index
    model = layout_model(payload)
    if model is not None:
        data["predicted_psp"] = float(model.predict(u[None, :])[0])
    return data


def _values(data: dict) -> dict[str, float]:
    return {str(p["name"]): float(p["value"]) for p in data["parameters"]}


def _same(a: dict[str, float], b: dict[str, float], tolerance: float) -> bool:
    return a.keys() == b.keys() and all(abs(a[k] - b[k]) <= tolerance for k in a)


@station_errors
def same_layout(a: dict, b: dict, tolerance: float = 1e-6) -> bool:
    """Whether two LAYOUT.json data have the same parameter values (within ``tolerance``)."""
    return _same(_values(a), _values(b), tolerance)


@station_errors
def distinct_layouts(options: list[dict], tolerance: float = 1e-6) -> list[dict]:
    """``options`` without repeats (the same parameter values), the first kept."""
    seen: list[dict[str, float]] = []
    out = []
    for data in options:
        values = _values(data)
        if any(_same(values, v, tolerance) for v in seen):
            continue
        seen.append(values)
        out.append(data)
    return out


def _logged(trials: Iterable[Mapping]) -> list[tuple[dict[str, float], bool]]:
    return [({str(k): float(v) for k, v in (t.get("layout") or {}).items()}, bool(t.get("success"))) for t in trials]


def _record(values: dict[str, float], logged, tolerance: float) -> tuple[int, int]:
    outcomes = [success for layout, success in logged if _same(values, layout, tolerance)]
    return sum(outcomes), len(outcomes)


@station_errors
def layout_record(values: Mapping[str, float], trials: Iterable[Mapping], tolerance: float = 1e-6) -> tuple[int, int]:
    """A layout's record on the table: ``(successes, attempts)`` of the ``trials`` (trial records, the log's form)
    logged with its ``values`` (``{parameter: value}``)."""
    return _record({str(k): float(v) for k, v in values.items()}, _logged(trials), tolerance)


@station_errors
def layout_records(options: list[dict], trials: Iterable[Mapping], tolerance: float = 1e-6) -> list[tuple[int, int]]:
    """Each option's record (:func:`layout_record`; the trials read once)."""
    logged = _logged(trials)
    return [_record(_values(data), logged, tolerance) for data in options]


@station_errors
def expected_success(predicted: float, successes: int = 0, attempts: int = 0,
                     weight: float = PREDICTION_WEIGHT) -> float:
    """The expected success of a layout's next attempt: its prediction as a Beta prior worth ``weight`` attempts,
    updated by its record (``successes`` of ``attempts``)."""
    return (weight * float(predicted) + successes) / (weight + attempts)


@station_errors
def choice_score(predicted: float, successes: int = 0, attempts: int = 0, weight: float = PREDICTION_WEIGHT,
                 quantile: float = CHOICE_QUANTILE) -> float:
    """What a layout is ranked by: the ``quantile`` of its success's Beta posterior, the prediction worth ``weight``
    attempts (held 0.01 inside 0 and 1) updated by its record (``successes`` of ``attempts``)."""
    from scipy.stats import beta  # heavy: scipy

    p = min(max(float(predicted), PREDICTION_EDGE), 1.0 - PREDICTION_EDGE)
    return float(beta.ppf(quantile, weight * p + successes, weight * (1.0 - p) + attempts - successes))


@station_errors
@dataclass(frozen=True)
class LayoutChoiceRequest:
    """How :func:`choose_layout` weighs the options.

    Parameters
    ----------
    profile : PhysicsProfile, optional
        Values and intervals to draw from (None: the scenario's own values, no draws).
    samples, seed : int
        Simulations per option, and their seed (the same for every option).
    trials : tuple of dict
        Trial records (the log's form) of layouts placed before: an option's record updates its prediction
        (:func:`expected_success`).
    prediction_weight : float
        What a prediction is worth, in attempts (> 0).
    workers, scheduler
        Where the simulations run: local processes, or a Dask scheduler's address.
    """

    profile: PhysicsProfile | None = None
    samples: int = 16
    seed: int = 0
    trials: tuple[Mapping, ...] = ()
    prediction_weight: float = PREDICTION_WEIGHT
    workers: int | None = None
    scheduler: str | None = None

    def __post_init__(self) -> None:
        if not self.prediction_weight > 0:
            raise ServiceError(f"prediction_weight must be > 0, got {self.prediction_weight!r}",
                               field="prediction_weight", value=self.prediction_weight)


@station_errors
def choose_layout(scenario, options: list[dict], request: LayoutChoiceRequest = LayoutChoiceRequest(), *,
                  report: Reporter | None = None, on_option: Callable[[int, int], None] | None = None) -> dict:
    """The option surest to succeed often physically (the highest :func:`choice_score`), with its
    ``"physical_choice"``: which option it was, every option's predicted success, record, expected success and
    score, and the simulations each had.

    Parameters
    ----------
    scenario : Scenario
    options : list of dict
        LAYOUT.json data, the preferred first (repeats are dropped).
    request : LayoutChoiceRequest
        The physics, the simulations per option and the record of trials the options are weighed with.
    on_option : callable, optional
        Called with ``(index, count)`` before each option is scored.

    Raises
    ------
    common.progress.Cancelled
        Stopped; the simulations done are in the cache.
    """
    options = distinct_layouts(options)
    if len(options) == 1:
        return options[0]
    # the simulations (pybullet, scipy) load when options are weighed: the loop's command imports this for --help
    from station.services import predict

    records = layout_records(options, request.trials)
    weight = request.prediction_weight
    predicting = predict.PredictionRequest(request.profile, samples=request.samples, seed=request.seed,
                                           workers=request.workers, scheduler=request.scheduler)
    scores = []
    for i, data in enumerate(options):
        if on_option is not None:
            on_option(i, len(options))
        x = np.asarray(layout_io.layout_from_data(data, scenario, file="<candidate layout>").x, dtype=float)
        scores.append(predict.predict_layout(scenario, x, predicting, report=report).probability)
    expected = [expected_success(p, s, n, weight) for p, (s, n) in zip(scores, records)]
    ranks = [choice_score(p, s, n, weight) for p, (s, n) in zip(scores, records)]
    best = int(np.argmax(ranks))  # the first of equals
    chosen = dict(options[best])
    chosen["physical_choice"] = {"chosen": best, "predicted_physical_success": [float(v) for v in scores],
                                 "record": [list(r) for r in records], "prediction_weight": float(weight),
                                 "expected_success": [float(v) for v in expected],
                                 "lower_quartile": [round(v, 6) for v in ranks], "samples": request.samples}
    return chosen


@station_errors
def describe_choice(chosen: dict) -> str:
    """A few words on why ``chosen`` (:func:`choose_layout`'s answer) won, for a status line ("" if there was no
    choice)."""
    choice = chosen.get("physical_choice")
    if not choice:
        return ""
    i = int(choice["chosen"])
    predicted = float(choice["predicted_physical_success"][i])
    expected = float(choice.get("expected_success", choice["predicted_physical_success"])[i])
    successes, attempts = choice.get("record", [[0, 0]] * (i + 1))[i]
    count = len(choice["predicted_physical_success"])
    why = f"predicted {predicted:.2f}"
    if attempts:
        why = f"{expected:.2f}: {why}, worked {successes} of {attempts} times placed"
    if "lower_quartile" not in choice:  # chosen by the mean, before the quartile
        return f"; of {count} layouts the one expected to succeed most often physically ({why})"
    sure = f"{(1.0 - CHOICE_QUANTILE) * 100:g} % sure of {float(choice['lower_quartile'][i]):.2f}"
    return (f"; of {count} layouts the one surest to succeed often physically "
            f"({'expected ' if attempts else ''}{why}; {sure})")
