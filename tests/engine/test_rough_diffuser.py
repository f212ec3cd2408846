"""The diffuser effect with a ``roughness`` plate: the rough slab law in the forward model
(regular paths, the directional plate source, inter-reflected light), against closed forms."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from lbscene.engine.scene.compile import compile_booth
from lbscene.engine.light import plates
from lbscene.engine.light.forward import ForwardModel
from lbscene.engine.light.rough_slab import RoughSlab

REPO = Path(__file__).resolve().parents[2]
SCENE = REPO / "tests" / "data" / "validation" / "rough-diffuser-r030"


def _ir_with(ir, **scattering):
    d = ir.diffuser.model_copy(update={"scattering": scattering})
    return ir.model_copy(update={"diffuser": d})


def _fresnel_unpolarised(cos_i, n):
    sin_t = np.sqrt(1 - cos_i ** 2) / n
    cos_t = np.sqrt(1 - sin_t ** 2)
    rs = ((cos_i - n * cos_t) / (cos_i + n * cos_t)) ** 2
    rp = ((cos_t - n * cos_i) / (cos_t + n * cos_i)) ** 2
    return 0.5 * (rs + rp)


@pytest.fixture(scope="module")
def ir():
    return compile_booth(SCENE)


def test_a_nearly_smooth_plate_transmits_like_the_clear_slab(ir):
    # roughness 0.01 (α = 1e-4): the straight path's factor is the clear slab's unpolarised
    # transmittance relative to normal incidence, times the declared total; no plate: 1
    smooth = _ir_with(ir, type="roughness", roughness=0.01)
    P = np.array([[0.0, 0.0, 0.0], [380.0, 250.0, 0.0], [-300.0, -200.0, 0.0]])
    on = ForwardModel(smooth, "L").illuminance_lx(P)
    off = ForwardModel(smooth, "L", effects={}).illuminance_lx(P)
    # one point emitter-like check per receiver: the ratio is a weighted mean of the factor over
    # the tube's points, bounded by the factor at its nearest and farthest incidence
    n = 1.49
    R0 = ((n - 1) / (n + 1)) ** 2
    T0 = (1 - R0) / (1 + R0)
    for k, p in enumerate(P):
        ends = np.array([[-300.0, y, 650.0] for y in (-120, 120)] + [[300.0, y, 650.0] for y in (-120, 120)]
                        + [[0.0, y, 650.0] for y in (-120, 120)] + [[p[0], y, 650.0] for y in (-120, 120)])
        # the path refracted through the 3 mm plate: its incidence and ray-tube spread (checked
        # against a ray trace below)
        c, spread = plates.slab_crossing(ends, p[None, :], 600.0, 3.0, n)
        R = _fresnel_unpolarised(c[0], n)
        f = float(ir.diffuser.transmittance.array_1nm[0]) * (1 - R) / (1 + R) / T0 * spread[0]
        assert f.min() - 2e-3 <= on[k] / off[k] <= f.max() + 2e-3, (k, on[k] / off[k], f)


def test_a_rough_plate_of_the_same_total_transmittance_transmits_less_at_larger_incidence(ir):
    P = np.array([[0.0, 0.0, 0.0], [440.0, 290.0, 0.0]])
    rough = ForwardModel(ir, "L").illuminance_lx(P)
    clear = ForwardModel(_ir_with(ir, type="roughness", roughness=0.01), "L").illuminance_lx(P)
    ratio = rough / clear
    # both declare the same total transmittance at normal incidence: under the lamps (incidence
    # near 0°) they transmit alike; toward the corner (incidence up to ~25°) the rough plate
    # loses more to the microfacets and to total internal reflection at its exit face
    assert ratio[0] == pytest.approx(1.0, abs=0.006)
    assert 0.95 < ratio[1] < ratio[0] - 0.002


def test_the_regime_switch_follows_the_lobe_footprint_and_width(ir):
    fp = [plates.plate_lobe_footprint_mm(_ir_with(ir, type="roughness", roughness=r), "L")
          for r in (0.04, 0.3, 0.5)]
    assert fp[0] < 1.0 < fp[1] < fp[2] and fp[1] < 25.0
    assert plates.plate_lobe_footprint_mm(_ir_with(ir, type="lambertian", diffuse_fraction=0.5), "L") == 0.0
    P = np.array([[0.0, 0.0, 0.0]])
    kinds = lambda fm: [type(s).__name__ for s in fm.secondary_sources()]      # noqa: E731
    # roughness 0.3 (θ₉₀ 11.6°, footprint under 25 mm): straight paths, unless the cells are
    # finer than its footprint
    from lbscene.engine.light.effects.builtin.diffuser import DiffuserEffect

    assert kinds(ForwardModel(ir, "L")) == []
    fm = ForwardModel(ir, "L", effects={"diffuser": {"scattered_cell_size_mm": fp[1] * 0.9}})
    assert DiffuserEffect._scattered(fm.ctx, fm.ctx.params("diffuser"))
    # roughness 0.5 (θ₉₀ 27°): a wide lobe re-emits through the cells however large they are
    wide = _ir_with(ir, type="roughness", roughness=0.5)
    assert float(plates.plate_slab(wide).lobe_deg(1.0, 0.9)) > 20.0
    fm = ForwardModel(wide, "L", effects={"diffuser": {"scattered_cell_size_mm": fp[2] * 2}})
    assert kinds(fm) == ["DirectionalSource"]
    assert fm.illuminance_lx(P)[0] > 0
    assert kinds(ForwardModel(wide, "L", effects={"diffuser": {"rough_transport": "regular"}})) == []


def test_the_rough_and_the_opal_directional_sources_agree_on_one_law(ir, monkeypatch):
    # the opal layer's bidirectional law given to the rough slab (f·T_ref/T_s(0)) makes the rough
    # plate's directional source (exit bins of 10°, azimuth grid, FFT) the opal plate's (nodes,
    # azimuthal modes): two codes, one law; a wrong π, cosine, azimuth sign or normalisation
    # would show here
    layer = plates.opal_plate_layer(ir, 1.0)
    T_ref = plates.reference_transmittance(ir)
    norm = T_ref / float(layer.scattered_total(np.ones(1))[0])

    def opal(self, cos_i, cos_o, dphi, absorption=1.0):
        return layer.btdf(cos_i, cos_o, dphi) * norm

    # the source's exit-radiance grid reads the law through btdf (RoughSlab._azimuth_kernel)
    monkeypatch.setattr(RoughSlab, "btdf", opal)
    P = np.array([[0.0, 0.0, 0.0], [0.0, -250.0, 0.0], [400.0, 250.0, 0.0]])
    a = ForwardModel(ir, "L", effects={"diffuser": {"rough_transport": "scattered"}}).illuminance_lx(P)
    b = ForwardModel(ir, "L", effects={"diffuser": {"rough_transport": "regular",
                                                    "diffuse_fraction": 1.0}}).illuminance_lx(P)
    np.testing.assert_allclose(a, b, rtol=1e-2)


def test_the_directional_source_sends_light_on_along_its_incident_direction(ir):
    # a wide rough plate lit from one side: its radiance is largest in the direction the light
    # travels (a slab with parallel faces has no net deviation), not mirrored about the normal
    wide = _ir_with(ir, type="roughness", roughness=0.7)
    fm = ForwardModel(wide, "L", effects={"diffuser": {"rough_transport": "scattered",
                                                                  "scattered_cell_size_mm": 100}})
    src = fm.secondary_sources()[0]
    from lbscene.engine.light.geometry import quad_centroids

    c = quad_centroids(src.polys)
    k = int(np.argmin(np.linalg.norm(c[:, :2] - [0.0, -300.0], axis=1)))     # near the front edge
    assert c[k, 1] < -150                                                     # tubes at y = ±120 behind it
    th = np.deg2rad(30.0)
    toward_front = np.array([0.0, -np.sin(th), -np.cos(th)])                  # continuing forward
    toward_back = np.array([0.0, np.sin(th), -np.cos(th)])
    dirs = np.zeros((len(c), 2, 3))
    dirs[:, :, 2] = -1
    dirs[k, 0], dirs[k, 1] = toward_front, toward_back
    L = src.radiance(dirs).sum(axis=2)
    assert L[k, 0] > 1.2 * L[k, 1]


def test_diffuse_light_crosses_a_rough_plate_with_its_hemispherical_transmittance(ir):
    # nearly smooth: T_h/T0 = 2∫ T(μ) μ dμ / T0 of the clear slab (closed form, integrated here)
    n = ir.diffuser.ior
    R0 = ((n - 1) / (n + 1)) ** 2
    T0 = (1 - R0) / (1 + R0)
    x, w = np.polynomial.legendre.leggauss(200)
    mu = 0.5 * (x + 1)
    R = _fresnel_unpolarised(mu, n)
    Th = np.sum(w * (1 - R) / (1 + R) * mu)
    smooth = _ir_with(ir, type="roughness", roughness=0.01)
    assert plates.plate_diffuse_light_factor(smooth) == pytest.approx(Th / T0, abs=3e-3)
    # rougher: less (light lost to the microfacets and trapped at grazing incidence)
    assert plates.plate_diffuse_light_factor(ir) < plates.plate_diffuse_light_factor(smooth)
    # an opal plate: diffuse light gets through as the layer's T(μ) relative to normal incidence,
    # averaged over the hemisphere (T(μ) solved here once per incidence, not read off the layer's
    # interpolated nodes)
    from lbscene.engine.light.opal_layer import slab_optics

    opal_ir = _ir_with(ir, type="lambertian", diffuse_fraction=1.0)
    layer = plates.opal_plate_layer(opal_ir, 1.0)
    T_mu, _ = slab_optics(layer.tau, layer.g, n, mu)
    T_1, _ = slab_optics(layer.tau, layer.g, n, [1.0])
    opal = plates.plate_diffuse_light_factor(opal_ir)
    assert opal == pytest.approx(np.sum(w * T_mu * mu) / T_1[0], rel=3e-3)


def test_an_opal_plate_scatters_the_regular_light_it_loses_at_oblique_incidence():
    # Beer–Lambert along the path: at n = 1 the unscattered part is e^{-τ/μ}, τ from (1 − f_d) T
    T, fd = 0.6, 0.9
    tau = plates.opal_optical_depth((1 - fd) * T, 1.0)
    assert tau == pytest.approx(-np.log(0.06), rel=1e-9)
    mu = np.array([1.0, 0.5, 0.2])
    np.testing.assert_allclose(plates.opal_regular_relative(mu, 1.0, tau), np.exp(-tau / mu) / np.exp(-tau),
                               rtol=1e-9)
    # ... and the layer scatters what it loses: scattered and regular light make its total T(μ)
    from lbscene.engine.light.opal_layer import fit_asymmetry, opal_layer, slab_optics

    g = fit_asymmetry(T, tau, 1.0)
    total, _ = slab_optics(tau, g, 1.0, mu)
    np.testing.assert_allclose(opal_layer(tau, g, 1.0).scattered_total(mu) + np.exp(-tau / mu), total,
                               rtol=2e-3)
    # a smooth face: the regular part is a clear slab's with the layer inside (closed form at 0°)
    n = 1.5
    r0 = ((n - 1) / (n + 1)) ** 2
    tau = plates.opal_optical_depth(0.05, n)
    e = np.exp(-tau)
    assert (1 - r0) ** 2 * e / (1 - r0 ** 2 * e ** 2) == pytest.approx(0.05, rel=1e-9)


def _black_box_booth(folder, name, interior, lamp_id, lamp, diffuser="", effects="  diffuser: {}\n"):
    """Write and compile a booth: a black open-front box, one lamp ``lamp_id`` (the rest of its
    YAML flow mapping in ``lamp``), lighting ``L`` with it, an optional diffuser block and the
    ``effects:`` lines."""
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "booth.yaml").write_text(f"""\
version: 1
kind: booth
name: {name}
provenance: {{status: synthetic, source: lbscene tests}}
interior: {{type: box, {interior}, open_front: true}}
materials:
  black: {{type: diffuse, reflectance: {{type: constant, value: 0.0}}}}
