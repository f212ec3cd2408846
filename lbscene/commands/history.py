"""``lbscene history MEASUREMENTS``: the error per step, labelled with what changed."""

from __future__ import annotations

from pathlib import Path
from typing import Optional

import typer

from lbscene.commands.console import echo
from lbscene.commands.options import Format
from lbscene.engine.files.textsafe import json_text


def register(app: typer.Typer) -> None:
    @app.command("history")
    def history(
        measurements: Path = typer.Argument(..., help="Measurement-set YAML whose history to show."),
        plot: Optional[Path] = typer.Option(None, "--plot", help="Write the error-per-step plot (PNG)."),
        format: Format = typer.Option(Format.text, "--format", help="text or json."),
    ) -> None:
        """Print the compare history of a measurement set (and plot it with --plot)."""
        from lbscene.commands.console import table

        from lbscene.engine.loop.history import plot_history, read_history

        from lbscene.engine.files.outputs import check_outputs

        from lbscene.engine.files.yamlio import read_bytes_bounded

        # a regular, readable file (a FIFO, a device or a folder is refused, not "no history")
        read_bytes_bounded(measurements, str(measurements), 4 * 1024 * 1024, is_input=False)
        hp = measurements.with_name(measurements.stem + ".history.jsonl")
        check_outputs([(plot, "--plot")], inputs=[measurements, hp if hp.exists() else None])
        entries = read_history(hp)
        if plot is not None and entries:
            from lbscene.engine.files.outputs import output_path

            from lbscene.engine.files.textsafe import plain_text_plots

            with plain_text_plots():
                fig = plot_history(entries, title=f"history of {measurements.name}")
                with output_path(plot, suffix=".png", option="--plot") as tmp:
                    fig.savefig(tmp, format="png", bbox_inches="tight")
        if format is Format.json:
            echo(json_text({"history": str(hp), "entries": entries,
                                   "plot": str(plot) if plot and entries else None}, indent=2,
                                  ensure_ascii=False))
            return
        from lbscene.commands.console import out_console

        con = out_console()
        if not entries:
            con.print(f"no history yet ({hp} does not exist): run `lbscene compare {measurements}`")
            return
        t = table(title=f"history of {measurements}", title_justify="left")
        for c in ("step", "time", "what changed", "effects", "RMSE %", "noise %", "verdict", ""):
            t.add_column(c, justify="right" if c in ("step", "RMSE %", "noise %") else "left")
        top = max((e.get("rmse_percent") or 0) for e in entries) or 1.0
        for e in entries:
            r = e.get("rmse_percent")
            bar = "█" * max(1, int(round(24 * (r or 0) / top))) if r is not None else ""
            t.add_row(str(e.get("step", "")), str(e.get("time", ""))[:19], e.get("label", ""),
                      ", ".join(sorted(e.get("effects", {}))) or "none",
                      "—" if r is None else f"{r:.2f}",
                      "—" if e.get("noise_percent_estimate") is None else f"{e['noise_percent_estimate']:.2g}",
                      e.get("verdict", ""), bar)
        con.print(t)
        if plot is not None:
            con.print(f"plot: {plot}")
