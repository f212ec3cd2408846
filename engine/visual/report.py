"""
The visual-test report: what the seed study reported, from the observers' results.

* mean grey-scale score (or ΔE estimate) per case, its standard deviation, and the
  visual difference ΔV (grades through ISO 105-A02, see :mod:`~lbscene.engine.visual.stats`);
* intra-observer repeatability (STRESS of each repeat against the observer's mean) and
  inter-observer repeatability (STRESS of each observer's mean against the panel mean);
* STRESS between the model's ΔE00 per case and the panel's mean ΔV;
* plots (matplotlib) embedded in one self-contained HTML file.
"""

from __future__ import annotations

import base64
import html
import io
import math
from pathlib import Path

import numpy as np

from lbscene.engine.files.diagnostics import LbsceneUserError

from .stats import inter_observer_stress, intra_observer_stress, stress, visual_differences

__all__ = ["analyse", "read_model_delta_e", "read_model_texture", "render_html", "TEXTURE_METRIC"]

#: The model metric set beside each texture attribute's scores (and ranked against them).
TEXTURE_METRIC = {"sparkle": "glint_contrast", "graininess": "grain_contrast_percent"}


def _f(x):
    return None if x is None or (isinstance(x, float) and math.isnan(x)) else round(float(x), 4)


def _case_rows(path: Path, need: tuple[str, ...]):
    """``(shown, [(line, {column: text}), …])`` of a model CSV: read bounded
    (:data:`~lbscene.engine.visual.protocol.MAX_RESULTS_BYTES`), the ``need`` columns present and
    every row as long as the header (``LB710`` located otherwise); blank rows skipped."""
    from lbscene.engine.files.load import display_path
    from lbscene.engine.files.yamlio import csv_rows, read_text_bounded

    from .protocol import MAX_RESULTS_BYTES

    shown = display_path(Path(path))
    table = csv_rows(read_text_bounded(Path(path), shown, MAX_RESULTS_BYTES), shown)
    header = [h.strip() for h in table[0][1]] if table else []
    if any(c not in header for c in need):
        raise LbsceneUserError.single("LB710", "missing column(s)", shown, 1, 1,
                                      expected=f"a CSV with columns {', '.join(need)}")
    rows = []
    for line, row in table[1:]:
        if not any(c.strip() for c in row):
            continue
        if len(row) != len(header):
            raise LbsceneUserError.single("LB710", f"row has {len(row)} fields, header has {len(header)}",
                                          shown, line, 1)
        rows.append((line, dict(zip(header, row))))
    return shown, rows


def read_model_delta_e(path: Path, session) -> dict:
    """``lighting,geometry,sample,delta_e00`` rows → {case: ΔE00}; every case of the session needed.

    Read bounded (:data:`~lbscene.engine.visual.protocol.MAX_RESULTS_BYTES`); a ΔE00 that is not a
    finite number ≥ 0 is a located ``LB710``.
    """
    shown, rows = _case_rows(path, ("lighting", "geometry", "sample", "delta_e00"))
    out = {}
    for line, d in rows:
        try:
            de = float(d["delta_e00"])
        except ValueError:
            de = math.nan
        if not math.isfinite(de) or de < 0:
            raise LbsceneUserError.single("LB710", "delta_e00 must be a finite number ≥ 0", shown, line, 1,
                                          value=repr(d["delta_e00"][:40]), expected="a ΔE00 ≥ 0")
        out[(d["lighting"], d["geometry"], d["sample"])] = de
    missing = [c for c in session.cases if len(c) == 3 and c not in out]
    if missing:
        raise LbsceneUserError.single("LB711", f"no model ΔE00 for case {' / '.join(missing[0])}", shown,
                                      expected="one row per case of the session")
    return out


def read_model_texture(path: Path, session) -> dict:
    """``model-texture.csv`` (the web export's; columns ``lighting,geometry,sample`` and
    :data:`lbscene.engine.coatings.visual.TEXTURE_COLUMNS`) → {(lighting, geometry, sample):
    metrics}; every texture case of the session needs a row."""
    from lbscene.engine.coatings.visual import TEXTURE_COLUMNS

    shown, rows = _case_rows(path, ("lighting", "geometry", "sample") + TEXTURE_COLUMNS)
    out = {}
    for line, d in rows:
        try:
            values = {c: float(d[c]) for c in TEXTURE_COLUMNS}
        except ValueError:
            values = {}
        if len(values) != len(TEXTURE_COLUMNS) or not all(math.isfinite(v) for v in values.values()):
            raise LbsceneUserError.single("LB710", "texture metrics must be finite numbers", shown, line, 1)
        out[(d["lighting"], d["geometry"], d["sample"])] = values
    missing = [c for c in session.cases if len(c) == 4 and c[:3] not in out]
    if missing:
        raise LbsceneUserError.single("LB711", f"no model texture metrics for case {' / '.join(missing[0])}",
                                      shown, expected="one row per lighting, geometry and sample of the "
                                                      "session's texture cases (an effect coating with flakes)")
    return out


