"""
Semantic rules for booth documents (what a schema cannot say).

Each rule yields located :class:`~lbscene.engine.files.diagnostics.Diagnostic` s with
a stable code; all rules run, so every problem is reported at once.

=====  ==========================================================  ========
code   rule                                                        severity
=====  ==========================================================  ========
LB202  reference to an undefined lamp/filter/reflector/material     error
LB304  duplicate id                                                error
LB300  lamp outside the booth interior                             error
LB306  sample position outside the booth                           error
LB309  lamp reaches a receiver point or crosses a surface             error
LB203  IES or mesh file with wrong content (located in that file)     error
LB312  mesh face degenerate or with an overflowing normal            error
LB313  mesh vertex outside the booth (at any platform rotation)       error
LB510  more lamps, point sources or mesh triangles than the bound     error
LB301  spectrum does not cover the band range (390–710 nm)         error
LB302  reflectance/transmittance outside [0, 1]                    error
LB307  effect parameter names something the booth lacks            error
LB310  illuminance at the sample (forward model with the booth's   warning
       effects) outside the viewing standard's range
LB311  values marked as estimates                                  info
LB314  a reflector the model draws only in part (a parabolic        warning
       trough drawn as a plane; a prism under 120° whose facet-to-
       facet reflections are left out)
=====  ==========================================================  ========
"""

from __future__ import annotations

from collections import Counter

import numpy as np

from lbscene.engine.files.diagnostics import Diagnostic, LbsceneUserError, Severity
from lbscene.engine.files.load import LoadedDocument
from lbscene.engine.light.geometry import rotation_matrix
from lbscene.engine.spectra.bands import DEFAULT_GRID, REFERENCE_WAVELENGTHS_NM
from lbscene.schemas.booth import Booth

from .effect_params import validate_effects
from .meshes import TOLERANCE_MM, inside_booth

__all__ = ["lint_booth", "illuminance_rules", "needs_illuminance_rules", "spectrum_coverage",
           "ILLUMINANCE_RANGES_LX", "TOLERANCE_MM"]

#: Illuminance ranges at the viewing plane by viewing standard.
ILLUMINANCE_RANGES_LX = {
    "ASTM_D1729": (1080.0, 3230.0),   # 100-300 fc: general to critical evaluation
    "ISO_3668": (1000.0, 4000.0),     # paints: 1000-4000 lx
    "ISO_3664_P1": (1500.0, 2500.0),  # 2000 lx ± 500 lx
    "ISO_3664_P2": (375.0, 625.0),    # 500 lx ± 125 lx
}


def spectrum_coverage(spec, resolve) -> tuple[float, float] | None:
    """Wavelength range a tabulated spectrum covers (None: analytic or dataset).

    ``resolve`` turns a file reference into a path (``LoadedDocument.resolve``).
    """
    if spec.type == "inline":
        return spec.wavelengths_nm[0], spec.wavelengths_nm[-1]
    if spec.type == "csv":
        from lbscene.engine.files.yamlio import read_text_bounded
        from lbscene.engine.spectra.evaluate import MAX_CSV_BYTES

        from lbscene.engine.files.load import display_path

        from lbscene.engine.files.yamlio import csv_rows

        shown = display_path(resolve(spec.path))
        text = read_text_bounded(resolve(spec.path), shown, MAX_CSV_BYTES)
        rows = [r for _, r in csv_rows(text, shown) if r and not r[0].lstrip().startswith("#")]
        try:
            col = [c.strip() for c in rows[0]].index("wavelength_nm")
            wl = [float(r[col]) for r in rows[1:]]
            return min(wl), max(wl)
        except (ValueError, IndexError):
            return None  # read_spectrum_csv reports the precise problem
    return None


def _segment_distance_mm(p, a, b) -> float:
    """Distance from point ``p`` to the segment ``a``–``b``."""
    ab = b - a
    t = 0.0 if not ab.any() else float(np.clip(np.dot(p - a, ab) / np.dot(ab, ab), 0.0, 1.0))
    return float(np.linalg.norm(p - (a + t * ab)))


