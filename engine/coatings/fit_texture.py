"""
Flake parameters from the instrument's texture readings.

Given sparkle area and intensity at up to three illumination angles and graininess (on
lbscene's scale, :mod:`~lbscene.engine.coatings.instrument`), find the flake density
:math:`ρ_A`, median diameter :math:`d_{50}` and orientation spread :math:`\\arctan α` whose
simulated instrument images give the same readings.  The diameter spread, the flake reflectance
and the base's diffuse reflectance (from the flop fit) are held.

The residuals are relative, :math:`r_j = \\ln(\\hat S_j / S_j)` (a reading of 0 is compared
absolutely, on the scale of the smallest non-zero reading), minimised by
``scipy.optimize.least_squares`` over :math:`(\\ln ρ_A, \\ln d_{50}, \\ln \\arctan α)`; the
simulations use common random numbers (:class:`~lbscene.engine.coatings.instrument.GlintPool`,
:class:`~lbscene.engine.coatings.instrument.FlakePool`), so the objective is a smooth function of
the parameters up to single flakes entering or leaving.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .flakes import FlakeModel
from .instrument import FlakePool, GlintPool, TextureMetrics, texture_metrics

__all__ = ["TextureReadings", "TextureFit", "fit_flakes", "BOUNDS"]

#: (density per mm², median diameter µm, orientation spread deg) searched
BOUNDS = ((20.0, 2.0, 1.0), (15000.0, 150.0, 40.0))
FIT_SEED = 20240


@dataclass(frozen=True)
class TextureReadings:
    """``sparkle``: illumination angle (deg) → (S_a, S_i); ``graininess``: G."""

    sparkle: dict
    graininess: float

    def vector(self) -> np.ndarray:
        out = []
        for a in sorted(self.sparkle):
            out.extend(self.sparkle[a])
        out.append(self.graininess)
        return np.asarray(out, float)

    def labels(self) -> list[str]:
        out = []
        for a in sorted(self.sparkle):
            out += [f"S_a({a:g}°)", f"S_i({a:g}°)"]
        return out + ["G"]


def _vector(tm: TextureMetrics, angles) -> np.ndarray:
    out = []
    for a in sorted(angles):
        out.extend(tm.sparkle[a])
    out.append(tm.graininess)
    return np.asarray(out, float)


@dataclass
class TextureFit:
    """The fitted flakes, the readings they give and those they were fitted to."""

    model: FlakeModel
    readings: TextureReadings
    recovered: np.ndarray
    target: np.ndarray
    labels: list[str]
    evaluations: int

    @property
    def relative_error(self) -> np.ndarray:
        return self.recovered / np.where(self.target > 0, self.target, np.nan) - 1.0

    def to_json(self) -> dict:
        return {"flakes": self.model.to_json(),
                "readings": [{"name": n, "input": float(t), "recovered": round(float(r), 4),
                              "relative_error": (None if not np.isfinite(e) else round(float(e), 4))}
                             for n, t, r, e in zip(self.labels, self.target, self.recovered,
                                                   self.relative_error)],
                "evaluations": self.evaluations}


def fit_flakes(readings: TextureReadings, base_diffuse: float, flake_reflectance: np.ndarray,
               diameter_spread: float = 0.35, n: float = 1.5, seed: int = FIT_SEED,
               start=(1500.0, 20.0, 12.0)) -> TextureFit:
    """Fit density, median diameter and orientation spread to the readings.

    Parameters
    ----------
    readings
        The instrument's S_a, S_i per angle and G.
    base_diffuse
        The base's diffuse term :math:`a` (luminance) of the flop fit.
    flake_reflectance
        Band reflectance of a flake (its luminance-weighted mean is what the camera sees).
    """
    from scipy.optimize import least_squares

    from .colorimetry import luminance_weights

    fr = np.atleast_1d(np.asarray(flake_reflectance, float))
    rho_y = float(fr @ luminance_weights()) if fr.size == 16 else float(fr.mean())
    angles = sorted(readings.sparkle)
    target = readings.vector()
    floor = max(float(target[target > 0].min()) if (target > 0).any() else 1.0, 1e-3) * 0.1
    pools = (GlintPool(seed), FlakePool(seed + 7919))
    lo, hi = np.log(BOUNDS[0]), np.log(BOUNDS[1])
    count = [0]

    def model_of(x):
        d, med, spread = np.exp(x)
        return FlakeModel.from_spread_deg(d, med, diameter_spread, spread, fr, n)

    def simulate(x):
        count[0] += 1
        tm = texture_metrics(model_of(x), base_diffuse, angles_deg=angles, flake_reflectance=rho_y,
                             pools=pools)
        return _vector(tm, angles)

    def resid(x):
        s = simulate(x)
        return np.log((s + floor) / (target + floor))

    x0 = np.clip(np.log(np.asarray(start, float)), lo + 1e-6, hi - 1e-6)
    r = least_squares(resid, x0, bounds=(lo, hi), diff_step=0.02, x_scale=1.0, max_nfev=60,
                      xtol=1e-4, ftol=1e-5)
    model = model_of(r.x)
    return TextureFit(model, readings, simulate(r.x), target, readings.labels(), count[0])
