"""The whole station loop on the simulated world, unattended (thesis 5.2.3): optimize, guide, place, check, run, log,
calibrate, re-optimize.

Used by ``station loop`` (and the bench). Per loop: the layout, its guide, and ``attempts`` attempts. The layout:
``station optimize``'s service gives a layout and its verified runners-up (loop 1: under the scenario's physics, its
default budget, made once and cached; loop k > 1: under the physics profile calibrated from every trial of the loops
before), and the loop places the one of them (and of the layouts placed before) surest to succeed often
physically under what it knows of the physics: loop 1 the scenario's values and ranges (with ``every_material``, the
plain numbers within default ranges too), later loops the calibrated values and intervals, and for a layout placed
before its record in the loop's trials (:func:`station.services.layout_choice.choice_score`). The optimizer takes
the physics as exact; a layout that works across the plausible physics, and has worked on the table, is the one to
place.
An attempt is the one ``station assemble`` walks a maker through (:class:`station.services.assemble.Assembly`), on the
simulated world: the simulated maker places every part with the projector highlighting it, each parameter set as the
guide says (on the sheet, with a ruler, on a laser-cut jig the maker cut first with ``jigs``, after a check:
:meth:`drivers.sim.world.SimulatedWorld.place`), the simulated camera sees the parts as placed and the check measures
them, the maker applies the instructions and the camera checks again until every part is within its tolerance (at most
``rounds`` corrections), the world runs (:func:`station.services.world.run_attempt`), the station predicts the physical
success of what the check measured (:func:`station.services.predict.predict_layout` with the check's residual error,
under the loop's profile and its intervals; in loop 1, before any trial, under the scenario's values and uncertain
ranges) and logs the trial (with the CHECK.json and the profile) and the attempt in one transaction. The attempt's
**forecast** is that prediction updated by the layout's record before it, as the choice weighs it
(:func:`record_forecasts`): what the station would tell the maker before the attempt. The **baseline** is the thesis's
workflow in the same world: the optimizer's own loop-1 layout placed from the printed sheet (no highlight), no check, no
calibration.

What it says is for a maker: every progress stage names the loop and what it does in their words ("loop 2:
calibrating the simulator from 5 trials", "loop 2: re-optimizing the layout for the calibrated physics
(exploration)", "loop 1: choosing the layout to place" counting candidate layouts), the work it calls (optimizer,
calibration, predictions) reported under those words (:func:`labelled`); and each attempt ends with an
:class:`AttemptReport`: what the check had the maker correct, and how the run went (the trial's notes keep the
check's own words for it).

Everything is in the station database (:mod:`station.loopstore`): a run is keyed by its arguments, every random
draw is seeded by the world seed, the loop, the attempt and the round, and a loop's layout and profile are stored
when made, so a second run with the same arguments resumes where the first stopped and ends with the same figures.
"""

from __future__ import annotations

import json
import math
import tempfile
from collections.abc import Callable, Mapping, Sequence
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

# The loop's work (optimizer, calibration, guides, the world) is imported inside the functions that do it, on
# purpose: `station loop --help` reads LoopSettings' defaults from here, and the CLI's --help stays fast.
from common.progress import Cancelled, Progress, Reporter
from drivers.sim.world import WORLD_REVISION
from station.errors import ServiceError, station_errors
from station.services.layout_choice import PREDICTION_WEIGHT, describe_choice
from station.services.robust import simulation_cache_path

__all__ = ["AttemptReport", "Correction", "LoopProgress", "LoopResult", "LoopSettings", "LoopSummary",
           "RunLog", "labelled", "record_forecasts", "run_loop"]

#: The world's attempt numbers: loop k's attempt a is ``k * ATTEMPT_BLOCK + a`` (the baseline is loop 0).
ATTEMPT_BLOCK = 1000
_CALIBRATE, _PREDICT, _CAMERA, _CHOOSE = 12, 13, 14, 15  # what a derived seed is for
#: The optimizer's seed (``station optimize``'s default): loop 1's layout is the same in every world, and cached once
#: (its physics are the scenario's); a later loop's differs by its calibrated profile only.
OPTIMIZE_SEED = 0


