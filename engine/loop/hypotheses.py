"""
Hypotheses for hardware the booth file does not declare.

A catalog effect models hardware the booth declares: the ``diffuser`` effect needs a
``diffuser:`` section, ``aperture_occlusion`` its ``occluders:``, ``spectral_filter`` a
``filters:`` entry.  When the file has none, the diagnosis still asks whether such hardware
would explain the measurements.  A *hypothesis* adds the hardware to a copy of the compiled
booth, where and as large as the lamps and the interior suggest, fits the properties the data
can pin down together with the booth's own free parameters, and writes the result as booth
YAML (hardware section plus its ``effects:`` entry) that validates and compiles.

==================  ===================  ========  =============================================
hypothesis          effect it turns on   channel   what is fitted
==================  ===================  ========  =============================================
``diffuser_plate``  ``diffuser``         spatial   a Lambertian-scattering plate
                                                   :data:`PLATE_GAP_MM` below the lowest lamp,
                                                   over the interior less :data:`MARGIN_MM`:
                                                   its diffuse fraction, and its transmittance
                                                   when the lamp output is declared known
``aperture_plate``  ``aperture_occlusion``  spatial  a black luminaire cavity: a plate over the
                                                   interior :data:`PLATE_GAP_MM` below the lowest
                                                   lamp, black panels from it to the ceiling, and
                                                   a rectangular opening around the lamps'
                                                   footprint: the opening's two extents
``smooth_filter``   ``spectral_filter``  spectral  a transmittance in front of every lamp,
                                                   :math:`T(λ) = \\exp \\sum_k b_k B_k(λ)` on
                                                   cubic B-splines over the measured range, as
                                                   many as the BIC chooses (knots down to the
                                                   tile's sampling), with its uncertainty
``lamp_ageing``     ``lamp_spectrum_     spectral  each lamp's spectrum shifted and tilted at
                    shift``                        its declared luminous output: the shift and
                                                   the tilt (not hardware: always tried)
==================  ===================  ========  =============================================

The plate hypotheses are refitted like catalog effects (the forward model on the augmented
booth, every free parameter of the booth refitted).  The filter is exact without a new
forward evaluation: a filter in front of every lamp multiplies the spectrum of every light
path by :math:`T(λ)`, so with :math:`E_{g,i}(λ)` the spectral irradiance of lamp group
:math:`g` at reading :math:`i` (the fit it is added to, at unit output)

.. math::

    E^{v}_{g,i}(T) = E^{v}_{g,i} \\frac{\\int T E_{g,i} V\\,dλ}{\\int E_{g,i} V\\,dλ}, \\qquad
    L_{g,b}(T) = \\frac{ρ}{π} \\int_b T(λ)\\,E_{g,\\text{tile}}(λ)\\,dλ ,

and the coefficients :math:`b_k` enter the same least-squares problem as the groups'
output scales (Levenberg–Marquardt on the exact Jacobian :math:`∂T/∂b_k = T B_k`, the scales
solved linearly at each step).  The filter's resolution is the data's to choose: it is fitted on
6, 12, 24, 48, … uniform B-splines up to a knot spacing equal to the width of the bands the tile
is compared in (the instrument's sampling interval, see :func:`lbscene.engine.loop.fit.tile_grid`),
and the basis of least :math:`\\mathrm{BIC} = χ^2 + k \\ln n` is kept.  The aged lamp is exact
the same way, with :math:`F_g(λ) = S_{a,g}(λ)/S_g(λ)` for group :math:`g`'s spectrum :math:`S_g`.  With the lamp output fitted, an overall factor on :math:`T` is the output
scale: the basis function nearest 555 nm is held at 0 and the written filter is normalised to
a maximum of 1.  Its uncertainty is
:math:`σ_T(λ) = T(λ) \\sqrt{B(λ)^\\mathsf{T} Σ_b B(λ)}` from the fit's covariance.

Where a hypothesis puts its hardware is a guess; what it fits is what the readings can tell.
The written YAML says which is which.

References
----------
Kass, R. E., Raftery, A. E. (1995). Bayes factors. *Journal of the American Statistical
Association* 90 (430), 773–795 (the BIC scale the diagnosis scores hypotheses on).
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass, replace
from typing import ClassVar, Literal

import numpy as np

from .fit import FitProblem, FitResult, FreeParameter

__all__ = [
    "Hypothesis",
    "PlateHypothesis",
    "DiffuserPlateHypothesis",
    "AperturePlateHypothesis",
    "SmoothFilterHypothesis",
    "LampAgeingHypothesis",
    "HYPOTHESES",
    "applicable_hypotheses",
    "filter_basis",
    "filter_basis_sizes",
    "fit_filter_by_evidence",
    "PLATE_GAP_MM",
    "MARGIN_MM",
    "FILTER_BASIS",
    "FITTED_FILTER_ID",
]

#: height of a hypothesised plate below the lowest point of the lamps that are on
PLATE_GAP_MM = 20.0
#: a hypothesised diffuser leaves this much room to each wall
MARGIN_MM = 10.0
#: a hypothesised opening starts this much larger than the lamps' footprint on each side
OPENING_MARGIN_MM = 20.0
#: starting (u, v) opening scales tried (1: the lamps' footprint plus the margin)
APERTURE_STARTS = ((1.0, 1.0), (0.6, 0.6), (1.0, 1.4), (1.4, 1.0))
#: cubic B-splines of the fitted filter's log-transmittance over 380–780 nm
FILTER_BASIS = 12
#: id of the fitted filter in the written YAML
FITTED_FILTER_ID = "fitted_filter"
#: bounds of the filter's log-transmittance coefficients (T from 0.02 to 7, relative)
FILTER_COEFF_BOUNDS = (-4.0, 2.0)
#: Levenberg–Marquardt iterations of one filter fit at most
FILTER_LM_ITERATIONS = 60
#: knots the filter's local refinement inserts at most
FILTER_MAX_INSERTIONS = 24
_WL = np.arange(360.0, 831.0)


def _lamps_on(ir, lighting):
    return [lp for lp, _ in ir.lamps_on(lighting)]


def _lamp_bottom_mm(lp) -> float:
    z = float(lp.position_mm[2])
    if lp.kind in ("tube", "bulb"):
        return z - float(lp.radius_mm)
    if lp.kind == "panel":
        # a panel's extent along z: its axis and the width direction (aim × axis)
        ax = np.asarray(lp.axis, float)
        wd = np.cross(np.asarray(lp.aim, float), ax)
        return z - abs(ax[2]) * lp.length_mm / 2 - abs(wd[2]) * lp.width_mm / 2
    return z


def _lamp_footprint_mm(lp) -> tuple[float, float, float, float]:
    """x-min, x-max, y-min, y-max of a lamp's body seen from below."""
    p = np.asarray(lp.position_mm, float)
    ax = np.asarray(lp.axis, float)
    if lp.kind == "tube":
        h = ax * lp.length_mm / 2
        r = float(lp.radius_mm)
        xs, ys = [p[0] - h[0], p[0] + h[0]], [p[1] - h[1], p[1] + h[1]]
        return min(xs) - r, max(xs) + r, min(ys) - r, max(ys) + r
    if lp.kind == "panel":
        wd = np.cross(np.asarray(lp.aim, float), ax)
        ex = abs(ax[0]) * lp.length_mm / 2 + abs(wd[0]) * lp.width_mm / 2
        ey = abs(ax[1]) * lp.length_mm / 2 + abs(wd[1]) * lp.width_mm / 2
        return p[0] - ex, p[0] + ex, p[1] - ey, p[1] + ey
    r = float(lp.radius_mm) if lp.kind == "bulb" else 0.0
    return p[0] - r, p[0] + r, p[1] - r, p[1] + r


