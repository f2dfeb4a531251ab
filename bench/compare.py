"""Side-by-side speed comparison of trazo with Embree, Mitsuba 3 and Blender
Cycles (see bench/compare).

Every peer runs on the same inputs in the same run; the table quotes ratios.
"""
import argparse
import glob
import json
import multiprocessing as mp
import os
import re
import subprocess
import sys
import tempfile
import time

import numpy as np


def bumpy_sphere(triangles):
    """A displaced UV sphere with about `triangles` triangles (vertices, indices)."""
    nv = max(4, int(round((triangles / 4) ** 0.5)))
    nu = 2 * nv
    theta = (np.arange(nv + 1) / nv * np.pi)[:, None]
    phi = (np.arange(nu) / nu * 2 * np.pi)[None, :]
    r = 1.0 + 0.05 * np.sin(7 * phi) * np.sin(5 * theta) + 0.02 * np.cos(31 * phi + 13 * theta)
    x = r * np.sin(theta) * np.cos(phi)
    y = r * np.cos(theta) * np.ones_like(phi)
    z = r * np.sin(theta) * np.sin(phi)
    verts = np.stack([x, y, z], axis=-1).reshape(-1, 3).astype(np.float32)
    j, i = np.meshgrid(np.arange(nv), np.arange(nu), indexing="ij")
    a = j * nu + i
    b = j * nu + (i + 1) % nu
    c = (j + 1) * nu + (i + 1) % nu
    d = (j + 1) * nu + i
    tris = np.concatenate([np.stack([a, b, c], -1).reshape(-1, 3), np.stack([a, c, d], -1).reshape(-1, 3)])
    return verts, tris.astype(np.uint32)


def write_ply(path, verts, tris):
    with open(path, "wb") as f:
        f.write(
            (
                "ply\nformat binary_little_endian 1.0\n"
                f"element vertex {len(verts)}\nproperty float x\nproperty float y\nproperty float z\n"
                f"element face {len(tris)}\nproperty list uchar uint vertex_indices\nend_header\n"
            ).encode()
        )
        f.write(verts.astype("<f4").tobytes())
        face = np.zeros(len(tris), dtype=[("n", "u1"), ("i", "<u4", 3)])
        face["n"] = 3
        face["i"] = tris
        f.write(face.tobytes())


def camera_rays(n):
    """Coherent rays: a pinhole camera's primary rays, row by row."""
    side = int(n**0.5)
    u, v = np.meshgrid((np.arange(side) + 0.5) / side, (np.arange(side) + 0.5) / side)
    d = np.stack([(u - 0.5) * 0.8, (0.5 - v) * 0.8, -np.ones_like(u)], -1).reshape(-1, 3)
    o = np.broadcast_to(np.array([0.0, 0.0, 3.0]), d.shape)
    return np.ascontiguousarray(o, np.float32), np.ascontiguousarray(d, np.float32)


def random_rays(n, rng):
    """Incoherent rays: origins in the mesh's bounding box, directions uniform on the sphere."""
    o = rng.uniform(-1.3, 1.3, (n, 3)).astype(np.float32)
    d = rng.normal(size=(n, 3)).astype(np.float32)
    return o, d


def write_rays(path, o, d):
    np.concatenate([o, d], axis=1).astype("<f4").tofile(path)


_scene = None


# Each timing is the best of this many runs, for trazo and every peer alike
# (a single run on a shared 2-core machine varies by tens of percent).
REPEAT = 3

# Ray queries take a tenth of a second a pass, so a short slow spell can
# spoil three passes in a row: trazo's coherent closest-hit rate, best of
# 3, ranged over 7.6–10.6 M rays/s from run to run, best of 20 over
# 10.9–11.1 (BENCHMARKS.md). Both trazo and Embree take the best of this
# many passes.
RAY_REPEAT = 10


