"""
Explicit flakes rendered by Mitsuba 3: the outside truth of the flake model's glints.

lbscene's texture model (:mod:`~lbscene.engine.coatings.flakes`,
:mod:`~lbscene.engine.coatings.instrument`) decides which flake glints with a mirror law and a
closed-form probability, and ignores what happens between flakes.  This module builds the
physical scene instead and hands it to an independent path tracer:

===================  ==========================================================
element              Mitsuba 3
===================  ==========================================================
flakes               one triangle mesh of octagons (area of the disc of the
                     flake's diameter), each at its position, its normal and a
                     height uniform through the effect layer (``layer_um``
                     above the base); ``twosided`` ``conductor``
                     (perfect mirror) scaled by the flake reflectance
clear coat           a ``dielectric`` plane (interior index n, air outside)
                     ``thickness_um`` above the base
base                 a ``diffuse`` plane of the base's reflectance
directional light    a ``disk`` area emitter 1 m away, of half-angle δ, radiance
                     :math:`L = 1/(π \\sin^2 δ \\cos θ)` so that the sample's
                     irradiance is 1 (pixel values are then reflectance factors)
diffuse light        a ``constant`` environment of radiance 1
camera               ``orthographic`` along the normal, one pixel per
                     ``PIXEL_UM`` (the instrument's camera)
===================  ==========================================================

The path tracer resolves what the model leaves out: flakes shadowing and hiding one another,
light reflected between the coat's underside, flakes and base, the Fresnel split at the coat.
Statistics of the glints (their density, the distribution of their flux, their change with
illumination angle and lamp size) are compared, not pixels: :func:`glint_statistics`.

The flakes are drawn here from the declared distributions (uniform positions, log-normal
diameters, Beckmann normals) with their own seed.  Mitsuba's ``scalar_rgb`` variant renders
them (the scene is grey, flat spectra, so RGB is exact; the scalar variants need neither LLVM
nor CUDA).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .flakes import FlakeModel, sample_normals

__all__ = ["FlakeScene", "make_flakes", "render_sparkle", "render_diffuse", "glint_statistics",
           "TRUTH_CONFIG", "truth_flake_model", "reference_statistics",
           "graininess_from_pair", "mitsuba_variant"]

PIXEL_UM = 10.0
#: distance of the disc source (mm)
SOURCE_DISTANCE_MM = 1000.0


VARIANT = "scalar_rgb"


def mitsuba_variant() -> str:
    """Select Mitsuba's ``scalar_rgb`` variant (no LLVM or CUDA needed) and return its name."""
    import mitsuba as mi

    if mi.variant() != VARIANT:
        mi.set_variant(VARIANT)
    return VARIANT


@dataclass(frozen=True)
class FlakeScene:
    """Explicit flakes of a square field (µm, centred on the origin)."""

    centres_um: np.ndarray     # (N, 3): x, y, height above the base
    normals: np.ndarray        # (N, 3)
    diameters_um: np.ndarray   # (N,)
    field_mm: float
    flake_reflectance: float
    base_reflectance: float
    n: float
    coat_um: float


def make_flakes(model: FlakeModel, field_mm: float, seed: int, base_reflectance: float,
                coat_um: float = 40.0, flake_reflectance: float | None = None) -> FlakeScene:
    """Draw the flakes of a ``field_mm`` square from ``model``'s distributions."""
    rng = np.random.default_rng(seed)
    count = int(rng.poisson(model.density_per_mm2 * field_mm ** 2))
    side = field_mm * 1000.0
    xy = (rng.random((count, 2)) - 0.5) * side
    d = model.median_diameter_um * np.exp(model.diameter_spread * rng.standard_normal(count))
    m = sample_normals(rng.standard_normal((count, 2)), model.alpha)
    # centres uniform through the effect layer (FlakeModel.layer_um) above the base; a tilted flake
    # is kept inside the coat
    half_h = d / 2 * np.sqrt(np.clip(1 - m[:, 2] ** 2, 0, None))      # vertical half extent
    z = np.clip(rng.random(count) * model.layer_um, half_h + 0.5, coat_um - 1.0 - half_h)
    rho = float(np.mean(model.flake_reflectance)) if flake_reflectance is None else float(flake_reflectance)
    return FlakeScene(np.c_[xy, z], m, d, field_mm, rho, float(base_reflectance), model.n, coat_um)


