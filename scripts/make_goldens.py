#!/usr/bin/python3
"""Golden reference values for the feature tests (tests/dsp/features_test.cc).

Run on purpose only, from the repository root (tests never regenerate the files):

    /usr/bin/python3 scripts/make_goldens.py [--only gate_]

Writes tests/data/goldens/features.json (manifest: parameters, and per array its file, shape
and dtype) and one raw little-endian float32 file per array (C order). Needs torch, torchaudio,
numpy and scipy (Debian 12: python3-torchaudio, python3-numpy, python3-scipy).

Arrays:
  multi_input   (6, 4000)      deterministic chirp / decaying sinusoids / noise, one per channel
  multi_mel     (6, 50, 32)    torchaudio MelSpectrogram(44100, n_fft=512, hop=128, n_mels=50)
  long_input    (66150,)       one 1.5 s channel (a strike-like burst)
  long_mel      (50, 517)      same transform
  band_mel      (40, 63)       MelSpectrogram(44100, n_fft=256, hop=64, n_mels=40, f_min=100,
                               f_max=8000) of multi_input[2]
  multi_gcc     (15, 883)      GCC-PHAT of multi_input, max_lag 441, zero-padded (numpy, float64)
  gate_noise    (2, 16000)     reference noise clip for the spectral gate (two different noises)
  gate_input    (2, 12000)     new draws of the same noises plus a strike at 0.1 s
  gate_threshold_db (2, 513)   per-channel, per-bin gate threshold, dB (numpy, float64)
  gate_output   (2, 12000)     gate_input through the spectral gate (spectral_gate_numpy below),
                               for tests/dsp/spectral_gate_test.cc
"""

import argparse
import json
import os

import numpy as np
import scipy
import scipy.signal
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


