"""The world twin, the station's half: what the camera sees of the parts as placed, the moves a check asks for, an
attempt's run under the hidden physics, and synthetic trials.

The twin is two modules, split by the layering alone: the device (:mod:`drivers.sim.world`, ``sim://world``: the
hidden material values and the simulated maker's hands; a driver never imports ``design``, so it only knows plain
poses) and this one, which holds everything that needs the contraption. It turns a guide into the parts the
simulated maker places (:func:`guide_parts`), the maker's placed poses into the scene the camera twin renders
(:func:`world_scene`: each part's tags carried rigidly with the part, through
:func:`station.services.check_scene.sim_scene`, so the check measures them as it would on a real table), a check
into the moves its instructions ask for (:func:`check_moves`), and runs an attempt (:func:`run_attempt`): the placed
poses become design parameters (:func:`calibration.asbuilt.as_built_layout`, the *as-placed* layout), and the
scenario simulates it under the world's hidden material values (:func:`run_hidden`, which sorts a simulation's
events into a maker's ticks for every run here, :func:`synthetic_trials`' too).

The simulated maker knows only what the guide says: the world is handed the guide's manifest (each part's drawn
pose and its ``parameters`` with their ``set_with``, the jigs) and the ranges of the design parameters, never the
layout. Parameters off the plane (a height, a tilt) are those the world set on its own with the error of how the
guide said to set them (:meth:`drivers.sim.world.SimulatedWorld.settings`); a parameter the guide did not state at
all is the maker's guess over its range.

The hidden physics is read here and nowhere else in the station (the bench reports it next to what calibration
found).
"""

from __future__ import annotations

import math
import uuid
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from calibration.asbuilt import PlanePose, as_built_layout
from calibration.check import NEGLIGIBLE_DEG, NEGLIGIBLE_MM, jig_views
from calibration.sim_runs import DEFAULT_ANGLE_SIGMA_DEG, DEFAULT_POSITION_SIGMA_M, widened
from design.contraption.schema import ANGLE_KEYS
from design.contraption.simulation import ASLEEP, SUCCESS, simulate
from design.contraption.validation import with_physics
from drivers.devices import UnknownDeviceURL, resolve
from drivers.grbl import GrblConnection, Job, JobRunner
from drivers.sim.world import maker_sigma
from projector.board import side_board
from projector.guide import IN_PLANE_ROLES
from station.errors import ServiceError, station_errors
from station.services.check import grab_frame
from station.services.check_scene import sim_scene
from station.services.check_side import side_frame, side_targets
from station.services.jigs import cut_jigs as laser_job

__all__ = ["AttemptRun", "as_placed_layout", "check_moves", "cut_jigs", "design_ranges", "grab_placed",
           "grab_placed_side", "guide_jigs", "guide_parts", "guide_sigma", "open_world", "place_parts", "prepare_world",
           "run_attempt", "run_hidden", "synthetic_trials", "trials_export", "world_scene"]


@station_errors
def open_world(url: str):
    """The world at ``url`` (``sim://world?...``): a ServiceError naming ``world`` for any other device; a bad
    option is the driver's one-line SimConfigError."""
    try:
        info = resolve(url)
    except UnknownDeviceURL as error:
        raise ServiceError(f"world: {error}", field="world", value=url) from None
    if info.kind != "world":
        raise ServiceError(f"world: {url!r} is a {info.kind}, not a world; expected sim://world?seed=S",
                           field="world", value=url)
    world = info.factory(info.url)
    world.open()
    return world


@station_errors
def prepare_world(world, scenario) -> dict[str, float]:
    """Draw the world's hidden material values around ``scenario``'s (every material value; an uncertain one kept in
    its range, which the simulator requires) and return them."""
    ranges = {name: bounds for name, (_, bounds) in scenario.uncertain_parameters().items()}
    world.draw_physics(scenario.physics_parameters(), bounds=ranges)
    return world.hidden_physics()


