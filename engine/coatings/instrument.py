"""
lbscene's texture instrument: simulated camera images of explicit flakes and the image analysis
that turns them into sparkle area, sparkle intensity and graininess.

A BYK-mac i style instrument photographs the sample with a camera along the normal, under
directional light at 15°, 45° and 75° (sparkle) and under diffuse light (graininess), and reports
sparkle area :math:`S_a`, sparkle intensity :math:`S_i` and graininess :math:`G`.  Its image analysis
is not published; lbscene computes its own, from published descriptions of what these numbers
measure (the area of the bright spots, their brightness, the contrast of the light/dark pattern
under diffuse light), on images it simulates.  **The numbers are on lbscene's scale.**

The simulated instrument
------------------------
* Camera along the normal (orthographic), pixels of ``PIXEL_UM`` (10 µm); the sparkle images
  cover ``SPARKLE_FIELD_MM`` × ``SPARKLE_FIELD_MM`` (60 mm; only the flakes that can glint are drawn, :class:`GlintPool`), the diffuse image ``GRAIN_FIELD_MM``
  square (4 mm; periodic edges).
* Directional light: a uniform disc source of half-angle ``SOURCE_HALF_ANGLE_DEG`` (2.5°) at
  illumination θ in the x–z plane; sample irradiance :math:`E = L\\, π \\sin^2 δ \\cos θ`.
* Diffuse light: a uniform dome with the camera's port (half-angle ``PORT_HALF_ANGLE_DEG``, 5°)
  black.
* Image values are reflectance factors :math:`R = π L_{pixel} / E` (1: a white diffuser).

Every flake is a disc (log-normal diameter, Beckmann normal, uniform position; the counts are
the expected :math:`ρ_A A`).  Seen along the normal, a flake reflects the one direction
:math:`\\mathbf r' = 2(\\mathbf m\\cdot\\mathbf z)\\mathbf m − \\mathbf z` inside the coat, which leaves
the coat as :math:`\\mathbf r` (Snell) or is totally reflected back.  Under the directional light a
flake glints when :math:`\\mathbf r` lies in the source's disc; its pixels then read
:math:`R = π ρ_f T(θ_r) T(0)\\, c / (π \\sin^2 δ \\cos θ)` with :math:`c` the share of the pixel it
covers (its projected area times its visible share :math:`s(u)`, the flakes above it hiding the
rest: :mod:`~lbscene.engine.coatings.flakes`; spread over 16 points of the disc).  The base between flakes reads its
diffuse reflectance :math:`a\\, T(θ)\\, T(0)/n^2` times the uncovered fraction.  Under the dome, a flake
whose :math:`\\mathbf r` leaves the coat outside the port reads :math:`ρ_f T(θ_r) T(0)`, inside the port
0, and one whose :math:`\\mathbf r'` is totally reflected sees, by that reflection, the layer
itself: it reads :math:`ρ_f` times the image's mean (a fixed point); the base reads :math:`a \\bar T T(0)/n^2`
(:math:`\\bar T`: the interface's transmittance for diffuse light).  Not modelled: the shape of what
hides a glint (its visible share is spread over its disc), light between flakes and the coat's
underside other than the total reflection above; in the diffuse image the flakes' coverages add,
capped at 1.

The analysis
------------
* **Sparkle area** :math:`S_a`: glint pixels (:math:`R >` ``GLINT_THRESHOLD``, 5 × a white
  diffuser) per thousand pixels.
* **Sparkle intensity** :math:`S_i`: mean :math:`R` of the glint pixels / 10.
* **Graininess** :math:`G`: the contrast, in per cent, of the diffuse image seen at the scale of the
  eye at reading distance — the standard deviation of the image blurred by a Gaussian of
  ``GRAIN_BLUR_UM`` (50 µm, about 1 arcmin at 20 cm) over its mean.

References
----------
.. [1] E. Kirchner, G.-J. van den Kieboom, L. Njo, R. Supèr, R. Gottenbos, "Observation of visual
   texture of metallic and pearlescent materials", Color Research & Application 32 (2007)
   (graininess under diffuse light, sparkle under directional light).
.. [2] A. Ferrero et al., "Preliminary measurement scales for sparkle and graininess", Optics
   Express 29 (2021).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .flakes import FlakeModel, sample_normals
from .optics import diffuse_transmittance, fresnel_transmittance, refract_into_coat

__all__ = [
    "MODEL_VERSION",
    "PIXEL_UM",
    "SPARKLE_FIELD_MM",
    "GRAIN_FIELD_MM",
    "SOURCE_HALF_ANGLE_DEG",
    "PORT_HALF_ANGLE_DEG",
    "GLINT_THRESHOLD",
    "GRAIN_BLUR_UM",
    "FlakePool",
    "GlintPool",
    "TextureMetrics",
    "reflected_directions",
    "Glints",
    "sparkle_glints",
    "sparkle_image",
    "dense_sparkle_image",
    "diffuse_image",
    "analyse_sparkle",
    "analyse_graininess",
    "texture_metrics",
]

#: bump when the simulated instrument or the flake model changes what it reads (cached fits)
MODEL_VERSION = "coating-instrument-2"
PIXEL_UM = 10.0
SPARKLE_FIELD_MM = 60.0
GRAIN_FIELD_MM = 4.0
SOURCE_HALF_ANGLE_DEG = 2.5
PORT_HALF_ANGLE_DEG = 5.0
GLINT_THRESHOLD = 5.0
GRAIN_BLUR_UM = 50.0
#: points per flake disc when its area is spread over pixels (sunflower pattern)
DISC_POINTS = 16
_CHUNK = 1 << 16


def _disc_points(k: int = DISC_POINTS) -> np.ndarray:
    i = np.arange(k) + 0.5
    r = np.sqrt(i / k)
    t = i * np.pi * (3.0 - np.sqrt(5.0))
    return np.stack([r * np.cos(t), r * np.sin(t)], -1)


class FlakePool:
    """Seeded standard random numbers of flakes (common random numbers for a fit): flake ``i``
    has the same position (unit square), size quantile and slopes whatever the parameters, and a
    field of density ρ uses the first ``round(ρ A)`` of them."""

    def __init__(self, seed: int = 0):
        self.seed = int(seed)
        self._rng = np.random.default_rng(self.seed)
        self._pos = np.zeros((0, 2))
        self._z = np.zeros(0)
        self._slopes = np.zeros((0, 2))

    def take(self, count: int):
        while len(self._z) < count:
            r = self._rng
            self._pos = np.concatenate([self._pos, r.random((_CHUNK, 2))])
            self._z = np.concatenate([self._z, r.standard_normal(_CHUNK)])
            self._slopes = np.concatenate([self._slopes, r.standard_normal((_CHUNK, 2))])
        return self._pos[:count], self._z[:count], self._slopes[:count]


class GlintPool:
    """Seeded uniforms for the flakes of a large sparkle field that can glint.

    A flake glints only if its slopes fall in a box ``B`` around the source's reflection; the
    slopes are independent normals, so the number of the field's ``N`` flakes inside ``B`` is
    binomial with :math:`P_B = \\prod_{x,y} [Φ(b_1/σ) − Φ(b_0/σ)]` (σ = α/√2), drawn by inverse
    CDF from one fixed uniform, and their slopes are drawn inside ``B`` by the inverse normal
    CDF from fixed uniforms.  This is the explicit-flake field in distribution (every flake
    outside ``B`` is dark), at the cost of the flakes inside ``B`` only."""

    def __init__(self, seed: int = 0):
        self.seed = int(seed)
        self._streams: dict[float, tuple[float, np.random.Generator, list]] = {}

    def draw(self, key: float, n_flakes: int, p_box: float):
        from scipy.stats import binom

        if key not in self._streams:
            rng = np.random.default_rng([self.seed, int(round(key * 1000))])
            self._streams[key] = (float(rng.random()), rng, [np.zeros((0, 6))])
        u0, rng, buf = self._streams[key]
        k = int(binom.ppf(u0, n_flakes, min(max(p_box, 0.0), 1.0))) if n_flakes > 0 else 0
        while len(buf[0]) < k:
            buf[0] = np.concatenate([buf[0], rng.random((max(4096, k - len(buf[0])), 6))])
        return buf[0][:k]


def _slope_box(src: np.ndarray, half_angle_deg: float, n: float, margin: float = 0.02):
    """Bounding box, in slope space (−m_x/m_z, −m_y/m_z), of the normals that reflect the
    camera's direction (+z) into the source's cone."""
    from .optics import refract_into_coat

    d = np.radians(half_angle_deg)
    u = np.cross(src, [0.0, 1.0, 0.0])
    u /= np.linalg.norm(u)
    w = np.cross(src, u)
    t = np.linspace(0, 2 * np.pi, 96, endpoint=False)
    ring = (np.cos(d) * src[None] + np.sin(d) * (np.cos(t)[:, None] * u + np.sin(t)[:, None] * w))
    ring = np.vstack([ring, src])
    ring = ring[ring[:, 2] > 1e-6]
    r_in = refract_into_coat(ring, n)
    m = r_in + np.array([0.0, 0.0, 1.0])
    s = -m[:, :2] / m[:, 2:3]
    lo, hi = s.min(0), s.max(0)
    pad = margin + 0.02 * (hi - lo)
    return lo - pad, hi + pad


def reflected_directions(m: np.ndarray, n: float):
    """For a camera along +z: the direction a flake of normal ``m`` reflects inside the coat,
    whether it leaves the coat, and its direction in air (z up)."""
    r_in = np.stack([2 * m[:, 2] * m[:, 0], 2 * m[:, 2] * m[:, 1], 2 * m[:, 2] ** 2 - 1], -1)
    t = r_in[:, :2] * n
    s2 = (t * t).sum(-1)
    leaves = (r_in[:, 2] > 0) & (s2 < 1.0)
    r_air = np.concatenate([t, np.sqrt(np.clip(1 - s2, 0, None))[:, None]], -1)
    return r_in, leaves, r_air


def _flakes(model: FlakeModel, pool: FlakePool, side_mm: float):
    count = int(round(model.density_per_mm2 * side_mm * side_mm))
    pos, z, slopes = pool.take(count)
    d_um = model.median_diameter_um * np.exp(model.diameter_spread * z)
    m = sample_normals(slopes, model.alpha)
    return pos * side_mm * 1000.0, d_um, m


def _splat(shape, pos_um, d_um, weights_px):
    """Spread each flake's weight over DISC_POINTS points of its disc; pixel grid periodic."""
    ny, nx = shape
    pts = _disc_points()
    out = np.zeros(ny * nx)
    if len(pos_um) == 0:
        return out.reshape(shape)
    p = pos_um[:, None, :] + pts[None] * (d_um[:, None, None] / 2)
    ix = np.floor(p[..., 0] / PIXEL_UM).astype(np.int64) % nx
    iy = np.floor(p[..., 1] / PIXEL_UM).astype(np.int64) % ny
    w = np.repeat((weights_px / DISC_POINTS)[:, None], DISC_POINTS, 1)
    out += np.bincount((iy * nx + ix).ravel(), weights=w.ravel(), minlength=ny * nx)
    return out.reshape(shape)


