"""Generate the reference pages of the documentation site from the code itself.

* ``docs/reference/files.md``: every document kind (booth, sample, display, measurement set,
  render configuration) and every type it contains, from the pydantic models in
  :mod:`lbscene.schemas`: fields, types, units, defaults, constraints, descriptions, and
  examples taken from the shipped booths, displays and example files (each example is
  validated against its model, so it cannot drift).
* ``docs/reference/cli.md``: every command of ``lbscene`` with its arguments and options, from
  the click command tree that Typer builds.
* ``docs/reference/diagnostics.md``: the table of diagnostic codes.

Run by ``make docs`` before ``mkdocs build``; the output folder is not committed.

Usage: ``python scripts/gen_docs.py [--out docs/reference]``
"""

from __future__ import annotations

import argparse
import inspect
import re
import types
import typing
from pathlib import Path

from pydantic import BaseModel
from pydantic.fields import FieldInfo
from pydantic_core import PydanticUndefined

REPO = Path(__file__).resolve().parents[1]

#: unit suffixes of field names (the project's convention: units in every name)
UNITS = [
    ("_W_sr_m2_nm", "W·sr⁻¹·m⁻²·nm⁻¹"), ("_W_sr_nm", "W·sr⁻¹·nm⁻¹"), ("_W_nm", "W·nm⁻¹"),
    ("_cd_m2", "cd/m²"), ("_per_mm2", "mm⁻²"), ("_mm2", "mm²"), ("_mm", "mm"), ("_um", "µm"),
    ("_nm", "nm"), ("_deg", "°"), ("_lx", "lx"),
    ("_lm", "lm"), ("_cd", "cd"), ("_K", "K"), ("_W", "W"), ("_GU", "gloss units"), ("_percent", "%"),
    ("_s", "s"), ("_px", "px"),
]

DOCUMENTS = [
    ("booth", "lbscene.schemas.booth", "Booth", "booths/*/booth.yaml"),
    ("sample", "lbscene.schemas.sample", "Sample", "examples/render/sample-*.yaml"),
    ("display", "lbscene.schemas.display", "Display", "displays/*.yaml"),
    ("measurement_set", "lbscene.schemas.measurement", "MeasurementSet", "examples/*/measurements.yaml"),
    ("render_config", "lbscene.schemas.render_config", "RenderConfig", "examples/render/*.yaml"),
    ("visual_session", "lbscene.schemas.visual_session", "VisualSession", "examples/render/session-*.yaml"),
]


def unit_of(name: str) -> str:
    for suffix, unit in UNITS:
        if name.endswith(suffix) or f"{suffix}_" in name:
            return unit
    return ""


def anchor(model: type[BaseModel]) -> str:
    return model.__name__.lower()


def models_in(annotation) -> list[type[BaseModel]]:
    """The pydantic models an annotation refers to, in order."""
    out: list[type[BaseModel]] = []
    if isinstance(annotation, type) and issubclass(annotation, BaseModel):
        return [annotation]
    for arg in typing.get_args(annotation):
        for m in models_in(arg):
            if m not in out:
                out.append(m)
    return out


def type_text(annotation) -> str:
    """Markdown for a field type, with links to the models it names."""
    origin = typing.get_origin(annotation)
    args = typing.get_args(annotation)
    if annotation is type(None):
        return "null"
    if isinstance(annotation, type) and issubclass(annotation, BaseModel):
        return f"[{annotation.__name__}](#{anchor(annotation)})"
    if origin is typing.Annotated:
        return type_text(args[0])
    if origin is typing.Literal:
        vals = [f"`{a}`" if isinstance(a, str) else f"`{a!r}`" for a in args]
        return vals[0] if len(vals) == 1 else "one of " + ", ".join(vals)
    if origin in (typing.Union, types.UnionType):
        return " or ".join(type_text(a) for a in args)
    if origin in (list, tuple, set, frozenset):
        if origin is tuple and args and args[-1] is not Ellipsis:
            return "[" + ", ".join(type_text(a) for a in args) + "]"
        return f"list of {type_text(args[0])}" if args else "list"
    if origin is dict:
        return f"mapping {type_text(args[0])} → {type_text(args[1])}" if args else "mapping"
    if isinstance(annotation, type):
        return {"str": "string", "int": "integer", "float": "number", "bool": "boolean"}.get(
            annotation.__name__, annotation.__name__)
    return str(annotation).replace("typing.", "")


