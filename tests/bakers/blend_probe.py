"""Run in a separate Python process with bpy: open a ``.blend`` written by ``lbscene export-blender``,
switch one lighting on, put a small white Lambertian probe at a point and render it with Cycles from
above; or print what the file holds.

``render``: for each lighting (comma-separated) prints
``PROBE {"lighting": …, "illuminance_lx": …, "rgb_radiance": […]}``: E = 683 lm/W · π · Y(L)
with L the probe's radiance (albedo 1) and Y the Rec. 709 luminance of Blender's linear RGB — the
683 lm/W convention of Blender's watts.

``inspect``: prints ``FILE {…}``: per object its type, collection, material names, vertices (m),
light data and the emission colour of its material, read back from the file.

``env``: the same from an equirectangular render of the radiance above the point (see
:func:`env_render`).

Usage: python blend_probe.py render FILE LIGHTING[,LIGHTING…] X_MM Y_MM Z_MM SAMPLES [MAX_BOUNCES]
       python blend_probe.py env FILE LIGHTING[,LIGHTING…] X_MM Y_MM Z_MM SAMPLES
       python blend_probe.py inspect FILE
"""

import json
import math
import sys
import tempfile
from pathlib import Path

import bpy
import numpy as np

REC709_Y = np.array([0.2126729, 0.7151522, 0.0721750])


def _strength(sock):
    """A Strength input's constant factor: its value, or the constant of the Multiply feeding it."""
    if not sock.is_linked:
        return sock.default_value
    node = sock.links[0].from_node
    if node.bl_idname == "ShaderNodeMath" and node.operation == "MULTIPLY" and not node.inputs[1].is_linked:
        return node.inputs[1].default_value
    return None


def _emission(mat):
    """Colour × strength of a material's (or light's) Emission node: radiance (or intensity) RGB."""
    if mat is None or mat.node_tree is None:
        return None
    for n in mat.node_tree.nodes:
        if n.bl_idname == "ShaderNodeEmission":
            k = _strength(n.inputs["Strength"])
            c = list(n.inputs["Color"].default_value)[:3]
            return [x * k for x in c] if k is not None else None
    return None


def inspect(path):
    bpy.ops.wm.open_mainfile(filepath=path)
    sc = bpy.context.scene
    objs = {}
    for obj in sc.objects:
        d = {"type": obj.type, "collections": [c.name for c in obj.users_collection],
             "props": {k: obj[k] for k in obj.keys() if isinstance(obj[k], (str, int, float))},
             "visible_camera": obj.visible_camera}
        if obj.type == "MESH":
            mw = obj.matrix_world
            d["vertices_m"] = [list(mw @ v.co) for v in obj.data.vertices]
            d["materials"] = [m.name if m else None for m in obj.data.materials]
            polys = []
            for p in obj.data.polygons:
                polys.append([list(mw @ obj.data.vertices[i].co) for i in p.vertices])
            d["area_m2"] = float(sum(p.area for p in obj.data.polygons))
            d["emission_rgb"] = _emission(obj.data.materials[0] if obj.data.materials else None)
            emis = [n for n in obj.data.materials[0].node_tree.nodes if n.bl_idname == "ShaderNodeEmission"] \
                if obj.data.materials and obj.data.materials[0] else []
            if emis:
                d["emission_color"] = list(emis[0].inputs["Color"].default_value)[:3]
            if obj.data.materials and obj.data.materials[0]:
                nodes = obj.data.materials[0].node_tree.nodes
                d["node_types"] = sorted({n.bl_idname for n in nodes})
                glossy = [n for n in nodes if n.bl_idname in ("ShaderNodeBsdfGlossy", "ShaderNodeBsdfAnisotropic")]
                if glossy:
                    d["glossy_rgb"] = list(glossy[0].inputs["Color"].default_value)[:3]
                    d["glossy_roughness"] = glossy[0].inputs["Roughness"].default_value
        elif obj.type == "LIGHT":
            ld = obj.data
            d["light"] = {"type": ld.type, "energy_W": ld.energy, "radius_m": ld.shadow_soft_size}
            d["emission_rgb"] = _emission(ld) if ld.node_tree is not None else None
            d["location_m"] = list(obj.matrix_world.translation)
        elif obj.type == "CAMERA":
            d["camera"] = {"angle_x": obj.data.angle_x, "angle_y": obj.data.angle_y,
                           "sensor_fit": obj.data.sensor_fit, "location_m": list(obj.matrix_world.translation),
                           "forward": list(obj.matrix_world.to_3x3() @ __import__("mathutils").Vector((0, 0, -1)))}
        objs[obj.name] = d
    layer = {c.name: c.exclude for c in sc.view_layers[0].layer_collection.children}
    print("FILE " + json.dumps({"objects": objs, "excluded": layer, "camera": sc.camera.name if sc.camera else None,
                                "resolution": [sc.render.resolution_x, sc.render.resolution_y],
                                "props": {k: sc[k] for k in sc.keys() if isinstance(sc[k], str)}}))


def _open(path, samples):
    """Open the exported file and set Cycles for a reproducible CPU render of ``samples``."""
    bpy.ops.wm.open_mainfile(filepath=path)
    sc = bpy.context.scene
    c = sc.cycles
    c.device = "CPU"
    c.samples = samples
    c.seed = 1
    c.use_denoising = False
    c.use_adaptive_sampling = False
    return sc


