#!/usr/bin/python3
"""Localize latency of trained runs, one Markdown row per run, beside their accuracy.

Each run is timed by `sonicboom localize --repeat N` on one core (taskset -c CORE, one torch
thread, OMP_NUM_THREADS=1): WAV read to answer, median of N, with its read / features / network
split. The runs are timed in turn, --rounds times over, so that a slow spell of a shared machine
falls on all of them alike; each row is the round with the median total. With --results (the
results.json of `sonicboom ablate`), each run's held-out 3-D MED is looked up by its directory
name.

With --bin given more than once (e.g. the build before and after a change), every run is timed
with every binary within each round, and the table gets one row per run and binary.

Usage: /usr/bin/python3 scripts/latency_table.py --wav STRIKE.wav [--repeat 20] [--rounds 5]
           [--core 0] [--results RESULTS.json] [--bin build/bin/sonicboom]... RUN_DIR...
"""
import argparse
import json
import os
import subprocess
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def run_json(cmd, env=None):
    """Runs a sonicboom command with --json and returns its parsed output; exits on failure."""
    done = subprocess.run(cmd, capture_output=True, text=True, env=env)
    if done.returncode != 0:
        sys.exit(f"latency_table: {' '.join(cmd)} failed ({done.returncode}):\n{done.stderr}")
    return json.loads(done.stdout)


def feature_keys(config_yaml):
    """The `features:` section of a run's config.yaml (as train writes it: one `  key: value`
    line per key) as strings."""
    keys, inside = {}, False
    with open(config_yaml) as f:
        for line in f:
            if not line.startswith(" "):
                inside = line.rstrip() == "features:"
            elif inside and line.startswith("  ") and ":" in line:
                key, value = line.strip().split(":", 1)
                keys[key] = value.strip().strip('"')
    if "gating" not in keys or "window_s" not in keys:
        sys.exit(f"latency_table: {config_yaml}: no features.gating / features.window_s")
    return keys


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("runs", nargs="+", help="run directories (model.json + model.pt)")
    parser.add_argument("--wav", required=True, help="6-channel strike WAV to localize")
    parser.add_argument("--repeat", type=int, default=20)
    parser.add_argument("--rounds", type=int, default=5, help="timings of each run, in turn")
    parser.add_argument("--core", type=int, default=0, help="CPU the timing runs on")
    parser.add_argument("--results", help="results.json of `sonicboom ablate` (MED per run)")
    parser.add_argument("--bin", action="append", help="sonicboom binary (repeatable; default "
                        "$SONICBOOM_BIN or build/bin/sonicboom)")
    args = parser.parse_args()
    bins = args.bin or [os.environ.get("SONICBOOM_BIN",
                                       os.path.join(ROOT, "build", "bin", "sonicboom"))]
    # each binary and run once, in the order given
    bins, args.runs = list(dict.fromkeys(bins)), list(dict.fromkeys(args.runs))
    if args.repeat < 1 or args.rounds < 1:
        sys.exit(f"latency_table: --repeat and --rounds must be >= 1, got {args.repeat} and "
                 f"{args.rounds}")
    for path in [args.wav] + bins + ([args.results] if args.results else []):
        if not os.path.exists(path):
            sys.exit(f"latency_table: {path}: not found")

    med = {}
    if args.results:
        with open(args.results) as f:
            # a diverged row (test null) has no MED
            med = {row["name"]: row["test"]["med_cm"] for row in json.load(f)["ablations"]
                   if row["test"] is not None}

    env = dict(os.environ, OMP_NUM_THREADS="1")
    timings = {(run, b): [] for run in args.runs for b in bins}
    for _ in range(args.rounds):
        for run in args.runs:
            for b in bins:
                timings[(run, b)].append(run_json(
                    ["taskset", "-c", str(args.core), b, "--threads", "1", "-q", "localize",
                     "--model", run, "--wav", args.wav, "--repeat", str(args.repeat), "--json"],
                    env))

    print(f"Localize latency: median of {args.repeat} per round, the median of {args.rounds} "
          f"rounds (ms), one core; {args.wav}\n")
    several = len(bins) > 1
    print("| run |" + (" binary |" if several else "") + " encoder | width | blocks "
          "| modalities | gating | GCC span (s) | parameters | 3-D MED (cm) | latency (ms) "
          "| range over rounds | read | features | network |")
    print("|---|" + ("---|" if several else "") + "---|---|---|---|---|---|---|---|---|---|---|"
          "---|---|")
    # each run's model and features, read once (not once per binary)
    inspected = {run: (run_json([bins[0], "inspect", run, "--json"]),
                       feature_keys(os.path.join(run, "config.yaml"))) for run in args.runs}
    for run, b in timings:
        name = os.path.basename(os.path.normpath(run))
        # a run directory named "model" (scripts/med_study.sh) goes by its study's directory
        label = name if name != "model" else \
            os.path.basename(os.path.dirname(os.path.normpath(run))) + "/model"
        info, features = inspected[run]
        model = info["model"]["model"]
        # configs written before features.gcc_window_s existed: the whole window
        span = float(features.get("gcc_window_s", "0")) or float(features["window_s"])
        rounds = sorted(timings[(run, b)], key=lambda out: out["latency_ms"])
        out = rounds[(len(rounds) - 1) // 2]
        split = out["latency_breakdown_ms"]
        med_cell = f"{med[name]:.2f}" if name in med else ""
        gating = "on" if features["gating"] == "true" else "off"
        print(f"| {label} |" + (f" {b} |" if several else "") +
              f" {model['audio_encoder']} | {model['width']} | {model['blocks']} "
              f"| {'+'.join(model['modalities'])} | {gating} | {span:g} "
              f"| {info['parameters']['total']:,} | {med_cell} | {out['latency_ms']:.1f} "
              f"| {rounds[0]['latency_ms']:.1f}–{rounds[-1]['latency_ms']:.1f} "
              f"| {split['read']:.1f} | {split['features']:.1f} | {split['network']:.1f} |")

if __name__ == "__main__":
    main()
