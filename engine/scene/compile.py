"""
Compile a booth document into the :class:`~lbscene.engine.scene.ir.SceneIR`.

parse (yamlio) → validate (schemas; effect parameters via the registry,
:mod:`lbscene.engine.scene.effect_params`) → semantic rules
(:mod:`lbscene.engine.scene.lint`) → instantiate (this module): read
every referenced file, evaluate spectra to numbers, triangulate geometry, turn
lamp output specs into absolute spectral intensity.
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Iterable

import numpy as np

from lbscene.engine.files.diagnostics import Diagnostic, DiagnosticBag, LbsceneUserError
from lbscene.engine.files.load import LoadedDocument, display_path, load_document
from lbscene.engine.spectra.bands import DEFAULT_GRID, BandGrid
from lbscene.schemas.booth import Booth, parse_geometry_name

from .effect_params import validate_effects
from .ir import (IR_VERSION, IRDiffuser, IRFilter, IRGeometry, IRInterior, IRLamp, IRLighting, IRMaterial,
                 IRObserver, IROccluder, IRPlatform, IRReflector, IRSpectrum, IRSurface, SceneIR)
from .lint import lint_booth
from .meshes import _mesh_from_obj, _meshes_from_usd, _rotation_matrix_xyz

__all__ = ["BOOTH_FILENAME", "find_booth_file", "load_booth", "compile_booth", "compile_loaded"]

BOOTH_FILENAME = "booth.yaml"


def find_booth_file(path: Path | str) -> Path:
    """A booth folder or file → its ``booth.yaml``."""
    from lbscene.engine.files.yamlio import path_kind

    p = Path(path)
    kind = path_kind(p)
    if kind == "dir":
        f = p / BOOTH_FILENAME
        if path_kind(f, display_path(f)) != "file":
            raise LbsceneUserError.single("LB011", f"no {BOOTH_FILENAME} in this folder",
                                          display_path(p), expected=f"a folder with {BOOTH_FILENAME}")
        return f
    if kind == "missing":
        from lbscene.engine.files.shipped import shipped_booth, shipped_booths

        # a bare name that is not a path here: one of the booths shipped with lbscene
        if len(p.parts) == 1 and (shipped := shipped_booth(p.name)) is not None:
            return shipped
        raise LbsceneUserError.single(
            "LB010", "file not found", str(p),
            expected=("a booth folder, a booth.yaml, or a shipped booth: "
                      + ", ".join(shipped_booths())) if len(p.parts) == 1 else None)
    return p


def load_booth(path: Path | str, allowed_dirs: Iterable[Path] = ()) -> LoadedDocument:
    """Load and validate a booth (schema + effect parameters); raise on errors."""
    f = find_booth_file(path)
    doc = load_document(f, Booth, allowed_dirs=allowed_dirs)
    _, diags = validate_effects(doc)
    if diags:
        raise LbsceneUserError(diags)
    return doc


def _apex_angle(r) -> float | None:
    """A prism reflector's apex angle: declared, or the schema's default; None for other types."""
    from lbscene.schemas.booth import PRISM_APEX_ANGLE_DEFAULT_DEG

    if r.type != "prism":
        return None
    return float(r.apex_angle_deg if r.apex_angle_deg is not None else PRISM_APEX_ANGLE_DEFAULT_DEG)


def compile_booth(path: Path | str, grid: BandGrid = DEFAULT_GRID,
                  allowed_dirs: Iterable[Path] = ()) -> SceneIR:
    """Booth folder or file → SceneIR (raises :class:`LbsceneUserError` on any error)."""
    doc = load_booth(path, allowed_dirs)
    bag = DiagnosticBag()
    bag.extend(lint_booth(doc))
    bag.raise_if_errors()
    return compile_loaded(doc, grid)


# --------------------------------------------------------------------------- geometry helpers

def _unit(v) -> tuple[float, float, float]:
    a = np.asarray(v, float)
    a = a / np.linalg.norm(a)
    return tuple(float(f"{x:.12g}") for x in a)


def _quad(p0, p1, p2, p3):
    """Two triangles of a quad given counter-clockwise as seen from its front side."""
    return [tuple(map(float, p)) for p in (p0, p1, p2, p3)], [(0, 1, 2), (0, 2, 3)]


def _box_surfaces(booth: Booth) -> list[IRSurface]:
    it = booth.interior
    w, d, h = it.width_mm / 2, it.depth_mm / 2, it.height_mm
    s = booth.surfaces
    # vertices ordered so that the triangle normal (right-hand rule) points into the box
    quads = {
        "floor": ((-w, -d, 0), (w, -d, 0), (w, d, 0), (-w, d, 0)),
        "ceiling": ((-w, -d, h), (-w, d, h), (w, d, h), (w, -d, h)),
        "left_wall": ((-w, -d, 0), (-w, d, 0), (-w, d, h), (-w, -d, h)),
        "right_wall": ((w, -d, 0), (w, -d, h), (w, d, h), (w, d, 0)),
        "rear_wall": ((-w, d, 0), (w, d, 0), (w, d, h), (-w, d, h)),
        "front_wall": ((-w, -d, 0), (-w, -d, h), (w, -d, h), (w, -d, 0)),
    }
    out = []
    for role, q in quads.items():
        if role == "front_wall" and (it.open_front or s.front_wall is None):
            continue
        mat = getattr(s, role)
        verts, tris = _quad(*q)
        out.append(IRSurface(id=role, role=role, material=mat, vertices_mm=tuple(verts),
                             triangles=tuple(tris)))
    return out


def _file_surfaces(doc: LoadedDocument) -> list[IRSurface]:
    booth: Booth = doc.model
    out = []
    for g in booth.geometry_files:
        path = doc.resolve(g.path)
        t = g.transform
        rot = _rotation_matrix_xyz(t.rotate_xyz_deg)
        if g.type == "obj":
            parts = [(g.id,) + _mesh_from_obj(path, g.path)]
        else:
            parts = [(f"{g.id}.{name}", v, f) for name, v, f in _meshes_from_usd(path, g.path)]
        for pid, v, f in parts:
            v = (v * t.scale) @ rot.T + np.asarray(t.translate_mm)
            out.append(IRSurface(
                id=pid, role="mesh", material=g.material,
                vertices_mm=tuple(tuple(float(f"{c:.9g}") for c in row) for row in v),
                triangles=tuple(tuple(int(i) for i in tri) for tri in f),
                source=f"{g.type}:{g.path}", mount=g.mount))
    return out


# --------------------------------------------------------------------------- lamps

def _lamp_ir(lamp, doc: LoadedDocument, grid: BandGrid) -> IRLamp:
    from lbscene.engine.light.emitters import emitter_from_lamp, projected_area_m2, unit_irradiance
    from lbscene.engine.spectra.evaluate import evaluate_spectrum, luminous_efficacy_sum
    from lbscene.engine.spectra.profiles import profile_shape, read_ies, solid_angle_weight_sr

    spd = evaluate_spectrum(lamp.spd, doc.resolve, "emission", display=f"lamp {lamp.id} spd")
    ref = np.interp(560.0, np.arange(360.0, 831.0), spd)
    spd = spd / (ref if ref > 0 else spd.max())
    profile = lamp.profile.model_dump(mode="json")
    if profile["type"] == "ies":
        data = read_ies(doc.resolve(lamp.profile.path), lamp.profile.path)
        profile["data"] = {"vertical_deg": data.vertical_deg.tolist(),
                           "horizontal_deg": data.horizontal_deg.tolist(),
                           "candela": data.candela.tolist(),
                           "lumens_per_lamp": data.lumens_per_lamp}
    shape = profile_shape(profile)
    lum_per_unit = luminous_efficacy_sum(spd)  # cd per (W·sr⁻¹·nm⁻¹ scale)
    aim = np.asarray(_unit(lamp.aim))
    axis = np.asarray(_unit(lamp.axis))
    # Φ / I_ref of the lamp's own Lambertian shape times its modulation (spectra.profiles)
    omega = solid_angle_weight_sr(lamp.type, axis, aim, shape, radius_mm=lamp.radius_mm,
                                  length_mm=lamp.length_mm, end_caps=lamp.end_caps)
    area_m2 = projected_area_m2(lamp.type, lamp.length_mm, lamp.width_mm, lamp.radius_mm)
    out = lamp.output
    if out.type == "peak_intensity_cd":
        scale = out.value_cd / lum_per_unit
    elif out.type == "luminous_flux_lm":
        scale = out.value_lm / (lum_per_unit * omega)
    elif out.type == "luminance_cd_m2":                 # I_ref = L_v · A
        scale = out.value_cd_m2 * area_m2 / lum_per_unit
    elif out.type == "radiance_W_sr_m2":
        scale = out.value_W_sr_m2 * area_m2 / float(spd.sum())
    elif out.type == "peak_radiant_intensity_W_sr":
        scale = out.value_W_sr / float(spd.sum())      # Σ over the 1 nm grid = ∫ dλ
    elif out.type == "radiant_flux_W":
        scale = out.value_W / (float(spd.sum()) * omega)
    else:  # illuminance at a point from the bare emitter (its shape and profile), upward receiver
        tmp = IRLamp(id=lamp.id, group=lamp.group or lamp.id, kind=lamp.type,
                     position_mm=lamp.position_mm, axis=tuple(axis), aim=tuple(aim),
                     length_mm=lamp.length_mm, width_mm=lamp.width_mm, radius_mm=lamp.radius_mm,
                     spd=IRSpectrum(values_1nm=(0.0,), bands=(0.0,)), intensity_scale_W_sr_nm=1.0,
                     peak_luminous_intensity_cd=0.0, luminous_flux_lm=0.0, profile=profile,
                     point_sources=lamp.point_sources, end_caps=lamp.end_caps)
        geo = unit_irradiance(emitter_from_lamp(tmp, shape), out.point_mm, (0.0, 0.0, 1.0))
        if geo <= 0:
            raise LbsceneUserError.single(
                "LB104", f"lamp {lamp.id}: the output point receives no light from the lamp",
                doc.file, expected="a point below the lamp")
        scale = out.value_lx / (lum_per_unit * geo)
    return IRLamp(
        id=lamp.id, group=lamp.group or lamp.id, kind=lamp.type,
        position_mm=tuple(float(c) for c in lamp.position_mm), axis=_unit(lamp.axis),
        aim=tuple(float(c) for c in aim), length_mm=lamp.length_mm, width_mm=lamp.width_mm,
        radius_mm=lamp.radius_mm, spd=IRSpectrum.from_1nm(spd, grid),
        intensity_scale_W_sr_nm=float(f"{scale:.10g}"),
        peak_luminous_intensity_cd=float(f"{scale * lum_per_unit:.10g}"),
        luminous_flux_lm=float(f"{scale * lum_per_unit * omega:.10g}"),
        profile=profile, point_sources=lamp.point_sources, filter=lamp.filter,
        reflector=lamp.reflector, mount=lamp.mount, end_caps=lamp.end_caps)


# --------------------------------------------------------------------------- compile

def compile_loaded(doc: LoadedDocument, grid: BandGrid = DEFAULT_GRID) -> SceneIR:
    """Instantiate a validated, linted booth document."""
    from lbscene.engine.spectra.evaluate import evaluate_spectrum

    booth: Booth = doc.model
    effects, diags = validate_effects(doc)
    if diags:
        raise LbsceneUserError(diags)

    def spectrum(spec, kind, what):
        return IRSpectrum.from_1nm(evaluate_spectrum(spec, doc.resolve, kind, display=what), grid)

    materials = {mid: IRMaterial(id=mid, type=m.type,
                                 reflectance=spectrum(m.reflectance, "reflectance", f"material {mid}"),
                                 gloss_GU=m.gloss_GU, roughness=m.roughness)
                 for mid, m in booth.materials.items()}
    if booth.interior.type == "box":
        interior = IRInterior(width_mm=booth.interior.width_mm, depth_mm=booth.interior.depth_mm,
                              height_mm=booth.interior.height_mm, open_front=booth.interior.open_front)
        surfaces = _box_surfaces(booth)
    else:
        bw, bd, bh = booth.interior.bounds_mm
        interior = IRInterior(width_mm=bw, depth_mm=bd, height_mm=bh, open_front=True)
        surfaces = []
        roles = set(type(booth.surfaces).model_fields)
        for name, v, f in _meshes_from_usd(doc.resolve(booth.interior.path), booth.interior.path):
            role = next((r for r in roles if r in name.lower()), "mesh")
            mat = getattr(booth.surfaces, role, None) if role != "mesh" else None
            mat = mat or booth.surfaces.floor
            surfaces.append(IRSurface(
                id=name, role=role, material=mat,
                vertices_mm=tuple(tuple(float(f"{c:.9g}") for c in row) for row in v),
                triangles=tuple(tuple(int(i) for i in t) for t in f),
                source=f"usd:{booth.interior.path}"))
    if booth.platform is not None and booth.surfaces.platform:
        cx, cy, cz = booth.platform.centre_mm
        sx, sy = booth.platform.size_mm[0] / 2, booth.platform.size_mm[1] / 2
        verts, tris = _quad((cx - sx, cy - sy, cz), (cx + sx, cy - sy, cz),
                            (cx + sx, cy + sy, cz), (cx - sx, cy + sy, cz))
        surfaces.append(IRSurface(id="platform", role="platform", material=booth.surfaces.platform,
                                  vertices_mm=tuple(verts), triangles=tuple(tris)))
    surfaces.extend(_file_surfaces(doc))

    lamps = tuple(_lamp_ir(lp, doc, grid) for lp in booth.lamps)
    filters = {fid: IRFilter(id=fid, transmittance=spectrum(f.transmittance, "transmittance",
                                                            f"filter {fid}"))
               for fid, f in booth.filters.items()}
    reflectors = {rid: IRReflector(id=rid, type=r.type,
                                   reflectance=spectrum(r.reflectance, "reflectance", f"reflector {rid}"),
                                   distance_mm=r.distance_mm, normal=_unit(r.normal), width_mm=r.width_mm,
                                   apex_angle_deg=_apex_angle(r))
                  for rid, r in booth.reflectors.items()}
    diffuser = None
    if booth.diffuser is not None:
        df = booth.diffuser
        diffuser = IRDiffuser(z_mm=df.z_mm, size_mm=df.size_mm, centre_mm=df.centre_mm,
                              thickness_mm=df.thickness_mm,
                              transmittance=spectrum(df.transmittance, "transmittance", "diffuser"),
                              scattering=df.scattering.model_dump(mode="json"), ior=df.ior)
    occluders = tuple(IROccluder(id=o.id, type=o.type, centre_mm=o.centre_mm, normal=_unit(o.normal),
                                 u_axis=_unit(o.u_axis), size_mm=o.size_mm, opening_mm=o.opening_mm,
                                 lamps=tuple(o.lamps) if o.lamps is not None else None,
                                 material=o.material, mount=o.mount)
                      for o in booth.occluders)
    lighting = {name: IRLighting(name=name, lamps=tuple(c.lamps), dimming=dict(c.dimming),
                                 description=c.description,
                                 nominal_illuminance_lx=c.nominal_illuminance_lx, standard=c.standard)
                for name, c in booth.lighting.items()}
    geometries = []
    for g in booth.geometries:
        ill, asp = parse_geometry_name(g.name)
        geometries.append(IRGeometry(name=g.name, illumination_deg=ill, aspecular_deg=asp,
                                     viewing_deg=ill - asp,
                                     platform_rotation_deg=g.platform_rotation_deg))
    ob = booth.observer
    platform = None
    if booth.platform is not None:
        p = booth.platform
        platform = IRPlatform(centre_mm=p.centre_mm, size_mm=p.size_mm,
                              rotation_axis=_unit(p.rotation_axis),
                              pivot_mm=p.pivot_mm if p.pivot_mm is not None else p.centre_mm,
                              illumination_fixed_to_platform=p.illumination_fixed_to_platform,
                              illumination_angle_deg=p.illumination_angle_deg)
    ir = SceneIR(
        ir_version=IR_VERSION, booth_name=booth.name,
        # folder/file, not a cwd-relative path: the IR (and its hash) must not depend on where
        # the command was run from
        booth_source=f"{doc.path.resolve().parent.name}/{doc.path.name}",
        provenance_status=booth.provenance.status,
        bands=grid.to_json(), interior=interior, materials=materials, surfaces=tuple(surfaces),
        lamps=lamps, filters=filters, reflectors=reflectors, diffuser=diffuser,
        occluders=occluders, lighting=lighting, geometries=tuple(geometries), platform=platform,
        observer=IRObserver(type=ob.type, position_mm=ob.position_mm, look_at_mm=ob.look_at_mm,
                            slit_size_mm=ob.slit_size_mm),
        sample_position_mm=booth.sample_position_mm, effects=effects,
        fit=booth.fit.model_dump(mode="json"))
    ir = _with_projected_reflectances(ir)
    try:
        ir.to_json()          # finite floats only: a NaN here would reach every product
    except ValueError:
        raise LbsceneUserError.single(
            "LB600", "the booth's numbers give a non-finite value (NaN or infinity) in the scene IR",
            display_path(doc.path), expected="a booth whose lamp levels and geometry are finite",
            hint="check lamp positions against output points and surfaces (LB309), and zero sizes") from None
    return ir


def _with_projected_reflectances(ir: SceneIR) -> SceneIR:
    """Lighting-dependent band reflectances of the booth's materials (colour accuracy)."""
    try:
        from lbscene.engine.colour.band_weighting import project_reflectance
    except ImportError:  # colour module not available in this build
        return ir
    new = {}
    for mid, m in ir.materials.items():
        by = {}
        for name in ir.lighting:
            light = ir.lighting_spd_1nm(name)
            if not np.any(light > 0):
                continue
            bands = project_reflectance(m.reflectance.array_1nm, light, ir.grid)
            by[name] = tuple(float(f"{x:.10g}") for x in np.asarray(bands).ravel())
        new[mid] = m.model_copy(update={"reflectance_bands_by_lighting": by})
    return ir.model_copy(update={"materials": new})