@station_errors
@dataclass(frozen=True)
class LoopSettings:
    """The loop's sizes (all part of the run's identity, except ``loops``, ``workers`` and ``scheduler``).

    Attributes
    ----------
    attempts : int
        Attempts per loop.
    loops : int
        Loops (each after the first calibrates and re-optimizes); a later run with more loops carries on.
    budget : int or None
        Simulations of loop 1's optimization (``station optimize --budget``; None: its default, the thesis's budget
        for the scenario). It is made once per scenario and cached: it is the same in every world.
    reoptimize_budget : int or None
        Simulations of each later loop's optimization under the calibrated physics (None: ``station optimize``'s
        default, the thesis's budget for the scenario: at 200 BRANCHING's loop 2 succeeded 15/25 in five worlds, at
        its default 600 20/25; see docs/results/2026-12-04-the-loop.md).
    candidates : int
        Layouts of each optimization compared by their predicted physical success (its verified candidates, best
        first): the loop places the one surest to succeed often under the physics it knows.
    prediction_weight : float
        What a predicted success is worth against a layout's record on the table, in attempts
        (:data:`station.services.layout_choice.PREDICTION_WEIGHT`).
    every_material : bool
        Treat every material value as unknown, not only those the scenario marks uncertain: the plain numbers in their
        default range (:func:`design.contraption.materials.default_range`), in loop 1's prior and in every
        calibration (the world may differ from any of them).
    rounds : int
        Corrections after the first check at most (the camera checks again after each).
    baseline : int or None
        Attempts of the baseline (default ``attempts``; 0: none).
    predict_samples : int
        Simulations per attempt's predicted success.
    fit_draws, fit_sobol, fit_rounds : int
        The simulator calibration's sizes (:class:`calibration.sim_fit.FitSettings` draws, sobol, rounds).
    fit_prior_width : float
        The calibration's prior around the scenario's values, a share of each range (``prior_width``; 0: none,
        maximum likelihood).
    camera : str
        The simulated camera (``sim://camera?...``).
    settings : str
        The optimizer's PSP settings (``recommended`` or ``thesis``).
    jigs : bool
        Loop attempts use the layout's laser-cut jigs (:mod:`station.services.jigs`): per loop the simulated maker
        cuts them (their laser job run to its end on the laser twin, :func:`station.services.world.cut_jigs`),
        lays each over its footprint and sets its part on it; the parameters they set are ``set_with: "jig"``.
        Their checks also use the side camera (``side_camera``): it reads the face tag of each jig stand facing the
        board, the check measures the heights and tilts of the parts on them, and the maker sets those again as
        it says. The baseline (the thesis's workflow) never does.
    side_camera : str
        The simulated side camera of the attempts with jigs (``sim://camera?view=side...``, facing the board behind
        the parts; part of a run's identity only with ``jigs``).
    """

    attempts: int = 5
    loops: int = 2
    budget: int | None = None
    reoptimize_budget: int | None = None
    candidates: int = 4
    prediction_weight: float = PREDICTION_WEIGHT
    every_material: bool = True
    rounds: int = 3
    baseline: int | None = None
    predict_samples: int = 32
    fit_draws: int = 4
    fit_sobol: int = 8
    fit_rounds: int = 2
    fit_prior_width: float = 0.25
    camera: str = "sim://camera?supersample=1"
    settings: str = "recommended"
    jigs: bool = False
    #: the side camera's figures were measured 700 mm from the board (docs/results/2026-12-05-side-camera.md); raised
    #: to look down 20 degrees, it sees every board tag over the parts of the examples (docs/guide/side-camera.md);
    #: one sample per pixel as the top camera's here, for the loop's speed. It is check_cameras.SIDE_CAMERA written
    #: out, not derived: a run's identity holds it, and must not change when that default does
    side_camera: str = "sim://camera?view=side&height=700&tilt=-20&supersample=1"
    workers: int | None = field(default=None, compare=False)
    scheduler: str | None = field(default=None, compare=False)

    def check(self) -> None:
        """Refuse a bad size (a ServiceError naming it)."""
        from station.services.robust import SETTINGS_CHOICES, check_budget

        for name, low in (("attempts", 1), ("loops", 1), ("candidates", 1), ("rounds", 0),
                          ("predict_samples", 1), ("fit_draws", 1), ("fit_sobol", 2), ("fit_rounds", 0)):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or value < low:
                raise ServiceError(f"{name} must be an integer >= {low}, got {value!r}", field=name, value=value)
        for name in ("budget", "reoptimize_budget"):
            check_budget(getattr(self, name), name)  # None: the scenario's default
        width = self.fit_prior_width
        if isinstance(width, bool) or not isinstance(width, (int, float)) or not 0 <= width < math.inf:
            raise ServiceError(f"fit_prior_width must be a share of each range >= 0 (0: no prior), got {width!r}",
                               field="fit_prior_width", value=width)
        weight = self.prediction_weight
        if isinstance(weight, bool) or not isinstance(weight, (int, float)) or not 0 < weight < math.inf:
            raise ServiceError(f"prediction_weight must be a number > 0 (attempts), got {weight!r}",
                               field="prediction_weight", value=weight)
        if self.baseline is not None and (not isinstance(self.baseline, int) or self.baseline < 0):
            raise ServiceError(f"baseline must be an integer >= 0, got {self.baseline!r}", field="baseline",
                               value=self.baseline)
        if self.settings not in SETTINGS_CHOICES:
            raise ServiceError(f"settings must be one of {', '.join(SETTINGS_CHOICES)}, got {self.settings!r}",
                               field="settings", value=self.settings)
        if not str(self.camera).startswith("sim://camera"):
            raise ServiceError(f"camera: the loop's world is simulated, so its camera must be too (sim://camera?...), "
                               f"got {self.camera!r}", field="camera", value=self.camera)
        if not str(self.side_camera).startswith("sim://camera"):
            raise ServiceError(f"side_camera: the loop's world is simulated, so its side camera must be too "
                               f"(sim://camera?view=side...), got {self.side_camera!r}", field="side_camera",
                               value=self.side_camera)

    @property
    def baseline_attempts(self) -> int:
        return self.attempts if self.baseline is None else self.baseline

    def identity(self) -> dict[str, Any]:
        """What makes two runs the same run (``loops`` left out: more loops carry a run on)."""
        data = asdict(self)
        for name in ("loops", "workers", "scheduler", "baseline"):
            data.pop(name)
        if not self.jigs:  # only the attempts on jigs have anything for the side camera to read
            data.pop("side_camera")
        data["baseline"] = self.baseline_attempts
        data["world_revision"] = WORLD_REVISION  # a run made in another world is not carried on in this one
        return data


def _mean_known(values: list) -> float | None:
    known = [v for v in values if v is not None]
    return float(np.mean(known)) if known else None


