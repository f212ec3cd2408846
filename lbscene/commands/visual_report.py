"""``lbscene visual-report RESULTS... --session S [--model-de CSV] [--report OUT.html]``"""

from __future__ import annotations

from pathlib import Path
from typing import List, Optional

import typer

from lbscene.commands.console import echo, out_console
from lbscene.commands.options import Format, allow_path_option
from lbscene.engine.files.textsafe import json_text


def register(app: typer.Typer) -> None:
    @app.command("visual-report")
    def visual_report(
        results: List[Path] = typer.Argument(..., help="Results files of the viewer's test mode (CSV or JSON)."),
        session: Path = typer.Option(..., "--session", help="The session file (kind: visual_session)."),
        model_de: Optional[Path] = typer.Option(
            None, "--model-de", help="CSV lighting,geometry,sample,delta_e00: the model's ΔE00 per case "
                                     "(for STRESS against the model)."),
        model_texture: Optional[Path] = typer.Option(
            None, "--model-texture", help="CSV lighting,geometry,sample + texture metrics (the web export's "
                                          "model-texture.csv): set beside the sparkle and graininess scores."),
        report: Optional[Path] = typer.Option(None, "--report", help="Write one self-contained HTML report."),
        json_out: Optional[Path] = typer.Option(None, "--json-out", help="Write the statistics as JSON."),
        format: Format = typer.Option(Format.text, "--format", help="text or json."),
        allow_path: Optional[List[Path]] = allow_path_option(),
    ) -> None:
        """Mean score per case, intra-/inter-observer STRESS and STRESS against the model's ΔE00; sparkle
        and graininess cases beside the model's texture metrics."""
        from lbscene.engine.files.load import display_path
        from lbscene.engine.files.outputs import check_outputs, write_output
        from lbscene.engine.visual.protocol import load_session, read_results
        from lbscene.engine.visual.report import analyse, read_model_delta_e, read_model_texture, render_html

        check_outputs([(report, "--report"), (json_out, "--json-out")],
                      inputs=[*results, session, model_de, model_texture])
        ses = load_session(session, tuple(allow_path or ()))
        rows = read_results(results, ses)
        model = read_model_delta_e(model_de, ses) if model_de is not None else None
        texture = read_model_texture(model_texture, ses) if model_texture is not None else None
        stats = analyse(rows, ses, model, texture)
        if report is not None:
            write_output(report, render_html(stats, ses), option="--report")
        if json_out is not None:
            write_output(json_out, json_text(stats, indent=1) + "\n", option="--json-out")
        if format is Format.json:
            echo(json_text(stats, indent=1))
            return
        from lbscene.commands.console import table

        def num(v, fmt: str = "{:.2f}") -> str:
            # a statistic the data cannot give (one repeat, one observer, one case) is None
            return "—" if v is None else fmt.format(v)

        t = table(title=f"session {stats['session']}: {stats['responses']} responses, "
                        f"{len(stats['observers'])} observers")
        texture_cases = any(c["attribute"] != "colour" for c in stats["cases"])
        cols = ["lighting", "geometry", "sample"] + (["attribute"] if texture_cases else []) + [
            "n", "mean score", "sd", "ΔV", "model ΔE00"] + (["model texture"] if texture_cases else [])
        for col in cols:
            t.add_column(col, justify="left" if col in ("lighting", "geometry", "sample", "attribute",
                                                        "model texture") else "right")
        for c in stats["cases"]:
            row = [c["lighting"], c["geometry"], c["sample"]] + ([c["attribute"]] if texture_cases else []) + [
                str(c["n"]), num(c["mean_score"]), num(c["sd_score"]), num(c["mean_delta_v"]), num(c.get("model_delta_e00"))]
            if texture_cases:
                m = c.get("model_texture")
                row.append("" if not m else f"{m['glints_per_cm2']:.0f} glints/cm², contrast "
                                            f"{m['glint_contrast']:.2f}, grain {m['grain_contrast_percent']:.1f} %")
            t.add_row(*row)
        out_console().print(t)
        s = stats["summary"]
        intra = s["intra_observer_stress_mean"]
        inter = s["inter_observer_stress_mean"]
        echo(f"intra-observer STRESS: mean {num(intra, '{:.1f}')}"
             + (" (one repeat per observer: no intra-observer STRESS)" if intra is None else "")
             + f"  inter-observer STRESS: mean {num(inter, '{:.1f}')}"
             + (" (needs two observers and two cases)" if inter is None else "")
             + (f"  STRESS vs model ΔE00: {s['stress_vs_model']:.1f}" if s.get("stress_vs_model") is not None
                else "  (no --model-de: no STRESS against the model)"))
        if report is not None:
            echo(f"wrote {display_path(report)}")
