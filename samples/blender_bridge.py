"""Blender bridge: bake vdbrad's radiosity of a Blender scene into a colour attribute on its
meshes, and render it with Cycles, headless.

    blender -b -noaudio --factory-startup --python samples/blender_bridge.py -- \
        [--blend scene.blend | --obj mesh.obj] [--out DIR] [--res 128] [--directions 1000] \
        [--size 320x240] [--samples 16]

(samples/blender_bridge.sh runs it on the Cornell box.) Steps, all inside Blender:
  1. the scene: a .blend, or an OBJ imported as Blender does (coordinates kept);
  2. each mesh subdivided so that its edges are at most ~1.5 voxels long (the colour attribute
     lives on the face corners; big quads would have 4 samples), in world space;
  3. written as OBJ + MTL (Kd: the base colour, Ke: emission colour x strength, one `o` per
     object) and solved by the `vdbrad` tool: `vdbrad voxelize`, `vdbrad solve`;
  4. each face corner takes the radiosity of the solved voxel that holds it (the nearest surface
     voxel whose normal faces the face's way, within one voxel, else two; else the nearest
     one), read with pyopenvdb (Debian's
     Blender runs the system's Python 3.11, where python3-openvdb installs it);
  5. stored as the FLOAT_COLOR corner attribute `vdbrad_radiosity`; every material replaced by
     an Emission shader showing it (strength 1: a pixel then shows the radiosity B itself, as
     `vdbrad render` does), rendered by Cycles without bounces (the light is baked), PNG.
Writes DIR/scene.obj, .mtl, scene.vdb, solved.vdb, baked.blend and baked.png.
"""
import argparse
import math
import os
import shutil
import subprocess
import sys

import bmesh
import bpy
from mathutils import Vector


def arguments():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    here = os.path.dirname(os.path.abspath(__file__))
    p = argparse.ArgumentParser(prog="blender_bridge.py")
    p.add_argument("--blend", help="a .blend scene")
    p.add_argument("--obj", default=os.path.join(here, "meshes", "cornell_box.obj"),
                   help="an OBJ scene, if no --blend (default: the Cornell box)")
    p.add_argument("--out", default="blender_bridge", help="output folder")
    p.add_argument("--res", type=int, default=128, help="voxels along the longest axis")
    p.add_argument("--directions", type=int, default=1000)
    p.add_argument("--size", default="320x240", help="image WIDTHxHEIGHT")
    p.add_argument("--samples", type=int, default=16, help="Cycles samples per pixel")
    p.add_argument("--vdbrad", default=os.environ.get("VDBRAD", "vdbrad"),
                   help="the vdbrad tool (default: $VDBRAD, else vdbrad on PATH)")
    return p.parse_args(argv)


def load_scene(args):
    if args.blend:
        bpy.ops.wm.open_mainfile(filepath=os.path.abspath(args.blend))
        return
    bpy.ops.wm.read_factory_settings(use_empty=True)
    # forward Y, up Z: the OBJ's coordinates as they are (vdbrad reads them so too).
    bpy.ops.wm.obj_import(filepath=os.path.abspath(args.obj), forward_axis='Y', up_axis='Z')


def meshes():
    return [o for o in bpy.context.scene.objects if o.type == 'MESH' and o.visible_get()]


def world_box(objects):
    lo, hi = Vector((math.inf,) * 3), Vector((-math.inf,) * 3)
    for o in objects:
        for c in o.bound_box:
            w = o.matrix_world @ Vector(c)
            lo = Vector(map(min, lo, w))
            hi = Vector(map(max, hi, w))
    return lo, hi


def subdivide(obj, longest):
    """Bake the object's transform into its mesh and cut edges longer than @a longest."""
    mesh = obj.data
    mesh.transform(obj.matrix_world)
    obj.matrix_world.identity()
    bm = bmesh.new()
    bm.from_mesh(mesh)
    for _ in range(12):   # each round at least halves the longest edges
        long_edges = [e for e in bm.edges if e.calc_length() > longest]
        if not long_edges:
            break
        bmesh.ops.subdivide_edges(bm, edges=long_edges, cuts=1, use_grid_fill=True)
    bm.to_mesh(mesh)
    bm.free()
    mesh.update()


