"""
Scene IR → USD stage (``scene.usda``).

Standard prims wherever USD has them (UsdGeom meshes for surfaces, UsdLux
lights: CylinderLight for tubes, SphereLight for bulbs and points, RectLight
for panels, ShapingAPI for angular profiles, a UsdGeom camera for the
observer); everything spectral or booth-specific goes into the ``lbscene:``
namespace through the codeless API schemas in ``engine/usd_schema``
(``LbsceneSpectralAPI``, ``LbsceneLampAPI``, ``LbsceneBoothAPI``), registered
at run time.

Units: the stage is in millimetres (``metersPerUnit = 0.001``), +Z up, booth
coordinates.  UsdLux ``intensity`` is set to the lamp's mean luminance in
nits (cd/m²) over its projected area along ``aim``, with ``color`` its linear
sRGB chromaticity; the exact spectral radiant intensity is in
``lbscene:spectral:*``.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from .ir import SceneIR

__all__ = ["SCHEMA_DIR", "register_schema", "write_stage", "stage_to_string", "API_SCHEMAS"]

SCHEMA_DIR = Path(__file__).resolve().parent / "usd_schema"
API_SCHEMAS = ("LbsceneSpectralAPI", "LbsceneLampAPI", "LbsceneBoothAPI")
_registered = False


def register_schema() -> None:
    """Register the codeless lbscene schema plugin (idempotent)."""
    global _registered
    if _registered:
        return
    from pxr import Plug

    Plug.Registry().RegisterPlugins([str(SCHEMA_DIR)])
    _registered = True


def _set(prim, name: str, value) -> None:
    attr = prim.GetAttribute(name)
    if not attr:
        raise RuntimeError(f"schema attribute {name} missing on {prim.GetPath()} (plugin not registered?)")
    attr.Set(value)


def _spectral(prim, ir: SceneIR, quantity: str, spectrum, scale: float = 1.0) -> None:
    from pxr import Vt

    prim.ApplyAPI("LbsceneSpectralAPI")
    _set(prim, "lbscene:spectral:quantity", quantity)
    _set(prim, "lbscene:spectral:bandCentres_nm", Vt.FloatArray([float(c) for c in ir.grid.centres_nm]))
    _set(prim, "lbscene:spectral:bandWidth_nm", Vt.FloatArray([float(ir.grid.width_nm)]))
    _set(prim, "lbscene:spectral:bandValues", Vt.FloatArray([float(v) * scale for v in spectrum.bands]))
    _set(prim, "lbscene:spectral:referenceStart_nm", 360.0)
    _set(prim, "lbscene:spectral:values1nm", Vt.FloatArray([float(v) * scale for v in spectrum.values_1nm]))


def _linear_srgb(values_1nm: np.ndarray) -> tuple[float, float, float]:
    """Normalised linear-sRGB colour of a spectrum (for UsdLux ``color`` / displayColor)."""
    from .spectra import cmfs_1nm

    xyz = values_1nm @ cmfs_1nm()
    m = np.array([[3.2404542, -1.5371385, -0.4985314],
                  [-0.9692660, 1.8760108, 0.0415560],
                  [0.0556434, -0.2040259, 1.0572252]])  # IEC 61966-2-1 XYZ→linear sRGB
    rgb = np.clip(m @ xyz, 0.0, None)
    peak = rgb.max()
    return tuple(float(f"{c / peak:.6g}") for c in rgb) if peak > 0 else (1.0, 1.0, 1.0)


def _orient(xf, origin, x_axis, z_hint) -> None:
    """Set an Xformable's transform so its local +X is ``x_axis`` and local -Z faces ``z_hint``."""
    from pxr import Gf

    x = np.asarray(x_axis, float)
    x /= np.linalg.norm(x)
    zdir = -np.asarray(z_hint, float)
    zdir = zdir - x * (zdir @ x)
    if np.linalg.norm(zdir) < 1e-9:
        zdir = np.cross(x, [0.0, 1.0, 0.0]) if abs(x[1]) < 0.9 else np.cross(x, [1.0, 0.0, 0.0])
    z = zdir / np.linalg.norm(zdir)
    y = np.cross(z, x)
    m = Gf.Matrix4d(x[0], x[1], x[2], 0, y[0], y[1], y[2], 0, z[0], z[1], z[2], 0,
                    float(origin[0]), float(origin[1]), float(origin[2]), 1)
    xf.MakeMatrixXform().Set(m)