def constraints(info: FieldInfo) -> str:
    parts = []
    for m in info.metadata:
        for attr, sym in (("ge", "≥"), ("gt", ">"), ("le", "≤"), ("lt", "<"),
                          ("min_length", "min length"), ("max_length", "max length"), ("pattern", "pattern")):
            v = getattr(m, attr, None)
            if v is not None:
                parts.append(f"{sym} `{v}`")
    return ", ".join(parts)


def default_text(info: FieldInfo) -> str:
    if info.is_required():
        return "**required**"
    if info.default_factory is not None:
        try:
            v = info.default_factory()
        except TypeError:
            return "(computed)"
    else:
        v = info.default
    if v is PydanticUndefined:
        return ""
    if isinstance(v, BaseModel):
        v = v.model_dump(mode="json")
    if isinstance(v, str):
        return f"`{v}`"
    import json

    try:
        return f"`{json.dumps(v, ensure_ascii=False)}`"
    except TypeError:
        return f"`{v!r}`"


def prose(text: str) -> str:
    """Plain text as Markdown: ``_``, ``*``, ``<`` and ``>`` escaped outside `code` spans."""
    parts = re.split(r"(`[^`]*`)", str(text))
    for i in range(0, len(parts), 2):
        parts[i] = re.sub(r"([_*<>\[\]])", r"\\\1", parts[i])
    return "".join(parts)


def cell(text: str) -> str:
    return " ".join(str(text).split()).replace("|", "\\|")


def collect(root: type[BaseModel]) -> list[type[BaseModel]]:
    """Every model reachable from ``root``, depth first in field order."""
    seen: list[type[BaseModel]] = []

    def walk(m):
        if m in seen:
            return
        seen.append(m)
        for f in m.model_fields.values():
            for sub in models_in(f.annotation):
                walk(sub)

    walk(root)
    return seen


# --------------------------------------------------------------------------- examples

def shipped_documents() -> list[tuple[Path, object]]:
    from ruamel.yaml import YAML

    yaml = YAML(typ="safe")
    out = []
    for _, _, _, pattern in DOCUMENTS:
        for p in sorted(REPO.glob(pattern)):
            try:
                out.append((p, yaml.load(p.read_text())))
            except Exception:  # noqa: BLE001 - an unreadable example is simply not an example
                continue
    return out


def mappings(node):
    if isinstance(node, dict):
        yield node
        for v in node.values():
            yield from mappings(v)
    elif isinstance(node, list):
        for v in node:
            yield from mappings(v)


def find_example(model: type[BaseModel], docs) -> tuple[Path, dict] | None:
    """The richest mapping in the shipped files that validates as ``model``."""
    from pydantic import ValidationError

    fields = set(model.model_fields)
    best = None
    for path, data in docs:
        for m in mappings(data):
            if not m or not set(m) <= fields:
                continue
            try:
                model.model_validate(m)
            except (ValidationError, ValueError, TypeError):
                continue
            if best is None or len(m) > len(best[1]):
                best = (path, m)
    return best


def yaml_text(data) -> str:
    import io

    from ruamel.yaml import YAML

    y = YAML()
    y.default_flow_style = None
    y.width = 100
    buf = io.StringIO()
    y.dump(data, buf)
    text = buf.getvalue()
    lines = text.splitlines()
    if len(lines) > 40:
        lines = lines[:40] + ["# … (shortened)"]
    return "\n".join(lines)


# --------------------------------------------------------------------------- files page

