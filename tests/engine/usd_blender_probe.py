"""Run inside a separate Python process with bpy: import a USD stage with Blender's USD importer,
put a small white Lambertian probe at a point and render it with Cycles from above.

Prints the illuminance at the probe as JSON: E = π · L with L the probe's radiance (albedo 1), its
luminance taken with the Rec. 709 weights of the linear RGB Cycles renders.

Usage: python usd_blender_probe.py STAGE X_MM Y_MM Z_MM SAMPLES
"""

import json
import math
import sys
import tempfile
from pathlib import Path

import bpy
import numpy as np

stage, x_mm, y_mm, z_mm, samples = sys.argv[1], *map(float, sys.argv[2:5]), int(sys.argv[5])
bpy.ops.wm.read_factory_settings(use_empty=True)
bpy.ops.wm.usd_import(filepath=stage)
sc = bpy.context.scene
sc.render.engine = "CYCLES"
sc.cycles.device = "CPU"
sc.cycles.samples = samples
sc.cycles.seed = 1
sc.cycles.use_denoising = False
sc.cycles.use_adaptive_sampling = False
sc.cycles.sample_clamp_direct = 0.0
sc.cycles.sample_clamp_indirect = 0.0
sc.cycles.light_sampling_threshold = 0.0
sc.cycles.max_bounces = 16
sc.cycles.diffuse_bounces = 16
sc.world = bpy.data.worlds.new("black")
sc.world.color = (0.0, 0.0, 0.0)
sc.world.use_nodes = False
for obj in sc.objects:                 # the booth's own camera is not ours
    if obj.type == "CAMERA":
        obj.hide_render = True
m = 1e-3                                # the importer scales the millimetre stage to metres
bpy.ops.mesh.primitive_plane_add(size=0.01, location=(x_mm * m, y_mm * m, z_mm * m + 0.0005))
probe = bpy.context.active_object
mat = bpy.data.materials.new("probe")
mat.use_nodes = True
nodes = mat.node_tree.nodes
nodes.clear()
diffuse = nodes.new("ShaderNodeBsdfDiffuse")
diffuse.inputs["Color"].default_value = (1.0, 1.0, 1.0, 1.0)
out = nodes.new("ShaderNodeOutputMaterial")
mat.node_tree.links.new(diffuse.outputs["BSDF"], out.inputs["Surface"])
probe.data.materials.append(mat)
cam = bpy.data.cameras.new("probe_camera")
cam.type = "ORTHO"
cam.ortho_scale = 0.004
cam.clip_start = 0.001
cam.clip_end = 1.0
cam_obj = bpy.data.objects.new("probe_camera", cam)
sc.collection.objects.link(cam_obj)
cam_obj.location = (x_mm * m, y_mm * m, z_mm * m + 0.05)
sc.camera = cam_obj
sc.render.resolution_x = sc.render.resolution_y = 4
sc.view_settings.view_transform = "Standard"
sc.render.image_settings.file_format = "OPEN_EXR"
sc.render.image_settings.color_depth = "32"
with tempfile.TemporaryDirectory() as d:
    sc.render.filepath = str(Path(d) / "probe.exr")
    bpy.ops.render.render(write_still=True)
    img = bpy.data.images.load(sc.render.filepath)
    px = np.array(img.pixels[:], float).reshape(-1, 4)[:, :3].mean(axis=0)
luminance = float(np.dot([0.2126729, 0.7151522, 0.0721750], px))
print("PROBE " + json.dumps({"illuminance_lx": math.pi * luminance, "rgb_radiance": px.tolist()}))