def _embree_worker(args):
    verts, tris, o, d, occluded = args
    from embreex import mesh_construction, rtcore_scene

    scene = rtcore_scene.EmbreeScene()
    mesh_construction.TriangleMesh(scene, verts, tris)
    scene.run(o[:16], d[:16])  # build before timing
    best = float("inf")
    for _ in range(RAY_REPEAT):
        start = time.perf_counter()
        scene.run(o, d, query="OCCLUDED" if occluded else "INTERSECT")
        best = min(best, time.perf_counter() - start)
    return best


def embree(verts, tris, o, d, occluded, procs):
    """Rays/s of Embree, one process per core (embreex traces in one thread)."""
    parts = [(verts, tris, oo, dd, occluded) for oo, dd in zip(np.array_split(o, procs), np.array_split(d, procs))]
    with mp.get_context("fork").Pool(procs) as pool:
        times = pool.map(_embree_worker, parts)
    return len(o) / max(times)


def embree_build(verts, tris):
    from embreex import mesh_construction, rtcore_scene

    start = time.perf_counter()
    scene = rtcore_scene.EmbreeScene()
    mesh_construction.TriangleMesh(scene, verts, tris)
    scene.run(np.zeros((1, 3), np.float32), np.ones((1, 3), np.float32))
    return time.perf_counter() - start, scene


def trazo_rays(trazo, mesh, rays, hits):
    out = subprocess.run(
        [trazo, "bench", "rays", "--mesh", mesh, "--rays", rays, "--hits", hits, "--repeat", str(RAY_REPEAT)],
        check=True, capture_output=True, text=True,
    ).stdout
    build = float(re.search(r"build: ([0-9.]+) s", out).group(1))
    closest = float(re.search(r"closest-hit: ([0-9.]+) rays/s", out).group(1))
    anyhit = float(re.search(r"any-hit: ([0-9.]+) rays/s", out).group(1))
    return build, closest, anyhit


def agreement(scene, o, d, hits_path):
    """Fraction of rays on which trazo's and Embree's closest hits agree."""
    k = min(len(o), 100_000)
    ref = scene.run(o[:k], d[:k], output=1)
    h = np.fromfile(hits_path, dtype=[("t", "<f4"), ("p", "<u4")])[:k]
    miss_ref = ref["primID"] < 0
    miss = h["p"] == 0xFFFFFFFF
    t_ok = np.isclose(h["t"], ref["tfar"], rtol=1e-4, atol=1e-6) | (miss & miss_ref)
    return np.mean((miss == miss_ref) & t_ok)


def peak_rss_kb(cmd):
    r = subprocess.run(["/usr/bin/time", "-f", "%M"] + cmd, capture_output=True, text=True)
    return int(r.stderr.strip().splitlines()[-1]) if r.returncode == 0 else None


def read_ply(path):
    """The vertices and triangles of a PLY written by write_ply."""
    with open(path, "rb") as f:
        header = b""
        while not header.endswith(b"end_header\n"):
            header += f.readline()
        nv = int(re.search(rb"element vertex (\d+)", header).group(1))
        nf = int(re.search(rb"element face (\d+)", header).group(1))
        verts = np.frombuffer(f.read(12 * nv), dtype="<f4").reshape(-1, 3)
        faces = np.frombuffer(f.read(13 * nf), dtype=[("n", "u1"), ("i", "<u4", 3)])
    return np.ascontiguousarray(verts), np.ascontiguousarray(faces["i"])


def embree_memory(mesh, rays):
    """Run in a child process: peak memory of Embree's default build and one
    trace, from the same PLY and ray file trazo reads. Prints the process's
    peak RSS and the part of it that building and tracing added (KiB)."""
    import resource
    from embreex import mesh_construction, rtcore_scene

    verts, tris = read_ply(mesh)
    r = np.fromfile(rays, dtype="<f4").reshape(-1, 6)
    o, d = np.ascontiguousarray(r[:, :3]), np.ascontiguousarray(r[:, 3:])
    del r
    # Resident memory now (KiB), not the peak so far: reading the PLY made
    # temporaries that are gone.
    with open("/proc/self/statm") as f:
        before = int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE") // 1024
    scene = rtcore_scene.EmbreeScene()
    mesh_construction.TriangleMesh(scene, verts, tris)
    scene.run(o, d)
    after = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    print(after, after - before)


