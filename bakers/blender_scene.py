"""
Build a Cycles scene from a :class:`~lbscene.bakers.job.BakeJob` with ``bpy``.

Cycles transports RGB; the baker makes it spectral by rendering **band groups**:
the 16 bands go three at a time into R, G, B (6 passes, the last one carries
band 16 in R only).  Cycles' channels are independent (a red-only emitter
leaves green and blue exactly 0, and light paths are the same for all three
channels), so a pass gives three bands at once; every value that varies
with wavelength (emitter output, reflectance, transmittance) is written into
the scene's node sockets by :meth:`BlenderScene.set_band_group`.

Radiometry (1 Blender unit = 1 m; verified by tests/bakers/test_radiometry.py):

* A zero-radius point light of power P W emits P/4π W·sr⁻¹ in every direction
  (times the node tree's emission).  The job's spectral intensity I(θ) =
  I0·f(θ) W·sr⁻¹·nm⁻¹ is set as ``energy = 4π·weight``, Emission colour = I0
  (per band) and Emission strength = f(θ) computed in the light's node tree
  from the emission direction (the light shader's Incoming vector, world space).
  Soft falloff is off, so irradiance is exactly I·cos/d².
* An Emission shader's colour × strength is the surface's radiance, so an area
  emitter's colour is its spectral radiance in W·sr⁻¹·m⁻²·nm⁻¹.
* A DIFFUSE bake of light only (no colour) stores irradiance/π; the baker
  multiplies by π.  Camera pixels are radiance.
* A lamp's straight light is in the direct products, so an environment map must not see it,
  but the lamp's body is in the way of what lies behind it.  A lamp surface is therefore
  visible to camera rays with its emission strength × (1 − *Is Camera Ray*) (Light Path
  node): camera rays stop at a black body (an emission-only surface scatters nothing), every
  other ray — diffuse, glossy, transmission, shadow — sees its emission.  Camera rays that
  pass a Transparent BSDF stay camera rays in Cycles, so the lamp seen through a clear sheet
  is black too, as its light through the sheet is the direct products' (a shadow ray passes a
  Transparent BSDF).  A mirror image is virtual: camera rays do not see it.

Exact-output settings: no clamping, light threshold 0, no adaptive sampling,
no denoiser, fixed seed, box pixel filter, float32 EXR, 'Raw' view transform.

Only this module, :mod:`lbscene.bakers.bake` and :mod:`lbscene.bakers.blender_export` (the
``.blend`` for Blender users, built with this module's scene in RGB) import ``bpy``.
"""

from __future__ import annotations

import math
import os
import tempfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .job import (AreaEmitter, BakeJob, EnvironmentMapProduct, IrradianceMapProduct,
                  IrradiancePointsProduct, PointEmitters, TransmissiveSheet)
from .products import cube_face_frames

__all__ = ["band_groups", "BlenderScene", "configure_device", "MM"]

MM = 1e-3  # Blender unit (m) per booth millimetre
#: samples of tabulated angular profiles over 0..180° (0.1° steps, linear interpolation)
PROFILE_TABLE_SIZE = 1801
#: signs (x, y) of the IES Texture node's input vector for C = 90° and C = 0 (see
#: :meth:`BlenderScene._ies_strength`; established by rendering an asymmetric file)
IES_NODE_FRAME = (-1.0, -1.0)
#: the IES Texture node's output per candela of the file: Blender's parser converts candela to
#: its lamp watts with 4π / 177.83 (the luminous efficacy of D65 it assumes), measured here as
#: 0.07067 (tests/bakers/test_lamp_effects_bake.py)
IES_NODE_SCALE = 4.0 * math.pi / 177.83
#: texels per point sensor side (each sensor bakes a k×k block that is averaged)
SENSOR_BLOCK = 2
#: scattering events a path may have in an opal plate's medium, on top of the job's
#: ``max_bounces`` (which count surface bounces): the light a 2.5 mm plate of optical depth
#: 3.0 (g 0.55) transmits or reflects has had 5 to 7 events on average, 0.2 % of it more than
#: 32 and 5e-6 more than 64, per crossing; a path in a luminaire cavity crosses the plate
#: several times
OPAL_VOLUME_BOUNCES = 256
#: transparent bounces (each crossing of an index-matched opal plate's faces is one, for the
#: path and for its shadow rays)
OPAL_TRANSPARENT_BOUNCES = 256


def band_groups(count: int, per_pass: int = 3) -> list[list[int]]:
    """Bands rendered together: ``[[0, 1, 2], [3, 4, 5], …]`` (the last group may be short).

    >>> band_groups(16)[-1], len(band_groups(16))
    ([15], 6)
    """
    return [list(range(i, min(i + per_pass, count))) for i in range(0, count, per_pass)]


def configure_device(prefer: str | None = None) -> str:
    """Use a GPU when one is available (``LBSCENE_BAKE_DEVICE=cpu|gpu|auto``); returns the device."""
    import bpy

    prefer = (prefer or os.environ.get("LBSCENE_BAKE_DEVICE", "auto")).lower()
    scene = bpy.context.scene
    scene.cycles.device = "CPU"
    if prefer == "cpu":
        return "CPU"
    try:
        prefs = bpy.context.preferences.addons["cycles"].preferences
        for kind in ("OPTIX", "CUDA", "HIP", "ONEAPI", "METAL"):
            try:
                prefs.compute_device_type = kind
            except TypeError:
                continue
            prefs.get_devices()
            gpus = [d for d in prefs.devices if d.type == kind]
            if gpus:
                for d in prefs.devices:
                    d.use = d.type == kind
                scene.cycles.device = "GPU"
                return f"GPU ({kind}: {', '.join(d.name for d in gpus)})"
    except Exception:  # no GPU backend compiled in / no driver: CPU it is
        pass
    return "CPU"


def _rgb(values, idx: list[int], scale=1.0) -> tuple[float, float, float, float]:
    v = [float(values[i]) * scale for i in idx] + [0.0] * (3 - len(idx))
    return (v[0], v[1], v[2], 1.0)


def _frame_from_aim(aim) -> np.ndarray:
    """3×3 rotation whose local −Z is ``aim`` (columns: local x, y, z in world)."""
    z = -np.asarray(aim, float)
    z /= np.linalg.norm(z)
    helper = np.array([1.0, 0, 0]) if abs(z[0]) < 0.9 else np.array([0, 1.0, 0])
    x = np.cross(helper, z)
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    return np.stack([x, y, z], axis=1)


