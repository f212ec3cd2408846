"""Environment maps: orientation conventions and radiance units (real tiny renders)."""

from __future__ import annotations

import numpy as np
import pytest

from lbscene.bakers.job import AreaEmitter, BakeJob, EnvironmentMapProduct, Quality
from lbscene.bakers.products import cube_directions, equirect_directions, read_product

pytestmark = pytest.mark.bake

#: marker direction → band carrying its radiance
MARKERS = {0: (0, 1, 0), 1: (-1, 0, 0), 2: (0, 0, 1), 3: (0.6, 0.48, -0.64), 4: (-0.3, -0.8, 0.52)}


def _quad(centre, normal, half=100.0):
    c, n = np.asarray(centre, float), np.asarray(normal, float)
    a = np.cross(n, [0, 0, 1] if abs(n[2]) < 0.9 else [1, 0, 0])
    a /= np.linalg.norm(a)
    b = np.cross(n, a)
    v = [c - half * a - half * b, c + half * a - half * b, c + half * a + half * b, c - half * a + half * b]
    return [tuple(x) for x in v], [(0, 1, 2), (0, 2, 3)]


@pytest.fixture(scope="module")
def marker_bake(tmp_path_factory):
    from lbscene.bakers.executor import BakeTask, run_tasks

    ems = []
    for b, d in MARKERS.items():
        d = np.asarray(d, float) / np.linalg.norm(d)
        v, t = _quad(1000 * d, -d)             # facing the centre, 200 mm at 1 m
        L = [0.0] * 16
        L[b] = 1.0 + b                          # radiance W·sr⁻¹·m⁻²·nm⁻¹
        ems.append(AreaEmitter(id=f"m{b}", vertices_mm=v, triangles=t, radiance_W_sr_m2_nm=L))
    job = BakeJob(name="markers", emitters=ems, products=[
        EnvironmentMapProduct(id="eq", position_mm=(0, 0, 0), width_px=64, samples=2),
        EnvironmentMapProduct(id="cube", position_mm=(0, 0, 0), projection="cube", width_px=48, samples=16)],
        quality=Quality(noise_estimate=False))
    out = tmp_path_factory.mktemp("env") / "markers"
    [r] = run_tasks([BakeTask(job, out)], progress=False)
    assert r.status == "baked", (r.error, r.log_tail)
    return out


@pytest.mark.parametrize("product", ["eq", "cube"])
def test_markers_appear_in_their_directions_with_their_radiance(marker_bake, product):
    img, header = read_product(marker_bake / f"{product}.exr")
    D = equirect_directions(64) if product == "eq" else cube_directions(48)
    assert img.shape[:2] == D.shape[:2]
    for b, d in MARKERS.items():
        d = np.asarray(d, float) / np.linalg.norm(d)
        w = img[..., b]
        # pixels fully inside the marker see exactly its radiance (emission = radiance)
        assert w.max() == pytest.approx(1.0 + b, rel=1e-6), b
        centroid = (D * w[..., None]).sum(axis=(0, 1))
        centroid /= np.linalg.norm(centroid)
        assert np.degrees(np.arccos(np.clip(centroid @ d, -1, 1))) < 3.0, (b, centroid, d)
    assert header["lbscene:projection"] == ("equirect" if product == "eq" else "cube")


def test_marker_irradiance_from_the_map(marker_bake):
    """∫ L cos dΩ over the map ≈ the closed form of a 200 mm square at 1 m (view factor)."""
    from lbscene.bakers.products import environment_irradiance

    import bake_closed_forms as cf

    img, _ = read_product(marker_bake / "cube.exr")
    E = environment_irradiance(img, "cube", (0, 1, 0), (0, 0, 1), (0, 1, 0))
    ref = cf.rect_E(1.0, -100, 100, -100, 100, 1000.0)      # marker 0 straight ahead
    assert E[0] == pytest.approx(ref, rel=0.05)    # 48-px faces: the square is ~6 px wide (edges)
