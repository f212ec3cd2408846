"""``lbscene export-web``: the folder is self-contained and carries the runtime's own render
graphs and shader files (one source, not a port); user errors are pinned."""

from __future__ import annotations

import json
import os
import re
from pathlib import Path

import pytest

DATA = Path(__file__).resolve().parent / "data"
CONFIG = DATA / "tube-gonio.yaml"
SESSION = DATA / "session-tube.yaml"

os.environ.setdefault("PYOPENGL_PLATFORM", "egl")


def read_export(folder: Path) -> dict:
    text = (folder / "lbscene-data.js").read_text()
    return json.loads(text[text.index("=") + 1:].strip().rstrip(";"))


@pytest.fixture(scope="module")
def exported(tmp_path_factory):
    from lbscene.cli import main

    out = tmp_path_factory.mktemp("web") / "viewer"
    assert main(["export-web", str(CONFIG), "--session", str(SESSION), "--out", str(out)]) == 0
    return out


def test_folder_is_self_contained(exported):
    names = sorted(p.name for p in exported.iterdir())
    assert names == ["index.html", "lbscene-data.js", "lbscene-executor.js", "manifest.json",
                     "model-delta-e00.csv", "viewer.css", "viewer.js"]
    for name in ("index.html", "viewer.js", "lbscene-executor.js", "viewer.css"):
        text = (exported / name).read_text()
        # nothing is fetched from elsewhere: no absolute URLs, no module imports, no CDN
        assert not re.search(r"(src|href)=[\"']?(https?:)?//", text), name
        assert "import " not in text and "https://" not in text, name
    html = (exported / "index.html").read_text()
    assert html.index("lbscene-data.js") < html.index("lbscene-executor.js") < html.index("viewer.js")


def test_same_graph_and_shader_files_as_the_runtime(exported):
    from lbscene.engine.scene.compile import compile_booth
    from lbscene.runtimes.graph import SHADER_DIR, build_render_graph

    d = read_export(exported)
    files = {p.name: p.read_text() for p in SHADER_DIR.iterdir() if p.suffix in (".vert", ".frag", ".glsl")}
    assert d["shaders"] == files
    ir = compile_booth(DATA.parent.parent / "runtimes" / "data" / "tube-booth")
    for lt in d["lightings"]:
        assert lt["graph"] == build_render_graph(ir, lt["name"])
    assert d["format"] == "lbscene.web_export" and d["ir_hash"] == ir.content_hash


def test_export_covers_views_samples_and_session(exported):
    d = read_export(exported)
    assert [v["name"] for v in d["lightings"][0]["views"]] == ["45as-15", "45as0", "45as15", "45as45"]
    assert [s["name"] for s in d["samples"]] == ["Blue metallic (synthetic, gonio-apparent)",
                                                  "Grey 40 % (synthetic)"]
    assert d["displays"][0]["name"].startswith("sRGB")
    for v in d["lightings"][0]["views"]:
        assert len(v["samples"]) == 2 and all(len(s["displays"]) == 1 for s in v["samples"])
        vals = v["samples"][0]["displays"][0]["values"]
        assert "view.view_proj" not in vals          # the camera is computed per frame in the browser
        assert vals["sample.model"] == [1.0, 0, 0, 0, 0, 1.0, 0, 0, 0, 0, 1.0, 0, 0, 0, 0, 1.0]
    ses = d["session"]
    assert ses["name"] == "tube-test" and len(ses["trials"]) == 2 * 2 * 4
    # every blob referenced exists; shared data (the booth under a fixed lamp) is stored once
    refs = re.findall(r'"blob":"([0-9a-f]+)"', json.dumps(d, separators=(",", ":")))
    assert set(refs) == set(d["blobs"])
    assert len(set(refs)) < len(refs)


def test_out_folder_that_is_not_an_export_is_refused(run_cli, tmp_path):
    out = tmp_path / "mine"
    out.mkdir()
    (out / "notes.txt").write_text("keep me")
    code, _, err = run_cli("export-web", CONFIG, "--out", out)
    assert code == 2
    assert (f"error LB700: --out {out} exists and is not a web export (got {out}; expected a new folder, "
            "or one an earlier export-web wrote (it is replaced whole))") in err
    assert (out / "notes.txt").read_text() == "keep me" and "Traceback" not in err


