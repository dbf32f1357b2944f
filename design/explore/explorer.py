"""The guided-exploration session, usable without any UI (thesis 3.5).

>>> from design.explore import Explorer
>>> ex = Explorer("spirograph", {"r_f": 7, "r_r": 3, "d": 2.0})
>>> ex.pois[:2]                               # Points of Interest of the current design
>>> ex.add_invariant("position", [0])         # freeze something; the sliders become invariant-space sliders
>>> ex.sliders                                # names, values, bounds (tightened by the machine's constraints)
>>> ex.move(0, 1.0).params                    # live preview of a slider move (no re-projection)
>>> result = ex.release()                     # re-projection onto the invariants, then a new subspace
>>> result.params, result.errors_after

Continuous parameters change; discrete ones (gear radii) are fixed for a session, as in the thesis.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace

import numpy as np

from design.explore.errors import ExploreError, InvariantSpecError, OverConstrainedError
from design.explore.invariants import ERROR_UNIT, Invariant, make_invariant
from design.explore.local import BatchCurve, LocalPoI, track_local
from design.explore.poi import CURVATURE, PointOfInterest, cumulative_arclength, detect_pois, menger_curvature
from design.explore.shape import bbox_diagonal, shape_distance
from design.explore.subspace import Subspace, compute_subspace, jacobian, line_interval
from design.explore.tracking import track_poi


@dataclass(frozen=True)
class Slider:
    """One slider of the current parametrization.

    Attributes
    ----------
    index : int
    name : str
        The parameter's name (base parametrization) or ``"axis k"`` (invariant space).
    value, lower, upper : float
        Current value and bounds (within [-2, 2] in invariant space; see :class:`Explorer`).
    direction : dict
        Change of each continuous parameter per unit of slider.
    """

    index: int
    name: str
    value: float
    lower: float
    upper: float
    direction: dict[str, float]

    def as_dict(self) -> dict:
        return {
            "index": self.index, "name": self.name, "value": self.value, "lower": self.lower, "upper": self.upper,
            "direction": dict(self.direction),
        }


@dataclass(frozen=True)
class MoveResult:
    """A previewed slider move: the design and its curve (no re-projection yet)."""

    params: dict[str, float]
    curve: np.ndarray
    sliders: list[Slider]


@dataclass(frozen=True)
class ReleaseResult:
    """What a release did.

    Attributes
    ----------
    params_moved : dict
        The design where the slider was released.
    params : dict
        The design after re-projection (the new current design).
    features_before, features_after : dict
        Per tracked PoI (label ``"poi N"`` with its id on the design before the move): position, curvature or
        angle on the moved and on the re-projected design (None where lost).
    errors_before, errors_after : dict
        Per invariant label: its error (unit in :data:`design.explore.invariants.ERROR_UNIT`), NaN where lost.
    lost : list of str
        PoIs that could not be tracked by arc length (Eq. 3.14) onto the new design's PoIs.
    shape_change : float
        :func:`~design.explore.shape.shape_distance` between the design before the move and after re-projection.
    converged : bool
        Whether the re-projection met its tolerance (if not, the design stays where it was before the move).
    fraction : float
        Fraction of the move that was kept: below 1 when the invariants could only be kept over a shorter move.
    warning : str
        Anything the user should know (e.g. the subspace could not be updated).
    """

    params_moved: dict[str, float]
    params: dict[str, float]
    features_before: dict[str, dict]
    features_after: dict[str, dict]
    errors_before: dict[str, float]
    errors_after: dict[str, float]
    lost: list[str] = field(default_factory=list)
    shape_change: float = 0.0
    converged: bool = True
    fraction: float = 1.0
    warning: str = ""


class Explorer:
    """A guided-exploration session on one machine.

    Parameters
    ----------
    machine : str or DrawingMachine
        The machine (name in :mod:`design.machines` or a model).
    params : mapping, optional
        The starting design (defaults completed, validated).
    n_points : int, optional
        Samples of the curve for PoI detection (default: about 400 per turn of the driving gear, 4096 to 20000).
    neighborhood : float
        Normalization of each continuous parameter: a slider unit moves a parameter by at most this fraction of its
        feasible range at the starting design (thesis: the grid resolution adapts per dimension to that range).
    sigma_poi : float
        Largest move of a tracked PoI between the current design and a neighbour, as a fraction of the size.
    budget : int
        About how many grid samples per subspace update.
    keep_fraction : float
        Fraction of best-scored samples given to the WPCA.
    pull : bool
        See :func:`design.explore.subspace.compute_subspace`.
    rel_prominence : float
        Curvature-peak prominence threshold (see :func:`design.explore.poi.detect_curvature_maxima`).
    """

    def __init__(
        self,
        machine,
        params: Mapping[str, float] | None = None,
        *,
        n_points: int | None = None,
        neighborhood: float = 0.2,
        sigma_poi: float = 0.1,
        budget: int = 1024,
        keep_fraction: float = 0.25,
        pull: bool = True,
        rel_prominence: float = 0.05,
    ):
        if isinstance(machine, str):
            from design.machines import get_machine

            machine = get_machine(machine)
        self.machine = machine
        self.sigma_poi = float(sigma_poi)
        self.budget = int(budget)
        self.keep_fraction = float(keep_fraction)
        self.pull = bool(pull)
        self.rel_prominence = float(rel_prominence)
        self._params = dict(machine.validate(params))
        self.names = tuple(machine.continuous_names)
        if not self.names:
            raise ExploreError(f"{machine.name}: no continuous parameter to explore")
        self.period = float(machine.period(self._params))
        turns = self.period / (2 * np.pi)
        # ~400 samples per turn of the driving gear keeps every loop resolved; bounded for long patterns.
        self.n_points = int(n_points) if n_points is not None else int(np.clip(400 * turns, 4096, 20000))
        self._x0 = np.array([self._params[n] for n in self.names], dtype=float)
        widths = []
        for name in self.names:
            lo, hi = machine.feasible_interval(self._params, name)
            if hi - lo <= 0:
                parameter = machine.parameter(name)
                lo, hi = parameter.lower, parameter.upper
            widths.append(hi - lo)
        self.scale = float(neighborhood) * np.array(widths)
        self._curves = BatchCurve(machine, self._params, self.names)
        self._detect()
        self.size = bbox_diagonal(self.curve)
        self.invariants: list[Invariant] = []
        self._refs: dict[int, LocalPoI] = {}
        self._current_ids: dict[int, int | None] = {}
        self._next_key = 0
        self._subspace = Subspace(np.eye(len(self.names)), True, np.zeros(0), 0, 0)
        self.values = np.zeros(len(self.names))
        self._bounds = np.zeros((len(self.names), 2))
        self._update_bounds()

    # -- state ---------------------------------------------------------------------------------------------------

    @property
    def base_design(self) -> dict[str, float]:
        """The design at the sliders' zero (the last released design)."""
        return dict(self._params)

    @property
    def design(self) -> dict[str, float]:
        """The current design, sliders included."""
        return self._design_at(self._u())

    @property
    def basis(self) -> np.ndarray:
        """Slider directions in normalized coordinates, (m, n)."""
        return self._subspace.basis.copy()

    @property
    def subspace(self) -> Subspace:
        return self._subspace

    @property
    def pois(self) -> list[PointOfInterest]:
        """PoIs of the base design (ids index this list)."""
        return list(self._pois)

    @property
    def sliders(self) -> list[Slider]:
        invariant_space = bool(self.invariants) and not self._subspace.redundant
        out = []
        for k, b in enumerate(self._subspace.basis):
            name = f"axis {k + 1}" if invariant_space else self.names[int(np.argmax(np.abs(b)))]
            direction = {n: float(v) for n, v in zip(self.names, b * self.scale)}
            lower, upper = self._bounds[k]
            out.append(Slider(k, name, float(self.values[k]), float(lower), float(upper), direction))
        return out

    def invariant_pois(self) -> dict[str, list[int | None]]:
        """For each invariant label, the ids of its PoIs in :attr:`pois` (None where lost)."""
        return {inv.label: [self._current_ids.get(k) for k in inv.feature_keys] for inv in self.invariants}

    def sample(self, params: Mapping[str, float] | None = None, n: int | None = None) -> np.ndarray:
        """The curve of a design (the current one by default), ``n`` points uniform in time, closed."""
        params = self.design if params is None else params
        t = np.linspace(0.0, self.period, (n or self.n_points) + 1)
        return self.machine.curve(params, t)

    # -- invariants ----------------------------------------------------------------------------------------------

    def add_invariant(self, kind: str, poi_ids: Sequence[int]) -> Invariant:
        """Freeze a feature of one or two PoIs of the base design, then recompute the subspace.

        Raises
        ------
        InvariantSpecError
            Bad type, PoI id or PoI kind.
        OverConstrainedError
            The invariants together leave no freedom (the invariant is not added).
        """
        if np.any(self.values != 0):
            self.release()
        ids = [int(i) for i in poi_ids]
        for i in ids:
            if not 0 <= i < len(self._pois):
                raise InvariantSpecError(
                    f"invariant {kind!r}: PoI id must be one of 0..{len(self._pois) - 1} on this design, got {i}"
                )
        refined = list(self._pois)
        new_refs: dict[int, LocalPoI] = {}
        keys = []
        by_current = {v: k for k, v in self._current_ids.items() if v is not None}
        for i in ids:
            if i in by_current:
                key = by_current[i]
                ref = self._refs[key]
            else:
                key = self._next_key + len(new_refs)
                ref = self._local_ref(self._pois[i])
                new_refs[key] = ref
            keys.append(key)
            refined[i] = self._refined_poi(self._pois[i], ref)
        invariant = make_invariant(kind, ids, refined, self.size)
        invariant = replace(invariant, keys=tuple(keys))
        saved = (list(self.invariants), dict(self._refs), dict(self._current_ids), self._subspace)
        self.invariants.append(invariant)
        self._refs.update(new_refs)
        for key, i in zip(keys, ids):
            self._current_ids[key] = i
        try:
            self._recompute_subspace(previous=None)
        except OverConstrainedError:
            self.invariants, self._refs, self._current_ids, self._subspace = saved
            raise
        self._next_key += len(new_refs)
        return invariant

    def remove_invariant(self, index: int) -> None:
        """Drop an invariant (by position in :attr:`invariants`) and recompute the subspace."""
        if not 0 <= index < len(self.invariants):
            raise InvariantSpecError(f"invariant index must be in 0..{len(self.invariants) - 1}, got {index}")
        if np.any(self.values != 0):
            self.release()
        del self.invariants[index]
        used = {k for inv in self.invariants for k in inv.feature_keys}
        self._refs = {k: v for k, v in self._refs.items() if k in used}
        self._current_ids = {k: v for k, v in self._current_ids.items() if k in used}
        self._recompute_subspace(previous=None)

    def clear_invariants(self) -> None:
        while self.invariants:
            self.remove_invariant(len(self.invariants) - 1)

    # -- sliders -------------------------------------------------------------------------------------------------

    def move(self, slider: int, value: float) -> MoveResult:
        """Move one slider (clamped to its bounds); the other sliders' bounds are recomputed. No re-projection."""
        if not 0 <= slider < len(self.values):
            raise ExploreError(f"slider index must be in 0..{len(self.values) - 1}, got {slider}")
        value = float(value)
        if not np.isfinite(value):
            raise ExploreError(f"slider value must be a finite number, got {value!r}")
        lower, upper = self._bounds[slider]
        self.values[slider] = float(np.clip(value, lower, upper))
        self._update_bounds()
        params = self.design
        return MoveResult(params, self.sample(params), self.sliders)

    def release(self) -> ReleaseResult:
        """Re-project the current design onto the invariants, make it the base design, recompute the subspace."""
        before_curve = self.curve
        u_moved = self._u()
        params_moved = self._design_at(u_moved)
        converged, fraction = True, 1.0
        if self.invariants:
            u_new, refs_new, converged, fraction = self._reproject(u_moved)
        else:
            u_new, refs_new = u_moved, dict(self._refs)
        features_before = self._features(u_moved[None, :], self._refs)
        features_after = self._features(u_new[None, :], refs_new)
        errors_before = self._errors(features_before)
        errors_after = self._errors(features_after)
        old_ids = dict(self._current_ids)
        # Commit: the re-projected design becomes the base.
        self._x0 = self._x0 + self.scale * u_new
        self._params = self._design_at(np.zeros(len(self.names)), self._x0)
        self._curves = BatchCurve(self.machine, self._params, self.names)
        self._refs = {key: self._updated_ref(ref, features_after[key]) for key, ref in refs_new.items()}
        self._detect()
        lost = self._map_ids()
        if not converged:
            warning = (
                "no design near the move keeps the invariants (a PoI is lost or the invariants cannot be met): "
                "the design did not change"
            )
        elif fraction < 1.0:
            warning = f"the invariants could only be kept over {fraction:.0%} of the move"
        else:
            warning = ""
        previous = self._subspace.basis if not self._subspace.redundant else None
        try:
            self._recompute_subspace(previous=previous)
        except OverConstrainedError as error:
            warning = (warning + "; " if warning else "") + f"subspace kept from the previous design: {error}"
            self.values = np.zeros(len(self._subspace.basis))
            self._update_bounds()
        describe = {}
        for key in refs_new:
            label = f"poi {old_ids.get(key)}"
            describe[label] = (self._describe(features_before[key]), self._describe(features_after[key]))
        return ReleaseResult(
            params_moved=params_moved,
            params=dict(self._params),
            features_before={k: v[0] for k, v in describe.items()},
            features_after={k: v[1] for k, v in describe.items()},
            errors_before=errors_before,
            errors_after=errors_after,
            lost=[f"poi {old_ids.get(k)}" for k in lost],
            shape_change=shape_distance(before_curve, self.curve, self.size),
            converged=converged,
            fraction=fraction,
            warning=warning,
        )

    def invariant_errors(self) -> dict[str, float]:
        """Current error of every invariant on the current design (sliders included)."""
        return self._errors(self._features(self._u()[None, :], self._refs))

    # -- internals -----------------------------------------------------------------------------------------------

    def _u(self) -> np.ndarray:
        return self.values @ self._subspace.basis

    def _design_at(self, u: np.ndarray, x0: np.ndarray | None = None) -> dict[str, float]:
        x = (self._x0 if x0 is None else x0) + self.scale * np.asarray(u)
        params = dict(self._params)
        params.update({n: float(v) for n, v in zip(self.names, x)})
        return params

    def _X(self, U: np.ndarray) -> np.ndarray:
        return self._x0[None, :] + np.atleast_2d(U) * self.scale[None, :]

    def _feasible_u(self, U: np.ndarray) -> np.ndarray:
        return self._curves.feasible(self._X(U))

    def _detect(self) -> None:
        times = np.linspace(0.0, self.period, self.n_points + 1)
        self.curve = self.machine.curve(self._params, times)
        self._times = times
        self._arclength = cumulative_arclength(self.curve)
        self._pois = detect_pois(self.curve, times, self.rel_prominence)
        self._median_curvature = float(np.median(np.abs(menger_curvature(self.curve))))

    def _local_ref(self, poi: PointOfInterest) -> LocalPoI:
        """Tracking window of a PoI: half the time to its nearest neighbour of the same kind (Eq. 3.14 in time)."""
        same = [p.times for p in self._pois if p.kind == poi.kind and p.id != poi.id]
        if poi.kind == CURVATURE:
            gaps = [abs(t[0] - poi.times[0]) for t in same]
            gaps = [min(g, self.period - g) for g in gaps]
            window = min(0.45 * min(gaps) if gaps else self.period / 8, self.period / 8)
        else:
            separation = abs(poi.times[0] - poi.times[1]) % self.period
            separation = min(separation, self.period - separation)
            window = min(0.25 * separation, self.period / 40)
        window = max(window, 1e-4 * self.period)
        # Half the detector's prominence threshold: a maximum fading below it is lost rather than followed.
        min_prominence = 0.5 * self.rel_prominence * self._median_curvature
        return LocalPoI(poi.kind, tuple(poi.times), tuple(poi.xy), window, self.period, min_prominence)

    def _refined_poi(self, poi: PointOfInterest, ref: LocalPoI) -> PointOfInterest:
        f = track_local(self._curves, self._x0[None, :], ref, np.inf, self.size)
        if f.lost[0]:
            return poi
        xy = (float(f.xy[0, 0]), float(f.xy[0, 1]))
        if poi.kind == CURVATURE:
            return replace(poi, xy=xy, curvature=float(f.curvature[0]), times=(float(f.times[0, 0]),))
        return replace(poi, xy=xy, angle=float(f.angle[0]), times=tuple(float(t) for t in f.times[0]))

    def _features(self, U: np.ndarray, refs: Mapping[int, LocalPoI]) -> dict[int, dict[str, np.ndarray]]:
        X = self._X(U)
        sigma = self.sigma_poi * self.size
        out = {}
        for key, ref in refs.items():
            f = track_local(self._curves, X, ref, sigma, self.size)
            out[key] = {"xy": f.xy, "curvature": f.curvature, "angle": f.angle, "times": f.times, "lost": f.lost}
        return out

    def _residuals(self, U: np.ndarray, refs: Mapping[int, LocalPoI] | None = None) -> np.ndarray:
        features = self._features(U, self._refs if refs is None else refs)
        return np.hstack([inv.residuals(features) for inv in self.invariants])

    def _errors(self, features) -> dict[str, float]:
        return {inv.label: float(inv.errors(features)[0]) for inv in self.invariants}

    @staticmethod
    def _describe(f: Mapping[str, np.ndarray]) -> dict | None:
        if f["lost"][0]:
            return None
        out = {"xy": [float(f["xy"][0, 0]), float(f["xy"][0, 1])], "times": [float(t) for t in f["times"][0]]}
        if np.isfinite(f["curvature"][0]):
            out["curvature"] = float(f["curvature"][0])
        if np.isfinite(f["angle"][0]):
            out["angle_deg"] = float(np.degrees(f["angle"][0]))
        return out

    def _updated_ref(self, ref: LocalPoI, f: Mapping[str, np.ndarray]) -> LocalPoI:
        if f["lost"][0]:
            return ref
        times = tuple(float(t) for t in f["times"][0])
        return replace(ref, times=times, xy=(float(f["xy"][0, 0]), float(f["xy"][0, 1])))

    def _map_ids(self) -> list[int]:
        """Match every tracked PoI to the new design's PoIs by arc length (Eq. 3.14); returns the lost keys."""
        lost = []
        length = float(self._arclength[-1])
        for key, ref in self._refs.items():
            arclength = tuple(float(np.interp(t % self.period, self._times, self._arclength)) for t in ref.times)
            probe = PointOfInterest(-1, ref.kind, ref.xy, tuple(sorted(arclength)), length, ref.times)
            result = track_poi(probe, self._pois, sigma_poi=0.02 * self.size, sigma_arclength=0.01)
            self._current_ids[key] = None if result.lost else result.match.id
            if result.lost:
                lost.append(key)
        return lost

    def _recompute_subspace(self, previous: np.ndarray | None) -> None:
        n = len(self.names)
        if not self.invariants:
            self._subspace = Subspace(np.eye(n), True, np.zeros(0), 0, 0)
        else:
            lower, upper = np.full(n, -1.0), np.full(n, 1.0)
            for i, name in enumerate(self.names):
                lo, hi = self.machine.feasible_interval(self._params, name)
                lower[i] = max(-1.0, (lo - self._x0[i]) / self.scale[i])
                upper[i] = min(1.0, (hi - self._x0[i]) / self.scale[i])
            self._subspace = compute_subspace(
                self._residuals, self._feasible_u, lower, upper, [inv.label for inv in self.invariants],
                budget=self.budget, keep_fraction=self.keep_fraction, pull=self.pull, previous=previous,
            )
        self.values = np.zeros(len(self._subspace.basis))
        self._update_bounds()

    def _update_bounds(self) -> None:
        u = self._u()
        basis = self._subspace.basis
        self._bounds = np.array(
            [line_interval(self._feasible_u, u, basis[k], float(self.values[k])) for k in range(len(basis))]
        ).reshape(len(basis), 2)

    def _reproject(self, u_moved: np.ndarray) -> tuple[np.ndarray, dict[int, LocalPoI], bool, float]:
        """Nearest design to ``u_moved`` that keeps the invariants: minimum-norm Gauss-Newton, with continuation.

        The move is split into 1, 2, 4 then 8 steps when a PoI cannot be tracked over the whole move: each step
        starts from the previous projection plus the step's share of the move (the last one from ``u_moved``
        itself when that works), and each projection is the tracking reference of the next step. If even that
        fails, shorter moves (1/2, 1/4, 1/8 of the way) are tried.

        Returns
        -------
        u, refs, converged, fraction
            The projected point, the PoI references there, whether the tolerance was met, and the fraction of the
            move that was kept (1 unless a shorter move had to be taken).
        """
        for fraction in (1.0, 0.5, 0.25, 0.125):
            target = u_moved * fraction
            for pieces in (1, 2, 4, 8):
                result = self._continuation(target, pieces)
                if result is not None:
                    return result[0], result[1], True, fraction
        return np.zeros_like(u_moved), dict(self._refs), False, 0.0

    def _continuation(self, target: np.ndarray, pieces: int):
        refs = dict(self._refs)
        u = np.zeros_like(target)
        for j in range(1, pieces + 1):
            starts = [u + target / pieces]
            if j == pieces:
                starts.insert(0, target)
            for start in starts:
                projected, norm, ok = self._gauss_newton(start, refs)
                if ok:
                    break
            if not ok:
                return None
            u = projected
            features = self._features(u[None, :], refs)
            if any(f["lost"][0] for f in features.values()):
                return None
            refs = {key: self._updated_ref(ref, features[key]) for key, ref in refs.items()}
        return u, refs

    def _gauss_newton(self, u: np.ndarray, refs: Mapping[int, LocalPoI], iterations: int = 20, tol: float = 1e-5):
        def residual(U):
            return self._residuals(U, refs)

        if not self._feasible_u(u[None, :])[0]:
            return u, np.inf, False
        r = residual(u[None, :])[0]
        norm = float(np.linalg.norm(r))
        if not np.isfinite(norm):
            return u, np.inf, False
        alphas = 0.5 ** np.arange(8)
        for _ in range(iterations):
            if norm < tol:
                break
            r0, J = jacobian(residual, u, step=0.005)
            if not np.all(np.isfinite(J)):
                break
            step = -np.linalg.pinv(J, rcond=1e-8) @ r0
            candidates = u[None, :] + alphas[:, None] * step[None, :]
            feasible = self._feasible_u(candidates)
            norms = np.full(len(alphas), np.inf)
            if feasible.any():
                norms[feasible] = np.linalg.norm(residual(candidates[feasible]), axis=1)
            norms = np.where(np.isfinite(norms), norms, np.inf)
            best = int(np.argmin(norms))
            if not norms[best] < norm:
                break
            u, norm = candidates[best], float(norms[best])
        return u, norm, norm < 1e-3


__all__ = ["ERROR_UNIT", "Explorer", "MoveResult", "ReleaseResult", "Slider"]
