"""The realtime graph's emitters read the effects' parameters as the forward model does
(diffuser transmittance_scale and diffuse_fraction; angular_profile sigma_deg and lamps)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from lbscene.engine.scene.compile import compile_booth
from lbscene.runtimes.graph import _emitters

DATA = Path(__file__).resolve().parents[1] / "data"


def test_runtime_emitters_follow_effect_parameters():
    base = compile_booth(DATA / "hidden-effect-booth")
    eff = {"diffuser": {"transmittance_scale": 0.5, "diffuse_fraction": 0.25},
           "angular_profile": {"sigma_deg": 30.0, "lamps": ["tube_rear"]}}
    ir = base.model_copy(update={"effects": eff})
    em = {e["id"]: e for e in _emitters(ir, "FL")}
    lamp = ir.lamp("tube_front")
    T = np.clip(ir.diffuser.transmittance.array_1nm * 0.5, 0, 1)
    # the runtime multiplies band means (emission × plate), as its shaders do
    want = ir.grid.integrate(lamp.peak_intensity_1nm) * ir.grid.integrate(T) * (1 - 0.25)
    assert np.allclose(em["tube_front"]["intensity_bands_W_sr_nm"], want, rtol=1e-5)
    # σ applies to the selected lamp only: exp(−(θ/2σ)²) at 60° is e⁻¹
    rear = np.asarray(em["tube_rear"]["profile"])
    theta = np.linspace(0, 180, len(rear))
    assert np.allclose(rear, np.exp(-(theta / 60.0) ** 2), atol=1e-4)
    assert np.allclose(em["tube_front"]["profile"], 1.0)
    assert math.isclose(rear[np.argmin(abs(theta - 60))], math.exp(-1), rel_tol=0.05)