def shader_colours(material):
    """(Kd, Ke) of a material: its Principled or Diffuse colour, its emission x strength."""
    kd, ke = (0.5, 0.5, 0.5), (0.0, 0.0, 0.0)
    if material is None:
        return kd, ke
    if material.use_nodes:
        for node in material.node_tree.nodes:
            if node.type == 'BSDF_PRINCIPLED':
                kd = tuple(node.inputs["Base Color"].default_value[:3])
                s = node.inputs["Emission Strength"].default_value
                ke = tuple(s * c for c in node.inputs["Emission"].default_value[:3])
            elif node.type == 'BSDF_DIFFUSE':
                kd = tuple(node.inputs["Color"].default_value[:3])
            elif node.type == 'EMISSION':
                s = node.inputs["Strength"].default_value
                ke = tuple(s * c for c in node.inputs["Color"].default_value[:3])
    else:
        kd = tuple(material.diffuse_color[:3])
    return kd, ke


def write_obj(objects, path):
    """The meshes in world space as OBJ + MTL, one `o` per object, faces as Blender winds them
    (counter-clockwise seen from the side their normal points to, as vdbrad reads them)."""
    mtl = os.path.splitext(path)[0] + ".mtl"
    materials = {}
    with open(path, "w") as f:
        f.write("# written by samples/blender_bridge.py\nmtllib %s\n" % os.path.basename(mtl))
        base = 1
        for o in objects:
            mesh = o.data
            f.write("o %s\n" % o.name)
            for v in mesh.vertices:
                f.write("v %.9g %.9g %.9g\n" % tuple(v.co))
            current = None
            for poly in mesh.polygons:
                slot = o.material_slots[poly.material_index] if o.material_slots else None
                m = slot.material if slot else None
                name = m.name if m else "default"
                materials[name] = m
                if name != current:
                    f.write("usemtl %s\n" % name)
                    current = name
                f.write("f %s\n" % " ".join(str(base + i) for i in poly.vertices))
            base += len(mesh.vertices)
    with open(mtl, "w") as f:
        for name, m in materials.items():
            kd, ke = shader_colours(m)
            f.write("newmtl %s\nKd %.6g %.6g %.6g\nKe %.6g %.6g %.6g\n\n" % ((name,) + kd + ke))


def run(cmd):
    print("blender_bridge: " + " ".join(cmd), flush=True)
    subprocess.run(cmd, check=True)


def sample_radiosity(solved, objects):
    """Per object, per face corner: the radiosity of the surface voxel holding it."""
    import pyopenvdb
    # By name: Debian's pyopenvdb cannot read the file's Int32 grid (`material_id`) whole.
    radiosity, normals = (pyopenvdb.read(solved, name) for name in ("radiosity", "normal"))
    acc, nacc = radiosity.getConstAccessor(), normals.getConstAccessor()
    xform = radiosity.transform
    out, missed, corners = {}, 0, 0
    def nearest(p, n, reach, facing):
        centre = tuple(int(math.floor(c + 0.5)) for c in p)
        best, best_d = None, math.inf
        span = range(-reach, reach + 1)
        for dx in span:
            for dy in span:
                for dz in span:
                    ijk = (centre[0] + dx, centre[1] + dy, centre[2] + dz)
                    value, active = acc.probeValue(ijk)
                    if not active or (facing and Vector(nacc.getValue(ijk)).dot(n) < 0.5):
                        continue
                    d = sum((a - b) ** 2 for a, b in zip(ijk, p))
                    if d < best_d:
                        best, best_d = value, d
        return best

    for o in objects:
        mesh = o.data
        colours = [(0.0, 0.0, 0.0)] * len(mesh.loops)
        for poly in mesh.polygons:
            n = Vector(poly.normal)
            for li in poly.loop_indices:
                p = xform.worldToIndex(tuple(mesh.vertices[mesh.loops[li].vertex_index].co))
                # A voxel facing the face's way within one voxel, else within two (at a
                # corner the nearest voxels may face the other wall), else any within one.
                best = nearest(p, n, 1, True)
                if best is None:
                    best = nearest(p, n, 2, True)
                if best is None:
                    best = nearest(p, n, 1, False)
                corners += 1
                if best is None:
                    missed += 1
                else:
                    colours[li] = tuple(best) if isinstance(best, tuple) else (best,) * 3
        out[o.name] = colours
    print("blender_bridge: %d of %d face corners found no solved voxel (shown black)"
          % (missed, corners), flush=True)
    return out


