"""
A rough dielectric slab: two GGX interfaces with the light bouncing between them.

A diffuser plate declared with ``scattering: {type: roughness, roughness: r}`` is a slab of
refractive index ``n`` whose two faces are rough in the sense of Walter, Marschner, Li and
Torrance (2007), "Microfacet models for refraction through rough surfaces" (EGSR 2007):
microfacets with the GGX distribution of width :math:`α = r^2` (as in Blender's Glass BSDF and
Mitsuba 3's ``roughdielectric``)

.. math::

    D(m) = \\frac{α^2}{π \\cos^4θ_m\\,(α^2 + \\tan^2θ_m)^2},

separable Smith shadowing–masking :math:`G = G_1(i)\\,G_1(o)` with

.. math:: G_1(v) = \\frac{2}{1 + \\sqrt{1 + α^2 \\tan^2θ_v}},

and the exact unpolarised Fresnel reflectance :math:`F(i·m)` of each microfacet.  One
interface scatters light arriving from :math:`i` into :math:`o` with Walter's BSDF

.. math::

    f_r = \\frac{F\\,G\\,D}{4\\,|i·n|\\,|o·n|}, \\qquad
    f_t = \\frac{|i·m|\\,|o·m|}{|i·n|\\,|o·n|}
          \\frac{n_o^2\\,(1-F)\\,G\\,D}{(n_i\\,(i·m) + n_o\\,(o·m))^2}.

The slab is what light does between two such interfaces (the faces are parallel; the plate
is thin, so a path's lateral displacement inside it is neglected).  Its bidirectional
transmittance :math:`f_T(ω_i, ω_o)` (light entering the top, leaving the bottom) and its
reflectance are integrals over every number of internal bounces, which this module computes
by Monte Carlo: photons enter with direction :math:`ω_i`, each interface samples a microfacet
normal from the distribution of visible normals :math:`D_v(m) = G_1(v) \\max(0, v·m) D(m)/(v·n)`
(Heitz 2018, "Sampling the GGX distribution of visible normals"); the reflected part carries
the weight :math:`F\\,G_1(o_r)` and the refracted part :math:`(1-F)\\,G_1(o_t)`
(:func:`interface_split`).  That is the expected value of the estimator of Mitsuba 3's
``roughdielectric`` (which picks one of the two with probability :math:`F`), an unbiased
estimator of Walter's BSDF.  The weight lost to :math:`G_1` and to directions on the wrong
side of a face (light the single-scattering microfacet model does not return) is tallied as
:math:`A_\\text{mf}`, so that for a non-absorbing slab

.. math:: T(μ_i) + R(μ_i) + A_\\text{mf}(μ_i) = 1

per incident direction (:math:`μ = \\cos θ`).

Absorption: a declared transmittance :math:`T_\\text{decl}(λ)` below the clear slab's
:math:`T_0 = (1-R_0)/(1+R_0)` is bulk absorption applied as a factor
:math:`a = \\sqrt{T_\\text{decl}/T_0}` on each *refraction* (the convention of the Mitsuba
truth, :mod:`lbscene.engine.truth.mitsuba`).  Light transmitted through the slab refracts
exactly twice and light reflected by it either never (the first face) or twice, so

.. math::

    f_T(a) = a^2 f_T, \\qquad R(a) = R_\\text{top} + a^2 R_\\text{int},

and the tables here are computed once per :math:`(α, n)` for :math:`a = 1`; the spectral
factor :math:`a^2 = T_\\text{decl}(λ)/T_0` multiplies them.

Tabulated (per incidence node :math:`μ_i`, :data:`THETA_I_DEG`):

* directional transmittance :math:`T(μ_i) = \\int f_T \\cos θ_o\\, dω_o`, reflectance split
  into :math:`R_\\text{top}` and :math:`R_\\text{int}`, loss :math:`A_\\text{mf}`;
* the transmitted lobe's angular widths: half-angles around the straight-through direction
  (the regular direction of a slab with parallel faces is the incident one) holding 50 % and
  90 % of the transmitted light;
* the BTDF on a grid of exit directions (:math:`θ_o` bins of :data:`BIN_THETA_DEG`,
  :math:`Δφ` bins of :data:`BIN_PHI_DEG`, symmetric in :math:`±Δφ`):
  :math:`f_T ≈ \\text{fraction in bin} / \\int_\\text{bin} \\cos θ_o\\, dω_o` — meaningful for
  lobes wider than a bin (see :attr:`RoughSlab.lobe_90_deg`).

Limits (tested): :math:`α → 0` gives the clear slab
(:func:`fresnel_slab_transmittance`), energy is conserved,
the BTDF is reciprocal, :math:`f_T(ω_i, ω_o) = f_T(ω_o, ω_i)`.

The hemispherical transmittance of diffuse (Lambertian) light is
:math:`T_h = 2 \\int_0^1 T(μ)\\, μ\\, dμ`.

Examples
--------
>>> s = rough_slab(0.09, 1.49)                                           # doctest: +SKIP
>>> s.transmittance(np.array([1.0, 0.5]))                               # doctest: +SKIP
array([0.92..., 0.89...])
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import numpy as np

from lbscene.engine.light.geometry import gauss_legendre

__all__ = ["RoughSlab", "rough_slab", "per_refraction_factor", "clear_slab_normal_transmittance",
           "fresnel_slab_transmittance",
           "interface_split", "THETA_I_DEG", "BIN_THETA_DEG", "BIN_PHI_DEG", "EXIT_PHI_STEPS", "PHOTONS",
           "MAX_EVENTS",
           "SHIPPED_PLATES", "SHIPPED_TABLES_DIR", "shipped_table_path", "write_shipped_table"]

#: incidence angles of the table (degrees); 90° is the limit T = 0
THETA_I_DEG = np.r_[np.arange(0.0, 88.0, 2.0), 88.0, 89.0, 89.75]
#: width of the exit-angle bins of the tabulated BTDF (degrees)
BIN_THETA_DEG = 2.0
#: width of the azimuth bins of the tabulated BTDF (degrees, over 0..180)
BIN_PHI_DEG = 10.0
#: photons per incidence node (the expected-value estimator leaves only the microfacet sampling's
#: variance: T's standard error is below 0.05 % for roughness ≤ 0.3).  The BTDF's bins hold a few
#: hundredths of them each: a plate cell's exit radiance sums the table over many incoming
#: directions, and the table's noise did not average out at 16 000 (α 0.3 under a uniform sky:
#: the radiance leaving at θ_o was 2 % off T(θ_o) at some angles, the reciprocal value; ±0.4 %
#: at 128 000; tested in tests/engine/test_rough_slab.py)
PHOTONS = 128_000
#: interface events a photon may have inside the slab before what it carries is counted as lost
#: (trapped light; the tally records how much)
MAX_EVENTS = 400
#: a photon whose weight falls below this stops (its weight is counted as lost)
MIN_WEIGHT = 1e-3
#: version of the computation (part of the cache key)
_FORMAT = "rough-slab-2"
#: plates whose tables travel with lbscene (``(roughness, ior)``; α = roughness²): the shipped
#: booths' glass plate, common PMMA / glass diffusers and the roughness grid of the diagnosis'
#: rough-plate hypothesis (``diffuser_plate``, ior 1.5), so that the first evaluation of a booth
#: with one of them does not pay the Monte Carlo (≈ 15–30 s; roughness 0.5477 is GGX α 0.3).  Made by
#: ``scripts/gen_rough_slab_tables.py``; a test checks they are current.
SHIPPED_PLATES = ((0.04, 1.52), (0.1, 1.52), (0.2, 1.52),
                  (0.01, 1.49), (0.04, 1.49), (0.05, 1.49), (0.1, 1.49), (0.2, 1.49), (0.3, 1.49), (0.5, 1.49),
                  (0.5477, 1.49), (0.7, 1.49),
                  (0.04, 1.5), (0.05, 1.5), (0.1, 1.5), (0.2, 1.5), (0.35, 1.5), (0.5, 1.5))
#: where the shipped tables live (package data)
SHIPPED_TABLES_DIR = Path(__file__).resolve().parent / "data" / "rough_slab"
#: azimuths of :meth:`RoughSlab.exit_radiance_grid` (a 5° step; the table's bins are 10°)
EXIT_PHI_STEPS = 72


def fresnel_slab_transmittance(cos_i: np.ndarray, ior: float) -> np.ndarray:
    """Unpolarised transmittance of a non-absorbing plate (two interfaces, multiple reflections)."""
    cos_i = np.clip(np.asarray(cos_i, float), 0.0, 1.0)
    sin_t = np.sqrt(np.clip(1.0 - cos_i ** 2, 0.0, None)) / ior
    cos_t = np.sqrt(np.clip(1.0 - sin_t ** 2, 0.0, None))
    with np.errstate(divide="ignore", invalid="ignore"):
        rs = ((cos_i - ior * cos_t) / (cos_i + ior * cos_t)) ** 2
        rp = ((ior * cos_i - cos_t) / (ior * cos_i + cos_t)) ** 2
    rs = np.where(cos_i > 0, rs, 1.0)
    rp = np.where(cos_i > 0, rp, 1.0)
    ts = (1 - rs) / (1 + rs)      # slab with incoherent multiple reflections
    tp = (1 - rp) / (1 + rp)
    return 0.5 * (ts + tp)


def clear_slab_normal_transmittance(ior: float) -> float:
    """:math:`T_0 = (1-R_0)/(1+R_0)`, :math:`R_0 = ((n-1)/(n+1))^2`: a clear non-absorbing slab
    at normal incidence (incoherent multiple reflections)."""
    r = ((ior - 1.0) / (ior + 1.0)) ** 2
    return (1.0 - r) / (1.0 + r)


def per_refraction_factor(transmittance, ior: float) -> np.ndarray:
    """:math:`a = \\sqrt{T_\\text{decl}/T_0}` clipped to [0, 1]: the absorption factor applied on
    each refraction so that the clear slab transmits the declared value at normal incidence."""
    t = np.asarray(transmittance, float)
    return np.sqrt(np.clip(t / clear_slab_normal_transmittance(ior), 0.0, 1.0))


# --------------------------------------------------------------------------- one interface

def _g1(cos_v: np.ndarray, alpha: float) -> np.ndarray:
    """Smith's GGX masking :math:`G_1 = 2/(1+\\sqrt{1+α^2\\tan^2θ})`."""
    c2 = np.clip(cos_v * cos_v, 1e-300, 1.0)
    return 2.0 / (1.0 + np.sqrt(1.0 + alpha * alpha * (1.0 - c2) / c2))


