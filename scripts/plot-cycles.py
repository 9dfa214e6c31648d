#!/usr/bin/env python3
"""Error against time, vdbrad beside Blender Cycles on the Cornell box (docs/cornell-vs-cycles.png).

    CSV=docs/cornell-vs-cycles.csv bash benchmarks/compare_cycles.sh
    python3 scripts/plot-cycles.py docs/cornell-vs-cycles.csv
    python3 scripts/plot-cycles.py CSV OUT.png "TITLE" "REFERENCE"   (other scenes)

One curve per vdbrad direction count over the resolutions (exact and sweeps' direct light),
other solve options as single points, Cycles over its sample counts. Needs python3-matplotlib
(a documentation tool only: nothing in the build or the tests uses it).
"""
import csv
import os
import sys
from collections import defaultdict

import matplotlib
matplotlib.use("Agg")
import matplotlib.pyplot as plt

path = sys.argv[1] if len(sys.argv) > 1 else "docs/cornell-vs-cycles.csv"
rows = list(csv.DictReader(open(path)))
fig, ax = plt.subplots(figsize=(8, 5.5))

curves = defaultdict(list)
for r in rows:
    if r["tool"] == "vdbrad" and not r["options"]:
        curves[(r["direct"], int(r["directions"]))].append(r)
for (direct, dirs), rs in sorted(curves.items()):
    rs.sort(key=lambda r: int(r["res"]))
    t = [float(r["seconds"]) for r in rs]
    e = [100 * float(r["error"]) for r in rs]
    style = "-o" if direct == "exact" else ":x"
    ax.plot(t, e, style, label="vdbrad, %d directions, %s direct light" % (dirs, direct))
    if direct == "exact":
        for r, x, y in zip(rs, t, e):
            ax.annotate(r["res"], (x, y), textcoords="offset points", xytext=(4, 4), fontsize=7)

variants = defaultdict(list)
for r in rows:
    if r["tool"] == "vdbrad" and r["options"]:
        variants[r["options"]].append(r)
markers = "svP*^<>ph"
for k, (options, rs) in enumerate(sorted(variants.items())):
    rs.sort(key=lambda r: (int(r["res"]), int(r["directions"])))
    t = [float(r["seconds"]) for r in rs]
    e = [100 * float(r["error"]) for r in rs]
    dirs = sorted({r["directions"] for r in rs}, key=int)
    ax.plot(t, e, markers[k % len(markers)], markersize=5, fillstyle="none",
            label="vdbrad res %s, %s directions, %s" % (
                "/".join(sorted({r["res"] for r in rs}, key=int)), "/".join(dirs), options))
    if len(dirs) > 1:   # several direction counts: label each point res:directions
        for r, x, y in zip(rs, t, e):
            ax.annotate("%s:%s" % (r["res"], r["directions"]), (x, y),
                        textcoords="offset points", xytext=(4, 4), fontsize=7)

cycles = sorted((r for r in rows if r["tool"] == "cycles"), key=lambda r: int(r["spp"]))
if cycles:
    t = [float(r["seconds"]) for r in cycles]
    e = [100 * float(r["error"]) for r in cycles]
    ax.plot(t, e, "-D", color="black", label="Blender Cycles (16 to %s spp)" % cycles[-1]["spp"])
    for r, x, y in zip(cycles, t, e):
        ax.annotate(r["spp"], (x, y), textcoords="offset points", xytext=(4, 4), fontsize=7)

ax.set_xscale("log")
ax.set_yscale("log")
ax.axhline(1.0, color="grey", linewidth=0.5)
ax.set_xlabel("seconds, whole process, 2 cores")
reference = sys.argv[4] if len(sys.argv) > 4 else "Cycles 2 x 4096 spp"
ax.set_ylabel("image error against %s, %%" % reference)
ax.set_title(sys.argv[3] if len(sys.argv) > 3
             else "Cornell box mesh, 320 x 240 (labels: vdbrad resolution, Cycles spp)")
ax.legend(fontsize=7)
fig.tight_layout()
out = sys.argv[2] if len(sys.argv) > 2 else os.path.join(
    os.path.dirname(os.path.abspath(path)), "cornell-vs-cycles.png")
fig.savefig(out, dpi=110)
print(out)
