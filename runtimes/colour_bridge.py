"""
What the runtime needs from colour science, in the form the shaders use.

* :func:`radiance_xyz_weights`: per-band XYZ weights for band-mean spectral
  radiance under a given light, so that ``XYZ = Σ_b L_b · W_b`` reproduces the
  1 nm integral ``683·Σ_λ L(λ)·cmf(λ)`` exactly for any reflectance that is
  constant within each band.
* :func:`project_reflectance`: band values of a 1 nm reflectance for a light,
  close to the band means but reproducing the light's 1 nm tristimulus values.
* :func:`blue_noise_mask`: dither thresholds in [0, 1).
* :func:`display_uniforms`: the display model as GLSL uniforms.

The colour science itself is the colour module's (:mod:`lbscene.engine.colour`);
this module puts it in the runtime's units and shapes.

Examples
--------
>>> import numpy as np
>>> from lbscene.engine.spectra.bands import DEFAULT_GRID
>>> w = radiance_xyz_weights(np.ones(471), DEFAULT_GRID)
>>> w.shape
(16, 3)
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import lru_cache

import numpy as np

__all__ = [
    "K_M",
    "band_membership",
    "radiance_xyz_weights",
    "project_reflectance",
    "blue_noise_mask",
    "DisplayUniforms",
    "D65_WHITE_XYZ",
    "srgb_display",
    "display_uniforms",
    "colour_module_features",
]

K_M = 683.0


def _colour_attr(module: str, name: str):
    """``lbscene.engine.colour.<module>.<name>`` when that exists, else None."""
    from importlib import import_module

    try:
        return getattr(import_module(f"lbscene.engine.colour.{module}"), name)
    except (ImportError, AttributeError):
        return None


def colour_module_features() -> dict[str, bool]:
    """Which colour-module functions this runtime found (reported by ``lbscene render``)."""
    return {
        "band_weighting.project_reflectance": _colour_attr("band_weighting", "project_reflectance") is not None,
        "band_weighting.band_xyz_weights": _colour_attr("band_weighting", "band_xyz_weights") is not None,
        "dither.blue_noise": _colour_attr("dither", "blue_noise") is not None,
        "display_model": _colour_attr("display_model", "load_display") is not None,
    }


# --------------------------------------------------------------------------- band weights

@lru_cache(maxsize=8)
def band_membership(first_centre_nm: float, width_nm: float, count: int) -> np.ndarray:
    """(count, 471) weights assigning each 1 nm sample to a band (halves on shared edges;
    light below the first / above the last edge goes to the first / last band)."""
    from lbscene.engine.spectra.bands import REFERENCE_WAVELENGTHS_NM as WL

    lo = first_centre_nm - width_nm / 2
    edges = lo + width_nm * np.arange(count + 1)
    a = np.zeros((count, WL.size))
    for b in range(count):
        inside = (WL > edges[b]) & (WL < edges[b + 1])
        a[b, inside] = 1.0
        a[b, WL == edges[b]] = 0.5 if b > 0 else 1.0
        a[b, WL == edges[b + 1]] = 0.5 if b < count - 1 else 1.0
    a[0, WL < edges[0]] = 1.0
    a[-1, WL > edges[-1]] = 1.0
    return a


def radiance_xyz_weights(light_1nm: np.ndarray, grid) -> np.ndarray:
    """(B, 3) weights: XYZ (Y in cd·m⁻²) per unit band-mean radiance (W·sr⁻¹·m⁻²·nm⁻¹).

    ``W_b = 683·Σ_{λ∈b} E(λ)·cmf(λ)·1 nm / E_b`` with ``E`` the spectral irradiance
    (any scale) of the light falling on what is seen and ``E_b`` its band mean, so
    that for a band-constant reflectance ρ_b: ``Σ_b ρ_b·E_b/π·W_b`` equals
    ``683/π·Σ_λ ρ·E·cmf`` exactly: the colour module's
    ``band_weighting.band_xyz_weights(light_1nm, grid, k=683)``.
    """
    from lbscene.engine.colour.band_weighting import band_xyz_weights

    return np.asarray(band_xyz_weights(np.asarray(light_1nm, float), grid, k=K_M), float)


def project_reflectance(reflectance_1nm: np.ndarray, light_1nm: np.ndarray, grid) -> np.ndarray:
    """Band reflectances of a 1 nm reflectance for a light (the colour module's
    ``band_weighting.project_reflectance``: close to the band means, reproducing the light's
    1 nm tristimulus values)."""
    from lbscene.engine.colour.band_weighting import project_reflectance as project

    return np.asarray(project(np.asarray(reflectance_1nm, float), np.asarray(light_1nm, float), grid),
                      float).ravel()


# --------------------------------------------------------------------------- dithering

@lru_cache(maxsize=4)
def blue_noise_mask(size: int = 64) -> np.ndarray:
    """(size, size) float32 thresholds in [0, 1): the colour module's ``dither.blue_noise(size)``."""
    from lbscene.engine.colour.dither import blue_noise

    m = np.asarray(blue_noise(size), np.float32)
    return m[..., 0] if m.ndim == 3 else m


