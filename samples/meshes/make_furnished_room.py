#!/usr/bin/env python3
"""Write furnished_room.obj and furnished_room.mtl beside this script.

    python3 samples/meshes/make_furnished_room.py

A living room of 4 x 2.6 x 5 m (metres, y up) open on its -z side, where the camera stands,
like the Cornell box: floor, ceiling, back wall and two side walls facing into the room; a table,
two chairs, a bookshelf with books, a sofa, a ball on the table and a rug, all closed and wound
outwards; an emitting ceiling panel and a warm emitting window panel. The committed OBJ and MTL
are this script's output, byte for byte; edit the script, not them. Python 3 standard library
only. Before writing, every closed part is checked to be watertight and wound outwards, and every
open one to face the way it should, so a geometry edit that breaks either fails here.
"""

import math
import os
import sys

# Room: x in [-W/2, W/2], y in [0, H], z in [0, D]; open at z = 0.
W, H, D = 4.0, 2.6, 5.0

# name: (Kd, Ke or None, what it is). Emission is radiosity (power per area), the unit of the
# `emission` grid vdbrad solves with.
MATERIALS = {
    'floor_oak': ((0.55, 0.36, 0.2), None, 'floor'),
    'ceiling_white': ((0.8, 0.8, 0.8), None, 'ceiling'),
    'wall_terracotta': ((0.7, 0.38, 0.28), None, 'back wall'),
    'wall_sage': ((0.42, 0.56, 0.4), None, 'side wall x = -2 (right, seen from the camera)'),
    'wall_white': ((0.78, 0.76, 0.72), None, 'side wall x = +2 (left), with the window'),
    'walnut': ((0.45, 0.28, 0.15), None, 'table and bookshelf'),
    'chair_blue': ((0.15, 0.3, 0.6), None, 'chairs'),
    'sofa_red': ((0.6, 0.12, 0.1), None, 'sofa'),
    'rug_teal': ((0.1, 0.45, 0.45), None, 'rug'),
    'ball_yellow': ((0.85, 0.7, 0.1), None, 'ball on the table'),
    'book_red': ((0.7, 0.1, 0.1), None, 'books'),
    'book_blue': ((0.1, 0.2, 0.6), None, 'books'),
    'book_green': ((0.1, 0.5, 0.2), None, 'books'),
    'book_yellow': ((0.85, 0.75, 0.2), None, 'books'),
    'book_cream': ((0.85, 0.82, 0.7), None, 'books'),
    'ceiling_light': ((0.8, 0.8, 0.8), (8.0, 8.0, 8.0), 'ceiling panel, cool white'),
    'window_light': ((0.8, 0.8, 0.8), (3.0, 2.2, 1.4), 'window panel, warm (low sun)'),
}


class Part:
    """One `o` object: a material, vertices and polygons (0-based, counter-clockwise seen from
    the side they face). Closed parts must be watertight; open ones state their normal."""

    def __init__(self, name, material, closed, normal=None):
        assert material in MATERIALS, material
        self.name, self.material, self.closed, self.normal = name, material, closed, normal
        self.points, self.faces = [], []


# ---- shapes ----------------------------------------------------------------------------------

# Unit-cube corners (bit 0: x, bit 1: y, bit 2: z, in this order) and its faces wound outwards.
CUBE = [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0), (0, 0, 1), (1, 0, 1), (1, 1, 1), (0, 1, 1)]
CUBE_FACES = [(0, 3, 2, 1), (4, 5, 6, 7), (0, 1, 5, 4), (3, 7, 6, 2), (0, 4, 7, 3), (1, 2, 6, 5)]


def box(name, material, lo, hi):
    p = Part(name, material, closed=True)
    p.points = [tuple(lo[a] + c[a] * (hi[a] - lo[a]) for a in range(3)) for c in CUBE]
    p.faces = [list(f) for f in CUBE_FACES]
    return p


def quad(name, material, corners, normal):
    p = Part(name, material, closed=False, normal=normal)
    p.points = list(corners)
    p.faces = [[0, 1, 2, 3]]
    return p


