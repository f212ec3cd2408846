"""Mesh visibility: the fast tests used by the radiosity gather against the plain
segment-by-segment test, and closed-form cases."""

from __future__ import annotations

import doctest

import numpy as np
import pytest

from lbscene.engine.light import geometry as fg

CUBE = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0],
                 [0, 0, 1], [1, 0, 1], [1, 1, 1], [0, 1, 1]], float)
CUBE_TRIS = CUBE[np.array([[0, 1, 2], [0, 2, 3], [4, 6, 5], [4, 7, 6], [0, 5, 1], [0, 4, 5],
                           [1, 6, 2], [1, 5, 6], [2, 7, 3], [2, 6, 7], [3, 4, 0], [3, 7, 4]])]


def test_doctests_of_the_geometry_module():
    result = doctest.testmod(fg)
    assert result.attempted >= 10 and result.failed == 0


@pytest.mark.parametrize("seed", range(5))
def test_hidden_from_apex_agrees_with_segments_blocked(seed):
    rng = np.random.default_rng(seed)
    tris = rng.normal(size=(rng.integers(1, 30), 3, 3)) * 2.0
    apex = rng.normal(size=3) * 3.0
    pts = rng.normal(size=(3000, 3)) * 5.0
    fast = fg.hidden_from_apex(apex, pts, tris)
    slow = fg.segments_blocked(np.repeat(apex[None], len(pts), axis=0), pts, tris)
    assert fast.any() and not fast.all()
    np.testing.assert_array_equal(fast, slow)


def test_hidden_from_apex_counts_a_seam_between_two_triangles_as_blocked():
    # rays through the shared diagonal of a square made of two triangles
    square = np.array([[[-1, -1, 5], [1, -1, 5], [1, 1, 5]], [[-1, -1, 5], [1, 1, 5], [-1, 1, 5]]], float)
    t = np.linspace(-0.9, 0.9, 101)
    far = np.c_[2 * t, 2 * t, np.full_like(t, 10.0)]
    assert fg.hidden_from_apex(np.zeros(3), far, square).all()
    # an end on the square's plane, or short of it, is not blocked
    assert not fg.hidden_from_apex(np.zeros(3), [[0.2, 0.1, 5.0], [0.2, 0.1, 4.0]], square).any()


@pytest.mark.parametrize("seed", range(4))
def test_pyramids_clear_of_never_clears_a_blocked_pair(seed):
    rng = np.random.default_rng(100 + seed)
    tris = rng.normal(size=(6, 3, 3)) + rng.normal(size=3) * 2.0
    K = 400
    apex = rng.normal(size=(K, 3)) * 4.0
    centre = rng.normal(size=(K, 1, 3)) * 4.0
    corners = np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], float) * 0.7
    quads = centre + corners[None]
    clear = fg.pyramids_clear_of(apex, quads, tris.reshape(-1, 3))
    assert clear.any() and not clear.all()
    # 64 points of each quad: none of a "clear" pair's segments may be blocked
    pts, _ = fg.quad_r2_points(quads, 64)
    blocked = fg.segments_blocked(np.repeat(apex, 64, axis=0), pts.reshape(-1, 3), tris).reshape(K, 64)
    assert not (blocked.any(axis=1) & clear).any()


def test_pyramids_clear_of_closed_form():
    hull = CUBE + [0.0, 0.0, 4.0]                     # unit cube at z 4…5
    quad = np.array([[-0.5, -0.5, 10], [1.5, -0.5, 10], [1.5, 1.5, 10], [-0.5, 1.5, 10]], float)
    apex = np.array([[0.5, 0.5, 0.0],                 # looks through the cube
                     [30.0, 0.5, 0.0],                # the pyramid passes beside it (side plane)
                     [0.5, 0.5, 11.0]])               # the cube is behind the apex (base/world axes)
    assert fg.pyramids_clear_of(apex, np.repeat(quad[None], 3, axis=0), hull).tolist() == [False, True, True]


