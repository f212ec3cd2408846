"""
The declarative realtime render graph of one booth and lighting configuration.

``lbscene build`` calls :func:`write_build_products` for every lighting
configuration; it writes ``lighting/<NAME>/render_graph.json``, which the
moderngl runtime (:mod:`lbscene.runtimes.executor`) executes, and which
``lbscene export-web`` hands, with the same shader files, to the WebGL2 executor
of the web viewer (:mod:`lbscene.runtimes.web`).  The graph is
plain data (canonical JSON, byte-identical for the same IR):

``passes``
    Every pass; ``schedules`` says which run, in order (``analysis``: every
    intermediate image — four spectral images, float XYZ, drive values;
    ``deferred``: the spectral images, then one full-screen ``resolve``;
    ``realtime``: one raster pass, ``shade_display``, whose fragment shaders
    take each fragment from its 16 bands to 8-bit display colour).  ``raster``
    passes draw meshes (``draws``; a draw with ``fullscreen: true`` is one
    full-screen triangle), ``fullscreen`` passes run a fragment shader once per
    pixel.  Each names its program (GLSL ES 3.00 files in ``runtimes/shaders``;
    ``include`` / ``vertex_include``: library chunks ``lib_*.glsl`` put into
    the fragment / vertex shader, see :func:`compose_shader`), compile-time
    ``defines`` (``#define NAME value`` lines the runtime puts after
    ``#version``; the files default them), the textures it samples
    (``textures``: sampler uniform → texture resource), its ``uniforms``
    (uniform → binding, see below) and its ``outputs`` (colour attachments in
    location order, optional depth).
``resources``
    ``textures``: render targets (``size: "viewport"``) and data textures
    (``source`` says who fills them); ``meshes``: vertex streams built from the
    IR's surfaces (``surfaces``) or from a render-time parameter (the sample),
    with their attribute layout and where their per-vertex irradiance comes
    from.  ``sides: 2``: surfaces that can be seen from both sides (the platform
    and meshes: a luminaire housing turning with the platform can come between
    the observer and the sample) are drawn as two one-sided layers, the back
    one with flipped normals and its own irradiance; every draw culls back faces.
``bindings``
    A binding is a string naming a value the runtime computes per frame
    (``view.view_proj``, ``view.xyz_weights``, ``display.xyz_to_rgb`` …) or
    ``{"value": …}`` for a constant.  ``values`` documents each name.
``scene``
    Materials (band reflectances for this lighting), emitters (lamps as area
    and line lights for the LTC highlights), the sample placement and the
    platform.
``views``
    One per viewing geometry of the booth (or one ``default`` view): platform
    rotation, the geometry it realises at the sample, the default camera.
``parameters``
    What a render configuration supplies: view, sample, display, camera,
    viewport, diffuse light source, exposure, dithering.
``notes``
    (only when there is something to say) physics of the booth the graph does
    not represent: a rough diffuser plate's lobe, :func:`diffuser_notes`.

Spectral data flow: 16 bands travel as four RGBA32F blocks (band ``4k + c`` in
channel ``c`` of block ``k``) from the materials and irradiance through the
shading pass to ``spectral_radiance_0..3`` (W·sr⁻¹·m⁻²·nm⁻¹, band means);
``spectral_to_xyz`` weights them into absolute XYZ (Y in cd·m⁻²); ``display``
applies the display model; ``dither`` quantises to 8 bits with a blue-noise
mask.  The realtime schedule runs the same library functions
(``lib_spectral.glsl``, ``lib_display.glsl``, ``lib_dither.glsl``) inside the
shading pass: on a CPU rasteriser (llvmpipe) writing, clearing and re-reading
four RGBA32F images costs more than all the shading.

Examples
--------
>>> from lbscene.engine.scene.compile import compile_booth          # doctest: +SKIP
>>> g = build_render_graph(compile_booth("tests/data/minimal-booth"), "A")  # doctest: +SKIP
>>> g["schedules"]["analysis"]                                # doctest: +SKIP
['surfaces', 'spectral_to_xyz', 'display', 'dither']
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path
from typing import Any

import numpy as np

from lbscene.engine.light.geometry import rotation_matrix

__all__ = [
    "GRAPH_FORMAT",
    "GRAPH_VERSION",
    "GRAPH_FILENAME",
    "SHADER_DIR",
    "EMITTER_TEXELS",
    "PROFILE_SAMPLES",
    "SAMPLE_LIFT_MM",
    "build_render_graph",
    "diffuser_notes",
    "write_build_products",
    "load_render_graph",
    "rotation_matrix",
    "realised_geometry",
    "view_names",
    "shader_sources",
    "compose_shader",
    "SCHEDULES",
]

GRAPH_FORMAT = "lbscene.render_graph"
GRAPH_VERSION = 1
GRAPH_FILENAME = "render_graph.json"
SHADER_DIR = Path(__file__).resolve().parent / "shaders"
#: Texels per emitter row of the ``emitters`` data texture (see sample.frag).
EMITTER_TEXELS = 25
#: Samples of an emitter's angular profile f(θ), θ = 0…180°, stored in its row.
PROFILE_SAMPLES = 64
#: The sample sits this far above the platform/floor (avoids depth fighting).
SAMPLE_LIFT_MM = 0.5
#: Radius given to ``point`` lamps so that their highlight has a finite size.
POINT_LAMP_RADIUS_MM = 2.0
SPECTRAL_TARGETS = [f"spectral_radiance_{k}" for k in range(4)]


def _r(x: float) -> float:
    return float(f"{float(x):.10g}")


def _rv(v) -> list[float]:
    return [_r(x) for x in np.asarray(v, float).ravel()]


# --------------------------------------------------------------------------- geometry of views

def _illumination_centre(ir, lighting: str) -> np.ndarray:
    """Luminous-intensity-weighted centre of the lamps that are on (the geometry's light)."""
    s = np.asarray(ir.sample_position_mm, float)
    pts, w = [], []
    for lamp, level in ir.lamps_on(lighting):
        c = np.asarray(lamp.position_mm, float)
        d = np.linalg.norm(c - s) * 1e-3
        pts.append(c)
        w.append(max(level * lamp.peak_luminous_intensity_cd, 1e-12) / max(d * d, 1e-9))
    w = np.asarray(w)
    return (np.asarray(pts) * w[:, None]).sum(axis=0) / w.sum()


def _platform_frame(ir):
    if ir.platform is None:
        return np.zeros(3), np.array([1.0, 0.0, 0.0]), False
    return (np.asarray(ir.platform.pivot_mm, float), np.asarray(ir.platform.rotation_axis, float),
            bool(ir.platform.illumination_fixed_to_platform))


def realised_geometry(ir, lighting: str, rotation_deg: float, eye_mm=None) -> dict:
    """Illumination, viewing and aspecular angles (degrees) at the sample centre for a
    platform rotation, with the booth's observer (or ``eye_mm``)."""
    origin, axis, lamps_rotate = _platform_frame(ir)
    r = rotation_matrix(axis, rotation_deg)
    s = r @ (np.asarray(ir.sample_position_mm, float) - origin) + origin
    n = r @ np.array([0.0, 0.0, 1.0])
    c = _illumination_centre(ir, lighting)
    if lamps_rotate:
        c = r @ (c - origin) + origin
    eye = np.asarray(ir.observer.position_mm if eye_mm is None else eye_mm, float)
    l = (c - s) / np.linalg.norm(c - s)
    v = (eye - s) / np.linalg.norm(eye - s)
    t = l - n * (l @ n)
    t = t / np.linalg.norm(t) if np.linalg.norm(t) > 1e-9 else np.cross(n, [1.0, 0.0, 0.0])
    theta_i = np.degrees(np.arccos(np.clip(l @ n, -1.0, 1.0)))
    theta_v = np.degrees(np.arctan2(-(v @ t), v @ n))
    # (+ 0.0 turns a rounded −0.0 into 0.0)
    return {"illumination_deg": _r(round(theta_i, 4) + 0.0), "viewing_deg": _r(round(theta_v, 4) + 0.0),
            "aspecular_deg": _r(round(theta_i - theta_v, 4) + 0.0)}


def _solve_rotation(ir, lighting: str, geom) -> tuple[float, str]:
    """Platform rotation realising ``geom``'s aspecular angle (declared one wins)."""
    if geom.platform_rotation_deg is not None:
        return float(geom.platform_rotation_deg), "declared"
    if ir.platform is None:
        return 0.0, "no_platform"
    from scipy.optimize import brentq

    def err(phi):
        return realised_geometry(ir, lighting, phi)["aspecular_deg"] - geom.aspecular_deg

    grid = np.arange(-120.0, 120.5, 1.0)
    e = np.array([err(p) for p in grid])
    roots = []
    for i in range(len(grid) - 1):
        if np.sign(e[i]) != np.sign(e[i + 1]) and abs(e[i] - e[i + 1]) < 90:
            roots.append(brentq(err, grid[i], grid[i + 1], xtol=1e-6))
    if roots:
        return float(min(roots, key=abs)), "solved"
    return float(grid[int(np.argmin(np.abs(e)))]), "closest"


def view_names(ir) -> list[str]:
    """Names of the views of a booth: its geometries, or ``['default']``."""
    return [g.name for g in ir.geometries] or ["default"]


def _views(ir, lighting: str) -> list[dict]:
    origin, axis, lamps_rotate = _platform_frame(ir)
    out = []
    geoms = list(ir.geometries) or [None]
    for g in geoms:
        if g is None:
            rot, how = 0.0, "none"
            nominal = None
        else:
            rot, how = _solve_rotation(ir, lighting, g)
            nominal = {"name": g.name, "illumination_deg": g.illumination_deg,
                       "aspecular_deg": g.aspecular_deg, "viewing_deg": g.viewing_deg}
        r = rotation_matrix(axis, rot)
        s = r @ (np.asarray(ir.sample_position_mm, float) - origin) + origin
        out.append({
            "name": g.name if g is not None else "default",
            "geometry": nominal,
            "platform_rotation_deg": _r(round(rot, 6)),
            "rotation_source": how,
            "rotation": {"axis": _rv(axis), "origin_mm": _rv(origin), "angle_deg": _r(round(rot, 6))},
            "realised": realised_geometry(ir, lighting, rot),
            "camera": {"position_mm": _rv(ir.observer.position_mm), "look_at_mm": _rv(np.round(s, 6)),
                       "up": [0.0, 0.0, 1.0]},
        })
    return out


# --------------------------------------------------------------------------- scene description

def _material_bands(ir, material, lighting: str) -> tuple[list[float], str]:
    by = material.reflectance_bands_by_lighting.get(lighting)
    if by:
        return _rv(by), f"projected:{lighting}"
    return _rv(material.reflectance.bands), "band_means"


def _profile_samples(ir, lamp) -> list[float]:
    """f(θ) at PROFILE_SAMPLES angles 0…180° (1 everywhere without the angular_profile effect)."""
    theta = np.linspace(0.0, np.pi, PROFILE_SAMPLES)
    if "angular_profile" not in ir.effects:
        return [1.0] * PROFILE_SAMPLES
    from lbscene.engine.light.effects.physics import effect_params
    from lbscene.engine.light.effects.registry import get_effect
    from lbscene.engine.spectra.profiles import GaussianShape, profile_shape

    # as the effect reads its parameters (engine/light/effects/builtin/angular_profile.py): its lamp selection, the
    # declared profile, else its σ for lamps that declare none
    p = effect_params(get_effect("angular_profile"), ir.effects["angular_profile"])
    if p.lamps is not None and lamp.id not in p.lamps:
        return [1.0] * PROFILE_SAMPLES
    if lamp.profile.get("type") != "isotropic":
        shape = profile_shape(lamp.profile)
    elif p.sigma_deg is not None:
        shape = GaussianShape(float(p.sigma_deg))
    else:
        return [1.0] * PROFILE_SAMPLES
    if getattr(shape, "two_d", False):
        # the highlight shader takes f(θ) only: an IES file's C-planes are averaged here (the
        # diffuse light, from the forward model or the bake, honours them)
        c = np.radians(np.arange(0.0, 360.0, 5.0))
        T, C = np.meshgrid(theta, c, indexing="ij")
        return _rv(np.clip(shape(T, C).mean(axis=1), 0.0, None))
    return _rv(np.clip(shape(theta), 0.0, None))


def _emitters(ir, lighting: str) -> list[dict]:
    """Lamps that are on, as LTC emitters (band intensity at θ = 0, W·sr⁻¹·nm⁻¹)."""
    _, _, lamps_rotate = _platform_frame(ir)
    grid = ir.grid
    out = []
    trans = np.ones(grid.count)
    diffuser = None
    if ir.diffuser is not None and "diffuser" in ir.effects:
        from lbscene.engine.light.effects.physics import effect_params
        from lbscene.engine.light.effects.registry import get_effect

        # the effect's parameters as the forward model reads them: transmittance_scale and the
        # diffuse_fraction override (the straight part is what the highlight sees)
        dp = effect_params(get_effect("diffuser"), ir.effects["diffuser"])
        diffuser = ir.diffuser
        trans = grid.integrate(np.clip(diffuser.transmittance.array_1nm * dp.transmittance_scale,
                                       0.0, 1.0))
        fd = dp.diffuse_fraction
        if fd is None:
            fd = (float(diffuser.scattering.get("diffuse_fraction", 0.0))
                  if diffuser.scattering.get("type") == "lambertian" else 0.0)
        trans = trans * (1.0 - float(fd))
        if diffuser.scattering.get("type") == "roughness":
            from lbscene.engine.light.plates import slab_relative

            # a rough slab's straight transmittance at normal incidence (the lobe and T(θ) are not
            # represented: diffuser_notes says so)
            trans = trans * float(slab_relative(ir, np.ones(1))[0])
    for lamp, level in ir.lamps_on(lighting):
        emission = grid.integrate(ir.lamp_emission_1nm(lamp)) * level
        below = diffuser is not None and lamp.position_mm[2] > diffuser.z_mm
        if below:
            emission = emission * trans
        if lamp.kind == "tube":
            kind, half_l, half_w = "tube", lamp.length_mm / 2, max(lamp.radius_mm, 0.5)
        elif lamp.kind == "panel":
            kind, half_l, half_w = "panel", lamp.length_mm / 2, lamp.width_mm / 2
        else:
            radius = lamp.radius_mm if lamp.radius_mm > 0 else POINT_LAMP_RADIUS_MM
            # a sphere of radius r seen from anywhere: a facing square of equal area π r²
            kind, half_l, half_w = "sphere", 0.0, radius * np.sqrt(np.pi) / 2
        axis = np.asarray(lamp.axis, float)
        aim = np.asarray(lamp.aim, float)
        w_axis = np.cross(aim, axis)
        w_axis = w_axis / np.linalg.norm(w_axis) if np.linalg.norm(w_axis) > 1e-9 else np.zeros(3)
        out.append({
            "id": lamp.id, "group": lamp.group, "kind": kind,
            "centre_mm": _rv(lamp.position_mm), "axis": _rv(axis), "aim": _rv(aim),
            "width_axis": _rv(w_axis), "half_length_mm": _r(half_l), "half_width_mm": _r(half_w),
            "intensity_bands_W_sr_nm": _rv(emission),
            "profile": _profile_samples(ir, lamp),
            "through_diffuser": bool(below),
            "rotates_with_platform": lamps_rotate,
        })
    return out


def diffuser_notes(ir) -> list[str]:
    """What the realtime graph does not represent of the booth's diffuser plate (empty when
    nothing is left out): a ``roughness`` plate's scattering lobe and angular transmittance, an
    opal plate's scattered light in the highlights."""
    d = ir.diffuser
    if d is None or "diffuser" not in ir.effects:
        return []
    if d.scattering.get("type") == "lambertian":
        return [f"diffuser opal (diffuse fraction {float(d.scattering['diffuse_fraction']):g}): the LTC "
                f"highlights of lamps behind the plate see its regular part only (1 - f of its declared "
                f"total transmittance); its scattered light and its reflection are in the analytic "
                f"irradiance of surfaces"]
    if d.scattering.get("type") != "roughness":
        return []
    from lbscene.engine.light.plates import plate_slab

    r = float(d.scattering["roughness"])
    slab = plate_slab(ir)
    return [f"diffuser roughness {r:g} (GGX α = {r * r:.4g}): the LTC highlights of lamps behind the "
            f"plate are sharp and dimmed by its normal-incidence transmittance only; the rough slab's "
            f"lobe (90 % of its light within {float(slab.lobe_deg(1.0, 0.9)):.2g}° at normal incidence) "
            f"and its fall with incidence T(θ) are not represented there (the analytic irradiance "
            f"of surfaces has them)"]


def _surfaces(ir) -> dict[str, list[str]]:
    """Split the IR's surfaces into meshes: static box faces, static meshes, platform-mounted."""
    _, _, fixed = _platform_frame(ir)
    box, meshes, platform = [], [], []
    for s in ir.surfaces:
        if s.role == "platform":
            platform.append(s.id)
        elif s.role == "mesh":
            # meshes of booths whose luminaire turns with the platform are the luminaire's
            # (the IR does not tag mounted meshes; see the runtime's documentation)
            (platform if fixed else meshes).append(s.id)
        else:
            box.append(s.id)
    return {"booth": box, "booth_meshes": meshes, "platform": platform}


def shader_sources() -> dict[str, str]:
    """Every shader file of the runtime (stages ``.vert``/``.frag`` and library chunks
    ``.glsl``): name → source."""
    return {p.name: p.read_text() for p in sorted(SHADER_DIR.iterdir())
            if p.suffix in (".vert", ".frag", ".glsl")}


def compose_shader(source: str, defines=(), include=(), read=None) -> str:
    """The source a program compiles: the stage file's ``#version`` line, one ``#define NAME
    value`` line per define, the ``include`` chunks in order, then the rest of the file.

    This is the whole preprocessing a runtime does (string concatenation, the same in
    WebGL2); ``read(name)`` returns a chunk's text (default: the file in ``SHADER_DIR``).

    >>> compose_shader("#version 300 es\nvoid main() {}\n", [("A", 1)])
    '#version 300 es\n#define A 1\nvoid main() {}\n'
    """
    read = read or (lambda name: (SHADER_DIR / name).read_text())
    head = "".join(f"#define {k} {v}\n" for k, v in defines)
    libs = "".join(f"// ---- include {name}\n{read(name).rstrip()}\n// ---- end {name}\n" for name in include)
    if not head and not libs:
        return source
    first, _, rest = source.partition("\n")
    return f"{first}\n{head}{libs}{rest}"


def _shader_digest() -> dict[str, str]:
    return {name: hashlib.sha256(src.encode()).hexdigest()[:16]
            for name, src in shader_sources().items()}


# --------------------------------------------------------------------------- passes

def _vertex_layout() -> list[dict]:
    return [{"name": "a_position_mm", "components": 3}, {"name": "a_normal", "components": 3},
            {"name": "a_uv", "components": 2}, {"name": "a_material", "components": 1}] + [
        {"name": f"a_irradiance{k}", "components": 4} for k in range(4)]


#: GLSL ES 3.00 chunks (no ``#version``) a program can ``include``.
LIB_SPECTRAL = "lib_spectral.glsl"
LIB_DISPLAY = "lib_display.glsl"
LIB_DITHER = "lib_dither.glsl"
LIB_COATING = "lib_coating.glsl"
RESOLVE_LIBS = [LIB_SPECTRAL, LIB_DISPLAY, LIB_DITHER]
DISPLAY_DEFINES = {"TONE_KIND": "display.tone_kind", "GAMUT_MAPPING": "display.gamut_mapping",
                   "HIGHLIGHT_ROLLOFF": "display.highlight_rolloff"}
DISPLAY_UNIFORMS = {"u_display_linear": "display.linear", "u_tone_params": "display.tone_params",
                    "u_tone_lut_size": "display.tone_lut_size",
                    "u_highlight_knee": "display.highlight_knee", "u_highlight_max": "display.highlight_max"}
#: the effect-coating inputs of the sample draw (runtimes/coating.py, sample.frag COATING 1)
COATING_UNIFORMS = {"u_coating_spectra": "sample.coating_spectra", "u_coating_lobes": "sample.coating_lobes", "u_coating_alphas": "sample.coating_alphas",
                    "u_coating_beckmann": "sample.coating_beckmann", "u_coat_n": "sample.coat_n",
                    "u_coat_diffuse_t": "sample.coat_diffuse_transmittance",
                    "u_sample_size_mm": "sample.size_mm", "u_flakes": "sample.flakes",
                    "u_flake_density_per_mm2": "sample.flake_density_per_mm2",
                    "u_flake_area_mm2": "sample.flake_area_mm2", "u_flake_alpha": "sample.flake_alpha",
                    "u_flake_cell_mm": "sample.flake_cell_mm", "u_grain_sigma": "sample.grain_sigma",
                    "u_glint_bin": "sample.glint_bin", "u_lobe_luminance": "sample.lobe_luminance",
                    "u_flake_luminance": "sample.flake_luminance", "u_glint_spectrum": "sample.glint_spectrum",
                    "u_lamp_band_sum": "sample.lamp_band_sum", "u_sample_u_axis": "sample.u_axis"}
DITHER_UNIFORMS = {"u_noise_size": "dither.noise_size", "u_dither_amplitude": "dither.amplitude"}
RESOLVE_UNIFORMS = dict({"u_xyz_weights": "view.xyz_weights"}, **DISPLAY_UNIFORMS, **DITHER_UNIFORMS)
RESOLVE_TEXTURES = {"u_tone_lut": "tone_lut", "u_noise": "blue_noise"}


def _surface_draws(to_display: bool) -> list[dict]:
    """The draws of the booth and the sample.  ``to_display``: the realtime variant, whose
    fragment shaders finish the pixel (``SHADE_TO_DISPLAY 1``, resolve libraries included).

    The sample and the platform go first: drawn front to back, what they hide of the booth
    fails the (early) depth test instead of being shaded and overwritten."""
    surface_uniforms = {"u_view_proj": "view.view_proj", "u_model": "view.identity"}
    sample_uniforms = dict(surface_uniforms)
    sample_uniforms.update({
        "u_model": "sample.model",
        "u_eye_mm": "view.eye_mm",
        "u_illumination_mm": "view.illumination_centre_mm",
        "u_sample_geometry_count": "sample.geometry_count",
        "u_emitter_count": "view.emitter_count",
        "u_ltc_size": "ltc.size",
        "u_roughness": "sample.roughness",
        "u_specular_weight": "sample.specular_weight",
        "u_f0": "sample.f0",
    })
    sample_uniforms.update(COATING_UNIFORMS)
    booth_program = {"vertex": "surface.vert", "fragment": "booth.frag"}
    sample_program = {"vertex": "surface.vert", "fragment": "sample.frag", "vertex_include": [LIB_COATING]}
    booth_uniforms = dict(surface_uniforms)
    booth_textures = {"u_materials": "materials"}
    sample_textures = {"u_sample_reflectance": "sample_reflectance", "u_emitters": "emitters",
                       "u_ltc_minv": "ltc_minv", "u_ltc_mag": "ltc_mag"}
    booth_extra: dict = {}
    emitter_defines = {"EMITTER_KINDS": "view.emitter_kinds", "EMITTER_PROFILES": "view.emitter_profiles"}
    sample_extra: dict = {"defines": dict(emitter_defines, COATING="sample.coating")}
    if to_display:
        # diffuse booth surfaces: bands → XYZ per vertex (surface.vert, VERTEX_XYZ 1), then
        # display and dither per pixel; the sample: everything per pixel
        booth_program.update(vertex_include=[LIB_SPECTRAL], include=[LIB_DISPLAY, LIB_DITHER])
        sample_program["include"] = list(RESOLVE_LIBS)
        booth_uniforms.update(RESOLVE_UNIFORMS)
        sample_uniforms.update(RESOLVE_UNIFORMS)
        booth_textures.update(RESOLVE_TEXTURES)
        sample_textures.update(RESOLVE_TEXTURES)
        booth_extra = {"defines": dict(DISPLAY_DEFINES, SHADE_TO_DISPLAY={"value": 1}, VERTEX_XYZ={"value": 1})}
        sample_extra = {"defines": dict(DISPLAY_DEFINES, SHADE_TO_DISPLAY={"value": 1},
                                        COATING="sample.coating", **emitter_defines)}

    def booth(name, mesh, cull):
        return dict({"name": name, "mesh": mesh, "cull_back_faces": cull, "program": dict(booth_program),
                     "uniforms": dict(booth_uniforms), "textures": dict(booth_textures)}, **booth_extra)

    return [
        dict({"name": "sample", "mesh": "sample", "cull_back_faces": False, "program": dict(sample_program),
              "uniforms": sample_uniforms, "textures": sample_textures}, **sample_extra),
        booth("platform", "platform", True),
        booth("booth_meshes", "booth_meshes", True),
        booth("booth", "booth", True),
    ]


def _passes() -> list[dict]:
    return [
        {"name": "surfaces", "kind": "raster",
         "doc": "Booth and sample from the observer: spectral radiance in 4 RGBA32F blocks. "
                "Diffuse: band reflectance × per-vertex band irradiance / π; sample: "
                "reflectance interpolated per pixel between measured geometries by aspecular "
                "angle, plus GGX highlights of area and line lights by LTC.",
         "outputs": {"color": list(SPECTRAL_TARGETS), "depth": "depth"},
         "clear": {"color": [0.0, 0.0, 0.0, 0.0], "depth": 1.0},
         "draws": _surface_draws(False)},
        {"name": "spectral_to_xyz", "kind": "fullscreen",
         "doc": "16 band radiances → absolute XYZ (Y in cd/m²) with band weights for the light "
                "at the sample.",
         "program": {"vertex": "fullscreen.vert", "fragment": "spectral_to_xyz.frag", "include": [LIB_SPECTRAL]},
         "textures": {f"u_radiance{k}": SPECTRAL_TARGETS[k] for k in range(4)},
         "uniforms": {"u_xyz_weights": "view.xyz_weights"},
         "outputs": {"color": ["xyz"]}},
        {"name": "display", "kind": "fullscreen",
         "doc": "Absolute XYZ → display drive values with the display model (exposure, black "
                "and ambient flare, primaries, out-of-gamut mapping, tone response); alpha = "
                "out-of-gamut excess.",
         "program": {"vertex": "fullscreen.vert", "fragment": "display.frag", "include": [LIB_DISPLAY]},
         "textures": {"u_xyz": "xyz", "u_tone_lut": "tone_lut"},
         "defines": dict(DISPLAY_DEFINES),
         "uniforms": dict(DISPLAY_UNIFORMS),
         "outputs": {"color": ["display_drive"]}},
        {"name": "dither", "kind": "fullscreen",
         "doc": "Blue-noise spatial dithering, then quantisation to 8 bits per channel.",
         "program": {"vertex": "fullscreen.vert", "fragment": "dither.frag", "include": [LIB_DITHER]},
         "textures": {"u_drive": "display_drive", "u_noise": "blue_noise"},
         "uniforms": dict(DITHER_UNIFORMS),
         "outputs": {"color": ["display_rgba8"]}},
        {"name": "resolve", "kind": "fullscreen",
         "doc": "spectral_to_xyz, display and dither fused into one full-screen pass (the deferred "
                "schedule): the same functions without the intermediate XYZ and drive images.",
         "program": {"vertex": "fullscreen.vert", "fragment": "resolve.frag", "include": list(RESOLVE_LIBS)},
         "textures": dict({f"u_radiance{k}": SPECTRAL_TARGETS[k] for k in range(4)}, **RESOLVE_TEXTURES),
         "defines": dict(DISPLAY_DEFINES),
         "uniforms": dict(RESOLVE_UNIFORMS),
         "outputs": {"color": ["display_rgba8"]}},
        {"name": "shade_display", "kind": "raster",
         "doc": "The realtime schedule's single pass: the surfaces pass's shading, each fragment "
                "then taken through spectral → XYZ → display → dither (the same library functions "
                "as the full-screen passes) and written as 8-bit colour; the 16 bands stay in "
                "registers as 4 vec4 blocks instead of round-tripping through four RGBA32F images. "
                "Pixels no surface covers get the background draw: zero radiance through the same "
                "functions, at the far plane (depth test <=, so only where the depth is still clear).",
         "outputs": {"color": ["display_rgba8"], "depth": "depth"},
         "clear": {"color": [0.0, 0.0, 0.0, 1.0], "depth": 1.0},
         "draws": _surface_draws(True) + [
             {"name": "background", "fullscreen": True, "depth_func": "<=", "depth_write": False,
              "program": {"vertex": "fullscreen.vert", "fragment": "background.frag",
                          "include": [LIB_DISPLAY, LIB_DITHER]},
              # the value as GLSL text: a JSON number would lose its ".0" (WebGL reads this graph too)
              "defines": dict(DISPLAY_DEFINES, FULLSCREEN_Z={"value": "1.0"}),
              "uniforms": dict(DISPLAY_UNIFORMS, **DITHER_UNIFORMS),
              "textures": dict(RESOLVE_TEXTURES)}]},
    ]


#: Which passes run, in order.  ``analysis`` keeps every intermediate image (four spectral
#: images, float XYZ, drive values with the out-of-gamut excess); ``deferred`` shades into the
#: spectral images and resolves them in one full-screen pass; ``realtime`` shades straight to
#: 8-bit display colour (one raster pass, no float images).  All three give the same 8-bit image.
SCHEDULES = {"analysis": ["surfaces", "spectral_to_xyz", "display", "dither"],
             "deferred": ["surfaces", "resolve"],
             "realtime": ["shade_display"]}


_VALUES_DOC = {
    "view.view_proj": "mat4, booth millimetres → clip space (camera of the view / config)",
    "view.identity": "mat4 identity (geometry is placed per view on the CPU)",
    "sample.model": "mat4, rigid transform of the sample after its placement: a tilt about its centre "
                    "(the web viewer's tilt control; identity in renders). The sample's per-vertex "
                    "irradiance stays that of the untilted sample",
    "view.eye_mm": "vec3, camera position (mm)",
    "view.illumination_centre_mm": "vec3, centre of the light defining the geometry, rotated",
    "view.emitter_count": "int, rows of the emitters texture",
    "view.emitter_kinds": "int, the kinds among the emitters (bits: 1 sphere, 2 tube, 4 panel; a #define: "
                          "sample.frag leaves out the highlight code of absent kinds)",
    "view.emitter_profiles": "int, 1: some emitter's angular profile is not flat (0: sample.frag leaves "
                             "out the profile lookup; a #define)",
    "view.xyz_weights": "mat4x3[4], XYZ (Y in cd/m²) per unit band radiance: 683·∫_band E·cmf dλ / E_band "
                        "for the spectral irradiance E at the sample (colour module's band weights when "
                        "available); bands 1 and 16 also take the light below 390 / above 710 nm",
    "sample.geometry_count": "int, measured geometries (columns of sample_reflectance)",
    "sample.roughness": "float, GGX roughness r (α = r²) of the clear coat",
    "sample.specular_weight": "float, gloss_GU / 100 (0: matte, no highlights)",
    "sample.f0": "float, Fresnel reflectance at normal incidence of the coat (n = 1.567: 0.0492)",
    "sample.coating": "int, 1: an effect coating (sample.frag COATING 1: flop BRDF, flakes), 0: "
                      "reflectance per geometry (a #define)",
    "sample.coating_spectra": "vec4[16], band blocks (projected for the light at the sample) of the diffuse "
                              "base a (0..3) and lobe weights s_1..s_3 (4..15); zeros without a coating",
    "sample.coating_lobes": "int, lobes of the flop BRDF",
    "sample.coating_alphas": "vec3, roughness of each lobe inside the clear coat",
    "sample.coating_beckmann": "int, 1: Beckmann lobes, 0: GGX",
    "sample.coat_n": "float, refractive index of the clear coat",
    "sample.coat_diffuse_transmittance": "float, transmittance of the clear coat for diffuse light",
    "sample.size_mm": "vec2, sample width and height (uv × size = sample-space millimetres)",
    "sample.flakes": "int, 1: sparkle and graininess from flakes",
    "sample.flake_density_per_mm2": "float, flakes per mm²",
    "sample.flake_area_mm2": "float, mean flake area × the mean share of a glint other flakes leave visible",
    "sample.flake_alpha": "float, Beckmann α of the flake normals",
    "sample.flake_cell_mm": "float, side of the sample-space cell whose flakes one hash draws (per view)",
    "sample.grain_sigma": "float, relative standard deviation of the diffuse part per cell (graininess)",
    "sample.glint_bin": "float, slope-space bin of the half vector for the flakes' draw",
    "sample.lobe_luminance": "vec3, luminance-weighted lobe weights (the glints' mean is at most the lobes')",
    "sample.flake_luminance": "float, luminance-weighted flake reflectance",
    "sample.glint_spectrum": "vec4[4], flake reflectance × the emitters' mean band intensity Ī",
    "sample.lamp_band_sum": "float, Σ over bands of Ī (an emitter's level relative to the mean)",
    "sample.u_axis": "vec3, the sample's u axis placed for the view (turned by sample.model in the shader)",
    "display.highlight_rolloff": "int, 1: luminance above display.highlight_knee of white is rolled off "
                                 "(extended Reinhard, display.highlight_max × white → white) instead of "
                                 "clipped (a #define)",
    "display.highlight_knee": "float, fraction of the display white where the roll-off starts",
    "display.highlight_max": "float, luminance (× display white) the roll-off brings to white",
    "ltc.size": "int, side of the LTC tables",
    "display.exposure": "float, absolute XYZ → display XYZ scale (cd/m² per cd/m²)",
    "display.adaptation": "mat3, chromatic adaptation: XYZ under the lighting → corresponding XYZ "
                          "under the display white (CAT16, or the identity)",
    "display.xyz_offset": "vec3, XYZ subtracted before the matrix: display black + reflected ambient",
    "display.xyz_to_rgb": "mat3, display XYZ → linear channel values (1 = channel peak)",
    "display.tone_kind": "int, 0 sRGB piecewise, 1 GOG (gain, offset, gamma), 2 LUT (a #define)",
    "display.tone_params": "vec4[3] per channel (gain, offset, gamma, unused) for GOG",
    "display.tone_lut_size": "int, entries of tone_lut (inverse tone response, linear → drive)",
    "display.gamut_mapping": "int, 0 clip, 1 chroma (a #define)",
    "display.inv_y_span": "float, 1 / (white − black luminance) of the display, for the chroma mapping",
    "display.linear": "mat4, the display model's affine part: (absolute XYZ, 1) → (linear channel values "
                      "before clipping, y) = (xyz_to_rgb · (exposure · adaptation · XYZ − xyz_offset), "
                      "(exposure · (adaptation · XYZ)_Y − xyz_offset_Y) · inv_y_span) (lib_display.glsl)",
    "dither.noise_size": "int, side of the blue-noise mask (a power of two)",
    "dither.amplitude": "float, 1: dithering on, 0: plain rounding",
}


def build_render_graph(ir, lighting: str) -> dict[str, Any]:
    """The render graph (a JSON-ready dict) of ``ir`` under ``lighting``."""
    if lighting not in ir.lighting:
        raise KeyError(f"unknown lighting {lighting!r}")
    from lbscene.engine.spectra.bands import band_labels

    grid = ir.grid
    materials = []
    for i, (mid, m) in enumerate(sorted(ir.materials.items())):
        bands, source = _material_bands(ir, m, lighting)
        materials.append({"id": mid, "index": i, "type": m.type, "gloss_GU": _r(m.gloss_GU),
                          "roughness": _r(m.roughness), "reflectance_bands": bands,
                          "band_source": source})
    mat_index = {m["id"]: m["index"] for m in materials}
    surfaces = [{"id": s.id, "role": s.role, "material_index": mat_index[s.material],
                 "triangles": len(s.triangles)} for s in ir.surfaces]
    split = _surfaces(ir)
    emitters = _emitters(ir, lighting)
    origin, axis, fixed = _platform_frame(ir)
    n_blocks = (grid.count + 3) // 4
    textures: dict[str, dict] = {}
    for k in range(n_blocks):
        textures[SPECTRAL_TARGETS[k]] = {"format": "rgba32f", "size": "viewport", "usage": "target",
                                         "bands": list(range(4 * k, min(4 * k + 4, grid.count)))}
    textures.update({
        "depth": {"format": "depth24", "size": "viewport", "usage": "depth"},
        "xyz": {"format": "rgba32f", "size": "viewport", "usage": "target",
                "units": "XYZ with Y in cd·m⁻² (absolute), alpha 1"},
        "display_drive": {"format": "rgba32f", "size": "viewport", "usage": "target",
                          "units": "display drive values 0..1; alpha: out-of-gamut excess"},
        "display_rgba8": {"format": "rgba8", "size": "viewport", "usage": "target"},
        "materials": {"format": "rgba32f", "size": [n_blocks, len(materials)], "usage": "data",
                      "source": "scene.materials", "layout": "row = material index, texel k = bands 4k..4k+3"},
        "emitters": {"format": "rgba32f", "size": [EMITTER_TEXELS, max(len(emitters), 1)], "usage": "data",
                     "source": "view.emitters",
                     "layout": "row per emitter: 0 centre_mm+kind(0 sphere,1 tube,2 panel), 1 axis+half_length_mm, "
                               "2 aim+half_width_mm, 3 width_axis+0, 4..7 intensity bands (W/sr/nm), "
                               "8..23 profile f(θ) at 64 angles 0..180°, 24 XYZ of the intensity bands "
                               "(view.xyz_weights: the realtime schedule sums the highlights in XYZ) + 0"},
        "ltc_minv": {"format": "rgba32f", "size": "ltc", "usage": "data", "source": "builtin:ltc_ggx.minv"},
        "ltc_mag": {"format": "rgba32f", "size": "ltc", "usage": "data", "source": "builtin:ltc_ggx.mag"},
        "sample_reflectance": {"format": "rgba32f", "size": ["sample.geometry_count", n_blocks + 1],
                               "usage": "data", "source": "parameter:sample",
                               "layout": "column per measured geometry sorted by aspecular angle; rows "
                                         "0..3 band blocks (projected for the light at the sample), "
                                         "row 4 x = aspecular angle (deg)"},
        "tone_lut": {"format": "rgba32f", "size": ["display.tone_lut_size", 1], "usage": "data",
                     "source": "parameter:display"},
        "blue_noise": {"format": "rgba32f", "size": ["dither.noise_size", "dither.noise_size"],
                       "usage": "data", "source": "colour.dither (builtin fallback)",
                       "layout": "r: the mask; g, b: the mask shifted by the channel offsets (x, y) of "
                                 "channels G and B (colour.dither.channel_offsets_xy, else (s/2, s/3) "
                                 "and (s/3, s/2)): texel (x, y) of g = mask((x + dx) mod s, (y + dy) mod s)"},
    })
    attrs = _vertex_layout()
    meshes = {
        "booth": {"surfaces": split["booth"], "attributes": attrs, "placement": "static",
                  "tessellation": "grid, cells <= 1/48 of the booth's largest dimension"},
        "booth_meshes": {"surfaces": split["booth_meshes"], "attributes": attrs, "placement": "static",
                         "tessellation": "triangles split to edges <= 1/24 of the largest dimension",
                         "sides": 2},
        "platform": {"surfaces": split["platform"], "attributes": attrs, "placement": "platform",
                     "tessellation": "as booth / booth_meshes", "sides": 2},
        "sample": {"source": "parameter:sample", "attributes": attrs, "placement": "platform",
                   "tessellation": "16 × 16 grid over the sample's size_mm"},
    }
    irradiance = {
        "analytic": "lbscene.engine.light.forward.ForwardModel(ir, lighting).spectral_irradiance_bands at each "
                    "vertex (lamps with every enabled effect; for views that turn the luminaire with "
                    "the platform, evaluated in the platform's frame)",
        "baked": "bake products of this lighting: environment map at the sample per geometry "
                 "(cosine-weighted → irradiance of the sample), floor irradiance map (floor vertices); "
                 "other vertices analytic",
    }
    graph = {
        "format": GRAPH_FORMAT, "version": GRAPH_VERSION,
        "booth": ir.booth_name, "ir_hash": ir.content_hash, "ir": "../../scene.ir.json",
        "lighting": lighting,
        "bands": dict(grid.to_json(), blocks=n_blocks, labels=band_labels(grid)),
        "requires": {"glsl": "300 es", "max_draw_buffers": n_blocks,
                     "webgl2_extensions": ["EXT_color_buffer_float"],
                     "note": "float textures are read with texelFetch only (no float filtering); "
                             "the realtime schedule renders to RGBA8 only (no float render targets)"},
        "units": {"length": "mm", "spectral_radiance": "W·sr⁻¹·m⁻²·nm⁻¹ (band mean)",
                  "spectral_irradiance": "W·m⁻²·nm⁻¹ (band mean)", "intensity": "W·sr⁻¹·nm⁻¹",
                  "xyz": "Y in cd·m⁻²"},
        "parameters": {
            "view": {"values": [v["name"] for v in _views(ir, lighting)]},
            "sample": {"kind": "sample", "doc": "reflectance per geometry, gloss, size"},
            "display": {"kind": "display"},
            "camera": {"default": "observer looking at the sample centre", "vertical_fov_deg": 30.0},
            "viewport": {"min_px": 16, "max_px": 8192},
            "diffuse": {"values": ["auto", "baked", "analytic"], "default": "auto"},
            "exposure": {"values": ["relative_white", "absolute"], "default": "relative_white"},
            "dither": {"default": True},
        },
        "scene": {
            "materials": materials,
            "surfaces": surfaces,
            "emitters": emitters,
            "sample_placement": {"centre_mm": _rv(ir.sample_position_mm), "normal": [0.0, 0.0, 1.0],
                                 "u_axis": [1.0, 0.0, 0.0], "lift_mm": SAMPLE_LIFT_MM},
            "platform": {"present": ir.platform is not None, "origin_mm": _rv(origin), "axis": _rv(axis),
                         "luminaire_turns_with_platform": fixed},
        },
        "views": _views(ir, lighting),
        "resources": {"textures": textures, "meshes": meshes, "irradiance": irradiance},
        "passes": _passes(),
        "schedules": SCHEDULES,
        "default_schedule": "realtime",
        "values": _VALUES_DOC,
        "outputs": {"image": "display_rgba8", "xyz": "xyz", "spectral": list(SPECTRAL_TARGETS[:n_blocks])},
        "shaders": _shader_digest(),
    }
    notes = diffuser_notes(ir)
    if notes:
        graph["notes"] = notes
    return json.loads(json.dumps(graph))  # plain JSON types only


def write_build_products(ir, lighting_name: str, folder: Path) -> list[Path]:
    """``lbscene build`` hook: write ``render_graph.json`` for one lighting configuration."""
    from lbscene.engine.scene.ir import canonical_json

    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    graph = build_render_graph(ir, lighting_name)
    path = folder / GRAPH_FILENAME
    text = json.dumps(json.loads(canonical_json(graph)), indent=1, sort_keys=True, ensure_ascii=False)
    path.write_text(text + "\n")
    return [path]


def load_render_graph(path: Path) -> dict[str, Any]:
    """Read a render graph written by :func:`write_build_products` (checks format/version)."""
    d = json.loads(Path(path).read_text())
    if d.get("format") != GRAPH_FORMAT or d.get("version") != GRAPH_VERSION:
        raise ValueError(f"{path}: not a {GRAPH_FORMAT} version {GRAPH_VERSION} file")
    return d
