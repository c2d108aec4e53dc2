"""Every figure of SonicBoom, drawn from the JSON the command that measured it wrote.

usage: /usr/bin/python3 scripts/plot.py KIND DATA.json OUT.png
  fidelity  the fidelity ladder's Pareto figure (`sonicboom fidelity`, FIDELITY.json)
  inspect   a dataset's (z, theta) coverage and one strike's six channels: waveform envelopes
            and mel spectrograms in dB with a colour scale (`sonicboom inspect D.h5 --png
            OUT.png`, OUT.png.json)
  map       a haptic map: predicted and true contact points in 3-D, each pair joined, over the
            mapped branch's skeleton where known (`sonicboom map`, DIR/map.json)
  fewshot   MED against the number of target strikes, fine-tuned and from scratch, per family
            (scripts/fewshot_study.sh, OUT/results.json)
  errors    per-scenario distributions of the 3-D, height and angle errors, box over violin
            (`sonicboom reproduce`, DIR/results.json and the eval CSVs it names)
  ablation  the modality ablation's held-out MED as bars, one per test set (`sonicboom
            reproduce`, DIR/results.json)
  transfer  the transfer study: zero-shot MED on our shell and on the reference solid, and MED
            on the solid against the labelled solid strikes fine-tuned on or trained from
            scratch on (`sonicboom reproduce`, DIR/results.json)
"""
import csv
import math
import os
import json
import sys

import matplotlib
matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

FIDELITY_COLOURS = {"solid": "tab:green", "modal": "tab:blue", "fd": "tab:red",
                    "closed-form": "tab:purple"}


def pareto(points):
    """Indices of the points no other point beats in both time and error."""
    order = sorted(range(len(points)), key=lambda i: (points[i][0], points[i][1]))
    front, best = [], float("inf")
    for i in order:
        if points[i][1] < best:
            front.append(i)
            best = points[i][1]
    return front


