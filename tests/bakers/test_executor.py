"""Executor: subprocess per job, content-hash cache, atomic outputs, resume (real tiny bakes)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from lbscene.bakers.executor import BakeTask, is_cached, run_tasks
from lbscene.bakers.job import (BakeJob, IrradiancePointsProduct, JobMaterial, JobMesh,
                                MeasurementPoint, PointEmitters, Quality)
from lbscene.bakers.products import read_product

pytestmark = pytest.mark.bake


def tiny_job(z_mm: float = 1000.0, band: int = 5) -> BakeJob:
    """One lamp emitting in one band over a grey floor; an up and a down sensor."""
    I = [0.0] * 16
    I[band] = 1.0
    floor = [(-1000, -1000, 0), (1000, -1000, 0), (1000, 1000, 0), (-1000, 1000, 0)]
    return BakeJob(
        name="tiny",
        materials={"grey": JobMaterial(reflectance=[0.5] * 16)},
        meshes=[JobMesh(id="floor", material="grey", vertices_mm=floor, triangles=[(0, 1, 2), (0, 2, 3)])],
        emitters=[PointEmitters(id="lamp", positions_mm=[(0, 0, z_mm)], intensity_W_sr_nm=I)],
        products=[IrradiancePointsProduct(id="pts", points=[
            MeasurementPoint(position_mm=(0, 0, 0), name="up"),
            MeasurementPoint(position_mm=(0, 0, 300), normal=(0, 0, -1), name="down")])],
        quality=Quality(samples=8, max_bounces=1))


def test_bake_cache_and_band_independence(tmp_path):
    job = tiny_job()
    out = tmp_path / "tiny"
    [r1] = run_tasks([BakeTask(job, out)], progress=False)
    assert r1.status == "baked", (r1.error, r1.log_tail)
    m = json.loads((out / "manifest.json").read_text())
    assert m["job_hash"] == job.content_hash
    assert {"pts.exr", "pts.points.json", "pts.points.csv", "scene.blend", "job.json"} <= set(m["files"])
    data, _ = read_product(out / "pts.exr")
    assert data.shape == (1, 2, 16)
    # only band 5 carries light — direct (up) and reflected by the floor (down) — all others exactly 0
    others = np.delete(data, 5, axis=-1)
    assert np.all(others == 0.0)
    assert data[0, 0, 5] == pytest.approx(1.0, rel=2e-4)      # I/d² at 1 m (0.05 mm sensor lift)
    assert data[0, 1, 5] > 0
    # unchanged job: cache hit, no process started
    [r2] = run_tasks([BakeTask(job, out)], progress=False)
    assert r2.status == "cached" and r2.time_s == 0.0
    # changed job: baked again, replacing the old products
    [r3] = run_tasks([BakeTask(tiny_job(z_mm=2000.0), out)], progress=False)
    assert r3.status == "baked"
    data, _ = read_product(out / "pts.exr")
    assert data[0, 0, 5] == pytest.approx(0.25, rel=2e-4)
    # a product file gone missing invalidates the cache
    assert is_cached(tiny_job(z_mm=2000.0), out) is not None
    (out / "pts.exr").unlink()
    assert is_cached(tiny_job(z_mm=2000.0), out) is None


def test_crash_leaves_no_partial_product_and_resume_finishes(tmp_path, monkeypatch):
    good = tiny_job()
    a, b = tmp_path / "a", tmp_path / "b"
    [ra] = run_tasks([BakeTask(good, a)], progress=False)
    assert ra.status == "baked"
    before = (a / "manifest.json").read_text()
    # a hard crash (os._exit, no clean-up in the child) after the first product file
    monkeypatch.setenv("LBSCENE_BAKE_CRASH_AFTER_PRODUCTS", "1")
    changed = tiny_job(z_mm=1500.0)
    results = run_tasks([BakeTask(changed, a), BakeTask(good, b)], progress=False)
    assert [r.status for r in results] == ["failed", "failed"]
    assert "exited with code 70" in results[0].error
    assert (a / "manifest.json").read_text() == before         # old products intact
    assert not b.exists()                                      # nothing half-written
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a"]  # no temporary folders left
    assert is_cached(changed, a) is None
    # resume: the finished job is a cache hit, the others are baked
    monkeypatch.delenv("LBSCENE_BAKE_CRASH_AFTER_PRODUCTS")
    results = run_tasks([BakeTask(good, b), BakeTask(changed, a)], progress=False)
    assert [r.status for r in results] == ["baked", "baked"]
    results = run_tasks([BakeTask(good, b), BakeTask(changed, a)], progress=False)
    assert [r.status for r in results] == ["cached", "cached"]