#: The closest a lamp's surface may come to a point the model evaluates (a receiver), in mm.
LAMP_CLEARANCE_MM = 1.0


def _lamp_clearance(doc: LoadedDocument) -> list[Diagnostic]:
    """LB309: a lamp whose body reaches a point the model must evaluate (the sample position,
    the point of an ``illuminance_at_point_lx`` output) or crosses a booth wall.  At such a
    point the inverse-square law divides by zero and every product would carry NaN."""
    booth: Booth = doc.model
    out: list[Diagnostic] = []
    w, d, h = booth.interior.width_mm / 2, booth.interior.depth_mm / 2, booth.interior.height_mm
    for i, lp in enumerate(booth.lamps):
        c = np.asarray(lp.position_mm, float)
        ax = np.asarray(lp.axis, float)
        ax = ax / np.linalg.norm(ax)
        half = lp.length_mm / 2 if lp.type in ("tube", "panel") else 0.0
        a, b = c - ax * half, c + ax * half
        body = max(lp.radius_mm, 0.0) if lp.type != "panel" else 0.0
        targets = [("the sample position", np.asarray(booth.sample_position_mm, float), ("sample_position_mm",))]
        if lp.output.type == "illuminance_at_point_lx":
            targets.append(("the point of its output", np.asarray(lp.output.point_mm, float),
                            ("lamps", i, "output", "point_mm")))
        for what, p, _ in targets:
            if lp.type == "panel":
                wdir = np.cross(np.asarray(lp.aim, float), ax)
                nw = np.linalg.norm(wdir)
                q = p - c
                inside = nw > 1e-9 and abs(q @ ax) <= half and abs(q @ (wdir / nw)) <= lp.width_mm / 2
                dist = abs(q @ np.cross(ax, wdir / nw)) if inside else _segment_distance_mm(p, a, b)
            else:
                dist = _segment_distance_mm(p, a, b)
            if dist - body < LAMP_CLEARANCE_MM:
                out.append(Diagnostic(
                    "LB309", f"lamp '{lp.id}' reaches {what}", doc.locate("lamps", i, "position_mm"),
                    value=f"{max(dist - body, 0.0):.3g} mm from it",
                    expected=f"at least {LAMP_CLEARANCE_MM:g} mm between the lamp's surface and {what}"))
        if body > 0:
            # the lamp's body must not cross the floor, the ceiling or a wall
            lo = np.minimum(a, b) - body
            hi = np.maximum(a, b) + body
            tol = 0.5
            if lo[2] < -tol or hi[2] > h + tol or lo[0] < -w - tol or hi[0] > w + tol \
                    or lo[1] < -d - tol or hi[1] > d + tol:
                out.append(Diagnostic(
                    "LB309", f"lamp '{lp.id}' (radius {body:g} mm) crosses a booth surface",
                    doc.locate("lamps", i, "position_mm"),
                    value=f"extent {np.round(lo, 1).tolist()} … {np.round(hi, 1).tolist()} mm",
                    expected="the whole lamp inside the interior box"))
    return out


def _adder(doc: LoadedDocument, diags: list[Diagnostic]):
    """``E(code, message, *path, key=False, **fields)``: append to ``diags`` a diagnostic located
    at ``path`` in the document (``key=True``: at the key itself)."""
    def add(code, message, *path, key=False, **fields):
        diags.append(Diagnostic(code, message, doc.locate(*path, key=key), **fields))
    return add


def _duplicate_ids(doc: LoadedDocument) -> list[Diagnostic]:
    """LB304: two lamps, occluders, geometry files or geometries with one id."""
    booth: Booth = doc.model
    diags: list[Diagnostic] = []
    E = _adder(doc, diags)
    for coll in ("lamps", "occluders", "geometry_files"):
        ids = [item.id for item in getattr(booth, coll)]
        for dup, n in Counter(ids).items():
            if n > 1:
                idx = [i for i, x in enumerate(ids) if x == dup][1]
                E("LB304", f"duplicate {coll[:-1].replace('_', ' ')} id '{dup}'", coll, idx, "id",
                  value=repr(dup), expected="unique ids")
    names = [g.name for g in booth.geometries]
    for dup, n in Counter(names).items():
        if n > 1:
            idx = [i for i, x in enumerate(names) if x == dup][1]
            E("LB304", f"geometry '{dup}' listed twice", "geometries", idx, "name")
    return diags


