#!/usr/bin/env python3
"""Equal-spp error of trazo's samplers against a high-spp reference.

Renders SCENE (default: the built-in Cornell box) once at REF_SPP samples
per pixel with the independent sampler and another seed (the reference), then
with each sampler at each spp for several seeds, and prints the mean relative
MSE (the formula of `trazo diff`) with its standard error over the seeds, the
relative MSE of the seeds' average image (for an unbiased sampler about the
single-seed figure divided by the seed count, plus the reference's own noise)
and the mean image value against the reference's, in standard errors (those
of the seeds' mean and of the reference's mean, the latter scaled from the
independent sampler's spread).

    flock /tmp/trazo-cpu.lock python3 bench/samplers.py [--scene FILE] \
        [--size 128] [--ref-spp 8192] [--spp 16,64] [--seeds 8]

Only the standard library: images go through PFM files.
"""

import argparse
import math
import os
import re
import struct
import subprocess
import sys
import tempfile

EPS = 1e-2  # REL_MSE_EPSILON of src/film/metrics.rs


def read_pfm(path):
    with open(path, "rb") as f:
        data = f.read()
    # Header: "PF\n<w> <h>\n<scale>\n", then rows of little-endian floats
    # when the scale is negative.
    parts = data.split(b"\n", 3)
    w, h = map(int, parts[1].split())
    scale = float(parts[2])
    fmt = ("<" if scale < 0 else ">") + "f" * (3 * w * h)
    return list(struct.unpack(fmt, parts[3][: 12 * w * h]))


def rel_mse(a, ref):
    return sum((x - y) ** 2 / (y * y + EPS) for x, y in zip(a, ref)) / len(ref)


def render(trazo, scene, size, spp, sampler, seed, out):
    cmd = [trazo, "render", "-o", out, "--width", str(size), "--height", str(size),
           "--spp", str(spp), "--sampler", sampler, "--seed", str(seed)]
    if scene:
        cmd.append(scene)
    p = subprocess.run(cmd, capture_output=True, text=True, check=True)
    m = re.search(r"in ([0-9.]+) s", p.stdout + p.stderr)
    return float(m.group(1)) if m else float("nan")


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--trazo", default="target/release/trazo")
    ap.add_argument("--scene", default=None)
    ap.add_argument("--size", type=int, default=128)
    ap.add_argument("--ref-spp", type=int, default=8192)
    ap.add_argument("--spp", default="16,64")
    ap.add_argument("--seeds", type=int, default=8)
    ap.add_argument("--samplers", default="independent,stratified,sobol,halton,halton-owen,halton-plain")
    args = ap.parse_args()

    tmp = tempfile.mkdtemp(prefix="trazo-samplers-")
    ref_path = os.path.join(tmp, "ref.pfm")
    t = render(args.trazo, args.scene, args.size, args.ref_spp, "independent", 1_000_003, ref_path)
    ref = read_pfm(ref_path)
    ref_mean = sum(ref) / len(ref)
    print(f"scene: {args.scene or 'built-in Cornell box'}, {args.size}x{args.size}; "
          f"reference: independent, {args.ref_spp} spp ({t:.1f} s)")
    print("| sampler | spp | relMSE (mean ± s.e. over seeds) | relMSE of the seed average "
          "| mean − reference (s.e.) | render time |")
    print("|---|---|---|---|---|---|")
    samplers = args.samplers.split(",")
    if samplers[0] != "independent":
        sys.exit("the first sampler must be independent: it estimates the reference's noise")
    for spp in [int(s) for s in args.spp.split(",")]:
        ref_se = 0.0
        for sampler in samplers:
            errs, means, times = [], [], []
            avg = [0.0] * len(ref)
            for seed in range(1, args.seeds + 1):
                path = os.path.join(tmp, f"{sampler}-{spp}-{seed}.pfm")
                times.append(render(args.trazo, args.scene, args.size, spp, sampler, seed, path))
                img = read_pfm(path)
                errs.append(rel_mse(img, ref))
                means.append(sum(img) / len(img))
                avg = [a + x / args.seeds for a, x in zip(avg, img)]
                os.remove(path)
            n = len(errs)
            e = sum(errs) / n
            se = math.sqrt(sum((x - e) ** 2 for x in errs) / (n - 1) / n) if n > 1 else float("nan")
            m = sum(means) / n
            mse = math.sqrt(sum((x - m) ** 2 for x in means) / (n - 1) / n) if n > 1 else float("nan")
            if sampler == "independent":
                # The reference's own error of the mean, scaled from the
                # independent renders at this spp.
                ref_se = mse * math.sqrt(spp / args.ref_spp)
            total_se = math.hypot(mse, ref_se)
            z = (m - ref_mean) / total_se if total_se > 0 else float("nan")
            print(f"| {sampler} | {spp} | {e:.5f} ± {se:.5f} | {rel_mse(avg, ref):.5f} "
                  f"| {m - ref_mean:+.5f} ({z:+.1f}) | {sum(times) / n:.2f} s |")
            sys.stdout.flush()
    os.remove(ref_path)
    os.rmdir(tmp)


if __name__ == "__main__":
    main()
