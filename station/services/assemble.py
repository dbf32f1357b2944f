"""One physical attempt step by step, as a service: guide, place, check (fix, check again)*, run, outcomes, log.

Used by ``station assemble`` (prompts in a terminal) and the Assemble screen (keys), so both walk the same states
and say the same things. An :class:`Assembly` holds the attempt: the guide (shown step by step on a projector, or
written as a 1:1 PDF sheet set), the camera checks of the parts as placed, the outcome of the run (said by the maker
event by event, or reported by a simulated world, ``sim://world``), and the trial it logs. At every stage it can
forecast the physical success and the expected attempts (:func:`station.services.predict.predict_layout`): as
designed before the check, as placed after it (the check's as-built layout and residual error).

With a simulated world the simulated maker places the parts (with its placement error; better when the projector
highlights each part), applies the check's instructions (with its smaller error), the simulated camera sees the parts
where they are, and the world runs the as-placed layout under its hidden physics. Without one, the maker does all of
that and says what happened.

A side camera facing the board behind the parts (``side_camera``; else the station's cameras of station.toml when it
names more than one, as ``station check`` takes them; else, with a simulated world, the world's own side camera,
:data:`station.services.check_cameras.SIDE_CAMERA`) checks the heights and tilts of the parts carried by jig stands
whose face tag looks at it: the check then combines both views (:func:`station.services.check_cameras.check_views`),
its instructions say to raise, lower or tilt a part, and a simulated maker sets those parameters again with its
correcting error. A guide with nothing for the side camera to read (no jigs, or no stand facing the board) is checked
by the top camera alone.

The states and what moves between them (anything else is refused with a :class:`ServiceError` naming ``stage``)::

    guide --placed()--> check --check()--> check --fix()--> check ... --accept()--> run --run()/answer()--> log
    log --log()--> done
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from common.progress import Reporter
from design.contraption.physics_profile import apply_profile
from projector.overlay import misplaced
from station.errors import ServiceError, station_errors
from station.paths import data_dir
from station.services import check as checks
from station.services import guide as guides
from station.services import robust
from station.services.calibrate import configured_camera_url
from station.services.check import overlay_frame
from station.services.check_cameras import SIDE_CAMERA, camera_names, check_views, configured_cameras, reads_side
from station.services.guide import export_guide, export_name, show_step
from station.services.layout_choice import (
    LayoutChoiceRequest,
    candidate_layouts,
    choose_layout,
    expected_success,
    layout_record,
)
from station.services.outlook import success_headline
from station.services.physics import problem_with_physics, read_profile
from station.services.predict import PredictionRequest, as_built_from_check, predict_layout
from station.services.projectors import projector_homography
from station.services.robust import check_count, check_seed
from station.services.sim_calibration import SimCalibrationRequest, calibrate_sim, save
from station.services.trials import (
    build_trial,
    check_values,
    layout_values,
    load_trial_scenario,
    open_store,
    read_physics,
)
from station.services.world import (
    as_placed_layout,
    check_moves,
    cut_jigs,
    guide_sigma,
    open_world,
    place_parts,
    prepare_world,
    run_attempt,
    world_scene,
)
from station.trialformat import check_times, complete_outcomes, goal_reached, resolve_outcomes

__all__ = ["STAGES", "Assembly", "AssemblyRequest", "Forecast", "calibrate_from_log", "guide_files", "jigs_folder",
           "misplaced", "open_assembly", "reoptimize"]

#: The stages of an attempt, in order.
STAGES = ("guide", "check", "run", "log", "done")
#: Simulations per forecast: enough for a first figure in a second or two (``samples`` changes it).
DEFAULT_SAMPLES = 60


@station_errors
@dataclass(frozen=True)
class Forecast:
    """The physical success and expected attempts at one point of the attempt.

    Attributes
    ----------
    when : str
        ``"designed"`` (before the check), ``"as placed"`` (after a check) or ``"after the run"``.
    prediction : calibration.sim_predict.PhysicalPrediction
    """

    when: str
    prediction: Any
    record: tuple[int, int] = (0, 0)  #: (successes, attempts) of the logged trials of this layout before it

    @property
    def with_record(self) -> float | None:
        """The prediction updated by the layout's record, as ``station loop`` weighs it
        (:func:`station.services.layout_choice.expected_success`); None without a record."""
        return expected_success(self.prediction.probability, *self.record) if self.record[1] else None

    def record_words(self) -> str:
        """``"0.78 with its record here (3 of 4 worked; expected attempts 1.3)"``, or "" without a record."""
        expected = self.with_record
        if expected is None:
            return ""
        attempts = f"{1 / expected:.1f}" if expected > 0 else "never"
        return (f"{expected:.2f} with its record here ({self.record[0]} of {self.record[1]} worked; expected attempts "
                f"{attempts})")

    def line(self) -> str:
        """The headline (:func:`station.services.outlook.success_headline`) with when and from how many
        simulations, and the record's word when the layout was logged before: ``physical success on the table 0.83
        (95 %: 0.71-0.91): expect 1.2 attempts (1.1-1.4) (as placed, 60 simulations)``."""
        words = self.record_words()
        record = f"; {words}" if words else ""
        return success_headline(self.prediction, when=f"{self.when}, {self.prediction.samples} simulations") + record

    def to_json(self) -> dict:
        return {"when": self.when, **self.prediction.to_json(), "record": list(self.record),
                "with_record": self.with_record}


@station_errors
@dataclass
class Assembly:
    """One attempt (see the module notes); made by :func:`open_assembly`.

    Attributes
    ----------
    job : station.services.guide.GuideJob
        The guide of the layout.
    scenario : design.contraption.Scenario
        The scenario as the trial stores it (read once, from the text logged).
    stage : str
        One of :data:`STAGES`.
    checks : list of station.services.check.CheckJob
        The checks made, the last one is the parts as they stand.
    forecasts : list of Forecast
    outcomes, times : dict
        What happened (every event, after :meth:`answer` or :meth:`run`), and when.
    trial_id : int or None
        The trial logged.
    highlighted : bool or None
        The projector highlights each part as the simulated maker places it (None: when there is a projector).
    station_camera : bool
        The camera is the station's own: its saved calibration read, and its plane kept between checks (and in the
        data folder) so that a check says whether the camera was bumped since the last. False: a simulated camera
        seen through its own lens and nothing kept (``station loop``'s unattended attempts).
    side_camera : str or None
        The side camera's URL (see the module notes for the side camera used without one).
    """

    job: Any
    scenario: Any
    camera: str | None = None
    world: Any = None
    projector: Any = None
    physics: str | None = None
    attempt: int = 1
    samples: int = DEFAULT_SAMPLES
    seed: int = 0
    workers: int | None = None
    scheduler: str | None = None
    highlighted: bool | None = None
    station_camera: bool = True
    side_camera: str | None = None
    stage: str = "guide"
    step: int = 0
    checks: list = field(default_factory=list)
    forecasts: list = field(default_factory=list)
    outcomes: dict = field(default_factory=dict)
    times: dict = field(default_factory=dict)
    fixes: int = 0
    trial_id: int | None = None
    record: tuple[int, int] = (0, 0)  #: (successes, attempts) of this layout's trials in the log before this attempt
    _profile: Any = None
    _camera_name: str | None = None
    _views: list | None = None

    # -- stages -------------------------------------------------------------------------------------------------
    def _expect(self, *stages: str) -> None:
        if self.stage not in stages:
            raise ServiceError(f"stage: this attempt is at {self.stage!r}; that is done at {' or '.join(stages)}",
                               field="stage", value=self.stage)

    @property
    def parts(self) -> tuple:
        return self.job.guide.parts

    @property
    def steps(self) -> tuple[str, ...]:
        return self.job.steps

    @property
    def highlight(self) -> bool:
        """Whether the parts are placed with the projector highlighting each (:attr:`highlighted`, else when there
        is a projector)."""
        return self.projector is not None if self.highlighted is None else bool(self.highlighted)

    @property
    def check(self):
        """The last check (None before the first)."""
        return self.checks[-1] if self.checks else None

    @property
    def within_tolerance(self) -> bool:
        """Whether the last check found every tagged part and none out of its tolerance (with a side camera: every
        part it reads found on the board's plane, none to set again in height or tilt: :attr:`side_off`)."""
        report = self.check.report if self.check is not None else None
        return (report is not None and report.plane is not None and not report.missing_tags
                and not any(misplaced(p) for p in report.parts)
                and all(p.found for p in report.side_parts) and not self.side_off)

    @property
    def side_off(self) -> tuple[str, ...]:
        """The parts whose height or tilt the last check's side camera asks to set again (the parameters of their
        moves, :func:`station.services.world.check_moves`: where a part stands along the table is the top
        camera's); () without a side view."""
        if self.check is None or not self.check.report.side_parts:
            return ()
        return tuple(move["name"] for move in self.moves() if move.get("parameters"))

    def cameras(self) -> list[tuple[str, str]]:
        """The cameras the checks use, ``(name, url)``: the top camera, then the side camera when there is one and
        the guide gives it something to read (see the module notes). Cameras given by URL are named as ``station
        check`` names its ``--camera`` URLs (``camera``, ``camera-2``); station.toml's keep their names."""
        if self._views is None:
            top = camera_names([self.camera])[0] if self.camera is not None else configured_camera_url()
            self._views = [top]
            if reads_side(self.job):
                station = self.side_camera is None and self.camera is None and self.station_camera
                configured = configured_cameras() if station else []
                if len(configured) > 1:
                    self._views = configured
                elif self.side_camera is not None or self.world is not None:  # a world serves its own side camera
                    side = SIDE_CAMERA if self.side_camera is None else self.side_camera
                    self._views = [top, camera_names([top[1], side])[1]]
        return list(self._views)

    @property
    def success(self) -> bool | None:
        if not self.outcomes:
            return None
        return goal_reached(self.scenario, self.outcomes)

    # -- guide ------------------------------------------------------------------------------------------------------
    def show_step(self, step: int | None) -> None:
        """Show step ``step`` (1-based; None: the calibrate frame) on the projector, if there is one."""
        self.step = step or 0
        if self.projector is not None:
            show_step(self.job, self.projector, step)

    def write_sheet(self, pdf: str | Path | None = None, paper: str = "a4") -> Path:
        """Write the 1:1 PDF sheet set with the steps (print at 100 %) to ``pdf`` (default: the data folder's
        ``guides/``, named by the scenario, the layout and a hash of its values); returns where."""
        path = Path(pdf) if pdf else guide_files(self.job)[0]
        path.parent.mkdir(parents=True, exist_ok=True)
        self.job = export_guide(self.job, pdf=path, paper=paper)
        return path

    def placed(self) -> None:
        """The maker has placed the parts (a simulated world places them now, each with the maker's error)."""
        self._expect("guide")
        if self.world is not None:
            place_parts(self.world, self.job.guide, attempt=self.attempt, highlighted=self.highlight,
                        scenario=self.job.scenario)
        self.stage = "check"

    # -- check ------------------------------------------------------------------------------------------------------
    def check_placed(self, *, fix: bool = False, report: Reporter | None = None):
        """Check the parts as they stand: placed first when they are not yet (:meth:`placed`), and with ``fix``
        moved first as the last check said (:meth:`fix`). Returns the check (:meth:`check_parts`)."""
        if self.stage == "guide":
            self.placed()
        if fix:
            self.fix()
        return self.check_parts(report)

    def check_parts(self, report: Reporter | None = None, *, seed: int | None = None):
        """Grab a frame from the camera and check the parts as they stand (a simulated camera sees the world's
        parts where the simulated maker put them, or the guide's tags at their designed poses without a world);
        with a side camera (:meth:`cameras`) its frame too, both views combined as ``station check`` combines them
        (:func:`station.services.check_cameras.check_views`). ``seed`` seeds a simulated camera's noise in this
        frame (without ``station_camera``; None: the camera's own)."""
        self._expect("check")
        scene = None
        if self.world is not None:
            scene = world_scene(self.job.guide, self.world.placed())
        views = self.cameras()
        if len(views) > 1:
            # the side twin shows each part where the world's maker really set it (its height and tilt included)
            layout = None if self.world is None else as_placed_layout(self.job.scenario, self.job.guide, self.world)
            result = check_views(self.job, views, scene=scene, side_layout=layout,
                                 seed=None if self.station_camera else seed, station_cameras=self.station_camera,
                                 report=report)
            self._camera_name = views[0][0] if self.station_camera else None
            self.checks.append(result)
            return result
        if self.station_camera:
            image, intrinsics, name, saved = checks.camera_frame(self.job.guide,
                                                                 checks.FrameSource(camera=self.camera, scene=scene))
            previous = self.check.measurement.plane if self.check is not None else saved
        else:
            image, intrinsics = checks.grab_frame(self.camera, self.job.guide, scene=scene, seed=seed)
            name = previous = None
        result = checks.check_frame(self.job, image, intrinsics, previous=previous, report=report)
        if name is not None:
            checks.remember_plane(name, result)
        self._camera_name = name
        self.checks.append(result)
        return result

    def project_check(self) -> bool:
        """Show the last check on the projector (an arrow per misplaced part to where it must go, a ring at the
        target); False without a projector or a check."""
        if self.projector is None or self.check is None:
            return False
        size = tuple(self.projector.size)
        self.projector.show(overlay_frame(self.check, size, projector_homography(self.projector)))
        return True

    def moves(self) -> list[dict]:
        """What the last check asks the maker to move (:func:`station.services.world.check_moves`); [] before the
        first check."""
        return [] if self.check is None else check_moves(self.check.to_json(), self.job.guide)

    def fix(self) -> list[dict]:
        """The maker moved the parts as the last check said (a simulated world applies the moves now, with the
        maker's smaller error); check again next. Returns the moves (:meth:`moves`)."""
        self._expect("check")
        if self.check is None:
            raise ServiceError("stage: no check yet; check the parts first", field="stage", value=self.stage)
        moves = self.moves()
        self.fixes += 1
        if self.world is not None and moves:
            self.world.apply(moves, round=self.fixes)
        return moves

    def accept(self) -> None:
        """Go on to the run with the parts as they stand (checked or not: the maker's call)."""
        self._expect("check")
        self.stage = "run"

    # -- run --------------------------------------------------------------------------------------------------------
    def run(self):
        """With a simulated world: run the attempt there (the as-placed layout under the world's hidden physics)
        and take its outcomes (a :class:`station.services.world.AttemptRun`); None without one (the maker runs it
        and :meth:`answer` says what happened)."""
        self._expect("run")
        if self.world is None:
            return None
        result = run_attempt(self.job.scenario, self.job.layout.x, self.job.guide, self.world)
        self.answer(result.outcomes, result.times)
        return result

    def resolve(self, given: Mapping[str, str]):
        """What ``given`` outcomes imply for every event, and the problems left
        (:func:`station.trialformat.resolve_outcomes`): ``(outcomes, problems)``, an event still to be said is
        None."""
        return resolve_outcomes(self.scenario, given)

    def answer(self, outcomes: Mapping[str, str], times: Mapping[str, float] | None = None) -> dict[str, str]:
        """What happened to each event (the implied ones may be left out); every event's outcome after that.

        Raises
        ------
        ServiceError
            ``outcome.EVENT`` / ``time.EVENT``: see :func:`station.trialformat.complete_outcomes`.
        """
        self._expect("run")
        full = complete_outcomes(self.scenario, outcomes)
        self.times = check_times(self.scenario, dict(times or {}), full)
        self.outcomes = full
        self.stage = "log"
        return full

    # -- log --------------------------------------------------------------------------------------------------------
    def trial(self, *, who: str | None = None, notes: str | None = None) -> dict:
        """The trial record (the trial log's form) of this attempt."""
        self._expect("log")
        check = self.check.to_json() if self.check is not None else None  # CHECK.json: what the log stores
        return build_trial(self.scenario, layout_values(self.scenario, self.job.layout.x), self.outcomes,
                           times=self.times, as_built=None if check is None else check_values(check), check=check,
                           physics=read_physics(self.physics) if self.physics else None, who=who,
                           notes=notes or f"station assemble, attempt {self.attempt}, {self.fixes} fix(es)")

    def log(self, store=None, *, who: str | None = None, notes: str | None = None) -> int:
        """Log the attempt in the trial log (``store``, default the station's); returns the trial's id."""
        record = self.trial(who=who, notes=notes)
        if store is None:
            with open_store() as opened:
                self.trial_id = opened.add(record)
        else:
            self.trial_id = store.add(record)
        self.stage = "done"
        return self.trial_id

    # -- forecasts --------------------------------------------------------------------------------------------------
    def forecast(self, report: Reporter | None = None) -> Forecast:
        """The physical success and expected attempts now: as designed before a check (every parameter with the
        error of how the guide tells the maker to set it, :func:`station.services.world.guide_sigma`), as placed
        after one (its as-built layout, its residual error on what it measured, the way each was set on the rest),
        under the physics profile if any."""
        scenario = self.job.scenario
        x = np.asarray(self.job.layout.x, dtype=float)
        set_sigma = guide_sigma(self.job.guide, scenario, highlighted=self.highlight)
        sigma = {"unmeasured": tuple(scenario.design_space.names)}
        when = "designed"
        if self.check is not None and self.check.report.plane is not None:
            x, position, angle, unmeasured = as_built_from_check(self.check.to_json(), scenario, x, "the last check")
            sigma = {"position_sigma_m": position, "angle_sigma_deg": angle, "unmeasured": tuple(unmeasured)}
            when = "as placed"
        if self.stage in ("log", "done"):
            when = f"{when}; this run: {'success' if self.success else 'failure'}"
        request = PredictionRequest(self._profile, samples=self.samples, seed=self.seed, workers=self.workers,
                                    scheduler=self.scheduler, set_sigma=set_sigma, **sigma)
        result = predict_layout(scenario, x, request, report=report)
        self.forecasts.append(Forecast(when, result, self.record))
        return self.forecasts[-1]

    def close(self) -> None:
        """Close the world (a projector is its opener's to close)."""
        world, self.world = self.world, None
        if world is not None:
            world.close()


@dataclass(frozen=True)
class AssemblyRequest:
    """The attempt :func:`open_assembly` starts: the guide of ``layout`` for ``scenario`` and how its forecasts run.

    What the attempt is lies here; the live objects it works with (an open projector, the open store) are handed
    beside it to :func:`open_assembly`, as ``report=`` is: they are opened and closed by the caller, are not values
    to compare or keep, and a request stays a plain description that can be built before any device is opened.

    Parameters
    ----------
    scenario : str
        A scenario file or an example's name.
    layout : str or None
        A LAYOUT.json, a layout named in the scenario, or None (the scenario's own).
    view : {"top", "side"} or None
        The guide plane (None: chosen from the scenario).
    camera : str, optional
        The camera's URL (default: the station's camera, ``station devices``).
    side_camera : str, optional
        A side camera's URL, facing the board behind the parts: the checks measure the heights and tilts of the parts
        on jig stands with it (default: the station's, when station.toml names more than one camera, as ``station
        check`` takes them; with a simulated world, the world's own side camera; none when the guide gives it
        nothing to read).
    world : str, optional
        A simulated world (``sim://world?seed=S``); None: a real table, the maker does and says.
    physics : path, optional
        A physics profile: the tolerances and forecasts use it, the trial stores it.
    attempt : int, optional
        This attempt's number (the simulated maker's errors are seeded by it); default one more than the trials
        of the scenario in the store (the station's log).
    jigs : bool
        The guide's steps use the layout's laser-cut jigs (``station jigs`` writes them): the parameters they set
        are set on them. With a simulated world the simulated maker cuts them first, their laser job run to its end
        on the laser twin (:func:`station.services.world.cut_jigs`), and sets the parts on them.
    samples, seed, workers :
        The forecasts' simulations, their seed and worker processes.
    """

    scenario: str
    layout: str | None
    view: str | None = None
    camera: str | None = None
    world: str | None = None
    physics: str | Path | None = None
    attempt: int | None = None
    jigs: bool = False
    samples: int = DEFAULT_SAMPLES
    seed: int = 0
    workers: int | None = None
    side_camera: str | None = None


@station_errors
def open_assembly(request: AssemblyRequest, *, projector=None, store=None,
                  report: Reporter | None = None) -> Assembly:
    """Start the attempt ``request`` describes: the guide (with its tolerances), the world opened.

    Parameters
    ----------
    request : AssemblyRequest
        The scenario, layout, world, physics and forecasts.
    projector : device, optional
        An open projector: the steps are shown on it (and a simulated maker places better). Beside the request:
        a live device, its opener's to close.
    store : TrialStore, optional
        An open trial store the default ``attempt`` counts the scenario's trials in (None: the station's log,
        opened and closed here). Beside the request: a live connection, its opener's to close.
    report : Reporter, optional
        Hears the guide's progress (the tolerance map) and can stop it.

    Raises
    ------
    ServiceError
        A bad count, seed, world or physics file (named); a side camera with nothing to read (``camera``: no jig
        stand of the layout faces the board).
    design.errors.DesignError, projector.errors.ProjectorError, OSError
        The scenario or the layout cannot be read or drawn.
    """
    scenario, layout, view, camera, world, physics = (request.scenario, request.layout, request.view, request.camera,
                                                      request.world, request.physics)
    attempt, jigs, samples, seed, workers, side_camera = (request.attempt, request.jigs, request.samples,
                                                          request.seed, request.workers, request.side_camera)
    check_count(samples, "samples")
    check_seed(seed)
    check_count(attempt, "attempt")
    profile = read_profile(physics) if physics is not None else None
    trial_scenario = load_trial_scenario(scenario)
    opened_world = None
    if world is not None:  # a bad URL refused before the guide's work
        opened_world = open_world(world)
    try:
        request = guides.GuideRequest(scenario, layout, view=view, physics=None if physics is None else str(physics),
                                      jigs=bool(jigs))
        job = guides.make_guide(request, report=report)
        if opened_world is not None:
            prepare_world(opened_world, job.scenario)
            if job.jigs is not None and job.jigs.plan.jigs:
                cut_jigs(job)
        if profile is not None:
            apply_profile(job.scenario, profile, str(physics))  # refuses a profile of another contraption, naming it
        if trial_scenario.content_hash != job.scenario.content_hash:
            raise ServiceError(f"scenario: {scenario} changed while it was read; start again", field="scenario")
        if store is None:
            with open_store() as opened:
                logged = opened.trials(scenario=trial_scenario.name)
        else:
            logged = store.trials(scenario=trial_scenario.name)
        if attempt is None:
            attempt = 1 + len(logged)
        record = _layout_record(trial_scenario, job.layout.x, logged)
        if side_camera is not None and not reads_side(job):
            raise ServiceError(f"camera: the side camera {side_camera} has nothing to read: no jig stand of "
                               "this layout faces the board (use the guide's jigs: --jigs)", field="camera",
                               value=side_camera)
    except BaseException:
        if opened_world is not None:
            opened_world.close()
        raise
    return Assembly(job, trial_scenario, camera=camera, side_camera=side_camera, world=opened_world,
                    projector=projector,
                    physics=None if physics is None else str(physics), attempt=attempt, samples=samples, seed=seed,
                    workers=workers, record=record, _profile=profile)


@station_errors
def guide_files(job) -> tuple[Path, Path]:
    """Where the guide of ``job`` is written unless told: the data folder's ``guides/``, a PDF and an SVG named by the
    scenario, the layout and a hash of its values (:func:`station.services.guide.export_name`), so that one layout's
    export never replaces another's."""
    stem = data_dir() / "guides" / export_name(job)
    return Path(f"{stem}.pdf"), Path(f"{stem}.svg")


@station_errors
def jigs_folder(job) -> Path:
    """Where the laser-cut jigs of ``job``'s layout are written: the data folder's ``jigs/``, named as the guide."""
    return data_dir() / "jigs" / export_name(job)


def _layout_record(scenario, x, trials) -> tuple[int, int]:
    """``(successes, attempts)`` of the ``trials`` logged with the layout ``x``'s values."""
    return layout_record(layout_values(scenario, x), trials)


# -- after attempts: calibrate, re-optimize ----------------------------------------------------------------------------
@station_errors
def calibrate_from_log(scenario, store=None, *, settings=None, workers: int | None = None,
                       report: Reporter | None = None, out: str | Path | None = None,
                       every_material: bool = False):
    """Fit ``scenario``'s uncertain material values (with ``every_material``, its plain ones too, each within its
    default range, as ``station loop`` does) to its trials in the log (``store``, default the station's) and write the
    physics profile (``out``, default the data folder's ``physics/NAME-calibrated.toml``).

    Returns ``(path, SimCalibration)``.

    Raises
    ------
    ServiceError
        No trials of the scenario, nothing uncertain to fit (named).
    common.progress.Cancelled
        Stopped; the simulations done are in the cache.
    """
    if store is None:
        with open_store() as opened:
            trials = opened.trials(scenario=scenario.name)
    else:
        trials = store.trials(scenario=scenario.name)
    request = SimCalibrationRequest(settings=settings, source="the trial log", every_material=every_material,
                                    workers=workers)
    result = calibrate_sim([scenario], trials, request, report=report)
    path = Path(out) if out is not None else data_dir() / "physics" / f"{scenario.name.lower()}-calibrated.toml"
    path.parent.mkdir(parents=True, exist_ok=True)
    return save(result, path, name=f"{scenario.name} calibrated on {result.fit.trials + result.fit.held_out} "
                "trials"), result


@dataclass(frozen=True)
class ReoptimizeRequest:
    """A layout optimized again under a physics profile, and the option surest to work physically chosen.

    Parameters
    ----------
    scenario : str
        A scenario file or example name.
    physics : path, optional
        The physics profile (the calibrated one); None: the scenario's own values.
    budget, seed : int
        The optimizer's simulations and seed (the seed of the choice's simulations too).
    settings : PSPSettings, optional
        The optimizer's settings (None: the station's default).
    current : path, optional
        The LAYOUT.json placed so far: one of the options, with its record in ``trials``.
    candidates : int
        The optimizer's verified candidates that are options.
    samples : int
        Simulations per option.
    trials : tuple of dict, optional
        Trial records the options' records come from (None: the scenario's trials in the station's log).
    workers : int, optional
        Local simulation processes.
    out : path, optional
        Where the chosen LAYOUT.json goes (None: the data folder's ``layouts/NAME-physics.json``).
    """

    scenario: str
    physics: str | Path | None = None
    budget: int = 40
    seed: int = 0
    settings: Any = None
    current: str | None = None
    candidates: int = 4
    samples: int = 16
    trials: tuple[Mapping, ...] | None = None
    workers: int | None = None
    out: str | Path | None = None


@station_errors
def reoptimize(request: ReoptimizeRequest, *, report: Reporter | None = None):
    """Optimize the layout again under the physics profile ``request.physics``, choose among the optimizer's
    verified candidates and the ``current`` layout (a LAYOUT.json) the one surest to succeed often under the
    profile's values and intervals (:func:`station.services.layout_choice.choose_layout`, ``samples`` simulations
    each) and, for the current layout, given its record in ``trials``, and write it (``out``).

    Returns ``(path, result, chosen)``: the optimizer's result and the LAYOUT.json data written (its
    ``physical_choice`` says which option won and every option's predicted success, record and expected success).
    """
    physics, current, trials = request.physics, request.current, request.trials
    problem = problem_with_physics(robust.load_problem(request.scenario), physics)
    settings = request.settings or robust.psp_settings(robust.DEFAULT_SETTINGS)
    result = robust.optimize(problem, request.budget, request.seed, settings, workers=request.workers, report=report)
    options = candidate_layouts(result.to_json(problem), request.candidates)
    if current is not None and Path(current).is_file() and str(current).lower().endswith(".json"):
        try:
            placed = json.loads(Path(current).read_text(encoding="utf-8"))
        except (OSError, ValueError):
            placed = None
        if isinstance(placed, dict) and isinstance(placed.get("parameters"), list):
            options.append(placed)
    profile = read_profile(physics) if physics is not None else None
    if trials is None and len(options) > 1:
        with open_store() as store:
            trials = store.trials(scenario=problem.scenario.name)
    chosen = choose_layout(problem.scenario, options, LayoutChoiceRequest(
        profile, samples=request.samples, seed=request.seed, trials=tuple(trials or ()), workers=request.workers),
        report=report)
    default = data_dir() / "layouts" / f"{result.scenario.lower()}-physics.json"
    path = Path(request.out) if request.out is not None else default
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(chosen, indent=2) + "\n", encoding="utf-8")
    return path, result, chosen
