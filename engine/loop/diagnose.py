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
    the booth as declared passes a χ² goodness-of-fit test at level :data:`GOF_ALPHA`
    (all the data, and the readings and the white tile each on their own:
    :math:`P(χ^2_ν ≥ χ^2) ≥ α`) and no suspect improves the fit significantly: nothing is
    invented.
``missing:<id>``
    one suspect beats every other by more than :data:`TIE_MARGIN` BIC units
    and the base by more than :data:`SIGNIFICANT`.
``ambiguous:<id>,<id>…``
    several suspects explain the data within :data:`TIE_MARGIN` of the best:
    the layout cannot tell them apart — plan more points
    (:mod:`lbscene.engine.loop.plan`) or declare the lamp output known.  Also where the
    verdict the data give recurs in fewer than :data:`STABLE_SHARE` of the noise resamples
    but a tie of it and its rivals does (:func:`_widened`): the tie is what the data support.
``unexplained``
    no suspect helps significantly: the report says where it fails.
``unstable:<verdict> (<share>), <rival> (<share>)…``
    the verdict the data give recurs in fewer than :data:`STABLE_SHARE` of the noise
    resamples (:class:`Confidence`), and no tie of it with its rivals does (the resamples say
    ``none`` or ``unexplained`` too often): it is given with the verdicts the resamples give
    instead and their shares, and no edit is suggested.

Explanations that change spectra only (a filter in front of the lamps, the lamps' spectrum
reshaped) are one thing to a spectroradiometer: when the best is one of them, the others that
also reach the noise are tied with it, the one with fewer parameters first.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from itertools import combinations
from typing import Literal

import numpy as np

from lbscene.engine.files.parallel import map_forked, process_count

from .fit import (GOF_ALPHA, NOISE_Z, FitProblem, FitResult, _spectral_parameters, _tile_consistent,  # noqa: F401
                  chi2_limit, consistent_with_noise, effect_parameter, readings_consistent, spectral_parameters)
from .hypotheses import HYPOTHESES, applicable_hypotheses, profile_geometry

__all__ = ["Suspect", "Diagnosis", "Verdict", "Confidence", "PAIR_CANDIDATES", "BOOTSTRAP_SAMPLES", "diagnose", "consistent_with_noise", "effects_snippet",
           "moran_i", "SIGNIFICANT", "TIE_MARGIN", "SCORING_TOLERANCE", "PINNED_FRACTION", "NoiseModel",
           "noise_model", "GOF_ALPHA", "STABLE_SHARE", "chi2_limit"]

#: prefix of a hypothesis (hardware the booth does not declare) among the diagnosis' candidates
HYPOTHESIS_PREFIX = "hypothesis:"
#: forward-model cache stores keyed by the content of their geometry, shared by the refits of
#: augmented booths (hypotheses) with the booth's own
SHARED_GEOMETRY_STORES = ("_pairs", ("_memo", "hit"))
#: BIC improvement a suspect needs to count at all (strong evidence on Kass–Raftery's scale).
SIGNIFICANT = 10.0
#: Suspects within this many BIC units of the best are tied.
TIE_MARGIN = 10.0
#: When no single effect reaches the noise, pairs of the best this-many suspects are refitted together.
PAIR_CANDIDATES = 4
#: Resamples of the linearised parametric bootstrap behind a verdict's recurrence.
BOOTSTRAP_SAMPLES = 2000
#: A verdict that recurs in fewer of the noise resamples than this is reported as unstable.
STABLE_SHARE = 0.5
#: least_squares xtol/ftol of the scoring refits: χ² (≈ n) to ~0.01 unit, far below the BIC
#: margins; 1e-8 made weakly identified candidates (tube-end falloff: level and length) crawl
#: along their valley for 400+ evaluations without changing the score.  A search these stop short
#: of its minimum is continued (:data:`~lbscene.engine.loop.fit.STALL_GAIN_CHI2`).
SCORING_TOLERANCE = 1e-4
#: the same for the refits of a geometry's profile points: χ² to ~0.05 unit, far below the Δχ²
#: of 1 its curvature and uncertainty are read at (a third of their evaluations)
PROFILE_TOLERANCE = 1e-3


@dataclass
class NoiseModel:
    """The noise the fit uses and where it came from.

    ``percent`` is the total σ of one reading: the meter's ``meter_percent`` and the declared
    model uncertainty ``model_percent`` added in quadrature, σ² = σ_meter² + σ_model².
    """

    percent: float
    estimate_percent: float | None
    declared_percent: float | None
    spectral_percent: float
    source: str
    meter_percent: float = 0.0
    model_percent: float = 0.0

    def model_share(self, rmse_percent: float) -> float | None:
        """Fraction of the residual's variance the declared model uncertainty covers (0–1)."""
        if not self.model_percent or rmse_percent <= 0:
            return None
        return min(1.0, self.model_percent ** 2 / rmse_percent ** 2)


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
    u = float(getattr(meas, "model_uncertainty_percent", 0.0) or 0.0)
    total = math.hypot(pct, u)
    if u:
        src += f" ⊕ declared model uncertainty {u:g} %"
    return NoiseModel(total, est, dec, meas.spectral_noise_percent or DEFAULT_SPECTRAL_NOISE_PERCENT, src,
                      meter_percent=pct, model_percent=u)


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
    #: the effects this explanation adds (one, or two for a pair) and their fitted parameters
    effects: tuple[str, ...] = ()
    params_by_effect: dict = field(default_factory=dict)
    #: what was refitted: effect ids, or ``hypothesis:<id>`` for hardware the booth lacks
    items: tuple[str, ...] = ()
    #: χ² gained on the illuminance readings and on the white-tile spectrum
    channel_gain: tuple[float, float] = (0.0, 0.0)
    #: why the explanation may not be chosen (it gains only on the other channel); '' if it may
    not_eligible: str = ""
    #: hypothesis id → booth YAML of the hardware it adds, fitted
    hardware: dict = field(default_factory=dict)

    def __post_init__(self) -> None:
        if not self.effects:
            self.effects = tuple(self.effect.split("+"))
        if not self.params_by_effect and len(self.effects) == 1:
            self.params_by_effect = {self.effects[0]: dict(self.params)}
        if not self.items:
            self.items = tuple(self.effects)

    def to_json(self) -> dict:
        return {"effect": self.effect, "effects": list(self.effects), "rmse_percent_after": round(self.rmse_percent_after, 4),
                "score": round(self.score, 3), "chi2": round(self.chi2, 3), "n_params": self.n_params,
                "explains_to_noise": self.explains, "structure_after": _r(self.structure_after),
                "spectral_rmse_percent_after": _r(self.spectral_rmse_after),
                "fitted_params": {k: _r(v, 6) for k, v in self.params.items()},
                "hypotheses": [i[len(HYPOTHESIS_PREFIX):] for i in self.items if i.startswith(HYPOTHESIS_PREFIX)],
                "hardware_yaml": self.hardware or None,
                "chi2_gain_illuminance": _r(self.channel_gain[0], 2),
                "chi2_gain_spectrum": _r(self.channel_gain[1], 2),
                "not_eligible": self.not_eligible or None}


def _r(x, nd=4):
    if x is None or (isinstance(x, float) and not math.isfinite(x)):
        return None
    return round(float(x), nd)


VerdictKind = Literal["none", "missing", "ambiguous", "unexplained", "unstable"]