def analyse(rows: list[dict], session, model_delta_e: dict | None = None,
            model_texture: dict | None = None) -> dict:
    """Statistics of a session's results (JSON-ready).  Colour cases are set against the model's
    ΔE00 (STRESS); sparkle and graininess cases beside the model's texture metrics
    (:mod:`lbscene.engine.coatings.visual`), with the rank correlation of the panel's mean ΔV and
    the attribute's metric (:data:`TEXTURE_METRIC`) over the cases."""
    from .protocol import case_attribute

    rtype = session.model.response.type
    dv = visual_differences([r["score"] for r in rows], rtype)
    for r, v in zip(rows, dv):
        r["delta_v"] = float(v)
    cases = []
    for case in session.cases:
        mine = [r for r in rows if r["case"] == case]
        if not mine:
            continue
        sc = np.array([r["score"] for r in mine])
        rt = np.array([r["response_time_ms"] for r in mine])
        attr = case_attribute(case)
        colour = attr == "colour"
        cases.append({"lighting": case[0], "geometry": case[1], "sample": case[2], "attribute": attr,
                      "n": len(mine),
                      "mean_score": _f(sc.mean()), "sd_score": _f(sc.std(ddof=1) if len(sc) > 1 else 0.0),
                      "mean_delta_v": _f(np.mean([r["delta_v"] for r in mine])),
                      "median_response_time_ms": _f(np.nanmedian(rt)) if np.isfinite(rt).any() else None,
                      "model_delta_e00": None if model_delta_e is None or not colour else _f(model_delta_e[case]),
                      "model_texture": (None if model_texture is None or colour
                                        else model_texture.get(case[:3]))})
    intra = intra_observer_stress(rows)
    inter = inter_observer_stress(rows)
    finite = [v for v in intra.values() if not math.isnan(v)]
    summary = {"intra_observer_stress_mean": _f(np.mean(finite)) if finite else None,
               "inter_observer_stress_mean": _f(np.mean([v for v in inter.values() if not math.isnan(v)]))
               if any(not math.isnan(v) for v in inter.values()) else None,
               "stress_vs_model": None, "cases_seen": len(cases), "cases_in_session": len(session.cases)}
    colour_cases = [c for c in cases if c["attribute"] == "colour"]
    if model_delta_e is not None and len(colour_cases) >= 2:
        summary["stress_vs_model"] = _f(stress([c["model_delta_e00"] for c in colour_cases],
                                               [c["mean_delta_v"] for c in colour_cases]))
    summary["texture"] = {}
    for attr, metric in TEXTURE_METRIC.items():
        mine = [c for c in cases if c["attribute"] == attr]
        if not mine:
            continue
        entry = {"cases": len(mine), "metric": metric, "spearman_rho": None}
        pairs = [(c["model_texture"][metric], c["mean_delta_v"]) for c in mine if c["model_texture"]]
        if len(pairs) >= 3 and len({p[0] for p in pairs}) > 1 and len({p[1] for p in pairs}) > 1:
            from scipy.stats import spearmanr

            entry["spearman_rho"] = _f(spearmanr([p[0] for p in pairs], [p[1] for p in pairs])[0])
        summary["texture"][attr] = entry
    return {"session": session.model.name, "session_hash": session.hash, "response": rtype,
            "responses": len(rows), "observers": sorted({r["observer"] for r in rows}),
            "cases": cases, "intra_observer_stress": {k: _f(v) for k, v in intra.items()},
            "inter_observer_stress": {k: _f(v) for k, v in inter.items()}, "summary": summary}


def _png(fig) -> str:
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=96, bbox_inches="tight")
    return base64.b64encode(buf.getvalue()).decode("ascii")


def _plots(stats: dict) -> list[tuple[str, str]]:
    """The report's figures; sample and observer names are drawn as written (no mathtext)."""
    from lbscene.engine.files.textsafe import plain_text_plots

    with plain_text_plots():
        return _make_plots(stats)


