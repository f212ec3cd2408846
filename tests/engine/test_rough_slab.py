"""The rough dielectric slab (engine/light/rough_slab.py) against closed forms and an independent
quadrature of Walter et al.'s microfacet BSDF."""

from __future__ import annotations

import numpy as np
import pytest

from lbscene.engine.light import rough_slab as rs
from lbscene.engine.light.rough_slab import fresnel_slab_transmittance

IOR = 1.49


def _table(alpha, theta_deg, photons, seed=3):
    nt, npf = rs._shape()
    flat = rs._simulate(alpha, IOR, photons, seed, theta_deg=theta_deg)
    return flat.reshape(len(theta_deg), 6 + nt * npf)


def _fresnel_unpolarised(cos_i, n1, n2):
    """Textbook Fresnel equations (unpolarised mean of s and p)."""
    sin_t = n1 / n2 * np.sqrt(1 - cos_i ** 2)
    cos_t = np.sqrt(1 - sin_t ** 2)
    rs_ = ((n1 * cos_i - n2 * cos_t) / (n1 * cos_i + n2 * cos_t)) ** 2
    rp_ = ((n1 * cos_t - n2 * cos_i) / (n1 * cos_t + n2 * cos_i)) ** 2
    return 0.5 * (rs_ + rp_)


def test_smooth_limit_is_the_clear_slab():
    # α → 0: a clear slab; light reflected back and forth between two faces of reflectance R
    # (unpolarised transport, as the Mitsuba truth): T = (1 − R)² / (1 − R²) = (1 − R)/(1 + R)
    th = np.array([0.0, 20.0, 40.0, 60.0, 75.0])
    n = 40_000
    tab = _table(1e-5, th, n)
    R = _fresnel_unpolarised(np.cos(np.deg2rad(th)), 1.0, IOR)
    T_closed = (1 - R) / (1 + R)
    se = np.sqrt(T_closed * (1 - T_closed) / n)
    assert np.all(np.abs(tab[:, 0] - T_closed) < 4 * se + 1e-4), (tab[:, 0], T_closed)
    # reflected: R from the first face, the rest after entering; nothing lost
    assert np.all(np.abs(tab[:, 1] - R) < 4 * np.sqrt(R * (1 - R) / n) + 1e-4)
    assert np.all(tab[:, 3] < 1e-3)
    # at normal incidence s and p coincide: the polarised clear-slab formula of the forward model
    assert tab[0, 0] == pytest.approx(fresnel_slab_transmittance(np.ones(1), IOR)[0], abs=4 * se[0] + 1e-4)
    assert tab[0, 0] == pytest.approx(rs.clear_slab_normal_transmittance(IOR), abs=4 * se[0] + 1e-4)
    # the lobe is a point: 90 % of the light within a few hundredths of a degree of the incident ray
    assert np.all(tab[:4, 5] < 0.05)


@pytest.mark.parametrize("alpha", [0.01, 0.09, 0.36])
def test_energy_is_conserved(alpha):
    # every photon's weight ends transmitted, reflected or lost (the microfacet model's G₁ < 1,
    # directions below a face, trapped light)
    tab = _table(alpha, np.array([0.0, 30.0, 60.0, 85.0]), 20_000)
    np.testing.assert_allclose(tab[:, 0] + tab[:, 1] + tab[:, 2] + tab[:, 3], 1.0, atol=1e-9)
    assert np.all(tab[:, :4] >= 0)
    # the BTDF's cosine-weighted integral over the exit hemisphere is the transmittance
    nt, npf = rs._shape()
    et = np.deg2rad(np.arange(0, 90.0 + 1e-9, rs.BIN_THETA_DEG))
    ep = np.deg2rad(np.arange(0, 180.0 + 1e-9, rs.BIN_PHI_DEG))
    proj = 0.5 * np.diff(np.sin(et) ** 2)[:, None] * 2 * np.diff(ep)[None, :]
    btdf = tab[:, 6:].reshape(len(tab), nt, npf)
    np.testing.assert_allclose((btdf * proj).sum(axis=(1, 2)), tab[:, 0], rtol=1e-9)