surfaces: {{floor: black, left_wall: black, right_wall: black, rear_wall: black, ceiling: black}}
lamps:
  - {{id: {lamp_id}, {lamp}}}
{diffuser}lighting:
  L: {{lamps: [{lamp_id}]}}
observer: {{type: eye_point, position_mm: [0, -900, 500]}}
effects:
{effects}""")
    return compile_booth(folder)


_NEAR_TUBE_DIFFUSER = """diffuser:
  z_mm: 600
  size_mm: [100, 300]
  thickness_mm: 3
  ior: 1.49
  transmittance: {type: constant, value: 0.8}
  scattering: {type: roughness, roughness: 0.5477}
"""


def _strip_flux_per_peak_intensity(tmp_path):
    """Flux the rough plate's cells receive (per unit peak intensity of the lamp), summed over
    each row of cells parallel to the tube, keyed by the row's y-range in mm."""
    from lbscene.engine.light.effects.builtin import diffuser as D
    from lbscene.engine.light.geometry import quad_areas, quad_centroids

    ir = _black_box_booth(
        tmp_path, "A rough plate 14 mm under a long tube", "width_mm: 1400, depth_mm: 600, height_mm: 700",
        "tube", "type: tube, position_mm: [0, 0, 627], axis: [1, 0, 0], length_mm: 1200, radius_mm: 13, "
        "spd: {type: cie_illuminant, name: D65}, output: {type: luminance_cd_m2, value_cd_m2: 20000}",
        _NEAR_TUBE_DIFFUSER)
    fm = ForwardModel(ir, "L", effects={"diffuser": {"rough_transport": "scattered"}})

    def direct(points, normals, exclude=()):
        raise AssertionError("the rough source reads its light point by point")
    direct.per_point = lambda points, normals, exclude=(): fm.direct_per_point(points, normals, exclude=exclude)
    p = fm.ctx.params("diffuser")
    polys = D.DiffuserEffect._cells(fm.ir.diffuser, p.scattered_cell_size_mm)
    per_cell = np.zeros(len(polys))
    for idx, light, _k in D.DiffuserEffect._incoming(fm.ctx, p, direct, p.scattered_cell_size_mm):
        for _, E, _, _, E_s in light.values():
            per_cell[idx] += E.sum(axis=1)                          # the cell's mean irradiance, 1/m²
            assert np.allclose(E_s.sum(axis=1), E.sum(axis=1))      # the sub-points' sums: the same light
    flux = per_cell * quad_areas(polys) * 1e-6                      # per unit peak intensity
    y0 = np.round(polys[:, :, 1].min(axis=1), 6)
    return {(a, a + 25.0): flux[y0 == a].sum() for a in np.unique(y0)}


