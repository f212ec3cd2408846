"""Display characterisation with ambient light: forward model, inverse, gamut mapping, files."""

import json
from pathlib import Path

import numpy as np
import pytest

REPO = Path(__file__).resolve().parents[2]
SRGB = REPO / "displays" / "srgb-reference.yaml"
TABLET = REPO / "displays" / "tablet-wide-gamut.yaml"


def _doc(**over):
    from lbscene.schemas.display import Display

    data = {"version": 1, "kind": "display", "name": "test", "provenance": {"status": "synthetic"},
            "primaries_xy": {"red": [0.64, 0.33], "green": [0.30, 0.60], "blue": [0.15, 0.06]},
            "white_xy": [0.3127, 0.3290], "white_luminance_cd_m2": 80,
            "tone_response": {c: {"type": "srgb"} for c in ("red", "green", "blue")}}
    data.update(over)
    return Display.model_validate(data)


def load(path):
    from lbscene.engine.colour.display_model import load_display

    return load_display(path)


def _model(**over):
    from lbscene.engine.colour.display_model import DisplayModel

    mapping = over.pop("mapping", "chroma")
    return DisplayModel(_doc(**over), mapping=mapping)


def test_srgb_matrix_is_the_published_one():
    # IEC 61966-2-1 linear sRGB → XYZ (D65), 4 decimals as published
    published = np.array([[0.4124, 0.3576, 0.1805], [0.2126, 0.7152, 0.0722],
                          [0.0193, 0.1192, 0.9505]])
    np.testing.assert_allclose(_model().rgb_to_xyz / 80, published, atol=1e-4)


def test_srgb_forward_matches_colour_science():
    import colour

    m = _model()
    d = np.random.default_rng(1).random((200, 3))
    # colour-science uses the standard's 4-decimal matrix: agreement to its rounding (80 × 5e-5)
    np.testing.assert_allclose(m.drive_to_xyz(d), 80 * colour.sRGB_to_XYZ(d), rtol=0, atol=0.005)
    x = np.linspace(0, 1, 101)
    np.testing.assert_allclose(m.curves[0].forward(x), colour.cctf_decoding(x, "sRGB"), atol=1e-12)


def test_ambient_reflection_adds_rho_e_over_pi_at_the_ambient_chromaticity():
    import colour

    m = load(SRGB)
    y = 0.0393 * 64 / np.pi                                   # closed form, cd/m²
    assert m.xyz_ambient[1] == pytest.approx(y, rel=1e-12)
    d50 = colour.CCS_ILLUMINANTS["CIE 1931 2 Degree Standard Observer"]["D50"]
    np.testing.assert_allclose(colour.XYZ_to_xy(m.xyz_ambient), d50, atol=2e-4)
    np.testing.assert_allclose(m.drive_to_xyz([0, 0, 0]), m.xyz_floor)
    # the inverse subtracts it: the drive for (floor + emitted) is the dark-room drive of emitted
    dark = _model()
    emitted = dark.drive_to_xyz([0.3, 0.5, 0.7])
    np.testing.assert_allclose(m.xyz_to_drive(emitted + m.xyz_floor), [0.3, 0.5, 0.7], atol=1e-12)


@pytest.mark.parametrize("path", [SRGB, TABLET], ids=["srgb", "tablet"])
def test_round_trip_in_gamut_is_exact(path):
    m = load(path)
    rng = np.random.default_rng(2)
    xyz = m.drive_to_xyz(rng.uniform(0.05, 1.0, (500, 3)))
    drive, rep = m.xyz_to_drive(xyz, report=True)
    assert rep.count == 0
    np.testing.assert_allclose(m.drive_to_xyz(drive), xyz, rtol=1e-10, atol=1e-10)


def test_gog_and_lut_round_trips():
    from lbscene.engine.colour.display_model import DisplayModel

    x = np.linspace(0, 1, 33)
    lut = {"type": "lut", "drive": x.tolist(), "output": (x ** 2.2).tolist()}
    gog = {"type": "gog", "gain": 1.05, "offset": -0.05, "gamma": 2.3}
    m = DisplayModel(_doc(tone_response={"red": lut, "green": gog, "blue": {"type": "gamma", "gamma": 2.0}},
                          black_luminance_cd_m2=0.3))
    d = np.random.default_rng(3).uniform(0.06, 1, (300, 3))
    xyz = m.drive_to_xyz(d)
    np.testing.assert_allclose(m.xyz_to_drive(xyz), d, atol=1e-12)
    # closed forms of each curve
    assert m.curves[1].forward(np.array(0.5)) == pytest.approx((1.05 * 0.5 - 0.05) ** 2.3)
    assert m.curves[1].forward(np.array(0.04)) == 0.0            # below the cut-off drive
    assert m.curves[2].inverse(np.array(0.25)) == pytest.approx(0.5)
    assert m.curves[0].forward(np.array(x[5])) == pytest.approx(x[5] ** 2.2)
    assert m.tone_kind() == 2


def test_black_level_and_max_luminance():
    m = _model(black_luminance_cd_m2=0.5)
    np.testing.assert_allclose(m.drive_to_xyz([1, 1, 1])[1], 80.0)
    np.testing.assert_allclose(m.drive_to_xyz([0, 0, 0])[1], 0.5)
    assert m.max_luminance_cd_m2((0.3127, 0.3290)) == pytest.approx(80.0, rel=1e-9)
    # with a (white) black level, a primary's own chromaticity cannot be shown at all …
    assert m.max_luminance_cd_m2((0.30, 0.60)) == 0.0
    # … without one, up to the luminance of the full green channel
    assert _model().max_luminance_cd_m2((0.30, 0.60)) == pytest.approx(80 * 0.7152, rel=2e-4)