@station_errors
@dataclass(frozen=True)
class LoopSummary:
    """One loop's figures."""

    loop: int
    attempts: int
    successes: int
    predicted: list[float]
    physics: dict[str, float]
    physics_name: str | None = None
    check_rounds: float = 0.0
    choice: str = ""  #: why its layout was placed (:func:`station.services.layout_choice.describe_choice`)
    forecast: list = field(default_factory=list)  #: each attempt's prediction updated by its layout's record
    jigs: bool = False  #: its attempts used the layout's laser-cut jigs

    @property
    def success_rate(self) -> float:
        return self.successes / self.attempts if self.attempts else math.nan

    @property
    def predicted_success(self) -> float | None:
        return _mean_known(self.predicted)

    @property
    def forecast_success(self) -> float | None:
        """The mean of the attempts' forecasts (:func:`record_forecasts`)."""
        return _mean_known(self.forecast)

    @property
    def interval(self) -> tuple[float, float]:
        """Wilson's 95 % interval of the success rate."""
        from calibration.sim_runs import wilson_interval

        return wilson_interval(self.successes, self.attempts)

    def to_json(self) -> dict[str, Any]:
        return {"loop": self.loop, "attempts": self.attempts, "successes": self.successes,
                "success_rate": self.success_rate, "predicted_success": self.predicted_success,
                "forecast_success": self.forecast_success, "physics": dict(self.physics)}


@station_errors
@dataclass(frozen=True)
class LoopResult:
    """A run's figures: its loops and the baseline, and its id in the database."""

    run_id: int
    scenario: str
    loops: list[LoopSummary]
    baseline_attempts: int
    baseline_successes: int
    #: (loop, attempt, success, predicted, forecast) of every loop attempt
    outcomes: list[tuple[int, int, bool, float | None, float | None]]
    hidden: dict[str, float]  #: the world's hidden material values (for benches: the station never reads them)
    baseline: list[bool] = field(default_factory=list)  #: the baseline's successes, in order
    jigs: bool = False  #: the loop attempts used the layout's laser-cut jigs

    @property
    def baseline_rate(self) -> float | None:
        return self.baseline_successes / self.baseline_attempts if self.baseline_attempts else None

    @property
    def baseline_interval(self) -> tuple[float, float]:
        """Wilson's 95 % interval of the baseline's success rate."""
        from calibration.sim_runs import wilson_interval

        return wilson_interval(self.baseline_successes, self.baseline_attempts)

    def to_json(self) -> dict[str, Any]:
        """Exactly the contract's ``station loop --json`` (``jigs``: the loop attempts used the laser-cut jigs)."""
        return {"loops": [s.to_json() for s in self.loops],
                "baseline": {"attempts": self.baseline_attempts, "success_rate": self.baseline_rate},
                "jigs": self.jigs}


def _attempts_words(count: int) -> str:
    return f"{count} attempt{'' if count == 1 else 's'}"


@station_errors
@dataclass(frozen=True)
class RunLog:
    """What a run of the loop has in the station database: its id, whether an earlier ``station loop`` began it,
    and its attempts logged against those it makes.

    Attributes
    ----------
    run_id : int
    resumed : bool
        An earlier invocation with the same arguments began the run (this one carries it on).
    logged : dict of int to int
        Attempts logged per loop (0: the baseline), each with its trial.
    planned : dict of int to int
        Attempts the run makes per loop (0: the baseline, when it has one).
    """

    run_id: int
    resumed: bool
    logged: dict[int, int]
    planned: dict[int, int]

    @property
    def attempts(self) -> int:
        """Attempts logged in all."""
        return sum(self.logged.values())

    def resuming(self) -> str:
        """``"resuming run 3: 4 attempts already logged"``."""
        return f"resuming run {self.run_id}: {_attempts_words(self.attempts)} already logged"

    def logged_words(self) -> str:
        """``"3 attempts logged (loop 1: 2 of 2, loop 2: 1 of 2, baseline: 0 of 1)"``: every loop begun or done."""
        parts = [f"{f'loop {k}' if k else 'baseline'}: {self.logged.get(k, 0)} of {n}"
                 for k, n in sorted(self.planned.items(), key=lambda item: (item[0] == 0, item[0]))
                 if self.logged.get(k, 0) or k == 1]
        return f"{_attempts_words(self.attempts)} logged ({', '.join(parts)})"


@station_errors
def loop_stopped(log: RunLog, new_simulations: int) -> Cancelled:
    """The :class:`~common.progress.Cancelled` of a run of the loop stopped on request (Ctrl-C, SIGTERM, a stop
    check): every attempt logged stays (each with its trial), and the same arguments resume the run; its
    ``partial`` is the :class:`RunLog` (what the run has), its ``new_simulations`` what the cache keeps."""
    return Cancelled(f"run {log.run_id} stopped: {log.logged_words()}", new_simulations=new_simulations,
                     cache=simulation_cache_path(), partial=log)


@dataclass(frozen=True)
class LoopProgress(Progress):
    """Progress of the loop: its stage says, in the maker's words, which loop and what it does ("loop 2:
    calibrating the simulator from 5 trials"); ``unit`` what ``done`` and ``total`` count (said by the CLI's bar)."""

    unit: str = "attempts"


#: The optimizer's phases where the loop's words would be ambiguous ("check" is the camera's in the loop).
_OPTIMIZER_PHASES = {"check": "verifying its best layouts"}


