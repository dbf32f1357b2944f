"""Designs drawn uniformly over a machine's feasible space with its gear radii fixed, many radii at once.

The feasible set of the continuous parameters (radii fixed) is a thin, oddly shaped part of their box, so plain
rejection sampling from the box finds few designs for some radii. Here each radii combination starts from a few
designs found by rejection (a *pilot*) within the machine's :meth:`sampling_box` (a box that holds the feasible
set, tightened by the constraints that bound one parameter by the radii), then runs Markov chains that update one
continuous parameter at a time: ``tries`` values are drawn uniformly over the parameter's side of that box, and
the chain moves to one picked uniformly among the feasible ones and its current value. Given the feasible ones,
the current value is exchangeable with them, so the move keeps the uniform distribution over the feasible set: the
parameter is drawn uniformly over its feasible values given the others (a Gibbs sampler for the uniform
distribution), and chains may jump between disconnected parts of the feasible set. Everything is vectorized over
chains and radii (one :meth:`feasible_mask` call per parameter and sweep).
"""

from __future__ import annotations

import numpy as np

from common.progress import Reporter


def uniform_feasible(machine, radii: np.ndarray, roles: tuple[str, ...], per_combination: int,
                     rng: np.random.Generator, pilot: int = 2048, sweeps: int = 3, tries: int = 12,
                     report: Reporter | None = None) -> tuple[np.ndarray, np.ndarray]:
    """``per_combination`` designs per radii combination, uniform over its feasible continuous parameters.

    Parameters
    ----------
    machine : DrawingMachine
        The model.
    radii : ndarray
        ``(C, G)`` integer radii, columns in the order of ``roles``.
    roles : tuple of str
        The radii's parameter names.
    per_combination : int
        Designs (chains) per combination.
    rng : numpy Generator
        Seeded source of randomness.
    pilot : int
        Rejection draws per combination for the chains' starting designs; a combination with no feasible draw is
        left out (its feasible set is then a sliver of the box, under ``1 / pilot`` of it).
    sweeps : int
        Updates of every continuous parameter of every chain.
    tries : int
        Values drawn per update.
    report : Reporter, optional
        Told ``("sampling", done, total, message)`` per sweep.

    Returns
    -------
    params : ndarray
        ``(M, P)`` designs, columns in :attr:`machine.parameter_names`.
    combination : ndarray
        ``(M,)`` the row of ``radii`` each design has.
    """
    names = list(machine.parameter_names)
    continuous = [names.index(n) for n in machine.continuous_names]
    radius_columns = [names.index(r) for r in roles]
    radii = np.asarray(radii, dtype=float).reshape(len(radii), len(roles))
    box = machine.sampling_box({r: radii[:, i] for i, r in enumerate(roles)})
    lows = np.column_stack([box[n][0] for n in machine.continuous_names])  # (C, n_continuous)
    highs = np.column_stack([box[n][1] for n in machine.continuous_names])

    # pilot: rejection from the box, in chunks of combinations to bound memory
    starts, owners = [], []
    chunk = max(1, 2_000_000 // max(pilot, 1))
    for begin in range(0, len(radii), chunk):
        block = radii[begin : begin + chunk]
        rows = np.zeros((len(block) * pilot, len(names)))
        rows[:, radius_columns] = np.repeat(block, pilot, axis=0)
        lo = np.repeat(lows[begin : begin + chunk], pilot, axis=0)
        hi = np.repeat(highs[begin : begin + chunk], pilot, axis=0)
        rows[:, continuous] = lo + rng.random(lo.shape) * (hi - lo)
        ok = machine.feasible_mask(rows).reshape(len(block), pilot)
        for i, mask in enumerate(ok):
            found = np.flatnonzero(mask)
            if found.size:
                picks = rng.choice(found, per_combination, replace=found.size < per_combination)
                starts.append(rows[i * pilot + picks])
                owners.append(np.full(per_combination, begin + i))
    if not starts:
        return np.zeros((0, len(names))), np.zeros(0, dtype=np.int64)
    chains = np.concatenate(starts)
    owner = np.concatenate(owners)
    total = sweeps * len(continuous)
    for sweep in range(sweeps):
        for step, column in enumerate(continuous):
            trial = np.repeat(chains, tries, axis=0)
            lo = np.repeat(lows[owner, step], tries)
            hi = np.repeat(highs[owner, step], tries)
            trial[:, column] = lo + rng.random(len(trial)) * (hi - lo)
            ok = machine.feasible_mask(trial).reshape(len(chains), tries)
            # the current value counts as one more feasible choice: pick uniformly among the 1 + ok.sum() values
            counts = ok.sum(axis=1)
            pick = np.floor(rng.random(len(chains)) * (counts + 1)).astype(np.int64)
            move = pick < counts
            ranks = np.cumsum(ok, axis=1) - 1
            chosen = np.argmax(ok & (ranks == pick[:, None]), axis=1)
            values = trial[:, column].reshape(len(chains), tries)[np.arange(len(chains)), chosen]
            chains[move, column] = values[move]
            if report is not None:
                done = sweep * len(continuous) + step + 1
                report("sampling", done, total, f"{machine.name}: sampling designs {done}/{total}")
    return chains, owner


__all__ = ["uniform_feasible"]