def gcc_fft_size(n):
    """Smallest multiple of 512 >= n whose other prime factors are 2, 3, 5 (same rule as
    dsp/features.cc)."""
    k = max((n + 511) // 512, 1)
    while True:
        r = k
        for p in (2, 3, 5):
            while r % p == 0:
                r //= p
        if r == 1:
            return 512 * k
        k += 1


def gcc_phat(x, max_lag):
    """(pairs, 2*max_lag+1): zero-padded (non-circular) GCC-PHAT, negative lags first."""
    channels, n = x.shape
    size = gcc_fft_size(n + max_lag)
    spectra = np.fft.rfft(x.astype(np.float64), n=size, axis=1)
    rows = []
    for i in range(channels):
        for j in range(i + 1, channels):
            g = spectra[i] * np.conj(spectra[j])
            r = np.fft.irfft(g / (np.abs(g) + 1e-10), n=size)
            rows.append(np.concatenate([r[size - max_lag:], r[:max_lag + 1]]))
    return np.array(rows, dtype=np.float32), size


# Spectral gate (dsp/spectral_gate.h): stationary gating against a reference noise clip,
# the noisereduce stationary algorithm written out in numpy. One deliberate difference from
# noisereduce: the mask smoothing is renormalized at the spectrogram's borders (divided by the
# same convolution of ones), so that a mask of ones stays ones.
GATE = {"n_fft": 1024, "hop": 256, "n_std": 2.5, "freq_smooth_hz": 500.0, "time_smooth_s": 0.05,
        "prop_decrease": 1.0, "top_db": 80.0}


def periodic_hann(n):
    return 0.5 - 0.5 * np.cos(2 * np.pi * np.arange(n) / n)


def stft_centred(x, n_fft, hop):
    """(bins, frames) complex: periodic Hann, centred with reflect padding, 1 + len // hop frames."""
    pad = n_fft // 2
    padded = np.pad(x.astype(np.float64), pad, mode="reflect")
    frames = 1 + len(x) // hop
    index = np.arange(n_fft)[None, :] + hop * np.arange(frames)[:, None]
    return np.fft.rfft(padded[index] * periodic_hann(n_fft), axis=1).T


def istft_centred(spec, n_fft, hop, length):
    """Overlap-add of windowed inverse frames over the summed squared window, centre trimmed."""
    window = periodic_hann(n_fft)
    frames = spec.shape[1]
    blocks = np.fft.irfft(spec.T, n=n_fft, axis=1) * window
    total = (frames - 1) * hop + n_fft
    y = np.zeros(total)
    window_sum = np.zeros(total)
    for f in range(frames):
        y[f * hop:f * hop + n_fft] += blocks[f]
        window_sum[f * hop:f * hop + n_fft] += window ** 2
    nonzero = window_sum > np.finfo(np.float64).tiny
    y[nonzero] /= window_sum[nonzero]
    return y[n_fft // 2:n_fft // 2 + length]


def amplitude_db(magnitude, top_db):
    """librosa amplitude_to_db(ref=1, amin=1e-20, top_db) of one spectrogram."""
    db = 20 * np.log10(np.maximum(magnitude, 1e-20))
    return np.maximum(db, db.max() - top_db)


def triangle(n):
    """noisereduce's smoothing taps, half width n: 2 n + 1 values, peak 1."""
    return np.concatenate([np.linspace(0, 1, n + 1, endpoint=False), np.linspace(1, 0, n + 2)])[1:-1]


def gate_threshold_db(noise, p):
    """(bins,) mean + n_std * std over frames of the noise clip's dB spectrogram."""
    noise_db = amplitude_db(np.abs(stft_centred(noise, p["n_fft"], p["hop"])), p["top_db"])
    return noise_db.mean(axis=1) + p["n_std"] * noise_db.std(axis=1)


def spectral_gate_numpy(x, noise, p, sr=SAMPLE_RATE):
    spec = stft_centred(x, p["n_fft"], p["hop"])
    mask = amplitude_db(np.abs(spec), p["top_db"]) > gate_threshold_db(noise, p)[:, None]
    mask = mask * p["prop_decrease"] + (1.0 - p["prop_decrease"])
    n_freq = int(p["freq_smooth_hz"] / (sr / (p["n_fft"] / 2)))
    n_time = int((p["time_smooth_s"] * 1000) / ((p["hop"] / sr) * 1000))
    kernel = np.outer(triangle(n_freq), triangle(n_time))
    kernel /= kernel.sum()
    smooth = scipy.signal.convolve2d(mask, kernel, mode="same")
    smooth /= scipy.signal.convolve2d(np.ones_like(mask), kernel, mode="same")
    return istft_centred(spec * smooth, p["n_fft"], p["hop"], len(x)), (n_freq, n_time)


def gate_signals():
    """(noise (2, 16000), input (2, 12000)) float32: channel 0 white noise with motor-like
    harmonics of 110 Hz, channel 1 low-passed noise 10 dB louder; the input draws both again and
    adds a strike (decaying modes) at 0.1 s, weaker and later on channel 1."""
    rng = np.random.default_rng(20251121)

    def noise(n):
        t = np.arange(n) / SAMPLE_RATE
        white = 2e-3 * rng.standard_normal(n)
        tones = sum(1e-3 / h * np.sin(2 * np.pi * 110.0 * h * t + rng.uniform(0, 2 * np.pi))
                    for h in range(1, 6))
        low = np.convolve(6e-3 * rng.standard_normal(n + 31), np.hanning(32) / 8, mode="valid")
        return np.stack([white + tones, low])

    reference = noise(16000)
    x = noise(12000)
    t = np.arange(12000) / SAMPLE_RATE
    for channel, (gain, delay) in enumerate([(0.2, 0), (0.08, 40)]):
        onset = int(0.1 * SAMPLE_RATE) + delay
        tt = t[onset:] - t[onset]
        x[channel, onset:] += gain * sum(
            a * np.exp(-tt / tau) * np.sin(2 * np.pi * f * tt)
            for a, tau, f in [(1.0, 0.03, 1250.0), (0.5, 0.01, 4100.0), (0.25, 0.004, 9800.0)])
    return reference.astype(np.float32), x.astype(np.float32)


def main():
    # --only PREFIX: rewrite only the arrays whose names start with PREFIX (the manifest lists
    # them all). torchaudio's mel output is not bit-reproducible across runs and machines, so
    # adding a golden should not rewrite the others.
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--only", default="", help="array name prefix, e.g. gate_")
    only = parser.parse_args().only
    os.makedirs(OUT_DIR, exist_ok=True)
    multi = multi_channel_input()
    longx = long_input()
    gcc, gcc_size = gcc_phat(multi, 441)
    gate_noise, gate_input = gate_signals()
    gated = []
    for channel in range(gate_input.shape[0]):
        y, smoothing = spectral_gate_numpy(gate_input[channel], gate_noise[channel], GATE)
        gated.append(y)
    gate_threshold = np.stack([gate_threshold_db(c, GATE) for c in gate_noise])
    arrays = {
        "multi_input": multi,
        "multi_mel": mel(multi),
        "long_input": longx,
        "long_mel": mel(longx),
        "band_mel": mel(multi[2], n_fft=256, hop=64, n_mels=40, f_min=100.0, f_max=8000.0),
        "multi_gcc": gcc,
        "gate_noise": gate_noise,
        "gate_input": gate_input,
        "gate_threshold_db": gate_threshold,
        "gate_output": np.stack(gated),
    }
    manifest = {
        "description": "goldens for tests/dsp/features_test.cc; made by "
                       "scripts/make_goldens.py; raw float32 little-endian, C order",
        "torch": torch.__version__,
        "torchaudio": torchaudio.__version__,
        "sample_rate_hz": SAMPLE_RATE,
        "mel": {"n_fft": 512, "hop": 128, "n_mels": 50, "f_min_hz": 0.0, "f_max_hz": 22050.0},
        "band_mel": {"n_fft": 256, "hop": 64, "n_mels": 40, "f_min_hz": 100.0,
                     "f_max_hz": 8000.0, "input": "multi_input[2]"},
        "gcc": {"max_lag": 441, "fft_size": gcc_size},
        "gate": dict(GATE, freq_smooth_bins=smoothing[0], time_smooth_frames=smoothing[1],
                     scipy=scipy.__version__),
        "arrays": {},
    }
    for name, value in arrays.items():
        value = np.ascontiguousarray(value, dtype="<f4")
        file_name = name + ".f32"
        manifest["arrays"][name] = {"file": file_name, "shape": list(value.shape),
                                    "dtype": "float32le"}
        if only and not name.startswith(only):
            continue
        value.tofile(os.path.join(OUT_DIR, file_name))
        print(f"{name}: shape {value.shape}, max |x| {np.abs(value).max():.6g}")
    with open(os.path.join(OUT_DIR, "features.json"), "w") as f:
        json.dump(manifest, f, indent=2)
        f.write("\n")


if __name__ == "__main__":
    main()
