"""
Hypotheses for hardware the booth file does not declare.

A catalog effect models hardware the booth declares: the ``diffuser`` effect needs a
``diffuser:`` section, ``aperture_occlusion`` its ``occluders:``, ``spectral_filter`` a
``filters:`` entry.  When the file has none, the diagnosis still asks whether such hardware
would explain the measurements.  A *hypothesis* adds the hardware to a copy of the compiled
booth, where and as large as the lamps and the interior suggest, fits the properties the data
can pin down together with the booth's own free parameters, and writes the result as booth
YAML (hardware section plus its ``effects:`` entry) that validates and compiles.

=======================  =========================  ========  ========================================
hypothesis               effect it turns on         channel   what is fitted
=======================  =========================  ========  ========================================
``diffuser_plate``       ``diffuser``               spatial   a plate below the lowest lamp, over the
                                                              interior less :data:`MARGIN_MM`: its
                                                              type (opal: a Lambertian part, its
                                                              diffuse fraction fitted; or rough
                                                              glass, its GGX roughness profiled), its
                                                              height (profiled), and its
                                                              transmittance when the lamp output is
                                                              declared known
``aperture_plate``       ``aperture_occlusion``     spatial   a black luminaire cavity: a plate over
                                                              the interior below the lowest lamp,
                                                              black panels from it to the ceiling,
                                                              and a rectangular opening around the
                                                              lamps' footprint: the plate's height,
                                                              the opening across the tubes and the
                                                              ceiling's reflectance inside
                                                              (profiled), the opening along them
``mirror``               ``reflector``              spatial   a plane mirror with every lamp that is
                                                              on, above it facing down or behind it
                                                              facing the room (a choice): its
                                                              distance from the lamp axis
                                                              (profiled), its width across the
                                                              lamp (profiled), its reflectance
``ceiling_reflectance``  ``surface_reflectance``    spatial   the ceiling's reflectance
``walls_reflectance``    ``surface_reflectance``    spatial   the side and rear walls' reflectance
``smooth_filter``        ``spectral_filter``        spectral  a transmittance in front of every lamp,
                                                              :math:`T(λ) = \\exp \\sum_k b_k B_k(λ)`
                                                              on cubic B-splines over the measured
                                                              range, as many as the BIC chooses (knots
                                                              down to the tile's sampling), with its
                                                              uncertainty
``lamp_ageing``          ``lamp_spectrum_shift``    spectral  each lamp's spectrum shifted, tilted and
                                                              curved at its declared luminous output:
                                                              the shift, tilt and curvature (not
                                                              hardware: always tried)
=======================  =========================  ========  ========================================

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

Profiled properties
-------------------
Some properties change the booth itself, not a parameter of an effect: a plate's height, a
cavity's interior reflectance, a mirror's distance, a surface's reflectance.  A hypothesis lists
them as :class:`GeometryParameter` s and :func:`profile_geometry` fits them by profiling: the
whole refit (every free parameter of the booth and of the hypothesis) is repeated on booths
with the property at the values of a coarse grid, one property after the other, and a parabola
through the three best values of the refit's :math:`χ^2` gives the estimate and its standard
uncertainty,

.. math::

    χ^2(θ) \\approx a\\,(θ - \\hat θ)^2 + χ^2_\\text{min}, \\qquad
    σ_θ = \\sqrt{\\frac{\\max(1, χ^2_\\text{min}/ν)}{a}} ,

the profile likelihood's curvature (:math:`Δχ^2 = 1` at one standard uncertainty), inflated by
the reduced :math:`χ^2` where the model leaves more than the noise; at an end of the grid (a
black interior, say) it is one-sided, :math:`σ_θ = \\max(1, χ^2_\\text{min}/ν)\\,|Δθ/Δχ^2|` to
the neighbouring value.  That uncertainty is conditional on the other profiled properties at
their fitted values: where two properties trade off (a higher plate with a smaller opening
casts nearly the same shadow) it understates the uncertainty, so each pair is also profiled
jointly (:func:`joint_profile`: a quadratic in both through the refits around the optimum) and
the larger, marginal uncertainty is given, with the pair's correlation; a pair along which
:math:`χ^2` has no minimum is an unidentified combination.  A profile without curvature
(:math:`a \\le 0`, or :math:`σ_θ` larger than the grid's span) means the readings cannot tell the
property: the written YAML says so.  Each profiled property counts as one parameter in the
diagnosis' BIC when the readings pin it (a flat profile changes no prediction).

The hardware is written as booth YAML sections to *merge* into the booth file
(:func:`paste_hardware`): mappings (``materials:``, ``surfaces:``, ``reflectors:``) add or
replace keys, lists of items with an ``id`` (``occluders:``, ``lamps:``) add items or update the
item with that id, and ``effects:`` (the whole list, as the diagnosis suggests it) replaces the
booth's.

References
----------
Kass, R. E., Raftery, A. E. (1995). Bayes factors. *Journal of the American Statistical
Association* 90 (430), 773–795 (the BIC scale the diagnosis scores hypotheses on).
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from dataclasses import dataclass, replace
from typing import ClassVar, Literal

import numpy as np

from lbscene.engine.files.parallel import map_forked

from .fit import FitProblem, FitResult, FreeParameter, consistent_with_noise

__all__ = [
    "Hypothesis",
    "PlateHypothesis",
    "DiffuserPlateHypothesis",
    "AperturePlateHypothesis",
    "SmoothFilterHypothesis",
    "LampAgeingHypothesis",
    "MirrorHypothesis",
    "SurfaceReflectanceHypothesis",
    "CeilingReflectanceHypothesis",
    "WallsReflectanceHypothesis",
    "GeometryParameter",
    "profile_geometry",
    "joint_profile",
    "paste_hardware",
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
#: an undeclared opening's extent across the tubes, profiled: these multiples of the lamps'
#: footprint plus :data:`OPENING_MARGIN_MM`
OPENING_SCALES = (0.8, 1.0, 1.25, 1.55, 1.9)
#: GGX roughness of a hypothesised rough glass plate, profiled, and its refractive index
PLATE_ROUGHNESSES = (0.05, 0.1, 0.2, 0.35, 0.5)
ROUGH_PLATE_IOR = 1.5
#: a hypothesised opal plate's faces, profiled: polished, at the index of its acrylic, or
#: neither reflecting nor refracting (index 1: a matte or index-matched face, the scattering
#: layer's light leaving as it arrives at the face); they set the angle its scattered light
#: leaves at for the same declared total and diffuse fraction
OPAL_PLATE_IOR = 1.49
#: a rough plate's fitted Lambertian part below this is written as none
ROUGH_DIFFUSE_MIN = 0.02
#: Δχ² between opal and rough glass below which the plate's type is said not to be identified
TYPE_DCHI2 = 10.0
#: a jointly refitted inter-reflection scale farther than this from 1 is written into the other
#: surfaces' materials by a surface hypothesis (the booth then predicts what the fit did)
JOINT_SCALE_MIN = 0.005
BOX_SURFACE_ROLES = ("floor", "ceiling", "left_wall", "right_wall", "rear_wall", "front_wall")
#: sweeps over the profiled properties, one after the other (fewer when a sweep changes nothing)
PROFILE_SWEEPS = 2
#: gaps (mm) between the lamps' lowest point and a hypothesised plate, profiled
PLATE_GAPS_MM = (5.0, 20.0, 45.0, 80.0, 130.0)
#: the cavity's inside (the ceiling over its plate), profiled: these fractions of the declared
#: ceiling reflectance
INTERIOR_SCALES = (0.0, 0.5, 1.0)
#: distances (mm) from the lamp axis to a hypothesised mirror above or behind it, profiled.  Once
#: the mirrors took part in the inter-reflection, the fit's χ² along the distance had narrow
#: minima (a 90 mm strip 40 mm behind a tube: 0.9 % RMS at 40 mm, 1.3 % at 30 and 35, 3.1 % at
#: 50): a 10 mm step where mirrors sit, against (20, 35, 60, 100) before
MIRROR_DISTANCES_MM = (20.0, 30.0, 40.0, 50.0, 60.0, 80.0, 100.0)
#: reflectances of a surface hypothesised to differ from its declared material, profiled
SURFACE_REFLECTANCES = (0.03, 0.15, 0.35, 0.6, 0.85)
#: id of the fitted mirror, and of the fitted materials, in the written YAML
FITTED_MIRROR_ID = "fitted_mirror"
#: widths (mm) of a hypothesised mirror across the lamp axis, profiled (those that fit: a mirror
#: above a lamp no wider than the room to its neighbours and the walls, one behind it no taller
#: than twice the room between the lamp and the ceiling)
MIRROR_WIDTHS_MM = (40.0, 60.0, 90.0, 130.0, 200.0)
#: the width a hypothesised mirror is built with before its width is profiled
MIRROR_WIDTH_MM = 90.0
CAVITY_MATERIAL_ID = "cavity_interior"


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


@dataclass(frozen=True)
class GeometryParameter:
    """A property of hypothesised hardware fitted by profiling (:func:`profile_geometry`).

    ``name`` carries its unit (``gap_mm``); ``grid`` are the values tried (ascending),
    ``initial`` the value :meth:`Hypothesis.augment` builds the booth with, ``bounds`` where an
    interpolated optimum may lie."""

    name: str
    grid: tuple[float, ...]
    initial: float
    bounds: tuple[float, float]
    #: a choice among the grid's values (no interpolation, no uncertainty: the χ² of each
    #: choice is kept instead)
    categorical: bool = False


def _constant_material(ir, mid: str, value: float):
    """A diffuse material ``mid`` of constant reflectance ``value``."""
    from lbscene.engine.scene.ir import IRMaterial, IRSpectrum

    return IRMaterial(id=mid, type="diffuse", reflectance=IRSpectrum.from_1nm(np.full(_WL.size, value), ir.grid))


def _with_surface_material(ir, roles, mat):
    """``ir`` with material ``mat`` added and given to the surfaces of ``roles``."""
    surf = tuple(s.model_copy(update={"material": mat.id}) if s.role in roles else s for s in ir.surfaces)
    return ir.model_copy(update={"materials": {**ir.materials, mat.id: mat}, "surfaces": surf})


def _mean_reflectance(ir, roles) -> float | None:
    """Mean (area-weighted) visible reflectance of the surfaces of ``roles``; None if none."""
    w = [(s.area_mm2(), float(np.mean(ir.materials[s.material].reflectance.array_1nm[40:341])))
         for s in ir.surfaces if s.role in roles]
    if not w or sum(a for a, _ in w) <= 0:
        return None
    return sum(a * r for a, r in w) / sum(a for a, _ in w)


def profile_geometry(H, ir, lighting: str, solve_on, fit, problem, problem_on=None):
    """Fit ``H``'s :class:`GeometryParameter` s by profiling the refit over them.

    Parameters
    ----------
    H : type[Hypothesis]
        The hypothesis; ``ir`` is the booth :meth:`Hypothesis.augment` built (its properties at
        their ``initial`` values), ``fit`` and ``problem`` the refit on it.
    solve_on : callable
        ``solve_on(ir, start) -> (FitProblem, FitResult)``: the same refit on another booth,
        started from the parameter values of the fit ``start`` (the profile passes ``fit``:
        starting each point from its neighbour's optimum instead changed the path of the
        profiles along the step-like χ² of an opening, and with it their cost and verdicts'
        shares).  The fit may be returned without its standard errors
        (``FitResult.errors_pending``): only the one kept needs them, and ``problem.add_errors``
        adds them.
    problem_on : callable, optional
        ``problem_on(ir, start) -> FitProblem``: the problem ``solve_on`` solves, unsolved.  With
        it the refits of a profile's points run side by side in forked processes
        (:func:`~lbscene.engine.files.parallel.map_forked`: each point's refit is the same,
        started from ``fit`` whichever runs first) and the problem of each point is made here.

    Returns
    -------
    ir, fit, problem, n : the booth at the fitted values, its refit and problem, and the number
        of profiled parameters the readings pin (finite uncertainty; a choice whose χ² differ
        by more than 1).  The fit's ``values`` / ``stderr`` gain
        ``hypothesis.<id>.<name>``; ``hypothesis_data["geometry"][<id>]`` maps each name to
        ``(value, stderr or None)`` (None: the readings cannot tell it).
    """
    params = H.geometry(ir, lighting)
    if not params:
        return ir, fit, problem, 0
    values = {p.name: float(p.initial) for p in params}
    seen = {}

    def key(v):
        return tuple(round(float(v[p.name]), 6) for p in params)

    seen[key(values)] = (ir, problem, fit)

    span = {p.name: max(float(p.grid[-1]) - float(p.grid[0]), 1e-9) for p in params}

    def at(v):
        k = key(v)
        if k not in seen:
            ir_v = H.regeometry(ir, lighting, v)
            seen[k] = (ir_v, *solve_on(ir_v, fit))
        return seen[k]

    def prefetch(vs):
        # the points a step of the profile compares, refitted side by side
        todo = {}
        for v in vs:
            if key(v) not in seen:
                todo.setdefault(key(v), v)
        if problem_on is None or len(todo) < 2:
            return
        irs = [H.regeometry(ir, lighting, v) for v in todo.values()]
        fits = map_forked(lambda ir_v: solve_on(ir_v, fit)[1], irs)
        for k, ir_v, f in zip(todo, irs, fits):
            seen[k] = (ir_v, problem_on(ir_v, fit), f)

    sig: dict[str, float | None] = {}
    choices: dict[str, dict[float, float]] = {}
    edge: set[str] = set()              # optimum at an end of its grid (one-sided uncertainty)
    for sweep in range(PROFILE_SWEEPS):
        before = dict(values)
        for p in params:
            if sweep and len(params) == 1:
                break
            if not getattr(H, "profiled", lambda *_: True)(p.name, values):
                sig.setdefault(p.name, None)
                continue
            xs = np.array(sorted(set(p.grid) | {values[p.name]}), float)
            partner = next((q for q in params if q.name == H.categorical_partner(p.name)), None) \
                if p.categorical and not sweep else None
            if partner is not None:
                # each choice at its own best value of the property it decides the meaning of
                # (a mirror behind the lamps at its best distance against one above at its)
                ys = sorted(set(partner.grid) | {values[partner.name]})
                prefetch([{**values, p.name: float(x), partner.name: float(y)} for x in xs for y in ys])
                best_y, chi = [], []
                for x in xs:
                    c = [at({**values, p.name: float(x), partner.name: float(y)})[2].chi2 for y in ys]
                    best_y.append(float(ys[int(np.argmin(c))]))
                    chi.append(min(c))
                chi = np.array(chi)
                j = int(np.argmin(chi))
                values[partner.name] = best_y[j]
            elif p.categorical:
                # each choice at its best of the choices only it has (an opal plate at its better
                # faces against a rough one): the faces kept from another choice decided the type
                # by a χ² unit where the better faces fitted by 30
                own = [({**values, p.name: float(x)}, _own_choices(H, params, p, xs, {**values, p.name: float(x)}))
                       for x in xs]
                prefetch([{**v, **sv} for v, svs in own for sv in svs])
                chi, subs = [], []
                for v, svs in own:
                    c = [(at({**v, **sv})[2].chi2, sv) for sv in svs]
                    c_min, sv = min(c, key=lambda t: t[0])
                    chi.append(c_min)
                    subs.append(sv)
                chi = np.array(chi)
                j = int(np.argmin(chi))
                values.update(subs[j])
            else:
                prefetch([{**values, p.name: float(x)} for x in xs])
                chi = np.array([at({**values, p.name: float(x)})[2].chi2 for x in xs])
                j = int(np.argmin(chi))
            if p.categorical:
                values[p.name] = float(xs[j])
                sig[p.name] = None
                choices[p.name] = {float(x): float(c) for x, c in zip(xs, chi)}
                continue
            lo = max(0, min(j - 1, len(xs) - 3))
            a, b, _ = np.polyfit(xs[lo:lo + 3], chi[lo:lo + 3], 2) if len(xs) >= 3 else (0.0, 0.0, 0.0)
            best = float(xs[j])
            if a > 0 and 0 < j < len(xs) - 1:
                xv = float(np.clip(-b / (2 * a), *p.bounds))
                if xs[j - 1] < xv < xs[j + 1] and abs(xv - best) > 1e-6 * (xs[-1] - xs[0]):
                    if at({**values, p.name: xv})[2].chi2 < chi[j]:
                        best = xv
            values[p.name] = best
            fb = at(values)[2]
            infl = max(1.0, fb.chi2 / max(fb.dof, 1))
            if a > 0 and 0 < j < len(xs) - 1:
                s = math.sqrt(infl / a)
            else:
                # optimum at the grid's end: one-sided, from the rise to its neighbour
                n = 1 if j == 0 else len(xs) - 2
                rise = abs(chi[n] - chi[j]) / abs(xs[n] - xs[j]) if len(xs) > 1 else 0.0
                s = infl / rise if rise > 0 else None
            sig[p.name] = s if s is not None and s < (xs[-1] - xs[0]) else None
            if 0 < j < len(xs) - 1:
                edge.discard(p.name)
            else:
                edge.add(p.name)
        if values == before:
            break
    # the parameters the readings pin count in the BIC; a flat profile (a height or a type the
    # data cannot tell) changes no prediction and costs nothing (decided on the 1-D profiles)
    pinned = sum(1 for p in params if (sig.get(p.name) is not None) or (
        p.categorical and len(choices.get(p.name, {})) > 1 and
        max(choices[p.name].values()) - min(choices[p.name].values()) > 1.0))
    fb = at(values)[2]
    joint = joint_profile([p for p in params if p.name not in edge], values, sig, seen, at,
                          max(1.0, fb.chi2 / max(fb.dof, 1)))
    for (a, b), j in joint.items():
        # the marginal uncertainty where two properties trade off: the wider of the two
        for n in (a, b):
            if sig[n] is not None:
                sig[n] = None if j["sigma"][n] is None or j["sigma"][n] >= span[n] else max(sig[n], j["sigma"][n])
    ir_b, prob_b, fit_b = at(values)
    if getattr(fit_b, "errors_pending", False):
        fit_b = prob_b.add_errors(fit_b)
    for n, v in values.items():
        fit_b.values[f"hypothesis.{H.id}.{n}"] = v
        if sig[n] is not None:
            fit_b.stderr[f"hypothesis.{H.id}.{n}"] = sig[n]
    hd = dict(getattr(fit_b, "hypothesis_data", None) or {})
    hd["geometry"] = {**hd.get("geometry", {}), H.id: {n: (values[n], sig[n]) for n in values}}
    hd["choices"] = {**hd.get("choices", {}), H.id: choices}
    hd["joint"] = {**hd.get("joint", {}), H.id: {f"{a}|{b}": j for (a, b), j in joint.items()}}
    fit_b.hypothesis_data = hd
    return ir_b, fit_b, prob_b, pinned


def _own_choices(H, params, p, xs, values) -> list[dict[str, float]]:
    """The combinations of the categorical properties that matter at ``values`` but not at every
    choice ``xs`` of ``p`` (a plate's faces matter for opal, not for rough glass): ``[{}]`` for
    none."""
    own = [q for q in params if q is not p and q.categorical
           and getattr(H, "profiled", lambda *_: True)(q.name, values)
           and not all(getattr(H, "profiled", lambda *_: True)(q.name, {**values, p.name: float(x)}) for x in xs)]
    out: list[dict[str, float]] = [{}]
    for q in own:
        out = [{**d, q.name: float(y)} for d in out for y in sorted(set(q.grid) | {values[q.name]})]
    return out


#: refits nearest the optimum (in conditional standard uncertainties) a pair's joint quadratic
#: is fitted to
JOINT_POINTS = 9


def _diagonal_cross_term(a, b, values, sa, sb, byname, at, infl) -> float | None:
    """The cross term :math:`c` of :math:`Δχ^2 \\approx \\mathrm{infl}\\,(u^2 + 2 c\\,u v + v^2)`
    (units of the conditional uncertainties, the axes' curvature the 1-D profiles') from the
    refits at both diagonals :math:`(±1, +1)`, least squares; None when neither can be refitted
    inside the bounds.  :math:`|c| \\ge 1`: a ridge; else the pair's correlation is :math:`-c`."""
    best = float(at(values)[2].chi2)
    num = den = 0.0
    for sign in (1.0, -1.0):
        ta = float(np.clip(values[a] + sign * sa, *byname[a].bounds))
        tb = float(np.clip(values[b] + sb, *byname[b].bounds))
        u, w = (ta - values[a]) / sa, (tb - values[b]) / sb
        if abs(u * w) < 1e-9:
            continue
        y = (float(at({**values, a: ta, b: tb})[2].chi2) - best) / infl - u * u - w * w
        num += y * 2.0 * u * w
        den += 4.0 * u * u * w * w
    return num / den if den > 0 else None


def joint_profile(params, values, sig, seen, at, infl) -> dict:
    """Joint uncertainty of each pair of profiled properties the 1-D profiles pin.

    The 1-D profile of a property holds the others at their fitted values: where two trade off
    (a higher plate with a smaller opening casts nearly the same shadow) its curvature
    understates the uncertainty.  For each pair :math:`(θ_a, θ_b)`, in units of their
    conditional uncertainties :math:`u = (θ_a - \\hat θ_a)/σ_a`, :math:`v = (θ_b - \\hat θ_b)/σ_b`,
    a quadratic is fitted to the refits' :math:`χ^2` at the :data:`JOINT_POINTS` profile points
    nearest the optimum with the other properties at their fitted values (one diagonal point is
    refitted when the profile left none off the axes),

    .. math::

        χ^2(u, v) \\approx c + g^\\mathsf{T} x + \\tfrac12 x^\\mathsf{T} \\mathbf H x, \\qquad
        Σ = 2 \\max(1, χ^2_\\text{min}/ν)\\,\\mathbf H^{-1},

    and the marginal uncertainties are :math:`σ_a \\sqrt{Σ_{uu}}`, :math:`σ_b \\sqrt{Σ_{vv}}`,
    their correlation :math:`ρ = Σ_{uv}/\\sqrt{Σ_{uu} Σ_{vv}}`.  A Hessian that is not
    positive definite, or whose marginal uncertainty exceeds a bound's range, is a ridge — unless
    the nearest refits lie where :math:`χ^2` is no quadratic (a minimum sharper than their
    spacing, a mirror's distance): then the axes' curvature of the 1-D profiles with the cross
    term of the refits at both diagonals (:func:`_diagonal_cross_term`) decides, and a pair whose
    cross term is under one in size gets its marginal uncertainties from that quadratic
    (``from_axes``).  A ridge is an unidentified combination (``sigma`` None).  ``range`` gives
    each property's extent in the region the quadratic allows within the bounds, :math:`χ^2 - χ^2_\\text{min} \\le 4
    \\max(1, χ^2_\\text{min}/ν)` (about two standard uncertainties); for a ridge, the extent of
    the refits themselves within that :math:`Δχ^2` of the best.  Properties whose optimum lies at an end of
    their grid (one-sided uncertainty) are left out by :func:`profile_geometry`.

    Returns
    -------
    dict : ``(a, b)`` → ``{"rho": ρ or None, "sigma": {a: σ or None, b: σ or None}[, "range":
    {a: (lo, hi), b: (lo, hi)}][, "sharp": True]}``; ``sharp``: no quadratic, but no refit other
    than the best within :math:`Δχ^2 = 4\\max(1, χ^2_\\text{min}/ν)`: a minimum sharper than the
    refits are spaced, the 1-D uncertainties kept.
    """
    names = [p.name for p in params if not p.categorical and sig.get(p.name) is not None]
    byname = {p.name: p for p in params}
    out = {}
    for i, a in enumerate(names):
        for b in names[i + 1:]:
            sa, sb = float(sig[a]), float(sig[b])

            def local():
                pts = []
                for k, (_, _, f) in seen.items():
                    v = dict(zip([p.name for p in params], k))
                    if any(abs(v[n] - round(float(values[n]), 6)) > 1e-9 for n in v if n not in (a, b)):
                        continue
                    pts.append(((v[a] - values[a]) / sa, (v[b] - values[b]) / sb, float(f.chi2)))
                pts = np.array(pts, float).reshape(-1, 3)
                return pts[np.argsort(pts[:, 0] ** 2 + pts[:, 1] ** 2)[:JOINT_POINTS]]

            pts = local()
            if not np.any((np.abs(pts[:, 0]) > 1e-9) & (np.abs(pts[:, 1]) > 1e-9)):
                # one refit off the axes gives the cross term (the axes give the rest)
                ta = float(np.clip(values[a] + sa, *byname[a].bounds))
                tb = float(np.clip(values[b] + sb, *byname[b].bounds))
                at({**values, a: ta, b: tb})
                pts = local()
            u, w, c = pts.T
            X = np.stack([np.ones_like(u), u, w, u * u, u * w, w * w], axis=1)
            if len(pts) < 6 or np.linalg.matrix_rank(X) < 6:
                continue
            coef, *_ = np.linalg.lstsq(X, c, rcond=None)
            # the region the readings allow (Δχ² ≤ 4 infl on the quadratic, ≈ 2 σ) within the
            # properties' bounds: its extent in each
            lo_a, hi_a = byname[a].bounds
            lo_b, hi_b = byname[b].bounds
            U, W = np.meshgrid(np.linspace((lo_a - values[a]) / sa, (hi_a - values[a]) / sa, 201),
                               np.linspace((lo_b - values[b]) / sb, (hi_b - values[b]) / sb, 201), indexing="ij")
            q = coef[3] * U * U + coef[4] * U * W + coef[5] * W * W + coef[1] * U + coef[2] * W

            def extent(ok):
                # each property's extent over the region ``ok`` of the (U, W) mesh
                return {a: (float(values[a] + sa * U[ok].min()), float(values[a] + sa * U[ok].max())),
                        b: (float(values[b] + sb * W[ok].min()), float(values[b] + sb * W[ok].max()))}

            rng = extent(q <= q.min() + 4.0 * infl)
            Hm = np.array([[2 * coef[3], coef[4]], [coef[4], 2 * coef[5]]])
            S = 2.0 * infl * np.linalg.inv(Hm) if Hm[0, 0] > 0 and np.linalg.det(Hm) > 0 else None
            if S is None or sa * math.sqrt(S[0, 0]) >= hi_a - lo_a or sb * math.sqrt(S[1, 1]) >= hi_b - lo_b:
                # a ridge (or a saddle: the quadratic says nothing there): the refits themselves
                # within Δχ² = 4 infl of the best give the values the readings allow
                near = pts[pts[:, 2] <= pts[:, 2].min() + 4.0 * infl * (1 + 1e-9)]
                rng = {n: (float(values[n] + s_ * near[:, k].min()), float(values[n] + s_ * near[:, k].max()))
                       for k, (n, s_) in enumerate(((a, sa), (b, sb)))}
                if len(near) == 1:
                    # no refit but the best within Δχ² = 4 infl: a minimum sharper than the
                    # refits' spacing (a mirror's distance), not a ridge: the 1-D uncertainties stand
                    out[(a, b)] = {"rho": None, "sigma": {a: sa, b: sb}, "range": rng, "sharp": True}
                    continue
                # the nearest refits may lie where χ² is no quadratic (a minimum sharper than
                # their spacing): the quadratic the 1-D profiles give along the axes, with the cross
                # term both diagonals at one uncertainty give, tells a ridge from such a minimum
                cross = _diagonal_cross_term(a, b, values, sa, sb, byname, at, infl)
                if cross is not None and abs(cross) < 1.0:
                    S = np.linalg.inv(np.array([[1.0, cross], [cross, 1.0]]))
                    if sa * math.sqrt(S[0, 0]) < hi_a - lo_a and sb * math.sqrt(S[1, 1]) < hi_b - lo_b:
                        rng = extent(infl * (U * U + 2.0 * cross * U * W + W * W) <= 4.0 * infl)
                        out[(a, b)] = {"rho": float(-cross), "sigma": {a: sa * math.sqrt(S[0, 0]),
                                                                       b: sb * math.sqrt(S[1, 1])},
                                       "range": rng, "from_axes": True}
                        continue
                out[(a, b)] = {"rho": None, "sigma": {a: None, b: None}, "range": rng}
                continue
            out[(a, b)] = {"rho": float(S[0, 1] / math.sqrt(S[0, 0] * S[1, 1])),
                           "sigma": {a: sa * math.sqrt(S[0, 0]), b: sb * math.sqrt(S[1, 1])}, "range": rng}
    return out


def _geo(fit, hid: str, name: str, default: float) -> tuple[float, float | None]:
    """A profiled value and its uncertainty from a fit (``default``, None when not profiled)."""
    g = (getattr(fit, "hypothesis_data", None) or {}).get("geometry", {}).get(hid, {})
    return g.get(name, (default, None))


def _pm(value: float, se: float | None, unit: str = "") -> str:
    """``# ± σ`` or ``# not pinned by the readings`` for a profiled value."""
    if se is None:
        return "   # not pinned by the readings (profile without curvature): measure it"
    return f"   # ± {_g(se)}{unit} (profiled)"


def _choice_note(fit, hid: str, name: str, chosen: str, both: str, what: str, verb: str = "fits") -> str:
    """The YAML comment's clause on a categorical profiled property ``name`` of hypothesis
    ``hid`` (two choices): ``chosen`` fits (``verb``) better by Δχ², or ``both`` fit alike and the
    ``what`` is not identified (Δχ² under :data:`TYPE_DCHI2`); '' when it was not profiled."""
    choice = (getattr(fit, "hypothesis_data", None) or {}).get("choices", {}).get(hid, {}).get(name)
    if not choice or len(choice) != 2:
        return ""
    dchi = abs(choice[0.0] - choice[1.0])
    if dchi >= TYPE_DCHI2:
        return f"; {chosen} {verb} better by Δχ² = {dchi:.3g}"
    return f"; {both} fit alike (Δχ² = {dchi:.2g}): the {what} is not identified"


def paste_hardware(booth_text: str, snippet: str) -> str:
    """The booth file with the diagnosis' snippet merged in.

    Mappings add or replace keys, lists of items with an ``id`` add items or update the item
    with that id, ``effects:`` and anything else replace the booth's.  Read and written
    round-trip (ruamel.yaml): the booth file's comments and layout stay where they were."""
    import io

    from ruamel.yaml import YAML

    y = YAML(typ="rt")
    y.width = 110
    booth = y.load(booth_text)
    add = y.load(snippet) or {}
    for k, v in add.items():
        old = booth.get(k)
        if k == "effects" or old is None:
            booth[k] = v
        elif isinstance(old, dict) and isinstance(v, dict):
            for kk, vv in v.items():
                old[kk] = vv
        elif isinstance(old, list) and isinstance(v, list) and all(isinstance(x, dict) and "id" in x for x in v):
            for item in v:
                hit = next((x for x in old if isinstance(x, dict) and x.get("id") == item["id"]), None)
                if hit is None:
                    old.append(item)
                else:
                    for kk, vv in item.items():
                        hit[kk] = vv
        else:
            booth[k] = v
    out = io.StringIO()
    y.dump(booth, out)
    return out.getvalue()


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
    def geometry(cls, ir, lighting: str) -> list[GeometryParameter]:
        """Properties fitted by profiling (:func:`profile_geometry`); [] for none."""
        return []

    @classmethod
    def regeometry(cls, ir, lighting: str, values: dict[str, float]):
        """The booth :meth:`augment` built (``ir``) with the profiled properties at ``values``."""
        return ir

    @classmethod
    def profiled(cls, name: str, values: dict[str, float]) -> bool:
        """Whether property ``name`` matters at ``values`` (a rough plate's roughness does not
        for an opal plate)."""
        return True

    @classmethod
    def categorical_partner(cls, name: str) -> str | None:
        """The property a categorical property ``name`` is first profiled together with (each
        choice at its own best value of it), or None: each choice at the current values."""
        return None

    @classmethod
    def starts(cls) -> list[dict[str, float]]:
        """Starting values to try before the fit (free-parameter target → value); [] for one."""
        return []

    @classmethod
    def effect_entry(cls, fit: FitResult) -> dict:
        """The effect's parameters to write (the hardware carries the fitted values)."""
        return {}


class PlateHypothesis(Hypothesis):
    """A plate below the lowest lamp that is on: :data:`PLATE_GAP_MM` at first, its gap to the
    lamps profiled over :data:`PLATE_GAPS_MM`."""

    @classmethod
    def plate_z_mm(cls, ir, lighting, gap_mm: float = PLATE_GAP_MM) -> float:
        return min(_lamp_bottom_mm(lp) for lp in _lamps_on(ir, lighting)) - gap_mm

    @classmethod
    def geometry(cls, ir, lighting):
        # the plate stays in the upper 60 % of the interior (above the readings)
        top = min(_lamp_bottom_mm(lp) for lp in _lamps_on(ir, lighting))
        hi = max(PLATE_GAP_MM, top - 0.4 * float(ir.interior.height_mm))
        grid = tuple(g for g in PLATE_GAPS_MM if g <= hi)
        return [GeometryParameter("gap_mm", grid, PLATE_GAP_MM, (1.0, hi))] if len(grid) >= 3 else []

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
                       scattering={"type": "lambertian", "diffuse_fraction": 0.5}, ior=OPAL_PLATE_IOR)
        # the transmittance is fitted whether the lamps' output is known or not: with it known it
        # is a level the data see; with it fitted the level is the output's, but an opal plate's
        # total still sets how its layer scatters and how much it reflects (a plate declared to
        # transmit everything can do neither), which the shape of the light shows
        free = [FreeParameter("effect.diffuser.diffuse_fraction", (0.0, 1.0), 0.5),
                FreeParameter("effect.diffuser.transmittance_scale", (0.1, 1.0), 0.8)]
        return ir.model_copy(update={"diffuser": d}), {"diffuser": {}}, free

    @classmethod
    def geometry(cls, ir, lighting):
        out = super().geometry(ir, lighting)
        # the plate's type: opal (Lambertian part, fitted fraction; its faces polished or not) or
        # rough glass (GGX roughness, profiled); first, as it decides what the other properties mean
        return [GeometryParameter("rough", (0.0, 1.0), 0.0, (0.0, 1.0), categorical=True),
                GeometryParameter("roughness", PLATE_ROUGHNESSES, 0.2, (PLATE_ROUGHNESSES[0], PLATE_ROUGHNESSES[-1])),
                GeometryParameter("matte_faces", (0.0, 1.0), 0.0, (0.0, 1.0), categorical=True)] + out

    @classmethod
    def profiled(cls, name, values):
        rough = values.get("rough", 0.0) >= 0.5
        return rough if name == "roughness" else not rough if name == "matte_faces" else True

    @classmethod
    def regeometry(cls, ir, lighting, values):
        upd = {"z_mm": cls.plate_z_mm(ir, lighting, values.get("gap_mm", PLATE_GAP_MM))}
        if values.get("rough", 0.0) >= 0.5:
            upd["scattering"] = {"type": "roughness", "roughness": float(values.get("roughness", 0.2))}
            upd["ior"] = ROUGH_PLATE_IOR
        else:
            upd["ior"] = 1.0 if values.get("matte_faces", 0.0) >= 0.5 else OPAL_PLATE_IOR
        return ir.model_copy(update={"diffuser": ir.diffuser.model_copy(update=upd)})

    @classmethod
    def effect_entry(cls, fit):
        rough = _geo(fit, cls.id, "rough", 0.0)[0] >= 0.5
        fd = fit.values.get("effect.diffuser.diffuse_fraction", 0.0)
        # a rough plate with a Lambertian part too: the effect's override carries it
        return {"diffuse_fraction": round(float(fd), 4)} if rough and fd >= ROUGH_DIFFUSE_MIN else {}

    @classmethod
    def hardware_yaml(cls, ir, fit):
        d = ir.diffuser
        gap, gse = _geo(fit, cls.id, "gap_mm", PLATE_GAP_MM)
        rough = d.scattering.get("type") == "roughness"
        fd = fit.values.get("effect.diffuser.diffuse_fraction", 0.5)
        se = fit.stderr.get("effect.diffuser.diffuse_fraction")
        t = fit.values.get("effect.diffuser.transmittance_scale")
        kind = "rough glass" if rough else "opal"
        why = _choice_note(fit, cls.id, "rough", kind, "opal and rough glass", "type")
        faces = "" if rough else _choice_note(
            fit, cls.id, "matte_faces", "matte faces" if d.ior == 1.0 else "polished faces",
            "polished and matte faces", "faces' finish", verb="fit")
        lines = [f"diffuser:   # hypothesis: {cls.summary}, {kind}; extent assumed, height and "
                 f"scattering fitted{why}",
                 f"  z_mm: {_g(d.z_mm)}" + _pm(d.z_mm, gse, " mm"), f"  size_mm: [{_g(d.size_mm[0])}, {_g(d.size_mm[1])}]",
                 f"  centre_mm: [{_g(d.centre_mm[0])}, {_g(d.centre_mm[1])}]",
                 f"  thickness_mm: {_g(d.thickness_mm)}",
                 f"  ior: {_g(d.ior)}" + (f"   # {faces[2:]}" if faces else "")]
        if t is None:
            lines.append("  transmittance: {type: constant, value: 1.0}   # not fitted: put the datasheet value")
        else:
            st = fit.stderr.get("effect.diffuser.transmittance_scale")
            # with the lamps' output fitted only the shape of the plate's light pins it
            shape_only = any(k.startswith("group.") for k in fit.values)
            note = ", from the shape of the light (the lamps' output fitted): the datasheet's is better" \
                if shape_only else ""
            lines.append(f"  transmittance: {{type: constant, value: {_g(t)}}}" +
                         (f"   # ± {_g(st)}{note}" if st else f"   # {note[2:]}" if note else ""))
        if rough:
            r, rse = _geo(fit, cls.id, "roughness", float(d.scattering["roughness"]))
            lines.append(f"  scattering: {{type: roughness, roughness: {_g(r)}}}" + _pm(r, rse))
        else:
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
    def _cavity(cls, ir, lighting, gap_mm: float):
        """``ir`` with the cavity: the plate ``gap_mm`` under the lamps, black sides above it."""
        from lbscene.engine.scene.ir import IROccluder

        fx0, fx1, fy0, fy1 = _floor_bounds_mm(ir)
        cx, cy, ou, ov = cls.opening(ir, lighting)
        size = (fx1 - fx0, fy1 - fy0)
        # the opening's centre follows the lamps: the plate is centred on them
        occ = IROccluder(id=cls.OCCLUDER_ID, type="aperture_plate",
                         centre_mm=(cx, cy, cls.plate_z_mm(ir, lighting, gap_mm)),
                         normal=(0.0, 0.0, -1.0), u_axis=(1.0, 0.0, 0.0), size_mm=size,
                         opening_mm=(min(ou, size[0]), min(ov, size[1])), lamps=None, material=None)
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
        mine = [o for o in ir.occluders if o.id != cls.OCCLUDER_ID and not o.id.startswith(cls.OCCLUDER_ID + "_")]
        return ir.model_copy(update={"occluders": tuple(mine) + (occ, *sides)}), occ, size

    @classmethod
    def across(cls, ir, lighting) -> int:
        """0 (u, along x) or 1 (v, along y): the opening's extent across the tubes.  A shadow
        edge parallel to a tube moves the light a tube's points see in steps (no gradient for
        the fit): that extent is profiled, the other is a fitted scale."""
        ax = np.array([np.abs(np.asarray(lp.axis, float)) for lp in _lamps_on(ir, lighting) if lp.kind == "tube"])
        return 0 if ax.size and ax[:, 1].sum() > ax[:, 0].sum() else 1

    @classmethod
    def augment(cls, ir, lighting, known_groups):
        aug, occ, size = cls._cavity(ir, lighting, PLATE_GAP_MM)
        a = 1 - cls.across(ir, lighting)
        hi = max(size[a] / occ.opening_mm[a], 1.05)
        return aug, {"aperture_occlusion": {}}, [
            FreeParameter(f"effect.aperture_occlusion.opening_scale_{'uv'[a]}", (0.2, min(hi, 5.0)), 1.0)]

    @classmethod
    def geometry(cls, ir, lighting):
        out = super().geometry(ir, lighting)
        occ = next(o for o in ir.occluders if o.id == cls.OCCLUDER_ID)
        c = cls.across(ir, lighting)
        o0 = occ.opening_mm[c]
        grid = tuple(o0 * s for s in OPENING_SCALES if o0 * s <= occ.size_mm[c])
        if len(grid) >= 3:
            out.insert(0, GeometryParameter(f"opening_{'uv'[c]}_mm", grid, o0, (grid[0], grid[-1])))
        rho = _mean_reflectance(ir, ("ceiling",))
        if rho is not None and rho > 0.01:
            # the ceiling over the plate is the cavity's inside: its reflectance (first: it
            # changes the level most)
            out.insert(0, GeometryParameter("interior_reflectance", tuple(rho * s for s in INTERIOR_SCALES), rho,
                                            (0.0, rho)))
        return out

    @classmethod
    def regeometry(cls, ir, lighting, values):
        out, occ, _ = cls._cavity(ir, lighting, values.get("gap_mm", PLATE_GAP_MM))
        c = cls.across(ir, lighting)
        key = f"opening_{'uv'[c]}_mm"
        if key in values:
            op = list(occ.opening_mm)
            op[c] = values[key]
            out = out.model_copy(update={"occluders": tuple(
                o.model_copy(update={"opening_mm": tuple(op)}) if o.id == cls.OCCLUDER_ID else o
                for o in out.occluders)})
        if "interior_reflectance" in values:
            out = _with_surface_material(out, ("ceiling",), _constant_material(
                ir, CAVITY_MATERIAL_ID, values["interior_reflectance"]))
        return out

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
        geo = (getattr(fit, "hypothesis_data", None) or {}).get("geometry", {}).get(cls.id, {})
        errs = []
        for k, name in enumerate("uv"):
            se = fit.stderr.get(f"effect.aperture_occlusion.opening_scale_{name}")
            se = o.opening_mm[k] * se if se is not None else geo.get(f"opening_{name}_mm", (0, None))[1]
            errs.append("not pinned" if se is None else _g(se))
        err = f"   # opening ± [{errs[0]}, {errs[1]}] mm"
        c = o.centre_mm
        gap, gse = _geo(fit, cls.id, "gap_mm", PLATE_GAP_MM)
        out = ""
        for pair, j in (getattr(fit, "hypothesis_data", None) or {}).get("joint", {}).get(cls.id, {}).items():
            a, b = pair.split("|")
            if j["rho"] is None and not j.get("sharp"):
                span_ = "; ".join(f"{n} {_g(lo)} to {_g(hi)}" for n, (lo, hi) in j.get("range", {}).items())
                out += (f"# hypothesis: {a} and {b} trade off: these readings cannot tell them apart"
                        + (f"; Δχ² ≤ 4 allows {span_}" if span_ else "") + "\n")
            elif j["rho"] is not None and abs(j["rho"]) >= 0.7:
                out += (f"# hypothesis: {a} and {b} trade off (correlation {j['rho']:+.2f}): their "
                        "uncertainties below are the joint ones\n")
        if "interior_reflectance" in geo:
            val, val_se = geo["interior_reflectance"]
            out += ("materials:   # hypothesis: the cavity's inside (the ceiling over the plate), "
                    "reflectance fitted\n"
                    f"  {CAVITY_MATERIAL_ID}: {{type: diffuse, reflectance: {{type: constant, value: {val:.3f}}}}}"
                    + _pm(val, val_se) + "\nsurfaces:\n"
                    f"  ceiling: {CAVITY_MATERIAL_ID}\n")
        out += ("occluders:   # hypothesis: " + cls.summary + "; height and opening fitted\n"
               f"  - {{id: {o.id}, type: aperture_plate, centre_mm: [{_g(c[0])}, {_g(c[1])}, {_g(c[2])}], "
               f"normal: [0, 0, -1], size_mm: [{_g(o.size_mm[0])}, {_g(o.size_mm[1])}], "
               f"opening_mm: [{_g(ou)}, {_g(ov)}]}}{err}\n"
               f"    # plate height z {_g(c[2])} mm" + _pm(c[2], gse, " mm").replace("   #", ";", 1) + "\n")
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


