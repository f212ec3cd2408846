"""The visual test for effect coatings: sessions judge colour, sparkle and graininess; the web
export writes the model's texture metrics per case; ``visual-report`` sets them beside the
panel's scores.  The model's glint density is checked against an independent quadrature."""

from __future__ import annotations

import csv
import io
import json
import shutil
from pathlib import Path

import numpy as np
import pytest

REPO = Path(__file__).resolve().parents[2]
TUBE = REPO / "tests" / "runtimes" / "data" / "tube-booth"
EXAMPLES = REPO / "examples" / "render"


@pytest.fixture(scope="module")
def session_dir(tmp_path_factory):
    d = tmp_path_factory.mktemp("coat-session")
    for name in ("sample-coating-coarse-silver.yaml", "sample-coating-blue-pearl.yaml"):
        shutil.copyfile(EXAMPLES / name, d / name)
    (d / "tube-coating.yaml").write_text(
        "version: 1\nkind: render_config\n"
        f"booth: {TUBE}\nlighting: D65\ngeometry: 45as15\nsample: sample-coating-coarse-silver.yaml\n"
        "display: builtin:srgb\ndiffuse: analytic\noutput: {png: out/c.png, width_px: 96, height_px: 72}\n")
    (d / "session.yaml").write_text(
        "version: 1\nkind: visual_session\nname: coat-test\nrender_config: tube-coating.yaml\n"
        "observers: [{id: O1}, {id: O2}]\n"
        "samples: [sample-coating-coarse-silver.yaml, sample-coating-blue-pearl.yaml]\n"
        "geometries: [45as-15, 45as15, 45as45]\nlightings: [D65]\nrepeats: 2\norder: {seed: 3}\n"
        "attributes: [colour, sparkle, graininess]\n")
    return d


def test_session_has_a_case_per_attribute(session_dir):
    from lbscene.engine.visual.protocol import case_attribute, load_session

    ses = load_session(session_dir / "session.yaml")
    assert len(ses.cases) == 1 * 3 * 2 * 3
    assert {case_attribute(c) for c in ses.cases} == {"colour", "sparkle", "graininess"}
    assert ("D65", "45as15", "Coarse silver metallic (synthetic)") in ses.cases            # colour: as before
    assert ("D65", "45as15", "Coarse silver metallic (synthetic)", "sparkle") in ses.cases
    mine = [t for t in ses.trials if t["observer"] == "O1" and t["repeat"] == 1]
    assert sorted((t["geometry"], t["sample"], t["attribute"]) for t in mine) == sorted(
        (c[1], c[2], case_attribute(c)) for c in ses.cases)


@pytest.fixture(scope="module")
def exported(session_dir):
    from lbscene.cli import main

    out = session_dir / "viewer"
    assert main(["export-web", str(session_dir / "tube-coating.yaml"), "--session", str(session_dir / "session.yaml"),
                 "--out", str(out), "--size", "96x72"]) == 0
    return out


def _texture_rows(exported):
    return list(csv.DictReader(io.StringIO((exported / "model-texture.csv").read_text())))


def test_export_writes_texture_metrics(exported):
    rows = _texture_rows(exported)
    assert len(rows) == 4 * 2                    # every view of the booth, every sample
    for r in rows:
        assert float(r["glints_per_cm2"]) > 0 and float(r["glint_contrast"]) > 0
        assert float(r["G"]) > 0 and float(r["grain_contrast_percent"]) > 0
    by = {(r["geometry"], r["sample"]): r for r in rows}
    s = "Coarse silver metallic (synthetic)"
    # near the specular direction more flakes glint than at 45as45
    assert float(by[("45as15", s)]["glints_per_cm2"]) > float(by[("45as45", s)]["glints_per_cm2"])


