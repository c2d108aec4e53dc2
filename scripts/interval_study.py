#!/usr/bin/python3
"""Interval scales fitted on one labelled family, scored on others (docs/transfer.md, "Honest
intervals"): per-strike predictions of `sonicboom eval --predictions` (z_std_m and theta_kappa as
the run's stored calibration gives them) are refitted on CALIBRATION.csv by the likelihood (the rms
of the standardized z errors; the von Mises NLL root for kappa) and by coverage (the conformal
90 % quantile), and the 90 % coverage of z and theta on every FAMILY.csv is printed under the
stored scales and under each refit. Usage: interval_study.py CALIBRATION.csv FAMILY.csv...
or interval_study.py --first N FAMILY.csv: fitted on the family's first N strikes (the taps a
user labels on their own tube), scored on the rest."""
import csv
import math
import sys

import numpy as np

Z90 = 1.6448536269514722


def read(path):
    with open(path) as f:
        rows = [r for r in csv.DictReader(f)]
    get = lambda k: np.array([float(r[k]) for r in rows])
    d = np.remainder(get("theta_pred_rad") - get("theta_rad") + math.pi, 2 * math.pi) - math.pi
    return {"u": np.abs(get("z_pred_m") - get("z_m")) / get("z_std_m"),
            "kappa": get("theta_kappa"), "d": np.abs(d)}


def central(kappa, h):
    """P(|x| <= h) for a von Mises of concentration kappa (Gauss-Legendre on [0, h])."""
    x, w = np.polynomial.legendre.leggauss(64)
    t = 0.5 * h[:, None] * (x[None, :] + 1)
    # e^{kappa (cos t - 1)} / (pi I0e(kappa)) integrated over [0, h]
    i0e = np.array([_i0e(k) for k in kappa])
    dens = np.exp(kappa[:, None] * (np.cos(t) - 1)) / (math.pi * i0e[:, None])
    return (0.5 * h * (dens * w[None, :]).sum(1))


def coverage(fam, zs, ks):
    return (np.mean(fam["u"] <= Z90 * zs), np.mean(central(ks * fam["kappa"], fam["d"]) <= 0.9))


def fit_likelihood(cal):
    zs = math.sqrt(np.mean(cal["u"] ** 2))
    # root of mean(kappa (A(c kappa) - cos d)), A = I1/I0
    def deriv(c):
        k = c * cal["kappa"]
        a1 = np.array([_i1e(v) / _i0e(v) for v in k])
        return np.mean(cal["kappa"] * (a1 - np.cos(cal["d"])))
    lo, hi = math.log(1e-4), math.log(1e4)
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        if deriv(math.exp(mid)) < 0:
            lo = mid
        else:
            hi = mid
    return zs, math.exp(0.5 * (lo + hi))


def _i0e(x):
    t = np.linspace(0, math.pi, 801)
    return np.trapz(np.exp(x * (np.cos(t) - 1)), t) / math.pi


def _i1e(x):
    # I1(x) e^{-x} by its integral (1/pi) int_0^pi e^{x (cos t - 1)} cos t dt
    t = np.linspace(0, math.pi, 801)
    f = np.exp(x * (np.cos(t) - 1)) * np.cos(t)
    return np.trapz(f, t) / math.pi


def fit_coverage(cal):
    n = len(cal["u"])
    rank = min(n, math.ceil(0.9 * (n + 1))) - 1
    zs = np.sort(cal["u"])[rank] / Z90
    target = (rank + 1) / n
    lo, hi = math.log(1e-4), math.log(1e4)
    for _ in range(50):
        mid = 0.5 * (lo + hi)
        if np.mean(central(math.exp(mid) * cal["kappa"], cal["d"]) <= 0.9) >= target:
            lo = mid
        else:
            hi = mid
    return zs, math.exp(lo)


def take(fam, rows):
    return {k: v[rows] for k, v in fam.items()}


def main():
    if sys.argv[1] == "--first":
        n, fam = int(sys.argv[2]), read(sys.argv[3])
        cal, rest = take(fam, slice(0, n)), take(fam, slice(n, None))
        fits = {"stored": (1.0, 1.0), "likelihood": fit_likelihood(cal),
                "coverage": fit_coverage(cal)}
        cells = [" / ".join(f"{c:.2f}" for c in coverage(rest, *f)) for f in fits.values()]
        print(f"fitted on the first {n}, scored on {len(rest['u'])}: " +
              ", ".join(f"{k} z / θ {c}" for k, c in zip(fits, cells)))
        return
    cal = read(sys.argv[1])
    fits = {"stored": (1.0, 1.0), "likelihood": fit_likelihood(cal), "coverage": fit_coverage(cal)}
    print("| family | " + " | ".join(f"{k} z / θ" for k in fits) + " |")
    print("|---|" + "---|" * len(fits))
    for path in [sys.argv[1]] + sys.argv[2:]:
        fam = read(path)
        cells = [" / ".join(f"{c:.2f}" for c in coverage(fam, *s)) for s in fits.values()]
        print(f"| {path.split('/')[-1]} | " + " | ".join(cells) + " |")
    print("scales (sigma_z x, kappa x): " +
          ", ".join(f"{k} {v[0]:.3g}, {v[1]:.3g}" for k, v in fits.items()))


if __name__ == "__main__":
    main()