def _floor_bounds_mm(ir) -> tuple[float, float, float, float]:
    for s in ir.surfaces:
        if s.role == "floor":
            v = np.asarray(s.vertices_mm, float)
            return float(v[:, 0].min()), float(v[:, 0].max()), float(v[:, 1].min()), float(v[:, 1].max())
    w, d = ir.interior.width_mm, ir.interior.depth_mm
    return -w / 2, w / 2, -d / 2, d / 2


def _g(x: float) -> str:
    return f"{x:.4g}"


class Hypothesis(ABC):
    """Hardware the booth does not declare, as a candidate explanation.

    Subclasses declare ``id``, the catalog ``effect`` it turns on, its ``channel`` (``spatial``
    or ``spectral``: which residuals it may claim, see :mod:`lbscene.engine.loop.diagnose`) and a
    one-line ``summary``; they implement :meth:`declared` and :meth:`hardware_yaml`, and
    either :meth:`augment` (plates: refitted through the forward model) or :meth:`fit_on`
    (a spectral factor fitted on top of a fit).
    """

    id: ClassVar[str]
    effect: ClassVar[str]
    channel: ClassVar[Literal["spatial", "spectral"]]
    summary: ClassVar[str]
    #: hardware the booth file lacks (tried only when the booth leaves something to explain);
    #: False for a property of what the booth declares (a lamp's spectrum aged)
    hardware: ClassVar[bool] = True

    @classmethod
    def applicable(cls, ir, lighting: str) -> str | None:
        """``None`` when the hypothesis can be tried (the booth lacks the hardware), else why not."""
        if not _lamps_on(ir, lighting):
            return "no lamp is on"
        return cls.declared(ir, lighting)

    @classmethod
    @abstractmethod
    def declared(cls, ir, lighting: str) -> str | None:
        """Why the booth's own hardware makes the hypothesis moot (the catalog effect tests it),
        or ``None``."""

    @classmethod
    @abstractmethod
    def hardware_yaml(cls, ir, fit: FitResult) -> str:
        """The hardware section(s) to add to the booth file, with the fitted values."""

    @classmethod
    def augment(cls, ir, lighting: str, known_groups) -> tuple[object, dict, list[FreeParameter]]:
        """``(augmented IR, effect entries to enable, free parameters)``."""
        raise NotImplementedError(f"hypothesis {cls.id!r} is not a plate: it is fitted by fit_on")

    @classmethod
    def fit_on(cls, problem: FitProblem, fit: FitResult, known: bool) -> FitResult:
        """Fit the hypothesis on top of ``fit`` (the solution of ``problem``)."""
        raise NotImplementedError(f"hypothesis {cls.id!r} is refitted through augment")

    @classmethod
    def starts(cls) -> list[dict[str, float]]:
        """Starting values to try before the fit (free-parameter target → value); [] for one."""
        return []

    @classmethod
    def effect_entry(cls, fit: FitResult) -> dict:
        """The effect's parameters to write (the hardware carries the fitted values)."""
        return {}


