"""Measured part poses back to design parameters: the **as-built layout** (pure computation).

A guide draws every part at the pose the scene graph gives it at the layout (:func:`projector.build.build_guide`):
its origin on the guide plane (u, v mm) and its turn about the plane's normal (degrees, counter-clockwise as the maker
sees it). The camera measures those three numbers per tagged part; this module finds the part's free layout
parameters that put it there, by inverting that same mapping (Gauss-Newton on finite differences of
:func:`design.contraption.geometry.world_poses`, so a part hanging from a moved or turned Empty frame is handled as
the simulator poses it).

Which parameters the camera measures: a position parameter whose move of the part lies in the guide plane (its
out-of-plane share under 10 %), a rotation parameter whose turn is about the plane's normal (within 25 degrees).
Every other parameter of the part (a height above the table in the top view, a pitch) is *not measured*: it keeps the
layout's value and is listed. The solution is clipped to the design space's range (a part placed beyond its range's
end is scored at the end, and said).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from design.contraption.geometry import world_poses
from projector.guide import GuidePlane
from projector.plane import heading_in_plane

__all__ = ["AsBuilt", "PlanePose", "as_built_layout", "measurable_parameters", "part_plane_pose"]

#: Finite-difference steps: metres for positions, degrees for rotations.
_STEP_M, _STEP_DEG = 1e-4, 0.05
#: A position parameter is measured when at most this share of its move leaves the plane.
_OUT_OF_PLANE = 0.1
#: A rotation parameter is measured when its axis is within this angle of the plane's normal.
_AXIS_COS = math.cos(math.radians(25.0))
_ITERATIONS = 8


@dataclass(frozen=True)
class PlanePose:
    """A part's pose on the guide plane: its origin (u, v mm) and heading (deg, counter-clockwise as seen)."""

    center_mm: tuple[float, float]
    heading_deg: float


@dataclass(frozen=True)
class AsBuilt:
    """The as-built layout.

    Attributes
    ----------
    x : ndarray
        Every design parameter in real units (m, degrees), design-space order, within the range.
    measured : tuple of str
        Parameters set from the camera.
    not_measured : tuple of str
        Parameters kept at the layout's value: out of the camera's plane, or of a part whose tag was not measured.
    clipped : tuple of str
        Measured parameters that fell outside their range and were set to its end.
    residual : dict of str to tuple
        Per part, what the fitted parameters could not reproduce: ``(du mm, dv mm, dheading deg)`` per measured pose
        (a part moved along an axis no parameter of it moves).
    unclipped : ndarray
        ``x`` before the clip: where the parts really are, which the simulations of calibration and prediction (on
        widened ranges) can use; the success model only knows the range.
    """

    x: np.ndarray
    measured: tuple[str, ...]
    not_measured: tuple[str, ...]
    clipped: tuple[str, ...]
    residual: Mapping[str, tuple[float, ...]]
    unclipped: np.ndarray

    def measured_values(self, names: Sequence[str]) -> dict[str, float]:
        """``{name: value}`` of the measured parameters as measured (not clipped), in design-space order."""
        return {name: float(value) for name, value in zip(names, self.unclipped) if name in self.measured}

    def parameters(self, names: Sequence[str]) -> dict[str, float]:
        """``{name: value}`` in design-space order (``names`` is the design space's)."""
        return {name: float(value) for name, value in zip(names, self.x)}


def part_plane_pose(scenario, x, plane: GuidePlane, names: Sequence[str]) -> dict[str, PlanePose]:
    """The plane poses of parts ``names`` at layout ``x`` (as :func:`projector.build.build_guide` draws them)."""
    frames = world_poses(scenario.objects, scenario.transforms(x, checked=False))
    result = {}
    for name in names:
        u, v = plane.to_plane(frames[name].position)[0]
        result[name] = PlanePose((float(u), float(v)), heading_in_plane(frames[name].rotation, plane))
    return result


def _step(name: str) -> float:
    return _STEP_DEG if name.rsplit(".", 1)[-1] in ("heading", "pitch", "roll") else _STEP_M