def ray_section(args, work):
    rng = np.random.default_rng(1)
    verts, tris = bumpy_sphere(args.triangles)
    mesh = os.path.join(work, "mesh.ply")
    write_ply(mesh, verts, tris)
    print(f"mesh: {len(tris)} triangles; rays: {args.rays} per set; {os.cpu_count()} cores")
    build_embree, scene = embree_build(verts, tris)
    rows = []
    for name, (o, d) in [("coherent", camera_rays(args.rays)), ("incoherent", random_rays(args.rays, rng))]:
        rays = os.path.join(work, f"{name}.bin")
        hits = os.path.join(work, f"{name}.hits")
        write_rays(rays, o, d)
        build, t_closest, t_any = trazo_rays(args.trazo, mesh, rays, hits)
        pgo = trazo_rays(args.trazo_pgo, mesh, rays, hits + ".pgo") if args.trazo_pgo else None
        e_closest = embree(verts, tris, o, d, False, os.cpu_count())
        e_any = embree(verts, tris, o, d, True, os.cpu_count())
        agree = agreement(scene, o, d, hits)
        rows.append((name, t_closest, e_closest, t_any, e_any, agree, build, pgo))
    print()
    if args.trazo_pgo:
        print("| rays | query | trazo rays/s | trazo PGO rays/s | Embree rays/s | trazo / Embree | trazo PGO / Embree |")
        print("|---|---|---|---|---|---|---|")
    else:
        print("| rays | query | trazo rays/s | Embree rays/s | trazo / Embree |")
        print("|---|---|---|---|---|")
    for name, tc, ec, ta, ea, _, _, pgo in rows:
        for query, t, e, p in [("closest hit", tc, ec, pgo and pgo[1]), ("any hit", ta, ea, pgo and pgo[2])]:
            if p:
                print(f"| {name} | {query} | {t / 1e6:.2f} M | {p / 1e6:.2f} M | {e / 1e6:.2f} M | {t / e:.2f} | {p / e:.2f} |")
            else:
                print(f"| {name} | {query} | {t / 1e6:.2f} M | {e / 1e6:.2f} M | {t / e:.2f} |")
    print()
    pgo_build = f", trazo PGO {rows[0][7][0]:.3f} s" if args.trazo_pgo else ""
    print(f"BVH build, {len(tris)} triangles: trazo {rows[0][6]:.3f} s{pgo_build}, Embree {build_embree:.3f} s (one process)")
    print("closest hits agreeing with Embree's (first 100k rays): " + ", ".join(f"{r[0]} {100 * r[5]:.3f}%" for r in rows))
    rays = os.path.join(work, "coherent.bin")
    rss = peak_rss_kb([args.trazo, "bench", "rays", "--mesh", mesh, "--rays", rays])
    if rss:
        print(f"trazo peak memory (load + build + trace): {rss / 1024:.0f} MiB, {rss * 1024 / len(tris):.0f} bytes/triangle")
    out = subprocess.run(
        [sys.executable, os.path.abspath(__file__), "--embree-memory", mesh, rays],
        check=True, capture_output=True, text=True,
    ).stdout.split()
    peak, added = int(out[0]), int(out[1])
    print(
        f"Embree peak memory (Python + load + build + trace): {peak / 1024:.0f} MiB, "
        f"{peak * 1024 / len(tris):.0f} bytes/triangle; of which build + trace {added * 1024 / len(tris):.0f} bytes/triangle"
    )


