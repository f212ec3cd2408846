"""The white-tile floor under hardware that only moves light (engine/loop/spectral_reach.py).

A cone member is reached exactly; a narrow dip is not; and the floor is a floor: the refits of
the plate, aperture and mirror hypotheses through the forward model, on the Mitsuba truth of a
booth whose undeclared filter has a dip, never bring the tile's χ² under it (the claim the
diagnosis skips their refits on)."""

from __future__ import annotations

import importlib.util
import sys
from dataclasses import dataclass
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from lbscene.engine.light.forward import spectral_tables
from lbscene.engine.loop.spectral_reach import REACH_ORDER, cone_spectra_1nm, spectral_floor_chi2
from lbscene.engine.spectra.bands import DEFAULT_GRID, BandGrid

WL = np.arange(360.0, 831.0)


@dataclass
class _Term:
    spectrum_1nm: np.ndarray
    geo: np.ndarray | None = None
    geo_bands: np.ndarray | None = None


@dataclass
class _IR:
    materials: dict
    grid: object = DEFAULT_GRID
    diffuser: object = None


def _material(values_1nm):
    from lbscene.engine.scene.ir import IRSpectrum

    return SimpleNamespace(reflectance=IRSpectrum.from_1nm(values_1nm, DEFAULT_GRID), reflectance_bands_by_lighting={})


def _booth():
    lamp = 1.0 + 0.6 * np.exp(-0.5 * ((WL - 450) / 30) ** 2) + 0.8 * np.exp(-0.5 * ((WL - 610) / 40) ** 2)
    walls = 0.35 + 0.25 * (WL - 360) / 470                      # a warm grey
    floor = 0.5 - 0.2 * np.exp(-0.5 * ((WL - 520) / 60) ** 2)   # a magenta tint
    ir = _IR(materials={"walls": _material(walls), "floor": _material(floor)})
    terms = [_Term(lamp, geo=np.array([1.0])),
             _Term(lamp, geo_bands=np.array([DEFAULT_GRID.integrate(0.3 * walls + 0.1)]))]
    return ir, lamp, walls, floor, terms


def _floor(ir, terms, tile_radiance, sigma=1.0):
    grid = BandGrid(first_centre_nm=382.5, width_nm=5.0, count=80)
    meas = grid.integrate(tile_radiance)
    return spectral_floor_chi2(ir, "L", terms, 0, np.full(WL.size, 0.99), grid, meas,
                               meas > 0.02 * meas.max(), sigma)


def test_a_spectrum_in_the_cone_is_reached():
    # the lamp after a wall and the floor (two reflections), at any level: within the cone
    ir, lamp, walls, floor, terms = _booth()
    _, _, P = spectral_tables(DEFAULT_GRID)
    shape = P @ (DEFAULT_GRID.integrate(walls) * DEFAULT_GRID.integrate(floor))
    tile = 0.99 / np.pi * 7.3 * (lamp + 0.4 * lamp * shape)
    assert _floor(ir, terms, tile) < 0.05


def test_a_narrow_dip_is_out_of_reach():
    # a 25 % Gaussian dip of σ 15 nm (a filter): no mix of broad reflectance products follows
    # it.  Bounds that do not share the cone's solver: above 0 by most of the dip's χ², below the
    # lamp's own χ² (the cone holds the lamp), and above the least squares with signed weights
    # (a larger family)
    ir, lamp, walls, floor, terms = _booth()
    dip = 1.0 - 0.25 * np.exp(-0.5 * ((WL - 560) / 15) ** 2)
    tile = 0.99 / np.pi * lamp * dip
    f = _floor(ir, terms, tile)
    grid = BandGrid(first_centre_nm=382.5, width_nm=5.0, count=80)
    meas = grid.integrate(tile)
    m = meas > 0.02 * meas.max()
    x = grid.integrate(0.99 / np.pi * lamp)[m] / meas[m]
    own = float(np.sum((100 * (x / x.mean() - 1)) ** 2))
    A = (grid.integrate(cone_spectra_1nm(ir, "L", terms, 0) * 0.99 / np.pi)[:, m] / meas[m][None, :]).T
    coef, *_ = np.linalg.lstsq(A, np.ones(m.sum()), rcond=None)
    free = float(np.sum((100 * (A @ coef - 1)) ** 2))
    assert free <= f <= own
    assert f > 0.3 * own and f > 1000


