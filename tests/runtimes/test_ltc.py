"""The project's own LTC fit for GGX against closed forms and brute-force integration."""

from __future__ import annotations

import numpy as np
import pytest


@pytest.fixture(scope="module")
def table():
    from lbscene.runtimes.ltc import load_table

    return load_table()


def _ggx_cos(v, l, alpha):
    """GGX BRDF × cos θ_l, Fresnel 1, height-correlated Smith masking (written independently)."""
    h = l + v
    h /= np.linalg.norm(h, axis=-1, keepdims=True)
    a2 = alpha * alpha
    d = a2 / (np.pi * (h[..., 2] ** 2 * (a2 - 1) + 1) ** 2)

    def lam(c):
        t2 = (1 - c * c) / (c * c)
        return 0.5 * (np.sqrt(1 + a2 * t2) - 1)

    g = 1 / (1 + lam(v[2]) + lam(np.clip(l[..., 2], 1e-9, 1)))
    return np.where(l[..., 2] > 0, d * g / (4 * v[2]), 0.0)


def _brute_rect(p, n_grid, centre, ex, ey, v, alpha):
    """∫ over a rectangle (centre ± ex ± ey) of GGX·cos dω, seen from the origin."""
    s = (np.arange(n_grid) + 0.5) / n_grid * 2 - 1
    a, b = np.meshgrid(s, s)
    pts = centre + a.ravel()[:, None] * ex + b.ravel()[:, None] * ey - p
    nrm = np.cross(ex, ey)
    nrm /= np.linalg.norm(nrm)
    dist = np.linalg.norm(pts, axis=1)
    l = pts / dist[:, None]
    da = 4 * np.linalg.norm(ex) * np.linalg.norm(ey) / n_grid ** 2
    return float(np.sum(_ggx_cos(v, l, alpha) * np.abs(l @ nrm) / dist ** 2 * da))


def test_table_shape_and_invariants(table):
    assert table.size == 64
    assert table.minv.shape == (64, 64, 4) and table.mag.shape == (64, 64, 2)
    assert np.all(np.isfinite(table.minv)) and np.all(np.isfinite(table.mag))
    n, f = table.mag[..., 0], table.mag[..., 1]
    assert np.all(n > 0) and np.all(n <= 1.0 + 1e-3)
    assert np.all(f >= 0) and np.all(f <= n)
    # at normal incidence the lobe is isotropic: no skew terms
    np.testing.assert_allclose(table.minv[:, 0, 1], 0.0, atol=1e-6)
    np.testing.assert_allclose(table.minv[:, 0, 2], 0.0, atol=1e-6)


def test_directional_albedo_closed_form(table):
    # α = 1, normal view: D = 1/π, G2 = 2μ/(1 + μ), ∫ D·G2/4 dω = 1 − ln 2
    assert table.mag[63, 0, 0] == pytest.approx(1 - np.log(2), rel=5e-3)
    # very smooth GGX reflects (almost) everything at normal incidence
    assert table.mag[2, 0, 0] == pytest.approx(1.0, abs=2e-3)


def test_polygon_form_factor_closed_form():
    from lbscene.runtimes.ltc import polygon_form_factor

    # differential area to a parallel a × b rectangle at height c with a corner above the point
    for a, b, c in [(1.0, 1.0, 1.0), (2.0, 0.5, 1.0), (0.3, 3.0, 0.7)]:
        A, B = a / c, b / c
        f = (A / np.sqrt(1 + A * A) * np.arctan(B / np.sqrt(1 + A * A))
             + B / np.sqrt(1 + B * B) * np.arctan(A / np.sqrt(1 + B * B))) / (2 * np.pi)
        quad = np.array([[0, 0, c], [0, b, c], [a, b, c], [a, 0, c]], float)  # CCW seen from below
        assert polygon_form_factor(quad) == pytest.approx(f, rel=1e-9)
        assert polygon_form_factor(quad[::-1]) == 0.0        # one-sided: the back gives nothing


# rel: the LTC is a 3-parameter lobe; up to 45° it follows GGX·cos within 5 % for a small light at
# the mirror direction.  At grazing view on a rough lobe (α = 0.49, 70°) GGX·cos peaks at about −60°
# while the best LTC peaks near −50° (a fresh fit with 64² samples agrees with the table), so a small
# light at the mirror direction is underestimated by ~30 %: a limit of the method, bounded here so a
# worse fit still fails.
@pytest.mark.parametrize("roughness,theta_deg,near,rel", [
    (0.1, 30.0, True, 0.05), (0.2, 60.0, True, 0.05), (0.3, 10.0, True, 0.05), (0.5, 45.0, True, 0.05),
    (0.7, 70.0, True, 0.35),
    (0.4, 40.0, False, 0.15), (0.6, 20.0, False, 0.15),
])
def test_ltc_matches_brute_force_ggx(table, roughness, theta_deg, near, rel):
    from lbscene.runtimes.ltc import ltc_polygon_integral

    alpha = roughness ** 2
    t = np.radians(theta_deg)
    v = np.array([np.sin(t), 0.0, np.cos(t)])
    spec = np.array([-np.sin(t), 0.0, np.cos(t)])
    if near:   # a 0.2 × 0.08 light around the mirror direction, 1 unit away
        centre = spec + np.array([0.0, 0.03, 0.0])
    else:      # beside it
        centre = spec + np.array([0.25, 0.3, 0.1])
    d = centre / np.linalg.norm(centre)
    ex = np.cross(d, [0.0, 1.0, 0.0])
    ex = 0.1 * ex / np.linalg.norm(ex)
    ey = np.cross(d, ex)
    ey = 0.04 * ey / np.linalg.norm(ey)
    quad = np.array([centre - ex - ey, centre + ex - ey, centre + ex + ey, centre - ex + ey])
    if np.cross(quad[1] - quad[0], quad[2] - quad[1]) @ centre > 0:
        quad = quad[::-1]                     # face the shading point
    ref = _brute_rect(np.zeros(3), 600, centre, ex, ey, v, alpha)
    got = ltc_polygon_integral(table, roughness, np.array([0, 0, 1.0]), v, np.zeros(3), quad, f0=1.0)
    assert got == pytest.approx(ref, rel=rel)
