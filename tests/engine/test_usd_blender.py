"""Round trip of the USD stage through another tool: Blender's USD importer (``bpy.ops.wm.usd_import``)
reads ``lighting/<name>/scene.usda``, Cycles renders a white Lambertian probe at the sample, and the
illuminance there matches the closed form of a Lambertian rectangle, lbscene's forward model and
lbscene's own Cycles bake (``lbscene bake``).

Blender 5.0's importer converts UsdLux units as the UsdLux documentation says for rectangle lights
(radiance = intensity × color); it does not for sphere and cylinder lights (it ignores their size and
imports a CylinderLight as a point light), so the round trip is tested with a panel lamp.  Walls are
black: the forward model's panel emission is being aligned with the Lambertian rectangle of UsdLux,
and the inter-reflected part is compared once both describe the same emitter.
"""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
from pathlib import Path

import pytest

pytestmark = pytest.mark.bake
HERE = Path(__file__).resolve().parent

BOOTH = """\
version: 1
kind: booth
name: Panel test booth
provenance: {status: synthetic, source: "lbscene test suite"}
interior: {type: box, width_mm: 1000, depth_mm: 600, height_mm: 800}
materials:
  black: {type: diffuse, reflectance: {type: constant, value: 0.0}}
surfaces: {floor: black, left_wall: black, right_wall: black, rear_wall: black, ceiling: black}
lamps:
  - id: panel
    type: panel
    position_mm: [0, 0, 700]
    axis: [1, 0, 0]
    aim: [0, 0, -1]
    length_mm: 200
    width_mm: 100
    spd: {type: cie_illuminant, name: A}
    output: {type: peak_intensity_cd, value_cd: 1000}
lighting:
  A: {lamps: [panel]}
geometries: [{name: 45as45}]
observer: {type: eye_point, position_mm: [0, -900, 500]}
sample_position_mm: [0, 0, 0]
"""


def lambertian_rectangle_lx(peak_cd: float, a_m: float, b_m: float, h_m: float) -> float:
    """Illuminance on the axis of a Lambertian rectangle a × b facing a parallel receiver at distance
    h: E = π·L·F with L = I_peak/(a·b) and F the form factor from the receiver element, four times
    the corner form factor F_c(X, Y) = [X/√(1+X²)·atan(Y/√(1+X²)) + Y/√(1+Y²)·atan(X/√(1+Y²))]/(2π)
    with X = a/2h, Y = b/2h (Howell's catalogue of configuration factors, case B-3)."""
    x, y = a_m / (2 * h_m), b_m / (2 * h_m)
    fc = (x / math.sqrt(1 + x * x) * math.atan(y / math.sqrt(1 + x * x))
          + y / math.sqrt(1 + y * y) * math.atan(x / math.sqrt(1 + y * y))) / (2 * math.pi)
    return math.pi * peak_cd / (a_m * b_m) * 4 * fc


def test_blender_imports_the_stage_and_cycles_sees_the_same_illuminance(tmp_path):
    pytest.importorskip("bpy")
    from lbscene.engine.scene.build import build_booth
    from lbscene.engine.scene.compile import compile_booth
    from lbscene.engine.light.forward import ForwardModel

    (tmp_path / "booth").mkdir()
    (tmp_path / "booth" / "booth.yaml").write_text(BOOTH)
    build_booth(tmp_path / "booth", tmp_path / "build")
    stage = tmp_path / "build" / "lighting" / "A" / "scene.usda"
    env = dict(os.environ, PYTHONPATH="")
    res = subprocess.run([sys.executable, str(HERE / "usd_blender_probe.py"), str(stage), "0", "0", "0", "256"],
                         capture_output=True, text=True, env=env, timeout=300)
    line = next((ln for ln in res.stdout.splitlines() if ln.startswith("PROBE ")), None)
    assert line, res.stdout[-2000:] + res.stderr[-2000:]
    probe = json.loads(line[len("PROBE "):])
    rgb = probe["rgb_radiance"]
    assert rgb[0] > rgb[1] > rgb[2]      # the A lamp is warm (lights keep their colour; materials adapt)
    e_blender = probe["illuminance_lx"]

    e_closed = lambertian_rectangle_lx(1000.0, 0.2, 0.1, 0.7)
    ir = compile_booth(tmp_path / "booth")
    e_lbscene = float(ForwardModel(ir, "A").illuminance_lx([[0.0, 0.0, 0.0]])[0])
    # lbscene's own Cycles bake of the same build (its scene is made from the IR, not from USD)
    bake = subprocess.run([sys.executable, "-m", "lbscene", "bake", str(tmp_path / "build"), "--lighting", "A",
                           "--quality", "preview", "--format", "json"],
                          capture_output=True, text=True, cwd=tmp_path, timeout=600)
    assert bake.returncode == 0, bake.stderr[-2000:]
    e_bake = json.loads(bake.stdout)["bakes"][0]["sample_lx_from_env"]
    assert e_blender == pytest.approx(e_closed, rel=0.05)
    assert e_blender == pytest.approx(e_lbscene, rel=0.05)
    assert e_blender == pytest.approx(e_bake, rel=0.05)