def _octagons(fs: FlakeScene):
    """Vertices (mm) and faces of one octagon per flake (area π d²/4)."""
    k = 8
    r = fs.diameters_um / 2 * np.sqrt(np.pi / (k / 2 * np.sin(2 * np.pi / k)))
    m = fs.normals
    a = np.cross(m, np.where(np.abs(m[:, :1]) < 0.9, [[1.0, 0, 0]], [[0, 1.0, 0]]))
    a /= np.linalg.norm(a, axis=1, keepdims=True)
    b = np.cross(m, a)
    t = 2 * np.pi * np.arange(k) / k
    ring = (np.cos(t)[None, :, None] * a[:, None, :] + np.sin(t)[None, :, None] * b[:, None, :])
    verts = np.concatenate([fs.centres_um[:, None, :], fs.centres_um[:, None, :] + r[:, None, None] * ring], 1)
    base = (np.arange(len(m)) * (k + 1))[:, None]
    faces = np.stack([np.zeros(k, int), 1 + np.arange(k), 1 + (np.arange(k) + 1) % k], -1)
    faces = (faces[None] + base[:, :, None]).reshape(-1, 3)
    return verts.reshape(-1, 3) * 1e-3, faces


def _write_ply(path, verts: np.ndarray, faces: np.ndarray) -> None:
    """Binary little-endian PLY of a triangle mesh (what Mitsuba's ``ply`` shape reads)."""
    head = ("ply\nformat binary_little_endian 1.0\n"
            f"element vertex {len(verts)}\nproperty float x\nproperty float y\nproperty float z\n"
            f"element face {len(faces)}\nproperty list uchar int vertex_indices\nend_header\n")
    f = np.zeros(len(faces), dtype=[("n", "u1"), ("i", "<i4", (3,))])
    f["n"] = 3
    f["i"] = faces
    with open(path, "wb") as fh:
        fh.write(head.encode("ascii"))
        fh.write(np.ascontiguousarray(verts, "<f4").tobytes())
        fh.write(f.tobytes())


def _scene_dict(fs: FlakeScene, emitter: dict, spp: int, seed: int, ply_path) -> dict:
    import mitsuba as mi

    verts, faces = _octagons(fs)
    _write_ply(ply_path, verts, faces)
    big = 20.0 * max(fs.field_mm, 1.0)
    npx = int(round(fs.field_mm * 1000 / PIXEL_UM))
    half = fs.field_mm / 2
    T = mi.ScalarTransform4f
    return {
        "type": "scene",
        "integrator": {"type": "path", "max_depth": 12, "hide_emitters": True},
        "sensor": {"type": "orthographic",
                   "to_world": T().look_at(origin=[0, 0, 5.0], target=[0, 0, 0], up=[0, 1, 0])
                   @ T().scale([half, half, 1.0]),
                   "near_clip": 0.1, "far_clip": 20.0,
                   "sampler": {"type": "independent", "sample_count": spp, "seed": seed},
                   "film": {"type": "hdrfilm", "width": npx, "height": npx, "pixel_format": "rgb",
                            "rfilter": {"type": "box"}}},
        "flakes": {"type": "ply", "filename": str(ply_path), "face_normals": True,
                   "bsdf": {"type": "twosided", "bsdf": {
                       "type": "conductor", "material": "none",
                       "specular_reflectance": {"type": "rgb", "value": [fs.flake_reflectance] * 3}}}},
        "base": {"type": "rectangle", "to_world": T().scale([big, big, 1.0]),
                 "bsdf": {"type": "diffuse", "reflectance": {"type": "rgb", "value": [fs.base_reflectance] * 3}}},
        "coat": {"type": "rectangle", "to_world": T().translate([0, 0, fs.coat_um * 1e-3]) @ T().scale([big, big, 1.0]),
                 "bsdf": {"type": "dielectric", "int_ior": fs.n, "ext_ior": 1.0}},
        "light": emitter,
    }


