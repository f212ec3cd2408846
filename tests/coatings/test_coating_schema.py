"""The sample file's effect_coating section: units, ranges and located, pinned errors."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
EXAMPLES = REPO / "examples" / "render"
COATINGS = sorted(EXAMPLES.glob("sample-coating-*.yaml"))

GEOMS = "".join(f"  - {{geometry: 45as{a}, reflectance: {{type: constant, value: {v}}}}}\n"
                for a, v in (("-15", 1.2), ("15", 0.9), ("25", 0.6), ("45", 0.3), ("75", 0.1), ("110", 0.08)))

GOOD = ("version: 1\n"
        "kind: sample\n"
        "name: S\n"
        "provenance: {status: synthetic}\n"
        "by_geometry:\n" + GEOMS +
        "effect_coating:\n"
        "  clear_coat: {refractive_index: 1.5}\n"
        "  texture:\n"
        "    type: measured\n"
        "    sparkle:\n"
        "      - {illumination_deg: 15, area: 6.0, intensity: 16.0}\n"
        "      - {illumination_deg: 45, area: 1.0, intensity: 22.0}\n"
        "    graininess: 10.0\n")


def _validate(tmp_path, text):
    from lbscene.engine.conformance.validate import validate_paths

    f = tmp_path / "s.yaml"
    f.write_text(text)
    rep = validate_paths([f])
    return [d.format().replace(str(tmp_path) + "/", "") for d in rep.diagnostics]


def test_good_coating_validates(tmp_path):
    assert _validate(tmp_path, GOOD) == []


def test_shipped_coating_samples_validate():
    from lbscene.engine.conformance.validate import validate_paths

    assert len(COATINGS) == 3
    rep = validate_paths(COATINGS)
    assert rep.errors == 0 and rep.warnings == 0, [d.format() for d in rep.diagnostics]


CASES = {
    "angle_not_measured": (
        GOOD.replace("illumination_deg: 45,", "illumination_deg: 30,"),
        "s.yaml:18:9: error LB104: effect_coating.texture.sparkle.1: sparkle is read at illumination 15, "
        "45 or 75 degrees, not 30 (got {'illumination_deg': 30, 'area': 1.0, 'intensity': 22.0})"),
    "angle_twice": (
        GOOD.replace("illumination_deg: 45,", "illumination_deg: 15,"),
        "s.yaml:15:5: error LB104: effect_coating.texture: sparkle given twice at illumination 15 deg "
        "(got {'type': 'measured', 'sparkle': [{'illumination_deg': 15, 'area': 6.0, 'intensi…)"),
    "negative_area": (
        GOOD.replace("area: 6.0", "area: -1"),
        "s.yaml:17:38: error LB103: effect_coating.texture.sparkle.0.area: Input should be greater than "
        "or equal to 0 (got -1; expected a value greater than or equal to 0)"),
    "ior_out_of_range": (
        GOOD.replace("refractive_index: 1.5", "refractive_index: 2.5"),
        "s.yaml:13:34: error LB103: effect_coating.clear_coat.refractive_index: Input should be less than "
        "or equal to 1.8 (got 2.5; expected a value less than or equal to 1.8)"),
    "too_few_geometries": (
        GOOD.replace("  - {geometry: 45as75, reflectance: {type: constant, value: 0.1}}\n", "")
            .replace("  - {geometry: 45as110, reflectance: {type: constant, value: 0.08}}\n", "")
            .replace("  - {geometry: 45as45, reflectance: {type: constant, value: 0.3}}\n", ""),
        "s.yaml:10:3: error LB104: effect_coating: an effect coating with 2 lobe(s) needs reflectances at "
        "4 or more geometries in `by_geometry` (has 3) (got {'clear_coat': {'refractive_index': 1.5}, "
        "'texture': {'type': 'measured', 'spar…)"),
    "flake_spread_too_wide": (
        GOOD.replace("    type: measured\n    sparkle:\n      - {illumination_deg: 15, area: 6.0, intensity: "
                     "16.0}\n      - {illumination_deg: 45, area: 1.0, intensity: 22.0}\n    graininess: 10.0\n",
                     "    type: flakes\n    density_per_mm2: 1000\n    diameter: {median_um: 20}\n"
                     "    orientation_spread_deg: 60\n"),
        "s.yaml:18:29: error LB103: effect_coating.texture.orientation_spread_deg: Input should be less "
        "than or equal to 45 (got 60; expected a value less than or equal to 45)"),
    "unknown_texture_type": (
        GOOD.replace("type: measured", "type: photo"),
        "s.yaml:15:5: error LB105: effect_coating.texture: Input tag 'photo' found using 'type' does not "
        "match any of the expected tags: 'measured', 'flakes' (got {'type': 'photo', 'sparkle': "
        "[{'illumination_deg': 15, 'area': 6.0, 'intensity'…; expected 'type' to be one of 'measured', "
        "'flakes')"),
}


@pytest.mark.parametrize("case", sorted(CASES))
def test_pinned_errors(tmp_path, case):
    text, expected = CASES[case]
    got = _validate(tmp_path, text)
    assert got[:1] == [expected], got


def test_json_schema_describes_the_coating():
    schema = json.loads((REPO / "schemas" / "json" / "sample.schema.json").read_text())
    assert "effect_coating" in schema["properties"]
    defs = schema["$defs"]
    assert set(defs["SparkleReading"]["properties"]) == {"illumination_deg", "area", "intensity"}
    assert defs["FlakeTexture"]["properties"]["orientation_spread_deg"]["maximum"] == 45
    assert defs["FlakeTexture"]["additionalProperties"] is False