@dataclass
class Glints:
    """The glinting flakes of a sparkle field: centres (µm), diameters (µm), visible projected
    area over the pixel area, and the reflectance factor of a pixel the flake would cover
    entirely."""

    centres_um: np.ndarray
    diameters_um: np.ndarray
    pixel_fraction: np.ndarray
    full_pixel_value: np.ndarray
    flakes_in_field: int
    candidates: int


def sparkle_glints(model: FlakeModel, illumination_deg: float, pool: GlintPool,
                   flake_reflectance: float | None = None, field_mm: float = SPARKLE_FIELD_MM,
                   source_half_angle_deg: float = SOURCE_HALF_ANGLE_DEG) -> Glints:
    """The flakes of the field that glint under the disc source at ``illumination_deg``."""
    from scipy.special import ndtr, ndtri

    n = model.n
    rho = float(np.mean(model.flake_reflectance)) if flake_reflectance is None else float(flake_reflectance)
    th = np.radians(illumination_deg)
    src = np.array([-np.sin(th), 0.0, np.cos(th)])
    cos_delta = np.cos(np.radians(source_half_angle_deg))
    proj_omega = np.pi * np.sin(np.radians(source_half_angle_deg)) ** 2 * np.cos(th)
    sigma = model.alpha / np.sqrt(2.0)
    lo, hi = _slope_box(src, source_half_angle_deg, n)
    c0, c1 = ndtr(lo / sigma), ndtr(hi / sigma)
    p_box = float(np.prod(c1 - c0))
    total = int(round(model.density_per_mm2 * field_mm ** 2))
    u = pool.draw(float(illumination_deg), total, p_box)
    slopes = sigma * ndtri(np.clip(c0 + u[:, 0:2] * (c1 - c0), 1e-300, 1 - 1e-16))
    m = np.concatenate([-slopes, np.ones((len(u), 1))], -1)
    m /= np.linalg.norm(m, axis=-1, keepdims=True)
    _, leaves, r_air = reflected_directions(m, n)
    glint = leaves & (r_air @ src >= cos_delta)
    d = model.median_diameter_um * np.exp(model.diameter_spread * ndtri(np.clip(u[glint, 4], 1e-12, 1 - 1e-12)))
    value = (np.pi * rho * fresnel_transmittance(r_air[glint, 2], n) * fresnel_transmittance(1.0, n)
             / proj_omega)
    # the glint's visible share: the flakes above it hide part of it (FlakeModel.visible_share)
    share = model.visible_share(u[glint, 5], refract_into_coat(src, n)[None, :], np.array([[0.0, 0.0, 1.0]]))
    return Glints(u[glint, 2:4] * field_mm * 1000.0, d,
                  np.pi / 4 * d ** 2 * m[glint, 2] * share / PIXEL_UM ** 2, value, total, len(u))


