"""``lbscene build BOOTH [--lighting NAME] [--out DIR]``"""

from __future__ import annotations

import time
from pathlib import Path
from typing import List, Optional

import typer

from lbscene.commands.console import echo
from lbscene.commands.options import Format, allow_path_option
from lbscene.engine.files.textsafe import json_text


def register(app: typer.Typer) -> None:
    @app.command("build")
    def build(
        booth: Path = typer.Argument(..., help="Booth folder (with booth.yaml) or booth file."),
        lighting: Optional[str] = typer.Option(None, "--lighting", "-l",
                                               help="Only this lighting configuration."),
        out: Optional[Path] = typer.Option(None, "--out", "-o",
                                           help="Build folder (default: build/<booth folder name>)."),
        format: Format = typer.Option(Format.text, "--format", help="text or json."),
        allow_path: Optional[List[Path]] = allow_path_option(),
    ) -> None:
        """Compile a booth: scene IR, USD stage, bake jobs and render graphs, written atomically."""
        from rich.progress import SpinnerColumn, TextColumn, TimeElapsedColumn
        from lbscene.commands.console import table

        from lbscene.engine.scene.build import build_booth
        from lbscene.engine.scene.compile import find_booth_file

        booth_file = find_booth_file(booth)
        out_dir = out or Path("build") / booth_file.resolve().parent.name
        from lbscene.commands.console import err_console, out_console, progress

        console = err_console()
        t0 = time.perf_counter()
        with progress(SpinnerColumn(), TextColumn("{task.description}"), TimeElapsedColumn(),
                      console=console, transient=True, disable=format is Format.json) as prog:
            task = prog.add_task("build", total=None)
            result = build_booth(booth_file, out_dir, lighting,
                                 progress=lambda msg: prog.update(task, description=f"build: {msg}"),
                                 allowed_dirs=tuple(allow_path or ()))
        elapsed = time.perf_counter() - t0
        if format is Format.json:
            d = result.to_json()
            d["elapsed_s"] = round(elapsed, 3)
            echo(json_text(d, indent=2))
            return
        tab = table(title=f"{result.booth_name} → {result.out_dir}")
        tab.add_column("file")
        tab.add_column("sha256", style="dim")
        for name, digest in result.files.items():
            tab.add_row(name, digest[:16])
        out_console().print(tab)
        echo(f"IR {result.ir_hash[:16]}  lightings: {', '.join(result.lightings)}  "
                   f"({elapsed:.2f} s)")
        for w in result.skipped_writers:
            echo(f"note: {w} is not available in this build; its products were not written",
                       err=True)