def find_libllvm():
    """The newest libLLVM shared library on the system (Dr.Jit's LLVM backend needs version 16 or later)."""
    if os.environ.get("DRJIT_LIBLLVM_PATH"):
        return os.environ["DRJIT_LIBLLVM_PATH"]
    found = glob.glob("/usr/lib/x86_64-linux-gnu/libLLVM*.so*") + glob.glob("/usr/lib/llvm-*/lib/libLLVM*.so*")
    versioned = []
    for path in found:
        m = re.search(r"(?:libLLVM-|llvm-)(\d+)", path)
        if m and int(m.group(1)) >= 16:
            versioned.append((int(m.group(1)), path))
    return max(versioned)[1] if versioned else None


MITSUBA = r"""
import sys, time, numpy as np, mitsuba as mi
variant, scene_path, res, spp, out = sys.argv[1:6]
mi.set_variant(variant)
scene = mi.load_file(scene_path, res=res, spp=spp)
# A warm-up render of the same size first: the LLVM variant compiles its
# kernels on the first render, which is not what is being compared.
np.array(mi.render(scene, spp=int(spp), seed=1))
start = time.perf_counter()
img = np.array(mi.render(scene, spp=int(spp), seed=0))
print(f"{time.perf_counter() - start:.3f}")
mi.Bitmap(img).write(out)
"""


def mitsuba_time(variant, scene, res, spp, out):
    env = dict(os.environ)
    if variant.startswith("llvm"):
        lib = find_libllvm()
        if not lib:
            return None, "no libLLVM 16 or later found (apt-get install libllvm19, or set DRJIT_LIBLLVM_PATH)"
        env["DRJIT_LIBLLVM_PATH"] = lib
    r = subprocess.run([sys.executable, "-c", MITSUBA, variant, scene, str(res), str(spp), out],
                       capture_output=True, text=True, env=env)
    if r.returncode != 0:
        return None, (r.stderr.strip().splitlines() or ["failed"])[-1]
    return float(r.stdout.strip().splitlines()[-1]), None


def cycles_time(res, spp, out):
    """Render the Cornell box in Blender Cycles (bench/cycles_cornell.py, in a
    child process): (best render time, the child's report) or (None, why)."""
    script = os.path.join(os.path.dirname(os.path.abspath(__file__)), "cycles_cornell.py")
    r = subprocess.run([sys.executable, script, "--res", str(res), "--spp", str(spp), "--repeat", str(REPEAT),
                        "--out", out], capture_output=True, text=True)
    if r.returncode != 0:
        return None, (r.stderr.strip().splitlines() or ["failed"])[-1]
    report = json.loads(r.stdout.strip().splitlines()[-1])
    return min(report["render_s"]), report


def channel_means(trazo, image, reference):
    """The mean R, G, B of `image` and of `reference`, as `trazo diff` prints them."""
    r = subprocess.run([trazo, "diff", image, reference], capture_output=True, text=True)
    means = re.findall(r"mean R G B: ([0-9.eE+-]+) ([0-9.eE+-]+) ([0-9.eE+-]+)", r.stdout)
    return [[float(x) for x in m] for m in means] if len(means) == 2 else None


def relmse(trazo, image, reference):
    """Relative MSE of `image` against `reference`, as `trazo diff` computes it."""
    r = subprocess.run([trazo, "diff", image, reference], capture_output=True, text=True)
    m = re.search(r"relative MSE: ([0-9.eE+-]+)", r.stdout + r.stderr)
    return float(m.group(1)) if m else None


def reference_image(args, scene):
    """A converged image of the Cornell box: Mitsuba llvm_ad_rgb (scalar_rgb
    if LLVM is missing) at --reference-spp, cached in bench/.cache."""
    cache = os.path.join(args.root, "bench", ".cache")
    os.makedirs(cache, exist_ok=True)
    path = os.path.join(cache, f"cornell-{args.res}px-{args.reference_spp}spp.exr")
    if not os.path.exists(path):
        print(f"rendering the reference ({args.reference_spp} spp, once; cached in {os.path.relpath(path, args.root)})...",
              file=sys.stderr)
        for variant in ["llvm_ad_rgb", "scalar_rgb"]:
            t, _ = mitsuba_time(variant, scene, args.res, args.reference_spp, path + ".tmp.exr")
            if t is not None:
                os.replace(path + ".tmp.exr", path)
                break
    return path if os.path.exists(path) else None