@station_errors
def guide_parts(guide) -> list[dict]:
    """Every part of ``guide`` as the maker is told it: ``{"name", "center_mm", "heading_deg", "parameters"}``, the
    parameters as the guide manifest states them (``name``, ``value``, ``unit``, ``role``, ``set_with``)."""
    return [{"name": p.name, "center_mm": [float(p.center_mm[0]), float(p.center_mm[1])],
             "heading_deg": float(p.heading_deg),
             "parameters": [{"name": q.name, "value": float(q.value), "unit": q.unit, "role": q.role,
                             "set_with": q.set_with} for q in p.settings]} for p in guide.parts]


@station_errors
def guide_jigs(guide) -> list[dict]:
    """The jigs the guide's steps use, as the maker is told them: ``{"id", "part", "parameters"}``."""
    return [{"id": j.id, "part": j.part, "parameters": list(j.parameters)} for j in guide.jigs]


@station_errors
def design_ranges(scenario) -> dict[str, list]:
    """Every design parameter's range as a maker sees it on the contraption: ``{name: [lower, upper, unit]}``, in
    mm or degrees (what the maker guesses within when the guide does not state a parameter)."""
    space = scenario.design_space
    ranges = {}
    for name, lower, upper in zip(space.names, space.lower, space.upper):
        scale, unit = (1.0, "deg") if name.rsplit(".", 1)[-1] in ANGLE_KEYS else (1000.0, "mm")
        ranges[name] = [float(lower) * scale, float(upper) * scale, unit]
    return ranges


@station_errors
def guide_sigma(guide, scenario, *, highlighted: bool) -> dict[str, float]:
    """Each design parameter's placement error (one standard deviation in real units, m or deg) as ``guide`` tells
    the maker to set it, by the world twin's maker (:func:`drivers.sim.world.maker_sigma`, its defaults): a part's
    in-plane parameters with the error of its pose (on a jig: the jig laid by eye and the part seated on it; with a
    ruler; else by eye on the sheet, ``highlighted`` or not), every other stated parameter with the error of its
    ``set_with``, and one the guide does not state guessed over its range (a uniform draw's standard deviation).
    What the station predicts with (:class:`station.services.predict.PredictionRequest`'s ``set_sigma``), so that a
    forecast knows a ruler from a jig as the world does."""
    jigged = {jig.part for jig in guide.jigs}
    sigma: dict[str, float] = {}
    for part in guide.parts:
        in_plane = {q.set_with for q in part.settings if q.role in IN_PLANE_ROLES}
        if part.name in jigged:  # the jig's own placement by eye, then the seating on it
            (sheet_mm, sheet_deg), (jig_mm, jig_deg) = maker_sigma("sheet", highlighted), maker_sigma("jig")
            pose = (math.hypot(sheet_mm, jig_mm), math.hypot(sheet_deg, jig_deg))
        else:
            pose = maker_sigma("ruler" if "ruler" in in_plane else "sheet", highlighted)
        for setting in part.settings:
            if setting.name not in sigma:  # stated by several parts (an Empty frame's): set once
                mm, deg = pose if setting.role in IN_PLANE_ROLES else maker_sigma(setting.set_with, highlighted)
                sigma[setting.name] = float(deg) if setting.unit == "deg" else float(mm) / 1000.0
    for name, (lower, upper, unit) in design_ranges(scenario).items():
        if name not in sigma:
            spread = (upper - lower) / math.sqrt(12.0)
            sigma[name] = spread if unit == "deg" else spread / 1000.0
    return sigma


def _offsets(guide, placed: Mapping[str, Mapping]) -> dict[str, tuple[float, float, float]]:
    """Per part, where it is minus where the guide draws it: ``(du mm, dv mm, dheading deg)``."""
    result = {}
    for part in guide.parts:
        pose = placed.get(part.name)
        if pose is not None:
            result[part.name] = (float(pose["center_mm"][0]) - part.center_mm[0],
                                 float(pose["center_mm"][1]) - part.center_mm[1],
                                 float(pose["heading_deg"]) - part.heading_deg)
    return result


