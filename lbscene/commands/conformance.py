"""``lbscene conformance BOOTH [--lighting L]… [--measurements M] [--report OUT.html] [--format json]``"""

from __future__ import annotations

import json
from pathlib import Path
from typing import List, Optional

import typer

from lbscene.commands.options import Format, allow_path_option

_STYLE = {"pass": "green", "fail": "red", "not_applicable": "dim"}


def _fmt(x, nd=1) -> str:
    if x is None:
        return "—"
    if isinstance(x, (list, tuple)):
        return ", ".join(_fmt(v, nd) for v in x)
    if abs(x) < 0.1 and x != 0:
        return f"{x:.4f}"
    return f"{x:.{nd}f}"


def print_text(res, console) -> None:
    """The result as rich tables on lbscene's literal console (user text is never parsed as
    markup; control characters show as escapes); styles come from :func:`styled` parts."""
    from lbscene.commands.console import table

    from .console import styled

    def escape(text) -> str:          # the console is literal: text goes through as written
        return str(text)

    from lbscene.engine.conformance.standards import STANDARD_TITLES

    a = res.area
    console.print(styled((res.booth_name, "bold"), f"  {res.booth_file}  effects: "
                         f"{', '.join(res.effects) or 'none'}"))
    console.print(f"viewing area: {escape(a.source)} {a.size_mm[0]:g} × {a.size_mm[1]:g} mm at z = "
                  f"{a.centre_mm[2]:g} mm ({res.grid_points[0]} × {res.grid_points[1]} points)"
                  + (f"; measurements {escape(res.measurements)} (lighting {escape(res.measured_lighting)})"
                     if res.measurements else ""))
    for n in res.notes:
        console.print(f"note: {escape(n)}", style="dim")
    t = table(title="lightings (forward model with the booth's effects)", title_justify="left")
    for c in ("lighting", "standard", "E sample lx", "uniformity", "x, y", "CCT K", "Duv", "Ra",
              "Rf 2017", "TM-30 Rf/Rg", "verdict"):
        t.add_column(c, justify="left" if c in ("lighting", "standard", "verdict", "x, y") else "right")
    for lc in res.lightings:
        m, c = lc.model, lc.model.colorimetry
        t.add_row(escape(lc.name), escape(lc.standard), _fmt(m.illuminance_at_sample_lx), _fmt(m.uniformity, 3),
                  _fmt(c.xy if c else None, 4), _fmt(c.cct_K if c else None, 0), _fmt(c.duv if c else None, 4),
                  _fmt(c.cri_ra if c else None), _fmt(c.cie2017_rf if c else None),
                  f"{_fmt(c.tm30_rf if c else None)} / {_fmt(c.tm30_rg if c else None)}",
                  styled((lc.verdict.replace('_', ' '), _STYLE[lc.verdict])))
    console.print(t)
    for lc in res.lightings:
        if lc.measured is not None:
            mm, mc = lc.measured, lc.measured.colorimetry
            console.print(f"measured ({escape(lc.name)}): E sample {_fmt(mm.illuminance_at_sample_lx)} lx, "
                          f"uniformity {_fmt(mm.uniformity, 3)}, x, y {_fmt(mc.xy if mc else None, 4)}, "
                          f"CCT {_fmt(mc.cct_K if mc else None, 0)} K, Ra {_fmt(mc.cri_ra if mc else None)}")
            for n in mm.notes:
                console.print(f"  {escape(n)}", style="dim")
        if not lc.checks:
            continue
        ct = table(title=f"{escape(lc.name)}: {escape(STANDARD_TITLES.get(lc.standard, lc.standard))}",
                   title_justify="left")
        for col in ("check", "source", "figure", "requirement", "verdict"):
            ct.add_column(col, justify="right" if col == "figure" else "left")
        for ch in lc.checks:
            fig = "—" if ch.value is None else f"{_fmt(ch.value, 3)} {ch.unit}".strip()
            ct.add_row(escape(ch.title), ch.source, escape(fig), escape(ch.requirement),
                       styled((ch.verdict.replace('_', ' '), _STYLE[ch.verdict])))
        console.print(ct)
        seen = set()
        for ch in lc.checks:
            if ch.verdict == "not_applicable" and ch.note and (ch.id, ch.note) not in seen:
                seen.add((ch.id, ch.note))
                console.print(f"  not assessed, {escape(ch.title)}: {escape(ch.note)}", style="dim")


def register(app: typer.Typer) -> None:
    @app.command("conformance")
    def conformance(
        booth: Path = typer.Argument(..., help="Booth folder, booth.yaml or a shipped booth's name."),
        lighting: Optional[List[str]] = typer.Option(
            None, "--lighting", "-l", help="Lighting to judge (repeatable, or comma-separated; default: all)."),
        measurements: Optional[Path] = typer.Option(
            None, "--measurements", "-m", help="Measurement set of this booth: its lighting is judged from "
                                               "the data too, side by side with the model."),
        report: Optional[Path] = typer.Option(None, "--report", help="Write a self-contained HTML report."),
        format: Format = typer.Option(Format.text, "--format", help="text or json."),
        allow_path: Optional[List[Path]] = allow_path_option(),
    ) -> None:
        """Does the booth meet its standard? Colorimetry, illuminance, uniformity and the checks of
        each lighting's standard (ISO 3664, …), from the model and the measurements.

        Exit 0 even when a check fails (it is a report); 2 on a user error.
        """
        from lbscene.commands.console import err_console, out_console, progress
        from lbscene.engine.files.diagnostics import LbsceneUserError
        from lbscene.engine.files.outputs import check_outputs

        if report is not None and report.suffix.lower() not in (".html", ".htm"):
            raise LbsceneUserError.single("LB500", "--report must name an .html file", str(report),
                                          value=str(report), expected="a path ending in .html")
        check_outputs([(report, "--report")], inputs=[booth, measurements])
        names = None
        if lighting:
            names = [n.strip() for item in lighting for n in item.split(",") if n.strip()]
        from rich.progress import SpinnerColumn, TextColumn, TimeElapsedColumn

        from lbscene.engine.conformance import run_conformance

        with progress(SpinnerColumn(), TextColumn("{task.description}"), TimeElapsedColumn(),
                      console=err_console(), transient=True, disable=format is Format.json) as prog:
            task = prog.add_task("conformance")
            res = run_conformance(booth, lightings=names, measurements=measurements,
                                  allowed_dirs=tuple(allow_path or ()),
                                  progress=lambda m: prog.update(task, description=m))
        if report is not None:
            from lbscene.engine.conformance.report import write_conformance_report

            write_conformance_report(res, report)
        if format is Format.json:
            out = res.to_json()
            out["report"] = None if report is None else str(report)
            typer.echo(json.dumps(out, indent=2, ensure_ascii=False, allow_nan=False))
            return
        print_text(res, out_console())
        if report is not None:
            typer.echo(f"report: {report}")
