"""
Colour flop: a multi-lobe Cook-Torrance BRDF fitted per band to the reflectance factors a
multi-angle spectrophotometer measures.

Model
-----
Under a clear coat of index :math:`n` (:mod:`~lbscene.engine.coatings.optics`), the effect layer
has a Lambertian base and :math:`K` (1–3) microfacet lobes with the GGX (Trowbridge–Reitz)
distribution, evaluated with the directions *inside* the coat (:math:`\\mathbf l', \\mathbf v'`,
:math:`\\mathbf h' = \\widehat{\\mathbf l' + \\mathbf v'}`):

.. math::

    f(\\mathbf l, \\mathbf v; λ) = \\frac{T(θ_l) T(θ_v)}{n^2}\\Big[\\frac{a(λ)}{π}
        + \\sum_{k=1}^{K} s_k(λ)\\, \\frac{D_{α_k}(\\mathbf h')}{4 \\cos θ_l' \\cos θ_v'}\\Big],
    \\qquad
    D_α(\\mathbf h) = \\frac{α^2}{π\\,(\\cos^2 θ_h\\,(α^2 − 1) + 1)^2}.

Fresnel and shadowing of the flakes are folded into the spectral weights :math:`s_k(λ)` (and the
pigment's absorption into :math:`a(λ)`); the roughnesses :math:`α_k` are shared by all bands.
The instrument reads the reflectance factor :math:`R = π f` (radiance over that of the
perfect white diffuser under the same light).

A lobe's energy: at normal incidence (:math:`\\mathbf l' = \\mathbf n`) the directional albedo of
:math:`s\\,D/(4\\cos\\cos)` over the views that leave the layer (:math:`θ_h < 45°`) is
:math:`s \\int_0^{π/4} D \\cos θ_h\\, dω_h = s/(1 + α^2)` (the GGX cumulative distribution).

Fit
---
For fixed :math:`α_k` the model is linear and non-negative in :math:`a, s_k` per band: a weighted
non-negative least squares per band (weights :math:`1/R`, i.e. relative residuals, as colour
differences are closer to relative than absolute).  The :math:`α_k` (ordered, 0.01–1) are found
by Nelder–Mead on :math:`\\ln α` from several starts.  With the six BYK geometries and two lobes,
each band has 3 linear parameters and the whole model 2 shared ones.

References
----------
.. [1] R. L. Cook, K. E. Torrance, "A reflectance model for computer graphics", ACM TOG 1 (1982).
.. [2] B. Walter, S. Marschner, H. Li, K. Torrance, "Microfacet models for refraction through
   rough surfaces", EGSR 2007 (the GGX distribution).
.. [3] J. Günther, T. Chen, M. Goesele, I. Wald, H.-P. Seidel, "Efficient acquisition and
   realistic rendering of car paint", Vision, Modeling and Visualization 2005 (a diffuse term
   plus several Cook–Torrance lobes fitted to measured car paint).
.. [4] M. Rump, G. Müller, R. Sarlette, D. Koch, R. Klein, "Photo-realistic rendering of
   metallic car paint from image-based measurements", Computer Graphics Forum 27 (2008)
   (multi-lobe Cook–Torrance BRDF of car paint, plus a flake texture).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .optics import fresnel_transmittance, geometry_directions, half_vector, refract_into_coat

__all__ = [
    "ggx_d",
    "beckmann_d",
    "DISTRIBUTIONS",
    "FlopModel",
    "fit_flop",
    "leave_one_out",
    "MeasuredGeometry",
]

ALPHA_MIN = 0.01
ALPHA_MAX = 1.0


def ggx_d(cos_h, alpha) -> np.ndarray:
    """GGX normal distribution :math:`D_α` (sr⁻¹); :math:`\\int D \\cos θ_h dω = 1`."""
    c2 = np.clip(np.asarray(cos_h, float), 0.0, 1.0) ** 2
    a2 = np.asarray(alpha, float) ** 2
    return a2 / (np.pi * (c2 * (a2 - 1.0) + 1.0) ** 2)


def beckmann_d(cos_h, alpha) -> np.ndarray:
    """Beckmann normal distribution (Cook and Torrance's choice),
    :math:`D_α = \\exp(−\\tan^2 θ_h/α^2) / (π α^2 \\cos^4 θ_h)`; :math:`\\int D \\cos θ_h dω = 1`."""
    c2 = np.clip(np.asarray(cos_h, float), 1e-9, 1.0) ** 2
    a2 = np.asarray(alpha, float) ** 2
    return np.exp(-(1.0 - c2) / (c2 * a2)) / (np.pi * a2 * c2 * c2)


#: lobe shape → normal distribution
DISTRIBUTIONS = {"beckmann": beckmann_d, "ggx": ggx_d}


@dataclass(frozen=True)
class MeasuredGeometry:
    """One measurement: illumination and aspecular angles (deg), band reflectance factors."""

    illumination_deg: float
    aspecular_deg: float
    bands: np.ndarray


@dataclass
class FlopModel:
    """A fitted flop BRDF (see the module docstring).

    Attributes
    ----------
    n : float
        Clear-coat refractive index.
    alphas : (K,) array
        Roughness of each lobe (inside the coat).
    diffuse : (B,) array
        :math:`a(λ)` per band.
    lobes : (K, B) array
        :math:`s_k(λ)` per band.
    distribution : str
        ``beckmann`` (Cook and Torrance's) or ``ggx``.
    rms_relative : float
        RMS relative residual of the fit over all geometries and bands.
    """

    n: float
    alphas: np.ndarray
    diffuse: np.ndarray
    lobes: np.ndarray
    distribution: str = "beckmann"
    rms_relative: float = float("nan")
    geometries: list[tuple[float, float]] = field(default_factory=list)

    def basis(self, l: np.ndarray, v: np.ndarray) -> np.ndarray:
        """Reflectance factor of each unit term, (…, 1 + K): column 0 the base (a = 1), column k
        lobe k (s_k = 1).  ``l``, ``v``: unit directions (…, 3) in the sample frame (z up)."""
        return _basis(np.asarray(l, float), np.asarray(v, float), self.n, self.alphas, self.distribution)

    def reflectance_factor(self, l, v) -> np.ndarray:
        """:math:`R = π f(\\mathbf l, \\mathbf v)` per band, (…, B)."""
        b = self.basis(l, v)
        coef = np.vstack([self.diffuse[None, :], self.lobes])          # (1 + K, B)
        return b @ coef

    def brdf(self, l, v) -> np.ndarray:
        """:math:`f` in sr⁻¹ per band, (…, B)."""
        return self.reflectance_factor(l, v) / np.pi

    def at_geometry(self, illumination_deg, aspecular_deg) -> np.ndarray:
        l, v = geometry_directions(illumination_deg, aspecular_deg)
        return self.reflectance_factor(l, v)

    def refit_linear(self, measured: list[MeasuredGeometry]) -> "FlopModel":
        """The same roughnesses, the spectral weights refitted to other band values of the same
        geometries (e.g. reflectances projected for the light of a view)."""
        a, s, rms = _solve_linear(measured, self.n, self.alphas, self.distribution)
        return FlopModel(self.n, self.alphas.copy(), a, s, self.distribution, rms, list(self.geometries))

    def to_json(self) -> dict:
        return {"refractive_index": self.n, "distribution": self.distribution,
                "alphas": self.alphas.tolist(), "diffuse": self.diffuse.tolist(),
                "lobes": self.lobes.tolist(), "rms_relative": self.rms_relative}


def _basis(l, v, n, alphas, distribution="beckmann") -> np.ndarray:
    d_of = DISTRIBUTIONS[distribution]
    li, vi = refract_into_coat(l, n), refract_into_coat(v, n)
    h = half_vector(li, vi)
    cl, cv = np.clip(li[..., 2], 1e-6, 1.0), np.clip(vi[..., 2], 1e-6, 1.0)
    t = fresnel_transmittance(l[..., 2], n) * fresnel_transmittance(v[..., 2], n) / (n * n)
    cols = [t]                                          # π · (T T / n²) · 1/π
    for a in np.atleast_1d(alphas):
        cols.append(t * np.pi * d_of(h[..., 2], a) / (4.0 * cl * cv))
    return np.stack(cols, -1)


def _design(measured, n, alphas, distribution) -> np.ndarray:
    ti = np.array([m.illumination_deg for m in measured])
    ta = np.array([m.aspecular_deg for m in measured])
    l, v = geometry_directions(ti, ta)
    return _basis(l, v, n, alphas, distribution)        # (G, 1 + K)


def _solve_linear(measured, n, alphas, distribution="beckmann"):
    from scipy.optimize import nnls

    A = _design(measured, n, alphas, distribution)
    R = np.stack([np.asarray(m.bands, float) for m in measured])      # (G, B)
    w = 1.0 / np.maximum(R, 1e-3)
    coef = np.zeros((A.shape[1], R.shape[1]))
    sse = 0.0
    for b in range(R.shape[1]):
        Aw = A * w[:, b:b + 1]
        x, r = nnls(Aw, R[:, b] * w[:, b], maxiter=200)
        coef[:, b] = x
        sse += r * r
    rms = float(np.sqrt(sse / R.size))
    return coef[0], coef[1:], rms


def fit_flop(measured: list[MeasuredGeometry], lobes: int = 2, n: float = 1.5,
             distribution: str = "beckmann") -> FlopModel:
    """Fit :class:`FlopModel` to reflectance factors at several geometries.

    Parameters
    ----------
    measured
        At least ``lobes + 2`` geometries (band values on one grid).
    lobes
        Number of lobes K (1–3).
    n
        Clear-coat refractive index.
    distribution
        Lobe shape: ``beckmann`` (Cook–Torrance) or ``ggx``.
    """
    from scipy.optimize import minimize

    if len(measured) < lobes + 2:
        raise ValueError(f"{lobes} lobe(s) need at least {lobes + 2} geometries, got {len(measured)}")
    if distribution not in DISTRIBUTIONS:
        raise ValueError(f"unknown lobe distribution {distribution!r}")
    lo, hi = np.log(ALPHA_MIN), np.log(ALPHA_MAX)

    def alphas_of(x):
        # lobes ordered by roughness: α_1 and the log-ratios between successive lobes
        return np.exp(np.clip(np.cumsum(np.r_[x[0], np.abs(x[1:]) + 0.05]), lo, hi))

    def cost(x):
        return _solve_linear(measured, n, alphas_of(x), distribution)[2]

    grid = np.log([0.03, 0.06, 0.12, 0.25, 0.5])
    starts = [np.r_[a, [np.log(2.5)] * (lobes - 1)] for a in grid]
    best = None
    for x0 in starts:
        r = minimize(cost, np.asarray(x0, float), method="Nelder-Mead",
                     options={"xatol": 1e-4, "fatol": 1e-8, "maxiter": 600 * lobes})
        if best is None or r.fun < best.fun:
            best = r
    alphas = alphas_of(best.x)
    a, s, rms = _solve_linear(measured, n, alphas, distribution)
    return FlopModel(n, alphas, a, s, distribution, rms,
                     [(m.illumination_deg, m.aspecular_deg) for m in measured])


def leave_one_out(measured: list[MeasuredGeometry], lobes: int = 2, n: float = 1.5,
                  distribution: str = "beckmann", grid=None) -> list[dict]:
    """Fit without each geometry in turn and predict it.

    Returns one dict per geometry: ``aspecular_deg``, ``delta_e00`` (CIE 2000 between the
    predicted and the measured band reflectance, D65, CIE 1964 10° observer:
    :func:`lbscene.engine.coatings.colorimetry.delta_e00_bands`) and ``relative_rms``.
    """
    from .colorimetry import delta_e00_bands

    out = []
    for j, m in enumerate(measured):
        rest = measured[:j] + measured[j + 1:]
        model = fit_flop(rest, lobes=lobes, n=n, distribution=distribution)
        pred = model.at_geometry(m.illumination_deg, m.aspecular_deg)
        out.append({"illumination_deg": m.illumination_deg, "aspecular_deg": m.aspecular_deg,
                    "delta_e00": float(delta_e00_bands(pred, m.bands, grid)),
                    "relative_rms": float(np.sqrt(np.mean((pred / np.maximum(m.bands, 1e-6) - 1) ** 2)))})
    return out
