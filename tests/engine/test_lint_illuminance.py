"""LB310 judges the illuminance at the sample from the forward model with the booth's effects.

The case: a white box (reflectance 0.69, open front) lit by one isotropic 430.71 cd point lamp
700 mm above the sample.  Direct light alone is the inverse-square law, 430.71 / 0.7² = 879 lx;
with inter-reflection the sample gets about 2634 lx (the brute-force Monte Carlo reference
engine, which never calls the forward model, says the same).  The old direct-light estimate
warned such a booth off ASTM D1729's range (1080-3230 lx) and let an ISO 3664 P1 check read 879 lx.
"""

from __future__ import annotations

import re

import pytest

BOX = """version: 1
kind: booth
name: white box
provenance: {{status: synthetic}}
interior: {{type: box, width_mm: 1000, depth_mm: 600, height_mm: 800}}
materials:
  white: {{type: diffuse, reflectance: {{type: constant, value: {rho}}}}}
surfaces: {{floor: white, left_wall: white, right_wall: white, rear_wall: white, ceiling: white}}
lamps:
  - id: bulb
    type: point
    position_mm: [0, 0, 700]
    spd: {{type: cie_illuminant, name: D50}}
    output: {{type: peak_intensity_cd, value_cd: 430.71}}
lighting:
  L: {{lamps: [bulb], standard: {standard}}}
observer: {{type: eye_point, position_mm: [0, -900, 500]}}
effects:
  interreflection: {{patch_size_mm: 100}}
"""

DIRECT_LX = 430.71 / 0.7 ** 2          # 879.0 lx: the inverse-square law


def _booth(tmp_path, standard, rho=0.69):
    d = tmp_path / f"box-{standard}-{rho}"
    d.mkdir()
    (d / "booth.yaml").write_text(BOX.format(rho=rho, standard=standard))
    return d


@pytest.fixture(scope="module")
def reference_full_lx(tmp_path_factory):
    """The sample's illuminance by the Monte Carlo reference engine (independent of the model)."""
    from lbscene.engine.scene.compile import compile_booth
    from lbscene.engine.truth.reference import ReferenceEngine

    d = _booth(tmp_path_factory.mktemp("ref"), "ISO_3664_P1")
    ir = compile_booth(d)
    return float(ReferenceEngine(ir, "L").illuminance_lx([[0.0, 0.0, 0.0]], None, False)[0])


def test_the_case_is_879_lx_direct_and_about_2634_in_full(reference_full_lx):
    assert DIRECT_LX == pytest.approx(879.0, abs=0.1)
    assert reference_full_lx == pytest.approx(2634, rel=0.02)


def test_a_white_booth_in_astm_range_in_full_is_clean(tmp_path, run_cli):
    # ASTM D1729: 1080-3230 lx. 879 lx direct would be out of range; the full 2634 lx is in it.
    d = _booth(tmp_path, "ASTM_D1729")
    code, out, err = run_cli("validate-config", d, "--strict")
    assert code == 0, err
    assert "LB310" not in err + out


def test_iso_p1_warning_gives_the_full_model_figure(tmp_path, run_cli, reference_full_lx):
    # ISO 3664 P1: 2000 lx ± 500 lx. The full light (2634 lx) is above it.
    d = _booth(tmp_path, "ISO_3664_P1")
    code, _, err = run_cli("validate-config", d, "--strict")
    assert code == 1
    m = re.search(r"warning LB310: lighting 'L' gives (\d+) lx at the sample \(forward model with the "
                  r"booth's effects: interreflection\), outside the ISO 3664 P1 range", err)
    assert m, err
    assert float(m.group(1)) == pytest.approx(reference_full_lx, rel=0.02)
    assert "(got" in err and "expected 1500-2500 lx" in err


def test_without_inter_reflection_the_figure_is_the_direct_light(tmp_path, run_cli):
    d = _booth(tmp_path, "ISO_3664_P1", rho=0.0)
    (d / "booth.yaml").write_text((d / "booth.yaml").read_text().replace(
        "effects:\n  interreflection: {patch_size_mm: 100}\n", ""))
    code, _, err = run_cli("validate-config", d, "--strict")
    assert code == 1
    assert f"warning LB310: lighting 'L' gives {DIRECT_LX:.0f} lx at the sample (forward model with the " \
           "booth's effects: none enabled)" in err
