"""
The conformance report: one self-contained HTML file (plots embedded as PNG data URIs, no
scripts, every user-supplied text escaped).

Per lighting: the verdict, the checks (requirement, figure, verdict; model and measurements
side by side), the colorimetry table, the illuminance map over the viewing area (with the
readings when measured), the relative spectrum at the sample with the standard's reference
illuminant, and the CIE 13.3 special indices R1–R14.
"""

from __future__ import annotations

import base64
import html
import io
from pathlib import Path

import numpy as np

__all__ = ["render_conformance_report", "write_conformance_report"]


def _png(fig) -> str:
    import matplotlib.pyplot as plt

    buf = io.BytesIO()
    fig.savefig(buf, format="png", bbox_inches="tight")
    plt.close(fig)
    return "data:image/png;base64," + base64.b64encode(buf.getvalue()).decode("ascii")


def _e(x) -> str:
    return html.escape(str(x))


def _f(x, nd=1) -> str:
    if x is None:
        return "—"
    if isinstance(x, (list, tuple)):
        return ", ".join(_f(v, nd) for v in x)
    try:
        x = float(x)
    except (TypeError, ValueError):
        return str(x)
    if not np.isfinite(x):
        return "—"
    if abs(x) < 0.1 and x != 0:
        return f"{x:.4f}"
    return f"{x:.{nd}f}"


def _table(headers, rows, classes=None) -> str:
    h = "".join(f"<th>{_e(x)}</th>" for x in headers)
    body = []
    for i, r in enumerate(rows):
        cls = f" class='{classes[i]}'" if classes and classes[i] else ""
        body.append(f"<tr{cls}>" + "".join(f"<td>{_e(c)}</td>" for c in r) + "</tr>")
    return f"<table><thead><tr>{h}</tr></thead><tbody>{''.join(body)}</tbody></table>"


def _map(res, lc) -> str | None:
    import matplotlib.pyplot as plt

    m = lc.model
    if m.grid_shape is None or m.grid_lx.size < 4:
        return None
    ny, nx = m.grid_shape
    X = m.grid_points_mm[:, 0].reshape(ny, nx)
    Y = m.grid_points_mm[:, 1].reshape(ny, nx)
    Z = m.grid_lx.reshape(ny, nx)
    meas = lc.measured if lc.measured is not None and lc.measured.grid_lx.size else None
    vmin = float(min(Z.min(), meas.grid_lx.min() if meas else np.inf))
    vmax = float(max(Z.max(), meas.grid_lx.max() if meas else -np.inf))
    ncols = 2 if meas else 1
    fig, axes = plt.subplots(1, ncols, figsize=(6.2 * ncols, 4.4), dpi=100, squeeze=False)
    ax = axes[0, 0]
    pc = ax.pcolormesh(X, Y, Z, shading="gouraud", cmap="viridis", vmin=vmin, vmax=vmax)
    cs = ax.contour(X, Y, Z / Z.mean(), levels=[0.75, 0.9, 1.0, 1.1], colors="w", linewidths=0.8)
    ax.clabel(cs, fmt="%.2f", fontsize=7)
    fig.colorbar(pc, ax=ax, shrink=0.85, label="lx")
    ax.set_title(f"model: illuminance over the viewing area\nuniformity (min/mean) {_f(m.uniformity, 3)}, "
                 "contours: E / mean", fontsize=9)
    if meas:
        ax2 = axes[0, 1]
        sc = ax2.scatter(meas.grid_points_mm[:, 0], meas.grid_points_mm[:, 1], c=meas.grid_lx, cmap="viridis",
                         vmin=vmin, vmax=vmax, s=60, marker="s", edgecolors="k", linewidths=0.3)
        fig.colorbar(sc, ax=ax2, shrink=0.85, label="lx")
        ax2.set_title(f"measured readings on the viewing area\nuniformity (min/mean) "
                      f"{_f(meas.uniformity, 3)}", fontsize=9)
    a = res.area
    for axx in axes[0]:
        axx.add_patch(plt.Rectangle((a.centre_mm[0] - a.size_mm[0] / 2, a.centre_mm[1] - a.size_mm[1] / 2),
                                    a.size_mm[0], a.size_mm[1], fill=False, color="0.4", lw=1))
        axx.set_aspect("equal")
        axx.set_xlabel("x (mm) → right")
        axx.set_ylabel("y (mm) → rear wall")
    fig.tight_layout()
    return _png(fig)


