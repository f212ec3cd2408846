"""
Name the physical effect the model is missing.

For every registered effect the booth does not enable (and whose booth
elements exist: a diffuser needs ``diffuser:``, an aperture ``occluders:``…),
refit with the effect added and its ``fit_parameters`` free, on top of the
base fit (the booth's free parameters plus the parameters of the effects it
already enables).  Each suspect gets

* ``rmse_percent_after``: illuminance RMSE (%) after the refit;
* ``score``: the drop of the Bayesian information criterion
  BIC = χ² + k·ln n (χ² in units of the measurement noise, k the number of
  free parameters): positive = better even after paying for the extra
  parameters;
* ``structure_after``: Moran's I of the residuals (nearest-neighbour
  weights): spatially organised residuals are a sign of missing physics.

The enabled effects' parameters are refitted with each candidate (an earlier
round's estimate may be biased by the effect still missing), except those the
data cannot pin down (standard error over a quarter of their range): those
are held at the booth's values, since refitting them cannot change a score.

Verdict:

``none``
    the base residual is already at the noise level (χ²/dof within 3σ of 1):
    nothing is invented.
``missing:<id>``
    one suspect beats every other by more than :data:`TIE_MARGIN` BIC units
    and the base by more than :data:`SIGNIFICANT`.
``ambiguous:<id>,<id>…``
    several suspects explain the data within :data:`TIE_MARGIN` of the best:
    the layout cannot tell them apart — plan more points
    (:mod:`lbscene.engine.plan`) or declare the lamp output known.
``unexplained``
    no suspect helps significantly: the report says where it fails.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

from .fit import FitProblem, FitResult, effect_parameter

__all__ = ["Suspect", "Diagnosis", "diagnose", "consistent_with_noise", "effects_snippet",
           "moran_i", "SIGNIFICANT", "TIE_MARGIN", "SCORING_TOLERANCE", "PINNED_FRACTION", "NoiseModel",
           "noise_model"]

#: BIC improvement a suspect needs to count at all (strong evidence on Kass–Raftery's scale).
SIGNIFICANT = 10.0
#: Suspects within this many BIC units of the best are tied.
TIE_MARGIN = 10.0
#: χ²/dof consistency with noise: within this many standard deviations of 1.
NOISE_Z = 3.0
#: least_squares xtol/ftol of the scoring refits: χ² (≈ n) to ~0.01 unit, far below the BIC
#: margins; 1e-8 made weakly identified candidates (tube-end falloff: level and length) crawl
#: along their valley for 400+ evaluations without changing the score.
SCORING_TOLERANCE = 1e-4


@dataclass
class NoiseModel:
    """The noise the fit uses and where it came from."""

    percent: float
    estimate_percent: float | None
    declared_percent: float | None
    spectral_percent: float
    source: str


def noise_model(meas) -> NoiseModel:
    from .fit import DEFAULT_NOISE_PERCENT, DEFAULT_SPECTRAL_NOISE_PERCENT, estimate_noise_percent

    est = estimate_noise_percent(meas.illuminance)
    dec = meas.declared_noise_percent
    if dec is not None:
        pct, src = dec, "declared instrument repeatability"
    elif est is not None:
        # never trust a noise estimate far below a good meter's repeatability
        pct, src = max(est, 0.2), "estimated from the data (smooth-surface residual)"
    else:
        pct, src = DEFAULT_NOISE_PERCENT, "default (too few points to estimate)"
    return NoiseModel(pct, est, dec, meas.spectral_noise_percent or DEFAULT_SPECTRAL_NOISE_PERCENT, src)


def consistent_with_noise(fit: FitResult, z: float = NOISE_Z, noise_percent: float | None = None,
                          spectral_noise_percent: float | None = None, level_test: bool = False) -> bool:
    """Residuals consistent with the noise.

    Each data block (illuminance readings, white-tile bands) on its own:
    χ²/dof within ``z`` standard deviations of 1.  With ``level_test`` (lamp
    output declared known) also the mean illuminance residual must be within
    ``z`` standard errors of 0 — a level mismatch of a fraction of the noise
    is invisible in χ² but certain in the mean of 55 readings.
    """
    dof = fit.dof
    if fit.chi2 / dof > 1.0 + z * math.sqrt(2.0 / dof):
        return False
    k = fit.n_params
    if noise_percent:
        r = fit.residual_percent / noise_percent
        if r.size:
            d = max(r.size - k, 1)
            if float(r @ r) / d > 1.0 + z * math.sqrt(2.0 / d):
                return False
            if level_test and abs(r.mean()) * math.sqrt(r.size) > z:
                return False
    if spectral_noise_percent:
        s = fit.spectral_residual_percent
        if s is not None:
            s = s[np.isfinite(s)] / spectral_noise_percent
            if s.size > 2:
                d = max(s.size - 1, 1)
                if float(s @ s) / d > 1.0 + z * math.sqrt(2.0 / d):
                    return False
    return True


def moran_i(points: np.ndarray, r: np.ndarray, k: int = 4) -> float:
    """Moran's I of residuals with k-nearest-neighbour weights (0: no spatial structure)."""
    n = len(r)
    if n < k + 2:
        return float("nan")
    d = np.linalg.norm(points[:, None, :] - points[None, :, :], axis=2)
    np.fill_diagonal(d, np.inf)
    nb = np.argsort(d, axis=1)[:, :k]
    z = r - r.mean()
    den = float(z @ z)
    if den <= 0:
        return 0.0
    num = float(sum(z[i] * z[nb[i]].sum() for i in range(n)))
    return (n / (n * k)) * num / den


