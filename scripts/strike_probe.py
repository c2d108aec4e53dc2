#!/usr/bin/python3
"""What a dataset's strikes carry of the wavefront: contact durations as rendered
(/label/duration_s, median and 5-95 %, ms) and the early GCC-PHAT lag of the axial pair (mics 0
and 3) over the 12 ms from 2 ms before the first contact, fitted as a line in z (samples per cm).

Usage: /usr/bin/python3 scripts/strike_probe.py D1.h5 [D2.h5 ...]
docs/history.md quotes it on the benchmark's test sets.
"""
import sys

import h5py
import numpy as np

PRE_S, POST_S, NFFT, MAX_LAG = 0.002, 0.010, 2048, 60


def early_lag(audio, k0):
    """Peak lag (samples) of PHAT-weighted cross-correlation of channels 0 and 3; audio (6, T)."""
    w = audio[[0, 3], k0 - int(PRE_S * FS):k0 + int(POST_S * FS)]  # (2, 529)
    w = w - w.mean(axis=1, keepdims=True)
    spec = np.fft.rfft(w, NFFT, axis=1)  # (2, NFFT/2+1)
    cross = spec[0] * np.conj(spec[1])
    g = np.fft.irfft(cross / (np.abs(cross) + 1e-20), NFFT)  # (NFFT,)
    window = np.concatenate([g[-MAX_LAG:], g[:MAX_LAG + 1]])  # lags -MAX_LAG..MAX_LAG
    return int(np.argmax(window)) - MAX_LAG


if len(sys.argv) < 2:
    sys.exit(__doc__)
for path in sys.argv[1:]:
    try:
        f = h5py.File(path, "r")
        FS = float(f["audio"].attrs.get("sample_rate_hz", 44100.0))
        valid = f["index/valid"][:].astype(bool)  # (N,)
        dur_ms = f["label/duration_s"][:] * 1e3  # (N,) ms
        z_cm = f["label/z_m"][:] * 100  # (N,) cm
        t0 = f["label/time_s"][:]  # (N,) s, first contact in the record
        audio = f["audio"]  # (N, 6, T) int16
    except (OSError, KeyError) as e:
        sys.exit("%s: not a SonicBoom dataset (%s)" % (path, e))
    idx = np.where(valid & np.isfinite(dur_ms) & (dur_ms > 0))[0]
    if idx.size < 2:
        sys.exit("%s: fewer than 2 valid strikes" % path)
    lags = [early_lag(audio[n].astype(np.float64), int(round(t0[n] * FS))) for n in idx]
    slope = np.polyfit(z_cm[idx], lags, 1)[0]
    p5, p50, p95 = np.percentile(dur_ms[idx], [5, 50, 95])
    print("%s: %d strikes, contact %.2f ms median, %.2f-%.2f ms (5-95 %%); early GCC-PHAT lag of "
          "mics 0-3: %.2f samples per cm of z" % (path, idx.size, p50, p5, p95, slope))
    f.close()
