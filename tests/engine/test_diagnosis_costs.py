"""Which enabled effects' parameters the diagnosis refits with every candidate is decided by each
effect's analytic cost model, never by timing.  The diffuser's model counts the pairs of plate
sub-points and lamp emitter points that an opal part of the plate gathers light over: it must
count what the forward model really gathers, and keep a declared glass plate's diffuse fraction
out of the refits where that gathering is dear (the shipped SpectraLight's D65 tubes behind
their prism mirrors: about 2 s a forward evaluation) while a single bulb's is refitted."""
from __future__ import annotations

import math
from pathlib import Path

import pytest

from lbscene.engine.light.effects.builtin.diffuser import DiffuserEffect
from lbscene.engine.light.forward import PER_POINT_AROUND, ForwardModel
from lbscene.engine.loop import diagnose as D
from lbscene.engine.scene.compile import compile_booth

ROOT = Path(__file__).resolve().parents[2]
SPECTRALIGHT = ROOT / "booths" / "xrite-spectralight-qc"


@pytest.fixture(scope="module")
def ir():
    return compile_booth(SPECTRALIGHT)


@pytest.mark.parametrize("lighting", ["D65", "A"])
def test_pairs_counted_are_the_models(ir, lighting):
    """The cost model's pairs = the plate's diagnosis cells × 2 × 2 sub-points × the emitter
    points the model's per-point gathering uses (each lamp's own quadrature, around a tube)."""
    params = DiffuserEffect.diagnosis_params({})
    fm = ForwardModel(ir, lighting)
    emitters = sum(len(es.points_mm) for lamp, level in ir.lamps_on(lighting)
                   for es in fm.base_emitters(lamp, lamp.point_sources, level, n_around=PER_POINT_AROUND))
    d = ir.diffuser
    cells = math.ceil(d.size_mm[0] / params["cell_size_mm"]) * math.ceil(d.size_mm[1] / params["cell_size_mm"])
    pairs = DiffuserEffect.refit_cost_s(ir, params, lighting) / DiffuserEffect.opal_pair_cost_s
    assert pairs == pytest.approx(cells * 4 * emitters, rel=1e-9)


def test_dear_plate_fraction_held_cheap_one_refitted(ir):
    effects = D._coarsen(dict(ir.effects))
    dear: list = []
    d65 = [fp.target for fp in D._enabled_fit_params(ir, "D65", effects, [], dear)]
    cheap: list = []
    a = [fp.target for fp in D._enabled_fit_params(ir, "A", effects, [], cheap)]
    assert "effect.diffuser.diffuse_fraction" not in d65
    assert "effect.diffuser.diffuse_fraction" in [fp.target for fp in dear]       # said, not dropped
    assert "effect.diffuser.diffuse_fraction" in a
    assert "effect.diffuser.diffuse_fraction" not in [fp.target for fp in cheap]
    # the inter-reflection's cost is the same in every lighting: held in both or in neither
    assert ("effect.interreflection.reflectance_scale" in [fp.target for fp in dear]) == \
        ("effect.interreflection.reflectance_scale" in [fp.target for fp in cheap])
    # the other effects' parameters are unaffected by the plate's cost
    assert "effect.aperture_occlusion.opening_scale" in d65


def test_no_plate_costs_nothing(ir):
    bare = ir.model_copy(update={"diffuser": None})
    assert DiffuserEffect.refit_cost_s(bare, {}, "D65") == 0.0