def _walter_interface_quadrature(alpha, theta_i_deg, eta_i, eta_o, n=700):
    """Directional reflectance and transmittance (power fractions) of one GGX interface by quadrature of
    Walter et al. 2007, eqs. 20–21 (with the separable Smith G), over the exit sphere."""
    ti = np.deg2rad(theta_i_deg)
    i = np.array([np.sin(ti), 0.0, np.cos(ti)])

    def D(m):
        c = m[..., 2]
        t2 = (1 - c ** 2) / c ** 2
        return np.where(c > 0, alpha ** 2 / (np.pi * c ** 4 * (alpha ** 2 + t2) ** 2), 0.0)

    def G1(v, m):
        c = v[..., 2]
        t2 = (1 - c ** 2) / c ** 2
        ok = (np.sum(v * m, -1) / c) > 0
        return np.where(ok, 2 / (1 + np.sqrt(1 + alpha ** 2 * t2)), 0.0)

    def F(c):
        c = np.abs(c)
        s2 = (eta_i / eta_o) ** 2 * (1 - c ** 2)
        ct = np.sqrt(np.clip(1 - s2, 0, None))
        a = ((eta_i * c - eta_o * ct) / (eta_i * c + eta_o * ct)) ** 2
        b = ((eta_i * ct - eta_o * c) / (eta_i * ct + eta_o * c)) ** 2
        return np.where(s2 >= 1, 1.0, 0.5 * (a + b))

    # exit directions: midpoint rule in (cos θ, φ) on each hemisphere, finer near the lobe
    x, w = np.polynomial.legendre.leggauss(n)
    mu = 0.5 * (x + 1)
    wm = 0.5 * w
    ph = (np.arange(2 * n) + 0.5) * np.pi / n
    MU, PH = np.meshgrid(mu, ph, indexing="ij")
    W = wm[:, None] * (np.pi / n) * np.ones_like(PH)
    s = np.sqrt(1 - MU ** 2)
    o_up = np.stack([s * np.cos(PH), s * np.sin(PH), MU], -1)
    # reflection
    h = i + o_up
    h /= np.linalg.norm(h, axis=-1, keepdims=True)
    fr = F(h @ i) * D(h) * G1(np.broadcast_to(i, h.shape), h) * G1(o_up, h) / (4 * i[2] * MU)
    R = np.sum(fr * MU * W)
    # transmission (exit cos θ = MU, downward)
    o = o_up * np.array([1, 1, -1.0])
    h = -(eta_i * i + eta_o * o)
    h /= np.linalg.norm(h, axis=-1, keepdims=True)
    h = np.where(h[..., 2:3] < 0, -h, h)
    im, om = h @ i, np.sum(o * h, -1)
    ft = (np.abs(im) * np.abs(om) / (i[2] * MU) * eta_o ** 2 * (1 - F(im)) * D(h)
          * G1(np.broadcast_to(i, h.shape), h) * G1(o, h) / (eta_i * im + eta_o * om) ** 2)
    ft = np.where((im > 0) & (om < 0), ft, 0.0)
    # Walter's f_t (n_o² in the numerator) integrates to the fraction of the incident power
    T = np.sum(ft * MU * W)
    return R, T


@pytest.mark.parametrize("alpha,theta,eta_i,eta_o", [(0.3, 0.0, 1.0, IOR), (0.3, 50.0, 1.0, IOR),
                                                     (0.3, 20.0, IOR, 1.0), (0.5, 35.0, IOR, 1.0)])
