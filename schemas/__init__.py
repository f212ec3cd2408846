"""
lbscene's file formats as pydantic v2 models (``lbscene.schemas``).

Every top-level document has ``version:`` and ``kind:``; :data:`DOCUMENT_KINDS`
maps a kind to its model (imported lazily, so reading one kind does not import
all of them).  JSON Schema exports of every kind live in ``schemas/json/``
(regenerate with ``make schemas``; a test fails when they are stale).
"""

from __future__ import annotations

from importlib import import_module

__all__ = ["DOCUMENT_KINDS", "document_model"]

#: kind → "module:Class"
DOCUMENT_KINDS: dict[str, str] = {
    "booth": "lbscene.schemas.booth:Booth",
    "sample": "lbscene.schemas.sample:Sample",
    "display": "lbscene.schemas.display:Display",
    "measurement_set": "lbscene.schemas.measurement:MeasurementSet",
    "render_config": "lbscene.schemas.render_config:RenderConfig",
    "visual_session": "lbscene.schemas.visual_session:VisualSession",
}


def document_model(kind: str):
    """The model class of a document kind (KeyError when unknown)."""
    mod, cls = DOCUMENT_KINDS[kind].split(":")
    return getattr(import_module(mod), cls)