def _make_plots(stats: dict) -> list[tuple[str, str]]:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out = []
    cases = stats["cases"]
    from lbscene.engine.files.textsafe import printable

    labels = [printable(f"{c['lighting']}/{c['geometry']}/{c['sample']}"
                        + ("" if c.get("attribute", "colour") == "colour" else f"/{c['attribute']}"),
                        newlines=False) for c in cases]
    fig, ax = plt.subplots(figsize=(max(6, 0.35 * len(cases) + 2), 3.6))
    ax.bar(range(len(cases)), [c["mean_score"] for c in cases], yerr=[c["sd_score"] for c in cases],
           color="#7a9cc6", capsize=2)
    ax.set_xticks(range(len(cases)))
    ax.set_xticklabels(labels, rotation=70, ha="right", fontsize=7)
    ax.set_ylabel("mean score (± sd)" if stats["response"] == "grey_scale" else "mean ΔE estimate (± sd)")
    ax.set_title("Mean score per case")
    out.append(("Mean score per case", _png(fig)))
    plt.close(fig)
    if stats["summary"]["stress_vs_model"] is not None:
        colour = [c for c in cases if c.get("attribute", "colour") == "colour"]
        e = np.array([c["model_delta_e00"] for c in colour])
        v = np.array([c["mean_delta_v"] for c in colour])
        f1 = float(e @ e) / float(e @ v) if float(e @ v) > 0 else 1.0
        fig, ax = plt.subplots(figsize=(4.6, 4.2))
        ax.scatter(e, v, s=18)
        lim = max(float(e.max()), float((f1 * v).max()), 1e-3) * 1.1
        x = np.linspace(0, lim, 2)
        ax.plot(x, x / f1, "k--", lw=1, label=f"ΔV = ΔE00 / F1 (F1 = {f1:.2f})")
        ax.set_xlabel("model ΔE00")
        ax.set_ylabel("visual difference ΔV (panel mean)")
        ax.set_title(f"STRESS = {stats['summary']['stress_vs_model']:.1f}")
        ax.legend(fontsize=8)
        out.append(("Visual difference against the model's ΔE00", _png(fig)))
        plt.close(fig)
    for attr, metric in TEXTURE_METRIC.items():
        mine = [c for c in cases if c.get("attribute") == attr and c.get("model_texture")]
        if len(mine) < 2:
            continue
        fig, ax = plt.subplots(figsize=(4.6, 4.2))
        ax.scatter([c["model_texture"][metric] for c in mine], [c["mean_delta_v"] for c in mine], s=18)
        ax.set_xlabel(f"model {metric.replace('_', ' ')}")
        ax.set_ylabel("visual difference ΔV (panel mean)")
        ax.set_title(f"{attr}: panel against the model's texture")
        out.append((f"{attr.capitalize()}: visual difference beside the model's {metric}", _png(fig)))
        plt.close(fig)
    obs = stats["observers"]
    fig, ax = plt.subplots(figsize=(max(5, 0.4 * len(obs) + 2), 3.2))
    x = np.arange(len(obs))
    intra = [stats["intra_observer_stress"].get(o) or 0.0 for o in obs]
    inter = [stats["inter_observer_stress"].get(o) or 0.0 for o in obs]
    ax.bar(x - 0.2, intra, 0.4, label="intra-observer")
    ax.bar(x + 0.2, inter, 0.4, label="inter-observer")
    ax.set_xticks(x)
    ax.set_xticklabels(obs, rotation=60, ha="right", fontsize=8)
    ax.set_ylabel("STRESS")
    ax.legend(fontsize=8)
    ax.set_title("Observer repeatability")
    out.append(("Observer repeatability (STRESS)", _png(fig)))
    plt.close(fig)
    return out