@dataclass
class Suspect:
    effect: str
    rmse_percent_after: float
    score: float
    chi2: float
    n_params: int
    explains: bool
    structure_after: float
    params: dict
    fit: FitResult | None = None
    spectral_rmse_after: float | None = None

    def to_json(self) -> dict:
        return {"effect": self.effect, "rmse_percent_after": round(self.rmse_percent_after, 4),
                "score": round(self.score, 3), "chi2": round(self.chi2, 3), "n_params": self.n_params,
                "explains_to_noise": self.explains, "structure_after": _r(self.structure_after),
                "spectral_rmse_percent_after": _r(self.spectral_rmse_after),
                "fitted_params": {k: _r(v, 6) for k, v in self.params.items()}}


def _r(x, nd=4):
    if x is None or (isinstance(x, float) and not math.isfinite(x)):
        return None
    return round(float(x), nd)


@dataclass
class Diagnosis:
    verdict: str
    base: FitResult
    suspects: list[Suspect]
    skipped: dict[str, str]
    noise: NoiseModel
    tied: list[str] = field(default_factory=list)
    explanation: list[str] = field(default_factory=list)
    snippet: str | None = None
    where: list[dict] = field(default_factory=list)
    structure_before: float = float("nan")
    consistent: bool = False
    #: enabled effects' parameters refitted with every candidate, and those held at the booth's
    #: values because these data cannot pin them (see _pinned_by_data)
    refitted: list[str] = field(default_factory=list)
    held: list[str] = field(default_factory=list)

    def to_json(self) -> dict:
        return {"verdict": self.verdict,
                "suspects": [s.to_json() for s in self.suspects],
                "not_tested": self.skipped,
                "tied": self.tied,
                "explanation": self.explanation,
                "snippet": self.snippet,
                "where_it_fails": self.where,
                "base_chi2_per_dof": round(self.base.chi2 / self.base.dof, 4),
                "structure_before": _r(self.structure_before),
                "base_consistent_with_noise": self.consistent,
                "joint_parameters_refitted": self.refitted,
                "joint_parameters_held": self.held}


# --------------------------------------------------------------------------- snippets

def _fmt(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, float):
        return f"{v:.4g}"
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_fmt(x) for x in v) + "]"
    if v is None:
        return "null"
    return str(v)


def effects_snippet(effects: dict, highlight: str | None = None) -> str:
    """The ``effects:`` block to paste into the booth file (non-default parameters only)."""
    from .effects.registry import get_effect

    lines = ["effects:"]
    for eid in sorted(effects):
        cls = get_effect(eid)
        defaults = cls.Params().model_dump(mode="json")
        params = {k: v for k, v in (effects[eid] or {}).items()
                  if k in defaults and (defaults[k] != v or (highlight == eid and k in getattr(
                      cls, "fit_parameters", {})))}
        body = ", ".join(f"{k}: {_fmt(v)}" for k, v in params.items())
        mark = "   # ← add" if eid == highlight else ""
        lines.append(f"  {eid}: {{{body}}}{mark}")
    return "\n".join(lines) + "\n"


# --------------------------------------------------------------------------- diagnosis