def test_the_light_a_plate_cell_close_under_a_tube_receives_is_integrated_finely(tmp_path):
    # an infinitely long Lambertian cylinder sends a parallel strip the share (φ_b − φ_a)/2π of its
    # flux, φ the strip's edges seen from the axis (the crossed-strings result): per unit peak
    # intensity I = L·2r·ℓ, a strip of length X receives π·Δφ·X/(2ℓ).  The tube's axis is 27 mm
    # above the plate's mid-plane, 25.5 mm above its top face where the light is taken (its
    # surface 12.5 mm); the cells are 25 mm, the strip 100 mm long, the tube 1200 mm (its ends,
    # 550 mm away, add < 0.1 %)
    h, X, ell = 25.5, 100.0, 1200.0

    def closed_form(a, b):
        return np.pi * (np.arctan(b / h) - np.arctan(a / h)) * X / (2 * ell)
    got = _strip_flux_per_peak_intensity(tmp_path)
    assert len(got) == 12
    err = {k: f / closed_form(*k) - 1 for k, f in got.items()}
    assert max(abs(e) for e in err.values()) < 0.01, err


def _bulb_over_plate(tmp_path, plate: bool, reflection: str = "specular"):
    diffuser = """diffuser:
  z_mm: 300
  size_mm: [1100, 1100]
  thickness_mm: 3
  ior: 1.5
  transmittance: {type: constant, value: 0.9199}
  scattering: {type: roughness, roughness: 0.04}
""" if plate else ""
    effects = f"  diffuser: {{plate_reflection: {reflection}}}\n" if plate else ""
    return _black_box_booth(
        tmp_path, "A bulb over a glass plate", "width_mm: 1200, depth_mm: 1200, height_mm: 800",
        "bulb", "type: bulb, position_mm: [0, 0, 400], radius_mm: 5, spd: {type: cie_illuminant, name: D65}, "
        "output: {type: luminance_cd_m2, value_cd_m2: 20000}", diffuser, effects + "  interreflection: {}\n")


