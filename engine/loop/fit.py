"""
Fit the forward model to measurements: free parameters, least squares, errors.

Free parameters come from the booth's ``fit:`` section; the default is each
lamp group's intensity scale (``group.<id>.intensity_scale``, 1 = the
output the booth declares) and σ where a Gaussian profile is on
(``group.<id>.sigma_deg`` for declared profiles, ``effect.angular_profile.sigma_deg``
for the effect's own σ).  Groups whose output is *known* (booth
``fit.known_output_groups`` or the measurement set's) are not fitted: a
level mismatch then counts as evidence.

Residuals are relative, in units of the measurement noise:
``(model − measured)/measured/σ`` for every illuminance reading and every
white-tile radiance band.  Intensity scales enter linearly and are solved
exactly (bounded linear least squares) inside the nonlinear fit
(variable projection), so the nonlinear search (``scipy.optimize.least_squares``,
trust-region reflective, with bounds) only sees profile and effect
parameters.  Its Jacobian is forward differences in which a parameter that moves
no residual by :data:`FLAT_RESIDUAL` of the noise has a zero column (the search
leaves it alone rather than follow rounding), and a search that its step
tolerances stopped while its last Jacobian still promises more than
:data:`STALL_GAIN_CHI2` (:func:`predicted_gain_chi2`) is continued from there: a
fit's χ² is its minimum whatever path led to it (a cold cache or a warm one).
Standard errors come from the full Jacobian at the optimum, scaled by the
reduced χ²; parameter pairs correlated beyond :data:`CORRELATION_WARNING` are
reported.
"""

from __future__ import annotations

import math
from collections import OrderedDict
from dataclasses import dataclass, field

import numpy as np

from lbscene.engine.files.diagnostics import LbsceneUserError

__all__ = [
    "FreeParameter",
    "FitProblem",
    "FitResult",
    "default_free_parameters",
    "spectral_parameters",
    "resolve_free_parameters",
    "estimate_noise_percent",
    "CORRELATION_WARNING",
    "predicted_gain_chi2",
    "INTENSITY_BOUNDS",
]

CORRELATION_WARNING = 0.95
#: forward evaluations of one least-squares search (a continuation, below, is a search of its own)
MAX_EVALUATIONS = 200
#: a search stopped by its step tolerances (``ftol``, ``xtol``) is continued from where it stopped
#: while the Gauss–Newton step of its final Jacobian, within the bounds, promises more than this
#: much χ²: after a step its linear model could not predict (a shadow edge that moves in steps, a
#: strongly curved direction) the trust region shrinks, and the next small, well predicted step
#: meets the tolerance with most of the gain still ahead.  Which step that is follows the last bits
#: of the arithmetic (a factorisation read from the cache or updated from another): the same
#: refit stopped 13 χ² apart with a cold and a warm cache before (the SpectraLight's walls).
STALL_GAIN_CHI2 = 0.5
#: at most this many continuations, each one only while the last realised at least this share of
#: the fall its Jacobian promised (a fall-off length traded against its level promised 3.7 χ² and
#: gave 0.01, twice: the valley is not the linear model's)
STALL_RESTARTS = 3
STALL_PROGRESS = 0.1
#: the relative step of the searches' forward differences
DIFF_STEP = 1e-4
#: a parameter whose step moves no residual by this much (in units of the noise) is flat where the
#: search stands: a step along it would follow rounding (an opening larger than every light path
#: moved the same refit 8 χ² apart, from a cold cache and a warm one), so its column is zero
FLAT_RESIDUAL = 1e-7
#: forward evaluations a problem remembers (:meth:`FitProblem.components`), at least: a trial
#: point, the steps of a Jacobian around it (one per non-linear parameter), and one more
COMPONENTS_MEMO = 4
INTENSITY_BOUNDS = (1e-3, 1e3)
DEFAULT_NOISE_PERCENT = 1.0
DEFAULT_SPECTRAL_NOISE_PERCENT = 1.0


def predicted_gain_chi2(J, r, lo, hi) -> float:
    """The fall of :math:`χ^2 = |r|^2` that the linear model :math:`r + J δ` predicts for its best
    step :math:`δ` within ``lo ≤ δ ≤ hi`` (bounded linear least squares): 0 at a minimum, more where
    a search stopped short of one.

    >>> J = np.array([[1.0], [1.0]]); r = np.array([1.0, 1.0])
    >>> round(predicted_gain_chi2(J, r, np.array([-10.0]), np.array([10.0])), 12)   # δ = -1: χ² 2 → 0
    2.0
    >>> round(predicted_gain_chi2(J, r, np.array([-0.5]), np.array([10.0])), 12)    # δ = -0.5 at its bound
    1.5
    """
    from scipy.optimize import lsq_linear

    J, r = np.asarray(J, float), np.asarray(r, float)
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    if J.size == 0 or not np.all(np.isfinite(J)):
        return 0.0
    d = lsq_linear(J, -r, bounds=(lo, hi)).x
    e = r + J @ d
    return max(float(r @ r - e @ e), 0.0)