#: Enabled effects' parameters are refitted jointly with each candidate only when changing one
#: costs less than this per forward evaluation (seconds, from the effect's ``refit_cost_s`` model).
MAX_JOINT_REFIT_COST_S = 0.15


def _enabled_fit_params(ir, lighting, effects, already) -> list:
    """Fit parameters of the effects the booth already enables (refitted with each candidate, so
    an earlier round's estimate is not frozen while it was biased by the effect still missing)."""
    from .effects.registry import get_effect

    out = []
    names = {fp.target for fp in already}
    for eid in effects:
        cls = get_effect(eid)
        cost = getattr(cls, "refit_cost_s", None)
        if cost is not None and cost(ir, effects.get(eid)) > MAX_JOINT_REFIT_COST_S:
            continue  # e.g. radiosity on a fine mesh: keep the booth's values
        fn = getattr(cls, "fit_parameters_for", None)
        fps = fn(ir, lighting) if fn else dict(getattr(cls, "fit_parameters", {}) or {})
        for name, b in fps.items():
            fp = effect_parameter(eid, name, effects, b)
            if fp.target not in names:
                out.append(fp)
    return out


#: A joint parameter is refitted only if the data pin it: its standard error at the start of the
#: diagnosis (noise-limited, from the Jacobian) is below this fraction of its bounds' range.
PINNED_FRACTION = 0.25


def _pinned_by_data(meas, effects, free, joint, noise, cache) -> tuple[list, list]:
    """Split the enabled effects' parameters into those these data pin down and those they
    cannot (standard error ≥ :data:`PINNED_FRACTION` of the range at the current values).

    A parameter the data cannot pin changes χ² by less than the noise anywhere in a wide
    range: refitting it cannot change a suspect's score, but the optimiser wanders along it
    (each step a new forward evaluation, e.g. new occlusion fractions for an aperture scale),
    which made the X-Rite diagnosis take 15 s.  Those are held at the booth's values.
    """
    if not joint:
        return joint, []
    prob = FitProblem(meas, effects, list(free) + list(joint), noise.percent, noise.spectral_percent, cache)
    x0 = np.array([prob.free[i].initial for i in prob.nl], float)
    A, T, *_ = prob.components(x0)
    scales = prob.scales_for(A, T)
    r = prob.residuals(x0, scales)
    chi2 = float(r @ r)
    # noise-limited: a model still missing an effect fits badly, which must not hide what the
    # data could pin
    se, _, _ = prob._errors(x0, scales, chi2, noise_limited=True)
    keep, held = [], []
    for fp in joint:
        e = se.get(fp.target, float("inf"))
        (keep if e < PINNED_FRACTION * (fp.bounds[1] - fp.bounds[0]) else held).append(fp)
    return keep, held


def _coarsen(effects: dict) -> dict:
    from .effects.registry import get_effect

    out = {}
    for eid, p in effects.items():
        fn = getattr(get_effect(eid), "diagnosis_params", None)
        out[eid] = fn(p) if fn else dict(p or {})
    return out


def candidate_config(ir, lighting, effects, eid, base_free, known):
    """Effects and free parameters with candidate ``eid`` added."""
    from .effects.registry import get_effect
    from .fit import default_free_parameters

    cls = get_effect(eid)
    fn = getattr(cls, "fit_parameters_for", None)
    fps = fn(ir, lighting) if fn else dict(getattr(cls, "fit_parameters", {}) or {})
    init = dict(getattr(cls, "fit_initial", {}) or {})
    new_eff = {k: dict(v or {}) for k, v in effects.items()}
    params = {k: init.get(k, None) for k in fps}
    params = {k: v for k, v in params.items() if v is not None}
    new_eff[eid] = cls.Params.model_validate(params).model_dump(mode="json")
    fn_d = getattr(cls, "diagnosis_params", None)
    if fn_d:
        new_eff[eid] = fn_d(new_eff[eid])
    free = list(base_free)
    names = {fp.target for fp in free}
    for name, b in fps.items():
        fp = effect_parameter(eid, name, new_eff, b)
        if fp.target not in names:
            free.append(fp)
            names.add(fp.target)
    # profiles declared by lamps become fittable once the profile effect is on
    for fp in default_free_parameters(ir, lighting, new_eff, known):
        if fp.target not in names:
            free.append(fp)
            names.add(fp.target)
    return new_eff, free


