"""Runs Mitsuba 3's own render tests (../shared/mitsuba-tests, see its
README) with trazo and judges each as Mitsuba's test does
(mitsuba3 src/render/tests/test_renders.py): image, reference and
per-sample variance in XYZ, the variance floored at 1e-4,
z = |image - reference| * sqrt(spp / variance) per pixel and channel,
p = 2 (1 - Phi(z)), and a pass when at most 0.25 % of the pixel-channels have
p at or below alpha = 0.01 corrected for the number of pixels (Sidak).

Each scene renders at its own film size with spp = 2,000,000 / pixels;
`*_volpath` scenes also as `volpathmis`. Prints a line per test and writes a
Markdown table. Run through ./run, which prepares the virtualenv and trazo.
"""

import argparse
import glob
import math
import os
import subprocess
import sys
import time

import mitsuba as mi
import numpy as np

mi.set_variant("scalar_rgb")

# Linear sRGB (Rec. 709 primaries, D65) to CIE XYZ, as Mitsuba's srgb_to_xyz.
SRGB_TO_XYZ = np.array(
    [
        [0.412453, 0.357580, 0.180423],
        [0.212671, 0.715160, 0.072169],
        [0.019334, 0.119193, 0.950227],
    ]
)


def read_xyz(path):
    rgb = np.array(mi.Bitmap(path), dtype=np.float64)[:, :, :3]
    return rgb @ SRGB_TO_XYZ.T