def render_section(args, work):
    scene = os.path.join(args.root, "tools/crosscheck/scenes/cornell-box.xml")
    reference = None if args.reference_spp == 0 else reference_image(args, scene)
    print(f"Cornell box ({os.path.relpath(scene, args.root)}), {args.res}×{args.res}, {args.spp} spp, max depth 8, {os.cpu_count()} cores")
    out = os.path.join(work, "trazo.exr")

    def trazo_time(binary, image):
        r = subprocess.run([binary, "render", scene, "-o", image, "--spp", str(args.spp), "--width", str(args.res),
                            "--height", str(args.res), "--max-depth", "8"], capture_output=True, text=True, check=True)
        return float(re.search(r" in ([0-9.]+) s", r.stderr).group(1)), None

    # Each renderer's best of REPEAT runs, the renderers taking turns
    # round by round, so that a slow spell of the shared machine does not
    # decide a ratio; every run renders the same image (fixed seeds).
    runners = [("trazo", "trazo (path:mis)", lambda: trazo_time(args.trazo, out), out)]
    if args.trazo_pgo:
        pgo_out = os.path.join(work, "trazo-pgo.exr")
        runners.append(("trazo_pgo", "trazo, PGO build (path:mis)", lambda: trazo_time(args.trazo_pgo, pgo_out), pgo_out))
    for variant in ["llvm_ad_rgb", "scalar_rgb"]:
        image = os.path.join(work, f"{variant}.exr")
        runners.append((variant, f"Mitsuba 3 {variant}",
                        lambda v=variant, i=image: mitsuba_time(v, scene, args.res, args.spp, i), image))
    runs = {key: [] for key, *_ in runners}
    failed = {}
    for _ in range(REPEAT):
        for key, _name, run, _image in runners:
            if key in failed:
                continue
            t, why = run()
            if t is None:
                failed[key] = why
            else:
                runs[key].append(t)
    rows = [(name, min(runs[key]) if key not in failed else None, failed.get(key), image)
            for key, name, _run, image in runners]
    t_trazo = rows[0][1]
    if t_trazo is None:
        raise SystemExit(f"trazo failed: {failed['trazo']}")
    t_pgo = rows[1][1] if args.trazo_pgo else None
    cycles = None
    if args.cycles:
        image = os.path.join(work, "cycles.exr")
        t, cycles = cycles_time(args.res, args.spp, image)
        name = f"Blender Cycles {cycles['settings']['blender']} CPU" if t is not None else "Blender Cycles CPU"
        rows.append((name, t, cycles if t is None else None, image))
    samples = args.res * args.res * args.spp
    print()
    if reference:
        print(f"error: relative MSE against {args.reference_spp} spp of Mitsuba ({os.path.relpath(reference, args.root)})")
        print()
    pgo_head, pgo_rule = (" trazo PGO time / peer time |", "---|") if t_pgo else ("", "")
    print(f"| renderer | render time | samples/s | trazo time / peer time |{pgo_head} relative MSE |")
    print(f"|---|---|---|---|{pgo_rule}---|")
    for name, t, why, image in rows:
        if t is None:
            print(f"| {name} | unavailable: {why} | | |{' |' if t_pgo else ''} |")
        else:
            err = relmse(args.trazo, image, reference) if reference else None
            err = f"{err:.2e}" if err is not None else "–"
            pgo = f" {t_pgo / t:.2f} |" if t_pgo else ""
            print(f"| {name} | {t:.2f} s | {samples / t / 1e6:.2f} M | {t_trazo / t:.2f} |{pgo} {err} |")
    print()
    print("render times, each the best of its runs: " + "; ".join(
        f"{key} {', '.join(f'{t:.2f}' for t in times)} s" for key, times in runs.items() if times))
    if isinstance(cycles, dict):
        print_cycles_notes(args, cycles, rows[-1][3], reference)