class PlateHypothesis(Hypothesis):
    """A plate :data:`PLATE_GAP_MM` below the lowest lamp that is on."""

    @classmethod
    def plate_z_mm(cls, ir, lighting) -> float:
        return min(_lamp_bottom_mm(lp) for lp in _lamps_on(ir, lighting)) - PLATE_GAP_MM


class DiffuserPlateHypothesis(PlateHypothesis):
    id = "diffuser_plate"
    effect = "diffuser"
    channel = "spatial"
    summary = "a diffusing plate under the lamps"

    @classmethod
    def declared(cls, ir, lighting):
        return "the booth declares a diffuser (the diffuser effect tests it)" if ir.diffuser else None

    @classmethod
    def augment(cls, ir, lighting, known_groups):
        from lbscene.engine.scene.ir import IRDiffuser, IRSpectrum

        x0, x1, y0, y1 = _floor_bounds_mm(ir)
        d = IRDiffuser(z_mm=cls.plate_z_mm(ir, lighting),
                       size_mm=(x1 - x0 - 2 * MARGIN_MM, y1 - y0 - 2 * MARGIN_MM),
                       centre_mm=((x0 + x1) / 2, (y0 + y1) / 2), thickness_mm=3.0,
                       transmittance=IRSpectrum.from_1nm(np.ones(_WL.size), ir.grid),
                       scattering={"type": "lambertian", "diffuse_fraction": 0.5}, ior=1.49)
        free = [FreeParameter("effect.diffuser.diffuse_fraction", (0.0, 1.0), 0.5)]
        groups = {lp.group for lp in _lamps_on(ir, lighting)}
        if groups and groups <= set(known_groups or ()):
            # with every output known the plate's transmittance is a level the data can see
            free.append(FreeParameter("effect.diffuser.transmittance_scale", (0.1, 1.0), 0.8))
        return ir.model_copy(update={"diffuser": d}), {"diffuser": {}}, free

    @classmethod
    def hardware_yaml(cls, ir, fit):
        d = ir.diffuser
        fd = fit.values.get("effect.diffuser.diffuse_fraction", 0.5)
        se = fit.stderr.get("effect.diffuser.diffuse_fraction")
        t = fit.values.get("effect.diffuser.transmittance_scale")
        lines = [f"diffuser:   # hypothesis: {cls.summary}; height and extent assumed, "
                 "scattering fitted",
                 f"  z_mm: {_g(d.z_mm)}", f"  size_mm: [{_g(d.size_mm[0])}, {_g(d.size_mm[1])}]",
                 f"  centre_mm: [{_g(d.centre_mm[0])}, {_g(d.centre_mm[1])}]",
                 f"  thickness_mm: {_g(d.thickness_mm)}", f"  ior: {_g(d.ior)}"]
        if t is None:
            lines.append("  transmittance: {type: constant, value: 1.0}   # not measurable with the "
                         "lamp output fitted: put the datasheet value")
        else:
            st = fit.stderr.get("effect.diffuser.transmittance_scale")
            lines.append(f"  transmittance: {{type: constant, value: {_g(t)}}}" +
                         (f"   # ± {_g(st)}" if st else ""))
        lines.append(f"  scattering: {{type: lambertian, diffuse_fraction: {_g(fd)}}}" +
                     (f"   # ± {_g(se)}" if se else ""))
        return "\n".join(lines) + "\n"


