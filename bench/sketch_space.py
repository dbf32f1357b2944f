"""A held-out sketch set drawn the way a maker's sketches come: designs from each machine's whole feasible space.

Designs: uniform over a machine's feasible space within practical dimensions. Every gear radius is drawn uniformly
from its lower bound to :data:`PRACTICAL_RADIUS` and every continuous parameter uniformly over its box; a draw is
kept when the machine's constraints accept it (rejection sampling). The kept designs are therefore uniform over the
feasible set, and each continuous parameter is uniform over its feasible interval given the others. Nothing is
taken from a retrieval database's grid or radii list.

Sketches: each design's pattern is drawn as a hand would draw it. Either the whole pattern, or (for a pattern with
rotational symmetry ``k > 1``, with probability ``sector_probability``) one sector of it with ``--symmetry k``.
The pattern is cut into 2-6 strokes with pen lifts (gaps) between some of them and overdraw (a stroke running on
past where the next one starts) at others; every stroke is sampled unevenly at a roughly constant spatial rate,
wobbles (a smooth drift of up to 1.5 % of the size) and jitters (point noise of 0.3-0.8 %); finally the whole
sketch is rotated, scaled and moved, and the strokes shuffled and reversed at random.

Two seeded sets are kept apart: :data:`TUNING_SEED` for tuning the method, :data:`EVALUATION_SEED` for reporting.

A *hit* (the issue's definition): one of the top-5 candidates draws the sketch's source curve, i.e. its pattern is
within :data:`HIT_DISTANCE` of it in shape distance (full Procrustes distance ``1 - |<a, b>|^2`` of the centred,
unit-norm curves resampled at :data:`HIT_POINTS` points uniform in arc length, minimized over start point,
direction and reflection; computed at full resolution here, not with the retrieval's low-harmonic bank), or the
candidate has the true machine and gear radii.
"""

from __future__ import annotations

import math
import zlib
from dataclasses import dataclass

import numpy as np

from design.sketch.distance import procrustes_distance_direct
from design.sketch.spline import resample_closed, resample_open
from design.sketch.strokes import make_sketch
from design.sketch.synthetic import SyntheticCase, drawn_piece

#: Largest gear radius drawn (the issue: every radius up to at least 10 that the constraints allow).
PRACTICAL_RADIUS = 10
#: Seeds of the two sets: tune on one, report the other.
TUNING_SEED = 7001
EVALUATION_SEED = 9002
#: Shape distance below which a candidate draws the sketched pattern (the issue's). On ring-like patterns (a wobbly
#: circle traced several times) it also accepts other patterns with the same winding, so the bench also reports
#: :data:`STRICT_DISTANCE`.
HIT_DISTANCE = 0.05
STRICT_DISTANCE = 0.01
#: Points per curve for the hit test.
HIT_POINTS = 2048


@dataclass(frozen=True)
class SpaceCase(SyntheticCase):
    """A sketch and the design it was drawn from, with the pattern's symmetry order and its source curve
    (:data:`HIT_POINTS` points uniform in arc length)."""

    symmetry: int = 1
    curve: np.ndarray | None = None


def feasible_designs(machine, count: int, rng: np.random.Generator, max_radius: int = PRACTICAL_RADIUS,
                     batch: int = 200_000) -> list[dict[str, float]]:
    """``count`` designs uniform over the machine's feasible space (radii up to ``max_radius``), by rejection."""
    names = machine.parameter_names
    found: list[np.ndarray] = []
    total = 0
    for _ in range(200):
        columns = []
        for name in names:
            p = machine.parameter(name)
            if p.is_discrete:
                columns.append(rng.integers(max(1, int(p.lower)), min(int(p.upper), max_radius) + 1, batch))
            else:
                columns.append(rng.uniform(p.lower, p.upper, batch))
        rows = np.column_stack(columns).astype(float)
        kept = rows[machine.feasible_mask(rows)]
        found.append(kept)
        total += len(kept)
        if total >= count:
            break
    rows = np.concatenate(found)[:count]
    if len(rows) < count:
        raise RuntimeError(f"{machine.name}: only {len(rows)} feasible designs found")
    discrete = set(machine.discrete_names)
    return [{n: (int(round(v)) if n in discrete else float(v)) for n, v in zip(names, row)} for row in rows]


def shape_distance(a: np.ndarray, b: np.ndarray) -> float:
    """Full Procrustes distance of two closed curves (``(N, 2)`` each, uniform in arc length), over start point,
    direction and reflection: 0 for the same shape under a similarity, 1 for unrelated ones."""
    za = a @ np.array([1.0, 1j])
    zb = b @ np.array([1.0, 1j])
    return float(min(procrustes_distance_direct(za, zb[None])[0], procrustes_distance_direct(za, zb.conj()[None])[0]))


def pattern(machine, params: dict[str, float], points: int = HIT_POINTS) -> np.ndarray:
    """A design's closed pattern, ``points`` points uniform in arc length (first not repeated)."""
    return resample_closed(machine.sample(params, n=8 * points + 1, spacing="time")[:-1], points)


