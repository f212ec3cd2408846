"""The opal slab's plane-parallel solution (:mod:`lbscene.bakers.opal_slab`) against closed forms,
a Monte Carlo simulation of the layer written here, and Mitsuba 3's measured plates.

Closed forms: the clear slab :math:`(1 - r)/(1 + r)`, a purely absorbing layer, single scattering
in a weakly scattering layer, and flux conservation of a non-absorbing one.  The Monte
Carlo follows photons through the slab (exponential free paths, Henyey–Greenstein directions,
Fresnel faces with total internal reflection) and shares no code with the solver.  The measured
plates are ``tests/data/validation/plate-optics/opal-*.csv`` (Mitsuba's ``plate_optics`` of the
medium recorded in each file's header).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from lbscene.bakers.opal_slab import opal_slab_medium
from lbscene.engine.light.opal_layer import (absorption_depth, fit_asymmetry,
                                      scattered_transmittance_to_normal, slab_optics)

PLATES = Path(__file__).resolve().parents[1] / "data" / "validation" / "plate-optics"


def _r0(n):
    return ((n - 1.0) / (n + 1.0)) ** 2


def _fresnel(mu_out, n):
    """Unpolarised reflectance of a face for light outside at cosine ``mu_out`` (Snell, no TIR)."""
    s2 = (1.0 - mu_out ** 2) / n ** 2
    c = np.sqrt(1.0 - s2)
    rs = ((mu_out - n * c) / (mu_out + n * c)) ** 2
    rp = ((n * mu_out - c) / (n * mu_out + c)) ** 2
    return 0.5 * (rs + rp), c


def _monte_carlo(tau, g, n, cos_theta, photons=400_000, seed=1):
    """(T, R, σ_T): photons through the slab; directions by their cosine to the downward normal.
    ``cos_theta`` ``"diffuse"``: incidence from a uniform sky (cosine-weighted directions)."""
    rng = np.random.default_rng(seed)
    c0 = np.sqrt(rng.random(photons)) if isinstance(cos_theta, str) else np.full(photons, float(cos_theta))
    F0, mu0 = _fresnel(c0, n) if n > 1 else (np.zeros(photons), c0)
    enter = rng.random(photons) >= F0
    R = float((~enter).sum())
    T = 0.0
    z = np.zeros(int(enter.sum()))
    mu = mu0[enter].copy()
    while len(z):
        zn = z + mu * -np.log(rng.random(len(z)))
        below, above = zn >= tau, zn <= 0.0
        hit = below | above
        m = np.abs(mu)
        if n > 1:
            s2 = n * n * (1.0 - m * m)
            c = np.sqrt(np.clip(1.0 - s2, 0.0, None))
            with np.errstate(divide="ignore", invalid="ignore"):
                F = np.where(s2 >= 1.0, 1.0, 0.5 * (((n * m - c) / (n * m + c)) ** 2
                                                    + ((m - n * c) / (m + n * c)) ** 2))
        else:
            F = np.zeros_like(m)
        back = hit & (rng.random(len(z)) < F)
        out = hit & ~back
        T += float((out & below).sum())
        R += float((out & above).sum())
        z = np.where(below, tau, np.where(above, 0.0, zn))
        mu = np.where(back, -mu, mu)
        k = np.nonzero(~hit)[0]
        xi = rng.random(len(k))
        ct = ((1 + g * g - ((1 - g * g) / (1 - g + 2 * g * xi)) ** 2) / (2 * g)) if g else 2 * xi - 1
        phi = 2 * np.pi * rng.random(len(k))
        mk = mu[k]
        mu[k] = np.clip(mk * ct + np.sqrt(np.clip(1 - mk * mk, 0, None) * np.clip(1 - ct * ct, 0, None))
                        * np.cos(phi), -1.0, 1.0)
        z, mu = z[~out], mu[~out]
    T, R = T / photons, R / photons
    return T, R, np.sqrt(T * (1 - T) / photons)


def test_a_slab_without_scattering_is_the_clear_plate():
    for n in (1.0, 1.5):
        T, R = slab_optics(1e-9, 0.5, n, [1.0])
        assert T[0] == pytest.approx((1 - _r0(n)) / (1 + _r0(n)), abs=1e-6)
        assert R[0] == pytest.approx(2 * _r0(n) / (1 + _r0(n)), abs=1e-6)


@pytest.mark.parametrize("n", [1.0, 1.49])
@pytest.mark.parametrize("cos_t", [1.0, 0.5])
def test_a_purely_absorbing_layer_passes_its_regular_light_only(n, cos_t):
    """ω = 0: (1 − F)² e^{−τ/μ_t} / (1 − F² e^{−2τ/μ_t}), F the face's reflectance at the
    incidence, μ_t the refracted cosine."""
    tau = 0.8
    if n > 1:
        F, mu_t = _fresnel(np.array(cos_t), n)
    else:
        F, mu_t = 0.0, cos_t
    e = np.exp(-tau / mu_t)
    T, _ = slab_optics(tau, 0.3, n, [cos_t], albedo=0.0)
    assert T[0] == pytest.approx((1 - F) ** 2 * e / (1 - F * F * e * e), rel=1e-6)


@pytest.mark.parametrize("tau,g,n", [(0.5, 0.0, 1.0), (3.0, 0.6, 1.0), (3.0, 0.9, 1.49), (8.0, 0.3, 1.52)])
def test_a_non_absorbing_layer_conserves_the_light(tau, g, n):
    T, R = slab_optics(tau, g, n, [1.0, 0.7, 0.3])
    np.testing.assert_allclose(T + R, 1.0, atol=2e-5)


@pytest.mark.parametrize("g", [0.0, 0.5, -0.3])
def test_a_weakly_scattering_layer_reflects_by_single_scattering(g):
    """Albedo ω = 10⁻³, normal incidence, no faces: light scattered once at depth t into the
    upward cosine μ turns by cos Θ = −μ, so R = ω ∫₀¹ 2π p(−μ) μ/(1 + μ) (1 − e^{−τ(1 + 1/μ)}) dμ
    with the HG phase p; scattering twice is a fraction ~ω of it."""
    tau, omega = 1.0, 1e-3
    mu = (np.arange(200000) + 0.5) / 200000
    p = (1 - g * g) / (4 * np.pi * (1 + g * g + 2 * g * mu) ** 1.5)
    expected = omega * np.mean(2 * np.pi * p * mu / (1 + mu) * (1 - np.exp(-tau * (1 + 1 / mu))))
    _, R = slab_optics(tau, g, 1.0, [1.0], albedo=omega)
    assert R[0] == pytest.approx(expected, rel=3e-3)


@pytest.mark.parametrize("tau,g,n,cos_t", [(3.04, 0.55, 1.0, 1.0), (3.04, 0.0, 1.0, 0.5),
                                           (2.34, 0.59, 1.49, 1.0), (4.34, 0.18, 1.5, 0.5),
                                           (2.17, 0.76, 1.52, 0.2)])
def test_the_solution_is_the_monte_carlo_layer(tau, g, n, cos_t):
    T_mc, R_mc, se = _monte_carlo(tau, g, n, cos_t)
    T, R = slab_optics(tau, g, n, [cos_t])
    assert abs(T[0] - T_mc) <= 4 * se + 1e-3, (T[0], T_mc, se)
    assert abs(R[0] - R_mc) <= 4 * se + 1e-3, (R[0], R_mc, se)


def _plates():
    out = []
    for f in sorted(PLATES.glob("opal-*.csv")):
        head = {}
        rows = []
        for line in f.read_text().splitlines():
            if line.startswith("# ") and ": " in line:
                k, v = line[2:].split(": ", 1)
                head[k] = v
            elif line and line[0].isdigit():
                rows.append([float(x) for x in line.split(",")])
        out.append(pytest.param(json.loads(head["declaration"]), json.loads(head["mitsuba_medium"]),
                                np.array(rows), id=f.stem))
    return out


@pytest.mark.parametrize("decl,medium,rows", _plates())
def test_mitsubas_measured_plates_are_the_solution(decl, medium, rows):
    """T(θ) and R(θ) to 80° of the medium Mitsuba fitted, as Mitsuba measured them (its σ,
    plus 0.003 for the fit's own spread of the plate measured at each angle)."""
    tau = medium["sigma_t"]["value"] * decl["thickness_mm"]
    T, R = slab_optics(tau, medium["phase"]["g"], decl["ior"], np.cos(np.radians(rows[:, 0])))
    np.testing.assert_array_less(np.abs(T - rows[:, 1]), 4 * rows[:, 2] + 0.003)
    np.testing.assert_array_less(np.abs(R - rows[:, 3]), 4 * rows[:, 4] + 0.003)


@pytest.mark.parametrize("decl,medium,rows", _plates())
def test_the_asymmetry_is_the_one_mitsuba_bisected(decl, medium, rows):
    """Mitsuba's g makes its measured total within about ±0.001 of the declaration; the
    plane-parallel solution's g lies within 0.02 of it (dT/dg ≈ 0.1 to 0.7 here)."""
    m = opal_slab_medium([decl["transmittance"]], decl["scattering"]["diffuse_fraction"], decl["ior"],
                         decl["thickness_mm"])
    assert m.scattering_per_mm == pytest.approx(medium["sigma_t"]["value"], rel=1e-6)
    assert m.anisotropy == pytest.approx(medium["phase"]["g"], abs=0.02)
    assert m.absorption_per_mm == (0.0,)


def test_a_declaration_no_layer_can_meet_is_refused():
    # 0.30 in total with 95 % of it diffuse: even isotropic scattering transmits more
    with pytest.raises(ValueError, match="out of reach"):
        opal_slab_medium([0.30], 0.05, 1.0, 2.0)
    with pytest.raises(ValueError, match="diffuse fraction"):
        opal_slab_medium([0.5], 1.0, 1.5, 2.0)


def test_a_spectral_transmittance_is_absorption_in_the_fitted_medium():
    """The medium scatters as fitted at the most transmissive band; the others absorb, each to
    its declared total (and the Monte Carlo layer with that absorption agrees)."""
    T = [0.50, 0.60, 0.55]
    m = opal_slab_medium(T, 0.92, 1.0, 2.5)
    assert m.fit_band == 1 and m.absorption_per_mm[1] == 0.0
    assert m.absorption_per_mm[0] > m.absorption_per_mm[2] > 0.0
    for t, a in zip(T, m.absorption_per_mm):
        tau = m.optical_depth + a * m.thickness_mm
        got, _ = slab_optics(tau, m.anisotropy, 1.0, [1.0], albedo=m.optical_depth / tau)
        assert got[0] == pytest.approx(t, abs=1e-6)
    assert absorption_depth(0.7, m.optical_depth, m.anisotropy, 1.0) == 0.0


def test_the_kernel_into_the_normal_is_the_layers_scattered_transmittance():
    """Reciprocity: the scattered radiance along the normal under a uniform sky of radiance 1,
    2π ∫ f(μ → 1) μ dμ, is the scattered part of the layer's total at normal incidence,
    T(0) − e^{−τ}."""
    tau, g = 3.0, 0.6
    mu, f = scattered_transmittance_to_normal(tau, g)
    x, w = np.polynomial.legendre.leggauss(200)
    x, w = 0.5 * (x + 1), 0.5 * w
    L = 2 * np.pi * np.sum(w * np.interp(x, mu, f) * x)
    T, _ = slab_optics(tau, g, 1.0, [1.0])
    assert L == pytest.approx(T[0] - np.exp(-tau), rel=2e-3)


@pytest.mark.slow
def test_mitsuba_measures_the_fitted_plate_at_its_declared_transmittance():
    """The medium fitted here, measured by Mitsuba's own ``plate_optics`` (when installed): the
    declared total at normal incidence, within its noise (4 σ) and 0.002."""
    pytest.importorskip("mitsuba")
    from lbscene.engine.truth.mitsuba import plate_bsdf, plate_optics

    for T_decl, fd, n, d in ((0.60, 0.92, 1.0, 2.5), (0.55, 0.95, 1.49, 3.0)):
        m = opal_slab_medium([T_decl], fd, n, d)
        medium = {"type": "homogeneous", "albedo": {"type": "uniform", "value": 1.0},
                  "sigma_t": {"type": "uniform", "value": m.scattering_per_mm},
                  "phase": {"type": "hg", "g": m.anisotropy}}
        ref = plate_optics({"type": "null"}, d, [1.0], spp=64, passes=2)["T"][0]
        res = plate_optics(plate_bsdf({"type": "lambertian"}, n), d, [1.0], medium=medium, spp=16384)
        assert abs(res["T"][0] / ref - T_decl) <= 4 * res["T_se"][0] / ref + 0.002, (res, ref)