def render(path, lightings, x_mm, y_mm, z_mm, samples, max_bounces=None):
    sc = _open(path, samples)
    c = sc.cycles
    if max_bounces is not None:
        c.max_bounces = max_bounces      # 0: the lamps' direct light only
    m = 1e-3
    bpy.ops.mesh.primitive_plane_add(size=0.004, location=(x_mm * m, y_mm * m, z_mm * m + 0.0005))
    probe = bpy.context.active_object
    mat = bpy.data.materials.new("probe")
    nodes = mat.node_tree.nodes
    nodes.clear()
    diffuse = nodes.new("ShaderNodeBsdfDiffuse")
    diffuse.inputs["Color"].default_value = (1.0, 1.0, 1.0, 1.0)
    out = nodes.new("ShaderNodeOutputMaterial")
    mat.node_tree.links.new(diffuse.outputs["BSDF"], out.inputs["Surface"])
    probe.data.materials.append(mat)
    probe.visible_shadow = False      # the probe measures; it does not take part in the light
    probe.visible_diffuse = False
    probe.visible_glossy = False
    cam = bpy.data.cameras.new("probe_camera")
    cam.type = "ORTHO"
    cam.ortho_scale = 0.002
    cam.clip_start = 0.001
    cam.clip_end = 1.0
    cam_obj = bpy.data.objects.new("probe_camera", cam)
    sc.collection.objects.link(cam_obj)
    cam_obj.location = (x_mm * m, y_mm * m, z_mm * m + 0.003)
    sc.camera = cam_obj
    sc.render.resolution_x = sc.render.resolution_y = 2
    sc.view_settings.view_transform = "Raw"
    sc.render.use_compositing = False
    sc.render.image_settings.file_format = "OPEN_EXR"
    sc.render.image_settings.color_depth = "32"
    for lighting in lightings.split(","):
        for lc in sc.view_layers[0].layer_collection.children:
            if lc.name.startswith("lighting "):
                lc.exclude = lc.name != f"lighting {lighting}"
        with tempfile.TemporaryDirectory() as d:
            sc.render.filepath = str(Path(d) / "probe.exr")
            bpy.ops.render.render(write_still=True)
            img = bpy.data.images.load(sc.render.filepath)
            px = np.array(img.pixels[:], float).reshape(-1, 4)[:, :3].mean(axis=0)
            bpy.data.images.remove(img)
        lum = float(REC709_Y @ px)
        print("PROBE " + json.dumps({"lighting": lighting, "illuminance_lx": 683.0 * math.pi * lum,
                                     "rgb_radiance": px.tolist()}))


def env_render(path, lightings, x_mm, y_mm, z_mm, samples, width=256):
    """Illuminance on an upward-facing receiver from an equirectangular render of the radiance
    around the point (1 mm above it): E = Σ L · sin(lat) · cos(lat) Δlat Δlon over the upper
    half; every emitter seen by camera rays.  Resolves small sources seen through a rough glass
    plate, which a diffuse probe reaches only by chance."""
    from mathutils import Matrix

    sc = _open(path, samples)
    for obj in sc.objects:
        if obj.type in ("MESH", "LIGHT") and str(obj.get("lbscene_role", "")).startswith("lamp"):
            obj.visible_camera = True
    cam = bpy.data.cameras.new("env_camera")
    cam.type = "PANO"
    cam.panorama_type = "EQUIRECTANGULAR"
    cam.clip_start = 1e-4
    cam.clip_end = 100.0
    cam_obj = bpy.data.objects.new("env_camera", cam)
    sc.collection.objects.link(cam_obj)
    # local +Y = world up, local -Z = world +y: latitude is the elevation above the horizon
    cam_obj.matrix_world = Matrix(((1, 0, 0, x_mm * 1e-3), (0, 0, -1, y_mm * 1e-3),
                                   (0, 1, 0, z_mm * 1e-3 + 1e-3), (0, 0, 0, 1)))
    sc.camera = cam_obj
    sc.render.resolution_x, sc.render.resolution_y = width, width // 2
    sc.render.resolution_percentage = 100
    sc.view_settings.view_transform = "Raw"
    sc.render.use_compositing = False
    sc.render.image_settings.file_format = "OPEN_EXR"
    sc.render.image_settings.color_depth = "32"
    h = width // 2
    lat = -math.pi / 2 + (np.arange(h) + 0.5) * math.pi / h          # pixel rows from the bottom
    weight = np.clip(np.sin(lat), 0, None) * np.cos(lat) * (math.pi / h) * (2 * math.pi / width)
    for lighting in lightings.split(","):
        for lc in sc.view_layers[0].layer_collection.children:
            if lc.name.startswith("lighting "):
                lc.exclude = lc.name != f"lighting {lighting}"
        with tempfile.TemporaryDirectory() as d:
            sc.render.filepath = str(Path(d) / "env.exr")
            bpy.ops.render.render(write_still=True)
            img = bpy.data.images.load(sc.render.filepath)
            px = np.array(img.pixels[:], float).reshape(h, width, 4)[..., :3]
            bpy.data.images.remove(img)
        e_rgb = (px * weight[:, None, None]).sum(axis=(0, 1))
        print("PROBE " + json.dumps({"lighting": lighting, "illuminance_lx": 683.0 * float(REC709_Y @ e_rgb),
                                     "rgb_irradiance": e_rgb.tolist()}))


if __name__ == "__main__":
    if sys.argv[1] == "inspect":
        inspect(sys.argv[2])
    elif sys.argv[1] == "env":
        env_render(sys.argv[2], sys.argv[3], *map(float, sys.argv[4:7]), int(sys.argv[7]))
    else:
        render(sys.argv[2], sys.argv[3], *map(float, sys.argv[4:7]), int(sys.argv[7]),
               int(sys.argv[8]) if len(sys.argv) > 8 else None)
