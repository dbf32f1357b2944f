"""Guided exploration as a service (thesis 3.5): a design's Points of Interest, invariants, slider moves.

Used by ``station explore`` (a scripted run: :func:`explore`) and the Explore screen (an interactive session:
:func:`start_session`, then the :class:`design.explore.Explorer` methods).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from design.machines import get_machine
from station.errors import ServiceError, station_errors

if TYPE_CHECKING:  # scipy and shapely load only when a design is explored
    from design.explore import Explorer, PointOfInterest, ReleaseResult

#: Curve samples for PoI detection a person may ask for (inclusive).
POINTS_RANGE = (256, 200_000)


@station_errors
def start_session(machine: str, params: Mapping[str, float], points: int | None = None) -> Explorer:
    """An exploration session on a design: its Points of Interest found, no invariant yet.

    Parameters
    ----------
    machine : str
        A registered machine's name.
    params : mapping
        The design (missing parameters take the machine's defaults).
    points : int, optional
        Curve samples for PoI detection (default: about 400 per turn of the driving gear).

    Raises
    ------
    ServiceError
        ``points`` out of :data:`POINTS_RANGE` (``field="points"``).
    design.errors.DesignError
        An unknown machine or a bad design.
    """
    from design.explore import Explorer  # heavy: scipy, shapely

    check_points(points)
    return Explorer(get_machine(machine), dict(params), n_points=points)


@station_errors
def check_points(points: int | None) -> None:
    """Refuse a number of curve samples out of :data:`POINTS_RANGE` (:class:`ServiceError`, ``field="points"``)."""
    low, high = POINTS_RANGE
    if points is not None and not low <= points <= high:
        raise ServiceError(f"points must be an integer in [{low}, {high}], got {points}", field="points",
                           value=points)


@dataclass
class Exploration:
    """A scripted exploration: the session at its end, and everything that happened as one JSON document.

    Attributes
    ----------
    explorer : Explorer
        The session after the last move.
    document : dict
        ``machine, params, size, pois, invariants, redundant, sliders, moves`` (what ``station explore --json``
        prints).
    first_curve : ndarray
        The starting design's curve.
    first_pois : list of PointOfInterest
        Its Points of Interest.
    """

    explorer: Explorer
    document: dict[str, Any]
    first_curve: np.ndarray
    first_pois: list[PointOfInterest] = field(default_factory=list)


@station_errors
def parse_keep(spec: str) -> tuple[str, tuple[int, ...]]:
    """An invariant to keep, from its words (``position:3``, ``distance:1,2``...): ``(kind, poi ids)``."""
    from design.explore import parse_keep as parse  # scipy and shapely: loaded only when a design is explored

    return parse(spec)


@station_errors
def explore(machine: str, params: Mapping[str, float], keeps: Sequence[tuple[str, Sequence[int]]] = (),
            moves: Sequence[tuple[int, float]] = (), points: int | None = None) -> Exploration:
    """Find the PoIs of a design, keep the invariants ``keeps`` (``(kind, poi ids)``, from
    :func:`design.explore.parse_keep`), then move and release each slider of ``moves`` (``(index, value)``).

    Raises
    ------
    ServiceError
        ``points`` out of range, or a move's slider index beyond the sliders there are (``field="move"``).
    design.errors.DesignError
        A bad design or invariant (e.g. a PoI that does not exist, or invariants that leave no freedom).
    """
    explorer = start_session(machine, params, points)
    first_curve, first_pois = explorer.curve, explorer.pois
    document: dict[str, Any] = {
        "machine": explorer.machine.name,
        "params": explorer.base_design,
        "size": explorer.size,
        "pois": [p.as_dict() for p in first_pois],
    }
    invariants = [explorer.add_invariant(kind, ids) for kind, ids in keeps]
    document["invariants"] = [
        {"label": inv.label, "type": inv.kind, "pois": list(inv.pois), "target": list(inv.target)} for inv in invariants
    ]
    document["redundant"] = bool(invariants) and explorer.subspace.redundant
    document["sliders"] = [s.as_dict() for s in explorer.sliders]
    document["moves"] = []
    for k, value in moves:
        if k >= len(explorer.sliders):
            raise ServiceError(f"move {k}={value:g}: slider index must be in 0..{len(explorer.sliders) - 1}",
                               field="move", value=k)
        moved = explorer.move(k, value)
        applied = explorer.sliders[k].value
        document["moves"].append(_move_document(k, value, applied, moved.params, explorer.release(), explorer))
    return Exploration(explorer, document, first_curve, list(first_pois))


def _move_document(k: int, requested: float, applied: float, moved: dict[str, float], result: ReleaseResult,
                   explorer: Explorer) -> dict[str, Any]:
    return {
        "slider": k,
        "requested": requested,
        "value": applied,
        "params_moved": moved,
        "params": result.params,
        "features_before": result.features_before,
        "features_after": result.features_after,
        "invariant_error_before": invariant_errors(result.errors_before),
        "invariant_error": invariant_errors(result.errors_after),
        "shape_change": result.shape_change,
        "lost": result.lost,
        "converged": result.converged,
        "warning": result.warning,
        "sliders": [s.as_dict() for s in explorer.sliders],
    }


@station_errors
def invariant_errors(values: Mapping[str, float]) -> list[dict[str, Any]]:
    """``[{"invariant", "error", "unit"}]`` from an invariant-label → error mapping (a lost feature: None)."""
    from design.explore import ERROR_UNIT  # heavy: scipy, shapely

    out = []
    for label, error in values.items():
        kind = label.split(":")[0]
        out.append({"invariant": label, "error": None if not np.isfinite(error) else error, "unit": ERROR_UNIT[kind]})
    return out


@station_errors
def write_picture(exploration: Exploration, path: str | Path) -> Path:
    """A PNG of the first and the last design with their PoIs, the kept ones highlighted."""
    from design.explore.render import write_png  # heavy: scipy, shapely

    path = Path(path)
    explorer = exploration.explorer
    highlight = [i for ids in explorer.invariant_pois().values() for i in ids if i is not None]
    with path.open("wb") as stream:
        write_png(stream, [exploration.first_curve, explorer.curve], [exploration.first_pois, explorer.pois],
                  highlight=highlight)
    return path


# -- a session a face drives step by step: the explorer's own errors come out as station errors -------------------
@station_errors
def keep_invariant(explorer: Explorer, kind: str, poi_ids: Sequence[int]):
    """Freeze feature ``kind`` of the PoIs ``poi_ids`` (one, two for ``distance``); the invariant kept."""
    return explorer.add_invariant(kind, list(poi_ids))


@station_errors
def drop_last_invariant(explorer: Explorer) -> str | None:
    """Unfreeze the invariant kept last; its label (None when there is none)."""
    if not explorer.invariants:
        return None
    label = explorer.invariants[-1].label
    explorer.remove_invariant(len(explorer.invariants) - 1)
    return label


@station_errors
def move_slider(explorer: Explorer, index: int, value: float):
    """Preview slider ``index`` at ``value`` (the design moves; the session keeps its invariants)."""
    return explorer.move(index, value)


@station_errors
def release_slider(explorer: Explorer, index: int, value: float) -> ReleaseResult:
    """Move slider ``index`` to ``value`` and re-project the design onto the invariants."""
    explorer.move(index, value)
    return explorer.release()
