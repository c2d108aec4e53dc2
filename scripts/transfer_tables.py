"""Shared by the table steps of scripts/transfer_ablation.sh, transfer_waveform.sh,
transfer_benchmark.sh and the theory studies (imported with PYTHONPATH=scripts): reading an
output directory's JSON results, eval cells and the training time of a run."""
import json
import os


def load(out, name):
    """The JSON file `name` in the output directory `out`."""
    with open(os.path.join(out, name)) as f:
        return json.load(f)


def train_seconds(out, run):
    """Wall time summed over every epoch of run directory out/run, or of every member of an
    ensemble there (their metrics.jsonl); None when it logged no epoch."""
    total, found = 0.0, False
    for root, _, files in os.walk(os.path.join(out, run)):
        if "metrics.jsonl" in files:
            found = True
            with open(os.path.join(root, "metrics.jsonl")) as f:
                total += sum(json.loads(line)["epoch_seconds"] for line in f if line.strip())
    return round(total) if found else None


def write(out, lines, results):
    """out/table.md (the table's lines) and out/results.json; the table also to stdout."""
    with open(os.path.join(out, "table.md"), "w") as f:
        f.write("\n".join(lines) + "\n")
    with open(os.path.join(out, "results.json"), "w") as f:
        json.dump(results, f, indent=1)
    print("\n".join(lines))


# Header of an eval cell (theory_augment_study.sh, turn_study.sh, adapt_study.sh).
EVAL_HEAD = "MED (cm) / height (cm) / angle (°) / 90 % z, θ coverage"


def eval_cell(path):
    """One `eval --json` result as 'MED / height / angle / z, theta coverage'."""
    with open(path) as f:
        e = json.load(f)
    return (f"{e['med_cm']:.2f} / {e['height_err_cm']:.2f} / {e['angle_err_deg']:.1f} / "
            f"{e['z_coverage_90']:.2f}, {e['theta_coverage_90']:.2f}")
