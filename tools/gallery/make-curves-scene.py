#!/usr/bin/env python3
"""Writes scenes/curves.toml: a fur ball of hair fibres and a tuft of grass
blades, both made of curves (docs/gallery.md). Deterministic: run it again
and the file is the same."""
import math
import random

rng = random.Random(7)
out = [
    "# Curves, as pbrt-v4's `curve` shape draws hair and grass (written by",
    "# tools/gallery/make-curves-scene.py): a ball of brown hair fibres (the",
    "# `hair` material, Chiang et al. 2016) and a tuft of grass blades, flat",
    "# ribbons that narrow to their tips, on a floor under the sky.",
    "",
    "[render]",
    "width = 640",
    "height = 320",
    "spp = 32",
    "max_depth = 16",
    "tonemap = \"aces\"",
    "",
    "[camera]",
    "from = [0, 1.6, 6.5]",
    "to = [0, 0.9, 0]",
    "fov = 30",
    "",
    "[world]",
    "background = { file = \"textures/sky.hdr\", scale = 1.0 }",
    "",
    "[[material]]",
    "name = \"fur\"",
    "type = \"hair\"",
    "eumelanin = 0.6",
    "pheomelanin = 0.4",
    "beta_m = 0.25",
    "beta_n = 0.3",
    "",
    "[[material]]",
    "name = \"grass\"",
    "type = \"diffuse\"",
    "reflectance = [0.12, 0.35, 0.08]",
    "",
    "[[material]]",
    "name = \"skin\"",
    "type = \"diffuse\"",
    "reflectance = [0.12, 0.07, 0.04]",
    "",
    "[[material]]",
    "name = \"floor\"",
    "type = \"diffuse\"",
    "reflectance = 0.45",
    "",
    "[[shape]]",
    "type = \"plane\"",
    "point = [0, 0, 0]",
    "normal = [0, 1, 0]",
    "material = \"floor\"",
    "",
    "[[shape]]",
    "type = \"sphere\"",
    "radius = 0.55",
    "material = \"skin\"",
    "transform = [{ translate = [-1.1, 0.9, 0] }]",
]


def fmt(p):
    return "[" + ", ".join("%.3f" % c for c in p) + "]"


# The fur ball: fibres leaving a sphere of radius 0.55 about (-1.1, 0.9, 0),
# bending under gravity.
centre = (-1.1, 0.9, 0.0)
for _ in range(700):
    z = rng.uniform(-1, 1)
    a = rng.uniform(0, 2 * math.pi)
    r = math.sqrt(1 - z * z)
    n = (r * math.cos(a), z, r * math.sin(a))
    length = rng.uniform(0.35, 0.55)
    pts = []
    for k in range(4):
        t = k / 3
        d = 0.55 + length * t
        sag = 0.12 * t * t
        pts.append((centre[0] + n[0] * d, centre[1] + n[1] * d - sag, centre[2] + n[2] * d))
    out += ["", "[[shape]]", "type = \"curve\"", "points = [" + ", ".join(fmt(p) for p in pts) + "]",
            "width0 = 0.012", "width1 = 0.004", "material = \"fur\""]

# The tuft: blades from a disk about (1.2, 0, 0), leaning outward.
for _ in range(260):
    a = rng.uniform(0, 2 * math.pi)
    rad = 0.45 * math.sqrt(rng.uniform(0, 1))
    base = (1.2 + rad * math.cos(a), 0.0, rad * math.sin(a))
    lean = (math.cos(a) * rng.uniform(0.1, 0.5), math.sin(a) * rng.uniform(0.1, 0.5))
    h = rng.uniform(0.9, 1.6)
    pts = [(base[0] + lean[0] * t * t, h * t, base[2] + lean[1] * t * t) for t in (0, 1 / 3, 2 / 3, 1)]
    out += ["", "[[shape]]", "type = \"curve\"", "points = [" + ", ".join(fmt(p) for p in pts) + "]",
            "width0 = 0.05", "width1 = 0.004", "curve_type = \"flat\"", "split_depth = 2", "material = \"grass\""]

with open("scenes/curves.toml", "w") as f:
    f.write("\n".join(out) + "\n")