def _render(fs: FlakeScene, emitter: dict, spp: int, seed: int) -> np.ndarray:
    import tempfile
    from pathlib import Path

    import mitsuba as mi

    mitsuba_variant()
    with tempfile.TemporaryDirectory(prefix="lbscene-flakes-") as tmp:
        scene = mi.load_dict(_scene_dict(fs, emitter, spp, seed, Path(tmp) / "flakes.ply"))
        img = np.asarray(mi.render(scene, spp=spp, seed=seed), float)
    # grey scene: the mean of the three equal channels; rows run from +y (top) to −y
    return img[..., :3].mean(-1)


def render_sparkle(fs: FlakeScene, illumination_deg: float, half_angle_deg: float = 2.5,
                   spp: int = 32, seed: int = 0) -> np.ndarray:
    """Reflectance-factor image under a disc source of ``half_angle_deg`` at ``illumination_deg``
    in the x–z plane (light on the −x side).

    The base is made black here: a path tracer reaches a small source from a diffuse base under a
    dielectric coat only by chance (no light sampling through a smooth interface), so a lit base
    would be a field of rare bright samples above the glint threshold.  The base's share of the
    image is a smooth background the model knows in closed form."""
    import dataclasses

    import mitsuba as mi

    fs = dataclasses.replace(fs, base_reflectance=0.0)

    mitsuba_variant()
    th, dl = np.radians(illumination_deg), np.radians(half_angle_deg)
    l = np.array([-np.sin(th), 0.0, np.cos(th)])
    radius = SOURCE_DISTANCE_MM * np.tan(dl)
    # the disc subtends δ from the sample; radiance for unit irradiance
    radiance = 1.0 / (np.pi * np.sin(dl) ** 2 * np.cos(th))
    T = mi.ScalarTransform4f
    c = l * SOURCE_DISTANCE_MM
    emitter = {"type": "disk",
               "to_world": T().look_at(origin=c.tolist(), target=[0, 0, 0], up=[0, 1, 0]) @ T().scale([radius] * 3),
               "emitter": {"type": "area", "radiance": {"type": "rgb", "value": [radiance] * 3}}}
    return np.pi * _render(fs, emitter, spp, seed)


def render_diffuse(fs: FlakeScene, spp: int = 128, seed: int = 0) -> np.ndarray:
    """Reflectance-factor image under a uniform dome (radiance 1: pixel radiance is R)."""
    return _render(fs, {"type": "constant", "radiance": {"type": "rgb", "value": [1.0, 1.0, 1.0]}}, spp, seed)


def glint_statistics(img: np.ndarray, threshold: float = 5.0, pixel_um: float = PIXEL_UM) -> dict:
    """Glints of a sparkle image: connected pixels above ``threshold``.

    Returns their number per mm², each glint's flux (the sum over its pixels of the value above
    the image's median, in reflectance-factor × pixels) and peak, and S_a, S_i as
    :func:`lbscene.engine.coatings.instrument.analyse_sparkle` reads them."""
    from scipy import ndimage

    from .instrument import analyse_sparkle

    bg = float(np.median(img))
    mask = img > threshold
    lab, k = ndimage.label(mask, structure=np.ones((3, 3)))
    # a glint is the flake's whole image: the pixels around the thresholded core count too
    grown = ndimage.grey_dilation(lab, size=(3, 3)) * (img > bg + 0.5 * (threshold - bg))
    idx = np.arange(1, k + 1)
    flux = np.asarray(ndimage.sum(img - bg, grown, idx)) if k else np.zeros(0)
    peak = np.asarray(ndimage.maximum(img, lab, idx)) if k else np.zeros(0)
    area_mm2 = img.size * (pixel_um * 1e-3) ** 2
    s_a, s_i = analyse_sparkle(img)
    return {"count": int(k), "density_per_mm2": k / area_mm2, "flux": flux, "peak": peak,
            "background": bg, "S_a": s_a, "S_i": s_i}


