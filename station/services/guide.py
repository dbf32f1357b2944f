"""Assembly guides as a service: a scenario's layout as a 1:1 sheet set, an SVG, projected steps, a manifest.

Used by ``station guide`` and the Assemble screen. The work is :mod:`projector` (the drawing) and
:mod:`station.services.tolerances` (how carefully each part must be placed); this module reads the inputs, puts the
tolerances on the guide, writes the outputs and shows the steps on a projector.
"""

from __future__ import annotations

import hashlib
import re
from collections.abc import Mapping
from dataclasses import dataclass, replace
from pathlib import Path

from common.progress import Reporter
from design.contraption.layout_io import read_layout_data
from projector.board import side_board, write_board_pdf
from projector.build import build_guide, steps_text
from projector.frames import render_calibrate, render_frames, render_step
from projector.guide import Guide, ParameterTolerance, where_coords
from projector.parameters import check_set_with
from projector.pdf import write_pdf
from projector.svg import write_svg
from station.errors import ServiceError, station_errors
from station.services.contraption import choose_layout, open_scenario
from station.services.jig_plan import JigOptions, attach_jigs, plan_guide_jigs
from station.services.outlook import layout_headline
from station.services.physics import scenario_with_physics
from station.services.projectors import projector_homography
from station.services.robust import check_count, check_seed
from station.services.tolerances import tolerance_map as tolerances_of

__all__ = ["PAPERS", "VIEWS", "GuideJob", "GuideRequest", "check_paper", "export_guide", "make_guide", "portable_name",
           "projected_frames", "show_step", "where_coords"]

PAPERS = ("a4", "letter", "a3")
VIEWS = ("top", "side")


@station_errors
@dataclass(frozen=True)
class GuideJob:
    """A guide ready to export or project.

    Attributes
    ----------
    guide : projector.guide.Guide
        The drawing, in assembly order, with the tolerances on its parts (and its pages once exported).
    steps : tuple of str
        The assembly steps in words (``"3. Place `bottom_track`: centre (50.0, 60.0) mm, ..."``).
    layout : design.contraption.layout_io.LoadedLayout
        The layout the guide draws, and where it came from.
    tolerances : station.services.tolerances.Tolerances or None
        The tolerance map, None when none was asked for (or for the scenario's own layout).
    scenario : design.contraption.Scenario
        The scenario.
    jigs : station.services.jig_plan.PlannedJigs or None
        The laser-cut jigs the steps use, when asked for (their footprints are on the guide).
    """

    guide: Guide
    steps: tuple[str, ...]
    layout: object
    tolerances: object | None
    scenario: object
    jigs: object | None = None

    def manifest(self) -> dict:
        """The guide's manifest (the ``--json`` contract of ``station guide``) plus the layout it draws and steps.

        The layout's ``source`` is its file relative to the folder the command ran in, or its name when it lies
        elsewhere: a manifest names no path of the machine that made it."""
        data = self.guide.manifest()
        data["layout"] = self.layout.to_dict()
        data["layout"]["source"] = portable_name(data["layout"].get("source") or "")
        data["steps"] = list(self.steps)

        board = side_board(self.guide)
        data["side_board"] = None if board is None else board.manifest()
        return data


@station_errors
def portable_name(path: str | Path) -> str:
    """``path`` as a manifest or a sheet may name it: relative to the working folder when it lies under it, else its
    file's name (never an absolute path of this machine); empty stays empty."""
    if not str(path):
        return ""
    path = Path(path)
    if not path.is_absolute():
        return path.as_posix()
    try:
        return path.resolve().relative_to(Path.cwd().resolve()).as_posix()
    except (ValueError, OSError):
        return path.name


