"""What a new user runs first, the way they run it: every command with its default options and
every output format (text, JSON, HTML report, plots), the diagnosis on and off, on the shipped
walkthrough and on a copy of it whose folder, file and set names hold rich markup, mathtext,
terminal escapes and non-ASCII text; and the visual test from session to ``visual-report`` with
its defaults.  No traceback, exit 0, every output parses.

The console script is exercised as installed (``python -m lbscene`` in a subprocess, so the
process's own streams and encoding are used) for the commands of the README's walkthrough; the
rest of the matrix runs in-process for speed.
"""

from __future__ import annotations

import csv
import json
import os
import re
import shutil
import subprocess
import sys
from html.parser import HTMLParser
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
WALK = REPO / "examples" / "walkthrough-spectralight-d65"
BOOTH = REPO / "booths" / "xrite-spectralight-qc"
WEB_DATA = REPO / "tests" / "web" / "data"

# a folder/file name a hostile or merely international user might have
ODD = "mess [bold]x[i] $\\frac{$ é 色 \x1b[2J"


def _assert_clean(code: int, out: str, err: str, expect: int = 0) -> None:
    assert "Traceback" not in out + err, err[-3000:]
    assert code == expect, (code, out[-2000:], err[-2000:])


def _parse_html(text: str) -> None:
    """The report is one well-formed HTML document with no script and nothing fetched."""

    class P(HTMLParser):
        tags: list[str] = []

        def handle_starttag(self, tag, attrs):
            self.tags.append(tag)

    p = P()
    p.feed(text)
    p.close()
    assert p.tags[:1] == ["html"] and "body" in p.tags
    assert "<script" not in text and "http://" not in text and "https://" not in text


def _png(path: Path) -> None:
    data = path.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n" and len(data) > 1000


def _walkthrough_copy(root: Path, odd: bool) -> Path:
    """The walkthrough's measurements and a copy of the booth; with ``odd``, hostile names."""
    name = ODD if odd else "walk"
    d = root / name
    (d / "meas").mkdir(parents=True)
    shutil.copytree(BOOTH, d / f"booth {ODD}" if odd else d / "booth")
    booth_dir = d / (f"booth {ODD}" if odd else "booth")
    grid, tile = ("grid [red]é[i] $x$.csv", "tile \x1b[31m色.csv") if odd else ("grid.csv", "tile.csv")
    shutil.copy(WALK / "measurements-grid.csv", d / "meas" / grid)
    shutil.copy(WALK / "measurements-tile.csv", d / "meas" / tile)
    text = (WALK / "measurements.yaml").read_text()
    text = text.replace("measurements-grid.csv", json.dumps(grid)).replace("measurements-tile.csv", json.dumps(tile))
    text = text.replace("../../booths/xrite-spectralight-qc", json.dumps(f"../{booth_dir.name}"))
    if odd:
        odd_name = 'name: "[link=file:///etc]x[/link] $\\\\frac{$ \\e[2J Prüfung 色"'
        text = re.sub(r"(?m)^name: .*$", lambda _m: odd_name, text)
    m = d / "meas" / ("measurements [i].yaml" if odd else "measurements.yaml")
    m.write_text(text, encoding="utf-8")
    return m


@pytest.fixture(scope="module", params=["plain", "odd"])
def walk_both(request, tmp_path_factory):
    """The walkthrough as shipped and under hostile names (the README's command runs on both)."""
    return _walkthrough_copy(tmp_path_factory.mktemp("front"), request.param == "odd")


@pytest.fixture(scope="module")
def walk(tmp_path_factory):
    """The matrix runs on the hostile copy: everything the plain one meets, and more."""
    return _walkthrough_copy(tmp_path_factory.mktemp("front-odd"), True)


# --------------------------------------------------------------------------- as installed


def _lb(*args, cwd: Path, env_extra: dict | None = None) -> subprocess.CompletedProcess:
    env = dict(os.environ)
    env.update(env_extra or {})
    return subprocess.run([sys.executable, "-m", "lbscene", *map(str, args)], cwd=cwd, env=env,
                          capture_output=True, text=True, encoding="utf-8", errors="replace", timeout=600)