def sparkle_image(model: FlakeModel, base_diffuse: float, illumination_deg: float, pool: GlintPool,
                  flake_reflectance: float | None = None, field_mm: float = SPARKLE_FIELD_MM,
                  source_half_angle_deg: float = SOURCE_HALF_ANGLE_DEG):
    """Sparse reflectance-factor image under the directional source at ``illumination_deg``:
    ``(values, pixels, background)``, the values of the pixels a glint touches, the image's
    pixel count and the value of every other pixel.

    ``base_diffuse``: the flop model's diffuse term :math:`a` (luminance); ``flake_reflectance``:
    :math:`ρ_f` (luminance; default the model's band mean)."""
    n = model.n
    th = np.radians(illumination_deg)
    npx = int(round(field_mm * 1000 / PIXEL_UM))
    t_base = fresnel_transmittance(np.cos(th), n) * fresnel_transmittance(1.0, n) / n ** 2
    background = base_diffuse * t_base * max(0.0, 1.0 - min(model.coverage, 1.0))
    g = sparkle_glints(model, illumination_deg, pool, flake_reflectance, field_mm, source_half_angle_deg)
    if len(g.diameters_um) == 0:
        return np.zeros(0), npx * npx, background
    pts = _disc_points()
    p = g.centres_um[:, None, :] + pts[None] * (g.diameters_um[:, None, None] / 2)
    idx = ((np.floor(p[..., 1] / PIXEL_UM).astype(np.int64) % npx) * npx
           + np.floor(p[..., 0] / PIXEL_UM).astype(np.int64) % npx)
    w = np.repeat((g.pixel_fraction * g.full_pixel_value / DISC_POINTS)[:, None], DISC_POINTS, 1)
    uniq, inv = np.unique(idx.ravel(), return_inverse=True)
    vals = np.bincount(inv, weights=w.ravel(), minlength=len(uniq)) + background
    return vals, npx * npx, background


