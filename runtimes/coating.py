"""
Render-time inputs of an effect coating (``sample.frag`` with ``COATING 1``).

:func:`coating_inputs` turns a sample's :class:`~lbscene.engine.coatings.model.CoatingAppearance`
into the ``sample.*`` values the render graph binds (the coating's spectra as a uniform array:
a fetch from a float texture costs a CPU rasteriser far more), for the light of one view:

* the flop model's spectral weights refitted (same roughnesses) to the measured reflectances
  *projected for the light at the sample* (as the flat path projects its reflectances), and the
  flake reflectance projected the same way;
* the flakes: density, mean area times the mean visible share :math:`V` at the view's geometry
  (:meth:`~lbscene.engine.coatings.flakes.FlakeModel.visibility`), Beckmann α;
* the flake cell: the sample-space square whose flakes one hash draws.  Its side is the
  footprint of one pixel of a 768-pixel-high view at the view's camera distance
  (``REFERENCE_HEIGHT_PX``), rounded to a power of two of a millimetre, so it is a property of
  the view, the same in every runtime, and it does not change when the sample tilts (where a
  pixel covers more of the sample — a smaller viewport — the fragment shader takes a
  power-of-two multiple of it and rescales λ and the grain);
* the glints' spectrum: the flake reflectance times the mean band intensity of the view's
  emitters (the lamps of one lighting share a spectrum; each emitter's level is kept);
* the graininess per cell: the instrument model's diffuse-image contrast ``G`` (per cent, at a
  Gaussian blur of σ_b = 50 µm, effective area :math:`4πσ_b^2`) scaled to the cell's area as for
  independent flakes, :math:`σ_{cell} = (G/100) \\sqrt{4 π σ_b^2} / s`.

The highlight roll-off of the display model (``display.highlight_*``) is on whenever the sample
has flakes: luminance above ``HIGHLIGHT_KNEE`` of the display white is compressed (extended
Reinhard) so that glints up to ``HIGHLIGHT_MAX`` × white keep distinct levels (and their
chromaticity, until the gamut mapping must desaturate) instead of all clipping to white; the same
curve applies to every pixel of the frame.
"""

from __future__ import annotations

import numpy as np

__all__ = [
    "REFERENCE_HEIGHT_PX",
    "HIGHLIGHT_KNEE",
    "HIGHLIGHT_MAX",
    "GLINT_BIN",
    "flake_cell_mm",
    "coating_inputs",
    "flat_coating_values",
]

REFERENCE_HEIGHT_PX = 768
HIGHLIGHT_KNEE = 0.8
HIGHLIGHT_MAX = 8.0
#: slope-space bin of the half vector (≈ 1.1°): flakes of one cell are drawn per bin
GLINT_BIN = 0.02
COATING_ROWS = 5


def flake_cell_mm(distance_mm: float, vertical_fov_deg: float) -> float:
    """Side of the flake cell for a camera ``distance_mm`` from the sample (module docstring)."""
    footprint = distance_mm * np.radians(vertical_fov_deg) / REFERENCE_HEIGHT_PX
    return float(2.0 ** np.round(np.log2(max(footprint, 1e-6))))


def flat_coating_values(size_mm=(100.0, 85.0)) -> dict:
    """Values of a sample without a coating (the graph binds them anyway)."""
    values = {
        "sample.coating_spectra": np.zeros(64, np.float32),
        "sample.coating": 0, "sample.coating_lobes": 0,
        "sample.coating_alphas": np.zeros(3, np.float32), "sample.coating_beckmann": 1,
        "sample.coat_n": 1.5, "sample.coat_diffuse_transmittance": 1.0,
        "sample.size_mm": np.asarray(size_mm, np.float32),
        "sample.flakes": 0, "sample.flake_density_per_mm2": 0.0, "sample.flake_area_mm2": 0.0,
        "sample.flake_alpha": 0.1, "sample.flake_cell_mm": 1.0, "sample.grain_sigma": 0.0,
        "sample.glint_bin": GLINT_BIN, "sample.lobe_luminance": np.zeros(3, np.float32),
        "sample.flake_luminance": 0.0, "sample.glint_spectrum": np.zeros(16, np.float32),
        "sample.lamp_band_sum": 1.0, "sample.u_axis": np.array([1.0, 0.0, 0.0], np.float32),
        "display.highlight_rolloff": 0, "display.highlight_knee": HIGHLIGHT_KNEE,
        "display.highlight_max": HIGHLIGHT_MAX,
    }
    return values