def test_compare_report_with_the_default_diagnosis_as_installed(walk_both, tmp_path):
    """The README walkthrough's first command: ``compare --report`` with its defaults."""
    walk = walk_both
    rep, js = tmp_path / "report.html", tmp_path / "compare.json"
    r = _lb("compare", walk, "--report", rep, "--json-out", js, cwd=tmp_path)
    _assert_clean(r.returncode, r.stdout, r.stderr)
    res = json.loads(js.read_text())
    # the walkthrough's data hide a detector cosine error (examples/…/make_measurements.py)
    assert res["verdict"] == "missing:detector_cosine_error"
    html = rep.read_text(encoding="utf-8")
    _parse_html(html)
    assert "verdict: <b>missing:detector_cosine_error</b>" in html
    assert "Suspects" in html and "Add to the booth file" in html
    # the glass plate's diffuse fraction is not refitted with every candidate (its opal part would
    # gather the light of the D65 tubes' 3200 points and their mirror images): the user is told
    assert "effect.diffuser.diffuse_fraction" in res["diagnosis"]["joint_parameters_held_for_cost"]
    assert re.search(r"too dear to refit with every candidate\): [^<]*effect\.diffuser\.diffuse_fraction", html)
    # the run is in the history, and the history command reads it back
    h = _lb("history", walk, "--format", "json", cwd=tmp_path)
    _assert_clean(h.returncode, h.stdout, h.stderr)
    assert json.loads(h.stdout)["entries"][-1]["verdict"] == "missing:detector_cosine_error"


def test_text_output_with_an_ascii_console(walk, tmp_path):
    """``PYTHONIOENCODING=ascii``: non-ASCII names and the rich tables still print."""
    r = _lb("compare", walk, "--no-history", cwd=tmp_path, env_extra={"PYTHONIOENCODING": "ascii"})
    _assert_clean(r.returncode, r.stdout, r.stderr)
    assert "verdict" in r.stdout


# --------------------------------------------------------------------------- the matrix, in-process


@pytest.mark.parametrize("diagnose", ["--diagnose", "--no-diagnose"])
@pytest.mark.parametrize("fmt", ["text", "json"])
def test_compare_every_format(walk, tmp_path, run_cli, fmt, diagnose):
    rep, js = tmp_path / "r.html", tmp_path / "r.json"
    code, out, err = run_cli("compare", walk, "--no-history", diagnose, "--format", fmt, "--report", rep,
                             "--json-out", js)
    _assert_clean(code, out, err)
    res = json.loads(js.read_text())
    if fmt == "json":
        assert json.loads(out) == res
    else:
        assert "RMSE" in out
        # markup and escapes in names print literally, never interpreted
        assert "\x1b" not in out
    _parse_html(rep.read_text(encoding="utf-8"))
    assert ("verdict" in res) and (res["verdict"] != "" if diagnose == "--diagnose" else True)


@pytest.mark.parametrize("fmt", ["text", "json"])
def test_plan_every_format(walk, tmp_path, run_cli, fmt):
    out_csv = tmp_path / "plan.csv"
    code, out, err = run_cli("plan", walk, "--format", fmt, "--out", out_csv)
    _assert_clean(code, out, err)
    if fmt == "json":
        json.loads(out)
    assert "\x1b" not in out
    rows = list(csv.reader(out_csv.open(encoding="utf-8")))
    assert rows and rows[0]


@pytest.mark.parametrize("fmt", ["text", "json"])
def test_history_every_format_and_plot(walk, tmp_path, run_cli, fmt):
    # a run to show (the history lives beside the measurements)
    _assert_clean(*run_cli("compare", walk, "--no-diagnose", "--format", "json"))
    png = tmp_path / "h.png"
    code, out, err = run_cli("history", walk, "--format", fmt, "--plot", png)
    _assert_clean(code, out, err)
    if fmt == "json":
        assert json.loads(out)["entries"]
    assert "\x1b" not in out
    _png(png)


