"""Renders a Mitsuba 3 XML scene with Mitsuba (variant scalar_rgb) to EXR.

Usage: render_mitsuba.py SCENE.xml OUT.exr --res N --spp N --seed N
"""
import argparse
import time

import mitsuba as mi


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("scene")
    ap.add_argument("out")
    ap.add_argument("--res", type=int, required=True)
    ap.add_argument("--spp", type=int, required=True)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--variant", default="scalar_rgb")
    args = ap.parse_args()
    mi.set_variant(args.variant)
    scene = mi.load_file(args.scene, res=str(args.res), spp=str(args.spp))
    start = time.time()
    image = mi.render(scene, spp=args.spp, seed=args.seed)
    seconds = time.time() - start
    mi.Bitmap(image).write(args.out)
    print(f"{seconds:.3f}")


if __name__ == "__main__":
    main()