def _sample_visible_normal(v: np.ndarray, alpha: float, u1: np.ndarray, u2: np.ndarray) -> np.ndarray:
    """GGX microfacet normals distributed as :math:`D_v(m)` for ``v`` (N, 3) with v_z > 0
    (Heitz 2018, listing 1)."""
    vh = np.stack([alpha * v[:, 0], alpha * v[:, 1], v[:, 2]], axis=1)
    vh /= np.linalg.norm(vh, axis=1, keepdims=True)
    lensq = vh[:, 0] ** 2 + vh[:, 1] ** 2
    inv = np.where(lensq > 0, 1.0 / np.sqrt(np.maximum(lensq, 1e-300)), 0.0)
    t1 = np.where(lensq[:, None] > 0, np.stack([-vh[:, 1] * inv, vh[:, 0] * inv, np.zeros_like(inv)], 1),
                  np.array([1.0, 0.0, 0.0]))
    t2 = np.cross(vh, t1)
    r = np.sqrt(u1)
    phi = 2.0 * np.pi * u2
    p1 = r * np.cos(phi)
    p2 = r * np.sin(phi)
    s = 0.5 * (1.0 + vh[:, 2])
    p2 = (1.0 - s) * np.sqrt(np.clip(1.0 - p1 * p1, 0.0, None)) + s * p2
    nh = (p1[:, None] * t1 + p2[:, None] * t2
          + np.sqrt(np.clip(1.0 - p1 * p1 - p2 * p2, 0.0, None))[:, None] * vh)
    m = np.stack([alpha * nh[:, 0], alpha * nh[:, 1], np.maximum(nh[:, 2], 1e-9)], axis=1)
    return m / np.linalg.norm(m, axis=1, keepdims=True)