@station_errors
def labelled(progress: Progress, words: str) -> Progress:
    """``progress`` of work the loop called (an optimization, a calibration, a prediction) under the loop's
    ``words``: the work's own stage kept in parentheses when it says more than its unit ("exploration"), its type
    and figures kept (a robust run's CV accuracy)."""
    unit = getattr(progress, "unit", "simulations")
    own = _OPTIMIZER_PHASES.get(progress.stage, progress.stage)
    stage = words if own in ("", unit, "simulations") else f"{words} ({own})"
    if hasattr(progress, "unit"):
        return replace(progress, stage=stage)
    return LoopProgress(stage, progress.done, progress.total, progress.message, unit="simulations")


@station_errors
@dataclass(frozen=True)
class Correction:
    """What the check had the maker do to one part over an attempt's rounds (each round's moves summed).

    Attributes
    ----------
    name : str
    distance_mm, turn_deg : float
        How far it was moved on the sheet and turned (the turn signed, counter-clockwise positive).
    instruction : str
        The same in the check's own words (:func:`calibration.check.instruction`: which way to move and turn), and
        the parameters the side camera had set again.
    parameters : tuple of (str, float, str)
        ``(parameter, change, unit)`` of each parameter the side camera measured off (a height, a tilt) and the
        maker set again, in mm or degrees, summed over the rounds.
    """

    name: str
    distance_mm: float
    turn_deg: float
    instruction: str
    parameters: tuple[tuple[str, float, str], ...] = ()

    def short(self) -> str:
        """``"`track` moved 2.1 mm and turned 4.0 deg"``, ``"`track` moved 2.1 mm, track.z set 2.3 mm lower"``,
        ``"`track`: track.z set 2.3 mm lower"`` (a negligible move or turn left out)."""
        from calibration.check import NEGLIGIBLE_DEG, NEGLIGIBLE_MM

        did = []
        if self.distance_mm >= NEGLIGIBLE_MM:
            did.append(f"moved {self.distance_mm:.1f} mm")
        if abs(self.turn_deg) >= NEGLIGIBLE_DEG:
            did.append(f"turned {abs(self.turn_deg):.1f} deg")
        if self.parameters:  # the side camera's: after the move, or alone
            words = _parameter_words(self.parameters)
            return f"`{self.name}` {' and '.join(did)}, {words}" if did else f"`{self.name}`: {words}"
        return f"`{self.name}` " + (" and ".join(did) or "nudged")


def _parameter_words(parameters: Sequence[tuple[str, float, str]]) -> str:
    """``"track.z set 2.3 mm lower, track.roll 3.3 deg higher"``: the side camera's changes."""
    return ", ".join(f"{name} {'set ' if i == 0 else ''}{abs(change):.1f} {unit} {'higher' if change > 0 else 'lower'}"
                     for i, (name, change, unit) in enumerate(parameters))


@station_errors
@dataclass(frozen=True)
class AttemptReport:
    """One attempt in a line of its own (:meth:`describe`): what the check found and the simulated maker corrected,
    and how the run went.

    Attributes
    ----------
    loop, attempt, trial_id : int
        Loop 0 is the baseline; ``trial_id`` the trial it logged.
    success : bool
    checked : bool
        Placed with the highlight and checked (False: the baseline, from the printed sheet).
    corrections : tuple of Correction or None
        Per part the check had moved or turned, in the order first asked; None for an attempt logged before the run
        was resumed (its trial's notes say).
    rounds : int
        Corrections made (each followed by another check).
    left : tuple of str
        Parts still out of their tolerance after the last correction allowed.
    failed_at : str or None
        The first event of the scenario that did not happen in a failed run (where it failed).
    """

    loop: int
    attempt: int
    trial_id: int
    success: bool
    checked: bool
    corrections: tuple[Correction, ...] | None
    rounds: int = 0
    left: tuple[str, ...] = ()
    failed_at: str | None = None

    def _check(self, full: bool) -> str:
        if self.corrections is None:
            return f"already logged (`station trial show {self.trial_id}` says what was corrected)"
        if not self.checked:
            return "placed from the printed sheet, not checked"
        if not self.corrections:
            words = "the check found every part within its tolerance"
        elif full:
            rounds = f" ({self.rounds} rounds)" if self.rounds > 1 else ""
            words = (f"the maker corrected as the check said{rounds}: "
                     f"{'; '.join(c.instruction for c in self.corrections)}")
        else:
            rounds = f" in {self.rounds} rounds" if self.rounds > 1 else ""
            words = f"the check had {', '.join(c.short() for c in self.corrections)}{rounds}"
        if self.left:
            words += f"; still out of tolerance: {', '.join(f'`{name}`' for name in self.left)}"
        return words

    def correction_words(self) -> str:
        """What the check found and the maker did, in the check's words (a trial's notes): ``"the maker corrected
        as the check said: move `track` 2.1 mm right, turn it 4.0 deg clockwise"``."""
        return self._check(full=True)

    def describe(self) -> str:
        """The attempt in a short line: ``"loop 1, attempt 3 (trial 12): the check had `track` moved 2.1 mm and
        turned 4.0 deg; ran: success"``."""
        who = f"loop {self.loop}, attempt {self.attempt}" if self.loop else f"baseline, attempt {self.attempt}"
        ran = "success" if self.success else (f"failed at `{self.failed_at}`" if self.failed_at else "failed")
        return f"{who} (trial {self.trial_id}): {self._check(full=False)}; ran: {ran}"


def _failed_at(scenario, outcomes: Mapping[str, str]) -> str | None:
    """The first event (in the scenario's order) that did not happen."""
    return next((name for name in scenario.events if outcomes.get(name) == "no"), None)


