"""Every file a booth refers to is opened by ``validate-config`` and its problems are located in
that file (``file:line:col``, exit 2, no traceback): IES photometry and OBJ/USD meshes."""

from __future__ import annotations

import pytest

from lbscene.engine.files.diagnostics import LbsceneUserError

IES_HEAD = "IESNA:LM-63-2002\nTILT=NONE\n"
GOOD_IES = "1 1000 1 3 1 1 2 0 0 0\n1 1 0\n0 45 90\n0\n100 50 0\n"


@pytest.fixture
def ies_booth(minimal_booth):
    f = minimal_booth / "booth.yaml"
    f.write_text(f.read_text().replace(
        "    output: {type: peak_intensity_cd, value_cd: 1000}\n",
        "    output: {type: peak_intensity_cd, value_cd: 1000}\n    profile: {type: ies, path: lamp.ies}\n"))
    return minimal_booth


@pytest.mark.parametrize("body,expected", [
    ("1 1000 1 inf 1 1 2 0 0 0\n1 1 0\n0 45 90\n0\n100 50 0\n",
     "lamp.ies:3:10: error LB203: IES number of vertical angles is not a finite number "
     "(got 'inf'; expected a finite number)"),
    ("1 1000 1 0 1 1 2 0 0 0\n1 1 0\n0 45 90\n0\n100 50 0\n",
     "lamp.ies:3:10: error LB203: IES number of vertical angles must be a whole number from 2 to 10000 "
     "(got '0'; expected a whole number 2 … 10000)"),
    ("1 1000 1 3 2.5 1 2 0 0 0\n1 1 0\n0 45 90\n0\n100 50 0\n",
     "lamp.ies:3:12: error LB203: IES number of horizontal angles must be a whole number from 1 to 10000 "
     "(got '2.5'; expected a whole number 1 … 10000)"),
    ("1 1000 1 3 1 1 2 0 0 0\n1 1 0\n0 45 90\n0\n100 50 0 7\n",
     "lamp.ies:7:10: error LB203: IES file has 8 values after its header; its counts (3 vertical × 1 "
     "horizontal angles) need 7 (got 8 values; expected 3 vertical angles, 1 horizontal angles and 3 × 1 "
     "candela values: the first extra value is here)"),
    ("1 1000 1 3 1 1 2 0 0 0\n1 1 0\n0 45 90\n0\n100 50\n",
     "lamp.ies:7:5: error LB203: IES file has 6 values after its header; its counts (3 vertical × 1 "
     "horizontal angles) need 7 (got 6 values; expected 3 vertical angles, 1 horizontal angles and 3 × 1 "
     "candela values)"),
    ("1 1000 1 3 1 1 2 0 0 0\n1 1 0\n0 45 90\n0\n100 nan 0\n",
     "lamp.ies:7:5: error LB203: IES candela value is not a finite number (got 'nan'; expected a finite number)"),
    ("1 1000 1 3 1 1 2 0 0 0\n1 1 0\n0 45 90\n0\n100 -50 0\n",
     "lamp.ies:7:5: error LB203: IES candela value is negative (got '-50'; expected candela values ≥ 0 "
     "(finite after the multiplier))"),
    ("1 1000 1e308 3 1 1 2 0 0 0\n1 1 0\n0 45 90\n0\n100 1e10 0\n",
     "lamp.ies:7:1: error LB203: IES candela value times the multiplier overflows (got '100'; expected "
     "candela values ≥ 0 (finite after the multiplier))"),
    ("1 1000 1 3 1 1 2 0 0 0\n1 1 0\n0 90 45\n0\n100 50 0\n",
     "lamp.ies:5:6: error LB203: IES vertical angles are not increasing (got 45 after 90; expected strictly "
     "increasing vertical angles)"),
    ("1 1000 1 3\n",
     "lamp.ies:3:10: error LB203: IES header has 4 of its 13 numbers after TILT=NONE"),
])
def test_bad_ies_is_located_in_the_ies_file_at_validate_time(ies_booth, run_cli, body, expected):
    (ies_booth / "lamp.ies").write_text(IES_HEAD + body)
    code, out, err = run_cli("validate-config", ies_booth, cwd=ies_booth)
    assert code == 2 and "Traceback" not in err
    assert expected in err