def _fresnel(cos_i: np.ndarray, eta: float) -> tuple[np.ndarray, np.ndarray]:
    """Unpolarised Fresnel reflectance at a microfacet (``cos_i`` = v·m > 0, ``eta`` =
    n_transmitted / n_incident) and the refracted cosine (0 under total internal reflection)."""
    s2 = (1.0 - cos_i * cos_i) / (eta * eta)
    ct2 = 1.0 - s2
    tir = ct2 <= 0
    ct = np.sqrt(np.clip(ct2, 0.0, None))
    rs = ((cos_i - eta * ct) / np.maximum(cos_i + eta * ct, 1e-300)) ** 2
    rp = ((eta * cos_i - ct) / np.maximum(eta * cos_i + ct, 1e-300)) ** 2
    return np.where(tir, 1.0, 0.5 * (rs + rp)), ct


def interface_split(v: np.ndarray, alpha: float, eta: float, rng: np.random.Generator):
    """One scattering by a rough interface, in the frame whose +z is the face's normal on the
    side of ``v`` (the unit direction toward where the light came from, v_z > 0; ``eta`` =
    n beyond the face / n on the side of ``v``).

    A microfacet normal :math:`m` is sampled from :math:`D_v(m)` and *both* outcomes are kept
    with their expected weights (no random choice between them):

    .. math::

        o_r = 2 (v·m) m - v,\\quad w_r = F(v·m)\\,G_1(o_r); \\qquad
        o_t = \\text{refract}(v, m),\\quad w_t = (1 - F(v·m))\\,G_1(o_t),

    each 0 where its direction lies on the wrong side of the macro-surface (light the
    single-scattering model loses).  :math:`E[w_r]` and :math:`E[w_t]` are the interface's
    directional reflectance and transmittance.

    Returns ``(o_r, w_r, o_t, w_t)``.
    """
    n = len(v)
    m = _sample_visible_normal(v, alpha, rng.random(n), rng.random(n))
    c = np.clip(np.einsum("ij,ij->i", v, m), 0.0, 1.0)
    F, ct = _fresnel(c, eta)
    o_r = 2.0 * c[:, None] * m - v
    o_r /= np.linalg.norm(o_r, axis=1, keepdims=True)
    w_r = np.where(o_r[:, 2] > 0, F * _g1(o_r[:, 2], alpha), 0.0)
    o_t = -v / eta + (c / eta - ct)[:, None] * m
    o_t /= np.maximum(np.linalg.norm(o_t, axis=1, keepdims=True), 1e-300)
    w_t = np.where((o_t[:, 2] < 0) & (F < 1.0), (1.0 - F) * _g1(o_t[:, 2], alpha), 0.0)
    return o_r, w_r, o_t, w_t


