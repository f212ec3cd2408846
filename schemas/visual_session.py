"""
The visual-test session: observers judge the rendering (the web viewer's test mode)
against the physical sample in the booth, case by case.

A case is one sample × viewing geometry × lighting (× judged attribute: colour, or the sparkle
or graininess of an effect coating); every observer sees every case
``repeats`` times, in a randomised, balanced order (see
:func:`lbscene.engine.visual.protocol.plan_trials`), and answers on a grey scale
(ISO 105-A02 style, 5 = no visible difference) or with an estimated ΔE.  This is the
protocol of "Visual validation of the appearance of chromatic objects rendered from
spectrophotometric measurements" (16 observers, six geometries of the byko-spectra
effect booth, scores against ΔE00).
"""

from __future__ import annotations

from typing import Literal

from pydantic import Field, model_validator

from .base import Document, Identifier, StrictModel
from .booth import GeometryName
from .refs import FileRef

__all__ = ["VisualSession", "SessionObserver", "ResponseScale", "TrialOrder", "ATTRIBUTES"]

#: What an observer judges in a case: the colour, or a texture attribute of an effect coating
#: (sparkle under the booth's lamp, graininess: the light/dark pattern).
ATTRIBUTES = ("colour", "sparkle", "graininess")


class SessionObserver(StrictModel):
    """One observer (no personal data is needed: an id, optionally notes such as the
    colour-vision test passed)."""

    id: Identifier
    notes: str = Field("", max_length=2000)


class ResponseScale(StrictModel):
    """How the observer answers."""

    type: Literal["grey_scale", "delta_e_estimate"] = Field(
        "grey_scale", description="grey_scale: a score min..max in steps of `step` (5: no visible "
                                  "difference); delta_e_estimate: the observer's estimate of the colour "
                                  "difference (ΔE units, ≥ 0).")
    min: float = Field(1.0, description="Lowest grey-scale score.")
    max: float = Field(5.0, description="Highest grey-scale score (no visible difference).")
    step: float = Field(0.5, gt=0, description="Grey-scale step (0.5: the half steps of the grey scale).")

    @model_validator(mode="after")
    def _range(self):
        if self.max <= self.min:
            raise ValueError("response: max must be greater than min")
        return self


class TrialOrder(StrictModel):
    """Randomised, balanced presentation order."""

    seed: int = Field(0, ge=0, description="Seed of the random order (same seed, same order).")
    method: Literal["balanced"] = Field(
        "balanced", description="Every case once per block (one block per observer and repeat); the "
                                "blocks are evenly spread cyclic shifts of one seeded permutation, so "
                                "each case is shown at evenly spread serial positions across blocks.")


class VisualSession(Document):
    """A visual-test session file."""

    kind: Literal["visual_session"] = Field(description="Document kind.")
    name: Identifier = Field(description="Session name (results files carry it).")
    render_config: FileRef | None = Field(
        None, description="Render configuration whose booth, display and camera the viewer uses "
                          "(`lbscene export-web --session` exports it when no other source is given).")
    observers: list[SessionObserver] = Field(min_length=1)
    samples: list[FileRef] = Field(min_length=1, description="Sample documents.")
    geometries: list[GeometryName] = Field(min_length=1, description="Viewing geometries of the booth.")
    lightings: list[str] = Field(min_length=1, description="Lighting configurations of the booth.")
    repeats: int = Field(1, ge=1, le=20, description="How often each observer sees each case.")
    attributes: list[Literal["colour", "sparkle", "graininess"]] = Field(
        default_factory=lambda: ["colour"], min_length=1,
        description="What is judged: each sample × geometry × lighting is a case per attribute (colour; "
                    "sparkle and graininess for effect coatings: the match of that texture attribute).")
    order: TrialOrder = TrialOrder()
    response: ResponseScale = ResponseScale()

    @model_validator(mode="after")
    def _unique(self):
        for what, items in (("observer id", [o.id for o in self.observers]), ("sample", self.samples),
                            ("geometry", self.geometries), ("lighting", self.lightings),
                            ("attribute", self.attributes)):
            dup = sorted({x for x in items if items.count(x) > 1})
            if dup:
                raise ValueError(f"duplicate {what}: {', '.join(dup)}")
        return self