def _references(doc: LoadedDocument) -> list[Diagnostic]:
    """LB202 (LB104): references to lamps, filters, reflectors and materials the booth does
    not define; an IES file that cannot be read (located at its line); an aperture plate
    without an opening."""
    booth: Booth = doc.model
    diags: list[Diagnostic] = []
    E = _adder(doc, diags)
    lamp_ids = {lp.id for lp in booth.lamps}
    mats = set(booth.materials)
    for i, lp in enumerate(booth.lamps):
        if lp.filter and lp.filter not in booth.filters:
            E("LB202", f"lamp '{lp.id}' uses undefined filter '{lp.filter}'", "lamps", i, "filter",
              value=repr(lp.filter), expected=f"one of {sorted(booth.filters) or 'the filters: section'}")
        if lp.reflector and lp.reflector not in booth.reflectors:
            E("LB202", f"lamp '{lp.id}' uses undefined reflector '{lp.reflector}'", "lamps", i,
              "reflector", value=repr(lp.reflector),
              expected=f"one of {sorted(booth.reflectors) or 'the reflectors: section'}")
    for i, lp in enumerate(booth.lamps):
        # IES photometry is read here too, so validate-config reports a bad file at its line
        if lp.profile.type == "ies":
            from lbscene.engine.spectra.profiles import read_ies

            try:
                read_ies(doc.resolve(lp.profile.path), lp.profile.path)
            except LbsceneUserError as exc:
                diags.extend(exc.diagnostics)
    # geometry files are opened here too: every problem of a mesh is located in its file
    from .meshes import geometry_file_diagnostics

    diags.extend(geometry_file_diagnostics(doc))
    for role, mat in booth.surfaces.model_dump().items():
        if mat is not None and mat not in mats:
            E("LB202", f"surface '{role}' uses undefined material '{mat}'", "surfaces", role,
              value=repr(mat), expected=f"one of {sorted(mats)}")
    for i, g in enumerate(booth.geometry_files):
        if g.material not in mats:
            E("LB202", f"geometry file '{g.id}' uses undefined material '{g.material}'",
              "geometry_files", i, "material", value=repr(g.material), expected=f"one of {sorted(mats)}")
    for i, o in enumerate(booth.occluders):
        for j, lid in enumerate(o.lamps or []):
            if lid not in lamp_ids:
                E("LB202", f"occluder '{o.id}' names undefined lamp '{lid}'", "occluders", i, "lamps", j,
                  value=repr(lid), expected=f"one of {sorted(lamp_ids)}")
        if o.material and o.material not in mats:
            E("LB202", f"occluder '{o.id}' uses undefined material '{o.material}'", "occluders", i,
              "material", value=repr(o.material), expected=f"one of {sorted(mats)}")
        if o.type == "aperture_plate" and o.opening_mm is None:
            E("LB104", f"aperture plate '{o.id}' needs opening_mm", "occluders", i,
              expected="opening_mm: [u, v]")
    for name, cfg in booth.lighting.items():
        for j, lid in enumerate(cfg.lamps):
            if lid not in lamp_ids:
                E("LB202", f"lighting '{name}' switches on undefined lamp '{lid}'", "lighting", name,
                  "lamps", j, value=repr(lid), expected=f"one of {sorted(lamp_ids)}")
        for lid in cfg.dimming:
            if lid not in cfg.lamps:
                E("LB202", f"lighting '{name}' dims lamp '{lid}' that it does not switch on",
                  "lighting", name, "dimming", lid, key=True, value=repr(lid),
                  expected=f"one of {list(cfg.lamps)}")
    return diags


