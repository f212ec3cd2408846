"""A diffuser plate inside a cavity sends its light to the room only through the aperture below it:
the ``aperture_occlusion`` effect's ``source_path_factors`` against the projection of the
opening's edge (a closed form), and through the forward model end to end."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from lbscene.engine.light.effects.builtin.aperture_occlusion import ApertureOcclusionEffect
from lbscene.engine.light.forward import ForwardModel
from lbscene.engine.scene.compile import compile_booth

# a rough plate at z 645 mm in a black cavity closed at z 625 mm by a plate with a 560 × 320 mm
# opening (x within ±280 mm, y within ±160 mm)
SCENE = Path(__file__).resolve().parents[1] / "data" / "validation" / "aperture-diffuser"


def _cell(x0, x1, y0=-25.0, y1=25.0, z=645.0):
    return np.array([[[x0, y0, z], [x1, y0, z], [x1, y1, z], [x0, y1, z]]], float)


@pytest.fixture(scope="module")
def ctx():
    ir = compile_booth(SCENE)
    return ForwardModel(ir, "L").ctx


def _seen(ctx, polys, rx):
    return ApertureOcclusionEffect.source_path_factors(ctx, ctx.params("aperture_occlusion"), polys,
                                                       np.asarray(rx, float))


def test_a_cell_over_the_opening_is_seen_and_one_over_the_plate_is_not(ctx):
    rx = [[0.0, 0.0, 0.0], [125.0, 0.0, 0.0], [425.0, 0.0, 0.0]]
    np.testing.assert_array_equal(_seen(ctx, _cell(100, 150), rx)[:, 0], [1.0, 1.0, 1.0])
    # over the plate (x 400–450 mm): the ray to any floor point below the opening crosses the plate
    np.testing.assert_array_equal(_seen(ctx, _cell(400, 450), rx)[:2, 0], [0.0, 0.0])


@pytest.mark.parametrize("x_rx", [280.0, 0.0, -300.0])
def test_the_openings_edge_cuts_a_cell_where_its_projection_falls(ctx, x_rx):
    # from a floor point at x_rx, the edge x = 280 mm at z 625 mm projects onto the plate's plane
    # (z 645 mm) at x = x_rx + (280 − x_rx)·645/625: the cell's part on the opening's side is seen
    edge = x_rx + (280.0 - x_rx) * 645.0 / 625.0
    cell = _cell(edge - 30.0, edge + 30.0)
    got = float(_seen(ctx, cell, [[x_rx, 0.0, 0.0]])[0, 0])
    assert got == pytest.approx(0.5, abs=1e-12)
    # the same cell moved a third of its width outward: a third of it seen (the cell's 6 × 6
    # points split 2 : 4)
    got = float(_seen(ctx, _cell(edge - 20.0, edge + 40.0), [[x_rx, 0.0, 0.0]])[0, 0])
    assert got == pytest.approx(1.0 / 3.0, abs=1e-12)


def test_an_opal_plates_light_does_not_pass_a_closed_aperture_plate(tmp_path):
    """End to end: a Lambertian (opal) plate in the cavity; with the opening shrunk to almost
    nothing, the floor under it gets almost none of the plate's light (before the plate's light
    was gathered with bare form factors: the aperture plate let all of it through)."""
    text = (SCENE / "booth.yaml").read_text()
    text = text.replace("scattering: {type: roughness, roughness: 0.5477}",
                        "scattering: {type: lambertian, diffuse_fraction: 1.0}")
    text = text.replace("ior: 1.49", "ior: 1.0").replace("interreflection: {}\n", "")
    (tmp_path / "booth.yaml").write_text(text)
    ir = compile_booth(tmp_path)
    P = np.array([[0.0, 0.0, 0.0], [100.0, 50.0, 0.0]])
    open_lx = ForwardModel(ir, "L").illuminance_lx(P)
    shut_lx = ForwardModel(ir, "L", effects={**{k: dict(v) for k, v in ir.effects.items()},
                                             "aperture_occlusion": {"opening_scale": 0.05}}).illuminance_lx(P)
    # the opening 28 × 16 mm: at most the share of the plate seen through it (a few per mille)
    assert np.all(shut_lx < 0.01 * open_lx)
    assert np.all(open_lx > 100.0)