@station_errors
def world_scene(guide, placed: Mapping[str, Mapping]):
    """The :class:`~drivers.sim.camera_scene.PlaneScene` of the parts as placed: reference tags, every tag carried
    with its part's pose, the sheet under them (with the parts' footprints where they are)."""
    tagged = {p.name for p in guide.parts if p.tag_views() or jig_views(guide, p)}  # a stand's tag moves with its part
    offsets = {k: v for k, v in _offsets(guide, placed).items() if k in tagged}
    return sim_scene(guide, offsets)


@station_errors
def grab_placed(camera_url: str, guide, placed: Mapping[str, Mapping], seed: int):
    """One frame of the parts as placed from the simulated camera at ``camera_url`` (its noise seeded by ``seed``
    unless the URL sets one), and the twin's own intrinsics."""
    return grab_frame(camera_url, guide, scene=world_scene(guide, placed), seed=seed)


@station_errors
def grab_placed_side(camera_url: str, job, world, seed: int):
    """One frame of the parts as placed from the simulated side camera at ``camera_url`` (``sim://camera?view=side``,
    facing the board behind them): the board's tags and each jig stand's face tag where the world's maker really set
    its part (:func:`as_placed_layout`: its height and tilt as the guide told them to be set, with that way's error),
    and the twin's own intrinsics; what :func:`station.services.check_side.measure_side` reads."""
    board = side_board(job.guide)
    targets = side_targets(job, board)
    layout = as_placed_layout(job.scenario, job.guide, world)
    return side_frame(job, board, targets, camera_url, layout=layout, seed=seed)


#: The zone a part is kept to when its check knows no tolerance for it (none fitted, or bound only by its range's
#: end): about twice the check's own resolution, so the maker is not sent back for every half millimetre.
UNKNOWN_TOLERANCE_MM, UNKNOWN_TOLERANCE_DEG = 1.0, 1.0


@station_errors
def check_moves(check: Mapping[str, Any], guide, *, all_parts: bool = False) -> list[dict]:
    """What a CHECK.json's instructions ask the maker to do: ``[{"name", "du_mm", "dv_mm", "dheading_deg"}]`` per
    part out of its tolerance (or, with no tolerance known, off by more than :data:`UNKNOWN_TOLERANCE_MM` /
    :data:`UNKNOWN_TOLERANCE_DEG`), designed minus measured (``all_parts``: every part the instruction moves). A
    part checked by its bodies (a run's first and last dominoes) is moved by its first measured body: the part's
    origin found from it as :func:`calibration.check.measured_pose` does. A part the side camera found off also
    carries ``"parameters": {name: change}`` (mm or degrees): its height and tilt set again as the side view says.
    """
    by_name = {p.name: p for p in guide.parts}
    bodies = {(p.name, b.body): b for p in guide.parts for b in p.body_tags}
    moves: dict[str, dict] = {}
    for entry in check.get("parts", []):
        error, name = entry.get("error"), str(entry.get("name", ""))
        if error is None or entry.get("within_tolerance") is True and not all_parts:
            continue
        owner, _, body = name.partition("[")
        part = by_name.get(owner)
        if part is None or owner in moves:
            continue
        du, dv, dheading = float(error["du_mm"]), float(error["dv_mm"]), float(error["heading_deg"])
        if body:  # the body's error: turn the part's origin about the body by the heading error
            drawn = bodies.get((owner, int(body.rstrip("]"))))
            if drawn is None:
                continue
            turn = math.radians(dheading)
            offset = np.subtract(part.center_mm, drawn.center_mm)
            rotated = np.array([math.cos(turn) * offset[0] - math.sin(turn) * offset[1],
                                math.sin(turn) * offset[0] + math.cos(turn) * offset[1]])
            du, dv = np.add([du, dv], rotated - offset)
        if abs(du) < NEGLIGIBLE_MM and abs(dv) < NEGLIGIBLE_MM and abs(dheading) < NEGLIGIBLE_DEG:
            continue
        if entry.get("within_tolerance") is None and not all_parts and abs(du) <= UNKNOWN_TOLERANCE_MM \
                and abs(dv) <= UNKNOWN_TOLERANCE_MM and abs(dheading) <= UNKNOWN_TOLERANCE_DEG:
            continue
        moves[owner] = {"name": owner, "du_mm": -float(du), "dv_mm": -float(dv), "dheading_deg": -float(dheading)}
    for owner, changes in _side_changes(check, by_name, all_parts).items():  # a side camera's heights and tilts
        moves.setdefault(owner, {"name": owner, "du_mm": 0.0, "dv_mm": 0.0, "dheading_deg": 0.0})["parameters"] = \
            changes
    return list(moves.values())