def _effect_references(doc: LoadedDocument) -> list[Diagnostic]:
    """LB307: effect parameters that name lamps, occluders or filters the booth lacks, and
    effects enabled without the hardware they model."""
    booth: Booth = doc.model
    diags: list[Diagnostic] = []
    E = _adder(doc, diags)
    lamp_ids = {lp.id for lp in booth.lamps}
    for eid, params in booth.effects.items():
        if not isinstance(params, dict):
            continue
        for j, lid in enumerate(params.get("lamps") or []):
            if lid not in lamp_ids:
                E("LB307", f"effect '{eid}' names undefined lamp '{lid}'", "effects", eid, "lamps", j,
                  value=repr(lid), expected=f"one of {sorted(lamp_ids)}")
        occ_ids = {o.id for o in booth.occluders}
        for j, oid in enumerate(params.get("occluders") or []):
            if oid not in occ_ids:
                E("LB307", f"effect '{eid}' names undefined occluder '{oid}'", "effects", eid,
                  "occluders", j, value=repr(oid), expected=f"one of {sorted(occ_ids)}")
        if params.get("filter") and params["filter"] not in booth.filters:
            E("LB307", f"effect '{eid}' names undefined filter '{params['filter']}'", "effects", eid,
              "filter", value=repr(params["filter"]), expected=f"one of {sorted(booth.filters)}")
    if "diffuser" in booth.effects and booth.diffuser is None:
        E("LB307", "effect 'diffuser' is enabled but the booth has no diffuser:", "effects", "diffuser",
          key=True, expected="a diffuser: section")
    if "aperture_occlusion" in booth.effects and not booth.occluders:
        E("LB307", "effect 'aperture_occlusion' is enabled but the booth has no occluders:", "effects",
          "aperture_occlusion", key=True, expected="an occluders: section")
    if "reflector" in booth.effects and not any(lp.reflector for lp in booth.lamps):
        E("LB307", "effect 'reflector' is enabled but no lamp has a reflector", "effects", "reflector",
          key=True, expected="`reflector:` on at least one lamp")
    if "spectral_filter" in booth.effects and not booth.filters:
        E("LB307", "effect 'spectral_filter' is enabled but the booth has no filters:", "effects",
          "spectral_filter", key=True, expected="a filters: section")
    return diags


def _placement(doc: LoadedDocument) -> list[Diagnostic]:
    """LB300, LB308, LB306: lamps, the turned platform and the sample inside the interior."""
    booth: Booth = doc.model
    diags: list[Diagnostic] = []
    E = _adder(doc, diags)
    for i, lp in enumerate(booth.lamps):
        c = np.asarray(lp.position_mm, float)
        ax = np.asarray(lp.axis, float)
        ax = ax / np.linalg.norm(ax)
        ends = [c] if lp.length_mm == 0 else [c - ax * lp.length_mm / 2, c + ax * lp.length_mm / 2]
        for e in ends:
            if not inside_booth(e, booth, margin=0.0):
                E("LB300", f"lamp '{lp.id}' extends outside the booth interior", "lamps", i,
                  "position_mm", value=f"point {np.round(e, 1).tolist()} mm",
                  expected="inside the interior box "
                           "(|x| ≤ width/2, |y| ≤ depth/2, 0 ≤ z ≤ height)")
                break
    pf = booth.platform
    for i, g in enumerate(booth.geometries):
        if pf is None or not g.platform_rotation_deg:
            continue
        # the platform's corners turned about its axis for this geometry must stay inside
        R = rotation_matrix(pf.rotation_axis, g.platform_rotation_deg)
        c = np.asarray(pf.centre_mm, float)
        o = np.asarray(pf.pivot_mm if pf.pivot_mm is not None else pf.centre_mm, float)
        sx, sy = pf.size_mm[0] / 2, pf.size_mm[1] / 2
        for dx, dy in ((-sx, -sy), (sx, -sy), (sx, sy), (-sx, sy)):
            q = R @ (c + [dx, dy, 0.0] - o) + o
            if not inside_booth(q, booth):
                E("LB308", f"geometry '{g.name}' turns the platform out of the booth", "geometries", i,
                  "platform_rotation_deg", value=f"corner at {np.round(q, 1).tolist()} mm",
                  expected="a platform inside the interior at every geometry (raise it, or turn it "
                           "about an edge with platform.pivot_mm)")
                break
    if not inside_booth(booth.sample_position_mm, booth):
        E("LB306", "sample position is outside the booth", "sample_position_mm",
          value=str(list(booth.sample_position_mm)), expected="a point inside the interior")
    return diags