def render_html(stats: dict, session) -> str:
    """One self-contained HTML page (plots as data: URIs)."""
    from lbscene.engine.files.textsafe import printable

    def e(x) -> str:
        return html.escape(printable(x))

    s = stats["summary"]

    def num(v, fmt="{:.2f}"):
        return "—" if v is None else fmt.format(v)

    def tex(c):
        t = c.get("model_texture")
        if not t:
            return "<td>—</td><td>—</td><td>—</td>"
        return (f"<td>{num(t['glints_per_cm2'], '{:.0f}')}</td><td>{num(t['glint_contrast'], '{:.2f}')}</td>"
                f"<td>{num(t['grain_contrast_percent'], '{:.1f}')}</td>")

    rows = "".join(
        f"<tr><td>{e(c['lighting'])}</td><td>{e(c['geometry'])}</td><td>{e(c['sample'])}</td>"
        f"<td>{e(c.get('attribute', 'colour'))}</td><td>{c['n']}</td>"
        f"<td>{num(c['mean_score'])}</td><td>{num(c['sd_score'])}</td><td>{num(c['mean_delta_v'])}</td>"
        f"<td>{num(c['model_delta_e00'])}</td>{tex(c)}<td>{num(c['median_response_time_ms'], '{:.0f}')}</td></tr>"
        for c in stats["cases"])
    tex_rows = "".join(
        f"<tr><td>{e(a)}</td><td>{t['cases']}</td><td>{e(t['metric'])}</td><td>{num(t['spearman_rho'])}</td></tr>"
        for a, t in s.get("texture", {}).items())
    tex_table = ("<h2>Texture attributes</h2><p>Sparkle and graininess cases beside the model's metrics "
                 "(lbscene.engine.coatings.visual): glints per cm² and one glint's luminance over the coating's "
                 "mean (sparkle), the diffuse part's relative standard deviation per cell (graininess); "
                 "Spearman's ρ between the panel's mean ΔV and the attribute's metric over its cases.</p>"
                 "<table><tr><th>attribute</th><th>cases</th><th>model metric</th><th>Spearman ρ</th></tr>"
                 f"{tex_rows}</table>") if tex_rows else ""
    obs_rows = "".join(
        f"<tr><td>{e(o)}</td><td>{num(stats['intra_observer_stress'].get(o), '{:.1f}')}</td>"
        f"<td>{num(stats['inter_observer_stress'].get(o), '{:.1f}')}</td></tr>" for o in stats["observers"])
    plots = "".join(f"<figure><img alt='{e(t)}' src='data:image/png;base64,{p}'><figcaption>{e(t)}"
                    f"</figcaption></figure>" for t, p in _plots(stats))
    scale = session.model.response
    scale_txt = (f"grey scale {scale.min:g}–{scale.max:g} in steps of {scale.step:g} (5: no visible difference; "
                 "ΔV from the grades by ISO 105-A02)" if scale.type == "grey_scale" else "estimated ΔE (ΔV = estimate)")
    return f"""<!doctype html>
<html lang="en"><head><meta charset="utf-8"><meta name="viewport" content="width=device-width, initial-scale=1">
<title>lbscene visual report: {e(stats['session'])}</title>
<style>body{{font:14px/1.45 system-ui,sans-serif;margin:16px;max-width:1100px}}
table{{border-collapse:collapse;display:block;max-width:100%;overflow-x:auto}}
td,th{{border:1px solid #ccc;padding:3px 8px;text-align:right}}td:nth-child(-n+4){{text-align:left}}
figure{{display:inline-block;margin:8px 0;max-width:100%}}img{{max-width:100%;height:auto}}</style></head><body>
<h1>Visual test: {e(stats['session'])}</h1>
<p>{stats['responses']} responses from {len(stats['observers'])} observers; {s['cases_seen']} of
{s['cases_in_session']} cases; response: {e(scale_txt)}. Session hash {e(stats['session_hash'])}.</p>
<h2>Summary</h2>
<table><tr><th>intra-observer STRESS (mean)</th><th>inter-observer STRESS (mean)</th><th>STRESS vs model ΔE00</th></tr>
<tr><td>{num(s['intra_observer_stress_mean'], '{:.1f}')}</td><td>{num(s['inter_observer_stress_mean'], '{:.1f}')}</td>
<td>{num(s['stress_vs_model'], '{:.1f}')}</td></tr></table>
<p>STRESS: 0 = agreement up to a scale factor, 100 = none (García et al., JOSA A 24, 2007).</p>
{plots}
{tex_table}
<h2>Cases</h2>
<table><tr><th>lighting</th><th>geometry</th><th>sample</th><th>attribute</th><th>n</th><th>mean score</th><th>sd</th>
<th>ΔV</th><th>model ΔE00</th><th>model glints/cm²</th><th>model glint contrast</th><th>model grain %</th>
<th>median time (ms)</th></tr>{rows}</table>
<h2>Observers</h2>
<table><tr><th>observer</th><th>intra-observer STRESS</th><th>inter-observer STRESS</th></tr>{obs_rows}</table>
</body></html>
"""
