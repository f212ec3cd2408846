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
from booth_text import write_booth

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


def test_the_low_rank_update_of_a_factored_radiosity_matrix_solves_the_moved_one():
    """(I − diag(r′) F) x = b and its transpose, solved from the factors of I − diag(r) F with r′
    differing on a third of the patches (Woodbury), equal numpy's dense solves."""
    from scipy.linalg import lu_factor

    from lbscene.engine.light.radiosity import _LowRankSolver, _LUSolver

    rng = np.random.default_rng(7)
    n = 90
    F = rng.random((n, n))
    np.fill_diagonal(F, 0.0)
    F *= 0.97 / F.sum(axis=1, keepdims=True)          # rows of a closed room's form factors
    r = np.full(n, 0.85)
    r2 = r.copy()
    moved = rng.choice(n, n // 3, replace=False)
    r2[moved] = rng.uniform(0.05, 0.95, moved.size)
    base = _LUSolver(lu_factor(np.eye(n) - r[:, None] * F), r)
    upd = _LowRankSolver(base, r2, lambda: F)
    assert upd.S.size == moved.size
    A2 = np.eye(n) - r2[:, None] * F
    b = rng.random((n, 3))
    assert np.allclose(upd.solve(b), np.linalg.solve(A2, b), rtol=1e-11, atol=1e-13)
    assert np.allclose(upd.solve(b, trans=1), np.linalg.solve(A2.T, b), rtol=1e-11, atol=1e-13)
    assert np.allclose(upd.solve(b[:, 0]), np.linalg.solve(A2, b[:, 0]), rtol=1e-11, atol=1e-13)
    # the same patch set again reuses the k solves kept with the base
    again = _LowRankSolver(base, np.where(np.isin(np.arange(n), moved), 0.5, r), lambda: F)
    assert np.allclose(again.solve(b, trans=1), np.linalg.solve((np.eye(n) - again.r[:, None] * F).T, b),
                       rtol=1e-11, atol=1e-13)
    assert len(base._updates) == 1


def test_a_low_rank_update_keeps_its_patch_sets_rows_with_the_base():
    """An update of most of the patches (60 %: the SpectraLight's ceiling and its cavity's are 51
    %) solves exactly; a later reflectance set on the same patches needs no form factors (the
    base keeps their rows), its products of the patch set are made once, and so is the base's
    solution for the same right-hand sides."""
    from scipy.linalg import lu_factor

    from lbscene.engine.light.radiosity import LOW_RANK_MAX_FRACTION, _LowRankSolver, _LUSolver

    rng = np.random.default_rng(11)
    n = 120
    F = rng.random((n, n))
    np.fill_diagonal(F, 0.0)
    F *= 0.95 / F.sum(axis=1, keepdims=True)
    r = np.full(n, 0.8)
    base = _LUSolver(lu_factor(np.eye(n) - r[:, None] * F), r)
    moved = rng.choice(n, int(0.6 * n), replace=False)
    assert moved.size > 0.5 * n and moved.size <= LOW_RANK_MAX_FRACTION * n
    b = rng.random((n, 4))
    asked = []

    def form_factors():
        asked.append(1)
        return F

    solved = []
    plain = base.solve

    def counting(rhs, trans=0):
        if rhs.shape == b.shape:
            solved.append(trans)
        return plain(rhs, trans=trans)

    base.solve = counting
    for value in (0.55, 0.9, 0.3):
        r2 = r.copy()
        r2[moved] = value
        upd = _LowRankSolver(base, r2, form_factors)
        A2 = np.eye(n) - r2[:, None] * F
        assert np.allclose(upd.solve(b), np.linalg.solve(A2, b), rtol=1e-11, atol=1e-13)
        assert np.allclose(upd.solve(b, trans=1), np.linalg.solve(A2.T, b), rtol=1e-11, atol=1e-13)
        # the first set's rows are kept with the base: the later ones need no form factors
        assert len(asked) == 1
    kept = base._updates[np.sort(moved).tobytes()]
    assert set(kept) == {"F_S", "P", "Q", "FSP"}
    # the base solved these right-hand sides once each way, for every reflectance set
    assert solved == [0, 1]
    # a patch set the base has not seen asks for them
    r3 = r.copy()
    r3[:7] = 0.1
    _LowRankSolver(base, r3, form_factors)
    assert len(asked) == 2


def test_a_fit_moving_the_ceiling_refactors_no_band_class_after_its_first_step(tmp_path):
    """A box whose ceiling, cut finer above the tubes, holds most of the patches (56 %), 16
    band classes (a reflectance that changes across the spectrum): after the first step of a fit
    moving the ceiling's reflectance, every band class is solved from its factors as a low-rank
    update, no n × n matrix factored again (they were, at every step, while an update was
    limited to half the patches: the SpectraLight's ceiling is 51 % of its), and the light at the
    receivers equals a fresh solve's."""
    import scipy.linalg

    from lbscene.engine.light.forward import ForwardModel

    ir = _box_with_sloped_reflectance(tmp_path)
    [rt] = ForwardModel(ir, "L").global_transports()
    n = len(rt.patches)
    share = np.mean(rt.patches.surface.astype(str) == "ceiling")
    assert 0.5 < share < 0.7, share
    x, y = np.meshgrid(np.linspace(-250, 250, 5), np.linspace(-180, 180, 4))
    P = np.c_[x.ravel(), y.ravel(), np.zeros(x.size)]
    N = np.tile([0.0, 0.0, 1.0], (len(P), 1))
    sizes = []
    real = scipy.linalg.lu_factor

    def counting(a, *args, **kw):
        sizes.append(len(a))
        return real(a, *args, **kw)

    def lux(scale, cache):
        eff = {**{k: dict(v) for k, v in ir.effects.items()}, "surface_reflectance": {"ceiling_scale": scale}}
        pred = ForwardModel(ir, "L", effects=eff, cache=cache).predict(P, N, np.ones(len(P), bool))
        return sum(pred.lux_by_group().values())

    shared: dict = {}
    moved = {}
    scipy.linalg.lu_factor = counting
    try:
        lux(1.0, shared)
        moved[0.9] = lux(0.9, shared)                  # the bases: one factorisation per class
        assert sizes.count(n) >= 16
        for scale in (0.95, 1.05, 0.8):
            sizes.clear()
            moved[scale] = lux(scale, shared)
            assert sizes and n not in sizes, (scale, sizes)
    finally:
        scipy.linalg.lu_factor = real
    for scale, got in moved.items():
        assert np.allclose(got, lux(scale, {}), rtol=1e-10, atol=0), scale


def test_a_fitted_diffuse_fraction_is_solved_on_its_own_plates_factors(tmp_path):
    """A fit moving an opal plate's diffuse fraction changes the plate's reflectance alone, but
    also its layer's transfer between its faces: an update of another plate's factors solved the
    wrong matrix (the light at the floor 1.7 % and 5.6 % off a fresh solve for fractions 0.8 and
    0.6 in the opal cavity); the light with a shared cache equals a fresh solve's."""
    from lbscene.engine.light.forward import ForwardModel

    tube = ("{{id: {id}, type: tube, position_mm: [0, {y}, 630], axis: [1, 0, 0], length_mm: 600, radius_mm: 13, "
            "spd: {{type: constant, value: 1}}, output: {{type: luminance_cd_m2, value_cd_m2: 15000}}}}")
    ir = compile_booth(write_booth(
        tmp_path, name="opal plate under a white cavity",
        interior="{type: box, width_mm: 800, depth_mm: 500, height_mm: 680, open_front: true}",
        materials="{grey: {type: diffuse, reflectance: {type: constant, value: 0.45}}, "
                  "white: {type: diffuse, reflectance: {type: constant, value: 0.8}}}",
        surfaces="{floor: grey, left_wall: grey, right_wall: grey, rear_wall: grey, ceiling: white}",
        lamps=[tube.format(id="a", y=-120), tube.format(id="b", y=120)], lighting="{L: {lamps: [a, b]}}",
        diffuser="{z_mm: 590, size_mm: [800, 500], thickness_mm: 2.5, ior: 1.0, "
                 "transmittance: {type: constant, value: 0.6}, "
                 "scattering: {type: lambertian, diffuse_fraction: 0.92}}",
        effects="{diffuser: {}, interreflection: {}}"))
    x, y = np.meshgrid(np.linspace(-300, 300, 4), np.linspace(-180, 180, 3))
    P = np.c_[x.ravel(), y.ravel(), np.zeros(x.size)]
    N = np.tile([0.0, 0.0, 1.0], (len(P), 1))

    def lux(fraction, cache):
        eff = {"diffuser": {"diffuse_fraction": fraction}, "interreflection": {}}
        pred = ForwardModel(ir, "L", effects=eff, cache=cache).predict(P, N, np.ones(len(P), bool))
        return sum(pred.lux_by_group().values())

    shared: dict = {}
    lux(0.92, shared)
    for fraction in (0.8, 0.6):
        assert np.allclose(lux(fraction, shared), lux(fraction, {}), rtol=1e-10, atol=0), fraction


def _box_with_sloped_reflectance(folder):
    """A 700 × 500 × 600 mm box, open at the front, walls whose reflectance rises across the
    spectrum (one band class per band), two bare tubes under the ceiling."""
    tube = ("{{id: {id}, type: tube, position_mm: [{x}, 0, 560], axis: [0, 1, 0], length_mm: 420, radius_mm: 13, "
            "spd: {{type: cie_illuminant, name: D65}}, output: {{type: luminance_cd_m2, value_cd_m2: 12000}}}}")
    return compile_booth(write_booth(
        folder, name="walls most of the patches",
        interior="{type: box, width_mm: 700, depth_mm: 500, height_mm: 600, open_front: true}",
        materials="{wall: {type: diffuse, reflectance: {type: inline, wavelengths_nm: [380, 780], "
                  "values: [0.6, 0.9]}}}",
        lamps=[tube.format(id="a", x=-140), tube.format(id="b", x=140)], lighting="{L: {lamps: [a, b]}}"))


@pytest.mark.slow
def test_a_surface_reflectance_moved_by_a_fit_is_solved_as_a_low_rank_update():
    """A fit moving the walls' reflectance in a bright booth: the receivers' inter-reflected light
    solved from the factors of an earlier step (a low-rank update) equals a fresh solve of the
    moved booth."""
    from lbscene.engine.light.forward import ForwardModel

    # a 0.85 ceiling: the series converges slowly, the transport factors its matrix
    ir = compile_booth(Path(__file__).resolve().parents[1] / "data" / "validation" / "ceiling-85" / "booth.yaml")
    x, y = np.meshgrid(np.linspace(-300, 300, 8), np.linspace(-200, 200, 5))
    P = np.c_[x.ravel(), y.ravel(), np.zeros(x.size)]
    N = np.tile([0.0, 0.0, 1.0], (len(P), 1))

    def lux(scales, cache):
        eff = {**{k: dict(v) for k, v in ir.effects.items()}, "surface_reflectance": scales}
        pred = ForwardModel(ir, "L", effects=eff, cache=cache).predict(P, N, np.ones(len(P), bool))
        return sum(pred.lux_by_group().values())

    shared: dict = {}
    lux({"ceiling_scale": 1.0}, shared)              # solved once, as declared
    # from then on the receivers' operators are solved (transposed) for each reflectance set
    # (the walls: a small share of the patches, most of them on the ceiling near the tubes)
    for scales in ({"walls_scale": 0.8}, {"walls_scale": 0.9}, {"walls_scale": 1.05}):
        assert np.allclose(lux(scales, shared), lux(scales, {}), rtol=1e-10, atol=0), scales
    kinds = {type(v).__name__ for v in shared["_rad_lu"].values()}
    assert kinds == {"_LUSolver", "_LowRankSolver"}, kinds
