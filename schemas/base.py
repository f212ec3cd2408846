"""
Conventions shared by every lbscene schema.

* :class:`StrictModel`: ``extra="forbid"`` (unknown keys are errors), frozen,
  no coercion surprises (strings are not silently numbers).
* :class:`Document`: a top-level file; carries ``version:`` (upgraded by
  :func:`lbscene.schemas.upgrade.upgrade` passes before validation).
* Polymorphic nodes are discriminated unions on a ``type:`` field.
* Every physical quantity has its unit in the field name (``_mm``, ``_nm``,
  ``_deg``, ``_lx``, ``_K``…).
* :class:`Provenance`: where values come from; ``status: estimate`` marks
  values that are not published or measured, so users know what to replace.
"""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import BaseModel, ConfigDict, Field, field_validator

__all__ = [
    "StrictModel",
    "Document",
    "Provenance",
    "Vec3_mm",
    "Direction",
    "Identifier",
    "CURRENT_VERSION",
]

#: The document format version this release writes and reads natively.
CURRENT_VERSION = 1


class StrictModel(BaseModel):
    """Base of every schema node: unknown keys are errors; values are immutable."""

    model_config = ConfigDict(
        extra="forbid",
        frozen=True,
        strict=False,
        validate_default=True,
        str_strip_whitespace=True,
        populate_by_name=False,
    )


Identifier = Annotated[
    str,
    Field(pattern=r"^[A-Za-z_][A-Za-z0-9_.\-]*$", max_length=64,
          description="A name: letters, digits, '_', '-', '.'; starts with a letter or '_'."),
]

#: A point in booth coordinates: millimetres, origin at the centre of the booth
#: floor, +x to the observer's right, +y from the open front toward the rear
#: wall, +z up.
Vec3_mm = Annotated[
    tuple[float, float, float],
    Field(description="Point in booth coordinates [x, y, z] in millimetres (origin: floor centre; "
                      "+x observer's right, +y toward the rear wall, +z up)."),
]

Direction = Annotated[
    tuple[float, float, float],
    Field(description="Direction vector [x, y, z] in booth coordinates (normalised on load)."),
]


class Provenance(StrictModel):
    """Where the values of a document (or a node) come from."""

    status: Literal["measured", "published", "estimate", "synthetic"] = Field(
        description="'estimate' marks plausible values that are not published or measured: "
                    "replace them with your own measurements.")
    source: str = Field("", max_length=2000, description="Citation, data sheet or measurement record.")
    notes: str = Field("", max_length=4000)
    estimated_fields: list[str] = Field(
        default_factory=list,
        description="Dotted paths of the fields that are estimates, when only some are.")


class Document(StrictModel):
    """A top-level lbscene file."""

    version: int = Field(description="Format version of this document (current: 1).")

    @field_validator("version")
    @classmethod
    def _known_version(cls, v: int) -> int:
        if v < 1 or v > CURRENT_VERSION:
            raise ValueError(f"unsupported version {v}; this lbscene reads versions 1..{CURRENT_VERSION}")
        return v
