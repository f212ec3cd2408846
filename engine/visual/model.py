"""
The model's ΔE00 of a visual-test case: how far the display's reproduction of the sample
is from the sample in the booth, as the model predicts it.

For a case (lighting, viewing geometry, sample) and a display:

1. the sample in the booth: spectral irradiance E(λ) at the sample for the view (the forward
   model, as the renderer uses it), reflectance factor R(λ) at the realised aspecular angle
   (linear between the measured geometries, as ``sample.frag`` does), radiance
   L = R·E/π, so XYZ_s = 683·∫ L·cmf dλ (cd/m²) and the white diffuser's XYZ_w = 683·∫ E/π·cmf dλ;
2. what the display emits for it: the exposure k (a white diffuser at ``white_fraction`` of the
   display's white), the display model's inverse with its gamut mapping, 8-bit quantisation,
   then its forward model: XYZ_d = display(round(255·drive(k·XYZ_s)) / 255);
3. ΔE00 between k·XYZ_s and XYZ_d in CIELAB relative to k·XYZ_w: the observer, adapted to the
   booth, compares the tablet with the sample (no chromatic adaptation of the display's colours).

This is the rendering error the observers judge in "Visual validation of the appearance of
chromatic objects rendered from spectrophotometric measurements", as this model predicts it;
``lbscene visual-report --model-de`` relates the panel's visual differences to it by STRESS.
"""

from __future__ import annotations

import numpy as np

__all__ = ["reflectance_at", "case_delta_e00"]


def reflectance_at(sample, aspecular_deg: float) -> np.ndarray:
    """R(λ) (1 nm) of a :class:`~lbscene.engine.scene.sample.SampleSpec` at an aspecular angle:
    linear between its measured geometries (sorted by angle), constant beyond them."""
    geoms = sorted(sample.geometries, key=lambda g: g[0])
    angles = np.array([g[0] for g in geoms], float)
    refl = np.stack([np.asarray(g[2], float) for g in geoms])
    if len(geoms) == 1:
        return refl[0]
    a = float(np.clip(aspecular_deg, angles[0], angles[-1]))
    j = int(np.clip(np.searchsorted(angles, a) - 1, 0, len(angles) - 2))
    t = (a - angles[j]) / max(angles[j + 1] - angles[j], 1e-12)
    return (1 - t) * refl[j] + t * refl[j + 1]


def case_delta_e00(irradiance_1nm, reflectance_1nm, display, *, display_path=None,
                   white_fraction: float = 1.0) -> float:
    """ΔE00 of one case (see the module's docstring); ``display``: the runtime's
    :class:`~lbscene.runtimes.colour_bridge.DisplayUniforms` (``display_path``: its
    document, for the colour module's display model; None: the sRGB reference display)."""
    import colour

    from lbscene.engine.spectra.evaluate import cmfs_1nm

    cmf = cmfs_1nm()
    e = np.asarray(irradiance_1nm, float)
    xyz_w = 683.0 / np.pi * (e @ cmf)
    xyz_s = 683.0 / np.pi * ((np.asarray(reflectance_1nm, float) * e) @ cmf)
    k = white_fraction * display.white_Y_cd_m2 / xyz_w[1] if xyz_w[1] > 0 else 1.0
    target = k * xyz_s
    if display_path is None:
        # sRGB reference display, white at display.white_Y_cd_m2, clipped
        lin = np.clip(target @ np.asarray(display.xyz_to_rgb, float).T, 0.0, 1.0)
        drive = colour.cctf_encoding(lin, function="sRGB")
        codes = np.round(drive * 255.0) / 255.0
        shown = colour.sRGB_to_XYZ(codes) * display.white_Y_cd_m2
    else:
        from lbscene.engine.colour.display_model import load_display

        model = load_display(display_path)
        drive = model.xyz_to_drive(target)
        shown = model.drive_to_xyz(np.round(drive * 255.0) / 255.0)
    white = k * xyz_w
    xy = colour.XYZ_to_xy(white)
    lab_s = colour.XYZ_to_Lab(target / white[1], xy)
    lab_d = colour.XYZ_to_Lab(np.asarray(shown, float) / white[1], xy)
    return float(colour.delta_E(lab_s, lab_d, method="CIE 2000"))