def graininess_from_pair(a: np.ndarray, b: np.ndarray, blur_um: float = 50.0,
                         pixel_um: float = PIXEL_UM) -> float:
    """G of two renders of one scene with independent seeds: the covariance of the blurred
    images is the variance of the scene's pattern without the path tracer's noise."""
    from scipy.ndimage import gaussian_filter

    ba = gaussian_filter(a, blur_um / pixel_um, mode="reflect")
    bb = gaussian_filter(b, blur_um / pixel_um, mode="reflect")
    cov = float(((ba - ba.mean()) * (bb - bb.mean())).mean())
    return 100.0 * np.sqrt(max(cov, 0.0)) / float(0.5 * (ba.mean() + bb.mean()))


#: The reference scene of ``tests/data/coatings/flake-truth.json`` (``render_flake_truth.py``).
TRUTH_CONFIG = {
    "density_per_mm2": 2000.0, "median_diameter_um": 12.0, "diameter_spread": 0.35,
    "orientation_spread_deg": 20.0, "flake_reflectance": 0.9, "base_reflectance": 0.05,
    "refractive_index": 1.5, "coat_um": 40.0,
    "field_mm": 14.0, "angles_deg": [15.0, 45.0, 75.0], "half_angle_deg": 2.5,
    "compact_half_angle_deg": 1.0, "compact_angle_deg": 45.0, "spp": 16,
    "diffuse_field_mm": 4.0, "diffuse_spp": 64, "seed": 11,
}


def truth_flake_model(cfg: dict | None = None) -> FlakeModel:
    """The :class:`FlakeModel` of :data:`TRUTH_CONFIG`."""
    c = TRUTH_CONFIG if cfg is None else cfg
    return FlakeModel.from_spread_deg(c["density_per_mm2"], c["median_diameter_um"], c["diameter_spread"],
                                      c["orientation_spread_deg"], c["flake_reflectance"], c["refractive_index"])


def _summary(st: dict) -> dict:
    flux = np.sort(np.asarray(st["flux"], float))
    return {"count": st["count"], "density_per_mm2": round(st["density_per_mm2"], 5),
            "S_a": round(st["S_a"], 5), "S_i": round(st["S_i"], 5),
            "total_flux": round(float(flux.sum()), 3),
            "flux_quantiles": [round(float(q), 3) for q in np.percentile(flux, [10, 25, 50, 75, 90])]
            if len(flux) else [],
            "flux": [round(float(x), 2) for x in flux]}


def reference_statistics(cfg: dict | None = None, progress=print) -> dict:
    """Render the reference scene with Mitsuba and summarise its glints and graininess (the
    content of ``tests/data/coatings/flake-truth.json``; several minutes)."""
    import mitsuba as mi

    c = dict(TRUTH_CONFIG if cfg is None else cfg)
    model = truth_flake_model(c)
    fs = make_flakes(model, c["field_mm"], c["seed"], c["base_reflectance"], c["coat_um"],
                     c["flake_reflectance"])
    out = {"mitsuba": mi.__version__, "variant": mitsuba_variant(), "config": c,
           "flakes_in_field": int(len(fs.diameters_um)), "sparkle": {}, "compact": None}
    for a in c["angles_deg"]:
        progress(f"sparkle at {a:g}°")
        img = render_sparkle(fs, a, c["half_angle_deg"], c["spp"], c["seed"])
        out["sparkle"][f"{a:g}"] = _summary(glint_statistics(img))
    progress(f"compact source at {c['compact_angle_deg']:g}°")
    img = render_sparkle(fs, c["compact_angle_deg"], c["compact_half_angle_deg"], c["spp"], c["seed"])
    out["compact"] = _summary(glint_statistics(img))
    progress("diffuse light (two seeds)")
    fd = make_flakes(model, c["diffuse_field_mm"], c["seed"] + 1, c["base_reflectance"], c["coat_um"],
                     c["flake_reflectance"])
    d1 = render_diffuse(fd, c["diffuse_spp"], c["seed"])
    d2 = render_diffuse(fd, c["diffuse_spp"], c["seed"] + 1000)
    out["diffuse"] = {"graininess": round(graininess_from_pair(d1, d2), 5),
                      "mean": round(float(0.5 * (d1.mean() + d2.mean())), 6)}
    return out