@dataclass(frozen=True)
class Verdict:
    """What the diagnosis concludes, as a value (not a string to parse).

    ``kind``
        ``none``: the residual is at the noise and nothing improves it significantly;
        ``missing``: adding ``effects`` (one, or two together) brings the residual to the noise
        and beats every other explanation by :data:`TIE_MARGIN` BIC units;
        ``ambiguous``: several explanations (``alternatives``, each a tuple of effects) reach
        the noise within :data:`TIE_MARGIN` of each other;
        ``unexplained``: no single effect nor pair reaches the noise; ``partial`` is the best
        partial explanation, if one helps significantly;
        ``unstable``: the verdict the data give (``point``) recurs in fewer than
        :data:`STABLE_SHARE` of the noise resamples; ``rivals`` are the verdicts the resamples
        give, each with its share, the data's own first.

    ``str(verdict)`` is the short form the command line prints and the JSON carries:
    ``none``, ``missing:a``, ``missing:a+b``, ``ambiguous:a,b+c``, ``unexplained``,
    ``unstable:missing:a (26 %), ambiguous:a,b (61 %)``.
    """

    kind: VerdictKind
    effects: tuple[str, ...] = ()
    alternatives: tuple[tuple[str, ...], ...] = ()
    partial: tuple[str, ...] = ()
    rivals: tuple[tuple[str, float], ...] = ()
    point: "Verdict | None" = None

    def __str__(self) -> str:
        if self.kind == "missing":
            return "missing:" + "+".join(self.effects)
        if self.kind == "ambiguous":
            return "ambiguous:" + ",".join("+".join(a) for a in self.alternatives)
        if self.kind == "unstable":
            return "unstable:" + ", ".join(f"{v} ({100 * x:.0f} %)" for v, x in self.rivals)
        return self.kind

    def __eq__(self, other) -> bool:
        if isinstance(other, str):
            return str(self) == other
        if isinstance(other, Verdict):
            return (self.kind, self.effects, self.alternatives, self.partial, self.rivals) == \
                (other.kind, other.effects, other.alternatives, other.partial, other.rivals)
        return NotImplemented

    def __hash__(self) -> int:
        return hash(str(self))

    @property
    def tied(self) -> list[str]:
        """Effects named by an ambiguous verdict (each alternative's effects, in order)."""
        return [e for a in self.alternatives for e in a]

    def to_json(self) -> dict:
        out = {"kind": self.kind, "effects": list(self.effects),
               "alternatives": [list(a) for a in self.alternatives], "partial": list(self.partial),
               "text": str(self)}
        if self.kind == "unstable":
            out["rivals"] = [{"verdict": v, "share": round(float(x), 3)} for v, x in self.rivals]
            out["point"] = self.point.to_json() if self.point is not None else None
        return out


@dataclass
class Confidence:
    """How firmly the data support the verdict.

    ``delta_bic_vs_base``: BIC units the verdict's explanation gains over the booth as it is;
    ``delta_bic_vs_next``: its lead over the next explanation; ``recurrence``: the fraction of
    data sets, resampled from the verdict's own model with the measured noise, on which the
    same verdict comes back (linearised parametric bootstrap: each explanation's predictions
    held at its fit, :data:`BOOTSTRAP_SAMPLES` resamples); for a tie, a tie or a single
    explanation among its alternatives counts as the same.  Below :data:`STABLE_SHARE` the
    verdict is reported ``unstable`` with the verdicts the resamples give (``shares``).
    """

    delta_bic_vs_base: float | None
    delta_bic_vs_next: float | None
    recurrence: float | None
    samples: int = 0
    #: verdict (short form) → fraction of the resamples that give it, largest first
    shares: dict = field(default_factory=dict)
    #: short form → the verdict the resamples counted under it gave (:func:`_widened`)
    verdicts: dict = field(default_factory=dict, repr=False, compare=False)
    #: ``(verdict, recurrence)`` the data gave, where it recurred in fewer than
    #: :data:`STABLE_SHARE` of the resamples and a tie of it and its rivals that does is the
    #: verdict instead (:func:`_widened`); None otherwise
    widened_from: "tuple[Verdict, float] | None" = None

    def to_json(self) -> dict:
        out = {"delta_bic_vs_base": _r(self.delta_bic_vs_base, 2), "delta_bic_vs_next": _r(self.delta_bic_vs_next, 2),
               "recurrence": _r(self.recurrence, 3), "bootstrap_samples": self.samples,
               "verdict_shares": {k: _r(v, 3) for k, v in self.shares.items()}}
        if self.widened_from is not None:
            out["widened_from"] = {"verdict": str(self.widened_from[0]), "recurrence": _r(self.widened_from[1], 3)}
        return out


@dataclass
class Diagnosis:
    verdict: Verdict
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
    #: … and those held because refitting them would cost too much per forward evaluation (their
    #: effect's analytic ``refit_cost_s`` above :data:`MAX_JOINT_REFIT_COST_S`)
    held_for_cost: list[str] = field(default_factory=list)
    #: refits with two effects together (when no single one reaches the noise)
    pairs: list[Suspect] = field(default_factory=list)
    confidence: Confidence | None = None

    def to_json(self) -> dict:
        return {"verdict": str(self.verdict),
                "verdict_detail": self.verdict.to_json(),
                "confidence": self.confidence.to_json() if self.confidence else None,
                "pairs": [p.to_json() for p in self.pairs],
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
                "joint_parameters_held": self.held,
                "joint_parameters_held_for_cost": self.held_for_cost}

    def held_lines(self) -> list[tuple[str, str]]:
        """What was held at the booth's values, one ``(prefix, names)`` per reason that holds any
        (the text output and the report print them)."""
        reasons = (("these data cannot pin them", self.held),
                   ("too dear to refit with every candidate", self.held_for_cost))
        return [(f"held at the booth's values ({why}): ", ", ".join(names)) for why, names in reasons if names]

    def not_tested_line(self) -> str:
        """The candidates not tested, those with one reason together (the text output and the
        report print it; the JSON's ``not_tested`` has each with its reason)."""
        by_reason: dict[str, list[str]] = {}
        for k, why in self.skipped.items():
            by_reason.setdefault(why, []).append(k)
        return "; ".join(f"{', '.join(ks)} ({why})" for why, ks in by_reason.items())


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


def effects_snippet(effects: dict, highlight: str | set | None = None) -> str:
    """The ``effects:`` block to paste into the booth file (non-default parameters only)."""
    from lbscene.engine.light.effects.registry import get_effect

    marked = {highlight} if isinstance(highlight, str) else set(highlight or ())
    lines = ["effects:"]
    for eid in sorted(effects):
        cls = get_effect(eid)
        defaults = cls.Params().model_dump(mode="json")
        params = {k: v for k, v in (effects[eid] or {}).items()
                  if k in defaults and (defaults[k] != v or (eid in marked and k in getattr(
                      cls, "fit_parameters", {})))}
        body = ", ".join(f"{k}: {_fmt(v)}" for k, v in params.items())
        mark = "   # ← add" if eid in marked else ""
        lines.append(f"  {eid}: {{{body}}}{mark}")
    return "\n".join(lines) + "\n"


# --------------------------------------------------------------------------- diagnosis

#: Enabled effects' parameters are refitted jointly with each candidate only when changing one
#: costs less than this per forward evaluation (seconds, from the effect's ``refit_cost_s`` model).
MAX_JOINT_REFIT_COST_S = 0.15


def _enabled_fit_params(ir, lighting, effects, already, costly: list | None = None) -> list:
    """Fit parameters of the effects the booth already enables (refitted with each candidate, so
    an earlier round's estimate is not frozen while it was biased by the effect still missing);
    those of an effect whose refit costs too much are left out (appended to ``costly``)."""
    from lbscene.engine.light.effects.registry import get_effect

    out = []
    names = {fp.target for fp in already}
    for eid in effects:
        cls = get_effect(eid)
        cost = getattr(cls, "refit_cost_s", None)
        dear = cost is not None and cost(ir, effects.get(eid), lighting) > MAX_JOINT_REFIT_COST_S
        fn = getattr(cls, "fit_parameters_for", None)
        fps = fn(ir, lighting) if fn else dict(getattr(cls, "fit_parameters", {}) or {})
        for name, b in fps.items():
            fp = effect_parameter(eid, name, effects, b)
            if fp.target in names:
                continue
            if dear:    # e.g. radiosity on a fine mesh: keep the booth's values
                if costly is not None:
                    costly.append(fp)
            else:
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
    from lbscene.engine.light.effects.registry import get_effect

    out = {}
    for eid, p in effects.items():
        fn = getattr(get_effect(eid), "diagnosis_params", None)
        out[eid] = fn(p) if fn else dict(p or {})
    return out