@pytest.mark.parametrize("x_mm", [150.0, 400.0])
def test_a_glass_plate_reflects_a_lamp_above_it_as_its_mirror_image(tmp_path, x_mm):
    # a bulb 100 mm over a smooth glass plate (n 1.5, no absorption: the declared 0.9199 is the
    # clear slab's own), a receiver beside and above it facing down: it gets the bulb and the
    # bulb's image 100 mm under the plate's top face, times the slab's reflectance with its
    # inner reflections, R = 1 − T = 2F/(1 + F), at the image path's incidence (F unpolarised at
    # each face, as the rough slab and Mitsuba 3's scalar variants take it)
    P = np.array([[x_mm, 0.0, 500.0]])
    N = np.array([[0.0, 0.0, -1.0]])
    bare = ForwardModel(_bulb_over_plate(tmp_path / "bare", False), "L").illuminance_lx(P, N, meter=False)[0]
    ir = _bulb_over_plate(tmp_path / "plate", True)
    with_plate = ForwardModel(ir, "L").illuminance_lx(P, N, meter=False)[0]
    bulb = np.array([0.0, 0.0, 400.0])
    image = np.array([0.0, 0.0, 2 * 301.5 - 400.0])
    d0, d1 = P[0] - bulb, P[0] - image
    cos0, cos1 = d0[2] / np.linalg.norm(d0), d1[2] / np.linalg.norm(d1)
    sin_t = np.sqrt(1 - cos1 ** 2) / 1.5
    cos_t = np.sqrt(1 - sin_t ** 2)
    rs = ((cos1 - 1.5 * cos_t) / (cos1 + 1.5 * cos_t)) ** 2
    rp = ((cos_t - 1.5 * cos1) / (cos_t + 1.5 * cos1)) ** 2
    F = 0.5 * (rs + rp)
    R = 2 * F / (1 + F)
    image_share = R * (cos1 / (d1 @ d1)) / (cos0 / (d0 @ d0))
    assert with_plate / bare - 1 == pytest.approx(image_share, rel=0.03)
    # re-emitted by the plate's patches instead (Lambertian), it is spread over the hemisphere
    diffuse = ForwardModel(_bulb_over_plate(tmp_path / "diffuse", True, "diffuse"), "L").illuminance_lx(
        P, N, meter=False)[0]
    assert abs(diffuse / bare - 1 - image_share) > 0.1 * image_share


