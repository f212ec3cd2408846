"""CLI conventions: JSON errors under --format json, shell completion, plain progress and wide
tables when piped, the HTML report's per-reading table, version and date."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]


def _run(*args, env=None):
    return subprocess.run([sys.executable, "-m", "lbscene", *map(str, args)], capture_output=True, text=True,
                          cwd=REPO, env={**os.environ, **(env or {})}, timeout=300)


def test_user_errors_under_format_json_are_one_json_object_on_stdout(run_cli):
    code, out, err = run_cli("build", "no-such-booth", "--format", "json")
    assert code == 2
    j = json.loads(out)
    assert j["ok"] is False and j["exit_code"] == 2
    assert [(e["code"], e["message"], e["location"]["file"]) for e in j["errors"]] == [
        ("LB010", "file not found", "no-such-booth")]
    assert err == ""


def test_usage_errors_under_format_json_too(run_cli):
    code, out, _ = run_cli("compare", "x.yaml", "--format", "json", "--fit-nope")
    assert code == 2
    j = json.loads(out)
    assert j["errors"][0]["code"] == "LB500"
    assert j["errors"][0]["message"].startswith("No such option '--fit-nope'.")


def test_shell_completion_is_available():
    exe = str(Path(sys.executable).parent / "lbscene")          # the installed console script
    # typed in bash, as a user does (the completion script is the detected shell's; bash stays the
    # parent: a lone command in `bash -c` would replace it, leaving no shell to detect)
    p = subprocess.run(["bash", "-c", '"$0" --show-completion; exit $?', exe], capture_output=True, text=True,
                       cwd=REPO)
    assert p.returncode == 0, p.stderr
    assert "complete -o default -F _lbscene_completion lbscene" in p.stdout
    p = subprocess.run([exe], capture_output=True, text=True, cwd=REPO,
                       env={**os.environ, "_LBSCENE_COMPLETE": "complete_bash", "COMP_WORDS": "lbscene rend",
                            "COMP_CWORD": "1"})
    assert p.stdout.split() == ["render"]


def test_piped_build_prints_plain_progress_lines_and_whole_table(minimal_booth, tmp_path):
    p = _run("build", minimal_booth, "--out", tmp_path / "a-rather-long-output-folder-name" / "build")
    assert p.returncode == 0, p.stderr
    steps = [line.split("] ", 1)[1] for line in p.stderr.splitlines() if line.startswith("[")]
    assert steps[:3] == ["build", "build: compile", "build: usd"] and steps[-1] == "build: finish"
    assert "\x1b[" not in p.stderr                       # no terminal escape codes in a pipe
    assert "…" not in p.stdout                            # nothing cut to fit 80 columns
    assert "lighting/A/scene.usda" in p.stdout


def test_report_has_every_reading_the_version_and_a_date(run_cli, tmp_path):
    from lbscene import __version__

    m = REPO / "examples" / "walkthrough-spectralight-d65" / "measurements.yaml"
    rep = tmp_path / "r.html"
    code, _, err = run_cli("compare", m, "--no-history", "--no-diagnose", "--report", rep)
    assert code == 0, err
    html = rep.read_text()
    assert "<h2>Every reading</h2>" in html
    n_rows = sum(1 for line in (m.parent / "measurements-grid.csv").read_text().splitlines()[1:] if line.strip())
    assert html.count("measurements-grid.csv:") == n_rows
    assert f"lbscene {__version__} · 20" in html
    assert f"<meta name='generator' content='lbscene {__version__}'>" in html


def test_a_narrow_terminal_folds_table_cells_and_cuts_nothing():
    """At 60 columns a table's long words (an effect's id, a verdict) are folded onto the next
    line, never cut with "…": every id is still there, letter for letter, down its column."""
    from lbscene.engine.light.effects.registry import available_effects

    p = _run("effects", env={"COLUMNS": "60"})
    assert p.returncode == 0, p.stderr
    assert "…" not in p.stdout
    assert max(len(line) for line in p.stdout.splitlines()) <= 60
    first_column = "".join(line.split("│")[1].strip() for line in p.stdout.splitlines()
                           if line.startswith("│"))
    for effect_id in available_effects():
        assert effect_id in first_column