def candidate_config(ir, lighting, effects, eid, base_free, known):
    """Effects and free parameters with candidate ``eid`` added."""
    from lbscene.engine.light.effects.registry import get_effect

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


def _chi2_parts(fit: FitResult, noise: NoiseModel) -> tuple[float, float]:
    """χ² in noise units split by what can explain it: *levels* — the illuminance readings and the
    white-tile spectrum's mean (light that geometry or a meter moves) — and the white-tile
    spectrum's *shape* (its relative residual less its mean: only spectra change it)."""
    r = fit.residual_percent / noise.percent if fit.lux_pred is not None else np.zeros(0)
    sp = fit.spectral_residual_percent
    sp = np.zeros(0) if sp is None else sp[np.isfinite(sp)] / noise.spectral_percent
    level = float(r @ r)
    if sp.size:
        level += sp.size * float(sp.mean()) ** 2
        sp = sp - sp.mean()
    return level, float(sp @ sp)


def _hypothesis(item: str):
    """The :class:`~lbscene.engine.loop.hypotheses.Hypothesis` a candidate ``hypothesis:<id>``
    names, or None for an effect of the catalog."""
    return HYPOTHESES[item[len(HYPOTHESIS_PREFIX):]] if item.startswith(HYPOTHESIS_PREFIX) else None


def _channels(item: str) -> tuple[str, ...]:
    """The residuals an explanation may claim: ``spectral`` for effects and hypotheses that change
    spectra only, ``spatial`` for geometry; an effect lists both in its ``channels`` attribute
    when it does both (a diffuser: a plate with a spectral transmittance)."""
    from lbscene.engine.light.effects.registry import get_effect

    H = _hypothesis(item)
    if H is not None:
        return (H.channel,)
    cls = get_effect(item)
    ch = getattr(cls, "channels", None)
    if ch:
        return tuple(ch)
    return ("spectral",) if getattr(cls, "kind", "") == "spectral" else ("spatial",)


def _channel(item: str) -> str:
    """The first channel of :func:`_channels`."""
    return _channels(item)[0]


def _channel_check(items: tuple[str, ...], gain: tuple[float, float], n_params: dict,
                   n_values: tuple[int, int]) -> str:
    """Channel honesty: each explanation must gain on a residual it can act on — the readings'
    levels (spatial: illuminance and the tile's mean) or the white-tile spectrum's shape
    (spectral) — by more than :data:`SIGNIFICANT` and more than its ``k`` parameters' price on
    that channel's ``n`` values, k·ln n (a 12-coefficient filter fitted to a 15-band spectrum's
    noise gains about 12).  So a geometry never wins on a purely spectral residual, nor a filter
    on a purely spatial one."""
    out = []
    names = {"spatial": "the readings' levels", "spectral": "the white-tile spectrum's shape"}
    for it in items:
        k = max(int(n_params.get(it, 1)), 1)
        ch = _channels(it)

        def need(c):
            n = n_values[0 if c == "spatial" else 1]
            return max(SIGNIFICANT, k * math.log(max(n, 2)))
        if not any(gain[0 if c == "spatial" else 1] > need(c) for c in ch):
            out.append(f"{it} gains only " + " and ".join(
                f"{gain[0 if c == 'spatial' else 1]:.1f} χ² on {names[c]} (needs {need(c):.0f})"
                for c in ch))
    return "; ".join(out)


@dataclass
class _Base:
    """The booth as declared, fitted: what every candidate refit starts from and is scored against."""

    meas: object
    effects: dict                    # the booth's effects (coarsened for the refits)
    free: list                       # the base fit's free parameters, started at its solution
    noise: NoiseModel
    cache: dict
    fit: FitResult
    bic: float
    logn: float
    pts: np.ndarray                  # the illuminance readings' points (residual structure)
    parts: tuple[float, float]       # χ² on the readings and on the white-tile spectrum
    channel_sizes: tuple[int, int]
    ctest: dict                      # consistent_with_noise's keyword arguments
    known_all: bool                  # every lamp group's output is known
    #: geometry caches shared by the refits on a booth augmented with the same hardware
    ir_caches: dict = field(default_factory=dict)
    #: the base fit's problem (spectral hypotheses alone are fitted on it, without a refit)
    problem: object = None
    #: the least white-tile χ² hardware that only moves light can reach (:func:`_beyond_reach`)
    reach_floor: float | None = None

    @property
    def ir(self):
        return self.meas.ir

    @property
    def lighting(self) -> str:
        return self.meas.lighting


def _fit_base(meas, base_problem: FitProblem, cache: dict) -> tuple[_Base, list, list, list]:
    """Fit the booth as declared (with the joint parameters the data pin down): the
    :class:`_Base`, the refitted joint parameters, the held ones and those held for their cost."""
    ir, lighting = meas.ir, meas.lighting
    effects = _coarsen(base_problem.effects)
    noise = noise_model(meas)
    costly: list = []
    joint = _enabled_fit_params(ir, lighting, effects, base_problem.free, costly)
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
    logn = math.log(max(base.n_residuals, 2))
    pts = meas.illuminance.points_mm if meas.illuminance is not None else np.zeros((0, 3))
    n_tile = int(np.isfinite(base.spectral_residual_percent).sum()) if base.spectral_residual_percent is not None else 0
    b = _Base(meas=meas, effects=effects, free=base_free, noise=noise, cache=cache, fit=base,
              bic=base.chi2 + len(base_free) * logn, logn=logn, pts=pts, parts=_chi2_parts(base, noise),
              channel_sizes=(base_problem.n_lux + (1 if n_tile else 0), n_tile),
              ctest=dict(noise_percent=noise.percent, spectral_noise_percent=noise.spectral_percent,
                         level_test=bool(meas.known_output_groups)),
              known_all=bool(base_problem.groups) and set(base_problem.groups) <= set(meas.known_output_groups or ()),
              problem=base_fp)
    return b, joint, held, costly


def _candidate_items(ir, lighting: str, effects: dict, candidates) -> tuple[list[str], dict[str, str]]:
    """What to refit with, one by one: every registered effect the booth does not enable (and
    that applies to it), then the hypotheses of hardware it does not declare; and the effects
    skipped, with why."""
    from lbscene.engine.light.effects.registry import available_effects

    todo, skipped = [], {}
    for eid, cls in available_effects().items():
        if eid in effects or (candidates is not None and eid not in candidates):
            continue
        why = cls.applicable(ir, lighting) if hasattr(cls, "applicable") else None
        if why:
            skipped[eid] = why
        else:
            todo.append(eid)
    # hardware the file does not declare: tried as hypotheses (engine/loop/hypotheses.py)
    hyps, _ = applicable_hypotheses(ir, lighting)
    for H in hyps:
        if H.effect in effects or (candidates is not None and H.effect not in candidates
                                   and H.id not in candidates):
            continue
        skipped.pop(H.effect, None)
        if not H.hardware and H.effect in todo:
            # the same effect, fitted exactly on the base fit's spectra instead of refitted
            # through the forward model
            todo.remove(H.effect)
        todo.append(HYPOTHESIS_PREFIX + H.id)
    return todo, skipped