def print_cycles_notes(args, report, image, reference):
    times = report["render_s"]
    s = report["settings"]
    print()
    print(f"Cycles: render time is the best of {len(times)} "
          + (f"({', '.join(f'{t:.2f}' for t in times)} s)" if len(times) > 1 else "(one render took over 3 minutes)")
          + f"; not counted: Blender start-up (import bpy) {report['import_s']:.2f} s, scene set-up {report['setup_s']:.2f} s")
    print(f"Cycles settings: {s['device']}, {s['threads']} threads, {s['samples']} spp, sampling pattern "
          f"{s['sampling_pattern'].lower()}, light tree {'on' if s['light_tree'] else 'off'}, max bounces "
          f"{s['max_bounces']} (= Mitsuba max depth 8), no adaptive sampling, no denoising, no clamping, "
          f"filter glossy 0, pixel filter {s['pixel_filter']}, view transform {s['view_transform']}, linear EXR")
    if reference:
        means = channel_means(args.trazo, image, reference)
        if means:
            ratio = " ".join(f"{a / b:.4f}" for a, b in zip(*means))
            print(f"Cycles image mean / Mitsuba reference mean, R G B: {ratio}")


def main():
    if len(sys.argv) == 4 and sys.argv[1] == "--embree-memory":
        embree_memory(sys.argv[2], sys.argv[3])
        return
    ap = argparse.ArgumentParser()
    ap.add_argument("--trazo", required=True)
    ap.add_argument("--trazo-pgo", help="a PGO build of trazo (tools/pgo/build) to measure beside --trazo")
    ap.add_argument("--root", required=True)
    ap.add_argument("--rays-only", action="store_true")
    ap.add_argument("--render-only", action="store_true")
    ap.add_argument("--spp", type=int, help="samples per pixel (default 256)")
    ap.add_argument("--res", type=int, help="image width and height (default 512; --suite: 128)")
    ap.add_argument("--triangles", type=int, default=1_000_000)
    ap.add_argument("--rays", type=int, default=1_000_000)
    ap.add_argument("--cycles", action="store_true",
                    help="also render the Cornell box in Blender Cycles (bpy, installed by bench/compare --cycles)")
    ap.add_argument("--reference-spp", type=int,
                    help="samples of the cached Mitsuba reference image the errors are measured against "
                         "(default 2048, 0: none; --suite: default 16384)")
    ap.add_argument("--suite", action="store_true",
                    help="the benchmark suite instead: trazo against Mitsuba on every scene of bench/suite/ (bench/suite.py)")
    ap.add_argument("--references-only", action="store_true",
                    help="--suite: only render (and cache) the converged references, untimed; no table")
    ap.add_argument("--scenes", help="--suite: only these scenes, comma-separated (names of bench/suite/*.xml)")
    ap.add_argument("--repeat", type=int, help="each time the best of this many runs (default 3; --suite: 1)")
    ap.add_argument("--seeds", type=int,
                    help="--suite: render each scene with this many seeds; errors are their median (default 4)")
    args = ap.parse_args()
    if args.suite:
        import suite

        suite.main(args)
        return
    global REPEAT
    REPEAT = args.repeat or REPEAT
    args.spp = args.spp or 256
    args.res = args.res or 512
    args.reference_spp = 2048 if args.reference_spp is None else args.reference_spp
    print(f"date: {time.strftime('%Y-%m-%d')}, cores: {os.cpu_count()}")
    with tempfile.TemporaryDirectory() as work:
        if not args.render_only:
            ray_section(args, work)
            print()
        if not args.rays_only:
            render_section(args, work)


if __name__ == "__main__":
    main()
