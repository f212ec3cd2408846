"""The opal layer's bidirectional law (:mod:`lbscene.engine.light.opal_layer`) against a Monte Carlo
simulation of the layer in three dimensions written here, reciprocity and its own totals.

The simulation follows photons through a slab of optical depth τ (exponential free paths,
Henyey–Greenstein directions turned about the current one, smooth faces of index n with Fresnel
reflection and total internal reflection, Snell's law on the way out) and counts the scattered ones
leaving the far face by their outgoing direction: cosine and azimuth relative to the incoming
beam's.  It shares no code with the adding–doubling solution.
"""

from __future__ import annotations

import numpy as np
import pytest

from lbscene.engine.light.opal_layer import opal_layer, slab_optics

MU_EDGES = np.array([0.0, 0.25, 0.5, 0.7, 0.85, 1.0])
PHI_EDGES_DEG = np.array([0.0, 30.0, 60.0, 90.0, 120.0, 150.0, 180.0])


def _fresnel_inside(mu, n):
    """Unpolarised reflectance of a face for light inside at cosine ``mu`` (1 beyond the critical angle)."""
    if n == 1.0:
        return np.zeros_like(mu)
    s2 = n * n * (1.0 - mu * mu)
    c = np.sqrt(np.clip(1.0 - s2, 0.0, None))
    with np.errstate(divide="ignore", invalid="ignore"):
        F = 0.5 * (((n * mu - c) / (n * mu + c)) ** 2 + ((mu - n * c) / (mu + n * c)) ** 2)
    return np.where(s2 >= 1.0, 1.0, F)


def _monte_carlo(tau, g, n, theta_deg, photons=400_000, seed=7):
    """Fractions of a unit beam leaving the far face scattered, per (μ_o, |Δφ|) bin of
    :data:`MU_EDGES` × :data:`PHI_EDGES_DEG`, and their standard errors."""
    rng = np.random.default_rng(seed)
    th = np.deg2rad(theta_deg)
    s_out = np.sin(th)
    c_out = np.cos(th)
    # refraction into the layer (azimuth 0: the beam travels toward +x)
    s_in = s_out / n
    c_in = np.sqrt(1.0 - s_in * s_in)
    if n > 1.0:
        ct = c_in
        rs = ((c_out - n * ct) / (c_out + n * ct)) ** 2
        rp = ((n * c_out - ct) / (n * c_out + ct)) ** 2
        F0 = 0.5 * (rs + rp)
    else:
        F0 = 0.0
    enter = rng.random(photons) >= F0
    k = int(enter.sum())
    d = np.tile([s_in, 0.0, c_in], (k, 1))        # +z: down into the layer
    z = np.zeros(k)
    scattered = np.zeros(k, bool)
    counts = np.zeros((len(MU_EDGES) - 1, len(PHI_EDGES_DEG) - 1))
    while len(z):
        step = -np.log(rng.random(len(z)))
        zn = z + d[:, 2] * step
        below, above = zn >= tau, zn <= 0.0
        hit = below | above
        mu = np.abs(d[:, 2])
        back = hit & (rng.random(len(z)) < _fresnel_inside(mu, n))
        out = hit & ~back
        leave = out & below & scattered
        if leave.any():
            o = d[leave]
            # outside: horizontal components times n (Snell), the cosine from them
            h = o[:, :2] * n
            mu_o = np.sqrt(np.clip(1.0 - (h ** 2).sum(1), 0.0, 1.0))
            phi = np.abs(np.rad2deg(np.arctan2(h[:, 1], h[:, 0])))
            i = np.clip(np.searchsorted(MU_EDGES, mu_o, side="right") - 1, 0, len(MU_EDGES) - 2)
            j = np.clip(np.searchsorted(PHI_EDGES_DEG, phi, side="right") - 1, 0, len(PHI_EDGES_DEG) - 2)
            np.add.at(counts, (i, j), 1.0)
        z = np.where(below, tau, np.where(above, 0.0, zn))
        d[back, 2] *= -1.0
        inside = ~hit
        idx = np.nonzero(inside)[0]
        if len(idx):
            xi = rng.random(len(idx))
            ct = (1 + g * g - ((1 - g * g) / (1 - g + 2 * g * xi)) ** 2) / (2 * g)
            st = np.sqrt(np.clip(1 - ct * ct, 0.0, None))
            ph = 2 * np.pi * rng.random(len(idx))
            u = d[idx]
            # an orthonormal frame around u
            a = np.where(np.abs(u[:, 2:3]) < 0.9, np.array([[0.0, 0.0, 1.0]]), np.array([[1.0, 0.0, 0.0]]))
            e1 = np.cross(u, a)
            e1 /= np.linalg.norm(e1, axis=1, keepdims=True)
            e2 = np.cross(u, e1)
            d[idx] = ct[:, None] * u + st[:, None] * (np.cos(ph)[:, None] * e1 + np.sin(ph)[:, None] * e2)
            scattered[idx] = True
        keep = ~out
        z, d, scattered = z[keep], d[keep], scattered[keep]
    frac = counts / photons
    return frac, np.sqrt(frac * (1 - frac) / photons)