def test_one_interface_matches_walters_bsdf(alpha, theta, eta_i, eta_o):
    # the sampler (visible normals, Fresnel choice, G₁ weight) against a deterministic
    # quadrature of the BSDF it estimates
    R_q, T_q = _walter_interface_quadrature(alpha, theta, eta_i, eta_o)
    n = 400_000
    rng = np.random.default_rng(11)
    t = np.deg2rad(theta)
    v = np.tile([-np.sin(t), 0.0, np.cos(t)], (n, 1))
    o_r, w_r, o_t, w_t = rs.interface_split(v, alpha, eta_o / eta_i, rng)
    assert np.all(o_r[w_r > 0, 2] > 0) and np.all(o_t[w_t > 0, 2] < 0)
    R_mc, T_mc = np.mean(w_r), np.mean(w_t)
    assert R_mc == pytest.approx(R_q, abs=4 * np.std(w_r) / np.sqrt(n) + 2e-3)
    assert T_mc == pytest.approx(T_q, abs=4 * np.std(w_t) / np.sqrt(n) + 2e-3)


def test_btdf_is_reciprocal():
    # f_T(ω_i, ω_o) = f_T(ω_o, ω_i): the table is filled by forward sampling from ω_i only,
    # so this is a property of the transport, not of the code's layout
    alpha = 0.36
    th = np.array([20.0, 21.0, 40.0, 41.0])
    tab = _table(alpha, th, 400_000)
    nt, npf = rs._shape()
    f = tab[:, 6:].reshape(len(th), nt, npf)
    # bins of 2°: [20, 22) holds 21°, [40, 42) holds 41°: f(20°→41°) vs f(41°→20°…22°) is not
    # symmetric, f(21°→41°) against f(41°→21°) is (both bin centres); summed over the Δφ bins
    # up to 40° (a few thousand photons each: 2 % noise)
    a = f[1, 20, :4].sum()         # θ_i = 21°, θ_o in [40, 42)
    b = f[3, 10, :4].sum()         # θ_i = 41°, θ_o in [20, 22)
    assert a == pytest.approx(b, rel=0.08), (a, b)



def _hat_btdf(s, cos_i, cos_o, dphi, n_phi, points=400):
    """The table's f_T averaged over a hat one grid step (2π/n_phi) wide on either side of Δφ,
    by a plain midpoint rule (independent of the kernel's 16 points)."""
    step = 2 * np.pi / n_phi
    u = (np.arange(points) + 0.5) / points * 2 - 1
    h = (1 - np.abs(u)) / np.sum(1 - np.abs(u))
    return np.sum(h * s.btdf(cos_i[..., None], cos_o[..., None], dphi[..., None] + u * step), axis=-1)


def test_the_exit_grid_is_the_hat_averaged_sum_of_the_btdf():
    # the radiance kernel of a rough plate's cells (diffuser's directional source), through the
    # FFT convolution, against its definition summed directly: incoming light at incidence
    # nodes and grid azimuths (where the linear splits are exact), leaving toward grid azimuths
    s = rs.rough_slab(0.2 ** 2, 1.5)
    n_phi = rs.EXIT_PHI_STEPS
    rng = np.random.default_rng(7)
    C, N = 3, 60
    k = rng.integers(0, len(rs.THETA_I_DEG) - 1, (C, N))
    cos_i = np.cos(np.deg2rad(rs.THETA_I_DEG[k]))
    b = rng.integers(0, n_phi, (C, N))
    phi_i = -np.pi + 2 * np.pi * b / n_phi
    w = rng.uniform(0.0, 2.0, (C, N))
    grid = s.exit_radiance_grid(cos_i, phi_i, w)
    assert grid.shape == (C, s.btdf_table.shape[1], n_phi)
    jo = np.array([0, 7, 22, 44])
    cos_o = np.cos(np.deg2rad((jo + 0.5) * rs.BIN_THETA_DEG))
    g = np.arange(0, n_phi, 5)
    phi_o = -np.pi + 2 * np.pi * g / n_phi
    want = np.einsum("cjgn,cn->cjg", _hat_btdf(s, cos_i[:, None, None, :], cos_o[None, :, None, None],
                                                (phi_o[None, None, :, None] - phi_i[:, None, None, :]),
                                                n_phi), w)
    np.testing.assert_allclose(grid[:, jo][:, :, g], want, rtol=1e-9, atol=1e-12)
    # read back at the grid's own directions: the same values
    got = rs.RoughSlab.exit_radiance_at(grid, np.broadcast_to(cos_o[None, :, None], want.shape).reshape(C, -1),
                                        np.broadcast_to(phi_o[None, None, :], want.shape).reshape(C, -1))
    np.testing.assert_allclose(got, want.reshape(C, -1), rtol=1e-9, atol=1e-12)