class MirrorHypothesis(Hypothesis):
    """A plane mirror with each lamp that is on: *above* it facing down (a luminaire's
    reflector) or *behind* it, between the lamp and the nearest wall across its axis, facing the
    room (the prism mirrors behind a light booth's tubes).  The placement is a categorical
    profiled property, then the distance from the lamp's axis; the reflectance is fitted."""

    id = "mirror"
    effect = "reflector"
    channel = "spatial"
    summary = "a mirror with the lamps, above or behind them"

    @classmethod
    def _lamps(cls, ir, lighting):
        return [lp for lp in _lamps_on(ir, lighting) if lp.kind in ("tube", "bulb") and lp.mount == "booth"]

    @classmethod
    def applicable(cls, ir, lighting):
        why = super().applicable(ir, lighting)
        if why is None and not cls._lamps(ir, lighting):
            why = "no tube or bulb is on"
        return why

    @classmethod
    def declared(cls, ir, lighting):
        if any(lp.reflector for lp in _lamps_on(ir, lighting)):
            return "the lamps that are on have reflectors (the reflector effect tests them)"
        return None

    @classmethod
    def _behind(cls, ir, lp) -> tuple[tuple[float, float, float], float]:
        """The normal of a mirror behind ``lp`` (from the nearest wall across its axis toward the
        lamp) and the room between the lamp's axis and that wall (mm)."""
        x0, x1, y0, y1 = _floor_bounds_mm(ir)
        p = np.asarray(lp.position_mm, float)
        ax = np.abs(np.asarray(lp.axis, float)) if lp.kind == "tube" else np.zeros(3)
        walls = []   # (room, normal): the wall at +y is behind a lamp whose mirror faces −y
        if ax[0] < 0.9:
            walls += [(x1 - p[0], (-1.0, 0.0, 0.0)), (p[0] - x0, (1.0, 0.0, 0.0))]
        if ax[1] < 0.9:
            walls.append((y1 - p[1], (0.0, -1.0, 0.0)))
            if not ir.interior.open_front:
                walls.append((p[1] - y0, (0.0, 1.0, 0.0)))
        if not walls:
            return (0.0, 0.0, -1.0), 0.0
        room, n = min(walls)
        return n, float(room)

    @classmethod
    def _grid(cls, ir, lighting, placement: str = "above") -> tuple[float, ...]:
        """Mirror distances that fit between every lamp's body and the ceiling (above) or the wall
        behind it (behind)."""
        lamps = cls._lamps(ir, lighting)
        if placement == "above":
            room = min(float(ir.interior.height_mm) - float(lp.position_mm[2]) for lp in lamps) - 1.0
        else:
            room = min(cls._behind(ir, lp)[1] for lp in lamps) - 1.0
        r = max(float(lp.radius_mm) for lp in lamps)
        return tuple(d for d in MIRROR_DISTANCES_MM if r + 2.0 < d <= room)

    @classmethod
    def _widths(cls, ir, lighting, placement: str = "above") -> tuple[float, ...]:
        """Mirror widths that fit: above the lamps, within the room across the axis to the next
        lamp (half the spacing on each side) and to the walls; behind them, within twice the room
        between each lamp's axis and the ceiling."""
        lamps = cls._lamps(ir, lighting)
        if placement == "above":
            x0, x1, y0, y1 = _floor_bounds_mm(ir)
            room = np.inf
            for lp in lamps:
                p = np.asarray(lp.position_mm, float)
                ax = np.abs(np.asarray(lp.axis, float)) if lp.kind == "tube" else np.zeros(3)
                k = 0 if ax[0] < 0.9 else 1          # the floor axis across the lamp
                lo, hi = (x0, x1) if k == 0 else (y0, y1)
                half = min(p[k] - lo, hi - p[k])
                for q in lamps:
                    if q is not lp and abs(float(q.position_mm[k]) - p[k]) > 1.0:
                        half = min(half, abs(float(q.position_mm[k]) - p[k]) / 2.0)
                room = min(room, 2.0 * half)
        else:
            room = min(2.0 * (float(ir.interior.height_mm) - float(lp.position_mm[2])) for lp in lamps)
        return tuple(w for w in MIRROR_WIDTHS_MM if w <= room + 1e-6)

    @classmethod
    def _mirrors(cls, ir, lighting, placement: str, distance_mm: float, width_mm: float = MIRROR_WIDTH_MM):
        """``ir`` with the hypothesised mirrors: one reflector per direction they face."""
        from lbscene.engine.scene.ir import IRReflector, IRSpectrum

        lamps = cls._lamps(ir, lighting)
        normals = {lp.id: ((0.0, 0.0, -1.0) if placement == "above" else cls._behind(ir, lp)[0]) for lp in lamps}
        ids: dict[tuple, str] = {}
        for n in normals.values():
            ids.setdefault(n, FITTED_MIRROR_ID if not ids else f"{FITTED_MIRROR_ID}_{len(ids) + 1}")
        mine = {k: v for k, v in ir.reflectors.items() if not k.startswith(FITTED_MIRROR_ID)}
        unit = IRSpectrum.from_1nm(np.ones(_WL.size), ir.grid)
        refl = {rid: IRReflector(id=rid, type="plane", reflectance=unit, distance_mm=float(distance_mm),
                                 normal=n, width_mm=float(width_mm)) for n, rid in ids.items()}
        lamps_ = tuple(lp.model_copy(update={"reflector": ids[normals[lp.id]]}) if lp.id in normals else lp
                       for lp in ir.lamps)
        return ir.model_copy(update={"reflectors": {**mine, **refl}, "lamps": lamps_})

    @classmethod
    def augment(cls, ir, lighting, known_groups):
        grid = cls._grid(ir, lighting)
        d0 = grid[min(1, len(grid) - 1)] if grid else max(float(lp.radius_mm) for lp in cls._lamps(ir, lighting)) + 5
        widths = cls._widths(ir, lighting, "above")
        w0 = MIRROR_WIDTH_MM if not widths or MIRROR_WIDTH_MM in widths else widths[-1]
        aug = cls._mirrors(ir, lighting, "above", d0, w0)
        return aug, {"reflector": {}}, [FreeParameter("effect.reflector.reflectance_scale", (0.05, 1.0), 0.8)]

    @classmethod
    def geometry(cls, ir, lighting):
        above = cls._grid(ir, lighting, "above")
        behind = cls._grid(ir, lighting, "behind")
        both = tuple(d for d in above if d in behind)
        first = ir.reflectors[FITTED_MIRROR_ID]
        w_above, w_behind = cls._widths(ir, lighting, "above"), cls._widths(ir, lighting, "behind")
        if len(both) >= 3:
            # where it is, first: it decides what the distance and the width mean
            out = [GeometryParameter("behind", (0.0, 1.0), 0.0, (0.0, 1.0), categorical=True),
                   GeometryParameter("distance_mm", both, first.distance_mm, (both[0], both[-1]))]
            widths = tuple(w for w in w_above if w in w_behind)
        elif len(above) >= 3:
            out = [GeometryParameter("distance_mm", above, first.distance_mm, (above[0], above[-1]))]
            widths = w_above
        else:
            return []
        if len(widths) >= 3 and first.width_mm in widths:
            out.append(GeometryParameter("width_mm", widths, first.width_mm, (widths[0], widths[-1])))
        return out

    @classmethod
    def categorical_partner(cls, name):
        # the distance decides how a placement looks (narrow minima, 10 mm apart): each placement
        # at its best distance
        return "distance_mm" if name == "behind" else None

    @classmethod
    def regeometry(cls, ir, lighting, values):
        placement = "behind" if values.get("behind", 0.0) >= 0.5 else "above"
        width = values.get("width_mm", ir.reflectors[FITTED_MIRROR_ID].width_mm)
        return cls._mirrors(ir, lighting, placement, values["distance_mm"], width)

    @classmethod
    def hardware_yaml(cls, ir, fit):
        rho = fit.values.get("effect.reflector.reflectance_scale", 0.8)
        se = fit.stderr.get("effect.reflector.reflectance_scale")
        mirrors = {k: r for k, r in ir.reflectors.items() if k.startswith(FITTED_MIRROR_ID)}
        first = mirrors[FITTED_MIRROR_ID]
        d, dse = _geo(fit, cls.id, "distance_mm", first.distance_mm)
        # where the mirrors are is what the booth carries (the fit's choice built it)
        behind = any(tuple(r.normal) != (0.0, 0.0, -1.0) for r in mirrors.values())
        where = "behind the lamps, facing the room" if behind else "above the lamps, facing down"
        why = _choice_note(fit, cls.id, "behind", "behind" if behind else "above", "above and behind",
                           "placement")
        w, wse = _geo(fit, cls.id, "width_mm", None)
        fitted = "distance, width and reflectance fitted" if w is not None else \
            "width assumed, distance and reflectance fitted"
        out = f"reflectors:   # hypothesis: a mirror {where}; {fitted}{why}\n"
        for rid, r in mirrors.items():
            n = r.normal
            out += (f"  {rid}: {{type: plane, reflectance: {{type: constant, value: {rho:.3f}}}, "
                    f"distance_mm: {_g(r.distance_mm)}, normal: [{_g(n[0])}, {_g(n[1])}, {_g(n[2])}], "
                    f"width_mm: {_g(r.width_mm)}}}"
                    + (f"   # reflectance ± {_g(se)};" if se else "   #")
                    + _pm(d, dse, " mm").replace("   #", " distance", 1)
                    + ("" if w is None else _pm(w, wse, " mm").replace("   #", "; width", 1)) + "\n")
        out += "lamps:   # the lamps that are on get the mirror (merged by id)\n"
        out += "".join(f"  - {{id: {lp.id}, reflector: {lp.reflector}}}\n" for lp in ir.lamps
                       if lp.reflector in mirrors)
        return out