def _model_bins(layer, theta_deg, sub=12):
    """The layer's :math:`\\int_\\text{bin} f\\,μ_o\\,dμ_o\\,dφ` over both signs of Δφ (midpoint rule,
    ``sub`` × ``sub`` points a bin)."""
    ci = np.cos(np.deg2rad(theta_deg))
    out = np.zeros((len(MU_EDGES) - 1, len(PHI_EDGES_DEG) - 1))
    for i in range(len(MU_EDGES) - 1):
        m = MU_EDGES[i] + (np.arange(sub) + 0.5) / sub * (MU_EDGES[i + 1] - MU_EDGES[i])
        for j in range(len(PHI_EDGES_DEG) - 1):
            p = np.deg2rad(PHI_EDGES_DEG[j] + (np.arange(sub) + 0.5) / sub * (PHI_EDGES_DEG[j + 1] - PHI_EDGES_DEG[j]))
            f = layer.btdf(ci, m[:, None], p[None, :])
            out[i, j] = 2.0 * np.sum(f * m[:, None]) * (MU_EDGES[i + 1] - MU_EDGES[i]) / sub * \
                np.deg2rad(PHI_EDGES_DEG[j + 1] - PHI_EDGES_DEG[j]) / sub
    return out


@pytest.mark.parametrize("tau,g,n,theta_deg", [(2.0, 0.6, 1.0, 60.0), (1.2, 0.75, 1.0, 30.0),
                                               (1.5, 0.5, 1.5, 45.0)])
def test_the_scattered_light_leaves_in_every_direction_as_the_monte_carlo_layer(tau, g, n, theta_deg):
    mc, se = _monte_carlo(tau, g, n, theta_deg)
    model = _model_bins(opal_layer(tau, g, n), theta_deg)
    # light goes on the way it came: the forward half of the azimuths gets more than the back one
    assert mc[:, :3].sum() > 1.2 * mc[:, 3:].sum()
    np.testing.assert_array_less(np.abs(model - mc), 4 * se + 0.02 * mc + 2e-4)


