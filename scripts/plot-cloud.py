#!/usr/bin/env python3
"""Plot of the cloud slab study from bench_cloud's CSV (docs/cloud-slab.png).

    rm -f docs/cloud-slab.csv
    build/benchmarks/bench_cloud 300 20 1 4 0 8 docs/cloud-slab.csv
    build/benchmarks/bench_cloud 300 20 1 4 0.848 8 docs/cloud-slab.csv
    /usr/bin/python3 scripts/plot-cloud.py docs/cloud-slab.csv

Needs python3-matplotlib (a documentation tool only: nothing in the build or the tests uses it).
"""
import csv
import os
import sys

import matplotlib
matplotlib.use("Agg")
import matplotlib.pyplot as plt

path = sys.argv[1] if len(sys.argv) > 1 else "docs/cloud-slab.csv"
rows = list(csv.DictReader(open(path)))
fig, ax = plt.subplots(1, 2, figsize=(12, 4.5))
for g, colour in (("0", "tab:blue"), ("0.848", "tab:red")):
    rs = sorted((r for r in rows if r["g"] == g), key=lambda r: float(r["tau"]))
    if not rs:
        continue
    tau = [float(r["tau"]) for r in rs]
    name = "isotropic" if g == "0" else "HG g = " + g
    ax[0].plot(tau, [float(r["exact"]) for r in rs], "-", color=colour, label=name + ": exact")
    ax[0].plot(tau, [float(r["albedo"]) for r in rs], "o", color=colour, label=name + ": vdbrad")
    ax[0].errorbar(tau, [float(r["monte_carlo"]) for r in rs],
                   yerr=[3 * float(r["mc_stderr"]) for r in rs], fmt="x", color="k",
                   label=name + ": Monte Carlo (3 sigma)")
    ax[0].plot(tau, [float(r["delta_eddington"]) for r in rs], ":", color=colour,
               label=name + ": delta-Eddington")
    for key, style, what in (("albedo", "-o", "vdbrad"), ("delta_eddington", ":s", "delta-Eddington"),
                             ("monte_carlo", "--x", "Monte Carlo 1e6")):
        ax[1].plot(tau, [100 * (float(r[key]) - float(r["exact"])) / float(r["exact"]) for r in rs],
                   style, color=colour, label=name + ": " + what)
ax[0].set_xscale("log")
ax[0].set_xlabel("optical thickness tau")
ax[0].set_ylabel("albedo (conservative slab, sun at zenith)")
ax[0].legend(fontsize=7)
ax[1].set_xscale("log")
ax[1].axhline(0, color="grey", lw=0.5)
ax[1].axhspan(-1, 1, color="grey", alpha=0.1)
ax[1].set_xlabel("optical thickness tau")
ax[1].set_ylabel("albedo error vs adding-doubling (%)")
ax[1].legend(fontsize=7)
fig.suptitle("vdbrad solve-cloud: periodic slab 4 x 20 x 4 voxels, 303 directions, order 8")
fig.tight_layout()
fig.savefig(os.path.join(os.path.dirname(os.path.abspath(path)), "cloud-slab.png"), dpi=110)