class AperturePlateHypothesis(PlateHypothesis):
    id = "aperture_plate"
    effect = "aperture_occlusion"
    channel = "spatial"
    summary = "an aperture (luminaire cavity opening) under the lamps"
    OCCLUDER_ID = "aperture"

    @classmethod
    def declared(cls, ir, lighting):
        on = {lp.id for lp in _lamps_on(ir, lighting)}
        if any(o.lamps is None or on & set(o.lamps) for o in ir.occluders):
            return "the booth declares occluders (the aperture_occlusion effect tests them)"
        return None

    @classmethod
    def opening(cls, ir, lighting) -> tuple[float, float, float, float]:
        """Centre (x, y) and extent (u, v) of the lamps' footprint plus the margin."""
        fp = np.array([_lamp_footprint_mm(lp) for lp in _lamps_on(ir, lighting)])
        x0, x1, y0, y1 = fp[:, 0].min(), fp[:, 1].max(), fp[:, 2].min(), fp[:, 3].max()
        m = OPENING_MARGIN_MM
        return (x0 + x1) / 2, (y0 + y1) / 2, x1 - x0 + 2 * m, y1 - y0 + 2 * m

    @classmethod
    def augment(cls, ir, lighting, known_groups):
        from lbscene.engine.scene.ir import IROccluder

        fx0, fx1, fy0, fy1 = _floor_bounds_mm(ir)
        cx, cy, ou, ov = cls.opening(ir, lighting)
        size = (fx1 - fx0, fy1 - fy0)
        occ = IROccluder(id=cls.OCCLUDER_ID, type="aperture_plate",
                         centre_mm=((fx0 + fx1) / 2, (fy0 + fy1) / 2, cls.plate_z_mm(ir, lighting)),
                         normal=(0.0, 0.0, -1.0), u_axis=(1.0, 0.0, 0.0), size_mm=size,
                         opening_mm=(min(ou, size[0]), min(ov, size[1])), lamps=None, material=None)
        # the opening's centre follows the lamps: the plate is re-centred on them
        occ = occ.model_copy(update={"centre_mm": (cx, cy, occ.centre_mm[2])})
        # a luminaire cavity is black inside: panels just inside the walls, plate to ceiling
        z0, z1 = occ.centre_mm[2], float(ir.interior.height_mm)
        zc, h = (z0 + z1) / 2, max(z1 - z0, 1.0)
        eps = 1.0
        sides = []
        if h > 1.0:
            for sid, c, n, u, w in (
                    ("left", (fx0 + eps, (fy0 + fy1) / 2, zc), (1.0, 0.0, 0.0), (0.0, 1.0, 0.0), fy1 - fy0),
                    ("right", (fx1 - eps, (fy0 + fy1) / 2, zc), (-1.0, 0.0, 0.0), (0.0, 1.0, 0.0), fy1 - fy0),
                    ("front", ((fx0 + fx1) / 2, fy0 + eps, zc), (0.0, 1.0, 0.0), (1.0, 0.0, 0.0), fx1 - fx0),
                    ("rear", ((fx0 + fx1) / 2, fy1 - eps, zc), (0.0, -1.0, 0.0), (1.0, 0.0, 0.0), fx1 - fx0)):
                sides.append(IROccluder(id=f"{cls.OCCLUDER_ID}_{sid}", type="panel", centre_mm=c, normal=n,
                                        u_axis=u, size_mm=(w - 2 * eps, h), opening_mm=None, lamps=None,
                                        material=None))
        hi_u = max(size[0] / occ.opening_mm[0], 1.05)
        hi_v = max(size[1] / occ.opening_mm[1], 1.05)
        free = [FreeParameter("effect.aperture_occlusion.opening_scale_u", (0.2, min(hi_u, 5.0)), 1.0),
                FreeParameter("effect.aperture_occlusion.opening_scale_v", (0.2, min(hi_v, 5.0)), 1.0)]
        return (ir.model_copy(update={"occluders": tuple(ir.occluders) + (occ, *sides)}),
                {"aperture_occlusion": {}}, free)

    @classmethod
    def starts(cls):
        u, v = "effect.aperture_occlusion.opening_scale_u", "effect.aperture_occlusion.opening_scale_v"
        return [{u: a, v: b} for a, b in APERTURE_STARTS]

    @classmethod
    def hardware_yaml(cls, ir, fit):
        o = next(x for x in ir.occluders if x.id == cls.OCCLUDER_ID)
        su = fit.values.get("effect.aperture_occlusion.opening_scale_u", 1.0)
        sv = fit.values.get("effect.aperture_occlusion.opening_scale_v", 1.0)
        ou = min(o.opening_mm[0] * su, o.size_mm[0])
        ov = min(o.opening_mm[1] * sv, o.size_mm[1])
        eu = fit.stderr.get("effect.aperture_occlusion.opening_scale_u")
        ev = fit.stderr.get("effect.aperture_occlusion.opening_scale_v")
        err = ""
        if eu is not None and ev is not None:
            err = f"   # ± [{_g(o.opening_mm[0] * eu)}, {_g(o.opening_mm[1] * ev)}] mm"
        c = o.centre_mm
        out = ("occluders:   # hypothesis: " + cls.summary + "; height assumed, opening fitted\n"
               f"  - {{id: {o.id}, type: aperture_plate, centre_mm: [{_g(c[0])}, {_g(c[1])}, {_g(c[2])}], "
               f"normal: [0, 0, -1], size_mm: [{_g(o.size_mm[0])}, {_g(o.size_mm[1])}], "
               f"opening_mm: [{_g(ou)}, {_g(ov)}]}}{err}\n")
        for p in ir.occluders:
            if p.id.startswith(cls.OCCLUDER_ID + "_"):
                q, n, u = p.centre_mm, p.normal, p.u_axis
                out += (f"  - {{id: {p.id}, type: panel, centre_mm: [{_g(q[0])}, {_g(q[1])}, {_g(q[2])}], "
                        f"normal: [{_g(n[0])}, {_g(n[1])}, {_g(n[2])}], u_axis: [{_g(u[0])}, {_g(u[1])}, "
                        f"{_g(u[2])}], size_mm: [{_g(p.size_mm[0])}, {_g(p.size_mm[1])}]}}   # black cavity side\n")
        return out


def filter_basis_on_knots(inner_nm) -> np.ndarray:
    """Cubic B-spline basis (471, len(inner_nm) + 2) on the 1 nm grid with the given interior
    knots (first and last: the ends of the measured range), held constant outside them."""
    from scipy.interpolate import BSpline

    deg = 3
    inner = np.asarray(inner_nm, float)
    t = np.concatenate([[inner[0]] * deg, inner, [inner[-1]] * deg])
    x = np.clip(_WL, inner[0], inner[-1] - 1e-9)
    return BSpline.design_matrix(x, t, deg).toarray()


def filter_basis(k: int = FILTER_BASIS, lo_nm: float = 380.0, hi_nm: float = 780.0) -> np.ndarray:
    """Cubic B-spline basis (471, k) on the 1 nm grid, uniform knots over ``lo_nm``–``hi_nm``
    (the range the white tile was measured over) and held constant outside it; the functions
    sum to 1 at every wavelength."""
    from scipy.interpolate import BSpline

    deg = 3
    inner = np.linspace(lo_nm, hi_nm, k - deg + 1)
    t = np.concatenate([[inner[0]] * deg, inner, [inner[-1]] * deg])
    x = np.clip(_WL, lo_nm, hi_nm - 1e-9)
    return BSpline.design_matrix(x, t, deg).toarray()


