"""Absolute radiometry of real Cycles bakes against closed forms (see bake_closed_forms.py)."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

import bake_closed_forms as cf
from conftest import AIM8, MAP, POINTS, TABLE, load_points, tolerance

pytestmark = pytest.mark.bake

POS = {n: p for n, p, _ in POINTS}
NRM = {n: nv for n, _, nv in POINTS}
SRC = (0.0, 0.0, cf.H0)


def _offset(name, off=0.05):
    return tuple(np.asarray(POS[name], float) + off * np.asarray(NRM[name], float))


def _point_ref(name, I, **kw):
    return cf.point_irradiance(I, kw.pop("src", SRC), _offset(name), NRM[name], **kw)


@pytest.mark.parametrize("name", ["axis", "x500", "y-1000", "x1500", "tilted", "wall"])
def test_point_source_inverse_square_cosine(closed_form_bake, name):
    job, out = closed_form_bake
    E = load_points(out, "pts")[name]
    for b, I in ((0, 1.0), (1, 0.5), (2, 0.25)):
        ref = _point_ref(name, I)
        assert E[b] == pytest.approx(ref, rel=1e-4), (name, b)


@pytest.mark.parametrize("name", ["axis", "x500", "y-1000", "x1500", "tilted", "wall"])
def test_angular_profiles(closed_form_bake, name):
    job, out = closed_form_bake
    E = load_points(out, "pts")[name]
    gauss20 = lambda th: math.exp(-(th / 40.0) ** 2)  # noqa: E731
    cos2 = lambda th: math.cos(math.radians(th)) ** 2 if th < 90 else 0.0  # noqa: E731
    table = lambda th: float(np.interp(th, TABLE.theta_deg, TABLE.relative, right=0.0))  # noqa: E731
    gauss30 = lambda th: math.exp(-(th / 60.0) ** 2)  # noqa: E731
    checks = [(3, 1.0, gauss20, (0, 0, -1)), (4, 2.0, gauss20, (0, 0, -1)), (5, 3.0, gauss20, (0, 0, -1)),
              (6, 1.0, cos2, (0, 0, -1)), (7, 1.0, table, (0, 0, -1)), (8, 1.0, gauss30, AIM8)]
    for b, I, prof, aim in checks:
        ref = _point_ref(name, I, aim=aim, profile=prof)
        # several lamps share a pass: Cycles picks one light per sample, hence noise
        assert E[b] == pytest.approx(ref, rel=tolerance(out, "pts", name, b), abs=1e-9), (name, b)


def test_lambertian_rectangle_emitter(closed_form_bake):
    job, out = closed_form_bake
    res = load_points(out, "pts")
    h = 800 - 0.05
    for name, (x, y) in {"rect_axis": (3000, 0), "rect_corner": (3200, 100), "rect_off": (3500, -300)}.items():
        ref = cf.rect_E(1.0, 2800 - x, 3200 - x, -100 - y, 100 - y, h)
        assert res[name][9] == pytest.approx(ref, rel=tolerance(out, "pts", name, 9)), name


def test_window_passes_light_only_through_its_rectangle(closed_form_bake):
    """Mirror images: light crosses the window or nothing; the plate behind it does not block."""
    job, out = closed_form_bake
    E = load_points(out, "pts")
    src = (3000, -3000, cf.H0)
    for name in ("win_centre", "win_in"):
        ref = cf.point_irradiance(1.0, src, _offset(name))
        assert E[name][10] == pytest.approx(ref, rel=tolerance(out, "pts", name, 10)), name
    for name in ("win_out", "win_out_v"):
        assert E[name][10] == 0.0, name


def test_lambertian_disk_emitter_on_axis(closed_form_bake):
    job, out = closed_form_bake
    E = load_points(out, "pts")["disk_axis"][11]
    ref = cf.disk_E(1.0, 300.0 * math.sqrt(256 * math.sin(2 * math.pi / 256) / (2 * math.pi)), 600 - 0.05)
    assert E == pytest.approx(ref, rel=tolerance(out, "pts", "disk_axis", 11))


@pytest.mark.parametrize("name", ["sheet_0", "sheet_45", "sheet_60"])
def test_clear_sheet_fresnel_transmittance(closed_form_bake, name):
    job, out = closed_form_bake
    E = load_points(out, "pts")[name]
    src = (0, 3000, cf.H0)
    d = np.asarray(_offset(name)) - np.asarray(src)
    cos_i = abs(d[2]) / np.linalg.norm(d)
    ratio = cf.slab_T(cos_i, 1.52) / cf.slab_T(1.0, 1.52)
    for b, T0 in ((12, 0.8), (13, 0.5)):
        ref = T0 * ratio * cf.point_irradiance(1.0, src, _offset(name))
        assert E[b] == pytest.approx(ref, rel=tolerance(out, "pts", name, b)), (name, b)


def test_single_bounce_off_lambertian_floor(closed_form_bake):
    job, out = closed_form_bake
    E = load_points(out, "pts")["bounce_down"]
    direct = load_points(out, "pts_direct")["bounce_down"]
    for b, rho in ((14, 0.5), (15, 0.9)):
        ref = cf.single_bounce_down_sensor(1.0, rho, cf.H0, 300 - 0.05, 1000.0)
        assert E[b] == pytest.approx(ref, rel=tolerance(out, "pts", "bounce_down", b)), b
        assert direct[b] == 0.0, "a downward sensor gets no direct light from a lamp above it"


def test_irradiance_map_orientation_and_values(closed_form_bake):
    from lbscene.bakers.products import read_product

    job, out = closed_form_bake
    img, header = read_product(out / "floor.exr")
    ny, nx = MAP.resolution[1], MAP.resolution[0]
    assert img.shape == (ny, nx, 16)
    # pixel (j, i) is the point value at the texel centre; row 0 is the far (+v) edge
    j, i = np.mgrid[0:ny, 0:nx]
    x = MAP.origin_mm[0] + (i + 0.5) / nx * MAP.size_mm[0]
    y = MAP.origin_mm[1] + (1.0 - (j + 0.5) / ny) * MAP.size_mm[1]
    h = (cf.H0 - 0.05) * 1e-3
    ref = h / (h * h + (x * x + y * y) * 1e-6) ** 1.5     # I = 1 in band 0
    np.testing.assert_allclose(img[..., 0], ref, rtol=1e-4)
    np.testing.assert_allclose(img[..., 1], 0.5 * ref, rtol=1e-4)


def test_direct_equals_all_without_surfaces_in_the_way(closed_form_bake):
    job, out = closed_form_bake
    a, d = load_points(out, "pts"), load_points(out, "pts_direct")
    for name in ("axis", "x500", "tilted"):
        # bands 0-5: one lamp per pass, no light-selection noise
        np.testing.assert_allclose(d[name][:6], a[name][:6], rtol=2e-4)


def test_illuminance_column_matches_photopic_sum(closed_form_bake):
    """lx = 683·Σ E_b ∫_band V — V(λ) from colour-science's CIE 1924 table, summed here."""
    import colour

    job, out = closed_form_bake
    d = json.loads((out / "pts.points.json").read_text())
    v = colour.colorimetry.SDS_LEFS_PHOTOPIC["CIE 1924 Photopic Standard Observer"]
    fine = np.linspace(0.0, 20.0, 2001)
    # ∫ V over each 20 nm band, V linearly interpolated in the CIE table, 0.01 nm trapezoids
    wv = [np.trapz(np.interp(lo + fine, v.wavelengths, v.values), fine) for lo in range(390, 710, 20)]
    for p in d["points"]:
        E = np.array(list(p["irradiance_W_m2_nm"].values()))
        assert p["illuminance_lx"] == pytest.approx(683.0 * E @ wv, rel=1e-6, abs=1e-9)
