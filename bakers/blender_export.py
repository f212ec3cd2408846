"""
The booth as a Blender file (``lbscene export-blender BOOTH -o booth.blend``).

The file is the Cycles scene of ``lbscene bake`` (:class:`~lbscene.bakers.blender_scene.BlenderScene`
built from the same :func:`~lbscene.bakers.from_ir.lighting_job` of every lighting), rendered
once in RGB instead of band by band, so that it holds one definition of the light:

* **Lamps** are the surfaces the bake makes them: a tube is an emitting cylinder of the tube's
  length and diameter (its caps where the booth has them), a panel an emitting rectangle of its
  size, a bulb an emitting sphere of its radius, a point lamp a Blender point light (its Power
  the watts, its node colour the chromaticity with peak 1: I = P · colour / 4π).  An emitting
  surface's Emission Strength is its radiance in W·sr⁻¹·m⁻² and its colour the chromaticity
  (peak 1): a Lambertian emitter of area A sends π · A · Strength · colour W.  Angular
  profiles, tube-end falloff, spectral filters and reflector images are the bake's node trees.
* **Watts** follow Blender's radiometric convention: an RGB value of light is radiant power in
  W (radiance in W·sr⁻¹·m⁻², intensity in W·sr⁻¹) whose luminous counterpart is
  683 lm/W × its Rec. 709 luminance ``Y = 0.2126 R + 0.7152 G + 0.0722 B``.  The emitters'
  band values (per nm) become

  ``rgb = M_709 · Σ_b v_b · ∫_band x̄ȳz̄(λ) dλ``

  with ``M_709`` the IEC 61966-2-1 XYZ → linear sRGB matrix, so ``683 · Y(rgb)`` is the
  luminance (or luminous intensity) of the spectrum, as the bake's photometry
  (683 lm/W · Σ E_b ∫_band V dλ) counts it: an illuminance E_v in lx rendered in Blender is
  ``683 · Y(E_rgb)``, a white sample (ρ = 0.8) under 2000 lx has radiance 2000·ρ/(683 π) ≈ 0.75 at
  exposure 0.  A spectrum outside the Rec. 709 gamut (a narrow-band or UV lamp) has negative
  components: they are cut to 0 and the rest scaled to keep ``Y``.  A point light's power P
  gives P/4π W·sr⁻¹, an Emission shader's
  colour × strength is the surface's radiance (both verified by tests/bakers/test_radiometry.py).
* **Surfaces** (reflectances, the diffuser's transmittance) are their colour under D65
  (Blender's white): ``rgb = N · M_709 · Σ_b ρ_b S_b X̄_b / Σ_b S_b Ȳ_b`` with ``N`` mapping
  ρ = 1 to (1, 1, 1).
* **Lightings**: one collection ``lighting <name>`` per lighting holding its lamps (and what
  differs between lightings: the bodies of the lamps that are off, mirror plates); the
  collection ``booth`` holds what all share.  The first lighting is on; switch by ticking a
  collection's checkbox in the outliner (only one at a time).
* **Camera**: the observer's eye (``observer.position_mm``) looking at ``look_at_mm``; its
  field of view frames the booth's floor (:func:`lbscene.engine.scene.viewing.observer_view`,
  the USD stage's camera too).
* **Mirrors** are the bake's plates behind each reflector lamp; a camera ray sees them as a
  mirror of the reflector's reflectance (Glossy BSDF), every other ray as the absorbing plate
  the bake has (the light they send is the bake's image emitter, exact).

Lengths are metres (1 Blender unit = 1 m, booth millimetres × 10⁻³), booth coordinates
(+z up).  What the file cannot hold: spectra (RGB only: a metameric sample looks the same under
every lighting), effects without a Cycles backend (named in the export's notes).
"""

from __future__ import annotations

import json
import math
import subprocess
import sys
import tempfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Iterable

import numpy as np

from .job import BakeJob, load_job, save_job

__all__ = ["band_rgb_matrices", "export_blender", "BlenderExport", "build_blend", "XYZ_TO_LINEAR_SRGB",
           "REC709_Y", "LIGHTING_ROLES", "main"]

#: IEC 61966-2-1 XYZ → linear sRGB (Rec. 709 primaries, D65 white): Blender's scene-linear space
XYZ_TO_LINEAR_SRGB = np.array([[3.2404542, -1.5371385, -0.4985314],
                               [-0.9692660, 1.8760108, 0.0415560],
                               [0.0556434, -0.2040259, 1.0572252]])