@pytest.mark.parametrize("tau,g,n", [(3.0, 0.55, 1.0), (1.0, 0.8, 1.49)])
def test_the_law_is_reciprocal_and_sums_to_the_layers_transmittance(tau, g, n):
    layer = opal_layer(tau, g, n)
    rng = np.random.default_rng(3)
    ci, co, dp = rng.uniform(0.05, 1.0, 50), rng.uniform(0.05, 1.0, 50), rng.uniform(0, np.pi, 50)
    np.testing.assert_allclose(layer.btdf(ci, co, dp), layer.btdf(co, ci, dp), rtol=1e-9)
    # hemispherical integral of f·μ_o plus the unscattered light: the slab's T(θ), solved apart
    mu_i = np.array([1.0, 0.8, 0.5, 0.3])
    x, w = np.polynomial.legendre.leggauss(96)
    mo = 0.5 * (x + 1.0)
    ph = (np.arange(72) + 0.5) / 72 * 2 * np.pi
    f = layer.btdf(mu_i[:, None, None], mo[None, :, None], ph[None, None, :])
    scat = np.einsum("imp,m->i", f, 0.5 * w * mo) * 2 * np.pi / 72
    mu_t = np.sqrt(1 - (1 - mu_i ** 2) / n ** 2)
    F = 0.0 if n == 1.0 else _fresnel_inside(mu_t, n)
    e = np.exp(-tau / mu_t)
    T, _ = slab_optics(tau, g, n, mu_i)
    np.testing.assert_allclose(scat + (1 - F) ** 2 * e / (1 - F * F * e * e), T, rtol=3e-3)
    np.testing.assert_allclose(layer.scattered_total(mu_i) + (1 - F) ** 2 * e / (1 - F * F * e * e), T, rtol=3e-3)


def test_binned_light_gives_the_radiance_of_the_law_summed_over_its_directions():
    # many arriving directions binned once (nodes × azimuth histogram, Fourier modes) and carried to
    # any exit direction: the sum of the law over the arriving directions, without the histogram
    layer = opal_layer(2.5, 0.6, 1.0)
    rng = np.random.default_rng(5)
    C, P, R = 3, 400, 30
    ci = rng.uniform(0.1, 1.0, (C, P))
    phi = rng.uniform(-np.pi, np.pi, (C, P))
    wgt = rng.uniform(0.0, 1.0, (C, P))
    G = layer.exit_modes(layer.histogram_modes(layer.histogram(ci, phi, wgt, 128), layer.modes))
    co = rng.uniform(0.05, 1.0, (C, R))
    po = rng.uniform(-np.pi, np.pi, (C, R))
    got = layer.radiance_at(G, co, po)
    want = np.einsum("cp,cpr->cr", wgt, layer.btdf(ci[:, :, None], co[:, None, :], po[:, None, :] - phi[:, :, None]))
    # the histogram splits each direction linearly between nodes: a cosine's law is linear between
    # them too, the azimuth's split corrected in the Fourier domain (aliasing of the high modes left)
    np.testing.assert_allclose(got, want, rtol=2e-3)


def test_a_layer_between_the_solved_depths_is_continuous_and_close_to_its_own_solution():
    from lbscene.engine.light.opal_layer import DEPTH_STEP, fit_asymmetry, opal_layer_at

    node = DEPTH_STEP ** 60                                  # a depth of the grid (3.28)
    ci, co = np.array([1.0, 0.6, 0.2])[:, None], np.array([0.9, 0.5, 0.15])[None, :]
    below = opal_layer_at(node * (1 - 1e-9), 0.55, 1.0).btdf(ci, co, 0.4)
    at = opal_layer_at(node, 0.55, 1.0).btdf(ci, co, 0.4)
    np.testing.assert_allclose(below, at, rtol=1e-6)
    # halfway between two solved depths: within 0.1 % of the layer solved there
    mid = node * DEPTH_STEP ** 0.5
    solved = opal_layer(mid, fit_asymmetry(0.55, mid, 1.0), 1.0)
    np.testing.assert_allclose(opal_layer_at(mid, 0.55, 1.0).btdf(ci, co, 0.4), solved.btdf(ci, co, 0.4), rtol=1e-3)