def test_the_exit_grid_keeps_the_azimuthal_integral_of_the_btdf():
    # whatever the incoming azimuths and incidences (between nodes, across ±π), the grid's
    # integral over exit azimuth equals Σ_n w_n ∫ f_T dΔφ of the table (its bins' sum times
    # their width, both sides), per exit bin: the azimuth splits and the hat move light, never
    # make or lose it
    s = rs.rough_slab(0.35 ** 2, 1.5)
    rng = np.random.default_rng(3)
    C, N = 4, 500
    cos_i = rng.uniform(0.0, 1.0, (C, N))
    cos_i[:, :3] = [1.0, 0.0, 1e-4]
    phi_i = rng.uniform(-np.pi, np.pi, (C, N))
    phi_i[:, 3:5] = [-np.pi, np.pi - 1e-12]
    w = rng.uniform(0.0, 2.0, (C, N))
    grid = s.exit_radiance_grid(cos_i, phi_i, w)
    nt, npf = s.btdf_table.shape[1:]
    cos_o = np.cos(np.deg2rad((np.arange(nt) + 0.5) * rs.BIN_THETA_DEG))
    bins = np.deg2rad((np.arange(npf) + 0.5) * rs.BIN_PHI_DEG)                     # bin centres
    f = s.btdf(cos_i[:, :, None, None], cos_o[None, None, :, None], bins[None, None, None, :])
    want = np.einsum("cnjb,cn->cj", f, w) * 2 * np.deg2rad(rs.BIN_PHI_DEG)
    np.testing.assert_allclose(grid.sum(axis=2) * 2 * np.pi / grid.shape[2], want, rtol=1e-9)


def test_absorption_scales_transmitted_light_by_a_squared():
    s = rs.rough_slab(0.09, IOR, photons=20_000)
    a = rs.per_refraction_factor(0.85, IOR)
    assert a ** 2 == pytest.approx(0.85 / rs.clear_slab_normal_transmittance(IOR))
    mu = np.array([1.0, 0.7, 0.3])
    np.testing.assert_allclose(s.transmittance(mu, a), a ** 2 * s.transmittance(mu))
    # the first face's reflection does not cross the bulk
    assert np.all(s.reflectance(mu, 0.0) > 0.03)
    np.testing.assert_allclose(s.reflectance(mu, a) - s.reflectance(mu, 0.0),
                               a ** 2 * (s.reflectance(mu) - s.reflectance(mu, 0.0)))


def test_hemispherical_transmittance_of_the_smooth_slab():
    # diffuse light: T_h = 2 ∫ T(μ) μ dμ; the clear slab's closed form, integrated here
    s = rs.rough_slab(1e-5, IOR, photons=20_000)
    x, w = np.polynomial.legendre.leggauss(200)
    mu = 0.5 * (x + 1)
    R = _fresnel_unpolarised(mu, 1.0, IOR)
    Th = np.sum(w * 0.5 * 2 * (1 - R) / (1 + R) * mu)
    assert s.hemispherical_transmittance() == pytest.approx(Th, abs=3e-3)
    assert s.hemispherical_transmittance() + s.hemispherical_reflectance() == pytest.approx(1.0, abs=2e-3)


def test_rougher_plates_spread_more_and_transmit_less_at_oblique_incidence():
    tabs = [_table(a, np.array([0.0, 60.0]), 20_000) for a in (0.0016, 0.01, 0.09)]
    l90 = [t[0, 5] for t in tabs]
    assert l90[0] < l90[1] < l90[2]
    # light inside at larger angles meets total internal reflection at the exit face
    T60 = [t[1, 0] for t in tabs]
    assert T60[0] > T60[2]


# --------------------------------------------------------------------------- shipped tables

