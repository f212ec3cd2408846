"""
Effect coatings (metallic and pearlescent paints): colour flop, sparkle and graininess.

* :mod:`.optics` — measurement directions, refraction at the clear coat, Fresnel;
* :mod:`.flop` — the multi-lobe Cook–Torrance BRDF fitted per band to the six geometries;
* :mod:`.flakes` — flakes as mirrors: orientation distribution, glint probability, mean lobe;
* :mod:`.instrument` — lbscene's texture instrument: simulated images, S_a, S_i, G;
* :mod:`.fit_texture` — flake parameters from the instrument's readings;
* :mod:`.model` — the coating of a sample as the renderer uses it;
* :mod:`.colorimetry` — CIELAB and ΔE00 of band reflectances (colour-science);
* :mod:`.mitsuba_flakes` — explicit flakes rendered by Mitsuba 3, the texture's outside truth;
* :mod:`.visual` — the model's texture metrics of a visual-test case.

The realtime runtime's side is :mod:`lbscene.runtimes.coating` (values the render graph binds)
and the shaders ``lib_coating.glsl`` (vertex stage) and ``sample.frag`` (``COATING 1``).

Layer: above :mod:`lbscene.engine.colour`, below :mod:`lbscene.engine.light`.

May import: :mod:`lbscene.engine.files`, :mod:`~lbscene.engine.spectra`,
:mod:`~lbscene.engine.colour` and :mod:`lbscene.schemas` (Mitsuba 3 only inside
:mod:`.mitsuba_flakes`, for the slow reference).
"""

from .flakes import FlakeModel
from .flop import FlopModel, MeasuredGeometry, fit_flop, leave_one_out
from .model import CoatingAppearance, coating_appearance

__all__ = ["FlakeModel", "FlopModel", "MeasuredGeometry", "fit_flop", "leave_one_out",
           "CoatingAppearance", "coating_appearance"]