def _configure(b: _Base, items: tuple[str, ...]):
    """The booth, effects and free parameters of a refit with ``items``: ``(ir, effects, free,
    spectral hypotheses fitted afterwards, hypotheses, free parameters added per item)``."""
    cur_ir, new_eff, free = b.ir, b.effects, b.free
    post, hw = [], []
    n_params: dict[str, int] = {}
    for it in items:
        before = len(free)
        H = _hypothesis(it)
        if H is not None:
            hw.append(H)
            if H.channel == "spectral":
                post.append((it, H))
                continue
            cur_ir, add_eff, add_free = H.augment(cur_ir, b.lighting, b.meas.known_output_groups)
            # the hypothesis' effects at the diagnosis' resolution, as a candidate's are
            new_eff = {**new_eff, **_coarsen(add_eff)}
            names = {fp.target for fp in free}
            free = list(free) + [fp for fp in add_free if fp.target not in names]
        else:
            new_eff, free = candidate_config(cur_ir, b.lighting, new_eff, it, free,
                                             b.meas.known_output_groups)
        n_params[it] = len(free) - before
    return cur_ir, new_eff, free, post, hw, n_params


def _measurements_for(b: _Base, cur_ir, hw):
    """The measurements and the cache a refit on booth ``cur_ir`` uses."""
    if cur_ir is b.ir:
        return b.meas, b.cache
    key = tuple(h.id for h in hw if h.channel != "spectral")
    if key not in b.ir_caches:
        # content-keyed geometry (pair geometry of emitter points and receivers, occlusion
        # fractions of a rectangle) is the same whatever booth it came from: shared
        b.ir_caches[key] = {k: b.cache.setdefault(k, {}) for k in SHARED_GEOMETRY_STORES}
    return replace(b.meas, ir=cur_ir), b.ir_caches[key]


def _shown_params(items, eids, hw, fit: FitResult, free) -> tuple[dict, dict]:
    """The fitted parameters of a refit: ``(shown in the report, by effect)``."""
    by_effect = {}
    for it, eid in zip(items, eids):
        H = _hypothesis(it)
        if H is not None:
            by_effect[eid] = H.effect_entry(fit)
        else:
            by_effect[eid] = {fp.name: fit.values[fp.target] for fp in free
                              if fp.scope == "effect" and fp.ident == eid}
    shown = {}
    for it, eid in zip(items, eids):
        if it.startswith(HYPOTHESIS_PREFIX):
            shown.update({t.split(".", 1)[1]: v for t, v in fit.values.items()
                          if t.startswith(f"effect.{eid}.") or t.startswith("hypothesis.")})
        else:
            shown.update({f"{eid}.{k_}": v for k_, v in by_effect[eid].items()})
    if len(items) == 1 and not hw:
        shown = by_effect[eids[0]]
    return shown, by_effect


def _refit(b: _Base, items: tuple[str, ...], rival: float | None = None) -> Suspect | None:
    """Refit the booth with ``items`` (effect ids, ``hypothesis:<id>``) added, scored against the
    base fit (None when a spectral hypothesis finds nothing to fit).  ``rival``: the score of the
    best explanation so far that reaches the noise; hardware whose geometry could not bring it
    within the tie margin of that keeps its first guess (:func:`_cannot_rival`)."""
    cur_ir, new_eff, free, post, hw, n_params = _configure(b, items)
    m, c = _measurements_for(b, cur_ir, hw)
    noise = b.noise
    if len(post) == len(items) and b.problem is not None:
        # spectral factors only: fitted on the base fit itself (its refit would be the same fit)
        return _finish(b, items, b.problem, b.fit, free, post, hw, n_params, cur_ir)
    prob = FitProblem(m, new_eff, free, noise.percent, noise.spectral_percent, c,
                      tolerance=SCORING_TOLERANCE)
    starts = [st for H in hw for st in H.starts()]
    if starts:
        # hardware whose parameters have no gradient where the guess puts them (an opening
        # larger than every path): start from the best of a coarse grid
        def chi2_at(st):
            x = np.array([st.get(prob.free[i].target, prob.free[i].initial) for i in prob.nl])
            r = prob.residuals(x)
            return float(r @ r)
        best = min(starts, key=chi2_at)
        free = [replace(fp, initial=float(best.get(fp.target, fp.initial))) for fp in free]
        prob = FitProblem(m, new_eff, free, noise.percent, noise.spectral_percent, c,
                          tolerance=SCORING_TOLERANCE)
    fit = prob.solve()
    k = len(free)
    for H in hw if len(items) == 1 else ():
        if _profiled_geometry(H, cur_ir, b.lighting):
            why = _cannot_rival(b, fit, k, rival)
            if why:
                fit.hypothesis_data = {**(getattr(fit, "hypothesis_data", None) or {}), "not_profiled": why}
                continue
            # properties the forward model cannot vary (a plate's height, a mirror's distance):
            # the refit repeated on booths with other values (hypotheses.profile_geometry); in a
            # pair the hardware keeps the hypothesis' first guess
            def problem_on(ir_v, start, m=m, new_eff=new_eff, free=free):
                # started from the hypothesis refit's optimum
                fr = [replace(fp, initial=float(np.clip(start.values.get(fp.target, fp.initial), *fp.bounds)))
                      for fp in free]
                c_v = {key: b.cache.setdefault(key, {}) for key in SHARED_GEOMETRY_STORES}
                return FitProblem(replace(m, ir=ir_v), new_eff, fr, noise.percent, noise.spectral_percent, c_v,
                                  tolerance=PROFILE_TOLERANCE)

            def solve_on(ir_v, start):
                # standard errors only for the point kept (profile_geometry adds them)
                p_v = problem_on(ir_v, start)
                return p_v, p_v.solve(errors=False)
            cur_ir, fit, prob, n_geo = profile_geometry(H, cur_ir, b.lighting, solve_on, fit, prob,
                                                        problem_on=problem_on)
            k += n_geo
            n_params[HYPOTHESIS_PREFIX + H.id] = n_params.get(HYPOTHESIS_PREFIX + H.id, 0) + n_geo
    if cur_ir is not b.ir:
        fit.ir = cur_ir          # the booth this explanation predicts with (plan)
    return _finish(b, items, prob, fit, free, post, hw, n_params, cur_ir, k)


#: what profiling a hypothesis' geometry may add to the white-tile shape gain of its first guess,
#: as a multiple of that gain (see :func:`_cannot_rival`)
SHAPE_GAIN_MARGIN = 2.0


def _cannot_rival(b: _Base, fit: FitResult, k: int, rival: float | None) -> str:
    """Why profiling a spatial hypothesis' geometry cannot change the verdict ('' if it might).

    A geometry moves light: refitted over its properties it can at most remove the readings'
    level χ² (``b.parts[0]``, every reading brought to its measured value); on the white tile's
    shape it acts only through the mix of lamps and inter-reflected light its first guess already
    shows, counted here as :data:`SHAPE_GAIN_MARGIN` times that guess' shape gain.  When that
    best case, less the parameters' price, stays more than :data:`TIE_MARGIN` under ``rival`` (an
    explanation that reaches the noise), the profile's refits (a few seconds each) are skipped."""
    if rival is None:
        return ""
    shape_gain = b.parts[1] - _chi2_parts(fit, b.noise)[1]
    best = b.parts[0] + SHAPE_GAIN_MARGIN * max(shape_gain, 0.0) - (k - len(b.free)) * b.logn
    if best >= rival - TIE_MARGIN:
        return ""
    return (f"geometry not fitted: at best ΔBIC {best:.0f} with every reading's level explained, "
            f"against {rival:.0f} for an explanation that reaches the noise")


