"""Readings far from the model (``LB406``): the hint names the likely cause found in the data —
sensors facing away from the lamps, points inside a lamp's body or level with the lamps, a filter
that blocks the visible — and falls back to the unit only when none of these is found."""

from __future__ import annotations

import os

import numpy as np

#: the minimal booth: one isotropic 1000 cd point lamp at (0, 0, 700) mm
PTS = [(x, y) for x in np.linspace(-400, 400, 5) for y in np.linspace(-250, 250, 3)]
LUX = [1000 * 0.7 / (0.49 + (x * x + y * y) / 1e6) ** 1.5 for x, y in PTS]


def _set(tmp_path, booth, rows: str, header: str = "x_mm,y_mm,illuminance_lx", entry: str = ""):
    d = tmp_path / "m"
    d.mkdir(exist_ok=True)
    (d / "grid.csv").write_text(header + "\n" + rows)
    (d / "meas.yaml").write_text(
        f"version: 1\nkind: measurement_set\nname: t\nbooth: {os.path.relpath(booth, d)}\nlighting: A\n"
        "illuminance:\n  - path: grid.csv\n" + entry)
    return d / "meas.yaml"


def _hint(run_cli, meas) -> str:
    code, _, err = run_cli("compare", meas, "--no-history", "--no-diagnose", cwd=meas.parent)
    assert code == 2 and "error LB406: readings are" in err, err
    return next(ln for ln in err.splitlines() if ln.startswith("    hint: "))[len("    hint: "):]


def test_a_meter_declared_facing_down_is_named(minimal_booth, tmp_path, run_cli):
    # the readings are right (an upward meter under the lamp); the file says "down": the model
    # sees no light from below the floor, and the readings look 10¹⁵ × too large
    meas = _set(tmp_path, minimal_booth, "".join(f"{x:g},{y:g},{e:.2f},down\n" for (x, y), e in zip(PTS, LUX)),
                header="x_mm,y_mm,illuminance_lx,orientation")
    assert _hint(run_cli, meas) == (
        "15 of 15 readings face away from every lamp of lighting 'A' (sensor facing down at grid.csv:2): check "
        "the orientation column or the file's orientation: (a meter on the floor faces up)")


def test_an_opaque_filter_is_named(minimal_booth, tmp_path, run_cli):
    f = minimal_booth / "booth.yaml"
    f.write_text(f.read_text().replace(
        "    output: {type: peak_intensity_cd, value_cd: 1000}\n",
        "    output: {type: peak_intensity_cd, value_cd: 1000}\n    filter: blue\n").replace(
        "lighting:\n", "filters:\n  blue: {transmittance: {type: constant, value: 0.0001}}\n"
                       "effects: {spectral_filter: {}}\nlighting:\n"))
    meas = _set(tmp_path, minimal_booth, "".join(f"{x:g},{y:g},{e:.2f}\n" for (x, y), e in zip(PTS, LUX)))
    assert _hint(run_cli, meas) == (
        "filter 'blue' of lamp 'bulb' lets through 0.0001 of its visible light: check its transmittance (a "
        "fraction 0..1; the right column, the right file)")


def test_points_inside_a_lamp_and_level_with_it_are_named(minimal_booth, tmp_path, run_cli):
    # z_mm: 700 for the file (meant: 7 cm?): the points lie in the lamp's plane, one in its body
    rows = "".join(f"{x:g},{y:g},1500\n" for x in (-20, 0, 20) for y in (-20, 0, 20))
    meas = _set(tmp_path, minimal_booth, rows, entry="    z_mm: 700\n")
    assert _hint(run_cli, meas) == (
        "1 reading(s) lie inside the body of a lamp (first: grid.csv:6 in lamp 'bulb'): is z_mm in another unit, "
        "or the point mistyped?; 9 of 9 readings are level with or beyond every lamp of lighting 'A' (z = 700 mm "
        "at grid.csv:2): check z_mm (millimetres above the floor)")


def test_otherwise_the_unit_and_the_lamp_output(minimal_booth, tmp_path, run_cli):
    # a lamp declared at 1 mcd instead of 1000 cd: readings facing the lamp, no filter, no point in
    # a lamp: the hint stays with the unit and the lamp output
    f = minimal_booth / "booth.yaml"
    f.write_text(f.read_text().replace("value_cd: 1000", "value_cd: 0.001"))
    meas = _set(tmp_path, minimal_booth, "".join(f"{x:g},{y:g},{e:.2f}\n" for (x, y), e in zip(PTS, LUX)))
    assert _hint(run_cli, meas) == "check the unit of illuminance_lx (klx? fc?) and the lamp output in the booth"
