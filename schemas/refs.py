"""
File references in documents: resolved relative to the referring file and
confined to the document's root folder (a booth's folder) unless the caller
explicitly allows other folders.

Validation needs a context (``model_validate(data, context=RefContext(...).as_context())``);
without one (e.g. JSON Schema export or programmatic construction) paths are
kept as written and checked later by the engine.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Annotated

from pydantic import AfterValidator, Field, ValidationInfo
from pydantic_core import PydanticCustomError

__all__ = ["FileRef", "RefContext", "resolve_ref"]

MAX_REF_LENGTH = 1024


@dataclass(frozen=True)
class RefContext:
    """Where references of one document resolve."""

    base_dir: Path                       # folder of the referring file
    root_dir: Path                       # sandbox: references must stay inside
    allowed_dirs: tuple[Path, ...] = ()  # extra folders explicitly allowed by the user
    check_exists: bool = True
    seen: list = field(default_factory=list)  # resolved references, in order

    def as_context(self) -> dict:
        return {"refs": self}


def resolve_ref(raw: str, ctx: RefContext) -> Path:
    """Resolve ``raw`` against ``ctx``; raise PydanticCustomError on escape/missing."""
    if "\x00" in raw or len(raw) > MAX_REF_LENGTH:
        raise PydanticCustomError("lb_bad_path", "not a valid file path")
    p = Path(raw)
    target = Path(os.path.realpath(p if p.is_absolute() else ctx.base_dir / p))
    roots = [Path(os.path.realpath(ctx.root_dir))] + [Path(os.path.realpath(d)) for d in ctx.allowed_dirs]
    if not any(target == r or r in target.parents for r in roots):
        raise PydanticCustomError(
            "lb_path_escape",
            "path {path} escapes the document's folder {root} (allow it explicitly with --allow-path)",
            {"path": raw, "root": str(ctx.root_dir)},
        )
    if ctx.check_exists and not target.is_file():
        raise PydanticCustomError(
            "lb_missing_file", "referenced file {path} does not exist (looked for {target})",
            {"path": raw, "target": str(target)})
    ctx.seen.append(target)
    return target


def _validate(value: str, info: ValidationInfo) -> str:
    ctx = (info.context or {}).get("refs") if info.context else None
    if ctx is None:
        return value
    resolve_ref(value, ctx)
    return value


FileRef = Annotated[
    str,
    Field(min_length=1, max_length=MAX_REF_LENGTH,
          description="Path of a file, relative to the file that refers to it; must stay inside "
                      "the document's folder."),
    AfterValidator(_validate),
]