def test_a_sound_ies_file_passes(ies_booth, run_cli):
    (ies_booth / "lamp.ies").write_text(IES_HEAD + GOOD_IES)
    code, _, err = run_cli("validate-config", ies_booth)
    assert code == 0, err
    from lbscene.engine.spectra.profiles import read_ies

    d = read_ies(ies_booth / "lamp.ies", "lamp.ies")
    assert d.vertical_deg.tolist() == [0, 45, 90] and d.candela.tolist() == [[100, 50, 0]]


# --------------------------------------------------------------------------- meshes

def _with_mesh(booth_dir, entry: str):
    f = booth_dir / "booth.yaml"
    f.write_text(f.read_text() + "geometry_files:\n" + entry)


@pytest.fixture
def obj_booth(minimal_booth):
    _with_mesh(minimal_booth, "  - {type: obj, id: m, path: m.obj, material: grey}\n")
    return minimal_booth


@pytest.mark.parametrize("obj,expected", [
    ("v 0 0 100\nv 100 0 100\nv 0 nan 100\nf 1 2 3\n",
     "m.obj:3:5: error LB203: vertex coordinate is not a finite number (got 'nan'; expected a finite number)"),
    ("v 0 0 100\nv 100 0 100\nv 200 0 100\nf 1 2 3\n",
     "m.obj:4:1: error LB312: mesh m.obj: face 1 is degenerate: its corners are collinear or coincide (got "
     "corners [[0.0, 0.0, 100.0], [100.0, 0.0, 100.0], [200.0, 0.0, 100.0]]; expected a face with an area "
     "(corners not on one line))"),
    ("v 0 0 100\nv 100 0 100\nv 0 100 100\nv 0 100 100\nf 1 2 3 4\n",       # a quad with a repeated corner
     "m.obj:5:1: error LB312: mesh m.obj: face 1 is degenerate"),
    ("v 0 0 100\nv 1e200 0 100\nv 0 1e200 100\nf 1 2 3\n",
     "m.obj:4:1: error LB312: mesh m.obj: face 1 normal overflows (coordinates too large)"),
    ("v 0 0 100\nv 100 0 100\nv 0 100 5000\nf 1 2 3\n",
     "m.obj:3:1: error LB313: mesh m.obj reaches outside the booth at rest (got vertex at [0.0, 100.0, 5000.0] "
     "mm; expected every vertex inside the interior"),
    ("v 0 0 100\nv 100 0 100\nv 0 100 500\nf 1 2 9\n",
     "m.obj:4:1: error LB203: face names vertex 9, the file has 3 (expected vertex numbers 1 … 3)"),
    ("v 0 0 100\nv 100 0 100\nv 0 100 500\nf 1 2 x\n",
     "m.obj:4:7: error LB203: face corner is not a vertex index (got 'x'; expected a vertex number"),
    ("v 0 0\n", "m.obj:1:1: error LB203: vertex needs three coordinates (got 'v 0 0'; expected v x y z)"),
])
def test_bad_obj_is_located_in_the_obj_file_at_validate_time(obj_booth, run_cli, obj, expected):
    # validate-config used to accept OBJ files it never opened
    (obj_booth / "m.obj").write_text(obj)
    code, out, err = run_cli("validate-config", obj_booth)
    assert code == 2 and "Traceback" not in err
    assert expected in err


def test_a_sound_obj_passes_and_relative_indices_work(obj_booth, run_cli):
    (obj_booth / "m.obj").write_text("v 0 0 100\nv 100 0 100\nv 100 100 100\nv 0 100 100\n"
                                     "vt 0 0\nf -4/1 -3/1 -2/1 -1/1\n")
    code, _, err = run_cli("validate-config", obj_booth)
    assert code == 0, err