class _SpectralBase:
    """What a spectral hypothesis needs from a solved fit, computed once and shared by every
    spectral hypothesis tried on it: the groups' spectral irradiance at the readings and at the
    tile (at unit output), their illuminance and V(λ)."""

    def __init__(self, base: FitProblem, fit: FitResult):
        from lbscene.engine.light.forward import spectral_tables

        x_nl = [fit.values[base.free[i].target] for i in base.nl]
        fm, self.eff, self.lo = base.model(x_nl)
        pred = fm.predict(base.P, base.N, base.meter)
        self.V = spectral_tables(base.ir.grid)[0]
        lux = pred.lux_by_group()
        self.E = {g: pred.spectral_1nm({h: (1.0 if h == g else 0.0) for h in base.groups})
                  for g in base.groups}
        self.lux = {g: lux[g][: base.n_lux] for g in base.groups}
        self.EV = {g: self.E[g][: base.n_lux] @ self.V for g in base.groups}
        edges = base.tile_grid.edges_nm if base.tile_grid is not None else base.ir.grid.edges_nm
        used = np.nonzero(base.tile_mask)[0] if base.tile_mask is not None else np.zeros(0, int)
        lo, hi = (float(edges[used[0]]), float(edges[used[-1] + 1])) if used.size else (380.0, 780.0)
        self.range_nm = (max(lo, 380.0), min(hi, 780.0))
        #: the finest structure the tile data resolve: the width of the bands it is compared in
        self.resolution_nm = float(base.tile_grid.width_nm) if base.tile_grid is not None else 20.0

    @classmethod
    def of(cls, base: FitProblem, fit: FitResult) -> "_SpectralBase":
        sb = getattr(fit, "_spectral_base", None)
        if sb is None or sb[0] is not base:
            sb = (base, cls(base, fit))
            fit._spectral_base = sb
        return sb[1]


class _ReshapedProblem(FitProblem):
    """The groups' spectra of a solved fit, each times a fitted factor ``F_g(λ)`` (no forward
    model): exact for anything that multiplies the light of every path by a function of
    wavelength (a filter in front of the lamps, a lamp's own spectrum reshaped)."""

    def __init__(self, base: FitProblem, fit: FitResult, free_nl: list[FreeParameter]):
        self._base = base
        sb = self._sb = _SpectralBase.of(base, fit)
        self._range_nm = sb.range_nm
        lin = [fp for fp in base.free if fp.linear]
        # the base fit's nonlinear values become fixed: the factor is fitted on that fit
        super().__init__(base.meas, fit.effects, lin + list(free_nl), base.noise_percent,
                         base.spectral_noise_percent, {}, tolerance=base.tolerance)
        self._eff, self._lo = sb.eff, sb.lo

    def factors(self, values_nl) -> np.ndarray:
        """``(G, 471)``: the factor on each group's spectrum."""
        raise NotImplementedError

    def components(self, values_nl):
        key = tuple(float(v) for v in values_nl)
        if self._last is not None and self._last[0] == key:
            return self._last[1]
        F = self.factors(values_nl)
        b, sb = self._base, self._sb
        A = None
        if b.n_lux:
            A = np.stack([sb.lux[g] * np.divide(sb.E[g][: b.n_lux] @ (F[k] * sb.V), sb.EV[g],
                                                out=np.ones(b.n_lux), where=sb.EV[g] > 0)
                          for k, g in enumerate(b.groups)])
        T = T1 = None
        if b.tile_row is not None:
            refl = self.meas.tile.reflectance_1nm
            T1 = np.stack([sb.E[g][b.tile_row] * F[k] * refl / np.pi for k, g in enumerate(b.groups)])
            T = self.tile_grid.integrate(T1)
        out = (A, T, T1, self._eff, self._lo)
        self._last = (key, out)
        self.nfev += 1
        return out


