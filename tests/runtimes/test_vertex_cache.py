"""The light at the render's vertices kept in the disk cache: the same numbers, never a stale hit."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

HERE = Path(__file__).resolve().parent
TUBE_BOOTH = HERE / "data" / "tube-booth"


@pytest.fixture(scope="module")
def tube_ir():
    from lbscene.engine.scene.compile import compile_booth

    return compile_booth(TUBE_BOOTH)


def _receivers():
    x, y = np.meshgrid(np.linspace(-200.0, 200.0, 5), np.linspace(-150.0, 150.0, 4))
    pts = np.c_[x.ravel(), y.ravel(), np.zeros(x.size)]
    return pts, np.tile([0.0, 0.0, 1.0], (len(pts), 1))


def test_a_cache_hit_equals_the_evaluation(tube_ir, tmp_path, monkeypatch):
    from lbscene.runtimes import scene

    monkeypatch.setenv("LBSCENE_CACHE_DIR", str(tmp_path))
    lighting = next(iter(tube_ir.lighting))
    pts, nrm = _receivers()
    exact = scene._irradiance_bands(tube_ir, lighting, pts, nrm, 100.0)
    first = scene._vertex_irradiance_bands(tube_ir, lighting, pts, nrm, 100.0)
    assert len(list((tmp_path / "vertex_irradiance").glob("*.npy"))) == 1
    calls = []
    monkeypatch.setattr(scene, "_irradiance_bands", lambda *a: calls.append(a))
    again = scene._vertex_irradiance_bands(tube_ir, lighting, pts, nrm, 100.0)
    assert not calls                                    # read from the disk cache
    np.testing.assert_array_equal(first, exact)
    np.testing.assert_array_equal(again, exact)
    e1 = scene._irradiance_1nm(tube_ir, lighting, pts[0], nrm[0])
    e2 = scene._irradiance_1nm(tube_ir, lighting, pts[0], nrm[0])
    np.testing.assert_array_equal(e1, e2)
    assert e1.shape == (471,) and e1.max() > 0


def test_other_receivers_or_code_are_other_entries(tube_ir, tmp_path, monkeypatch):
    from lbscene.runtimes import scene

    monkeypatch.setenv("LBSCENE_CACHE_DIR", str(tmp_path))
    lighting = next(iter(tube_ir.lighting))
    pts, nrm = _receivers()
    scene._vertex_irradiance_bands(tube_ir, lighting, pts, nrm, 100.0)
    scene._vertex_irradiance_bands(tube_ir, lighting, pts + [0.0, 0.0, 1.0], nrm, 100.0)
    assert len(list((tmp_path / "vertex_irradiance").glob("*.npy"))) == 2
    # an edited forward model (another digest) never reads the earlier result
    monkeypatch.setattr(scene, "model_code_digest", lambda ir: "edited")
    scene._vertex_irradiance_bands(tube_ir, lighting, pts, nrm, 100.0)
    assert len(list((tmp_path / "vertex_irradiance").glob("*.npy"))) == 3


def test_the_code_digest_covers_the_transport_and_the_effects(tube_ir):
    from lbscene.runtimes.scene import model_code_digest

    d = model_code_digest(tube_ir)
    assert d == model_code_digest(tube_ir) and len(d) == 32
