"""``lbscene compare MEASUREMENTS [--booth FILE] [--fit/--no-fit] [--format text|json] [--report OUT.html]
[--json-out OUT.json]``"""

from __future__ import annotations

from pathlib import Path
from typing import List, Optional

import typer

from lbscene.commands.console import echo
from lbscene.commands.options import (
    Format,
    allow_path_option,
    booth_override_option,
    measurements_argument,
)
from lbscene.engine.files.textsafe import json_text


def diagnosis_progress(console, enabled: bool):
    """A rich progress bar over the diagnosis' candidate refits (context manager + callback)."""
    from rich.progress import BarColumn, TextColumn, TimeElapsedColumn

    from lbscene.commands.console import progress

    prog = progress(TextColumn("{task.description}"), BarColumn(), TextColumn("{task.completed}/{task.total}"),
                    TimeElapsedColumn(), console=console, transient=True, disable=not enabled)
    state = {}

    def cb(k, n, eid):
        if "task" not in state:
            state["task"] = prog.add_task("diagnosis", total=n)
        prog.update(state["task"], completed=k, description=f"diagnosis: refit with {eid}" if eid else
                    "diagnosis")

    return prog, cb


def print_text(res, console) -> None:
    from lbscene.commands.console import table

    from lbscene.commands.console import styled

    j = res.to_json()
    f = res.fit
    console.print(styled((res.meas.name, "bold"), f"  booth {res.meas.booth_file}  lighting {res.meas.lighting}"))
    console.print(f"effects: {', '.join(sorted(f.effects)) or 'none'}"
                  + (f"   known output: {', '.join(res.meas.known_output_groups)}"
                     if res.meas.known_output_groups else ""))
    n = j["n_points"]
    if n:
        console.print(f"illuminance ({n} readings{'' if f.fitted else ', not fitted'}): "
                      f"RMSE {j['rmse_percent']:.2f} %, mean |r| {j['mean_abs_percent']:.2f} %, "
                      f"max {j['max_percent']:.2f} %   noise {j['noise_percent_used']:.2g} % "
                      f"({res.noise.source}; data estimate "
                      f"{'—' if res.noise.estimate_percent is None else f'{res.noise.estimate_percent:.2g} %'})")
    if j["spectral"]:
        console.print(f"white-tile spectrum: RMSE {j['spectral']['rmse_percent']:.2f} % over the bands")
    if j["parameters"]:
        t = table(title="fitted parameters", title_justify="left")
        for c in ("parameter", "value", "std. error", "bounds"):
            t.add_column(c, justify="right" if c != "parameter" else "left")
        for p in j["parameters"]:
            t.add_row(p["target"], f"{p['value']:.5g}", "—" if p["stderr"] is None else f"{p['stderr']:.2g}",
                      f"{p['bounds'][0]:g} … {p['bounds'][1]:g}" + (" (at bound)" if p["at_bound"] else ""))
        console.print(t)
    for w in f.warnings:
        console.print(styled(("warning:", "yellow"), f" {w}"))
    if n:
        worst = sorted(j["residuals"], key=lambda r: -abs(r["residual_percent"]))[:5]
        t = table(title="largest residuals", title_justify="left")
        for c in ("x mm", "y mm", "z mm", "facing", "measured lx", "model lx", "residual %"):
            t.add_column(c, justify="right")
        for r in worst:
            t.add_row(f"{r['x_mm']:g}", f"{r['y_mm']:g}", f"{r['z_mm']:g}", r["orientation"],
                      f"{r['measured_lx']:.1f}", f"{r['predicted_lx']:.1f}", f"{r['residual_percent']:+.2f}")
        console.print(t)
    d = res.diagnosis
    if d is None:
        return
    if d.suspects:
        t = table(title="suspects (refit with each effect the booth does not enable)", title_justify="left")
        for c in ("effect", "RMSE after %", "score ΔBIC", "+params", "to noise", "χ² gain lx / spectrum",
                  "fitted"):
            t.add_column(c, justify="left" if c in ("effect", "fitted") else "right")
        for s in d.suspects:
            name = s.effect + "".join(f" ({i})" for i in s.items if i.startswith("hypothesis:"))
            t.add_row(name, f"{s.rmse_percent_after:.2f}", f"{s.score:.1f}", str(s.n_params),
                      "yes" if s.explains else "no",
                      f"{s.channel_gain[0]:.0f} / {s.channel_gain[1]:.0f}"
                      + (" not eligible" if s.not_eligible else ""),
                      ", ".join(f"{k}={v:.4g}" for k, v in s.params.items()))
        console.print(t)
        for s in d.suspects:
            if s.not_eligible:
                console.print(f"not eligible: {s.not_eligible}", style="dim")
    if d.skipped:
        console.print("not tested: " + d.not_tested_line(), style="dim")
    for prefix, names in d.held_lines():
        console.print(prefix + names, style="dim")
    if res.outliers:
        t = table(title="outlying readings (far from the model and from their neighbours)", title_justify="left")
        for c in ("file:line", "x mm", "y mm", "z mm", "measured lx", "model lx", "off by %"):
            t.add_column(c, justify="left" if c == "file:line" else "right")
        for o in res.outliers:
            t.add_row(f"{o['file']}:{o['line']}", f"{o['x_mm']:g}", f"{o['y_mm']:g}", f"{o['z_mm']:g}",
                      f"{o['measured_lx']:.1f}", f"{o['model_lx']:.1f}", f"{o['deviation_percent']:+.1f}")
        console.print(t)
    style = {"none": "green", "ambiguous": "yellow", "unstable": "yellow"}.get(d.verdict.kind, "red")
    console.print(styled("verdict: ", (str(d.verdict), f"bold {style}"),
                         f"  ({res.outlier_note})" if res.outlier_note else ""))
    c = d.confidence
    if c is not None:
        bits = []
        if c.delta_bic_vs_base is not None:
            bits.append(f"ΔBIC {c.delta_bic_vs_base:.1f} over the booth as is")
        if c.delta_bic_vs_next is not None and d.verdict.kind != "none":
            bits.append(f"{c.delta_bic_vs_next:.1f} over the next explanation")
        if c.recurrence is not None:
            same = (f"{d.verdict.point} in" if d.verdict.kind == "unstable" and d.verdict.point is not None
                    else "the same verdict in")
            bits.append(f"{same} {100 * c.recurrence:.0f} % of {c.samples} noise resamples")
        if bits:
            console.print("confidence: " + "; ".join(bits))
    for x in d.explanation:
        console.print(f"  {x}")
    if d.snippet:
        console.print("add to the booth file (sections it already has are merged: keys added, list "
                      "items updated by id; effects: replaced):")
        console.print(d.snippet, markup=False, highlight=False)
    if res.plan is not None and res.plan.points:
        t = table(title="measure next (where the candidates disagree most)", title_justify="left")
        for c in ("x mm", "y mm", "z mm", "facing", *[f"{c} lx" for c in res.plan.candidates], "spread %"):
            t.add_column(c, justify="right")
        for p in res.plan.points:
            t.add_row(f"{p.position_mm[0]:g}", f"{p.position_mm[1]:g}", f"{p.position_mm[2]:g}", p.orientation(),
                      *[f"{p.predicted_lx[c]:.1f}" for c in res.plan.candidates], f"{p.spread_percent:.1f}")
        console.print(t)
    if res.history_entry:
        console.print(f"history: step {res.history_entry['step']} ({res.history_entry['label']}) → "
                      f"{res.meas.history_path}", style="dim")


