"""Cycloid Drawing Machine (A.2.3) and Hoot-Nanny (A.2.4): kinematics, Eq. 3.6 on their spectra, constraints."""

from __future__ import annotations

import math

import numpy as np
import pytest

from design.errors import ConstraintViolation
from design.machines import get_machine
from design.machines.hoot_nanny import triangle_apex

cdm = get_machine("cycloid_drawing_machine")
hoot = get_machine("hoot_nanny")

CDM_DESIGNS = [
    cdm.defaults(),
    {"r_t": 10, "r_e": 3, "d_tf": 12.0, "theta_te": 2.1, "r_s": 2.8, "d_fh": 15.5},
    {"r_t": 11, "r_e": 4, "d_tf": 13.0, "theta_te": 1.9, "r_s": 3.2, "d_fh": 12.5},
]
HOOT_DESIGNS = [
    hoot.defaults(),
    {"r_t": 4, "r_g1": 3, "r_g2": 2, "theta_12": 1.38, "r_p1": 2.8, "r_p2": 1.85, "l1": 7.32, "l2": 6.69},
    {"r_t": 7, "r_g1": 3, "r_g2": 2, "theta_12": 1.14, "r_p1": 2.9, "r_p2": 1.9, "l1": 9.85, "l2": 9.58},
    {"r_t": 9, "r_g1": 4, "r_g2": 5, "theta_12": 1.53, "r_p1": 3.98, "r_p2": 4.78, "l1": 15.57, "l2": 14.8},
]


def spectrum(machine, design, n=4096):
    """|Z_k| of the centered curve sampled uniformly in time over one period (Eq. 3.3, 3.5 with T = 1)."""
    points = machine.sample(design, n + 1)[:-1]
    z = points[:, 0] + 1j * points[:, 1]
    amplitude = np.abs(np.fft.fft(z - z.mean())) / n
    frequency = np.rint(np.fft.fftfreq(n, 1.0 / n)).astype(int)
    return frequency, amplitude