@pytest.mark.parametrize("fmt", ["text", "json"])
def test_validate_and_build_every_format(walk, tmp_path, run_cli, fmt):
    code, out, err = run_cli("validate-config", walk.parent.parent, "--format", fmt)
    _assert_clean(code, out, err)
    if fmt == "json":
        json.loads(out)
    booth = next(p for p in walk.parent.parent.iterdir() if p.name.startswith("booth"))
    code, out, err = run_cli("build", booth, "--lighting", "D65", "--out", tmp_path / "b", "--format", fmt)
    _assert_clean(code, out, err)
    if fmt == "json":
        json.loads(out)
    assert (tmp_path / "b" / "scene.ir.json").is_file() and (tmp_path / "b" / "manifest.json").is_file()
    assert "\x1b" not in out


@pytest.mark.parametrize("fmt", ["text", "json"])
def test_effects_and_accuracy_every_format(tmp_path, run_cli, fmt):
    code, out, err = run_cli("effects", "--format", fmt)
    _assert_clean(code, out, err)
    if fmt == "json":
        json.loads(out)
    png = tmp_path / f"acc {ODD}.png"
    code, out, err = run_cli("accuracy", "--booth", BOOTH, "--format", fmt, "--plot", png, "--no-cie")
    _assert_clean(code, out, err)
    if fmt == "json":
        json.loads(out)
    _png(png)


@pytest.mark.parametrize("fmt", ["text", "json"])
def test_render_defaults_every_format(tmp_path, run_cli, fmt):
    """``render CONFIG -o PNG`` at the config's defaults: every output goes where -o says."""
    cfg = REPO / "examples" / "render" / "splqc-d65-moderate-red.yaml"
    png = tmp_path / f"{ODD}.png"
    code, out, err = run_cli("render", cfg, "-o", png, "--size", "128x96", "--format", fmt)
    _assert_clean(code, out, err)
    if fmt == "json":
        json.loads(out)
    _png(png)
    # the config's float XYZ follows -o: nothing written into the examples folder
    assert (tmp_path / f"{ODD}.xyz.exr").is_file()
    assert "\x1b" not in out


def test_visual_test_with_its_defaults(tmp_path, run_cli):
    """Session (``repeats`` left at its default) → viewer → results → ``visual-report``."""
    from lbscene.engine.visual.protocol import load_session

    root = tmp_path / ODD
    shutil.copytree(WEB_DATA, root / "web" / "data")
    shutil.copytree(REPO / "tests" / "runtimes" / "data", root / "runtimes" / "data")
    d = root / "web" / "data"
    ses_file = d / "session.yaml"
    text = (WEB_DATA / "session-tube.yaml").read_text()
    ses_file.write_text(re.sub(r"(?m)^repeats: .*\n", "", text))
    viewer = tmp_path / "viewer"
    code, out, err = run_cli("export-web", d / "tube-gonio.yaml", "--out", viewer, "--session", ses_file,
                             "--size", "160x120")
    _assert_clean(code, out, err)
    _parse_index = (viewer / "index.html").read_text(encoding="utf-8")
    assert "<canvas" in _parse_index
    model_de = viewer / "model-delta-e00.csv"
    assert model_de.is_file()
    ses = load_session(ses_file)
    assert {t["repeat"] for t in ses.trials} == {1}
    res = tmp_path / "results.csv"
    with res.open("w", newline="", encoding="utf-8") as f:
        w = csv.writer(f)
        w.writerow(["session", "observer", "repeat", "order", "lighting", "geometry", "sample", "display",
                    "score", "response_time_ms"])
        for t in ses.trials:
            w.writerow([ses.model.name, t["observer"], t["repeat"], t["order"], t["lighting"], t["geometry"],
                        t["sample"], "sRGB", 4.0 if t["sample"].startswith("Grey") else 3.0, 1500])
    for fmt in ("text", "json"):
        code, out, err = run_cli("visual-report", res, "--session", ses_file, "--format", fmt)
        _assert_clean(code, out, err)
        if fmt == "json":
            st = json.loads(out)
            assert st["responses"] == len(ses.trials)
    rep = tmp_path / "visual.html"
    code, out, err = run_cli("visual-report", res, "--session", ses_file, "--model-de", model_de,
                             "--report", rep, "--json-out", tmp_path / "v.json")
    _assert_clean(code, out, err)
    _parse_html(rep.read_text(encoding="utf-8"))
    json.loads((tmp_path / "v.json").read_text())


