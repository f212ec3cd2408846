"""Undeclared hardware found, and fitted, on data from an independent renderer.

The truth is Mitsuba 3, committed as data beside the script that rendered it
(``tests/data/hypotheses/<scene>/truth-{a3,floor}.csv``, ``render_cases.py`` there): booths of
other sizes, lamp layouts and plate heights than the validation scenes, each with hardware the
booth file handed to the diagnosis does not declare — a black luminaire cavity (its occluders
deleted and the ceiling declared in the walls' grey), a ceiling darker than declared, walls
lighter than declared, a rough plate (deleted), an opal plate (deleted), a plane mirror above each
tube (deleted), a vertical mirror behind each of two tubes along the side walls (deleted).  As in
``tests/engine/test_diagnosis_on_truth.py`` (whose helpers are reused), 1 % seeded meter noise is added and ``compare`` runs on the edited booth.

Every case states the verdicts the data allow; the truth must be in the verdict (named, or one
of a tie).  The hardware YAML of the truth's explanation, merged into the booth file
(:func:`lbscene.engine.loop.hypotheses.paste_hardware`), must bring the RMSE to within
:data:`AFTER_FACTOR` × the noise.  ``CASES`` and :func:`run_case` are shared with
``benchmarks/hypothesis_truth_table.py``.
"""

from __future__ import annotations

import importlib.util
import re
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest

HERE = Path(__file__).resolve().parent
DATA = HERE.parents[0] / "data" / "hypotheses"
NOISE_PERCENT = 1.0
AFTER_FACTOR = 1.5


def _shared():
    name = "diagnosis_on_truth_shared"
    if name not in sys.modules:
        spec = importlib.util.spec_from_file_location(name, HERE / "test_diagnosis_on_truth.py")
        mod = importlib.util.module_from_spec(spec)
        sys.modules[name] = mod
        spec.loader.exec_module(mod)
    return sys.modules[name]


@dataclass(frozen=True)
class Case:
    id: str
    scene: str                    # folder under tests/data/hypotheses
    grid: str                     # a3 or floor
    remove: tuple[str, ...]       # what the user's booth file lacks (see _edit)
    known: bool                   # lamp output declared known
    truth: str                    # the effect the truth's hardware turns on
    #: verdicts the data allow; ``ambiguous:<id>`` allows any tie that lists ``<id>``
    allowed: tuple[str, ...]
    seed: int = 0
    slow: bool = False
    #: a known gap of the model on this truth (the case is expected to fail, and says why)
    gap: str = ""
    #: the hypothesis whose hardware is the truth, where several share ``truth`` (the ceiling's and
    #: the walls' reflectance are both ``surface_reflectance``): its explanation is the one pasted
    hypothesis: str = ""

    def allows(self, verdict) -> bool:
        if str(verdict) in self.allowed:
            return True
        return verdict.kind == "ambiguous" and any(
            a.startswith("ambiguous:") and a.split(":", 1)[1] in verdict.tied for a in self.allowed)

    @property
    def folder(self) -> Path:
        return DATA / self.scene


