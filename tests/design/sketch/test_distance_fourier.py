"""Procrustes distance (Eq. 3.13) over direction and start point, spectrum bank, Fourier radii (Eq. 3.6)."""

from __future__ import annotations

import numpy as np
import pytest

from design.sketch.distance import SpectrumBank, low_spectrum, procrustes_distance_direct
from design.sketch.fourier import estimate_symmetry, radii_from_frequencies, radii_hypotheses, spectrum


def trochoid(r_f: int, r_r: int, d: float, n: int = 1024, start: float = 0.0) -> np.ndarray:
    t = start + np.linspace(0, 2 * np.pi * r_r, n, endpoint=False)
    z = (r_f - r_r) * np.exp(1j * t) + d * np.exp(-1j * (r_f / r_r - 1) * t)
    return np.column_stack([z.real, z.imag])


def similarity(points, angle=0.7, scale=3.0, shift=(5.0, -2.0)):
    c, s = np.cos(angle), np.sin(angle)
    return points @ (scale * np.array([[c, -s], [s, c]])).T + shift


def test_distance_is_invariant_to_similarity_direction_and_start():
    a = trochoid(5, 3, 1.5)
    b = similarity(np.roll(a, 137, axis=0)[::-1])
    direct = procrustes_distance_direct(a, b[None])
    assert direct[0] < 1e-10
    bank = SpectrumBank(low_spectrum(b[None], 160))
    match = bank.match(low_spectrum(a, 160))
    assert match.distance[0] < 1e-3
    assert bool(match.reversed[0])
    # without the start-point search the thesis' two-term distance misses the match
    assert procrustes_distance_direct(a, b[None], start_point=False)[0] > 0.1


def test_distance_is_symmetric_and_ranks_the_true_curve_first():
    curves = np.stack([trochoid(5, 3, d) for d in (0.5, 1.0, 1.5, 2.5)] + [trochoid(7, 2, 1.0)])
    query = similarity(trochoid(5, 3, 1.4, start=0.3))
    bank = SpectrumBank(low_spectrum(curves, 160))
    match = bank.match(low_spectrum(query, 160))
    assert int(np.argmin(match.distance)) == 2
    direct = procrustes_distance_direct(query, curves)
    assert np.allclose(match.distance, direct, atol=2e-3)  # low-passed equals full resolution for smooth curves
    ab = procrustes_distance_direct(curves[0], curves[1][None])[0]
    ba = procrustes_distance_direct(curves[1], curves[0][None])[0]
    assert ab == pytest.approx(ba, abs=1e-9)


def test_mirror_option():
    a = trochoid(5, 2, 1.2)
    mirrored = a * [1, -1]
    bank = SpectrumBank(low_spectrum(np.stack([mirrored]), 64))
    q = low_spectrum(trochoid(5, 2, 1.2, start=0.4), 64)
    assert bank.match(q, mirror=True).distance[0] < 1e-3
    # a trochoid is mirror-symmetric, so even without mirror it matches; check a chiral curve instead
    t = np.linspace(0, 2 * np.pi, 512, endpoint=False)
    z = np.exp(1j * t) + 0.4 * np.exp(3j * t) + 0.3 * np.exp(-2j * t + 0.5j)
    chiral = np.column_stack([z.real, z.imag])
    bank = SpectrumBank(low_spectrum(np.stack([chiral * [1, -1]]), 64))
    q = low_spectrum(chiral, 64)
    assert bank.match(q, mirror=False).distance[0] > 0.01
    assert bank.match(q, mirror=True).distance[0] < 1e-3


def test_eq_3_6_examples():
    # Figure 3.8: a Hoot-Nanny with peaks (-3, 1, 3) has radii (4, 3, 2)
    assert radii_from_frequencies([-3, 1, 3]) == (4, 3, 2)
    # epitrochoid / hypotrochoid: f1 = r_r, f2 = r_r - r_f
    assert radii_from_frequencies([3, 3 - 5]) == (5, 3)
    assert radii_from_frequencies([0, 2]) is None


def test_spectrum_gives_the_trochoid_radii_and_symmetry():
    curve = trochoid(7, 3, 1.0, n=1024)
    spec = spectrum(curve)
    assert set(spec.peaks[:2].tolist()) == {3, -4}
    assert estimate_symmetry(spec) == 7
    hypotheses = radii_hypotheses(spec, 2)
    assert (7, 3) in [h.radii for h in hypotheses]
    # ambiguous fundamental: both assignments are tried
    assert (7, 4) in [h.radii for h in hypotheses]
    with_symmetry = radii_hypotheses(spec, 2, symmetry=7)
    assert all(h.radii[0] == 7 for h in with_symmetry)
    wrong = radii_hypotheses(spec, 2, symmetry=5)
    assert [h.radii for h in wrong] == [(5, None)]  # nothing agrees: the leading radius only


def test_three_gear_hypotheses_try_both_orders():
    t = np.linspace(0, 2 * np.pi, 1024, endpoint=False)
    z = np.exp(-3j * t) + 0.5 * np.exp(1j * t) + 0.4 * np.exp(3j * t)
    spec = spectrum(np.column_stack([z.real, z.imag]))
    radii = [h.radii for h in radii_hypotheses(spec, 3)]
    assert (4, 3, 2) in radii and (4, 2, 3) in radii
