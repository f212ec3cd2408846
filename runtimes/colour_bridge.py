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

Each prefers the colour module of this project (:mod:`lbscene.engine.colour`)
when it provides the function, and otherwise uses the fallback defined here
(documented next to each), so that the runtime works on its own.

Examples
--------
>>> import numpy as np
>>> from lbscene.engine.spectral import DEFAULT_GRID
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
    "void_and_cluster",
    "DisplayUniforms",
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
    from lbscene.engine.spectral import REFERENCE_WAVELENGTHS_NM as WL

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


def _grid_key(grid) -> tuple:
    return (float(grid.first_centre_nm), float(grid.width_nm), int(grid.count))


def radiance_xyz_weights(light_1nm: np.ndarray, grid) -> np.ndarray:
    """(B, 3) weights: XYZ (Y in cd·m⁻²) per unit band-mean radiance (W·sr⁻¹·m⁻²·nm⁻¹).

    ``W_b = 683·Σ_{λ∈b} E(λ)·cmf(λ)·1 nm / E_b`` with ``E`` the spectral irradiance
    (any scale) of the light falling on what is seen and ``E_b`` its band mean, so
    that for a band-constant reflectance ρ_b: ``Σ_b ρ_b·E_b/π·W_b`` equals
    ``683/π·Σ_λ ρ·E·cmf`` exactly.  Bands where the light is dark use an equal-energy
    light.  The colour module's ``band_weighting.band_xyz_weights(light_1nm, grid, k=683)``
    (the same definition) replaces this fallback when present.
    """
    from lbscene.engine.spectra import cmfs_1nm

    e = np.asarray(light_1nm, float)
    fn = _colour_attr("band_weighting", "band_xyz_weights")
    if fn is not None:
        return np.asarray(fn(e, grid, k=K_M), float)
    eb = grid.integrate(e)
    m = band_membership(*_grid_key(grid))
    w_refl = K_M * (m * e[None, :]) @ cmfs_1nm()
    flat = K_M * band_membership(*_grid_key(grid)) @ cmfs_1nm()
    dark = eb <= 1e-12 * max(float(eb.max()), 1e-300)
    with np.errstate(divide="ignore", invalid="ignore"):
        w = np.where(dark[:, None], flat, w_refl / np.where(dark, 1.0, eb)[:, None])
    return w


def project_reflectance(reflectance_1nm: np.ndarray, light_1nm: np.ndarray, grid) -> np.ndarray:
    """Band reflectances of a 1 nm reflectance for a light.

    The colour module's ``project_reflectance(reflectance_1nm, light_1nm, grid)`` when
    present; otherwise the band means plus the smallest correction (least norm) that
    makes ``Σ_b ρ_b·E_b·W_b`` equal the light's 1 nm tristimulus values
    ``683·Σ_λ ρ·E·cmf`` (W from :func:`radiance_xyz_weights`).
    """
    fn = _colour_attr("band_weighting", "project_reflectance")
    r = np.asarray(reflectance_1nm, float)
    e = np.asarray(light_1nm, float)
    if fn is not None:
        return np.asarray(fn(r, e, grid), float).ravel()
    from lbscene.engine.spectra import cmfs_1nm

    m = grid.integrate(r)
    a = grid.integrate(e)[:, None] * radiance_xyz_weights(e, grid)      # (B, 3)
    target = K_M * (r * e) @ cmfs_1nm()
    scale = np.abs(a).max(axis=0)
    scale[scale == 0] = 1.0
    an = a / scale                                                     # column scaling
    resid = (target - a.T @ m) / scale
    corr, *_ = np.linalg.lstsq(an.T, resid, rcond=None)
    return m + corr


# --------------------------------------------------------------------------- dithering

def void_and_cluster(size: int = 64, sigma: float = 1.5, seed: int = 0) -> np.ndarray:
    """Blue-noise threshold matrix (Ulichney 1993, void-and-cluster), values (rank + ½)/size²."""
    rng = np.random.default_rng(seed)
    n = size * size
    d = np.minimum(np.arange(size), size - np.arange(size)).astype(float)
    kernel = np.exp(-(d[:, None] ** 2 + d[None, :] ** 2) / (2 * sigma * sigma))

    def energy_of(pattern):
        return np.real(np.fft.ifft2(np.fft.fft2(pattern) * np.fft.fft2(kernel)))

    def add(en, idx, sign):
        i, j = divmod(idx, size)
        en += sign * np.roll(np.roll(kernel, i, axis=0), j, axis=1)

    pattern = np.zeros((size, size), bool)
    pattern.flat[rng.choice(n, n // 10, replace=False)] = True
    en = energy_of(pattern.astype(float))
    for _ in range(4 * n):  # relax: move the tightest cluster into the largest void
        c = int(np.argmax(np.where(pattern, en, -np.inf)))
        pattern.flat[c] = False
        add(en, c, -1.0)
        v = int(np.argmin(np.where(pattern, np.inf, en)))
        if v == c:
            pattern.flat[c] = True
            add(en, c, 1.0)
            break
        pattern.flat[v] = True
        add(en, v, 1.0)
    rank = np.zeros(n, int)
    ones = int(pattern.sum())
    p = pattern.copy()
    e = en.copy()
    for r in range(ones - 1, -1, -1):      # phase 1: remove tightest clusters
        c = int(np.argmax(np.where(p, e, -np.inf)))
        p.flat[c] = False
        add(e, c, -1.0)
        rank[c] = r
    p = pattern.copy()
    e = en.copy()
    for r in range(ones, n):               # phases 2 and 3: fill the largest voids
        v = int(np.argmin(np.where(p, np.inf, e)))
        p.flat[v] = True
        add(e, v, 1.0)
        rank[v] = r
    return ((rank.reshape(size, size) + 0.5) / n).astype(np.float32)


@lru_cache(maxsize=4)
def blue_noise_mask(size: int = 64) -> np.ndarray:
    """(size, size) float32 thresholds in [0, 1): the colour module's ``dither.blue_noise(size)``
    when present, else :func:`void_and_cluster`."""
    fn = _colour_attr("dither", "blue_noise")
    if fn is not None:
        m = np.asarray(fn(size), np.float32)
        return m[..., 0] if m.ndim == 3 else m
    return void_and_cluster(size)


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


def srgb_display(white_Y_cd_m2: float = 80.0) -> DisplayUniforms:
    """The sRGB reference display (IEC 61966-2-1: 80 cd/m² white; no flare, unlike
    ``displays/srgb-reference.yaml``, which adds the standard's viewing flare)."""
    return DisplayUniforms(name="sRGB (IEC 61966-2-1)", white_Y_cd_m2=white_Y_cd_m2,
                           xyz_to_rgb=SRGB_XYZ_TO_RGB / white_Y_cd_m2, xyz_offset=np.zeros(3),
                           tone_kind=0, source="builtin sRGB")


def display_uniforms(path=None) -> DisplayUniforms:
    """The display of a render configuration as shader uniforms.

    With the colour module's display model (``display_model.load_display(path)``
    returning a model with ``glsl_uniforms()``), its export is used; otherwise (or
    for ``path=None``) the built-in sRGB reference display.
    """
    load = _colour_attr("display_model", "load_display")
    if path is None or load is None:
        return srgb_display()
    model = load(path)
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
        source=f"colour module: {path}")
