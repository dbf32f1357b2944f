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

#: Largest number of strokes solved exactly. Measured by ``bench_sketch`` on a 2-core machine: the MILP with lazy
#: subtour cuts takes ~0.01-0.05 s up to 16 strokes, ~0.1-0.4 s at 24-32 and grows quickly beyond.
EXACT_MAX_STROKES = 24
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


def _head(ends: np.ndarray, stroke: int, backwards: bool) -> np.ndarray:
    return ends[stroke, 1 if backwards else 0]


def _tail(ends: np.ndarray, stroke: int, backwards: bool) -> np.ndarray:
    return ends[stroke, 0 if backwards else 1]


def _dist(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.hypot(*(a - b)))


def _two_opt(ends: np.ndarray, order: list[int], rev: list[bool]) -> bool:
    n = len(order)
    changed = False
    for i in range(n - 1):
        for j in range(i + 1, n):
            if i == 0 and j == n - 1:
                continue
            # connections (i-1 -> i) and (j -> j+1) become (i-1 -> j reversed) and (i reversed -> j+1)
            before = _tail(ends, order[i - 1], rev[i - 1])
            after = _head(ends, order[(j + 1) % n], rev[(j + 1) % n])
            head_i, tail_j = _head(ends, order[i], rev[i]), _tail(ends, order[j], rev[j])
            old = _dist(before, head_i) + _dist(tail_j, after)
            new = _dist(before, tail_j) + _dist(head_i, after)
            if new < old - 1e-12:
                order[i : j + 1] = order[i : j + 1][::-1]
                rev[i : j + 1] = [not r for r in rev[i : j + 1][::-1]]
                changed = True
    return changed


def _or_opt(ends: np.ndarray, order: list[int], rev: list[bool]) -> bool:
    n = len(order)
    if n < 4:
        return False
    changed = False
    i = 0
    while i < n:
        stroke, backwards = order[i], rev[i]
        prev_tail = _tail(ends, order[i - 1], rev[i - 1])
        next_head = _head(ends, order[(i + 1) % n], rev[(i + 1) % n])
        removed = (
            _dist(prev_tail, _head(ends, stroke, backwards))
            + _dist(_tail(ends, stroke, backwards), next_head)
            - _dist(prev_tail, next_head)
        )
        rest_order = order[:i] + order[i + 1 :]
        rest_rev = rev[:i] + rev[i + 1 :]
        best_gain, best_at, best_dir = 1e-12, -1, backwards
        for j in range(n - 1):  # insert between rest[j] and rest[j+1]
            a = _tail(ends, rest_order[j], rest_rev[j])
            b = _head(ends, rest_order[(j + 1) % (n - 1)], rest_rev[(j + 1) % (n - 1)])
            for direction in (False, True):
                added = (
                    _dist(a, _head(ends, stroke, direction)) + _dist(_tail(ends, stroke, direction), b) - _dist(a, b)
                )
                gain = removed - added
                if gain > best_gain:
                    best_gain, best_at, best_dir = gain, j, direction
        if best_at >= 0:
            rest_order.insert(best_at + 1, stroke)
            rest_rev.insert(best_at + 1, best_dir)
            order[:], rev[:] = rest_order, rest_rev
            changed = True
        i += 1
    return changed