def test_an_occluder_on_the_way_down_to_the_plate_hides_the_lamps_image(tmp_path):
    # the bulb 100 mm over the glass plate as above, and a black panel 50 mm under the bulb over
    # x 20 to 120 mm.  A receiver at x 400 mm, 200 mm over the plate's top face, gets the image's
    # light reflected at x 400·98.5/297 = 132.7 mm: on its way down from the bulb (0 to 132.7 mm)
    # the light crosses z 350 at x 67 mm, on the panel, so none of it is reflected there; the
    # way up to the receiver crosses z 350 at x 198 mm, past the panel, and the bulb's own light
    # goes up, away from it.  At x -400 mm nothing of the reflected path meets the panel.
    panel = ("occluders:\n  - {id: shade, type: panel, centre_mm: [70, 0, 350], normal: [0, 0, -1], "
             "u_axis: [1, 0, 0], size_mm: [100, 400], material: black}\n")
    P = np.array([[400.0, 0.0, 500.0], [-400.0, 0.0, 500.0]])
    N = np.array([[0.0, 0.0, -1.0]] * 2)

    def booth(folder, shade):
        ir = _bulb_over_plate(folder, True)
        if not shade:
            return ir
        y = (folder / "booth.yaml").read_text().replace("lighting:\n", panel + "lighting:\n")
        y = y.replace("effects:\n", "effects:\n  aperture_occlusion: {}\n")
        (folder / "booth.yaml").write_text(y)
        return compile_booth(folder)

    bare = ForwardModel(_bulb_over_plate(tmp_path / "bare", False), "L").illuminance_lx(P, N, meter=False)
    plate = ForwardModel(booth(tmp_path / "plate", False), "L").illuminance_lx(P, N, meter=False)
    shaded = ForwardModel(booth(tmp_path / "shaded", True), "L").illuminance_lx(P, N, meter=False)
    image = plate - bare
    assert image[0] > 0.03 * bare[0]                  # the image's light, the panel away
    assert shaded[0] == pytest.approx(bare[0], rel=1e-3)
    assert shaded[1] == pytest.approx(plate[1], rel=1e-3)


