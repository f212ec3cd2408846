"""
The compare report: one self-contained HTML file (plots embedded as PNG data URIs).

Sections: summary and verdict, measured / predicted / residual maps of the
floor readings, other readings, fitted parameters, suspects, the YAML snippet,
planned points, white-tile spectrum with its residual, and the history plot.
Written atomically (temp file + ``os.replace``).
"""

from __future__ import annotations

import base64
import html
import io
from pathlib import Path

import numpy as np

from lbscene.engine.files.outputs import write_output

__all__ = ["render_report", "write_report"]


def _png(fig) -> str:
    buf = io.BytesIO()
    fig.savefig(buf, format="png", bbox_inches="tight")
    import matplotlib.pyplot as plt

    plt.close(fig)
    return "data:image/png;base64," + base64.b64encode(buf.getvalue()).decode("ascii")


def _maps(res):
    import matplotlib.pyplot as plt

    ill = res.meas.illuminance
    up = ill.horizontal_up & (np.abs(ill.points_mm[:, 2] - np.median(ill.points_mm[ill.horizontal_up, 2])) < 1)
    if up.sum() < 3:
        return None
    P = ill.points_mm[up]
    meas = ill.lux[up]
    pred = res.fit.lux_pred[up]
    resid = res.fit.residual_percent[up]
    it = res.meas.ir.interior
    fig, axes = plt.subplots(1, 3, figsize=(13, 4.2), dpi=100)
    vmin, vmax = float(min(meas.min(), pred.min())), float(max(meas.max(), pred.max()))
    lim = float(max(np.abs(resid).max(), 1e-6))
    size = 8000.0 / max(len(P), 1) ** 0.9
    for ax, vals, title, cmap, (lo, hi) in (
            (axes[0], meas, "measured (lx)", "viridis", (vmin, vmax)),
            (axes[1], pred, "predicted (lx)", "viridis", (vmin, vmax)),
            (axes[2], resid, "residual: (model − measured)/measured (%)", "RdBu_r", (-lim, lim))):
        sc = ax.scatter(P[:, 0], P[:, 1], c=vals, cmap=cmap, vmin=lo, vmax=hi, s=size, marker="s",
                        edgecolors="none")
        fig.colorbar(sc, ax=ax, shrink=0.85)
        ax.add_patch(plt.Rectangle((-it.width_mm / 2, -it.depth_mm / 2), it.width_mm, it.depth_mm,
                                   fill=False, color="0.4", lw=1))
        ax.set_aspect("equal")
        ax.set_xlim(-it.width_mm / 2 - 20, it.width_mm / 2 + 20)
        ax.set_ylim(-it.depth_mm / 2 - 20, it.depth_mm / 2 + 20)
        ax.set_xlabel("x (mm) → right")
        ax.set_ylabel("y (mm) → rear wall")
        ax.set_title(title, fontsize=10)
    fig.tight_layout()
    return _png(fig)


def _spectrum(res):
    import matplotlib.pyplot as plt

    f = res.fit
    tile = res.meas.tile
    if tile is None or f.tile_1nm_pred is None:
        return None
    wl = np.arange(360.0, 831.0)
    cov = tile.covered
    fig, (a1, a2) = plt.subplots(2, 1, figsize=(8, 5.2), dpi=100, sharex=True,
                                 gridspec_kw={"height_ratios": [2, 1]})
    a1.plot(wl[cov], tile.radiance_1nm[cov], color="k", lw=1.2, label="measured")
    a1.plot(wl[cov], f.tile_1nm_pred[cov], color="#d0582a", lw=1.2, label="model")
    a1.set_ylabel("radiance (W·sr⁻¹·m⁻²·nm⁻¹)")
    a1.legend(fontsize=8)
    a1.set_title("white tile", fontsize=10)
    c = f.tile_centres_nm if f.tile_centres_nm is not None else res.meas.ir.grid.centres_nm
    r = f.spectral_residual_percent
    a2.bar(c, np.nan_to_num(r), width=(c[1] - c[0] if len(c) > 1 else 20.0) * 0.8, color="#1f5fa8")
    a2.axhline(0, color="0.3", lw=0.8)
    a2.set_ylabel("band residual (%)")
    a2.set_xlabel("wavelength (nm)")
    fig.tight_layout()
    return _png(fig)


def _history(res):
    from lbscene.engine.files.diagnostics import LbsceneUserError
    from .history import plot_history, read_history

    try:
        entries = read_history(res.meas.history_path)
    except LbsceneUserError:      # a history that cannot be read has no plot; `lbscene history` says why
        return None
    if not entries:
        return None
    return _png(plot_history(entries, title=f"history of {res.meas.path.name}"))


