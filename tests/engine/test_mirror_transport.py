"""The lamps' mirrors in the inter-reflection, against closed forms and an independent renderer.

A plane mirror reflects the surfaces' light as it does the lamps': a surface element sees the
others' images behind it (:func:`lbscene.engine.light.plate_mirror.face_image_factors`, the image
method of :mod:`lbscene.engine.light.plate_mirror` on any plane), and the mirror's back hides what
lies behind it.  Checked here:

* a patch facing a tilted mirror sees its own image twice their distance away: the closed form
  of two parallel squares;
* a point facing a finite mirror, standing on a uniform Lambertian surface, sees that surface's
  image through the mirror's window only: the closed form of a point and a parallel rectangle;
* the model with the mirrors declared against Mitsuba 3 in the bright rooms of the hypothesis
  scenes (vertical mirrors behind two tubes near the side walls; a strip above each of two
  tubes), whose truth the diagnosis tests also read.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from scipy.optimize import brentq

from lbscene.engine.light.geometry import Capsule, Patches, Rectangle, polygon_form_factor, quad_areas
from lbscene.engine.light.plate_mirror import face_image_factors, face_receiver_factors

HYPOTHESES = Path(__file__).resolve().parents[1] / "data" / "hypotheses"


def _rotation(seed: int = 3) -> np.ndarray:
    """A fixed proper rotation (QR of a seeded Gaussian matrix)."""
    q, r = np.linalg.qr(np.random.default_rng(seed).normal(size=(3, 3)))
    q = q * np.sign(np.diag(r))
    return q if np.linalg.det(q) > 0 else -q


def _plane_patches(breaks: np.ndarray, z_mm: float, normal_z: float, rot: np.ndarray) -> Patches:
    polys = []
    for x0, x1 in zip(breaks[:-1], breaks[1:]):
        for y0, y1 in zip(breaks[:-1], breaks[1:]):
            q = [[x0, y0, z_mm], [x1, y0, z_mm], [x1, y1, z_mm], [x0, y1, z_mm]]
            polys.append(q if normal_z > 0 else q[::-1])
    polys = np.array(polys) @ rot.T
    n = len(polys)
    normals = np.tile(rot @ np.array([0.0, 0.0, normal_z]), (n, 1))
    return Patches(polys, normals, quad_areas(polys), np.array(["w"] * n, object), np.array(["wall"] * n, object))


def _mirror(rot: np.ndarray, z_mm: float, half: tuple[float, float]) -> Rectangle:
    """A mirror in the plane ``z = z_mm`` of the rotated frame, reflecting toward −z."""
    return Rectangle(rot @ np.array([0.0, 0.0, z_mm]), rot @ np.array([0.0, 0.0, -1.0]), rot @ np.array([1.0, 0.0, 0.0]),
                     half)


def _parallel_squares(a_mm: float, c_mm: float) -> float:
    """Form factor between two equal, aligned, parallel squares of side ``a_mm`` ``c_mm`` apart."""
    X = Y = a_mm / c_mm
    return 2.0 / (np.pi * X * Y) * (
        0.5 * np.log((1 + X * X) * (1 + Y * Y) / (1 + X * X + Y * Y))
        + X * np.sqrt(1 + Y * Y) * np.arctan(X / np.sqrt(1 + Y * Y))
        + Y * np.sqrt(1 + X * X) * np.arctan(Y / np.sqrt(1 + X * X)) - X * np.arctan(X) - Y * np.arctan(Y))


def _point_to_centred_rectangle(a_mm: float, b_mm: float, c_mm: float) -> float:
    """Form factor from a point to a parallel rectangle of half sizes ``a_mm``, ``b_mm`` centred
    on its normal ``c_mm`` away: four times the corner case
    :math:`\\frac{1}{2π}\\bigl(\\frac{X}{\\sqrt{1+X^2}}\\arctan\\frac{Y}{\\sqrt{1+X^2}} +
    \\frac{Y}{\\sqrt{1+Y^2}}\\arctan\\frac{X}{\\sqrt{1+Y^2}}\\bigr)`, :math:`X = a/c, Y = b/c`."""
    X, Y = a_mm / c_mm, b_mm / c_mm
    return 4.0 / (2 * np.pi) * (X / np.sqrt(1 + X * X) * np.arctan(Y / np.sqrt(1 + X * X))
                                + Y / np.sqrt(1 + Y * Y) * np.arctan(X / np.sqrt(1 + Y * Y)))


def test_a_patch_sees_its_own_image_in_a_tilted_mirror():
    rot = _rotation()
    H = 100.0
    wall = _plane_patches(np.arange(-50.0, 51.0, 20.0), 0.0, 1.0, rot)     # facing the mirror
    F, cos = face_image_factors(wall, [_mirror(rot, H, (1e5, 1e5))])
    centre = int(np.argmin(np.linalg.norm(wall.centres, axis=1)))
    assert F[centre, centre] == pytest.approx(_parallel_squares(20.0, 2 * H), rel=0.01)
    assert cos[centre, centre] == pytest.approx(1.0)
    A = wall.areas_mm2
    for j in (centre + 1, centre + 6, 0):
        assert A[centre] * F[centre, j] == pytest.approx(A[j] * F[j, centre], rel=0.01)
    # patches behind the mirror's plane see nothing in it
    behind = _plane_patches(np.arange(-50.0, 51.0, 20.0), 2 * H, -1.0, rot)
    assert not face_image_factors(behind, [_mirror(rot, H, (1e5, 1e5))])[0].any()


@pytest.mark.parametrize("half", [(60.0, 40.0), (150.0, 25.0)])
def test_a_point_sees_its_surface_through_the_mirror_window_only(half):
    rot = _rotation(5)
    d = 80.0
    # the receiver stands on a uniform Lambertian plane facing a finite mirror d away; through the
    # mirror it sees the plane's image, uniform, so what it gathers is the window's form factor
    b = np.r_[-40000.0, -np.geomspace(2000, 5, 24), 0.0, np.geomspace(5, 2000, 24), 40000.0]
    surface = _plane_patches(b, -1.0, 1.0, rot)
    P = (rot @ np.array([0.0, 0.0, 0.0]))[None, :]
    N = (rot @ np.array([0.0, 0.0, 1.0]))[None, :]

    def gather(polys, normals, rows):
        return polygon_form_factor(P[rows], N[rows], polys, normals)

    G, _ = face_receiver_factors(surface, [_mirror(rot, d, half)], P, N, gather)
    assert float(G.sum()) == pytest.approx(_point_to_centred_rectangle(*half, d), rel=0.02)
    # a rod of radius r halfway to the mirror, along its u axis, hides the window's strip
    # |v| < v_e on the way there (the line to the mirror point at v passes the rod's axis at
    # (v/2)·cos θ, cos θ = d/√(v² + d²)); the way back passes it at 1.5 v, inside that strip
    r = 10.0
    v_e = float(brentq(lambda v: 0.5 * v * d / np.hypot(v, d) - r, 1.0, 200.0))
    body = Capsule(rot @ np.array([-1000.0, 0.0, d / 2]), rot @ np.array([1000.0, 0.0, d / 2]), r)
    G1, _ = face_receiver_factors(surface, [_mirror(rot, d, half)], P, N, gather, [body])
    expected = _point_to_centred_rectangle(*half, d) - _point_to_centred_rectangle(half[0], min(v_e, half[1]), d)
    assert float(G1.sum()) == pytest.approx(expected, rel=0.03)


@pytest.mark.parametrize("scene", ["mirror-sides", "mirror-above"])
@pytest.mark.parametrize("grid", ["a3", "floor"])
def test_mirrors_in_a_bright_room_meet_the_truth(scene, grid):
    """Declared mirrors in a grey room against Mitsuba 3 (the hypothesis scenes' truth, the
    noise removed in quadrature): the mirrors' images of the walls and ceiling and their backs'
    shadows.  Before, with the mirrors acting on the lamps' light only: mirror-sides 1.7 % (A3)
    and 1.6 % (floor) RMS, mirror-above 0.9 %."""
    from lbscene.engine.scene.compile import compile_booth
    from lbscene.engine.truth.validation import compare_with_truth

    folder = HYPOTHESES / scene
    c = compare_with_truth(folder, grid, ir=compile_booth(folder))
    assert c.rms_percent < 0.8, c.rms_percent
