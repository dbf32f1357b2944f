"""The symmetric Procrustes distance of Eq. 3.13, minimized over direction and start point, for many candidates.

Curves are closed, resampled uniformly in arc length to ``N`` points and written as complex numbers. After the usual
Procrustes normalization (centred, unit norm) the full Procrustes distance between ``a`` and ``b`` is

    min over complex c of  sum_n |a_n - c b_n|^2  =  1 - |<b, a>|^2,

(``c`` is the optimal rotation and scale) which is symmetric in ``a`` and ``b``. A closed curve has no start point,
so the distance is also minimized over the circular shifts ``s`` of ``b`` and over both directions (Eq. 3.13's two
terms). By Parseval the correlations for every shift are one FFT of the product of spectra:

    sum_n a_n conj(b_{n+s}) = FFT(A * conj(B))[s] / N,     reversed b: B_k -> B_{-k}.

A :class:`SpectrumBank` keeps only the low frequencies ``|k| <= K`` of each candidate, so the distances over all
candidates, shifts and both directions are one batched FFT of a short (zero-padded) length. This is the Procrustes
distance of the curves low-passed to ``K`` harmonics (exact when the curves have no energy above ``K``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.fft

from design.sketch.errors import SketchError

#: Points per curve (thesis, Table 3.1).
DEFAULT_POINTS = 1024
#: Harmonics kept per curve in a :class:`SpectrumBank`.
DEFAULT_HARMONICS = 128


def as_complex(curves: np.ndarray) -> np.ndarray:
    """``(..., N, 2)`` real points as ``(..., N)`` complex numbers."""
    curves = np.asarray(curves)
    if np.iscomplexobj(curves):
        return curves
    return curves[..., 0] + 1j * curves[..., 1]


def normalize(curves: np.ndarray) -> np.ndarray:
    """Procrustes normalization of ``(..., N)`` complex curves: centred, unit norm (degenerate curves become 0)."""
    z = as_complex(curves)
    z = z - z.mean(axis=-1, keepdims=True)
    norm = np.sqrt(np.sum(np.abs(z) ** 2, axis=-1, keepdims=True))
    return np.divide(z, norm, out=np.zeros_like(z), where=norm > 0)


def procrustes_distance_direct(a: np.ndarray, b: np.ndarray, start_point: bool = True) -> np.ndarray:
    """Eq. 3.13 at full resolution: ``a`` is one curve ``(N,)`` or ``(N, 2)``, ``b`` is ``(M, N[, 2])``.

    Minimizes over both directions and, with ``start_point``, over all ``N`` circular shifts (one length-``N`` FFT
    per candidate and direction). Returns ``(M,)`` distances in ``[0, 1]``.
    """
    a = normalize(a)
    b = normalize(b)
    if b.ndim == 1:
        b = b[None]
    if a.shape[-1] != b.shape[-1]:
        raise SketchError(
            f"procrustes distance: curves must have the same number of points, got {a.shape} and {b.shape}"
        )
    n = a.shape[-1]
    if not start_point:
        forward = np.abs(b.conj() @ a) ** 2
        backward = np.abs(b[:, ::-1].conj() @ a) ** 2
        return 1.0 - np.maximum(forward, backward)
    fa = np.fft.fft(a)
    fb = np.fft.fft(b, axis=-1)
    reversed_fb = np.roll(fb[:, ::-1], 1, axis=-1)  # spectrum of b[-n mod N]: B_{-k}
    forward = np.abs(np.fft.fft(fa * fb.conj(), axis=-1)).max(axis=-1) / n
    backward = np.abs(np.fft.fft(fa * reversed_fb.conj(), axis=-1)).max(axis=-1) / n
    return np.clip(1.0 - np.maximum(forward, backward) ** 2, 0.0, 1.0)


def low_spectrum(curves: np.ndarray, harmonics: int = DEFAULT_HARMONICS) -> np.ndarray:
    """Normalized curves' Fourier coefficients ``k = -K..K`` (``(..., 2K+1)`` complex, scaled so that the sum of
    squared moduli equals the curve's squared norm, i.e. 1)."""
    z = normalize(curves)
    n = z.shape[-1]
    if 2 * harmonics + 1 > n:
        raise SketchError(f"spectrum: {harmonics} harmonics need more than {2 * harmonics} points, got {n}")
    f = scipy.fft.fft(z, axis=-1) / np.sqrt(n)
    return np.concatenate([f[..., n - harmonics :], f[..., : harmonics + 1]], axis=-1)


@dataclass
class Match:
    """Best alignment of a candidate to the query: its distance, direction and start shift (fraction of a period)."""

    distance: np.ndarray
    reversed: np.ndarray
    shift: np.ndarray


