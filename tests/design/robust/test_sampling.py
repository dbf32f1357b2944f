"""Drawing valid layouts: the same layouts as checking every candidate, with fewer validity checks."""

from __future__ import annotations

import dataclasses

import numpy as np
from scipy.stats import qmc

from design.robust import synthetic_chain
from design.robust.sampling import sobol_valid


@dataclasses.dataclass(frozen=True)
class CountingChain:
    """synthetic_chain (one layout in eight impossible) counting the layouts its validity check is asked about."""

    inner: object
    checked: list

    def __getattr__(self, name):
        return getattr(self.inner, name)

    def is_valid(self, U):
        self.checked.append(len(U))
        return self.inner.is_valid(U)


def test_sobol_valid_keeps_the_first_valid_points_and_checks_only_what_it_needs():
    problem = CountingChain(synthetic_chain(), [])
    n, seed = 512, 4
    # The reference: the whole first batch (2n points, a power of two) checked, its first n valid points kept.
    batch = qmc.Sobol(d=3, scramble=True, seed=seed).random_base2(int(np.ceil(np.log2(2 * n))))
    valid = batch[problem.inner.is_valid(batch)]
    assert len(valid) >= n and len(valid) < len(batch)
    reports = []
    U = sobol_valid(problem, n, seed, on_checked=lambda checked, kept: reports.append((checked, kept)))
    np.testing.assert_array_equal(U, valid[:n])
    # Most of this design space is valid: about n / 0.9 candidates are checked, not all 2n of the batch.
    assert sum(problem.checked) < 1.5 * n
    assert reports[-1] == (sum(problem.checked), n)
    assert [c for c, _ in reports] == sorted(c for c, _ in reports) and len(reports) > 4
