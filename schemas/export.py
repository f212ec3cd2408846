"""
Export the JSON Schema of every document kind into ``schemas/json/``.

Run ``make schemas`` (or ``python -m lbscene.schemas.export``) after changing a
model; ``tests/schemas/test_json_schema.py`` fails while the committed files
are stale.  The booth schema's ``effects`` property is filled from the effect
registry, so editors complete effect ids and their parameters.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

__all__ = ["JSON_DIR", "document_json_schema", "render_all", "main"]

JSON_DIR = Path(__file__).resolve().parent / "json"


def _effects_schema() -> dict:
    from lbscene.engine.light.effects.registry import available_effects

    props = {}
    for eid, eff in available_effects().items():
        s = eff.Params.model_json_schema()
        s["description"] = eff.summary
        props[eid] = s
    return {"type": "object", "description": "Physical effects the forward model includes, by id.",
            "properties": props,
            "additionalProperties": {"type": "object",
                                     "description": "An effect registered by a plugin."}}


def document_json_schema(kind: str) -> dict:
    from . import document_model

    model = document_model(kind)
    schema = model.model_json_schema()
    schema["$schema"] = "https://json-schema.org/draft/2020-12/schema"
    schema["$id"] = f"https://lbscene.org/schemas/{kind}.schema.json"
    if kind == "booth":
        schema["properties"]["effects"] = _effects_schema()
    return schema


def render_all() -> dict[str, str]:
    """File name → JSON text for every available document kind."""
    from . import DOCUMENT_KINDS

    out = {}
    for kind in DOCUMENT_KINDS:
        try:
            schema = document_json_schema(kind)
        except ModuleNotFoundError:
            continue  # a kind whose module is not part of this build
        out[f"{kind}.schema.json"] = json.dumps(schema, indent=2, sort_keys=True,
                                                ensure_ascii=False) + "\n"
    return out


def main() -> int:
    from lbscene.engine.files.atomic import write_atomic

    JSON_DIR.mkdir(exist_ok=True)
    for name, text in render_all().items():
        write_atomic(JSON_DIR / name, text)
        print(f"wrote {JSON_DIR / name}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
