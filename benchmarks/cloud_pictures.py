# Run by cloud_pictures.sh in its work folder (w0.vdb, w877.vdb): the render's error against
# the fewest moments and the coarsest steps, and the docs picture (argv[1]).
import struct
import sys
import time
import zlib

import numpy as np
import pyopenvdb as vdb
import vdbrad

iso, _ = vdb.readAll("w0.vdb")
fwd, _ = vdb.readAll("w877.vdb")
centre, to_sun = np.array([-12.0, 72.0, -45.0]), np.array([0.7071, 0.7071, 0.0])
views = {"side": None, "backlit": (centre - 800 * to_sun, centre),
         "frontlit": (centre + 800 * np.array([0.8, 0.25, 0.55]), centre)}


def camera(view):
    if view is None:
        return {}
    eye, target = view
    return {"camera": ",".join("%g" % x for x in list(eye) + list(target) + [0, 1, 0, 50])}


def difference(image, ref):
    # Mean absolute difference over the cloud's pixels, relative to their mean.
    lum = ref.mean(axis=2)
    mask = lum > 0.02 * lum.max()
    return np.abs(image - ref).mean(axis=2)[mask].sum() / lum[mask].sum()


res = (480, 320)
for name, view in views.items():
    ref = None
    for order in [8, 4, 2, 1, 0]:
        start = time.time()
        image = vdbrad.render(fwd, res=res, cloud_source_order=order, **camera(view))
        seconds = time.time() - start
        ref = image if ref is None else ref
        print("g 0.877 %s, moments to order %d: %.2f s, %.2f %% from order 8"
              % (name, order, seconds, 100 * difference(image, ref)), flush=True)
ref = None
for step in [0.125, 0.25, 0.5, 1.0, 2.0]:
    start = time.time()
    image = vdbrad.render(fwd, res=res, cloud_step=step)
    seconds = time.time() - start
    ref = image if ref is None else ref
    print("g 0.877 side, step %g voxels: %.2f s, %.3f %% from step 1/8"
          % (step, seconds, 100 * difference(image, ref)), flush=True)

# The picture: isotropic backlit, g 0.877 backlit, g 0.877 from the side; one exposure.
small = (400, 280)
back = camera(views["backlit"])
images = [vdbrad.render(iso, res=small, **back), vdbrad.render(fwd, res=small, **back),
          vdbrad.render(fwd, res=small)]
lum = np.concatenate([i.mean(axis=2).ravel() for i in images])
scale = 0.8 / np.percentile(lum[lum > 0.01 * lum.max()], 90)
x = np.clip(np.concatenate(images, axis=1) * scale, 0.0, 1.0)
srgb = np.where(x <= 0.0031308, 12.92 * x, 1.055 * x ** (1 / 2.4) - 0.055)
pixels = (srgb * 255 + 0.5).astype(np.uint8)
h, w, _ = pixels.shape
raw = b"".join(b"\x00" + pixels[y].tobytes() for y in range(h))


def chunk(tag, data):
    return struct.pack(">I", len(data)) + tag + data + struct.pack(">I", zlib.crc32(tag + data))


with open(sys.argv[1], "wb") as f:
    f.write(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 8, 2, 0, 0, 0))
            + chunk(b"IDAT", zlib.compress(raw, 9)) + chunk(b"IEND", b""))
