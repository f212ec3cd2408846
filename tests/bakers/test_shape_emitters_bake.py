"""Cycles bakes a tube and a panel from their emissive meshes: irradiance against closed forms
written here (a dense quadrature of the Lambertian cylinder, the rectangle's exact configuration
factor), so the bake is an independent check of the analytic emitters."""

from __future__ import annotations

import math

import numpy as np
from closed_forms import cylinder_quadrature_lx
import pytest

from lbscene.bakers.crosscheck import bake_points, cross_check
from lbscene.engine.scene.compile import compile_booth

BOOTH = """\
version: 1
kind: booth
name: Shape emitter bake test
provenance: {status: synthetic, source: "lbscene test suite (shape emitters)"}
interior: {type: box, width_mm: 1000, depth_mm: 600, height_mm: 800}
materials:
  grey: {type: diffuse, reflectance: {type: constant, value: 0.5}}
surfaces: {floor: grey, left_wall: grey, right_wall: grey, rear_wall: grey, ceiling: grey}
lamps:
  - id: T
    type: tube
    position_mm: [0, -100, 700]
    axis: [1, 0, 0]
    length_mm: 590
    radius_mm: 13
    spd: {type: constant, value: 1.0}
    output: {type: luminance_cd_m2, value_cd_m2: 10000}
  - id: P
    type: panel
    position_mm: [0, 150, 600]
    length_mm: 300
    width_mm: 150
    spd: {type: constant, value: 1.0}
    output: {type: luminance_cd_m2, value_cd_m2: 10000}
lighting:
  T: {lamps: [T]}
  P: {lamps: [P]}
geometries: [{name: 45as45}]
observer: {type: eye_point, position_mm: [0, -900, 500]}
"""

POINTS = np.array([[0, -100, 0], [250, 50, 0], [0, -100, 640], [-200, 150, 0]], float)


def _tube_lx(p, n=(0, 0, 1.0), lv=10000, c=(0, -100, 700), length=590, r=13):
    return cylinder_quadrature_lx(lv, c, length, r, p, n)


def _rect_lx(p, lv=10000, c=(0, 150, 600), a=300, b=150):
    def corner(x, y, h):
        rx, ry = math.hypot(x, h), math.hypot(y, h)
        return 0.5 * (x / rx * math.atan(y / rx) + y / ry * math.atan(x / ry))

    x0, y0, h = (p[0] - c[0]) * 1e-3, (p[1] - c[1]) * 1e-3, (c[2] - p[2]) * 1e-3
    g = lambda x, y: math.copysign(1, x) * math.copysign(1, y) * corner(abs(x), abs(y), h)  # noqa: E731
    x1, x2, y1, y2 = -a / 2e3 - x0, a / 2e3 - x0, -b / 2e3 - y0, b / 2e3 - y0
    return lv * (g(x2, y2) - g(x1, y2) - g(x2, y1) + g(x1, y1))


@pytest.fixture(scope="module")
def ir(tmp_path_factory):
    d = tmp_path_factory.mktemp("shape-bake")
    (d / "booth.yaml").write_text(BOOTH)
    return compile_booth(d / "booth.yaml")


def test_cycles_tube_and_panel_meshes_match_closed_forms(ir):
    # (the tube's long facets are noisy in Cycles: ~1 % at 512 samples; the panel's ~0.1 %)
    for lighting, truth in (("T", _tube_lx), ("P", _rect_lx)):
        pts = POINTS if lighting == "T" else POINTS[[0, 1, 3]]
        _, lux, noise, _ = bake_points(ir, lighting, pts, surfaces="black", light_paths="direct",
                                       samples=512)
        want = np.array([truth(p) for p in pts])
        assert np.all(np.abs(lux / want - 1) <= 0.01 + 4 * noise), (lighting, lux / want, noise)


@pytest.mark.slow
def test_cycles_cross_check_of_shape_emitters_passes(ir):
    for lighting in ("T", "P"):
        check = cross_check(ir, lighting, mode="direct", points=POINTS[[0, 1, 3]], samples=256)
        assert check.summary()["agrees"], check.summary()