class SurfaceReflectanceHypothesis(Hypothesis):
    """A surface (``roles``) whose reflectance differs from its declared material's: the
    ``surface_reflectance`` effect's scale on it is fitted (uncertainty from the Jacobian), and
    the fitted material is written."""

    effect = "surface_reflectance"
    channel = "spatial"
    roles: ClassVar[tuple[str, ...]]
    param: ClassVar[str]
    material_id: ClassVar[str]

    @classmethod
    def declared(cls, ir, lighting):
        if "surface_reflectance" in ir.effects:
            return "the booth declares surface_reflectance (its scales are that effect's to fit)"
        if "interreflection" not in ir.effects:
            return "inter-reflection is off: the model's surfaces reflect nothing"
        rho = _mean_reflectance(ir, cls.roles)
        if rho is None:
            return f"the booth has no {' or '.join(cls.roles)}"
        if rho < 0.02:
            return f"the {' and '.join(cls.roles)} are declared black: a scale on them changes nothing"
        return None

    @classmethod
    def _rho_max(cls, ir) -> float:
        return max(float(ir.materials[s.material].reflectance.array_1nm.max())
                   for s in ir.surfaces if s.role in cls.roles)

    @classmethod
    def augment(cls, ir, lighting, known_groups):
        hi = max(1.05, min(3.0, 0.99 / max(cls._rho_max(ir), 1e-3)))
        return ir, {"surface_reflectance": {}}, [
            FreeParameter(f"effect.surface_reflectance.{cls.param}", (0.02, hi), 1.0)]

    @classmethod
    def hardware_yaml(cls, ir, fit):
        s = fit.values.get(f"effect.surface_reflectance.{cls.param}", 1.0)
        se = fit.stderr.get(f"effect.surface_reflectance.{cls.param}")
        # the booth's own inter-reflection scale, refitted jointly, multiplies every surface
        g = fit.values.get("effect.interreflection.reflectance_scale", 1.0)
        gse = fit.stderr.get("effect.interreflection.reflectance_scale")
        rho = _mean_reflectance(ir, cls.roles)
        mats = {ir.materials[x.material].reflectance.values_1nm for x in ir.surfaces if x.role in cls.roles}
        flat = all(np.ptp(np.asarray(m)[40:341]) < 1e-6 for m in mats)
        note = "" if flat else " (the declared spectra's mean; their shape is not kept)"
        present = [x.role for x in ir.surfaces if x.role in cls.roles]
        out = (f"materials:   # hypothesis: {cls.summary}; reflectance fitted{note}\n"
               f"  {cls.material_id}: {{type: diffuse, reflectance: {{type: constant, value: {min(rho * s * g, 0.99):.3f}}}}}"
               + (f"   # ± {_g(rho * g * se)}" if se else "   # not pinned by the readings") + "\n")
        roles = {r: cls.material_id for r in present}
        if abs(g - 1.0) > JOINT_SCALE_MIN:
            # the readings also scale the other surfaces: written, so that the booth predicts
            # what the fit did
            out += (f"  # the joint fit scales every surface's reflectance by {g:.3f}"
                    + (f" ± {_g(gse)}" if gse else "") + " "
                    "(inter-reflection's reflectance_scale): the other surfaces as fitted\n")
            for x in ir.surfaces:
                if x.role in BOX_SURFACE_ROLES and x.role not in cls.roles:
                    r0 = float(np.mean(ir.materials[x.material].reflectance.array_1nm[40:341]))
                    out += (f"  fitted_{x.role}: {{type: diffuse, reflectance: {{type: constant, "
                            f"value: {min(r0 * g, 0.99):.3f}}}}}\n")
                    roles[x.role] = f"fitted_{x.role}"
        return out + "surfaces:\n" + "".join(f"  {r}: {m}\n" for r, m in roles.items())