class SpectrumBank:
    """Low-frequency spectra of many candidate curves, queried with one sketch curve at a time.

    Parameters
    ----------
    spectra : ndarray
        ``(M, 2K+1)`` complex coefficients from :func:`low_spectrum`.
    shifts : int
        Number of start points tried (FFT length, at least ``2K + 1``; default the next power of two). The curves'
        energy is in their low harmonics, so the sampled correlation's peak is within ~1e-6 of the distance found
        with 4 times more shifts (measured on the Cycloid Drawing Machine database).
    """

    def __init__(self, spectra: np.ndarray, shifts: int | None = None) -> None:
        spectra = np.asarray(spectra)
        if spectra.ndim != 2 or spectra.shape[1] % 2 == 0:
            raise SketchError(f"spectrum bank: expected (M, 2K+1) coefficients, got shape {spectra.shape}")
        self.spectra = spectra.astype(np.complex64, copy=False)
        self.harmonics = spectra.shape[1] // 2
        minimum = 2 * self.harmonics + 1
        self.shifts = int(shifts) if shifts is not None else int(2 ** np.ceil(np.log2(minimum)))
        if self.shifts < 2 * self.harmonics + 1:
            raise SketchError(f"spectrum bank: shifts must be >= {2 * self.harmonics + 1}, got {self.shifts}")

    def __len__(self) -> int:
        return len(self.spectra)

    def coarse(self, harmonics: int) -> SpectrumBank:
        """The same candidates low-passed to ``harmonics`` (cached): a cheaper first pass over many rows."""
        cached = getattr(self, "_coarse", None)
        if cached is None or cached.harmonics != harmonics:
            k = self.harmonics
            cached = SpectrumBank(self.spectra[:, k - harmonics : k + harmonics + 1])
            self._coarse = cached
        return cached

    def screen(self, queries: np.ndarray, rows: np.ndarray | None = None, mirror: bool = False,
               harmonics: int = 32, keep: int = 1500) -> np.ndarray:
        """Smallest distance from any of ``queries`` (``(V, 2K+1)``) to candidates ``rows``, coarse to fine.

        Over more than ``keep`` rows, all are first compared at ``harmonics`` harmonics (a 4x shorter FFT), and
        only the ``keep`` closest are compared at full resolution; the others score 1 + their coarse distance,
        behind every row compared in full. Returns ``(len(rows),)`` distances.
        """
        queries = np.atleast_2d(queries)
        count = len(self) if rows is None else len(rows)
        if count <= keep or harmonics >= self.harmonics:
            return np.min([self.match(q, rows=rows, mirror=mirror).distance for q in queries], axis=0)
        k = self.harmonics
        small = self.coarse(harmonics)
        rough = np.min([small.match(q[k - harmonics : k + harmonics + 1], rows=rows, mirror=mirror).distance
                        for q in queries], axis=0)
        best = np.argpartition(rough, keep)[:keep]
        distance = 1.0 + rough
        chosen = best if rows is None else np.asarray(rows)[best]
        distance[best] = np.min([self.match(q, rows=chosen, mirror=mirror).distance for q in queries], axis=0)
        return distance

    def match(self, query: np.ndarray, rows: np.ndarray | None = None, mirror: bool = False) -> Match:
        """Distances from the query to candidates ``rows`` (all by default).

        Parameters
        ----------
        query : ndarray
            ``(2K+1,)`` coefficients from :func:`low_spectrum` (same ``K``).
        rows : ndarray of int, optional
            Candidate indices.
        mirror : bool
            Also try the mirror image of each candidate (off by default: a machine draws one handedness).
        """
        query = np.asarray(query)
        if query.shape != (self.spectra.shape[1],):
            raise SketchError(f"spectrum bank: query must have shape ({self.spectra.shape[1]},), got {query.shape}")
        bank = self.spectra if rows is None else self.spectra[rows]
        q = query.astype(np.complex64)
        best = np.zeros(len(bank), dtype=np.float32)
        reversed_ = np.zeros(len(bank), dtype=bool)
        shift = np.zeros(len(bank), dtype=np.float32)
        variants = [(bank, False), (bank[:, ::-1], True)]  # B_{-k}: the candidate walked backwards
        if mirror:
            variants += [(bank[:, ::-1].conj(), False), (bank.conj(), True)]  # conj(b)_n has spectrum conj(B_{-k})
        chunk = max(1, 4_000_000 // (self.shifts * 8))
        for start in range(0, len(bank), chunk):
            stop = min(start + chunk, len(bank))
            for coefficients, is_reversed in variants:
                product = np.zeros((stop - start, self.shifts), dtype=np.complex64)
                k = self.harmonics
                block = q[None, :] * coefficients[start:stop].conj()
                product[:, : k + 1] = block[:, k:]
                product[:, self.shifts - k :] = block[:, :k]
                correlation = np.abs(scipy.fft.fft(product, axis=-1, workers=-1))
                peak = correlation.argmax(axis=-1)
                value = correlation[np.arange(stop - start), peak]
                better = value > best[start:stop]
                best[start:stop] = np.where(better, value, best[start:stop])
                reversed_[start:stop] = np.where(better, is_reversed, reversed_[start:stop])
                shift[start:stop] = np.where(better, peak / self.shifts, shift[start:stop])
        distance = np.clip(1.0 - best.astype(np.float64) ** 2, 0.0, 1.0)
        return Match(distance, reversed_, shift)
