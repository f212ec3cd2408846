"""
A booth's ``effects:`` checked against the effect registry.

Every effect id must be registered (a built-in or a plugin) and its parameters must
validate against the effect's ``Params`` model; both mistakes are located diagnostics
(``LB106``, and the schema codes of the parameter).  The loader, the linter and the
compiler all call :func:`validate_effects`, which needs nothing but the loaded document.
"""

from __future__ import annotations

from pydantic import ValidationError

from lbscene.engine.files.diagnostics import Diagnostic
from lbscene.engine.files.load import LoadedDocument, pydantic_to_diagnostics
from lbscene.engine.light.effects.registry import available_effects

__all__ = ["validate_effects"]


def validate_effects(doc: LoadedDocument) -> tuple[dict[str, dict], list[Diagnostic]]:
    """Validate ``effects:`` against the registry: unknown ids and bad params, located."""
    registry = available_effects()
    out: dict[str, dict] = {}
    diags: list[Diagnostic] = []
    for eid, params in doc.model.effects.items():
        if eid not in registry:
            diags.append(Diagnostic(
                "LB106", f"unknown effect id '{eid}'", doc.locate("effects", eid, key=True),
                value=repr(eid), expected=f"one of {', '.join(registry)} (or a plugin's id)"))
            continue
        model = registry[eid].Params
        try:
            out[eid] = model.model_validate(params if params is not None else {}).model_dump(mode="json")
        except ValidationError as exc:
            data = params if params is not None else {}
            diags.extend(pydantic_to_diagnostics(exc, data, doc.yaml.positions,
                                                 prefix=("effects", eid)))
    return out, diags
