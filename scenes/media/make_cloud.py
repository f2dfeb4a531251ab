#!/usr/bin/env python3
"""Writes cloud.vol, the density grid of scenes/cloud.toml: a 32³ Mitsuba
volume (version 3, float32, one channel) of a few overlapping soft blobs
with a ripple, densest about 1 at the core and 0 at the edges. Pure
Python, deterministic: `python3 scenes/media/make_cloud.py`."""
import math
import os
import struct

N = 32
BLOBS = [  # centre (unit cube), radius, weight
    ((0.50, 0.45, 0.50), 0.28, 1.0),
    ((0.32, 0.52, 0.45), 0.20, 0.8),
    ((0.68, 0.55, 0.55), 0.22, 0.9),
    ((0.52, 0.68, 0.48), 0.18, 0.7),
]


def density(x, y, z):
    d = 0.0
    for (cx, cy, cz), r, w in BLOBS:
        q = ((x - cx) ** 2 + (y - cy) ** 2 + (z - cz) ** 2) / (r * r)
        d += w * math.exp(-2.5 * q)
    ripple = 0.75 + 0.25 * math.sin(17 * x + 3) * math.sin(13 * y + 1) * math.sin(19 * z + 2)
    return max(0.0, min(1.0, d * ripple))


def main():
    values = []
    for k in range(N):
        for j in range(N):
            for i in range(N):
                values.append(density((i + 0.5) / N, (j + 0.5) / N, (k + 0.5) / N))
    out = os.path.join(os.path.dirname(os.path.abspath(__file__)), "cloud.vol")
    with open(out, "wb") as f:
        f.write(b"VOL" + bytes([3]))
        f.write(struct.pack("<iiiii", 1, N, N, N, 1))
        f.write(struct.pack("<6f", 0, 0, 0, 1, 1, 1))
        f.write(struct.pack("<%df" % len(values), *values))
    print(out)


if __name__ == "__main__":
    main()
