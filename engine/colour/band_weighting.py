r"""
Lighting-dependent band weighting: 16 bands that reproduce 1 nm colorimetry.

The renderer carries every spectrum as :class:`~lbscene.engine.spectra.bands.BandGrid`
band values (16 bands of 20 nm, edges 390–710 nm).  Box averages of illuminant,
reflectance and colour-matching functions lose up to ~2 ΔE00 under spiky
fluorescent lamps, and even weights that integrate illuminant × CMF at 1 nm
inside each band leave ~0.3/0.7 ΔE00 (mean/max, ColorChecker under D65): the
reflectance varies inside a band and light outside 390–710 nm is not seen.
This module removes both for the lighting a surface is seen under.

The reference (what "exact" means here)
---------------------------------------
Tristimulus values from the 1 nm reference sampling, 360–830 nm, CIE 1931 2°
colour-matching functions :math:`\bar x,\bar y,\bar z` (colour-science),
rectangle-rule sum with :math:`\Delta\lambda = 1` nm — what colour-science's
``sd_to_XYZ(..., method='Integration')`` computes on that shape::

    XYZ_ref = k · Σ_λ S(λ) · R(λ) · cmf(λ) · 1 nm                      (1)

with ``S`` the spectral irradiance of the light falling on the surface and
``R`` the reflectance factor; ``k = 1`` gives XYZ in the unit of ``S`` × nm
(``k = 683`` lm/W: ``Y`` in lux of reflected light for ``S`` in W·m⁻²·nm⁻¹;
divide by π for the luminance of a Lambertian surface in cd/m²).

What the renderer carries, and how it must combine it
-----------------------------------------------------
For one lighting configuration with 1 nm irradiance ``S`` at the sample:

``E_b`` — the 16 **illuminant band values**: band means of ``S`` (exactly
    ``grid.integrate(S)``, i.e. what :class:`~lbscene.engine.scene.ir.IRSpectrum`
    ``.bands`` holds for a lamp spectrum).  Unit of ``S``.
``r_b`` — the 16 **band reflectances** of each surface from
    :func:`project_reflectance` ``(R, S)`` (what the IR carries as
    ``reflectance_bands_by_lighting``).
``W`` — (16, 3) **XYZ weights** from :func:`band_xyz_weights` ``(S)``::

        W_bj = k · Σ_{λ ∈ b} S(λ) · cmf_j(λ) · 1 nm  /  E_b               (2)

    where the 1 nm samples are split between bands by
    :func:`band_partition_matrix` (a sample on a shared edge counts half in
    each band; samples below 390 nm belong to the first band and above 710 nm
    to the last, so no light of the 360–830 nm reference is dropped).  Bands
    with no light (``E_b <= 1e-12·max E``) get the equal-energy weights
    ``k · Σ_{λ∈b} cmf_j``.

The renderer multiplies band values in band space — light × reflectance ×
any further band transfer (inter-reflection, filters) — and converts to XYZ
once, at the end, with the weights of the lighting::

    XYZ = Σ_b (E_b · r_b · t_b …) · W_b            (GLSL: xyz = W^T · bands)   (3)

For a Lambertian surface seen directly: radiance bands ``L_b = E_b·r_b/π`` and
``Y`` of Σ L_b W_b (k = 683) is its luminance in cd/m².

The projection
--------------
For a reflectance ``R`` the band reflectances are the band means ``r̄`` plus
the smallest (least-squares norm) correction that makes (3) equal (1)::

    A = (E ⊙ W)ᵀ               (3 × 16)
    r = r̄ + Aᵀ (A Aᵀ)⁺ (C R − A r̄),     C = (S ⊙ cmf)ᵀ   (3 × 471)     (4)

``r = P_S R`` with a (16 × 471) matrix (:func:`projection_matrix`): the map is
**linear** in ``R`` (mixtures and filtered textures stay consistent) and maps a
constant reflectance to the same constant (a perfect white stays 1 in every
band), so a white surface renders exactly the light's 1 nm white point.
Under the light it was projected for, (3) equals (1) to rounding (~1e-13 ΔE00).

When the light reaching a surface differs from ``S`` — inter-reflection off a
coloured wall, a filter applied in band space — the renderer still uses the
band values projected for ``S``; the remaining error is second order (the
within-band variations of the light change and the reflectance both have to
matter).  ``tests/colour/test_band_weighting.py`` measures it: grey N7 walls
with form factor up to 0.9 and coloured walls (any ColorChecker patch) up to
0.5, a diffuser, half and full CTB/CTO conversion filters stay within mean
0.1 / max 0.3 ΔE00.  For strong filters that are part of a lamp (the D65
conversion filter on a halogen lamp), project for the filtered light, as the
compiler does (:meth:`SceneIR.lighting_spd_1nm` includes modelled filters).

Examples
--------
>>> import numpy as np
>>> from lbscene.engine.spectra.bands import REFERENCE_WAVELENGTHS_NM as wl
>>> light = np.interp(wl, [360, 830], [0.5, 1.5])          # a tilted light
>>> refl = 0.2 + 0.6 / (1 + np.exp(-(wl - 580) / 15))       # an orange-ish edge
>>> r = project_reflectance(refl, light)
>>> W = band_xyz_weights(light)
>>> xyz_bands = band_to_xyz(illuminant_bands(light) * r, W)
>>> np.allclose(xyz_bands, reference_xyz(refl, light), rtol=1e-12)
True
>>> np.allclose(project_reflectance(np.ones_like(wl), light), 1.0)
True
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from lbscene.engine.spectra.bands import DEFAULT_GRID, REFERENCE_WAVELENGTHS_NM, BandGrid

__all__ = [
    "DEFAULT_GRID",
    "DARK_BAND_RELATIVE",
    "band_partition_matrix",
    "cmfs_1nm",
    "reference_xyz",
    "illuminant_bands",
    "band_xyz_weights",
    "projection_matrix",
    "project_reflectance",
    "band_to_xyz",
    "reflectance_bands_to_xyz",
    "BandWeighting",
]

#: A band whose illuminant band mean is below this fraction of the brightest band is "dark".
DARK_BAND_RELATIVE = 1e-12
_N_REF = REFERENCE_WAVELENGTHS_NM.size


def cmfs_1nm() -> np.ndarray:
    """CIE 1931 2° colour-matching functions on the 1 nm reference grid, shape (471, 3)."""
    from lbscene.engine.spectra.evaluate import cmfs_1nm as _cmfs

    return _cmfs()


@lru_cache(maxsize=16)
def _partition(grid: BandGrid) -> np.ndarray:
    wl = REFERENCE_WAVELENGTHS_NM
    edges = grid.edges_nm
    m = np.zeros((grid.count, wl.size))
    for b in range(grid.count):
        lo, hi = edges[b], edges[b + 1]
        m[b, (wl > lo) & (wl < hi)] = 1.0
        # a sample on a shared edge is half in each band; on an outer edge, wholly inside
        m[b, wl == lo] = 0.5 if b > 0 else 1.0
        m[b, wl == hi] = 0.5 if b < grid.count - 1 else 1.0
    m[0, wl < edges[0]] = 1.0       # light below the first band is seen through the first band
    m[-1, wl > edges[-1]] = 1.0     # … and above the last through the last
    m.setflags(write=False)
    return m


def band_partition_matrix(grid: BandGrid = DEFAULT_GRID) -> np.ndarray:
    """(count, 471) 0/½/1 matrix splitting the 1 nm reference samples between bands.

    Every column sums to 1 (each sample is counted once over all bands):
    shared edges count half in each band, samples outside the band range
    belong to the first/last band.
    """
    return _partition(grid)


def _as_1nm(values, what: str) -> np.ndarray:
    a = np.asarray(values, float)
    if a.shape[-1:] != (_N_REF,):
        raise ValueError(f"{what} must be sampled on REFERENCE_WAVELENGTHS_NM "
                         f"({_N_REF} values, 360-830 nm at 1 nm); got shape {a.shape}")
    return a


def reference_xyz(reflectance_1nm, illuminant_1nm, *, k: float = 1.0) -> np.ndarray:
    """Equation (1): ``k·Σ S·R·cmf·1 nm`` (1 nm, 360–830 nm, CIE 1931 2°), shape (..., 3).

    Equals colour-science's ``sd_to_XYZ(R, cmfs, S, method='Integration', k=k)``
    on the 1 nm 360–830 nm shape.  A scalar or constant reflectance of 1 gives
    the white point of the light.
    """
    s = _as_1nm(illuminant_1nm, "illuminant_1nm")
    r = np.asarray(reflectance_1nm, float)
    return k * ((r * s) @ cmfs_1nm())


def illuminant_bands(illuminant_1nm, grid: BandGrid = DEFAULT_GRID) -> np.ndarray:
    """The 16 illuminant band values ``E_b``: band means of the 1 nm irradiance (``grid.integrate``)."""
    return grid.integrate(_as_1nm(illuminant_1nm, "illuminant_1nm"))


def _dark(eb: np.ndarray) -> np.ndarray:
    top = float(np.max(eb)) if eb.size else 0.0
    return eb <= DARK_BAND_RELATIVE * max(top, 1e-300)


def band_xyz_weights(illuminant_1nm, grid: BandGrid = DEFAULT_GRID, *, k: float = 1.0) -> np.ndarray:
    """Equation (2): (count, 3) XYZ weights per unit illuminant band value × band reflectance.

    ``XYZ = (illuminant_bands(S) * r) @ W`` reproduces ``reference_xyz(R, S, k=k)``
    exactly for any reflectance constant within each band (and, with ``r`` from
    :func:`project_reflectance`, for any reflectance).  Units: nm × ``k``.
    """
    s = _as_1nm(illuminant_1nm, "illuminant_1nm")
    part = band_partition_matrix(grid)
    cmf = cmfs_1nm()
    eb = grid.integrate(s)
    dark = _dark(eb)
    with np.errstate(divide="ignore", invalid="ignore"):
        w = (part * s) @ cmf / np.where(dark, 1.0, eb)[:, None]
    flat = part @ cmf
    return k * np.where(dark[:, None], flat, w)


@lru_cache(maxsize=64)
def _projection_cached(key: bytes, grid: BandGrid) -> np.ndarray:
    s = np.frombuffer(key, dtype=float)
    g = grid.integration_matrix                       # (B, 471): band means r̄ = G R
    a = (illuminant_bands(s, grid)[:, None] * band_xyz_weights(s, grid)).T   # (3, B)
    c = (s[:, None] * cmfs_1nm()).T                   # (3, 471): reference XYZ = C R
    # least-norm correction; pinv keeps degenerate lights (one or two lit bands) finite
    aat = a @ a.T
    scale = np.sqrt(np.diag(aat))
    scale[scale == 0] = 1.0
    inv = np.linalg.pinv(aat / np.outer(scale, scale), rcond=1e-12) / np.outer(scale, scale)
    p = g + a.T @ inv @ (c - a @ g)
    p.setflags(write=False)
    return p


def projection_matrix(illuminant_1nm, grid: BandGrid = DEFAULT_GRID) -> np.ndarray:
    """Equation (4) as a (count, 471) matrix ``P_S``: band reflectances ``r = P_S @ R``.

    Cached on the illuminant's values (the compiler projects every material for
    every lighting).  Read-only.
    """
    s = np.ascontiguousarray(_as_1nm(illuminant_1nm, "illuminant_1nm"), dtype=float)
    if s.ndim != 1:
        raise ValueError("illuminant_1nm must be one spectrum (shape (471,))")
    if not np.all(np.isfinite(s)) or np.any(s < 0):
        raise ValueError("illuminant_1nm must be finite and non-negative")
    return _projection_cached(s.tobytes(), grid)


def project_reflectance(reflectance_1nm, illuminant_1nm, grid: BandGrid = DEFAULT_GRID) -> np.ndarray:
    """Lighting-dependent band values of reflectance(s) for the light that falls on them.

    Parameters
    ----------
    reflectance_1nm
        Reflectance (or transmittance) factors on
        :data:`~lbscene.engine.spectra.bands.REFERENCE_WAVELENGTHS_NM`, shape (..., 471).
    illuminant_1nm
        Relative spectral irradiance of the light reaching the surface, shape (471,).
    grid
        The band grid (default 16 bands of 20 nm, 390–710 nm).

    Returns
    -------
    numpy.ndarray
        Shape (..., count): the band means plus the least-norm correction that
        makes ``(illuminant_bands(S) * r) @ band_xyz_weights(S)`` equal the 1 nm
        tristimulus values ``reference_xyz(R, S)`` (see the module notes).
    """
    r = _as_1nm(reflectance_1nm, "reflectance_1nm")
    return r @ projection_matrix(illuminant_1nm, grid).T


def band_to_xyz(band_values, weights) -> np.ndarray:
    """Equation (3): XYZ of band values (light × reflectance × …), shape (..., 3).

    ``band_values`` (..., count) are products of illuminant band values and band
    transfers; ``weights`` the (count, 3) result of :func:`band_xyz_weights`.
    """
    return np.asarray(band_values, float) @ np.asarray(weights, float)


def reflectance_bands_to_xyz(reflectance_bands, illuminant_1nm, grid: BandGrid = DEFAULT_GRID,
                             *, k: float = 1.0) -> np.ndarray:
    """XYZ of band reflectances seen under a light: ``(E ⊙ r) @ W``, shape (..., 3)."""
    return band_to_xyz(illuminant_bands(illuminant_1nm, grid) * np.asarray(reflectance_bands, float),
                       band_xyz_weights(illuminant_1nm, grid, k=k))


@dataclass(frozen=True, eq=False)
class BandWeighting:
    """Everything the bake and the shaders carry for one lighting configuration.

    Examples
    --------
    >>> import numpy as np
    >>> bw = BandWeighting.for_light(np.ones(471))
    >>> bw.illuminant_bands.shape, bw.weights.shape, bw.matrix.shape
    ((16,), (16, 3), (16, 471))
    """

    illuminant_1nm: np.ndarray
    grid: BandGrid
    illuminant_bands: np.ndarray   # E_b, (count,)
    weights: np.ndarray            # W, (count, 3), k = 1
    matrix: np.ndarray             # P_S, (count, 471)

    @classmethod
    def for_light(cls, illuminant_1nm, grid: BandGrid = DEFAULT_GRID) -> "BandWeighting":
        s = np.array(_as_1nm(illuminant_1nm, "illuminant_1nm"), float)
        s.setflags(write=False)
        return cls(s, grid, illuminant_bands(s, grid), band_xyz_weights(s, grid),
                   projection_matrix(s, grid))

    def project(self, reflectance_1nm) -> np.ndarray:
        """Band reflectances, shape (..., count)."""
        return _as_1nm(reflectance_1nm, "reflectance_1nm") @ self.matrix.T

    def xyz(self, reflectance_bands, *, k: float = 1.0) -> np.ndarray:
        """XYZ of band reflectances under this light (equation 3)."""
        return k * band_to_xyz(self.illuminant_bands * np.asarray(reflectance_bands, float),
                               self.weights)

    @property
    def white_xyz(self) -> np.ndarray:
        """1 nm white point of the light (``k = 1``)."""
        return reference_xyz(1.0, self.illuminant_1nm)

    def to_json(self, *, k: float = 1.0) -> dict:
        """Plain floats for bakes and shaders (``weights`` row b = band b; scaled by ``k``)."""
        return {"grid": self.grid.to_json(), "k": k,
                "illuminant_bands": [float(x) for x in self.illuminant_bands],
                "xyz_weights": [[float(k * x) for x in row] for row in self.weights]}