def _corrections(rounds: Sequence[Sequence[Mapping[str, Any]]], view: str) -> tuple[Correction, ...]:
    """What the check had the maker do over ``rounds`` (each round's :func:`station.services.world.check_moves`),
    per part in the order first asked: its moves summed."""
    from calibration.check import instruction
    from design.contraption.schema import ANGLE_KEYS

    total: dict[str, list[float]] = {}
    changed: dict[str, dict[str, float]] = {}  # per part, the side camera's parameter changes summed
    for moves in rounds:
        for move in moves:
            summed = total.setdefault(str(move["name"]), [0.0, 0.0, 0.0])
            for i, key in enumerate(("du_mm", "dv_mm", "dheading_deg")):
                summed[i] += float(move[key])
            for parameter, change in (move.get("parameters") or {}).items():
                part = changed.setdefault(str(move["name"]), {})
                part[parameter] = part.get(parameter, 0.0) + float(change)
    result = []
    for name, (du, dv, dh) in total.items():
        # a move is designed minus measured; the check's words undo an error, measured minus designed
        words = instruction(name, (-du, -dv, math.hypot(du, dv), -dh), view)
        parameters = tuple((p, c, "deg" if p.rsplit(".", 1)[-1] in ANGLE_KEYS else "mm")
                           for p, c in changed.get(name, {}).items())
        if parameters:
            words += f"; the side camera had {_parameter_words(parameters)}"
        result.append(Correction(name, math.hypot(du, dv), dh, words, parameters))
    return tuple(result)


@station_errors
def record_forecasts(layouts: Mapping[int, dict], attempts: Sequence, weight: float) -> list[float | None]:
    """Each attempt's forecast: its predicted success updated by its layout's record before it.

    The record of attempt ``a`` of loop ``k`` is every earlier attempt (of loops >= 1: the baseline places another
    way) whose loop placed the same layout: in the loops before and earlier in loop ``k``. The forecast is
    :func:`station.services.layout_choice.expected_success` of the prediction and that record, so it is what the
    station could say before the attempt, knowing what it knew then.

    Parameters
    ----------
    layouts : mapping of int to dict
        Each loop's LAYOUT.json data.
    attempts : sequence of AttemptRow
        Attempts in order (loop, attempt); the baseline's (loop 0) get None.
    weight : float
        What a prediction is worth, in attempts.
    """
    from station.services.layout_choice import expected_success, same_layout

    # each loop's layout by the first loop that placed the same values: its record is kept under that loop
    first = {k: next(j for j in sorted(layouts) if j >= 1 and same_layout(layouts[j], layouts[k]))
             for k in layouts if k >= 1}
    records: dict[int, list[int]] = {}  # first loop -> [successes, attempts]
    out: list[float | None] = []
    for attempt in attempts:
        if attempt.loop < 1:
            out.append(None)
            continue
        record = records.setdefault(first[attempt.loop], [0, 0])
        out.append(None if attempt.predicted is None else expected_success(attempt.predicted, *record, weight))
        record[0] += attempt.success
        record[1] += 1
    return out


def _seed(world_seed: int, *words: int) -> int:
    """A seed for one purpose of one run (the world seed, what it is for, the loop, the attempt, the round)."""
    return int(np.random.SeedSequence([int(world_seed), *map(int, words)]).generate_state(1)[0] % 2**31)