def measurable_parameters(scenario, x, plane: GuidePlane, part: str, parameters: Sequence[str]) -> list[str]:
    """Which of ``parameters`` (the part's) the camera measures on ``plane`` (module notes)."""
    names = list(scenario.design_space.names)
    x = np.asarray(x, dtype=float)
    base = world_poses(scenario.objects, scenario.transforms(x, checked=False))[part]
    result = []
    for parameter in parameters:
        moved = x.copy()
        moved[names.index(parameter)] += _step(parameter)
        pose = world_poses(scenario.objects, scenario.transforms(moved, checked=False))[part]
        if parameter.rsplit(".", 1)[-1] in ("x", "y", "z"):
            shift = pose.position - base.position
            size = float(np.linalg.norm(shift))
            if size > 0 and abs(float(shift @ plane.normal)) <= _OUT_OF_PLANE * size:
                result.append(parameter)
        else:
            turn = (pose.rotation * base.rotation.inv()).as_rotvec()
            size = float(np.linalg.norm(turn))
            if size > 0 and abs(float(turn @ plane.normal)) >= _AXIS_COS * size:
                result.append(parameter)
    return result


def _wrap(angle: float) -> float:
    return (angle + 180.0) % 360.0 - 180.0


class _Fit:
    """One part's pose error as a function of its measured parameters' values: for each measured pose (the part's
    own, or one of its bodies': a run's first and last dominoes), (du mm, dv mm, dheading deg) stacked."""

    def __init__(self, scenario, x, plane, part, columns, targets) -> None:
        from design.contraption.primitives import body_specs

        self.scenario, self.x, self.plane, self.part, self.columns = scenario, x, plane, part, columns
        specs = body_specs(scenario.object(part))
        self.targets = [(None if body is None else specs[body].pose, np.array([*pose.center_mm, pose.heading_deg]))
                        for body, pose in targets]

    def error(self, values: np.ndarray) -> np.ndarray:
        """The part's (or its bodies') poses at these values minus the measured ones."""
        trial = self.x.copy()
        trial[self.columns] = values
        frame = world_poses(self.scenario.objects, self.scenario.transforms(trial, checked=False))[self.part]
        errors = []
        for offset, target in self.targets:
            pose = frame if offset is None else frame * offset
            u, v = self.plane.to_plane(pose.position)[0]
            errors += [u - target[0], v - target[1], _wrap(heading_in_plane(pose.rotation, self.plane) - target[2])]
        return np.array(errors)


def as_built_layout(scenario, x, plane: GuidePlane, measured: Mapping[str, PlanePose],
                    part_parameters: Mapping[str, Sequence[str]]) -> AsBuilt:
    """The as-built layout: the layout ``x`` with each measured part's in-plane parameters fitted to its pose.

    Parameters
    ----------
    scenario : Scenario
    x : array_like
        The designed layout (real units, design-space order).
    plane : GuidePlane
        The guide's plane.
    measured : mapping of str to PlanePose or to a sequence of (int or None, PlanePose)
        The measured pose of each part the camera found (its origin and heading on the plane), or of some of its
        bodies (``(index, pose)``: a run's first and last dominoes; None for the part's own origin).
    part_parameters : mapping of str to sequence of str
        Every part's free layout parameters (:attr:`projector.guide.PartDrawing.parameters`).
    """
    names = list(scenario.design_space.names)
    lower, upper = np.asarray(scenario.design_space.lower), np.asarray(scenario.design_space.upper)
    x = np.asarray(x, dtype=float).copy()
    fitted: list[str] = []
    residual: dict[str, tuple[float, ...]] = {}
    for part, poses in measured.items():
        targets = [(None, poses)] if isinstance(poses, PlanePose) else list(poses)
        own = list(part_parameters.get(part, ()))
        free = measurable_parameters(scenario, x, plane, part, own) if own else []
        columns = [names.index(p) for p in free]
        fit = _Fit(scenario, x, plane, part, columns, targets)

        values = x[columns].copy()
        if columns:
            steps = np.array([_step(p) for p in free])
            for _ in range(_ITERATIONS):
                now = fit.error(values)
                jacobian = np.column_stack([(fit.error(values + np.eye(len(values))[i] * steps[i]) - now) / steps[i]
                                            for i in range(len(values))])
                delta = np.linalg.lstsq(jacobian, -now, rcond=None)[0]
                values = values + delta
                if np.all(np.abs(delta) < steps * 1e-3):
                    break
            x[columns] = values
            fitted.extend(free)
        residual[part] = tuple(float(r) for r in fit.error(values))
    clipped = tuple(n for n in fitted if not lower[names.index(n)] <= x[names.index(n)] <= upper[names.index(n)])
    unclipped = x.copy()
    x = np.clip(x, lower, upper)
    not_measured = tuple(n for n in names if n not in fitted)
    return AsBuilt(x, tuple(n for n in names if n in fitted), not_measured, clipped, residual, unclipped)