def _beyond_reach(b: _Base, item: str, rival: float | None) -> str:
    """Why refitting spatial hardware ``item`` cannot change the verdict ('' if it might).

    Hardware that only moves light (flat transmittance and reflectance) leaves the white tile's
    spectrum in the cone of the spectra light can carry to it (:mod:`.spectral_reach`): at best
    it explains every reading's level and the tile's shape down to that cone's floor.  When
    that best case, less the price of the hardware's parameters, stays more than
    :data:`TIE_MARGIN` under ``rival`` (an explanation that reaches the noise), its refits and
    profile are not run.  Not where the refit reshapes the lamps' spectra itself
    (:func:`_reshapes_spectra`)."""
    if rival is None or b.problem is None or b.problem.tile_row is None or _reshapes_spectra(b.free):
        return ""
    if b.reach_floor is None:
        b.reach_floor = _tile_floor(b)
    k = _configure(b, (item,))[5].get(item, 0)
    best = b.fit.chi2 - b.reach_floor - k * b.logn
    if best >= rival - TIE_MARGIN:
        return ""
    return (f"not refitted: hardware that only moves light leaves the white tile's spectrum at best "
            f"χ² {b.reach_floor:.0f} from the measured one, too far to come within {TIE_MARGIN:g} of an "
            f"explanation that reaches the noise (ΔBIC {rival:.0f})")


def _reshapes_spectra(free) -> bool:
    """Whether a refit moves spectra through free parameters of its own (an enabled spectral
    effect's, refitted with every candidate): the cone of :mod:`.spectral_reach` holds the lamps'
    spectra as the base fit has them, so a refit that reshapes them too may leave it."""
    return bool(spectral_parameters(free))


def _tile_floor(b: _Base) -> float:
    """:func:`~.spectral_reach.spectral_floor_chi2` of the base fit's booth."""
    from .spectral_reach import spectral_floor_chi2

    p = b.problem
    x = np.array([b.fit.values[p.free[i].target] for i in p.nl])
    fm = p.model(x)[0]
    r = [p.tile_row]
    pred = fm.predict(p.P[r], p.N[r], p.meter[r])
    return spectral_floor_chi2(b.ir, b.lighting, pred.terms, 0, b.meas.tile.reflectance_1nm, p.tile_grid,
                               p.tile_meas, p.tile_mask, b.noise.spectral_percent)


def _finish(b: _Base, items, prob, fit, free, post, hw, n_params, cur_ir, k: int | None = None) -> Suspect | None:
    """Fit the spectral hypotheses on top of ``fit`` and score the explanation (``k``: the
    parameters fitted so far, the free ones and the profiled geometry)."""
    k = len(free) if k is None else k
    for it, H in post:
        f2 = H.fit_on(prob, fit, b.known_all)
        if f2 is None:
            return None
        n_params[it] = sum(1 for fp in f2.free if not fp.linear)
        k += n_params[it]
        fit = f2
    bic = fit.chi2 + k * b.logn
    eids = tuple(H.effect if (H := _hypothesis(i)) is not None else i for i in items)
    shown, by_effect = _shown_params(items, eids, hw, fit, free)
    parts = _chi2_parts(fit, b.noise)
    gain = (b.parts[0] - parts[0], b.parts[1] - parts[1])
    why_not = _channel_check(items, gain, n_params, b.channel_sizes)
    return Suspect(
        effect="+".join(eids), rmse_percent_after=fit.rmse_percent, score=b.bic - bic, chi2=fit.chi2,
        n_params=k - len(b.free), explains=consistent_with_noise(fit, **b.ctest),
        structure_after=moran_i(b.pts, fit.residual_percent) if len(b.pts) else float("nan"),
        params=shown, fit=fit, spectral_rmse_after=fit.spectral_rmse_percent, effects=eids,
        params_by_effect=by_effect, items=items, channel_gain=gain, not_eligible=why_not,
        hardware={H.id: _not_profiled_note(fit) + y for H in hw if (y := H.hardware_yaml(cur_ir, fit))})


def _not_profiled_note(fit: FitResult) -> str:
    """A comment line saying a hypothesis' geometry kept its first guess, and why ('' if not)."""
    why = (getattr(fit, "hypothesis_data", None) or {}).get("not_profiled")
    return f"# hypothesis: {why}\n" if why else ""


def _side_by_side(b: _Base, items: list[tuple[str, ...]], rival: float | None = None,
                  progress=None, step: tuple[int, int] = (0, 0)) -> dict:
    """``{items: _refit(b, items, rival)}``, the refits run side by side in processes forked from
    this one (:func:`~lbscene.engine.files.parallel.map_forked`); ``{}`` when there are fewer than
    two or one process only (then each is refitted where the loop reaches it, as before).  Only
    refits whose result cannot depend on the ones before them are given here: each is what the
    loop would compute at its turn, from the same base fit, started from the same values.
    ``progress(done, total, what)`` at ``step`` names the batch, only when it does run side by
    side."""
    if len(items) < 2 or process_count() < 2:
        return {}
    if progress:
        progress(*step, ", ".join("+".join(it) for it in items))
    return dict(zip(items, map_forked(lambda it: _refit(b, it, rival), items)))


def _profiled_geometry(H, ir, lighting) -> bool:
    """Whether refitting hypothesis ``H`` alone on booth ``ir`` profiles its geometry
    (:func:`profile_geometry`: properties the forward model cannot vary, refitted on booths with
    other values, the refits forked side by side; skipped against a rival, :func:`_cannot_rival`)."""
    return H.channel == "spatial" and bool(H.geometry(ir, lighting))


def _profiles_geometry(b: _Base, item: str) -> bool:
    """:func:`_profiled_geometry` of candidate ``item`` (False for a catalog effect)."""
    H = _hypothesis(item)
    return H is not None and _profiled_geometry(H, _configure(b, (item,))[0], b.lighting)


def _single_refits(b: _Base, todo: list[str], consistent: bool, progress,
                   skipped: dict[str, str]) -> list[Suspect]:
    """Every candidate on its own, best first; hardware whose refit cannot change the verdict
    (:func:`_beyond_reach`) is added to ``skipped`` with why.

    What the order decides (hardware refitted only when something before it helps, the rival
    explanation hardware is weighed against) is decided in the order below; the refits it does
    not decide run side by side (:func:`_side_by_side`): first every candidate that is not
    hardware of the spatial channel, then, at the first such hardware, the hardware without a
    geometry to profile that is still within reach of the rival.  A rival only grows as the
    loop goes on, so hardware out of reach there stays out of reach."""
    # hardware the file does not declare is hypothesised only when the booth as declared leaves
    # something to explain: its residual above the noise, or a catalog effect that helps
    suspects = []

    def spatial_hardware(item):
        H = _hypothesis(item)
        return H is not None and H.hardware and H.channel == "spatial"

    def hardware(item):
        H = _hypothesis(item)
        return H is not None and H.hardware

    # hardware with a geometry to profile last: the explanations before it may make its profile
    # moot (_cannot_rival), or the hardware itself (_beyond_reach)
    order = [i for i in todo if not spatial_hardware(i)] + [i for i in todo if spatial_hardware(i)]
    # with the booth consistent, hardware is refitted only after a helpful explanation: in order
    first = [(i,) for i in order if not spatial_hardware(i) and not (consistent and hardware(i))]
    ready = _side_by_side(b, first, None, progress, (0, len(order)))
    spatial_started = False
    for k, item in enumerate(order):
        if hardware(item) and consistent and not any(x.score > SIGNIFICANT and not x.not_eligible for x in suspects):
            continue
        if progress:
            progress(k, len(order), item)
        rival = max((x.score for x in suspects if x.explains and not x.not_eligible), default=None)
        if spatial_hardware(item) and (why := _beyond_reach(b, item, rival)):
            skipped[item] = why
            continue
        if spatial_hardware(item) and not spatial_started:
            spatial_started = True
            later = [(i,) for i in order[k:] if not _profiles_geometry(b, i) and not _beyond_reach(b, i, rival)]
            ready.update(_side_by_side(b, later, rival, progress, (k, len(order))))
        s_ = ready.pop((item,)) if (item,) in ready else _refit(b, (item,), rival)
        if s_ is not None:
            suspects.append(s_)
    suspects.sort(key=lambda s: -s.score)
    return suspects