def _work_bounds(doc: LoadedDocument) -> list[Diagnostic]:
    """LB510: more lamps or point sources than the work bounds allow (before anything is
    computed)."""
    from lbscene.engine.files.limits import LIMITS, limit_value

    booth: Booth = doc.model
    diags: list[Diagnostic] = []
    E = _adder(doc, diags)
    for name, count, path in (("lamps", len(booth.lamps), ("lamps",)),
                              ("source_points", sum(lp.point_sources for lp in booth.lamps), ("lamps",))):
        n = limit_value(name)
        if count > n:
            lim = LIMITS[name]
            E("LB510", f"{lim.counts}: {count} exceeds the limit of {n}", *path, key=True, value=str(count),
              expected=f"at most {n} ({lim.cost})",
              hint=f"raise the limit with the environment variable {lim.env}=N if the machine has the memory")
    return diags


def _spectra(doc: LoadedDocument) -> list[Diagnostic]:
    """LB301, LB302: every spectrum covers the bands; reflectances and transmittances in
    [0, 1] (and every spectrum file readable)."""
    from lbscene.engine.spectra.evaluate import evaluate_spectrum

    booth: Booth = doc.model
    diags: list[Diagnostic] = []
    E = _adder(doc, diags)
    lo_need, hi_need = DEFAULT_GRID.edges_nm[0], DEFAULT_GRID.edges_nm[-1]
    band = (REFERENCE_WAVELENGTHS_NM >= lo_need) & (REFERENCE_WAVELENGTHS_NM <= hi_need)

    def check_spectrum(spec, kind, path, what):
        cov = None
        try:
            cov = spectrum_coverage(spec, doc.resolve)
            values = evaluate_spectrum(spec, doc.resolve, kind, display=what)
        except LbsceneUserError as exc:
            diags.extend(exc.diagnostics)
            return
        if cov is not None and (cov[0] > lo_need or cov[1] < hi_need):
            E("LB301", f"{what} covers only {cov[0]:g}-{cov[1]:g} nm", *path,
              value=f"{cov[0]:g}-{cov[1]:g} nm", expected=f"at least {lo_need:g}-{hi_need:g} nm")
        if kind != "emission":
            v = values[band]
            if v.min() < 0 or v.max() > 1:
                E("LB302", f"{what} outside [0, 1]", *path,
                  value=f"{v.min():.4g}..{v.max():.4g}", expected="values between 0 and 1")

    for mid, m in booth.materials.items():
        check_spectrum(m.reflectance, "reflectance", ("materials", mid, "reflectance"),
                       f"reflectance of material '{mid}'")
    for fid, f in booth.filters.items():
        check_spectrum(f.transmittance, "transmittance", ("filters", fid, "transmittance"),
                       f"transmittance of filter '{fid}'")
    for rid, r in booth.reflectors.items():
        check_spectrum(r.reflectance, "reflectance", ("reflectors", rid, "reflectance"),
                       f"reflectance of reflector '{rid}'")
    if booth.diffuser is not None:
        check_spectrum(booth.diffuser.transmittance, "transmittance", ("diffuser", "transmittance"),
                       "diffuser transmittance")
    for i, lp in enumerate(booth.lamps):
        check_spectrum(lp.spd, "emission", ("lamps", i, "spd"), f"SPD of lamp '{lp.id}'")
    return diags


def _provenance(doc: LoadedDocument) -> list[Diagnostic]:
    """LB311 (info): values marked as estimates."""
    booth: Booth = doc.model
    if booth.provenance.status != "estimate":
        return []
    fields = ", ".join(booth.provenance.estimated_fields) or "all values"
    return [Diagnostic("LB311", f"booth values are estimates ({fields}): replace them with "
                       "measurements where you have them", doc.locate("provenance"),
                       severity=Severity.INFO)]