def _refract(d, n, eta):
    """Vector Snell: direction ``d`` through a face of normal ``n`` (against ``d``), index ratio ``eta``."""
    c = -np.sum(d * n, axis=-1, keepdims=True)
    k = 1 - eta ** 2 * (1 - c ** 2)
    return eta * d + (eta * c - np.sqrt(k)) * n


def _landing_radius(theta, h_src, t, h_rx, n):
    """Trace a ray leaving a point source at polar angle ``theta`` (downward) through a slab of
    thickness ``t`` ``h_src`` below it and return where it meets the plane ``h_rx`` below the slab."""
    d = np.stack([np.sin(theta), np.zeros_like(theta), -np.cos(theta)], -1)
    up = np.array([0.0, 0.0, 1.0])
    x = d[:, 0] / -d[:, 2] * h_src                       # to the top face
    d1 = _refract(d, up, 1.0 / n)
    x = x + d1[:, 0] / -d1[:, 2] * t                    # through the slab
    d2 = _refract(d1, up, n)
    return x + d2[:, 0] / -d2[:, 2] * h_rx


@pytest.mark.parametrize("rho_mm", [0.0, 150.0, 400.0, 900.0])
def test_a_thick_plate_brings_the_lamps_behind_it_closer_as_a_ray_trace_does(rho_mm):
    # A point source 48.5 mm above a 3 mm plate (n 1.49), a receiver plane 598.5 mm below it: the
    # flux through a thin ring of the receiver plane is the source's intensity times the solid angle
    # of the directions that land in it, found by tracing rays with the vector form of Snell's law
    # (independent of slab_crossing's closed form for the landing radius).  Against the straight
    # line's inverse-square law the ring is brighter by the spread slab_crossing returns.
    n, t, hs, hr = 1.49, 3.0, 48.5, 598.5
    from scipy.optimize import brentq

    def theta_at(r):
        return 0.0 if r == 0 else brentq(lambda a: _landing_radius(np.array([a]), hs, t, hr, n)[0] - r,
                                          0.0, 1.5, xtol=1e-15)
    dr = 0.05
    r1, r2 = max(rho_mm - dr, 0.0), rho_mm + dr
    solid = 2 * np.pi * (np.cos(theta_at(r1)) - np.cos(theta_at(r2)))
    E_traced = solid / (np.pi * (r2 ** 2 - r1 ** 2))          # per unit intensity, on the plane
    D = hs + t + hr
    rr = np.linspace(r1, r2, 201)
    E_line = np.trapz(D / (D ** 2 + rr ** 2) ** 1.5 * rr, rr) / np.trapz(rr, rr)   # I cos θ / r², mean
    cos_path, spread = plates.slab_crossing(np.array([[0.0, 0.0, 650.0]]), np.array([[rho_mm, 0.0, 0.0]]),
                                             600.0, t, n)
    # the receiver plane's cosine at the traced path against the straight line's: the same to
    # about t(1 - 1/n)/D (slab_crossing's docstring), so compare on the plane with it folded in
    c_line = D / np.hypot(D, rho_mm)
    expect = float(spread[0, 0]) * float(cos_path[0, 0]) / c_line
    assert E_traced / E_line == pytest.approx(expect, rel=2e-4), (E_traced / E_line, expect)
    # near the normal: the source 1 mm (t(1 - 1/n)) closer
    if rho_mm == 0.0:
        assert float(spread[0, 0]) == pytest.approx((D / (D - t * (1 - 1 / n))) ** 2, rel=1e-9)


