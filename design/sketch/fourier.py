"""Search-space pruning from the spectrum of the sketch (thesis, section 3.4.2, Eq. 3.3-3.6).

The closed curve is resampled at ``N_f`` points over one period and read as complex numbers; its DFT has peaks at
integer frequencies (the period is set to 1, Eq. 3.5). The fundamental ``f1`` is found by an autocorrelation of
the peaks (the spectrum is symmetric around it), the other dominant frequencies ``f2`` (and ``f3``) are the next
highest peaks (``f3`` not a harmonic of ``f2``), and gear radii follow from Eq. 3.6:

    r_i = lcm(n_1, ..., n_G) / n_i,   n_1 = |f1|,  n_i = |f_i - f1|.

The symmetry order, when given, is the leading radius ``r_1``. Ambiguities are kept as several hypotheses (the two
highest peaks can each be the fundamental; ``r_2`` and ``r_3`` can be swapped); a radius whose peak is too weak is
left free (``None``) and sampled.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from design.sketch.distance import as_complex

#: A peak weaker than this fraction of the highest one is noise.
PEAK_THRESHOLD = 0.04
#: At most this many peaks take part in the analysis.
MAX_PEAKS = 12


@dataclass(frozen=True)
class Spectrum:
    """Frequency spectrum of a closed curve over one period (period set to 1, so frequencies are integers).

    Attributes
    ----------
    frequencies : ndarray
        ``(N,)`` integer frequencies ``-N/2 .. N/2 - 1``.
    magnitudes : ndarray
        ``(N,)`` ``|Z_k|`` with the constant term set to 0, normalized so that the highest peak is 1.
    peaks : ndarray
        Frequencies of the dominant peaks, strongest first.
    """

    frequencies: np.ndarray
    magnitudes: np.ndarray
    peaks: np.ndarray

    def magnitude(self, frequency: int) -> float:
        """Normalized magnitude at one integer frequency (0 outside the range)."""
        n = len(self.frequencies)
        if not -n // 2 <= frequency < n // 2:
            return 0.0
        return float(self.magnitudes[frequency + n // 2])


def spectrum(curve: np.ndarray, threshold: float = PEAK_THRESHOLD) -> Spectrum:
    """DFT (Eq. 3.3) of a closed curve sampled at ``N`` points over one period, with its dominant peaks.

    Parameters
    ----------
    curve : ndarray
        ``(N, 2)`` points or ``(N,)`` complex numbers, uniformly spaced over one period, first point not repeated.
    threshold : float
        Peaks weaker than this fraction of the strongest are ignored.
    """
    z = as_complex(curve)
    n = len(z)
    coefficients = np.fft.fftshift(np.fft.fft(z))
    frequencies = np.arange(-(n // 2), n - n // 2)
    magnitudes = np.abs(coefficients)
    magnitudes[frequencies == 0] = 0.0  # the constant term only places the curve
    top = magnitudes.max()
    if top > 0:
        magnitudes = magnitudes / top
    padded = np.concatenate([[0.0], magnitudes, [0.0]])
    local_max = (padded[1:-1] >= padded[:-2]) & (padded[1:-1] >= padded[2:]) & (magnitudes >= threshold)
    candidates = np.flatnonzero(local_max)
    strongest = candidates[np.argsort(-magnitudes[candidates], kind="stable")][:MAX_PEAKS]
    return Spectrum(frequencies, magnitudes, frequencies[strongest])


def fundamental_candidates(spec: Spectrum, count: int = 2) -> list[int]:
    """Candidate fundamentals ``f1``: the centre of symmetry of the peaks by autocorrelation, then the strongest.

    The discrete convolution of the peak spectrum with itself is largest at twice the centre around which the peaks
    are symmetric; when that centre is a peak it is the fundamental (thesis, section 3.4.2).
    """
    n = len(spec.frequencies)
    peak_spectrum = np.zeros(n)
    index = spec.peaks + n // 2
    peak_spectrum[index] = spec.magnitudes[index]
    correlation = np.convolve(peak_spectrum, peak_spectrum)  # index i <-> frequency sum i - 2 * (n // 2)
    found: list[int] = []
    for i in np.argsort(-correlation, kind="stable")[: 4 * count]:
        total = int(i) - 2 * (n // 2)
        if total % 2 == 0 and total // 2 in set(spec.peaks.tolist()) and total // 2 != 0:
            if total // 2 not in found:
                found.append(total // 2)
        if len(found) >= count:
            break
    for f in spec.peaks.tolist():
        if len(found) >= count:
            break
        if f not in found:
            found.append(int(f))
    return found


def radii_from_frequencies(frequencies: list[int]) -> tuple[int, ...] | None:
    """Eq. 3.6: gear radii from the fundamental and the other dominant frequencies (``None`` if degenerate)."""
    f1 = frequencies[0]
    counts = [abs(f1)] + [abs(f - f1) for f in frequencies[1:]]
    if any(c == 0 for c in counts):
        return None
    common = math.lcm(*counts)
    radii = [common // c for c in counts]
    divisor = math.gcd(*radii)
    return tuple(r // divisor for r in radii)


@dataclass(frozen=True)
class RadiiHypothesis:
    """Radii of the gears ``(r_1, r_2[, r_3])`` suggested by the spectrum; ``None`` = free (sampled).

    ``support`` is the product of the normalized magnitudes of the peaks used (higher is more credible).
    """

    radii: tuple[int | None, ...]
    support: float
    frequencies: tuple[int, ...] = field(default=())


def radii_hypotheses(
    spec: Spectrum, n_gears: int, symmetry: int | None = None, max_hypotheses: int = 8
) -> list[RadiiHypothesis]:
    """Hypotheses on the radii of an ``n_gears``-gear machine (2 or 3) from a spectrum.

    Parameters
    ----------
    spec : Spectrum
        The sketch's spectrum.
    n_gears : int
        2 (Spirograph, elliptic Spirograph, Cycloid Drawing Machine) or 3 (Hoot-Nanny).
    symmetry : int, optional
        The known rotational symmetry order: the leading radius ``r_1``.
    max_hypotheses : int
        Most hypotheses returned (best supported first).
    """
    if n_gears not in (2, 3):
        raise ValueError(f"radii hypotheses: n_gears must be 2 or 3, got {n_gears}")
    peaks = [int(f) for f in spec.peaks]
    hypotheses: dict[tuple, RadiiHypothesis] = {}

    def add(radii: tuple[int | None, ...], support: float, freqs: tuple[int, ...]) -> None:
        if symmetry is not None and radii[0] is not None and radii[0] != symmetry:
            return
        old = hypotheses.get(radii)
        if old is None or old.support < support:
            hypotheses[radii] = RadiiHypothesis(radii, support, freqs)

    fundamentals = fundamental_candidates(spec, count=3)
    for f1 in fundamentals:
        m1 = spec.magnitude(f1)
        seconds = [f for f in peaks if f != f1][:4]
        for f2 in seconds:
            m2 = spec.magnitude(f2)
            pair = radii_from_frequencies([f1, f2])
            if pair is None:
                continue
            if n_gears == 2:
                add(pair, m1 * m2, (f1, f2))
                continue
            step = f2 - f1
            thirds = [f for f in peaks if f not in (f1, f2) and (f - f1) % step != 0][:3]
            for f3 in thirds:
                triple = radii_from_frequencies([f1, f2, f3])
                if triple is None:
                    continue
                support = m1 * m2 * spec.magnitude(f3)
                add(triple, support, (f1, f2, f3))
                add((triple[0], triple[2], triple[1]), support, (f1, f3, f2))  # r2 / r3 order is ambiguous
            # f3 too weak (or a harmonic of f2): r_3 stays free, in either slot
            weak = 0.5 * m1 * m2 * PEAK_THRESHOLD
            add((pair[0], pair[1], None), weak, (f1, f2))
            add((pair[0], None, pair[1]), weak, (f1, f2))
    if symmetry is not None:
        # The leading radius is known even when no second peak is usable: the others are sampled.
        add((symmetry,) + (None,) * (n_gears - 1), 0.0, ())
    ranked = sorted(hypotheses.values(), key=lambda h: -h.support)
    return ranked[:max_hypotheses]


def estimate_symmetry(spec: Spectrum, max_order: int = 32) -> int:
    """The rotational symmetry order suggested by the spectrum: the gcd of the differences between dominant peaks.

    A curve with ``k``-fold symmetry only has frequencies ``f = f1 (mod k)``.
    """
    peaks = [int(f) for f in spec.peaks[:6]]
    if len(peaks) < 2:
        return 1
    g = 0
    for f in peaks[1:]:
        g = math.gcd(g, f - peaks[0])
    return int(min(max(g, 1), max_order))