# --------------------------------------------------------------------------- the slab

def _simulate(alpha: float, ior: float, photons: int, seed: int, theta_deg=THETA_I_DEG) -> np.ndarray:
    """Monte Carlo of the slab for every incidence angle of ``theta_deg``; one flat float array:
    per angle ``[T, R_top, R_int, A_mf, lobe_50_deg, lobe_90_deg, btdf (n_θ × n_φ)]``.

    Each photon follows the refracted branch through the top face and then, inside, the
    reflected branch at every face, the light leaving the slab at each event being tallied
    with its expected weight (:func:`interface_split`): the Fresnel choice adds no variance,
    and a smooth slab's tallies are exact.  A photon stops when its weight falls below
    :data:`MIN_WEIGHT` or after :data:`MAX_EVENTS` events, and all stop when they carry less
    than :data:`MIN_WEIGHT` / 100 of the light that entered; what they still carry is counted in
    :math:`A_\\text{mf}` (trapped light)."""
    rng = np.random.default_rng(seed)
    edges_t = np.deg2rad(np.arange(0.0, 90.0 + 1e-9, BIN_THETA_DEG))
    edges_p = np.deg2rad(np.arange(0.0, 180.0 + 1e-9, BIN_PHI_DEG))
    # ∫_bin cos θ dω over both signs of Δφ
    proj = 0.5 * np.diff(np.sin(edges_t) ** 2)[:, None] * (2.0 * np.diff(edges_p))[None, :]
    th = np.deg2rad(np.asarray(theta_deg, float))
    K = len(th)
    D0 = np.stack([np.sin(th), np.zeros(K), -np.cos(th)], axis=1)      # propagation, downward
    # every incidence angle in one batch: photon j belongs to angle node[j]
    node = np.repeat(np.arange(K), photons)
    # top face from outside: frame +z up, v = -d
    o_r, w_r, o_t, w_t = interface_split(-D0[node], alpha, ior, rng)
    R_top = np.bincount(node, w_r, K)
    A = photons - R_top - np.bincount(node, w_t, K)
    live = w_t > 0
    d, wt, nd = o_t[live], w_t[live], node[live]
    R_int = np.zeros(K)
    T_dirs, T_w, T_n = [], [], []
    for _ in range(MAX_EVENTS):
        if wt.sum() < MIN_WEIGHT * 1e-2 * photons:
            break                                               # the rest is counted as lost
        down = d[:, 2] < 0
        # the face the photon reaches, in the frame whose +z faces the photon (inside: +z toward
        # the glass); moving up flips z
        vv = -d
        vv[~down, 2] *= -1.0
        o_r, w_r, o_t, w_t = interface_split(vv, alpha, 1.0 / ior, rng)
        o_r[~down, 2] *= -1.0                                   # back to the world frame
        out_w = wt * w_t
        A += np.bincount(nd, wt * (1.0 - w_r - w_t), K)
        R_int += np.bincount(nd[~down], out_w[~down], K)
        esc = down & (out_w > 0)
        T_dirs.append(o_t[esc])
        T_w.append(out_w[esc])
        T_n.append(nd[esc])
        wt = wt * w_r
        keep = wt > MIN_WEIGHT
        A += np.bincount(nd[~keep], wt[~keep], K)
        d, wt, nd = o_r[keep], wt[keep], nd[keep]
    A += np.bincount(nd, wt, K)                                 # trapped beyond MAX_EVENTS
    od = np.concatenate(T_dirs)
    ow = np.concatenate(T_w)
    on = np.concatenate(T_n)
    rows = []
    for k in range(K):
        sel = on == k
        odk, owk = od[sel], ow[sel]
        T = owk.sum()
        # lobe widths around the straight-through direction
        ang = np.rad2deg(np.arccos(np.clip(odk @ D0[k], -1.0, 1.0)))
        if T > 0:
            order = np.argsort(ang)
            cw = np.cumsum(owk[order]) / T
            l50 = float(ang[order][min(np.searchsorted(cw, 0.5), len(cw) - 1)])
            l90 = float(ang[order][min(np.searchsorted(cw, 0.9), len(cw) - 1)])
        else:
            l50 = l90 = 0.0
        th_o = np.arccos(np.clip(-odk[:, 2], 0.0, 1.0))
        ph_o = np.abs(np.arctan2(odk[:, 1], odk[:, 0]))        # Δφ from the plane of incidence
        H, _, _ = np.histogram2d(th_o, ph_o, bins=(edges_t, edges_p), weights=owk)
        btdf = H / photons / proj
        rows.append(np.r_[T / photons, R_top[k] / photons, R_int[k] / photons, A[k] / photons, l50, l90,
                          btdf.ravel()])
    return np.concatenate(rows)


