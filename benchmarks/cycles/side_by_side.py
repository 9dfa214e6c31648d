# Images side by side in one PNG, one tone map for all (the first image's 90th percentile of
# luminance at 0.8, then sRGB), for comparing renders by eye (docs/*-vs-cycles.png):
#
#   blender -b -noaudio --factory-startup --python benchmarks/cycles/side_by_side.py -- \
#       OUT.png SCALE REF.exr A.exr [B.exr ...]
#
# Blender's Python reads the EXRs (Debian's has no OpenEXR module otherwise); the PNG is
# written by hand (zlib) so that no colour management touches the values.
import struct
import sys
import zlib

import bpy
import numpy as np

args = sys.argv[sys.argv.index("--") + 1:]
out, scale, paths = args[0], int(args[1]), args[2:]


def load(path):
    image = bpy.data.images.load(path)
    w, h = image.size
    px = np.empty(w * h * 4, np.float32)
    image.pixels.foreach_get(px)
    return px.reshape(h, w, 4)[::-1, :, :3].astype(np.float64)   # top row first


images = [load(p) for p in paths]
k = 0.8 / np.percentile(images[0].mean(axis=2), 90)
# A white gutter of two pixels between images.
row = np.concatenate([np.pad(i, ((0, 0), (0, 2), (0, 0)), constant_values=1.0 / k)
                      for i in images], axis=1) * k
row = np.clip(row, 0.0, 1.0)
row = np.where(row <= 0.0031308, 12.92 * row, 1.055 * row ** (1 / 2.4) - 0.055)
row = np.repeat(np.repeat(row, scale, 0), scale, 1)
b = (row * 255 + 0.5).astype(np.uint8)
h, w, _ = b.shape
raw = b"".join(b"\0" + b[y].tobytes() for y in range(h))


def chunk(tag, data):
    return (struct.pack(">I", len(data)) + tag + data
            + struct.pack(">I", zlib.crc32(tag + data) & 0xffffffff))


with open(out, "wb") as f:
    f.write(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 8, 2, 0, 0, 0))
            + chunk(b"IDAT", zlib.compress(raw, 9)) + chunk(b"IEND", b""))
print("wrote %s (%d x %d, tone scale %.4g)" % (out, w, h, k))
