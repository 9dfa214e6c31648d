# Render an OBJ scene in Blender Cycles as the path-traced reference for vdbrad (issues 23, 25):
# vdbrad's reflectance model from the MTL the OBJ names (read here as vdbrad's voxelizer reads
# it): f = Kd / pi + Ks lobe (vdbrad/glossy/Brdf.h), a Lambertian Diffuse BSDF of colour Kd plus, for
# materials with Ks, a Glossy BSDF of weight Ks (Add Shader; see reflection()) with the
# multiscatter GGX distribution (energy-conserving, as vdbrad's compensated lobes are; no
# Fresnel) and vdbrad's roughness r: Pr, else from Ns r = sqrt(sqrt(2 / (Ns + 2))), else 0.5;
# clamped to [0.1, 1] and rounded to the solver's 0.01 steps; Cycles' alpha = r^2 as vdbrad's.
# Kd and Ks are scaled by 1 / max(Kd + Ks) where that exceeds 1, as the voxelizer does.
# Emission strength = Ke (so every pixel equals vdbrad's radiosity B: an Emission shader of
# strength S shows radiance S, vdbrad's exitance E is radiance E / pi), one-sided emitters, no
# denoising, no clamping, no adaptive sampling, a box pixel filter of the narrowest width (point
# samples at the pixel centre, as vdbrad's renderer), float EXR, the Standard view transform.
# Scenes with glossy materials also get glossy bounces, reflective caustics (diffuse -> glossy ->
# light paths: the floor lit through the blocks' lobes) and no glossy blur; purely diffuse scenes
# render exactly as before.
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

# The MTL's Kd, Ks, Ns, Pr and Ke by material name (vdbrad/mesh/ObjReader.cc's reading).
materials = {}
mtl = None
with open(mesh) as f:
    for line in f:
        if line.startswith("mtllib"):
            mtl = os.path.join(os.path.dirname(mesh), line.split(None, 1)[1].strip())
name = None
with open(mtl) as f:
    for line in f:
        w = line.split("#", 1)[0].split()
        if not w:
            continue
        key = w[0].capitalize()
        if key == "Newmtl":
            name = w[1]
            # vdbrad's default Kd is 0.5 (its --albedo), its default roughness 0.5.
            materials[name] = {"Kd": (0.5, 0.5, 0.5), "Ks": (0.0, 0.0, 0.0),
                               "Ke": (0.0, 0.0, 0.0)}
        elif key in ("Kd", "Ks", "Ke") and name:
            v = [float(x) for x in w[1:4]]
            materials[name][key] = tuple(v + v[-1:] * (3 - len(v)))
        elif key in ("Ns", "Pr") and name:
            materials[name][key] = float(w[1])


def roughness(m):
    """vdbrad's roughness: Pr, else from the Phong exponent Ns (Brdf::roughnessFromExponent),
    else 0.5; in [0.1, 1], rounded to the solver's 0.01 steps (GlossySurfaces::roughnessKey)."""
    if "Pr" in m:
        r = m["Pr"]
    elif "Ns" in m:
        r = math.sqrt(math.sqrt(2.0 / (max(m["Ns"], 0.0) + 2.0)))
    else:
        r = 0.5
    r = min(max(r, 0.1), 1.0)
    return min(max(round(r / 0.01) * 0.01, 0.1), 1.0)


glossy = False
for m in materials.values():
    # A surface reflects no more than it receives: the voxelizer scales Kd and Ks alike.
    worst = max(d + s for d, s in zip(m["Kd"], m["Ks"]))
    if worst > 1.0:
        m["Kd"] = tuple(d / worst for d in m["Kd"])
        m["Ks"] = tuple(s / worst for s in m["Ks"])
    glossy = glossy or max(m["Ks"]) > 0.0

bpy.ops.wm.read_factory_settings(use_empty=True)
# forward Y, up Z keeps the OBJ's own coordinates.
bpy.ops.wm.obj_import(filepath=mesh, forward_axis="Y", up_axis="Z")