def diffuse_image(model: FlakeModel, base_diffuse: float, pool: FlakePool,
                  flake_reflectance: float | None = None, field_mm: float = GRAIN_FIELD_MM,
                  port_half_angle_deg: float = PORT_HALF_ANGLE_DEG) -> np.ndarray:
    """Reflectance-factor image under the diffuse dome (camera port black)."""
    n = model.n
    rho = float(np.mean(model.flake_reflectance)) if flake_reflectance is None else float(flake_reflectance)
    pos, d, m = _flakes(model, pool, field_mm)
    _, leaves, r_air = reflected_directions(m, n)
    t0 = fresnel_transmittance(1.0, n)
    base = base_diffuse * diffuse_transmittance(n) * t0 / n ** 2
    in_port = r_air[:, 2] > np.cos(np.radians(port_half_angle_deg))
    r_esc = np.where(in_port, 0.0, rho * fresnel_transmittance(r_air[:, 2], n) * t0)
    npx = int(round(field_mm * 1000 / PIXEL_UM))
    a_px = np.pi / 4 * d ** 2 * m[:, 2] / PIXEL_UM ** 2
    cov = _splat((npx, npx), pos, d, a_px)
    over = cov > 1.0
    lit_esc = _splat((npx, npx), pos, d, a_px * np.where(leaves, r_esc, 0.0))
    tir = _splat((npx, npx), pos, d, a_px * np.where(leaves, 0.0, rho))
    lit_esc[over] /= cov[over]
    tir[over] /= cov[over]
    rest = base * np.clip(1.0 - cov, 0.0, None)
    # a flake whose reflection is totally reflected by the coat sees the layer itself: the mean
    # of the image (a fixed point, R_TIR = ρ · mean R)
    mean = float((lit_esc + rest).mean()) / max(1.0 - float(tir.mean()), 1e-6)
    return lit_esc + tir * mean + rest