class CeilingReflectanceHypothesis(SurfaceReflectanceHypothesis):
    id = "ceiling_reflectance"
    summary = "the ceiling reflects otherwise than declared"
    roles = ("ceiling",)
    param = "ceiling_scale"
    material_id = "fitted_ceiling"


class WallsReflectanceHypothesis(SurfaceReflectanceHypothesis):
    id = "walls_reflectance"
    summary = "the side and rear walls reflect otherwise than declared"
    roles = ("left_wall", "right_wall", "rear_wall", "front_wall")
    param = "walls_scale"
    material_id = "fitted_walls"


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
        """``(G, 471)``: the factor on each group's spectrum (each reshaping defines it)."""
        raise NotImplementedError(f"{type(self).__name__} defines no factor on the groups' spectra")

    def components(self, values_nl):
        key = tuple(float(v) for v in values_nl)
        hit = self._recall(key)
        if hit is not None:
            return hit
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
        self._remember(key, out)
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
    """Each lamp group's spectrum shifted, tilted and curved at its declared luminous output
    (:func:`~lbscene.engine.light.effects.builtin.lamp_spectrum_shift.aged_spectrum_1nm`):
    the factor on group ``g`` is :math:`S_{a,g}(λ) / S_g(λ)` (the group's lamps summed)."""

    def __init__(self, base: FitProblem, fit: FitResult, names=("shift_nm", "tilt", "curvature")):
        from lbscene.engine.light.effects.builtin.lamp_spectrum_shift import LampSpectrumShiftEffect

        lamps = _lamps_on(base.ir, base.lighting)
        self._S = np.stack([sum(np.asarray(lp.peak_intensity_1nm, float) for lp in lamps if lp.group == g)
                            for g in base.groups])
        fps = LampSpectrumShiftEffect.fit_parameters
        init = LampSpectrumShiftEffect.fit_initial
        self._names = tuple(names)
        # the parameters left out of the fit stay at the effect's own defaults (no reshaping)
        self._held = {n: float(LampSpectrumShiftEffect.Params.model_fields[n].default) for n in fps}
        free = [FreeParameter(f"effect.{LampAgeingHypothesis.effect}.{n}", tuple(fps[n]), float(init.get(n, 0.0)))
                for n in self._names]
        super().__init__(base, fit, free)

    def factors(self, values_nl) -> np.ndarray:
        from lbscene.engine.light.effects.builtin.lamp_spectrum_shift import aged_spectrum_1nm

        v = {**self._held, **dict(zip(self._names, (float(x) for x in values_nl)))}
        shift, tilt, curvature = v["shift_nm"], v["tilt"], v["curvature"]
        out = np.ones_like(self._S)
        for k, S in enumerate(self._S):
            ok = S > 1e-9 * S.max() if S.max() > 0 else np.zeros(S.shape, bool)
            out[k, ok] = aged_spectrum_1nm(S, shift, tilt, curvature)[ok] / S[ok]
        return out