def test_a_cut_azimuthal_series_is_the_law_of_that_many_modes():
    # exit_modes(…, modes=k): the radiance the law gives with its series stopped after k modes, as
    # btdf summed by hand over those modes; a layer of g 0.55 (a booth's opal plate) converges
    # like g^m: 12 modes (the diagnosis' cut) within 0.1 % of every mode, 2 modes far from it
    layer = opal_layer(2.0, 0.55, 1.5)
    assert layer.modes > 12
    rng = np.random.default_rng(7)
    C, P, R = 2, 300, 25
    # light from tubes close above: grazing, from nearly one azimuth (the high modes matter)
    ci = rng.uniform(0.25, 0.45, (C, P))
    phi = rng.normal(0.0, 0.1, (C, P))
    wgt = rng.uniform(0.0, 1.0, (C, P))
    B = layer.histogram_modes(layer.histogram(ci, phi, wgt, 128), layer.modes)
    co = rng.uniform(0.05, 1.0, (C, R))
    po = rng.uniform(-np.pi, np.pi, (C, R))
    full = layer.radiance_at(layer.exit_modes(B), co, po)
    cut = {k: layer.radiance_at(layer.exit_modes(B, k), co, po) for k in (2, 12)}
    assert layer.exit_modes(B, 12).shape[1] == 13
    np.testing.assert_allclose(cut[12], full, rtol=1e-3)
    assert np.max(np.abs(cut[2] / full - 1.0)) > 1e-2
    # the cut series by hand: mode 0 once, modes 1…k twice, each cos(m Δφ)
    ji, fi = layer._split(ci)
    jo, fo = layer._split(co)
    kernel = layer.kernel
    by_hand = np.zeros((C, R))
    for m in range(3):
        Km = kernel[m]
        f = ((1 - fo[:, None, :]) * ((1 - fi[:, :, None]) * Km[jo[:, None, :], ji[:, :, None]]
                                     + fi[:, :, None] * Km[jo[:, None, :], ji[:, :, None] + 1])
             + fo[:, None, :] * ((1 - fi[:, :, None]) * Km[jo[:, None, :] + 1, ji[:, :, None]]
                                 + fi[:, :, None] * Km[jo[:, None, :] + 1, ji[:, :, None] + 1]))
        azimuth = np.cos(m * (po[:, None, :] - phi[:, :, None]))
        by_hand += (1.0 if m == 0 else 2.0) * np.einsum("cp,cpr->cr", wgt, f * azimuth)
    np.testing.assert_allclose(cut[2], by_hand, rtol=3e-3, atol=1e-3 * np.abs(by_hand).max())


@pytest.mark.parametrize("modes", [1, 2, 13])
def test_the_radiance_toward_many_directions_is_its_fourier_series(monkeypatch, modes):
    # the series written out term by term, sum_m (2 - delta_m0) Re(G_m e^{i m phi}), at cosines a
    # fraction f of the way between two nodes (linear between them); small blocks, so that the
    # directions run over several
    import lbscene.engine.light.opal_layer as ol

    monkeypatch.setattr(ol, "RADIANCE_BLOCK", 300)
    layer = opal_layer(2.0, 0.5, 1.5)
    nodes = layer.cos_nodes
    rng = np.random.default_rng(7)
    C, N, R = 3, len(nodes), 400
    G = rng.normal(size=(C, modes, N, 2, 3)) + 1j * rng.normal(size=(C, modes, N, 2, 3))
    j = rng.integers(0, N - 1, (C, R))
    f = rng.uniform(0.0, 1.0, (C, R))
    cos_o = nodes[j] + f * (nodes[j + 1] - nodes[j])
    phi = rng.uniform(-np.pi, np.pi, (C, R))
    want = np.zeros((C, R, 2, 3))
    for c in range(C):
        for r in range(R):
            g = (1 - f[c, r]) * G[c, :, j[c, r]] + f[c, r] * G[c, :, j[c, r] + 1]        # (modes, 2, 3)
            want[c, r] = g[0].real + sum(2 * (g[m].real * np.cos(m * phi[c, r]) - g[m].imag * np.sin(m * phi[c, r]))
                                         for m in range(1, modes))
    got = layer.radiance_at(G, cos_o, phi)
    assert got.shape == (C, R, 2, 3)
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-12 * np.abs(want).max())