def _pair_refits(b: _Base, suspects: list[Suspect], consistent: bool, progress, done: int) -> list[Suspect]:
    """Two candidates together, best first, when no single one reaches the noise (and the base
    does not either, or something helps): the best few suspects, and the best of each channel
    (refitted side by side, :func:`_side_by_side`)."""
    eligible = [x for x in suspects if not x.not_eligible]
    helpful = [x for x in eligible if x.score > SIGNIFICANT]
    if any(x.explains for x in helpful) or (consistent and not helpful):
        return []
    # no single effect reaches the noise: two together might (search the best few suspects)
    top = [x.items[0] for x in (helpful or eligible)[:PAIR_CANDIDATES]]
    # and the candidate that explains most of each channel on its own, whatever its total
    # score: a filter with an unexplained geometry beside it worsens the readings' level
    for ch, i in (("spatial", 0), ("spectral", 1)):
        own = [x for x in suspects if _channel(x.items[0]) == ch and x.channel_gain[i] > SIGNIFICANT]
        if own:
            best_ch = max(own, key=lambda x: x.channel_gain[i]).items[0]
            if best_ch not in top:
                top.append(best_ch)
    # two spectral factors together are one spectral factor (a filter follows any reshaping)
    combos = [cb for cb in combinations(top, 2) if not _spectral_only(cb)]
    ready = _side_by_side(b, combos, None, progress, (done, done + len(combos)))
    pairs: list[Suspect] = []
    for k, (a, c) in enumerate(combos):
        if progress:
            progress(done + k, done + len(combos), f"{a}+{c}")
        p_ = ready[(a, c)] if (a, c) in ready else _refit(b, (a, c))
        if p_ is not None:
            pairs.append(p_)
    pairs.sort(key=lambda x: -x.score)
    return pairs


def diagnose(meas, base_problem: FitProblem, *, candidates: list[str] | None = None,
             progress=None, cache: dict | None = None) -> Diagnosis:
    """Refit with each missing effect and rank the suspects (see the module docstring)."""
    cache = base_problem.cache if cache is None else cache
    b, joint, held, costly = _fit_base(meas, base_problem, cache)
    structure_before = moran_i(b.pts, b.fit.residual_percent) if len(b.pts) else float("nan")
    todo, skipped = _candidate_items(b.ir, b.lighting, b.effects, candidates)
    consistent = consistent_with_noise(b.fit, **b.ctest)
    suspects = _single_refits(b, todo, consistent, progress, skipped)
    pairs = _pair_refits(b, suspects, consistent, progress, len(todo))
    if progress:
        progress(1, 1, "")

    d = Diagnosis(Verdict("none"), b.fit, suspects, skipped, b.noise, structure_before=structure_before,
                  refitted=[fp.target for fp in joint], held=[fp.target for fp in held],
                  held_for_cost=[fp.target for fp in costly], pairs=pairs)
    d.consistent = consistent
    d.where = _where(meas, b.fit)
    d.verdict = _decide(consistent, [_scored(x) for x in suspects if not x.not_eligible],
                        [_scored(x) for x in pairs if not x.not_eligible])
    d.confidence = _confidence(d, b.bic, b.noise, b.ctest)
    wide = _widened(d.verdict, d.confidence, suspects + pairs)
    if wide is not None:
        d.verdict, d.confidence = wide
    _explain(d, meas, base_problem.effects, b.noise)
    d.verdict = _unstable(d.verdict, d.confidence)
    if d.verdict.kind == "unstable":
        _explain_unstable(d)
    return d


def _decide(base_explains: bool, singles, pairs) -> Verdict:
    """The verdict from scored explanations: ``(effects, ΔBIC vs the booth as is, reaches the
    noise?[, acts on spectra only?, free parameters])`` for each single effect and each pair
    (see :class:`Verdict`).  The same rule scores the data and every bootstrap resample.

    Explanations that act on spectra only (a filter in front of the lamps, the lamps' spectrum
    reshaped) multiply every light path by the same function of wavelength: a
    spectroradiometer cannot tell them apart, whatever BIC margin the parametrisation makes.
    When the best is one and another also reaches the noise significantly, they are tied,
    the one with fewer parameters first."""
    helpful = [h for h in singles if h[1] > SIGNIFICANT]
    if base_explains and not helpful:
        return Verdict("none")

    def spectral(h):
        return len(h) > 3 and bool(h[3])

    def pick(cands, reach):
        best = max(reach, key=lambda h: h[1])
        # a rival within the tie margin counts if it is significant or reaches the noise too: a
        # best at ΔBIC 14 does not beat one at 9 that explains the data as well
        tied = [h for h in cands if h[1] >= best[1] - TIE_MARGIN and (h[2] or h[1] > SIGNIFICANT)]
        same = []
        if spectral(best):
            same = [h for h in cands if spectral(h) and h[2] and h[1] > SIGNIFICANT
                    and all(h[0] != t[0] for t in tied)]
        if same or (spectral(best) and any(spectral(h) and h[0] != best[0] for h in tied)):
            tied = sorted(tied + same, key=lambda h: (h[4] if len(h) > 4 else 0, -h[1]))
        else:
            tied = sorted(tied, key=lambda h: -h[1])
        # two hypotheses of hardware that add the same effects (the ceiling's and the walls'
        # reflectance) are one alternative of the verdict, which names effects: the best of them
        seen: set = set()
        tied = [h for h in tied if not (h[0] in seen or seen.add(h[0]))]
        if len(tied) == 1:
            return Verdict("missing", best[0])
        return Verdict("ambiguous", alternatives=tuple(h[0] for h in tied))

    reach = [h for h in helpful if h[2]]
    if reach:
        return pick(singles, reach)
    best_single = max((h[1] for h in helpful), default=0.0)
    # a pair counts only if its second effect matters: it must beat the best single effect too
    good_pairs = [h for h in pairs if h[1] > SIGNIFICANT and h[1] > best_single + SIGNIFICANT]
    reach = [h for h in good_pairs if h[2]]
    if reach:
        return pick(good_pairs, reach)
    partial = max(helpful + good_pairs, key=lambda h: h[1], default=None)
    return Verdict("unexplained", partial=partial[0] if partial else ())


def _scored(x: Suspect) -> tuple:
    """The tuple :func:`_decide` scores an explanation by."""
    return (x.effects, x.score, x.explains, _spectral_only(x.items), x.n_params)


def _spectral_only(items) -> bool:
    """Whether every item of an explanation acts on spectra only."""
    return all(_channels(i) == ("spectral",) for i in items)