#: luminance of linear Rec. 709: the Y row of the inverse of :data:`XYZ_TO_LINEAR_SRGB`
REC709_Y = np.linalg.inv(XYZ_TO_LINEAR_SRGB)[1]
#: roles of the job's meshes that go into a lighting's collection even where all lightings share them
LIGHTING_ROLES = ("lamp_body", "mirror")
#: render samples written into the file (a user's preview; tests set their own)
DEFAULT_SAMPLES = 128


def band_rgb_matrices(bands) -> tuple[np.ndarray, np.ndarray]:
    """``(E, F)``, both (3, bands): emitter band values (per nm) → Blender RGB watts, and a
    reflectance or transmittance → its RGB under D65 (see the module docstring).

    >>> from lbscene.bakers.job import BandGridSpec
    >>> E, F = band_rgb_matrices(BandGridSpec())
    >>> bool(np.allclose(F @ np.ones(16), 1.0))
    True
    """
    import colour

    from lbscene.engine.spectra.evaluate import cmfs_1nm

    grid = bands.grid() if hasattr(bands, "grid") else bands
    cmf = cmfs_1nm()                                         # (471, 3)
    xyz_b = grid.integrate(cmf.T) * grid.width_nm            # (3, nb): ∫_band cmf dλ
    E = XYZ_TO_LINEAR_SRGB @ xyz_b
    d65 = colour.SDS_ILLUMINANTS["D65"].copy().align(colour.SpectralShape(360, 830, 1)).values
    s_b = grid.integrate(d65)                                # band means of D65
    w = xyz_b * s_b[None, :] / float(xyz_b[1] @ s_b)
    F = XYZ_TO_LINEAR_SRGB @ w
    F = F / (F @ np.ones(grid.count))[:, None]               # ρ = 1 → (1, 1, 1)
    return E, F


@dataclass
class BlenderExport:
    """What :func:`export_blender` wrote."""

    booth: str
    out: Path
    lightings: list[str]
    camera: dict
    notes: list[str] = field(default_factory=list)

    def to_json(self) -> dict:
        return {"booth": self.booth, "out": str(self.out), "lightings": self.lightings,
                "camera": {"angle_x_deg": math.degrees(self.camera["angle_x_rad"]),
                           "angle_y_deg": math.degrees(self.camera["angle_y_rad"]),
                           "resolution": self.camera["resolution"],
                           "position_mm": self.camera["position_mm"],
                           "look_at_mm": self.camera["look_at_mm"]},
                "notes": self.notes}


def _child_env() -> dict:
    from .executor import _child_env as env

    return env()


