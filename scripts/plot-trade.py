#!/usr/bin/env python3
"""Plots of the speed/accuracy trade from bench_trade's CSV (docs/trade-*.png).

    build/benchmarks/bench_trade docs/trade.csv && python3 scripts/plot-trade.py docs/trade.csv

Needs python3-matplotlib (a documentation tool only: nothing in the build or the tests uses it).
"""
import csv
import os
import sys
from collections import defaultdict

import matplotlib
matplotlib.use("Agg")
import matplotlib.pyplot as plt

rows = list(csv.DictReader(open(sys.argv[1] if len(sys.argv) > 1 else "docs/trade.csv")))
outdir = os.path.dirname(os.path.abspath(sys.argv[1] if len(sys.argv) > 1 else "docs/trade.csv"))
disk = [r for r in rows if r["study"] == "disk"]
its = [r for r in rows if r["study"] == "iterations"]

# Error vs time, one curve per (resolution, lines) over the direction counts.
fig, ax = plt.subplots(1, 2, figsize=(12, 4.5))
curves = defaultdict(list)
for r in disk:
    curves[(int(r["res"]), r["lines"])].append(r)
for (res, lines), rs in sorted(curves.items()):
    rs.sort(key=lambda r: int(r["directions"]))
    style = "-o" if lines == "naive" else "--s"
    for k, key in enumerate(("mean_err", "max_err")):
        ax[k].loglog([float(r["seconds"]) for r in rs], [float(r[key]) for r in rs], style,
                     label=f"res {res}, {lines}", markersize=4)
for k, title in enumerate(("mean relative error", "max relative error")):
    ax[k].set_xlabel("seconds (2 cores, construction + 2 iterations)")
    ax[k].set_ylabel(title)
    ax[k].set_title(f"disk: {title} vs time (50 ... 20000 directions)", fontsize=10)
    ax[k].grid(True, which="both", alpha=0.3)
ax[0].legend(fontsize=7)
fig.tight_layout()
fig.savefig(os.path.join(outdir, "trade-disk-error-vs-time.png"), dpi=110)

# Error vs each knob: directions (per resolution) and resolution (per direction count).
fig, ax = plt.subplots(1, 2, figsize=(12, 4.5))
for (res, lines), rs in sorted(curves.items()):
    if lines != "naive":
        continue
    ax[0].loglog([int(r["directions"]) for r in rs], [float(r["mean_err"]) for r in rs], "-o",
                 label=f"res {res}", markersize=4)
ax[0].set_xlabel("directions")
ax[0].set_ylabel("mean relative error")
ax[0].set_title("disk, naive lines: error vs directions")
ax[0].legend(fontsize=8)
by_dirs = defaultdict(list)
for r in disk:
    if r["lines"] == "naive":
        by_dirs[int(r["directions"])].append(r)
for dirs, rs in sorted(by_dirs.items()):
    rs.sort(key=lambda r: int(r["res"]))
    ax[1].loglog([int(r["res"]) for r in rs], [float(r["mean_err"]) for r in rs], "-o",
                 label=f"{dirs} directions", markersize=4)
ax[1].set_xlabel("resolution (voxels across the receiver)")
ax[1].set_ylabel("mean relative error")
ax[1].set_title("disk, naive lines: error vs resolution")
ax[1].legend(fontsize=8)
for a in ax:
    a.grid(True, which="both", alpha=0.3)
fig.tight_layout()
fig.savefig(os.path.join(outdir, "trade-disk-error-vs-knobs.png"), dpi=110)

# Cornell box against the Monte Carlo reference: error vs time per (resolution, lines).
cornell = [r for r in rows if r["study"] == "cornell"]
split = [r for r in rows if r["study"] == "cornell-split"]
if cornell:
    fig, axes = plt.subplots(1, 2, figsize=(12, 4.5))
    ax = axes[0]
    curves = defaultdict(list)
    for r in cornell:
        curves[(int(r["res"]), r["lines"])].append(r)
    for (res, lines), rs in sorted(curves.items()):
        rs.sort(key=lambda r: int(r["directions"]))
        ax.loglog([float(r["seconds"]) for r in rs], [float(r["mean_err"]) for r in rs],
                  "-o" if lines == "naive" else "--s", label=f"res {res}, {lines}", markersize=4)
        floor = float(rs[0]["axis_err"])
        ax.axhline(floor, color=ax.lines[-1].get_color(), linewidth=0.6, alpha=0.5)
    ax.set_xlabel("seconds (2 cores, to tolerance 1e-5)")
    ax.set_ylabel("mean |B - B_MC| / mean B")
    ax.set_title("Cornell box vs Monte Carlo (thin lines: MC noise)", fontsize=10)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7)
    ax = axes[1]
    kinds = defaultdict(list)
    for r in split:
        kinds[r["scene"]].append(r)
    for kind, rs in sorted(kinds.items()):
        rs.sort(key=lambda r: int(r["directions"]))
        ax.loglog([int(r["directions"]) for r in rs], [float(r["mean_err"]) for r in rs], "-o",
                  label=f"{kind} ({rs[0]['voxels']} of the 4096 sampled voxels)", markersize=4)
    ax.set_xlabel("directions")
    ax.set_ylabel("mean |B - B_MC| / mean B of the kind")
    ax.set_title("res 64, naive lines: by kind of voxel", fontsize=10)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(os.path.join(outdir, "trade-cornell-error-vs-time.png"), dpi=110)

# Iterations: error vs iterations per update scheme.
fig, ax = plt.subplots(figsize=(6.5, 4.5))
schemes = defaultdict(list)
for r in its:
    schemes[r["update"]].append(r)
for scheme, rs in sorted(schemes.items()):
    rs.sort(key=lambda r: int(r["iterations"]))
    ax.semilogy([int(r["iterations"]) for r in rs], [float(r["max_err"]) for r in rs], "-o",
                label=scheme, markersize=4)
ax.set_xlabel("iterations")
ax.set_ylabel("max |B_k - B| / max B")
ax.set_title("Cornell res 48, 300 directions: error vs iterations")
ax.grid(True, which="both", alpha=0.3)
ax.legend()
fig.tight_layout()
fig.savefig(os.path.join(outdir, "trade-cornell-iterations.png"), dpi=110)
print("wrote", outdir + "/trade-*.png")
