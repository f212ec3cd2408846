"""Build: deterministic, atomic, and the USD stage reads back with usd-core."""

import json

import pytest

from lbscene.engine.scene import build as build_mod
from lbscene.engine.scene.build import build_booth


def _tree(d):
    return {p.relative_to(d).as_posix(): p.read_bytes() for p in sorted(d.rglob("*")) if p.is_file()}


def test_build_is_byte_identical_across_runs_and_cwd(minimal_booth, tmp_path, monkeypatch):
    build_booth(minimal_booth, tmp_path / "o1")
    monkeypatch.chdir(minimal_booth)
    build_booth(minimal_booth / "booth.yaml", tmp_path / "o2")
    assert _tree(tmp_path / "o1") == _tree(tmp_path / "o2")


def test_interrupted_build_leaves_previous_output_intact(minimal_booth, tmp_path, monkeypatch):
    out = tmp_path / "out"
    build_booth(minimal_booth, out)
    before = _tree(out)

    def boom(*a, **k):
        raise KeyboardInterrupt

    monkeypatch.setattr(build_mod, "PRODUCT_WRITERS", [("lbscene.engine.scene.build", "_boom")])
    monkeypatch.setattr(build_mod, "_boom", boom, raising=False)
    (minimal_booth / "booth.yaml").write_text(
        (minimal_booth / "booth.yaml").read_text().replace("value_cd: 1000", "value_cd: 2000"))
    with pytest.raises(KeyboardInterrupt):
        build_booth(minimal_booth, out)
    assert _tree(out) == before
    assert [p.name for p in tmp_path.iterdir() if p.name.startswith(".out")] == []


def test_manifest_lists_every_file_with_its_hash(minimal_booth, tmp_path):
    import hashlib

    out = tmp_path / "out"
    res = build_booth(minimal_booth, out)
    man = json.loads((out / "manifest.json").read_text())
    assert man["ir_hash"] == res.ir_hash
    for rel, digest in man["files"].items():
        assert hashlib.sha256((out / rel).read_bytes()).hexdigest() == digest
    assert set(man["files"]) == {p.relative_to(out).as_posix() for p in out.rglob("*")
                                 if p.is_file() and p.name != "manifest.json"}


def test_usd_stage_lights_and_spectral_attributes_read_back(minimal_booth, tmp_path):
    from pxr import Usd, UsdGeom, UsdLux

    from lbscene.engine.scene.compile import compile_booth
    from lbscene.engine.scene.usd_stage import register_schema

    register_schema()
    out = tmp_path / "out"
    build_booth(minimal_booth, out)
    ir = compile_booth(minimal_booth)
    stage = Usd.Stage.Open(str(out / "lighting" / "A" / "scene.usda"))
    assert UsdGeom.GetStageMetersPerUnit(stage) == pytest.approx(0.001)
    root = stage.GetDefaultPrim()
    assert root.HasAPI("LbsceneBoothAPI")
    assert root.GetAttribute("lbscene:booth:irHash").Get() == ir.content_hash
    light = stage.GetPrimAtPath("/Booth/Lamps/bulb")
    assert light.IsA(UsdLux.SphereLight) and light.HasAPI("LbsceneLampAPI")
    assert light.HasAPI("LbsceneSpectralAPI")
    bands = list(light.GetAttribute("lbscene:spectral:bandValues").Get())
    assert bands == pytest.approx([ir.lamps[0].intensity_scale_W_sr_nm * b for b in ir.lamps[0].spd.bands],
                                  rel=1e-6)
    assert light.GetAttribute("lbscene:lamp:peakIntensity_cd").Get() == pytest.approx(1000.0)
    # the codeless schema defines the attributes: they exist with fallbacks before authoring
    floor = stage.GetPrimAtPath("/Booth/Surfaces/floor")
    assert floor.IsA(UsdGeom.Mesh) and floor.HasAPI("LbsceneSpectralAPI")
    assert floor.GetAttribute("lbscene:spectral:quantity").Get() == "reflectance"
    # the paint CSV: 0.2 @ 380 nm … 0.4 @ 500 nm (linear): band 390-410 mean = value at 400 nm = 0.2333…
    assert floor.GetAttribute("lbscene:spectral:bandValues").Get()[0] == pytest.approx(0.2 + 0.2 * 20 / 120,
                                                                                          rel=1e-6)


def test_unknown_lighting_is_a_user_error(minimal_booth, tmp_path, run_cli):
    code, _, err = run_cli("build", minimal_booth, "--lighting", "D65", "--out", tmp_path / "o")
    assert code == 2
    assert "error LB500: booth has no lighting configuration 'D65' (got 'D65'; expected one of A)" in err


def test_build_json_output(minimal_booth, tmp_path, run_cli):
    code, out, _ = run_cli("build", minimal_booth, "--out", tmp_path / "o", "--format", "json")
    assert code == 0
    d = json.loads(out)
    assert d["lightings"] == ["A"] and "scene.usda" in d["files"]