def test_coplanar_convex_faces_of_a_cube_are_six_quads():
    faces = fg.coplanar_convex_faces(CUBE_TRIS)
    assert sorted(len(f) for f in faces) == [4] * 6
    area = sum(np.linalg.norm(np.cross(f[2] - f[0], f[1] - f[0]) + np.cross(f[3] - f[0], f[2] - f[0])) / 2
               for f in faces)
    assert area == pytest.approx(6.0)


def test_coplanar_convex_faces_keep_a_frame_around_a_hole_convex():
    # a 3×3 square with the middle cell open: 8 cells, 16 triangles, never one polygon
    tris = []
    for i in range(3):
        for j in range(3):
            if i == j == 1:
                continue
            a, b, c, d = ([i, j, 0], [i + 1, j, 0], [i + 1, j + 1, 0], [i, j + 1, 0])
            tris += [[a, b, c], [a, c, d]]
    faces = fg.coplanar_convex_faces(np.array(tris, float))
    area = 0.0
    for f in faces:
        xy = f[:, :2]
        area += 0.5 * abs(np.dot(xy[:, 0], np.roll(xy[:, 1], -1)) - np.dot(xy[:, 1], np.roll(xy[:, 0], -1)))
        # every face is convex: all turns the same way
        e = np.roll(xy, -1, axis=0) - xy
        turn = e[:, 0] * np.roll(e, -1, axis=0)[:, 1] - e[:, 1] * np.roll(e, -1, axis=0)[:, 0]
        assert (turn > 0).all() or (turn < 0).all()
    assert area == pytest.approx(8.0)
    assert 2 <= len(faces) < 16
    # and the hole still lets a ray through
    hit = [fg.segments_blocked_by_polygon([[1.5, 1.5, -1.0]], [[1.5, 1.5, 1.0]], f)[0] for f in faces]
    assert not any(hit)


@pytest.mark.parametrize("seed", range(3))
def test_segments_blocked_by_polygon_matches_its_triangles(seed):
    rng = np.random.default_rng(7 + seed)
    for f in fg.coplanar_convex_faces(CUBE_TRIS * 3.0):
        tris = np.array([[f[0], f[k], f[k + 1]] for k in range(1, len(f) - 1)])
        a = rng.normal(size=(2000, 3)) * 4.0
        b = rng.normal(size=(2000, 3)) * 4.0
        np.testing.assert_array_equal(fg.segments_blocked_by_polygon(a, b, f),
                                      fg.segments_blocked(a, b, tris))


def test_gather_visibility_of_a_half_hidden_patch():
    """A receiver under a 100 mm patch, a plate hiding exactly the patch's left half (as
    seen from the receiver): the gather's visible fraction is one half, up to the fine
    point set's resolution."""
    from types import SimpleNamespace

    from lbscene.engine.light.radiosity import RadiosityTransport

    quad = np.array([[[-50, -50, 1000], [50, -50, 1000], [50, 50, 1000], [-50, 50, 1000]]], float)
    # plate at z = 500: the left half of the patch projects to x ∈ [−25, 0]
    plate = np.array([[[-40, -40, 500], [0, -40, 500], [0, 40, 500]], [[-40, -40, 500], [0, 40, 500], [-40, 40, 500]]],
                     float)
    rt = object.__new__(RadiosityTransport)
    rt.blockers = plate
    rt.hulls = [plate.reshape(-1, 3)]
    rt.patches = SimpleNamespace(polys=quad, normals=np.array([[0.0, 0.0, -1.0]]))
    store = {}
    rt.ctx = SimpleNamespace(memo=lambda name, key, fn, limit=0: store.setdefault(name, fn()))
    V = rt._gather_visibility(np.array([[0.0, 0.0, 0.0], [300.0, 0.0, 0.0]]), np.ones((2, 1)))
    assert V[0, 0] == pytest.approx(0.5, abs=0.02)
    # the second receiver, 300 mm aside, sees the patch past the plate's edge: whole
    assert V[1, 0] == 1.0