class _Loop:
    """One run of the loop (see :func:`run_loop`)."""

    def __init__(self, store, scenario, world, url: str, settings: LoopSettings, report: Reporter,
                 folder: Path) -> None:
        from station.loopstore import run_key

        self.store, self.scenario, self.world, self.settings = store, scenario, world, settings
        self.report, self.folder = report, folder
        self.hidden = world.hidden_physics()
        identity = {"scenario": scenario.content_hash, "scenario_name": scenario.name, "world": url,
                    **settings.identity()}
        self.run_id, made = store.run(run_key(identity), scenario=scenario.name, content_hash=scenario.content_hash,
                                      world=url, settings=identity)
        self.resumed = not made
        self.where = {"workers": settings.workers, "scheduler": settings.scheduler}
        self._problem = None

    def log(self) -> RunLog:
        """What the run has logged so far."""
        logged: dict[int, int] = {}
        for attempt in self.store.attempts(self.run_id):
            logged[attempt.loop] = logged.get(attempt.loop, 0) + 1
        planned = {k: self.settings.attempts for k in range(1, self.settings.loops + 1)}
        if self.settings.baseline_attempts:
            planned[0] = self.settings.baseline_attempts
        return RunLog(self.run_id, self.resumed, logged, planned)

    # -- stopping and progress ------------------------------------------------------------------------------------
    def stop_point(self) -> None:
        self.report.check()

    def emit(self, stage: str, done: int, total: int, message: str = "", unit: str = "attempts") -> None:
        self.report.emit(LoopProgress(stage, done, total, message, unit=unit))

    def under(self, words: str) -> Reporter:
        """The reporter of work the loop calls: the loop's stop, its progress under ``words`` (:func:`labelled`)."""
        return self.report.mapped(lambda progress: labelled(progress, words))

    # -- layouts ------------------------------------------------------------------------------------------------
    def optimized(self, profile_path: Path | None, budget: int | None, words: str) -> dict:
        """The LAYOUT.json of ``station optimize`` for the scenario (under the profile), cached in the database by
        what it was optimized from and the revisions of the optimizing and simulating code; its progress reported
        under ``words``."""
        from design.contraption.simulation import SIMULATOR_REVISION
        from design.robust.pipeline import OPTIMIZER_REVISION
        from station.loopstore import run_key
        from station.services import robust
        from station.services.physics import problem_with_physics

        if self._problem is None:  # parsed once; a profile only changes its materials
            self._problem = robust.load_problem(self.scenario.source)
        problem = problem_with_physics(self._problem, profile_path)
        budget = robust.default_budget(problem, budget)
        key = run_key({"content_hash": problem.scenario.content_hash, "budget": budget, "seed": OPTIMIZE_SEED,
                       "settings": self.settings.settings, "optimizer": OPTIMIZER_REVISION,
                       "simulator": SIMULATOR_REVISION})
        cached = self.store.cached_layout(key)
        if cached is not None:
            return cached
        result = robust.optimize(problem, budget, OPTIMIZE_SEED, robust.psp_settings(self.settings.settings),
                                 report=self.under(words), **self.where)
        payload = result.to_json(problem)
        self.store.cache_layout(key, payload)
        return payload

    def loop_row(self, k: int):
        """Loop ``k``'s layout and physics: stored, or made now (and stored)."""
        from station.loopstore import LoopRow
        from station.services.layout_choice import candidate_layouts

        row = self.store.loop(self.run_id, k)
        if row is not None:
            return row
        self.stop_point()
        first = self.optimized(None, self.settings.budget, "loop 1: optimizing the layout")
        if k == 1:
            prior = self.prior()
            # The same choice in every world (the prior is the scenario's): its simulations are cached once.
            layout = self.choose(candidate_layouts(first, self.settings.candidates), prior, k, world_seed=0)
            row = LoopRow(1, layout, None, None, dict(prior.values) if prior is not None else {})
        else:
            profile = self.calibrate(k)
            text = profile.to_toml()
            path = self.folder / f"profile-{k}.toml"
            path.write_text(text, encoding="utf-8")
            new = self.optimized(path, self.settings.reoptimize_budget,
                                 f"loop {k}: re-optimizing the layout for the calibrated physics")
            # the layouts placed before (the latest first: ties keep it), each with its record in the trials
            placed = [self.store.loop(self.run_id, j).layout for j in range(k - 1, 0, -1)]
            options = [*placed, *candidate_layouts(new, self.settings.candidates),
                       *candidate_layouts(first, self.settings.candidates)]
            layout = self.choose(options, profile, k, world_seed=self.world.seed, trials=self.trials(k))
            row = LoopRow(k, layout, profile.name, text, dict(profile.values))
        self.store.add_loop(self.run_id, row)
        return self.store.loop(self.run_id, k)

    def choose(self, options: list[dict], profile, k: int, *, world_seed: int, trials: list[dict] = ()) -> dict:
        """The layout among ``options`` (the preferred first) surest to succeed often physically under
        ``profile`` and given its record in ``trials`` (:func:`station.services.layout_choice.choose_layout`), with
        the default placement error."""
        from station.services.layout_choice import LayoutChoiceRequest, choose_layout

        scored = [0, 0]  # the option being scored, of how many

        def scoring(i: int, count: int) -> None:
            self.stop_point()
            scored[:] = [i, count]
            self.emit(f"loop {k}: choosing the layout to place", i, count, f"candidate layout {i + 1} of {count}",
                      unit="candidate layouts")

        predicting = self.report.mapped(lambda progress: labelled(
            progress, f"loop {k}: predicting candidate layout {scored[0] + 1} of {scored[1]}"))

        request = LayoutChoiceRequest(profile, samples=self.settings.predict_samples,
                                      seed=_seed(world_seed, _CHOOSE, k), trials=tuple(trials),
                                      prediction_weight=self.settings.prediction_weight, **self.where)
        chosen = choose_layout(self.scenario, options, request, report=predicting, on_option=scoring)
        if scored[1]:
            self.emit(f"loop {k}: choosing the layout to place", scored[1], scored[1], "chosen",
                      unit="candidate layouts")
        return chosen

    def trials(self, k: int) -> list[dict]:
        """The trials of loops 1 .. k-1 (the baseline's, placed from the sheet with no check, left out)."""
        return [self.store.trial(a.trial_id) for a in self.store.attempts(self.run_id) if 0 < a.loop < k]

    def calibrate(self, k: int):
        """The physics profile fitted to every trial of loops 1 .. k-1."""
        from calibration.sim_fit import FitSettings
        from station.services.sim_calibration import SimCalibrationRequest, calibrate_sim

        trials = self.trials(k)
        s = self.settings
        fit = FitSettings(draws=s.fit_draws, sobol=s.fit_sobol, rounds=s.fit_rounds, held_out=0.0,
                          prior_width=s.fit_prior_width or None, seed=_seed(self.world.seed, _CALIBRATE, k))
        words = f"loop {k}: calibrating the simulator from {len(trials)} trial{'s' if len(trials) != 1 else ''}"
        request = SimCalibrationRequest(settings=fit, source="loop", every_material=self.settings.every_material,
                                        **self.where)
        result = calibrate_sim([self.scenario], trials, request, report=self.under(words))
        profile = result.profile(f"loop {k} of run {self.run_id}: calibrated {self.scenario.name}")
        # the creation time is the only thing of a profile that changes between two runs of the same data
        return replace(profile, created="", source=f"station loop run {self.run_id}: {len(trials)} trials of loops "
                       f"1-{k - 1}")

    # -- attempts -----------------------------------------------------------------------------------------------
    def files(self, row) -> tuple[Path, Path | None]:
        layout = self.folder / f"layout-{row.loop}.json"
        layout.write_text(json.dumps(row.layout), encoding="utf-8")
        profile = None
        if row.physics_content:
            profile = self.folder / f"profile-{row.loop}.toml"
            profile.write_text(row.physics_content, encoding="utf-8")
        return layout, profile

    def attempt(self, job, physics: Path | None, profile, k: int, a: int, *, checked: bool):
        """One attempt, an :class:`~station.services.assemble.Assembly` on the simulated world (the attempt
        ``station assemble`` walks a maker through): placed, checked and corrected until no part is to move (when
        ``checked``: highlighted, at most ``rounds`` corrections), run, predicted as checked, logged with the
        attempt in one transaction. Returns the stored attempt and its :class:`AttemptReport`."""
        from station.services.assemble import Assembly

        s, seed = self.settings, self.world.seed
        # with jigs the side camera reads the stands facing the board (none facing it: the top camera alone)
        side = s.side_camera if job.jigs is not None else None
        assembly = Assembly(job, self.scenario, camera=s.camera, side_camera=side, world=self.world,
                            physics=None if physics is None else str(physics), attempt=k * ATTEMPT_BLOCK + a,
                            samples=s.predict_samples, seed=_seed(seed, _PREDICT, k, a), workers=s.workers,
                            scheduler=s.scheduler, highlighted=checked, station_camera=False, _profile=profile)
        assembly.placed()
        applied, left = [], []
        if checked:
            for r in range(s.rounds + 1):
                assembly.check_parts(seed=_seed(seed, _CAMERA, k, a, r))
                moves = assembly.moves()
                if not moves or r == s.rounds:
                    left = [move["name"] for move in moves]
                    break
                applied.append(assembly.fix())
        assembly.accept()
        run = assembly.run()
        predicted = None
        if checked:
            words = f"loop {k}, attempt {a}: predicting its physical success as checked"
            predicted = float(assembly.forecast(report=self.under(words)).prediction.probability)
        said = AttemptReport(k, a, 0, run.success, checked, _corrections(applied, job.guide.view), len(applied),
                             tuple(left), _failed_at(self.scenario, run.outcomes))
        side = assembly.check.report.measured_by_side if assembly.check is not None else ()
        notes = self.note(job, said, predicted, side)
        stored = self.store.add_attempt(self.run_id, k, a, assembly.trial(who=f"simulated maker ({self.world.url})",
                                                                          notes=notes),
                                        predicted=predicted, check_rounds=len(applied))
        return stored, replace(said, trial_id=stored.trial_id)

    def note(self, job, said: AttemptReport, predicted: float | None, side: Sequence[str] = ()) -> str:
        """An attempt's trial notes: the run, the jigs, the parameters the side camera measured (``side``), the
        prediction and the check's corrections."""
        k, a = said.loop, said.attempt
        note = f"station loop run {self.run_id}: " + (f"loop {k} attempt {a}" if k else f"baseline attempt {a}")
        if job.guide.jigs:
            note += f"; set on laser-cut jigs {', '.join(j.id for j in job.guide.jigs)}"
        if job.jigs is not None and job.jigs.plan.by_hand:
            note += "; no jig for " + ", ".join(f"`{b.part}` ({b.reason})" for b in job.jigs.plan.by_hand)
        if side:
            note += f"; the side camera measured {', '.join(side)}"
        if predicted is not None:
            note += f"; predicted physical success {predicted:.3f}"
        return note + f"; {said.correction_words()}"

    def prior(self):
        """What the station knows of the physics before any trial: the scenario's values and their ranges (the
        uncertain ones', and with ``every_material`` the default ranges of the others). Loop 1 chooses its layout
        and predicts with them, so its probabilities carry that uncertainty, as a calibrated profile's do."""
        from design.contraption.physics_profile import PhysicsProfile
        from station.services.sim_calibration import material_ranges

        ranges = material_ranges(self.scenario, self.settings.every_material)
        if not ranges:
            return None
        return PhysicsProfile(name=f"{self.scenario.name}: its own values and ranges",
                              values={k: v for k, (v, _) in ranges.items()},
                              intervals={k: bounds for k, (_, bounds) in ranges.items()})

    def run_attempts(self, row, k: int, count: int, *, checked: bool,
                     on_attempt: Callable[[AttemptReport], None] | None = None) -> list:
        """Loop ``k``'s attempts (``k`` 0: the baseline, on loop 1's layout), the stored ones kept; ``on_attempt``
        is told each attempt in order (a stored one as logged before this run was resumed)."""
        from station.services.guide import GuideRequest, make_guide
        from station.services.physics import read_profile

        done = {a.attempt: a for a in self.store.attempts(self.run_id, k)}
        who = f"loop {k}" if k else "baseline"
        stage = f"{who}: placing, checking and running" if k else f"{who}: placing from the printed sheet and running"
        job = profile = profile_path = None
        for a in range(1, count + 1):
            if a in done:
                said = self.stored_report(done[a], checked)
            else:
                if job is None:
                    layout_path, profile_path = self.files(row)
                    profile = read_profile(profile_path) if profile_path else self.prior()
                    request = GuideRequest(self.scenario.source, str(layout_path), physics=profile_path,
                                           jigs=bool(k and self.settings.jigs))
                    job = make_guide(request, report=self.under(f"{who}: making the guide"))
                    if job.jigs is not None:
                        self.cut(job, who)
                self.stop_point()
                self.emit(stage, len(done), count, f"attempt {a} of {count}")
                done[a], said = self.attempt(job, profile_path, profile, k, a, checked=checked)
            if on_attempt is not None:
                on_attempt(said)
        self.emit(stage, count, count, "done")
        return [done[a] for a in range(1, count + 1)]

    def cut(self, job, who: str) -> None:
        """The simulated maker cuts the guide's jigs on the laser twin (their laser job run to its end)."""
        from station.services import world as worlds

        count = len(job.jigs.plan.jigs)
        stage = f"{who}: cutting the jigs on the laser"
        self.emit(stage, 0, 1, f"{count} jig{'' if count == 1 else 's'}", unit="laser jobs")
        worlds.cut_jigs(job)
        self.emit(stage, 1, 1, "cut", unit="laser jobs")

    def stored_report(self, stored, checked: bool) -> AttemptReport:
        """The :class:`AttemptReport` of an attempt logged before the run was resumed: its corrections only in its
        trial's notes."""
        trial = self.store.trial(stored.trial_id)
        return AttemptReport(stored.loop, stored.attempt, stored.trial_id, stored.success, checked, None,
                             stored.check_rounds, (), _failed_at(self.scenario, trial.get("outcomes") or {}))


