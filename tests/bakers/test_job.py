"""Bake job format: validation, identity (content hash), files, quality."""

from __future__ import annotations

import json

import pytest

from lbscene.bakers.job import (JOB_VERSION, QUALITY_PRESETS, BakeJob, IrradiancePointsProduct,
                                JobMaterial, JobMesh, MeasurementPoint, PointEmitters, RigidTransform,
                                load_job, save_job)
from lbscene.engine.files.diagnostics import LbsceneUserError
from lbscene.engine.spectra.bands import band_labels


def tiny(**kw) -> BakeJob:
    base = dict(name="tiny",
                emitters=[PointEmitters(id="p", positions_mm=[(0, 0, 1000)], intensity_W_sr_nm=[0.01] * 16)],
                products=[IrradiancePointsProduct(id="pts", points=[MeasurementPoint(position_mm=(0, 0, 0))])])
    base.update(kw)
    return BakeJob(**base)


def test_bands_follow_the_engine_grid():
    job = tiny()
    assert job.bands.labels() == band_labels()
    assert job.bands.labels()[0] == "390-410nm" and job.bands.labels()[-1] == "690-710nm"
    assert job.bands.centres_nm()[0] == 400 and job.bands.centres_nm()[-1] == 700


def test_round_trip_keeps_the_hash(tmp_path):
    job = tiny(emitters=[PointEmitters(id="p", positions_mm=[(0, 0, 1000)], aim=(0.3, 0.1, -1.0),
                                       intensity_W_sr_nm=[0.1 / 3] * 16)])
    path = save_job(job, tmp_path / "job.json")
    again = load_job(path)
    assert again == job
    assert again.content_hash == job.content_hash
    assert json.loads(path.read_text())["job_version"] == JOB_VERSION


def test_hash_changes_with_content_and_quality():
    a = tiny()
    assert tiny().content_hash == a.content_hash
    assert tiny(emitters=[PointEmitters(id="p", positions_mm=[(0, 0, 1001)], intensity_W_sr_nm=[0.01] * 16)]
                ).content_hash != a.content_hash
    assert a.with_quality("final").content_hash != a.content_hash
    assert a.with_quality(samples=64).content_hash != a.content_hash


def test_samples_resolution_order():
    job = tiny()
    p = job.products[0]
    assert job.samples_for(p) == QUALITY_PRESETS["preview"].points
    assert job.with_quality("final").samples_for(p) == QUALITY_PRESETS["final"].points
    own = tiny(products=[IrradiancePointsProduct(id="pts", samples=10,
                                                 points=[MeasurementPoint(position_mm=(0, 0, 0))])])
    assert own.samples_for(own.products[0]) == 10
    assert own.with_quality(samples=20).samples_for(own.products[0]) == 20


@pytest.mark.parametrize("change, message", [
    (dict(emitters=[PointEmitters(id="p", positions_mm=[(0, 0, 1)], intensity_W_sr_nm=[1.0] * 15)]),
     "15 band values for a 16-band grid"),
    (dict(meshes=[JobMesh(id="m", material="nope", vertices_mm=[(0, 0, 0), (1, 0, 0), (0, 1, 0)],
                          triangles=[(0, 1, 2)])]), "unknown material 'nope'"),
    (dict(emitters=[PointEmitters(id="p", positions_mm=[(0, 0, 1)], intensity_W_sr_nm=[1.0] * 16,
                                  filter="f")]), "unknown filter 'f'"),
    (dict(products=[IrradiancePointsProduct(id="a", points=[MeasurementPoint(position_mm=(0, 0, 0))]),
                    IrradiancePointsProduct(id="a", points=[MeasurementPoint(position_mm=(0, 0, 0))])]),
     "duplicate product id(s): a"),
    (dict(products=[IrradiancePointsProduct(id="a", points=[MeasurementPoint(position_mm=(0, 0, 0))],
                                            group_transforms={"lum": RigidTransform(axis=(1, 0, 0),
                                                                                    angle_deg=30)})]),
     "unknown transform group(s) lum"),
])
def test_inconsistent_jobs_are_rejected(change, message):
    with pytest.raises(ValueError, match=message.replace("(", r"\(").replace(")", r"\)")):
        tiny(**change)


def test_reflectance_outside_unit_range_is_rejected():
    with pytest.raises(ValueError, match=r"reflectance band values must lie in \[0, 1\]"):
        JobMaterial(reflectance=[1.2] * 16)


def test_bad_job_files_give_located_errors(tmp_path):
    p = tmp_path / "job.json"
    p.write_text("{not json")
    with pytest.raises(LbsceneUserError) as e:
        load_job(p)
    assert e.value.diagnostics[0].code == "LB602"
    p.write_text(json.dumps({"kind": "something else"}))
    with pytest.raises(LbsceneUserError, match="not a bake job"):
        load_job(p)
    data = json.loads(tiny().to_json())
    data["emitters"][0]["intensity_W_sr_nm"] = [1.0] * 3
    p.write_text(json.dumps(data))
    with pytest.raises(LbsceneUserError, match="3 band values for a 16-band grid") as e:
        load_job(p)
    assert e.value.diagnostics[0].format().startswith(f"{p}: error LB602: invalid bake job")
    with pytest.raises(LbsceneUserError) as e:
        load_job(tmp_path / "missing.json")
    assert e.value.diagnostics[0].code == "LB010"


def test_rigid_transform_is_a_right_handed_rotation_about_a_centre():
    import numpy as np

    M = RigidTransform(axis=(1, 0, 0), angle_deg=90, centre_mm=(0, 0, 300)).matrix()
    # +z normal → −y (right-hand rule about +x); the centre stays put
    np.testing.assert_allclose(M[:3, :3] @ [0, 0, 1], [0, -1, 0], atol=1e-12)
    np.testing.assert_allclose(M @ [0, 0, 300, 1], [0, 0, 300, 1], atol=1e-9)
