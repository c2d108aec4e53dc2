"""Shared by the table steps of scripts/transfer_ablation.sh, transfer_waveform.sh and
transfer_benchmark.sh (imported with PYTHONPATH=scripts): reading an output directory's JSON
results and the training time of a run."""
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
