"""The plate's images in the inter-reflection against closed forms.

Under a uniform Lambertian ceiling, a point facing a specular plate receives the ceiling's light
reflected from every direction of its hemisphere, each with the plate's directional
reflectance: its image gather is the hemispherical reflectance
:math:`R_h = 2\\int_0^1 R(μ)\\,μ\\,dμ` (here for a clear glass slab, whose :math:`R(μ)` is
Fresnel's law with the light's repeated bounces between the two faces, written out below), and a
plate covering half of the view returns half of it.
"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest
from scipy.integrate import quad

from lbscene.engine.light.geometry import Capsule, Patches, Rectangle, polygon_form_factor, quad_areas
from lbscene.engine.light.plate_mirror import _face_image, patch_image_factors, receiver_image_factors

N_GLASS = 1.52
H_MM = 100.0           # the ceiling above the plate's top face


def _slab_reflectance(mu: float, n: float = N_GLASS) -> float:
    """Clear non-absorbing slab: per polarisation R_slab = 2r/(1 + r) of one face's r."""
    sin_t = np.sqrt(max(0.0, 1.0 - mu * mu)) / n
    cos_t = np.sqrt(1.0 - sin_t * sin_t)
    rs = ((mu - n * cos_t) / (mu + n * cos_t)) ** 2
    rp = ((n * mu - cos_t) / (n * mu + cos_t)) ** 2
    return 0.5 * (2 * rs / (1 + rs) + 2 * rp / (1 + rp))


def _hemispherical(frac: float = 1.0) -> float:
    return frac * 2.0 * quad(lambda mu: _slab_reflectance(mu) * mu, 0.0, 1.0, limit=200)[0]


def _breaks() -> np.ndarray:
    """Cell edges from the centre out, finer near it: ±(10 … 40 960) mm, each 2^(1/3) times the
    last (the reflectance is read on each cell's centre line)."""
    out = 10.0 * 2.0 ** (np.arange(37) / 3.0)
    return np.r_[-out[::-1], out]


def _ceiling(z_mm: float, b=None) -> Patches:
    b = _breaks() if b is None else b
    polys = []
    for x0, x1 in zip(b[:-1], b[1:]):
        for y0, y1 in zip(b[:-1], b[1:]):
            polys.append([[x0, y0, z_mm], [x1, y0, z_mm], [x1, y1, z_mm], [x0, y1, z_mm]])
    polys = np.array(polys)
    n = len(polys)
    return Patches(polys, np.tile([0.0, 0.0, -1.0], (n, 1)), quad_areas(polys), np.array(["c"] * n, object),
                   np.array(["ceiling"] * n, object))


def _ir(size_mm=(200_000.0, 200_000.0), centre_mm=(0.0, 0.0)):
    # what the image factors read of a booth: the plate's height, thickness, centre and size
    return SimpleNamespace(diffuser=SimpleNamespace(z_mm=-2.0, thickness_mm=4.0, centre_mm=centre_mm,
                                                    size_mm=size_mm))


def _R(cos):
    return np.vectorize(_slab_reflectance)(cos)


def test_image_polygons_mirror_points_and_normals_across_the_plane():
    p = np.array([[[0.0, 0, 10], [1, 0, 10], [1, 1, 12], [0, 1, 12]]])
    face = Rectangle(centre=np.array([5.0, -3.0, 2.0]), normal=np.array([0.0, 0.0, 1.0]),
                     u=np.array([1.0, 0.0, 0.0]), half=(1.0, 1.0))
    ip, n = _face_image(p, np.array([[0.0, 0.6, -0.8]]), face)
    assert ip[0, :, 2].tolist() == [-6.0, -6.0, -8.0, -8.0]
    assert ip[0, :, :2].tolist() == p[0, :, :2].tolist()
    assert n[0].tolist() == [0.0, 0.6, 0.8]


def _parallel_squares(a_mm: float, c_mm: float) -> float:
    """Form factor between two equal, aligned, parallel squares of side ``a_mm`` ``c_mm`` apart
    (the closed form for parallel rectangles, e.g. Incropera's tables)."""
    X = Y = a_mm / c_mm
    return 2.0 / (np.pi * X * Y) * (
        0.5 * np.log((1 + X * X) * (1 + Y * Y) / (1 + X * X + Y * Y))
        + X * np.sqrt(1 + Y * Y) * np.arctan(X / np.sqrt(1 + Y * Y))
        + Y * np.sqrt(1 + X * X) * np.arctan(Y / np.sqrt(1 + X * X)) - X * np.arctan(X) - Y * np.arctan(Y))


