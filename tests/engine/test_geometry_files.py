"""OBJ and USD geometry enter the IR with their transforms (units: mm)."""

import numpy as np
import pytest

from lbscene.engine.scene.compile import compile_booth
from lbscene.engine.files.diagnostics import LbsceneUserError

OBJ_QUAD = """# a 1 x 2 quad in metres, in the xy plane
v 0 0 0
v 1 0 0
v 1 2 0
v 0 2 0
f 1 2 3 4
"""


def _add_geometry(booth_dir, entry: str):
    f = booth_dir / "booth.yaml"
    f.write_text(f.read_text() + "geometry_files:\n" + entry)


def test_obj_mesh_scaled_rotated_translated(minimal_booth):
    (minimal_booth / "quad.obj").write_text(OBJ_QUAD)
    _add_geometry(minimal_booth, "  - {type: obj, id: quad, path: quad.obj, material: grey,\n"
                  "     transform: {scale: 100, rotate_xyz_deg: [0, 0, 90], translate_mm: [10, 20, 30]}}\n")
    ir = compile_booth(minimal_booth)
    s = next(s for s in ir.surfaces if s.id == "quad")
    assert s.role == "mesh" and s.source == "obj:quad.obj" and len(s.triangles) == 2
    v = s.vertex_array
    # (1, 2, 0) m-units ×100 → (100, 200, 0) mm, rotated 90° about z → (-200, 100, 0), + (10, 20, 30)
    assert v[2] == pytest.approx([-190.0, 120.0, 30.0])
    assert s.area_mm2() == pytest.approx(100 * 200)


def test_usd_mesh_in_metres_converted_to_mm(minimal_booth):
    from pxr import Gf, Usd, UsdGeom

    stage = Usd.Stage.CreateNew(str(minimal_booth / "prop.usda"))
    UsdGeom.SetStageMetersPerUnit(stage, 1.0)
    UsdGeom.Xform.Define(stage, "/Prop")
    mesh = UsdGeom.Mesh.Define(stage, "/Prop/Tri")
    mesh.CreatePointsAttr([Gf.Vec3f(0, 0, 0), Gf.Vec3f(0.1, 0, 0), Gf.Vec3f(0, 0.1, 0)])
    mesh.CreateFaceVertexCountsAttr([3])
    mesh.CreateFaceVertexIndicesAttr([0, 1, 2])
    UsdGeom.Xformable(stage.GetPrimAtPath("/Prop")).AddTranslateOp().Set(Gf.Vec3d(0, 0, 0.5))
    stage.Save()
    _add_geometry(minimal_booth, "  - {type: usd, id: prop, path: prop.usda, material: grey}\n")
    ir = compile_booth(minimal_booth)
    s = next(s for s in ir.surfaces if s.id == "prop.Tri")
    np.testing.assert_allclose(s.vertex_array, [[0, 0, 500], [100, 0, 500], [0, 100, 500]], atol=1e-4)


def test_build_of_a_booth_with_usd_geometry_in_one_process(minimal_booth, tmp_path):
    """Reading a USD mesh first must not keep the lbscene schema out of the stage ``build`` writes.

    Run as a user runs it: one fresh ``lbscene build`` process (USD's schema registry is made once per
    process, by the first stage opened).
    """
    import subprocess
    import sys

    from pxr import Gf, Usd, UsdGeom

    stage = Usd.Stage.CreateNew(str(minimal_booth / "prop.usda"))
    UsdGeom.SetStageMetersPerUnit(stage, 0.001)
    mesh = UsdGeom.Mesh.Define(stage, "/Prop")
    mesh.CreatePointsAttr([Gf.Vec3f(0, 0, 10), Gf.Vec3f(100, 0, 10), Gf.Vec3f(0, 100, 10)])
    mesh.CreateFaceVertexCountsAttr([3])
    mesh.CreateFaceVertexIndicesAttr([0, 1, 2])
    stage.Save()
    _add_geometry(minimal_booth, "  - {type: usd, id: prop, path: prop.usda, material: grey}\n")
    out = tmp_path / "out"
    r = subprocess.run([sys.executable, "-m", "lbscene", "build", str(minimal_booth), "-o", str(out)],
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stdout + r.stderr
    text = next(out.rglob("*.usda")).read_text()
    assert "LbsceneBoothAPI" in text and "lbscene:spectral:bandValues" in text


def test_garbage_obj_is_a_located_error(minimal_booth):
    (minimal_booth / "bad.obj").write_bytes(b"this is not an obj file\n")
    _add_geometry(minimal_booth, "  - {type: obj, id: bad, path: bad.obj, material: grey}\n")
    with pytest.raises(LbsceneUserError) as exc:
        compile_booth(minimal_booth)
    d = exc.value.diagnostics[0]
    assert d.code == "LB203" and d.location.file == "bad.obj"


@pytest.mark.parametrize("faces", [["1 2 3", "1 3 4", "2 4 3/7/1"],
                                   ["1 2 3 4", "5 6 7 8", "1 5 8 4"],
                                   ["1 2 3", "1 3 4 5", "5 6 7 8 1"]])
def test_obj_triangles_are_trimeshs(faces, tmp_path):
    """An OBJ of triangles or of quads is triangulated without trimesh, into the very arrays trimesh
    gives (same vertices, same triangles in the same order); mixed polygons still go to trimesh."""
    import trimesh

    from lbscene.engine.scene.meshes import _mesh_from_obj

    rng = np.random.default_rng(len(faces[0]))
    pts = rng.uniform(-50.0, 50.0, (8, 3))
    p = tmp_path / "m.obj"
    p.write_text("o m\n" + "".join(f"v {x:.4f} {y:.4f} {z:.4f}\n" for x, y, z in pts)
                 + "vt 0 0\n" * 8 + "".join(f"f {f}\n" for f in faces))
    v, f = _mesh_from_obj(p, "m.obj")
    ref = trimesh.load(str(p), file_type="obj", force="mesh", process=False)
    np.testing.assert_array_equal(v[f], np.asarray(ref.vertices)[np.asarray(ref.faces)])
