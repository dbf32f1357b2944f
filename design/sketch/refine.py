"""Refinement of candidates' continuous parameters, many candidates at once (thesis 3.4: sampling, then refinement).

The database holds a few designs per gear radii; the sketched design lies between them. Each candidate's continuous
parameters (radii fixed) are improved by a (1 + lambda) evolution strategy on the retrieval's own distance: each
round, ``offspring`` designs are drawn around the current one (Gaussian steps, a fraction ``step`` of the
machine's :meth:`sampling_box` per parameter), infeasible ones are dropped, the curves of all candidates' offspring
are sampled and compared in one batch, and a candidate moves to its best offspring when it is closer to the sketch
(the step grows by 1.5); otherwise the step shrinks by 0.5. A candidate never gets worse and stays feasible.
Seeded: the same query refines the same way.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace

import numpy as np

from design.sketch.candidates import curve_spectra
from design.sketch.distance import SpectrumBank

#: Rounds, offspring per round and initial step (fraction of the sampling box) of the default refinement.
ROUNDS = 6
OFFSPRING = 10
STEP = 0.08


def refine_many(machine, candidates: Sequence, targets: np.ndarray, mirror: bool = False, rounds: int = ROUNDS,
                offspring: int = OFFSPRING, step: float = STEP, points: int = 512, seed: int = 0) -> list:
    """Refined copies of ``candidates`` (all of ``machine``), each at most as far from the sketch as before.

    Parameters
    ----------
    machine : DrawingMachine
        The candidates' machine.
    candidates : sequence of Candidate
        Their ``params`` hold the radii and the starting continuous parameters; ``distance`` the starting distance.
    targets : ndarray
        ``(V, 2K+1)`` low spectra of the sketch's readings; a design's distance is its smallest to any of them.
    mirror : bool
        Also match mirror images.
    rounds, offspring, step : int, int, float
        The evolution strategy's rounds, offspring per candidate and round, and initial step.
    points : int
        Points per curve (as the database).
    seed : int
        Seed of the steps.
    """
    names = list(machine.parameter_names)
    continuous = [names.index(n) for n in machine.continuous_names]
    if not candidates or not continuous:
        return list(candidates)
    targets = np.atleast_2d(targets)
    harmonics = targets.shape[1] // 2
    rng = np.random.default_rng(seed)
    current = np.array([[c.params[n] for n in names] for c in candidates], dtype=float)
    best = np.array([c.distance for c in candidates], dtype=float)
    radii = {n: current[:, names.index(n)] for n in machine.discrete_names}
    box = machine.sampling_box(radii)
    lows = np.column_stack([box[n][0] for n in machine.continuous_names])
    highs = np.column_stack([box[n][1] for n in machine.continuous_names])
    width = np.maximum(highs - lows, 1e-9)
    sigma = np.full(len(candidates), step)
    improved = np.zeros(len(candidates), dtype=bool)
    count = len(candidates)
    for _ in range(rounds):
        trial = np.repeat(current, offspring, axis=0)
        moves = rng.normal(size=(len(trial), len(continuous))) * np.repeat(sigma[:, None] * width, offspring, axis=0)
        trial[:, continuous] = np.clip(trial[:, continuous] + moves, np.repeat(lows, offspring, axis=0),
                                       np.repeat(highs, offspring, axis=0))
        ok = machine.feasible_mask(trial)
        distance = np.full(len(trial), np.inf)
        if ok.any():
            bank = SpectrumBank(curve_spectra(machine, trial[ok], points, harmonics))
            distance[ok] = np.min([bank.match(t, mirror=mirror).distance for t in targets], axis=0)
        distance = distance.reshape(count, offspring)
        pick = distance.argmin(axis=1)
        better = distance[np.arange(count), pick] < best
        current[better] = trial.reshape(count, offspring, -1)[np.flatnonzero(better), pick[better]]
        best[better] = distance[np.arange(count), pick][better]
        improved |= better
        sigma = np.where(better, sigma * 1.5, sigma * 0.5)
    discrete = set(machine.discrete_names)
    out = []
    for i, candidate in enumerate(candidates):
        if not improved[i]:
            out.append(candidate)
            continue
        params = {n: (int(round(v)) if n in discrete else float(v)) for n, v in zip(names, current[i])}
        out.append(replace(candidate, params=params, distance=float(best[i]), refined=True))
    return out


__all__ = ["refine_many"]