def bake(objects, colours):
    shown = bpy.data.materials.new("vdbrad_radiosity")
    shown.use_nodes = True
    nodes, links = shown.node_tree.nodes, shown.node_tree.links
    nodes.clear()
    attribute = nodes.new("ShaderNodeAttribute")
    attribute.attribute_name = "vdbrad_radiosity"
    emission = nodes.new("ShaderNodeEmission")
    emission.inputs["Strength"].default_value = 1.0
    output = nodes.new("ShaderNodeOutputMaterial")
    links.new(attribute.outputs["Color"], emission.inputs["Color"])
    links.new(emission.outputs["Emission"], output.inputs["Surface"])
    for o in objects:
        mesh = o.data
        attr = mesh.color_attributes.new("vdbrad_radiosity", 'FLOAT_COLOR', 'CORNER')
        for i, c in enumerate(colours[o.name]):
            attr.data[i].color = (c[0], c[1], c[2], 1.0)
        mesh.materials.clear()
        mesh.materials.append(shown)


def camera_for(lo, hi, aspect):
    """A camera on the -z side looking along +z at the box, which it frames (as vdbrad
    render's default camera; the sample meshes are open towards -z)."""
    cam = bpy.data.cameras.new("vdbrad_camera")
    cam.sensor_fit = 'VERTICAL'
    fov = math.radians(40.0)
    cam.angle_y = fov
    obj = bpy.data.objects.new("vdbrad_camera", cam)
    bpy.context.scene.collection.objects.link(obj)
    centre = (lo + hi) / 2
    half = max((hi.y - lo.y) / 2, (hi.x - lo.x) / 2 / aspect)
    distance = half / math.tan(fov / 2) * 1.05
    obj.location = Vector((centre.x, centre.y, lo.z - distance))
    # A camera looks along its -z, up its +y: half a turn about y looks along +z, up +y.
    obj.rotation_euler = (0.0, math.pi, 0.0)
    return obj


def main():
    args = arguments()
    os.makedirs(args.out, exist_ok=True)
    out = os.path.abspath(args.out)
    tool = shutil.which(args.vdbrad) or args.vdbrad
    load_scene(args)
    objects = meshes()
    if not objects:
        sys.exit("blender_bridge: the scene has no meshes")
    lo, hi = world_box(objects)
    voxel = max(hi - lo) / args.res
    for o in objects:
        subdivide(o, 1.5 * voxel)
    obj = os.path.join(out, "scene.obj")
    write_obj(objects, obj)
    scene_vdb, solved = os.path.join(out, "scene.vdb"), os.path.join(out, "solved.vdb")
    run([tool, "voxelize", obj, scene_vdb, "--res", str(args.res), "--overwrite", "--quiet"])
    run([tool, "solve", scene_vdb, solved, "--directions", str(args.directions),
         "--tolerance", "1e-4", "--overwrite", "--quiet"])
    colours = sample_radiosity(solved, objects)
    bake(objects, colours)

    scene = bpy.context.scene
    width, height = (int(v) for v in args.size.split("x"))
    scene.render.resolution_x, scene.render.resolution_y = width, height
    scene.render.resolution_percentage = 100
    if scene.camera is None or not args.blend:
        scene.camera = camera_for(lo, hi, width / height)
    scene.render.engine = 'CYCLES'
    scene.cycles.device = 'CPU'
    scene.cycles.samples = args.samples
    scene.cycles.use_denoising = False
    scene.cycles.max_bounces = 0   # the light is baked: show it, nothing more
    scene.view_settings.view_transform = 'Standard'
    # Exposure as vdbrad render's PNG: the 90th percentile of the radiosity shown at 0.8.
    grey = sorted(sum(c) / 3 for cs in colours.values() for c in cs)
    p90 = grey[int(0.9 * (len(grey) - 1))] if grey else 0.0
    scene.view_settings.exposure = math.log2(0.8 / p90) if p90 > 0 else 0.0
    if scene.world is None:
        scene.world = bpy.data.worlds.new("World")
    scene.world.use_nodes = False
    scene.world.color = (0.0, 0.0, 0.0)
    scene.render.image_settings.file_format = 'PNG'
    scene.render.filepath = os.path.join(out, "baked.png")
    bpy.ops.render.render(write_still=True)
    bpy.ops.wm.save_as_mainfile(filepath=os.path.join(out, "baked.blend"))
    print("blender_bridge: %s/baked.png and %s/baked.blend" % (out, out), flush=True)


if __name__ == "__main__":
    main()