def _reflector_shapes(doc: LoadedDocument) -> list[Diagnostic]:
    """LB314 (warning): reflectors that the model (the ``reflector`` effect: first-order mirror
    images of plane facets) draws only in part."""
    booth: Booth = doc.model
    used = {lp.reflector for lp in booth.lamps if lp.reflector}
    diags: list[Diagnostic] = []
    for rid, r in booth.reflectors.items():
        if rid not in used:
            continue
        if r.type == "parabolic_trough":
            diags.append(Diagnostic(
                "LB314", f"reflector '{rid}' is a parabolic trough: the model and the Cycles bakes draw it as a "
                "plane mirror of the same width (its focusing is not modelled; the Mitsuba truth refuses it)",
                doc.locate("reflectors", rid, "type"), severity=Severity.WARNING))
        elif r.type == "prism" and r.apex_angle_deg is not None and r.apex_angle_deg < 120.0:
            diags.append(Diagnostic(
                "LB314", f"reflector '{rid}': apex angle {r.apex_angle_deg:g}° is under 120°, where light "
                "meets both facets; the model draws one reflection per facet and leaves the facet-to-facet "
                "reflections out (Mitsuba and Cycles draw them)", doc.locate("reflectors", rid, "apex_angle_deg"),
                severity=Severity.WARNING, expected="apex_angle_deg >= 120"))
    return diags


#: The rules of :func:`lint_booth`, in the order their diagnostics are listed.
RULES = (_duplicate_ids, _references, _effect_references, _placement, _lamp_clearance, _work_bounds,
         _spectra, _reflector_shapes, _provenance)


def lint_booth(doc: LoadedDocument) -> list[Diagnostic]:
    """The semantic diagnostics of a schema-valid booth document that need no compiled IR.

    Every rule of the table above but LB310: the viewing-standard warnings need the
    compiled booth (:func:`illuminance_rules`; ``validate-config`` runs them once these
    rules find no error).  All rules run (:data:`RULES`), so every problem is reported at once.
    """
    _, diags = validate_effects(doc)        # unknown effect ids, bad effect parameters
    for rule in RULES:
        diags.extend(rule(doc))
    return diags


def needs_illuminance_rules(doc: LoadedDocument) -> bool:
    """Whether a lighting of the booth names a viewing standard with an illuminance range."""
    return any(c.standard in ILLUMINANCE_RANGES_LX for c in doc.model.lighting.values())


def illuminance_rules(doc: LoadedDocument, ir) -> list[Diagnostic]:
    """LB310: the illuminance at the sample (upward surface at ``sample_position_mm``) of each
    lighting that names a viewing standard, from the forward model with the booth's effects
    (inter-reflection, diffuser, occlusion, …) of the compiled booth ``ir``, against the range of
    the lighting's ``standard:`` (warnings).  A direct-light estimate misses what the interior
    adds (a white booth at 879 lx direct reaches 2634 lx in full)."""
    from lbscene.engine.light.forward import ForwardModel

    booth: Booth = doc.model
    todo = {n: c for n, c in booth.lighting.items() if c.standard in ILLUMINANCE_RANGES_LX}
    out = []
    cache: dict = {}   # geometry (form factors, occlusion) shared by the lightings of this booth
    effects = ", ".join(sorted(ir.effects)) or "none enabled"
    for name, cfg in todo.items():
        lx = float(ForwardModel(ir, name, cache=cache).illuminance_lx([ir.sample_position_mm], None,
                                                                      meter=False)[0])
        lo, hi = ILLUMINANCE_RANGES_LX[cfg.standard]
        if not lo <= lx <= hi:
            out.append(Diagnostic(
                "LB310", f"lighting '{name}' gives {lx:.0f} lx at the sample (forward model with the "
                f"booth's effects: {effects}), outside the {cfg.standard.replace('_', ' ')} range",
                doc.locate("lighting", name, key=True), value=f"{lx:.0f} lx",
                expected=f"{lo:.0f}-{hi:.0f} lx", severity=Severity.WARNING,
                hint="`lbscene conformance` checks the rest of the standard"))
    return out
