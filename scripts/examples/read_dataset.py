#!/usr/bin/python3
"""Read a SonicBoom strike dataset with h5py (schema: docs/dataset.md).

Usage: /usr/bin/python3 scripts/examples/read_dataset.py DATASET.h5
"""
import sys

import h5py
import numpy as np


def main(path):
    with h5py.File(path, "r") as f:
        # Refuse files that are not datasets or whose writer did not finish.
        if f.attrs.get("schema") != "sonicboom.strikes":
            sys.exit(f"{path}: not a sonicboom dataset")
        version = f.attrs.get("schema_version")
        if version not in ("1.0", "1.1"):
            sys.exit(f"{path}: unsupported schema_version {version}")
        if f.attrs.get("complete", 0) != 1:
            sys.exit(f"{path}: incomplete dataset (no `complete` attribute)")

        # Per-sample columns, shape (N): index fields and labels (tube frame, SI units).
        n = int(f.attrs["num_samples"])
        sample_index = f["index/sample_index"][:]
        valid = f["index/valid"][:].astype(bool)
        reasons = f["index/invalid_reason"].asstr()[:]
        z_m = f["label/z_m"][:]
        theta_rad = f["label/theta_rad"][:]
        point_m = f["label/point_m"][:]  # (N, 3)

        # Audio (N, C, T): stored int16 or float32; multiply by `scale` for full scale 1.
        audio = f["audio"]
        scale = float(audio.attrs["scale"])
        x0 = audio[0].astype(np.float32) * scale  # (C, T) of the first sample
        sample_rate_hz = float(f.attrs["sample_rate_hz"])

        # Proprio (N, K, 10): position m (3), quaternion wxyz (4), velocity m/s (3).
        proprio_rows = f["proprio"].shape[1]

        print(f"samples: {n} valid: {int(valid.sum())} channels: {audio.shape[1]} "
              f"frames: {audio.shape[2]} sample_rate_hz: {sample_rate_hz:g} "
              f"proprio_rows: {proprio_rows}")
        print(f"first: index={sample_index[0]} z_m={z_m[0]:.6f} theta_rad={theta_rad[0]:.6f} "
              f"point_m=({point_m[0, 0]:.4f}, {point_m[0, 1]:.4f}, {point_m[0, 2]:.4f}) "
              f"valid={bool(valid[0])} peak={np.abs(x0).max():.4f}")
        for i in np.flatnonzero(~valid):
            print(f"invalid: index={sample_index[i]} reason={reasons[i]}")

        # Contact episodes (version 1.1; a 1.0 file has none): a flat table of M rows, sample n
        # owns rows [contact_first[n], contact_first[n] + contact_count[n]), in time order.
        if version == "1.0":
            print("contacts: not recorded (schema_version 1.0)")
            return
        contacts = f["contacts"]
        first = int(f["index/contact_first"][0])
        count = int(f["index/contact_count"][0])
        rows = slice(first, first + count)
        kind_names = contacts["kind"].attrs["names"].split(",")  # code -> name
        kinds = contacts["kind"][rows]
        times = contacts["time_s"][rows]
        zs = contacts["z_m"][rows]
        thetas = contacts["theta_rad"][rows]
        impulses = contacts["impulse_Ns"][rows]
        objects = contacts["object"].asstr()[rows]
        materials = contacts["material"].asstr()[rows]
        print(f"contacts: total={contacts['kind'].shape[0]} first sample: {count}")
        for k in range(count):
            print(f"  contact: kind={kind_names[kinds[k]]} time_s={times[k]:.6f} "
                  f"z_m={zs[k]:.6f} theta_rad={thetas[k]:.6f} impulse_Ns={impulses[k]:.6f} "
                  f"object={objects[k]} material={materials[k]}")


if __name__ == "__main__":
    if len(sys.argv) != 2:
        sys.exit(__doc__)
    main(sys.argv[1])