def _spectrum(lc, reference: str | None) -> str | None:
    import matplotlib.pyplot as plt

    srcs = [s for s in (lc.model, lc.measured) if s is not None and s.spectrum_1nm is not None]
    if not srcs:
        return None
    fig, ax = plt.subplots(figsize=(7.5, 3.4), dpi=100)
    V = (380, 780)
    for s, colr in zip(srcs, ("#d0582a", "k")):
        wl, v = s.wavelengths_nm, s.spectrum_1nm
        m = (wl >= 555) & (wl <= 565)
        norm = v[m].mean() if m.any() and v[m].mean() > 0 else max(v.max(), 1e-30)
        ax.plot(wl, v / norm, color=colr, lw=1.2, label=s.source)
    if reference:
        import colour

        sd = colour.SDS_ILLUMINANTS[reference]
        wl = sd.wavelengths
        v = sd.values / np.interp(560.0, wl, sd.values)
        keep = (wl >= 360) & (wl <= 830)
        ax.plot(wl[keep], v[keep], color="#1f5fa8", lw=1, ls="--", label=f"CIE {reference}")
    ax.set_xlim(360, 830)
    ax.axvspan(360, 400, color="0.92", zorder=0)
    ax.set_xlabel("wavelength (nm)")
    ax.set_ylabel("relative spectral irradiance (560 nm = 1)")
    ax.set_title(f"spectrum at the sample (visible {V[0]}–{V[1]} nm; grey: UV 360–400 nm)", fontsize=9)
    ax.legend(fontsize=8)
    fig.tight_layout()
    return _png(fig)


def _cri_bars(lc) -> str | None:
    import matplotlib.pyplot as plt

    srcs = [s for s in (lc.model, lc.measured) if s is not None and s.colorimetry is not None
            and s.colorimetry.cri_r is not None]
    if not srcs:
        return None
    fig, ax = plt.subplots(figsize=(7.5, 2.8), dpi=100)
    w = 0.8 / len(srcs)
    x = np.arange(1, 15)
    for k, (s, colr) in enumerate(zip(srcs, ("#d0582a", "0.3"))):
        ax.bar(x + (k - (len(srcs) - 1) / 2) * w, s.colorimetry.cri_r, width=w, color=colr, label=s.source)
    ax.axhline(80, color="#1f5fa8", lw=0.8, ls="--")
    ax.set_xticks(x, [f"R{i}" for i in x])
    ax.set_ylim(min(0.0, min(min(s.colorimetry.cri_r) for s in srcs) - 5), 105)
    ax.set_title("CIE 13.3 special colour rendering indices (dashed: 80)", fontsize=9)
    ax.legend(fontsize=8)
    fig.tight_layout()
    return _png(fig)


def _colorimetry_rows(lc) -> tuple[list[str], list[list]]:
    srcs = [s for s in (lc.model, lc.measured) if s is not None]
    head = ["quantity", *[s.source for s in srcs]]

    def col(s, f):
        return f(s) if s.colorimetry is not None else None

    spec = [
        ("illuminance at the sample (lx)", lambda s: _f(s.illuminance_at_sample_lx)),
        ("uniformity over the viewing area (min/mean)", lambda s: _f(s.uniformity, 3)),
        ("uniformity (min/max)", lambda s: _f(s.uniformity_min_to_max, 3)),
        ("x, y (CIE 1931 2°)", lambda s: _f(col(s, lambda s: s.colorimetry.xy), 4)),
        ("u', v' (2°)", lambda s: _f(col(s, lambda s: s.colorimetry.uv_prime), 4)),
        ("u'10, v'10 (10°)", lambda s: _f(col(s, lambda s: s.colorimetry.uv_prime_10deg), 4)),
        ("CCT (K)", lambda s: _f(col(s, lambda s: s.colorimetry.cct_K), 0)),
        ("Duv", lambda s: _f(col(s, lambda s: s.colorimetry.duv), 4)),
        ("CIE 13.3 Ra", lambda s: _f(col(s, lambda s: s.colorimetry.cri_ra))),
        ("CIE 224:2017 Rf", lambda s: _f(col(s, lambda s: s.colorimetry.cie2017_rf))),
        ("ANSI/IES TM-30-18 Rf", lambda s: _f(col(s, lambda s: s.colorimetry.tm30_rf))),
        ("ANSI/IES TM-30-18 Rg", lambda s: _f(col(s, lambda s: s.colorimetry.tm30_rg))),
        ("UV 360–400 / visible 400–700 nm", lambda s: _f(col(s, lambda s: s.colorimetry.uv_to_visible_ratio), 4)),
    ]
    return head, [[name, *[f(s) for s in srcs]] for name, f in spec]


