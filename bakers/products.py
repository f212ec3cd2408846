"""
Bake products on disk: multi-channel float32 EXR (one channel per band),
point tables (JSON/CSV), map conventions, illuminance and noise summaries.

No ``bpy`` here: the realtime runtime and the tests read products with this
module and numpy only.

EXR layout
----------
One file per product, channels named by band (``'390-410nm'`` …, from
:func:`lbscene.engine.spectra.bands.band_labels`), FLOAT (32-bit), ZIP, rows top
to bottom.  Header string attributes: ``lbscene:product``, ``lbscene:type``,
``lbscene:units``, ``lbscene:job_hash``, ``lbscene:band_edges_nm`` and, for
environment maps, ``lbscene:projection``/``lbscene:forward``/``lbscene:up``.

* environment map, equirect: (W/2, W); column u → azimuth φ = π(1 − 2(i+½)/W)
  from ``forward`` toward ``left = up × forward``; row j → elevation
  π(½ − (j+½)/H) toward ``up``.
* environment map, cube: (F, 6F), faces in the order of
  :func:`cube_face_frames`.
* irradiance map: (ny, nx); pixel (j, i) at s = (i+½)/nx along ``u_axis``,
  t = 1 − (j+½)/ny along ``v_axis``.
* irradiance points: (1, N), in the order of the job's points.

Illuminance
-----------
E_v = 683 lm/W · Σ_b E_b · ∫_band V(λ) dλ with the CIE 1924 photopic V(λ)
(colour-science), i.e. the spectral irradiance is taken as constant within a
band (the band mean), consistent with the engine's band grid.  V(λ) outside
the band grid (< 390 nm, > 710 nm; 0.03 % of ∫V) is not counted.
"""

from __future__ import annotations

import csv
import io
import json
from pathlib import Path

import numpy as np

__all__ = [
    "UNITS",
    "cube_face_frames",
    "equirect_directions",
    "cube_directions",
    "pixel_solid_angles",
    "environment_irradiance",
    "write_exr",
    "read_exr",
    "read_exr_rgb",
    "band_photopic_weights",
    "illuminance_lx",
    "noise_summary",
    "write_points_tables",
    "read_product",
]

UNITS = {
    "environment_map": "W·sr⁻¹·m⁻²·nm⁻¹ (spectral radiance, band mean)",
    "irradiance_map": "W·m⁻²·nm⁻¹ (spectral irradiance, band mean)",
    "irradiance_points": "W·m⁻²·nm⁻¹ (spectral irradiance, band mean); illuminance in lx",
}


def _unit(v) -> np.ndarray:
    a = np.asarray(v, float)
    return a / np.linalg.norm(a)


def cube_face_frames(forward, up) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """The six cube faces as ``(direction, right, up)`` unit vectors.

    Order: +forward, −forward, +left, −left, +up, −up (left = up × forward).
    Each face is a 90° square view along ``direction``; its image's columns
    run along ``right`` and its rows from ``up`` (top) to −``up`` (bottom), as
    seen from the centre.
    """
    f, u = _unit(forward), _unit(up)
    l = np.cross(u, f)
    faces = []
    for d, fup in ((f, u), (-f, u), (l, u), (-l, u), (u, -f), (-u, f)):
        right = np.cross(d, fup)   # camera convention: right = forward × up
        faces.append((d, right, fup))
    return faces


def equirect_directions(width: int, forward=(0, 1, 0), up=(0, 0, 1)) -> np.ndarray:
    """World direction of every pixel centre of an equirect map, shape (W/2, W, 3)."""
    f, u = _unit(forward), _unit(up)
    l = np.cross(u, f)
    h = width // 2
    phi = np.pi * (1.0 - 2.0 * (np.arange(width) + 0.5) / width)
    el = np.pi * (0.5 - (np.arange(h) + 0.5) / h)
    ph, e = np.meshgrid(phi, el)
    return (np.cos(e) * np.cos(ph))[..., None] * f + (np.cos(e) * np.sin(ph))[..., None] * l \
        + np.sin(e)[..., None] * u


def cube_directions(face_px: int, forward=(0, 1, 0), up=(0, 0, 1)) -> np.ndarray:
    """World direction of every pixel centre of a cube strip, shape (F, 6F, 3)."""
    c = 2.0 * (np.arange(face_px) + 0.5) / face_px - 1.0
    x, y = np.meshgrid(c, -c)
    out = []
    for d, right, fup in cube_face_frames(forward, up):
        v = d + x[..., None] * right + y[..., None] * fup
        out.append(v / np.linalg.norm(v, axis=-1, keepdims=True))
    return np.concatenate(out, axis=1)