def _side_changes(check: Mapping[str, Any], by_name, all_parts: bool) -> dict[str, dict[str, float]]:
    """Per part the side camera found off (``side_parts``, the same rule as :func:`check_moves`), the change of
    each parameter it measured (``measured_by`` "side"): designed minus measured, in mm or degrees."""
    layout, measured, by = check.get("layout", {}), check.get("as_measured", {}), check.get("measured_by", {})
    result = {}
    for entry in check.get("side_parts", []):
        owner, error = str(entry.get("name", "")), entry.get("error")
        part = by_name.get(owner)
        if part is None or error is None or entry.get("within_tolerance") is True and not all_parts:
            continue
        changes = {}
        for name in part.parameters:
            if by.get(name) != "side" or name not in measured or name not in layout:
                continue
            angle = name.rsplit(".", 1)[-1] in ANGLE_KEYS
            change = (float(layout[name]) - float(measured[name])) * (1.0 if angle else 1000.0)
            limit = (UNKNOWN_TOLERANCE_DEG if angle else UNKNOWN_TOLERANCE_MM) \
                if entry.get("within_tolerance") is None and not all_parts else \
                (NEGLIGIBLE_DEG if angle else NEGLIGIBLE_MM)
            if abs(change) >= limit:
                changes[name] = change
        if changes:
            result[owner] = changes
    return result


@station_errors
@dataclass(frozen=True)
class AttemptRun:
    """One attempt's run in the world.

    Attributes
    ----------
    outcomes : dict
        ``{event: "yes" | "no" | "not-reached"}``, the way a maker ticks them.
    times : dict
        ``{event: seconds}`` of the events that happened (to the millisecond).
    success : bool
    as_placed : dict
        The layout as the parts were really placed (design parameters), what was simulated.
    """

    outcomes: dict[str, str]
    times: dict[str, float]
    success: bool
    as_placed: dict[str, float]

    def to_json(self) -> dict:
        return {"outcomes": dict(self.outcomes), "times": dict(self.times), "success": self.success}


@station_errors
def as_placed_layout(scenario, guide, world) -> np.ndarray:
    """The layout as the world's parts are really placed: every parameter as the maker set it
    (:meth:`drivers.sim.world.SimulatedWorld.settings`: out of the plane with the error of its ``set_with``, a
    parameter the guide did not state guessed over its range), then the in-plane ones the guide states fitted to the
    parts' poses as placed (:meth:`~drivers.sim.world.SimulatedWorld.placed`). The designed layout is not read.

    Raises
    ------
    ServiceError
        A design parameter the world did not set (placed without the scenario's ranges: :func:`place_parts`).
    """
    names = list(scenario.design_space.names)
    settings = world.settings()
    missing = [n for n in names if n not in settings]
    if missing:
        raise ServiceError(f"world: {', '.join(missing)} not set by the maker: the guide does not state it and the "
                           "world was placed without the scenario's ranges (place_parts(..., scenario=...))",
                           field="world", value=missing[0])
    values = np.array([settings[n]["value"] / (1.0 if settings[n]["unit"] == "deg" else 1000.0) for n in names])
    in_plane = {p.name: [q.name for q in p.settings if q.role in IN_PLANE_ROLES] for p in guide.parts}
    placed = world.placed()
    poses = {name: PlanePose(tuple(pose["center_mm"]), pose["heading_deg"]) for name, pose in placed.items()
             if in_plane.get(name)}
    wide = widened(scenario)
    built = as_built_layout(wide, values, guide.plane, poses, in_plane)
    return np.clip(np.asarray(built.x, dtype=float), wide.design_space.lower, wide.design_space.upper)