_CAVITY = ("effect:aperture_occlusion", "section:occluders", "surface:ceiling=wall")
_CEILING = ("surface:ceiling=wall",)
_PLATE = ("effect:diffuser", "section:diffuser")
_MIRROR = ("effect:reflector", "section:reflectors", "lamp:reflector")
_WALLS = ("surface:left_wall=ceiling", "surface:right_wall=ceiling", "surface:rear_wall=ceiling")
CASES = [
    Case("cavity-floor-known", "cavity-wide", "floor", _CAVITY, True, "aperture_occlusion",
         ("missing:aperture_occlusion",), slow=True),
    Case("cavity-floor-fitted", "cavity-wide", "floor", _CAVITY, False, "aperture_occlusion",
         ("missing:aperture_occlusion", "ambiguous:aperture_occlusion"), slow=True,
         gap="the verdict is ambiguous:surface_reflectance,angular_profile: with the output fitted the "
             "cavity leaves 1.31 % RMS at 1 % noise, and every explanation brings it to the noise (the "
             "cavity 0.936 %, the walls' reflectance 0.945 %, the ceiling's 0.947 %, an angular profile "
             "1.02 %).  The cavity fits best but prices four parameters (its opening along the tubes, "
             "across them, its height and its inside, each pinned) against one: Delta BIC 36.7 against "
             "48.0, 1.3 past the tie margin.  The resamples give missing:surface_reflectance in 54 %.  "
             "The truth's ceiling is black, so the ceiling's reflectance found dark is true of it; the "
             "plate's edge shows too faintly to price the rest"),
    Case("cavity-a3-known", "cavity-wide", "a3", _CAVITY, True, "aperture_occlusion",
         ("missing:aperture_occlusion", "ambiguous:aperture_occlusion"), slow=True),
    # the opening's edge lies far beyond the A3 sheet: with the output fitted the sheet sees a
    # level only (RMSE at the noise), and the fit takes it
    Case("cavity-a3-fitted", "cavity-wide", "a3", _CAVITY, False, "aperture_occlusion",
         ("missing:aperture_occlusion", "ambiguous:aperture_occlusion", "none"), slow=True),
    Case("ceiling-floor-known", "ceiling-dark", "floor", _CEILING, True, "surface_reflectance",
         ("missing:surface_reflectance", "ambiguous:surface_reflectance"), slow=True),
    Case("ceiling-a3-known", "ceiling-dark", "a3", _CEILING, True, "surface_reflectance",
         ("missing:surface_reflectance", "ambiguous:surface_reflectance"), slow=True),
    Case("ceiling-floor-fitted", "ceiling-dark", "floor", _CEILING, False, "surface_reflectance",
         ("missing:surface_reflectance", "ambiguous:surface_reflectance", "none"), slow=True),
    # side and rear walls at 0.70, declared in the ceiling's 0.35 (three tubes along x, 900 mm wide)
    Case("walls-floor-known", "walls-light", "floor", _WALLS, True, "surface_reflectance",
         ("missing:surface_reflectance", "ambiguous:surface_reflectance"), slow=True,
         hypothesis="walls_reflectance"),
    Case("walls-a3-known", "walls-light", "a3", _WALLS, True, "surface_reflectance",
         ("missing:surface_reflectance", "ambiguous:surface_reflectance"), slow=True,
         hypothesis="walls_reflectance"),
    Case("walls-floor-fitted", "walls-light", "floor", _WALLS, False, "surface_reflectance",
         ("missing:surface_reflectance", "ambiguous:surface_reflectance", "none"), slow=True,
         hypothesis="walls_reflectance"),
    Case("rough-plate-a3-known", "rough-plate", "a3", _PLATE, True, "diffuser",
         ("missing:diffuser", "ambiguous:diffuser"), slow=True),
    # a plate on the A3 sheet with the output fitted changes the level only: the fit takes it
    Case("rough-plate-a3-fitted", "rough-plate", "a3", _PLATE, False, "diffuser",
         ("missing:diffuser", "ambiguous:diffuser", "none"), slow=True),
    Case("rough-plate-floor-known", "rough-plate", "floor", _PLATE, True, "diffuser",
         ("missing:diffuser", "ambiguous:diffuser"), slow=True),
    # (it was a tie of detector_cosine_error, angular_profile and tube_end_falloff while the
    # plate's light went to one lamp group and the plate transmitted everything)
    Case("rough-plate-floor-fitted", "rough-plate", "floor", _PLATE, False, "diffuser",
         ("missing:diffuser", "ambiguous:diffuser"), slow=True),
    # an opal plate 70 mm under three tubes running front to back, in a 30 % grey box (deleted):
    # the plate's type (opal or rough glass) is fitted too
    Case("opal-plate-a3-known", "opal-plate", "a3", _PLATE, True, "diffuser",
         ("missing:diffuser", "ambiguous:diffuser"), slow=True),
    Case("opal-plate-a3-fitted", "opal-plate", "a3", _PLATE, False, "diffuser",
         ("missing:diffuser", "ambiguous:diffuser", "none"), slow=True),
    # (it was 'unexplained' while a fitted transmittance left the opal layer at the declared one's
    # and the plate's faces were always polished: this plate's are index-matched)
    Case("opal-plate-floor-known", "opal-plate", "floor", _PLATE, True, "diffuser",
         ("missing:diffuser", "ambiguous:diffuser"), slow=True),
    Case("opal-plate-floor-fitted", "opal-plate", "floor", _PLATE, False, "diffuser",
         ("missing:diffuser", "ambiguous:diffuser"), slow=True),
    # a plane mirror above each tube, facing down (deleted, and the lamps' reference to it).
    # The booth with its mirrors declared is 0.5 % RMS off this truth on the floor (0.9 % while
    # the mirrors acted on the lamps' light only, and the verdict was 'unexplained')
    Case("mirror-floor-known", "mirror-above", "floor", _MIRROR, True, "reflector",
         ("missing:reflector", "ambiguous:reflector"), slow=True),
    Case("mirror-a3-known", "mirror-above", "a3", _MIRROR, True, "reflector",
         ("missing:reflector", "ambiguous:reflector"), slow=True),
    Case("mirror-floor-fitted", "mirror-above", "floor", _MIRROR, False, "reflector",
         ("missing:reflector", "ambiguous:reflector", "none"), slow=True),
    Case("mirror-a3-fitted", "mirror-above", "a3", _MIRROR, False, "reflector",
         ("missing:reflector", "ambiguous:reflector", "none"), slow=True),
    # a vertical mirror behind each of two tubes along the side walls, facing the room (deleted):
    # the mirror's placement (above or behind the lamps) is fitted too
    # (its width is fitted: 40–200 mm; the placement chosen with each at its best distance)
    Case("mirror-sides-a3-known", "mirror-sides", "a3", _MIRROR, True, "reflector",
         ("missing:reflector", "ambiguous:reflector"), slow=True),
    Case("mirror-sides-floor-known", "mirror-sides", "floor", _MIRROR, True, "reflector",
         ("missing:reflector", "ambiguous:reflector"), slow=True),
    Case("mirror-sides-a3-fitted", "mirror-sides", "a3", _MIRROR, False, "reflector",
         ("missing:reflector", "ambiguous:reflector", "none"), slow=True),
    Case("mirror-sides-floor-fitted", "mirror-sides", "floor", _MIRROR, False, "reflector",
         ("missing:reflector", "ambiguous:reflector"), slow=True),
]


