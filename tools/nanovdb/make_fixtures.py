"""Writes the NanoVDB test files of tests/data/nanovdb/ and the values NVIDIA
Warp's NanoVDB sampler reads from them, which trazo's reader must match.

Run by tools/nanovdb/make-fixtures (which installs Warp, from PyPI, into a
virtual environment of its own). The grids' bytes are built by the NanoVDB
code inside Warp (`wp.Volume.load_from_numpy`); this script writes the file
container around them (header, per-grid metadata and name, zlib chunks) as
NanoVDB's own writer lays it out, so that a file can hold several named
grids, as pbrt-v4's media expect ("density", "temperature").
"""

import os
import struct
import sys
import zlib

import numpy as np
import warp as wp

OUT = sys.argv[1] if len(sys.argv) > 1 else "tests/data/nanovdb"
MAGIC = 0x304244566F6E614E  # "NanoVDB0"
VERSION = 32 << 21 | 3 << 10 | 3


@wp.kernel
def sample(vol: wp.uint64, ijk: wp.array(dtype=wp.vec3), world: wp.array(dtype=wp.vec3), out: wp.array(dtype=float)):
    i = wp.tid()
    world[i] = wp.volume_index_to_world(vol, ijk[i])
    out[i] = wp.volume_sample_f(vol, ijk[i], wp.Volume.LINEAR)


def grid_bytes(values, min_world, voxel_size, name, grid_class=2, background=0.0):
    """The bytes of one float grid built by Warp from a dense array (x, y, z
    order), renamed `name` and of class `grid_class` (1: level set, 2: fog
    volume), reading `background` where the array has no value (Warp fills
    whole leaves)."""
    v = wp.Volume.load_from_numpy(values.astype(np.float32), min_world=min_world, voxel_size=voxel_size,
                                  bg_value=background, device="cpu")
    data = bytearray(v.array().numpy().tobytes())
    encoded = name.encode() + b"\0"
    data[40:40 + len(encoded)] = encoded  # GridData.mGridName
    struct.pack_into("<I", data, 632, grid_class)  # GridData.mGridClass
    return v, bytes(data)


def write_file(path, grids, codec):
    """A single-segment file of `grids` ([(name, bytes, type, class)])."""
    out = [struct.pack("<QIHH", MAGIC, VERSION, len(grids), codec)]
    payloads = []
    for name, data, gtype, gclass in grids:
        stored = data if codec == 0 else struct.pack("<Q", len(z := zlib.compress(data))) + z
        payloads.append(stored)
        world = struct.unpack_from("<6d", data, 560)
        vsize = struct.unpack_from("<3d", data, 608)
        meta = struct.pack("<QQQQII", len(data), len(stored), 0, 0, gtype, gclass)
        meta += struct.pack("<6d", *world) + struct.pack("<6i", 0, 0, 0, 0, 0, 0) + struct.pack("<3d", *vsize)
        meta += struct.pack("<I", len(name) + 1) + struct.pack("<4I", 0, 0, 0, 0) + struct.pack("<3I", 0, 0, 0)
        meta += struct.pack("<HHI", codec, 0, VERSION)
        assert len(meta) == 176
        out.append(meta + name.encode() + b"\0")
    with open(path, "wb") as f:
        f.write(b"".join(out + payloads))


def samples(volume, shape, count, rng):
    """`count` random index-space points inside the array's voxel centres, their
    world positions and Warp's trilinear values there."""
    ijk = rng.uniform(0.0, 1.0, (count, 3)) * (np.array(shape, dtype=np.float64) - 1.0)
    # Some points exactly on voxel centres, where no interpolation happens.
    ijk[: count // 8] = np.floor(ijk[: count // 8])
    ijk = wp.array(ijk.astype(np.float32), dtype=wp.vec3, device="cpu")
    world = wp.zeros(count, dtype=wp.vec3, device="cpu")
    out = wp.zeros(count, dtype=float, device="cpu")
    wp.launch(sample, dim=count, inputs=[volume.id, ijk, world, out], device="cpu")
    return world.numpy().tolist(), out.numpy().tolist()


def main():
    wp.init()
    os.makedirs(OUT, exist_ok=True)
    rng = np.random.default_rng(7)
    shape = (21, 13, 10)
    # A density with structure at every scale, some voxels exactly zero.
    density = rng.uniform(0.0, 2.0, shape) * (rng.uniform(size=shape) > 0.2)
    temperature = 300.0 + 2000.0 * rng.uniform(size=shape)
    origin, voxel = (-1.25, 0.5, 2.0), 0.125
    dv, density_bytes = grid_bytes(density, origin, voxel, "density")
    tv, temperature_bytes = grid_bytes(temperature, origin, voxel, "temperature")
    write_file(os.path.join(OUT, "smoke.nvdb"),
               [("density", density_bytes, 1, 2), ("temperature", temperature_bytes, 1, 2)], codec=1)
    points, values = samples(dv, shape, 400, rng)
    t_points, t_values = samples(tv, shape, 100, rng)
    # A narrow-band level set of a torus (major radius 0.6, minor 0.25,
    # about the y axis, centred at TORUS_CENTRE), 3 voxels wide either side.
    h = 0.05
    centre = np.array([0.3, -0.2, 0.1])
    lo = centre - np.array([1.0, 0.4, 1.0])
    ijk = np.stack(np.meshgrid(np.arange(41), np.arange(17), np.arange(41), indexing="ij"), axis=-1)
    p = lo + h * ijk - centre
    q = np.sqrt(p[..., 0] ** 2 + p[..., 2] ** 2) - 0.6
    sdf = np.clip(np.sqrt(q ** 2 + p[..., 1] ** 2) - 0.25, -3 * h, 3 * h)
    _, torus = grid_bytes(sdf, tuple(lo), h, "surface", grid_class=1, background=3 * h)
    write_file(os.path.join(OUT, "torus.nvdb"), [("surface", torus, 1, 1)], codec=1)

    for grid, (pts, vals) in [("density", (points, values)), ("temperature", (t_points, t_values))]:
        with open(os.path.join(OUT, f"smoke-{grid}.txt"), "w") as f:
            f.write(f"# smoke.nvdb, grid \"{grid}\": world x y z, then the value NVIDIA Warp {wp.__version__}\n")
            f.write("# reads there (volume_sample_f, LINEAR); made by tools/nanovdb/make-fixtures\n")
            for p, v in zip(pts, vals):
                f.write("%r %r %r %r\n" % (p[0], p[1], p[2], v))


if __name__ == "__main__":
    main()