def _where(meas, fit: FitResult, n: int = 5) -> list[dict]:
    ill = meas.illuminance
    if ill is None or fit.lux_pred is None:
        return []
    r = fit.residual_percent
    order = np.argsort(-np.abs(r))[:n]
    labels = ill.orientation_labels()
    return [{"x_mm": float(ill.points_mm[i, 0]), "y_mm": float(ill.points_mm[i, 1]),
             "z_mm": float(ill.points_mm[i, 2]), "orientation": labels[i],
             "residual_percent": round(float(r[i]), 3), "file": ill.files[i], "line": int(ill.lines[i])}
            for i in order]


def _trend(meas, fit: FitResult) -> list[str]:
    ill = meas.illuminance
    if ill is None or len(ill) < 6:
        return []
    r = fit.residual_percent
    out = []
    names = {0: "x (toward the right wall)", 1: "y (toward the rear wall)", 2: "z (height)"}
    for ax, label in names.items():
        x = ill.points_mm[:, ax]
        if np.ptp(x) < 1e-6:
            continue
        c = float(np.corrcoef(x, r)[0, 1])
        if abs(c) > 0.5:
            out.append(f"the model is too {'low' if c < 0 else 'high'} toward +{label} "
                       f"(residual correlation {c:+.2f})")
    dist_c = np.linalg.norm(ill.points_mm[:, :2], axis=1)
    if np.ptp(dist_c) > 1e-6:
        c = float(np.corrcoef(dist_c, r)[0, 1])
        if abs(c) > 0.5:
            out.append(f"residuals grow {'positive' if c > 0 else 'negative'} away from the floor centre "
                       f"(correlation {c:+.2f})")
    return out