class _FilteredProblem(_ReshapedProblem):
    """A transmittance :math:`T = \\exp(B b)` in front of every lamp on ``k`` B-splines."""

    def __init__(self, base: FitProblem, fit: FitResult, known: bool, k: int = FILTER_BASIS,
                 initial_log_1nm: np.ndarray | None = None, knots_nm=None):
        sb = _SpectralBase.of(base, fit)
        if knots_nm is None:
            knots_nm = np.linspace(sb.range_nm[0], sb.range_nm[1], k - 3 + 1)
        self.knots_nm = np.asarray(knots_nm, float)
        self._basis = filter_basis_on_knots(self.knots_nm)
        self._held = None if known else int(np.argmin(np.abs(
            (self._basis * _WL[:, None]).sum(0) / self._basis.sum(0) - 555.0)))
        b0 = np.zeros(self._basis.shape[1])
        if initial_log_1nm is not None:
            # start from a coarser solution, projected on this basis over the measured range
            m = (_WL >= sb.range_nm[0]) & (_WL <= sb.range_nm[1])
            b0 = np.linalg.lstsq(self._basis[m], initial_log_1nm[m], rcond=None)[0]
            if self._held is not None:
                b0 = b0 - b0[self._held]     # the basis sums to 1: a constant is the output scale
            b0 = np.clip(b0, FILTER_COEFF_BOUNDS[0] + 1e-6, FILTER_COEFF_BOUNDS[1] - 1e-6)
        coeffs = [FreeParameter(f"hypothesis.smooth_filter.b{j}", FILTER_COEFF_BOUNDS, float(b0[j]))
                  for j in range(self._basis.shape[1]) if j != self._held]
        super().__init__(base, fit, coeffs)

    def coefficients(self, values_nl) -> np.ndarray:
        b = list(values_nl)
        if self._held is not None:
            b.insert(self._held, 0.0)
        return np.asarray(b, float)

    def transmittance_1nm(self, values_nl) -> np.ndarray:
        return np.exp(self._basis @ self.coefficients(values_nl))

    def factors(self, values_nl) -> np.ndarray:
        return np.broadcast_to(self.transmittance_1nm(values_nl), (len(self._base.groups), _WL.size))

    def _jacobian(self, x, scales) -> np.ndarray:
        """∂r/∂b at fixed output scales, exact: :math:`∂T/∂b_j = T B_j`, and the readings and
        the tile bands are linear in :math:`T`."""
        b, sb = self._base, self._sb
        F = self.transmittance_1nm(x)
        Bf = self._basis if self._held is None else np.delete(self._basis, self._held, axis=1)
        FB = F[:, None] * Bf                                       # (471, K)
        rows = []
        if b.n_lux:
            y = self.meas.illuminance.lux
            J = 0.0
            for g in b.groups:
                w = np.divide(sb.lux[g], sb.EV[g], out=np.zeros(b.n_lux), where=sb.EV[g] > 0)
                J = J + scales[g] * (w[:, None] * (sb.E[g][: b.n_lux] @ (FB * sb.V[:, None])))
            rows.append(J / (y * self.sigma_e)[:, None])
        if b.tile_row is not None and self.tile_mask.any():
            m = self.tile_mask
            refl = self.meas.tile.reflectance_1nm
            Mi = self.tile_grid.integration_matrix[m]
            J = 0.0
            for g in b.groups:
                J = J + scales[g] * (Mi @ ((sb.E[g][b.tile_row] * refl / np.pi)[:, None] * FB))
            rows.append(J / (self.tile_meas[m] * self.sigma_s)[:, None])
        return np.concatenate(rows)

    def solve(self) -> FitResult:
        """Levenberg–Marquardt on the exact Jacobian (:meth:`_jacobian`, with the output scales'
        columns), the output scales solved linearly after every step; no finite differences."""
        lo = np.array([self.free[i].bounds[0] for i in self.nl], float)
        hi = np.array([self.free[i].bounds[1] for i in self.nl], float)
        x = np.clip(np.array([self.free[i].initial for i in self.nl], float), lo, hi)

        def state(x):
            A, T, *_ = self.components(x)
            sc = self.scales_for(A, T)
            r = self.residuals(x, sc)
            return sc, r, float(r @ r)

        sc, r, chi2 = state(x)
        mu, ok, msg = 1e-3, True, "converged"
        idx = [self.groups.index(g) for g in self.lin_groups]
        nb = len(x)
        for _ in range(FILTER_LM_ITERATIONS):
            # the output scales move with the coefficients: their columns join the Jacobian
            # (the step is taken jointly, the scales then solved again exactly)
            A, T, *_ = self.components(x)
            D, _t = self._design(A, T)
            J = np.hstack([self._jacobian(x, sc), D[:, idx]])
            H = J.T @ J
            gvec = J.T @ r
            improved = False
            for _try in range(12):
                Hd = H + mu * (np.diag(np.diag(H)) + 1e-9 * np.eye(len(H)))
                try:
                    step = np.linalg.solve(Hd, -gvec)[:nb]
                except np.linalg.LinAlgError:
                    mu *= 10.0
                    continue
                x2 = np.clip(x + step, lo, hi)
                sc2, r2, chi2b = state(x2)
                if chi2b < chi2:
                    improved = True
                    break
                mu *= 10.0
            if not improved:
                break
            done = chi2 - chi2b < 1e-6 * max(chi2, 1.0) + 1e-4
            x, sc, r, chi2 = x2, sc2, r2, chi2b
            mu = max(mu / 10.0, 1e-9)
            if done:
                break
        else:
            ok, msg = False, f"stopped after {FILTER_LM_ITERATIONS} iterations"
        self.components(x)
        self.solution = (x, sc, ok, msg)
        return self._result(x, sc, ok, msg, fitted=True)

    #: while the basis is searched, the standard errors (a finite-difference Jacobian over every
    #: coefficient) are skipped; the chosen fit gets them (:meth:`with_errors`)
    skip_errors = False

    def _errors(self, x_nl, scales, chi2, *, noise_limited: bool = False):
        if self.skip_errors:
            return {}, np.eye(len(self.free)), []
        return super()._errors(x_nl, scales, chi2, noise_limited=noise_limited)

    def with_errors(self) -> FitResult:
        """The solved fit again, with its standard errors."""
        self.skip_errors = False
        x, sc, ok, msg = self.solution
        return self._result(x, sc, ok, msg, fitted=True)


