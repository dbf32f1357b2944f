"""Synthetic physical trials: runs made by the simulator itself under hidden material values, as the log exports them.

For checking simulator calibration against a known answer (tests, ``bench/bench_sim_calibration.py``) and for
trying the calibration commands without a workshop: each trial is one simulation of a designed layout with a
Gaussian placement error (1 mm / 1 degree by default) and material values the fit is not told. The trials are
written in the trial log's export format (issue 20's contract), as a maker's logged runs would be, with the
designed layout and no check (so the fit, like for a real unchecked run, simulates the designed layout).

This deliberately does not reuse :class:`calibration.sim_runs.OutcomeProblem`: it calls the simulator directly,
so a mistake in the fit's own simulation path does not also shape its test data.
"""

from __future__ import annotations

import uuid
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np

from calibration.sim_runs import DEFAULT_ANGLE_SIGMA_DEG, DEFAULT_POSITION_SIGMA_M, widened
from design.contraption.model import Scenario
from design.contraption.schema import ANGLE_KEYS


def synthetic_trials(scenario: Scenario, layouts: Sequence[np.ndarray], hidden: Mapping[str, float], *, seed: int = 0,
                     times: bool = True, position_sigma_m: float = DEFAULT_POSITION_SIGMA_M,
                     angle_sigma_deg: float = DEFAULT_ANGLE_SIGMA_DEG, content: str | None = None) -> list[dict]:
    """One trial per designed layout of ``layouts`` (real units), simulated under ``hidden`` material values.

    Parameters
    ----------
    scenario : Scenario
        The scenario as the maker has it (its own material values are not used).
    layouts : sequence of arrays
        Designed layouts, one trial each.
    hidden : mapping
        The "real" material values, ``{"wood.friction": 0.55}``.
    seed : int
        Seed of the placement errors.
    times : bool
        Log the times of the events that happened (to the millisecond, as a video would give them).
    content : str, optional
        The scenario file's text for the trials' ``scenario.content`` (default: the file at ``scenario.source``).

    Returns
    -------
    list of dict
        Trials in the export format (``id`` from 1).
    """
    from design.contraption.simulation import ASLEEP, SUCCESS, simulate

    truth = widened(scenario.with_physics(dict(hidden)))
    if content is None:
        content = Path(scenario.source).read_text(encoding="utf-8")
    names = scenario.design_space.names
    sigma = np.array([angle_sigma_deg if n.rsplit(".", 1)[1] in ANGLE_KEYS else position_sigma_m for n in names])
    rng = np.random.default_rng(seed)
    trials = []
    for i, layout in enumerate(layouts):
        layout = np.asarray(layout, dtype=float)
        placed = layout + rng.standard_normal(len(names)) * sigma
        result = simulate(truth, placed, early_stop="settled")
        outcomes, logged = {}, {}
        for event in scenario.events:
            outcome = result.events[event]
            if outcome.state == SUCCESS:
                outcomes[event] = "yes"
                if times:
                    logged[event] = round(float(outcome.time), 3)
            else:
                outcomes[event] = "not-reached" if outcome.state == ASLEEP else "no"
        trials.append({
            "id": i + 1, "uid": uuid.UUID(int=int(rng.integers(0, 2**63)) << 64 | i).hex,
            "scenario": {"name": scenario.name, "content_hash": scenario.content_hash, "content": content},
            "layout": dict(zip(names, layout.tolist())), "as_built": None, "check": None, "physics": None,
            "outcomes": outcomes, "times": logged, "success": bool(result.success),
            "who": "simulator", "created_at": "2026-01-01T00:00:00Z",
            "notes": "synthetic: simulated under hidden material values", "photos": [],
        })
    return trials


def export(trials: list[dict]) -> dict:
    """Trials as a whole export file's content."""
    return {"format": "chaos-station trials", "version": 1, "trials": trials}