def test_a_layer_between_the_solved_asymmetries_is_continuous_and_close_to_its_own_solution():
    # a fitted transmittance moves the total: the law between the grid's asymmetries (a cubic over
    # four) is continuous across a node and within 0.02 % of the layer solved at the total itself,
    # at low and high asymmetry and in a thin layer (whose reachable totals span 0.05); the
    # mixture transmits the total
    from lbscene.engine.light.opal_layer import DEPTH_STEP, _node_g, fit_asymmetry, opal_layer_at, slab_optics

    ci, co = np.array([1.0, 0.6, 0.2])[:, None], np.array([0.9, 0.5, 0.15])[None, :]
    one = np.array([1.0])
    tau = DEPTH_STEP ** 35                                   # a depth of the grid (2.0)
    node = float(slab_optics(tau, _node_g(20), 1.49, one)[0][0])
    np.testing.assert_allclose(opal_layer_at(tau, node - 1e-8, 1.49).btdf(ci, co, 0.4),
                               opal_layer_at(tau, node + 1e-8, 1.49).btdf(ci, co, 0.4), rtol=1e-5)
    for tau, T in ((tau, 0.615), (tau, 0.8049), (0.078, 0.899), (0.078, 0.91)):
        solved = opal_layer(tau, fit_asymmetry(T, tau, 1.49), 1.49)
        mixed = opal_layer_at(tau, T, 1.49)
        peak = np.abs(solved.btdf(ci, co, 0.0)).max()
        assert np.abs(mixed.btdf(ci, co, 0.4) - solved.btdf(ci, co, 0.4)).max() < 2e-4 * peak
        assert mixed.scattered_total(one)[0] == pytest.approx(solved.scattered_total(one)[0], rel=1e-4)


@pytest.mark.parametrize("tau,g", [(0.01, 0.5), (0.05, 0.9), (0.5, 0.6), (3.0, 0.8), (8.0, 0.93)])
def test_the_doubling_start_is_converged(monkeypatch, tau, g):
    """The thin layer the doubling starts from (diamond rule) is thin enough: starting from one a
    hundred times thinner (seven more doublings) moves no operator entry by more than 1e-5 of its
    largest, in any azimuthal mode; the single-scattering start the doubling used before needed
    a layer of 1e-7 for a few 1e-5."""
    import lbscene.engine.light.opal_layer as OL

    mu, w = OL._quadrature(OL._breakpoints(1.49, []), OL.NODES_PER_PIECE)
    args = (tau, g, 1.0, tuple(mu), tuple(w), 2 * OL.NODES_PER_PIECE - 2, tuple(range(0, 40, 3)))
    R, T = OL._layers(*args)
    monkeypatch.setattr(OL, "THIN_LAYER", OL.THIN_LAYER / 100)
    monkeypatch.setattr(OL, "THIN_FRACTION", OL.THIN_FRACTION / 100)
    R0, T0 = OL._layers(*args)
    assert np.abs(R - R0).max() < 1e-5 * np.abs(R0).max()
    assert np.abs(T - T0).max() < 1e-5 * np.abs(T0).max()


def test_a_non_absorbing_layer_keeps_every_photon_at_every_depth():
    """Flux conservation: every column of the mode-0 operators of a non-absorbing layer sums to one
    (the diamond rule keeps the net flux exactly, as the transfer equation does), and an absorbing
    one loses light."""
    import lbscene.engine.light.opal_layer as OL

    mu, w = OL._quadrature(OL._breakpoints(1.49, []), OL.NODES_PER_PIECE)
    for tau, g in ((0.02, 0.3), (1.0, 0.85), (12.0, 0.6)):
        R, T = OL._layers(tau, g, 1.0, tuple(mu), tuple(w), 2 * OL.NODES_PER_PIECE - 2, (0,))
        assert np.allclose((R[0] + T[0]).sum(axis=0), 1.0, atol=1e-9), tau
        Ra, Ta = OL._layers(tau, g, 0.9, tuple(mu), tuple(w), 2 * OL.NODES_PER_PIECE - 2, (0,))
        assert ((Ra[0] + Ta[0]).sum(axis=0) < 1.0 - 1e-4).all(), tau