def test_a_ceiling_patch_sees_its_own_image_twice_its_height_away():
    ceiling = _ceiling(H_MM, np.arange(-50.0, 51.0, 20.0))           # 5 × 5 patches of 20 mm
    F, cos = patch_image_factors(ceiling, _ir())
    centre = np.argmin(np.linalg.norm(ceiling.centres[:, :2], axis=1))
    assert F[centre, centre] == pytest.approx(_parallel_squares(20.0, 2 * H_MM), rel=0.01)
    assert cos[centre, centre] == pytest.approx(1.0)
    # reciprocity of the image exchange between two patches: A_i F_ij' = A_j F_ji'
    A = ceiling.areas_mm2
    for j in (centre + 1, centre + 6, 0):
        assert A[centre] * F[centre, j] == pytest.approx(A[j] * F[j, centre], rel=0.01)


def test_a_receiver_over_half_a_plate_sees_half_the_reflected_ceiling():
    ceiling = _ceiling(H_MM)
    P = np.array([[0.0, 0.0, H_MM / 2], [0.0, 0.0, -50.0]])
    N = np.array([[0.0, 0.0, -1.0], [0.0, 0.0, -1.0]])

    def gather(polys, normals, rows):
        return polygon_form_factor(P[rows], N[rows], polys, normals)

    G, cos = receiver_image_factors(ceiling, _ir(), P, N, gather)
    assert float((G[0] * _R(cos[0])).sum()) == pytest.approx(_hemispherical(), rel=0.01)
    # the receiver under the plate sees the other face, which the ceiling is not in front of
    assert not G[1].any()
    # the plate covers x > 0 only: half of the hemisphere's images
    G, cos = receiver_image_factors(ceiling, _ir(size_mm=(100_000.0, 200_000.0), centre_mm=(50_000.0, 0.0)),
                                    P[:1], N[:1], gather)
    assert float((G[0] * _R(cos[0])).sum()) == pytest.approx(_hemispherical(0.5), rel=0.02)


def test_a_body_between_the_plate_and_a_patch_hides_its_image():
    ceiling = _ceiling(H_MM, np.r_[-1000.0, np.arange(-50.0, 51.0, 20.0), 1000.0])
    centre = np.argmin(np.linalg.norm(ceiling.centres[:, :2], axis=1))
    c = ceiling.centres[centre]
    F0, _ = patch_image_factors(ceiling, _ir())
    # a capsule halfway down, right under the centre patch: its own image is hidden on the way
    # down; a far patch's image, seen past it, is not
    body = Capsule(np.array([c[0] - 30.0, c[1], H_MM / 2]), np.array([c[0] + 30.0, c[1], H_MM / 2]), 20.0)
    F1, _ = patch_image_factors(ceiling, _ir(), [body])
    assert F1[centre, centre] == 0.0 and F0[centre, centre] > 0
    far = int(np.argmax(np.linalg.norm(ceiling.centres[:, :2] - c[:2], axis=1)))
    assert F0[centre, far] > 0 and F1[centre, far] == pytest.approx(F0[centre, far])


def test_bodies_are_tested_only_where_they_may_block_and_the_images_do_not_change(monkeypatch):
    """A body is tested only against the lines of the pairs that may pass near it (the same
    conservative test that marks a pair for sampling): with five capsules among the patches,
    the images' form factors and the receivers' are exactly those of testing every body."""
    from lbscene.engine.light import plate_mirror

    ceiling = _ceiling(H_MM, np.arange(-90.0, 91.0, 20.0))
    rng = np.random.default_rng(7)
    bodies = []
    for _ in range(5):
        c = np.r_[rng.uniform(-80, 80, 2), rng.uniform(0.2, 0.8) * H_MM]
        d = np.r_[rng.normal(size=2), 0.0]
        d = 40.0 * d / np.linalg.norm(d)
        bodies.append(Capsule(c - d, c + d, float(rng.uniform(3.0, 12.0))))
    P = np.c_[rng.uniform(-80, 80, (12, 2)), np.full(12, 0.3 * H_MM)]
    N = np.tile([0.0, 0.0, -1.0], (12, 1))               # facing the plate

    def gather(polys, normals, rows):
        return polygon_form_factor(P[rows], N[rows], polys, normals)

    F, _ = patch_image_factors(ceiling, _ir(), bodies)
    G, _ = receiver_image_factors(ceiling, _ir(), P, N, gather, bodies)
    every = plate_mirror._uncertain
    monkeypatch.setattr(plate_mirror, "_uncertain", lambda *a: (every(*a)[0], None))
    F_all, _ = patch_image_factors(ceiling, _ir(), bodies)
    G_all, _ = receiver_image_factors(ceiling, _ir(), P, N, gather, bodies)
    assert G.any() and np.array_equal(F, F_all) and np.array_equal(G, G_all)
    # the bodies hide something: the test compares images that the bodies shape
    F0, _ = patch_image_factors(ceiling, _ir())
    assert (F < F0 - 1e-12).any()
