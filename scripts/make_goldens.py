#!/usr/bin/python3
"""Golden reference values for the feature tests (tests/acoustics/features_test.cc).

Run on purpose only, from the repository root (tests never regenerate the files):

    /usr/bin/python3 scripts/make_goldens.py

Writes tests/data/goldens/features.json (manifest: parameters, and per array its file, shape
and dtype) and one raw little-endian float32 file per array (C order). Needs torch, torchaudio
and numpy (Debian 12: python3-torchaudio, python3-numpy).

Arrays:
  multi_input   (6, 4000)      deterministic chirp / decaying sinusoids / noise, one per channel
  multi_mel     (6, 50, 32)    torchaudio MelSpectrogram(44100, n_fft=512, hop=128, n_mels=50)
  long_input    (66150,)       one 1.5 s channel (a strike-like burst)
  long_mel      (50, 517)      same transform
  band_mel      (40, 63)       MelSpectrogram(44100, n_fft=256, hop=64, n_mels=40, f_min=100,
                               f_max=8000) of multi_input[2]
  multi_gcc     (15, 883)      GCC-PHAT of multi_input, max_lag 441, zero-padded (numpy, float64)
"""

import json
import os

import numpy as np
import torch
import torchaudio

SAMPLE_RATE = 44100
OUT_DIR = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "tests", "data",
                       "goldens")


def multi_channel_input(n=4000, channels=6):
    """(channels, n) float32: each channel a different deterministic test signal."""
    t = np.arange(n) / SAMPLE_RATE
    rng = np.random.default_rng(20240611)
    x = np.zeros((channels, n))
    # linear chirp 200 Hz -> 15 kHz
    x[0] = 0.8 * np.sin(2 * np.pi * (200 * t + 0.5 * (15000 - 200) / t[-1] * t ** 2))
    # decaying sinusoids (tube modes)
    x[1] = sum(a * np.exp(-t / tau) * np.sin(2 * np.pi * f * t + ph)
               for a, tau, f, ph in [(0.5, 0.02, 1250.0, 0.3), (0.3, 0.01, 4100.0, 1.1),
                                     (0.2, 0.005, 9800.0, 2.0)])
    # white noise
    x[2] = 0.1 * rng.standard_normal(n)
    # delayed, attenuated copies of the noise (known TDOAs for the GCC golden)
    x[3] = 0.5 * np.concatenate([np.zeros(37), x[2][:-37]]) + 0.01 * rng.standard_normal(n)
    x[4] = 0.7 * np.concatenate([x[2][120:], np.zeros(120)]) + 0.01 * rng.standard_normal(n)
    # small-amplitude tone plus DC offset
    x[5] = 1e-3 * np.sin(2 * np.pi * 440.0 * t) + 2e-3
    return x.astype(np.float32)


def long_input(n=66150):
    """(n,) float32: quiet noise, then a strike at 0.6 s ringing at several modes."""
    rng = np.random.default_rng(7)
    t = np.arange(n) / SAMPLE_RATE
    x = 1e-3 * rng.standard_normal(n)
    onset = int(0.6 * SAMPLE_RATE)
    tt = t[onset:] - t[onset]
    x[onset:] += sum(a * np.exp(-tt / tau) * np.sin(2 * np.pi * f * tt)
                     for a, tau, f in [(0.6, 0.05, 820.0), (0.3, 0.02, 2900.0),
                                       (0.15, 0.008, 7600.0), (0.05, 0.003, 16000.0)])
    return x.astype(np.float32)


def mel(x, n_fft=512, hop=128, n_mels=50, f_min=0.0, f_max=None):
    transform = torchaudio.transforms.MelSpectrogram(
        sample_rate=SAMPLE_RATE, n_fft=n_fft, hop_length=hop, n_mels=n_mels, f_min=f_min,
        f_max=f_max)
    return transform(torch.from_numpy(x)).numpy().astype(np.float32)


def next_fast_size(n):
    """Smallest m >= n with prime factors only 2, 3, 5 (same rule as acoustics/features.cc)."""
    m = max(n, 1)
    while True:
        r = m
        for p in (2, 3, 5):
            while r % p == 0:
                r //= p
        if r == 1:
            return m
        m += 1


def gcc_phat(x, max_lag):
    """(pairs, 2*max_lag+1): zero-padded (non-circular) GCC-PHAT, negative lags first."""
    channels, n = x.shape
    size = next_fast_size(n + max_lag)
    spectra = np.fft.rfft(x.astype(np.float64), n=size, axis=1)
    rows = []
    for i in range(channels):
        for j in range(i + 1, channels):
            g = spectra[i] * np.conj(spectra[j])
            r = np.fft.irfft(g / (np.abs(g) + 1e-10), n=size)
            rows.append(np.concatenate([r[size - max_lag:], r[:max_lag + 1]]))
    return np.array(rows, dtype=np.float32), size


def main():
    os.makedirs(OUT_DIR, exist_ok=True)
    multi = multi_channel_input()
    longx = long_input()
    gcc, gcc_fft_size = gcc_phat(multi, 441)
    arrays = {
        "multi_input": multi,
        "multi_mel": mel(multi),
        "long_input": longx,
        "long_mel": mel(longx),
        "band_mel": mel(multi[2], n_fft=256, hop=64, n_mels=40, f_min=100.0, f_max=8000.0),
        "multi_gcc": gcc,
    }
    manifest = {
        "description": "goldens for tests/acoustics/features_test.cc; made by "
                       "scripts/make_goldens.py; raw float32 little-endian, C order",
        "torch": torch.__version__,
        "torchaudio": torchaudio.__version__,
        "sample_rate_hz": SAMPLE_RATE,
        "mel": {"n_fft": 512, "hop": 128, "n_mels": 50, "f_min_hz": 0.0, "f_max_hz": 22050.0},
        "band_mel": {"n_fft": 256, "hop": 64, "n_mels": 40, "f_min_hz": 100.0,
                     "f_max_hz": 8000.0, "input": "multi_input[2]"},
        "gcc": {"max_lag": 441, "fft_size": gcc_fft_size},
        "arrays": {},
    }
    for name, value in arrays.items():
        value = np.ascontiguousarray(value, dtype="<f4")
        file_name = name + ".f32"
        value.tofile(os.path.join(OUT_DIR, file_name))
        manifest["arrays"][name] = {"file": file_name, "shape": list(value.shape),
                                    "dtype": "float32le"}
        print(f"{name}: shape {value.shape}, max |x| {np.abs(value).max():.6g}")
    with open(os.path.join(OUT_DIR, "features.json"), "w") as f:
        json.dump(manifest, f, indent=2)
        f.write("\n")


if __name__ == "__main__":
    main()