def radii_from_frequencies(f):
    """Eq. 3.6: r_i = lcm(n) / n_i with n_1 = |f_1| and n_i = |f_i - f_1|."""
    n = [abs(f[0])] + [abs(fi - f[0]) for fi in f[1:]]
    multiple = math.lcm(*n)
    return [multiple // ni for ni in n]


def dominant_frequencies(frequency, amplitude, count):
    """Fundamental and gear frequencies, detected as in thesis 3.4.2.

    The spectrum is symmetric about the fundamental f_1, which need not be the highest peak: f_1 is the center of
    symmetry found by autocorrelating the peaks (convolving the spectrum with itself). Then f_2 is the highest other
    peak, f_3 the highest one that is not f_1 plus a multiple of f_2 - f_1 (a harmonic of f_2), and so on.
    """
    order = np.argsort(frequency)
    f_sorted, a_sorted = frequency[order], amplitude[order]
    correlation = np.convolve(a_sorted, a_sorted)  # index i + j <-> frequency f_i + f_j
    sums = np.arange(correlation.size) + 2 * f_sorted[0]
    even = sums % 2 == 0
    f1 = int(sums[even][np.argmax(correlation[even])] // 2)
    found = [f1]
    for index in np.argsort(amplitude)[::-1]:
        f = int(frequency[index])
        offset = f - f1
        if offset == 0 or any(offset % (g - f1) == 0 for g in found[1:]):
            continue
        found.append(f)
        if len(found) == count:
            break
    return found


@pytest.mark.parametrize("design", CDM_DESIGNS)
def test_cycloid_spectrum_obeys_eq_3_6(design):
    frequency, amplitude = spectrum(cdm, design)
    f = dominant_frequencies(frequency, amplitude, 2)
    turns = cdm.turns(design)
    assert f[0] == -turns  # the turntable's turns: the paper turns under a pen that oscillates around a point
    assert radii_from_frequencies(f) == [design["r_t"], design["r_e"]]
    # Every peak is the fundamental plus a whole number of the external gear's turns.
    gear_turns = turns * design["r_t"] // design["r_e"]
    significant = frequency[amplitude > 1e-6 * amplitude.max()]
    assert np.all((significant - f[0]) % gear_turns == 0)


@pytest.mark.parametrize("design", HOOT_DESIGNS)
def test_hoot_nanny_spectrum_obeys_eq_3_6(design):
    frequency, amplitude = spectrum(hoot, design)
    f = dominant_frequencies(frequency, amplitude, 3)
    radii = radii_from_frequencies(f)
    assert f[0] == -hoot.turns(design)
    # The order of r_g1 and r_g2 is ambiguous from the spectrum alone (thesis 3.4.2).
    assert radii[0] == design["r_t"]
    assert sorted(radii[1:]) == sorted([design["r_g1"], design["r_g2"]])


def test_hoot_nanny_figure_3_8_frequencies():
    """Figure 3.8: radii (4, 3, 2); peaks at -3 (fundamental), -3 + 4 = 1 and -3 + 6 = 3 (or their mirrors)."""
    frequency, amplitude = spectrum(hoot, HOOT_DESIGNS[1])
    f1, f2, f3 = dominant_frequencies(frequency, amplitude, 3)
    assert f1 == -3
    assert f2 in (1, -7) and f3 in (3, -9)
    assert radii_from_frequencies([f1, f2, f3]) == [4, 3, 2]


@pytest.mark.parametrize("machine, designs", [(cdm, CDM_DESIGNS), (hoot, HOOT_DESIGNS)])
def test_symmetry_order(machine, designs):
    for design in designs:
        order = machine.symmetry_order(design)
        period = machine.period(design)
        t = np.linspace(0, period, 500)
        for shift in range(1, order + 1):
            # Some time shift maps the pattern onto itself rotated by shift / order of a turn.
            rotated = machine.curve(design, t) @ _rotation(2 * np.pi * shift / order).T
            shifts = np.linspace(0, period, 4 * machine.turns(design) * order + 1)[:-1]
            best = min(np.abs(machine.curve(design, t + s) - rotated).max() for s in shifts)
            assert best < 1e-9 * design["r_t"]


def _rotation(angle):
    return np.array([[np.cos(angle), -np.sin(angle)], [np.sin(angle), np.cos(angle)]])


def test_drawing_bounds_hold_on_sampled_curves_of_random_feasible_designs():
    rng = np.random.default_rng(7)
    for machine in (cdm, hoot):
        rows = {}
        k = 100000
        for parameter in machine.parameters:
            if parameter.kind == "discrete":
                rows[parameter.name] = rng.integers(2, 12, k)
            else:
                rows[parameter.name] = rng.uniform(parameter.lower, min(parameter.upper, 20.0), k)
        ok = machine.feasible_mask(rows)
        assert ok.sum() > 20
        chosen = {name: values[ok][:200] for name, values in rows.items()}
        points = machine.sample_many(chosen, 1500, check=False)
        radius = np.hypot(points[..., 0], points[..., 1]).max(axis=1)
        assert np.all(radius < chosen["r_t"])
        assert np.isfinite(points).all()


def test_hoot_nanny_arms_always_close_the_triangle():
    rng = np.random.default_rng(3)
    k = 20000
    rows = {
        "r_t": rng.integers(3, 12, k), "r_g1": rng.integers(1, 8, k), "r_g2": rng.integers(1, 8, k),
        "theta_12": rng.uniform(0, np.pi, k), "r_p1": rng.uniform(0, 7, k), "r_p2": rng.uniform(0, 7, k),
        "l1": rng.uniform(0, 30, k), "l2": rng.uniform(0, 30, k),
    }  # fmt: skip
    ok = hoot.feasible_mask(rows)
    P = {name: values[ok][:300, None] for name, values in rows.items()}
    t = hoot._period(P) * np.linspace(0, 1, 1000)[None, :]
    _, _, p1, p2, pen = hoot._fixed_frame(P, t)
    base = np.abs(p1 - p2)
    cos_alpha = (P["l2"] ** 2 + base**2 - P["l1"] ** 2) / (2 * P["l2"] * base)
    assert np.abs(cos_alpha).max() < 1
    np.testing.assert_allclose(np.abs(pen - p1), np.broadcast_to(P["l1"], pen.shape), rtol=1e-9)
    np.testing.assert_allclose(np.abs(pen - p2), np.broadcast_to(P["l2"], pen.shape), rtol=1e-9)


def test_triangle_apex_is_on_the_turntable_side():
    apex = triangle_apex(np.array(5 + 0j), np.array(5j), np.array(5.0), np.array(5.0))
    assert abs(apex) < 1e-12  # the two circles meet at the origin and at 5 + 5j; the pen takes the origin


def test_cycloid_kinematics_by_hand():
    design = cdm.defaults()
    t = 0.9
    gear = (design["r_t"] + design["r_e"]) * np.exp(1j * design["theta_te"])
    slider = gear + design["r_s"] * np.exp(-1j * design["r_t"] / design["r_e"] * t)
    pen = design["d_tf"] + design["d_fh"] * (slider - design["d_tf"]) / abs(slider - design["d_tf"])
    expected = pen * np.exp(-1j * t)
    np.testing.assert_allclose(cdm.curve(design, [t])[0], [expected.real, expected.imag], atol=1e-12)
    # The exact drawing bound equals the sampled maximum radius.
    from design.machines.cycloid_drawing_machine import farthest_pen_distance

    points = cdm.sample(design, 20001)
    bound = float(farthest_pen_distance({k: np.float64(v) for k, v in design.items()}))
    assert np.hypot(*points.T).max() == pytest.approx(bound, rel=1e-6)


CDM_CASES = [
    ("fulcrum_outside_turntable", {"d_tf": 6.5}, "d_tf must exceed r_t = 7"),
    ("pen_offset_positive", {"d_fh": 0.0}, "d_fh must be greater than 0"),
    ("pen_before_gear", {"d_fh": 14.8}, "d_fh must be smaller than d_fe - r_e = 14.6549"),
    ("slider_inside_gear", {"r_s": 4.5}, "r_s must be smaller than r_e = 4, got 4.5"),
    ("coprime_radii", {"r_t": 8}, "gcd(8, 4) = 4"),
    ("pen_on_turntable", {"d_fh": 1.0}, "must be below r_t = 7, got 8.19315"),
]


def test_cdm_cases_cover_every_named_constraint():
    box = {c.name for c in cdm._box_constraints()}
    assert {case[0] for case in CDM_CASES} == {c.name for c in cdm.all_constraints()} - box


@pytest.mark.parametrize("constraint, params, message", CDM_CASES)
def test_cycloid_each_constraint_raises(constraint, params, message):
    with pytest.raises(ConstraintViolation) as info:
        cdm.validate(params)
    assert info.value.constraint == constraint
    assert message in str(info.value)


HOOT_CASES = [
    ("pivot1_inside_gear", {"r_p1": 3.2}, "r_p1 must be smaller than r_g1 = 3, got 3.2"),
    ("pivot2_inside_gear", {"r_p2": 2.5}, "r_p2 must be smaller than r_g2 = 2, got 2.5"),
    ("gears_apart", {"theta_12": 0.3}, "|G1G2| = 3.86458 must exceed r_g1 + r_g2 = 5"),
    ("arm1_long_enough", {"l1": 5.0}, "l1 must exceed r_g1 + r_p1 = 5.8, got 5"),
    ("arm1_short_enough", {"l1": 20.5}, "l1 must be below 2 r_t + r_g1 - r_p1 = 20.2, got 20.5"),
    ("arm2_long_enough", {"l2": 3.0}, "l2 must exceed r_g2 + r_p2 = 3.8, got 3"),
    ("arm2_short_enough", {"l2": 20.5}, "l2 must be below 2 r_t + r_g2 - r_p2 = 20.2, got 20.5"),
    ("coprime_radii", {"r_t": 8, "r_g1": 4, "r_g2": 2}, "gcd(8, 4, 2) = 2"),
    ("arms_reach", {"l1": 10.0, "l2": 6.0}, "l1 + l2 must exceed |G1G2| + r_p1 + r_p2 = 18.7402, got 16"),
    ("arms_not_folded", {"l1": 16.0, "l2": 4.5}, "|l1 - l2| must be below |G1G2| - r_p1 - r_p2 = 9.54017"),
    ("pen_on_turntable", {"l1": 15.5}, "within r_t = 10 of the turntable's center, got 11.8045"),
]


def test_hoot_cases_cover_every_named_constraint():
    box = {c.name for c in hoot._box_constraints()}
    assert {case[0] for case in HOOT_CASES} == {c.name for c in hoot.all_constraints()} - box


@pytest.mark.parametrize("constraint, params, message", HOOT_CASES)
def test_hoot_nanny_each_constraint_raises(constraint, params, message):
    with pytest.raises(ConstraintViolation) as info:
        hoot.validate(params)
    assert info.value.constraint == constraint
    assert message in str(info.value)


def test_hoot_nanny_pairwise_common_divisors_are_allowed():
    # Figure 3.8's radii (4, 3, 2): r_t and r_g2 share 2, but the three share nothing.
    assert hoot.is_feasible(HOOT_DESIGNS[1])
    assert hoot.period(HOOT_DESIGNS[1]) == pytest.approx(2 * np.pi * 3)


def test_affine_slider_bounds_are_exact():
    _, hi = hoot.feasible_interval(hoot.defaults(), "r_p1")  # strict r_p1 < r_g1 = 3 (A.58)
    assert hi == np.nextafter(3.0, 0.0)
    lo, _ = cdm.feasible_interval(cdm.defaults(), "d_tf")  # strict d_tf > r_t = 7 (A.42)
    assert lo == np.nextafter(7.0, 8.0)
    _, hi = cdm.feasible_interval(cdm.defaults(), "r_s")  # strict r_s < r_e = 4 (A.44)
    assert hi == np.nextafter(4.0, 0.0)
    # Non-affine ends (here the drawing bound A.67) are bracketed: feasible, and infeasible just outside.
    lo, _ = hoot.feasible_interval(hoot.defaults(), "l1")
    assert hoot.violations(hoot.defaults() | {"l1": lo - 1e-9})[0].constraint == "pen_on_turntable"