@station_errors
def run_attempt(scenario, x, guide, world, hidden: Mapping[str, float] | None = None) -> AttemptRun:
    """Run the attempt the world's parts are placed for, under its hidden physics.

    Parameters
    ----------
    scenario : Scenario
        As the maker has it (its own material values are not used).
    x : array_like
        The designed layout (real units), the one the guide draws: named for the record, never read (the maker set
        what the guide told them, :func:`as_placed_layout`).
    guide : projector.guide.Guide
    world : drivers.sim.world.SimulatedWorld
        Placed (:meth:`~drivers.sim.world.SimulatedWorld.place`) and possibly corrected.
    hidden : mapping, optional
        The hidden material values (default the world's, :func:`prepare_world` first).
    """
    hidden = dict(world.hidden_physics() if hidden is None else hidden)
    if not hidden:
        raise ServiceError("world: no hidden physics drawn yet (prepare_world first)", field="world")
    layout = as_placed_layout(scenario, guide, world)
    outcomes, times, success = run_hidden(scenario, hidden, layout)
    names = scenario.design_space.names
    return AttemptRun(outcomes, times, success, dict(zip(names, map(float, layout))))


@station_errors
def run_hidden(scenario, hidden: Mapping[str, float], x) -> tuple[dict[str, str], dict[str, float], bool]:
    """Simulate the layout ``x`` (real units, as really placed) under the ``hidden`` material values: every event
    as a maker ticks it (``{event: "yes" | "no" | "not-reached"}``, in the scenario's order), the times of those that
    happened (seconds, to the millisecond, as a video would give them) and whether the goal was reached."""
    result = simulate(widened(with_physics(scenario, dict(hidden))), np.asarray(x, dtype=float), early_stop="settled")
    outcomes, times = {}, {}
    for event in scenario.events:
        outcome = result.events[event]
        if outcome.state == SUCCESS:
            outcomes[event] = "yes"
            times[event] = round(float(outcome.time), 3)
        else:
            outcomes[event] = "not-reached" if outcome.state == ASLEEP else "no"
    return outcomes, times, bool(result.success)


