"""A directional secondary source (an opal plate's bottom face) is evaluated only toward the
receivers that see it: the receivers above the plate get none of its light, and those below get
the same light whatever else is asked for with them."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np

from lbscene.engine.light.forward import ForwardModel
from lbscene.engine.scene.compile import compile_booth

SCENE = Path(__file__).resolve().parents[1] / "data" / "validation" / "opal-cavity-45"


def _plate_light(fm, P, N):
    terms = fm.first_order_terms(P, N, None)
    return np.stack([t.geo for t in terms if getattr(t, "kind", None) == "diffuser"], axis=1)


def test_a_plates_light_is_asked_for_only_where_it_arrives(monkeypatch):
    ir = compile_booth(SCENE)
    z = float(ir.diffuser.z_mm)
    fm = ForwardModel(ir, "L", effects={"diffuser": {}})
    x = np.linspace(-300.0, 300.0, 7)
    floor = np.stack([x, np.zeros_like(x), np.full_like(x, 1.0)], axis=1)
    up = np.tile([0.0, 0.0, 1.0], (len(x), 1))
    # in the cavity above the plate, facing down onto its top face; and under it, facing away
    cavity = np.stack([x, np.zeros_like(x), np.full_like(x, z + 40.0)], axis=1)
    away = np.stack([x, np.zeros_like(x), np.full_like(x, z - 100.0)], axis=1)
    asked = []
    real = fm.secondary_sources

    def spied():
        out = []
        for s in real():
            def radiance(d, f=s.radiance):
                asked.append(d.shape[1])
                return f(d)
            out.append(replace(s, radiance=radiance))
        return out

    monkeypatch.setattr(fm, "secondary_sources", spied)
    alone = _plate_light(fm, floor, up)
    assert alone.shape[1] >= 1 and np.all(alone > 0)
    P = np.concatenate([cavity, floor[:3], away, floor[3:]])
    N = np.concatenate([-up, up[:3], -up, up[3:]])
    asked.clear()
    mixed = _plate_light(fm, P, N)
    # the floor's light, read back from its rows among the others, is the floor's alone
    rows = np.r_[len(x):len(x) + 3, 2 * len(x) + 3:3 * len(x)]
    assert np.array_equal(mixed[rows], alone)
    # nothing for the cavity over the plate's top or the points facing up under it, and the
    # plate's law was asked for the floor's points only
    assert np.all(mixed[:len(x)] == 0) and np.all(mixed[len(x) + 3:2 * len(x) + 3] == 0)
    assert asked == [len(x)]