def test_unknown_lighting_and_bad_size(run_cli, tmp_path):
    code, _, err = run_cli("export-web", CONFIG, "--out", tmp_path / "v", "--lighting", "TL84")
    assert code == 2
    assert ("error LB202: booth 'Tube test booth' has no lighting configuration 'TL84' (got TL84; "
            "expected one of D65)") in err
    code, _, err = run_cli("export-web", CONFIG, "--out", tmp_path / "v", "--size", "10x10")
    assert code == 2 and "error LB500: --size: 10x10: each side must be 16..8192 px" in err
    assert not (tmp_path / "v").exists()


def test_size_limit(run_cli, tmp_path):
    code, _, err = run_cli("export-web", CONFIG, "--out", tmp_path / "v", "--max-mb", "1")
    assert code == 2
    assert "error LB701: the export would hold 5 MB of data (got 4.8 MB; expected at most --max-mb 1)" in err
    assert not (tmp_path / "v").exists()


def test_model_delta_e_feeds_visual_report(exported, run_cli, tmp_path):
    import csv

    from lbscene.engine.visual.protocol import load_session

    rows = list(csv.DictReader((exported / "model-delta-e00.csv").open()))
    ses = load_session(SESSION)
    # every exported view × sample (a superset of the session's cases)
    assert set(ses.cases) < {(r["lighting"], r["geometry"], r["sample"]) for r in rows}
    assert len(rows) == 4 * 2
    grey = {r["delta_e00"] for r in rows if r["sample"].startswith("Grey")}
    assert len(grey) == 1 and float(grey.pop()) < 0.5      # a neutral: 8-bit rounding only
    res = tmp_path / "r.csv"
    res.write_text("observer,repeat,lighting,geometry,sample,score\n" + "".join(
        f'{t["observer"]},{t["repeat"]},{t["lighting"]},{t["geometry"]},"{t["sample"]}",4\n' for t in ses.trials))
    code, out, err = run_cli("visual-report", res, "--session", SESSION, "--model-de",
                             exported / "model-delta-e00.csv", "--format", "json")
    assert code == 0, err
    st = json.loads(out)
    assert st["summary"]["stress_vs_model"] is not None
    want = {(r["geometry"], r["sample"]): float(r["delta_e00"]) for r in rows}
    assert {c["model_delta_e00"] for c in st["cases"]} == {want[(c["geometry"], c["sample"])] for c in st["cases"]}


def test_export_replaces_only_an_export_it_made_unchanged(run_cli, tmp_path):
    """``--out`` follows the output policy of ``build``: an earlier export is replaced only while every
    file in it is one export-web wrote (its manifest) and unchanged."""
    out = tmp_path / "v"
    booth = DATA.parent.parent / "runtimes" / "data" / "tube-booth"
    for _ in range(2):                                                     # the second replaces the first
        code, _, err = run_cli("export-web", booth, "--out", out)
        assert code == 0, err
    m = json.loads((out / "manifest.json").read_text())
    assert m["format"] == "lbscene.web_export" and set(m["files"]) == {
        "index.html", "viewer.css", "lbscene-executor.js", "viewer.js", "lbscene-data.js"}
    (out / "notes.txt").write_text("what I saw in the viewer")            # the user keeps notes in it
    code, _, err = run_cli("export-web", booth, "--out", out)
    assert code == 2 and "Traceback" not in err
    assert (f"{out}: error LB611: --out: folder holds files lbscene did not write; it is left as it is "
            "(got notes.txt;") in err
    assert (out / "notes.txt").read_text() == "what I saw in the viewer"
    (out / "notes.txt").unlink()
    css = out / "viewer.css"
    css.write_text(css.read_text() + "body { background: black }\n")     # a hand edit
    code, _, err = run_cli("export-web", booth, "--out", out)
    assert code == 2
    assert (f"{css}: error LB611: --out: this file was changed since lbscene wrote it; the output folder is "
            "left as it is") in err
    assert css.read_text().endswith("body { background: black }\n")


def test_a_users_web_folder_with_an_index_html_is_kept(run_cli, tmp_path):
    out = tmp_path / "site"
    out.mkdir()
    (out / "index.html").write_text("<html>my site</html>")
    (out / "lbscene-data.js").write_text("// my notes on the data\n")
    code, _, err = run_cli("export-web", CONFIG, "--out", out)
    assert code == 2
    assert f"error LB700: --out {out} exists and is not a web export" in err
    assert (out / "index.html").read_text() == "<html>my site</html>"
    assert (out / "lbscene-data.js").read_text() == "// my notes on the data\n"
