#!/usr/bin/env python3
"""Write bunny.obj and bunny.mtl beside this script from the Stanford bunny's PLY.

    python3 samples/meshes/make_bunny.py bun_zipper_res2.ply

The Stanford bunny (Stanford 3D Scanning Repository, bunny/reconstruction/bun_zipper_res2.ply:
8171 vertices, 16301 triangles; see README.md for where it came from) standing on a square grey
floor, for the sun + sky benchmark of issue 45. Python 3 standard library only; reads the ASCII
PLY the Stanford archive holds (any of bun_zipper*.ply). The committed OBJ and MTL are this
script's output from bun_zipper_res2.ply, byte for byte.

The bunny keeps its triangles, winding (counter-clockwise seen from outside: positive signed
volume) and scale (metres, y up, about 0.153 m high); it is only turned 180 degrees about y (x and
z negated), so that its familiar side view (head on the left) is seen from -z, where the other
samples' camera stands, and moved so that its lowest point touches the floor (y = 0) and its
footprint is centred on x = z = 0. The scan is not watertight (a few holes in the base) and holds
81 pairs of coincident triangles of opposite winding, as the archive's file does; they are left
as they are.
"""

import os
import sys

FLOOR_HALF = 0.25   # floor: x, z in [-0.25, 0.25] m, about 3 x the bunny's footprint

MTL = """\
# Materials of bunny.obj (written by make_bunny.py). Kd: diffuse albedo. No emission: the scene
# is lit from outside (vdbrad solve --sun, --sky, --sky-model clear, --environment; issue 45).
newmtl bunny
Kd 0.8 0.8 0.8

newmtl floor
Kd 0.5 0.5 0.5
"""


def read_ply(path):
    """The vertices (x, y, z) and triangles (0-based) of an ASCII PLY."""
    with open(path) as f:
        lines = f.read().splitlines()
    if not lines or lines[0].strip() != 'ply':
        raise SystemExit(f'{path}: not a PLY file')
    counts, order, end = {}, [], None
    for i, line in enumerate(lines):
        w = line.split()
        if w[:1] == ['format'] and w[1] != 'ascii':
            raise SystemExit(f'{path}: {w[1]} PLY; this script reads ASCII ones')
        if w[:1] == ['element']:
            counts[w[1]] = int(w[2])
            order.append(w[1])
        if w[:1] == ['end_header']:
            end = i + 1
            break
    if end is None or order[:2] != ['vertex', 'face']:
        raise SystemExit(f'{path}: expected vertex then face elements')
    nv, nf = counts['vertex'], counts['face']
    points = [tuple(float(x) for x in line.split()[:3]) for line in lines[end:end + nv]]
    triangles = []
    for line in lines[end + nv:end + nv + nf]:
        w = [int(x) for x in line.split()]
        if w[0] < 3 or len(w) != w[0] + 1:
            raise SystemExit(f'{path}: bad face line {line!r}')
        # A polygon as a fan (the Stanford files hold triangles only).
        triangles += [(w[1], w[k], w[k + 1]) for k in range(2, w[0])]
    return points, triangles


def signed_volume(points, triangles):
    v = 0.0
    for a, b, c in triangles:
        (ax, ay, az), (bx, by, bz), (cx, cy, cz) = points[a], points[b], points[c]
        v += (ax * (by * cz - bz * cy) - ay * (bx * cz - bz * cx) + az * (bx * cy - by * cx)) / 6
    return v


def fmt(x):
    s = '%.7g' % x
    return '0' if s in ('0', '-0') else s


def write(ply, folder):
    points, triangles = read_ply(ply)
    # Turned half a turn about y: a rotation, so the winding still faces outwards.
    points = [(-x, y, -z) for x, y, z in points]
    if signed_volume(points, triangles) <= 0.0:
        raise SystemExit(f'{ply}: negative signed volume: wound inwards?')
    lo = [min(p[k] for p in points) for k in range(3)]
    hi = [max(p[k] for p in points) for k in range(3)]
    shift = (-(lo[0] + hi[0]) / 2, -lo[1], -(lo[2] + hi[2]) / 2)
    moved = [tuple(p[k] + shift[k] for k in range(3)) for p in points]
    size = [hi[k] - lo[k] for k in range(3)]
    if max(size[0], size[2]) / 2 >= FLOOR_HALF:
        raise SystemExit(f'{ply}: the bunny is larger than the floor')
    h = FLOOR_HALF
    out = [
        '# bunny.obj: the Stanford bunny on a square floor, for vdbrad\'s sun + sky benchmark',
        '# (issue 45). Written by make_bunny.py from the Stanford 3D Scanning Repository\'s',
        f'# {os.path.basename(ply)} (edit the script, not this file); materials: bunny.mtl.',
        '#',
        f'# Units metres, y up. The bunny, {len(triangles)} triangles as scanned and decimated by',
        '# Stanford (counter-clockwise seen from outside), is not scaled: it is turned 180 degrees',
        '# about y (its head, on the left seen from -z, looks towards +x) and stands on the floor',
        f'# (y = 0), {fmt(size[1])} m high, its footprint ({fmt(size[0])} x {fmt(size[2])} m) centred',
        f'# on x = z = 0. The floor, x and z in [-{h}, {h}], faces up (+y). Nothing emits: light',
        '# it from outside (vdbrad solve --sun / --sky / --sky-model clear).',
        'mtllib bunny.mtl',
        '',
        'o floor',
        'usemtl floor',
        f'v -{h} 0 -{h}',
        f'v -{h} 0 {h}',
        f'v {h} 0 {h}',
        f'v {h} 0 -{h}',
        'f 1 2 3',
        'f 1 3 4',
        '',
        'o bunny',
        'usemtl bunny',
    ]
    out += ['v %s %s %s' % tuple(fmt(x) for x in p) for p in moved]
    base = 5   # 1-based, after the floor's 4 vertices
    out += ['f %d %d %d' % (a + base, b + base, c + base) for a, b, c in triangles]
    with open(os.path.join(folder, 'bunny.obj'), 'w', newline='\n') as f:
        f.write('\n'.join(out) + '\n')
    with open(os.path.join(folder, 'bunny.mtl'), 'w', newline='\n') as f:
        f.write(MTL)
    print(f'bunny.obj: {len(points)} + 4 vertices, {len(triangles)} + 2 triangles; '
          f'bunny {fmt(size[0])} x {fmt(size[1])} x {fmt(size[2])} m', file=sys.stderr)


if __name__ == '__main__':
    if len(sys.argv) != 2:
        raise SystemExit(__doc__)
    write(sys.argv[1], os.path.dirname(os.path.abspath(__file__)))