def reflection(nodes, links, m):
    """vdbrad's f = Kd / pi + Ks lobe: a Lambertian Diffuse BSDF, plus a multiscatter GGX Glossy
    BSDF where Ks > 0. Returns the shader socket."""
    kd, ks = m["Kd"], m["Ks"]
    diffuse = nodes.new("ShaderNodeBsdfDiffuse")
    diffuse.inputs["Color"].default_value = (kd[0], kd[1], kd[2], 1.0)
    diffuse.inputs["Roughness"].default_value = 0.0   # Lambert
    if max(ks) <= 0.0:
        return diffuse.outputs["BSDF"]
    lobe = nodes.new("ShaderNodeBsdfGlossy")
    # Multiscatter GGX: GGX made energy-conserving (the light lost to shadowing and masking comes
    # back, by a random walk on the microsurface), as vdbrad's compensated lobes reflect all of
    # Ks; no Fresnel (vdbrad has none either).
    lobe.distribution = "MULTI_GGX"
    lobe.inputs["Roughness"].default_value = roughness(m)   # alpha = r^2, as vdbrad's
    # The lobe's colour Ks / max(Ks), weighted by max(Ks) through a Mix Shader (its other input
    # empty): the weight is Ks all the same, but Cycles also tints every microfacet bounce of the
    # random walk after the first by the colour, so colour Ks would reflect Ks^k, not Ks, of the
    # light that leaves after k bounces (glossy_cornell's short block top 5 % darker at Ks 0.6).
    # Grey Ks now reflects Ks exactly, coloured Ks (Ks / max Ks)^(k-1) Ks: nearly.
    k = max(ks)
    lobe.inputs["Color"].default_value = (ks[0] / k, ks[1] / k, ks[2] / k, 1.0)
    weight = nodes.new("ShaderNodeMixShader")
    weight.inputs["Fac"].default_value = k
    links.new(lobe.outputs["BSDF"], weight.inputs[2])
    add = nodes.new("ShaderNodeAddShader")
    links.new(diffuse.outputs["BSDF"], add.inputs[0])
    links.new(weight.outputs["Shader"], add.inputs[1])
    return add.outputs["Shader"]


for mat in bpy.data.materials:
    base = mat.name.split(".")[0]
    if base not in materials:
        continue
    m = materials[base]
    ke = m["Ke"]
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
        # The emitter also reflects its Kd (and Ks), as vdbrad's emitting voxels do (an Emission
        # shader alone is black to incoming light: the Cornell light's Kd 0.73 moved the back
        # wall 1 %).
        front = nodes.new("ShaderNodeAddShader")
        links.new(emit.outputs["Emission"], front.inputs[0])
        links.new(reflection(nodes, links, m), front.inputs[1])
        black = nodes.new("ShaderNodeBsdfDiffuse")
        black.inputs["Color"].default_value = (0.0, 0.0, 0.0, 1.0)
        geometry = nodes.new("ShaderNodeNewGeometry")
        mix = nodes.new("ShaderNodeMixShader")
        links.new(geometry.outputs["Backfacing"], mix.inputs["Fac"])
        links.new(front.outputs["Shader"], mix.inputs[1])
        links.new(black.outputs["BSDF"], mix.inputs[2])
        links.new(mix.outputs["Shader"], output.inputs["Surface"])
    else:
        links.new(reflection(nodes, links, m), output.inputs["Surface"])

# The world: black, or the light from outside that vdbrad's solve options in $WORLD give (issue
# 45), each pi times brighter in Cycles as the lamps are (a pixel shows radiance, vdbrad's
# radiosity): --sky L or R,G,B (a Background of that colour); --sky-model clear with --sun and
# --turbidity (the Preetham Sky Texture; black below the horizon for --ground-albedo 0, as
# vdbrad's ground is then); --environment FILE [--environment-rotation DEG] (an
# Environment Texture, linear); --sun ZENITH,AZIMUTH --irradiance E --sun-diameter D (a Sun lamp of
# strength pi E and that angle). --up gives the up axis of the OBJ's coordinates, which the import
# keeps: Blender's sky and map textures take z as up and turn azimuth the other way, so a y-up
# scene's view vector reaches them as (x, z, y).
def world_options(text):
    words, options = text.split(), {}
    for i, w in enumerate(words):
        if w.startswith("--"):
            nxt = words[i + 1] if i + 1 < len(words) else ""
            options[w[2:]] = "" if nxt.startswith("--") else nxt
    return options


def numbers(text):
    v = [float(x) for x in text.split(",")]
    return v if len(v) == 3 else v * 3


light = world_options(os.environ.get("WORLD", ""))
up = {"x": 0, "y": 1, "z": 2}[light.get("up", "y")]


def to_world(zenith, azimuth):
    """vdbrad's direction towards the sun (vdbrad/scene/Sun.cc) in the OBJ's coordinates."""
    first, second = sorted(((up + 1) % 3, (up + 2) % 3))
    z, a = math.radians(zenith), math.radians(azimuth)
    d = [0.0, 0.0, 0.0]
    d[up], d[first], d[second] = math.cos(z), math.sin(z) * math.cos(a), math.sin(z) * math.sin(a)
    return mathutils.Vector(d)


def sky_space(v):
    """A world vector as Blender's sky and environment textures read it (z up)."""
    if up == 2:
        return v
    first, second = sorted(((up + 1) % 3, (up + 2) % 3))
    return mathutils.Vector((v[first], v[second], v[up]))


world = bpy.data.worlds.new("world")
world.use_nodes = True
wnodes, wlinks = world.node_tree.nodes, world.node_tree.links
background = wnodes["Background"]
background.inputs["Strength"].default_value = 0.0
if "sky" in light:
    r, g, b = numbers(light["sky"])
    background.inputs["Color"].default_value = (r, g, b, 1.0)
    background.inputs["Strength"].default_value = math.pi
