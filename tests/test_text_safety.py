"""User text is shown as written in every output: rich markup is not parsed, terminal control
sequences are shown as escapes, plots never parse mathtext, and a console that cannot encode
a character gets an escape instead of a crash."""

from __future__ import annotations

import csv
import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

REPO = Path(__file__).resolve().parents[1]
WEB = REPO / "tests" / "web" / "data"

#: markup rich would parse (a closing tag without its opening one raises), mathtext matplotlib
#: would parse (unbalanced: raises), and "clear the screen"
HOSTILE = "[/link][bold]x $\\frac{$ \x1b[2J"
#: the same, as it must be printed
SHOWN = "[/link][bold]x $\\frac{$ \\x1b[2J"
#: in a YAML double-quoted scalar
YAML_QUOTED = '"[/link][bold]x $\\\\frac{$ \\e[2J"'


def _no_control(text: str) -> None:
    assert "\x1b" not in text and "Traceback" not in text


def test_printable_and_json_text():
    from lbscene.engine.files.textsafe import json_text, printable

    assert printable(HOSTILE) == SHOWN
    assert printable("a\rb\x9bc\u202ed\x7f") == "a\\rb\\x9bc\\u202ed\\x7f"
    assert printable("two\nlines\tok") == "two\nlines\tok"
    assert printable("one\nline", newlines=False) == "one\\nline"
    text = json_text({"n": "x\x9by\x1b"}, indent=1)
    assert "\x9b" not in text and json.loads(text) == {"n": "x\x9by\x1b"}


def test_diagnostics_escape_every_part():
    from lbscene.engine.files.diagnostics import Diagnostic, SourceLocation

    d = Diagnostic("LB104", f"bad {HOSTILE}", SourceLocation("a\nb.yaml", 2, 3), value=HOSTILE,
                   expected="x", hint="h\x1b")
    assert d.format() == (f"a\\nb.yaml:2:3: error LB104: bad {SHOWN} (got {SHOWN}; expected x)\n"
                          "    hint: h\\x1b")


@pytest.fixture
def hostile_meas(minimal_booth, tmp_path):
    """A measurement set whose name and file name hold markup, mathtext and an escape sequence."""
    d = tmp_path / "m"
    d.mkdir()
    pts = np.array([[x, y, 0.0] for x in np.linspace(-400, 400, 5) for y in np.linspace(-250, 250, 3)])
    r = np.linalg.norm(pts - [0, 0, 700], axis=1) / 1000.0
    lux = 1000.0 * (0.7 / r) / r ** 2
    (d / "grid.csv").write_text("x_mm,y_mm,illuminance_lx\n" + "".join(
        f"{p[0]:g},{p[1]:g},{e:.3f}\n" for p, e in zip(pts, lux)))
    f = d / "[bold]$\\frac{$\x1b[2J.yaml"
    f.write_text(f"version: 1\nkind: measurement_set\nname: {YAML_QUOTED}\n"
                 f"booth: {os.path.relpath(minimal_booth, d)}\nlighting: A\n"
                 "instrument: {illuminance_meter: m, repeatability_percent: 0.5}\n"
                 "illuminance:\n  - path: grid.csv\n")
    return f


def test_compare_text_report_and_history_plot_show_names_literally(hostile_meas, run_cli, tmp_path):
    code, out, err = run_cli("compare", hostile_meas, "--no-diagnose")
    assert code == 0, err
    _no_control(out + err)
    assert out.splitlines()[0].startswith(SHOWN + "  booth ")
    report = tmp_path / "report.html"
    code, out, err = run_cli("compare", hostile_meas, "--no-diagnose", "--report", report)  # 2nd history step
    assert code == 0, err
    html = report.read_text()
    assert "[/link][bold]x $\\frac{$ \\x1b[2J" in html and "\x1b" not in html
    assert html.count("data:image/png;base64,") == 2      # floor maps and the history plot
    plot = tmp_path / "history.png"
    code, out, err = run_cli("history", hostile_meas, "--plot", plot)
    assert code == 0, err
    _no_control(out + err)
    assert plot.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert "[bold]$\\frac{$\\x1b[2J.yaml" in "".join(x.strip() for x in out.splitlines())
    code, out, err = run_cli("compare", hostile_meas, "--no-diagnose", "--format", "json")
    assert code == 0 and "\x1b" not in out and json.loads(out)["name"] == HOSTILE


def test_validate_config_error_in_a_hostile_file_name(tmp_path, run_cli):
    (tmp_path / "[").mkdir()
    f = tmp_path / "[" / "link]\x1b[2J.yaml"        # the path reads [/link]…
    f.write_text(f"version: 1\nkind: sample\nname: {YAML_QUOTED}\nsize_mm: [1, 2]\n")
    code, out, err = run_cli("validate-config", f)
    assert code == 2
    _no_control(out + err)
    assert f"{tmp_path}/[/link]\\x1b[2J.yaml:1:1: error LB102: missing required key 'provenance'" in err
    code, out, err = run_cli("validate-config", f, "--format", "json")
    assert code == 2 and "\x1b" not in out
    assert json.loads(out)["diagnostics"][0]["location"]["file"] == str(f)


