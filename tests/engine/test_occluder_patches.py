"""Occluders in the inter-reflection: their faces as patches, the patches they cut, the faces they cover.

The light these patches carry is checked against Mitsuba 3 in the validation scenes
(``cavity-white``: white side panels and a grey plate, ``mesh-cavity``: a dark plate lying on a
white mesh's face; ``tests/engine/test_model_vs_truth.py``).  Here the geometry they rest on:
areas against the declared sizes, no patch across a plate that stands on its surface, and one
reflecting face where a plate lies on a mesh face.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from lbscene.engine.scene.compile import compile_booth
from lbscene.engine.light.effects.builtin.aperture_occlusion import ApertureOcclusionEffect
from lbscene.engine.light.plates import occluder_rects
from lbscene.engine.light.radiosity import interior_patches, occluder_patches

VALIDATION = Path(__file__).resolve().parents[1] / "data" / "validation"


def _occluders(ir):
    return occluder_rects(ir, ApertureOcclusionEffect.Params())


@pytest.fixture(scope="module")
def white():
    return compile_booth(VALIDATION / "cavity-white")


@pytest.fixture(scope="module")
def mesh():
    return compile_booth(VALIDATION / "mesh-cavity")


def test_both_faces_of_each_occluder_with_its_declared_area_and_material(white):
    p = occluder_patches(_occluders(white), 100.0)
    for oid, size, hole, mat in (("aperture", (900, 600), (640, 300), "plate"),
                                 ("side_left", (340, 70), None, "white"),
                                 ("side_front", (660, 70), None, "white")):
        area = size[0] * size[1] - (hole[0] * hole[1] if hole else 0)
        front = p.surface == f"occluder:{oid}"
        back = p.surface == f"occluder:{oid}:back"
        assert p.areas_mm2[front].sum() == pytest.approx(area)
        assert p.areas_mm2[back].sum() == pytest.approx(area)
        assert set(p.material[front | back]) == {mat}
        o = next(o for o in white.occluders if o.id == oid)
        assert np.allclose(p.normals[front], o.normal) and np.allclose(p.normals[back], -np.asarray(o.normal))
    # no patch in the opening
    c = p.centres[p.surface == "occluder:aperture"]
    assert not np.any((np.abs(c[:, 0]) < 320) & (np.abs(c[:, 1]) < 150))
    # a 70 mm panel is two patches across, whatever the patch size
    side = p.polys[p.surface == "occluder:side_left"]
    assert np.ptp(side[..., 2], axis=1).max() == pytest.approx(70 / 2)


def test_an_occluder_without_a_material_is_no_patch(white):
    occ = [(o.model_copy(update={"material": None}), r) for o, r in _occluders(white)]
    assert len(occluder_patches(occ, 100.0)) == 0


def _straddles(polys, axis, value):
    lo, hi = polys[..., axis].min(axis=1), polys[..., axis].max(axis=1)
    return (lo < value - 1e-6) & (hi > value + 1e-6)


def test_no_patch_lies_across_a_plate_or_panel_standing_on_its_surface(white):
    p = interior_patches(white, 100.0, lamps=white.lamps, occluders=_occluders(white))
    walls = np.isin(p.surface, ["left_wall", "right_wall", "rear_wall"])
    # the plate (z 630) spans the interior: no wall patch is half above it, half below
    assert walls.any() and not _straddles(p.polys[walls], 2, 630.0).any()
    # the side panels stand on the ceiling: no ceiling patch is half inside the cavity
    ceiling = p.surface == "ceiling"
    for axis, v in ((0, -330.0), (0, 330.0), (1, -170.0), (1, 170.0)):
        assert not _straddles(p.polys[ceiling], axis, v).any(), (axis, v)
    # ... nor a patch of the plate under a panel
    plate = np.char.startswith(p.surface.astype(str), "occluder:aperture")
    for axis, v in ((0, -330.0), (0, 330.0), (1, -170.0), (1, 170.0)):
        assert not _straddles(p.polys[plate], axis, v).any(), (axis, v)
    # without the occluders, 100 mm patches do lie across them
    bare = interior_patches(white, 100.0, lamps=white.lamps)
    assert _straddles(bare.polys[np.isin(bare.surface, ["left_wall"])], 2, 630.0).any()


def test_a_plate_on_a_mesh_face_leaves_one_face_each_way(mesh):
    p = interior_patches(mesh, 100.0, lamps=mesh.lamps, occluders=_occluders(mesh))
    c = p.centres
    on_plate = (np.abs(c[:, 2] - 630.0) < 1e-6) & (np.abs(c[:, 0]) <= 330) & (np.abs(c[:, 1]) <= 170)
    is_mesh = ~np.char.startswith(p.surface.astype(str), "occluder:")
    down = p.normals[:, 2] < -0.5
    # seen from below: the dark plate only (the mesh's face under it is covered)
    assert not np.any(on_plate & is_mesh & down)
    assert set(p.material[on_plate & down]) == {"dark"}
    # seen from inside the cavity: the white mesh only (the plate's back is covered)
    assert not np.any(on_plate & ~is_mesh & ~down)
    assert set(p.material[on_plate & ~down]) == {"white"}
    # one face each way, over the whole frame around the opening
    frame = 660 * 340 - 640 * 300
    assert p.areas_mm2[on_plate & down].sum() == pytest.approx(frame)
    assert p.areas_mm2[on_plate & ~down].sum() == pytest.approx(frame)