@dataclass(frozen=True)
class RoughSlab:
    """The tabulated slab of :func:`rough_slab` (non-absorbing: multiply by :math:`a^2`)."""

    alpha: float
    ior: float
    cos_i: np.ndarray            # (K,) incidence nodes, decreasing (θ increasing)
    T: np.ndarray                # (K,) directional transmittance
    R_top: np.ndarray            # (K,) reflected by the first face
    R_int: np.ndarray            # (K,) reflected after entering (refracted twice)
    A_mf: np.ndarray             # (K,) lost by the single-scattering microfacet model
    lobe_50_deg: np.ndarray      # (K,) half-angle holding 50 % of the transmitted light
    lobe_90_deg: np.ndarray      # (K,) ... 90 %
    btdf_table: np.ndarray       # (K, n_θo, n_Δφ) 1/sr

    def _interp(self, y, cos_i, at_90=0.0):
        """Linear in θ_i between the nodes; ``at_90``: the value at grazing incidence."""
        th = np.rad2deg(np.arccos(np.clip(np.asarray(cos_i, float), 0.0, 1.0)))
        return np.interp(th, np.r_[THETA_I_DEG, 90.0], np.r_[y, at_90])

    def transmittance(self, cos_i, absorption: float | np.ndarray = 1.0) -> np.ndarray:
        """Directional-hemispherical transmittance :math:`a^2 T(μ_i)` (``absorption`` = a)."""
        return np.asarray(absorption, float) ** 2 * self._interp(self.T, cos_i)

    def reflectance(self, cos_i, absorption: float | np.ndarray = 1.0) -> np.ndarray:
        """Directional-hemispherical reflectance :math:`R_\\text{top} + a^2 R_\\text{int}`."""
        return self._interp(self.R_top, cos_i, at_90=1.0) + np.asarray(absorption, float) ** 2 * \
            self._interp(self.R_int, cos_i)

    def loss(self, cos_i) -> np.ndarray:
        """:math:`A_\\text{mf}(μ_i)`: light the microfacet model loses (non-absorbing slab)."""
        return self._interp(self.A_mf, cos_i, at_90=float(self.A_mf[-1]))

    def lobe_deg(self, cos_i, fraction: float = 0.9) -> np.ndarray:
        """Half-angle of the transmitted lobe around the incident direction holding 50 % or
        90 % (``fraction``) of the transmitted light."""
        y = {0.5: self.lobe_50_deg, 0.9: self.lobe_90_deg}[fraction]
        return self._interp(y, cos_i, at_90=float(y[-1]))

    def hemispherical_transmittance(self, absorption: float | np.ndarray = 1.0) -> np.ndarray:
        """Transmittance of Lambertian light, :math:`T_h = 2\\int_0^1 a^2 T(μ) μ\\, dμ`
        (Gauss–Legendre in μ on the interpolated table)."""
        x, w = gauss_legendre(64)
        mu = 0.5 * (x + 1.0)
        return np.asarray(absorption, float) ** 2 * float(np.sum(w * 0.5 * 2.0 * self.transmittance(mu) * mu))

    def hemispherical_reflectance(self, absorption: float | np.ndarray = 1.0) -> np.ndarray:
        """Reflectance of Lambertian light, :math:`2\\int_0^1 R(μ) μ\\, dμ`."""
        x, w = gauss_legendre(64)
        mu = 0.5 * (x + 1.0)
        return np.asarray([float(np.sum(w * self.reflectance(mu, a) * mu))
                           for a in np.atleast_1d(absorption)]).reshape(np.shape(absorption))

    def btdf(self, cos_i, cos_o, dphi_rad, absorption: float | np.ndarray = 1.0) -> np.ndarray:
        """:math:`a^2 f_T(θ_i, θ_o, Δφ)` (1/sr), linear in θ_i between nodes and piecewise
        constant over the exit bins; broadcasts its arguments."""
        th_i = np.rad2deg(np.arccos(np.clip(np.asarray(cos_i, float), 0.0, 1.0)))
        th_o = np.rad2deg(np.arccos(np.clip(np.asarray(cos_o, float), 0.0, 1.0)))
        ph = np.rad2deg(np.abs(np.asarray(dphi_rad, float)))
        ph = np.where(ph > 180.0, 360.0 - ph, ph)
        nt, npf = self.btdf_table.shape[1:]
        jo = np.clip((th_o / BIN_THETA_DEG).astype(int), 0, nt - 1)
        jp = np.clip((ph / BIN_PHI_DEG).astype(int), 0, npf - 1)
        k = np.clip(np.searchsorted(THETA_I_DEG, th_i, side="right") - 1, 0, len(THETA_I_DEG) - 2)
        t = np.clip((th_i - THETA_I_DEG[k]) / (THETA_I_DEG[k + 1] - THETA_I_DEG[k]), 0.0, 1.0)
        f = (1.0 - t) * self.btdf_table[k, jo, jp] + t * self.btdf_table[k + 1, jo, jp]
        return np.asarray(absorption, float) ** 2 * f

    def exit_radiance_grid(self, cos_i, phi_i_rad, weights, n_phi: int = EXIT_PHI_STEPS) -> np.ndarray:
        """:math:`L_c(j_o, φ_g) = \\sum_n f_T(θ_{i,cn}, θ_o \\in j_o, φ_g - φ_{i,cn})\\, w_{cn}`
        (1/sr times the weights' unit), ``(C, n_θo, n_phi)``: per group ``c`` (a plate cell), light
        arriving from ``N`` directions ``(cos_i, phi_i_rad)`` (C, N) with weights ``weights``
        (C, N), leaving in each exit-angle bin of the table and toward ``n_phi`` azimuths
        :math:`φ_g = -π + 2πg/n_φ` (:meth:`exit_radiance_at` reads it for any direction).

        The sum is a circular convolution in azimuth: each incoming direction's weight is split
        linearly in θ_i between two table nodes and in azimuth between two grid azimuths,
        giving per cell a histogram :math:`H_c(k, b)`; then
        :math:`L_c(j_o, g) = \\sum_k \\sum_b H_c(k, b)\\, κ_k(j_o, g - b)` with the kernel
        :math:`κ_k(j_o, d)` the table's :math:`f_T` at :math:`Δφ = 2πd/n_φ`, averaged over the
        same hat (the grid's linear split) — computed with FFTs, so the cost does not grow with
        the number of receivers that later look at the plate.  Against the direct sum over
        ``N`` × receivers: a blur of the azimuth by a grid step (5°; the table's bins are 10°)."""
        w = np.asarray(weights, float)
        C, N = w.shape
        nt = self.btdf_table.shape[1]
        if N == 0 or C == 0:
            return np.zeros((C, nt, n_phi))
        th_i = np.rad2deg(np.arccos(np.clip(np.asarray(cos_i, float), 0.0, 1.0)))          # (C, N)
        k = np.clip(np.searchsorted(THETA_I_DEG, th_i, side="right") - 1, 0, len(THETA_I_DEG) - 2)
        t = np.clip((th_i - THETA_I_DEG[k]) / (THETA_I_DEG[k + 1] - THETA_I_DEG[k]), 0.0, 1.0)
        b0, b1, fr = _azimuth_split(phi_i_rad, n_phi)
        # the θ_i nodes this light uses (a plate under tubes: a few dozen of the table's)
        used = np.zeros(len(THETA_I_DEG), bool)
        used[np.unique(k)] = True
        used[np.unique(k) + 1] = True
        nodes = np.nonzero(used)[0]
        pos = np.full(len(THETA_I_DEG), -1)
        pos[nodes] = np.arange(len(nodes))
        Kc = len(nodes)
        row = np.arange(C)[:, None] * (Kc * n_phi)
        H = np.zeros(C * Kc * n_phi)
        for kk, wk in ((pos[k], 1.0 - t), (pos[k + 1], t)):
            for bb, wb in ((b0, 1.0 - fr), (b1, fr)):
                H += np.bincount((row + kk * n_phi + bb).ravel(), (w * wk * wb).ravel(),
                                 minlength=H.size)
        Hf = np.fft.rfft(H.reshape(C, Kc, n_phi), axis=-1)                                 # (C, Kc, W)
        Kf = np.fft.rfft(self._azimuth_kernel(n_phi)[nodes], axis=-1)                      # (Kc, nt, W)
        return np.fft.irfft(np.einsum("ckw,kjw->cjw", Hf, Kf), n=n_phi, axis=-1)

    def _azimuth_kernel(self, n_phi: int) -> np.ndarray:
        """:math:`κ_k(j_o, d)` ``(K, n_θo, n_phi)``: :meth:`btdf` at each incidence node, in the
        middle of each exit bin, at :math:`Δφ = 2πd/n_φ`, averaged over a hat one grid step wide
        on either side (16 points)."""
        nt = self.btdf_table.shape[1]
        step = 2.0 * np.pi / n_phi
        s = (np.arange(16) + 0.5) / 16 * 2.0 - 1.0                                         # (−1, 1)
        hat = (1.0 - np.abs(s)) / np.sum(1.0 - np.abs(s))
        dphi = np.arange(n_phi)[:, None] * step + s[None, :] * step                        # (n, 16)
        cos_o = np.cos(np.deg2rad((np.arange(nt) + 0.5) * BIN_THETA_DEG))
        f = self.btdf(self.cos_i[:, None, None, None], cos_o[None, :, None, None], dphi[None, None])
        return np.einsum("kjds,s->kjd", f, hat)

    @staticmethod
    def exit_radiance_at(grid, cos_o, phi_o_rad) -> np.ndarray:
        """``(C, M, …)`` values of an :meth:`exit_radiance_grid` ``(C, n_θo, n_phi, …)`` (trailing
        axes: several grids at once, a plate's terms) toward ``M`` directions per group
        ``(cos_o, phi_o_rad)`` (C, M): the exit bin holding θ_o (the table's own resolution),
        linear between the two nearest grid azimuths."""
        C, nt, n_phi = grid.shape[:3]
        th_o = np.rad2deg(np.arccos(np.clip(np.asarray(cos_o, float), 0.0, 1.0)))
        jo = np.clip((th_o / BIN_THETA_DEG).astype(int), 0, nt - 1)                        # (C, M)
        g0, g1, fr = _azimuth_split(phi_o_rad, n_phi)
        fr = fr.reshape(fr.shape + (1,) * (grid.ndim - 3))
        c = np.arange(C)[:, None]
        return (1.0 - fr) * grid[c, jo, g0] + fr * grid[c, jo, g1]


