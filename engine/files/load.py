"""
Parse → upgrade → validate: turn a YAML file into a schema model, or into
located diagnostics.

pydantic reports errors as paths (``('lamps', 0, 'length_mm')``); the
:class:`~lbscene.engine.files.yamlio.PositionMap` recorded while parsing turns each
into ``file:line:col``.  Every error of a document is reported at once.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any, Iterable, TypeVar

from pydantic import BaseModel, ValidationError

from lbscene.schemas.refs import RefContext

from .diagnostics import Diagnostic, LbsceneUserError, SourceLocation
from .yamlio import PositionMap, YamlDocument, load_yaml_file

__all__ = ["LoadedDocument", "load_document", "validate_data", "pydantic_to_diagnostics",
           "display_path", "UPGRADES"]

M = TypeVar("M", bound=BaseModel)

#: Upgrade passes: ``UPGRADES[(ModelName, from_version)] = fn(data) -> data`` bringing a
#: document from ``from_version`` to ``from_version + 1``.  Applied in order before validation.
UPGRADES: dict[tuple[str, int], Any] = {}


@dataclass
class LoadedDocument:
    """A validated model with its source (for later located diagnostics)."""

    model: Any
    yaml: YamlDocument
    path: Path
    refs: RefContext

    @property
    def file(self) -> str:
        return self.yaml.file

    def locate(self, *path, key: bool = False) -> SourceLocation:
        return self.yaml.positions.locate(tuple(path), key=key)

    def resolve(self, raw: str) -> Path:
        """Resolve a file reference of this document (already checked at load)."""
        from lbscene.schemas.refs import resolve_ref

        return resolve_ref(raw, self.refs)


def display_path(path: Path) -> str:
    """Path as shown in messages: relative to the working directory when inside it."""
    try:
        return str(path.resolve().relative_to(Path.cwd().resolve()))
    except (ValueError, OSError, RuntimeError):   # outside the cwd; a name too long; a link loop
        return str(path)


_TYPE_CODES = {
    "extra_forbidden": "LB100",
    "missing": "LB102",
    "union_tag_not_found": "LB102",
    "union_tag_invalid": "LB105",
    "greater_than": "LB103",
    "greater_than_equal": "LB103",
    "less_than": "LB103",
    "less_than_equal": "LB103",
    "too_short": "LB103",
    "too_long": "LB103",
    "finite_number": "LB103",
    "lb_path_escape": "LB201",
    "lb_missing_file": "LB200",
    "lb_bad_path": "LB200",
    "lb_geometry_name": "LB303",
    "lb_unknown_effect": "LB106",
}


def _code_for(err_type: str) -> str:
    if err_type in _TYPE_CODES:
        return _TYPE_CODES[err_type]
    if err_type.endswith("_type") or err_type.endswith("_parsing") or err_type in (
            "model_attributes_type", "dict_type", "list_type", "tuple_type", "is_instance_of"):
        return "LB101"
    return "LB104"


def _data_path(data: Any, loc: Iterable) -> tuple:
    """Drop pydantic's synthetic loc parts (union tags, validator names) not present in data."""
    out = []
    node = data
    for part in loc:
        if isinstance(node, dict) and part in node:
            out.append(part)
            node = node[part]
        elif isinstance(node, list) and isinstance(part, int) and 0 <= part < len(node):
            out.append(part)
            node = node[part]
        elif isinstance(node, dict) and node.get("type") == part:
            continue  # discriminated-union tag inserted by pydantic
        elif isinstance(part, str) and ("[" in part or part.startswith("function-")):
            continue
        else:
            out.append(part)  # a missing key: keep it for the message, locate its parent
            node = None
    return tuple(out)


def _short(value: Any, limit: int = 80) -> str:
    text = repr(value)
    return text if len(text) <= limit else text[: limit - 1] + "…"