def coating_inputs(appearance, sample, light_1nm: np.ndarray, grid, distance_mm: float,
                   vertical_fov_deg: float, light_dir=None, view_dir=None, emitter_bands=(),
                   u_axis=(1.0, 0.0, 0.0)) -> tuple[dict, dict]:
    """(values, info) for one view.

    ``appearance``: :class:`~lbscene.engine.coatings.model.CoatingAppearance`; ``sample``:
    :class:`~lbscene.runtimes.scene.SampleSpec`; ``light_1nm``: the spectral irradiance at the
    sample (for the projection of reflectances); ``light_dir``, ``view_dir``: unit directions of
    the geometry's light and of the eye in the sample's frame (z: its normal), for the flakes'
    mean visible share (default 45° light, view along the normal); ``emitter_bands``: the band
    intensities of the view's emitters (the glints' spectrum: ρ_f times their mean); ``u_axis``:
    the sample's u axis placed for the view."""
    from lbscene.engine.coatings.flop import MeasuredGeometry
    from lbscene.engine.coatings.instrument import GRAIN_BLUR_UM
    from lbscene.engine.coatings.model import _angles
    from lbscene.engine.coatings.optics import diffuse_transmittance

    from .colour_bridge import project_reflectance

    values = flat_coating_values(sample.size_mm)
    values["sample.u_axis"] = np.asarray(u_axis, np.float32)
    tex = np.zeros((COATING_ROWS, 4, 4), np.float32)
    measured = [MeasuredGeometry(*_angles(label, asp), project_reflectance(r, light_1nm, grid))
                for asp, label, r in sample.geometries]
    flop = appearance.flop.refit_linear(measured)
    nb = grid.count

    def blocks(v):
        b = np.zeros(16)
        b[:nb] = v
        return b.reshape(4, 4)

    tex[0] = blocks(flop.diffuse)
    for k in range(min(3, len(flop.alphas))):
        tex[1 + k] = blocks(flop.lobes[k])
    alphas = np.zeros(3, np.float32)
    alphas[:len(flop.alphas)] = flop.alphas
    from lbscene.engine.coatings.colorimetry import luminance_weights

    lw = luminance_weights(grid)
    lobe_lum = np.zeros(3, np.float32)
    lobe_lum[:len(flop.alphas)] = flop.lobes @ lw
    values.update({"sample.coating": 1, "sample.coating_lobes": int(len(flop.alphas)),
                   "sample.coating_alphas": alphas,
                   "sample.coating_beckmann": 1 if flop.distribution == "beckmann" else 0,
                   "sample.lobe_luminance": lobe_lum, "sample.coat_n": float(flop.n), "sample.coat_diffuse_transmittance": diffuse_transmittance(flop.n)})
    info: dict = {"flop_alphas": [float(a) for a in flop.alphas], "distribution": flop.distribution}
    fl = appearance.flakes
    if fl is not None:
        r1 = getattr(sample, "flake_reflectance_1nm", None)
        rho = (project_reflectance(r1, light_1nm, grid) if r1 is not None
               else np.asarray(fl.flake_reflectance, float))
        tex[4] = blocks(rho)
        values["sample.flake_luminance"] = float(np.asarray(rho) @ lw)
        mean_i = (np.mean(np.asarray(emitter_bands, float), axis=0) if len(emitter_bands)
                  else np.zeros(nb))
        values["sample.glint_spectrum"] = np.ascontiguousarray(blocks(np.asarray(rho) * mean_i).ravel(), np.float32)
        values["sample.lamp_band_sum"] = float(max(mean_i.sum(), 1e-30))
        cell = flake_cell_mm(distance_mm, vertical_fov_deg)
        g = appearance.predicted.graininess if appearance.predicted is not None else 0.0
        blur_mm = GRAIN_BLUR_UM * 1e-3
        sigma = g / 100.0 * np.sqrt(4 * np.pi * blur_mm ** 2) / cell
        from lbscene.engine.coatings.optics import refract_into_coat

        ld = np.array([-np.sqrt(0.5), 0.0, np.sqrt(0.5)]) if light_dir is None else np.asarray(light_dir, float)
        vd = np.array([0.0, 0.0, 1.0]) if view_dir is None else np.asarray(view_dir, float)
        vis = float(fl.visibility(refract_into_coat(ld, fl.n), refract_into_coat(vd, fl.n)))
        values.update({"sample.flakes": 1, "sample.flake_density_per_mm2": float(fl.density_per_mm2),
                       "sample.flake_area_mm2": float(fl.mean_area_um2 * 1e-6 * vis),
                       "sample.flake_alpha": float(fl.alpha), "sample.flake_cell_mm": cell,
                       "sample.grain_sigma": float(sigma), "display.highlight_rolloff": 1})
        info.update({"flake_cell_mm": cell, "grain_sigma": float(sigma), "visible_share": vis,
                     "flakes_per_cell": float(fl.density_per_mm2 * cell * cell)})
    values["sample.coating_spectra"] = np.ascontiguousarray(tex[:4].reshape(-1), np.float32)
    return values, info
