"""
The engine's spectral band grid and band integration.

lbscene renders in ``count`` contiguous bands (default 16 bands of 20 nm whose
centres run 400–700 nm, i.e. edges 390–710 nm).  Spectra of any input sampling
are first brought onto a 1 nm reference grid (360–830 nm, linear interpolation
of the input, zero outside a measured range unless the caller extrapolates) and
then reduced to the bands by **band integration** (the mean over each band),
never by point sampling at band centres.

Colour-accurate, lighting-dependent band values for reflectances (the
per-lighting projection) live in :mod:`lbscene.engine.colour`; this module
only provides the grid and the plain band means.

Examples
--------
>>> g = BandGrid()
>>> g.count, g.centres_nm[0], g.centres_nm[-1], g.edges_nm[0], g.edges_nm[-1]
(16, 400.0, 700.0, 390.0, 710.0)
>>> import numpy as np
>>> g.integrate(np.ones(REFERENCE_WAVELENGTHS_NM.size)).round(6).tolist() == [1.0] * 16
True
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np

__all__ = [
    "REFERENCE_WAVELENGTHS_NM",
    "BandGrid",
    "DEFAULT_GRID",
    "to_reference",
    "band_labels",
]

#: The 1 nm reference sampling every spectrum is brought onto first.
REFERENCE_WAVELENGTHS_NM = np.arange(360.0, 831.0, 1.0)


@dataclass(frozen=True)
class BandGrid:
    """Contiguous equal-width bands given by first centre, width and count."""

    first_centre_nm: float = 400.0
    width_nm: float = 20.0
    count: int = 16

    def __post_init__(self) -> None:
        lo = self.first_centre_nm - self.width_nm / 2
        hi = self.first_centre_nm + (self.count - 0.5) * self.width_nm
        if self.count < 1 or self.width_nm <= 0:
            raise ValueError("a band grid needs count >= 1 and width_nm > 0")
        if lo < REFERENCE_WAVELENGTHS_NM[0] or hi > REFERENCE_WAVELENGTHS_NM[-1]:
            raise ValueError(f"bands {lo}-{hi} nm exceed the 360-830 nm reference range")

    @cached_property
    def centres_nm(self) -> np.ndarray:
        return self.first_centre_nm + self.width_nm * np.arange(self.count, dtype=float)

    @cached_property
    def edges_nm(self) -> np.ndarray:
        return self.first_centre_nm - self.width_nm / 2 + self.width_nm * np.arange(
            self.count + 1, dtype=float)

    @cached_property
    def integration_matrix(self) -> np.ndarray:
        """``(count, n_ref)`` matrix: band mean of a 1 nm reference spectrum.

        Trapezoidal integration of the piecewise-linear 1 nm spectrum over each
        band, divided by the band width.  Rows sum to 1.
        """
        wl = REFERENCE_WAVELENGTHS_NM
        m = np.zeros((self.count, wl.size))
        fine = np.linspace(0.0, 1.0, 41)  # sub-sampling of each band for exact trapezoids
        for b, (lo, hi) in enumerate(zip(self.edges_nm[:-1], self.edges_nm[1:])):
            x = lo + (hi - lo) * fine
            # weights of the linear interpolation of x on wl, integrated by trapezoid over x
            idx = np.clip(np.searchsorted(wl, x) - 1, 0, wl.size - 2)
            t = (x - wl[idx]) / (wl[idx + 1] - wl[idx])
            tw = np.full(x.size, (hi - lo) / (x.size - 1))
            tw[0] *= 0.5
            tw[-1] *= 0.5
            np.add.at(m[b], idx, tw * (1 - t))
            np.add.at(m[b], idx + 1, tw * t)
            m[b] /= hi - lo
        return m

    def integrate(self, values_ref: np.ndarray) -> np.ndarray:
        """Band means of spectra sampled on :data:`REFERENCE_WAVELENGTHS_NM` (last axis)."""
        return np.asarray(values_ref, float) @ self.integration_matrix.T

    def labels(self) -> list[str]:
        return band_labels(self)

    def to_json(self) -> dict:
        return {"first_centre_nm": self.first_centre_nm, "width_nm": self.width_nm,
                "count": self.count}


DEFAULT_GRID = BandGrid()


def band_labels(grid: BandGrid = DEFAULT_GRID) -> list[str]:
    """Channel names such as ``'390-410nm'`` (edges, so that bands tile the range)."""
    e = grid.edges_nm
    return [f"{e[i]:g}-{e[i + 1]:g}nm" for i in range(grid.count)]


def to_reference(wavelengths_nm, values, *, extrapolate: str = "zero") -> np.ndarray:
    """Linear interpolation of a sampled spectrum onto the 1 nm reference grid.

    Parameters
    ----------
    wavelengths_nm, values
        Strictly increasing wavelengths and the values there (any sampling).
    extrapolate
        ``'zero'`` (default; emission outside a measured range is unknown and
        counted as none) or ``'constant'`` (hold the end values, suitable for
        reflectances and transmittances).
    """
    wl = np.asarray(wavelengths_nm, float)
    v = np.asarray(values, float)
    if wl.ndim != 1 or wl.shape != v.shape[-1:] or wl.size < 2:
        raise ValueError("need at least two wavelengths and matching values")
    if np.any(np.diff(wl) <= 0):
        raise ValueError("wavelengths must be strictly increasing")
    ref = REFERENCE_WAVELENGTHS_NM
    if extrapolate == "constant":
        return np.interp(ref, wl, v)
    if extrapolate == "zero":
        out = np.interp(ref, wl, v, left=0.0, right=0.0)
        return out
    raise ValueError(f"unknown extrapolate mode {extrapolate!r}")