def export_blender(booth: Path | str, out: Path | str, *, lightings: Iterable[str] | None = None,
                   allowed_dirs: Iterable[Path] = ()) -> BlenderExport:
    """Write a booth's Blender file: every lighting (or those named) as a collection.

    Parameters
    ----------
    booth : path or str
        Booth folder, ``booth.yaml`` or a shipped booth's name.
    out : path or str
        The ``.blend`` to write (never over a file lbscene did not write).
    lightings : iterable of str, optional
        Lightings to include (default: all; the first is the one switched on).
    allowed_dirs : iterable of path
        Extra folders file references may point into.

    Returns
    -------
    BlenderExport

    Raises
    ------
    LbsceneUserError
        ``LB500`` an ``out`` that is not ``.blend``, ``LB202`` an unknown lighting, ``LB604``
        without ``bpy``, ``LB600`` Blender failed, ``LB610``–``LB612`` an output the policy
        refuses, and the booth's located errors.
    """
    from importlib.util import find_spec

    from lbscene.schemas.booth import Booth

    from lbscene.engine.files.diagnostics import Diagnostic, LbsceneUserError, Severity, SourceLocation
    from lbscene.engine.files.load import display_path, load_document
    from lbscene.engine.files.outputs import check_output_file, output_path, register_input
    from lbscene.engine.files.processes import dies_with_parent
    from lbscene.engine.scene.compile import compile_loaded, find_booth_file
    from lbscene.engine.scene.lint import lint_booth
    from lbscene.engine.scene.viewing import observer_view

    from .from_ir import lighting_job

    out = Path(out)
    if out.suffix.lower() != ".blend":
        raise LbsceneUserError(Diagnostic("LB500", "--out must be a .blend file", SourceLocation("<arguments>"),
                                          value=out.name, expected="a name ending in .blend"))
    booth_file = find_booth_file(Path(booth))
    register_input(booth_file)
    check_output_file(out, option="--out")
    if find_spec("bpy") is None:
        raise LbsceneUserError(Diagnostic("LB604", "export-blender needs Blender's Python module bpy",
                                          SourceLocation("<environment>"),
                                          expected="pip install 'lbscene[bake]'"))
    doc = load_document(booth_file, Booth, allowed_dirs=allowed_dirs)
    errors = [d for d in lint_booth(doc) if d.severity is Severity.ERROR]
    if errors:
        raise LbsceneUserError(errors)
    ir = compile_loaded(doc)
    names = list(ir.lighting) if lightings is None else list(dict.fromkeys(lightings))
    for name in names:
        if name not in ir.lighting:
            raise LbsceneUserError(Diagnostic(
                "LB202", f"--lighting: booth {ir.booth_name!r} has no lighting configuration {name!r}",
                SourceLocation(display_path(booth_file)), value=repr(name),
                expected=f"one of {', '.join(ir.lighting)}"))
    if not names:
        raise LbsceneUserError(Diagnostic("LB500", "no lighting to export", SourceLocation("<arguments>"),
                                          expected=f"one of {', '.join(ir.lighting)}"))
    jobs = [(name, lighting_job(ir, name, environment=False, maps=False, grid=True)) for name in names]
    notes = sorted({n for _, j in jobs for n in (j.source.get("notes") or "").split("; ") if n})
    cam = observer_view(ir)
    mirrors = {}
    for lamp in ir.lamps:
        if lamp.reflector and lamp.reflector in ir.reflectors:
            refl = ir.reflectors[lamp.reflector]
            mirrors[lamp.id] = {"reflectance_bands": [float(x) for x in ir.grid.integrate(
                np.clip(refl.reflectance.array_1nm, 0, 1))]}
    spec = {"booth": ir.booth_name, "lightings": names, "camera": cam, "mirrors": mirrors,
            "lamps": {lp.id: {"kind": lp.kind} for lp in ir.lamps}}
    with tempfile.TemporaryDirectory(prefix="lbscene-blend-") as tmp:
        tmp = Path(tmp)
        for i, (_, job) in enumerate(jobs):
            save_job(job, tmp / f"job{i}.json")
        (tmp / "spec.json").write_text(json.dumps(spec), encoding="utf-8")
        with output_path(out, suffix=".blend", option="--out") as target:
            cmd = dies_with_parent([sys.executable, "-m", "lbscene.bakers.blender_export", str(tmp),
                                    str(target)])
            res = subprocess.run(cmd, capture_output=True, text=True, env=_child_env(),
                                 encoding="utf-8", errors="replace")
            if res.returncode != 0 or not target.is_file():
                tail = (res.stderr or res.stdout)[-1500:].strip()
                raise LbsceneUserError(Diagnostic("LB600", "Blender could not write the file",
                                                  SourceLocation(display_path(out)), value=tail))
    return BlenderExport(ir.booth_name, out, names, cam, notes)


# --------------------------------------------------------------------------- inside Blender


def _matrix(rot_cols: np.ndarray, pos_m) -> "object":
    from mathutils import Matrix

    m = Matrix.Identity(4)
    for r in range(3):
        for c in range(3):
            m[r][c] = float(rot_cols[r, c])
        m[r][3] = float(pos_m[r])
    return m


def _key(item) -> str:
    return item.model_dump_json()


def _mirror_material(name: str, rgb) -> "object":
    """Glossy mirror for camera rays, the bake's absorbing black for every other ray."""
    import bpy

    m = bpy.data.materials.new(name)
    nt = m.node_tree
    nt.nodes.clear()
    out = nt.nodes.new("ShaderNodeOutputMaterial")
    gl = nt.nodes.new("ShaderNodeBsdfGlossy")
    gl.distribution = "GGX"
    gl.inputs["Roughness"].default_value = 0.0
    gl.inputs["Color"].default_value = (*[float(c) for c in rgb], 1.0)
    black = nt.nodes.new("ShaderNodeBsdfDiffuse")
    black.inputs["Color"].default_value = (0.0, 0.0, 0.0, 1.0)
    lp = nt.nodes.new("ShaderNodeLightPath")
    mix = nt.nodes.new("ShaderNodeMixShader")
    nt.links.new(lp.outputs["Is Camera Ray"], mix.inputs["Fac"])
    nt.links.new(black.outputs[0], mix.inputs[1])
    nt.links.new(gl.outputs[0], mix.inputs[2])
    nt.links.new(mix.outputs[0], out.inputs["Surface"])
    return m


