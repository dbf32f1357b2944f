"""Stroke ordering: the shortest closed path through all strokes (thesis, section 3.4.1).

The ``2 N_s`` stroke ends are the vertices of a complete graph. Each stroke's own edge (its two ends) is forced into
the tour, which is the ``k -> infinity`` limit of the thesis' edge cost ``c_ij = -k`` (Eq. 3.2); the other edges
cost the Euclidean distance between ends. The tour is solved exactly as an integer program (degree 2 at every
vertex) with scipy's MILP solver (HiGHS), adding subtour elimination constraints lazily (Dantzig, Fulkerson and
Johnson) until the solution is one cycle. Beyond :data:`EXACT_MAX_STROKES` strokes a nearest-neighbour tour
improved by 2-opt moves (which reverse stroke directions too) is used instead.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import Bounds, LinearConstraint, milp
from scipy.sparse import coo_array, csr_array
from scipy.sparse.csgraph import connected_components

from design.sketch.errors import SketchError

#: Largest number of strokes solved exactly. Measured by ``bench_sketch`` on a 2-core machine (random strokes, the
#: hard case): the MILP with lazy subtour cuts takes ~0.03 s up to 16 strokes, 0.1-0.3 s at 24-32, ~1 s at 48-64.
EXACT_MAX_STROKES = 40
#: Most strokes (symmetry copies included) a tour is computed for.
MAX_TOUR_STROKES = 400
#: Cutting-plane rounds before giving up on the exact tour and falling back to the heuristic.
MAX_CUT_ROUNDS = 60


@dataclass(frozen=True)
class StrokeOrder:
    """A closed tour through strokes.

    Attributes
    ----------
    order : tuple of int
        Stroke indices in tour order.
    reversed : tuple of bool
        Whether each stroke (in tour order) is walked backwards.
    gap_length : float
        Total length of the connections between strokes (the tour cost without the strokes themselves).
    method : str
        ``"exact"`` (MILP), ``"heuristic"`` (2-opt) or ``"trivial"`` (one stroke).
    """

    order: tuple[int, ...]
    reversed: tuple[bool, ...]
    gap_length: float
    method: str

    def path(self, strokes: list[np.ndarray]) -> np.ndarray:
        """The strokes concatenated in tour order, ``(n, 2)``; closing it back to its start is implied."""
        parts = [strokes[i][::-1] if rev else strokes[i] for i, rev in zip(self.order, self.reversed)]
        return np.concatenate(parts)


def stroke_ends(strokes: list[np.ndarray]) -> np.ndarray:
    """The ``(2 N_s, 2)`` ends: stroke ``s`` has its start at row ``2 s`` and its end at row ``2 s + 1``."""
    return np.stack([np.stack([s[0], s[-1]]) for s in strokes]).reshape(-1, 2)


def tour_gap_length(strokes: list[np.ndarray], order, reversed_) -> float:
    """Length of the connections of a tour (end of each stroke to the start of the next, cyclically)."""
    ends = stroke_ends(strokes).reshape(-1, 2, 2)
    heads = np.array([ends[i, 1 if r else 0] for i, r in zip(order, reversed_)])
    tails = np.array([ends[i, 0 if r else 1] for i, r in zip(order, reversed_)])
    return float(np.linalg.norm(np.roll(heads, -1, axis=0) - tails, axis=1).sum())


def order_strokes(strokes: list[np.ndarray], method: str = "auto", time_limit: float = 5.0) -> StrokeOrder:
    """The shortest closed path through all strokes.

    Parameters
    ----------
    strokes : list of ndarray
        ``(n_i, 2)`` polylines (``n_i >= 1``).
    method : {"auto", "exact", "heuristic"}
        ``"auto"`` is exact up to :data:`EXACT_MAX_STROKES` strokes, heuristic beyond.
    time_limit : float
        Seconds allowed to each MILP solve; on time-out the heuristic tour is returned.

    Returns
    -------
    StrokeOrder
    """
    if not strokes:
        raise SketchError("stroke ordering: no strokes; expected at least one")
    if method not in {"auto", "exact", "heuristic"}:
        raise SketchError(f"stroke ordering: method must be 'auto', 'exact' or 'heuristic', got {method!r}")
    n = len(strokes)
    if n > MAX_TOUR_STROKES:
        raise SketchError(
            f"stroke ordering: {n} strokes (symmetry copies included) is too many; expected at most "
            f"{MAX_TOUR_STROKES}: draw fewer strokes or give a smaller symmetry order"
        )
    if n == 1:
        return StrokeOrder((0,), (False,), tour_gap_length(strokes, (0,), (False,)), "trivial")
    if method == "heuristic" or (method == "auto" and n > EXACT_MAX_STROKES):
        return _heuristic(strokes)
    exact = _exact(strokes, time_limit)
    return exact if exact is not None else _heuristic(strokes)


def _exact(strokes: list[np.ndarray], time_limit: float) -> StrokeOrder | None:
    """The optimal tour by MILP with lazy subtour elimination; ``None`` if the solver gives up."""
    ends = stroke_ends(strokes)
    v = len(ends)
    iu, ju = np.triu_indices(v, k=1)
    cost = np.linalg.norm(ends[iu] - ends[ju], axis=1)
    own = (iu // 2 == ju // 2) & (ju == iu + 1)  # a stroke's own edge: forced into the tour
    cost[own] = 0.0
    n_edges = len(iu)
    rows = np.concatenate([iu, ju])
    cols = np.concatenate([np.arange(n_edges), np.arange(n_edges)])
    degree = coo_array((np.ones(2 * n_edges), (rows, cols)), shape=(v, n_edges)).tocsr()
    if len(strokes) == 2:
        # Two strokes: the degree constraints allow a double edge (a 2-cycle) that is no tour; enumerate the two
        # pairings of ends instead.
        forward = cost[_edge_index(v, 1, 2)] + cost[_edge_index(v, 0, 3)]
        backward = cost[_edge_index(v, 1, 3)] + cost[_edge_index(v, 0, 2)]
        rev = bool(backward < forward)
        return StrokeOrder((0, 1), (False, rev), float(min(forward, backward)), "exact")
    bounds = Bounds(np.where(own, 1.0, 0.0), np.ones(n_edges))
    integrality = np.ones(n_edges)
    cut_rows: list[np.ndarray] = []
    cut_limits: list[float] = []
    for _ in range(MAX_CUT_ROUNDS):
        constraints = [LinearConstraint(degree, 2.0, 2.0)]
        if cut_rows:
            constraints.append(LinearConstraint(csr_array(np.vstack(cut_rows)), -np.inf, np.array(cut_limits)))
        result = milp(
            cost,
            constraints=constraints,
            integrality=integrality,
            bounds=bounds,
            options={"time_limit": time_limit, "disp": False},
        )
        if result.status != 0 or result.x is None:
            return None
        chosen = result.x > 0.5
        graph = coo_array((np.ones(int(chosen.sum())), (iu[chosen], ju[chosen])), shape=(v, v))
        n_comp, labels = connected_components(graph, directed=False)
        if n_comp == 1:
            return _order_from_edges(strokes, iu[chosen], ju[chosen], "exact")
        for comp in range(n_comp):
            members = labels == comp
            # subtour elimination: at most |S| - 1 chosen edges inside any proper vertex subset S
            cut_rows.append((members[iu] & members[ju]).astype(float))
            cut_limits.append(float(members.sum() - 1))
    return None


def _edge_index(v: int, i: int, j: int) -> int:
    """Index of edge ``(i, j)``, ``i < j``, in ``np.triu_indices(v, 1)`` order."""
    return i * v - i * (i + 1) // 2 + (j - i - 1)


def _order_from_edges(strokes: list[np.ndarray], iu: np.ndarray, ju: np.ndarray, method: str) -> StrokeOrder:
    """Walk the cycle given by its edges into stroke order and directions."""
    v = 2 * len(strokes)
    neighbours: list[list[int]] = [[] for _ in range(v)]
    for a, b in zip(iu.tolist(), ju.tolist()):
        neighbours[a].append(b)
        neighbours[b].append(a)
    order: list[int] = []
    reversed_: list[bool] = []
    vertex = 0
    for _ in range(len(strokes)):
        stroke = vertex // 2
        entered_at_end = vertex % 2 == 1
        other = vertex ^ 1
        order.append(stroke)
        reversed_.append(entered_at_end)
        nxt = [w for w in neighbours[other] if w // 2 != stroke]
        vertex = nxt[0] if nxt else other
    return StrokeOrder(tuple(order), tuple(reversed_), tour_gap_length(strokes, order, reversed_), method)


def _heuristic(strokes: list[np.ndarray], starts: int = 8) -> StrokeOrder:
    """Nearest-neighbour tours from a few start strokes, each improved by 2-opt and Or-opt moves; the best.

    A 2-opt move reverses a run of strokes in the tour, which also reverses the direction of every stroke in the
    run; only the two connections at the run's boundaries change, so each move is evaluated in O(1). An Or-opt move
    takes one stroke out and puts it back elsewhere, in either direction.
    """
    ends = stroke_ends(strokes).reshape(-1, 2, 2)
    n = len(strokes)
    best: tuple[float, list[int], list[bool]] | None = None
    starts = starts if n <= 64 else 2 if n <= 160 else 1  # each start costs O(n^2) per improvement round
    for first in np.unique(np.linspace(0, n - 1, min(starts, n)).astype(int)):
        order, rev = _nearest_neighbour(ends, int(first))
        for _ in range(50):
            changed = _two_opt(ends, order, rev)
            changed |= _or_opt(ends, order, rev)
            if not changed:
                break
        cost = tour_gap_length(strokes, order, rev)
        if best is None or cost < best[0] - 1e-12:
            best = (cost, order, rev)
    assert best is not None
    cost, order, rev = best
    return StrokeOrder(tuple(order), tuple(rev), cost, "heuristic")


def _nearest_neighbour(ends: np.ndarray, first: int) -> tuple[list[int], list[bool]]:
    n = len(ends)
    order, rev = [first], [False]
    free = np.ones(n, dtype=bool)
    free[first] = False
    tail = ends[first, 1]
    for _ in range(n - 1):
        cand = np.flatnonzero(free)
        d_start = np.linalg.norm(ends[cand, 0] - tail, axis=1)
        d_end = np.linalg.norm(ends[cand, 1] - tail, axis=1)
        best = int(np.argmin(np.minimum(d_start, d_end)))
        stroke = int(cand[best])
        backwards = bool(d_end[best] < d_start[best])
        order.append(stroke)
        rev.append(backwards)
        free[stroke] = False
        tail = ends[stroke, 0 if backwards else 1]
    return order, rev


def _heads_tails(ends: np.ndarray, order: list[int], rev: list[bool]) -> tuple[np.ndarray, np.ndarray]:
    """Entry and exit points of the strokes in tour order, ``(n, 2)`` each."""
    o = np.asarray(order)
    r = np.asarray(rev, dtype=int)
    return ends[o, r], ends[o, 1 - r]


def _two_opt(ends: np.ndarray, order: list[int], rev: list[bool]) -> bool:
    """One pass of best-improvement 2-opt moves from each tour position (vectorized over the run's end)."""
    n = len(order)
    changed = False
    for i in range(n - 1):
        heads, tails = _heads_tails(ends, order, rev)
        j = np.arange(i + 1, n)
        if i == 0:
            j = j[:-1]
        if not len(j):
            continue
        before = tails[i - 1]
        after = heads[(j + 1) % n]
        old = np.linalg.norm(before - heads[i]) + np.linalg.norm(tails[j] - after, axis=1)
        new = np.linalg.norm(before - tails[j], axis=1) + np.linalg.norm(heads[i] - after, axis=1)
        gain = old - new
        best = int(np.argmax(gain))
        if gain[best] > 1e-12:
            k = int(j[best])
            order[i : k + 1] = order[i : k + 1][::-1]
            rev[i : k + 1] = [not r for r in rev[i : k + 1][::-1]]
            changed = True
    return changed


def _or_opt(ends: np.ndarray, order: list[int], rev: list[bool]) -> bool:
    """One pass of Or-opt moves: each stroke is moved to its best other place and direction, if that is shorter."""
    n = len(order)
    if n < 4:
        return False
    changed = False
    for i in range(n):
        heads, tails = _heads_tails(ends, order, rev)
        stroke = order[i]
        prev_tail, next_head = tails[i - 1], heads[(i + 1) % n]
        removed = (
            np.linalg.norm(prev_tail - heads[i])
            + np.linalg.norm(tails[i] - next_head)
            - np.linalg.norm(prev_tail - next_head)
        )
        keep = np.r_[0:i, i + 1 : n]
        a = tails[keep]  # insert after rest[j] ...
        b = heads[np.roll(keep, -1)]  # ... and before rest[j + 1]
        gap = np.linalg.norm(a - b, axis=1)
        best_gain, best_at, best_dir = 1e-12, -1, False
        for direction in (False, True):
            head, tail = ends[stroke, int(direction)], ends[stroke, 1 - int(direction)]
            added = np.linalg.norm(a - head, axis=1) + np.linalg.norm(tail - b, axis=1) - gap
            j = int(np.argmin(added))
            if removed - added[j] > best_gain:
                best_gain, best_at, best_dir = removed - added[j], j, direction
        if best_at >= 0:
            rest_order = [order[k] for k in keep]
            rest_rev = [rev[k] for k in keep]
            rest_order.insert(best_at + 1, stroke)
            rest_rev.insert(best_at + 1, best_dir)
            order[:], rev[:] = rest_order, rest_rev
            changed = True
    return changed
