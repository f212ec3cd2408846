"""``lbscene export-mitsuba BOOTH [--lighting L] [--measurements M] [--out scene.xml | scene.py] [--format json]``"""

from __future__ import annotations

import json
from pathlib import Path
from typing import List, Optional

import typer

from lbscene.commands.options import Format, allow_path_option


def register(app: typer.Typer) -> None:
    @app.command("export-mitsuba")
    def export_mitsuba(
        booth: Path = typer.Argument(..., help="Booth folder, booth.yaml or a shipped booth's name."),
        lighting: Optional[str] = typer.Option(
            None, "--lighting", "-l", help="Lighting configuration (default: the measurement set's, else the "
                                           "booth's first)."),
        measurements: Optional[Path] = typer.Option(
            None, "--measurements", "-m", help="Measurement set: its readings become the scene's sensors "
                                               "(default: the 55-point A3 grid at the sample)."),
        out: Path = typer.Option(Path("scene.xml"), "--out", "-o",
                                 help="scene.xml (Mitsuba 3 XML, meshes as PLY in <stem>_meshes/) or scene.py "
                                      "(a Python module whose scene_dict() is the scene)."),
        spp: int = typer.Option(16384, "--spp", help="Samples per reading written into the scene."),
        format: Format = typer.Option(Format.text, "--format", help="text or json."),
        allow_path: Optional[List[Path]] = allow_path_option(),
    ) -> None:
        """Write the Mitsuba 3 scene lbscene's truth provider renders (booth, lighting, readings), to check
        a booth independently."""
        from lbscene.engine.conformance.mitsuba_export import export_mitsuba as _export
        from lbscene.engine.files.load import display_path

        res = _export(booth, out, lighting=lighting, measurements=measurements, spp=spp,
                      allowed_dirs=tuple(allow_path or ()))
        if format is Format.json:
            typer.echo(json.dumps(res.to_json(), indent=2, ensure_ascii=False))
            return
        extra = f" and {len(res.files) - 1} mesh file(s)" if len(res.files) > 1 else ""
        typer.echo(f"wrote {display_path(res.out)}{extra}: {res.booth}, lighting {res.lighting}, "
                   f"{len(res.points_mm)} readings ({res.receivers_from}); effects: {', '.join(res.effects) or 'none'}")
        typer.echo("render with mitsuba (variant scalar_spectral); a reading's film value x 683 x pi is its "
                   "illuminance in lx" + ("; `python " + res.out.name + "` prints them" if res.format == "python" else ""))
        for n in res.notes:
            typer.echo(f"note: {n}", err=True)