def _edit(text: str, remove: tuple[str, ...], others=None) -> str:
    """The booth file as the user has it: ``surface:<role>=<material>`` declares a surface with
    another material; the other edits are ``test_diagnosis_on_truth``'s (``others``)."""
    rest = []
    for what in remove:
        kind, name = what.split(":")
        if kind == "surface":
            role, mat = name.split("=")
            text = re.sub(rf"(surfaces: \{{[^}}]*\b{role}: )\w+", rf"\g<1>{mat}", text)
        else:
            rest.append(what)
    return (others or _shared()._edit)(text, tuple(rest))


def make_case(case: Case, tmp: Path) -> Path:
    """The user's booth (hardware removed) and a measurement set from the truth; its path."""
    S = _shared()
    proxy = S.Case(case.id, case.scene, case.grid, (), case.known, (), seed=case.seed)
    orig_edit, orig_folder = S._edit, S.Case.folder
    try:
        S._edit = lambda text, remove: _edit(text, case.remove, orig_edit)
        S.Case.folder = property(lambda self: case.folder)
        return S.make_case(proxy, tmp)
    finally:
        S._edit, S.Case.folder = orig_edit, orig_folder


def truth_suspect(res, case: Case):
    """The diagnosis' explanation that is the truth (the verdict's, or the tied one), or None."""
    d = res.diagnosis
    named = res.verdict.effects if res.verdict.kind == "missing" else tuple(getattr(res.verdict, "tied", ()))
    if case.truth not in named:
        return None
    mine = [s for s in d.suspects + d.pairs if s.effects == (case.truth,)
            and (not case.hypothesis or f"hypothesis:{case.hypothesis}" in s.items)]
    return mine[0] if mine else None