def register(app: typer.Typer) -> None:
    @app.command("compare")
    def compare(
        measurements: Path = measurements_argument(),
        booth: Optional[Path] = booth_override_option(),
        fit: bool = typer.Option(True, "--fit/--no-fit", help="Fit the free parameters (default) or "
                                 "compare the booth as declared."),
        format: Format = typer.Option(Format.text, "--format", help="text or json."),
        report: Optional[Path] = typer.Option(None, "--report", help="Write a self-contained HTML report."),
        json_out: Optional[Path] = typer.Option(None, "--json-out", help="Also write the JSON result to "
                                                "this file (whatever --format prints)."),
        diagnose: bool = typer.Option(True, "--diagnose/--no-diagnose",
                                      help="Refit with each missing effect and give a verdict."),
        history: bool = typer.Option(True, "--history/--no-history",
                                     help="Append this run to the history next to the measurements."),
        allow_path: Optional[List[Path]] = allow_path_option(),
        keep_outliers: bool = typer.Option(False, "--keep-outliers",
                                           help="Fit and diagnose with the readings flagged as outliers "
                                                "(default: without them; they are listed either way)."),
    ) -> None:
        """Compare a booth model with measurements: errors, fit, missing effect, plan, history."""

        from lbscene.engine.loop.compare import run_compare

        from lbscene.engine.files.outputs import check_outputs

        check_outputs([(report, "--report"), (json_out, "--json-out")], inputs=[measurements, booth])
        from lbscene.commands.console import err_console, out_console

        err = err_console()
        prog, cb = diagnosis_progress(err, format is not Format.json)
        with prog:
            res = run_compare(measurements, booth=booth, fit=fit, do_diagnose=diagnose, history=history,
                              allowed_dirs=tuple(allow_path or ()), progress=cb,
                              keep_outliers=keep_outliers)
        if report is not None:
            from lbscene.engine.loop.report import write_report

            write_report(res, report)
        if format is Format.json or json_out is not None:
            out = res.to_json()
            if report is not None:
                out["report"] = str(report)
            text = json_text(out, indent=2)
            if json_out is not None:
                from lbscene.engine.files.outputs import write_output

                write_output(json_out, text + "\n", option="--json-out")
        if format is Format.json:
            echo(text)
        else:
            print_text(res, out_console())
            if report is not None:
                echo(f"report: {report}")
