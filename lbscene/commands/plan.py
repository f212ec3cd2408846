"""``lbscene plan MEASUREMENTS``: the extra readings that would tell the suspects apart."""

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


def register(app: typer.Typer) -> None:
    @app.command("plan")
    def plan(
        measurements: Path = measurements_argument(),
        booth: Optional[Path] = booth_override_option(),
        points: int = typer.Option(8, "--points", min=1, max=50, help="At most this many readings."),
        out: Optional[Path] = typer.Option(None, "--out", help="Write a CSV template of the readings."),
        format: Format = typer.Option(Format.text, "--format", help="text or json."),
        allow_path: Optional[List[Path]] = allow_path_option(),
    ) -> None:
        """Propose extra readings (positions, orientations) where tied candidates differ most."""
        from lbscene.commands.console import table

        from lbscene.commands.compare import diagnosis_progress
        from lbscene.engine.loop.compare import plan_for, run_compare

        from lbscene.engine.files.outputs import check_outputs

        check_outputs([(out, "--out")], inputs=[measurements, booth])
        from lbscene.commands.console import err_console, out_console, styled

        err = err_console()
        prog, cb = diagnosis_progress(err, format is not Format.json)
        with prog:
            res = run_compare(measurements, booth=booth, do_plan=False, history=False,
                              allowed_dirs=tuple(allow_path or ()), progress=cb)
        p = plan_for(res, max_points=points)
        if out is not None and p is not None:
            from lbscene.engine.files.outputs import write_output

            write_output(out, p.csv_template(), option="--out")
        if format is Format.json:
            echo(json_text({"verdict": str(res.verdict), "rmse_percent": round(res.fit.rmse_percent, 4),
                                   "plan": p.to_json() if p else None,
                                   "csv": str(out) if out and p else None}, indent=2))
            return
        con = out_console()
        con.print(styled("verdict: ", (str(res.verdict), "bold"), f"  (RMSE {res.fit.rmse_percent:.2f} %, noise "
                         f"{res.noise.percent:.2g} %)"))
        if p is None or not p.points:
            con.print("nothing to plan: there are no competing explanations to separate")
            return
        t = table(title=f"measure next: {', '.join(p.candidates)}", title_justify="left")
        for c in ("x mm", "y mm", "z mm", "facing", "kind", *[f"{c} lx" for c in p.candidates], "spread %"):
            t.add_column(c, justify="right")
        for q in p.points:
            t.add_row(f"{q.position_mm[0]:g}", f"{q.position_mm[1]:g}", f"{q.position_mm[2]:g}", q.orientation(),
                      q.kind, *[f"{q.predicted_lx[c]:.1f}" for c in p.candidates], f"{q.spread_percent:.1f}")
        con.print(t)
        for k, v in p.separation.items():
            con.print(f"  {k.replace('|', ' vs ')}: χ² {v:.0f} in noise units after these readings")
        for n in p.notes:
            con.print(f"  note: {n}")
        con.print("add the readings as a CSV (x_mm,y_mm,z_mm,normal_x,normal_y,normal_z,illuminance_lx) under "
                  "`illuminance:` of the measurement set and run compare again"
                  + (f"; template: {out}" if out else " (--out FILE writes a template)"))
