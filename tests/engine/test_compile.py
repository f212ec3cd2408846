"""Compilation to the scene IR: absolute lamp output against closed forms."""

import math

import numpy as np
import pytest

from lbscene.engine.scene.compile import compile_booth
from lbscene.engine.spectra.evaluate import luminous_efficacy_sum


def _set_lamp(booth_dir, text_old, text_new):
    f = booth_dir / "booth.yaml"
    s = f.read_text()
    assert text_old in s
    f.write_text(s.replace(text_old, text_new))


def test_point_lamp_inverse_square_law(minimal_booth):
    ir = compile_booth(minimal_booth)
    lamp = ir.lamps[0]
    assert lamp.peak_luminous_intensity_cd == pytest.approx(1000.0, rel=1e-9)
    # isotropic: flux = 4π I
    assert lamp.luminous_flux_lm == pytest.approx(4 * math.pi * 1000.0, rel=1e-4)
    # E = I / d² with d = 0.7 m straight below the lamp
    lx = luminous_efficacy_sum(ir.lighting_spd_1nm("A"))
    assert lx == pytest.approx(1000.0 / 0.7**2, rel=1e-6)
    # 0.4 m to the side: E = I cos θ / d² with cos θ = 0.7/d
    d = math.hypot(0.4, 0.7)
    lx_side = luminous_efficacy_sum(ir.lighting_spd_1nm("A", (400.0, 0.0, 0.0)))
    assert lx_side == pytest.approx(1000.0 * (0.7 / d) / d**2, rel=1e-6)


def test_cosine_power_flux_closed_form(minimal_booth):
    _set_lamp(minimal_booth, "output: {type: peak_intensity_cd, value_cd: 1000}",
              "output: {type: luminous_flux_lm, value_lm: 1000}\n    profile: {type: cosine_power, exponent: 2}")
    ir = compile_booth(minimal_booth)
    # Φ = I0 · 2π/(n+1)  →  I0 = 1000 · 3 / 2π
    assert ir.lamps[0].peak_luminous_intensity_cd == pytest.approx(1000 * 3 / (2 * math.pi), rel=1e-4)


def test_illuminance_output_reproduces_requested_lux(minimal_booth):
    _set_lamp(minimal_booth, "output: {type: peak_intensity_cd, value_cd: 1000}",
              "output: {type: illuminance_at_point_lx, value_lx: 1500, point_mm: [0, 0, 0]}")
    ir = compile_booth(minimal_booth)
    assert luminous_efficacy_sum(ir.lighting_spd_1nm("A")) == pytest.approx(1500, rel=1e-9)
    assert ir.lamps[0].peak_luminous_intensity_cd == pytest.approx(1500 * 0.49, rel=1e-9)


def test_illuminant_a_spd_matches_cie_table(minimal_booth):
    # CIE illuminant A is tabulated relative to 100 at 560 nm; the IR keeps the shape (1 at 560 nm)
    ir = compile_booth(minimal_booth)
    spd = ir.lamps[0].spd.array_1nm
    wl = np.arange(360, 831)
    assert spd[wl == 560][0] == pytest.approx(1.0)
    # CIE 15:2004 eq. for illuminant A: S(λ) = 100 (560/λ)^5 (e^(c2/(2848·560)) − 1)/(e^(c2/(2848 λ)) − 1),
    # c2 = 1.435e7 nm·K  →  S(400) = 14.708, S(700) = 198.26 (relative to 100 at 560 nm)
    assert spd[wl == 400][0] == pytest.approx(0.14708, rel=1e-3)
    assert spd[wl == 700][0] == pytest.approx(1.9826, rel=1e-3)


def test_ir_hash_is_stable_and_content_sensitive(minimal_booth):
    a = compile_booth(minimal_booth)
    b = compile_booth(minimal_booth)
    assert a.content_hash == b.content_hash and a.to_json() == b.to_json()
    _set_lamp(minimal_booth, "value_cd: 1000", "value_cd: 1001")
    assert compile_booth(minimal_booth).content_hash != a.content_hash


def test_box_surfaces_face_inward(minimal_booth):
    ir = compile_booth(minimal_booth)
    centre = np.array([0.0, 0.0, 400.0])
    for s in ir.surfaces:
        v = s.vertex_array
        for t in s.triangle_array:
            n = np.cross(v[t[1]] - v[t[0]], v[t[2]] - v[t[0]])
            assert n @ (centre - v[t[0]]) > 0, s.id
    roles = sorted(s.role for s in ir.surfaces)
    assert roles == ["ceiling", "floor", "left_wall", "rear_wall", "right_wall"]  # open front


def test_radiant_output_for_uv_lamps(minimal_booth):
    # an inline UVA line 360-380 nm (triangle, no visible light): radiant intensity is ∫ I_λ dλ
    _set_lamp(minimal_booth, "spd: {type: cie_illuminant, name: A}\n    output: {type: peak_intensity_cd, value_cd: 1000}",
              "spd: {type: inline, wavelengths_nm: [360, 370, 380, 720], values: [0, 1, 0, 0]}\n"
              "    output: {type: radiant_flux_W, value_W: 2.0}\n    profile: {type: cosine_power, exponent: 1}")
    ir = compile_booth(minimal_booth)
    lamp = ir.lamps[0]
    # cosine emitter: Φ = π I0  →  ∫ I0_λ dλ = 2/π W/sr
    assert lamp.peak_intensity_1nm.sum() == pytest.approx(2.0 / math.pi, rel=1e-3)
    # CIE 1924 V(λ) ≤ 3.9e-5 below 380 nm: at most 683 · (2/π) · 3.9e-5 = 0.017 cd of "visible" leak
    assert 0 < lamp.peak_luminous_intensity_cd <= 683 * (2 / math.pi) * 3.9e-5


def test_panel_point_sources_cover_length_and_width(minimal_booth):
    # A 400 × 100 mm Lambertian panel 0.7 m above the floor: with points spread over the whole
    # area, the base model approaches the closed-form illuminance of a uniform rectangular
    # Lambertian source (sum of exact corner contributions, IES handbook form).
    _set_lamp(minimal_booth, "type: point\n    position_mm: [0, 0, 700]",
              "type: panel\n    position_mm: [0, 0, 700]\n    length_mm: 400\n    width_mm: 100\n"
              "    point_sources: 400")
    # a panel is Lambertian by its type: no profile, no effect needed (a cosine profile would
    # modulate it to cos²)
    ir = compile_booth(minimal_booth)
    pts = ir.lamps[0].point_positions_mm()
    assert pts[:, 0].max() - pts[:, 0].min() > 350 and pts[:, 1].max() - pts[:, 1].min() > 70
    # uniform Lambertian rectangle of luminance L = I0/A, receiver parallel, under its centre:
    # E = 4 · L · [a/√(a²+h²) · atan(b/√(a²+h²)) + b/√(b²+h²) · atan(a/√(b²+h²))] / 2 (corner formula)
    a, b, h = 0.2, 0.05, 0.7
    L = 1000.0 / (0.4 * 0.1)
    corner = 0.5 * (a / math.hypot(a, h) * math.atan(b / math.hypot(a, h))
                    + b / math.hypot(b, h) * math.atan(a / math.hypot(b, h)))
    exact = 4 * L * corner
    lx = luminous_efficacy_sum(ir.lighting_spd_1nm("A"))
    assert lx == pytest.approx(exact, rel=2e-3)