@pytest.mark.parametrize("roughness,ior", rs.SHIPPED_PLATES)
def test_shipped_tables_were_made_by_the_current_computation(roughness, ior):
    # a changed Monte Carlo (format, bins, photons, limits) without regenerating the shipped
    # tables makes this fail: run scripts/gen_rough_slab_tables.py
    path = rs.shipped_table_path(roughness, ior)
    assert path.is_file(), f"{path.name} is missing: run scripts/gen_rough_slab_tables.py"
    with np.load(path, allow_pickle=False) as z:
        assert str(z["meta"]) == rs._table_meta(roughness ** 2, ior, rs.PHOTONS, 0)
        nt, npf = rs._shape()
        assert z["table"].shape == (len(rs.THETA_I_DEG) * (6 + nt * npf),)


def test_a_shipped_plate_is_read_not_simulated(monkeypatch):
    rs.rough_slab.cache_clear()

    def boom(*a, **k):
        raise AssertionError("the shipped table should have been used")

    monkeypatch.setattr(rs, "_simulate", boom)
    s = rs.rough_slab(0.04 ** 2, 1.52)
    # a near-clear glass plate: normal transmittance of the clear slab (1 − R0)/(1 + R0)
    assert s.transmittance(1.0) == pytest.approx(rs.clear_slab_normal_transmittance(1.52), abs=2e-3)
    rs.rough_slab.cache_clear()


def test_a_shipped_table_equals_a_fresh_computation(tmp_path):
    # the cheapest shipped plate, recomputed with the same photons and seed
    fresh = rs.write_shipped_table(0.5, 1.49, tmp_path)
    with np.load(fresh) as a, np.load(rs.shipped_table_path(0.5, 1.49)) as b:
        assert np.allclose(a["table"], b["table"], rtol=1e-9, atol=1e-12)


@pytest.mark.slow
@pytest.mark.parametrize("roughness,ior", rs.SHIPPED_PLATES)
def test_every_shipped_table_equals_a_fresh_computation(tmp_path, roughness, ior):
    fresh = rs.write_shipped_table(roughness, ior, tmp_path)
    with np.load(fresh) as a, np.load(rs.shipped_table_path(roughness, ior)) as b:
        assert np.allclose(a["table"], b["table"], rtol=1e-9, atol=1e-12)


def test_a_plate_under_a_uniform_sky_sends_its_reciprocal_transmittance_every_way():
    # Helmholtz reciprocity: under a sky of radiance 1 the radiance a plate sends toward θ_o is
    # ∫ f_T(ω_i, ω_o) cos θ_i dω_i = T(θ_o), the transmittance of a beam arriving from θ_o.  The
    # rough cells' exit radiance (exit_radiance_grid, read by exit_radiance_at) sums the table over
    # incoming directions, the way this test does: the BTDF's noise per bin must average out (at
    # 16 000 photons a node it was 1-2 % off at 11°, 21° and 61°, and a booth under a wide-lobed
    # plate came out 0.5-0.8 % bright against Mitsuba 3)
    s = rs.rough_slab(0.3, IOR)                          # GGX α 0.3 (roughness 0.5477, shipped)
    th = np.deg2rad((np.arange(450) + 0.5) * 0.2)
    ph = np.deg2rad((np.arange(360) + 0.5) * 1.0) - np.pi
    TH, PH = np.meshgrid(th, ph, indexing="ij")
    w = np.cos(TH) * np.sin(TH) * np.deg2rad(0.2) * np.deg2rad(1.0)      # cos θ_i dω_i, radiance 1
    grid = s.exit_radiance_grid(np.cos(TH).reshape(1, -1), PH.reshape(1, -1), w.reshape(1, -1))
    theta_o = np.array([11.0, 21.0, 31.0, 41.0, 51.0, 61.0, 71.0])       # exit bins' centres
    L = rs.RoughSlab.exit_radiance_at(grid, np.cos(np.deg2rad(theta_o))[None, :], np.zeros((1, 7)))[0]
    T = s.transmittance(np.cos(np.deg2rad(theta_o)))
    assert np.abs(L / T - 1).max() < 0.01, dict(zip(theta_o, np.round(L / T - 1, 4)))