@pytest.mark.bake
@pytest.mark.parametrize("fmt", ["text", "json"])
def test_bake_every_format(tmp_path, run_cli, fmt):
    """``bake`` at its default quality on a small booth copied under a hostile folder name, then
    its cross-check."""
    pytest.importorskip("bpy")
    booth = tmp_path / ODD / "booth"
    shutil.copytree(REPO / "tests" / "data" / "minimal-booth", booth)
    code, out, err = run_cli("bake", booth, "--out", tmp_path / "bakes", "--samples", "4", "--format", fmt)
    _assert_clean(code, out, err)
    if fmt == "json":
        assert [b["status"] for b in json.loads(out)["bakes"]] == ["baked"]
    assert "\x1b" not in out
    assert json.loads(next((tmp_path / "bakes").rglob("manifest.json")).read_text())
    code, out, err = run_cli("bake", booth, "--out", tmp_path / "bakes", "--samples", "4", "--format", fmt,
                             "--cross-check", "--cross-check-mode", "direct")
    assert "Traceback" not in out + err
    assert code in (0, 1), err[-2000:]       # 1: the cross-check finds a difference
    if fmt == "json":
        (row,) = json.loads(out)["cross_check"]
        assert row["mode"] == "direct" and row["points"] == 55


@pytest.mark.parametrize("fmt", ["text", "json"])
def test_conformance_and_export_mitsuba_every_format(tmp_path, run_cli, fmt):
    """``conformance`` (text, JSON, HTML report) and ``export-mitsuba`` on a shipped booth copied
    under a hostile folder name."""
    booth = tmp_path / ODD / "booth"
    shutil.copytree(REPO / "booths" / "iso3664-p1-d50", booth)
    rep = tmp_path / f"{ODD} conformance.html"
    code, out, err = run_cli("conformance", booth, "--format", fmt, "--report", rep)
    _assert_clean(code, out, err)
    if fmt == "json":
        res = json.loads(out)
        assert res["lightings"]
    assert "\x1b" not in out
    _parse_html(rep.read_text(encoding="utf-8"))
    pytest.importorskip("mitsuba")
    xml = tmp_path / "scene.xml"
    code, out, err = run_cli("export-mitsuba", booth, "--out", xml, "--format", fmt)
    _assert_clean(code, out, err)
    assert xml.read_text(encoding="utf-8").lstrip().startswith("<")


@pytest.mark.parametrize("fmt", ["text", "json"])
def test_export_blender_every_format(tmp_path, run_cli, fmt):
    """``export-blender`` on a shipped booth copied under a hostile folder name: a ``.blend`` with
    one collection per lighting; a second run replaces its own file, a file lbscene did not write is
    refused (``LB61x``) and left as it was, a bad suffix is ``LB500`` without a traceback."""
    pytest.importorskip("bpy")
    booth = tmp_path / ODD / "booth"
    shutil.copytree(REPO / "booths" / "iso3664-p1-d50", booth)
    blend = tmp_path / f"{ODD} booth.blend"
    code, out, err = run_cli("export-blender", booth, "--out", blend, "--format", fmt)
    _assert_clean(code, out, err)
    head = blend.read_bytes()[:7]
    assert head == b"BLENDER" or head[:4] == b"\x28\xb5\x2f\xfd"     # plain or zstd-compressed
    if fmt == "json":
        res = json.loads(out)
        assert res["lightings"] == ["P1", "P2"]
        assert 0 < res["camera"]["angle_x_deg"] < 180
    else:
        assert "lightings P1, P2" in out
    assert "\x1b" not in out
    if fmt == "json":
        return
    code, out, err = run_cli("export-blender", booth, "--out", blend)
    _assert_clean(code, out, err)
    foreign = tmp_path / "mine.blend"
    foreign.write_bytes(b"not lbscene's")
    code, out, err = run_cli("export-blender", booth, "--out", foreign)
    _assert_clean(code, out, err, expect=2)
    assert "LB61" in err and foreign.read_bytes() == b"not lbscene's"
    code, out, err = run_cli("export-blender", booth, "--out", tmp_path / "booth.usd")
    _assert_clean(code, out, err, expect=2)
    assert "LB500" in err and "--out must be a .blend file" in err
