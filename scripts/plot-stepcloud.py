#!/usr/bin/env python3
"""Error against CPU time on the I3RC step cloud, vdbrad beside SHDOM (docs/step-cloud.png).

    rm -f docs/step-cloud.csv
    B=build/benchmarks/bench_stepcloud; C=docs/step-cloud.csv; E=0:1,0:0.99,60:1,60:0.99
    $B 32 300 constant cells anderson 2000000 8 $E -1 $C
    $B 32 1000 linear harmonic anderson 2000000 8 $E -1 $C
    $B 64 300 linear harmonic auto 2000000 8 $E -1 $C
    $B 64 1000 linear harmonic auto 2000000 8 $E -1 $C
    $B 32 auto auto auto auto 2000000 auto $E -1 $C
    $B 64 auto auto auto auto 2000000 auto $E -1 $C
    $B 128 300 linear harmonic auto 2000000 8 0:1,60:1 -1 $C
    /usr/bin/python3 scripts/plot-stepcloud.py docs/step-cloud.csv

vdbrad's error is the larger of the reflectance's and the transmittance's against the photon Monte
Carlo of the same columns (2e6 photons, +-0.1 %); SHDOM's is its reflectance against the
intercomparison's consensus (ω₀ = 1 only), from ../shared/notes/peers.md. CPU: user + sys seconds
of one solve. Needs python3-matplotlib (a documentation tool only).
"""
import csv
import sys

import matplotlib
matplotlib.use("Agg")
import matplotlib.pyplot as plt

path = sys.argv[1] if len(sys.argv) > 1 else "docs/step-cloud.csv"
out = path.rsplit(".", 1)[0] + ".png"
rows = list(csv.DictReader(open(path)))
experiments = [("0", "1"), ("0", "0.99"), ("60", "1"), ("60", "0.99")]
colours = {"0": "tab:blue", "60": "tab:red"}
markers = {"1": "o", "0.99": "s"}
fig, ax = plt.subplots(figsize=(11, 5.5))
for zenith, omega in experiments:
    rs = [r for r in rows if r["zenith"] == zenith and r["omega0"] == omega]
    if not rs:
        continue
    cpu = [float(r["cpu_s"]) for r in rs]
    err = [100 * max(abs(float(r["R"]) / float(r["R_mc"]) - 1),
                     abs(float(r["T"]) / float(r["T_mc"]) - 1)) for r in rs]
    ax.scatter(cpu, err, color=colours[zenith], marker=markers[omega],
               label="vdbrad, sun %s°, ω₀ %s" % (zenith, omega))
    for r, x, y in zip(rs, cpu, err):
        ax.annotate("%s/%s/K%s%s" % (r["res"], r["directions"], r["order"],
                                     "" if r["source"] == "linear" else " const"),
                    (x, y), fontsize=6, xytext=(3, 2), textcoords="offset points")
# SHDOM (peers.md): reflectance error, conservative, single-threaded user time.
ax.plot([19, 81, 179], [0.77, 0.26, 0.05], "-^", color="tab:blue", mfc="white",
        label="SHDOM, sun 0°, ω₀ 1 (4×101, 8×201, 8×401)")
ax.plot([176], [0.63], "^", color="tab:red", mfc="white", label="SHDOM, sun 60°, ω₀ 1 (8×401)")
ax.axhline(0.3, color="grey", lw=0.8, ls="--")
ax.axvline(36, color="grey", lw=0.8, ls="--")
ax.text(37, 2.5, "issue 24's target: 0.3 % in 36 s", fontsize=8, color="grey")
ax.set_xscale("log")
ax.set_yscale("log")
ax.set_xlabel("CPU seconds of one solve (user + sys)")
ax.set_ylabel("error, % (vdbrad: max of R and T; SHDOM: R)")
ax.set_title("I3RC step cloud: error against CPU time (labels: res / directions / phase order)")
ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0))
ax.grid(True, which="both", lw=0.3)
fig.tight_layout()
fig.savefig(out, dpi=110)
print("wrote", out)