def filter_basis_sizes(range_nm: tuple[float, float], resolution_nm: float) -> list[int]:
    """The B-spline counts the filter's resolution is chosen among: :data:`FILTER_BASIS`
    halved and doubled, down to a knot spacing of the data's resolution (the instrument's
    sampling interval, or the bands the tile is compared in)."""
    span = max(range_nm[1] - range_nm[0], 1.0)
    k_max = int(span // max(resolution_nm, 1.0)) + 3
    out = [k for k in (6, FILTER_BASIS, 2 * FILTER_BASIS, 4 * FILTER_BASIS, 8 * FILTER_BASIS) if k < k_max]
    return out + [k_max]


def fit_filter_by_evidence(problem: FitProblem, fit: FitResult, known: bool):
    """The filter at the resolution the data choose, by BIC = χ² + k·ln n (n: every data value
    of the fit, as the diagnosis scores).

    First uniform knots, 6, 12, 24, … B-splines up to a spacing of the data's resolution, the
    one of least BIC kept (stopping once the BIC has risen twice); then knots are inserted
    where the tile's residual is largest — the midpoint of the worst knot interval, or of
    its neighbours — while an insertion lowers the BIC and the interval is wider than twice the
    data's resolution: a broad tint keeps a few coefficients, a narrow notch gets fine knots
    around it only.  Returns ``(problem, result, BIC by number of B-splines tried)``.
    """
    sb = _SpectralBase.of(problem, fit)
    logn = np.log(max(problem.n_residuals, 2))
    tried: dict[int, float] = {}

    def run(knots, init):
        fp = _FilteredProblem(problem, fit, known, initial_log_1nm=init, knots_nm=knots)
        fp.skip_errors = True
        res = fp.solve()
        bic = res.chi2 + len(fp.nl) * logn
        k = fp._basis.shape[1]
        tried[k] = min(bic, tried.get(k, np.inf))
        return fp, res, bic

    def log_t(fp, res):
        return np.log(fp.transmittance_1nm([res.values[fp.free[i].target] for i in fp.nl]))

    best, rises, prev, init = None, 0, None, None
    for k in filter_basis_sizes(sb.range_nm, sb.resolution_nm):
        fp, res, bic = run(np.linspace(sb.range_nm[0], sb.range_nm[1], k - 2), init)
        if best is None or bic < best[2]:
            best = (fp, res, bic)
        rises = rises + 1 if prev is not None and bic >= prev else 0
        if rises >= 2:
            break
        prev = bic
        init = log_t(fp, res)
    # local refinement where the residual is
    for _round in range(FILTER_MAX_INSERTIONS):
        fp, res, bic = best
        knots = fp.knots_nm
        r = res.spectral_residual_percent
        if r is None:
            break
        c = problem.tile_grid.centres_nm
        ok = np.isfinite(r)
        interval = np.clip(np.searchsorted(knots, c[ok]) - 1, 0, len(knots) - 2)
        bad = np.bincount(interval, weights=r[ok] ** 2, minlength=len(knots) - 1)
        order = [int(i) for i in np.argsort(-bad)]
        wide = [i for i in order if knots[i + 1] - knots[i] >= 2 * sb.resolution_nm][:2]
        improved = None
        for i in wide:
            cand = np.sort(np.append(knots, 0.5 * (knots[i] + knots[i + 1])))
            out = run(cand, log_t(fp, res))
            if out[2] < bic and (improved is None or out[2] < improved[2]):
                improved = out
        if improved is None:
            break
        best = improved
    return best[0], best[0].with_errors(), tried


class _AgedProblem(_ReshapedProblem):
    """Each lamp group's spectrum shifted and tilted at its declared luminous output
    (:func:`~lbscene.engine.light.effects.builtin.lamp_spectrum_shift.aged_spectrum_1nm`):
    the factor on group ``g`` is :math:`S_{a,g}(λ) / S_g(λ)` (the group's lamps summed)."""

    def __init__(self, base: FitProblem, fit: FitResult):
        from lbscene.engine.light.effects.builtin.lamp_spectrum_shift import LampSpectrumShiftEffect

        lamps = _lamps_on(base.ir, base.lighting)
        self._S = np.stack([sum(np.asarray(lp.peak_intensity_1nm, float) for lp in lamps if lp.group == g)
                            for g in base.groups])
        fps = LampSpectrumShiftEffect.fit_parameters
        init = LampSpectrumShiftEffect.fit_initial
        free = [FreeParameter(f"effect.{LampAgeingHypothesis.effect}.{n}", tuple(b), float(init.get(n, 0.0)))
                for n, b in fps.items()]
        super().__init__(base, fit, free)

    def factors(self, values_nl) -> np.ndarray:
        from lbscene.engine.light.effects.builtin.lamp_spectrum_shift import aged_spectrum_1nm

        shift, tilt = (float(v) for v in values_nl)
        out = np.ones_like(self._S)
        for k, S in enumerate(self._S):
            ok = S > 1e-9 * S.max() if S.max() > 0 else np.zeros(S.shape, bool)
            out[k, ok] = aged_spectrum_1nm(S, shift, tilt)[ok] / S[ok]
        return out


def _reshaped_result(fp: _ReshapedProblem, res: FitResult, fit: FitResult) -> FitResult:
    # the parameters held from the fit it was added to keep their values
    res.values = {**fit.values, **res.values}
    return res


class SmoothFilterHypothesis(Hypothesis):
    id = "smooth_filter"
    effect = "spectral_filter"
    channel = "spectral"
    summary = "a spectral filter in front of the lamps"

    @classmethod
    def declared(cls, ir, lighting):
        if any(lp.filter for lp in _lamps_on(ir, lighting)):
            return "the lamps that are on name a filter (the spectral_filter effect tests it)"
        return None

    @classmethod
    def fit_on(cls, problem, fit, known):
        if problem.tile_row is None:
            return None
        fp, res, tried = fit_filter_by_evidence(problem, fit, known)
        x = [res.values[fp.free[i].target] for i in fp.nl]
        T = fp.transmittance_1nm(x)
        # σ of log T from the coefficients' covariance
        idx = [i for i in fp.nl]
        se = np.array([res.stderr.get(fp.free[i].target, 0.0) for i in idx])
        C = res.correlation[np.ix_(idx, idx)] * np.outer(se, se) if se.size else np.zeros((0, 0))
        B = fp._basis if fp._held is None else np.delete(fp._basis, fp._held, axis=1)
        sig = np.sqrt(np.clip(np.einsum("ij,jk,ik->i", B, C, B), 0, None)) if se.size else np.zeros_like(T)
        k = fp._basis.shape[1]
        res.hypothesis_data = {"transmittance_1nm": T, "log_sigma_1nm": sig, "known": known,
                               "range_nm": fp._range_nm, "basis_size": k, "knots_nm": fp.knots_nm,
                               "knot_spacing_nm": float(np.diff(fp.knots_nm).min()),
                               "resolution_nm": fp._sb.resolution_nm, "bic_by_basis_size": tried}
        # the parameters held from the fit it was added to keep their values
        res.values = {**fit.values, **res.values}
        # the fitted filter as booth hardware: the booth of this explanation, for whoever
        # predicts with it (plan)
        from lbscene.engine.scene.ir import IRFilter, IRSpectrum

        base_ir = getattr(fit, "ir", None) or problem.ir
        filt = IRFilter(id=FITTED_FILTER_ID, transmittance=IRSpectrum.from_1nm(T, base_ir.grid))
        res.ir = base_ir.model_copy(update={"filters": {**base_ir.filters, FITTED_FILTER_ID: filt}})
        res.effects = {**res.effects, cls.effect: {"filter": FITTED_FILTER_ID}}
        return res

    @classmethod
    def effect_entry(cls, fit):
        return {"filter": FITTED_FILTER_ID}

    @classmethod
    def hardware_yaml(cls, ir, fit):
        h = fit.hypothesis_data
        T, sig = h["transmittance_1nm"], h["log_sigma_1nm"]
        note = ""
        if not h["known"]:
            T = T / T.max()
            note = " (normalised to a maximum of 1: the lamp output is fitted)"
        elif T.max() > 1.0:
            note = (f" (peaks at {T.max():.3g} > 1: the lamps emit more than declared; "
                    "clipped to 1)")
            T = np.minimum(T, 1.0)
        # written as finely as the filter was resolved (the data's sampling for a narrow notch)
        step = 10 if h.get("knot_spacing_nm", 40.0) >= 20.0 else max(1, int(round(h.get("resolution_nm", 5.0))))
        wl = np.arange(380, 781, step)
        t = np.interp(wl, _WL, T)
        s = np.interp(wl, _WL, T * sig)
        lo, hi = h.get("range_nm", (380.0, 780.0))
        res_note = (f"; {h['basis_size']} B-splines, knots {h['knot_spacing_nm']:.0f} nm apart at the "
                    "finest (chosen by BIC)" if "basis_size" in h else "")
        return (f"filters:   # hypothesis: {cls.summary}; transmittance fitted to the white-tile "
                f"spectrum{note}; measured {lo:.0f}–{hi:.0f} nm, held constant outside{res_note}\n"
                f"  {FITTED_FILTER_ID}:\n"
                "    transmittance: {type: inline, wavelengths_nm: [" + ", ".join(str(int(w)) for w in wl) +
                "],\n                    values: [" + ", ".join(f"{v:.3f}" for v in np.clip(t, 0, 1)) + "]}\n"
                "    # standard uncertainty: [" + ", ".join(f"{v:.3f}" for v in s) + "]\n")


class LampAgeingHypothesis(Hypothesis):
    """The lamps' spectrum aged: shifted and tilted at the declared luminous output, both fitted
    on the white tile.  Not hardware: tried whenever the booth does not enable the effect."""

    id = "lamp_ageing"
    effect = "lamp_spectrum_shift"
    channel = "spectral"
    summary = "the lamps' spectrum shifted and tilted (ageing) at the declared output"
    hardware = False

    @classmethod
    def declared(cls, ir, lighting):
        return None

    @classmethod
    def fit_on(cls, problem, fit, known):
        if problem.tile_row is None:
            return None
        fp = _AgedProblem(problem, fit)
        res = _reshaped_result(fp, fp.solve(), fit)
        res.hypothesis_data = {"known": known}
        res.effects = {**res.effects, cls.effect: cls.effect_entry(res)}
        return res

    @classmethod
    def effect_entry(cls, fit):
        return {n: float(fit.values[f"effect.{cls.effect}.{n}"]) for n in ("shift_nm", "tilt")
                if f"effect.{cls.effect}.{n}" in fit.values}

    @classmethod
    def hardware_yaml(cls, ir, fit):
        return ""


#: hypothesis id → class
HYPOTHESES: dict[str, type[Hypothesis]] = {
    h.id: h for h in (DiffuserPlateHypothesis, AperturePlateHypothesis, SmoothFilterHypothesis,
                      LampAgeingHypothesis)}


def applicable_hypotheses(ir, lighting: str) -> tuple[list[type[Hypothesis]], dict[str, str]]:
    """Hypotheses that can be tried on this booth, and why the others cannot."""
    todo, skipped = [], {}
    for h in HYPOTHESES.values():
        why = h.applicable(ir, lighting)
        (skipped.__setitem__(h.id, why) if why else todo.append(h))
    return todo, skipped