elif light.get("sky-model") == "clear" or "environment" in light:
    preetham_scale = 1.0
    # The view vector mapped to the textures' z-up space: a Mapping node (scale, then rotate)
    # swapping the up axis into z: y up: scale z by -1, then +90 degrees about x: (x, y, z) ->
    # (x, z, y). A turn of the map about up adds to the rotation about the textures' z.
    coords = wnodes.new("ShaderNodeTexCoord")
    mapping = wnodes.new("ShaderNodeMapping")
    mapping.vector_type = "VECTOR"
    if up == 1:
        mapping.inputs["Scale"].default_value = (1.0, 1.0, -1.0)
        mapping.inputs["Rotation"].default_value = (math.pi / 2, 0.0, 0.0)
    elif up == 0:
        raise SystemExit("--up x: not mapped")
    wlinks.new(coords.outputs["Generated"], mapping.inputs["Vector"])
    if light.get("sky-model") == "clear":
        tex = wnodes.new("ShaderNodeTexSky")
        tex.sky_type = "PREETHAM"
        tex.turbidity = float(light.get("turbidity", "3"))
        zen, azi = (float(x) for x in light["sun"].split(","))
        tex.sun_direction = sky_space(to_world(zen, azi))
        # Cycles scales Preetham's zenith luminance by 0.06 (scene/shader_nodes.cpp,
        # sky_texture_precompute_preetham); vdbrad keeps the paper's kcd/m^2.
        preetham_scale = 1.0 / 0.06
    else:
        tex = wnodes.new("ShaderNodeTexEnvironment")
        tex.image = bpy.data.images.load(os.path.abspath(light["environment"]))
        tex.image.colorspace_settings.name = "Linear"
        tex.interpolation = "Linear"
        turn = math.radians(float(light.get("environment-rotation", "0")))
        # vdbrad turns the map by +turn about up (from the first horizontal axis towards the
        # second); in the textures' space that is a turn about z of the opposite sense.
        rot = mapping.inputs["Rotation"].default_value
        if up == 2:
            mapping.inputs["Rotation"].default_value = (rot[0], rot[1], -turn)
        else:
            # Applied after the swap: a rotation about the textures' z.
            mapping2 = wnodes.new("ShaderNodeMapping")
            mapping2.vector_type = "VECTOR"
            mapping2.inputs["Rotation"].default_value = (0.0, 0.0, -turn)
            wlinks.new(mapping.outputs["Vector"], mapping2.inputs["Vector"])
            mapping = mapping2
    wlinks.new(mapping.outputs["Vector"], tex.inputs["Vector"])
    colour = tex.outputs["Color"]
    if light.get("sky-model") == "clear" and float(light.get("ground-albedo", "0.2")) == 0.0:
        # Below the horizon vdbrad's clear sky is a uniform ground of radiance --ground-albedo x
        # (the sky's and the sun's horizontal irradiance) / pi, where Blender's Preetham texture
        # repeats the horizon: the two agree for --ground-albedo 0, black below the horizon
        # (the textures' z <= 0). Other albedos differ there (compare_cycles.sh warns).
        xyz = wnodes.new("ShaderNodeSeparateXYZ")
        wlinks.new(mapping.outputs["Vector"], xyz.inputs["Vector"])
        above = wnodes.new("ShaderNodeMath")
        above.operation = "GREATER_THAN"
        above.inputs[1].default_value = 0.0
        wlinks.new(xyz.outputs["Z"], above.inputs[0])
        mask = wnodes.new("ShaderNodeMixRGB")
        mask.inputs["Color1"].default_value = (0.0, 0.0, 0.0, 1.0)
        wlinks.new(above.outputs["Value"], mask.inputs["Fac"])
        wlinks.new(colour, mask.inputs["Color2"])
        colour = mask.outputs["Color"]
    wlinks.new(colour, background.inputs["Color"])
    background.inputs["Strength"].default_value = math.pi * (
        preetham_scale if light.get("sky-model") == "clear" else 1.0)
scene = bpy.context.scene
scene.world = world
if "sun" in light and float(max(numbers(light.get("irradiance", "1")))) > 0.0:
    zen, azi = (float(x) for x in light["sun"].split(","))
    E = numbers(light.get("irradiance", "1"))
    k = max(E)
    lamp = bpy.data.lights.new("sun", type="SUN")
    lamp.energy = math.pi * k
    lamp.color = (E[0] / k, E[1] / k, E[2] / k)
    lamp.angle = math.radians(float(light.get("sun-diameter", "0.53")))
    sun = bpy.data.objects.new("sun", lamp)
    # A Sun lamp shines along its local -Z: towards -d.
    sun.rotation_euler = to_world(zen, azi).to_track_quat("Z", "Y").to_euler()
    scene.collection.objects.link(sun)

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
if glossy:
    # Every path vdbrad's solution holds: glossy bounces as many as diffuse ones, the light
    # reflected by a lobe onto diffuse surfaces (Cycles drops glossy closures after a diffuse
    # bounce without reflective caustics), and no blur of glossy closures after rough bounces.
    c.glossy_bounces = 64
    c.caustics_reflective = True
    c.blur_glossy = 0.0
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
