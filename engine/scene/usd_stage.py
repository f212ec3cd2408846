"""
Scene IR → USD stage (``scene.usda``).

Standard prims wherever USD has them (UsdGeom meshes for surfaces, UsdLux
lights: CylinderLight for tubes, SphereLight for bulbs and points, RectLight
for panels, ShapingAPI for angular profiles, a UsdGeom camera for the
observer); everything spectral or booth-specific goes into the ``lbscene:``
namespace through the codeless API schemas in ``engine/scene/usd_schema``
(``LbsceneSpectralAPI``, ``LbsceneLampAPI``, ``LbsceneBoothAPI``), registered
at run time.

Units: the stage is in millimetres (``metersPerUnit = 0.001``), +Z up, booth
coordinates.  UsdLux ``intensity`` × the luminance of ``color`` is the lamp's
mean luminance in nits (cd/m²) over its projected area along ``aim`` (area in
m²: the stage's millimetres × ``metersPerUnit``); ``color`` is its linear sRGB
chromaticity with peak 1; the exact spectral radiant intensity is in
``lbscene:spectral:*``.

So that the stage renders right in a standard tool:

* every surface is bound to a ``UsdPreviewSurface`` material whose
  ``diffuseColor`` is the colour of its spectral reflectance *as seen under the
  lighting, adapted to that lighting's white* (CAT16 to D65, see
  :mod:`lbscene.engine.colour.adaptation`), in linear Rec. 709 / sRGB primaries,
  normalised so that a perfect white is (1, 1, 1): a neutral grey of
  reflectance ρ is (ρ, ρ, ρ) under any lighting;
* the diffuser is a thin two-sided plate with a transmissive material
  (``opacity`` = 1 − its luminous transmittance under the lighting, ``ior``),
  not an opaque box;
* declared angular profiles become ``ShapingAPI``: ``cosine_power`` sets
  ``shaping:focus`` to its exponent and a 90° cone, ``gaussian`` the focus of
  the cosine power that fits it best (least squares over the hemisphere,
  solid-angle weighted), ``ies`` an IES file written next to the stage
  (``assets/<lamp>.ies``, from the candela table the build read) and referenced
  relatively in ``shaping:ies:file``;
* a stage for one lighting holds only the lamps that are on; the stage of
  all lightings has a variant set ``lighting`` on ``/Booth`` with one variant
  per lighting configuration (its lamps and the material colours under it).
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from .ir import SceneIR
from .viewing import observer_view

__all__ = ["SCHEMA_DIR", "register_schema", "write_stage", "stage_to_string", "stage_assets", "API_SCHEMAS",
           "lighting_spectrum_1nm", "adapted_linear_srgb", "luminous_factor", "fit_cosine_power",
           "ies_text", "validate_stage"]

SCHEMA_DIR = Path(__file__).resolve().parent / "usd_schema"
API_SCHEMAS = ("LbsceneSpectralAPI", "LbsceneLampAPI", "LbsceneBoothAPI")
#: the observer camera's focal length (UsdGeom lens units); its apertures give the field of view
CAMERA_FOCAL_LENGTH = 50.0
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
    from lbscene.engine.spectra.evaluate import cmfs_1nm

    xyz = values_1nm @ cmfs_1nm()
    m = np.array([[3.2404542, -1.5371385, -0.4985314],
                  [-0.9692660, 1.8760108, 0.0415560],
                  [0.0556434, -0.2040259, 1.0572252]])  # IEC 61966-2-1 XYZ→linear sRGB
    rgb = np.clip(m @ xyz, 0.0, None)
    peak = rgb.max()
    return tuple(float(f"{c / peak:.6g}") for c in rgb) if peak > 0 else (1.0, 1.0, 1.0)


#: IEC 61966-2-1 XYZ → linear sRGB (Rec. 709 primaries, D65 white)
_XYZ_TO_SRGB = np.array([[3.2404542, -1.5371385, -0.4985314],
                         [-0.9692660, 1.8760108, 0.0415560],
                         [0.0556434, -0.2040259, 1.0572252]])
#: luminance of linear Rec. 709 / sRGB (the Y row of the sRGB → XYZ matrix, IEC 61966-2-1)
_REC709_Y = np.array([0.2126729, 0.7151522, 0.0721750])
_D65_XYZ = np.array([0.3127 / 0.3290, 1.0, (1.0 - 0.3127 - 0.3290) / 0.3290])


def lighting_spectrum_1nm(ir: SceneIR, lighting: str | None) -> np.ndarray:
    """Sum of the filtered emission (1 nm) of the lamps on in a lighting (all lamps for None)."""
    on = set(ir.lighting[lighting].lamps) if lighting else {lp.id for lp in ir.lamps}
    total = np.zeros(471)
    for lp in ir.lamps:
        if lp.id in on:
            total = total + np.asarray(ir.lamp_emission_1nm(lp, with_filter=True), float)
    return total


def adapted_linear_srgb(factor_1nm, light_1nm) -> tuple[float, float, float]:
    """Linear sRGB of a reflectance (or transmittance) factor seen under a light, adapted (CAT16,
    D = 1) from the light's white to D65 and normalised so that a factor of 1 gives (1, 1, 1).

    ``rgb = N · M_sRGB · A · Σ_λ ρ(λ) S(λ) cmf(λ) / Y_S`` with ``A`` the CAT16 matrix from the
    light's white to D65 and ``N`` the diagonal that maps D65 exactly onto (1, 1, 1).  Lights with
    no visible output (a UV lamp alone) count as equal-energy.
    """
    from lbscene.engine.colour.adaptation import adaptation_matrix
    from lbscene.engine.spectra.evaluate import cmfs_1nm

    cmf = cmfs_1nm()
    light = np.asarray(light_1nm, float)
    white = light @ cmf
    if not white[1] > 1e-9 * max(float(np.abs(light).max()), 1e-300):
        light = np.ones(471)
        white = light @ cmf
    xyz = (np.asarray(factor_1nm, float) * light) @ cmf / white[1]
    a = adaptation_matrix(white, _D65_XYZ, "cat16")
    norm = _XYZ_TO_SRGB @ _D65_XYZ
    rgb = np.clip((_XYZ_TO_SRGB @ (a @ xyz)) / norm, 0.0, 1.0)
    return tuple(float(f"{c:.6g}") for c in rgb)


def luminous_factor(factor_1nm, light_1nm) -> float:
    """Luminous reflectance/transmittance under a light: Σ ρ S ȳ / Σ S ȳ (0 … 1)."""
    from lbscene.engine.spectra.evaluate import cmfs_1nm

    ybar = cmfs_1nm()[:, 1]
    light = np.asarray(light_1nm, float)
    den = float(light @ ybar)
    if not den > 0:
        light, den = np.ones(471), float(ybar.sum())
    return float(np.clip((np.asarray(factor_1nm, float) * light) @ ybar / den, 0.0, 1.0))


def fit_cosine_power(sigma_deg: float) -> float:
    """Exponent n of the cosⁿθ that best fits a Gaussian profile exp(−(θ/2σ)²) on 0 ≤ θ ≤ 90°.

    Least squares with the solid-angle weight sin θ (what the light carries); for small σ it tends
    to the small-angle match n = 1/(2σ²) (σ in radians).
    """
    from scipy.optimize import minimize_scalar

    t = np.linspace(0.0, np.pi / 2, 721)
    w = np.sin(t)
    g = np.exp(-(np.degrees(t) / (2.0 * sigma_deg)) ** 2)
    c = np.cos(t)

    def err(log_n):
        return float(np.sum(w * (g - c ** np.exp(log_n)) ** 2))

    res = minimize_scalar(err, bounds=(np.log(1e-4), np.log(1e4)), method="bounded",
                          options={"xatol": 1e-8})
    return float(np.exp(res.x))


def ies_text(lamp_id: str, data: dict) -> str:
    """An IES LM-63-2002 file (type C photometry, TILT=NONE) from a candela table of the IR.

    ``data``: ``vertical_deg`` (γ, 0 along ``aim``), ``horizontal_deg`` (C, 0 along ``axis``),
    ``candela`` rows per horizontal angle, ``lumens_per_lamp``.
    """
    v = [float(x) for x in data["vertical_deg"]]
    h = [float(x) for x in data["horizontal_deg"]]
    cd = [[float(x) for x in row] for row in data["candela"]]
    lm = float(data.get("lumens_per_lamp", -1) or -1)

    def rows(vals):
        out, line = [], []
        for x in vals:
            line.append(f"{x:.6g}")
            if len(line) == 10:
                out.append(" ".join(line))
                line = []
        if line:
            out.append(" ".join(line))
        return out

    lines = ["IESNA:LM-63-2002", f"[TEST] lbscene: candela table of lamp {lamp_id}",
             "[MANUFAC] lbscene", "TILT=NONE",
             # lamps, lm/lamp, multiplier, n vertical, n horizontal, type C, units (2 = metres), w, l, h
             f"1 {lm:.6g} 1 {len(v)} {len(h)} 1 2 0 0 0",
             "1 1 0"]  # ballast factor, future use, input watts
    lines += rows(v) + rows(h)
    for row in cd:
        lines += rows(row)
    return "\n".join(lines) + "\n"


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


def _preview_surface(stage, path: str, rgb, roughness: float, metallic: float, *, define: bool) -> None:
    """A UsdPreviewSurface material at ``path`` (``define``), or only its colour authored over it
    (inside a variant of the ``lighting`` variant set)."""
    from pxr import Sdf, UsdShade

    if not define:
        stage.OverridePrim(f"{path}/PreviewSurface").CreateAttribute(
            "inputs:diffuseColor", Sdf.ValueTypeNames.Color3f).Set(rgb)
        return
    material = UsdShade.Material.Define(stage, path)
    shader = UsdShade.Shader.Define(stage, f"{path}/PreviewSurface")
    shader.CreateIdAttr("UsdPreviewSurface")
    shader.CreateInput("roughness", Sdf.ValueTypeNames.Float).Set(roughness)
    shader.CreateInput("metallic", Sdf.ValueTypeNames.Float).Set(metallic)
    shader.CreateInput("diffuseColor", Sdf.ValueTypeNames.Color3f).Set(rgb)
    material.CreateSurfaceOutput().ConnectToSource(shader.ConnectableAPI(), "surface")


def _define_materials(stage, ir: SceneIR, light_1nm, *, define: bool) -> None:
    """UsdPreviewSurface materials of the booth's surfaces and the diffuser, coloured for a light.

    ``define``: create the prims (the base layer); otherwise only author the colour inputs (inside a
    variant of the ``lighting`` variant set)."""
    from pxr import Gf, Sdf, UsdShade

    for mat in ir.materials.values():
        path = f"/Booth/Materials/{_prim_name(mat.id)}"
        rgb = Gf.Vec3f(*adapted_linear_srgb(mat.reflectance.array_1nm, light_1nm))
        # matte unless the material declares gloss (≥ 10 GU: a visible sheen)
        rough = 1.0 if mat.gloss_GU < 10 else float(np.clip(1.0 - mat.gloss_GU / 100.0, 0.1, 0.9))
        _preview_surface(stage, path, rgb, rough, 0.0, define=define)
    for r in ir.reflectors.values():
        # a mirror: metallic, smooth, its colour the reflectance's (UsdPreviewSurface takes a
        # metal's specular colour from diffuseColor)
        path = f"/Booth/Materials/{_prim_name('reflector_' + r.id)}"
        rgb = Gf.Vec3f(*adapted_linear_srgb(np.clip(r.reflectance.array_1nm, 0, 1), light_1nm))
        _preview_surface(stage, path, rgb, 0.0, 1.0, define=define)
    if ir.diffuser is not None:
        d = ir.diffuser
        path = "/Booth/Materials/Diffuser"
        rgb = Gf.Vec3f(*adapted_linear_srgb(d.transmittance.array_1nm, light_1nm))
        opacity = 1.0 - luminous_factor(d.transmittance.array_1nm, light_1nm)
        if define:
            material = UsdShade.Material.Define(stage, path)
            shader = UsdShade.Shader.Define(stage, f"{path}/PreviewSurface")
            shader.CreateIdAttr("UsdPreviewSurface")
            shader.CreateInput("diffuseColor", Sdf.ValueTypeNames.Color3f).Set(rgb)
            shader.CreateInput("opacity", Sdf.ValueTypeNames.Float).Set(float(f"{opacity:.6g}"))
            shader.CreateInput("ior", Sdf.ValueTypeNames.Float).Set(float(d.ior))
            shader.CreateInput("roughness", Sdf.ValueTypeNames.Float).Set(1.0)
            material.CreateSurfaceOutput().ConnectToSource(shader.ConnectableAPI(), "surface")
        else:
            over = stage.OverridePrim(f"{path}/PreviewSurface")
            over.CreateAttribute("inputs:diffuseColor", Sdf.ValueTypeNames.Color3f).Set(rgb)
            over.CreateAttribute("inputs:opacity", Sdf.ValueTypeNames.Float).Set(float(f"{opacity:.6g}"))


def _bind(stage, prim, material_path: str) -> None:
    from pxr import UsdShade

    UsdShade.MaterialBindingAPI.Apply(prim).Bind(UsdShade.Material.Get(stage, material_path))


def _define_lamps(stage, ir: SceneIR, lamp_ids) -> None:
    from pxr import Gf, Sdf, UsdGeom, UsdLux

    UsdGeom.Scope.Define(stage, "/Booth/Lamps")
    for lp in ir.lamps:
        if lp.id not in lamp_ids:
            continue
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
        colour = _linear_srgb(ir.lamp_emission_1nm(lp, with_filter=True))
        # UsdLux: emitted luminance = intensity × luminance of `color`; the colour is kept in
        # [0, 1] (peak 1), so the intensity carries 1/Y(colour): intensity·Y·area = peak cd
        y_colour = float(np.dot(_REC709_Y, colour)) or 1.0
        light.CreateIntensityAttr(float(f"{lp.peak_luminous_intensity_cd / area_m2 / y_colour:.8g}"))
        light.CreateNormalizeAttr(False)
        light.CreateColorAttr(Gf.Vec3f(*colour))
        prim = light.GetPrim()
        shaping = UsdLux.ShapingAPI.Apply(prim)
        prof = lp.profile
        if prof["type"] == "cosine_power":
            shaping.CreateShapingFocusAttr(float(prof["exponent"]))
            shaping.CreateShapingConeAngleAttr(90.0)
        elif prof["type"] == "gaussian":
            shaping.CreateShapingFocusAttr(float(f"{fit_cosine_power(float(prof['sigma_deg'])):.6g}"))
            shaping.CreateShapingConeAngleAttr(90.0)
        elif prof["type"] == "ies" and "data" in prof:
            shaping.CreateShapingIesFileAttr(Sdf.AssetPath(f"./assets/{_prim_name(lp.id)}.ies"))
            shaping.CreateShapingIesNormalizeAttr(True)
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


def stage_assets(ir: SceneIR, lighting: str | None = None) -> dict[str, str]:
    """Files the stage references, relative to it → their text (IES files of the lamps)."""
    on = set(ir.lighting[lighting].lamps) if lighting else {lp.id for lp in ir.lamps}
    return {f"assets/{_prim_name(lp.id)}.ies": ies_text(lp.id, lp.profile["data"])
            for lp in ir.lamps
            if lp.id in on and lp.profile.get("type") == "ies" and "data" in lp.profile}


def _build(ir: SceneIR, lighting: str | None):
    from pxr import Gf, Sdf, Usd, UsdGeom, Vt

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

    lightings = [lighting] if lighting else list(ir.lighting)
    default = lightings[0] if lightings else None
    UsdGeom.Scope.Define(stage, "/Booth/Materials")
    _define_materials(stage, ir, lighting_spectrum_1nm(ir, default), define=True)

    UsdGeom.Scope.Define(stage, "/Booth/Surfaces")
    for s in ir.surfaces:
        mesh = UsdGeom.Mesh.Define(stage, f"/Booth/Surfaces/{_prim_name(s.id)}")
        mesh.CreatePointsAttr(Vt.Vec3fArray([Gf.Vec3f(*p) for p in s.vertices_mm]))
        mesh.CreateFaceVertexCountsAttr(Vt.IntArray([3] * len(s.triangles)))
        mesh.CreateFaceVertexIndicesAttr(Vt.IntArray([i for t in s.triangles for i in t]))
        mesh.CreateSubdivisionSchemeAttr(UsdGeom.Tokens.none)
        mat = ir.materials[s.material]
        mesh.CreateDisplayColorAttr(Vt.Vec3fArray([Gf.Vec3f(*adapted_linear_srgb(
            mat.reflectance.array_1nm, lighting_spectrum_1nm(ir, default)))]))
        prim = mesh.GetPrim()
        _bind(stage, prim, f"/Booth/Materials/{_prim_name(mat.id)}")
        prim.CreateAttribute("lbscene:surface:role", Sdf.ValueTypeNames.Token, custom=True).Set(s.role)
        prim.CreateAttribute("lbscene:surface:material", Sdf.ValueTypeNames.Token, custom=True).Set(mat.id)
        prim.CreateAttribute("lbscene:surface:gloss_GU", Sdf.ValueTypeNames.Float, custom=True).Set(
            float(mat.gloss_GU))
        _spectral(prim, ir, "reflectance", mat.reflectance)

    if lighting is not None:
        _define_lamps(stage, ir, set(ir.lighting[lighting].lamps))
    else:
        # one variant per lighting configuration: its lamps, and the material colours under it
        vset = root.GetVariantSets().AddVariantSet("lighting")
        for name in lightings:
            vset.AddVariant(name)
            vset.SetVariantSelection(name)
            with vset.GetVariantEditContext():
                _define_lamps(stage, ir, set(ir.lighting[name].lamps))
                _define_materials(stage, ir, lighting_spectrum_1nm(ir, name), define=False)
        if default is not None:
            vset.SetVariantSelection(default)

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
        prim.CreateAttribute("lbscene:reflector:width_mm", Sdf.ValueTypeNames.Float,
                             custom=True).Set(float(r.width_mm))
        prim.CreateAttribute("lbscene:reflector:normal", Sdf.ValueTypeNames.Vector3f,
                             custom=True).Set(Gf.Vec3f(*map(float, r.normal)))
        if r.apex_angle_deg is not None:
            prim.CreateAttribute("lbscene:reflector:apex_angle_deg", Sdf.ValueTypeNames.Float,
                                 custom=True).Set(float(r.apex_angle_deg))
        _spectral(prim, ir, "reflectance", r.reflectance)
        # the mirror behind each lamp that uses it, as the model draws it: one rectangle (a plane
        # mirror) or its two facets (a prism), facing the lamp, one-sided
        for lamp in ir.lamps:
            if lamp.reflector != r.id:
                continue
            verts, tris = _mirror_mesh(ir, lamp, r)
            mesh = UsdGeom.Mesh.Define(stage, prim.GetPath().AppendChild(_prim_name(lamp.id)))
            mesh.CreatePointsAttr(Vt.Vec3fArray([Gf.Vec3f(*map(float, p)) for p in verts]))
            mesh.CreateFaceVertexCountsAttr(Vt.IntArray([3] * len(tris)))
            mesh.CreateFaceVertexIndicesAttr(Vt.IntArray([int(i) for t in tris for i in t]))
            mesh.CreateSubdivisionSchemeAttr(UsdGeom.Tokens.none)
            mesh.CreateDoubleSidedAttr(False)
            mesh.CreateDisplayColorAttr(Vt.Vec3fArray([Gf.Vec3f(*adapted_linear_srgb(
                np.clip(r.reflectance.array_1nm, 0, 1), lighting_spectrum_1nm(ir, default)))]))
            _bind(stage, mesh.GetPrim(), f"/Booth/Materials/{_prim_name('reflector_' + r.id)}")
    if ir.diffuser is not None:
        d = ir.diffuser
        # a thin plate at the diffuser's mid-plane, seen from both sides, with a transmissive material
        mesh = UsdGeom.Mesh.Define(stage, "/Booth/Diffuser")
        cx, cy = float(d.centre_mm[0]), float(d.centre_mm[1])
        hx, hy = float(d.size_mm[0]) / 2, float(d.size_mm[1]) / 2
        z = float(d.z_mm)
        mesh.CreatePointsAttr(Vt.Vec3fArray([Gf.Vec3f(cx - hx, cy - hy, z), Gf.Vec3f(cx + hx, cy - hy, z),
                                             Gf.Vec3f(cx + hx, cy + hy, z), Gf.Vec3f(cx - hx, cy + hy, z)]))
        mesh.CreateFaceVertexCountsAttr(Vt.IntArray([4]))
        mesh.CreateFaceVertexIndicesAttr(Vt.IntArray([0, 1, 2, 3]))
        mesh.CreateSubdivisionSchemeAttr(UsdGeom.Tokens.none)
        mesh.CreateDoubleSidedAttr(True)
        prim = mesh.GetPrim()
        _bind(stage, prim, "/Booth/Materials/Diffuser")
        prim.CreateAttribute("lbscene:diffuser:scattering", Sdf.ValueTypeNames.String, custom=True).Set(
            json.dumps(d.scattering, sort_keys=True))
        prim.CreateAttribute("lbscene:diffuser:ior", Sdf.ValueTypeNames.Float, custom=True).Set(float(d.ior))
        prim.CreateAttribute("lbscene:diffuser:thickness_mm", Sdf.ValueTypeNames.Float,
                             custom=True).Set(float(d.thickness_mm))
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
        mesh.CreateDoubleSidedAttr(True)
        if o.material is not None and o.material in ir.materials:
            mat = ir.materials[o.material]
            mesh.CreateDisplayColorAttr(Vt.Vec3fArray([Gf.Vec3f(*adapted_linear_srgb(
                mat.reflectance.array_1nm, lighting_spectrum_1nm(ir, default)))]))
            _bind(stage, mesh.GetPrim(), f"/Booth/Materials/{_prim_name(mat.id)}")
            mesh.GetPrim().CreateAttribute("lbscene:occluder:material", Sdf.ValueTypeNames.Token,
                                           custom=True).Set(mat.id)

    cam = UsdGeom.Camera.Define(stage, "/Booth/Observer")
    _orient_camera(UsdGeom.Xformable(cam.GetPrim()), ir.observer.position_mm, ir.observer.look_at_mm)
    cam.CreateClippingRangeAttr(Gf.Vec2f(1.0, 100000.0))
    # the field of view frames the floor (viewing.observer_view): aperture / focal length = 2 tan(α/2)
    view = observer_view(ir)
    cam.CreateFocalLengthAttr(float(CAMERA_FOCAL_LENGTH))
    cam.CreateHorizontalApertureAttr(float(2 * CAMERA_FOCAL_LENGTH * math.tan(view["angle_x_rad"] / 2)))
    cam.CreateVerticalApertureAttr(float(2 * CAMERA_FOCAL_LENGTH * math.tan(view["angle_y_rad"] / 2)))
    return stage


def _mirror_mesh(ir: SceneIR, lamp, refl) -> tuple[np.ndarray, list[tuple[int, int, int]]]:
    """Triangles of a lamp's mirror: its rectangles
    (:func:`~lbscene.engine.light.effects.builtin.reflector.mirror_facets`), wound so that their
    normal faces the lamp."""
    from lbscene.engine.light.effects.builtin.reflector import mirror_facets

    pts, tris = [], []
    for r in mirror_facets(ir, lamp, refl):
        c, u, v = np.asarray(r.centre, float), np.asarray(r.u, float), np.asarray(r.v, float)
        k = len(pts)
        pts += [c - r.half[0] * u - r.half[1] * v, c + r.half[0] * u - r.half[1] * v,
                c + r.half[0] * u + r.half[1] * v, c - r.half[0] * u + r.half[1] * v]
        tris += [(k, k + 1, k + 2), (k, k + 2, k + 3)]        # counter-clockwise about normal = u × v
    return np.asarray(pts), tris


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
    """Write the stage and the files it references (``assets/``, relative to it)."""
    path = Path(path)
    for rel, text in stage_assets(ir, lighting).items():
        (path.parent / rel).parent.mkdir(parents=True, exist_ok=True)
        (path.parent / rel).write_text(text)
    path.write_text(stage_to_string(ir, lighting))


#: validators of usd-core that concern packages (.usdz) rather than a stage in a folder
_PACKAGE_VALIDATORS = ("usdUtilsValidators:UsdzPackageValidator", "usdUtilsValidators:RootPackageValidator",
                       "usdUtilsValidators:PackageEncapsulationValidator")


def validate_stage(path) -> list[str]:
    """Run usd-core's validation framework (``pxr.UsdValidation``, every registered validator
    except the ``.usdz`` package ones) on a stage file; returns the problems as text lines
    (empty: the stage passes).  usd-core's wheel has no ``usdchecker``/``ComplianceChecker``; this
    is the framework that replaces them."""
    from pxr import Usd, UsdValidation

    register_schema()
    reg = UsdValidation.ValidationRegistry()
    names = [str(m.name) for m in reg.GetAllValidatorMetadata() if str(m.name) not in _PACKAGE_VALIDATORS]
    ctx = UsdValidation.ValidationContext(list(reg.GetOrLoadValidatorsByName(names)))
    stage = Usd.Stage.Open(str(path))
    out = []
    for err in ctx.Validate(stage):
        if err.GetType() in (UsdValidation.ValidationErrorType.Error, UsdValidation.ValidationErrorType.Warn):
            sites = ", ".join(str(s.GetPrim().GetPath()) if s.IsPrim() else "stage" for s in err.GetSites())
            out.append(f"{err.GetValidator().GetMetadata().name}: {err.GetMessage()} ({sites})")
    return out