def sphere(name, material, centre, radius, segments, rings):
    """UV sphere: two poles and rings - 1 circles of `segments` vertices; 2 segments (rings - 1)
    triangles."""
    p = Part(name, material, closed=True)
    cx, cy, cz = centre
    p.points.append((cx, cy - radius, cz))                       # 0: south pole
    for r in range(1, rings):
        theta = math.pi * r / rings                              # from the south pole
        y = cy - radius * math.cos(theta)
        ring = radius * math.sin(theta)
        for s in range(segments):
            phi = 2.0 * math.pi * s / segments
            p.points.append((cx + ring * math.cos(phi), y, cz + ring * math.sin(phi)))
    p.points.append((cx, cy + radius, cz))                       # north pole
    north = len(p.points) - 1

    def v(r, s):                                                 # ring r in 1..rings-1
        return 1 + (r - 1) * segments + s % segments

    for s in range(segments):
        p.faces.append([0, v(1, s), v(1, s + 1)])
        for r in range(1, rings - 1):
            p.faces.append([v(r, s), v(r + 1, s), v(r + 1, s + 1), v(r, s + 1)])
        p.faces.append([north, v(rings - 1, s + 1), v(rings - 1, s)])
    # Quads between rings are planar (a ring's vertices share y), so the fan triangulation a
    # reader does is exact; write them as triangles anyway to give every reader the same mesh.
    tris = []
    for f in p.faces:
        tris.extend([[f[0], f[i], f[i + 1]] for i in range(1, len(f) - 1)])
    p.faces = tris
    return p


# ---- the scene -------------------------------------------------------------------------------

def room():
    x0, x1 = -W / 2, W / 2
    parts = [
        quad('floor', 'floor_oak', [(x0, 0, 0), (x0, 0, D), (x1, 0, D), (x1, 0, 0)], (0, 1, 0)),
        quad('ceiling', 'ceiling_white', [(x0, H, 0), (x1, H, 0), (x1, H, D), (x0, H, D)],
             (0, -1, 0)),
        quad('back_wall', 'wall_terracotta', [(x0, 0, D), (x0, H, D), (x1, H, D), (x1, 0, D)],
             (0, 0, -1)),
        quad('wall_x_minus', 'wall_sage', [(x0, 0, 0), (x0, H, 0), (x0, H, D), (x0, 0, D)],
             (1, 0, 0)),
        quad('wall_x_plus', 'wall_white', [(x1, 0, 0), (x1, 0, D), (x1, H, D), (x1, H, 0)],
             (-1, 0, 0)),
    ]
    # Lights 1 cm off their surfaces, so that they are not coplanar with them.
    y = H - 0.01
    parts.append(quad('ceiling_light', 'ceiling_light',
                      [(-0.6, y, 2.2), (0.6, y, 2.2), (0.6, y, 3.0), (-0.6, y, 3.0)], (0, -1, 0)))
    x = x1 - 0.01
    parts.append(quad('window', 'window_light',
                      [(x, 0.9, 2.0), (x, 0.9, 3.4), (x, 2.0, 3.4), (x, 2.0, 2.0)], (-1, 0, 0)))
    return parts


RUG_TOP = 0.01