@station_errors
def run_loop(scenario: str, world: str, settings: LoopSettings | None = None, *, database: str | None = None,
             report: Reporter | None = None, on_start: Callable[[RunLog], None] | None = None,
             on_loop: Callable[[LoopSummary], None] | None = None,
             on_attempt: Callable[[AttemptReport], None] | None = None) -> LoopResult:
    """Run (or resume) the station loop of ``scenario`` in the simulated ``world``.

    Parameters
    ----------
    scenario : str
        A scenario file or example name.
    world : str
        ``sim://world?seed=S&...`` (:mod:`drivers.sim.world`).
    settings : LoopSettings, optional
    database : str, optional
        The station database (default :func:`station.db.database_url`).
    report : Reporter, optional
        Progress (:class:`common.progress.Progress`) and the stop check.
    on_start : callable, optional
        Called with the run's :class:`RunLog` once it is found or made (``resumed``: an earlier ``station loop``
        with the same arguments began it, and its attempts logged are kept).
    on_loop : callable, optional
        Called with each loop's summary as it ends (a CLI prints it).
    on_attempt : callable, optional
        Called with each attempt's :class:`AttemptReport` as it ends (an attempt logged before a resume too, as
        the loop reaches it), the baseline's last.

    Raises
    ------
    common.progress.Cancelled
        A stop (``report``'s stop check, or KeyboardInterrupt: a second Ctrl-C): what was logged stays, and the
        same arguments resume the run; it says what the run has logged (:func:`loop_stopped`).
    ServiceError
        A bad setting or world URL (naming it).
    drivers.errors.SimConfigError
        A bad world or camera option (one line).
    """
    from station.loopstore import LoopStore
    from station.services import world as worlds
    from station.services.trials import load_trial_scenario

    settings = settings or LoopSettings()
    settings.check()
    report = Reporter.of(report)
    loaded = load_trial_scenario(scenario)
    if not loaded.design_space.names:
        raise ServiceError(f"scenario: {loaded.name} has no design parameters: there is nothing to optimize or "
                           "check", field="scenario", value=scenario)
    the_world = worlds.open_world(world)
    worlds.prepare_world(the_world, loaded)
    with LoopStore(database) as store, tempfile.TemporaryDirectory(prefix="station-loop-") as folder:
        run = _Loop(store, loaded, the_world, world, settings, report, Path(folder))
        if on_start is not None:
            on_start(run.log())
        try:
            result = _run(run, settings, on_loop, on_attempt)
        except (Cancelled, KeyboardInterrupt) as stopped:
            raise loop_stopped(run.log(), getattr(stopped, "new_simulations", 0)) from None
        finally:
            the_world.close()
    return result


