"""Pareto figure of `sonicboom fidelity`: time per strike against the errors, from its JSON.

usage: /usr/bin/python3 scripts/plot_fidelity.py FIDELITY.json OUT.png
"""
import json
import sys

import matplotlib
matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

src, png = sys.argv[1], sys.argv[2]
data = json.load(open(src))
rows = data["rungs"][1:]  # the first row is the yardstick itself
colours = {"solid": "tab:green", "modal": "tab:blue", "fd": "tab:red", "closed-form": "tab:purple"}
panels = [("delay_error_us", "inter-channel delay error (µs, mean over pairs)", 20.0),
          ("delay_error_median_us", "inter-channel delay error (µs, median over pairs)", 20.0),
          ("frequency_median_pct",
           f"frequency error to {data['frequency_max_hz'] / 1000:.0f} kHz (%, median)", 1.0),
          ("band_energy_error_db", "octave-band energy error (dB)", None)]


def pareto(points):
    """Indices of the points no other point beats in both time and error."""
    order = sorted(range(len(points)), key=lambda i: (points[i][0], points[i][1]))
    front, best = [], float("inf")
    for i in order:
        if points[i][1] < best:
            front.append(i)
            best = points[i][1]
    return front


fig, axes = plt.subplots(1, len(panels), figsize=(5 * len(panels), 7))
for ax, (key, label, target) in zip(axes, panels):
    pts = [(r["ms_per_strike"], max(r[key], 1e-3)) for r in rows]
    for r, (x, y) in zip(rows, pts):
        ax.scatter(x, y, color=colours.get(r["kind"], "k"), s=30, zorder=3)
    for i, (x, y) in enumerate(pts, start=1):
        ax.annotate(str(i), (x, y), fontsize=7, xytext=(3, 2), textcoords="offset points")
    front = pareto(pts)
    ax.plot([pts[i][0] for i in front], [pts[i][1] for i in front], "k--", lw=0.8,
            label="Pareto front")
    if target is not None:
        ax.axhline(target, color="grey", lw=0.8, ls=":", label=f"target {target:g}")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("ms per strike (1 s of 6 channels, one core)")
    ax.set_ylabel(label)
    ax.grid(True, which="both", alpha=0.3)
for kind, colour in colours.items():
    axes[0].scatter([], [], color=colour, label=kind)
axes[0].legend(fontsize=7)
fig.suptitle("Fidelity ladder against the reference solid (" + src + "); numbers: the rows of "
             "the table below the yardstick", fontsize=9)
key = [f"{i}: {r['rung']} ({r['grid']})" for i, r in enumerate(rows, start=1)]
columns = 3
per = -(-len(key) // columns)
for c in range(columns):
    fig.text(0.02 + c / columns, 0.02, "\n".join(key[c * per:(c + 1) * per]), fontsize=7,
             va="bottom", family="monospace")
fig.tight_layout(rect=(0, 0.06 + 0.022 * per, 1, 0.95))
fig.savefig(png, dpi=110)