def test_a_million_faces_are_refused_before_any_parsing(obj_booth, run_cli, monkeypatch):
    (obj_booth / "m.obj").write_text("v 0 0 100\nv 100 0 100\nv 0 100 100\n" + "f 1 2 3\n" * 1_000_000)
    import trimesh

    def never(*a, **k):  # the bound comes before the mesh library sees the file
        raise AssertionError("trimesh opened a mesh over the bound")

    monkeypatch.setattr(trimesh, "load", never)
    code, _, err = run_cli("validate-config", obj_booth)
    assert code == 2
    assert ("m.obj: error LB510: faces in m.obj: 1000000 exceeds the limit of 20000 (got 1000000; expected at "
            "most 20000 (each triangle is two inter-reflection patches and a visibility test at every receiver))\n"
            "    hint: raise the limit with the environment variable LBSCENE_MAX_MESH_TRIANGLES=N") in err
    from lbscene.engine.scene.compile import compile_booth

    with pytest.raises(LbsceneUserError) as exc:        # the API: the same refusal
        compile_booth(obj_booth)
    assert exc.value.diagnostics[0].code == "LB510"


def test_polygons_count_as_their_triangles(obj_booth, run_cli, monkeypatch):
    # one face of 12 corners is 10 triangles: over a bound of 9, within one of 10
    ring = "".join(f"v {300 * __import__('math').cos(k * 0.5236):.6f} {200 * __import__('math').sin(k * 0.5236):.6f} "
                   f"100\n" for k in range(12))
    (obj_booth / "m.obj").write_text(ring + "f " + " ".join(str(i) for i in range(1, 13)) + "\n")
    monkeypatch.setenv("LBSCENE_MAX_MESH_TRIANGLES", "9")
    code, _, err = run_cli("validate-config", obj_booth)
    assert code == 2 and "m.obj:13:1: error LB510: triangles in m.obj (counted up to this line): 10 exceeds " \
                         "the limit of 9" in err
    monkeypatch.setenv("LBSCENE_MAX_MESH_TRIANGLES", "10")
    code, _, err = run_cli("validate-config", obj_booth)
    assert code == 0, err


def test_a_platform_mesh_turned_out_of_the_booth(minimal_booth, run_cli):
    f = minimal_booth / "booth.yaml"
    f.write_text(f.read_text().replace(
        "geometries: [{name: 45as45}]\n",
        "platform: {centre_mm: [0, 0, 100], size_mm: [200, 200], rotation_axis: [1, 0, 0]}\n"
        "geometries: [{name: 45as45}, {name: 45as15, platform_rotation_deg: 90}]\n"))
    _with_mesh(minimal_booth, "  - {type: obj, id: m, path: m.obj, material: grey, mount: platform}\n")
    # a 500 mm tall fin on the platform: inside at rest; turned 90° about x its top (line 3) leaves
    # through the open front (y = -500 mm, the booth is 600 mm deep)
    (minimal_booth / "m.obj").write_text("v 0 0 100\nv 0 280 100\nv 0 280 600\nf 1 2 3\n")
    code, _, err = run_cli("validate-config", minimal_booth)
    assert code == 2
    assert ("m.obj:3:1: error LB313: mesh m.obj reaches outside the booth at geometry 45as15 (got vertex at "
            "[0.0, -500.0, 380.0] mm") in err


def _usd(path, points, counts, indices):
    from lbscene.engine.scene.usd_stage import register_schema

    register_schema()   # before pxr's schema registry is first used (later builds apply lbscene's schemas)
    from pxr import Gf, Usd, UsdGeom

    stage = Usd.Stage.CreateNew(str(path))
    UsdGeom.SetStageMetersPerUnit(stage, 0.001)
    mesh = UsdGeom.Mesh.Define(stage, "/Prop/Fin")
    mesh.CreatePointsAttr([Gf.Vec3f(*p) for p in points])
    mesh.CreateFaceVertexCountsAttr(counts)
    mesh.CreateFaceVertexIndicesAttr(indices)
    stage.Save()