def _esc(x) -> str:
    """Text for HTML: markup escaped, control characters shown as escapes."""
    from lbscene.engine.files.textsafe import printable

    return html.escape(printable(x))


def _table(headers, rows) -> str:
    h = "".join(f"<th>{_esc(x)}</th>" for x in headers)
    body = "".join("<tr>" + "".join(f"<td>{_esc(c)}</td>" for c in r) + "</tr>" for r in rows)
    return f"<table><thead><tr>{h}</tr></thead><tbody>{body}</tbody></table>"


def _f(x, nd=3):
    if x is None:
        return "—"
    try:
        if not np.isfinite(x):
            return "—"
    except TypeError:
        return str(x)
    return f"{x:.{nd}g}" if abs(x) >= 1e4 or (abs(x) < 1e-2 and x != 0) else f"{x:.{nd}f}"


def render_report(res) -> str:
    """The report as an HTML string (its plots draw user text as written: no mathtext)."""
    from lbscene.engine.files.textsafe import plain_text_plots

    with plain_text_plots():
        return _render_report(res)


def _render_report(res) -> str:
    j = res.to_json()
    d = res.diagnosis
    e = _esc

    parts = [f"<h1>{e(res.meas.name)}</h1>",
             f"<p class=meta>measurements <code>{e(str(res.meas.path))}</code> · booth "
             f"<code>{e(str(res.meas.booth_file))}</code> (IR {e(res.booth_hash[:12])}) · lighting "
             f"<b>{e(res.meas.lighting)}</b> · effects: {e(', '.join(sorted(res.fit.effects)) or 'none')}</p>"]
    verdict = res.verdict
    kind = getattr(verdict, "kind", "none")
    cls = "ok" if kind == "none" else ("warn" if kind in ("ambiguous", "unstable") else "bad")
    parts.append(f"<div class='verdict {cls}'>verdict: <b>{e(verdict)}</b>"
                 + (f" <small>({e(res.outlier_note)})</small>" if res.outlier_note else "") + "</div>")
    c = d.confidence if d is not None else None
    if c is not None:
        parts.append(_table(["ΔBIC over the booth as is", "ΔBIC over the next explanation",
                             "same verdict under resampled noise"],
                            [[_f(c.delta_bic_vs_base), _f(c.delta_bic_vs_next),
                              "—" if c.recurrence is None else f"{100 * c.recurrence:.0f} % of {c.samples}"]]))
    if res.outliers:
        parts.append("<h2>Outlying readings</h2><p>Far from the model and from their neighbours.</p>" + _table(
            ["file:line", "x mm", "y mm", "z mm", "measured lx", "model lx", "off by %"],
            [[f"{o['file']}:{o['line']}", o["x_mm"], o["y_mm"], o["z_mm"], _f(o["measured_lx"]),
              _f(o["model_lx"]), _f(o["deviation_percent"])] for o in res.outliers]))
    parts.append(_table(["RMSE %", "mean |r| %", "max %", "noise % (used)", "noise % (estimate)",
                         "χ²/dof", "points", "fitted"],
                        [[_f(j["rmse_percent"]), _f(j["mean_abs_percent"]), _f(j["max_percent"]),
                          _f(j["noise_percent_used"]), _f(j["noise_percent_estimate"]),
                          _f(j["chi2_per_dof"]), j["n_points"], "yes" if j["fitted"] else "no"]]))
    if d is not None and d.explanation:
        parts.append("<ul>" + "".join(f"<li>{e(x)}</li>" for x in d.explanation) + "</ul>")
    if d is not None and d.snippet:
        parts.append("<h2>Add to the booth file</h2><pre>" + e(d.snippet) + "</pre>")
    if res.meas.illuminance is not None:
        m = _maps(res)
        if m:
            parts.append("<h2>Floor readings</h2>" + f"<img src='{m}' alt='maps'>")
        other = [r for r in j["residuals"] if not (r["orientation"] == "up")]
        if other:
            parts.append("<h3>Other readings</h3>" + _table(
                ["x mm", "y mm", "z mm", "orientation", "measured lx", "model lx", "residual %"],
                [[r["x_mm"], r["y_mm"], r["z_mm"], r["orientation"], _f(r["measured_lx"]),
                  _f(r["predicted_lx"]), _f(r["residual_percent"])] for r in other]))
    if j["parameters"]:
        parts.append("<h2>Fitted parameters</h2>" + _table(
            ["parameter", "value", "std. error", "bounds"],
            [[p["target"], _f(p["value"], 5), _f(p["stderr"], 3), f"{p['bounds'][0]:g} … {p['bounds'][1]:g}"
              + (" (at bound)" if p["at_bound"] else "")] for p in j["parameters"]]))
    if res.fit.warnings:
        parts.append("<ul class=warn>" + "".join(f"<li>{e(w)}</li>" for w in res.fit.warnings) + "</ul>")
    if d is not None:
        parts.append("<h2>Suspects</h2>" + _table(
            ["effect", "RMSE after %", "score (ΔBIC)", "extra params", "explains to noise",
             "structure (Moran's I)", "spectral RMSE after %", "χ² gain: readings / spectrum shape",
             "fitted"],
            [[s.effect + "".join(f" ({i})" for i in s.items if i.startswith("hypothesis:")),
              _f(s.rmse_percent_after), _f(s.score, 4), s.n_params,
              "yes" if s.explains else "no", _f(s.structure_after), _f(s.spectral_rmse_after),
              f"{s.channel_gain[0]:.0f} / {s.channel_gain[1]:.0f}"
              + (f" — not eligible: {s.not_eligible}" if s.not_eligible else ""),
              ", ".join(f"{k}={v:.4g}" for k, v in s.params.items())] for s in d.suspects]))
        if d.skipped:
            parts.append("<p class=meta>not tested: " + e(d.not_tested_line()) + "</p>")
        for prefix, names in d.held_lines():
            parts.append("<p class=meta>" + prefix + e(names) + "</p>")
    if res.plan is not None and res.plan.points:
        names = res.plan.candidates
        parts.append("<h2>Measure next</h2><p>Readings where the candidates disagree most "
                     f"(noise {res.plan.noise_percent:.2g} %):</p>" + _table(
                         ["x mm", "y mm", "z mm", "orientation", "kind", *[f"{n} lx" for n in names],
                          "spread %"],
                         [[f"{p.position_mm[0]:g}", f"{p.position_mm[1]:g}", f"{p.position_mm[2]:g}",
                           p.orientation(), p.kind, *[_f(p.predicted_lx[n], 4) for n in names],
                           _f(p.spread_percent)] for p in res.plan.points]))
        parts.append("<pre>" + e(res.plan.csv_template()) + "</pre>")
    sp = _spectrum(res)
    if sp:
        parts.append("<h2>White-tile spectrum</h2>" + f"<img src='{sp}' alt='spectrum'>")
    hp = _history(res)
    if hp:
        parts.append("<h2>History</h2>" + f"<img src='{hp}' alt='history'>")
    if j["residuals"]:
        parts.append("<h2>Every reading</h2>" + _table(
            ["file:line", "x mm", "y mm", "z mm", "orientation", "measured lx", "model lx", "residual %"],
            [[f"{r['file']}:{r['line']}", r["x_mm"], r["y_mm"], r["z_mm"], r["orientation"],
              _f(r["measured_lx"]), _f(r["predicted_lx"]), _f(r["residual_percent"])] for r in j["residuals"]]))
    import datetime

    from lbscene._version import __version__

    stamp = datetime.datetime.now(datetime.timezone.utc).astimezone().isoformat(timespec="seconds")
    parts.append(f"<p class=meta>lbscene {e(__version__)} · {e(stamp)} · measurements "
                 f"<code>{e(str(res.meas.path))}</code></p>")
    css = ("body{font-family:system-ui,sans-serif;max-width:1200px;margin:2em auto;color:#222}"
           "table{border-collapse:collapse;margin:.6em 0}td,th{border:1px solid #ccc;padding:3px 8px;"
           "font-size:13px;text-align:right}th{background:#f3f3f3}td:first-child{text-align:left}"
           ".verdict{padding:.6em 1em;margin:1em 0;border-radius:4px;font-size:18px}.ok{background:#e3f4e3}"
           ".warn{background:#fff4d6}.bad{background:#fde4e1}.meta{color:#666;font-size:13px}"
           "pre{background:#f6f6f6;padding:.6em;border:1px solid #ddd}img{max-width:100%}")
    return ("<!DOCTYPE html><html><head><meta charset='utf-8'>"
            f"<meta name='generator' content='lbscene {e(__version__)}'><title>lbscene compare: "
            f"{e(res.meas.name)}</title><style>{css}</style></head><body>" + "\n".join(parts)
            + "</body></html>\n")


def write_report(res, out: Path) -> Path:
    """Render and write the report atomically."""
    import matplotlib

    matplotlib.use("Agg")
    text = render_report(res)
    out = Path(out)
    write_output(out, text, option="--report")
    return out
