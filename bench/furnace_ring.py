#!/usr/bin/env python3
"""Light a glass sphere in a white furnace loses to the depth limit in its
silhouette's one-pixel ring (bench/suite/furnace-glass.xml, 128²): the exact
expectation, integrated over the ring's pixels in double precision, beside
trazo's and Mitsuba 3's renders of it.

A camera ray at impact parameter b enters the unit sphere with cos θ = √(1 − b²)
(the sphere reflects it with Fresnel's R(θ) first); inside, every hit meets the
surface at the refracted angle, where the reflectance is the same R(θ), so a
path stays in for D − 2 reflections with probability (1 − R)·R^(D−2): the
light lost at max_depth D. The ring's mean is 1 less the mean loss over its
pixels' uniformly drawn positions.

    bench/.venv/bin/python bench/furnace_ring.py [--depths 6,8,16] [--spp 4096] [--trazo target/release/trazo]
"""
import argparse
import math
import os
import subprocess
import tempfile

import numpy as np

SCENE = os.path.join(os.path.dirname(os.path.abspath(__file__)), "suite", "furnace-glass.xml")
RES, FOV, EYE, ETA = 128, 30.0, 4.0, 1.5


def ring_pixels():
    """Pixels within 1.5 px inside and 0.5 px outside the disk's edge."""
    radius = math.tan(math.asin(1.0 / EYE)) / math.tan(math.radians(FOV / 2)) * RES / 2
    ys, xs = np.mgrid[0:RES, 0:RES]
    d = np.hypot(xs + 0.5 - RES / 2, ys + 0.5 - RES / 2)
    return (d > radius - 1.5) & (d < radius + 0.5)


def fresnel(cos_i):
    sin2_t = (1 - cos_i * cos_i) / (ETA * ETA)
    cos_t = np.sqrt(np.maximum(1 - sin2_t, 0))
    parallel = (ETA * cos_i - cos_t) / (ETA * cos_i + cos_t)
    perpendicular = (cos_i - ETA * cos_t) / (cos_i + ETA * cos_t)
    return 0.5 * (parallel**2 + perpendicular**2)


def exact_ring_mean(depth, samples=20000, seed=1):
    rng = np.random.default_rng(seed)
    tan_half = math.tan(math.radians(FOV / 2))
    means = []
    for py, px in np.argwhere(ring_pixels()):
        u, v = rng.random(samples), rng.random(samples)
        sx = ((px + u) / RES * 2 - 1) * tan_half
        sy = (1 - (py + v) / RES * 2) * tan_half
        # Distance from the centre to the ray from (0, 0, EYE) along (sx, sy, −1).
        b = EYE * np.hypot(sx, sy) / np.sqrt(sx * sx + sy * sy + 1)
        r = fresnel(np.sqrt(np.maximum(1 - b * b, 0)))
        loss = np.where(b < 1, (1 - r) * r ** (depth - 2), 0.0)
        means.append(1 - loss.mean())
    return float(np.mean(means))


def image_ring_mean(rgb):
    return float(rgb[..., :3].mean(axis=2)[ring_pixels()].mean())


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--depths", default="6,8,10,12,16")
    ap.add_argument("--spp", type=int, default=4096)
    ap.add_argument("--trazo", default="target/release/trazo")
    args = ap.parse_args()
    import mitsuba as mi

    mi.set_variant("llvm_ad_rgb")
    text = open(SCENE).read()
    print("| max_depth | exact | trazo | Mitsuba llvm_ad_rgb |\n|---|---|---|---|")
    with tempfile.TemporaryDirectory() as tmp:
        for depth in (int(d) for d in args.depths.split(",")):
            scene = os.path.join(tmp, "scene.xml")
            with open(scene, "w") as f:
                f.write(text.replace('name="max_depth" value="16"', f'name="max_depth" value="{depth}"'))
            out = os.path.join(tmp, "trazo.exr")
            subprocess.run(
                [args.trazo, "render", scene, "-D", f"spp={args.spp}", "-D", f"res={RES}", "-o", out, "-q"],
                check=True,
            )
            trazo = image_ring_mean(np.array(mi.Bitmap(out)))
            mitsuba = image_ring_mean(np.array(mi.render(mi.load_file(scene, res=RES, spp=args.spp), seed=1)))
            print(f"| {depth} | {exact_ring_mean(depth):.5f} | {trazo:.5f} | {mitsuba:.5f} |")


if __name__ == "__main__":
    main()
