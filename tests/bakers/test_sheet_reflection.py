"""A diffuser sheet reflects what a clear plate's faces reflect.

A Lambertian disc (radius 500 mm, radiance L) faces down 1000 mm above a large horizontal
sheet (ior 1.52); a sensor 1 mm above the sheet faces down toward it and sees only the disc's
image in the sheet.  Closed form: the image is a disc
1001 mm away, so E = R · π L a² / (a² + d²) with R the clear plate's reflectance (both faces,
incoherent), R = 1 − (1 − r)/(1 + r) = 2r/(1 + r), r = ((n − 1)/(n + 1))², for the near-normal
directions that carry most of it (0.0817 at 0°, 0.0821 at 20°).
"""

from __future__ import annotations

import math

import pytest

from conftest import disk, only, rect
from lbscene.bakers.job import (AreaEmitter, BakeJob, IrradiancePointsProduct, MeasurementPoint,
                                Quality, TransmissiveSheet)

pytestmark = pytest.mark.bake

N = 1.52
A_MM, H_MM = 500.0, 1000.0


def _plate_R(n: float) -> float:
    r = ((n - 1) / (n + 1)) ** 2
    return 2 * r / (1 + r)


@pytest.mark.slow
def test_the_sheet_reflects_the_clear_plates_share(tmp_path):
    from lbscene.bakers.executor import BakeTask, run_tasks
    from lbscene.bakers.products import read_product

    dv, dt = disk(0, 0, H_MM, A_MM)                      # faces down
    sv, st = rect(0, 0, 0.0, 20000, 20000, down=False)
    job = BakeJob(name="sheet-reflection",
                  emitters=[AreaEmitter(id="disc", vertices_mm=dv, triangles=dt,
                                        radiance_W_sr_m2_nm=only({0: 1.0}))],
                  sheets=[TransmissiveSheet(id="plate", vertices_mm=sv, triangles=st, ior=N,
                                            transmittance=only({0: 0.9}))],
                  products=[IrradiancePointsProduct(id="down", light_paths="all", samples=2048,
                                                    offset_mm=0.0, points=[MeasurementPoint(
                                                        position_mm=(0, 0, 1.0), normal=(0, 0, -1))])],
                  quality=Quality(noise_estimate=False))
    [r] = run_tasks([BakeTask(job, tmp_path / "bake")], progress=False)
    assert r.status == "baked", (r.error, r.log_tail)
    e, _ = read_product(tmp_path / "bake" / "down.exr")
    d = H_MM + 1.0
    expected = _plate_R(N) * math.pi * A_MM ** 2 / (A_MM ** 2 + d ** 2)
    assert e.reshape(-1, e.shape[-1])[0][0] == pytest.approx(expected, rel=0.06)