@dataclass(frozen=True)
class GuideRequest:
    """The guide :func:`make_guide` builds: ``layout`` (a LAYOUT.json, any form :mod:`design.contraption.layout_io`
    reads, a layout named in the scenario, or None for the scenario's own layout) for ``scenario`` (a file or an
    example's name).

    Parameters
    ----------
    view : {"top", "side"} or None
        The guide plane; None chooses it from the scenario.
    verify : int
        Layouts simulated per parameter to check each tolerance (0: none).
    seed : int
        Seed of the verification's random layouts.
    tolerances : bool
        False skips the tolerance map altogether (a guide with none).
    physics : str, optional
        A physics profile: the tolerances' simulations use its material values (the drawing, and the guide's
        content hash, are the scenario's: materials change no part's place).
    set_with : mapping of str to str, optional
        Per layout parameter, how the guide tells the maker to set it (``"jig"`` for one a laser-cut jig sets:
        :data:`projector.guide.SET_WITH`); the others as :mod:`projector.parameters` says.
    jigs : True or station.services.jig_plan.JigOptions, optional
        Plan the laser-cut jigs of the layout (for the profile's material, or the options' one): the parameters
        they set are set ``"jig"``, the sheets draw their footprints and the steps say how to use them
        (:func:`station.services.jig_plan.attach_jigs`); the plan is the job's ``jigs``.
    """

    scenario: str
    layout: str | None = None
    view: str | None = None
    verify: int = 0
    seed: int = 0
    tolerances: bool = True
    physics: str | None = None
    set_with: Mapping[str, str] | None = None
    jigs: bool | JigOptions | None = None


@station_errors
def make_guide(request: GuideRequest, *, report: Reporter | None = None) -> GuideJob:
    """Build the guide ``request`` describes; ``report`` is given :class:`common.progress.Progress` while
    tolerances are computed or verified, and its stop check ends the verifying simulations.

    Raises
    ------
    ServiceError
        A bad ``view``, ``verify`` or ``seed`` (the message names the value).
    StationError
        The scenario or the layout cannot be read (the message names the file, the field and the expected value),
        or the scenario cannot be drawn in that view.
    """
    scenario, layout, view, verify, seed = request.scenario, request.layout, request.view, request.verify, request.seed
    tolerances, physics, set_with, jigs = request.tolerances, request.physics, request.set_with, request.jigs
    if view is not None and view not in VIEWS:
        raise ServiceError(f"view must be one of {', '.join(VIEWS)}, got {view!r}", field="view", value=view)
    check_count(verify, "verify", 0)
    check_seed(seed)
    report = Reporter.of(report)
    loaded_scenario = open_scenario(scenario)
    check_set_with(set_with, tuple(loaded_scenario.design_space.names))  # before the tolerances' simulations
    tolerance_map = None
    by_parameter: dict[str, ParameterTolerance] | None = None
    if tolerances and layout is not None:
        # the tolerance map reads the layout (and the model its file carries) once, for both
        tolerance_map = tolerances_of(scenario_with_physics(loaded_scenario, physics), layout, verify=verify,
                                      seed=seed, report=report)
        loaded_layout = tolerance_map.layout
        by_parameter = _guide_tolerances(tolerance_map)
    else:
        loaded_layout = choose_layout(loaded_scenario, layout=layout)
    guide = build_guide(loaded_scenario, loaded_layout.x, view=view, tolerances=by_parameter, set_with=set_with)
    guide = replace(guide, tolerance_note=tolerance_map.map.note if tolerance_map is not None else None,
                    headline=_layout_headline(layout, tolerance_map))
    job = GuideJob(guide, tuple(steps_text(guide)), loaded_layout, tolerance_map, loaded_scenario)
    if jigs:
        job = attach_jigs(job, plan_guide_jigs(job, jigs if isinstance(jigs, JigOptions) else None))
    return job


def _layout_headline(layout: str | None, tolerance_map=None) -> str | None:
    """The physical success a LAYOUT.json carries (``station optimize`` writes it), in the station's words; from the
    tolerance map's reading of the file when there is one."""
    if tolerance_map is not None:
        return layout_headline(tolerance_map.layout_data)
    if layout is None or not Path(str(layout)).is_file():
        return None
    return layout_headline(read_layout_data(str(layout)))


@station_errors
def export_guide(job: GuideJob, *, pdf: str | Path | None = None, svg: str | Path | None = None,
                 paper: str = "a4") -> GuideJob:
    """Write the PDF sheet set and/or the SVG; returns the job with the guide's pages (after a PDF). A table guide
    whose jig stands carry a tag for the side camera (:func:`reads_side`) comes with the side camera's board sheet
    next to its PDF (:func:`board_pdf_path`: ``NAME-board.pdf``).

    Raises
    ------
    ServiceError
        A paper size the station does not know (``paper``).
    """
    check_paper(paper)
    guide = job.guide
    if pdf is not None:
        guide = write_pdf(guide, Path(pdf), paper=paper, steps=job.steps, title=_title(job))

        board = side_board(guide, paper)
        if board is not None and reads_side(guide):
            write_board_pdf(board, board_pdf_path(pdf), title=_title(job))
    if svg is not None:
        with open(svg, "w", encoding="utf-8") as stream:
            write_svg(guide, stream)
    return replace(job, guide=guide)