def _azimuth_split(phi_rad, n_phi: int):
    """The two grid azimuths :math:`φ_g = -π + 2πg/n_φ` around each azimuth ``phi_rad`` and its
    linear weight toward the second: ``(g0, g1, fraction)``."""
    x = (np.asarray(phi_rad, float) + np.pi) * (n_phi / (2.0 * np.pi))
    g0 = np.floor(x)
    fr = x - g0
    g0 = g0.astype(int) % n_phi
    return g0, (g0 + 1) % n_phi, fr


def _shape():
    nt = int(round(90.0 / BIN_THETA_DEG))
    npf = int(round(180.0 / BIN_PHI_DEG))
    return nt, npf


def _table_meta(alpha: float, ior: float, photons: int, seed: int) -> str:
    """What a table was computed with (a shipped table is used only when all of it matches)."""
    return (f"{_FORMAT}|alpha={float(alpha)!r}|ior={float(ior)!r}|photons={int(photons)}|seed={int(seed)}"
            f"|bins={BIN_THETA_DEG!r},{BIN_PHI_DEG!r}|events={MAX_EVENTS}|weight={MIN_WEIGHT!r}"
            f"|theta={','.join(f'{t:g}' for t in THETA_I_DEG)}")


def shipped_table_path(roughness: float, ior: float, folder: Path | None = None) -> Path:
    """The file of a shipped plate's table: ``r<roughness>-n<ior>.npz``."""
    return Path(folder or SHIPPED_TABLES_DIR) / f"r{float(roughness):g}-n{float(ior):g}.npz"