def _build(ir: SceneIR, lighting: str | None):
    from pxr import Gf, Sdf, Usd, UsdGeom, UsdLux, Vt

    register_schema()
    stage = Usd.Stage.CreateInMemory("scene.usda")
    UsdGeom.SetStageMetersPerUnit(stage, 0.001)
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.z)
    root = UsdGeom.Xform.Define(stage, "/Booth").GetPrim()
    stage.SetDefaultPrim(root)
    stage.GetRootLayer().documentation = f"lbscene booth stage: {ir.booth_name} (IR {ir.content_hash[:16]})"
    root.ApplyAPI("LbsceneBoothAPI")
    _set(root, "lbscene:booth:name", ir.booth_name)
    _set(root, "lbscene:booth:irHash", ir.content_hash)
    _set(root, "lbscene:booth:lighting", lighting or "")
    _set(root, "lbscene:booth:lightingConfigurations", Vt.StringArray(sorted(ir.lighting)))
    _set(root, "lbscene:booth:geometries", Vt.StringArray([g.name for g in ir.geometries]))
    _set(root, "lbscene:booth:effects", Vt.StringArray(sorted(ir.effects)))
    _set(root, "lbscene:booth:effectsJson", json.dumps(ir.effects, sort_keys=True))
    _set(root, "lbscene:booth:samplePosition_mm", Gf.Vec3f(*ir.sample_position_mm))
    _set(root, "lbscene:booth:observerPosition_mm", Gf.Vec3f(*ir.observer.position_mm))

    UsdGeom.Scope.Define(stage, "/Booth/Surfaces")
    for s in ir.surfaces:
        mesh = UsdGeom.Mesh.Define(stage, f"/Booth/Surfaces/{_prim_name(s.id)}")
        mesh.CreatePointsAttr(Vt.Vec3fArray([Gf.Vec3f(*p) for p in s.vertices_mm]))
        mesh.CreateFaceVertexCountsAttr(Vt.IntArray([3] * len(s.triangles)))
        mesh.CreateFaceVertexIndicesAttr(Vt.IntArray([i for t in s.triangles for i in t]))
        mesh.CreateSubdivisionSchemeAttr(UsdGeom.Tokens.none)
        mat = ir.materials[s.material]
        mesh.CreateDisplayColorAttr(Vt.Vec3fArray([Gf.Vec3f(*_linear_srgb(mat.reflectance.array_1nm))]))
        prim = mesh.GetPrim()
        prim.CreateAttribute("lbscene:surface:role", Sdf.ValueTypeNames.Token, custom=True).Set(s.role)
        prim.CreateAttribute("lbscene:surface:material", Sdf.ValueTypeNames.Token, custom=True).Set(mat.id)
        prim.CreateAttribute("lbscene:surface:gloss_GU", Sdf.ValueTypeNames.Float, custom=True).Set(
            float(mat.gloss_GU))
        _spectral(prim, ir, "reflectance", mat.reflectance)

    on = set(ir.lighting[lighting].lamps) if lighting else {lp.id for lp in ir.lamps}
    UsdGeom.Scope.Define(stage, "/Booth/Lamps")
    for lp in ir.lamps:
        path = f"/Booth/Lamps/{_prim_name(lp.id)}"
        if lp.kind == "tube":
            light = UsdLux.CylinderLight.Define(stage, path)
            light.CreateLengthAttr(float(lp.length_mm))
            light.CreateRadiusAttr(float(lp.radius_mm))
            area_m2 = lp.length_mm * 2 * lp.radius_mm * 1e-6
        elif lp.kind == "panel":
            light = UsdLux.RectLight.Define(stage, path)
            light.CreateWidthAttr(float(lp.length_mm))
            light.CreateHeightAttr(float(lp.width_mm))
            area_m2 = lp.length_mm * lp.width_mm * 1e-6
        else:
            light = UsdLux.SphereLight.Define(stage, path)
            r = lp.radius_mm if lp.kind == "bulb" else 1.0
            light.CreateRadiusAttr(float(r))
            if lp.kind == "point":
                light.CreateTreatAsPointAttr(True)
            area_m2 = np.pi * (r * 1e-3) ** 2
        _orient(UsdGeom.Xformable(light.GetPrim()), lp.position_mm, lp.axis, lp.aim)
        light.CreateIntensityAttr(float(f"{lp.peak_luminous_intensity_cd / area_m2:.8g}"))
        light.CreateNormalizeAttr(False)
        light.CreateColorAttr(Gf.Vec3f(*_linear_srgb(ir.lamp_emission_1nm(lp, with_filter=True))))
        prim = light.GetPrim()
        if lp.id not in on:
            UsdGeom.Imageable(prim).CreateVisibilityAttr(UsdGeom.Tokens.invisible)
        shaping = UsdLux.ShapingAPI.Apply(prim)
        prof = lp.profile
        if prof["type"] == "cosine_power":
            shaping.CreateShapingFocusAttr(float(prof["exponent"]))
        elif prof["type"] == "ies" and "path" in prof:
            shaping.CreateShapingIesFileAttr(Sdf.AssetPath(prof["path"]))
        prim.ApplyAPI("LbsceneLampAPI")
        _set(prim, "lbscene:lamp:id", lp.id)
        _set(prim, "lbscene:lamp:group", lp.group)
        _set(prim, "lbscene:lamp:kind", lp.kind)
        _set(prim, "lbscene:lamp:pointSources", int(lp.point_sources))
        _set(prim, "lbscene:lamp:profileType", prof["type"])
        if prof["type"] == "gaussian":
            _set(prim, "lbscene:lamp:profileSigma_deg", float(prof["sigma_deg"]))
        if prof["type"] == "cosine_power":
            _set(prim, "lbscene:lamp:profileExponent", float(prof["exponent"]))
        _set(prim, "lbscene:lamp:aim", Gf.Vec3f(*lp.aim))
        _set(prim, "lbscene:lamp:peakIntensity_cd", float(lp.peak_luminous_intensity_cd))
        _set(prim, "lbscene:lamp:luminousFlux_lm", float(lp.luminous_flux_lm))
        if lp.filter:
            _set(prim, "lbscene:lamp:filter", lp.filter)
        if lp.reflector:
            _set(prim, "lbscene:lamp:reflector", lp.reflector)
        _spectral(prim, ir, "spectral_radiant_intensity_W_sr_nm", lp.spd, lp.intensity_scale_W_sr_nm)

    if ir.filters or ir.reflectors:
        UsdGeom.Scope.Define(stage, "/Booth/Optics")
    for f in ir.filters.values():
        prim = UsdGeom.Scope.Define(stage, f"/Booth/Optics/{_prim_name('filter_' + f.id)}").GetPrim()
        _spectral(prim, ir, "transmittance", f.transmittance)
    for r in ir.reflectors.values():
        prim = UsdGeom.Scope.Define(stage, f"/Booth/Optics/{_prim_name('reflector_' + r.id)}").GetPrim()
        prim.CreateAttribute("lbscene:reflector:type", Sdf.ValueTypeNames.Token, custom=True).Set(r.type)
        prim.CreateAttribute("lbscene:reflector:distance_mm", Sdf.ValueTypeNames.Float,
                             custom=True).Set(float(r.distance_mm))
        _spectral(prim, ir, "reflectance", r.reflectance)
    if ir.diffuser is not None:
        d = ir.diffuser
        cube = UsdGeom.Cube.Define(stage, "/Booth/Diffuser")
        cube.CreateSizeAttr(1.0)
        xf = UsdGeom.Xformable(cube.GetPrim())
        xf.AddTranslateOp().Set(Gf.Vec3d(d.centre_mm[0], d.centre_mm[1], d.z_mm))
        xf.AddScaleOp().Set(Gf.Vec3f(d.size_mm[0], d.size_mm[1], d.thickness_mm))
        prim = cube.GetPrim()
        prim.CreateAttribute("lbscene:diffuser:scattering", Sdf.ValueTypeNames.String, custom=True).Set(
            json.dumps(d.scattering, sort_keys=True))
        prim.CreateAttribute("lbscene:diffuser:ior", Sdf.ValueTypeNames.Float, custom=True).Set(float(d.ior))
        _spectral(prim, ir, "transmittance", d.transmittance)
    if ir.occluders:
        UsdGeom.Scope.Define(stage, "/Booth/Occluders")
    for o in ir.occluders:
        verts, tris = occluder_mesh(o)
        mesh = UsdGeom.Mesh.Define(stage, f"/Booth/Occluders/{_prim_name(o.id)}")
        mesh.CreatePointsAttr(Vt.Vec3fArray([Gf.Vec3f(*map(float, p)) for p in verts]))
        mesh.CreateFaceVertexCountsAttr(Vt.IntArray([3] * len(tris)))
        mesh.CreateFaceVertexIndicesAttr(Vt.IntArray([int(i) for t in tris for i in t]))
        mesh.CreateSubdivisionSchemeAttr(UsdGeom.Tokens.none)

    cam = UsdGeom.Camera.Define(stage, "/Booth/Observer")
    _orient_camera(UsdGeom.Xformable(cam.GetPrim()), ir.observer.position_mm, ir.observer.look_at_mm)
    cam.CreateClippingRangeAttr(Gf.Vec2f(1.0, 100000.0))
    return stage