def test_the_cone_holds_every_product_up_to_its_order():
    ir, lamp, walls, floor, terms = _booth()
    S = cone_spectra_1nm(ir, "L", terms, 0)
    # one lamp spectrum × (1 + products of two materials up to REACH_ORDER) + the inter-reflected
    # term's own (the direct term's is the lamp's: one column)
    n_products = sum(k + 1 for k in range(REACH_ORDER + 1))
    assert len(S) == n_products + 1
    assert np.allclose(np.linalg.norm(S, axis=1), 1.0)


def _truth_cases():
    spec = importlib.util.spec_from_file_location("diagnosis_on_truth_reach",
                                                  Path(__file__).parent / "test_diagnosis_on_truth.py")
    mod = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = mod
    spec.loader.exec_module(mod)
    return mod


@pytest.mark.parametrize("hyp", ["aperture_plate", "mirror",
                                 pytest.param("diffuser_plate", marks=pytest.mark.slow)])
def test_hardware_refits_stay_above_the_floor(tmp_path, monkeypatch, hyp):
    """The undeclared 25 % dip filter (Mitsuba truth, A3 grid, white tile at 5 nm, output
    fitted): each hardware hypothesis, refitted as if it could rival the filter, leaves the
    tile's χ² above the floor that let the diagnosis skip it; its first guess is kept, and said to
    be."""
    import lbscene.engine.loop.diagnose as D
    from lbscene.engine.loop.fit import FitProblem, resolve_free_parameters
    from lbscene.engine.loop.measurements import load_measurements

    T = _truth_cases()
    case = next(c for c in T.CASES if c.id == "filter-undeclared-fitted")
    path = T.make_case(case, tmp_path)
    meas = load_measurements(path)
    floors, why = [], []
    real = D._beyond_reach

    def forced(b, item, rival):
        why.append(real(b, item, rival))
        floors.append(b.reach_floor)
        return ""

    monkeypatch.setattr(D, "_beyond_reach", forced)
    ir = meas.ir
    effects = {k: dict(v) for k, v in ir.effects.items()}
    noise = D.noise_model(meas)
    free = resolve_free_parameters(ir, meas.lighting, effects, meas.known_output_groups, str(meas.booth_file))
    prob = FitProblem(meas, effects, free, noise.percent, noise.spectral_percent, {})
    d = D.diagnose(meas, prob, candidates=["smooth_filter", hyp])
    assert why and why[0].startswith("not refitted: hardware that only moves light leaves the white tile's "
                                     "spectrum at best χ² ")
    s = next(x for x in d.suspects if x.items == (D.HYPOTHESIS_PREFIX + hyp,))
    sp = s.fit.spectral_residual_percent
    tile_chi2 = float(np.sum((sp[np.isfinite(sp)] / noise.spectral_percent) ** 2))
    assert tile_chi2 >= floors[0] - 1e-6
    # refitted anyway, its geometry is still not profiled (it cannot rival the filter either way),
    # and the hardware it suggests says so
    assert s.fit.hypothesis_data["not_profiled"].startswith("geometry not fitted: at best ΔBIC ")
    assert "geometry" not in s.fit.hypothesis_data
    assert next(iter(s.hardware.values())).startswith("# hypothesis: geometry not fitted")
    # and the floor is not vacuous: most of the tile's misfit is out of reach
    assert floors[0] > 0.5 * D._chi2_parts(d.base, noise)[1]


def test_no_floor_where_the_refit_reshapes_the_lamps_spectra():
    # a booth whose enabled spectral effect is refitted with every candidate: the lamps'
    # spectra move in the hardware's refit too, out of the cone; the hardware is refitted
    import lbscene.engine.loop.diagnose as D
    from lbscene.engine.loop.fit import FreeParameter

    level = [FreeParameter("group.tubes.intensity_scale", (0.1, 10.0), 1.0)]
    b = SimpleNamespace(problem=SimpleNamespace(tile_row=0), free=level, reach_floor=None)
    assert D._reshapes_spectra(level) is False
    for target in ("effect.lamp_spectrum_shift.shift_nm", "effect.spectral_filter.coefficients_0"):
        b.free = level + [FreeParameter(target, (-10.0, 10.0), 0.0)]
        assert D._reshapes_spectra(b.free) is True
        assert D._beyond_reach(b, "hypothesis:mirror", rival=1e9) == ""
        assert b.reach_floor is None             # not even computed
