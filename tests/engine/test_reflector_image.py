"""The reflector effect's mirror image against a quadrature of the Lambertian cylinder and its
image, seen through the mirror and past the lamp's own body (written here, not the model's code):
below a tube under its mirror the lamp hides its image, beside it the image shows."""

from __future__ import annotations

import numpy as np
import pytest
from closed_forms import cylinder_quadrature_lx, mirror_image_visible

from lbscene.engine.scene.compile import compile_booth
from lbscene.engine.light.forward import ForwardModel

H, LV, L, R = 700.0, 10000.0, 590.0, 13.0
RM, DM, WM = 0.9, 35.0, 130.0

BOOTH = f"""\
version: 1
kind: booth
name: Mirror image test
provenance: {{status: synthetic, source: "lbscene test suite (reflector image)"}}
interior: {{type: box, width_mm: 4000, depth_mm: 4000, height_mm: 900}}
materials:
  grey: {{type: diffuse, reflectance: {{type: constant, value: 0.5}}}}
surfaces: {{floor: grey, left_wall: grey, right_wall: grey, rear_wall: grey, ceiling: grey}}
reflectors:
  mirror: {{type: plane, reflectance: {{type: constant, value: {RM}}}, distance_mm: {DM}, normal: [0, 0, -1],
           width_mm: {WM}}}
lamps:
  - {{id: M, type: tube, position_mm: [0, 0, {H}], axis: [1, 0, 0], length_mm: {L}, radius_mm: {R},
     reflector: mirror, spd: {{type: constant, value: 1.0}}, output: {{type: luminance_cd_m2, value_cd_m2: {LV}}}}}
lighting:
  M: {{lamps: [M]}}
geometries: [{{name: 45as45}}]
observer: {{type: eye_point, position_mm: [0, -900, 500]}}
effects:
  reflector: {{}}
"""


_visible = mirror_image_visible(H + DM, L / 2, WM / 2, H, R)


#: (point, allowed relative error): the last one sees the image cut by the mirror's edge, which
#: the model's six lines around the tube resolve to about 3 % of the image's light
CASES = [((0, 0, 0), 0.005), ((0, 150, 0), 0.01), ((200, -250, 0), 0.01), ((-100, 450, 0), 0.01),
         ((0, 700, 300), 0.02)]


@pytest.fixture(scope="module")
def model(tmp_path_factory):
    d = tmp_path_factory.mktemp("mirror")
    (d / "booth.yaml").write_text(BOOTH)
    ir = compile_booth(d / "booth.yaml")
    return ir, ForwardModel(ir, "M")


def test_the_lamp_hides_its_own_image_below_it(model):
    ir, fm = model
    P = np.array([c[0] for c in CASES], float)
    lux = np.asarray(fm.illuminance_lx(P, np.tile([0.0, 0, 1], (len(P), 1))), float)
    for (p, tol), got in zip(CASES, lux):
        direct = cylinder_quadrature_lx(LV, (0, 0, H), L, R, p, (0, 0, 1), n_along=600, n_around=720)
        image = RM * cylinder_quadrature_lx(LV, (0, 0, H + 2 * DM), L, R, p, (0, 0, 1), n_along=600,
                                            n_around=720, visible=_visible)
        assert got == pytest.approx(direct + image, rel=tol), (p, got, direct, image)
    # below the tube the image is hidden: the reading is the bare tube's
    nadir = cylinder_quadrature_lx(LV, (0, 0, H), L, R, (0, 0, 0), (0, 0, 1), n_along=600, n_around=720)
    assert lux[0] == pytest.approx(nadir, rel=0.005)


def test_the_reference_engine_hides_the_image_behind_the_lamp_too(model):
    # the Monte Carlo reference engine (truth for effects Mitsuba 3 does not render) samples the
    # image's surface and tests each path against the lamp's cylinder with its own ray code
    from lbscene.engine.truth.reference import ReferenceEngine

    ir, _ = model
    ref = ReferenceEngine(ir, "M", {"reflector": {}}, samples_per_lamp=64000, seed=2)
    P = np.array([c[0] for c in CASES], float)
    lux = np.asarray(ref.illuminance_lx(P, np.tile([0.0, 0, 1], (len(P), 1))), float)
    for p, got in zip(P, lux):
        direct = cylinder_quadrature_lx(LV, (0, 0, H), L, R, p, (0, 0, 1), n_along=600, n_around=720)
        image = RM * cylinder_quadrature_lx(LV, (0, 0, H + 2 * DM), L, R, p, (0, 0, 1), n_along=600,
                                            n_around=720, visible=_visible)
        assert got == pytest.approx(direct + image, rel=0.01), (p, got, direct, image)


