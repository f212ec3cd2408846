"""
What moving light around can do to the white tile's spectrum: a bound before a refit.

Hardware that changes only where light goes (a plate of flat transmittance, an aperture plate
with a grey interior, a mirror of flat reflectance, a wall or ceiling of another grey) cannot
give the light a spectrum it did not have.  Whatever its geometry, the tile's predicted radiance stays in the cone

.. math:: L(λ) = \\frac{ρ_\\text{tile}(λ)}{π} \\sum_j a_j\\, S_j(λ), \\qquad a_j ≥ 0,

of the spectra light can carry to the tile in the booth: each lamp spectrum the base
prediction's terms carry :math:`s_t(λ)` (lamp, declared filter, declared diffuser), alone and
times each product of up to :data:`REACH_ORDER` of the booth's band reflectances (the
inter-reflection's paths, interpolated from the bands as the radiosity does), and each term's
own contribution at the tile.  Its best shape against the measured tile, with its mean at the
measured mean (the readings' level is free: every one of them could be explained), is a floor
under any such hypothesis' χ²:

.. math:: χ^2 ≥ \\min_c\\; c^2 S_1 + n_b\\,\\frac{10^4 (c - 1)^2}{σ_s^2}
          = \\frac{S_1 K}{S_1 + K}, \\qquad K = \\frac{10^4 n_b}{σ_s^2},

:math:`S_1` the cone's least shape χ² at mean 1 (non-negative least squares), :math:`n_b` the
tile's bands and :math:`σ_s` their noise (%).  Where even that floor leaves the hypothesis more
than the tie margin under an explanation that reaches the noise, its refits (seconds each,
through the forward model) cannot change the verdict and are not run
(:func:`lbscene.engine.loop.diagnose.diagnose` says so under "not tested").

The cone is a relaxation: it lets every path's weight vary freely, so for paths of up to
:data:`REACH_ORDER` reflections the bound is never tighter than what a geometry can do.  Longer
paths enter only through the terms' own contributions, at the base fit's weights: a geometry that
reweights them on strongly coloured surfaces could leave the cone by the difference between a
fourth power of a reflectance and its nearest mix of the lower ones.  The floor is checked against
the refits it saves, through the forward model, on the Mitsuba truth of an undeclared filter
(``tests/engine/test_spectral_reach.py``).
"""

from __future__ import annotations

from itertools import combinations_with_replacement

import numpy as np

__all__ = ["REACH_ORDER", "cone_spectra_1nm", "spectral_floor_chi2"]

#: reflections per path whose spectra the cone holds (products of the booth's band reflectances)
REACH_ORDER = 3
#: normalised spectra equal to this resolution are one column
_SAME = 1e-6


def _unique(rows: list[np.ndarray]) -> list[np.ndarray]:
    """The rows normalised, each shape once (keyed by its values rounded to :data:`_SAME`: a
    booth of many materials has hundreds of products, compared in one pass)."""
    out: list[np.ndarray] = []
    seen: set[bytes] = set()
    for r in rows:
        n = float(np.linalg.norm(r))
        if not np.isfinite(n) or n <= 0:
            continue
        u = r / n
        key = np.round(u / _SAME).astype(np.int64).tobytes()
        if key not in seen:
            seen.add(key)
            out.append(u)
    return out


def _band_factors(ir, lighting: str) -> list[np.ndarray]:
    """Each booth material's band reflectances as the radiosity sees them (the lighting's own
    where declared), and a declared diffuser's band transmittance."""
    out = []
    for m in ir.materials.values():
        b = m.reflectance_bands_by_lighting.get(lighting)
        out.append(np.asarray(b if b is not None else m.reflectance.array_bands, float))
    if ir.diffuser is not None:
        out.append(ir.diffuser.transmittance.array_bands)
    return _unique(out)


def cone_spectra_1nm(ir, lighting: str, terms, row: int) -> np.ndarray:
    """``(J, 471)``: the spectra light can carry to receiver ``row`` (module docstring), from
    the base prediction's ``terms``."""
    from lbscene.engine.light.forward import spectral_tables

    _, _, P = spectral_tables(ir.grid)                                     # (471, B)
    sources, own = [], []
    for t in terms:
        s = np.asarray(t.spectrum_1nm, float)
        sources.append(s)
        c = np.zeros_like(s)
        if t.geo is not None:
            c = c + float(t.geo[row]) * s
        if t.geo_bands is not None:
            c = c + (np.asarray(t.geo_bands[row], float) @ P.T) * s
        own.append(c)
    sources = _unique(sources)
    factors = _band_factors(ir, lighting)
    products = [np.ones(P.shape[1])]
    for k in range(1, REACH_ORDER + 1):
        for combo in combinations_with_replacement(range(len(factors)), k):
            products.append(np.prod([factors[i] for i in combo], axis=0))
    shapes = [P @ p for p in _unique(products)]
    cols = [s * f for s in sources for f in shapes] + own
    return np.asarray(_unique(cols))


def spectral_floor_chi2(ir, lighting: str, terms, row: int, tile_reflectance_1nm, tile_grid,
                        tile_meas, tile_mask, spectral_percent: float) -> float:
    """The least white-tile χ² (noise units) any flat-spectrum change of geometry can reach
    (module docstring); 0 where no band of the tile is compared."""
    from scipy.optimize import nnls

    m = np.asarray(tile_mask, bool)
    if not m.any():
        return 0.0
    S = cone_spectra_1nm(ir, lighting, terms, row)
    if not len(S):
        return 0.0
    A = (tile_grid.integrate(S * np.asarray(tile_reflectance_1nm, float)[None, :] / np.pi)[:, m]
         / np.asarray(tile_meas, float)[m][None, :]).T                    # (n_b, J): predicted / measured
    A = A / np.maximum(np.abs(A).max(axis=0), 1e-300)[None, :]
    n = A.shape[0]
    u = 100.0 / float(spectral_percent)
    C = A - A.mean(axis=0)[None, :]
    w = 1e3 * u * np.sqrt(n)
    try:
        a, _ = nnls(np.vstack([u * C, w * A.mean(axis=0)[None, :]]), np.concatenate([np.zeros(n), [w]]),
                    maxiter=50 * A.shape[1])
    except RuntimeError:        # not converged: no floor (every refit runs)
        return 0.0
    mean = float(A.mean(axis=0) @ a)
    if mean <= 0:
        return 0.0
    x = (A @ a) / mean
    S1 = float(np.sum((u * (x - x.mean())) ** 2))
    K = n * u * u
    return S1 * K / (S1 + K)
