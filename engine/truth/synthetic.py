"""
Synthetic measurement sets: readings from a truth engine, with meter noise.

Used by the hidden-effect tests and the shipped walkthrough: the truth (by
default the brute-force :class:`~lbscene.engine.truth.reference.ReferenceEngine`,
or any registered truth provider such as a Cycles bake) includes effects the
booth file does not enable; the files written here are exactly what a user
would write by hand (CSV + a measurement-set YAML).

Examples
--------
>>> a3_grid().shape      # the seed's 55 points on an A3 sheet at the floor centre
(55, 3)
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np

__all__ = ["a3_grid", "synthesize", "write_illuminance_csv", "truth_engine", "measure"]


def a3_grid(nx: int = 11, ny: int = 5, width_mm: float = 400.0, depth_mm: float = 240.0,
            centre_mm=(0.0, 0.0), z_mm: float = 0.0) -> np.ndarray:
    """``nx × ny`` grid points on an A3 sheet (420 × 297 mm) centred on the floor."""
    x = centre_mm[0] + np.linspace(-width_mm / 2, width_mm / 2, nx)
    y = centre_mm[1] + np.linspace(-depth_mm / 2, depth_mm / 2, ny)
    X, Y = np.meshgrid(x, y, indexing="xy")
    return np.c_[X.ravel(), Y.ravel(), np.full(X.size, z_mm)]


def truth_engine(ir, lighting: str, effects: dict, provider: str = "reference", **kw):
    """A truth engine from a registered provider (``'reference'``: brute-force Monte Carlo)."""
    from .reference import get_truth_provider

    return get_truth_provider(provider)(ir, lighting, effects=effects, **kw)


def measure(engine, points, normals=None, noise_percent: float = 1.0, rng=None) -> np.ndarray:
    """Meter readings: the truth's illuminance times (1 + N(0, noise))."""
    rng = rng or np.random.default_rng(0)
    e = np.asarray(engine.illuminance_lx(points, normals, True), float)
    return e * (1.0 + noise_percent / 100.0 * rng.standard_normal(e.shape))


def write_illuminance_csv(path: Path, points, lux, normals=None) -> None:
    points = np.asarray(points, float)
    lines = []
    if normals is None or np.allclose(np.asarray(normals)[:, 2], 1.0):
        has_z = np.any(points[:, 2] != 0)
        lines.append("x_mm,y_mm,z_mm,illuminance_lx" if has_z else "x_mm,y_mm,illuminance_lx")
        for p, e in zip(points, lux):
            lines.append(f"{p[0]:g},{p[1]:g},{p[2]:g},{e:.6g}" if has_z else f"{p[0]:g},{p[1]:g},{e:.6g}")
    else:
        lines.append("x_mm,y_mm,z_mm,normal_x,normal_y,normal_z,illuminance_lx")
        for p, n, e in zip(points, normals, lux):
            lines.append(f"{p[0]:g},{p[1]:g},{p[2]:g},{n[0]:.6g},{n[1]:.6g},{n[2]:.6g},{e:.6g}")
    Path(path).write_text("\n".join(lines) + "\n")


def synthesize(booth, out_dir, *, lighting: str, truth_effects: dict, points=None, normals=None,
               noise_percent: float = 1.0, seed: int = 0, white_tile: bool = True,
               tile_noise_percent: float = 1.0, name: str | None = None,
               declare_noise: bool = True, known_output_groups=(), provider: str = "reference",
               engine=None, stem: str = "measurements", extra_sets=()) -> Path:
    """Write ``<out_dir>/<stem>.yaml`` + CSVs measured from a truth with ``truth_effects``.

    ``extra_sets``: further ``(csv_name, points, normals)`` measured from the same truth.
    Returns the measurement-set path.
    """
    from lbscene.engine.scene.compile import compile_booth, find_booth_file

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    booth_file = find_booth_file(booth)
    ir = compile_booth(booth_file)
    eng = engine or truth_engine(ir, lighting, truth_effects, provider)
    rng = np.random.default_rng(seed)
    pts = a3_grid() if points is None else np.asarray(points, float)
    lux = measure(eng, pts, normals, noise_percent, rng)
    write_illuminance_csv(out / f"{stem}-grid.csv", pts, lux, normals)
    files = [f"{stem}-grid.csv"]
    for fname, p2, n2 in extra_sets:
        lux2 = measure(eng, p2, n2, noise_percent, rng)
        write_illuminance_csv(out / fname, p2, lux2, n2)
        files.append(fname)
    rel = os.path.relpath(booth_file.resolve().parent, out.resolve())
    y = ["# yaml-language-server: $schema=" + os.path.relpath(
        Path(__file__).resolve().parents[2] / "schemas" / "json" / "measurement_set.schema.json",
        out.resolve()),
        "version: 1", "kind: measurement_set",
        # JSON strings are valid YAML scalars: names may hold ': ' or '#'
        f"name: {json.dumps(name or 'synthetic measurements', ensure_ascii=False)}",
        f"booth: {rel}", f"lighting: {lighting}",
        "provenance: {status: synthetic, source: \"lbscene " + provider + " truth, effects: " +
        (", ".join(sorted(truth_effects)) or "none") + "\"}"]
    inst = "instrument: {illuminance_meter: synthetic meter"
    if declare_noise:
        inst += f", repeatability_percent: {noise_percent:g}"
    inst += f", spectral_noise_percent: {max(tile_noise_percent, 0.1):g}}}"
    y.append(inst)
    if known_output_groups:
        y.append("known_output_groups: [" + ", ".join(known_output_groups) + "]")
    y.append("illuminance:")
    for f in files:
        y.append(f"  - path: {f}")
    if white_tile:
        from lbscene.engine.spectra.bands import BandGrid

        # a spectroradiometer's output: 5 nm samples, each the mean over its 5 nm bandpass
        bins = BandGrid(first_centre_nm=380.0, width_nm=5.0, count=81)
        wl = bins.centres_nm
        L = eng.white_tile_radiance_1nm(None, (0, 0, 1.0), 0.99)
        L5 = bins.integrate(L)
        L5 = L5 * (1.0 + tile_noise_percent / 100.0 * rng.standard_normal(L5.shape))
        (out / f"{stem}-tile.csv").write_text(
            "wavelength_nm,radiance\n" + "\n".join(f"{a:g},{b:.6g}" for a, b in zip(wl, L5)) + "\n")
        y.append("white_tile:")
        y.append(f"  radiance: {{type: csv, path: {stem}-tile.csv}}")
        y.append("  reflectance: {type: constant, value: 0.99}")
    path = out / f"{stem}.yaml"
    path.write_text("\n".join(y) + "\n")
    return path