#: two bulbs side by side, each under its own plane mirror: the two mirrors tile one plane
TWO_MIRRORS = """\
version: 1
kind: booth
name: Two mirrors test
provenance: {status: synthetic, source: "lbscene test suite (reflector image)"}
interior: {type: box, width_mm: 3000, depth_mm: 3000, height_mm: 3000}
materials:
  black: {type: diffuse, reflectance: {type: constant, value: 0.0}}
surfaces: {floor: black, left_wall: black, right_wall: black, rear_wall: black, ceiling: black}
reflectors:
  mirror: {type: plane, reflectance: {type: constant, value: 0.9}, distance_mm: 500, normal: [0, 0, -1],
           width_mm: 300}
lamps:
  - {id: A, type: bulb, position_mm: [-150, 0, 1000], radius_mm: 30, reflector: mirror,
     spd: {type: constant, value: 1.0}, output: {type: peak_intensity_cd, value_cd: 1000}}
  - {id: B, type: bulb, position_mm: [150, 0, 1000], radius_mm: 30, reflector: mirror,
     spd: {type: constant, value: 1.0}, output: {type: peak_intensity_cd, value_cd: 1000}}
lighting:
  AB: {lamps: [A, B]}
observer: {type: eye_point, position_mm: [0, -1400, 1500]}
effects:
  reflector: {}
"""


def test_a_mirror_reflects_the_other_lamps_light_too(tmp_path):
    """Closed form (inverse-square laws): each bulb and its image 1000 mm above it, the image
    counted where the line from it to the receiver crosses either mirror (the plane z = 1500 mm,
    |x| ≤ 300, |y| ≤ 150).  Far to the right, bulb A's image is seen through bulb B's mirror:
    a model that mirrors each lamp in its own mirror only misses that light."""
    (tmp_path / "booth.yaml").write_text(TWO_MIRRORS)
    ir = compile_booth(tmp_path / "booth.yaml")
    P = np.array([[0, 0, 0], [800, 0, 0], [-1000, 100, 0]], float)
    N = np.tile([0, 0, 1.0], (len(P), 1))

    def law(src):
        d = np.asarray(src, float) - P
        r = np.linalg.norm(d, axis=1)
        return 1000.0 * d[:, 2] / r / (r * 1e-3) ** 2

    def through_mirrors(src):
        t = (1500.0 - src[2]) / (P[:, 2] - src[2])
        x = src[0] + t * (P[:, 0] - src[0])
        y = src[1] + t * (P[:, 1] - src[1])
        return (np.abs(x) <= 300) & (np.abs(y) <= 150)

    expected = np.zeros(len(P))
    for x0 in (-150.0, 150.0):
        img = (x0, 0.0, 2000.0)
        expected += law((x0, 0.0, 1000.0)) + 0.9 * law(img) * through_mirrors(img)
    # the middle receiver sees A's image through B's mirror
    t = 500.0 / 2000.0
    assert 0 < -150 + t * (800 + 150) <= 300
    E = ForwardModel(ir, "AB").illuminance_lx(P, N, meter=False)
    np.testing.assert_allclose(E, expected, rtol=2e-3)


def test_an_occluder_between_the_lamp_and_its_mirror_hides_the_image(tmp_path):
    # a panel standing 20 mm beside the tube's axis, from 10 mm under the tube to 1 mm under the
    # mirror: the light going up to the mirror's far half crosses it (below z 734 everywhere on
    # the tube) and the receiver far out on that side, 1 m off, gets none of the image, though
    # the way down from the mirror to it is clear; the receiver on the other side keeps it
    panel = ("occluders:\n  - {id: shade, type: panel, centre_mm: [0, 20, 712], normal: [0, 1, 0], "
             "u_axis: [1, 0, 0], size_mm: [700, 44]}\n")

    def model(folder, mirror: bool, shade: bool):
        folder.mkdir()
        y = BOOTH if mirror else BOOTH.replace(" reflector: mirror,", "").replace("  reflector: {}\n", "")
        if shade:
            y = y.replace("lighting:\n", panel + "lighting:\n") + "  aperture_occlusion: {}\n"
        (folder / "booth.yaml").write_text(y)
        return ForwardModel(compile_booth(folder / "booth.yaml"), "M")

    P = np.array([[0.0, 1000.0, 0.0], [0.0, -1000.0, 0.0]])
    N = np.array([[0.0, 0.0, 1.0]] * 2)
    both = model(tmp_path / "mirror", True, False).illuminance_lx(P, N, meter=False)
    bare = model(tmp_path / "bare", False, False).illuminance_lx(P, N, meter=False)
    shaded = model(tmp_path / "shaded", True, True).illuminance_lx(P, N, meter=False)
    shaded_bare = model(tmp_path / "shaded-bare", False, True).illuminance_lx(P, N, meter=False)
    assert both[1] - bare[1] > 0.05 * bare[1]                    # the image's light on the far side
    assert shaded[0] == pytest.approx(shaded_bare[0], rel=1e-3)
    assert shaded[1] == pytest.approx(both[1], rel=1e-3)