def _expected(err: dict) -> str | None:
    t = err["type"]
    ctx = err.get("ctx") or {}
    if t == "extra_forbidden":
        return None
    if t == "missing":
        return "this key to be present"
    if t == "union_tag_invalid":
        return f"'type' to be one of {ctx.get('expected_tags')}"
    if t == "union_tag_not_found":
        return f"a '{ctx.get('discriminator', 'type').strip(chr(39))}' key"
    if t.startswith("greater_than") or t.startswith("less_than"):
        return err["msg"].replace("Input should be ", "a value ")
    if t == "literal_error":
        return f"one of {ctx.get('expected')}"
    if t.endswith("_type") or t.endswith("_parsing"):
        return err["msg"].replace("Input should be ", "").replace("Input should ", "")
    return None


def pydantic_to_diagnostics(exc: ValidationError, data: Any, positions: PositionMap,
                            prefix: tuple = ()) -> list[Diagnostic]:
    """Map a pydantic ValidationError onto located diagnostics."""
    diags = []
    seen = set()
    for err in exc.errors(include_url=False):
        path = prefix + _data_path(data, err["loc"])
        t = err["type"]
        code = _code_for(t)
        is_key = t == "extra_forbidden"
        loc = positions.locate(path, key=is_key or t == "missing")
        where = ".".join(str(p) for p in path) or "<document>"
        if t == "extra_forbidden":
            msg = f"unknown key '{path[-1]}'" if path else "unknown key"
            parent = ".".join(str(p) for p in path[:-1]) or "the document"
            msg += f" in {parent}"
            value, expected = None, "only the keys the schema defines (see the JSON Schema)"
        elif t == "missing":
            msg = f"missing required key '{path[-1]}'" if path else "missing required key"
            value, expected = None, None
            parent = ".".join(str(p) for p in path[:-1])
            if parent:
                msg += f" in {parent}"
        else:
            text = err["msg"]
            if text.startswith("Value error, "):
                text = text[len("Value error, "):]
            msg = f"{where}: {text}"
            value = None if t.startswith("lb_") else _short(err.get("input"))
            expected = _expected(err)
        key = (code, loc, msg)
        if key in seen:
            continue
        seen.add(key)
        diags.append(Diagnostic(code, msg, loc, value=value, expected=expected))
    return diags


def _upgrade(model: type[BaseModel], data: dict, yaml: YamlDocument) -> dict:
    from lbscene.schemas.base import CURRENT_VERSION

    v = data.get("version")
    if not isinstance(v, int) or isinstance(v, bool):
        return data  # validation reports the problem
    while v < CURRENT_VERSION and (model.__name__, v) in UPGRADES:
        data = UPGRADES[(model.__name__, v)](dict(data))
        v += 1
        data["version"] = v
    return data


def validate_data(model: type[M], data: Any, yaml: YamlDocument, refs: RefContext) -> M:
    """Validate already-parsed data; raise :class:`LbsceneUserError` with all problems."""
    if not isinstance(data, dict):
        raise LbsceneUserError.single(
            "LB008", "the document must be a mapping of keys to values", yaml.file, 1, 1,
            value=type(data).__name__, expected=f"a {model.__name__} mapping")
    data = _upgrade(model, data, yaml)
    try:
        return model.model_validate(data, context=refs.as_context())
    except ValidationError as exc:
        raise LbsceneUserError(pydantic_to_diagnostics(exc, data, yaml.positions)) from None


def load_document(path: Path | str, model: type[M], *, root_dir: Path | None = None,
                  allowed_dirs: Iterable[Path] = (), check_exists: bool = True) -> LoadedDocument:
    """Read, upgrade and validate one YAML document.

    ``root_dir`` is the sandbox for file references (default: the file's folder).
    """
    path = Path(path)
    yaml = load_yaml_file(path, display_path(path))
    refs = RefContext(base_dir=path.resolve().parent,
                      root_dir=(root_dir or path.resolve().parent),
                      allowed_dirs=tuple(Path(d) for d in allowed_dirs),
                      check_exists=check_exists)
    m = validate_data(model, yaml.data, yaml, refs)
    return LoadedDocument(model=m, yaml=yaml, path=path, refs=refs)