def _hostile_session(tmp_path):
    for n in ("sample-gonio.yaml", "tube-gonio.yaml"):
        shutil.copy(WEB / n, tmp_path / n)
    (tmp_path / "sample-grey.yaml").write_text(
        (WEB / "sample-grey.yaml").read_text().replace("name: Grey 40 % (synthetic)", f"name: {YAML_QUOTED}"))
    (tmp_path / "session.yaml").write_text((WEB / "session-tube.yaml").read_text())
    from lbscene.engine.visual.protocol import load_session

    ses = load_session(tmp_path / "session.yaml")
    res = tmp_path / "results.csv"
    with open(res, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["session", "observer", "repeat", "order", "lighting", "geometry", "sample", "display",
                    "score", "response_time_ms"])
        for t in ses.trials:
            w.writerow([ses.model.name, t["observer"], t["repeat"], t["order"], t["lighting"], t["geometry"],
                        t["sample"], "sRGB", 4.5 if t["repeat"] == 1 else 4.0, 1000])
    return tmp_path / "session.yaml", res


def test_visual_report_shows_a_hostile_sample_name_literally(tmp_path, run_cli):
    ses, res = _hostile_session(tmp_path)
    report = tmp_path / "report.html"
    code, out, err = run_cli("visual-report", res, "--session", ses, "--report", report)
    assert code == 0, err
    _no_control(out + err)
    assert SHOWN in out
    html = report.read_text()
    assert "[/link][bold]x $\\frac{$ \\x1b[2J" in html and html.count("data:image/png;base64,") == 2
    code, out, err = run_cli("visual-report", res, "--session", ses, "--format", "json")
    assert code == 0 and "\x1b" not in out
    assert HOSTILE in {c["sample"] for c in json.loads(out)["cases"]}


def test_plots_never_parse_mathtext(tmp_path):
    from lbscene.engine.loop.history import plot_history

    fig = plot_history([{"step": 1, "rmse_percent": 2.0, "label": "$\\frac{$"}], title="$\\frac{$ [bold]")
    fig.savefig(tmp_path / "h.png")          # outside plain_text_plots(): still no mathtext
    assert (tmp_path / "h.png").stat().st_size > 0


@pytest.mark.parametrize("args", [["effects"], ["validate-config", "tests/data/minimal-booth", "-v"],
                                  ["validate-config", "nope\u0394.yaml"]])
def test_an_ascii_console_does_not_crash(args):
    env = {**os.environ, "PYTHONIOENCODING": "ascii"}
    p = subprocess.run([sys.executable, "-m", "lbscene", *args], capture_output=True, cwd=REPO, env=env,
                       timeout=120)
    assert p.returncode in (0, 2), p.stderr
    assert b"Traceback" not in p.stderr and b"UnicodeEncodeError" not in p.stderr
    if args[0] == "validate-config" and args[1].startswith("nope"):
        # click writes UTF-8 to a stream it finds configured for ASCII; rich's consoles escape
        assert b"error LB010: file not found" in p.stderr


def test_compare_on_an_ascii_console(hostile_meas):
    env = {**os.environ, "PYTHONIOENCODING": "ascii"}
    p = subprocess.run([sys.executable, "-m", "lbscene", "compare", hostile_meas.name, "--no-history",
                        "--no-diagnose"], capture_output=True, cwd=hostile_meas.parent, env=env, timeout=300)
    assert p.returncode == 0, p.stderr
    assert b"Traceback" not in p.stderr and b"\x1b" not in p.stdout
    assert p.stdout.startswith(SHOWN.encode() + b"  booth ")
    assert b"fitted parameters" in p.stdout and b"\\u2026" in p.stdout     # "…" in the bounds, escaped


def test_visual_report_on_an_ascii_console(tmp_path):
    ses, res = _hostile_session(tmp_path)
    env = {**os.environ, "PYTHONIOENCODING": "ascii"}
    p = subprocess.run([sys.executable, "-m", "lbscene", "visual-report", str(res), "--session", str(ses)],
                       capture_output=True, cwd=tmp_path, env=env, timeout=120)
    assert p.returncode == 0, p.stderr
    assert b"\\u0394V" in p.stdout and b"\x1b" not in p.stdout       # the ΔV column, escaped


def test_progress_descriptions_are_literal():
    import io

    from rich.console import Console
    from rich.progress import TextColumn

    from lbscene.commands.console import PlainProgress, progress

    term = Console(file=io.StringIO(), force_terminal=True, width=100)
    with progress(TextColumn("{task.description}"), console=term, transient=False) as p:
        t = p.add_task(f"build: {HOSTILE}")               # rich raised MarkupError on "[/link]"
        p.update(t, description=f"bake: {HOSTILE}")
    assert f"bake: {SHOWN}" in term.file.getvalue()
    plain = io.StringIO()
    pp = PlainProgress(plain)
    pp.add_task(f"render: {HOSTILE}")
    assert plain.getvalue().endswith(f"render: {SHOWN}\n")