def judge(image, ref, var, spp):
    """(passes, share of pixel-channels rejected, mean signed z)."""
    var = np.maximum(var, 1e-4)
    scale = np.sqrt(spp / var)
    signed = (image - ref) * scale
    # p = 2 (1 - Phi(|z|)) = erfc(|z| / sqrt 2).
    p = np.vectorize(math.erfc)(np.abs(signed) / math.sqrt(2.0))
    pixels = image.shape[0] * image.shape[1]
    alpha = 1.0 - (1.0 - 0.01) ** (1.0 / pixels)
    rejected = float(np.mean(p <= alpha))
    return rejected <= 0.0025, rejected, float(np.mean(signed))


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--trazo", required=True)
    ap.add_argument("--data", required=True)
    ap.add_argument("--out", required=True)
    ap.add_argument("--spp-scale", type=float, default=1.0)
    ap.add_argument("--commit", default="")
    ap.add_argument(
        "--mitsuba",
        action="store_true",
        help="render with Mitsuba 3 scalar_rgb instead of trazo (the judge's own check: Mitsuba passes)",
    )
    ap.add_argument(
        "--exclude",
        action="append",
        default=[],
        help="leave out the tests whose name contains this (may be repeated)",
    )
    ap.add_argument(
        "--known-failures",
        help="a file naming, one a line (# starts a comment), the tests that fail today: the run then fails "
        "only when another test fails or a listed one passes (so that the list stays true)",
    )
    ap.add_argument("filters", nargs="*")
    args = ap.parse_args()
    known = set()
    if args.known_failures:
        with open(args.known_failures) as f:
            known = {line.split("#")[0].strip() for line in f} - {""}

    rows = []
    for scene in sorted(glob.glob(os.path.join(args.data, "tests/scenes/*/*.xml"))):
        stem = os.path.basename(scene)[: -len(".xml")]
        base, integrator = stem.rsplit("_", 1)
        integrators = [integrator] + (["volpathmis"] if integrator == "volpath" else [])
        refs = os.path.join(os.path.dirname(scene), "refs")
        for integ in integrators:
            name = f"{os.path.basename(os.path.dirname(scene))}/{base}_{integ}"
            if args.filters and not any(f in name for f in args.filters):
                continue
            if any(x in name for x in args.exclude):
                continue
            ref = read_xyz(os.path.join(refs, f"{base}_ref_rgb.exr"))
            var = read_xyz(os.path.join(refs, f"{base}_ref_rgb_var.exr"))
            pixels = ref.shape[0] * ref.shape[1]
            spp = max(1, int(2_000_000 // pixels * args.spp_scale))
            image_path = os.path.join(args.out, f"{name.replace('/', '-')}.exr")
            cmd = [args.trazo, "render", scene, "-D", f"spp={spp}", "-D", f"integrator={integ}", "-o", image_path]
            start = time.perf_counter()
            if args.mitsuba:
                try:
                    img = mi.render(mi.load_file(scene, spp=str(spp), integrator=integ), spp=spp)
                    mi.Bitmap(img).write(image_path)
                    run = subprocess.CompletedProcess(cmd, 0, "", "")
                except Exception as e:  # a scene Mitsuba cannot load
                    run = subprocess.CompletedProcess(cmd, 1, "", f"error: {e}")
            else:
                run = subprocess.run(cmd, capture_output=True, text=True)
            seconds = time.perf_counter() - start
            messages = [
                l.replace(args.data + "/", "")
                for l in run.stderr.splitlines()
                if l.startswith(("warning", "error"))
            ]
            if run.returncode != 0:
                row = (name, pixels, spp, "error", None, None, None, messages)
            else:
                image = read_xyz(image_path)
                if image.shape != ref.shape:
                    messages.insert(0, f"size {image.shape[1]}x{image.shape[0]}, reference {ref.shape[1]}x{ref.shape[0]}")
                    row = (name, pixels, spp, "fail", None, None, seconds, messages)
                else:
                    ok, rejected, z = judge(image, ref, var, spp)
                    row = (name, pixels, spp, "pass" if ok else "fail", rejected, z, seconds, messages)
            rows.append(row)
            r = row
            print(f"{name}: {r[3]}" + (f" (rejected {r[4]:.4f}, mean signed z {r[5]:.2f})" if r[4] is not None else ""), flush=True)

    passed = sum(r[3] == "pass" for r in rows)
    table = os.path.join(args.out, "results.md")
    with open(table, "w") as f:
        who = "Mitsuba 3 scalar_rgb (the judge's check)" if args.mitsuba else f"trazo {args.commit}"
        f.write(f"# Mitsuba 3's render tests with {who}\n\n")
        f.write(f"spp: Mitsuba's × {args.spp_scale:g}; {os.cpu_count()} cores; command: tools/mitsuba-tests/run")
        f.write(f"{' --spp-scale ' + format(args.spp_scale, 'g') if args.spp_scale != 1 else ''}\n\n")
        f.write("| test | pixels | spp | verdict | rejected | mean signed z | seconds | warnings and errors |\n")
        f.write("|---|---|---|---|---|---|---|---|\n")
        for name, pixels, spp, verdict, rejected, z, seconds, messages in rows:
            fmt = lambda x, p: "–" if x is None else f"{x:.{p}f}"
            note = "; ".join(messages[:3]).replace("|", "\\|")
            if len(messages) > 3:
                note += f"; and {len(messages) - 3} more"
            f.write(f"| {name} | {pixels} | {spp} | {verdict} | {fmt(rejected, 4)} | {fmt(z, 2)} | {fmt(seconds, 1)} | {note} |\n")
        f.write(f"\n**{passed} of {len(rows)} pass.**\n")
    print(f"{passed} of {len(rows)} pass (table: {table})")
    # The exit status: 0 when every test passes, or fails only as the list
    # of known failures says.
    unexpected = [r[0] for r in rows if r[3] != "pass" and r[0] not in known]
    fixed = [r[0] for r in rows if r[3] == "pass" and r[0] in known]
    for name in unexpected:
        print(f"FAILED: {name}", file=sys.stderr)
    for name in fixed:
        print(f"PASSES NOW: {name} (remove it from {args.known_failures})", file=sys.stderr)
    return 1 if unexpected or fixed else 0


if __name__ == "__main__":
    sys.exit(main())