@dataclass(frozen=True)
class FreeParameter:
    """One fitted quantity, addressed like ``group.fl.intensity_scale``."""

    target: str
    bounds: tuple[float, float]
    initial: float

    @property
    def scope(self) -> str:
        return self.target.split(".", 1)[0]

    @property
    def ident(self) -> str:
        return self.target.split(".")[1]

    @property
    def name(self) -> str:
        return self.target.rsplit(".", 1)[1]

    @property
    def linear(self) -> bool:
        return self.scope == "group" and self.name == "intensity_scale"


# --------------------------------------------------------------------------- parameters

def _gaussian_groups(ir, lighting, effects) -> dict[str, float]:
    """Groups whose lamps emit a declared Gaussian profile (with the effect on): group → σ."""
    if "angular_profile" not in effects:
        return {}
    sel = (effects.get("angular_profile") or {}).get("lamps")
    out = {}
    for lp, _ in ir.lamps_on(lighting):
        if sel is not None and lp.id not in sel:
            continue
        if lp.profile.get("type") == "gaussian":
            out.setdefault(lp.group, float(lp.profile["sigma_deg"]))
    return out


def _effect_sigma_on(ir, lighting, effects) -> bool:
    ap = effects.get("angular_profile")
    if ap is None or ap.get("sigma_deg") is None:
        return False
    sel = ap.get("lamps")
    return any(lp.profile.get("type") == "isotropic" and (sel is None or lp.id in sel)
               for lp, _ in ir.lamps_on(lighting))


def default_free_parameters(ir, lighting: str, effects: dict, known_groups=()) -> list[FreeParameter]:
    """Each lamp group's intensity scale (unless known) and σ where a Gaussian profile is on."""
    out = []
    groups = []
    for lp, _ in ir.lamps_on(lighting):
        if lp.group not in groups:
            groups.append(lp.group)
    for g in groups:
        if g not in known_groups:
            out.append(FreeParameter(f"group.{g}.intensity_scale", INTENSITY_BOUNDS, 1.0))
    for g, s in _gaussian_groups(ir, lighting, effects).items():
        out.append(FreeParameter(f"group.{g}.sigma_deg", (2.0, 1000.0), s))
    if _effect_sigma_on(ir, lighting, effects):
        out.append(FreeParameter("effect.angular_profile.sigma_deg", (2.0, 1000.0),
                                 float(effects["angular_profile"]["sigma_deg"])))
    return out


def effect_parameter(eid: str, name: str, effects: dict, bounds=None, initial=None) -> FreeParameter:
    """A free effect parameter with bounds from the effect's ``fit_parameters`` (or given)."""
    from lbscene.engine.light.effects.registry import get_effect

    cls = get_effect(eid)
    fp = getattr(cls, "fit_parameters", {}) or {}
    if bounds is None:
        if name not in fp:
            raise KeyError(name)
        bounds = fp[name]
    cur = (effects.get(eid) or {}).get(name)
    if initial is None:
        initial = cur if cur is not None else getattr(cls, "fit_initial", {}).get(name)
        if initial is None:
            f = cls.Params.model_fields[name]
            initial = f.default if f.default is not None else 0.5 * (bounds[0] + bounds[1])
    lo, hi = bounds
    initial = float(min(max(float(initial), lo), hi))
    return FreeParameter(f"effect.{eid}.{name}", (float(lo), float(hi)), initial)


def resolve_free_parameters(ir, lighting: str, effects: dict, known_groups=(),
                            booth_file: str = "booth.yaml") -> list[FreeParameter]:
    """The booth's ``fit.free`` (validated against the booth), or the defaults."""
    from lbscene.engine.light.effects.registry import UnknownEffectError, get_effect

    spec = ir.fit.get("free")
    if spec is None:
        return default_free_parameters(ir, lighting, effects, known_groups)
    groups = {lp.group for lp in ir.lamps}
    lamps = {lp.id for lp in ir.lamps}
    out = []
    for item in spec:
        tgt, b, init = item["target"], item.get("bounds"), item.get("initial")
        scope, ident, name = tgt.split(".")[0], tgt.split(".")[1], tgt.rsplit(".", 1)[1]

        def bad(msg, expected):
            raise LbsceneUserError.single("LB307", f"fit.free: {msg}", booth_file, value=repr(tgt),
                                          expected=expected)
        if scope == "group":
            if ident not in groups:
                bad(f"unknown lamp group '{ident}'", f"one of {', '.join(sorted(groups))}")
            if name == "intensity_scale":
                if ident in known_groups:
                    continue  # known output wins
                out.append(FreeParameter(tgt, tuple(b or INTENSITY_BOUNDS), float(init or 1.0)))
            elif name == "sigma_deg":
                s = _gaussian_groups(ir, lighting, effects).get(ident, 60.0)
                out.append(FreeParameter(tgt, tuple(b or (2.0, 1000.0)), float(init or s)))
            else:
                bad(f"unknown group parameter '{name}'", "intensity_scale or sigma_deg")
        elif scope == "lamp":
            if ident not in lamps:
                bad(f"unknown lamp '{ident}'", f"one of {', '.join(sorted(lamps))}")
            if name != "sigma_deg":
                bad(f"unknown lamp parameter '{name}'", "sigma_deg")
            prof = ir.lamp(ident).profile
            s = float(prof["sigma_deg"]) if prof.get("type") == "gaussian" else 60.0
            out.append(FreeParameter(tgt, tuple(b or (2.0, 1000.0)), float(init or s)))
        else:
            try:
                cls = get_effect(ident)
            except UnknownEffectError:
                bad(f"unknown effect '{ident}'", "a registered effect id (see `lbscene effects`)")
            if ident not in effects:
                bad(f"effect '{ident}' is not enabled in effects:", "an enabled effect")
            if name not in cls.Params.model_fields:
                bad(f"effect '{ident}' has no parameter '{name}'",
                    f"one of {', '.join(cls.Params.model_fields)}")
            try:
                out.append(effect_parameter(ident, name, effects, tuple(b) if b else None, init))
            except KeyError:
                bad(f"no default bounds for '{tgt}'", "bounds: [low, high]")
    return out