@station_errors
def synthetic_trials(scenario, layouts, hidden: Mapping[str, float], *, seed: int = 0, times: bool = True,
                     position_sigma_m: float | None = None, angle_sigma_deg: float | None = None,
                     content: str | None = None) -> list[dict]:
    """Trials of the crudest world: each designed layout of ``layouts`` (real units) placed with a Gaussian error on
    every parameter (default :data:`calibration.sim_runs.DEFAULT_POSITION_SIGMA_M` /
    :data:`~calibration.sim_runs.DEFAULT_ANGLE_SIGMA_DEG`) and run under ``hidden`` material values
    (:func:`run_hidden`), in the trial log's export format with the designed layout and no check, as a maker's
    unchecked runs are logged (so a fit, as for those, simulates the designed layout).

    For checking the simulator calibration against a known answer (tests, ``bench/bench_sim_calibration.py``) and
    trying the calibration commands without a workshop. It does not go through
    :class:`calibration.sim_runs.OutcomeProblem`, the fit's own simulation path, so that a mistake there does not
    also shape its test data.

    Parameters
    ----------
    scenario : Scenario
        As the maker has it (its own material values are not used).
    layouts : sequence of arrays
        Designed layouts, one trial each.
    hidden : mapping
        The "real" material values, ``{"wood.friction": 0.55}``.
    seed : int
        Seed of the placement errors.
    times : bool
        Log the times of the events that happened.
    content : str, optional
        The scenario file's text for the trials' ``scenario.content`` (default: the file at ``scenario.source``).

    Returns
    -------
    list of dict
        Trials in the export format (``id`` from 1; :func:`trials_export` makes the file's content).
    """
    position = DEFAULT_POSITION_SIGMA_M if position_sigma_m is None else position_sigma_m
    angle = DEFAULT_ANGLE_SIGMA_DEG if angle_sigma_deg is None else angle_sigma_deg
    if content is None:
        content = Path(scenario.source).read_text(encoding="utf-8")
    names = scenario.design_space.names
    sigma = np.array([angle if n.rsplit(".", 1)[1] in ANGLE_KEYS else position for n in names])
    rng = np.random.default_rng(seed)
    trials = []
    for i, layout in enumerate(layouts):
        layout = np.asarray(layout, dtype=float)
        outcomes, logged, success = run_hidden(scenario, hidden, layout + rng.standard_normal(len(names)) * sigma)
        trials.append({
            "id": i + 1, "uid": uuid.UUID(int=int(rng.integers(0, 2**63)) << 64 | i).hex,
            "scenario": {"name": scenario.name, "content_hash": scenario.content_hash, "content": content},
            "layout": dict(zip(names, layout.tolist())), "as_built": None, "check": None, "physics": None,
            "outcomes": outcomes, "times": logged if times else {}, "success": success,
            "who": "simulator", "created_at": "2026-01-01T00:00:00Z",
            "notes": "synthetic: simulated under hidden material values", "photos": [],
        })
    return trials


@station_errors
def trials_export(trials: list[dict]) -> dict:
    """Trials as a whole trial export file's content."""
    return {"format": "chaos-station trials", "version": 1, "trials": trials}


#: The laser the simulated maker cuts the jigs on: the station's laser twin on a virtual clock (a cut of minutes runs
#: in well under a second; the G-code, the pre-flight and the streaming are the real ones).
JIG_LASER = "sim://grbl?profile=laser&clock=virtual"


@station_errors
def cut_jigs(job, laser: str = JIG_LASER) -> list[dict]:
    """The simulated maker cuts a guide job's jigs (``make_guide(..., jigs=True)``): each sheet's laser job, as
    ``station jigs`` writes it (``jigs.gcode``), pre-flighted and run to its end on the laser at ``laser``.

    Returns
    -------
    list of dict
        Per sheet: ``{"sheet", "lines", "state"}``.

    Raises
    ------
    ServiceError
        The job has no jigs, or a sheet's job did not run to its end with the beam off (naming the sheet).
    """
    if job.jigs is None:
        raise ServiceError("jigs: the guide has no jigs to cut (make_guide(..., jigs=True))", field="jigs")
    sheets = laser_job(job, job.jigs).sheets
    done = []
    connection = GrblConnection(laser, poll_interval=0.05, lost_ok_timeout=0.3, silence_timeout=0.6).open()
    try:
        for output in sheets:
            runner = JobRunner(connection, Job.from_text(f"jigs sheet {output.index}", output.gcode, laser=True))
            runner.preflight()
            result = runner.run()
            if result.state != "done" or not result.laser_off:
                raise ServiceError(f"jigs: sheet {output.index}'s laser job did not finish on {laser}: "
                                   f"{result.message}", field="jigs", value=output.index)
            done.append({"sheet": output.index, "lines": len(output.gcode.splitlines()), "state": result.state})
    finally:
        connection.close()
    return done


@station_errors
def place_parts(world, guide, *, attempt: int, highlighted: bool, scenario=None) -> None:
    """The maker places every part of ``guide`` for ``attempt`` (highlighted: the projector shows each), on its jig
    where the guide has one, and sets every parameter as the guide says; with ``scenario``, a parameter the guide
    does not state is guessed over its range (without it, :func:`as_placed_layout` refuses such a guide)."""
    world.place(guide_parts(guide), attempt=attempt, highlighted=highlighted, jigs=guide_jigs(guide),
                ranges=None if scenario is None else design_ranges(scenario))
