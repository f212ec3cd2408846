"""``lbscene validate-config PATH...``"""

from __future__ import annotations

from pathlib import Path
from typing import List, Optional

import typer

from lbscene.commands.console import echo
from lbscene.commands.options import Format, allow_path_option
from lbscene.engine.files.textsafe import json_text


def register(app: typer.Typer) -> None:
    @app.command("validate-config")
    def validate_config(
        paths: List[Path] = typer.Argument(..., help="Files or folders (searched for *.yaml)."),
        format: Format = typer.Option(Format.text, "--format", help="text or json."),
        strict: bool = typer.Option(False, "--strict", help="Exit 1 when there are warnings."),
        verbose: bool = typer.Option(False, "--verbose", "-v", help="Also show info notes."),
        allow_path: Optional[List[Path]] = allow_path_option(),
    ) -> None:
        """Check booth, sample, display, measurement and render files: schema and semantic rules.

        Exit 0 clean, 1 warnings with --strict, 2 errors.
        """
        from lbscene.engine.files.diagnostics import Severity
        from lbscene.engine.conformance.validate import validate_paths

        report = validate_paths(paths, allowed_dirs=tuple(allow_path or ()))
        if format is Format.json:
            echo(json_text(report.to_json(), indent=2))
        else:
            for d in sorted(report.diagnostics,
                            key=lambda d: (d.location.file if d.location else "",
                                           d.location.line if d.location else 0,
                                           d.location.column if d.location else 0)):
                if d.severity is Severity.INFO and not verbose:
                    continue
                echo(d.format(), err=d.severity is not Severity.INFO)
            n = len(report.files)
            echo(f"{n} file{'s' if n != 1 else ''} checked: {report.errors} error(s), "
                       f"{report.warnings} warning(s)", err=True)
        raise typer.Exit(report.exit_code(strict))
