"""Bad measurement data: located messages (file:line:col), exit code 2, no traceback.

Golden messages: the exact text a user sees is pinned, so a change to it is a
deliberate change to this file.
"""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest

from lbscene.cli import main

BOOTH = Path(__file__).resolve().parents[1] / "data" / "hidden-effect-booth"

MEAS_YAML = """\
version: 1
kind: measurement_set
name: bad data
booth: booth
lighting: FL
instrument: {illuminance_meter: test meter}
illuminance:
  - path: grid.csv
"""

TILE_YAML = """\
white_tile:
  radiance: {type: csv, path: tile.csv}
  reflectance: {type: constant, value: 0.99}
"""

GOOD_GRID = "x_mm,y_mm,illuminance_lx\n0,0,1500\n100,0,1400\n-100,0,1450\n"


@pytest.fixture
def mset(tmp_path, monkeypatch):
    shutil.copytree(BOOTH, tmp_path / "booth")
    monkeypatch.chdir(tmp_path)        # messages show paths relative to the working directory

    def make(grid: str, tile: str | None = None, yaml_text: str = MEAS_YAML) -> str:
        (tmp_path / "grid.csv").write_text(grid)
        text = yaml_text
        if tile is not None:
            (tmp_path / "tile.csv").write_text(tile)
            text += TILE_YAML
        (tmp_path / "m.yaml").write_text(text)
        return "m.yaml"

    return make


def run(capsys, *args) -> tuple[int, str]:
    rc = main(["compare", *args, "--no-fit", "--no-diagnose", "--no-history"])
    err = capsys.readouterr().err
    assert "Traceback" not in err
    return rc, err


@pytest.mark.parametrize("grid, expected", [
    ("x_mm,y_mm,illuminance_lx\n0,0,1500\n100,0,nan\n-100,0,1450\n",
     ["grid.csv:3:7: error LB401: 'illuminance_lx' is not a finite number (got 'nan'; expected a finite number)"]),
    ("x_mm,y_mm,illuminance_lx\n0,0,1500\n100,0,1400\n-100,0,-3\n",
     ["grid.csv:4:8: error LB402: negative illuminance (got '-3'; expected a reading > 0 lx)"]),
    ("x_mm,y_mm,illuminance_lx\n0,0,1500\n100,0,1400\n0,0,1450\n",
     ["grid.csv:4:1: error LB403: duplicate point (0, 0, 0) mm, already on line 2 (got line 4; expected one "
      "reading per point and orientation (average repeats first))"]),
    ("x_mm,y_mm,illuminance_lx\n0,0,1500\n100,0,1400\n9000,0,1450\n",
     ["grid.csv:4:1: error LB404: point (9000, 0, 0) mm is outside the floor (got (9000, 0, 0) mm; expected "
      "|x| ≤ 450, |y| ≤ 300, 0 ≤ z ≤ 700 mm (origin at the floor centre))"]),
    ("x_mm,y_mm\n0,0\n100,0\n-100,0\n",
     ["grid.csv:1:1: error LB400: missing column 'illuminance_lx' (got x_mm,y_mm; expected a header with "
      "x_mm, y_mm and illuminance_lx)"]),
    ("x_mm,y_mm,illuminance_klx\n0,0,1.5\n100,0,1.4\n-100,0,1.45\n",
     ["grid.csv:1:11: error LB406: column 'illuminance_klx': illuminance must be given in lux (got "
      "'illuminance_klx'; expected illuminance_lx)",
      "    hint: convert to lux (× 1000) and name the column illuminance_lx"]),
    ("x_mm,y_mm,illuminance_lx\n0,0,1.5\n100,0,1.4\n-100,0,1.45\n",
     ["grid.csv:1:11: error LB406: readings are implausibly small for a light booth (median 1.45) (got median "
      "1.45; expected lux (booths give ~500-5000 lx))",
      "    hint: the values look like klx: multiply by 1000"]),
    ("x_mm,y_mm,illuminance_lx\n0,0,1500\n",
     ["grid.csv:1:1: error LB407: only 1 reading(s) (expected at least 3 readings)"]),
], ids=["nan", "negative", "duplicate", "outside-floor", "missing-column", "klx-column", "klx-values",
        "too-few"])
def test_bad_illuminance_grid(mset, capsys, grid, expected):
    rc, err = run(capsys, mset(grid))
    assert rc == 2
    assert err.splitlines()[:len(expected)] == expected


def test_all_problems_of_a_file_are_reported_at_once(mset, capsys):
    rc, err = run(capsys, mset("x_mm,y_mm,illuminance_lx\n0,0,1500\n100,0,nan\n0,0,1400\n-100,0,-3\n"))
    assert rc == 2
    codes = sorted(line.split(" error ")[1][:5] for line in err.splitlines() if " error " in line)
    assert codes == ["LB401", "LB402", "LB403"]
    assert err.splitlines()[-1] == "3 errors"


def test_wavelengths_not_increasing_in_the_tile_spectrum(mset, capsys):
    rc, err = run(capsys, mset(GOOD_GRID, tile="wavelength_nm,radiance\n400,0.1\n390,0.2\n410,0.2\n"))
    assert rc == 2
    assert err.splitlines()[0] == ("tile.csv:3:1: error LB405: wavelengths are not strictly increasing "
                                   "(got 390 after 400; expected a wavelength above 400 nm)")


def test_unknown_key_in_the_measurement_set_is_located(mset, capsys):
    rc, err = run(capsys, mset(GOOD_GRID, yaml_text=MEAS_YAML + "colour: blue\n"))
    assert rc == 2
    assert err.startswith("m.yaml:9:1: error LB100: unknown key 'colour' in the document")


def test_missing_booth_is_located(mset, capsys):
    rc, err = run(capsys, mset(GOOD_GRID, yaml_text=MEAS_YAML.replace("booth: booth", "booth: nowhere")))
    assert rc == 2
    assert err.startswith("m.yaml:4:8: error LB200: booth 'nowhere' not found")