def files_page() -> str:
    import importlib

    docs = shipped_documents()
    out = ["# File reference", "",
           "Generated from the pydantic models in `lbscene.schemas` by `scripts/gen_docs.py` (run by "
           "`make docs`): every document kind, every type, every field with its type, unit, default and "
           "constraints. The examples are taken from the files shipped with lbscene (booths, displays, "
           "examples) and validate against the model they illustrate.", "",
           "Conventions: every document has `version:` and `kind:`; every polymorphic node has a `type:`; "
           "unknown keys are errors; units are part of field names (`_mm`, `_nm`, `_deg`, `_lx`, "
           "`_cd_m2`, `_K`, …). Booth coordinates are millimetres with the origin at the centre of the "
           "booth floor, +x to the observer's right, +y from the open front toward the rear wall, +z up. "
           "File references are relative to the file that names them. JSON Schemas of every kind ship in "
           "`lbscene/schemas/json/` (editors complete and check YAML against them through the "
           "`# yaml-language-server: $schema=…` line).", ""]
    documented: set[type[BaseModel]] = set()
    for kind, module, cls, pattern in DOCUMENTS:
        root = getattr(importlib.import_module(module), cls)
        out += [f"## Document `kind: {kind}`", "",
                f"Model `{module}.{cls}`; shipped examples: `{pattern}`.", ""]
        for m in collect(root):
            if m in documented:
                continue
            documented.add(m)
            out += model_section(m, docs)
    out += named_spectra()
    return "\n".join(out) + "\n"


def named_spectra() -> list[str]:
    """The names a ``cie_illuminant`` / ``light_source`` spectrum accepts (colour-science's datasets)."""
    from lbscene.engine.spectra.evaluate import ILLUMINANT_ALIASES, known_names

    out = ["## Named spectra {#named-spectra}", "",
           "`{type: cie_illuminant, name: …}` takes a name from colour-science's `SDS_ILLUMINANTS`; "
           "`{type: light_source, name: …}` one from `SDS_LIGHT_SOURCES` (measured lamps). Names are "
           "matched exactly, then ignoring case.", ""]
    if ILLUMINANT_ALIASES:
        out += ["Aliases: " + ", ".join(f"`{a}` → `{b}`" for a, b in sorted(ILLUMINANT_ALIASES.items())),
                ""]
    for title, dataset in (("CIE and other illuminants", "illuminant"), ("Light sources", "light_source")):
        out += [f"### {title}", "", ", ".join(f"`{n}`" for n in known_names(dataset)), ""]
    return out


def model_section(m: type[BaseModel], docs) -> list[str]:
    out = [f"### {m.__name__} {{#{anchor(m)}}}", ""]
    doc = inspect.getdoc(m)
    if doc and not doc.startswith(("A base class", "Usage docs")):
        out += [prose(doc), ""]
    tfield = m.model_fields.get("type")
    if tfield is not None and typing.get_origin(tfield.annotation) is typing.Literal:
        vals = typing.get_args(tfield.annotation)
        out += [f"Selected by `type: {vals[0]}`." if len(vals) == 1 else
                "`type:` one of " + ", ".join(f"`{v}`" for v in vals) + ".", ""]
    out += ["| field | type | unit | default | constraints | description |",
            "|---|---|---|---|---|---|"]
    for name, f in m.model_fields.items():
        key = f.alias or name
        desc = prose(f.description or "")
        if f.examples:
            desc += " Examples: " + ", ".join(f"`{e!r}`" for e in f.examples)
        out.append(f"| `{key}` | {cell(type_text(f.annotation))} | {unit_of(key)} | {cell(default_text(f))} "
                   f"| {cell(constraints(f))} | {cell(desc)} |")
    out.append("")
    ex = find_example(m, docs)
    if ex is not None:
        path, data = ex
        out += [f"Example (from `{path.relative_to(REPO).as_posix()}`):", "", "```yaml",
                yaml_text(data), "```", ""]
    return out


# --------------------------------------------------------------------------- CLI page