def apply_parameters(effects: dict, free: list[FreeParameter], values) -> tuple[dict, dict, dict]:
    """Parameter values → (effects, lamp_overrides, group σ) for the forward model."""
    eff = {k: dict(v or {}) for k, v in effects.items()}
    lamp_over: dict = {}
    group_sigma: dict = {}
    for fp, v in zip(free, values):
        if fp.linear:
            continue
        if fp.scope == "effect":
            eff.setdefault(fp.ident, {})[fp.name] = float(v)
        elif fp.scope == "lamp":
            lamp_over.setdefault(fp.ident, {})[fp.name] = float(v)
        elif fp.scope == "group" and fp.name == "sigma_deg":
            group_sigma[fp.ident] = float(v)
    return eff, lamp_over, group_sigma


# --------------------------------------------------------------------------- noise

def estimate_noise_percent(ill) -> float | None:
    """Model-free noise estimate: residual of a smooth 2-D polynomial through log(E).

    Uses the largest set of upward readings at one height (≥ 15 points);
    the polynomial degree leaves ≥ 20 degrees of freedom where it can.
    Returns ``None`` when there are too few points.
    """
    if ill is None or len(ill) < 15:
        return None
    up = ill.normals[:, 2] > 0.999
    z = np.round(ill.points_mm[:, 2], 0)
    best = None
    for zz in np.unique(z[up]):
        sel = up & (z == zz)
        if best is None or sel.sum() > best.sum():
            best = sel
    if best is None or best.sum() < 15:
        return None
    P = ill.points_mm[best]
    y = np.log(ill.lux[best])
    n = len(y)
    x0 = (P[:, 0] - P[:, 0].mean()) / max(np.ptp(P[:, 0]) / 2, 1e-9)
    y0 = (P[:, 1] - P[:, 1].mean()) / max(np.ptp(P[:, 1]) / 2, 1e-9)
    for deg in (4, 3, 2, 1):
        terms = [(a, b) for a in range(deg + 1) for b in range(deg + 1 - a)]
        # a direction with few distinct values cannot carry high powers
        nx, ny = len(np.unique(np.round(x0, 6))), len(np.unique(np.round(y0, 6)))
        terms = [(a, b) for a, b in terms if a < nx and b < ny]
        if n - len(terms) >= min(20, n // 2):
            break
    A = np.stack([x0 ** a * y0 ** b for a, b in terms], axis=1)
    coef, *_ = np.linalg.lstsq(A, y, rcond=None)
    r = y - A @ coef
    dof = n - np.linalg.matrix_rank(A)
    if dof <= 0:
        return None
    return float(100.0 * np.sqrt(np.sum(r ** 2) / dof))


# --------------------------------------------------------------------------- result

@dataclass
class FitResult:
    """Outcome of one fit (or of an evaluation without fitting)."""

    free: list[FreeParameter]
    values: dict[str, float]
    stderr: dict[str, float]
    correlation: np.ndarray
    warnings: list[str]
    effects: dict
    lamp_overrides: dict
    scales: dict[str, float]
    chi2: float
    n_residuals: int
    lux_pred: np.ndarray | None
    lux_meas: np.ndarray | None
    tile_bands_pred: np.ndarray | None
    tile_bands_meas: np.ndarray | None
    tile_band_mask: np.ndarray | None
    tile_1nm_pred: np.ndarray | None
    success: bool = True
    #: centres of the bands the white tile is compared in (:func:`tile_grid`)
    tile_centres_nm: np.ndarray | None = None
    message: str = ""
    nfev: int = 0
    fitted: bool = True
    #: solved without its standard errors (:meth:`FitProblem.solve` with ``errors=False``); the
    #: problem's :meth:`FitProblem.add_errors` computes them when the fit is kept
    errors_pending: bool = False

    @property
    def n_params(self) -> int:
        return len(self.free) if self.fitted else 0

    @property
    def dof(self) -> int:
        return max(self.n_residuals - self.n_params, 1)

    @property
    def residual_percent(self) -> np.ndarray:
        if self.lux_pred is None:
            return np.zeros(0)
        return 100.0 * (self.lux_pred - self.lux_meas) / self.lux_meas

    @property
    def spectral_residual_percent(self) -> np.ndarray | None:
        if self.tile_bands_pred is None:
            return None
        m = self.tile_band_mask
        out = np.full(self.tile_bands_pred.shape, np.nan)
        out[m] = 100.0 * (self.tile_bands_pred[m] - self.tile_bands_meas[m]) / self.tile_bands_meas[m]
        return out

    @property
    def rmse_percent(self) -> float:
        r = self.residual_percent
        return float(np.sqrt(np.mean(r ** 2))) if r.size else float("nan")

    @property
    def mean_abs_percent(self) -> float:
        r = self.residual_percent
        return float(np.mean(np.abs(r))) if r.size else float("nan")

    @property
    def max_percent(self) -> float:
        r = self.residual_percent
        return float(np.max(np.abs(r))) if r.size else float("nan")

    @property
    def spectral_rmse_percent(self) -> float | None:
        s = self.spectral_residual_percent
        if s is None:
            return None
        s = s[np.isfinite(s)]
        return float(np.sqrt(np.mean(s ** 2))) if s.size else None

    def bic(self) -> float:
        """χ² + k·ln n (the noise is known or estimated, so χ² is the likelihood term)."""
        return self.chi2 + self.n_params * math.log(max(self.n_residuals, 2))

    def parameters_table(self) -> list[dict]:
        return [{"target": fp.target, "value": self.values[fp.target],
                 "stderr": self.stderr.get(fp.target), "bounds": list(fp.bounds),
                 "at_bound": bool(np.isclose(self.values[fp.target], fp.bounds[0], rtol=1e-6, atol=1e-9)
                                  or np.isclose(self.values[fp.target], fp.bounds[1], rtol=1e-6,
                                                atol=1e-9))}
                for fp in self.free] if self.fitted else []


# --------------------------------------------------------------------------- the problem

def tile_grid(tile, render_grid):
    """The bands the white-tile spectrum is compared in.

    Where the instrument samples finer than the render bands (a spectroradiometer at 5 nm
    resolves a filter's 15 nm dip that 20 nm bands average away), one band per sample within
    380–780 nm, centred on it and as wide as the sampling interval: the model's band mean is
    what a spectroradiometer of that (rectangular) bandwidth reads there, compared with the
    sample itself.  Otherwise the render bands, compared with the measured spectrum's band means.
    """
    from lbscene.engine.spectra.bands import BandGrid

    step = getattr(tile, "sampling_nm", None)
    first = getattr(tile, "first_sample_nm", None)
    if step is None or first is None or step >= render_grid.width_nm or step < 1.0:
        return render_grid
    c0 = first + step * max(np.ceil((380.0 + step / 2 - first) / step), 0.0)
    count = int(np.floor((780.0 - step / 2 - c0) / step + 1e-9)) + 1
    if count < render_grid.count:
        return render_grid
    return BandGrid(first_centre_nm=float(c0), width_nm=float(step), count=count)


@dataclass
class FitProblem:
    """Measurements + a model configuration (enabled effects, free parameters).

    ``cache`` is shared by every forward evaluation (and may be shared by
    several problems on the same IR: the diagnosis does).
    """

    meas: object
    effects: dict
    free: list[FreeParameter]
    noise_percent: float
    spectral_noise_percent: float = DEFAULT_SPECTRAL_NOISE_PERCENT
    cache: dict = field(default_factory=dict)
    extra_points: object = None     # IlluminanceData of points to predict (not fitted)
    #: least_squares' xtol and ftol: the user's fit converges tightly; the diagnosis, which only
    #: needs χ² to a small fraction of a BIC unit, loosens it (see diagnose.SCORING_TOLERANCE)
    tolerance: float = 1e-8

    def __post_init__(self):
        m = self.meas
        self.ir = m.ir
        self.lighting = m.lighting
        self.groups = []
        for lp, _ in self.ir.lamps_on(self.lighting):
            if lp.group not in self.groups:
                self.groups.append(lp.group)
        pts, nrm, meter = [], [], []
        self.n_lux = 0
        if m.illuminance is not None:
            pts.append(m.illuminance.points_mm)
            nrm.append(m.illuminance.normals)
            meter.append(np.ones(len(m.illuminance), bool))
            self.n_lux = len(m.illuminance)
        self.tile_row = None
        if m.tile is not None:
            self.tile_row = sum(len(p) for p in pts)
            pts.append(m.tile.position_mm[None])
            nrm.append(m.tile.normal[None])
            meter.append(np.zeros(1, bool))
        self.P = np.concatenate(pts)
        self.N = np.concatenate(nrm)
        self.meter = np.concatenate(meter)
        self.sigma_e = self.noise_percent / 100.0
        self.sigma_s = self.spectral_noise_percent / 100.0
        self.tile_grid = tile_grid(m.tile, self.ir.grid) if m.tile is not None else None
        if m.tile is not None:
            g = self.tile_grid
            inside = np.array([m.tile.covered[(np.arange(360, 831) >= lo) & (np.arange(360, 831) <= hi)].all()
                               for lo, hi in zip(g.edges_nm[:-1], g.edges_nm[1:])])
            if g is self.ir.grid:
                self.tile_meas = g.integrate(m.tile.radiance_1nm)
            else:   # the samples themselves (the 1 nm spectrum interpolates them linearly)
                wl = np.arange(360.0, 831.0)
                self.tile_meas = np.interp(g.centres_nm, wl, m.tile.radiance_1nm)
                cw = wl[m.tile.covered]
                # both 1 nm neighbours of a sample measured (the interpolation is exact there)
                inside = (g.centres_nm >= cw.min()) & (g.centres_nm <= cw.max())
            self.tile_mask = inside & (self.tile_meas > 0.02 * self.tile_meas.max())
        else:
            self.tile_meas = None
            self.tile_mask = None
        self.lin = [i for i, fp in enumerate(self.free) if fp.linear]
        self.nl = [i for i, fp in enumerate(self.free) if not fp.linear]
        self.lin_groups = [self.free[i].ident for i in self.lin]
        self.nfev = 0
        self._memo: OrderedDict = OrderedDict()

    def _recall(self, key):
        """:meth:`components` at ``key`` if one of the last :data:`COMPONENTS_MEMO` evaluations
        (None if not).  A search evaluates a trial point and, when it keeps it, its Jacobian's
        steps around it and the point again: with one point remembered the point was computed
        twice (a quarter of a two-parameter fit's evaluations)."""
        hit = self._memo.get(key)
        if hit is not None:
            self._memo.move_to_end(key)
        return hit

    def _remember(self, key, out) -> None:
        self._memo[key] = out
        self._memo.move_to_end(key)
        while len(self._memo) > max(COMPONENTS_MEMO, len(self.nl) + 2):
            self._memo.popitem(last=False)

    # ------------------------------------------------------------------ model
    def model(self, values_nl) -> "ForwardModel":  # noqa: F821
        from lbscene.engine.light.forward import ForwardModel

        full = [fp.initial for fp in self.free]
        for k, i in enumerate(self.nl):
            full[i] = values_nl[k]
        eff, lamp_over, group_sigma = apply_parameters(self.effects, self.free, full)
        for lp, _ in self.ir.lamps_on(self.lighting):
            if lp.group in group_sigma:
                lamp_over.setdefault(lp.id, {})["sigma_deg"] = group_sigma[lp.group]
        return ForwardModel(self.ir, self.lighting, effects=eff, lamp_overrides=lamp_over,
                            cache=self.cache), eff, lamp_over

    def components(self, values_nl):
        """Per-group illuminance (G, M) and tile radiance bands (G, B) at unit scales."""
        key = tuple(float(v) for v in values_nl)
        hit = self._recall(key)
        if hit is not None:
            return hit
        fm, eff, lo = self.model(values_nl)
        pred = fm.predict(self.P, self.N, self.meter)
        self.nfev += 1
        lux = pred.lux_by_group()
        A = np.stack([lux[g][: self.n_lux] for g in self.groups]) if self.n_lux else None
        T = T1 = None
        if self.tile_row is not None:
            refl = self.meas.tile.reflectance_1nm
            T1 = []
            for g in self.groups:
                spec = pred.spectral_1nm({h: (1.0 if h == g else 0.0) for h in self.groups},
                                         rows=[self.tile_row])
                T1.append(spec[0] * refl / np.pi)
            T1 = np.stack(T1)
            T = self.tile_grid.integrate(T1)
        out = (A, T, T1, eff, lo)
        self._remember(key, out)
        return out

    # ------------------------------------------------------------------ residuals
    def _design(self, A, T):
        """Rows of the weighted linear system: D (n, G), target t (n,)."""
        rows, tgt = [], []
        if A is not None:
            y = self.meas.illuminance.lux
            rows.append((A / (y * self.sigma_e)[None, :]).T)
            tgt.append(np.full(len(y), 1.0 / self.sigma_e))
        if T is not None and self.tile_mask.any():
            m = self.tile_mask
            rows.append((T[:, m] / (self.tile_meas[m] * self.sigma_s)[None, :]).T)
            tgt.append(np.full(int(m.sum()), 1.0 / self.sigma_s))
        return np.concatenate(rows), np.concatenate(tgt)

    def scales_for(self, A, T) -> dict[str, float]:
        """Best intensity scales (bounded, linear) for fixed nonlinear parameters."""
        D, t = self._design(A, T)
        s = np.ones(len(self.groups))
        free_idx = [self.groups.index(g) for g in self.lin_groups]
        if free_idx:
            fixed = [i for i in range(len(self.groups)) if i not in free_idx]
            rhs = t - (D[:, fixed] @ s[fixed] if fixed else 0.0)
            Df = D[:, free_idx]
            lo = np.array([self.free[i].bounds[0] for i in self.lin])
            hi = np.array([self.free[i].bounds[1] for i in self.lin])
            sol, *_ = np.linalg.lstsq(Df, rhs, rcond=None)
            if np.any(sol < lo) or np.any(sol > hi) or not np.all(np.isfinite(sol)):
                from scipy.optimize import lsq_linear

                sol = lsq_linear(Df, rhs, bounds=(lo, hi)).x
            s[free_idx] = sol
        return dict(zip(self.groups, s))

    def residuals(self, values_nl, scales=None) -> np.ndarray:
        A, T, *_ = self.components(values_nl)
        if scales is None:
            scales = self.scales_for(A, T)
        D, t = self._design(A, T)
        s = np.array([scales[g] for g in self.groups])
        return D @ s - t

    @property
    def n_residuals(self) -> int:
        return self.n_lux + (int(self.tile_mask.sum()) if self.tile_mask is not None else 0)

    # ------------------------------------------------------------------ solve
    def evaluate(self, fitted: bool = False) -> FitResult:
        """The model at the initial parameter values (declared booth), no fitting."""
        x0 = np.array([self.free[i].initial for i in self.nl])
        scales = {g: 1.0 for g in self.groups}
        return self._result(x0, scales, success=True, message="not fitted", fitted=False)

    def solve(self, errors: bool = True) -> FitResult:
        """Least-squares fit of the free parameters (the linear output scales solved exactly at
        each step).  ``errors=False`` skips the finite-difference Jacobian of the standard errors
        (one forward evaluation per non-linear parameter): for fits only compared by χ², such as
        the points of a profile, of which only the one kept needs them (:meth:`add_errors`)."""
        from lbscene.engine.light.forward import blas_single_thread

        if self.n_residuals < len(self.free) + 1:
            f = self.meas.illuminance.files[0] if self.meas.illuminance is not None else str(self.meas.path)
            raise LbsceneUserError.single(
                "LB407", f"{self.n_residuals} data values cannot fit {len(self.free)} free parameters",
                f, expected=f"at least {len(self.free) + 1} readings (or fewer free parameters)")
        with blas_single_thread():
            if not self.nl:
                A, T, *_ = self.components(np.zeros(0))
                return self._result(np.zeros(0), self.scales_for(A, T), True, "linear", fitted=True,
                                    errors=errors)
            lo = np.array([self.free[i].bounds[0] for i in self.nl], float)
            hi = np.array([self.free[i].bounds[1] for i in self.nl], float)
            x0 = np.clip(np.array([self.free[i].initial for i in self.nl], float),
                         lo + 1e-9 * (hi - lo), hi - 1e-9 * (hi - lo))
            x, sol = self._search(x0, self._jacobian(x0, lo, hi), lo, hi)
            for _ in range(STALL_RESTARTS):
                # stopped by a step tolerance with its own Jacobian promising more: go on from there
                if sol is None or sol.status not in (2, 3, 4):
                    break
                J = self._jacobian(x, lo, hi, cols=np.setdiff1d(np.arange(x.size), sol.moved))
                J[:, sol.moved] = sol.jac                  # the search's own, at x
                promised = predicted_gain_chi2(J, sol.fun, lo - x, hi - x)
                if promised <= STALL_GAIN_CHI2:
                    break
                x2, more = self._search(x, J, lo, hi)
                gained = 2.0 * (sol.cost - more.cost) if more is not None else 0.0
                if gained > 0.0:
                    x, sol = x2, more
                if gained < STALL_PROGRESS * promised:
                    break                 # the promise was the linear model's, not the booth's
            A, T, *_ = self.components(x)
            if sol is None:
                return self._result(x, self.scales_for(A, T), True, "no free parameter moves the readings",
                                    fitted=True, errors=errors)
            return self._result(x, self.scales_for(A, T), bool(sol.success), str(sol.message),
                                fitted=True, errors=errors)

    def _search(self, x_start, J_start, lo, hi):
        """One least-squares search from ``x_start`` over the parameters that move the readings
        there (a non-zero column of its Jacobian ``J_start``): ``(x, solution)``, the solution
        ``None`` when none does.  The others stay where they are: a search moves a parameter of
        a zero column too (the bounds' scaling and reflections), and there it follows rounding."""
        from scipy.optimize import least_squares

        x_start = np.asarray(x_start, float)
        moved = np.nonzero(np.any(J_start != 0.0, axis=0))[0]
        if not moved.size:
            return x_start, None

        def full(z):
            x = x_start.copy()
            x[moved] = z
            return x

        start = x_start[moved].copy()

        def jac(z):
            if np.array_equal(z, start):
                return J_start[:, moved]
            return self._jacobian(full(z), lo, hi, cols=moved)[:, moved]

        sol = least_squares(lambda z: self.residuals(full(z)), start, bounds=(lo[moved], hi[moved]), method="trf",
                            x_scale=np.maximum(hi - lo, 1e-9)[moved] * 0.1, jac=jac, xtol=self.tolerance,
                            ftol=self.tolerance, max_nfev=MAX_EVALUATIONS)
        sol.moved = moved
        return full(sol.x), sol

    def _jacobian(self, x, lo, hi, cols=None) -> np.ndarray:
        """Forward differences of the residuals, a step of :data:`DIFF_STEP` × max(1, |x|) (away
        from a bound it would cross), in the columns ``cols`` (all by default; the others zero).
        A parameter that moves no residual by :data:`FLAT_RESIDUAL`
        gets an exactly zero column: the search leaves it where it is (:meth:`_search`)."""
        x = np.asarray(x, float)
        steps = []
        for i in (range(x.size) if cols is None else cols):
            h = DIFF_STEP * max(1.0, abs(float(x[i])))
            if x[i] + h > hi[i] and x[i] - h >= lo[i]:
                h = -h
            xi = x.copy()
            xi[i] += h
            steps.append((i, h, self.residuals(xi)))
        r0 = self.residuals(x)            # a search's trial point, remembered (:meth:`_recall`)
        J = np.zeros((r0.size, x.size))
        for i, h, r in steps:
            d = r - r0
            if np.max(np.abs(d), initial=0.0) >= FLAT_RESIDUAL:
                J[:, i] = d / h
        return J

    def add_errors(self, fit: FitResult) -> FitResult:
        """``fit`` (a solution of this problem) with the standard errors, correlations and
        warnings :meth:`solve` skipped with ``errors=False``; unchanged if it has them."""
        if not fit.errors_pending:
            return fit
        from lbscene.engine.light.forward import blas_single_thread

        x_nl = np.array([fit.values[self.free[i].target] for i in self.nl], float)
        with blas_single_thread():
            fit.stderr, fit.correlation, fit.warnings = self._errors(x_nl, fit.scales, fit.chi2)
        fit.errors_pending = False
        return fit

    def _result(self, x_nl, scales, success, message, fitted, errors: bool = True) -> FitResult:
        A, T, T1, eff, lamp_over = self.components(x_nl)
        s = np.array([scales[g] for g in self.groups])
        values = {}
        for k, i in enumerate(self.nl):
            values[self.free[i].target] = float(x_nl[k])
        for i in self.lin:
            values[self.free[i].target] = float(scales[self.free[i].ident])
        r = self.residuals(x_nl, scales)
        chi2 = float(r @ r)
        stderr, corr, warns = {}, np.eye(len(self.free)), []
        pending = bool(fitted and self.free and not errors)
        if fitted and self.free and errors:
            stderr, corr, warns = self._errors(x_nl, scales, chi2)
        lux_pred = s @ A if A is not None else None
        tile_pred = s @ T if T is not None else None
        tile1 = s @ T1 if T1 is not None else None
        return FitResult(
            free=list(self.free), values=values, stderr=stderr, correlation=corr, warnings=warns,
            effects=eff, lamp_overrides=lamp_over, scales=dict(scales), chi2=chi2,
            n_residuals=self.n_residuals, lux_pred=lux_pred,
            lux_meas=self.meas.illuminance.lux if self.n_lux else None,
            tile_bands_pred=tile_pred, tile_bands_meas=self.tile_meas, tile_band_mask=self.tile_mask,
            tile_1nm_pred=tile1, success=success, message=message, nfev=self.nfev, fitted=fitted,
            errors_pending=pending,
            tile_centres_nm=self.tile_grid.centres_nm if self.tile_grid is not None else None)

    def _errors(self, x_nl, scales, chi2, *, noise_limited: bool = False):
        """Standard errors and correlations from the Jacobian over all free parameters.

        The covariance is scaled by χ²/dof (a fit worse than the noise widens it), unless
        ``noise_limited``: then it is what the data could pin down at the declared noise."""
        n = self.n_residuals
        cols = []
        A, T, *_ = self.components(x_nl)
        D, _ = self._design(A, T)
        r0 = self.residuals(x_nl, scales)
        for i, fp in enumerate(self.free):
            if fp.linear:
                cols.append(D[:, self.groups.index(fp.ident)])
            else:
                k = self.nl.index(i)
                h = 1e-4 * max(abs(x_nl[k]), 1e-3 * (fp.bounds[1] - fp.bounds[0]))
                x2 = np.array(x_nl, float)
                if x2[k] + h > fp.bounds[1]:
                    h = -h
                x2[k] += h
                cols.append((self.residuals(x2, scales) - r0) / h)
        self.components(x_nl)  # restore the cache to the optimum
        J = np.stack(cols, axis=1)
        dof = max(n - J.shape[1], 1)
        s2 = 1.0 if noise_limited else chi2 / dof
        try:
            cov = np.linalg.pinv(J.T @ J) * s2
        except np.linalg.LinAlgError:
            return {}, np.eye(J.shape[1]), ["the fit's Jacobian is singular: parameters are not "
                                            "identifiable from these data"]
        se = np.sqrt(np.clip(np.diag(cov), 0, None))
        with np.errstate(divide="ignore", invalid="ignore"):
            corr = cov / np.outer(se, se)
        corr = np.nan_to_num(corr)
        warns = []
        names = [fp.target for fp in self.free]
        for a in range(len(names)):
            for b in range(a + 1, len(names)):
                if abs(corr[a, b]) > CORRELATION_WARNING:
                    warns.append(f"{names[a]} and {names[b]} are strongly correlated "
                                 f"(ρ = {corr[a, b]:+.3f}): these data cannot tell them apart")
        return dict(zip(names, se.tolist())), corr, warns


# ----------------------------------------------------------------------- goodness of fit

#: χ²/dof consistency with noise: within this many standard deviations of 1 (the level test's z).
NOISE_Z = 3.0
#: Significance level of the goodness-of-fit test behind "nothing is missing": each data block's
#: χ² must have an upper-tail probability P(χ²_dof ≥ χ²) of at least this.
GOF_ALPHA = 0.01


def chi2_limit(dof: int, alpha: float = GOF_ALPHA) -> float:
    """The largest χ² the goodness-of-fit test accepts on ``dof`` degrees of freedom:
    the upper ``alpha`` quantile of the χ² distribution."""
    from scipy.special import chdtri

    return float(chdtri(max(int(dof), 1), alpha))


def consistent_with_noise(fit: FitResult, z: float = NOISE_Z, noise_percent: float | None = None,
                          spectral_noise_percent: float | None = None, level_test: bool = False,
                          alpha: float = GOF_ALPHA) -> bool:
    """Residuals consistent with the noise: a χ² goodness-of-fit test at level ``alpha``.

    The whole fit and each data block on its own (the illuminance readings on
    ``n − k`` degrees of freedom, the white-tile bands on ``n − 1``) must have
    :math:`P(χ^2_\\nu \\ge χ^2) \\ge α`; a 1.2 % residual at 1 % noise on 55 readings
    (χ² ≈ 79, p ≈ 0.007) fails it.  With ``level_test`` (lamp output declared known) also the
    mean illuminance residual must be within ``z`` standard errors of 0 — a level mismatch of a
    fraction of the noise is invisible in χ² but certain in the mean of 55 readings.
    """
    if fit.chi2 > chi2_limit(fit.dof, alpha):
        return False
    # parameters that shape spectra only are paid for by the tile's bands, the others by the readings
    k_s = _spectral_parameters(fit)
    k = fit.n_params - k_s
    if noise_percent:
        r = fit.residual_percent / noise_percent
        if r.size and not readings_consistent(float(r @ r), float(r.mean()), r.size, k, level_test, z, alpha):
            return False
    return _tile_consistent(fit, spectral_noise_percent, k_s, alpha)


def readings_consistent(chi2, mean_z, n: int, k: int, level_test: bool = False, z: float = NOISE_Z,
                        alpha: float = GOF_ALPHA):
    """:func:`consistent_with_noise`'s test of the readings' block: their χ² (``chi2``, in noise
    units) on ``n − k`` degrees of freedom and, with ``level_test``, their mean residual
    ``mean_z`` (noise units) within ``z`` standard errors of 0.  ``chi2`` and ``mean_z`` may be
    arrays (resamples: the diagnosis' bootstrap applies the same test to each)."""
    ok = np.asarray(chi2) <= chi2_limit(max(n - k, 1), alpha)
    if level_test:
        ok = ok & (np.abs(np.asarray(mean_z)) * math.sqrt(n) <= z)
    return ok


def _tile_consistent(fit: FitResult, spectral_noise_percent: float | None, k_s: int | None = None,
                     alpha: float = GOF_ALPHA) -> bool:
    """:func:`consistent_with_noise`'s test of the white-tile bands alone (on ``n − 1 − k_s``
    degrees of freedom, ``k_s`` the parameters that shape spectra only)."""
    if not spectral_noise_percent:
        return True
    s = fit.spectral_residual_percent
    if s is None:
        return True
    s = s[np.isfinite(s)] / spectral_noise_percent
    if s.size <= 2:
        return True
    k_s = _spectral_parameters(fit) if k_s is None else k_s
    return float(s @ s) <= chi2_limit(max(s.size - 1 - k_s, 1), alpha)


def spectral_parameters(free) -> list:
    """The free parameters that change spectra only (a hypothesised filter's coefficients, a
    spectral effect's parameters)."""
    from lbscene.engine.light.effects.registry import available_effects

    eff = available_effects()
    return [fp for fp in free if fp.scope == "hypothesis" or
            (fp.scope == "effect" and getattr(eff.get(fp.ident), "kind", "") == "spectral")]


def _spectral_parameters(fit: FitResult) -> int:
    """How many of a fit's free parameters change spectra only (:func:`spectral_parameters`)."""
    return len(spectral_parameters(fit.free)) if fit.fitted else 0