# --------------------------------------------------------------------------- display

#: IEC 61966-2-1 XYZ → linear sRGB (D65).
SRGB_XYZ_TO_RGB = np.array([[3.2404542, -1.5371385, -0.4985314],
                            [-0.9692660, 1.8760108, 0.0415560],
                            [0.0556434, -0.2040259, 1.0572252]])


@dataclass
class DisplayUniforms:
    """The display model in shader form (see display.frag)."""

    name: str
    white_Y_cd_m2: float                 # luminance of drive (1, 1, 1)
    xyz_to_rgb: np.ndarray               # (3, 3): display XYZ (cd/m²) → linear channel 0..1
    xyz_offset: np.ndarray               # (3,): black + reflected ambient, cd/m²
    tone_kind: int = 0                   # 0 sRGB, 1 GOG, 2 LUT
    tone_params: np.ndarray = field(default_factory=lambda: np.tile([1.0, 0.0, 2.2, 0.0], (3, 1)))
    tone_lut: np.ndarray | None = None   # (n, 3) drive for linear i/(n−1)
    gamut_mapping: int = 1               # 0 clip, 1 chroma (constant luminance toward the neutral)
    y_span_cd_m2: float | None = None     # white − black luminance (default: white_Y_cd_m2)
    source: str = "builtin"
    #: XYZ (cd/m²) of the display's white as seen: the white chromatic adaptation aims at
    white_xyz_cd_m2: np.ndarray | None = None

    @property
    def adapted_white_xyz(self) -> np.ndarray:
        """The display's white (cd/m²); D65 at ``white_Y_cd_m2`` when not given."""
        if self.white_xyz_cd_m2 is not None:
            return np.asarray(self.white_xyz_cd_m2, float)
        return D65_WHITE_XYZ * self.white_Y_cd_m2

    @property
    def inv_y_span(self) -> float:
        return 1.0 / (self.y_span_cd_m2 or self.white_Y_cd_m2)

    @property
    def gamut_mapping_name(self) -> str:
        return ("clip: each linear channel clipped to [0, 1]" if self.gamut_mapping == 0 else
                "chroma: constant luminance, toward the display's neutral until it fits")

    def lut_texture(self) -> np.ndarray:
        """(1, n, 4) float32 for the tone_lut texture (a 2-entry identity when unused)."""
        lut = self.tone_lut if self.tone_lut is not None else np.array([[0.0] * 3, [1.0] * 3])
        out = np.zeros((1, len(lut), 4), np.float32)
        out[0, :, :3] = lut
        return out


#: CIE D65 at Y = 1 from its IEC 61966-2-1 chromaticity (0.3127, 0.3290).
D65_WHITE_XYZ = np.array([0.3127 / 0.3290, 1.0, (1.0 - 0.3127 - 0.3290) / 0.3290])


def srgb_display(white_Y_cd_m2: float = 80.0) -> DisplayUniforms:
    """The sRGB reference display (IEC 61966-2-1: 80 cd/m² white; no flare, unlike
    ``displays/srgb-reference.yaml``, which adds the standard's viewing flare)."""
    return DisplayUniforms(name="sRGB (IEC 61966-2-1)", white_Y_cd_m2=white_Y_cd_m2,
                           xyz_to_rgb=SRGB_XYZ_TO_RGB / white_Y_cd_m2, xyz_offset=np.zeros(3),
                           tone_kind=0, source="builtin sRGB")


def display_uniforms(path=None) -> DisplayUniforms:
    """The display of a render configuration as shader uniforms.

    The colour module's display model (``display_model.load_display(path)``) exported by
    its ``glsl_uniforms()``; for ``path=None`` the built-in sRGB reference display.
    """
    if path is None:
        return srgb_display()
    from lbscene.engine.colour.display_model import load_display

    model = load_display(path)
    u = model.glsl_uniforms()
    return DisplayUniforms(
        gamut_mapping=int(u.get("gamut_mapping", 1)),
        y_span_cd_m2=float(u.get("y_span_cd_m2", u["white_Y_cd_m2"])),
        name=str(u.get("name", getattr(model, "name", "display"))),
        white_Y_cd_m2=float(u["white_Y_cd_m2"]),
        xyz_to_rgb=np.asarray(u["xyz_to_rgb"], float).reshape(3, 3),
        xyz_offset=np.asarray(u.get("xyz_offset", np.zeros(3)), float).reshape(3),
        tone_kind=int(u.get("tone_kind", 0)),
        tone_params=np.asarray(u.get("tone_params", np.tile([1.0, 0.0, 2.2, 0.0], (3, 1))),
                               float).reshape(3, 4),
        tone_lut=None if u.get("tone_lut") is None else np.asarray(u["tone_lut"], float).reshape(-1, 3),
        white_xyz_cd_m2=np.asarray(u["xyz_white_seen"], float).reshape(3),
        source=f"colour module: {path}")
