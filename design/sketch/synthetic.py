"""Seeded synthetic sketches made from known machine curves (the retrieval benchmark set).

A case takes a random feasible design of a machine (radii among the database's combinations, continuous parameters
uniform over their feasible set, not on the database grid), samples its curve, and turns it into what a maker would
draw: either the whole pattern or, when it is rotationally symmetric, one symmetric sector with ``k`` given; cut
into 1-4 strokes separated by gaps (pen lifts of 2-6 % of the pattern's size); subsampled unevenly at a roughly
constant spatial rate; jittered with noise (0.6 % of the size); randomly rotated, scaled and moved, with the strokes
in random order and direction. Near-circles, whose radii no sketch can tell, are drawn again.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from design.sketch.spline import resample_open
from design.sketch.strokes import Sketch, make_sketch, rotation


@dataclass(frozen=True)
class SyntheticCase:
    """A benchmark sketch and the design it was made from."""

    machine: str
    params: dict[str, float]
    radii: tuple[int, ...]
    sketch: Sketch
    sector: bool
    strokes: int
    rejected: int = 0


def random_design(
    machine, radii: dict[str, int], rng: np.random.Generator, tries: int = 20000
) -> dict[str, float] | None:
    """A design with the given radii and continuous parameters uniform over their feasible set (rejection)."""
    continuous = machine.continuous_names
    box = np.array([[machine.parameter(n).lower, machine.parameter(n).upper] for n in continuous])
    for shrink in (1.0, 0.25, 0.0625):
        defaults = machine.defaults()
        centre = np.array([defaults[n] for n in continuous])
        lo = centre - (centre - box[:, 0]) * shrink
        hi = centre + (box[:, 1] - centre) * shrink
        draws = lo + rng.random((tries, len(continuous))) * (hi - lo)
        rows = {n: draws[:, i] for i, n in enumerate(continuous)} | {n: np.full(tries, v) for n, v in radii.items()}
        ok = np.flatnonzero(machine.feasible_mask(rows))
        if len(ok):
            pick = draws[rng.choice(ok)]
            return dict(radii) | {n: float(v) for n, v in zip(continuous, pick)}
    return None


def pattern_detail(curve: np.ndarray) -> float:
    """How far a closed curve is from a circle: the energy fraction outside its strongest harmonic (arc length).

    A near-circle (e.g. a Spirograph with a tiny pen offset) looks the same, within a hand's noise, as the
    near-circles every other machine and radii draw, so its radii cannot be told from a sketch.
    """
    from design.sketch.spline import resample_closed

    z = resample_closed(curve, 1024) @ np.array([1.0, 1j])
    power = np.abs(np.fft.fft(z - z.mean())) ** 2
    total = power.sum()
    return float(1.0 - power.max() / total) if total > 0 else 0.0


def drawn_piece(machine, design: dict[str, float], sector: int, rng: np.random.Generator, points: int) -> np.ndarray:
    """``points`` points of the design's pattern over one period, or (``sector`` = ``k > 1``) over one ``k``-th of
    it from a random start time: the piece a maker draws with ``--symmetry k``."""
    period = machine.period(design)
    if sector > 1:
        return machine.curve(design, rng.random() * period + np.linspace(0.0, period / sector, points))
    return machine.curve(design, np.linspace(0.0, period, points))


def make_case(
    machine,
    radii: dict[str, int],
    rng: np.random.Generator,
    symmetry: int = 1,
    noise: float = 0.006,
    sector_probability: float = 0.4,
    points_per_size: tuple[float, float] = (25.0, 60.0),
    min_detail: float = 0.02,
    tries: int = 20,
) -> SyntheticCase | None:
    """One synthetic sketch of a random design with the given radii.

    Parameters
    ----------
    machine : DrawingMachine
        The model.
    radii : dict
        Gear radii of the design.
    rng : numpy Generator
        Source of randomness (seeded by the caller).
    symmetry : int
        Rotational symmetry order ``k`` of the design's pattern (its leading radius); with ``k > 1`` a sector sketch
        may be drawn (probability ``sector_probability``).
    noise : float
        Standard deviation of the jitter, as a fraction of the pattern's size.
    points_per_size : (float, float)
        Range of the sampling density of a stroke, in points per pattern size (bounding-box diagonal) of stroke
        length: a hand or a tablet samples at a roughly constant spatial rate, so a long intricate stroke keeps
        more points. The spacing along the stroke is uneven (the hand slows down and speeds up).
    min_detail : float
        Designs whose :func:`pattern_detail` is below this are drawn again (up to ``tries`` times): a near-circle
        cannot tell its radii. The number of designs drawn again is reported in ``rejected``.
    """
    design = None
    rejected = 0
    for _ in range(tries):
        design = random_design(machine, radii, rng)
        if design is None:
            return None
        if pattern_detail(machine.sample(design, n=2048, spacing="arclength")[:-1]) >= min_detail:
            break
        rejected += 1
        design = None
    if design is None:
        return None
    sector = symmetry > 1 and rng.random() < sector_probability
    curve = drawn_piece(machine, design, symmetry if sector else 1, rng, 1500 if sector else 6000)
    size = float(np.linalg.norm(np.ptp(curve, axis=0)))
    n_strokes = int(rng.integers(1, 5))
    # stroke boundaries along the arc length, each followed by a pen lift of 2-6 % of the pattern's size
    length = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(curve, axis=0), axis=1))])
    total = length[-1]
    cuts = np.sort(rng.uniform(0.05, 0.95, n_strokes - 1)) * total if n_strokes > 1 else np.array([])
    edges = np.concatenate([[0.0], cuts, [total]])
    if not sector:
        edges = edges + rng.random() * total  # random start on the closed curve
    strokes = []
    for a, b in zip(edges[:-1], edges[1:]):
        gap = rng.uniform(0.02, 0.06) * size
        a_, b_ = a + gap / 2, b - gap / 2
        if b_ - a_ < 0.02 * total:
            continue
        s = np.linspace(a_, b_, max(400, int(40 * (b_ - a_) / size)))
        s_mod = np.mod(s, total) if not sector else s
        piece = np.column_stack([np.interp(s_mod, length, curve[:, 0]), np.interp(s_mod, length, curve[:, 1])])
        count = int(np.clip(rng.uniform(*points_per_size) * (b_ - a_) / size, 12, 3000))
        # uneven subsampling: a hand slows down and speeds up
        warp = np.cumsum(rng.uniform(0.3, 1.7, count))
        warp = (warp - warp[0]) / (warp[-1] - warp[0])
        dense = max(400, 4 * count)
        piece = resample_open(piece, dense)[np.round(warp * (dense - 1)).astype(int)]
        piece = piece + rng.normal(0.0, noise * size, piece.shape)
        strokes.append(piece)
    if not strokes:
        return None
    # random similarity transform, stroke order and direction
    angle = rng.uniform(0, 2 * math.pi)
    scale = rng.uniform(20, 200) / size
    shift = rng.uniform(-100, 100, 2)
    transform = rotation(angle) * scale
    strokes = [(s @ transform.T) + shift for s in strokes]
    order = rng.permutation(len(strokes))
    strokes = [strokes[i][::-1] if rng.random() < 0.5 else strokes[i] for i in order]
    centre = shift  # the machine's patterns are centred on the origin (ring or turntable centre)
    sketch = make_sketch(strokes, symmetry=symmetry if sector else 1, center=centre, source="synthetic")
    roles_radii = tuple(int(v) for v in radii.values())
    return SyntheticCase(machine.name, design, roles_radii, sketch, sector, len(strokes), rejected)
