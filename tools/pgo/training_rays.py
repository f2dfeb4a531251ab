"""Training inputs for `trazo bench rays` in tools/pgo/build: a bumpy sphere
of about TRIANGLES triangles as binary PLY, and coherent (camera) and incoherent
(random) rays, like those of bench/compare.py. Standard library only: that
script makes its inputs with numpy, in a virtualenv this build should not
need.

Usage: training_rays.py DIR TRIANGLES SIDE (SIDE² rays of each kind)
"""

import math
import random
import struct
import sys


def main():
    out, triangles, side = sys.argv[1], int(sys.argv[2]), int(sys.argv[3])
    rings = max(4, int((triangles / 2) ** 0.5))
    segments = max(4, triangles // (2 * rings))
    verts = []
    for i in range(rings + 1):
        theta = math.pi * i / rings
        for j in range(segments):
            phi = 2 * math.pi * j / segments
            r = 1 + 0.05 * math.sin(7 * theta) * math.sin(9 * phi)
            verts.append((r * math.sin(theta) * math.cos(phi), r * math.cos(theta), r * math.sin(theta) * math.sin(phi)))
    faces = []
    for i in range(rings):
        for j in range(segments):
            a, b = i * segments + j, i * segments + (j + 1) % segments
            c, d = a + segments, b + segments
            faces.append((a, c, b))
            faces.append((b, c, d))
    with open(f"{out}/mesh.ply", "wb") as f:
        f.write(
            (
                "ply\nformat binary_little_endian 1.0\n"
                f"element vertex {len(verts)}\nproperty float x\nproperty float y\nproperty float z\n"
                f"element face {len(faces)}\nproperty list uchar uint vertex_indices\nend_header\n"
            ).encode()
        )
        f.write(b"".join(struct.pack("<3f", *v) for v in verts))
        f.write(b"".join(struct.pack("<B3I", 3, *t) for t in faces))
    rng = random.Random(1)
    with open(f"{out}/coherent.bin", "wb") as f:
        for y in range(side):
            for x in range(side):
                d = ((x + 0.5) / side - 0.5, 0.5 - (y + 0.5) / side, -1.0)
                f.write(struct.pack("<6f", 0.0, 0.0, 3.0, *d))
    with open(f"{out}/incoherent.bin", "wb") as f:
        for _ in range(side * side):
            o = [rng.uniform(-1.3, 1.3) for _ in range(3)]
            d = [rng.gauss(0, 1) for _ in range(3)]
            f.write(struct.pack("<6f", *o, *d))


if __name__ == "__main__":
    main()