def write_shipped_table(roughness: float, ior: float, folder: Path | None = None) -> Path:
    """Compute the table of the plate (``roughness``, ``ior``) with the default photons and seed
    and write it (compressed ``.npz``: the flat table and its :func:`_table_meta`)."""
    alpha = float(roughness) ** 2
    path = shipped_table_path(roughness, ior, folder)
    path.parent.mkdir(parents=True, exist_ok=True)
    flat = _simulate(alpha, float(ior), PHOTONS, 0)
    tmp = path.with_name(path.name + ".tmp.npz")
    np.savez_compressed(tmp, table=flat, meta=np.array(_table_meta(alpha, ior, PHOTONS, 0)))
    tmp.replace(path)
    return path


def _shipped(alpha: float, ior: float, photons: int, seed: int) -> np.ndarray | None:
    """The shipped table for exactly this computation, or None."""
    if photons != PHOTONS or seed != 0:
        return None
    for r, n in SHIPPED_PLATES:
        if np.isclose(r * r, alpha, rtol=1e-9, atol=0.0) and np.isclose(n, ior, rtol=1e-9, atol=0.0):
            path = shipped_table_path(r, n)
            try:
                with np.load(path, allow_pickle=False) as z:
                    if str(z["meta"]) != _table_meta(r * r, n, photons, seed):
                        return None                             # made by another version: compute
                    return np.array(z["table"], float)
            except (OSError, KeyError, ValueError):
                return None
    return None


