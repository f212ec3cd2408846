"""
Effect flakes: tiny mirrors in the effect layer under the clear coat.

Statistics
----------
Flakes are discs lying at random positions (a Poisson process of ``density_per_mm2`` flakes per
mm² of sample surface), with log-normal diameters (:math:`\\ln d \\sim N(\\ln d_{50}, σ_d^2)`, so
:math:`E[d^k] = d_{50}^k e^{k^2 σ_d^2/2}`) and normals :math:`\\mathbf m` drawn from the Beckmann
distribution about the sample normal: per flake, the probability density (per steradian) is

.. math::

    p(\\mathbf m) = D_B(\\mathbf m) \\cos θ_m = \\frac{\\exp(−\\tan^2 θ_m / α^2)}{π α^2 \\cos^3 θ_m},
    \\qquad \\int_{Ω_+} p\\, dω = 1,

i.e. the two slopes :math:`−m_x/m_z, −m_y/m_z` are independent normal with variance
:math:`α^2/2`; ``orientation_spread_deg`` is :math:`\\arctan α`.

Glints
------
A flake is a mirror: seen along :math:`\\mathbf v`, it shows the light of the one direction
:math:`\\mathbf l` with :math:`\\mathbf m = \\widehat{\\mathbf l' + \\mathbf v'}` (inside the coat).
For a lamp of small solid angle :math:`Ω` (seen from the sample, in air) the glinting normals fill
:math:`Ω_h = Ω' / (4\\, \\mathbf l' \\cdot \\mathbf h')` with :math:`Ω' = Ω \\cos θ_l / (n^2 \\cos θ_l')`
(refraction compresses solid angles), so a flake glints with probability

.. math:: P = p(\\mathbf h')\\, \\frac{Ω \\cos θ_l}{4 n^2 \\cos θ_l'\\, (\\mathbf l' \\cdot \\mathbf h')} ,

and a glinting flake has the lamp's radiance times :math:`ρ_f\\,T(θ_l)\\,T(θ_v)` (the :math:`n^2`
gained entering the coat is lost leaving it).  An extended lamp (a tube, a panel) of the same
intensity has a larger :math:`Ω` and a lower radiance: more glints, each dimmer.

On average over the surface the flakes are a microfacet lobe (no shadowing):

.. math:: f_{flakes}(\\mathbf l, \\mathbf v) = \\frac{T(θ_l)T(θ_v)}{n^2}
          \\frac{ρ_A\\, \\bar a\\, ρ_f\\, p(\\mathbf h')}{4 \\cos θ_l' \\cos θ_v'},

with :math:`ρ_A \\bar a` the area fraction the flakes cover (:math:`\\bar a = π E[d^2]/4`).

Flakes hide one another
-----------------------
Flakes lie at random depths in an effect layer of thickness :math:`t` (``layer_um``).  A flake with a
fraction :math:`u` of the layer's flakes above it (:math:`u` uniform) is reached by the lamp's light
and seen by the viewer through the flakes above it: each path crosses a coverage :math:`c\\,u`
(:math:`c = ρ_A \\bar a`; a flat flake's projection shrinks by the same cosine by which a slanted
path crosses more of them).  The two paths leave the flake along :math:`\\mathbf l'` and
:math:`\\mathbf v'`; at the mean height :math:`u t / 2` of the flakes above, they are
:math:`Δ = (u t/2)\\,|\\mathbf l'_{xy}/l'_z − \\mathbf v'_{xy}/v'_z|` apart, so a share
:math:`κ(Δ/\\bar d)` of what hides one hides the other (the overlap of two discs of the mean
diameter :math:`\\bar d` at that offset, :math:`κ(x) = \\tfrac{2}{π}(\\arccos x − x\\sqrt{1 − x^2})`).
Treating the flakes above as a Poisson screen, the visible share of a glint is

.. math:: s(u) = e^{−c u (2 − κ)}, \\qquad V = \\int_0^1 s(u)\\, du ,

:math:`V` multiplying the flakes' mean lobe (:meth:`FlakeModel.visibility`).  Mitsuba's explicit
flakes (:mod:`~lbscene.engine.coatings.mitsuba_flakes`) check it.

References
----------
.. [1] P. Beckmann, A. Spizzichino, *The Scattering of Electromagnetic Waves from Rough
   Surfaces* (1963) (the slope distribution).
.. [2] W. Jakob, M. Hašan, L.-Q. Yan, J. Lawrence, R. Ramamoorthi, S. Marschner, "Discrete
   stochastic microfacet models", ACM TOG 33 (SIGGRAPH 2014) (glints as counts of facets whose
   normals fall in the half-vector set of a pixel and an extended light).
.. [3] E. Kirchner, G.-J. van den Kieboom, L. Njo, R. Supèr, R. Gottenbos, "Observation of visual
   texture of metallic and pearlescent materials", Color Research & Application 32 (2007).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .optics import fresnel_transmittance, half_vector, refract_into_coat

__all__ = [
    "FlakeModel",
    "beckmann_normal_pdf",
    "sample_normals",
    "DEFAULT_FLAKE_REFLECTANCE",
]

#: Reflectance of an aluminium flake seen through a clear coat, when none is declared.
DEFAULT_FLAKE_REFLECTANCE = 0.9


def beckmann_normal_pdf(m: np.ndarray, alpha: float) -> np.ndarray:
    """Per-flake density :math:`p(\\mathbf m)` (sr⁻¹) of unit normals (…, 3), z up."""
    m = np.asarray(m, float)
    c = np.clip(m[..., 2], 1e-9, 1.0)
    t2 = np.clip(1.0 - c * c, 0.0, None) / (c * c)
    return np.exp(-t2 / (alpha * alpha)) / (np.pi * alpha * alpha * c ** 3)


def sample_normals(slopes_unit: np.ndarray, alpha: float) -> np.ndarray:
    """Unit normals from standard-normal slope pairs (…, 2): slopes × α/√2 (Beckmann)."""
    s = np.asarray(slopes_unit, float) * (alpha / np.sqrt(2.0))
    m = np.concatenate([-s, np.ones(s.shape[:-1] + (1,))], -1)
    return m / np.linalg.norm(m, axis=-1, keepdims=True)


@dataclass(frozen=True)
class FlakeModel:
    """Flake parameters (see the module docstring).

    Attributes
    ----------
    density_per_mm2 : float
        Flakes per mm² of sample.
    median_diameter_um, diameter_spread : float
        Log-normal diameter: median (µm) and σ of ln d.
    alpha : float
        Beckmann α of the flake normals (``orientation_spread_deg = atan α``).
    flake_reflectance : (B,) array
        Band reflectance of a flake (a mirror).
    n : float
        Clear-coat refractive index.
    layer_um : float
        Thickness of the effect layer the flakes are spread through (basecoats: 12–25 µm).
    """

    density_per_mm2: float
    median_diameter_um: float
    diameter_spread: float
    alpha: float
    flake_reflectance: np.ndarray
    n: float = 1.5
    layer_um: float = 20.0

    @classmethod
    def from_spread_deg(cls, density_per_mm2, median_diameter_um, diameter_spread, spread_deg,
                        flake_reflectance, n=1.5) -> "FlakeModel":
        return cls(float(density_per_mm2), float(median_diameter_um), float(diameter_spread),
                   float(np.tan(np.radians(spread_deg))), np.atleast_1d(np.asarray(flake_reflectance, float)),
                   float(n))

    @property
    def orientation_spread_deg(self) -> float:
        return float(np.degrees(np.arctan(self.alpha)))

    def diameter_moment_um(self, k: int) -> float:
        """:math:`E[d^k]` in µmᵏ."""
        return float(self.median_diameter_um ** k * np.exp(0.5 * (k * self.diameter_spread) ** 2))

    @property
    def mean_area_um2(self) -> float:
        """:math:`\\bar a = π E[d^2] / 4`."""
        return float(np.pi / 4 * self.diameter_moment_um(2))

    @property
    def mean_area_squared_um4(self) -> float:
        """:math:`E[a^2] = (π/4)^2 E[d^4]`."""
        return float((np.pi / 4) ** 2 * self.diameter_moment_um(4))

    @property
    def coverage(self) -> float:
        """Area fraction :math:`ρ_A \\bar a` (may exceed 1 for stacked flakes)."""
        return self.density_per_mm2 * self.mean_area_um2 * 1e-6

    def visible_share(self, u, l_in=None, v_in=None) -> np.ndarray:
        """Visible share :math:`s(u)` of a glint with a fraction ``u`` of the flakes above it, for
        the directions inside the coat ``l_in``, ``v_in`` (default: both along the normal)."""
        u = np.asarray(u, float)
        if l_in is None:
            kappa = 1.0
        else:
            l_in, v_in = np.asarray(l_in, float), np.asarray(v_in, float)
            dt = (l_in[..., :2] / np.clip(l_in[..., 2:3], 1e-6, None)
                  - v_in[..., :2] / np.clip(v_in[..., 2:3], 1e-6, None))
            x = np.clip(u * self.layer_um / 2 * np.linalg.norm(dt, axis=-1)
                        / self.diameter_moment_um(1), 0.0, 1.0)
            kappa = 2 / np.pi * (np.arccos(x) - x * np.sqrt(1 - x * x))
        return np.exp(-self.coverage * u * (2.0 - kappa))

    def visibility(self, l_in=None, v_in=None) -> np.ndarray:
        """Mean visible share :math:`V = \\int_0^1 s(u) du` (module docstring), midpoint rule."""
        u = (np.arange(64) + 0.5) / 64
        if l_in is None:
            return float(self.visible_share(u).mean())
        l_in, v_in = np.asarray(l_in, float), np.asarray(v_in, float)
        return self.visible_share(u, l_in[..., None, :], v_in[..., None, :]).mean(-1)

    def normal_pdf(self, m) -> np.ndarray:
        return beckmann_normal_pdf(m, self.alpha)

    def glint_probability(self, l, v, omega_sr) -> np.ndarray:
        """Probability that a flake glints toward ``v`` under a small lamp of solid angle
        ``omega_sr`` in direction ``l`` (both in air, unit, z up); closed form of the module
        docstring."""
        l, v = np.asarray(l, float), np.asarray(v, float)
        li, vi = refract_into_coat(l, self.n), refract_into_coat(v, self.n)
        h = half_vector(li, vi)
        omega_in = np.asarray(omega_sr, float) * l[..., 2] / (self.n ** 2 * np.clip(li[..., 2], 1e-9, None))
        omega_h = omega_in / (4.0 * np.clip((li * h).sum(-1), 1e-9, None))
        return self.normal_pdf(h) * omega_h

    def glint_radiance_factor(self, l, v) -> np.ndarray:
        """Radiance of a glinting flake over the lamp's radiance, per band:
        :math:`ρ_f T(θ_l) T(θ_v)`."""
        l, v = np.asarray(l, float), np.asarray(v, float)
        t = fresnel_transmittance(l[..., 2], self.n) * fresnel_transmittance(v[..., 2], self.n)
        return np.asarray(t)[..., None] * self.flake_reflectance

    def mean_reflectance_factor(self, l, v) -> np.ndarray:
        """:math:`π V f_{flakes}` per band (the flakes' mean lobe with their visibility, module
        docstring)."""
        l, v = np.asarray(l, float), np.asarray(v, float)
        li, vi = refract_into_coat(l, self.n), refract_into_coat(v, self.n)
        h = half_vector(li, vi)
        t = fresnel_transmittance(l[..., 2], self.n) * fresnel_transmittance(v[..., 2], self.n)
        k = (t / self.n ** 2 * self.coverage * self.visibility(li, vi) * self.normal_pdf(h) * np.pi
             / (4.0 * np.clip(li[..., 2], 1e-9, None) * np.clip(vi[..., 2], 1e-9, None)))
        return np.asarray(k)[..., None] * self.flake_reflectance

    def to_json(self) -> dict:
        return {"density_per_mm2": self.density_per_mm2, "median_diameter_um": self.median_diameter_um,
                "diameter_spread": self.diameter_spread, "orientation_spread_deg": self.orientation_spread_deg,
                "alpha": self.alpha, "flake_reflectance": np.asarray(self.flake_reflectance).tolist(),
                "refractive_index": self.n, "coverage": self.coverage}
