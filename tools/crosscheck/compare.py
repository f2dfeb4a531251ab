"""Judges whether trazo and Mitsuba agree on a scene, given two renders of
each with different seeds (T1, T2 by trazo; M1, M2 by Mitsuba).

Two renders of one renderer differ only by noise, so they measure it:
- noise = relMSE(X1, X2) / 2 is each image's relative error from noise;
- if trazo and Mitsuba converge to the same image, relMSE(T1, M1) should be
  about noise_T + noise_M, so the ratio printed stays near 1; bias shows
  up as a ratio well above 1;
- the mean of each channel is compared with a z-score whose standard error
  comes from the per-pixel differences between the two seeds.

Prints one Markdown table row; exits with status 1 if the scene fails.
"""
import argparse
import sys

import mitsuba as mi
import numpy as np

EPSILON = 1e-2  # the relative MSE's ε, as in `trazo diff`


def load(path):
    return np.array(mi.Bitmap(path), dtype=np.float64)[:, :, :3]


def rel_mse(a, b):
    return float(np.mean((a - b) ** 2 / (b * b + EPSILON)))


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("name")
    ap.add_argument("t1")
    ap.add_argument("t2")
    ap.add_argument("m1")
    ap.add_argument("m2")
    ap.add_argument("--max-ratio", type=float, default=1.5)
    ap.add_argument("--max-z", type=float, default=4.5)
    args = ap.parse_args()
    mi.set_variant("scalar_rgb")
    t1, t2, m1, m2 = (load(p) for p in (args.t1, args.t2, args.m1, args.m2))
    if t1.shape != m1.shape:
        print(f"| {args.name} | size mismatch {t1.shape} vs {m1.shape} |")
        sys.exit(1)
    n = t1.shape[0] * t1.shape[1]
    noise_t = 0.5 * (rel_mse(t1, t2) + rel_mse(t2, t1)) / 2
    noise_m = 0.5 * (rel_mse(m1, m2) + rel_mse(m2, m1)) / 2
    cross = 0.25 * (rel_mse(t1, m1) + rel_mse(t2, m2) + rel_mse(t1, m2) + rel_mse(t2, m1))
    ratio = cross / max(noise_t + noise_m, 1e-12)
    mean_t = (t1 + t2).reshape(-1, 3).mean(axis=0) / 2
    mean_m = (m1 + m2).reshape(-1, 3).mean(axis=0) / 2
    # Var of the mean of (X1 + X2)/2 over n pixels: Σ (X1 − X2)²/4 / n².
    se_t = np.sqrt(((t1 - t2) ** 2).reshape(-1, 3).sum(axis=0) / 4) / n
    se_m = np.sqrt(((m1 - m2) ** 2).reshape(-1, 3).sum(axis=0) / 4) / n
    z = (mean_t - mean_m) / np.maximum(np.sqrt(se_t**2 + se_m**2), 1e-12)
    zmax = float(np.max(np.abs(z)))
    ok = ratio <= args.max_ratio and zmax <= args.max_z
    fmt = lambda v: " ".join(f"{x:.4f}" for x in v)
    print(
        f"| {args.name} | {fmt(mean_t)} | {fmt(mean_m)} | {zmax:.2f} | {cross:.5f} | "
        f"{noise_t + noise_m:.5f} | {ratio:.2f} | {'ok' if ok else 'DIFFERENT'} |"
    )
    sys.exit(0 if ok else 1)


if __name__ == "__main__":
    main()
