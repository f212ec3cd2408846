"""Golden error messages: every broken input gives a located message and exit code 2.

The expected lines are pinned on purpose: users grep for codes, editors jump to
file:line:col, and a changed message must be a conscious change.
"""

import pytest

def _write(tmp_path, text, name="booth.yaml", binary=False):
    d = tmp_path / "b"
    d.mkdir(exist_ok=True)
    f = d / name
    if binary:
        f.write_bytes(text)
    else:
        f.write_text(text)
    return f


GOOD = (
    "version: 1\n"
    "kind: booth\n"
    "name: T\n"
    "provenance: {status: synthetic}\n"
    "interior: {type: box, width_mm: 1000, depth_mm: 600, height_mm: 800}\n"
    "materials:\n"
    "  grey: {type: diffuse, reflectance: {type: constant, value: 0.5}}\n"
    "surfaces: {floor: grey, left_wall: grey, right_wall: grey, rear_wall: grey, ceiling: grey}\n"
    "lamps:\n"
    "  - id: bulb\n"
    "    type: point\n"
    "    position_mm: [0, 0, 700]\n"
    "    spd: {type: cie_illuminant, name: A}\n"
    "    output: {type: peak_intensity_cd, value_cd: 1000}\n"
    "lighting:\n"
    "  A: {lamps: [bulb]}\n"
    "observer: {type: eye_point, position_mm: [0, -900, 500]}\n"
)

CASES = {
    "syntax_error": (GOOD.replace("lamps: [bulb]}", "lamps: [bulb}"),
                     "b/booth.yaml:16:19: error LB001: YAML syntax error"),
    "unknown_key": (GOOD.replace("    type: point\n", "    type: point\n    colour: red\n"),
                    "b/booth.yaml:12:5: error LB100: unknown key 'colour' in lamps.0 "
                    "(expected only the keys the schema defines (see the JSON Schema))"),
    "wrong_type": (GOOD.replace("value_cd: 1000", "value_cd: bright"),
                   "b/booth.yaml:14:49: error LB101: lamps.0.output.value_cd: Input should be a valid "
                   "number, unable to parse string as a number (got 'bright'; expected a valid number, "
                   "unable to parse string as a number)"),
    "missing_key": (GOOD.replace("name: T\n", ""),
                    "b/booth.yaml:1:1: error LB102: missing required key 'name'"),
    "bad_polymorphic_type": (GOOD.replace("type: point", "type: laser"),
                             "b/booth.yaml:11:11: error LB104: lamps.0.type: Input should be 'tube', "
                             "'bulb', 'panel' or 'point' (got 'laser'; expected one of 'tube', 'bulb', "
                             "'panel' or 'point')"),
    "unknown_spectrum_type": (GOOD.replace("type: cie_illuminant, name: A", "type: led, name: A"),
                              "b/booth.yaml:13:10: error LB105: lamps.0.spd: Input tag 'led' found using "
                              "'type' does not match any of the expected tags"),
    "missing_file": (GOOD.replace("{type: constant, value: 0.5}", "{type: csv, path: spectra/none.csv}"),
                     "b/booth.yaml:7:56: error LB200: materials.grey.reflectance.path: referenced "
                     "file spectra/none.csv does not exist"),
    "path_escape": (GOOD.replace("{type: constant, value: 0.5}", "{type: csv, path: ../../etc/passwd}"),
                    "b/booth.yaml:7:56: error LB201: materials.grey.reflectance.path: path "
                    "../../etc/passwd escapes the document's folder"),
    "alias_bomb": ("version: 1\n"
                   "a: &a [x, x, x, x, x, x, x, x, x, x]\n"
                   "b: &b [*a, *a, *a, *a, *a, *a, *a, *a, *a, *a]\n"
                   "c: &c [*b, *b, *b, *b, *b, *b, *b, *b, *b, *b]\n"
                   "d: &d [*c, *c, *c, *c, *c, *c, *c, *c, *c, *c]\n"
                   "e: &e [*d, *d, *d, *d, *d, *d, *d, *d, *d, *d]\n"
                   "f: &f [*e, *e, *e, *e, *e, *e, *e, *e, *e, *e]\n",
                   "b/booth.yaml:7:4: error LB005: aliases expand to too many values (alias bomb?)"),
    "empty_file": ("", "b/booth.yaml:1:1: error LB002: document is empty"),
    "binary_garbage": (b"\x89PNG\r\n\x1a\n\x00\x00\x00\rIHDR\xff\xfe", "b/booth.yaml: error LB003: file "
                       "contains NUL bytes: binary data, not text (expected a UTF-8 text file)"),
    "python_tag": (GOOD.replace("name: T", "name: !!python/object/apply:os.system [ls]"),
                   "b/booth.yaml:3:7: error LB006: YAML tag not allowed"),
    "duplicate_key": (GOOD + "name: again\n", "b/booth.yaml:18:1: error LB007: duplicate key 'name'"),
    "undefined_lamp": (GOOD.replace("lamps: [bulb]}", "lamps: [bulb, spot]}"),
                       "b/booth.yaml:16:21: error LB202: lighting 'A' switches on undefined lamp 'spot' "
                       "(got 'spot'; expected one of ['bulb'])"),
    "lamp_outside": (GOOD.replace("position_mm: [0, 0, 700]", "position_mm: [0, 0, 900]"),
                     "b/booth.yaml:12:18: error LB300: lamp 'bulb' extends outside the booth interior"),
    "reflectance_above_one": (GOOD.replace("value: 0.5}", "value: 1.5}"),
                              "b/booth.yaml:7:38: error LB302: reflectance of material 'grey' outside "
                              "[0, 1] (got 1.5..1.5; expected values between 0 and 1)"),
    "unknown_effect": (GOOD + "effects:\n  ghost_light: {}\n",
                       "b/booth.yaml:19:3: error LB106: unknown effect id 'ghost_light'"),
    "bad_effect_param": (GOOD + "effects:\n  interreflection: {patch_size_mm: -5}\n",
                         "b/booth.yaml:19:36: error LB103: effects.interreflection.patch_size_mm: Input "
                         "should be greater than 1 (got -5; expected a value greater than 1)"),
    "bad_geometry_name": (GOOD + "geometries: [{name: 45as140}]\n",
                          "b/booth.yaml:18:21: error LB303: geometries.0.name: 45as140: aspecular angle "
                          "140° puts the observer 95° from the normal, below the sample plane"),
    "platform_turned_out": (GOOD + "platform: {size_mm: [400, 300], rotation_axis: [1, 0, 0]}\n"
                                   "geometries: [{name: 45as45, platform_rotation_deg: 45}]\n",
                            "b/booth.yaml:19:52: error LB308: geometry '45as45' turns the platform out of "
                            "the booth (got corner at [-200.0, -106.1, -106.1] mm; expected a platform "
                            "inside the interior at every geometry (raise it, or turn it about an edge "
                            "with platform.pivot_mm))"),
    "unsupported_version": (GOOD.replace("version: 1", "version: 7"),
                            "b/booth.yaml:1:10: error LB104: version: unsupported version 7; this lbscene "
                            "reads versions 1..1"),
}