def _confidence(d: "Diagnosis", base_bic: float, noise: NoiseModel, ctest: dict | None = None) -> Confidence:
    """ΔBIC margins and the recurrence of the verdict under resampled noise.

    Linearised parametric bootstrap: data are redrawn from the verdict's own model with the
    meter noise, y* = ŷ_W + σ·ε; an explanation k's χ² then moves from its fitted value by
    2·d_k·ε (d_k: its predictions minus the verdict's, in noise units — the refit is taken as
    fixed, which is exact to first order), and the verdict's own χ² is drawn from χ²_dof.  For
    ``unexplained`` the model resampled is the best partial explanation with the structure it
    leaves kept: its χ² is drawn as χ²_dof plus the excess it leaves (χ² − dof).  The same
    decision rule (:func:`_decide`) is applied to each resample; ``shares`` counts the verdicts
    they give.  Whether an explanation reaches the noise in a resample is the same test as on the
    data (:func:`consistent_with_noise`, ``ctest`` its arguments): the whole χ², the readings'
    block and their mean (moved by the same draw) and the white tile's block (not resampled: kept
    as the data give it).
    """
    v = d.verdict
    hyps = [x for x in d.suspects + d.pairs if not x.not_eligible]
    by_name = {x.effects: x for x in hyps}
    # the model resampled: the verdict's explanation (of a tie, the best that reaches the noise)
    alts = [by_name[a] for a in v.alternatives if a in by_name] if v.kind == "ambiguous" else []
    reach = [x for x in alts if x.explains]
    winner = by_name.get(v.effects) if v.kind == "missing" else (
        max(reach or alts, key=lambda x: x.score) if alts else (
            by_name.get(v.partial) if v.kind == "unexplained" and v.partial else None))
    wfit = winner.fit if winner is not None else d.base
    w_score = winner.score if winner is not None else 0.0
    others = sorted((x.score for x in hyps if x is not winner), reverse=True)
    if winner is not None:
        others.append(0.0)          # the booth as it is
    vs_next = (w_score - others[0]) if others else None
    if wfit.lux_pred is None or noise.percent <= 0:
        return Confidence(w_score if winner else None, vs_next, None)
    z_w = wfit.residual_percent / noise.percent
    rng = np.random.default_rng(20261123)
    n = len(z_w)
    eps = rng.standard_normal((BOOTSTRAP_SAMPLES, n))
    dof_w = max(wfit.dof, 1)
    chi2_w = rng.chisquare(dof_w, BOOTSTRAP_SAMPLES)
    if v.kind == "unexplained":
        chi2_w = chi2_w + max(wfit.chi2 - dof_w, 0.0)
    limit = chi2_limit(dof_w)

    def moved(fit, chi2):
        dk = fit.residual_percent / noise.percent - z_w
        return chi2 + 2.0 * (eps @ dk)

    base_chi2 = moved(d.base, d.base.chi2) if winner is not None else chi2_w
    base_ok = base_chi2 <= chi2_limit(max(d.base.dof, 1))
    ctest = ctest or {}

    def blocks_ok(fit):
        # the data's block tests, the readings' moved by the same draw as the whole χ²
        k_s = _spectral_parameters(fit)
        ok = np.full(BOOTSTRAP_SAMPLES, _tile_consistent(fit, ctest.get("spectral_noise_percent"), k_s))
        if fit.lux_pred is None or not ctest.get("noise_percent"):
            return ok
        zx = fit.residual_percent / noise.percent
        dk = zx - z_w
        k = fit.n_params - k_s
        return ok & readings_consistent(float(zx @ zx) + 2.0 * (eps @ dk), dk.mean() + eps.mean(axis=1), n, k,
                                        bool(ctest.get("level_test")))

    cols = []
    for x in hyps:
        c = chi2_w if x is winner else moved(x.fit, x.chi2)
        lim = limit if x is winner else chi2_limit(max(x.fit.dof, 1))
        # score = base BIC − BIC: the parameter penalties are those of the fits
        pen = d.base.chi2 - x.chi2 - x.score       # (k_x − k_base)·ln n
        cols.append((x, base_chi2 - (c + pen), (c <= lim) if x is winner else (c <= lim) & blocks_ok(x.fit)))
    meta = [(x.effects, len(x.effects) > 1, _spectral_only(x.items), x.n_params) for x, _, _ in cols]
    sc_rows = np.stack([sc for _, sc, _ in cols], axis=1).tolist() if cols else [[]] * BOOTSTRAP_SAMPLES
    ok_rows = np.stack([ok for _, _, ok in cols], axis=1).tolist() if cols else [[]] * BOOTSTRAP_SAMPLES
    counts: dict[str, int] = {}
    kinds: dict[str, Verdict] = {}
    same = 0
    for b in range(BOOTSTRAP_SAMPLES):
        singles, pairs = [], []
        for (eff, is_pair, spec, k), sc, ok in zip(meta, sc_rows[b], ok_rows[b]):
            (pairs if is_pair else singles).append((eff, sc, ok, spec, k))
        verdict = _decide(bool(base_ok[b]), singles, pairs)
        key = _share_key(verdict, v)
        counts[key] = counts.get(key, 0) + 1
        kinds.setdefault(key, verdict)
        same += _supports(verdict, v)
    shares = {k: c / BOOTSTRAP_SAMPLES for k, c in sorted(counts.items(), key=lambda kv: -kv[1])}
    return Confidence(w_score if winner else None, vs_next, same / BOOTSTRAP_SAMPLES, BOOTSTRAP_SAMPLES,
                      shares, verdicts={k: kinds[k] for k in shares})


def _named(r: Verdict) -> list[tuple[str, ...]]:
    """The explanations a verdict names: its effects (``missing``), its alternatives (a tie)."""
    return [r.effects] if r.kind == "missing" else list(r.alternatives) if r.kind == "ambiguous" else []


def _widened(v: Verdict, c: Confidence | None, scored) -> "tuple[Verdict, Confidence] | None":
    """The tie the noise resamples support where the data's verdict ``v`` recurs in fewer than
    :data:`STABLE_SHARE` of them; None where ``v`` is stable or no such tie exists.

    A tie says the cause is one of its explanations: a resample supports it when its own
    verdict names only explanations among them (:func:`_supports`).  Starting from ``v``'s own
    explanations, those of a resample verdict are added until the tie recurs in
    :data:`STABLE_SHARE` of the resamples: the fewest that reach it (the most support among
    them), else those that add most support; verdicts that name nothing (``none``,
    ``unexplained``) cannot join it.  The tie lists its explanations best first by the data's
    scores (``scored``: the suspects and pairs).
    Where no tie reaches the share (the resamples say ``none`` or ``unexplained`` too often), the
    verdict stays ``v``, reported ``unstable`` (:func:`_unstable`)."""
    if c is None or c.recurrence is None or c.recurrence >= STABLE_SHARE or v.kind not in ("missing", "ambiguous"):
        return None
    named = {k: set(_named(r)) for k, r in c.verdicts.items() if _named(r)}
    tie = set(_named(v))

    def support(t):
        return sum(c.shares[k] for k, n in named.items() if n <= t)

    while support(tie) < STABLE_SHARE:
        adds = [n - tie for n in named.values() if not n <= tie]
        if not adds:
            return None
        enough = [a for a in adds if support(tie | a) >= STABLE_SHARE]
        tie |= (min(enough, key=lambda a: (len(a), -support(tie | a))) if enough
                else max(adds, key=lambda a: (support(tie | a), -len(a))))
    score = {x.effects: x.score for x in scored if not x.not_eligible}
    alts = tuple(sorted(tie, key=lambda a: -score.get(a, -math.inf)))
    if len(alts) < 2:
        return None
    out = Verdict("ambiguous", alternatives=alts)
    return out, replace(c, recurrence=support(tie), widened_from=(v, c.recurrence))


def _supports(r: Verdict, v: Verdict) -> bool:
    """Whether a resample's verdict ``r`` is the verdict ``v``: the same, or for a tie, a tie or
    a single explanation among its alternatives (a tie says the cause is one of them); for
    ``unexplained``, any unexplained verdict (its best partial explanation is an aside, and the
    shares count it as one verdict)."""
    if v.kind == "ambiguous" and r.kind in ("missing", "ambiguous"):
        return set(_named(r)) <= set(v.alternatives)
    if v.kind == "unexplained":
        return r.kind == "unexplained"
    return r == v


def _share_key(r: Verdict, v: Verdict) -> str:
    """The short form a resample's verdict is counted under: a tie of the same explanations as
    ``v``'s in another order counts as ``v``; other ties in a fixed order."""
    if r.kind == "ambiguous":
        if v.kind == "ambiguous" and set(r.alternatives) == set(v.alternatives):
            return str(v)
        return str(Verdict("ambiguous", alternatives=tuple(sorted(r.alternatives))))
    return str(r)


