"""Stroke ordering: the shortest closed path through all strokes (thesis, section 3.4.1).

The ``2 N_s`` stroke ends are the vertices of a complete graph. Each stroke's own edge (its two ends) is forced into
the tour, which is the ``k -> infinity`` limit of the thesis' edge cost ``c_ij = -k`` (Eq. 3.2); the other edges
cost the Euclidean distance between ends, plus (``continuity`` > 0, an addition to the thesis) how far each end lies
off the straight continuation of the other stroke: a hand-drawn pattern is cut into strokes with small gaps, and at
a crossing of the pattern the nearest end often belongs to the wrong branch.

The tour is solved exactly as an integer program (degree 2 at every vertex) with scipy's MILP solver (HiGHS),
adding subtour elimination constraints lazily (Dantzig, Fulkerson and Johnson) until the solution is one cycle.
Beyond :data:`EXACT_MAX_STROKES` strokes a nearest-neighbour tour improved by 2-opt and Or-opt moves (which reverse
stroke directions too) is used instead, on the same costs.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import Bounds, LinearConstraint, milp
from scipy.sparse import coo_array, csr_array
from scipy.sparse.csgraph import connected_components

from design.sketch.errors import SketchError

#: Largest number of strokes solved exactly: beyond it the MILP's time outgrows the heuristic's by far while the
#: heuristic's tours stay within a few per cent (``bench_sketch`` measures both; the figures are in the sketch
#: retrieval results page).
EXACT_MAX_STROKES = 32
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
        Total length of the connections between strokes.
    cost : float
        The tour's cost (gap length plus the continuity terms).
    method : str
        ``"exact"`` (MILP), ``"heuristic"`` (2-opt) or ``"trivial"`` (one stroke).
    """

    order: tuple[int, ...]
    reversed: tuple[bool, ...]
    gap_length: float
    method: str
    cost: float = 0.0

    def path(self, strokes: list[np.ndarray]) -> np.ndarray:
        """The strokes concatenated in tour order, ``(n, 2)``; closing it back to its start is implied."""
        parts = [strokes[i][::-1] if rev else strokes[i] for i, rev in zip(self.order, self.reversed)]
        return np.concatenate(parts)


def stroke_ends(strokes: list[np.ndarray]) -> np.ndarray:
    """The ``(2 N_s, 2)`` ends: stroke ``s`` has its start at row ``2 s`` and its end at row ``2 s + 1``."""
    return np.stack([np.stack([s[0], s[-1]]) for s in strokes]).reshape(-1, 2)


def end_directions(strokes: list[np.ndarray], reach: float) -> np.ndarray:
    """Outward unit tangents at the ``2 N_s`` ends (zero for a dot), from the chord to the point ``reach`` inside."""
    directions = np.zeros((2 * len(strokes), 2))
    for s, stroke in enumerate(strokes):
        if len(stroke) < 2:
            continue
        seg = np.linalg.norm(np.diff(stroke, axis=0), axis=1)
        cum = np.concatenate([[0.0], np.cumsum(seg)])
        depth = min(reach, 0.3 * cum[-1])
        for end, (points, arc) in enumerate([(stroke, cum), (stroke[::-1], cum[-1] - cum[::-1])]):
            inner = np.array([np.interp(depth, arc, points[:, 0]), np.interp(depth, arc, points[:, 1])])
            chord = points[0] - inner
            norm = np.linalg.norm(chord)
            if norm > 0:
                directions[2 * s + end] = chord / norm
    return directions


def connection_costs(strokes: list[np.ndarray], continuity: float = 1.0) -> np.ndarray:
    """``(2 N_s, 2 N_s)`` symmetric cost of joining two stroke ends (own-stroke pairs included, cost 0).

    ``cost = d + continuity * (off_a + off_b) / 2`` where ``d`` is the distance between the ends and ``off_a`` is how
    far end ``b`` lies from the straight continuation of the stroke at end ``a`` (``d`` itself when ``b`` is behind).
    """
    ends = stroke_ends(strokes)
    delta = ends[None, :, :] - ends[:, None, :]  # [a, b] = b - a
    distance = np.linalg.norm(delta, axis=-1)
    cost = distance.copy()
    if continuity > 0:
        diagonal = float(np.linalg.norm(np.ptp(np.concatenate(strokes), axis=0)))
        u = end_directions(strokes, reach=0.04 * diagonal)
        along = np.einsum("abk,ak->ab", delta, u)
        across = np.abs(delta[..., 0] * u[:, None, 1] - delta[..., 1] * u[:, None, 0])
        off = np.where(along >= 0, across, distance)
        off = np.where(np.linalg.norm(u, axis=1)[:, None] > 0, off, 0.0)
        cost = distance + continuity * (off + off.T) / 2
    own = np.arange(0, len(ends), 2)
    cost[own, own + 1] = cost[own + 1, own] = 0.0
    return cost


