# Error of EXR images against a reference, as peers.md measures it: mean |X - ref| / mean ref over
# the pixels outside the light, all channels. The light's pixels: where the reference or the image
# is brighter than half the reference's maximum, grown by one pixel (a voxelised light's rim is up
# to half a voxel wider than the mesh light, and each such pixel, 250 times the mean, would
# dominate the mean: that is the picture's outline, not the light the room receives); the same
# over the interior pixels only (away from every outline: the shading's error). And
# a stripe measure: the high-frequency energy of the back wall's pixels (the residual of a 5 x 5
# box blur, RMS, relative to their mean), to set against the reference's own.
#
# LIGHT_MASK=off keeps the brightest pixels (a daylit scene shows no lamp: its brightest pixels
# are the sunlit surfaces, which the error must count); BACKGROUND=r,g,b leaves out the pixels
# where the reference shows that colour (a uniform sky seen past the scene: the same in every
# image, it would only dilute the error).
#
#   blender -b -noaudio --factory-startup --python image_error.py -- REF.exr X.exr [X.exr ...]
#   ("--noise REF2.exr" first: REF2 of another seed; the reference is then the mean of the two,
#   and its noise the error of the mean moved by (REF - REF2) / (2 sqrt 2), the mean's own spread)
import os
import sys

import bpy
import numpy as np

args = sys.argv[sys.argv.index("--") + 1:]


def load(path):
    image = bpy.data.images.load(path)
    w, h = image.size
    pixels = np.empty(w * h * 4, dtype=np.float32)
    image.pixels.foreach_get(pixels)
    return pixels.reshape(h, w, 4)[:, :, :3].astype(np.float64)


noise = None
if args[0] == "--noise":
    noise = load(args[1])
    args = args[2:]
ref = load(args[0])
if noise is not None:
    # Two seeds: their mean is the reference, half their difference its noise.
    other = noise
    ref, noise = 0.5 * (ref + other), 0.5 * (ref - other)
lum = ref.mean(axis=2)
# The back wall between the blocks' tops and the ceiling, right of the tall block (Blender's
# rows run bottom-up: rows 42-77 %, columns 53-70 % of the default Cornell view).
masked = os.environ.get("LIGHT_MASK", "on") != "off"
seen = np.ones(lum.shape, dtype=bool)
if os.environ.get("BACKGROUND"):
    bg = np.array([float(v) for v in os.environ["BACKGROUND"].split(",")])
    seen = ~np.all(np.abs(ref - bg) <= 1e-4 * np.maximum(np.abs(bg), 1e-30), axis=2)
h, w = lum.shape
wall = (slice(int(0.42 * h), int(0.77 * h)), slice(int(0.53 * w), int(0.70 * w)))


def stripes(img):
    g = img.mean(axis=2)
    k = 2
    pad = np.pad(g, k, mode="edge")
    blur = sum(pad[k + dy:k + dy + g.shape[0], k + dx:k + dx + g.shape[1]]
               for dy in range(-k, k + 1) for dx in range(-k, k + 1)) / (2 * k + 1) ** 2
    r = (g - blur)[wall]
    return np.sqrt((r ** 2).mean()) / g[wall].mean()


def interior():
    """Pixels away from outlines: no 4-neighbour of the reference differs by more than 15 %,
    grown by 3 pixels (a voxel surface's outline is up to half a voxel off the mesh's, which
    the full error counts; this one measures the shading)."""
    edge = (lum >= 0.5 * lum.max()) * masked | (lum <= 0)
    for dy, dx in ((0, 1), (1, 0)):
        other = np.roll(lum, (dy, dx), (0, 1))
        edge |= np.abs(other - lum) > 0.15 * np.maximum(np.maximum(lum, other), 1e-30)
    for _ in range(3):
        edge = edge | np.roll(edge, 1, 0) | np.roll(edge, -1, 0) | np.roll(edge, 1, 1) \
            | np.roll(edge, -1, 1)
    return ~edge & seen


def error(x):
    bright = ((lum >= 0.5 * lum.max()) | (x.mean(axis=2) >= 0.5 * lum.max())) * masked
    grown = bright.copy()
    grown[1:, :] |= bright[:-1, :]
    grown[:-1, :] |= bright[1:, :]
    grown[:, 1:] |= bright[:, :-1]
    grown[:, :-1] |= bright[:, 1:]
    keep = ~grown & seen
    return np.abs(x - ref)[keep].mean() / ref[keep].mean()


print("reference %s: stripes %.4f" % (args[0], stripes(ref)))
if noise is not None:
    print("reference noise: %.4f" % error(ref + noise / 2 ** 0.5))
keep = interior()
print("interior pixels: %.0f %%" % (100 * keep.mean()))
for path in args[1:]:
    x = load(path)
    inside = np.abs(x - ref)[keep].mean() / ref[keep].mean()
    print("%s: error %.4f interior %.4f stripes %.4f" % (path, error(x), inside, stripes(x)))
