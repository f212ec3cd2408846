"""``lbscene effects``: the registered physical effects and their parameters."""

from __future__ import annotations

import typer

from lbscene.commands.console import echo
from lbscene.commands.options import Format
from lbscene.engine.files.textsafe import json_text


def register(app: typer.Typer) -> None:
    @app.command("effects")
    def effects(format: Format = typer.Option(Format.text, "--format", help="text or json.")) -> None:
        """List the effects a booth's `effects:` section can enable (built-ins and plugins)."""
        from lbscene.commands.console import table

        from lbscene.engine.light.effects.registry import available_effects

        rows = []
        for eid, cls in available_effects().items():
            params = []
            for name, f in cls.Params.model_fields.items():
                params.append({"name": name, "default": f.default if not callable(f.default) else None,
                               "description": f.description or "",
                               "fit_bounds": list(getattr(cls, "fit_parameters", {}).get(name, ()))
                               or None})
            rows.append({"id": eid, "kind": getattr(cls, "kind", ""), "summary": cls.summary,
                         "module": cls.__module__, "parameters": params})
        if format is Format.json:
            echo(json_text(rows, indent=2, default=str))
            return
        t = table(title="registered effects (enable under `effects:` in a booth file)", title_justify="left")
        t.add_column("id")
        t.add_column("kind")
        t.add_column("what it models")
        t.add_column("parameters (default; * = fitted by the diagnosis)")
        for r in rows:
            ps = ", ".join(f"{p['name']}={p['default']}{'*' if p['fit_bounds'] else ''}" for p in r["parameters"])
            t.add_row(r["id"], r["kind"], r["summary"], ps or "—")
        from lbscene.commands.console import out_console

        out_console().print(t)