def test_a_thick_plate_does_not_bend_paths_that_do_not_cross_it():
    src = np.array([[0.0, 0.0, 650.0], [0.0, 0.0, 601.0]])       # above; inside the plate
    rx = np.array([[100.0, 0.0, 700.0], [100.0, 50.0, 0.0]])     # above; below
    cos_i, spread = plates.slab_crossing(src, rx, 600.0, 3.0, 1.49)
    assert spread[0, 0] == 1.0 and spread[0, 1] == 1.0 and spread[1, 1] == 1.0
    assert spread[1, 0] > 1.0
    # a plate without refraction (index 1) or thickness bends nothing
    assert np.all(plates.slab_crossing(src, rx, 600.0, 3.0, 1.0)[1] == 1.0)
    assert np.all(plates.slab_crossing(src, rx, 600.0, 0.0, 1.49)[1] == 1.0)


def test_without_thickness_refraction_the_plate_is_a_sheet_of_no_thickness(ir):
    # the bake draws a clear or rough plate as a thin sheet; its cross-check compares it with the
    # model's plate with thickness_refraction off: the same plate made (nearly) infinitely thin
    P = np.array([[0.0, 0.0, 0.0], [380.0, 250.0, 0.0]])
    off = ForwardModel(ir, "L", effects={"diffuser": {"thickness_refraction": False}}).illuminance_lx(P)
    thin = ir.model_copy(update={"diffuser": ir.diffuser.model_copy(update={"thickness_mm": 1e-6})})
    assert np.allclose(off, ForwardModel(thin, "L").illuminance_lx(P), rtol=1e-6)
    on = ForwardModel(ir, "L").illuminance_lx(P)
    # the 3 mm plate 50 mm under the tubes, the floor 600 mm below: about 0.3 % more light
    assert np.all(on / off - 1 > 0.002) and np.all(on / off - 1 < 0.004), on / off - 1


def test_the_bake_says_its_sheet_leaves_out_the_plates_thickness(ir):
    from lbscene.bakers.from_ir import lighting_job

    notes = lighting_job(ir, "L").source["notes"]
    # 3 mm × (1 − 1/1.49): the lamps 0.99 mm closer near the plate's normal
    assert "diffuser: a sheet of no thickness; the 3 mm plate's refraction" in notes
    assert "lamps behind it 0.99 mm closer" in notes


def test_the_cross_check_compares_a_thin_sheet_with_the_plate_of_no_thickness(ir):
    # the plate the bake draws decides: a rough plate and an opal plate without a diffuse part are
    # sheets of no thickness, an opal plate with one is a slab of its thickness
    from lbscene.bakers.from_ir import diffuser_is_thin_sheet

    assert diffuser_is_thin_sheet(ir, {"diffuser": {}})
    assert not diffuser_is_thin_sheet(ir, {})
    opal = compile_booth(REPO / "tests" / "data" / "validation" / "opal-black")
    assert not diffuser_is_thin_sheet(opal, {"diffuser": {}})
    assert diffuser_is_thin_sheet(opal, {"diffuser": {"diffuse_fraction": 0.0}})
