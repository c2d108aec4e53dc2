#!/usr/bin/python3
"""How far the meshes of one `sonicboom reference --json` report lie from the converged limit of
another: each level's frequencies (matched by rank) against the other report's Richardson limits,
by band, and its disc arrivals and inter-disc delays against the other report's finest mesh.
Used to state how close the fidelity ladder's yardstick (the graded 13.5 mm mesh, level 0 of
scripts/reference_20k.sh's version-3 run) is to the self-similar family's limit
(docs/reference_model.md, docs/fidelity.md).

Usage: /usr/bin/python3 scripts/reference_yardstick.py MESHES.json LIMIT.json [OUT.md]
"""
import json
import sys

BANDS_HZ = [(0.0, 5000.0), (5000.0, 10000.0), (10000.0, 20000.0)]


def quantile(v, q):
    v = sorted(v)
    return v[min(len(v) - 1, int(q * len(v)))] if v else float("nan")


def stats(v):
    return f"{quantile(v, 0.5):.3f} / {quantile(v, 0.9):.3f} / {max(v):.3f}" if v else "—"


def main():
    if len(sys.argv) not in (3, 4):
        sys.exit(__doc__)
    meshes_path, limit_path = sys.argv[1], sys.argv[2]
    meshes, limit = json.load(open(meshes_path)), json.load(open(limit_path))
    f_limit = [m["limit_hz"] for m in limit["modes"]]
    t_finest = limit["levels"][-1]["arrivals_s"]  # (probe) x (disc), s
    md = [
        f"Made by `/usr/bin/python3 scripts/reference_yardstick.py {meshes_path} {limit_path}`: "
        f"each mesh of the first report against the {len(f_limit)} Richardson limits (by rank) "
        "and the finest mesh's disc arrivals of the second.\n",
        "| mesh h (mm) | DOFs | "
        + " | ".join(f"{lo / 1e3:g}–{hi / 1e3:g} kHz: median / 90th / max (%)" for lo, hi in BANDS_HZ)
        + " | arrivals median / max (µs) | delays median / max (µs) |",
        "|---|---|" + "---|" * len(BANDS_HZ) + "---|---|",
    ]
    for level in meshes["levels"]:
        f = level["frequencies_hz"]
        n = min(len(f), len(f_limit))
        errs = [[] for _ in BANDS_HZ]
        for fi, fl in zip(f[:n], f_limit[:n]):
            for b, (lo, hi) in enumerate(BANDS_HZ):
                if lo <= fl < hi:
                    errs[b].append(100.0 * abs(fi - fl) / fl)
        t = level["arrivals_s"]
        arrivals, delays = [], []
        for p, (row, ref) in enumerate(zip(t, t_finest)):
            for a in range(len(row)):
                arrivals.append(1e6 * abs(row[a] - ref[a]))
                for b in range(a + 1, len(row)):
                    delays.append(1e6 * abs((row[a] - row[b]) - (ref[a] - ref[b])))
        md.append(
            f"| {1e3 * level['h_m']:.2f} | {level['dofs']} | "
            + " | ".join(stats(e) for e in errs)
            + f" | {quantile(arrivals, 0.5):.2f} / {max(arrivals):.2f}"
            + f" | {quantile(delays, 0.5):.2f} / {max(delays):.2f} |"
        )
    text = "\n".join(md) + "\n"
    if len(sys.argv) == 4:
        open(sys.argv[3], "w").write(text)
    print(text)


if __name__ == "__main__":
    main()
