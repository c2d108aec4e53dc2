#!/usr/bin/python3
"""Where a localizer's errors lie: the per-strike errors of `sonicboom eval --predictions P.csv`
sliced by what each strike's record drew (the dataset's /variation columns), its contact
duration, height and angle. For each quantity, the strikes are split into QUANTILES groups of
equal size and each group's MED (cm) and mean angle error (degrees) printed.
Usage: /usr/bin/python3 scripts/error_slices.py DATA.h5 P.csv [QUANTILES=4] [COLUMN ...]
(COLUMN: /variation names; default: the striker, level, noise and structure draws)."""
import csv
import sys

import h5py
import numpy as np

DEFAULT_COLUMNS = ["striker_mass_scale", "striker_radius_m", "striker_youngs_modulus_pa",
                   "record_level_db", "noise_floor_v", "hum_rms_v", "structure_variant",
                   "youngs_modulus_scale", "loss_factor_scale"]


def main():
    data, pred = sys.argv[1], sys.argv[2]
    quantiles = int(sys.argv[3]) if len(sys.argv) > 3 else 4
    columns = sys.argv[4:] or DEFAULT_COLUMNS
    f = h5py.File(data, "r")
    rows = {int(r["index"]): r for r in csv.DictReader(open(pred))}
    index = f["index/sample_index"][:]
    # dataset rows that have a prediction (valid strikes), in file order
    sel = np.array([i for i, x in enumerate(index) if int(x) in rows])
    if len(sel) == 0:
        sys.exit("%s: no strike of %s has a prediction" % (pred, data))
    col = lambda k: np.array([float(rows[int(index[i])][k]) for i in sel])
    err = col("error_cm")
    dtheta = np.degrees(np.abs(np.angle(np.exp(1j * (col("theta_pred_rad") - col("theta_rad"))))))
    dz = np.abs(col("z_pred_m") - col("z_m")) * 100
    print("%d strikes: MED %.2f cm (median %.2f, 90th percentile %.2f); |dz| %.2f cm; "
          "|dtheta| %.1f deg (median %.1f); the worst 10 %% hold %.0f %% of the summed error"
          % (len(err), err.mean(), np.median(err), np.percentile(err, 90), dz.mean(),
             dtheta.mean(), np.median(dtheta), 100 * np.sort(err)[-len(err) // 10:].sum() / err.sum()))

    def slices(name, values):
        edges = np.percentile(values, np.linspace(0, 100, quantiles + 1))
        parts = []
        for lo, hi in zip(edges[:-1], edges[1:]):
            m = (values >= lo) & (values <= hi)
            parts.append("[%.3g, %.3g]: %.2f cm / %.1f deg" % (lo, hi, err[m].mean(), dtheta[m].mean()))
        print("%-26s %s" % (name, " | ".join(parts)))

    slices("contact duration (ms)", f["label/duration_s"][:][sel] * 1e3)
    slices("z (cm)", col("z_m") * 100)
    slices("theta (deg)", np.degrees(col("theta_rad")))
    if "variation" in f:
        names = f["variation"].attrs["names"].split(",")
        variation = f["variation"][:][sel]
        for c in columns:
            if c not in names:
                sys.exit("%s: no /variation column %r (it has: %s)" % (data, c, ", ".join(names)))
            slices(c, variation[:, names.index(c)])


if __name__ == "__main__":
    main()
