"""``lbscene history``: the steps of earlier compare runs, as JSON, a table and a plot."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

from lbscene.cli import main
from lbscene.engine.truth.synthetic import synthesize

BOOTH = Path(__file__).resolve().parents[1] / "data" / "hidden-effect-booth"


def test_history_lists_each_compare_and_plots_it(tmp_path, capsys):
    shutil.copytree(BOOTH, tmp_path / "booth")
    m = synthesize(tmp_path / "booth", tmp_path / "m", lighting="FL", truth_effects={})
    assert main(["history", str(m)]) == 0
    assert "no history yet" in capsys.readouterr().out

    for fit in ("--no-fit", "--fit"):
        assert main(["compare", str(m), fit, "--no-diagnose", "--format", "json"]) == 0
    capsys.readouterr()
    png = tmp_path / "history.png"
    assert main(["history", str(m), "--plot", str(png), "--format", "json"]) == 0
    out = json.loads(capsys.readouterr().out)
    steps = out["entries"]
    assert [e["step"] for e in steps] == [1, 2]
    assert steps[0]["fitted"] is False and steps[1]["fitted"] is True
    # the declared model (400 cd, 1 % noise, nothing hidden) is right: fitting changes little
    assert abs(steps[0]["rmse_percent"] - steps[1]["rmse_percent"]) < 0.5
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert out["plot"] == str(png)
