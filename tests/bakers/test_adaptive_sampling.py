"""Points products sample on until their noise target (real Cycles bake, closed-form check)."""

from __future__ import annotations

import json

import numpy as np
import pytest

import bake_closed_forms as cf
from conftest import rect
from lbscene.bakers.job import (BakeJob, IrradiancePointsProduct, JobMaterial, JobMesh, MeasurementPoint,
                                PointEmitters, Quality)

pytestmark = pytest.mark.bake

TARGET = 0.002
SENSOR_Z = 300.0


def down_sensor_job(noise_target=TARGET, samples=None) -> BakeJob:
    """A lamp 1 m over a 2 × 2 m Lambertian floor (ρ = 0.5); downward sensors see only the
    floor's single bounce (noisy: every sample is a reflected path)."""
    fv, ft = rect(0, 0, 0, 2000, 2000, down=False)
    pts = tuple(MeasurementPoint(position_mm=(0.0, 0.0, SENSOR_Z), normal=(0, 0, -1), name=f"d{k}")
                for k in range(8))
    return BakeJob(
        name="adaptive",
        materials={"floor": JobMaterial(type="diffuse", reflectance=[0.5] * 16)},
        meshes=(JobMesh(id="floor", material="floor", vertices_mm=fv, triangles=ft),),
        emitters=(PointEmitters(id="lamp", positions_mm=((0.0, 0.0, cf.H0),), intensity_W_sr_nm=[1.0] * 16),),
        products=(IrradiancePointsProduct(id="down", points=pts),),
        quality=Quality(preset="preview", samples=samples, max_bounces=1, seed=5, noise_target=noise_target),
    )


def test_noise_target_adds_rounds_and_stays_unbiased(tmp_path):
    from lbscene.bakers.executor import BakeTask, run_tasks
    from lbscene.bakers.job import QUALITY_PRESETS

    job = down_sensor_job()
    first = QUALITY_PRESETS["preview"].points
    assert job.noise_target_for(job.products[0]) == TARGET
    assert down_sensor_job(samples=64).noise_target_for(job.products[0]) is None   # fixed samples
    [r] = run_tasks([BakeTask(job, tmp_path / "b")], progress=False)
    assert r.status == "baked", (r.error, r.log_tail)
    p = r.manifest["products"]["down"]
    ad = p["adaptive_sampling"]
    assert ad["noise_target"] == TARGET and ad["rounds"] >= 1
    assert first < p["samples"] <= ad["max_samples"]
    noise = p["noise"]["illuminance_relative_rms"]
    # the target is met (or the cap reached); the estimate is itself noisy, hence the margin
    assert noise <= 1.5 * TARGET or p["samples"] == ad["max_samples"], (noise, p["samples"])
    # the sample-weighted mean of the rounds is the closed form, within the bake's own noise
    d = json.loads((tmp_path / "b" / "down.points.json").read_text())
    E = np.array([list(q["irradiance_W_m2_nm"].values()) for q in d["points"]])
    ref = cf.single_bounce_down_sensor(1.0, 0.5, cf.H0, SENSOR_Z - 0.05, 1000.0)
    mean = E.mean(axis=1)                                    # all bands carry the same light
    assert np.abs(mean.mean() / ref - 1) < 4 * noise / np.sqrt(len(mean)) + 1e-3, (mean, ref, noise)
