"""
An effect coating as the renderer uses it: the flop BRDF fitted to the sample's geometries and
the flakes (declared, or fitted to the instrument's texture readings), with the texture metrics
lbscene's instrument model predicts for them.

Fits are cached on disk (:mod:`lbscene.engine.files.disk_cache`, keyed by the sample's numbers), so a
sample's first render pays for them once (the flake fit: a few seconds to a minute).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .fit_texture import TextureFit, TextureReadings, fit_flakes
from .flakes import DEFAULT_FLAKE_REFLECTANCE, FlakeModel
from .flop import FlopModel, MeasuredGeometry, fit_flop
from .instrument import MODEL_VERSION, TextureMetrics, texture_metrics

__all__ = ["CoatingAppearance", "coating_appearance", "PREDICTION_SEED"]

#: seed of the instrument simulation that reports the model's predicted texture metrics
PREDICTION_SEED = 777


@dataclass
class CoatingAppearance:
    """Flop model, flakes and their texture metrics.

    Attributes
    ----------
    flop : FlopModel
        Fitted to the band means of the measured reflectances.
    flakes : FlakeModel or None
        None when the coating declares no texture.
    texture_source : str or None
        ``measured`` (flakes fitted to readings) or ``flakes`` (declared).
    readings : TextureReadings or None
        The declared readings (``measured``).
    predicted : TextureMetrics or None
        lbscene's instrument model applied to ``flakes``.
    fit : TextureFit or None
        The flake fit, when it ran in this process (else it came from the cache).
    base_diffuse_luminance : float
        The flop model's diffuse term, luminance-weighted (the instrument's base).
    """

    flop: FlopModel
    flakes: FlakeModel | None
    texture_source: str | None
    readings: TextureReadings | None
    predicted: TextureMetrics | None
    fit: TextureFit | None
    base_diffuse_luminance: float

    def summary(self) -> dict:
        out = {"flop": self.flop.to_json(), "texture_source": self.texture_source,
               "flakes": None if self.flakes is None else self.flakes.to_json(),
               "predicted": None if self.predicted is None else self.predicted.to_json()}
        if self.readings is not None:
            out["readings"] = {"sparkle": {f"{a:g}": list(s) for a, s in sorted(self.readings.sparkle.items())},
                               "graininess": self.readings.graininess}
        return out


def _flop(measured, spec, grid) -> FlopModel:
    from lbscene.engine.files.disk_cache import cached_array

    bands = np.stack([m.bands for m in measured])
    angles = np.array([[m.illumination_deg, m.aspecular_deg] for m in measured])
    params = ("coating-flop-1", spec.flop.lobes, spec.flop.distribution, spec.clear_coat.refractive_index)
    alphas = cached_array("coating_flop", (bands, angles), params,
                          lambda: fit_flop(measured, spec.flop.lobes, spec.clear_coat.refractive_index,
                                           spec.flop.distribution).alphas, shape=(spec.flop.lobes,))
    base = FlopModel(spec.clear_coat.refractive_index, np.asarray(alphas, float), np.zeros(grid.count),
                     np.zeros((spec.flop.lobes, grid.count)), spec.flop.distribution)
    return base.refit_linear(measured)


def coating_appearance(sample, grid=None, predict: bool = True) -> CoatingAppearance | None:
    """The coating of a :class:`~lbscene.runtimes.scene.SampleSpec` (None without
    ``effect_coating``)."""
    from lbscene.engine.files.disk_cache import cached_array
    from lbscene.engine.spectra.bands import DEFAULT_GRID

    from .colorimetry import luminance_weights

    spec = getattr(sample, "coating", None)
    if spec is None:
        return None
    grid = grid or DEFAULT_GRID
    measured = [MeasuredGeometry(*_angles(label, asp), grid.integrate(r)) for asp, label, r in sample.geometries]
    flop = _flop(measured, spec, grid)
    w = luminance_weights(grid)
    base_y = float(flop.diffuse @ w)
    tex = spec.texture
    if tex is None:
        return CoatingAppearance(flop, None, None, None, None, None, base_y)
    r1 = getattr(sample, "flake_reflectance_1nm", None)
    rho = grid.integrate(r1) if r1 is not None else np.full(grid.count, DEFAULT_FLAKE_REFLECTANCE)
    n = spec.clear_coat.refractive_index
    fit = None
    readings = None
    if tex.type == "flakes":
        flakes = FlakeModel.from_spread_deg(tex.density_per_mm2, tex.diameter.median_um, tex.diameter.spread,
                                            tex.orientation_spread_deg, rho, n)
    else:
        readings = TextureReadings({float(s.illumination_deg): (float(s.area), float(s.intensity))
                                    for s in tex.sparkle}, float(tex.graininess))
        holder: dict = {}

        def run():
            holder["fit"] = fit_flakes(readings, base_y, rho, tex.diameter_spread, n)
            m = holder["fit"].model
            return np.array([m.density_per_mm2, m.median_diameter_um, m.alpha])

        x = cached_array("coating_flakes", (readings.vector(), rho, np.array([base_y, n, tex.diameter_spread])),
                         (MODEL_VERSION,), run, shape=(3,))
        fit = holder.get("fit")
        flakes = FlakeModel(float(x[0]), float(x[1]), tex.diameter_spread, float(x[2]), rho, n)
    predicted = None
    if predict:
        predicted = texture_metrics(flakes, base_y, seed=PREDICTION_SEED, flake_reflectance=float(rho @ w))
    return CoatingAppearance(flop, flakes, tex.type, readings, predicted, fit, base_y)


def _angles(label: str, aspecular_deg: float) -> tuple[float, float]:
    from lbscene.schemas.booth import parse_geometry_name

    try:
        return parse_geometry_name(label)
    except ValueError:
        return 45.0, float(aspecular_deg)