def tour_cost(costs: np.ndarray, order, reversed_) -> float:
    """Cost of a tour: the connections from each stroke's exit end to the next stroke's entry end, cyclically."""
    o = np.asarray(order)
    r = np.asarray(reversed_, dtype=int)
    entry, exit_ = 2 * o + r, 2 * o + 1 - r
    return float(costs[exit_, np.roll(entry, -1)].sum())


def tour_gap_length(strokes: list[np.ndarray], order, reversed_) -> float:
    """Length of the connections of a tour (end of each stroke to the start of the next, cyclically)."""
    ends = stroke_ends(strokes)
    distance = np.linalg.norm(ends[:, None] - ends[None], axis=-1)
    return tour_cost(distance, order, reversed_)


def order_strokes(
    strokes: list[np.ndarray], method: str = "auto", time_limit: float = 5.0, continuity: float = 1.0
) -> StrokeOrder:
    """The shortest closed path through all strokes.

    Parameters
    ----------
    strokes : list of ndarray
        ``(n_i, 2)`` polylines (``n_i >= 1``).
    method : {"auto", "exact", "heuristic"}
        ``"auto"`` is exact up to :data:`EXACT_MAX_STROKES` strokes, heuristic beyond.
    time_limit : float
        Seconds allowed to each MILP solve; on time-out the heuristic tour is returned.
    continuity : float
        Weight of the continuation term of :func:`connection_costs` (0: the thesis' plain distances).

    Returns
    -------
    StrokeOrder
    """
    if not strokes:
        raise SketchError("stroke ordering: no strokes; expected at least one")
    if method not in {"auto", "exact", "heuristic"}:
        raise SketchError(f"stroke ordering: method must be 'auto', 'exact' or 'heuristic', got {method!r}")
    if not np.isfinite(continuity) or continuity < 0:
        raise SketchError(f"stroke ordering: continuity must be a finite number >= 0, got {continuity!r}")
    n = len(strokes)
    if n > MAX_TOUR_STROKES:
        raise SketchError(
            f"stroke ordering: {n} strokes (symmetry copies included) is too many; expected at most "
            f"{MAX_TOUR_STROKES}: draw fewer strokes or give a smaller symmetry order"
        )
    costs = connection_costs(strokes, continuity)
    if n == 1:
        return _result(strokes, costs, (0,), (False,), "trivial")
    if method == "heuristic" or (method == "auto" and n > EXACT_MAX_STROKES):
        return _heuristic(strokes, costs)
    exact = _exact(strokes, costs, time_limit)
    return exact if exact is not None else _heuristic(strokes, costs)


def _result(strokes, costs, order, reversed_, method) -> StrokeOrder:
    order = tuple(int(i) for i in order)
    reversed_ = tuple(bool(r) for r in reversed_)
    return StrokeOrder(
        order, reversed_, tour_gap_length(strokes, order, reversed_), method, tour_cost(costs, order, reversed_)
    )