@lru_cache(maxsize=16)
def rough_slab(alpha: float, ior: float, *, photons: int = PHOTONS, seed: int = 0) -> RoughSlab:
    """The slab of GGX width ``alpha`` and refractive index ``ior``: a shipped table
    (:data:`SHIPPED_PLATES`) when there is one for exactly this computation, else computed once
    and kept in the disk cache (:func:`~lbscene.engine.files.disk_cache.cached_array`)."""
    from lbscene.engine.files.disk_cache import cached_array

    nt, npf = _shape()
    K = len(THETA_I_DEG)
    width = 6 + nt * npf
    flat = _shipped(float(alpha), float(ior), int(photons), int(seed))
    if flat is None or flat.shape != (K * width,):
        flat = cached_array("rough_slab", (THETA_I_DEG,),
                            (_FORMAT, float(alpha), float(ior), int(photons), int(seed), BIN_THETA_DEG,
                             BIN_PHI_DEG, MAX_EVENTS),
                            lambda: _simulate(float(alpha), float(ior), int(photons), int(seed)),
                            shape=(K * width,))
    tab = flat.reshape(K, width)
    return RoughSlab(float(alpha), float(ior), np.cos(np.deg2rad(THETA_I_DEG)), tab[:, 0], tab[:, 1],
                     tab[:, 2], tab[:, 3], tab[:, 4], tab[:, 5], tab[:, 6:].reshape(K, nt, npf))