def cli_page() -> str:
    import click
    import typer

    from lbscene.cli import app

    root = typer.main.get_command(app)
    ctx = click.Context(root, info_name="lbscene")
    out = ["# Command-line reference", "",
           "Generated from the commands themselves by `scripts/gen_docs.py` (run by `make docs`). "
           "Exit codes: 0 success, 1 warnings under `--strict` or a failed check, 2 a user error "
           "(a located `LB…` diagnostic on stderr, never a traceback). `lbscene --version` prints "
           "the version; `lbscene COMMAND --help` the help of a command.", "",
           "| command | what it does |", "|---|---|"]
    for name in root.list_commands(ctx):
        cmd = root.get_command(ctx, name)
        out.append(f"| [`{name}`](#lbscene-{name}) | {cell(cmd.get_short_help_str(200))} |")
    out.append("")
    for name in root.list_commands(ctx):
        cmd = root.get_command(ctx, name)
        sub = click.Context(cmd, info_name=name, parent=ctx)
        out += [f"## lbscene {name} {{#lbscene-{name}}}", "", prose(inspect.cleandoc(cmd.help or "")), "",
                "```text", " ".join(cmd.collect_usage_pieces(sub)).join(["lbscene " + name + " ", ""]),
                "```", "", "| argument / option | type | default | description |", "|---|---|---|---|"]
        for p in cmd.params:
            if p.hidden if hasattr(p, "hidden") else False:
                continue
            names = ", ".join(f"`{o}`" for o in (p.opts + p.secondary_opts)) \
                if isinstance(p, click.Option) else f"`{p.human_readable_name}`"
            ptype = p.type
            tname = ("one of " + ", ".join(f"`{c}`" for c in ptype.choices)
                     if isinstance(ptype, click.Choice) else ptype.name)
            if getattr(p, "multiple", False):
                tname += " (repeatable)"
            default = p.default
            if callable(default) or default in (None, (), []) or isinstance(p, click.Argument):
                dtext = "**required**" if p.required else ""
            else:
                dtext = f"`{getattr(default, 'value', default)}`"
            help_text = getattr(p, "help", None)
            if not help_text and cmd.callback is not None:
                # Typer keeps an argument's help on the parameter default of the callback
                spec = inspect.signature(cmd.callback).parameters.get(p.name)
                help_text = getattr(getattr(spec, "default", None), "help", None)
            out.append(f"| {names} | {cell(tname)} | {cell(dtext)} | {cell(help_text or '')} |")
        out.append("")
    return "\n".join(out) + "\n"


# --------------------------------------------------------------------------- diagnostics page

def diagnostics_page() -> str:
    from lbscene.engine.files.diagnostics import CODES

    groups = {"0": "reading files", "1": "schema", "2": "references", "3": "semantic rules",
              "4": "measurement data", "5": "usage", "6": "build, bake and render"}
    out = ["# Diagnostic codes", "",
           "Generated from `lbscene.engine.files.diagnostics.CODES`. Every user mistake is reported as "
           "`file:line:col: error LBxxx: message (got …; expected …)` and the command exits with code 2.",
           ""]
    last = None
    for code, text in CODES.items():
        g = code[2]
        if g != last:
            out += ["", f"## LB{g}xx: {groups.get(g, '')}", "", "| code | meaning |", "|---|---|"]
            last = g
        out.append(f"| `{code}` | {cell(text)} |")
    return "\n".join(out) + "\n"


def api_source_tree(dest: Path) -> None:
    """A ``lbscene/`` folder laid out as installed (symbolic links to the repository's folders), so
    that mkdocstrings reads the sources statically, without importing them."""
    import shutil
    import tomllib

    cfg = tomllib.loads((REPO / "pyproject.toml").read_text())["tool"]["setuptools"]["package-dir"]
    if dest.exists():
        shutil.rmtree(dest)
    root = dest / "lbscene"
    root.mkdir(parents=True)
    for f in (REPO / cfg["lbscene"]).iterdir():
        (root / f.name).symlink_to(f)
    for pkg, folder in cfg.items():
        if pkg != "lbscene" and (REPO / folder / "__init__.py").is_file():
            (root / pkg.split(".", 1)[1]).symlink_to(REPO / folder)


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=REPO / "docs" / "reference")
    ap.add_argument("--api-src", type=Path, default=REPO / "build" / "docs-src")
    args = ap.parse_args(argv)
    api_source_tree(args.api_src)
    args.out.mkdir(parents=True, exist_ok=True)
    # the contributing guide lives at the repository root (where people look for it)
    contributing = (REPO / "CONTRIBUTING.md").read_text()
    for name, make in (("files.md", files_page), ("cli.md", cli_page), ("diagnostics.md", diagnostics_page),
                       ("contributing.md", lambda: contributing)):
        text = make()
        text = re.sub(r"\n{3,}", "\n\n", text)
        (args.out / name).write_text(text)
        print(f"wrote {(args.out / name).relative_to(REPO) if (args.out / name).is_relative_to(REPO) else args.out / name}")


if __name__ == "__main__":
    main()