@pytest.mark.parametrize("points,counts,indices,expected", [
    ([(0, 0, 100), (100, 0, 100), (0, 100, 100)], [3], [0, 1, 7],
     "prop.usda: error LB203: USD mesh /Prop/Fin has a face-vertex index outside the 3 points"),
    ([(0, 0, 100), (100, 0, 100), (0, 100, 100)], [3, 3], [0, 1, 2],
     "prop.usda: error LB203: USD mesh /Prop/Fin has 3 face-vertex indices for faces of 6 corners"),
    ([(0, 0, 100), (100, 0, 100), (200, 0, 100)], [3], [0, 1, 2],
     "prop.usda: error LB312: USD mesh Fin: face 1 is degenerate"),
    ([(0, 0, 100), (100, 0, 100), (0, 100, 9000)], [3], [0, 1, 2],
     "prop.usda: error LB313: USD mesh Fin reaches outside the booth at rest"),
])
def test_bad_usd_mesh_is_located_in_the_usd_file(minimal_booth, run_cli, points, counts, indices, expected):
    _usd(minimal_booth / "prop.usda", points, counts, indices)
    _with_mesh(minimal_booth, "  - {type: usd, id: prop, path: prop.usda, material: grey}\n")
    code, _, err = run_cli("validate-config", minimal_booth)
    assert code == 2 and "Traceback" not in err
    assert expected in err


# --------------------------------------------------------------------------- measurement sets, CSV, JSON

@pytest.fixture
def meas_dir(minimal_booth, tmp_path):
    import os

    d = tmp_path / "m"
    d.mkdir()
    (d / "grid.csv").write_text("x_mm,y_mm,illuminance_lx\n0,0,2000\n100,0,1900\n0,100,1900\n")
    (d / "meas.yaml").write_text(
        "version: 1\nkind: measurement_set\nname: t\n"
        f"booth: {os.path.relpath(minimal_booth, d)}\nlighting: A\n"
        "instrument: {illuminance_meter: m, repeatability_percent: 0.5}\n"
        "illuminance:\n  - path: grid.csv\n")
    return d


def test_measurement_data_files_are_read_at_validate_time(meas_dir, run_cli):
    (meas_dir / "grid.csv").write_text("x_mm,y_mm,illuminance_lx\n0,0,2000\n100,0,nan\n0,100,-3\n")
    code, _, err = run_cli("validate-config", meas_dir / "meas.yaml", cwd=meas_dir)
    assert code == 2
    assert "grid.csv:3:7: error LB401: 'illuminance_lx' is not a finite number (got 'nan'; expected a finite " \
           "number)" in err
    assert "grid.csv:4:7: error LB402: negative illuminance (got '-3'; expected a reading > 0 lx)" in err


def test_a_csv_cell_over_128_kB_is_a_located_error(meas_dir, run_cli, minimal_booth):
    (meas_dir / "grid.csv").write_text("x_mm,y_mm,illuminance_lx\n0,0,2000\n1,\"" + "9" * 200_000 + "\",3\n")
    code, _, err = run_cli("validate-config", meas_dir / "meas.yaml", cwd=meas_dir)
    assert code == 2 and "Traceback" not in err
    assert "grid.csv:3:1: error LB014: a CSV cell is larger than 128 kB (expected cells of at most 131072 " \
           "characters)" in err
    (minimal_booth / "spectra" / "paint.csv").write_text("wavelength_nm,r\n" + "5" * 140_000 + ",0.5\n")
    code, _, err = run_cli("validate-config", minimal_booth, cwd=minimal_booth)
    assert code == 2 and "spectra/paint.csv:2:1: error LB014: a CSV cell is larger than 128 kB" in err


def test_instrument_file_values_are_checked(tmp_path):
    import shutil
    from pathlib import Path

    colour = pytest.importorskip("colour")
    from lbscene.engine.spectra.evaluate import evaluate_spectrum
    from lbscene.schemas.spectrum import InstrumentFileSpectrum

    src = Path(colour.__file__).parent / "io" / "tests" / "resources" / "RANDOM_001_02._3262K.csv"
    text = src.read_text()
    for bad, code, msg in (("nan", "LB401", "the value at 500 nm is not a finite number"),
                           ("-5", "LB402", "the value at 500 nm is negative")):
        f = tmp_path / f"{code}.csv"
        f.write_text("\n".join(f"Spectral Data 500[nm],{bad}" if ln.startswith("Spectral Data 500[nm]") else ln
                               for ln in text.splitlines()) + "\n")
        spec = InstrumentFileSpectrum(type="instrument_file", format="sekonic", path=f.name)
        with pytest.raises(LbsceneUserError) as exc:
            evaluate_spectrum(spec, lambda p: tmp_path / p, "emission", display=f.name)
        d = exc.value.diagnostics[0]
        assert (d.code, d.message, d.location.file) == (code, msg, str(f))
    shutil.copy(src, tmp_path / "ok.csv")     # the instrument's own export passes
    spec = InstrumentFileSpectrum(type="instrument_file", format="sekonic", path="ok.csv")
    assert evaluate_spectrum(spec, lambda p: tmp_path / p, "emission").max() > 0


