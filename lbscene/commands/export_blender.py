"""``lbscene export-blender BOOTH [--lighting L ...] --out booth.blend [--format json]``"""

from __future__ import annotations

from pathlib import Path
from typing import List, Optional

import typer

from lbscene.commands.options import Format, allow_path_option


def register(app: typer.Typer) -> None:
    @app.command("export-blender")
    def export_blender(
        booth: Path = typer.Argument(..., help="Booth folder, booth.yaml or a shipped booth's name."),
        lighting: Optional[List[str]] = typer.Option(
            None, "--lighting", "-l", help="Lighting to include (repeat for several; default: all, "
                                           "the first is switched on)."),
        out: Path = typer.Option(Path("booth.blend"), "--out", "-o", help="The Blender file to write (.blend)."),
        format: Format = typer.Option(Format.text, "--format", help="text or json."),
        allow_path: Optional[List[Path]] = allow_path_option(),
    ) -> None:
        """Write the booth as a Blender file: the Cycles scene of `lbscene bake` in RGB, lamps as
        emitters of their shape in Blender's watts, one collection per lighting, the observer's camera."""
        from lbscene.bakers.blender_export import export_blender as _export
        from lbscene.commands.console import echo
        from lbscene.engine.files.load import display_path
        from lbscene.engine.files.textsafe import json_text

        res = _export(booth, out, lightings=lighting or None, allowed_dirs=tuple(allow_path or ()))
        if format is Format.json:
            typer.echo(json_text(res.to_json(), indent=2))
            return
        cam = res.to_json()["camera"]
        echo(f"wrote {display_path(res.out)}: {res.booth}, lightings {', '.join(res.lightings)} "
             f"(collections 'lighting <name>', {res.lightings[0]} on); camera {cam['angle_x_deg']:.1f}° x "
             f"{cam['angle_y_deg']:.1f}°")
        echo("open it in Blender 5.0 or later and render with Cycles; light is in Blender's watts "
             "(683 lm/W): an illuminance in lx is 683 x the luminance of the rendered irradiance")
        for n in res.notes:
            echo(f"note: {n}", err=True)