@station_errors
def reads_side(guide) -> bool:
    """Whether the side camera has something to read in ``guide``: a jig stand with a tag on its plate's face."""
    return any(j.face_tag_id is not None for j in guide.jigs)


@station_errors
def board_words(guide) -> str | None:
    """What the side camera's board sheet of ``guide`` shows, in words; None when the guide has no board the side
    camera reads."""
    board = side_board(guide)
    return board.words() if board is not None and reads_side(guide) else None


@station_errors
def board_pdf_path(pdf: str | Path) -> Path:
    """Where the board sheet of the guide PDF ``pdf`` goes: next to it, ``NAME-board.pdf``."""
    pdf = Path(pdf)
    return pdf.with_name(f"{pdf.stem}-board.pdf")


@station_errors
def check_paper(paper: str) -> None:
    """Refuse a paper size the station does not know (``paper``), before any work."""
    if paper not in PAPERS:
        raise ServiceError(f"paper must be one of {', '.join(PAPERS)}, got {paper!r}", field="paper", value=paper)


@station_errors
def projected_frames(job: GuideJob, size: tuple[int, int], homography=None):
    """The guide's frames for a screen of ``size`` pixels (:func:`projector.frames.render_frames`): a calibrate
    frame and one per step; without a projector calibration the guide is fitted to the screen, not at true scale."""
    return render_frames(job.guide, size=size, homography=homography)


@station_errors
def show_step(job: GuideJob, projector, step: int | None = None, homography=None) -> bool:
    """Show step ``step`` (1-based; None: the calibrate frame) of the guide on an open ``projector`` device, drawn
    at the projector's own size (a frame of another size would be letterboxed, and no longer true to scale).

    ``homography`` (guide mm -> projector pixels) defaults to the map measured on this projector (`station
    calibrate projector`, :func:`station.services.projectors.projector_homography`) when it has one of this size.
    Returns whether the frame is at true scale (False until the projector is calibrated).

    Raises
    ------
    ServiceError
        A step outside 1..number of parts (``step``).
    """
    count = len(job.guide.parts)
    if step is not None and not 1 <= step <= count:
        raise ServiceError(f"step must be from 1 to {count}, got {step}", field="step", value=step)
    size = tuple(projector.size)
    if homography is None:
        homography = projector_homography(projector)
    if step is None:
        frame = render_calibrate(job.guide, size, homography)
    else:
        frame = render_step(job.guide, step, size, homography)
    projector.show(frame)
    return homography is not None


def _title(job: GuideJob) -> str:
    """The sheets' title: the scenario and the layout, short (a file's name, not its whole path)."""
    layout = job.layout
    if layout.format == "defaults":
        which = "the scenario's own layout"
    elif layout.format == "named":
        which = f"layout {layout.name!r}"
    else:
        which = Path(layout.source).name or layout.describe()
    return f"{job.guide.scenario}: {which}"


def _guide_tolerances(tolerances) -> dict[str, ParameterTolerance]:
    """The tolerances in the guide's units (mm and degrees), by layout parameter."""
    return {t.parameter: t for per_part in tolerances.parameter_tolerances().values() for t in per_part}


@station_errors
def export_name(job) -> str:
    """The file name (no suffix) of ``job``'s export: the scenario, the layout (its name, its file's name, or "own"
    for the scenario's own), a hash of the layout's values and the view, e.g. ``simple-success-1f0c2a-top``. The
    hash (of the values at 6 decimals, as a check keeps them) tells apart two layouts named alike (two files called
    layout.json, a scenario file edited), so that one layout's export never replaces another's."""
    layout = job.layout
    which = {"defaults": "own", "named": layout.name}.get(layout.format) or Path(layout.source).stem or "values"
    values = ",".join(f"{value:.6f}" for value in layout.x)
    digest = hashlib.sha256(f"{job.guide.scenario}\n{values}".encode()).hexdigest()[:6]
    name = f"{job.guide.scenario}-{which}-{digest}-{job.guide.view}".lower()
    return re.sub(r"[^a-z0-9._-]+", "-", name)
