"""The as-built check as a service: a camera frame of the placed parts against the layout's guide.

Used by ``station check`` and the Assemble screen (key c). :func:`prepare_check` makes (or reads) the guide once;
:func:`check_frame` measures one frame (:func:`calibration.measure.measure`), checks every part
(:mod:`calibration.check`), fits the as-built layout (:mod:`calibration.asbuilt`) and scores it with the layout's
success model (the ``"model"`` a LAYOUT.json of ``station optimize`` carries), and on request by simulating it
(``simulate=N``: the as-built layout N times with the measurement's residual error as placement noise, on the shared
simulation cache). :func:`grab_frame` takes the frame from a camera; a simulated camera (``sim://camera``) is handed a
scene of the guide's reference tags and part tags at their designed poses first (:func:`sim_scene`), moved only by
explicit simulation offsets (``--sim-offset``, documented as such).
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from calibration.intrinsics import CameraIntrinsics
from calibration.measure import measure
from common.progress import Progress, Reporter
from design.contraption.physics_profile import apply_profile
from design.robust.budget import BudgetedOracle
from station.errors import ServiceError, station_errors
from station.services import calibrate
from station.services.calibrate import open_camera
from station.services.check_scene import aim_camera, parse_offset, sim_scene, twin_intrinsics
from station.services.check_side import hidden_as_built, merge_as_built, plane_json, side_lines
from station.services.contraption import open_scenario
from station.services.guide_manifest import read_manifest
from station.services.images import load_image
from station.services.outlook import disagreement, left_out_words, model_detail, success_headline
from station.services.robust import check_count, check_seed, simulations
from station.services.tolerances import contraption_problem, layout_and_model

__all__ = ["CheckJob", "apply_manifest", "camera_frame", "camera_overlay", "check_frame", "check_measurement",
           "grab_frame", "load_image", "overlay_frame", "parse_offset", "prepare_check",
           "remember_plane", "report_lines", "sim_scene", "summary_lines"]

#: Stages of a check, for progress.
STAGES = ("measure", "as-built", "simulation")


@station_errors
@dataclass(frozen=True)
class CheckJob:
    """One check's result and what it was made from.

    Attributes
    ----------
    report : calibration.check.CheckReport
        The result (``report.to_json()`` is CHECK.json).
    guide_job : station.services.guide.GuideJob
        The guide checked against (and its layout, scenario and tolerances).
    image : ndarray
        The camera frame (RGB uint8).
    measurement : calibration.measure.Measurement
    intrinsics : calibration.intrinsics.CameraIntrinsics
    """

    report: object
    guide_job: object
    image: np.ndarray
    measurement: object
    intrinsics: object
    #: The physical success of the as-built layout (calibration.sim_predict.PhysicalPrediction), when asked for.
    physical: object = None
    #: The side camera's view (station.services.check_side.SideView), when there was one.
    side: object = None

    def to_json(self) -> dict:
        """CHECK.json; with a physical prediction, its ``physical_success`` too (``station predict``'s fields)."""
        data = self.report.to_json()
        if self.physical is not None:
            data["physical_success"] = self.physical.to_json()
        return data


# -- the guide --------------------------------------------------------------------------------------------------------
@station_errors
def prepare_check(scenario: str, layout: str, *, guide: str | Path | None = None,
                  report: Reporter | None = None, jigs: bool = False):
    """The guide to check against: made again from the scenario and the layout with the default options, or the
    manifest ``guide`` (``station guide --json``) applied to it (the tags, reference tags and tolerances printed).
    With ``jigs`` (or a manifest that lists jigs) the guide has the layout's laser-cut jigs, whose tags the check
    reads.

    Raises
    ------
    ServiceError
        A manifest that is not one of this scenario (``guide``), or of another layout.
    """
    from station.services import guide as guides  # heavy: scipy, shapely

    manifest = read_manifest(guide) if guide is not None else None
    view = manifest.get("view") if manifest is not None else None
    if manifest is None:
        return guides.make_guide(guides.GuideRequest(scenario, layout, jigs=jigs or None), report=report)
    jigs = jigs or bool(manifest.get("jigs"))
    # refused before any work: the scenario is cheap to read, the tolerances are not (and the manifest has them)
    loaded = open_scenario(scenario)
    _same_scenario(manifest, loaded.name, loaded.content_hash, str(guide))
    job = guides.make_guide(guides.GuideRequest(loaded.source, layout, view=view if view in guides.VIEWS else None,
                                                tolerances=False, jigs=jigs or None))
    return replace(job, guide=apply_manifest(job.guide, manifest, str(guide)),
                   tolerances=_model_of(loaded, layout))


@dataclass(frozen=True)
class ScoringModel:
    """The layout's fitted success model and its problem, for a guide whose tolerances came with its manifest (what
    :func:`check_frame` reads of a guide job's ``tolerances``)."""

    problem: object
    model: object | None


def _model_of(scenario, layout: str) -> ScoringModel | None:
    try:
        problem = contraption_problem(scenario)
    except ValueError:  # no design space: nothing to score
        return None
    return ScoringModel(problem, layout_and_model(str(layout), problem)[1])


@station_errors
def apply_manifest(guide, manifest: Mapping, source: str = "<manifest>"):
    """``guide`` with the manifest's reference tags, part tags and tolerances (what was printed and stuck on).

    Raises
    ------
    ServiceError
        The manifest is of another scenario, content hash or view, lacks a part, or puts a part elsewhere (another
        layout): one line naming the file and the field.
    """
    from projector.guide import BodyTag, ParameterTolerance, ReferenceTag  # heavy: shapely

    def refuse(what: str) -> ServiceError:
        return ServiceError(f"guide {source}: {what}", field="guide", value=source)

    _same_scenario(manifest, guide.scenario, guide.content_hash, source)
    try:
        by_name = {p["name"]: p for p in manifest["parts"]}
        parts = []
        for part in guide.parts:
            entry = by_name.get(part.name)
            if entry is None:
                raise refuse(f"parts: no part {part.name!r}; expected the guide of this scenario")
            if np.hypot(*np.subtract(entry["center_mm"], part.center_mm)) > 0.05:
                raise refuse(f"parts[{part.name!r}].center_mm is {entry['center_mm']}, the layout puts it at "
                             f"[{part.center_mm[0]:.3f}, {part.center_mm[1]:.3f}]: a guide of another layout")
            tolerances = tuple(ParameterTolerance(t["parameter"], t["delta"], t["unit"], t.get("predicted"),
                                                  t.get("measured"), t.get("source", "model"),
                                                  bool(t.get("bound_limited", False)))
                               for t in entry.get("tolerances", []))
            centre = entry.get("tag_center_mm")
            parts.append(replace(
                part, tag_id=entry.get("tag_id"), tag_center_mm=None if centre is None else tuple(map(float, centre)),
                tag_size_mm=float(entry.get("tag_size_mm", part.tag_size_mm)),
                tag_height_mm=float(entry.get("tag_height_mm", part.tag_height_mm)),
                tag_heading_deg=float(entry.get("tag_heading_deg", part.heading_deg)),
                tolerances=tolerances, care=entry.get("care"),
                body_tags=tuple(BodyTag(int(b["body"]), int(b["tag_id"]), tuple(map(float, b["tag_center_mm"])),
                                        float(b["tag_size_mm"]), float(b["tag_height_mm"]),
                                        float(b["tag_heading_deg"]), tuple(map(float, b["center_mm"])),
                                        float(b["heading_deg"])) for b in entry.get("body_tags", []))))
        references = tuple(ReferenceTag(int(t["id"]), tuple(map(float, t["center_mm"])), float(t["size_mm"]))
                           for t in manifest["reference_tags"])
    except (KeyError, TypeError, ValueError) as error:
        raise refuse(f"malformed manifest ({type(error).__name__}: {error}); expected what `station guide --json` "
                     "prints") from None
    return replace(guide, parts=tuple(parts), reference_tags=references)


def _same_scenario(manifest: Mapping, name: str, content_hash: str, source: str) -> None:
    for key, ours in (("scenario", name), ("content_hash", content_hash)):
        if manifest.get(key) != ours:
            raise ServiceError(f"guide {source}: {key} is {manifest.get(key)!r}, expected {ours!r} (the guide of "
                               "another scenario)", field="guide", value=source)


# -- the frame --------------------------------------------------------------------------------------------------------
@station_errors
def grab_frame(url: str, guide, *, offsets=None, occluded: Sequence[int] = (), scene=None, seed: int | None = None):
    """One frame from the camera at ``url``, and the intrinsics it knows of itself (a simulated camera's own; None
    for a real camera, which needs its calibration). A simulated camera is handed ``scene`` first (a simulated
    world's parts where they stand), else :func:`sim_scene` (the guide's tags at their designed poses); ``seed``
    seeds its noise unless the URL sets one.

    Raises
    ------
    ServiceError
        ``url`` is not a camera (``camera``); simulation offsets for a real camera (``sim_offset``).
    drivers.errors.DriverError
        The camera cannot be opened or gives no frame (one line).
    """
    camera = open_camera(url)
    try:
        simulated = hasattr(camera, "set_scene")
        if scene is not None and not simulated:
            raise ServiceError(f"camera: a simulated world's parts are seen by a simulated camera (sim://camera), "
                               f"not by {url!r}", field="camera", value=url)
        if (offsets or occluded) and not simulated:
            raise ServiceError("sim_offset: simulation offsets go with a simulated camera (sim://camera) only",
                               field="sim_offset", value=url)
        if simulated:
            camera.set_scene(scene if scene is not None else sim_scene(guide, offsets, occluded=occluded))
            if "target=" not in url:
                aim_camera(camera, guide)
            if seed is not None and "seed=" not in url:
                camera.options = replace(camera.options, seed=int(seed) % 2**32)
        image = np.asarray(camera.grab())
        intrinsics = twin_intrinsics(camera, url) if simulated else None
    finally:
        camera.close()
    return image, intrinsics


@dataclass(frozen=True)
class FrameSource:
    """Where a check's frame comes from (:func:`camera_frame`): the file ``image``, else grabbed from ``camera`` (a
    URL; default the station's camera, ``station devices``). The intrinsics: the file ``intrinsics``, else the
    camera's saved calibration, else a simulated camera's own, else guessed (their ``notes`` say so). ``offsets``
    (part -> offset), ``occluded`` tags and a ``scene`` (a simulated world's, :mod:`station.services.world`) go to a
    simulated camera only. ``name`` names the camera ``camera`` is (its saved calibration and plane: a station.toml
    camera's name); default the station's camera's."""

    image: str | Path | None = None
    camera: str | None = None
    intrinsics: str | Path | None = None
    offsets: Any = None
    occluded: tuple[int, ...] = ()
    scene: Any = None
    name: str | None = None


@station_errors
def camera_frame(guide, source: FrameSource = FrameSource()):
    """The frame to check and how to read it: ``(image, intrinsics, camera name, its last plane fix)``, from
    ``source``."""
    image, camera, intrinsics, offsets, occluded = (source.image, source.camera, source.intrinsics, source.offsets,
                                                    source.occluded)
    name, twin = source.name or calibrate.DEFAULT_CAMERA, None
    if image is not None:
        if offsets or occluded:
            raise ServiceError("sim_offset: simulation offsets change a simulated camera's scene, not an image file",
                               field="sim_offset", value=str(image))
        frame = load_image(image)
    else:
        if camera is None:
            name, camera = calibrate.configured_camera_url()
        frame, twin = grab_frame(camera, guide, offsets=offsets, occluded=occluded, scene=source.scene)
    size = (int(frame.shape[1]), int(frame.shape[0]))
    if intrinsics is not None or twin is None or calibrate.camera_file(name).exists():
        lens = calibrate.intrinsics_for(size, intrinsics=intrinsics, name=name)
    else:
        lens = twin  # the simulated camera knows its own lens
    return frame, lens, name, calibrate.load_plane(_plane_name(name, guide))


def _plane_name(name: str, guide) -> str:
    """Where a check keeps camera ``name``'s last plane: per printed sheet (its reference tags), so that "moved since
    the last check" compares checks of the same sheet, never a new sheet with the old one."""
    sheet = json.dumps([[t.id, *map(float, t.center_mm), float(t.size_mm)] for t in guide.reference_tags])
    return f"{name}-check-{hashlib.sha256(sheet.encode()).hexdigest()[:12]}"


@station_errors
def remember_plane(name: str, check: CheckJob) -> None:
    """Keep the check's plane fix as camera ``name``'s last (the next check says how far the camera moved)."""
    if check.measurement.plane is not None:
        try:
            calibrate.save_plane(_plane_name(name, check.guide_job.guide), check.measurement.plane)
        except OSError:
            pass  # the check stands without it; only the next "moved" report is lost


# -- the check --------------------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class CheckRequest:
    """What a check does beyond measuring the parts (:func:`check_frame`).

    Parameters
    ----------
    simulate : int
        Simulate the as-built layout this many times with the residual measurement error (0: none).
    seed : int
        Seed of those simulations' noise.
    physics : PhysicsProfile, optional
        Simulate (``simulate``, ``predict``) with its material values instead of the scenario's.
    predict : int
        Predict the as-built layout's physical success and expected attempts from this many simulations under the
        physics and the residual measurement error as placement noise (0: none).
    camera : str
        The top camera's name, for the report's ``views``.
    """

    simulate: int = 0
    seed: int = 0
    physics: Any = None
    predict: int = 0
    camera: str = ""


@station_errors
def check_frame(job, image: np.ndarray, intrinsics=None, request: CheckRequest = CheckRequest(), *, previous=None,
                detector=None, side=None, report: Reporter | None = None) -> CheckJob:
    """Check the parts in one camera frame against the guide ``job`` (:func:`prepare_check`), as ``request`` says.

    Parameters
    ----------
    job : GuideJob
    image : ndarray
        RGB or grey uint8.
    intrinsics : CameraIntrinsics, optional
        The camera's; None guesses them from the image size (said in the prediction note: distances are then rough).
    request : CheckRequest
        The simulations and the prediction of the as-built layout, and the top camera's name.
    previous : PlaneFix, optional
        The last check's plane (a bumped camera is then said).
    detector : vision.detection.TagDetector, optional
        One to reuse between checks.
    side : station.services.check_side.SideView, optional
        The side camera's frame measured (:func:`station.services.check_side.measure_side`): the heights and tilts
        it measured join the as-built layout, its checks the report (``side_parts``).
    report : Reporter, optional
        Progress of the measure and of the simulations; its stop check ends the simulations
        (:class:`common.progress.Cancelled`).

    Raises
    ------
    ServiceError
        ``simulate`` or ``seed`` negative.
    calibration.errors.CalibrationError
        An image of another size than the intrinsics'.
    """
    from calibration.check import part_tags, reference_tags  # heavy: scipy, shapely

    check_count(request.simulate, "simulate", 0)
    check_seed(request.seed)
    report = Reporter.of(report)
    image = np.asarray(image)
    if intrinsics is None:
        intrinsics = CameraIntrinsics.guess((image.shape[1], image.shape[0]))
    notes = list(getattr(intrinsics, "notes", ()))  # a guessed camera says so: its distances are rough
    guide = job.guide
    report.emit(_progress("measure", 0, 1))
    measurement = measure(image, intrinsics, reference_tags(guide), part_tags(guide), previous, detector=detector)
    report.emit(_progress("measure", 1, 1))
    return check_measurement(job, measurement, image, intrinsics, request, notes=notes, side=side, report=report)


@station_errors
def check_measurement(job, measurement, image: np.ndarray, intrinsics, request: CheckRequest = CheckRequest(), *,
                      notes: Sequence[str] = (), side=None, report: Reporter | None = None) -> CheckJob:
    """The check of a :class:`~calibration.measure.Measurement` already made (see :func:`check_frame`)."""
    simulate, seed, physics, predict, camera = (request.simulate, request.seed, request.physics, request.predict,
                                                request.camera)
    from calibration.asbuilt import PlanePose, as_built_layout  # heavy: scipy, shapely
    from calibration.check import CheckReport, check_parts, residual_error  # heavy: scipy, shapely

    report = Reporter.of(report)
    notes = list(notes)
    guide = job.guide
    checks, by_eye = check_parts(guide, measurement)
    checks = [replace(c, view=guide.view) for c in checks]
    scenario = job.scenario
    names = list(scenario.design_space.names)
    x = np.asarray(job.layout.x, dtype=float)
    poses: dict[str, list] = {}  # per part, its measured poses: its own (body None), or its bodies'
    for c in checks:
        if c.found:
            poses.setdefault(c.owner, []).append((c.body, PlanePose(c.measured_center_mm, c.measured_heading_deg)))
    built = as_built_layout(scenario, x, guide.plane, poses, {p.name: p.parameters for p in guide.parts})
    measured_by = {n: "top" if guide.view == "top" else guide.view for n in built.measured}

    views = ({"view": guide.view, "camera": camera, "plane": plane_json(measurement.plane)},)
    if side is not None:
        built, measured_by = merge_as_built(job, built, side)
        side = hidden_as_built(job, side, built.unclipped, built.measured)  # where the parts are, as far as known
        views += ({"view": "side", "camera": side.camera, "plane": side.plane_json(),
                   "missing_reference_tags": list(side.measurement.missing_reference_ids),
                   "unknown_tags": list(side.measurement.unknown_ids),
                   "hidden_tags": {str(k): list(v) for k, v in side.hidden.items() if v},
                   "hidden_tags_as_built": list(side.as_built)},)
        notes.extend(f"side camera: {note}" for note in getattr(side.intrinsics, "notes", ()))
    model = getattr(job.tolerances, "model", None)
    problem = getattr(job.tolerances, "problem", None)
    predicted_built = predicted_designed = None
    if model is None:
        notes.insert(0, "no success-model score: the layout carries no fitted success model (a LAYOUT.json of "
                     "`station optimize` has one)" if names else
                     "no success-model score: the scenario has no design parameters")
    else:
        predicted_designed, predicted_built, costs = _scores(model, problem, x, built, guide)
        checks = [replace(c, cost=costs.get(c.owner)) for c in checks]
    if measurement.plane is None:
        notes.insert(0, "no plane: too few reference tags seen (missing "
                     f"{', '.join(map(str, measurement.missing_reference_ids))}); nothing was measured")
    if built.clipped:
        notes.append(f"placed outside the design range, scored at its end: {', '.join(built.clipped)}")
    residual = residual_error(measurement, [p.tag_size_mm for p in guide.parts if p.tag_id is not None])
    simulated = physical = None
    if physics is not None:
        scenario = apply_profile(scenario, physics)
        problem = None  # the layout's model scores; simulations run under the profile's values
    if simulate:
        if problem is None:
            problem = contraption_problem(scenario)
        simulated = _simulate(problem, built, residual, simulate, seed, report)
    if predict:
        from station.services.predict import PredictionRequest, predict_layout  # heavy: pybullet, scipy, shapely

        check_count(predict, "predict")
        request = PredictionRequest(physics, position_sigma_m=max(residual["position_mm"], 0.1) / 1000.0,
                                    angle_sigma_deg=max(residual["heading_deg"], 0.1),
                                    unmeasured=tuple(built.not_measured), samples=predict, seed=seed)
        physical = predict_layout(scenario, built.unclipped, request, report=report)
    # a misplaced part no design parameter places: the simulations put it where the guide does, and say so
    from projector.overlay import misplaced

    owners_placed = {p.name for p in guide.parts if p.parameters}
    not_simulated = tuple(dict.fromkeys(c.owner for c in checks if misplaced(c) and c.owner not in owners_placed))
    simulated_rate = physical.probability if physical is not None else simulated
    warning = disagreement(predicted_built, simulated_rate,
                           physical.samples if physical is not None else (simulate or None))
    if warning:
        notes.append(warning)
    missing = () if measurement.plane is None else tuple(  # without a plane nothing is measured: none is missing
        c.tag_id for c in checks if not c.found and c.tag_id not in measurement.duplicate_ids)
    result = CheckReport(
        scenario=guide.scenario, content_hash=guide.content_hash, layout=dict(zip(names, x.tolist())),
        view=guide.view, plane=measurement.plane, parts=tuple(sorted(checks, key=_order)), missing_tags=missing,
        unknown_tags=tuple(measurement.unknown_ids), duplicate_tags=tuple(measurement.duplicate_ids),
        by_eye=tuple(by_eye), as_built=built.parameters(names), not_measured=built.not_measured,
        residual_error=residual, predicted_success_as_built=predicted_built,
        predicted_success_as_designed=predicted_designed, prediction_note="; ".join(notes) or None,
        simulated_success_as_built=simulated, missing_reference_tags=tuple(measurement.missing_reference_ids),
        as_measured=built.measured_values(names), not_simulated=not_simulated, views=views,
        side_parts=tuple(side.checks) if side is not None else (), measured_by=measured_by)
    return CheckJob(result, job, image, measurement, intrinsics, physical, side)



def _progress(stage: str, done: int, total: int):
    return Progress(stage, done, total)


def _order(check) -> tuple:
    """Costliest first; then parts out of tolerance, the farthest first; parts not found last."""
    distance = check.error[2] if check.error is not None else -1.0
    return (not check.found, -(check.cost if check.cost is not None else -1.0), check.within_tolerance is not False,
            -distance)


def _scores(model, problem, x, built, guide) -> tuple[float, float, dict[str, float]]:
    """The model's success as designed, as built, and per part how much it falls with that part's error alone."""
    normalized = problem.to_normalized
    designed = float(model.predict(normalized(x)[None, :])[0])
    as_built = float(model.predict(normalized(built.x)[None, :])[0])
    names = list(problem.parameter_names)
    costs = {}
    for part in guide.parts:
        own = [names.index(p) for p in part.parameters if p in built.measured]
        if not own:
            continue
        alone = np.asarray(x, dtype=float).copy()
        alone[own] = built.x[own]
        costs[part.name] = designed - float(model.predict(normalized(alone)[None, :])[0])
    return designed, as_built, costs


def _simulate(problem, built, residual, n: int, seed: int, report: Reporter) -> float:
    """The success rate of ``n`` layouts around the as-built one: each measured parameter moved by the residual
    measurement error (mm for positions, degrees for rotations), each one not measured by at least the error of a
    layout placed with no check (:func:`calibration.sim_runs.placement_sigma`), Gaussian; an invalid layout (parts
    overlapping) counts as a failure."""
    from calibration.sim_runs import placement_sigma  # heavy: pybullet, scipy

    rng = np.random.default_rng(seed)
    names = list(problem.parameter_names)
    sigma = placement_sigma(problem.scenario, residual["position_mm"] / 1000.0, residual["heading_deg"],
                            built.not_measured)
    layouts = np.clip(built.x + rng.standard_normal((n, len(names))) * sigma, problem.lower, problem.upper)
    U = problem.to_normalized(layouts)
    valid = problem.is_valid(U)
    success = np.zeros(n, dtype=bool)
    if valid.any():
        with simulations(problem, report=report) as executor:
            oracle = BudgetedOracle(executor, None, report=report, expected=int(valid.sum()))
            oracle.phase = "simulation"
            success[valid] = np.asarray(oracle(U[valid])).all(axis=1)
    return float(success.mean())


# -- what the check shows ---------------------------------------------------------------------------------------------
@station_errors
def no_zone_words() -> str:
    """What a starred ok (``yes*``, ``NO*``) means, in the check's text and on the Assemble screen."""
    from projector.drawing import UNTOLERATED_DEG, UNTOLERATED_MM  # heavy: scipy, shapely

    return f"no zone on the sheet, so off by {UNTOLERATED_MM:g} mm / {UNTOLERATED_DEG:g} deg or more is to move"


@station_errors
def summary_lines(report, physical=None) -> list[str]:
    """The check's headline in words, most important first: the physical success as placed (``physical``, a
    :class:`calibration.sim_predict.PhysicalPrediction`; else the simulated success of ``--simulate``), the parts to
    move, what the predictions leave out, and the success model's own score as a detail."""
    from projector.drawing import UNTOLERATED_DEG, UNTOLERATED_MM  # heavy: scipy, shapely
    from projector.overlay import misplaced  # heavy: scipy, shapely

    to_move = sum(1 for p in report.parts if misplaced(p))
    unknown = sum(1 for p in report.parts if misplaced(p) and p.within_tolerance is None)
    found = sum(1 for p in report.parts if p.found)
    lines = []
    if physical is not None:
        lines.append(success_headline(physical, when=f"as placed, {physical.samples} simulations"))
    elif report.simulated_success_as_built is not None:
        lines.append(f"simulated success as placed {report.simulated_success_as_built:.2f} (with the check's "
                     "measurement error)")
    why = (f" ({unknown} with no tolerance on the sheet: off by {UNTOLERATED_MM:g} mm / {UNTOLERATED_DEG:g} deg or "
           "more)" if unknown else "")
    lines.append(f"{found} of {len(report.parts)} tagged parts measured, {to_move} to move{why}"
                 + (f", {len(report.by_eye)} to check by eye" if report.by_eye else ""))
    left_out = left_out_words(getattr(report, "not_simulated", ()))
    if left_out:
        lines.append(left_out)
    if physical is not None and report.simulated_success_as_built is not None:
        lines.append(f"detail: simulated success as placed {report.simulated_success_as_built:.2f} (with the "
                     "check's measurement error alone)")
    detail = model_detail(report.predicted_success_as_built, report.predicted_success_as_designed)
    if detail:
        lines.append(detail)
    return lines


@station_errors
def overlay_frame(check: CheckJob, size: tuple[int, int], homography=None) -> np.ndarray:
    """The projector frame after the check (:func:`projector.overlay.render_check`): an arrow per misplaced part
    from where it is to where it must go, a ring at the target, the prediction as placed in the caption."""
    from projector.overlay import render_check  # heavy: scipy, shapely

    return render_check(check.guide_job.guide, check.report.parts, tuple(size), homography,
                        caption=summary_lines(check.report, check.physical)[:2])


@station_errors
def camera_overlay(check: CheckJob) -> np.ndarray:
    """The camera frame with the check drawn over it through the camera's pose from the reference tags (the frame
    as it is when no plane was found)."""
    from projector.overlay import draw_check  # heavy: scipy, shapely

    plane = check.measurement.plane
    image = np.asarray(check.image)
    if plane is None:
        return image if image.ndim == 3 else np.repeat(image[:, :, None], 3, axis=2)

    matrix = np.asarray(check.intrinsics.camera_matrix, dtype=float)
    dist = np.asarray(check.intrinsics.dist_coeffs, dtype=float)

    def project(points_mm: np.ndarray, height_mm: float) -> np.ndarray:
        points = np.column_stack([points_mm, np.full(len(points_mm), float(height_mm))])
        pixels, _ = cv2.projectPoints(points, np.asarray(plane.rvec, float), np.asarray(plane.tvec, float), matrix,
                                      dist)
        return pixels.reshape(-1, 2)

    return draw_check(image, check.guide_job.guide, check.report.parts, project,
                      caption=summary_lines(check.report, check.physical)[:2])


@station_errors
def report_lines(report, physical=None) -> list[str]:
    """The check as text: the headline (:func:`summary_lines`), one row per tagged part (costliest first) with a
    legend, the instructions, what was not measured and the notes, the success model's score last (a detail)."""
    from projector.overlay import misplaced  # heavy: scipy, shapely

    summary = summary_lines(report, physical)
    detail = [line for line in summary if line.startswith("detail: ")]
    lines = []
    if report.plane is not None:
        moved = "" if report.plane.moved_mm is None else f", moved {report.plane.moved_mm:.1f} mm since the last check"
        lines.append(f"plane from reference tags {', '.join(map(str, report.plane.reference_ids))} (residual "
                     f"{report.plane.residual_mm:.2f} mm{moved})")
    lines.extend(line for line in summary if line not in detail)
    header = ("part", "tag", "du mm", "dv mm", "dist mm", "turn deg", "tolerance", "ok", "cost")
    rows = [header]
    starred = False
    for part in report.parts:
        tolerance = "/".join("-" if t is None else f"{t:.1f}" for t in part.tolerance)
        if part.error is None:
            values = ["not seen" if part.tag_id not in report.duplicate_tags else "twice", "", "", ""]
            ok = "-"
        else:
            values = [f"{part.error[0]:+.1f}", f"{part.error[1]:+.1f}", f"{part.error[2]:.1f}", f"{part.error[3]:+.1f}"]
            ok = {True: "yes", False: "NO"}.get(part.within_tolerance) or ("NO*" if misplaced(part) else "yes*")
            starred = starred or part.within_tolerance is None
        rows.append((part.name, str(part.tag_id), *values, tolerance, ok, "-" if part.cost is None
                     else f"{round(part.cost, 2) + 0.0:.2f}"))
    widths = [max(len(row[i]) for row in rows) for i in range(len(header))]
    for row in rows:
        lines.append("  ".join(cell.ljust(width) for cell, width in zip(row, widths)).rstrip())
    if len(rows) > 1:
        lines.append("  tolerance: +-u/+-v mm, +-turn deg, the zone drawn on the sheet (-: none there)")
        if starred:
            lines.append(f"  NO*/yes*: {no_zone_words()}")
        lines.append("  cost: how much the success model's score falls with that part's error alone (-: none)")
    steps = [p.instruction for p in report.parts if p.instruction]
    lines.extend(f"  {i}. {text}" for i, text in enumerate(steps, start=1))
    if report.by_eye:
        lines.append(f"check by eye against the sheet (no tag): {', '.join(report.by_eye)}")
    for words, ids in (("missing tags", report.missing_tags), ("unknown tags (ignored)", report.unknown_tags),
                       ("duplicate tags (not measured)", report.duplicate_tags),
                       ("reference tags not seen", report.missing_reference_tags)):
        if ids:
            lines.append(f"{words}: {', '.join(map(str, ids))}")

    lines.extend(side_lines(report))
    if report.not_measured:
        lines.append(f"not measured (kept at the layout's value; predictions place them as with no check, 1 mm / "
                     f"1 deg): {', '.join(report.not_measured)}")
    if report.prediction_note:
        lines.append(f"note: {report.prediction_note}")
    lines.extend(detail)
    return lines

