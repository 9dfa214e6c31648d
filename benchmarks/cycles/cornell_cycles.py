# Render an OBJ scene in Blender Cycles as the path-traced reference for vdbrad (issue 23):
# pure Lambertian materials from the MTL's Kd (emitters' too), emission strength = Ke (so every
# pixel equals vdbrad's radiosity B: an Emission shader of strength S shows radiance S, vdbrad's
# exitance E is radiance E / pi), one-sided emitters, no denoising, no clamping, no adaptive
# sampling, a box pixel filter of the narrowest width (point samples at the pixel centre, as
# vdbrad's renderer), float EXR, the Standard view transform.
#
#   blender -b -noaudio --factory-startup --python cornell_cycles.py -- \
#       MESH.obj OUT.exr SAMPLES [SEED] [WIDTHxHEIGHT] [eye,target,up,fov]
import math
import os
import sys

import bpy
import mathutils

args = sys.argv[sys.argv.index("--") + 1:]
mesh, out, samples = args[0], args[1], int(args[2])
seed = int(args[3]) if len(args) > 3 else 0
width, height = (int(v) for v in (args[4] if len(args) > 4 else "320x240").split("x"))
cam = [float(v) for v in (args[5] if len(args) > 5 else
       "0.278,0.273,-0.8,0.278,0.273,0,0,1,0,39.3").split(",")]

# The MTL's Kd and Ke by material name.
materials = {}
mtl = None
with open(mesh) as f:
    for line in f:
        if line.startswith("mtllib"):
            mtl = os.path.join(os.path.dirname(mesh), line.split(None, 1)[1].strip())
name = None
with open(mtl) as f:
    for line in f:
        w = line.split()
        if not w or w[0].startswith("#"):
            continue
        if w[0] == "newmtl":
            name = w[1]
            materials[name] = {"Kd": (0.0, 0.0, 0.0), "Ke": (0.0, 0.0, 0.0)}
        elif w[0] in ("Kd", "Ke") and name:
            v = [float(x) for x in w[1:4]]
            materials[name][w[0]] = tuple(v + v[-1:] * (3 - len(v)))

bpy.ops.wm.read_factory_settings(use_empty=True)
# forward Y, up Z keeps the OBJ's own coordinates.
bpy.ops.wm.obj_import(filepath=mesh, forward_axis="Y", up_axis="Z")

for mat in bpy.data.materials:
    base = mat.name.split(".")[0]
    if base not in materials:
        continue
    kd, ke = materials[base]["Kd"], materials[base]["Ke"]
    mat.use_nodes = True
    nodes, links = mat.node_tree.nodes, mat.node_tree.links
    nodes.clear()
    output = nodes.new("ShaderNodeOutputMaterial")
    if max(ke) > 0.0:
        # One-sided: the back face is black.
        emit = nodes.new("ShaderNodeEmission")
        s = max(ke)
        emit.inputs["Color"].default_value = (ke[0] / s, ke[1] / s, ke[2] / s, 1.0)
        emit.inputs["Strength"].default_value = s
        # The emitter also reflects its Kd, as vdbrad's emitting voxels do (an Emission shader
        # alone is black to incoming light: the Cornell light's Kd 0.73 moved the back wall 1 %).
        reflect = nodes.new("ShaderNodeBsdfDiffuse")
        reflect.inputs["Color"].default_value = (kd[0], kd[1], kd[2], 1.0)
        reflect.inputs["Roughness"].default_value = 0.0
        front = nodes.new("ShaderNodeAddShader")
        links.new(emit.outputs["Emission"], front.inputs[0])
        links.new(reflect.outputs["BSDF"], front.inputs[1])
        black = nodes.new("ShaderNodeBsdfDiffuse")
        black.inputs["Color"].default_value = (0.0, 0.0, 0.0, 1.0)
        geometry = nodes.new("ShaderNodeNewGeometry")
        mix = nodes.new("ShaderNodeMixShader")
        links.new(geometry.outputs["Backfacing"], mix.inputs["Fac"])
        links.new(front.outputs["Shader"], mix.inputs[1])
        links.new(black.outputs["BSDF"], mix.inputs[2])
        links.new(mix.outputs["Shader"], output.inputs["Surface"])
    else:
        diffuse = nodes.new("ShaderNodeBsdfDiffuse")
        diffuse.inputs["Color"].default_value = (kd[0], kd[1], kd[2], 1.0)
        diffuse.inputs["Roughness"].default_value = 0.0   # Lambert
        links.new(diffuse.outputs["BSDF"], output.inputs["Surface"])

world = bpy.data.worlds.new("black")
world.use_nodes = True
world.node_tree.nodes["Background"].inputs["Strength"].default_value = 0.0
scene = bpy.context.scene
scene.world = world

camera = bpy.data.cameras.new("camera")
camera.sensor_fit = "VERTICAL"
camera.angle_y = math.radians(cam[9])
camera.clip_start = 1e-3
obj = bpy.data.objects.new("camera", camera)
scene.collection.objects.link(obj)
eye = mathutils.Vector(cam[0:3])
forward = mathutils.Vector(cam[3:6]) - eye
up = mathutils.Vector(cam[6:9])
right = forward.cross(up).normalized()
true_up = right.cross(forward).normalized()
# Blender cameras look along their local -Z with local +Y up.
rotation = mathutils.Matrix((right, true_up, -forward.normalized())).transposed()
obj.matrix_world = mathutils.Matrix.Translation(eye) @ rotation.to_4x4()
scene.camera = obj

scene.render.engine = "CYCLES"
c = scene.cycles
c.device = "CPU"
c.samples = samples
c.seed = seed
c.use_adaptive_sampling = False
c.use_denoising = False
c.sample_clamp_direct = 0.0
c.sample_clamp_indirect = 0.0
c.max_bounces = 64
c.diffuse_bounces = 64
c.glossy_bounces = 0
c.transmission_bounces = 0
c.volume_bounces = 0
c.transparent_max_bounces = 0
c.caustics_reflective = False
c.caustics_refractive = False
c.filter_width = 0.01
c.pixel_filter_type = "BOX"
scene.render.threads_mode = "FIXED"
scene.render.threads = int(os.environ.get("THREADS", "2"))
scene.render.resolution_x = width
scene.render.resolution_y = height
scene.render.resolution_percentage = 100
scene.view_settings.view_transform = "Standard"
scene.view_settings.look = "None"
scene.view_settings.exposure = 0.0
scene.view_settings.gamma = 1.0
scene.render.image_settings.file_format = "OPEN_EXR"
scene.render.image_settings.color_depth = "32"
scene.render.image_settings.color_mode = "RGB"
scene.render.filepath = out
bpy.ops.render.render(write_still=True)