def test_a_history_line_with_a_non_numeric_field(meas_dir, run_cli):
    h = meas_dir / "meas.history.jsonl"
    code, _, err = run_cli("compare", meas_dir / "meas.yaml", "--no-diagnose", "--no-fit")
    assert code == 0, err
    line = h.read_text().splitlines()[0]
    h.write_text(line + "\n" + line.replace('"rmse_percent": ', '"rmse_percent": "abc", "x": ') + "\n")
    code, out, err = run_cli("history", meas_dir / "meas.yaml")
    assert code == 2 and "Traceback" not in err
    assert (f"{h}:2:1: error LB101: history line: 'rmse_percent' has the wrong type (got 'abc'; expected a "
            "finite number or null)") in err
    # compare does not rewrite a history it cannot read (the damaged line would be lost)
    before = h.read_text()
    assert run_cli("compare", meas_dir / "meas.yaml", "--no-diagnose", "--no-fit")[0] == 2
    assert h.read_text() == before
    h.write_text(line + "\n" + "[" * 5000 + "]" * 5000 + "\n")
    code, _, err = run_cli("history", meas_dir / "meas.yaml")
    assert code == 2 and f"{h}:2:65: error LB015: JSON nested too deeply (expected at most 64 levels)" in err


@pytest.mark.parametrize("kind", ["long name", "symlink loop"])
@pytest.mark.parametrize("command", ["validate-config", "build", "compare", "plan", "history", "render", "bake",
                                     "export-web", "visual-report"])
def test_a_path_the_system_refuses_is_a_located_error(tmp_path, run_cli, kind, command):
    if kind == "long name":
        p = tmp_path / ("a" * 300 + ".yaml")             # ENAMETOOLONG
    else:
        (tmp_path / "l1.yaml").symlink_to(tmp_path / "l2.yaml")
        (tmp_path / "l2.yaml").symlink_to(tmp_path / "l1.yaml")
        p = tmp_path / "l1.yaml"                           # ELOOP
    args = {"build": ["--out", tmp_path / "o"], "export-web": ["--out", tmp_path / "o"],
            "visual-report": ["--session", p], "render": ["--no-input"]}.get(command, [])
    code, out, err = run_cli(command, p, *args)
    assert code == 2 and "Traceback" not in err
    assert "error LB013: cannot" in err
    assert ("name is longer than the file system allows" in err or "File name too long" in err) if kind == \
        "long name" else ("loop of symbolic links" in err or "Too many levels of symbolic links" in err)


def test_a_deeply_nested_bake_manifest_is_skipped_or_located(tmp_path):
    from lbscene.engine.scene.compile import compile_booth
    from lbscene.runtimes.bake import find_bakes, load_bake

    d = tmp_path / "bake"
    d.mkdir()
    (d / "manifest.json").write_text('{"products": ' + "[" * 50_000 + "]" * 50_000 + "}")
    from pathlib import Path

    ir = compile_booth(Path(__file__).resolve().parents[1] / "data" / "minimal-booth")
    assert find_bakes([d], ir, "A") == (None, "no bake products found")   # looked past, no RecursionError
    with pytest.raises(LbsceneUserError) as exc:
        load_bake(d)
    assert exc.value.diagnostics[0].format().startswith(f"{d / 'manifest.json'}:1:")
    assert "error LB015: JSON nested too deeply" in exc.value.diagnostics[0].format()
