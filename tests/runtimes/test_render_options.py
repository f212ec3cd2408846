"""``render --lighting`` and ``--geometry`` lists; ``accuracy --display builtin:srgb``."""

from __future__ import annotations

import json
import os
import shutil
from pathlib import Path

import numpy as np
import pytest

HERE = Path(__file__).resolve().parent
DATA = HERE / "data"
TUBE_GONIO = DATA / "tube-gonio.yaml"

os.environ.setdefault("PYOPENGL_PLATFORM", "egl")


@pytest.fixture
def two_lightings(tmp_path):
    """The tube test booth with a second lighting: the same tube at half its level."""
    shutil.copytree(DATA / "tube-booth", tmp_path / "tube-booth")
    for name in ("sample-gonio.yaml", "tube-gonio.yaml"):
        shutil.copy(DATA / name, tmp_path / name)
    b = tmp_path / "tube-booth" / "booth.yaml"
    b.write_text(b.read_text().replace("  D65: {lamps: [tube]}\n",
                                       "  D65: {lamps: [tube]}\n  half: {lamps: [tube], dimming: {tube: 0.5}}\n"))
    return tmp_path / "tube-gonio.yaml"


def test_geometry_list_parsing():
    from lbscene.runtimes.render import geometry_list

    assert geometry_list("45as0") == ["45as0"]
    assert geometry_list("45as15, 45as-15") == ["45as15", "45as-15"]
    assert geometry_list(["45as15,45as0", "45as45", "45as0"]) == ["45as15", "45as0", "45as45"]
    assert geometry_list(None) == []
    with pytest.raises(TypeError):
        geometry_list(45)


def test_unknown_lighting_option_is_pinned(run_cli, tmp_path):
    out = tmp_path / "x.png"
    code, _, err = run_cli("render", TUBE_GONIO, "--lighting", "A", "-o", out)
    assert code == 2
    assert ("error LB202: --lighting: booth 'Tube test booth' has no lighting configuration 'A' "
            "(got 'A'; expected one of D65)") in err
    assert not out.exists()


def test_one_unknown_geometry_in_a_list_is_pinned(run_cli, tmp_path):
    code, _, err = run_cli("render", TUBE_GONIO, "--geometry", "45as0,45as99", "-o", tmp_path / "x.png")
    assert code == 2
    assert "error LB303: --geometry: unknown viewing geometry '45as99' for booth 'Tube test booth'" in err


def test_prepare_with_lighting_and_geometries(two_lightings):
    from lbscene.runtimes.render import prepare_from_config

    job = prepare_from_config(two_lightings, lighting="half", geometry="45as45,45as-15", size=(32, 24))
    assert job.graph["lighting"] == "half" and job.views == ["45as45", "45as-15"] and job.contact
    one = prepare_from_config(two_lightings, geometry=["45as15"])
    assert one.views == ["45as15"] and not one.contact and one.graph["lighting"] == "D65"
    with pytest.raises(TypeError):
        prepare_from_config(two_lightings, lighting=["half"])


@pytest.mark.gl
def test_render_with_another_lighting_and_a_list_of_geometries(run_cli, two_lightings, tmp_path):
    from PIL import Image

    out = tmp_path / "sheet.png"
    code, stdout, err = run_cli("render", two_lightings, "--lighting", "half", "--geometry", "45as15,45as-15",
                                "-g", "45as45", "--size", "48x32", "-o", out, "--format", "json")
    assert code == 0, err
    half = json.loads(stdout)
    assert half["lighting"] == "half"
    assert [v["view"] for v in half["views"]] == ["45as15", "45as-15", "45as45"]
    assert half["contact_sheet"] == {"views": 3, "columns": 3, "tile_px": [48, 32]}
    assert Image.open(out).size == (3 * 48, 32)
    code, stdout, err = run_cli("render", two_lightings, "--geometry", "45as15,45as-15,45as45", "--size", "48x32",
                                "-o", tmp_path / "full.png", "--format", "json")
    assert code == 0, err
    full = json.loads(stdout)
    assert full["lighting"] == "D65"
    # dimming 0.5: half the light on the sample at every view
    for a, b in zip(half["views"], full["views"]):
        assert a["sample_illuminance_lx"] == pytest.approx(0.5 * b["sample_illuminance_lx"], rel=1e-6)


# --------------------------------------------------------------------------- accuracy

def test_accuracy_accepts_the_builtin_srgb_display(run_cli, minimal_booth):
    code, out, err = run_cli("accuracy", "--no-cie", "--booth", minimal_booth, "--display", "builtin:srgb",
                             "--format", "json")
    assert code in (0, 1), err
    rows = [r for r in json.loads(out) if r.get("display")]
    assert rows and {r["display"] for r in rows} == {"sRGB (IEC 61966-2-1), builtin"}


def test_the_builtin_srgb_display_is_iec_61966_2_1():
    from lbscene.commands.accuracy import load_display_arg

    m = load_display_arg("builtin:srgb", "chroma")
    # IEC 61966-2-1:1999, the linear sRGB → XYZ matrix (D65 white, Y = 1), white 80 cd/m², no flare
    iec = np.array([[0.4124, 0.3576, 0.1805], [0.2126, 0.7152, 0.0722], [0.0193, 0.1192, 0.9505]])
    np.testing.assert_allclose(m.rgb_to_xyz / 80.0, iec, atol=2e-4)


def test_accuracy_unknown_builtin_display(run_cli):
    code, _, err = run_cli("accuracy", "--no-cie", "--display", "builtin:p3")
    assert code == 2
    assert "error LB500: --display: unknown built-in display 'builtin:p3' (got 'builtin:p3'; expected " \
           "builtin:srgb or a display file)" in err