def diagnose(meas, base_problem: FitProblem, *, candidates: list[str] | None = None,
             progress=None, cache: dict | None = None) -> Diagnosis:
    """Refit with each missing effect and rank the suspects (see the module docstring)."""
    from .effects.registry import available_effects

    ir, lighting = meas.ir, meas.lighting
    booth_effects = base_problem.effects
    effects = _coarsen(booth_effects)
    noise = noise_model(meas)
    cache = base_problem.cache if cache is None else cache
    joint = _enabled_fit_params(ir, lighting, effects, base_problem.free)
    # which joint parameters are affordable is decided by each effect's analytic cost model
    # (refit_cost_s), never by timing: the verdict must not depend on the machine's load
    joint, held = _pinned_by_data(meas, effects, list(base_problem.free), joint, noise, cache)
    base_free = list(base_problem.free) + joint
    base_fp = FitProblem(meas, effects, base_free, noise.percent, noise.spectral_percent, cache,
                         tolerance=SCORING_TOLERANCE)
    base = base_fp.solve()
    # every candidate refit starts from the base solution: the candidate's own parameters are the
    # only ones far from their optimum, so the refits need a few iterations instead of dozens
    base_free = [replace(fp, initial=float(np.clip(base.values.get(fp.target, fp.initial), *fp.bounds)))
                 for fp in base_free]
    n = base.n_residuals
    logn = math.log(max(n, 2))
    base_bic = base.chi2 + len(base_free) * logn
    pts = meas.illuminance.points_mm if meas.illuminance is not None else np.zeros((0, 3))
    structure_before = moran_i(pts, base.residual_percent) if len(pts) else float("nan")

    registry = available_effects()
    todo, skipped = [], {}
    for eid, cls in registry.items():
        if eid in effects or (candidates is not None and eid not in candidates):
            continue
        why = cls.applicable(ir, lighting) if hasattr(cls, "applicable") else None
        if why:
            skipped[eid] = why
        else:
            todo.append(eid)
    ctest = dict(noise_percent=noise.percent, spectral_noise_percent=noise.spectral_percent,
                 level_test=bool(meas.known_output_groups))
    suspects = []
    for k, eid in enumerate(todo):
        if progress:
            progress(k, len(todo), eid)
        new_eff, free = candidate_config(ir, lighting, effects, eid, base_free,
                                         meas.known_output_groups)
        prob = FitProblem(meas, new_eff, free, noise.percent, noise.spectral_percent, cache,
                          tolerance=SCORING_TOLERANCE)
        fit = prob.solve()
        bic = fit.chi2 + len(free) * logn
        params = {fp.name: fit.values[fp.target] for fp in free if fp.scope == "effect" and fp.ident == eid}
        suspects.append(Suspect(
            effect=eid, rmse_percent_after=fit.rmse_percent, score=base_bic - bic, chi2=fit.chi2,
            n_params=len(free) - len(base_free), explains=consistent_with_noise(fit, **ctest),
            structure_after=moran_i(pts, fit.residual_percent) if len(pts) else float("nan"),
            params=params, fit=fit, spectral_rmse_after=fit.spectral_rmse_percent))
    if progress:
        progress(len(todo), len(todo), "")
    suspects.sort(key=lambda s: -s.score)

    d = Diagnosis("none", base, suspects, skipped, noise, structure_before=structure_before,
                  refitted=[fp.target for fp in joint], held=[fp.target for fp in held])
    d.consistent = consistent_with_noise(base, **ctest)
    red = base.chi2 / base.dof
    d.where = _where(meas, base)
    helpful = [s for s in suspects if s.score > SIGNIFICANT]
    # χ²/dof is a weak test (its spread is √(2/dof)); a suspect that lowers the BIC by more than
    # SIGNIFICANT is strong evidence even when χ² looks acceptable, so only the two together say
    # "none".  Under pure noise one extra parameter gains χ²₁ − ln n, beyond 10 with p < 1e-3.
    if d.consistent and not helpful:
        d.verdict = "none"
        d.explanation.append(
            f"the residual is at the noise level (χ²/dof = {red:.2f} with noise {noise.percent:.2g} %) "
            "and no candidate effect improves the fit significantly: no missing effect is needed "
            "to explain these data")
        return d
    if d.consistent:
        d.explanation.append(
            f"χ²/dof = {red:.2f} is within the noise, but {helpful[0].effect} lowers the BIC by "
            f"{helpful[0].score:.1f}: the residual has structure that noise does not explain")
    if not helpful:
        d.verdict = "unexplained"
        d.explanation.append(f"χ²/dof = {red:.2f}: the residual is above the noise "
                             f"({noise.percent:.2g} %), but no registered effect explains it")
        d.explanation.extend(_trend(meas, base))
        if d.where:
            w = d.where[0]
            d.explanation.append(
                f"largest residual {w['residual_percent']:+.2f} % at ({w['x_mm']:g}, {w['y_mm']:g}, "
                f"{w['z_mm']:g}) mm ({w['file']}:{w['line']})")
        return d
    best = helpful[0]
    tied = [s for s in helpful if s.score >= best.score - TIE_MARGIN]
    d.tied = [s.effect for s in tied]
    if len(tied) > 1:
        d.verdict = "ambiguous:" + ",".join(d.tied)
        d.explanation.append(
            "these effects explain the data equally well (BIC within "
            f"{TIE_MARGIN:g}): " + ", ".join(f"{s.effect} (RMSE {s.rmse_percent_after:.2f} %, score "
                                              f"{s.score:.1f})" for s in tied))
        d.explanation.append("run `lbscene plan` for the points that tell them apart, or declare the "
                             "lamp output known (fit.known_output_groups)")
    else:
        d.verdict = f"missing:{best.effect}"
        runner = next((s for s in suspects if s is not best), None)
        msg = (f"{best.effect} lowers the RMSE from {base.rmse_percent:.2f} % to "
               f"{best.rmse_percent_after:.2f} % (BIC −{best.score:.1f})")
        if runner is not None:
            msg += f"; the next suspect, {runner.effect}, scores {runner.score:.1f}"
        d.explanation.append(msg)
        if not best.explains:
            d.explanation.append(
                f"after adding it the residual is still above the noise (χ²/dof = "
                f"{best.fit.chi2 / best.fit.dof:.2f}): add it, run compare again — another effect "
                "may be missing too")
        # the suggestion is minimal: the booth's effects exactly as declared plus the new one with
        # its fitted parameters.  The joint refit of the enabled effects' parameters is there to
        # score candidates fairly; a 55-point grid rarely pins those values, so they stay the user's.
        eff = {k: dict(v or {}) for k, v in booth_effects.items()}
        eff[best.effect] = dict(best.params)
        d.snippet = effects_snippet(eff, highlight=best.effect)
    if base.spectral_rmse_percent is not None and d.verdict.startswith(("missing", "ambiguous")):
        sp = [s for s in tied if s.spectral_rmse_after is not None]
        if sp:
            d.explanation.append("white-tile spectrum: RMSE " f"{base.spectral_rmse_percent:.2f} % → " +
                                 ", ".join(f"{s.effect} {s.spectral_rmse_after:.2f} %" for s in sp))
    return d
