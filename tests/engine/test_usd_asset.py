"""The USD stage as an asset for other tools: materials from spectral reflectances (adapted to the
lighting's white, linear Rec. 709), a transmissive diffuser, shaping for declared profiles, per
lighting only the lamps that are on (variants in the stage of all lightings), IES files written
next to the stage and referenced relatively, and usd-core's validators."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest

REPO = Path(__file__).resolve().parents[2]
SPLQC = REPO / "booths" / "xrite-spectralight-qc"


def _sd_1nm(sd):
    import colour

    sd = sd.copy().align(colour.SpectralShape(360, 830, 1), extrapolator_kwargs={"method": "Constant"})
    return np.asarray(sd.values, float)


@pytest.mark.parametrize("light", ["A", "FL11", "D65"])
def test_neutral_grey_stays_neutral_under_any_lighting(light):
    import colour

    from lbscene.engine.scene.usd_stage import adapted_linear_srgb

    spd = _sd_1nm(colour.SDS_ILLUMINANTS[light])
    assert adapted_linear_srgb(np.full(471, 0.18), spd) == pytest.approx((0.18, 0.18, 0.18), abs=1e-5)
    assert adapted_linear_srgb(np.ones(471), spd) == pytest.approx((1.0, 1.0, 1.0), abs=1e-5)


def test_material_colour_under_d65_is_colour_sciences_linear_srgb():
    """Under D65 the adaptation is (nearly) the identity: the colour is colour-science's
    ``sd_to_XYZ`` → ``XYZ_to_sRGB`` (linear) of the ColorChecker patch."""
    import colour

    from lbscene.engine.scene.usd_stage import adapted_linear_srgb

    d65 = colour.SDS_ILLUMINANTS["D65"]
    for name in ("dark skin", "blue sky", "moderate red"):
        sd = colour.SDS_COLOURCHECKERS["ColorChecker N Ohta"][name]
        xyz = colour.sd_to_XYZ(sd.copy().align(colour.SpectralShape(360, 830, 1),
                                               extrapolator_kwargs={"method": "Constant"}),
                               illuminant=d65.copy().align(colour.SpectralShape(360, 830, 1))) / 100
        want = colour.XYZ_to_sRGB(xyz, apply_cctf_encoding=False)
        got = adapted_linear_srgb(_sd_1nm(sd), _sd_1nm(d65))
        np.testing.assert_allclose(got, want, atol=2e-3)


def test_gaussian_profile_fitted_cosine_power():
    from lbscene.engine.scene.usd_stage import fit_cosine_power

    # narrow beams: the small-angle closed form exp(−θ²/4σ²) ≈ cosⁿθ ⇔ n = 1/(2σ²)
    for sigma_deg in (3.0, 6.0):
        assert fit_cosine_power(sigma_deg) == pytest.approx(1 / (2 * np.radians(sigma_deg) ** 2), rel=0.03)
    # a wide beam (cosⁿ must reach 0 at 90°, a Gaussian does not): the least-squares exponent
    # carries the light (solid-angle weighted) better than the small-angle one or no shaping at all
    t = np.linspace(0, np.pi / 2, 1801)
    g = np.exp(-(np.degrees(t) / 80.0) ** 2)

    def rms(n):
        return np.sqrt(np.sum(np.sin(t) * (np.cos(t) ** n - g) ** 2) / np.sum(np.sin(t)))

    n = fit_cosine_power(40.0)
    assert rms(n) < 0.8 * rms(1 / (2 * np.radians(40.0) ** 2)) and rms(n) < 0.5 * rms(0.0)


def test_ies_text_round_trip():
    from lbscene.engine.spectra.profiles import read_ies
    from lbscene.engine.scene.usd_stage import ies_text

    data = {"vertical_deg": [0, 30, 60, 90], "horizontal_deg": [0, 90, 180],
            "candela": [[100, 80, 40, 0], [100, 70, 30, 0], [100, 60, 20, 0]], "lumens_per_lamp": 500}
    with pytest.MonkeyPatch().context():
        import tempfile

        with tempfile.TemporaryDirectory() as d:
            p = Path(d) / "x.ies"
            p.write_text(ies_text("x", data))
            got = read_ies(p, "x.ies")
    np.testing.assert_array_equal(got.vertical_deg, data["vertical_deg"])
    np.testing.assert_array_equal(got.horizontal_deg, data["horizontal_deg"])
    np.testing.assert_array_equal(got.candela, data["candela"])
    assert got.lumens_per_lamp == 500


@pytest.fixture(scope="module")
def splqc_build(tmp_path_factory):
    from lbscene.engine.scene.build import build_booth
    from lbscene.engine.scene.compile import compile_booth

    out = tmp_path_factory.mktemp("splqc") / "build"
    build_booth(SPLQC, out)
    return out, compile_booth(SPLQC)


def test_per_lighting_stage_has_only_the_lamps_on(splqc_build):
    from pxr import Usd, UsdLux

    from lbscene.engine.scene.usd_stage import register_schema

    out, ir = splqc_build
    register_schema()
    for name, cfg in ir.lighting.items():
        stage = Usd.Stage.Open(str(out / "lighting" / name / "scene.usda"))
        ids = {p.GetAttribute("lbscene:lamp:id").Get() for p in stage.Traverse()
               if p.HasAPI(UsdLux.LightAPI) or p.IsA(UsdLux.BoundableLightBase)}
        assert ids == set(cfg.lamps), name


def test_stage_of_all_lightings_has_a_lighting_variant_set(splqc_build):
    from pxr import Usd, UsdLux, UsdShade

    out, ir = splqc_build
    stage = Usd.Stage.Open(str(out / "scene.usda"))
    vset = stage.GetDefaultPrim().GetVariantSets().GetVariantSet("lighting")
    assert vset.GetVariantNames() == sorted(ir.lighting)
    assert vset.GetVariantSelection() == next(iter(ir.lighting))
    grey = UsdShade.Shader.Get(stage, "/Booth/Materials/grey_n7/PreviewSurface")
    colours = {}
    for name, cfg in ir.lighting.items():
        vset.SetVariantSelection(name)
        ids = {p.GetAttribute("lbscene:lamp:id").Get() for p in stage.Traverse()
               if p.IsA(UsdLux.BoundableLightBase)}
        assert ids == set(cfg.lamps), name
        colours[name] = tuple(grey.GetInput("diffuseColor").Get())
    # the N7 grey is (nearly) neutral under every lighting, adapted: no pink, no orange
    for name, rgb in colours.items():
        assert max(rgb) - min(rgb) < 0.01, (name, rgb)


def test_materials_diffuser_and_shaping(splqc_build):
    from pxr import Usd, UsdGeom, UsdLux, UsdShade

    from lbscene.engine.scene.usd_stage import fit_cosine_power, luminous_factor, lighting_spectrum_1nm

    out, ir = splqc_build
    stage = Usd.Stage.Open(str(out / "lighting" / "D65" / "scene.usda"))
    for prim in stage.GetPrimAtPath("/Booth/Surfaces").GetChildren():
        mat, _ = UsdShade.MaterialBindingAPI(prim).ComputeBoundMaterial()
        assert mat, prim.GetPath()
        shader = mat.ComputeSurfaceSource()[0]
        assert shader.GetIdAttr().Get() == "UsdPreviewSurface"
    diffuser = stage.GetPrimAtPath("/Booth/Diffuser")
    assert diffuser.IsA(UsdGeom.Mesh) and not diffuser.IsA(UsdGeom.Cube)
    shader = UsdShade.MaterialBindingAPI(diffuser).ComputeBoundMaterial()[0].ComputeSurfaceSource()[0]
    tau = luminous_factor(ir.diffuser.transmittance.array_1nm, lighting_spectrum_1nm(ir, "D65"))
    assert 0.5 < tau < 1.0
    assert shader.GetInput("opacity").Get() == pytest.approx(1.0 - tau, abs=1e-5)
    for lp in ir.lamps:
        if lp.id not in ir.lighting["D65"].lamps or lp.profile["type"] != "gaussian":
            continue
        shaping = UsdLux.ShapingAPI(stage.GetPrimAtPath(f"/Booth/Lamps/{lp.id}"))
        assert shaping.GetShapingFocusAttr().Get() == pytest.approx(
            fit_cosine_power(lp.profile["sigma_deg"]), rel=1e-5)
        break
    else:
        pytest.fail("the SpectraLight QC's D65 lamps declare a Gaussian profile")


def test_every_mesh_has_its_declared_material(splqc_build):
    """Lint of the stage: every mesh (surfaces, diffuser, the SpectraLight's masks and lamp boxes)
    is bound to a material, an occluder to the one its booth file declares."""
    from pxr import Usd, UsdGeom, UsdShade

    out, ir = splqc_build
    declared = {o.id: o.material for o in ir.occluders}
    assert declared == {"D65_left_mask": "mask_black", "D65_right_mask": "mask_black",
                        "D65_left_box_inner": "luminaire_white", "D65_left_box_outer": "luminaire_white",
                        "D65_right_box_inner": "luminaire_white", "D65_right_box_outer": "luminaire_white"}
    for path in (out / "scene.usda", out / "lighting" / "D65" / "scene.usda"):
        stage = Usd.Stage.Open(str(path))
        unbound = [str(p.GetPath()) for p in stage.Traverse() if p.IsA(UsdGeom.Mesh)
                   and not UsdShade.MaterialBindingAPI(p).ComputeBoundMaterial()[0]]
        assert unbound == [], path
        for oid, mid in declared.items():
            prim = stage.GetPrimAtPath(f"/Booth/Occluders/{oid}")
            mat = UsdShade.MaterialBindingAPI(prim).ComputeBoundMaterial()[0]
            assert mat.GetPath().name == mid


def test_observer_camera_frames_the_floor(splqc_build):
    """The stage's camera stands at the observer, looks at ``look_at_mm`` and its field of view,
    2 atan(aperture / 2 focal length), holds the whole floor, its corners within the 5 % margin."""
    from pxr import Gf, Usd, UsdGeom

    out, ir = splqc_build
    stage = Usd.Stage.Open(str(out / "scene.usda"))
    cam = UsdGeom.Camera(stage.GetPrimAtPath("/Booth/Observer"))
    m = cam.ComputeLocalToWorldTransform(Usd.TimeCode.Default())
    eye = np.array(m.ExtractTranslation())
    assert eye == pytest.approx([0, -600, 560])                   # the booth file's eye point
    fwd = np.array(m.TransformDir(Gf.Vec3d(0, 0, -1)))
    fwd /= np.linalg.norm(fwd)
    right = np.array(m.TransformDir(Gf.Vec3d(1, 0, 0)))
    right /= np.linalg.norm(right)
    up = np.cross(right, fwd)
    assert fwd == pytest.approx(-eye / np.linalg.norm(eye))      # looking at the sample
    f = cam.GetFocalLengthAttr().Get()
    tx = cam.GetHorizontalApertureAttr().Get() / (2 * f)
    ty = cam.GetVerticalApertureAttr().Get() / (2 * f)
    w, d = ir.interior.width_mm / 2, ir.interior.depth_mm / 2
    p = np.array([[x, y, 0] for x in (-w, w) for y in (-d, d)]) - eye
    u = np.abs(p @ right) / (p @ fwd) / tx
    v = np.abs(p @ up) / (p @ fwd) / ty
    assert u.max() == pytest.approx(1 / 1.05, rel=1e-4) and v.max() == pytest.approx(1 / 1.05, rel=1e-4)


def test_validators_pass_and_can_fail(splqc_build, tmp_path):
    from lbscene.engine.scene.usd_stage import validate_stage

    out, _ = splqc_build
    assert validate_stage(out / "scene.usda") == []
    assert validate_stage(out / "lighting" / "A" / "scene.usda") == []
    bad = tmp_path / "bad.usda"
    bad.write_text('#usda 1.0\n(\n)\ndef Mesh "m"\n{\n    rel material:binding = </nowhere>\n}\n')
    assert validate_stage(bad)      # stage metadata missing, binding without MaterialBindingAPI


def test_ies_file_copied_and_referenced_relatively(minimal_booth, tmp_path):
    from pxr import Sdf, Usd, UsdLux

    from lbscene.engine.scene.build import build_booth
    from lbscene.engine.spectra.profiles import read_ies
    from lbscene.engine.scene.usd_stage import validate_stage

    (minimal_booth / "bulb.ies").write_text(
        "IESNA:LM-63-2002\nTILT=NONE\n1 1000 1 4 1 1 2 0 0 0\n1 1 0\n0 30 60 90\n0\n200 150 60 0\n")
    text = (minimal_booth / "booth.yaml").read_text()
    text = text.replace("    output: {type: peak_intensity_cd, value_cd: 1000}",
                        "    output: {type: peak_intensity_cd, value_cd: 1000}\n"
                        "    profile: {type: ies, path: bulb.ies}")
    (minimal_booth / "booth.yaml").write_text(text)
    out = tmp_path / "out"
    build_booth(minimal_booth, out)
    moved = tmp_path / "moved"
    shutil.move(str(out), moved)               # relative references survive moving the build
    for stage_path in (moved / "scene.usda", moved / "lighting" / "A" / "scene.usda"):
        stage = Usd.Stage.Open(str(stage_path))
        asset = UsdLux.ShapingAPI(stage.GetPrimAtPath("/Booth/Lamps/bulb")).GetShapingIesFileAttr().Get()
        assert isinstance(asset, Sdf.AssetPath) and asset.path == "./assets/bulb.ies"
        resolved = Path(asset.resolvedPath)
        assert resolved.is_file() and resolved.parent == stage_path.parent / "assets"
        got = read_ies(resolved, "bulb.ies")
        np.testing.assert_array_equal(got.candela, [[200, 150, 60, 0]])
        assert validate_stage(stage_path) == []


def test_light_intensity_times_colour_luminance_is_the_peak_candela(splqc_build):
    """UsdLux: luminance = intensity × Y(color) (Rec. 709 luminance weights, IEC 61966-2-1), area in m²
    from the stage's millimetres and metersPerUnit."""
    from pxr import Usd, UsdGeom, UsdLux

    out, ir = splqc_build
    stage = Usd.Stage.Open(str(out / "lighting" / "A" / "scene.usda"))
    mpu = UsdGeom.GetStageMetersPerUnit(stage)
    y709 = np.array([0.2126, 0.7152, 0.0722])
    for lp in ir.lamps:
        if lp.id not in ir.lighting["A"].lamps:
            continue
        prim = stage.GetPrimAtPath(f"/Booth/Lamps/{lp.id}")
        light = UsdLux.LightAPI(prim)
        if prim.IsA(UsdLux.CylinderLight):
            c = UsdLux.CylinderLight(prim)
            area_m2 = c.GetLengthAttr().Get() * 2 * c.GetRadiusAttr().Get() * mpu ** 2
        elif prim.IsA(UsdLux.RectLight):
            r = UsdLux.RectLight(prim)
            area_m2 = r.GetWidthAttr().Get() * r.GetHeightAttr().Get() * mpu ** 2
        else:
            area_m2 = np.pi * (UsdLux.SphereLight(prim).GetRadiusAttr().Get() * mpu) ** 2
        cd = light.GetIntensityAttr().Get() * float(y709 @ np.array(light.GetColorAttr().Get())) * area_m2
        assert cd == pytest.approx(lp.peak_luminous_intensity_cd, rel=2e-4), lp.id