def pixel_solid_angles(shape: tuple[int, int], projection: str) -> np.ndarray:
    """Solid angle (sr) of every pixel of an equirect (H, W) or cube strip (F, 6F) map."""
    h, w = shape
    if projection == "equirect":
        edges = np.pi * (0.5 - np.arange(h + 1) / h)
        band = np.sin(edges[:-1]) - np.sin(edges[1:])          # exact per row
        return np.repeat((2 * np.pi / w * band)[:, None], w, axis=1)
    f = h
    e = 2.0 * np.arange(f + 1) / f - 1.0
    # exact solid angle of a face pixel: corner function atan(xy / sqrt(1 + x² + y²))
    X, Y = np.meshgrid(e, e)
    A = np.arctan2(X * Y, np.sqrt(1 + X * X + Y * Y))
    face = A[1:, 1:] - A[:-1, 1:] - A[1:, :-1] + A[:-1, :-1]
    return np.tile(np.abs(face), (1, 6))


def environment_irradiance(data: np.ndarray, projection: str, forward, up, normal) -> np.ndarray:
    """Irradiance (…, bands) on a surface of ``normal`` at the map's centre: Σ L·max(n·ω, 0)·ΔΩ."""
    h, w = data.shape[:2]
    dirs = equirect_directions(w, forward, up) if projection == "equirect" else \
        cube_directions(h, forward, up)
    n = _unit(normal)
    weight = np.clip(dirs @ n, 0.0, None) * pixel_solid_angles((h, w), projection)
    return np.einsum("hwb,hw->b", np.asarray(data, float), weight)


# --------------------------------------------------------------------------- EXR


def write_exr(path: Path, data: np.ndarray, channel_names: list[str],
              attributes: dict[str, str] | None = None) -> None:
    """Write ``data`` (H, W, C) as a float32 EXR with named channels (ZIP)."""
    import OpenEXR

    data = np.asarray(data, np.float32)
    if data.ndim != 3 or data.shape[2] != len(channel_names):
        raise ValueError(f"data {data.shape} does not match {len(channel_names)} channels")
    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
    for k, v in (attributes or {}).items():
        header[k] = str(v)
    channels = {name: np.ascontiguousarray(data[..., i]) for i, name in enumerate(channel_names)}
    with OpenEXR.File(header, channels) as f:
        f.write(str(path))


def read_exr(path: Path) -> tuple[dict[str, np.ndarray], dict[str, object]]:
    """Channels (name → (H, W) float32) and header of an EXR file."""
    import OpenEXR

    with OpenEXR.File(str(path), separate_channels=True) as f:
        chans = {name: np.array(ch.pixels, np.float32) for name, ch in f.channels().items()}
        header = dict(f.header())
    return chans, header


def read_exr_rgb(path: Path) -> np.ndarray:
    """An RGB(A) EXR as (H, W, 3) float64 (R, G, B)."""
    chans, _ = read_exr(path)
    return np.stack([chans[c].astype(np.float64) for c in ("R", "G", "B")], axis=-1)


def read_product(path: Path, labels: list[str] | None = None) -> tuple[np.ndarray, dict[str, object]]:
    """A product EXR as (H, W, bands) in band order, plus its header."""
    chans, header = read_exr(path)
    if labels is None:
        edges = [float(x) for x in str(header["lbscene:band_edges_nm"]).split(",")]
        labels = [f"{a:g}-{b:g}nm" for a, b in zip(edges[:-1], edges[1:])]
    return np.stack([chans[name] for name in labels], axis=-1), header


# --------------------------------------------------------------------------- photometry


def band_photopic_weights(bands) -> np.ndarray:
    """683·∫_band V(λ) dλ per band (lm·W⁻¹·nm), CIE 1924 V(λ): E_v = Σ E_b · w_b."""
    from lbscene.engine.spectra.evaluate import K_M_LM_PER_W, photopic_1nm

    grid = bands.grid() if hasattr(bands, "grid") else bands
    return K_M_LM_PER_W * grid.integrate(photopic_1nm()) * grid.width_nm


def illuminance_lx(irradiance_bands: np.ndarray, bands) -> np.ndarray:
    """Illuminance (lx) of band-mean spectral irradiance (W·m⁻²·nm⁻¹, last axis)."""
    return np.asarray(irradiance_bands, float) @ band_photopic_weights(bands)