@pytest.mark.parametrize("case", sorted(CASES))
def test_broken_input_gives_located_message_and_exit_2(case, tmp_path, run_cli):
    text, expected = CASES[case]
    _write(tmp_path, text, binary=isinstance(text, bytes))
    code, out, err = run_cli("validate-config", "b/booth.yaml", cwd=tmp_path)
    assert code == 2, err
    first = [ln for ln in err.splitlines() if " error LB" in ln]
    assert first, err
    assert any(ln.startswith(expected) for ln in first), "\n".join(first)
    assert "Traceback" not in err + out


def test_all_problems_reported_at_once(tmp_path, run_cli):
    text = GOOD.replace("value_cd: 1000", "value_cd: -1").replace("    type: point\n",
                                                                  "    type: point\n    colour: red\n")
    _write(tmp_path, text)
    code, _, err = run_cli("validate-config", "b/booth.yaml", cwd=tmp_path)
    assert code == 2
    codes = sorted(ln.split(" error ")[1][:5] for ln in err.splitlines() if " error LB" in ln)
    assert codes == ["LB100", "LB103"]


def test_build_of_broken_booth_exits_2_without_output(tmp_path, run_cli):
    _write(tmp_path, GOOD.replace("value: 0.5}", "value: 1.5}"))
    code, _, err = run_cli("build", "b", "--out", "out", cwd=tmp_path)
    assert code == 2 and "LB302" in err
    assert not (tmp_path / "out").exists()


def test_json_format(tmp_path, run_cli):
    import json

    _write(tmp_path, GOOD.replace("lamps: [bulb]}", "lamps: [bulb, spot]}"))
    code, out, _ = run_cli("validate-config", "b", "--format", "json", cwd=tmp_path)
    assert code == 2
    rep = json.loads(out)
    assert rep["errors"] == 1
    d = rep["diagnostics"][0]
    assert d["code"] == "LB202" and d["location"] == {"file": "b/booth.yaml", "line": 16, "column": 21}


def test_strict_turns_warnings_into_exit_1(tmp_path, run_cli):
    # ISO 3664 P1 asks 2000 ± 500 lx; this lamp gives 1000/0.49 = 2041 lx → clean; 500 cd → 1020 lx → warning
    text = GOOD.replace("A: {lamps: [bulb]}", "A: {lamps: [bulb], standard: ISO_3664_P1}")
    _write(tmp_path, text)
    assert run_cli("validate-config", "b", "--strict", cwd=tmp_path)[0] == 0
    _write(tmp_path, text.replace("value_cd: 1000", "value_cd: 500"))
    code, _, err = run_cli("validate-config", "b", "--strict", cwd=tmp_path)
    assert code == 1 and "warning LB310: lighting 'A' gives 1020 lx" in err
    assert run_cli("validate-config", "b", cwd=tmp_path)[0] == 0