def _strokes(curve: np.ndarray, closed: bool, size: float, rng: np.random.Generator) -> list[np.ndarray]:
    """Cut a densely sampled curve into hand-drawn strokes (see the module docstring); ``size`` is the drawn
    piece's (bounding-box diagonal), which sets the hand's noise and sampling rate."""
    length = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(curve, axis=0), axis=1))])
    total = float(length[-1])
    count = int(rng.integers(2, 7))
    cuts = np.sort(rng.uniform(0.05, 0.95, count - 1)) * total
    edges = np.concatenate([[0.0], cuts, [total]]) + (rng.random() * total if closed else 0.0)
    noise = rng.uniform(0.003, 0.008) * size
    strokes = []
    for a, b in zip(edges[:-1], edges[1:]):
        # at each joint a pen lift (gap) or overdraw (the stroke runs past the joint), 1-5 % of the size
        a += rng.uniform(-0.02, 0.04) * size * (rng.random() < 0.5)
        b += rng.uniform(-0.04, 0.03) * size
        if not closed:
            a, b = max(a, 0.0), min(b, total)
        if b - a < 0.02 * total:
            continue
        s = np.linspace(a, b, max(200, int(60 * (b - a) / size)))
        s = np.mod(s, total) if closed else s
        piece = np.column_stack([np.interp(s, length, curve[:, 0]), np.interp(s, length, curve[:, 1])])
        n = int(np.clip(rng.uniform(40.0, 100.0) * (b - a) / size, 10, 4000))
        speed = np.cumsum(rng.uniform(0.3, 1.7, n))  # a hand slows down and speeds up
        at = (speed - speed[0]) / max(speed[-1] - speed[0], 1e-12)
        dense = resample_open(piece, max(400, 4 * n))
        piece = dense[np.round(at * (len(dense) - 1)).astype(int)]
        u = np.linspace(0.0, 1.0, n)[:, None]
        waves = rng.uniform(0.5, 2.5, 2)
        phase = rng.uniform(0, 2 * math.pi, 2)
        wobble = rng.uniform(0.0, 0.015) * size * np.sin(2 * math.pi * waves * u + phase)
        strokes.append(piece + wobble + rng.normal(0.0, noise, piece.shape))
    return strokes


def make_space_case(machine, params: dict[str, float], rng: np.random.Generator,
                    sector_probability: float = 0.35) -> SpaceCase | None:
    """One hand-drawn sketch of ``params``'s pattern (``None`` when the strokes come out degenerate)."""
    from design.sketch.candidates import radius_roles
    from design.sketch.errors import SketchError
    from design.sketch.strokes import rotation

    k = machine.symmetry_order(params)
    sector = k > 1 and rng.random() < sector_probability
    drawn = drawn_piece(machine, params, k if sector else 1, rng, 3000 if sector else 12000)
    # a maker draws what they draw at the size of the canvas: the hand's noise scales with the drawn piece
    strokes = _strokes(drawn, not sector, float(np.linalg.norm(np.ptp(drawn, axis=0))), rng)
    if not strokes:
        return None
    size = float(np.linalg.norm(np.ptp(np.concatenate(strokes), axis=0)))
    transform = rotation(rng.uniform(0, 2 * math.pi)) * (rng.uniform(20, 300) / size)
    shift = rng.uniform(-200, 200, 2)
    strokes = [s @ transform.T + shift for s in strokes]
    strokes = [strokes[i][::-1] if rng.random() < 0.5 else strokes[i] for i in rng.permutation(len(strokes))]
    try:
        # the patterns are centred on the machine's origin (ring or turntable centre): the symmetry centre
        sketch = make_sketch(strokes, symmetry=k if sector else 1, center=shift, source="space-sketch")
    except SketchError:
        return None
    radii = tuple(int(params[r]) for r in radius_roles(machine))
    return SpaceCase(machine.name, dict(params), radii, sketch, sector, len(strokes), symmetry=k,
                     curve=pattern(machine, params))


def space_set(machine_names, per_machine: int, seed: int) -> list[SpaceCase]:
    """The seeded set: ``per_machine`` sketches per machine (designs uniform over the feasible space)."""
    from design.machines import get_machine

    cases = []
    for name in machine_names:
        machine = get_machine(name)
        rng = np.random.default_rng([seed, zlib.crc32(name.encode())])  # a machine's cases whatever the others
        designs = feasible_designs(machine, 3 * per_machine, rng)
        made = 0
        for params in designs:
            case = make_space_case(machine, params, rng)
            if case is not None:
                cases.append(case)
                made += 1
            if made == per_machine:
                break
    return cases


def closest_shape(case: SpaceCase, candidates) -> float:
    """The smallest shape distance from the case's source curve to the patterns of the top-5 candidates."""
    from design.machines import get_machine

    return min((shape_distance(case.curve, pattern(get_machine(c.machine), c.params)) for c in candidates[:5]),
               default=1.0)


def is_hit(case: SpaceCase, candidates) -> tuple[bool, bool]:
    """(pattern hit, radii hit) of a top-5 list of retrieval candidates for one case (a hit is either)."""
    radii = any(c.machine == case.machine and tuple(c.radii) == case.radii for c in candidates[:5])
    return closest_shape(case, candidates) <= HIT_DISTANCE, radii


__all__ = [
    "EVALUATION_SEED",
    "HIT_DISTANCE",
    "PRACTICAL_RADIUS",
    "TUNING_SEED",
    "SpaceCase",
    "feasible_designs",
    "closest_shape",
    "is_hit",
    "make_space_case",
    "shape_distance",
    "space_set",
]
