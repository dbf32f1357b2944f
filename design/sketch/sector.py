"""A sector sketch chained the way the machine draws it: the sector, then its rotated copies one after the other.

A pattern with ``k``-fold symmetry is drawn in ``k`` equal pieces of time: each piece is the previous one rotated by
the same angle ``2 pi m / k`` (``m`` coprime with ``k``). A maker who draws one piece (with ``--symmetry k``) gives
everything the pattern holds, and the way the copies join follows: the end of the piece is the start of the next
copy. The closed tour through all copies (:func:`design.sketch.ordering.order_strokes` on
:meth:`Sketch.symmetrized`) finds the same path when the copies lie apart, but on a ring-like pattern (the copies
overlap, a few turns of a wobbly circle) the nearest end often belongs to another copy, and the tour's path goes
round in the wrong order. Here the sector's own strokes are ordered into an open path and the copies are chained by
a rotation ``2 pi m / k``: of every order, direction and ``m``, the one whose joins (the tour's costs) and closing gap
(the path's end to the rotated copy of its start) are the smallest.
"""

from __future__ import annotations

import itertools
import math

import numpy as np

from design.sketch.ordering import StrokeOrder, connection_costs, order_strokes, stroke_ends
from design.sketch.strokes import Sketch, rotation

#: Most strokes of a sector ordered by trying every order and direction (7: 5040 orders x 64 directions).
MAX_EXACT_STROKES = 7


def sector_path(sketch: Sketch, ordering: str = "auto") -> tuple[np.ndarray, list[np.ndarray], StrokeOrder] | None:
    """The closed path of a sector sketch's copies chained in drawing order, or ``None`` without a symmetry.

    Returns
    -------
    path : ndarray
        ``(n, 2)`` points; closing it back to its start is implied.
    strokes : list of ndarray
        The copies of the sector's strokes in path order (each copy's strokes in the sector's order).
    order : StrokeOrder
        The trivial order of ``strokes`` (they are already in path order), its method ``"sector"``.
    """
    k = sketch.symmetry
    if k <= 1:
        return None
    base = [np.asarray(s, dtype=float) for s in sketch.strokes]
    centre = np.asarray(sketch.center, dtype=float)
    steps = [m for m in range(1, k) if math.gcd(m, k) == 1]
    turns = np.stack([rotation(2 * math.pi * m / k) for m in steps])  # (S, 2, 2)
    ends = stroke_ends(base) - centre
    # closing[a, b, m]: from exit end a to the copy (by step m) of entry end b
    closing = np.linalg.norm(ends[:, None, None, :] - np.einsum("mij,bj->bmi", turns, ends)[None], axis=-1)
    if len(base) <= MAX_EXACT_STROKES:
        order, reversed_, m = _best_open_path(connection_costs(base), closing)
    else:
        # many strokes: the closed tour opened at its longest connection, then the best step
        tour = order_strokes(base, method=ordering)
        order, reversed_ = list(tour.order), list(tour.reversed)
        entry = [2 * i + int(r) for i, r in zip(order, reversed_)]
        exit_ = [2 * i + 1 - int(r) for i, r in zip(order, reversed_)]
        jumps = [float(np.linalg.norm(ends[entry[(i + 1) % len(order)]] - ends[exit_[i]])) for i in range(len(order))]
        cut = int(np.argmax(jumps)) + 1
        order, reversed_ = order[cut:] + order[:cut], reversed_[cut:] + reversed_[:cut]
        m = int(np.argmin(closing[2 * order[-1] + 1 - int(reversed_[-1]), 2 * order[0] + int(reversed_[0])]))
    parts = [base[i][::-1] if r else base[i] for i, r in zip(order, reversed_)]
    m = steps[m]
    gap = float(closing[2 * order[-1] + 1 - int(reversed_[-1]), 2 * order[0] + int(reversed_[0]), steps.index(m)])
    inner = sum(float(np.linalg.norm(b[0] - a[-1])) for a, b in zip(parts[:-1], parts[1:]))
    strokes = []
    for j in range(k):
        turn = rotation(2 * math.pi * j * m / k)
        strokes.extend((p - centre) @ turn.T + centre for p in parts)
    return np.concatenate(strokes), strokes, StrokeOrder(tuple(range(len(strokes))), (False,) * len(strokes),
                                                         k * (gap + inner), "sector")


def _best_open_path(costs: np.ndarray, closing: np.ndarray) -> tuple[list[int], list[bool], int]:
    """Every order and direction of a few strokes (the first walked forwards: the reverse path is the same chain
    with the inverse step): the open path whose joins (``costs``, as in the closed tour) plus the closing gap to
    the best rotated copy of its start are the smallest. Returns (order, reversed, step index)."""
    n = costs.shape[0] // 2
    best = (np.inf, [0], [False], 0)
    flips = np.zeros((2 ** (n - 1), n), dtype=np.int64)
    if n > 1:
        flips[:, 1:] = np.array(list(itertools.product((0, 1), repeat=n - 1)), dtype=np.int64)
    gap = closing.min(axis=2)
    for perm in itertools.permutations(range(n)):
        p = np.array(perm)
        entry = 2 * p[None, :] + flips
        exit_ = 2 * p[None, :] + 1 - flips
        total = costs[exit_[:, :-1], entry[:, 1:]].sum(axis=1) + gap[exit_[:, -1], entry[:, 0]]
        i = int(np.argmin(total))
        if total[i] < best[0]:
            best = (float(total[i]), list(perm), [bool(f) for f in flips[i]], int(np.argmin(closing[exit_[i, -1],
                                                                                                  entry[i, 0]])))
    return best[1], best[2], best[3]


__all__ = ["sector_path"]
