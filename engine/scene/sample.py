"""
A sample as the renderers and the visual test need it: its reflectance per geometry.

:meth:`SampleSpec.from_document` evaluates a sample document's spectra (1 nm), one
reflectance per aspecular angle it declares; the realtime runtime draws it, the visual
test names its cases by it and hashes it (:meth:`SampleSpec.digest`).

Examples
--------
>>> import numpy as np
>>> s = SampleSpec.flat(np.full(471, 0.5), name="grey")
>>> s.name, len(s.geometries)
('grey', 1)
"""

from __future__ import annotations

from typing import Any

import hashlib
from dataclasses import dataclass

import numpy as np

from lbscene.engine.spectra.evaluate import evaluate_spectrum
from lbscene.schemas.booth import parse_geometry_name

__all__ = ["SampleSpec"]


@dataclass
class SampleSpec:
    """The sample as the renderers need it.

    ``geometries``: ``(aspecular_deg, label, reflectance_1nm)``; one entry (any
    angle) for a geometry-independent reflectance.
    """

    name: str
    geometries: list[tuple[float, str, np.ndarray]]
    size_mm: tuple[float, float] = (100.0, 85.0)
    gloss_GU: float = 0.0
    roughness: float = 0.1
    #: ``effect_coating`` of the sample document (:class:`lbscene.schemas.coating.EffectCoating`)
    coating: Any = None
    #: its flakes' reflectance on the 1 nm grid (None: the default)
    flake_reflectance_1nm: np.ndarray | None = None

    @classmethod
    def flat(cls, reflectance_1nm, name: str = "flat", size_mm=(100.0, 85.0), gloss_GU: float = 0.0,
             roughness: float = 0.1) -> "SampleSpec":
        return cls(name, [(0.0, "all", np.asarray(reflectance_1nm, float))], tuple(size_mm),
                   gloss_GU, roughness)

    @classmethod
    def from_document(cls, doc) -> "SampleSpec":
        """From a loaded :class:`lbscene.schemas.sample.Sample` document."""
        m = doc.model
        geoms = []
        for g in m.by_geometry:
            _, asp = parse_geometry_name(g.geometry)
            geoms.append((asp, g.geometry, evaluate_spectrum(g.reflectance, doc.resolve, "reflectance",
                                                             display=f"{m.name} {g.geometry}")))
        if not geoms:
            geoms.append((0.0, "all", evaluate_spectrum(m.reflectance, doc.resolve, "reflectance",
                                                         display=m.name)))
        geoms.sort(key=lambda g: g[0])
        coat = m.effect_coating
        flake_r = None
        if coat is not None and coat.texture is not None and coat.texture.flake_reflectance is not None:
            flake_r = evaluate_spectrum(coat.texture.flake_reflectance, doc.resolve, "reflectance",
                                        display=f"{m.name} flake_reflectance")
        return cls(m.name, geoms, tuple(m.size_mm), m.gloss_GU, m.roughness, coat, flake_r)

    def digest(self) -> str:
        h = hashlib.sha256(repr((self.name, self.size_mm, self.gloss_GU, self.roughness)).encode())
        if self.coating is not None:
            h.update(self.coating.model_dump_json().encode())
        if self.flake_reflectance_1nm is not None:
            h.update(np.asarray(self.flake_reflectance_1nm, float).tobytes())
        for a, label, r in self.geometries:
            h.update(f"{a}:{label}".encode())
            h.update(np.asarray(r, float).tobytes())
        return h.hexdigest()[:16]
