"""Fixtures for the baker tests: tiny jobs baked once per session through the real executor."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from lbscene.bakers.job import (AreaEmitter, BakeJob, CosinePowerProfile, GaussianProfile,
                                IrradianceMapProduct, IrradiancePointsProduct, JobMaterial, JobMesh,
                                MeasurementPoint, PointEmitters, Quality, TableProfile,
                                TransmissiveSheet, Window)

import bake_closed_forms as cf

N_BANDS = 16


def only(bands: dict[int, float]) -> list[float]:
    v = [0.0] * N_BANDS
    for b, x in bands.items():
        v[b] = x
    return v


def rect(cx, cy, z, sx, sy, down=True):
    v = [(cx - sx / 2, cy - sy / 2, z), (cx + sx / 2, cy - sy / 2, z),
         (cx + sx / 2, cy + sy / 2, z), (cx - sx / 2, cy + sy / 2, z)]
    t = [(0, 2, 1), (0, 3, 2)] if down else [(0, 1, 2), (0, 2, 3)]
    return v, t


def disk(cx, cy, z, R, n=256):
    v = [(cx, cy, z)] + [(cx + R * math.cos(2 * math.pi * k / n), cy + R * math.sin(2 * math.pi * k / n), z)
                         for k in range(n)]
    t = [(0, 1 + (k + 1) % n, 1 + k) for k in range(n)]    # clockwise from above: faces down
    return v, t


TABLE = TableProfile(theta_deg=(0, 30, 60, 90), relative=(1.0, 0.8, 0.3, 0.0))
AIM8 = (1 / math.sqrt(2), 0.0, -1 / math.sqrt(2))

#: sensors: (name, position, normal)
POINTS = [
    ("axis", (0, 0, 0), (0, 0, 1)),
    ("x500", (500, 0, 0), (0, 0, 1)),
    ("y-1000", (0, -1000, 0), (0, 0, 1)),
    ("x1500", (1500, 0, 0), (0, 0, 1)),
    ("tilted", (0, 0, 0), (1 / math.sqrt(2), 0, 1 / math.sqrt(2))),
    ("wall", (600, 300, 400), (-1, 0, 0)),
    ("rect_axis", (3000, 0, 0), (0, 0, 1)),
    ("rect_corner", (3200, 100, 0), (0, 0, 1)),
    ("rect_off", (3500, -300, 0), (0, 0, 1)),
    ("disk_axis", (-3000, 0, 0), (0, 0, 1)),
    ("win_centre", (3000, -3000, 0), (0, 0, 1)),
    ("win_in", (3450, -3000, 0), (0, 0, 1)),
    ("win_out", (3600, -3000, 0), (0, 0, 1)),
    ("win_out_v", (3000, -2700, 0), (0, 0, 1)),
    ("sheet_0", (0, 3000, 0), (0, 0, 1)),
    ("sheet_45", (0, 4000, 0), (0, 0, 1)),
    ("sheet_60", (0, 3000 + 1000 * math.tan(math.radians(60)), 0), (0, 0, 1)),
    ("bounce_down", (0, -3000, 300), (0, 0, -1)),
]
MAP = IrradianceMapProduct(id="floor", origin_mm=(-200, -700, 0), size_mm=(1200, 800),
                           resolution=(12, 8), samples=16, light_paths="direct")


def closed_form_job(samples: int = 1024) -> BakeJob:
    src = (0.0, 0.0, cf.H0)
    pts = tuple(MeasurementPoint(name=n, position_mm=p, normal=nv) for n, p, nv in POINTS)
    rv, rt = rect(3000, 0, 800, 400, 200)
    dv, dt = disk(-3000, 0, 600, 300)
    sv, st = rect(0, 3000, 500, 4000, 2000, down=False)
    fv, ft = rect(0, -3000, 0, 2000, 2000, down=False)
    bv, bt = rect(3000, -3000, 900, 600, 600)
    return BakeJob(
        name="closed-forms",
        materials={"floor": JobMaterial(type="diffuse", reflectance=only({14: 0.5, 15: 0.9}))},
        meshes=(JobMesh(id="floor", material="floor", vertices_mm=fv, triangles=ft),
                JobMesh(id="behind_window", material="floor", vertices_mm=bv, triangles=bt)),
        emitters=(
            PointEmitters(id="iso", positions_mm=(src,), intensity_W_sr_nm=only({0: 1, 1: 0.5, 2: 0.25})),
            PointEmitters(id="gauss", positions_mm=(src,), intensity_W_sr_nm=only({3: 1, 4: 2, 5: 3}),
                          profile=GaussianProfile(sigma_deg=20)),
            PointEmitters(id="cos2", positions_mm=(src,), intensity_W_sr_nm=only({6: 1}),
                          profile=CosinePowerProfile(exponent=2)),
            PointEmitters(id="table", positions_mm=(src,), intensity_W_sr_nm=only({7: 1}), profile=TABLE),
            PointEmitters(id="tilted", positions_mm=(src,), intensity_W_sr_nm=only({8: 1}), aim=AIM8,
                          profile=GaussianProfile(sigma_deg=30)),
            AreaEmitter(id="rect", vertices_mm=rv, triangles=rt, radiance_W_sr_m2_nm=only({9: 1})),
            PointEmitters(id="windowed", positions_mm=((3000, -3000, cf.H0),), intensity_W_sr_nm=only({10: 1}),
                          window=Window(centre_mm=(3000, -3000, 800), normal=(0, 0, -1), u_axis=(1, 0, 0),
                                        half_size_mm=(100, 50))),
            AreaEmitter(id="disk", vertices_mm=dv, triangles=dt, radiance_W_sr_m2_nm=only({11: 1})),
            PointEmitters(id="behind_sheet", positions_mm=((0, 3000, cf.H0),),
                          intensity_W_sr_nm=only({12: 1, 13: 1})),
            PointEmitters(id="over_floor", positions_mm=((0, -3000, cf.H0),),
                          intensity_W_sr_nm=only({14: 1, 15: 1})),
        ),
        sheets=(TransmissiveSheet(id="plate", vertices_mm=sv, triangles=st, ior=1.52,
                                  transmittance=[1.0] * 12 + [0.8, 0.5, 1.0, 1.0]),),
        products=(IrradiancePointsProduct(id="pts", points=pts, samples=samples),
                  IrradiancePointsProduct(id="pts_direct", points=pts, samples=64,
                                          light_paths="direct"),
                  MAP),
        quality=Quality(preset="preview", max_bounces=2, seed=3),
    )


@pytest.fixture(scope="session")
def closed_form_bake(tmp_path_factory):
    """Bake :func:`closed_form_job` once (real Cycles, subprocess); returns (job, out_dir)."""
    from lbscene.bakers.executor import BakeTask, run_tasks

    job = closed_form_job()
    out = tmp_path_factory.mktemp("bake") / "closed-forms"
    [res] = run_tasks([BakeTask(job, out)], progress=False)
    assert res.status == "baked", (res.error, "\n".join(res.log_tail))
    return job, out


def load_points(out: Path, product: str) -> dict[str, np.ndarray]:
    """name → band irradiances (W·m⁻²·nm⁻¹)."""
    d = json.loads((out / f"{product}.points.json").read_text())
    return {p["name"]: np.array(list(p["irradiance_W_m2_nm"].values())) for p in d["points"]}


def load_noise(out: Path, product: str) -> dict[str, np.ndarray]:
    """name → standard error of each band irradiance (two-half estimate)."""
    d = json.loads((out / f"{product}.points.json").read_text())
    return {p["name"]: np.array(list(p["irradiance_noise_W_m2_nm"].values())) for p in d["points"]}


def tolerance(out: Path, product: str, name: str, band: int, floor: float = 2e-4) -> float:
    """Relative tolerance: 5 σ of this point and band, at least 4× the band's RMS noise, + floor.

    A one-point two-half σ can be small by chance; the band's RMS over all points
    (from the manifest) bounds it from below.
    """
    E = load_points(out, product)[name][band]
    sig = load_noise(out, product)[name][band]
    m = json.loads((out / "manifest.json").read_text())
    band_rms = m["products"][product]["noise"]["relative_rms_per_band"][band]
    return max(5 * sig / max(abs(E), 1e-30), 2 * band_rms) + floor