def _run(run: _Loop, settings: LoopSettings, on_loop, on_attempt) -> LoopResult:
    """The loops and the baseline of ``run`` (see :func:`run_loop`)."""
    from station.loopstore import LoopRow

    summaries: list[LoopSummary] = []
    outcomes: list[tuple[int, int, bool, float | None, float | None]] = []
    layouts: dict[int, dict] = {}
    placed: list = []  # every loop attempt so far, in order
    for k in range(1, settings.loops + 1):
        row = run.loop_row(k)
        attempts = run.run_attempts(row, k, settings.attempts, checked=True, on_attempt=on_attempt)
        rounds = float(np.mean([a.check_rounds for a in attempts]))
        layouts[k] = row.layout
        placed += attempts
        forecast = record_forecasts(layouts, placed, settings.prediction_weight)[-len(attempts):]
        summary = LoopSummary(k, len(attempts), sum(a.success for a in attempts), [a.predicted for a in attempts],
                              dict(row.physics_values), row.physics_name, rounds, describe_choice(row.layout),
                              forecast, settings.jigs)
        summaries.append(summary)
        outcomes += [(k, a.attempt, a.success, a.predicted, f) for a, f in zip(attempts, forecast)]
        if on_loop is not None:
            on_loop(summary)
    baseline = []
    if settings.baseline_attempts:
        # the thesis's workflow places the optimizer's own layout (no choice by physical prediction)
        thesis = LoopRow(0, run.optimized(None, settings.budget, "baseline: optimizing the layout"), None, None, {})
        baseline = run.run_attempts(thesis, 0, settings.baseline_attempts, checked=False, on_attempt=on_attempt)
    return LoopResult(run.run_id, run.scenario.name, summaries, len(baseline), sum(a.success for a in baseline),
                      outcomes, run.hidden, [a.success for a in baseline], settings.jigs)