def test_glint_density_against_a_quadrature(session_dir):
    """The model's glints per cm² (64 points along the tube) against an independent quadrature of
    the closed-form glint probability over the tube's lateral surface (every patch a small lamp)."""
    from lbscene.engine.scene.compile import compile_booth
    from lbscene.engine.files.load import load_document
    from lbscene.runtimes.colour_bridge import srgb_display
    from lbscene.runtimes.graph import build_render_graph
    from lbscene.runtimes.scene import SampleSpec, SceneBuilder
    from lbscene.schemas.sample import Sample
    from lbscene.engine.coatings.visual import case_texture_metrics

    ir = compile_booth(TUBE)
    g = build_render_graph(ir, "D65")
    sp = SampleSpec.from_document(load_document(session_dir / "sample-coating-coarse-silver.yaml", Sample))
    b = SceneBuilder(ir, g, sp, srgb_display())
    vi = b.view("45as15")
    vs = b._view_spec("45as15")
    eye = np.asarray(vs["camera"]["position_mm"], float)
    v = vi.values
    app = b.coating_appearance()
    m = case_texture_metrics(app, vi.textures["emitters"], int(v["view.emitter_count"]), vi.sample_centre_mm,
                             vi.sample_normal, eye, v["sample.u_axis"], np.asarray(v["view.xyz_weights"]).reshape(16, 3),
                             float(v["sample.flake_cell_mm"]), float(v["sample.grain_sigma"]),
                             float(vi.info["coating"]["visible_share"]))
    # quadrature over the cylinder (sample frame: u axis, its normal)
    row = vi.textures["emitters"][0]
    c, ax, hl, r = row[0, :3], row[1, :3], row[1, 3], row[2, 3]
    P = vi.sample_centre_mm
    N = vi.sample_normal / np.linalg.norm(vi.sample_normal)
    u = np.asarray(v["sample.u_axis"], float)
    u = (u - N * (u @ N)) / np.linalg.norm(u - N * (u @ N))
    frame = np.stack([u, np.cross(N, u), N])
    na, nr = 1500, 120
    t = ((np.arange(na) + 0.5) / na - 0.5) * 2 * hl
    a = (np.arange(nr) + 0.5) / nr * 2 * np.pi
    b1 = np.cross(ax, [0.0, 0.0, 1.0])
    b1 /= np.linalg.norm(b1)
    b2 = np.cross(ax, b1)
    T, A = np.meshgrid(t, a, indexing="ij")
    ns = np.cos(A)[..., None] * b1 + np.sin(A)[..., None] * b2
    pts = c + T[..., None] * ax + r * ns
    d = pts - P
    dist = np.linalg.norm(d, axis=-1)
    ldir = d / dist[..., None]
    omega = (2 * hl / na) * (2 * np.pi * r / nr) * np.clip(-(ldir * ns).sum(-1), 0, None) / dist ** 2
    V = (eye - P) / np.linalg.norm(eye - P)
    l_loc = (ldir @ frame.T).reshape(-1, 3)
    p = app.flakes.glint_probability(l_loc, np.broadcast_to(frame @ V, l_loc.shape), omega.reshape(-1))
    expected = app.flakes.density_per_mm2 * 100.0 * float(p[l_loc[:, 2] > 0].sum())
    assert m["glints_per_cm2"] == pytest.approx(expected, rel=0.03)


def _results(session_dir, tmp_path):
    from lbscene.engine.visual.protocol import load_session

    ses = load_session(session_dir / "session.yaml")
    rng = np.random.default_rng(1)
    lines = ["session,observer,repeat,order,lighting,geometry,sample,display,score,response_time_ms,attribute"]
    for t in ses.trials:
        s = float(np.clip(np.round(rng.uniform(2.5, 5) * 2) / 2, 1, 5))
        lines.append(f"coat-test,{t['observer']},{t['repeat']},{t['order']},{t['lighting']},{t['geometry']},"
                     f"{t['sample']},sRGB,{s},1200,{t['attribute']}")
    f = tmp_path / "results.csv"
    f.write_text("\n".join(lines) + "\n")
    return f


def test_visual_report_sets_texture_beside_scores(session_dir, exported, tmp_path, run_cli):
    res = _results(session_dir, tmp_path)
    code, out, err = run_cli("visual-report", res, "--session", session_dir / "session.yaml",
                             "--model-de", exported / "model-delta-e00.csv",
                             "--model-texture", exported / "model-texture.csv", "--format", "json",
                             "--report", tmp_path / "report.html")
    assert code == 0, err
    st = json.loads(out)
    attrs = {c["attribute"] for c in st["cases"]}
    assert attrs == {"colour", "sparkle", "graininess"}
    for c in st["cases"]:
        if c["attribute"] == "colour":
            assert c["model_delta_e00"] is not None and c["model_texture"] is None
        else:
            assert c["model_delta_e00"] is None and c["model_texture"]["glints_per_cm2"] > 0
    tex = st["summary"]["texture"]
    assert tex["sparkle"]["cases"] == 6 and tex["sparkle"]["metric"] == "glint_contrast"
    assert tex["graininess"]["spearman_rho"] is not None
    html = (tmp_path / "report.html").read_text()
    assert "Texture attributes" in html and "model glints/cm²" in html


def test_texture_cases_need_texture_metrics(session_dir, exported, tmp_path, run_cli):
    res = _results(session_dir, tmp_path)
    bad = tmp_path / "tex.csv"
    rows = (exported / "model-texture.csv").read_text().splitlines()
    bad.write_text("\n".join(rows[:-1]) + "\n")
    code, out, err = run_cli("visual-report", res, "--session", session_dir / "session.yaml",
                             "--model-texture", bad)
    assert code == 2
    assert "error LB711: no model texture metrics for case D65 / " in err


def test_browser_runs_the_coating_shaders(exported, tmp_path):
    """The WebGL2 viewer (headless Chromium) runs the same shader files: its image of the coarse
    silver matches moderngl's (mean ΔE00 ≤ 1)."""
    from lbscene.runtimes.web.browser import find_chromium, image_delta_e00, screenshot

    if find_chromium() is None:
        pytest.skip("chromium is not installed (scripts/install-test-deps.sh installs it)")
    from PIL import Image

    from lbscene.runtimes.render import prepare_from_config

    size = (192, 144)
    shot = screenshot(exported, tmp_path / "shot.png", size_px=size, extra={"view": "45as45"})
    browser = np.asarray(Image.open(shot).convert("RGB"))
    job = prepare_from_config(exported.parent / "tube-coating.yaml")
    r = job.renderer()
    try:
        ref = r.render("45as45", size).rgba8[..., :3]
    finally:
        r.close()
    de = image_delta_e00(browser, ref)
    assert de.mean() <= 1.0, de.mean()
    assert browser.std() > 5