class _Nodes:
    """Tiny helper to build math expressions in a node tree."""

    def __init__(self, tree):
        self.t = tree
        self.nodes = tree.nodes
        self.links = tree.links

    def new(self, kind, **props):
        n = self.nodes.new(kind)
        for k, v in props.items():
            setattr(n, k, v)
        return n

    def link(self, out, inp):
        self.links.new(out, inp)

    def math(self, op, a, b=None, clamp=False):
        n = self.new("ShaderNodeMath", operation=op, use_clamp=clamp)
        for sock, val in ((n.inputs[0], a), (n.inputs[1], b)):
            if val is None:
                continue
            if isinstance(val, (int, float)):
                sock.default_value = float(val)
            else:
                self.link(val, sock)
        return n.outputs[0]


@dataclass
class _SensorSet:
    obj: object
    image: object
    cells: tuple[int, int, int]          # (cols, rows, k): k×k texels per sensor
    count: int = 0


@dataclass
class BlenderScene:
    """A job's Blender scene plus the sockets that carry per-band values."""

    job: BakeJob
    #: (socket, band values, kind): every socket whose value varies with wavelength; kind is
    #: ``"emission"`` (spectral radiance or intensity per nm) or ``"factor"`` (reflectance,
    #: transmittance: dimensionless)
    _colour_sockets: list = field(default_factory=list)
    _sensors: dict = field(default_factory=dict)
    #: group → [(object, original matrix)] and [(aim socket, aim)] for group transforms
    _groups: dict = field(default_factory=dict)
    _group_aims: dict = field(default_factory=dict)
    _pending_blockers: list = field(default_factory=list)
    device: str = "CPU"
    #: camera rays see a lamp's emission (a user's render); False (the bake): a lamp whose job
    #: hides it from the camera is a black body to camera rays, its light left to the direct products
    camera_sees_lamps: bool = False

    # ------------------------------------------------------------------ setup
    @classmethod
    def build(cls, job: BakeJob) -> "BlenderScene":
        import bpy

        bpy.ops.wm.read_factory_settings(use_empty=True)
        self = cls(job=job)
        scene = bpy.context.scene
        scene.name = job.name
        self._settings(scene)
        self.device = configure_device()
        for mid, mat in job.materials.items():
            self._material(mid, mat)
        self.add_objects(job.meshes, job.emitters, job.sheets)
        for p in job.products:
            if p.type == "irradiance_points":
                self._sensors[p.id] = self._point_sensors(p)
            elif p.type == "irradiance_map":
                self._sensors[p.id] = self._map_sensor(p)
        self.set_band_group(band_groups(job.bands.count)[0])
        return self

    def add_objects(self, meshes, emitters, sheets) -> None:
        """Add a job's meshes (materials already made), emitters and transmissive sheets to the
        scene; the shadow links of mirror images are made once all of them exist."""
        import bpy

        for mesh in meshes:
            obj = self._mesh_object(mesh.id, mesh.vertices_mm, mesh.triangles)
            obj.data.materials.append(bpy.data.materials[f"mat.{mesh.material}"])
            obj.visible_camera = mesh.visible_to_camera
            obj["lbscene_role"] = mesh.role
            self._add_to_group(mesh.group, obj)
        for em in emitters:
            if em.type == "points":
                self._point_emitters(em)
            else:
                self._area_emitter(em)
        for sheet in sheets:
            self._sheet(sheet)
        # shadow linking once every object exists
        for obj, win in self._pending_blockers:
            obj.light_linking.blocker_collection = self._blockers_outside(win)
        self._pending_blockers.clear()

    def _add_to_group(self, group, obj) -> None:
        if group is not None:
            self._groups.setdefault(group, []).append((obj, obj.matrix_world.copy()))

    def apply_group_transforms(self, transforms: dict) -> None:
        """Move the objects of each group (a product's ``group_transforms``)."""
        from mathutils import Matrix

        for group, tr in transforms.items():
            M = tr.matrix()
            M[:3, 3] *= MM
            mb = Matrix([list(map(float, row)) for row in M])
            for obj, orig in self._groups.get(group, []):
                obj.matrix_world = mb @ orig
            for sock, aim in self._group_aims.get(group, []):
                sock.default_value = tuple(float(c) for c in M[:3, :3] @ np.asarray(aim))

    def reset_group_transforms(self) -> None:
        for group, items in self._groups.items():
            for obj, orig in items:
                obj.matrix_world = orig
            for sock, aim in self._group_aims.get(group, []):
                sock.default_value = tuple(float(c) for c in aim)

    def _settings(self, scene) -> None:
        scene.render.engine = "CYCLES"
        c = scene.cycles
        c.samples = 16
        c.use_adaptive_sampling = False
        c.use_denoising = False
        c.sample_clamp_direct = 0.0
        c.sample_clamp_indirect = 0.0
        c.light_sampling_threshold = 0.0
        c.seed = self.job.quality.seed
        c.use_animated_seed = False
        c.blur_glossy = 0.0
        c.caustics_reflective = True
        c.caustics_refractive = True
        b = self.job.max_bounces
        c.max_bounces = b
        c.diffuse_bounces = b
        c.glossy_bounces = b
        c.transmission_bounces = b
        c.volume_bounces = 0
        c.transparent_max_bounces = 64
        if any(s.model == "opal" for s in self.job.sheets):
            # an opal plate's medium: its scattering events (and, behind refracting faces, the
            # refractions and total internal reflections) come on top of the job's surface bounces
            v = OPAL_VOLUME_BOUNCES
            c.volume_bounces = v
            c.max_bounces = b + v
            if any(s.model == "opal" and (s.ior or 1.0) > 1.0 + 1e-9 for s in self.job.sheets):
                c.glossy_bounces = b + v
                c.transmission_bounces = b + v
            c.transparent_max_bounces = OPAL_TRANSPARENT_BOUNCES
        c.min_light_bounces = 0
        c.min_transparent_bounces = 0
        c.pixel_filter_type = "BOX"
        c.filter_width = 1.0
        if hasattr(c, "use_guiding"):
            # path guiding (CPU only): unbiased, fewer fireflies from hot spots; off by default
            # so CPU and GPU runs of a job sample the same way
            c.use_guiding = self.job.quality.path_guiding
            c.use_surface_guiding = self.job.quality.path_guiding
            c.use_volume_guiding = False
        scene.render.film_transparent = False
        vs = scene.view_settings
        vs.view_transform = "Raw"
        vs.look = "None"
        vs.exposure = 0.0
        vs.gamma = 1.0
        scene.render.use_compositing = False
        scene.render.use_sequencer = False
        im = scene.render.image_settings
        if hasattr(im, "media_type"):
            im.media_type = "IMAGE"   # Blender 5.0: before file_format
        im.file_format = "OPEN_EXR"
        im.color_depth = "32"
        im.color_mode = "RGB"
        im.exr_codec = "ZIP"
        scene.render.resolution_percentage = 100
        # the world is black: nothing enters the booth except through its emitters
        world = bpy_world(scene)
        world.color = (0.0, 0.0, 0.0)

    # ------------------------------------------------------------------ geometry
    def _mesh_object(self, name, vertices_mm, triangles, collection=None):
        import bpy

        me = bpy.data.meshes.new(name)
        v = (np.asarray(vertices_mm, float) * MM).tolist()
        me.from_pydata(v, [], [tuple(t) for t in triangles])
        me.update()
        obj = bpy.data.objects.new(name, me)
        (collection or bpy.context.scene.collection).objects.link(obj)
        return obj

    def _material(self, mid, mat) -> None:
        import bpy

        m = bpy.data.materials.new(f"mat.{mid}")
        nt = m.node_tree
        nt.nodes.clear()
        out = nt.nodes.new("ShaderNodeOutputMaterial")
        if mat.type == "diffuse":
            bsdf = nt.nodes.new("ShaderNodeBsdfDiffuse")
            bsdf.inputs["Roughness"].default_value = 0.0   # Lambertian
            sock = bsdf.inputs["Color"]
        elif mat.type == "glossy":
            bsdf = nt.nodes.new("ShaderNodeBsdfPrincipled")
            bsdf.inputs["Roughness"].default_value = mat.roughness
            bsdf.inputs["Metallic"].default_value = 0.0
            bsdf.inputs["IOR"].default_value = 1.5
            sock = bsdf.inputs["Base Color"]
        else:  # mirror
            bsdf = nt.nodes.new("ShaderNodeBsdfGlossy")
            bsdf.distribution = "GGX"
            bsdf.inputs["Roughness"].default_value = mat.roughness
            sock = bsdf.inputs["Color"]
        nt.links.new(bsdf.outputs[0], out.inputs["Surface"])
        values = mat.reflectance
        self._colour_sockets.append((sock, values, "factor"))

    # ------------------------------------------------------------------ emitters
    def _emitter_bands(self, em) -> np.ndarray:
        v = np.asarray(em.intensity_W_sr_nm if em.type == "points" else em.radiance_W_sr_m2_nm, float)
        if em.filter is not None:
            v = v * np.asarray(self.job.filters[em.filter].transmittance, float)
        return v

    def _profile_strength(self, nb: _Nodes, profile, aim, group=None):
        """Output socket of f(θ) in a light node tree (None: isotropic).

        θ is the angle between ``aim`` and the emission direction: a light shader's
        *Incoming* vector points from the light (its sampled point, for a sphere
        light) to the shaded point, in world space.
        """
        if profile.type == "isotropic":
            return None
        if profile.type == "ies":
            return self._ies_strength(nb, profile, aim, group)
        geo = nb.new("ShaderNodeNewGeometry")
        dot = nb.new("ShaderNodeVectorMath", operation="DOT_PRODUCT")
        nb.link(geo.outputs["Incoming"], dot.inputs[0])
        dot.inputs[1].default_value = tuple(float(c) for c in aim)
        if group is not None:
            self._group_aims.setdefault(group, []).append((dot.inputs[1], tuple(aim)))
        cos_t = dot.outputs["Value"]
        if profile.type == "cosine_power":
            c = nb.math("MAXIMUM", cos_t, 0.0)
            pw = nb.math("POWER", c, float(profile.exponent))
            return nb.math("MULTIPLY", pw, nb.math("GREATER_THAN", cos_t, 0.0))
        theta = nb.math("ARCCOSINE", nb.math("MINIMUM", nb.math("MAXIMUM", cos_t, -1.0), 1.0))
        if profile.type == "gaussian":
            x = nb.math("DIVIDE", theta, 2.0 * math.radians(profile.sigma_deg))
            return nb.math("EXPONENT", nb.math("MULTIPLY", nb.math("MULTIPLY", x, x), -1.0))
        # table: a 1-D float image over 0..180°, sampled at texel centres (exact linear interp.)
        import bpy

        grid = np.linspace(0.0, 180.0, PROFILE_TABLE_SIZE)
        vals = np.interp(grid, profile.theta_deg, profile.relative, left=0.0, right=0.0)
        img = bpy.data.images.new(f"profile.{nb.t.name}", PROFILE_TABLE_SIZE, 1, float_buffer=True,
                                  is_data=True)
        px = np.zeros((PROFILE_TABLE_SIZE, 4), np.float32)
        px[:, :3] = vals[:, None]
        px[:, 3] = 1.0
        img.pixels.foreach_set(px.ravel())
        img.pack()
        n = PROFILE_TABLE_SIZE
        u = nb.math("ADD", nb.math("MULTIPLY", theta, (n - 1) / (n * math.pi)), 0.5 / n)
        comb = nb.new("ShaderNodeCombineXYZ")
        nb.link(u, comb.inputs["X"])
        comb.inputs["Y"].default_value = 0.5
        tex = nb.new("ShaderNodeTexImage", image=img, interpolation="Linear", extension="EXTEND")
        nb.link(comb.outputs[0], tex.inputs["Vector"])
        return tex.outputs["Color"]

    def _ies_strength(self, nb: _Nodes, profile, aim, group=None):
        """f(γ, C) of an :class:`~lbscene.bakers.job.IesProfile` through Cycles' IES Texture node.

        The node (Blender's own LM-63 parser and symmetry unfolding) is given the emission
        direction d (Incoming, world space) in the frame it expects: it reads the vertical
        angle as acos(−z) and the horizontal one as atan2(x, y) + π with the C planes the
        parser lays out (:data:`IES_NODE_FRAME`), so with a = d·aim, b0 = d·c0, b90 = d·c90
        the vector is ``(sx·b90, sy·b0, −a)``: γ = 0 along ``aim``, C = 0 along ``c0_axis``,
        C = 90° along ``c90_axis`` (checked against the file's own numbers in
        tests/bakers/test_lamp_effects_bake.py).  Its output is candela × :data:`IES_NODE_SCALE`,
        so its strength is 1 / (``peak_cd`` × :data:`IES_NODE_SCALE`).
        """
        import bpy

        geo = nb.new("ShaderNodeNewGeometry")
        comps = []
        for vec in (aim, profile.c0_axis, profile.c90_axis):
            dot = nb.new("ShaderNodeVectorMath", operation="DOT_PRODUCT")
            nb.link(geo.outputs["Incoming"], dot.inputs[0])
            dot.inputs[1].default_value = tuple(float(c) for c in vec)
            if group is not None:
                self._group_aims.setdefault(group, []).append((dot.inputs[1], tuple(vec)))
            comps.append(dot.outputs["Value"])
        a, b0, b90 = comps
        sx, sy = IES_NODE_FRAME
        comb = nb.new("ShaderNodeCombineXYZ")
        nb.link(nb.math("MULTIPLY", b90, float(sx)), comb.inputs["X"])
        nb.link(nb.math("MULTIPLY", b0, float(sy)), comb.inputs["Y"])
        nb.link(nb.math("MULTIPLY", a, -1.0), comb.inputs["Z"])
        text = bpy.data.texts.new(f"ies.{nb.t.name}")
        text.from_string(profile.ies_text)
        tex = nb.new("ShaderNodeTexIES", mode="INTERNAL")
        tex.ies = text
        tex.inputs["Strength"].default_value = 1.0 / (float(profile.peak_cd) * IES_NODE_SCALE)
        nb.link(comb.outputs[0], tex.inputs["Vector"])
        return tex.outputs["Fac"]

    def _axial_weight(self, nb: _Nodes, w):
        """w(d) of an :class:`~lbscene.bakers.job.AxialWeight` from the shaded point's object-space
        position (the mesh's own coordinates: group transforms move the object, not them)."""
        tc = nb.new("ShaderNodeTexCoord")
        dot = nb.new("ShaderNodeVectorMath", operation="DOT_PRODUCT")
        nb.link(tc.outputs["Object"], dot.inputs[0])
        dot.inputs[1].default_value = tuple(float(c) for c in w.axis)
        c = np.asarray(w.centre_mm, float) * MM
        s = nb.math("SUBTRACT", dot.outputs["Value"], float(c @ np.asarray(w.axis, float)))
        d_end = nb.math("SUBTRACT", 0.5 * w.length_mm * MM, nb.math("ABSOLUTE", s))
        t = nb.math("DIVIDE", d_end, w.falloff_length_mm * MM, clamp=True)
        return nb.math("ADD", nb.math("MULTIPLY", t, 1.0 - w.end_level), float(w.end_level))

    def _window_mask(self, nb: _Nodes, win):
        """1 where the ray light→shaded point crosses the window rectangle, else 0."""
        geo = nb.new("ShaderNodeNewGeometry")
        c = np.asarray(win.centre_mm, float) * MM
        n = np.asarray(win.normal, float)
        u = np.asarray(win.u_axis, float)
        u = u - n * (u @ n)
        u /= np.linalg.norm(u)
        v = np.cross(n, u)

        def vdot(a, const):
            d = nb.new("ShaderNodeVectorMath", operation="DOT_PRODUCT")
            nb.link(a, d.inputs[0])
            d.inputs[1].default_value = tuple(float(x) for x in const)
            return d.outputs["Value"]

        pos, inc = geo.outputs["Position"], geo.outputs["Incoming"]
        # t = (c − P)·n / (d·n);  X − c = P − c + t d
        pn = vdot(pos, n)
        dn = vdot(inc, n)
        t = nb.math("DIVIDE", nb.math("SUBTRACT", float(c @ n), pn), dn)
        mask = nb.math("GREATER_THAN", t, 0.0)
        for axis, half in ((u, win.half_size_mm[0]), (v, win.half_size_mm[1])):
            coord = nb.math("ADD", nb.math("SUBTRACT", vdot(pos, axis), float(c @ axis)),
                            nb.math("MULTIPLY", t, vdot(inc, axis)))
            inside = nb.math("LESS_THAN", nb.math("ABSOLUTE", coord), half * MM)
            mask = nb.math("MULTIPLY", mask, inside)
        return mask

    def _blockers_outside(self, win):
        """Collection of every shadow-casting object not lying entirely behind the window plane."""
        import bpy

        key = f"blockers.{hash((win.centre_mm, win.normal)) & 0xffffffff:08x}"
        coll = bpy.data.collections.get(key)
        if coll is not None:
            return coll
        coll = bpy.data.collections.new(key)   # not linked to the scene: only a blocker list
        c = np.asarray(win.centre_mm, float) * MM
        n = np.asarray(win.normal, float)
        for obj in bpy.context.scene.objects:
            if obj.type != "MESH" or obj.name.startswith("sensor."):
                continue
            v = np.array([(obj.matrix_world @ x.co)[:] for x in obj.data.vertices])
            if len(v) and np.all((v - c) @ n <= 1e-6):
                continue          # behind (or on) the mirror: between the mirror and the image
            coll.objects.link(obj)
        return coll

    def _point_emitters(self, em: PointEmitters) -> None:
        import bpy
        from mathutils import Matrix

        bands = self._emitter_bands(em)
        weights = em.weights or (1.0,) * len(em.positions_mm)
        rot = _frame_from_aim(em.aim)
        coll = bpy.data.collections.new(f"emitter.{em.id}")
        bpy.context.scene.collection.children.link(coll)
        datas: dict[float, object] = {}
        for k, (pos, w) in enumerate(zip(em.positions_mm, weights)):
            if w <= 0:
                continue
            key = round(float(w), 12)
            if key not in datas:  # one light datablock per distinct weight (shared node tree)
                ld = bpy.data.lights.new(f"{em.id}.w{len(datas)}", "POINT")
                ld.energy = 4.0 * math.pi * float(w)   # → W·sr⁻¹ = colour × strength × w
                # radius 0: a true point; > 0: a uniform sphere of the same intensity that
                # camera rays can see (environment maps); soft falloff off = physical sphere
                ld.shadow_soft_size = em.radius_mm * MM
                ld.use_soft_falloff = False
                ld.color = (1.0, 1.0, 1.0)
                ld.use_nodes = True
                nt = ld.node_tree
                nb = _Nodes(nt)
                emis = next(n for n in nt.nodes if n.bl_idname == "ShaderNodeEmission")
                strength = self._profile_strength(nb, em.profile, em.aim, em.group)
                if em.window is not None:
                    mask = self._window_mask(nb, em.window)
                    strength = mask if strength is None else nb.math("MULTIPLY", strength, mask)
                if strength is not None:
                    nb.link(strength, emis.inputs["Strength"])
                else:
                    emis.inputs["Strength"].default_value = 1.0
                sock = emis.inputs["Color"]
                self._colour_sockets.append((sock, bands, "emission"))
                datas[key] = ld
            obj = bpy.data.objects.new(f"{em.id}.{k:04d}", datas[key])
            m = Matrix.Identity(4)
            for i in range(3):
                for j in range(3):
                    m[i][j] = rot[i, j]
                m[i][3] = pos[i] * MM
            obj.matrix_world = m
            obj.visible_camera = em.radius_mm > 0 and em.window is None
            coll.objects.link(obj)
            if em.window is not None:
                self._pending_blockers.append((obj, em.window))
            self._add_to_group(em.group, obj)

    def _area_emitter(self, em: AreaEmitter) -> None:
        import bpy

        bands = self._emitter_bands(em)
        obj = self._mesh_object(em.id, em.vertices_mm, em.triangles)
        m = bpy.data.materials.new(f"emitter.{em.id}")
        nt = m.node_tree
        nt.nodes.clear()
        nb = _Nodes(nt)
        out = nb.new("ShaderNodeOutputMaterial")
        emis = nb.new("ShaderNodeEmission")
        emis.inputs["Strength"].default_value = 1.0   # colour = radiance
        # a lamp's modulation: on a surface, Incoming points from the emitting point toward
        # the receiver, as a light shader's does from the light
        strength = self._profile_strength(nb, em.profile, em.aim, em.group)
        for extra in ((self._axial_weight(nb, em.axial_weight) if em.axial_weight is not None else None),
                      (self._window_mask(nb, em.window) if em.window is not None else None)):
            if extra is not None:
                strength = extra if strength is None else nb.math("MULTIPLY", strength, extra)
        camera_black = not em.visible_to_camera and em.window is None and not self.camera_sees_lamps
        if camera_black:
            # black to camera rays, but there: the environment maps see the lamp's body (not what
            # lies behind it) while its straight light is the direct products' (no double count);
            # every other ray (diffuse, glossy, transmission, shadow) sees its emission
            lp = nb.new("ShaderNodeLightPath")
            not_camera = nb.math("SUBTRACT", 1.0, lp.outputs["Is Camera Ray"])
            strength = not_camera if strength is None else nb.math("MULTIPLY", strength, not_camera)
        if strength is not None:
            nb.link(strength, emis.inputs["Strength"])
        if em.two_sided:
            nb.link(emis.outputs[0], out.inputs["Surface"])
            m.cycles.emission_sampling = "FRONT_AND_BACK"
        else:
            geo = nb.new("ShaderNodeNewGeometry")
            mix = nb.new("ShaderNodeMixShader")   # back side: black, absorbing
            nb.link(geo.outputs["Backfacing"], mix.inputs["Fac"])
            nb.link(emis.outputs[0], mix.inputs[1])
            nb.link(mix.outputs[0], out.inputs["Surface"])
            m.cycles.emission_sampling = "FRONT"
        obj.data.materials.append(m)
        # a mirror image is virtual: camera rays pass it; a lamp is a body they stop at
        obj.visible_camera = em.window is None
        if em.window is not None:
            self._pending_blockers.append((obj, em.window))
        self._add_to_group(em.group, obj)
        sock = emis.inputs["Color"]
        self._colour_sockets.append((sock, bands, "emission"))

    # ------------------------------------------------------------------ sheets
    def _slab_transmittance_ratio(self, nb: _Nodes, ior: float):
        """S(θ)/S(0): unpolarised clear-plate transmittance (1−r)/(1+r), both faces, vs 0°."""
        geo = nb.new("ShaderNodeNewGeometry")
        dot = nb.new("ShaderNodeVectorMath", operation="DOT_PRODUCT")
        nb.link(geo.outputs["Incoming"], dot.inputs[0])
        nb.link(geo.outputs["Normal"], dot.inputs[1])
        ci = nb.math("MINIMUM", nb.math("ABSOLUTE", dot.outputs["Value"]), 1.0)
        n = float(ior)
        sin2t = nb.math("DIVIDE", nb.math("SUBTRACT", 1.0, nb.math("MULTIPLY", ci, ci)), n * n)
        ct = nb.math("SQRT", nb.math("MAXIMUM", nb.math("SUBTRACT", 1.0, sin2t), 0.0))

        def ratio_sq(a, b):
            num = nb.math("SUBTRACT", a, b)
            den = nb.math("MAXIMUM", nb.math("ADD", a, b), 1e-9)
            r = nb.math("DIVIDE", num, den)
            return nb.math("MULTIPLY", r, r)

        rs = ratio_sq(ci, nb.math("MULTIPLY", ct, n))
        rp = ratio_sq(ct, nb.math("MULTIPLY", ci, n))

        def slab(r):
            return nb.math("DIVIDE", nb.math("SUBTRACT", 1.0, r), nb.math("ADD", 1.0, r))

        s = nb.math("MULTIPLY", nb.math("ADD", slab(rs), slab(rp)), 0.5)
        r0 = ((n - 1.0) / (n + 1.0)) ** 2
        s0 = (1.0 - r0) / (1.0 + r0)
        return nb.math("DIVIDE", s, s0)

    def _opal_exit_shape(self, nb: _Nodes, ior: float):
        """(1 − F(θ))/(1 − F_h): a thin translucent sheet's scattered radiance leaving through its
        smooth face at the viewing angle θ, relative to a Lambertian emitter of the same exitance
        (the face's loss only: the scattering layer's own shape,
        ``lbscene.engine.light.opal_layer.OpalLayer.exit_shape``, is in the bake only where the
        plate is drawn as its slab); F the face's unpolarised Fresnel reflectance, F_h its
        hemispherical mean."""
        geo = nb.new("ShaderNodeNewGeometry")
        dot = nb.new("ShaderNodeVectorMath", operation="DOT_PRODUCT")
        nb.link(geo.outputs["Incoming"], dot.inputs[0])
        nb.link(geo.outputs["Normal"], dot.inputs[1])
        ci = nb.math("MAXIMUM", nb.math("MINIMUM", nb.math("ABSOLUTE", dot.outputs["Value"]), 1.0), 1e-4)
        n = float(ior)
        sin2t = nb.math("DIVIDE", nb.math("SUBTRACT", 1.0, nb.math("MULTIPLY", ci, ci)), n * n)
        ct = nb.math("SQRT", nb.math("MAXIMUM", nb.math("SUBTRACT", 1.0, sin2t), 0.0))

        def ratio_sq(a, b):
            r = nb.math("DIVIDE", nb.math("SUBTRACT", a, b), nb.math("MAXIMUM", nb.math("ADD", a, b), 1e-9))
            return nb.math("MULTIPLY", r, r)

        F = nb.math("MULTIPLY", nb.math("ADD", ratio_sq(ci, nb.math("MULTIPLY", ct, n)),
                                        ratio_sq(ct, nb.math("MULTIPLY", ci, n))), 0.5)
        mu = (np.arange(2000) + 0.5) / 2000
        st = np.sqrt(1 - mu * mu) / n
        ctt = np.sqrt(1 - st * st)
        Fh = float(np.mean(2 * mu * 0.5 * (((mu - n * ctt) / (mu + n * ctt)) ** 2
                                            + ((n * mu - ctt) / (n * mu + ctt)) ** 2)))
        return nb.math("DIVIDE", nb.math("SUBTRACT", 1.0, F), 1.0 - Fh)

    def _sheet(self, sheet: TransmissiveSheet) -> None:
        import bpy

        m = bpy.data.materials.new(f"sheet.{sheet.id}")
        nt = m.node_tree
        nt.nodes.clear()
        nb = _Nodes(nt)
        out = nb.new("ShaderNodeOutputMaterial")
        t = np.asarray(sheet.transmittance, float)
        if sheet.model == "opal":
            obj = self._opal_slab(sheet, nb, out)
            # a dense medium lit from outside: distance sampling
            m.cycles.volume_sampling = "DISTANCE"
        elif sheet.model == "glass":
            obj = self._slab_object(sheet)
            glass = nb.new("ShaderNodeBsdfGlass", distribution="GGX")
            glass.inputs["Roughness"].default_value = sheet.roughness
            n = sheet.ior or 1.5
            glass.inputs["IOR"].default_value = n
            r0 = ((n - 1) / (n + 1)) ** 2
            s0 = (1 - r0) / (1 + r0) if sheet.reference_transmittance is None else sheet.reference_transmittance
            # Glass colour tints each of the two refractions: colour² = the declared total
            # transmittance over the non-absorbing plate's (the bulk absorption)
            colour = np.sqrt(np.clip(t / s0, 0.0, 1.0))
            nb.link(glass.outputs[0], out.inputs["Surface"])
            sock = glass.inputs["Color"]
            self._colour_sockets.append((sock, colour, "factor"))
        else:
            obj = self._mesh_object(sheet.id, sheet.vertices_mm, sheet.triangles)
            mult = nb.new("ShaderNodeMix", data_type="RGBA", blend_type="MULTIPLY")
            mult.inputs["Factor"].default_value = 1.0
            if sheet.ior is not None:
                ratio = self._slab_transmittance_ratio(nb, sheet.ior)
                comb = nb.new("ShaderNodeCombineColor")
                for ch in ("Red", "Green", "Blue"):
                    nb.link(ratio, comb.inputs[ch])
                nb.link(comb.outputs[0], mult.inputs[7])
            else:
                mult.inputs[7].default_value = (1.0, 1.0, 1.0, 1.0)
            colour_sock = mult.inputs[6]
            d = sheet.diffuse_fraction
            transp = nb.new("ShaderNodeBsdfTransparent")
            nb.link(mult.outputs[2], transp.inputs["Color"])
            if d > 0:
                transl = nb.new("ShaderNodeBsdfTranslucent")
                if sheet.ior is not None:
                    # the scattered part leaves with the opal exit law, not the clear plate's ratio
                    mult_o = nb.new("ShaderNodeMix", data_type="RGBA", blend_type="MULTIPLY")
                    mult_o.inputs["Factor"].default_value = 1.0
                    comb_o = nb.new("ShaderNodeCombineColor")
                    shape = self._opal_exit_shape(nb, sheet.ior)
                    for ch in ("Red", "Green", "Blue"):
                        nb.link(shape, comb_o.inputs[ch])
                    nb.link(comb_o.outputs[0], mult_o.inputs[7])
                    self._colour_sockets.append((mult_o.inputs[6], t, "factor"))
                    nb.link(mult_o.outputs[2], transl.inputs["Color"])
                else:
                    nb.link(mult.outputs[2], transl.inputs["Color"])
                mix = nb.new("ShaderNodeMixShader")
                mix.inputs["Fac"].default_value = d
                nb.link(transp.outputs[0], mix.inputs[1])
                nb.link(transl.outputs[0], mix.inputs[2])
                nb.link(mix.outputs[0], out.inputs["Surface"])
            else:
                nb.link(transp.outputs[0], out.inputs["Surface"])
            if sheet.ior is not None:
                # its faces reflect: the clear plate's R(θ) = 1 − S(θ) (both faces, incoherent),
                # a sharp mirror; light the plate sends back (into a luminaire cavity, or down into
                # the booth) takes part in the inter-reflection as it does in the model
                surf = out.inputs["Surface"].links[0].from_socket
                n = float(sheet.ior)
                r0 = ((n - 1.0) / (n + 1.0)) ** 2
                s0 = (1.0 - r0) / (1.0 + r0)
                refl = nb.math("SUBTRACT", 1.0, nb.math("MULTIPLY", self._slab_transmittance_ratio(nb, n), s0))
                comb_r = nb.new("ShaderNodeCombineColor")
                for ch in ("Red", "Green", "Blue"):
                    nb.link(refl, comb_r.inputs[ch])
                mirror = nb.new("ShaderNodeBsdfGlossy", distribution="GGX")
                mirror.inputs["Roughness"].default_value = 0.0
                nb.link(comb_r.outputs[0], mirror.inputs["Color"])
                add = nb.new("ShaderNodeAddShader")
                nb.link(surf, add.inputs[0])
                nb.link(mirror.outputs[0], add.inputs[1])
                nb.link(add.outputs[0], out.inputs["Surface"])
            self._colour_sockets.append((colour_sock, t, "factor"))
        obj.data.materials.append(m)
        obj["lbscene_role"] = sheet.role
        self._add_to_group(sheet.group, obj)

    def _opal_slab(self, sheet: TransmissiveSheet, nb: _Nodes, out):
        """An opal plate: the closed slab (:meth:`_slab_object`) with a smooth Glass BSDF of the
        faces' ``ior`` (no surface shader for ior 1: the faces do not exist for any ray, shadow
        rays included) and the medium as its volume: Volume Scatter (Henyey–Greenstein,
        ``anisotropy``; Cycles' σ_s = density × colour, per metre: the Blender unit) plus, when
        the sheet absorbs, Volume Absorption (σ_a = density × (1 − colour), the colour per band)."""
        obj = self._slab_object(sheet)
        n = sheet.ior or 1.0
        if n > 1.0 + 1e-9:
            glass = nb.new("ShaderNodeBsdfGlass", distribution="GGX")
            glass.inputs["Roughness"].default_value = 0.0
            glass.inputs["IOR"].default_value = float(n)
            glass.inputs["Color"].default_value = (1.0, 1.0, 1.0, 1.0)
            nb.link(glass.outputs[0], out.inputs["Surface"])
        scatter = nb.new("ShaderNodeVolumeScatter")
        if hasattr(scatter, "phase"):
            scatter.phase = "HENYEY_GREENSTEIN"
        scatter.inputs["Color"].default_value = (1.0, 1.0, 1.0, 1.0)
        scatter.inputs["Density"].default_value = float(sheet.scattering_per_mm) / MM
        scatter.inputs["Anisotropy"].default_value = float(sheet.anisotropy)
        volume = scatter.outputs[0]
        a = None if sheet.absorption_per_mm is None else np.asarray(sheet.absorption_per_mm, float)
        if a is not None and a.max() > 0:
            absorb = nb.new("ShaderNodeVolumeAbsorption")
            absorb.inputs["Density"].default_value = float(a.max()) / MM
            self._colour_sockets.append((absorb.inputs["Color"], 1.0 - a / a.max(), "factor"))
            add = nb.new("ShaderNodeAddShader")
            nb.link(scatter.outputs[0], add.inputs[0])
            nb.link(absorb.outputs[0], add.inputs[1])
            volume = add.outputs[0]
        nb.link(volume, out.inputs["Volume"])
        return obj

    def _slab_object(self, sheet: TransmissiveSheet):
        """Extrude the sheet's triangles by ``thickness_mm`` along their normals into a closed slab."""
        v = np.asarray(sheet.vertices_mm, float)
        tris = np.asarray(sheet.triangles, int)
        nrm = np.cross(v[tris[:, 1]] - v[tris[:, 0]], v[tris[:, 2]] - v[tris[:, 0]]).sum(axis=0)
        nrm /= np.linalg.norm(nrm)
        h = sheet.thickness_mm / 2
        top, bot = v + h * nrm, v - h * nrm
        verts = np.vstack([top, bot])
        nv = len(v)
        faces = [tuple(t) for t in tris] + [(c + nv, b + nv, a + nv) for a, b, c in tris]
        # side walls along boundary edges (edges used by one triangle)
        from collections import Counter

        edges = Counter()
        for a, b, c in tris:
            for e in ((a, b), (b, c), (c, a)):
                edges[e] += 1
        for (a, b), _ in edges.items():
            if (b, a) not in edges:
                faces += [(b, a, a + nv), (b, a + nv, b + nv)]
        return self._mesh_object(sheet.id, verts, faces)

    # ------------------------------------------------------------------ sensors
    def _sensor_material(self, name, image):
        import bpy

        m = bpy.data.materials.new(name)
        nt = m.node_tree
        nt.nodes.clear()
        out = nt.nodes.new("ShaderNodeOutputMaterial")
        bsdf = nt.nodes.new("ShaderNodeBsdfDiffuse")
        bsdf.inputs["Roughness"].default_value = 0.0
        nt.links.new(bsdf.outputs[0], out.inputs["Surface"])
        tex = nt.nodes.new("ShaderNodeTexImage")
        tex.image = image
        nt.nodes.active = tex
        return m

    def _hide_sensor(self, obj) -> None:
        # a sensor must not shadow, reflect or be seen; it stays renderable only while it is baked
        for flag in ("visible_shadow", "visible_diffuse", "visible_glossy", "visible_transmission",
                     "visible_volume_scatter"):
            setattr(obj, flag, False)
        obj.hide_render = True

    def _sensor_grid(self, name, positions, normals, size_mm, offset_mm) -> _SensorSet:
        """Small square cosine sensors, each baked into its own k×k texel block.

        Cycles jitters bake samples over a texel's footprint; a sensor of
        ``size_mm`` therefore measures the irradiance at its centre to within
        the variation over its size (1 mm: negligible).
        """
        import bpy

        n = len(positions)
        k = SENSOR_BLOCK
        cols = int(math.ceil(math.sqrt(n)))
        rows = int(math.ceil(n / cols))
        W, H = cols * k, rows * k
        pos = np.asarray(positions, float)
        nrm = np.asarray(normals, float)
        nrm = nrm / np.linalg.norm(nrm, axis=1, keepdims=True)
        helper = np.where(np.abs(nrm[:, 2:3]) < 0.9, [[0.0, 0.0, 1.0]], [[1.0, 0.0, 0.0]])
        a = np.cross(nrm, helper)
        a /= np.linalg.norm(a, axis=1, keepdims=True)
        b = np.cross(nrm, a)                      # (a, b, n) right-handed: CCW seen from n
        c = pos + offset_mm * nrm
        h = size_mm / 2
        corners = np.stack([c - h * a - h * b, c + h * a - h * b, c + h * a + h * b,
                            c - h * a + h * b], axis=1).reshape(-1, 3)
        faces = np.arange(4 * n).reshape(n, 4)
        i = np.arange(n)
        ci, ri = i % cols, i // cols
        u0, v0, u1, v1 = ci * k / W, ri * k / H, (ci + 1) * k / W, (ri + 1) * k / H
        uvs = np.stack([np.stack([u0, v0], 1), np.stack([u1, v0], 1), np.stack([u1, v1], 1),
                        np.stack([u0, v1], 1)], axis=1).reshape(-1, 2)
        obj = self._mesh_object(f"sensor.{name}", corners, faces.tolist())
        ul = obj.data.uv_layers.new(name="UVMap")
        loop_vert = np.empty(len(obj.data.loops), np.int64)
        obj.data.loops.foreach_get("vertex_index", loop_vert)
        ul.data.foreach_set("uv", uvs[loop_vert].astype(np.float32).ravel())
        img = bpy.data.images.new(f"bake.{name}", W, H, float_buffer=True, is_data=True)
        obj.data.materials.append(self._sensor_material(f"sensor.{name}", img))
        self._hide_sensor(obj)
        return _SensorSet(obj, img, (cols, rows, k), n)

    def _point_sensors(self, p: IrradiancePointsProduct) -> _SensorSet:
        return self._sensor_grid(p.id, [q.position_mm for q in p.points], [q.normal for q in p.points],
                                 p.sensor_size_mm, p.offset_mm)

    def _map_sensor(self, p: IrradianceMapProduct) -> _SensorSet:
        """One point sensor per texel centre, in row-major order from the top row."""
        o = np.asarray(p.origin_mm, float)
        u = np.asarray(p.u_axis, float) / np.linalg.norm(p.u_axis)
        v = np.asarray(p.v_axis, float) / np.linalg.norm(p.v_axis)
        nx, ny = p.resolution
        j, i = np.mgrid[0:ny, 0:nx]
        s = (i.ravel() + 0.5) / nx * p.size_mm[0]
        t = (1.0 - (j.ravel() + 0.5) / ny) * p.size_mm[1]
        pos = o + s[:, None] * u + t[:, None] * v
        size = min(1.0, 0.5 * p.size_mm[0] / nx, 0.5 * p.size_mm[1] / ny)
        nrm = np.repeat(np.cross(u, v)[None, :], len(pos), axis=0)
        return self._sensor_grid(p.id, pos, nrm, size, p.offset_mm)

    # ------------------------------------------------------------------ passes
    def set_band_group(self, idx: list[int]) -> None:
        """Write bands ``idx`` (≤ 3) into the R, G, B of every spectral socket."""
        for sock, values, _ in self._colour_sockets:
            sock.default_value = _rgb(values, idx)

    def set_rgb(self, emission_to_rgb: np.ndarray, factor_to_rgb: np.ndarray) -> None:
        """Write one RGB rendering of every spectral socket (instead of band groups).

        ``emission_to_rgb`` (3, bands) maps band values per nm of an emitter to its RGB,
        ``factor_to_rgb`` (3, bands) a reflectance or transmittance to its RGB (see
        :mod:`lbscene.bakers.blender_export`).
        """
        for sock, values, kind in self._colour_sockets:
            m = emission_to_rgb if kind == "emission" else factor_to_rgb
            rgb = m @ np.asarray(values, float)
            if kind == "factor":
                rgb = np.clip(rgb, 0.0, 1.0)
            sock.default_value = (float(rgb[0]), float(rgb[1]), float(rgb[2]), 1.0)

    def _samples(self, samples: int, seed: int) -> None:
        import bpy

        c = bpy.context.scene.cycles
        c.samples = int(samples)
        c.seed = int(seed)

    def bake_irradiance(self, product, samples: int, seed: int) -> np.ndarray:
        """Irradiance (W·m⁻²·nm⁻¹ per channel) of a points/map product: (N, 3) or (ny, nx, 3)."""
        import bpy

        s = self._sensors[product.id]
        self._samples(samples, seed)
        for o in bpy.context.scene.objects:
            o.select_set(False)
        s.obj.hide_render = False
        try:
            bpy.context.view_layer.objects.active = s.obj
            s.obj.select_set(True)
            passes = {"DIRECT"} if product.light_paths == "direct" else {"DIRECT", "INDIRECT"}
            bpy.ops.object.bake(type="DIFFUSE", pass_filter=passes, margin=0, use_clear=True,
                                target="IMAGE_TEXTURES")
        finally:
            s.obj.hide_render = True
            s.obj.select_set(False)
        W, H = s.image.size
        px = np.empty(W * H * 4, np.float32)
        s.image.pixels.foreach_get(px)
        px = px.reshape(H, W, 4)[..., :3].astype(np.float64) * math.pi   # DIFFUSE light = E/π
        cols, rows, k = s.cells
        cells = px.reshape(rows, k, cols, k, 3).mean(axis=(1, 3)).reshape(rows * cols, 3)[: s.count]
        if product.type == "irradiance_map":
            return cells.reshape(product.resolution[1], product.resolution[0], 3)
        return cells

    def render_environment(self, product: EnvironmentMapProduct, samples: int, seed: int) -> np.ndarray:
        """Radiance seen from the product's position: (H, W, 3) equirect or (F, F·6, 3) cube strip."""
        import bpy
        from mathutils import Matrix

        scene = bpy.context.scene
        self._samples(samples, seed)
        scene.cycles.filter_width = 1.0   # box over the pixel: mean radiance over its solid angle
        cam_data = bpy.data.cameras.get("lbscene.envcam") or bpy.data.cameras.new("lbscene.envcam")
        cam = bpy.data.objects.get("lbscene.envcam")
        if cam is None:
            cam = bpy.data.objects.new("lbscene.envcam", cam_data)
            scene.collection.objects.link(cam)
        scene.camera = cam
        cam_data.clip_start = product.clip_start_mm * MM
        cam_data.clip_end = 1000.0
        pos = np.asarray(product.position_mm, float) * MM
        frames = []
        if product.projection == "equirect":
            cam_data.type = "PANO"
            cam_data.panorama_type = "EQUIRECTANGULAR"
            cam_data.latitude_min, cam_data.latitude_max = -math.pi / 2, math.pi / 2
            cam_data.longitude_min, cam_data.longitude_max = -math.pi, math.pi
            scene.render.resolution_x = product.width_px
            scene.render.resolution_y = product.width_px // 2
            f = np.asarray(product.forward, float)
            up = np.asarray(product.up, float)
            left = np.cross(up, f)
            # Cycles' equirect camera: image centre = camera local −Z, left edge…right edge
            # sweeps azimuth from +π to −π about local +Y (checked by tests/bakers)
            frames.append(np.stack([-left, up, -f], axis=1))
        else:
            cam_data.type = "PERSP"
            cam_data.sensor_fit = "HORIZONTAL"
            cam_data.angle = math.pi / 2
            cam_data.shift_x = cam_data.shift_y = 0.0
            scene.render.resolution_x = scene.render.resolution_y = product.width_px
            for d, right, upf in cube_face_frames(product.forward, product.up):
                frames.append(np.stack([right, upf, -d], axis=1))
        images = []
        with tempfile.TemporaryDirectory(prefix="lbscene-env-") as tmp:
            for i, rot in enumerate(frames):
                m = Matrix.Identity(4)
                for r in range(3):
                    for c in range(3):
                        m[r][c] = float(rot[r, c])
                    m[r][3] = float(pos[r])
                cam.matrix_world = m
                path = os.path.join(tmp, f"face{i}.exr")
                scene.render.filepath = path
                bpy.ops.render.render(write_still=True)
                from .products import read_exr_rgb

                images.append(read_exr_rgb(path))
        return images[0] if len(images) == 1 else np.concatenate(images, axis=1)

    def save_blend(self, path: Path) -> None:
        import bpy

        for s in self._sensors.values():
            s.obj.hide_render = False
        bpy.ops.wm.save_as_mainfile(filepath=str(path), compress=True, copy=True)
        for s in self._sensors.values():
            s.obj.hide_render = True


def bpy_world(scene):
    import bpy

    if scene.world is None:
        scene.world = bpy.data.worlds.new("black")
    w = scene.world
    if w.node_tree is not None:
        bg = next((n for n in w.node_tree.nodes if n.bl_idname == "ShaderNodeBackground"), None)
        if bg is not None:
            bg.inputs["Color"].default_value = (0.0, 0.0, 0.0, 1.0)
            bg.inputs["Strength"].default_value = 0.0
    return w