def run_case(case: Case, tmp: Path) -> dict:
    """Compare, merge the truth's hardware YAML, compare again: the row of the table."""
    import time

    from lbscene.engine.loop.compare import run_compare
    from lbscene.engine.loop.diagnose import effects_snippet
    from lbscene.engine.loop.hypotheses import paste_hardware

    m = make_case(case, tmp)
    t0 = time.perf_counter()
    res = run_compare(m)
    secs = time.perf_counter() - t0
    row = {"case": case.id, "verdict": str(res.verdict), "allowed": case.allows(res.verdict),
           "rmse_before": res.fit.rmse_percent, "rmse_after": None, "verdict_after": None,
           "seconds": secs, "snippet": None, "fitted": None}
    s = truth_suspect(res, case)
    if s is not None:
        booth = tmp / "booth" / "booth.yaml"
        eff = {**yaml_effects(booth), **{e: dict(p) for e, p in s.params_by_effect.items()}}
        snippet = "".join(s.hardware.values()) + effects_snippet(eff, highlight=set(s.effects))
        row["snippet"] = snippet
        row["fitted"] = {k: (v, s.fit.stderr.get(k)) for k, v in s.fit.values.items()
                         if k.startswith(("hypothesis.", "effect."))}
        booth.write_text(paste_hardware(booth.read_text(), snippet))
        after = run_compare(m)
        row["rmse_after"] = after.fit.rmse_percent
        row["verdict_after"] = str(after.verdict)
    return row


def yaml_effects(booth: Path) -> dict:
    from ruamel.yaml import YAML

    return {k: dict(v or {}) for k, v in ((YAML(typ="safe").load(booth.read_text()) or {}).get("effects") or {}).items()}


def _marks(c: Case) -> list:
    return ([pytest.mark.slow] if c.slow else []) + ([pytest.mark.xfail(reason=c.gap, strict=False)] if c.gap else [])


@pytest.mark.parametrize("case", [pytest.param(c, marks=_marks(c)) for c in CASES], ids=[c.id for c in CASES])
def test_hypothesis_on_independent_truth(case, tmp_path):
    if not (case.folder / f"truth-{case.grid}.csv").is_file():
        pytest.skip(f"no committed truth for {case.scene} ({case.grid})")
    row = run_case(case, tmp_path)
    assert row["allowed"], (row["verdict"], case.allowed)
    if case.allowed != ("none",) and row["verdict"] != "none":
        assert row["snippet"] is not None, row
        # the truth's hardware, merged into the booth file, brings the error to the noise
        assert row["rmse_after"] <= AFTER_FACTOR * NOISE_PERCENT, row


@pytest.mark.slow
def test_the_cavity_hypothesis_fits_the_truths_cavity(tmp_path):
    """The cavity hypothesis alone on the floor-wide grid, output known: its profiled hardware
    (plate height, opening across the tubes, the inside's reflectance) brings the error to the
    noise, the black inside is found black, and its YAML merged into the booth file does too."""
    from lbscene.engine.loop.compare import run_compare
    from lbscene.engine.loop.diagnose import diagnose, effects_snippet, noise_model
    from lbscene.engine.loop.fit import FitProblem, resolve_free_parameters
    from lbscene.engine.loop.hypotheses import paste_hardware
    from lbscene.engine.loop.measurements import load_measurements

    case = next(c for c in CASES if c.id == "cavity-floor-known")
    m = make_case(case, tmp_path)
    meas = load_measurements(m, None, ())
    noise = noise_model(meas)
    eff = {k: dict(v) for k, v in meas.ir.effects.items()}
    free = resolve_free_parameters(meas.ir, meas.lighting, eff, meas.known_output_groups, str(meas.booth_file))
    d = diagnose(meas, FitProblem(meas, eff, free, noise.percent, noise.spectral_percent, {}),
                 candidates=["aperture_plate"])
    s = next(x for x in d.suspects if x.items == ("hypothesis:aperture_plate",))
    assert s.rmse_percent_after <= AFTER_FACTOR * NOISE_PERCENT
    rho, rho_se = s.fit.hypothesis_data["geometry"]["aperture_plate"]["interior_reflectance"]
    # truth: black inside (declared 0.5 in the user's file)
    assert rho <= 0.1 and rho_se is not None
    booth = tmp_path / "booth" / "booth.yaml"
    snippet = "".join(s.hardware.values()) + effects_snippet({**yaml_effects(booth), **s.params_by_effect})
    booth.write_text(paste_hardware(booth.read_text(), snippet))
    assert run_compare(m).fit.rmse_percent <= AFTER_FACTOR * NOISE_PERCENT