def occluder_mesh(o) -> tuple[np.ndarray, list[tuple[int, int, int]]]:
    """Triangles of an occluder plate (with its rectangular opening cut out)."""
    c = np.asarray(o.centre_mm, float)
    u = np.asarray(o.u_axis, float)
    n = np.asarray(o.normal, float)
    v = np.cross(n, u)
    su, sv = o.size_mm[0] / 2, o.size_mm[1] / 2
    if o.opening_mm is None:
        pts = [c - su * u - sv * v, c + su * u - sv * v, c + su * u + sv * v, c - su * u + sv * v]
        return np.asarray(pts), [(0, 1, 2), (0, 2, 3)]
    ou, ov = o.opening_mm[0] / 2, o.opening_mm[1] / 2
    outer = [(-su, -sv), (su, -sv), (su, sv), (-su, sv)]
    inner = [(-ou, -ov), (ou, -ov), (ou, ov), (-ou, ov)]
    pts = [c + a * u + b * v for a, b in outer + inner]
    tris = []
    for i in range(4):  # a frame of four quads between the outer and inner rectangles
        j = (i + 1) % 4
        tris += [(i, j, 4 + j), (i, 4 + j, 4 + i)]
    return np.asarray(pts), tris


def _orient_camera(xf, eye, target) -> None:
    from pxr import Gf

    eye = np.asarray(eye, float)
    fwd = np.asarray(target, float) - eye
    fwd /= np.linalg.norm(fwd)
    zc = -fwd  # USD cameras look down their local -Z
    up = np.array([0.0, 0.0, 1.0])
    xc = np.cross(up, zc)
    if np.linalg.norm(xc) < 1e-9:
        xc = np.array([1.0, 0.0, 0.0])
    xc /= np.linalg.norm(xc)
    yc = np.cross(zc, xc)
    xf.MakeMatrixXform().Set(Gf.Matrix4d(*xc, 0, *yc, 0, *zc, 0, *eye, 1))


def _prim_name(s: str) -> str:
    out = "".join(c if c.isalnum() or c == "_" else "_" for c in s)
    return out if out and not out[0].isdigit() else "_" + out


def stage_to_string(ir: SceneIR, lighting: str | None = None) -> str:
    """The stage as USDA text (deterministic for a given IR)."""
    stage = _build(ir, lighting)  # keep the stage alive: it owns the in-memory layer
    return stage.GetRootLayer().ExportToString()


def write_stage(ir: SceneIR, path: Path, lighting: str | None = None) -> None:
    Path(path).write_text(stage_to_string(ir, lighting))