def fidelity(data, src, png):
    """Time per strike against four errors, one panel each, with the Pareto front."""
    rows = data["rungs"][1:]  # the first row is the yardstick itself
    panels = [("wavefront_delay_error_us",
               "inter-channel delay error, aligned wavefronts (µs, mean over pairs)", 20.0),
              ("delay_error_us", "inter-channel delay error, 20 % threshold (µs, mean)", None),
              ("frequency_median_pct",
               f"frequency error to {data['frequency_max_hz'] / 1000:.0f} kHz (%, median)", 1.0),
              ("band_energy_error_db", "octave-band energy error (dB)", None)]
    fig, axes = plt.subplots(1, len(panels), figsize=(5 * len(panels), 7))
    for ax, (key, label, target) in zip(axes, panels):
        pts = [(r["ms_per_strike"], max(r[key], 1e-3)) for r in rows]
        for r, (x, y) in zip(rows, pts):
            ax.scatter(x, y, color=FIDELITY_COLOURS.get(r["kind"], "k"), s=30, zorder=3)
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
    for kind, colour in FIDELITY_COLOURS.items():
        axes[0].scatter([], [], color=colour, label=kind)
    axes[0].legend(fontsize=7)
    fig.suptitle("Fidelity ladder against the reference solid (" + src + "); numbers: the rows "
                 "of the table below the yardstick", fontsize=9)
    key = [f"{i}: {r['rung']} ({r['grid']})" for i, r in enumerate(rows, start=1)]
    columns = 3
    per = -(-len(key) // columns)
    for c in range(columns):
        fig.text(0.02 + c / columns, 0.02, "\n".join(key[c * per:(c + 1) * per]), fontsize=7,
                 va="bottom", family="monospace")
    fig.tight_layout(rect=(0, 0.06 + 0.022 * per, 1, 0.95))
    fig.savefig(png, dpi=110)


def inspect(data, src, png):
    """Coverage of (z, theta) over the valid strikes, then one strike: waveform envelope and mel
    spectrogram of each channel (time in ms from the record start, frequency in kHz on the mel
    axis, dB against the strike's loudest bin with the floor `sonicboom inspect` chose)."""
    import math
    strike = data["strike"]
    envelopes = strike["envelopes"]  # per channel: min and max per column, counts of full scale
    spec = strike["spectrograms"]  # db: (C, mels, frames)
    fs = strike["sample_rate_hz"]
    duration_ms = 1000.0 * strike["frames"] / fs
    fig = plt.figure(figsize=(13, 3 + 1.6 * len(envelopes)))
    grid = fig.add_gridspec(1 + len(envelopes), 3, height_ratios=[2.2] + [1] * len(envelopes),
                            width_ratios=[1, 1, 0.03])
    ax = fig.add_subplot(grid[0, :2])
    cov = data["coverage"]
    ax.scatter([math.degrees(t) for t in cov["theta_rad"]], [100 * z for z in cov["z_m"]], s=6,
               alpha=0.5, label=f"{len(cov['z_m'])} valid strikes")
    ax.scatter([math.degrees(strike["theta_rad"])], [100 * strike["z_m"]], s=60, marker="x",
               color="tab:red", label=f"row {strike['row']} (drawn below)")
    ax.set_xlim(-180, 180)
    ax.set_xlabel("theta (deg)")
    ax.set_ylabel("z (cm)")
    ax.legend(fontsize=8, loc="upper right")
    ax.set_title("(z, theta) of the valid strikes", fontsize=9)
    # HTK mel of a frequency, for the spectrograms' kHz ticks
    def mel(f_hz):
        return 2595.0 * math.log10(1.0 + f_hz / 700.0)
    mel_top = mel(spec["f_max_hz"])
    ticks_khz = [k for k in (0.5, 1, 2, 5, 10, 20) if 1000 * k < spec["f_max_hz"]]
    image = None
    for c, env in enumerate(envelopes):
        cols = len(env["min"])
        t_ms = [duration_ms * (k + 0.5) / cols for k in range(cols)]
        wave = fig.add_subplot(grid[1 + c, 0])
        wave.fill_between(t_ms, [v / env["full_scale"] for v in env["min"]],
                          [v / env["full_scale"] for v in env["max"]], lw=0.3, color="tab:blue")
        wave.set_xlim(0, duration_ms)
        wave.set_ylabel(f"mic {c}", fontsize=8)
        ax_s = fig.add_subplot(grid[1 + c, 1])
        db = spec["db"][c]
        frames = len(db[0]) if db else 0
        image = ax_s.imshow(db, origin="lower", aspect="auto", cmap="magma",
                            vmin=spec["floor_db"], vmax=0,
                            extent=[0, 1000.0 * frames * spec["seconds_per_frame"], 0, len(db)])
        ax_s.set_xlim(0, duration_ms)
        ax_s.set_yticks([len(db) * mel(1000 * k) / mel_top for k in ticks_khz])
        ax_s.set_yticklabels([f"{k:g}" for k in ticks_khz], fontsize=7)
        ax_s.set_ylabel("kHz (mel)", fontsize=8)
        if c + 1 == len(envelopes):
            wave.set_xlabel("ms from the record start")
            ax_s.set_xlabel("ms from the record start")
    if image is not None:
        bar = fig.colorbar(image, cax=fig.add_subplot(grid[1:, 2]))
        bar.set_label("dB against the strike's loudest bin", fontsize=8)
    fig.suptitle(f"{data['path']}: strike index {strike['index']} at z = {100 * strike['z_m']:.1f} cm, "
                 f"theta = {math.degrees(strike['theta_rad']):.0f} deg", fontsize=9)
    fig.tight_layout()
    fig.savefig(png, dpi=100)


def haptic_map(data, src, png):
    """Predicted (red) and true (black) contact points in the base frame, each pair joined, cm."""
    pred = [p["predicted_m"] for p in data["points"]]
    true = [p["true_m"] for p in data["points"]]
    fig = plt.figure(figsize=(9, 8))
    ax = fig.add_subplot(projection="3d")
    # the mapped object's skeleton (guided taps only): each segment's axis, drawn by its radius
    for k, seg in enumerate(data.get("skeleton", [])):
        a, b = seg["p0_m"], seg["p1_m"]
        ax.plot([100 * a[0], 100 * b[0]], [100 * a[1], 100 * b[1]], [100 * a[2], 100 * b[2]],
                color="tab:green", lw=max(1.0, 300 * seg["radius_m"]), alpha=0.5,
                label="branch skeleton" if k == 0 else None)
    for p, t in zip(pred, true):
        ax.plot([100 * p[0], 100 * t[0]], [100 * p[1], 100 * t[1]], [100 * p[2], 100 * t[2]],
                color="grey", lw=0.5)
    ax.scatter([100 * t[0] for t in true], [100 * t[1] for t in true],
               [100 * t[2] for t in true], s=8, color="k", label="true contact points")
    ax.scatter([100 * p[0] for p in pred], [100 * p[1] for p in pred],
               [100 * p[2] for p in pred], s=8, color="tab:red", label="predicted")
    ax.set_xlabel("x (cm)")
    ax.set_ylabel("y (cm)")
    ax.set_zlabel("z (cm)")
    ax.legend(fontsize=8)
    surface = ""
    if data.get("surface_cm") is not None:
        surface = f", to the surface {data['surface_cm']:.2f}"
    ax.set_title(f"{data['data']} by {data['model']}\n{data['taps']} taps, MED "
                 f"{data['med_cm']:.2f} cm, RMS Chamfer {data['chamfer_cm']:.2f} cm "
                 f"(reverse {data['reverse_chamfer_cm']:.2f}{surface})", fontsize=9)
    fig.tight_layout()
    fig.savefig(png, dpi=100)


def fewshot(data, src, png):
    """Per family: the pretrained model fine-tuned on n target strikes (n = 0: zero-shot) and the
    same network trained from scratch on them, MED on the family's held-out part, cm."""
    fig, ax = plt.subplots(figsize=(6, 4))
    for fam, r in data["families"].items():
        n = r["shots"]
        line, = ax.plot([0] + n, [r["pretrained"]] + r["fine_tuned"], "o-",
                        label=f"{fam}: fine-tuned")
        ax.plot(n, r["scratch"], "s--", color=line.get_color(), label=f"{fam}: from scratch")
    ax.set_xscale("symlog", linthresh=10)
    ax.set_xlabel("target strikes used")
    ax.set_ylabel("MED on the held-out part (cm)")
    ax.set_title("Few-shot fine-tuning of the transfer model")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(png, dpi=120)


def errors(data, src, png):
    """Per scenario, the per-strike 3-D error (cm), height error (cm) and angle error (deg) of
    the model, as violins with boxes over them; the paper's MED marked on the first panel."""
    names, columns = [], [[], [], []]
    for ts, s in data["scenarios"].items():
        rows = list(csv.DictReader(open(os.path.join(os.path.dirname(src), s["predictions_csv"]))))
        names.append(ts)
        columns[0].append([float(r["error_cm"]) for r in rows])
        columns[1].append([100 * abs(float(r["z_pred_m"]) - float(r["z_m"])) for r in rows])
        columns[2].append([abs(math.degrees(math.remainder(
            float(r["theta_pred_rad"]) - float(r["theta_rad"]), 2 * math.pi))) for r in rows])
    fig, axes = plt.subplots(1, 3, figsize=(12, 4))
    for ax, values, label in zip(axes, columns, ["3-D error (cm)", "height error (cm)",
                                                 "angle error (deg)"]):
        ax.violinplot(values, showextrema=False)
        ax.boxplot(values, widths=0.15, showfliers=False)
        ax.set_xticks(range(1, len(names) + 1), names)
        ax.set_ylabel(label)
        ax.grid(True, axis="y", alpha=0.3)
    axes[0].scatter(range(1, len(names) + 1), [s["paper_med_cm"] for s in data["scenarios"].values()],
                    marker="x", color="tab:red", zorder=3, label="paper's MED")
    axes[0].scatter(range(1, len(names) + 1), [s["med_cm"] for s in data["scenarios"].values()],
                    marker="o", color="k", zorder=3, label="our MED")
    axes[0].legend(fontsize=8)
    fig.suptitle(f"Per-strike errors by scenario ({data['size']}: {data['train_strikes']} ts1 "
                 f"training strikes, {data['test_strikes_per_scenario']} per scenario)", fontsize=10)
    fig.tight_layout()
    fig.savefig(png, dpi=110)


def ablation(data, src, png):
    """The modality ablation's held-out MED, cm: one group of bars per ablation, one bar per
    test set it was scored on (paper Fig. 6)."""
    rows = data["ablations"]
    sets = [os.path.splitext(os.path.basename(t["data"]))[0].replace("test_", "")
            for t in rows[0].get("tests", [])] or ["held-out"]
    width = 0.8 / len(sets)
    fig, ax = plt.subplots(figsize=(max(5, 0.5 * len(rows) * len(sets) + 2), 4))
    for k, name in enumerate(sets):
        # a variant whose training diverged has no errors (null): no bar, its name marked
        errs = [r["tests"][k]["test"] if "tests" in r else r["test"] for r in rows]
        meds = [float("nan") if e is None else e["med_cm"] for e in errs]
        ax.bar([i + (k - (len(sets) - 1) / 2) * width for i in range(len(rows))], meds, width,
               label=name)
    ax.set_xticks(range(len(rows)),
                  [r["name"] + (" (diverged)" if r.get("diverged") else "") for r in rows],
                  rotation=30, ha="right")
    ax.set_ylabel("MED on held-out strikes (cm)")
    ax.set_title("Modality ablation (trained on ts1)")
    if len(sets) > 1:
        ax.legend(title="test set")
    ax.grid(True, axis="y", alpha=0.3)
    fig.tight_layout()
    fig.savefig(png, dpi=110)


def transfer(data, src, png):
    """Zero-shot bars per theory, then the few-shot curve on the solid, MED in cm."""
    t = data["transfer"]
    rows = t["rows"]
    fig, (bars, curve) = plt.subplots(1, 2, figsize=(10, 4))
    # left: the transfer model and the arrival locator on each theory's render of one set
    width = 0.38
    top = 0.0
    for k, (name, key, colour) in enumerate([("transfer, zero-shot", "zero_shot", "tab:blue"),
                                             ("arrival locator", "arrival", "tab:gray")]):
        meds = [rows[f"{key}_{theory}"]["med_cm"] for theory in ("shell", "solid")]
        bars.bar([x + (k - 0.5) * width for x in range(2)], meds, width, label=name,
                 color=colour)
        top = max([top] + meds)
    # headroom above the tallest bar for the legend
    bars.set_ylim(0, 1.35 * top)
    bars.set_xticks(range(2), ["our shell", "reference solid"])
    bars.set_ylabel("MED on held-out ts4 strikes (cm)")
    bars.set_title(f"Zero-shot ({t['train_strikes']} randomized training strikes)")
    bars.legend(loc="upper center", ncol=2, fontsize=8)
    bars.grid(True, axis="y", alpha=0.3)
    # right: MED on the solid against the labelled solid strikes
    points = rows["fewshot"]
    ns = [p["n"] for p in points]
    curve.plot([0] + ns, [rows["zero_shot_solid"]["med_cm"]] + [p["tuned"]["med_cm"]
                                                             for p in points],
               "o-", color="tab:blue", label="pretrained, fine-tuned")
    curve.plot(ns, [p["scratch"]["med_cm"] for p in points], "s--", color="tab:red",
               label="from scratch")
    curve.axhline(rows["arrival_solid"]["med_cm"], color="tab:gray", ls=":",
                  label="arrival locator")
    curve.set_xlabel("labelled strikes of the reference solid")
    curve.set_ylabel("MED on the solid's held-out strikes (cm)")
    curve.set_title("Few-shot in another theory")
    curve.set_ylim(bottom=0)
    curve.legend()
    curve.grid(True, alpha=0.3)
    fig.tight_layout()
    fig.savefig(png, dpi=110)


KINDS = {"fidelity": fidelity, "inspect": inspect, "map": haptic_map, "fewshot": fewshot,
         "errors": errors, "ablation": ablation, "transfer": transfer}

if __name__ == "__main__":
    if len(sys.argv) != 4 or sys.argv[1] not in KINDS:
        sys.exit(__doc__)
    kind, src, out = sys.argv[1:]
    KINDS[kind](json.load(open(src)), src, out)