def analyse_sparkle(image) -> tuple[float, float]:
    """(S_a, S_i) of a sparkle image (module docstring): a dense array, or the sparse
    ``(values, pixel_count, background)`` of :func:`sparkle_image`."""
    if isinstance(image, tuple):
        vals, count, background = image
    else:
        vals, count, background = np.asarray(image, float).ravel(), image.size, 0.0
    if background > GLINT_THRESHOLD:
        raise ValueError("the background is above the glint threshold")
    g = vals > GLINT_THRESHOLD
    s_a = 1000.0 * g.sum() / count
    s_i = float(vals[g].mean()) / 10.0 if g.any() else 0.0
    return float(s_a), s_i


def analyse_graininess(img: np.ndarray) -> float:
    """G of a diffuse image (module docstring)."""
    from scipy.ndimage import gaussian_filter

    b = gaussian_filter(img, GRAIN_BLUR_UM / PIXEL_UM, mode="wrap")
    return float(100.0 * b.std() / max(b.mean(), 1e-12))


@dataclass
class TextureMetrics:
    """Sparkle (S_a, S_i) per illumination angle and graininess G, on lbscene's scale."""

    sparkle: dict[float, tuple[float, float]] = field(default_factory=dict)
    graininess: float = float("nan")

    def to_json(self) -> dict:
        return {"sparkle": [{"illumination_deg": a, "area": round(s[0], 4), "intensity": round(s[1], 4)}
                            for a, s in sorted(self.sparkle.items())],
                "graininess": round(self.graininess, 4)}


def texture_metrics(model: FlakeModel, base_diffuse: float, seed: int = 0,
                    angles_deg=(15.0, 45.0, 75.0), flake_reflectance: float | None = None,
                    pools: tuple[GlintPool, FlakePool] | None = None) -> TextureMetrics:
    """Simulate the instrument's images of ``model`` and analyse them.

    ``base_diffuse`` and ``flake_reflectance`` are luminance values (see
    :func:`lbscene.engine.coatings.colorimetry.luminance_weights`)."""
    sp, dp = pools or (GlintPool(seed), FlakePool(seed + 7919))
    out = TextureMetrics()
    for a in angles_deg:
        out.sparkle[float(a)] = analyse_sparkle(sparkle_image(model, base_diffuse, a, sp, flake_reflectance))
    out.graininess = analyse_graininess(diffuse_image(model, base_diffuse, dp, flake_reflectance))
    return out


def dense_sparkle_image(model: FlakeModel, base_diffuse: float, illumination_deg: float, pool: GlintPool,
                        flake_reflectance: float | None = None, field_mm: float = SPARKLE_FIELD_MM,
                        source_half_angle_deg: float = SOURCE_HALF_ANGLE_DEG) -> np.ndarray:
    """:func:`sparkle_image` as a full (npx, npx) array (for analyses that need neighbours)."""
    n = model.n
    th = np.radians(illumination_deg)
    npx = int(round(field_mm * 1000 / PIXEL_UM))
    t_base = fresnel_transmittance(np.cos(th), n) * fresnel_transmittance(1.0, n) / n ** 2
    background = base_diffuse * t_base * max(0.0, 1.0 - min(model.coverage, 1.0))
    g = sparkle_glints(model, illumination_deg, pool, flake_reflectance, field_mm, source_half_angle_deg)
    img = _splat((npx, npx), g.centres_um, g.diameters_um, g.pixel_fraction * g.full_pixel_value)
    return img + background