@pytest.mark.slow
def test_the_mirror_hypothesis_fits_the_truths_mirrors(tmp_path):
    """The mirror hypothesis alone on the floor grid, output fitted (the truth: 90 mm strips of
    88 % 40 mm behind two tubes, facing the room): behind the lamps, at 40 mm, 90 mm wide, each
    with an uncertainty, brings the error to the noise."""
    from lbscene.engine.loop.diagnose import diagnose, noise_model
    from lbscene.engine.loop.fit import FitProblem, resolve_free_parameters
    from lbscene.engine.loop.measurements import load_measurements

    case = next(c for c in CASES if c.id == "mirror-sides-floor-fitted")
    meas = load_measurements(make_case(case, tmp_path), None, ())
    noise = noise_model(meas)
    eff = {k: dict(v) for k, v in meas.ir.effects.items()}
    free = resolve_free_parameters(meas.ir, meas.lighting, eff, meas.known_output_groups, str(meas.booth_file))
    d = diagnose(meas, FitProblem(meas, eff, free, noise.percent, noise.spectral_percent, {}), candidates=["mirror"])
    s = next(x for x in d.suspects if x.items == ("hypothesis:mirror",))
    assert s.explains and s.rmse_percent_after <= AFTER_FACTOR * NOISE_PERCENT
    geo = s.fit.hypothesis_data["geometry"]["mirror"]
    assert geo["behind"][0] == 1.0
    (dist, dist_se), (width, width_se) = geo["distance_mm"], geo["width_mm"]
    assert dist_se is not None and abs(dist - 40.0) <= max(2 * dist_se, 5.0)
    assert width_se is not None and abs(width - 90.0) <= max(2 * width_se, 15.0)
    assert s.fit.values["effect.reflector.reflectance_scale"] == pytest.approx(0.88, abs=0.1)


def test_edit_declares_the_ceiling_otherwise():
    text = (DATA / "cavity-wide" / "booth.yaml").read_text()
    out = _edit(text, _CAVITY)
    assert "occluders:" not in out and "aperture_occlusion" not in out
    assert "surfaces: {floor: floor, left_wall: wall, right_wall: wall, rear_wall: wall, ceiling: wall}" in out


def test_truth_is_current():
    """The committed truth was rendered from the booth files as they are now."""
    from lbscene.engine.truth.validation import booth_files_sha256, read_truth_csv

    for scene in sorted(p for p in DATA.iterdir() if p.is_dir()):
        for f in sorted(scene.glob("truth-*.csv")):
            t = read_truth_csv(f)
            assert t.meta["booth_sha256"] == booth_files_sha256(scene), f
            # the truth's own noise is well below the meter noise the cases add
            assert np.max(t.std_error_lx / t.illuminance_lx) <= 0.0035, f


@pytest.mark.slow
def test_truth_rerenders(tmp_path):
    """A few receivers of every scene re-rendered with fresh seeds agree with the committed truth."""
    spec = importlib.util.spec_from_file_location("render_hypothesis_cases", DATA / "render_cases.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    scenes = [s for s in mod.SCENES if (DATA / s / "truth-a3.csv").is_file()]
    assert max(mod.check_scene(s, 2) for s in scenes) == 0