def _exact(strokes: list[np.ndarray], costs: np.ndarray, time_limit: float) -> StrokeOrder | None:
    """The optimal tour by MILP with lazy subtour elimination; ``None`` if the solver gives up."""
    v = 2 * len(strokes)
    iu, ju = np.triu_indices(v, k=1)
    cost = costs[iu, ju].copy()
    own = (iu // 2 == ju // 2) & (ju == iu + 1)  # a stroke's own edge: forced into the tour
    cost[own] = 0.0
    n_edges = len(iu)
    if len(strokes) == 2:
        # Two strokes: the degree constraints allow a double edge (a 2-cycle) that is no tour; enumerate the two
        # ways of joining the ends instead.
        forward = tour_cost(costs, (0, 1), (False, False))
        backward = tour_cost(costs, (0, 1), (False, True))
        return _result(strokes, costs, (0, 1), (False, bool(backward < forward)), "exact")
    rows = np.concatenate([iu, ju])
    cols = np.concatenate([np.arange(n_edges), np.arange(n_edges)])
    degree = coo_array((np.ones(2 * n_edges), (rows, cols)), shape=(v, n_edges)).tocsr()
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
            order, reversed_ = _order_from_edges(len(strokes), iu[chosen], ju[chosen])
            return _result(strokes, costs, order, reversed_, "exact")
        for comp in range(n_comp):
            members = labels == comp
            # subtour elimination: at most |S| - 1 chosen edges inside any proper vertex subset S
            cut_rows.append((members[iu] & members[ju]).astype(float))
            cut_limits.append(float(members.sum() - 1))
    return None


def _order_from_edges(n_strokes: int, iu: np.ndarray, ju: np.ndarray) -> tuple[list[int], list[bool]]:
    """Walk the cycle given by its edges into stroke order and directions."""
    neighbours: list[list[int]] = [[] for _ in range(2 * n_strokes)]
    for a, b in zip(iu.tolist(), ju.tolist()):
        neighbours[a].append(b)
        neighbours[b].append(a)
    order: list[int] = []
    reversed_: list[bool] = []
    vertex = 0
    for _ in range(n_strokes):
        stroke = vertex // 2
        order.append(stroke)
        reversed_.append(vertex % 2 == 1)  # entered at its end
        other = vertex ^ 1
        nxt = [w for w in neighbours[other] if w // 2 != stroke]
        vertex = nxt[0] if nxt else other
    return order, reversed_


def _heuristic(strokes: list[np.ndarray], costs: np.ndarray, starts: int = 8) -> StrokeOrder:
    """Nearest-neighbour tours from a few start strokes, each improved by 2-opt and Or-opt moves; the best.

    A 2-opt move reverses a run of strokes in the tour, which also reverses the direction of every stroke in the
    run; only the two connections at the run's boundaries change, so each move is evaluated in O(1) (costs are
    symmetric). An Or-opt move takes one stroke out and puts it back elsewhere, in either direction.
    """
    n = len(strokes)
    best: tuple[float, list[int], list[bool]] | None = None
    starts = starts if n <= 64 else 2 if n <= 160 else 1  # each start costs O(n^2) per improvement round
    for first in np.unique(np.linspace(0, n - 1, min(starts, n)).astype(int)):
        order, rev = _nearest_neighbour(costs, int(first))
        for _ in range(50):
            changed = _two_opt(costs, order, rev)
            changed |= _or_opt(costs, order, rev)
            if not changed:
                break
        value = tour_cost(costs, order, rev)
        if best is None or value < best[0] - 1e-12:
            best = (value, order, rev)
    assert best is not None
    return _result(strokes, costs, best[1], best[2], "heuristic")


def _nearest_neighbour(costs: np.ndarray, first: int) -> tuple[list[int], list[bool]]:
    n = len(costs) // 2
    order, rev = [first], [False]
    free = np.ones(n, dtype=bool)
    free[first] = False
    exit_ = 2 * first + 1
    for _ in range(n - 1):
        cand = np.flatnonzero(free)
        to_start = costs[exit_, 2 * cand]
        to_end = costs[exit_, 2 * cand + 1]
        best = int(np.argmin(np.minimum(to_start, to_end)))
        stroke = int(cand[best])
        backwards = bool(to_end[best] < to_start[best])
        order.append(stroke)
        rev.append(backwards)
        free[stroke] = False
        exit_ = 2 * stroke + (0 if backwards else 1)
    return order, rev


def _entries_exits(order: list[int], rev: list[bool]) -> tuple[np.ndarray, np.ndarray]:
    """Entry and exit end vertices of the strokes in tour order."""
    o = np.asarray(order)
    r = np.asarray(rev, dtype=int)
    return 2 * o + r, 2 * o + 1 - r


def _two_opt(costs: np.ndarray, order: list[int], rev: list[bool]) -> bool:
    """One pass of best-improvement 2-opt moves from each tour position (vectorized over the run's end)."""
    n = len(order)
    changed = False
    for i in range(n - 1):
        entries, exits = _entries_exits(order, rev)
        j = np.arange(i + 1, n)
        if i == 0:
            j = j[:-1]
        if not len(j):
            continue
        before = exits[i - 1]
        after = entries[(j + 1) % n]
        old = costs[before, entries[i]] + costs[exits[j], after]
        new = costs[before, exits[j]] + costs[entries[i], after]
        gain = old - new
        best = int(np.argmax(gain))
        if gain[best] > 1e-12:
            k = int(j[best])
            order[i : k + 1] = order[i : k + 1][::-1]
            rev[i : k + 1] = [not r for r in rev[i : k + 1][::-1]]
            changed = True
    return changed


def _or_opt(costs: np.ndarray, order: list[int], rev: list[bool]) -> bool:
    """One pass of Or-opt moves: each stroke is moved to its best other place and direction, if that is cheaper."""
    n = len(order)
    if n < 4:
        return False
    changed = False
    for i in range(n):
        entries, exits = _entries_exits(order, rev)
        stroke = order[i]
        prev_exit, next_entry = exits[i - 1], entries[(i + 1) % n]
        removed = costs[prev_exit, entries[i]] + costs[exits[i], next_entry] - costs[prev_exit, next_entry]
        keep = np.r_[0:i, i + 1 : n]
        a = exits[keep]  # insert after rest[j] ...
        b = entries[np.roll(keep, -1)]  # ... and before rest[j + 1]
        gap = costs[a, b]
        best_gain, best_at, best_dir = 1e-12, -1, False
        for direction in (False, True):
            entry, exit_ = 2 * stroke + int(direction), 2 * stroke + 1 - int(direction)
            added = costs[a, entry] + costs[exit_, b] - gap
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