def furniture():
    parts = [box('rug', 'rug_teal', (-1.7, 0, 1.7), (1.3, RUG_TOP, 3.5))]

    # Table: top 1.4 x 0.8 m at 0.75 m, centred on (x, z) = (-0.2, 2.6); legs stand on the rug.
    parts.append(box('table_top', 'walnut', (-0.9, 0.72, 2.2), (0.5, 0.75, 3.0)))
    for i, (lx, lz) in enumerate([(-0.86, 2.24), (0.4, 2.24), (-0.86, 2.9), (0.4, 2.9)]):
        parts.append(box('table_leg_%d' % (i + 1), 'walnut', (lx, RUG_TOP, lz),
                         (lx + 0.06, 0.72, lz + 0.06)))

    # A ball resting on the table top.
    parts.append(sphere('ball', 'ball_yellow', (0.1, 0.9, 2.55), 0.15, segments=20, rings=12))

    # Two chairs facing each other across the table: seat 0.44 m square at 0.47 m, back 0.95 m.
    for n, (cx, back_side) in enumerate([(-1.25, -1), (0.85, 1)]):
        s0, s1 = cx - 0.22, cx + 0.22
        name = 'chair_%d' % (n + 1)
        parts.append(box(name + '_seat', 'chair_blue', (s0, 0.43, 2.38), (s1, 0.47, 2.82)))
        bx0 = s0 if back_side < 0 else s1 - 0.04
        parts.append(box(name + '_back', 'chair_blue', (bx0, 0.47, 2.38), (bx0 + 0.04, 0.95, 2.82)))
        for i, (lx, lz) in enumerate([(s0 + 0.02, 2.4), (s1 - 0.06, 2.4), (s0 + 0.02, 2.76),
                                      (s1 - 0.06, 2.76)]):
            parts.append(box('%s_leg_%d' % (name, i + 1), 'chair_blue', (lx, RUG_TOP, lz),
                             (lx + 0.04, 0.43, lz + 0.04)))

    # Sofa against the back wall, on the +x side: base, back and two arms, none overlapping.
    parts.append(box('sofa_base', 'sofa_red', (0.3, 0, 4.05), (1.9, 0.42, 4.75)))
    parts.append(box('sofa_back', 'sofa_red', (0.3, 0, 4.75), (1.9, 0.85, 4.95)))
    parts.append(box('sofa_arm_1', 'sofa_red', (0.3, 0.42, 4.05), (0.5, 0.62, 4.75)))
    parts.append(box('sofa_arm_2', 'sofa_red', (1.7, 0.42, 4.05), (1.9, 0.62, 4.75)))

    # Bookshelf against the back wall, on the -x side: 1 x 2 x 0.35 m, five boards.
    bx0, bx1, bz0, bz1 = -1.9, -0.9, 4.6, 4.95
    parts.append(box('shelf_side_1', 'walnut', (bx0, 0, bz0), (bx0 + 0.02, 2.0, bz1)))
    parts.append(box('shelf_side_2', 'walnut', (bx1 - 0.02, 0, bz0), (bx1, 2.0, bz1)))
    parts.append(box('shelf_back', 'walnut', (bx0 + 0.02, 0, bz1 - 0.02), (bx1 - 0.02, 2.0, bz1)))
    boards = [(0.0, 0.08), (0.5, 0.52), (1.0, 1.02), (1.5, 1.52), (1.98, 2.0)]
    for i, (y0, y1) in enumerate(boards):
        parts.append(box('shelf_board_%d' % (i + 1), 'walnut', (bx0 + 0.02, y0, bz0),
                         (bx1 - 0.02, y1, bz1 - 0.02)))

    # Books on the lower four boards: widths, heights and colours from a fixed cycle, so the
    # output never changes; a gap leaves each shelf partly empty.
    colours = ['book_red', 'book_blue', 'book_cream', 'book_green', 'book_yellow', 'book_blue',
               'book_red', 'book_cream', 'book_green']
    widths = [0.04, 0.03, 0.05, 0.035, 0.045, 0.03, 0.06, 0.04]
    heights = [0.28, 0.24, 0.3, 0.22, 0.26, 0.32, 0.25, 0.27]
    k = 0
    for shelf in range(4):
        y0 = boards[shelf][1]
        x = bx0 + 0.04 + 0.03 * shelf
        for b in range(7 - shelf % 2):
            w, h = widths[k % len(widths)], heights[(3 * k) % len(heights)]
            parts.append(box('book_%d' % (k + 1), colours[k % len(colours)],
                             (x, y0, bz0 + 0.06), (x + w, y0 + h, bz1 - 0.04)))
            x += w + 0.005
            k += 1
    return parts


# ---- checks ----------------------------------------------------------------------------------

def sub(a, b):
    return tuple(p - q for p, q in zip(a, b))


def cross(a, b):
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def dot(a, b):
    return sum(p * q for p, q in zip(a, b))


def triangles(part):
    for f in part.faces:
        for i in range(1, len(f) - 1):
            yield f[0], f[i], f[i + 1]