#: rounds of a spectral reshaping fitted on the base fit, the base's own non-linear parameters
#: refitted with it held (:func:`_rebase`), and it refitted on them
RESHAPE_ROUNDS = 3
#: χ² a round must gain to be kept
RESHAPE_GAIN = 0.5


def _reaches_noise(problem, res) -> bool:
    """Whether the fit ``res`` of ``problem`` explains its data down to the noise, as the diagnosis
    tests an explanation (:func:`~lbscene.engine.loop.fit.consistent_with_noise` with the problem's
    noise, and the readings' level tested where the lamps' output is known)."""
    return consistent_with_noise(res, noise_percent=problem.noise_percent,
                                 spectral_noise_percent=problem.spectral_noise_percent,
                                 level_test=bool(problem.meas.known_output_groups))


def _rebase(problem: FitProblem, fit: FitResult, effects: dict, res: FitResult, ir=None) -> FitResult | None:
    """The base's non-linear parameters (an inter-reflection's scale, …) refitted with a spectral
    reshaping held (``effects``: the reshaping's effect at its fitted values, ``res`` its fit),
    from ``fit``'s values; None when the base has none, when the reshaping already reaches the
    noise (:func:`~lbscene.engine.loop.fit.consistent_with_noise`, as the diagnosis tests
    it), or when the refit gains less than :data:`RESHAPE_GAIN`.

    A reshaping is fitted on the base fit with the base's non-linear values fixed; but that fit
    was made without it, and its parameters may have bent to pay for the spectrum it could not
    follow (an inter-reflection scaled down 3 % to lower the white tile's level, at the cost of
    the readings).  Refitted with the reshaping held, they return; the reshaping is then
    refitted on them (block coordinate descent, :data:`RESHAPE_ROUNDS`).  ``ir``: the booth with
    the reshaping's hardware (a fitted filter), spectral only, so the forward cache is shared."""
    if not problem.nl or _reaches_noise(problem, res):
        return None
    free = [replace(f, initial=float(np.clip(fit.values.get(f.target, f.initial), *f.bounds))) for f in problem.free]
    meas = problem.meas if ir is None else replace(problem.meas, ir=ir)
    p2 = FitProblem(meas, {**problem.effects, **effects}, free, problem.noise_percent,
                    problem.spectral_noise_percent, problem.cache, tolerance=problem.tolerance)
    f2 = p2.solve(errors=False)
    if not f2.chi2 < res.chi2 - RESHAPE_GAIN:
        return None
    f2.effects = {k: v for k, v in f2.effects.items() if k not in effects}
    return f2


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
        base_fit = fit
        for _ in range(RESHAPE_ROUNDS - 1):
            # the base's own parameters refitted with the filter held, the filter on them
            logt = np.log(fp.transmittance_1nm([res.values[fp.free[i].target] for i in fp.nl]))
            nxt = _rebase(problem, base_fit, {cls.effect: {"filter": FITTED_FILTER_ID}}, res,
                          ir=cls._with_filter(problem.ir, np.exp(logt)))
            if nxt is None:
                break
            fp2 = _FilteredProblem(problem, nxt, known, initial_log_1nm=logt, knots_nm=fp.knots_nm)
            r2 = fp2.solve()
            if r2.chi2 >= res.chi2 - RESHAPE_GAIN:
                break
            fp, res, base_fit = fp2, r2, nxt
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
        res.values = {**base_fit.values, **res.values}
        # the fitted filter as booth hardware: the booth of this explanation, for whoever
        # predicts with it (plan)
        res.ir = cls._with_filter(getattr(fit, "ir", None) or problem.ir, T)
        res.effects = {**res.effects, cls.effect: {"filter": FITTED_FILTER_ID}}
        return res

    @staticmethod
    def _with_filter(ir, T_1nm):
        """``ir`` with the fitted filter (transmittance ``T_1nm``) among its filters."""
        from lbscene.engine.scene.ir import IRFilter, IRSpectrum

        filt = IRFilter(id=FITTED_FILTER_ID, transmittance=IRSpectrum.from_1nm(T_1nm, ir.grid))
        return ir.model_copy(update={"filters": {**ir.filters, FITTED_FILTER_ID: filt}})

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
    """The lamps' spectrum aged: shifted, tilted and curved at the declared luminous output, fitted
    on the white tile.  Not hardware: tried whenever the booth does not enable the effect."""

    id = "lamp_ageing"
    effect = "lamp_spectrum_shift"
    channel = "spectral"
    summary = "the lamps' spectrum shifted, tilted and curved (ageing) at the declared output"
    hardware = False

    @classmethod
    def declared(cls, ir, lighting):
        return None

    @classmethod
    def fit_on(cls, problem, fit, known):
        if problem.tile_row is None:
            return None
        # the simpler ageing first: the curvature is fitted only where a shift and a tilt do not
        # reach the noise (a small smooth misfit of a booth that is right is no ageing)
        res = cls._fit(problem, fit, ("shift_nm", "tilt"))
        if not _reaches_noise(problem, res):
            res = cls._fit(problem, fit, ("shift_nm", "tilt", "curvature"))
        res.hypothesis_data = {"known": known}
        res.effects = {**res.effects, cls.effect: cls.effect_entry(res)}
        return res

    @classmethod
    def _fit(cls, problem, fit, names):
        """The ageing with ``names`` free, refitted with the base's own parameters (:func:`_rebase`)."""
        cur, res = fit, None
        for _ in range(RESHAPE_ROUNDS):
            fp = _AgedProblem(problem, cur, names)
            r = _reshaped_result(fp, fp.solve(), cur)
            if res is not None and r.chi2 >= res.chi2 - RESHAPE_GAIN:
                break
            res = r
            nxt = _rebase(problem, cur, {cls.effect: cls.effect_entry(res)}, res)
            if nxt is None:
                break
            cur = nxt
        return res

    @classmethod
    def effect_entry(cls, fit):
        return {n: float(fit.values[f"effect.{cls.effect}.{n}"]) for n in ("shift_nm", "tilt", "curvature")
                if f"effect.{cls.effect}.{n}" in fit.values}

    @classmethod
    def hardware_yaml(cls, ir, fit):
        return ""


#: hypothesis id → class
HYPOTHESES: dict[str, type[Hypothesis]] = {
    h.id: h for h in (DiffuserPlateHypothesis, AperturePlateHypothesis, MirrorHypothesis,
                      CeilingReflectanceHypothesis, WallsReflectanceHypothesis, SmoothFilterHypothesis,
                      LampAgeingHypothesis)}


def applicable_hypotheses(ir, lighting: str) -> tuple[list[type[Hypothesis]], dict[str, str]]:
    """Hypotheses that can be tried on this booth, and why the others cannot."""
    todo, skipped = [], {}
    for h in HYPOTHESES.values():
        why = h.applicable(ir, lighting)
        (skipped.__setitem__(h.id, why) if why else todo.append(h))
    return todo, skipped