def test_out_of_gamut_chroma_mapping_keeps_luminance_and_hue_line():
    import colour

    m = _model()
    # Display P3 green at 30 cd/m² is outside sRGB
    target = colour.xyY_to_XYZ([0.265, 0.690, 30.0])
    inside = m.drive_to_xyz([0.5, 0.5, 0.5])
    drive, rep = m.xyz_to_drive(np.array([target, inside]), report=True)
    assert rep.count == 1 and rep.mask.tolist() == [True, False] and rep.total == 2
    assert rep.max_excess > 0.1 and rep.max_delta_e00 > 1 and rep.delta_e00[1] == 0
    shown = m.drive_to_xyz(drive[0])
    assert shown[1] == pytest.approx(30.0, rel=1e-9)          # luminance kept
    p, t, w = colour.XYZ_to_xy(shown), np.array([0.265, 0.690]), np.array([0.3127, 0.3290])
    cross = (t - w)[0] * (p - w)[1] - (t - w)[1] * (p - w)[0]
    assert abs(cross) < 1e-9                                 # on the line target → white
    lin = m.xyz_to_linear(shown)
    assert lin.min() >= -1e-12 and lin.max() <= 1 + 1e-12 and np.isclose(lin.min(), 0, atol=1e-9)
    js = rep.to_json()
    assert js["count"] == 1 and json.dumps(js)


def test_clip_mapping_and_colours_below_the_floor():
    import colour

    m = load(SRGB)
    target = colour.xyY_to_XYZ([0.265, 0.690, 30.0])
    d_clip, rep = m.xyz_to_drive(target[None], mapping="clip", report=True)
    lin = m.xyz_to_linear(target)
    np.testing.assert_allclose(m.drive_to_linear(d_clip[0]), np.clip(lin, 0, 1), atol=1e-12)
    assert rep.mapping == "clip"
    # darker than the reflected ambient: cannot be shown, becomes black and is counted
    d, rep = m.xyz_to_drive(0.5 * m.xyz_floor[None], report=True)
    assert rep.count == 1 and rep.below_floor == 1
    np.testing.assert_allclose(d, 0.0)


def test_glsl_uniforms_are_plain_and_consistent():
    for path, kind in ((SRGB, 0), (TABLET, 1)):
        m = load(path)
        u = m.glsl_uniforms()
        json.dumps(u)
        assert u["tone_kind"] == kind
        np.testing.assert_allclose(np.array(u["xyz_to_rgb_column_major"]).reshape(3, 3).T,
                                   np.array(u["xyz_to_rgb"]))
        np.testing.assert_allclose(np.array(u["xyz_to_rgb"]) @ np.array(u["rgb_to_xyz"]),
                                   np.eye(3), atol=1e-12)
        np.testing.assert_allclose(u["xyz_offset"], m.xyz_floor)
    tablet = load(TABLET).glsl_uniforms()
    assert tablet["tone_params"][0] == pytest.approx([1.02, -0.02, 2.18, 0.0])


def test_shipped_display_files_load_and_mark_estimates():
    from lbscene.engine.files.load import load_document
    from lbscene.schemas.display import Display

    for path in (SRGB, TABLET):
        text = path.read_text()
        assert text.startswith("# yaml-language-server: $schema=../schemas/json/display.schema.json")
        doc = load_document(path, Display).model
        assert doc.provenance.status == "estimate" or doc.provenance.estimated_fields
    assert load_document(TABLET, Display).model.provenance.status == "estimate"


BAD = [
    ("tone_response:\n  red: {type: cubic}\n", "LB105"),
    ("tone_response:\n  red: {type: gog, gain: 1.2, offset: -0.1, gamma: 2.2}\n", "LB104"),
    ("white_xy: [0.7, 0.25]\n", "LB104"),
    ("screen_reflection: 0.1\n", "LB100"),
    ("white_luminance_cd_m2: -5\n", "LB103"),
]


@pytest.mark.parametrize("patch,code", BAD, ids=[b[1] + str(i) for i, b in enumerate(BAD)])
def test_display_file_errors_are_located(tmp_path, patch, code):
    import io

    from ruamel.yaml import YAML

    from lbscene.engine.files.diagnostics import LbsceneUserError
    from lbscene.engine.files.load import load_document
    from lbscene.schemas.display import Display

    safe = YAML(typ="safe")
    data, change = safe.load(SRGB.read_text()), safe.load(patch)
    for key, value in change.items():
        data[key] = {**data[key], **value} if key == "tone_response" else value
    buf = io.StringIO()
    YAML().dump(data, buf)
    p = tmp_path / "d.yaml"
    p.write_text(buf.getvalue())
    with pytest.raises(LbsceneUserError) as exc:
        load_document(p, Display)
    assert code in [d.code for d in exc.value.diagnostics]
    assert all(d.location is not None and d.location.line > 0 for d in exc.value.diagnostics)


def test_missing_display_file_is_a_user_error(tmp_path):
    from lbscene.engine.files.diagnostics import LbsceneUserError

    with pytest.raises(LbsceneUserError) as exc:
        load(tmp_path / "nope.yaml")
    assert exc.value.diagnostics[0].code == "LB010"
