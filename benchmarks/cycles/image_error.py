# Error of EXR images against a reference, as peers.md measures it: mean |X - ref| / mean ref over
# the pixels outside the light (reference luminance below half its maximum), all channels; and
# a stripe measure: the high-frequency energy of the back wall's pixels (the residual of a 5 x 5
# box blur, RMS, relative to their mean), to set against the reference's own.
#
#   blender -b -noaudio --factory-startup --python image_error.py -- REF.exr X.exr [X.exr ...]
#   (a REF2.exr given as "--noise REF2.exr" first: the reference's noise, |REF - REF2| / 2)
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
    noise = args[1]
    args = args[2:]
ref = load(args[0])
lum = ref.mean(axis=2)
mask = lum < 0.5 * lum.max()
# The back wall: the middle of the picture above the blocks (rows 10-35 %, columns 35-65 %).
h, w = lum.shape
wall = (slice(int(0.10 * h), int(0.35 * h)), slice(int(0.35 * w), int(0.65 * w)))


def stripes(img):
    g = img.mean(axis=2)
    k = 2
    pad = np.pad(g, k, mode="edge")
    blur = sum(pad[k + dy:k + dy + g.shape[0], k + dx:k + dx + g.shape[1]]
               for dy in range(-k, k + 1) for dx in range(-k, k + 1)) / (2 * k + 1) ** 2
    r = (g - blur)[wall]
    return np.sqrt((r ** 2).mean()) / g[wall].mean()


def error(x):
    return np.abs(x - ref)[mask].mean() / ref[mask].mean()


print("reference %s: stripes %.4f" % (args[0], stripes(ref)))
if noise:
    print("reference noise (|ref - ref2| / 2): %.4f" % (error(load(noise)) / 2))
for path in args[1:]:
    x = load(path)
    print("%s: error %.4f stripes %.4f" % (path, error(x), stripes(x)))