def check(part):
    """Closed parts: every edge used exactly twice, once in each direction, and a positive
    signed volume (so outwards, not inwards). Open parts: every triangle faces `normal`."""
    if not part.closed:
        for a, b, c in triangles(part):
            n = cross(sub(part.points[b], part.points[a]), sub(part.points[c], part.points[a]))
            if dot(n, part.normal) <= 0:
                sys.exit('%s: a triangle does not face %s' % (part.name, part.normal))
        return
    edges = {}
    volume = 0.0
    for a, b, c in triangles(part):
        for e in ((a, b), (b, c), (c, a)):
            edges[e] = edges.get(e, 0) + 1
        volume += dot(part.points[a], cross(part.points[b], part.points[c])) / 6.0
    for (a, b), n in edges.items():
        if n != 1 or edges.get((b, a)) != 1:
            sys.exit('%s: edge %d-%d is not shared by exactly two faces in opposite senses'
                     % (part.name, a, b))
    if volume <= 0:
        sys.exit('%s: signed volume %g <= 0 (wound inwards)' % (part.name, volume))


def overlaps(p, q):
    """True when the bounding boxes of two closed parts overlap by more than touching."""
    lo = [max(min(v[a] for v in p.points), min(v[a] for v in q.points)) for a in range(3)]
    hi = [min(max(v[a] for v in p.points), max(v[a] for v in q.points)) for a in range(3)]
    return all(h - l > 1e-9 for l, h in zip(lo, hi))


# ---- output ----------------------------------------------------------------------------------

def fmt(v):
    s = ('%.5f' % v).rstrip('0').rstrip('.')
    return '0' if s in ('-0', '') else s


HEADER = """\
# furnished_room.obj: a furnished living room for vdbrad's mesh voxelizer.
# Written by make_furnished_room.py (edit that, not this file); materials: furnished_room.mtl.
#
# Units metres, y up. The room spans x in [-2, 2], y in [0, 2.6], z in [0, 5] and is open at
# z = 0, towards the camera on the -z side (like the Cornell box); seen from there the window
# wall (x = +2) is on the left.
# Winding: counter-clockwise seen from the side a face faces. Floor, ceiling and walls face into
# the room; every furniture part is a closed mesh wound outwards (checked by the script).
# Lights: ceiling_light, a 1.2 x 0.8 m panel 1 cm below the ceiling facing down, and window, a
# 1.4 x 1.1 m warm panel 1 cm off the x = +2 wall facing into the room.
"""


def write(folder):
    parts = room() + furniture()
    for p in parts:
        check(p)
    # Parts may touch but not interpenetrate, so each one's surface is all visible surface.
    closed = [p for p in parts if p.closed]
    for i, p in enumerate(closed):
        for q in closed[i + 1:]:
            if overlaps(p, q):
                sys.exit('%s and %s overlap' % (p.name, q.name))

    lines = [HEADER + 'mtllib furnished_room.mtl']
    base = 1
    for p in parts:
        lines.append('')
        lines.append('o ' + p.name)
        lines.append('usemtl ' + p.material)
        lines.extend('v %s %s %s' % tuple(fmt(c) for c in v) for v in p.points)
        lines.extend('f ' + ' '.join(str(base + i) for i in f) for f in p.faces)
        base += len(p.points)
    with open(os.path.join(folder, 'furnished_room.obj'), 'w', newline='\n') as f:
        f.write('\n'.join(lines) + '\n')

    mtl = ['# Materials of furnished_room.obj (written by make_furnished_room.py). Kd: diffuse',
           '# albedo (RGB, in [0, 1]); Ke: emitted radiosity. Nothing else matters to vdbrad.']
    for name, (kd, ke, what) in MATERIALS.items():
        mtl += ['', '# ' + what, 'newmtl ' + name, 'Kd ' + ' '.join(fmt(c) for c in kd)]
        if ke:
            mtl.append('Ke ' + ' '.join(fmt(c) for c in ke))
    with open(os.path.join(folder, 'furnished_room.mtl'), 'w', newline='\n') as f:
        f.write('\n'.join(mtl) + '\n')
    triangles_total = sum(len(list(triangles(p))) for p in parts)
    print('furnished_room.obj: %d parts (%d closed), %d triangles'
          % (len(parts), sum(p.closed for p in parts), triangles_total))


if __name__ == '__main__':
    write(os.path.dirname(os.path.abspath(__file__)))