def noise_summary(half_a: np.ndarray, half_b: np.ndarray, photopic_w: np.ndarray | None = None) -> dict:
    """Noise of the mean of two independent half-sample estimates.

    For each element the standard error of ``(a + b)/2`` is estimated by
    ``|a − b|/2``; the summary gives RMS values relative to the mean signal,
    per band and (with ``photopic_w``) for illuminance per element.
    """
    a = np.asarray(half_a, float)
    b = np.asarray(half_b, float)
    mean = 0.5 * (a + b)
    err = 0.5 * np.abs(a - b)
    flat_m = mean.reshape(-1, mean.shape[-1])
    flat_e = err.reshape(-1, err.shape[-1])
    sig = flat_m.mean(axis=0)
    with np.errstate(invalid="ignore", divide="ignore"):
        per_band = np.where(sig > 0, np.sqrt((flat_e ** 2).mean(axis=0)) / sig, 0.0)
    out = {"method": "two half-sample renders with different seeds; σ ≈ |a−b|/2 per element",
           "relative_rms_per_band": [round(float(x), 6) for x in per_band],
           "relative_rms_all_bands": round(float(np.sqrt(np.mean(per_band ** 2))), 6)}
    if photopic_w is not None:
        ea = (a.reshape(-1, a.shape[-1]) @ photopic_w)
        eb = (b.reshape(-1, b.shape[-1]) @ photopic_w)
        ya = 0.5 * (ea + eb)
        ey = 0.5 * np.abs(ea - eb)
        ok = ya > 0
        if ok.any():
            rel = ey[ok] / ya[ok]
            out["illuminance_relative_rms"] = round(float(np.sqrt(np.mean(rel ** 2))), 6)
            out["illuminance_relative_max"] = round(float(rel.max()), 6)
            out["illuminance_relative_rms_of_mean"] = round(
                float(np.sqrt(np.mean(ey[ok] ** 2)) / ya[ok].mean()), 6)
    return out


def write_points_tables(folder: Path, product, irradiance: np.ndarray, labels: list[str],
                        lux: np.ndarray, noise_rel: np.ndarray | None,
                        noise_bands: np.ndarray | None = None) -> list[Path]:
    """``<id>.points.json`` and ``<id>.points.csv``: per point E_b and illuminance.

    ``noise_rel``: relative standard error of each point's illuminance;
    ``noise_bands``: standard error of each E_b (JSON only), both from the two halves.
    """
    rows = []
    for i, pt in enumerate(product.points):
        r: dict = {"index": i, "name": pt.name or f"p{i}",
             "x_mm": pt.position_mm[0], "y_mm": pt.position_mm[1], "z_mm": pt.position_mm[2],
             "nx": pt.normal[0], "ny": pt.normal[1], "nz": pt.normal[2],
             "illuminance_lx": float(lux[i])}
        if noise_rel is not None:
            r["illuminance_noise_relative"] = float(noise_rel[i])
        r["irradiance_W_m2_nm"] = {lab: float(v) for lab, v in zip(labels, irradiance[i])}
        if noise_bands is not None:
            r["irradiance_noise_W_m2_nm"] = {lab: float(v) for lab, v in zip(labels, noise_bands[i])}
        rows.append(r)
    jpath = Path(folder) / f"{product.id}.points.json"
    jpath.write_text(json.dumps({"product": product.id, "light_paths": product.light_paths,
                                 "units": {"irradiance": "W·m⁻²·nm⁻¹", "illuminance": "lx",
                                           "position": "mm"},
                                 "bands": labels, "points": rows}, indent=1, ensure_ascii=False) + "\n")
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    head = ["name", "x_mm", "y_mm", "z_mm", "nx", "ny", "nz", "illuminance_lx"]
    if noise_rel is not None:
        head.append("illuminance_noise_relative")
    w.writerow(head + [f"E_{lab}_W_m2_nm" for lab in labels])
    for r in rows:
        vals = [r[h] for h in head]
        w.writerow([f"{v:.9g}" if isinstance(v, float) else v for v in vals]
                   + [f"{r['irradiance_W_m2_nm'][lab]:.9g}" for lab in labels])
    cpath = Path(folder) / f"{product.id}.points.csv"
    cpath.write_text(buf.getvalue())
    return [jpath, cpath]