def build_blend(jobs: list[BakeJob], spec: dict, out: Path) -> None:
    """Build every lighting's scene with :class:`BlenderScene` in RGB and save ``out`` (needs bpy)."""
    import bpy

    from .blender_scene import MM, BlenderScene

    names = spec["lightings"]
    E, F = band_rgb_matrices(jobs[0].bands)

    def common(attr):
        # what every lighting has alike, except what belongs to a lighting's lamps (the bodies of
        # the lamps it leaves off, the mirrors behind those it switches on)
        keys = [{_key(x) for x in getattr(j, attr) if getattr(x, "role", None) not in LIGHTING_ROLES}
                for j in jobs]
        return set.intersection(*keys)

    shared_meshes, shared_sheets = common("meshes"), common("sheets")
    first = jobs[0]
    base = first.model_copy(update={
        "meshes": tuple(m for m in first.meshes if _key(m) in shared_meshes),
        "sheets": tuple(s for s in first.sheets if _key(s) in shared_sheets),
        "emitters": (), "products": ()})
    scene_b = BlenderScene.build(base)
    scene_b.camera_sees_lamps = True      # a user sees the lamps shine (the bake's maps see them black)
    scene = bpy.context.scene
    scene.name = spec["booth"][:63]
    booth = bpy.data.collections.new("booth")
    scene.collection.children.link(booth)

    def adopt(coll, before_objs, before_colls):
        for obj in list(scene.collection.objects):
            if obj.name not in before_objs:
                scene.collection.objects.unlink(obj)
                coll.objects.link(obj)
        for ch in list(scene.collection.children):
            if ch.name not in before_colls and ch is not coll:
                scene.collection.children.unlink(ch)
                coll.children.link(ch)

    def tag(obj, lighting: str | None) -> None:
        base_name = obj.name
        obj["lbscene_lighting"] = lighting or "all"
        if base_name.startswith("lamp."):
            lamp_id = base_name[5:].split(".mirror")[0]
            if obj.type == "LIGHT":
                lamp_id = lamp_id.rsplit(".", 1)[0]
            obj["lbscene_role"] = "lamp_image" if ".mirror" in base_name else "lamp"
            obj["lbscene_lamp"] = lamp_id
            info = spec["lamps"].get(lamp_id)
            if info:
                obj["lbscene_lamp_kind"] = info["kind"]
            if ".mirror" not in base_name:
                obj.visible_camera = True     # a user sees the lamps (the bake's maps do not)
        elif obj.get("lbscene_role") == "mirror":
            lid = base_name.split("mirror.", 1)[-1].split(".facet")[0]     # a prism: one plate per facet
            m = spec["mirrors"].get(lid)
            rgb = (F @ np.asarray(m["reflectance_bands"])) if m else np.full(3, 0.9)
            obj.data.materials.clear()
            obj.data.materials.append(_mirror_material(f"mirror.{lid}"[:63], np.clip(rgb, 0, 1)))
            obj["lbscene_lamp"] = lid
        if lighting is not None:
            obj.name = f"{lighting}/{base_name}"[:63]

    adopt(booth, set(), {booth.name})
    for obj in booth.all_objects:
        tag(obj, None)
    lighting_colls = []
    for name, job in zip(names, jobs):
        coll = bpy.data.collections.new(f"lighting {name}"[:63])
        scene.collection.children.link(coll)
        before_o = {o.name for o in bpy.data.objects}
        before_m = {m.name for m in bpy.data.materials}
        before_c = {c.name for c in scene.collection.children}
        scene_b.job = job
        scene_b.add_objects([m for m in job.meshes if _key(m) not in shared_meshes], job.emitters,
                            [s for s in job.sheets if _key(s) not in shared_sheets])
        adopt(coll, before_o, before_c)
        for obj in [o for o in bpy.data.objects if o.name not in before_o]:
            tag(obj, name)
        # the next lighting makes its own shadow-link lists (its own objects block its mirror images)
        for bc in bpy.data.collections:
            if bc.name.startswith("blockers."):
                bc.name = f"{name}/{bc.name}"[:63]
        for mat in [m for m in bpy.data.materials if m.name not in before_m]:
            if "/" not in mat.name:
                mat.name = f"{name}/{mat.name}"[:63]
        lighting_colls.append(coll)
    scene_b.set_rgb(E, F)
    # emitter colours keep their luminance when negative RGB components (out of Rec. 709) are cut
    for sock, values, kind in scene_b._colour_sockets:
        if kind != "emission":
            continue
        rgb = E @ np.asarray(values, float)
        cut = np.clip(rgb, 0.0, None)
        y, yc = float(REC709_Y @ rgb), float(REC709_Y @ cut)
        if yc > 0 and y > 0:
            cut = cut * (y / yc)
        sock.default_value = (float(cut[0]), float(cut[1]), float(cut[2]), 1.0)
    # an emitting surface's Strength holds its radiance (W·sr⁻¹·m⁻²), its colour the chromaticity
    # (peak 1); where a profile drives Strength, the product goes through a Multiply node
    for mat in bpy.data.materials:
        if mat.node_tree is None:
            continue
        for emis in [n for n in mat.node_tree.nodes if n.bl_idname == "ShaderNodeEmission"]:
            rgb = np.asarray(emis.inputs["Color"].default_value[:3], float)
            peak = float(rgb.max())
            if peak <= 0 or emis.inputs["Color"].is_linked:
                continue
            emis.inputs["Color"].default_value = (*(rgb / peak).tolist(), 1.0)
            strength = emis.inputs["Strength"]
            if strength.is_linked:
                src = strength.links[0].from_socket
                mul = mat.node_tree.nodes.new("ShaderNodeMath")
                mul.operation = "MULTIPLY"
                mul.label = "radiance W/(sr m²)"
                mat.node_tree.links.new(src, mul.inputs[0])
                mul.inputs[1].default_value = peak
                mat.node_tree.links.new(mul.outputs[0], strength)
            else:
                strength.default_value = float(strength.default_value * peak)
    # a point light's Power field holds its watts: the node colour keeps the chromaticity (peak 1)
    for ld in bpy.data.lights:
        emis = next((n for n in ld.node_tree.nodes if n.bl_idname == "ShaderNodeEmission"), None) \
            if ld.node_tree is not None else None
        if emis is None:
            continue
        rgb = np.asarray(emis.inputs["Color"].default_value[:3], float)
        peak = float(rgb.max())
        if peak > 0:
            emis.inputs["Color"].default_value = (*(rgb / peak).tolist(), 1.0)
            ld.energy = float(ld.energy * peak)
    # only the first lighting is on
    for i, coll in enumerate(lighting_colls):
        scene.view_layers[0].layer_collection.children[coll.name].exclude = i > 0
    # camera: the observer
    cam = spec["camera"]
    cd = bpy.data.cameras.new("observer")
    cd.type = "PERSP"
    cd.sensor_fit = "HORIZONTAL"
    cd.angle = cam["angle_x_rad"]
    cd.clip_start = 0.01
    cd.clip_end = 100.0
    co = bpy.data.objects.new("observer", cd)
    scene.collection.objects.link(co)
    rot = np.stack([cam["right"], cam["up"], -np.asarray(cam["forward"])], axis=1)
    co.matrix_world = _matrix(rot, np.asarray(cam["position_mm"]) * MM)
    co["lbscene_angle_y_rad"] = cam["angle_y_rad"]
    scene.camera = co
    scene.render.resolution_x, scene.render.resolution_y = cam["resolution"]
    # a user's render: the bake's exact settings, a preview sample count, a display transform
    scene.cycles.samples = DEFAULT_SAMPLES
    scene.cycles.use_adaptive_sampling = True
    scene.cycles.use_denoising = True
    scene.view_settings.view_transform = "AgX"
    scene.render.image_settings.file_format = "PNG"
    scene.render.image_settings.color_depth = "8"
    scene.render.use_compositing = True
    scene.unit_settings.system = "METRIC"
    scene.unit_settings.scale_length = 1.0
    scene["lbscene_booth"] = spec["booth"]
    scene["lbscene_lightings"] = json.dumps(names)
    scene["lbscene_light_unit"] = "W (683 lm/W, Rec. 709 luminance)"
    bpy.ops.wm.save_as_mainfile(filepath=str(out), compress=True)


def main(argv: list[str] | None = None) -> int:
    """``python -m lbscene.bakers.blender_export SPEC_DIR OUT.blend`` (called by :func:`export_blender`)."""
    args = sys.argv[1:] if argv is None else argv
    folder, out = Path(args[0]), Path(args[1])
    spec = json.loads((folder / "spec.json").read_text(encoding="utf-8"))
    jobs = [load_job(folder / f"job{i}.json") for i in range(len(spec["lightings"]))]
    build_blend(jobs, spec, out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