def _unstable(v: Verdict, c: Confidence | None) -> Verdict:
    """``v`` itself when it recurs in at least :data:`STABLE_SHARE` of the resamples, else an
    ``unstable`` verdict listing it and its rivals with their shares (those of 1 % or more)."""
    if c is None or c.recurrence is None or c.recurrence >= STABLE_SHARE:
        return v
    rivals = [(str(v), c.recurrence)] + [(k, x) for k, x in c.shares.items() if k != str(v) and x >= 0.01]
    return Verdict("unstable", effects=v.effects, alternatives=v.alternatives, partial=v.partial,
                   rivals=tuple(rivals), point=v)


def _gof_line(fit: FitResult, consistent: bool) -> str:
    """The goodness-of-fit test of the booth as declared (:func:`consistent_with_noise`), in words."""
    from scipy.special import chdtrc

    p = float(chdtrc(max(fit.dof, 1), fit.chi2))
    return (f"goodness of fit of the booth as declared: χ² = {fit.chi2:.1f} on {fit.dof} degrees of "
            f"freedom, p = {p:.2g}; tested at α = {100 * GOF_ALPHA:g} % on all the data and on each "
            f"block (readings, white tile): {'consistent with the noise' if consistent else 'above the noise'}")


def _explain_unstable(d: "Diagnosis") -> None:
    """An unstable verdict says so first, with its rivals, and suggests no edit."""
    v, c = d.verdict, d.confidence
    rivals = ", ".join(f"{r} in {100 * x:.0f} %" for r, x in v.rivals[1:])
    d.explanation.insert(0, (
        f"unstable: these data give {v.point}, but the same verdict comes back in only "
        f"{100 * c.recurrence:.0f} % of {c.samples} noise resamples" +
        (f" (rivals: {rivals})" if rivals else "") +
        "; no edit is suggested: measure more (`lbscene plan`) or with less noise"))
    d.snippet = None


def _explain(d: "Diagnosis", meas, booth_effects: dict, noise: NoiseModel) -> None:
    """The verdict's explanation lines and the booth-file snippet."""
    base, suspects, v = d.base, d.suspects, d.verdict
    red = base.chi2 / base.dof
    d.explanation.append(_gof_line(base, d.consistent))
    share = noise.model_share(base.rmse_percent)
    if share is not None:
        d.explanation.append(f"the declared model uncertainty ({noise.model_percent:g} %) covers "
                             f"{100 * share:.0f} % of the residual variance (RMSE {base.rmse_percent:.2f} %)")
    helpful = [s for s in suspects if s.score > SIGNIFICANT and not s.not_eligible]
    if v.kind == "none":
        d.explanation.append(
            f"the residual is at the noise level (χ²/dof = {red:.2f} with noise {noise.percent:.2g} %) "
            "and no candidate effect improves the fit significantly: no missing effect is needed "
            "to explain these data")
        return
    if d.consistent and helpful:
        d.explanation.append(
            f"χ²/dof = {red:.2f} is within the noise, but {helpful[0].effect} lowers the BIC by "
            f"{helpful[0].score:.1f}: the residual has structure that noise does not explain")
    by_name = {x.effects: x for x in suspects + d.pairs if x.not_eligible}
    by_name.update({x.effects: x for x in suspects + d.pairs if not x.not_eligible})
    if v.kind == "unexplained":
        d.explanation.append(f"χ²/dof = {red:.2f}: the residual is above the noise ({noise.percent:.2g} %), "
                             "and no effect, nor any pair of the best suspects, brings it to the noise")
        if v.partial:
            p = by_name[v.partial]
            excess = max(base.chi2 - base.dof, 1e-9)
            part = max(0.0, min(1.0, (base.chi2 - p.chi2) / excess))
            d.explanation.append(
                f"best partial explanation: {p.effect} explains {100 * part:.0f} % of the excess χ² "
                f"(RMSE {base.rmse_percent:.2f} % → {p.rmse_percent_after:.2f} %, χ²/dof "
                f"{p.fit.chi2 / p.fit.dof:.2f}); something else is missing too")
        d.explanation.extend(_trend(meas, base))
        if d.where:
            w = d.where[0]
            d.explanation.append(
                f"largest residual {w['residual_percent']:+.2f} % at ({w['x_mm']:g}, {w['y_mm']:g}, "
                f"{w['z_mm']:g}) mm ({w['file']}:{w['line']})")
        return
    if v.kind == "ambiguous":
        alts = [by_name[a] for a in v.alternatives]
        d.tied = v.tied
        spec = [s for s in alts if _spectral_only(s.items)]
        if len(spec) > 1:
            d.explanation.append(
                "a filter in front of the lamps and the lamps' own spectrum reshaped are the same to a "
                "spectroradiometer (each multiplies every light path by one function of wavelength): "
                "the white tile cannot tell " + " from ".join(s.effect for s in spec) +
                ", the simpler first, whatever BIC margin their parametrisations make")
        if d.confidence is not None and d.confidence.widened_from is not None:
            was, share = d.confidence.widened_from
            d.explanation.append(
                f"these data give {was}, but that verdict comes back in only {100 * share:.0f} % of "
                f"{d.confidence.samples} noise resamples; the tie below in "
                f"{100 * d.confidence.recurrence:.0f} %: the noise cannot tell its explanations apart")
        d.explanation.append(
            "these explanations fit the data equally well (BIC within "
            f"{TIE_MARGIN:g}, the same spectral factor, or a lead the noise resamples overturn): " +
            ", ".join(f"{s.effect} (RMSE {s.rmse_percent_after:.2f} %, score {s.score:.1f}, "
                      f"{s.n_params} parameters)" for s in alts))
        d.explanation.append("run `lbscene plan` for the points that tell them apart, or declare the "
                             "lamp output known (known_output_groups in the measurement set)")
    else:
        best = by_name[v.effects]
        d.tied = [best.effect]
        runner = next((s for s in suspects + d.pairs if s is not best), None)
        what = best.effect if len(v.effects) == 1 else " and ".join(v.effects) + " together"
        msg = (f"{what} {'lowers' if len(v.effects) == 1 else 'lower'} the RMSE from "
               f"{base.rmse_percent:.2f} % to {best.rmse_percent_after:.2f} % (BIC −{best.score:.1f}), "
               "to the noise")
        if runner is not None:
            msg += f"; the next explanation, {runner.effect}, scores {runner.score:.1f}"
        d.explanation.append(msg)
        if len(v.effects) > 1:
            singles = {e: by_name.get((e,)) for e in v.effects}
            d.explanation.append("alone, neither reaches the noise: " + ", ".join(
                f"{e} leaves RMSE {x.rmse_percent_after:.2f} %" for e, x in singles.items() if x is not None))
        # the suggestion is minimal: the booth's effects exactly as declared plus the new ones with
        # their fitted parameters.  The joint refit of the enabled effects' parameters is there to
        # score candidates fairly; a 55-point grid rarely pins those values, so they stay the user's.
        eff = {k: dict(v_ or {}) for k, v_ in booth_effects.items()}
        for e, params in best.params_by_effect.items():
            eff[e] = dict(params)
        d.snippet = "".join(best.hardware.values()) + effects_snippet(eff, highlight=set(v.effects))
    if base.spectral_rmse_percent is not None:
        alts = [by_name[a] for a in (v.alternatives if v.kind == "ambiguous" else (v.effects,))]
        sp = [s for s in alts if s.spectral_rmse_after is not None]
        if sp:
            d.explanation.append("white-tile spectrum: RMSE " f"{base.spectral_rmse_percent:.2f} % → " +
                                 ", ".join(f"{s.effect} {s.spectral_rmse_after:.2f} %" for s in sp))