def render_conformance_report(res) -> str:
    """The report of a :class:`~lbscene.engine.conformance.evaluate.ConformanceResult` as HTML."""
    import datetime

    from lbscene._version import __version__

    from .standards import STANDARD_TITLES

    parts = [f"<h1>Conformance: {_e(res.booth_name)}</h1>",
             f"<p class=meta>booth <code>{_e(res.booth_file)}</code> (IR {_e(res.ir_hash[:12])}) · effects: "
             f"{_e(', '.join(res.effects) or 'none')} · viewing area {_e(res.area.source)} "
             f"{res.area.size_mm[0]:g} × {res.area.size_mm[1]:g} mm at z = {res.area.centre_mm[2]:g} mm, "
             f"{res.grid_points[0]} × {res.grid_points[1]} points"
             + (f" · measurements <code>{_e(res.measurements)}</code> (lighting {_e(res.measured_lighting)})"
                if res.measurements else "") + "</p>"]
    summary = [[lc.name, STANDARD_TITLES.get(lc.standard, lc.standard), lc.verdict,
                _f(lc.model.illuminance_at_sample_lx), _f(lc.model.uniformity, 3),
                _f(lc.model.colorimetry.cct_K if lc.model.colorimetry else None, 0),
                _f(lc.model.colorimetry.cri_ra if lc.model.colorimetry else None)] for lc in res.lightings]
    parts.append("<h2>Summary</h2>" + _table(
        ["lighting", "standard", "verdict", "E sample lx", "uniformity", "CCT K", "Ra"], summary,
        [{"pass": "ok", "fail": "bad"}.get(lc.verdict, "") for lc in res.lightings]))
    for n in res.notes:
        parts.append(f"<p class=meta>{_e(n)}</p>")
    for lc in res.lightings:
        ref = "D50" if lc.standard.startswith("ISO_3664") else None
        cls = {"pass": "ok", "fail": "bad"}.get(lc.verdict, "na")
        parts.append(f"<h2 id='{_e(lc.name)}'>Lighting {_e(lc.name)}</h2>"
                     + (f"<p>{_e(lc.description)}</p>" if lc.description else "")
                     + f"<div class='verdict {cls}'>{_e(STANDARD_TITLES.get(lc.standard, lc.standard))}: "
                       f"<b>{_e(lc.verdict)}</b></div>")
        if lc.checks:
            parts.append(_table(["check", "source", "verdict", "figure", "requirement", "reference", "note"],
                                [[c.title, c.source, c.verdict.replace("_", " "),
                                  f"{_f(c.value, 3)} {c.unit}".strip() if c.value is not None else "—",
                                  c.requirement, c.reference, c.note] for c in lc.checks],
                                [{"pass": "ok", "fail": "bad"}.get(c.verdict, "na") for c in lc.checks]))
        head, rows = _colorimetry_rows(lc)
        parts.append("<h3>Colorimetry at the sample</h3>" + _table(head, rows))
        for s in (lc.model, lc.measured):
            if s is not None:
                for n in s.notes + (list(s.colorimetry.notes) if s.colorimetry else []):
                    parts.append(f"<p class=meta>{_e(s.source)}: {_e(n)}</p>")
        mp = _map(res, lc)
        if mp:
            parts.append("<h3>Illuminance over the viewing area</h3>" + f"<img src='{mp}' alt='uniformity map'>")
        sp = _spectrum(lc, ref)
        if sp:
            parts.append("<h3>Spectrum at the sample</h3>" + f"<img src='{sp}' alt='spectrum'>")
        cb = _cri_bars(lc)
        if cb:
            parts.append(f"<img src='{cb}' alt='special colour rendering indices'>")
    stamp = datetime.datetime.now(datetime.timezone.utc).astimezone().isoformat(timespec="seconds")
    parts.append(f"<p class=meta>lbscene {_e(__version__)} · {_e(stamp)} · colorimetry by colour-science "
                 "(CIE 13.3-1995, CIE 224:2017, ANSI/IES TM-30-18); requirements: ISO 3664:2009, CIE 51.2 "
                 "(not assessed: see the documentation's Booth conformance page)</p>")
    css = ("body{font-family:system-ui,sans-serif;max-width:1200px;margin:2em auto;color:#222}"
           "table{border-collapse:collapse;margin:.6em 0}td,th{border:1px solid #ccc;padding:3px 8px;"
           "font-size:13px;text-align:left}th{background:#f3f3f3}"
           ".verdict{padding:.5em 1em;margin:.8em 0;border-radius:4px;font-size:17px}"
           "tr.ok td,div.ok{background:#e3f4e3}tr.bad td,div.bad{background:#fde4e1}div.na{background:#eee}"
           ".meta{color:#666;font-size:13px}img{max-width:100%}")
    return ("<!DOCTYPE html><html><head><meta charset='utf-8'>"
            f"<meta name='generator' content='lbscene {_e(__version__)}'><title>lbscene conformance: "
            f"{_e(res.booth_name)}</title><style>{css}</style></head><body>" + "\n".join(parts)
            + "</body></html>\n")


def write_conformance_report(res, out: Path | str) -> Path:
    """Render the report and write it through the output policy (:func:`lbscene.engine.files.outputs.write_output`)."""
    import matplotlib

    matplotlib.use("Agg")
    from lbscene.engine.files.outputs import write_output

    out = Path(out)
    write_output(out, render_conformance_report(res), option="--report")
    return out
