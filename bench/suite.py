"""The benchmark suite: trazo against Mitsuba 3 on the scenes of bench/suite/
(`bench/compare --suite`; see bench/compare).

For each scene:

- a converged reference, Mitsuba `llvm_ad_rgb` (`scalar_rgb` where no
  libLLVM is found) at --reference-spp, in passes of at most 256 spp with
  their own seeds, averaged; cached in bench/.cache/suite/, keyed by a hash
  of the scene file and every file it names, the resolution and the spp;
- trazo, `trazo render SCENE -o OUT.exr --spp N --width R --height R`, timed
  by its own "rendered ... in X s" line (the render, without loading the
  scene and building the BVH; the process's wall time is recorded too);
- Mitsuba `llvm_ad_rgb` at the same spp, in a child process: the scene
  loaded, a warm-up render of the pass size (JIT compilation), then the timed
  passes (at most 256 spp each, their own seeds, summed), the timed region
  ending when each pass has been converted to a NumPy array (Dr.Jit's kernels
  run asynchronously);
- each renderer rendering the scene with --seeds seeds (default 4), each
  --repeat times, the renderers taking turns; its time is the best of these
  runs;
- errors: relative MSE against the reference, the formula of `trazo diff`
  (src/film/metrics.rs: the mean over pixels and channels of
  (a - b)^2 / (b^2 + 0.01)), computed here at full precision because `trazo
  diff` prints six decimals (its figure is kept in the JSON beside ours),
  the median over the seeds: on scenes whose error comes from rare bright
  paths (caustics, small lights, media) one seed's error varies by 2x from
  seed to seed and now and then by 50x (one firefly), so that a single seed,
  or the mean of a few, can decide the comparison either way;
- the time at equal error, (t_trazo * err_trazo) / (t_mitsuba * err_mitsuba):
  the ratio of the times the two would take to reach the same error, as the
  error of an unbiased renderer falls as 1 / time. Below 1: trazo is faster.

The table goes to stdout and, with the raw figures as JSON, to
bench/results/<date>/suite-<commit>.{md,json}.
"""
import datetime
import glob
import hashlib
import json
import math
import os
import platform
import re
import subprocess
import sys
import tempfile
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
SUITE = os.path.join(HERE, "suite")
CACHE = os.path.join(HERE, ".cache", "suite")

# The most samples per pixel of one Mitsuba render call: llvm_ad_rgb renders
# a whole pass as one wavefront, which thousands of spp would not fit.
MAX_PASS = 256

# The scenes in the order of the table; other files in bench/suite/ follow
# in alphabetical order.
ORDER = [
    "cornell-box", "conductors", "dielectrics", "plastic", "textured", "sky-sun", "mesh-instances",
    "many-lights", "smallpt-explicit", "caustic", "furnace-diffuse", "furnace-glass", "media-fog",
    "media-smoke",
]

# Seeds: the timed Mitsuba passes of seed k use k * SEED_STRIDE, +1, ...
# (trazo takes `--seed k`); the warm-up and the
# reference their own ranges, so that no timed image shares samples with
# the reference it is measured against.
WARMUP_SEED = 1_000_000
REFERENCE_SEED = 2_000_000
SEED_STRIDE = 1_000

REL_MSE_EPSILON = 1e-2  # as src/film/metrics.rs


def scene_names():
    names = [os.path.basename(p)[:-4] for p in glob.glob(os.path.join(SUITE, "*.xml"))]
    return [n for n in ORDER if n in names] + sorted(n for n in names if n not in ORDER)


def scene_hash(path, seen=None):
    """SHA-256 of a scene file and, recursively, of every file it names in a
    `filename` attribute (includes, textures, meshes), so that a cached
    reference is redone when any of them changes."""
    seen = set() if seen is None else seen
    h = hashlib.sha256()
    path = os.path.realpath(path)
    seen.add(path)
    with open(path, "rb") as f:
        data = f.read()
    h.update(data)
    if path.endswith(".xml"):
        for name in re.findall(rb'filename"\s+value="([^"]+)"', data) + re.findall(rb'<include\s+filename="([^"]+)"', data):
            other = os.path.realpath(os.path.join(os.path.dirname(path), name.decode()))
            h.update(name)
            if os.path.isfile(other) and other not in seen:
                h.update(scene_hash(other, seen).encode())
    return h.hexdigest()


def pass_sizes(spp):
    """The spp of each Mitsuba render call: as many of MAX_PASS as fit, then the rest."""
    sizes = [MAX_PASS] * (spp // MAX_PASS)
    if spp % MAX_PASS:
        sizes.append(spp % MAX_PASS)
    return sizes


def read_exr(path):
    import mitsuba as mi  # Bitmap needs no variant

    return np.array(mi.Bitmap(path), dtype=np.float64)[..., :3]


def write_exr(path, image):
    import mitsuba as mi

    tmp = path + ".tmp.exr"
    mi.Bitmap(np.ascontiguousarray(image, dtype=np.float32)).write(tmp)
    os.replace(tmp, path)


def relative_mse(a, b):
    return float(np.mean((a - b) ** 2 / (b * b + REL_MSE_EPSILON)))


# --- the Mitsuba side, in a child process -------------------------------


def worker(spec):
    """Renders in this process (run as `suite.py --worker SPEC.json`).
    mode "time": a warm-up render of each pass size, then the timed passes;
    mode "reference": the passes, averaged, and the averages of the even and
    of the odd passes (whose difference measures the reference's noise)."""
    import mitsuba as mi

    mi.set_variant(spec["variant"])
    sizes = pass_sizes(spec["spp"])
    start = time.perf_counter()
    scene = mi.load_file(spec["scene"], res=str(spec["res"]), spp=str(sizes[0]))
    result = {"load_s": time.perf_counter() - start, "passes": sizes, "mitsuba": mi.__version__}
    if spec["mode"] == "time":
        start = time.perf_counter()
        for k, size in enumerate(sorted(set(sizes))):
            np.array(mi.render(scene, spp=size, seed=WARMUP_SEED + k))
        result["warmup_s"] = time.perf_counter() - start
        acc = None
        start = time.perf_counter()
        for i, size in enumerate(sizes):
            img = np.array(mi.render(scene, spp=size, seed=spec["seed"] + i), dtype=np.float64) * size
            acc = img if acc is None else acc + img
        result["render_s"] = time.perf_counter() - start
        write_exr(spec["out"], acc / spec["spp"])
    else:
        halves = [None, None]
        weights = [0, 0]
        start = time.perf_counter()
        for i, size in enumerate(sizes):
            img = np.array(mi.render(scene, spp=size, seed=spec["seed"] + i), dtype=np.float64) * size
            halves[i % 2] = img if halves[i % 2] is None else halves[i % 2] + img
            weights[i % 2] += size
            if (i + 1) % 8 == 0 or i + 1 == len(sizes):
                elapsed = time.perf_counter() - start
                print(f"  {os.path.basename(spec['scene'])}: pass {i + 1}/{len(sizes)}, {elapsed:.0f} s, "
                      f"about {elapsed / (i + 1) * (len(sizes) - i - 1):.0f} s to go", file=sys.stderr, flush=True)
        result["render_s"] = time.perf_counter() - start
        write_exr(spec["out"], sum(h for h in halves if h is not None) / spec["spp"])
        if weights[1]:
            write_exr(spec["out_even"], halves[0] / weights[0])
            write_exr(spec["out_odd"], halves[1] / weights[1])
    with open(spec["result"], "w") as f:
        json.dump(result, f)


def mitsuba_env(variant):
    from compare import find_libllvm

    env = dict(os.environ)
    if variant.startswith("llvm"):
        lib = find_libllvm()
        if not lib:
            return None
        env["DRJIT_LIBLLVM_PATH"] = lib
    return env


def run_worker(spec, work, log_to_stderr=False):
    """(the worker's result, the command) or (None, why)."""
    env = mitsuba_env(spec["variant"])
    if env is None:
        return None, "no libLLVM 16 or later found (apt-get install libllvm19, or set DRJIT_LIBLLVM_PATH)"
    fd, spec_path = tempfile.mkstemp(suffix=".json", dir=work)
    spec = dict(spec, result=spec_path + ".result")
    with os.fdopen(fd, "w") as f:
        json.dump(spec, f)
    cmd = [sys.executable, os.path.abspath(__file__), "--worker", spec_path]
    if log_to_stderr:
        r = subprocess.run(cmd, stdout=sys.stderr, env=env)
        tail = ""
    else:
        r = subprocess.run(cmd, capture_output=True, text=True, env=env)
        tail = (r.stdout + r.stderr).strip().splitlines()
        tail = tail[-1] if tail else "failed"
    if r.returncode != 0 or not os.path.exists(spec["result"]):
        return None, f"exit status {r.returncode}: {tail or 'see above'}"
    with open(spec["result"]) as f:
        result = json.load(f)
    result["command"] = cmd
    result["spec"] = {k: v for k, v in spec.items() if k != "result"}
    if "DRJIT_LIBLLVM_PATH" in env:
        result["DRJIT_LIBLLVM_PATH"] = env["DRJIT_LIBLLVM_PATH"]
    return result, None


def reference(args, name, path, variants, work):
    """The cached reference of a scene (rendering it first if need be):
    (EXR path, its record) or (None, why)."""
    os.makedirs(CACHE, exist_ok=True)
    key = f"{name}-{scene_hash(path)[:16]}-{args.res}px-{args.reference_spp}spp"
    out = os.path.join(CACHE, key + ".exr")
    record_path = os.path.join(CACHE, key + ".json")
    if os.path.exists(out) and os.path.exists(record_path):
        with open(record_path) as f:
            record = json.load(f)
        record["cached"] = True
        return out, record
    why = None
    for variant in variants:
        print(f"{name}: rendering the reference, Mitsuba {variant}, {args.reference_spp} spp at {args.res}×{args.res} "
              f"(once; cached in {os.path.relpath(CACHE, args.root)})...", file=sys.stderr, flush=True)
        spec = {"mode": "reference", "variant": variant, "scene": path, "res": args.res, "spp": args.reference_spp,
                "seed": REFERENCE_SEED, "out": out, "out_even": os.path.join(CACHE, key + ".even.exr"),
                "out_odd": os.path.join(CACHE, key + ".odd.exr")}
        result, why = run_worker(spec, work, log_to_stderr=True)
        if result is None:
            print(f"{name}: Mitsuba {variant} failed: {why}", file=sys.stderr)
            continue
        ref = read_exr(out)
        if not np.all(np.isfinite(ref)):
            why = f"Mitsuba {variant}'s reference has non-finite pixels"
            os.remove(out)
            continue
        record = {"variant": variant, "spp": args.reference_spp, "res": args.res, "passes": len(result["passes"]),
                  "seed": REFERENCE_SEED, "render_s": result["render_s"], "mitsuba": result["mitsuba"],
                  "scene_sha256": scene_hash(path), "command": result["command"], "spec": result["spec"],
                  "date": time.strftime("%Y-%m-%d %H:%M:%S")}
        if os.path.exists(spec["out_odd"]):
            # Each half has twice the variance of the whole: a quarter of
            # their relative MSE is the reference's own (about).
            record["noise_relmse"] = relative_mse(read_exr(spec["out_even"]), read_exr(spec["out_odd"])) / 4
        with open(record_path, "w") as f:
            json.dump(record, f, indent=1)
        record["cached"] = False
        return out, record
    return None, why


# --- trazo ---------------------------------------------------------------


def trazo_run(args, path, out, seed):
    cmd = [args.trazo, "render", path, "-o", out, "--spp", str(args.spp), "--width", str(args.res),
           "--height", str(args.res), "--seed", str(seed)]
    start = time.perf_counter()
    r = subprocess.run(cmd, capture_output=True, text=True)
    wall = time.perf_counter() - start
    if r.returncode != 0:
        return None, (r.stderr.strip().splitlines() or ["failed"])[-1]
    m = re.search(r"rendered .*? in ([0-9.]+) s", r.stderr)
    if not m:
        return None, "no 'rendered ... in X s' line on stderr"
    warnings = [line[len("warning: "):] for line in r.stderr.splitlines() if line.startswith("warning: ")]
    return {"render_s": float(m.group(1)), "wall_s": wall, "warnings": warnings, "command": cmd}, None


def trazo_diff(args, image, ref):
    """`trazo diff`'s relative MSE and the two means it prints."""
    r = subprocess.run([args.trazo, "diff", image, ref], capture_output=True, text=True)
    rel = re.search(r"relative MSE: ([0-9.eE+-]+)", r.stdout)
    means = re.findall(r"mean R G B: ([0-9.eE+-]+) ([0-9.eE+-]+) ([0-9.eE+-]+)", r.stdout)
    return {"relmse": float(rel.group(1)) if rel else None,
            "mean": [float(x) for x in means[0]] if means else None,
            "reference_mean": [float(x) for x in means[1]] if len(means) > 1 else None}


def git(args, *cmd):
    r = subprocess.run(["git", "-C", args.root, *cmd], capture_output=True, text=True)
    return r.stdout.strip() if r.returncode == 0 else None


def fmt_t(t):
    return f"{t:.3g} s" if t is not None else "–"


def fmt_e(e):
    return f"{e:.3e}" if e is not None else "–"


def geomean(xs):
    return math.exp(sum(math.log(x) for x in xs) / len(xs)) if xs else None


def main(args):
    import suite_assets

    suite_assets.generate()
    args.res = args.res or 128
    args.spp = args.spp or 256
    args.reference_spp = args.reference_spp or 16384
    args.repeat = args.repeat or 1
    args.seeds = args.seeds or 4
    if args.seeds > 100:
        raise SystemExit("bench/compare --suite: --seeds is at most 100")
    names = scene_names()
    if args.scenes:
        wanted = [s.strip().removesuffix(".xml") for s in args.scenes.split(",") if s.strip()]
        unknown = [s for s in wanted if s not in names]
        if unknown:
            raise SystemExit(f"bench/compare --suite: no scene {', '.join(unknown)} in bench/suite/ (there are: {', '.join(names)})")
        names = wanted
    variants = ["llvm_ad_rgb", "scalar_rgb"] if mitsuba_env("llvm_ad_rgb") is not None else ["scalar_rgb"]
    timed_variant = variants[0]
    commit = git(args, "rev-parse", "HEAD") or "unknown"
    dirty = bool(git(args, "status", "--porcelain", "--", "src", "Cargo.toml", "Cargo.lock"))
    short = (commit[:7] if commit != "unknown" else commit) + ("-dirty" if dirty else "")
    import mitsuba

    date = time.strftime("%Y-%m-%d")
    report = {
        "date": time.strftime("%Y-%m-%d %H:%M:%S"),
        "trazo": {"binary": args.trazo, "commit": commit, "dirty": dirty},
        "mitsuba": {"version": mitsuba.__version__, "timed_variant": timed_variant},
        "machine": {"cores": os.cpu_count(), "platform": platform.platform(), "python": platform.python_version()},
        "settings": {"res": args.res, "spp": args.spp, "reference_spp": args.reference_spp, "repeat": args.repeat,
                     "seeds": args.seeds,
                     "max_pass_spp": MAX_PASS, "trazo_time": "the render time trazo prints (without scene loading and BVH build)",
                     "mitsuba_time": "load_file excluded; after a warm-up render of each pass size; timed passes including conversion to NumPy"},
        "scenes": [],
    }
    with tempfile.TemporaryDirectory() as work:
        for name in names:
            path = os.path.join(SUITE, name + ".xml")
            entry = {"name": name, "file": os.path.relpath(path, args.root), "sha256": scene_hash(path)}
            report["scenes"].append(entry)
            ref, record = reference(args, name, path, variants, work)
            if ref is None:
                entry["failed"] = f"no reference: {record}"
                print(f"{name}: no reference ({record})", file=sys.stderr)
                continue
            entry["reference"] = dict(record, path=os.path.relpath(ref, args.root))
            if args.references_only:
                continue
            print(f"{name}: timing trazo and Mitsuba {timed_variant}, {args.spp} spp, {args.seeds} seeds, "
                  f"best of {args.seeds * args.repeat}...", file=sys.stderr, flush=True)
            t_runs, m_runs = [], []
            t_fail = m_fail = None
            t_images, m_images = {}, {}
            for seed in range(args.seeds):
                t_out = os.path.join(work, f"{name}.trazo.{seed}.exr")
                m_out = os.path.join(work, f"{name}.{timed_variant}.{seed}.exr")
                for _ in range(args.repeat):
                    if t_fail is None:
                        run, t_fail = trazo_run(args, path, t_out, seed)
                        if run:
                            t_runs.append(dict(run, seed=seed))
                            t_images[seed] = t_out
                    if m_fail is None:
                        spec = {"mode": "time", "variant": timed_variant, "scene": path, "res": args.res,
                                "spp": args.spp, "seed": seed * SEED_STRIDE, "out": m_out}
                        run, m_fail = run_worker(spec, work)
                        if run:
                            m_runs.append(dict(run, seed=seed))
                            m_images[seed] = m_out
            reference_image = read_exr(ref)
            for key, runs, fail, images in [
                ("trazo", t_runs, t_fail, t_images),
                ("mitsuba", m_runs, m_fail, m_images),
            ]:
                side = {"runs": runs}
                if fail or not runs:
                    side["failed"] = fail
                else:
                    side["best_s"] = min(r["render_s"] for r in runs)
                    per_seed = []
                    for seed in sorted(images):
                        img = read_exr(images[seed])
                        per_seed.append(relative_mse(img, reference_image))
                        if seed == 0:
                            side["trazo_diff"] = trazo_diff(args, images[seed], ref)
                            side["mean"] = img.reshape(-1, 3).mean(0).tolist()
                            side["reference_mean"] = reference_image.reshape(-1, 3).mean(0).tolist()
                        if not np.all(np.isfinite(img)):
                            side["non_finite_pixels"] = side.get("non_finite_pixels", 0) + int(np.sum(~np.isfinite(img)))
                    side["relmse_per_seed"] = per_seed
                    side["relmse"] = float(np.median(per_seed))
                    side["relmse_mean"] = float(np.mean(per_seed))
                entry[key] = side
            entry["warnings"] = t_runs[0]["warnings"] if t_runs else []
            t, m = entry["trazo"], entry["mitsuba"]
            if "best_s" in t and "best_s" in m and t["relmse"] > 0 and m["relmse"] > 0 and m["best_s"] > 0:
                entry["equal_error_ratio"] = (t["best_s"] * t["relmse"]) / (m["best_s"] * m["relmse"])
            print(f"{name}: trazo {fmt_t(t.get('best_s'))}, error {fmt_e(t.get('relmse'))}; "
                  f"Mitsuba {fmt_t(m.get('best_s'))}, error {fmt_e(m.get('relmse'))}", file=sys.stderr, flush=True)

    if args.references_only:
        print("references rendered and cached in bench/.cache/suite", file=sys.stderr)
        return
    lines = table(args, report, timed_variant)
    print("\n".join(lines))
    out_dir = os.path.join(args.root, "bench", "results", date)
    os.makedirs(out_dir, exist_ok=True)
    # A binary other than the work tree's own build is named in the file
    # name (the commit is the work tree's, not necessarily the binary's),
    # and a second run of the same day and commit does not overwrite the
    # first.
    own = os.path.realpath(os.path.join(args.root, "target", "release", "trazo"))
    label = "" if os.path.realpath(args.trazo) == own else "-" + re.sub(r"[^A-Za-z0-9_.-]", "_", os.path.basename(args.trazo))
    stem = os.path.join(out_dir, f"suite-{short}{label}")
    run = 2
    while os.path.exists(stem + ".json"):
        stem = os.path.join(out_dir, f"suite-{short}{label}-run{run}")
        run += 1
    with open(stem + ".json", "w") as f:
        json.dump(report, f, indent=1)
        f.write("\n")
    with open(stem + ".md", "w") as f:
        f.write("\n".join(lines) + "\n")
    print(f"\nwritten: {os.path.relpath(stem, args.root)}.md, .json")


def uncertainty(t, m, ratio):
    """' ± x': the standard error of the time at equal error from the
    spread of both renderers' per-seed errors (times taken as exact), by
    resampling the seeds (bootstrap, a fixed generator); '' with fewer
    than three seeds."""
    a = np.array(t.get("relmse_per_seed", []))
    b = np.array(m.get("relmse_per_seed", []))
    if len(a) < 3 or len(b) < 3:
        return ""
    rng = np.random.default_rng(1)
    draws = [np.median(rng.choice(a, len(a))) / np.median(rng.choice(b, len(b))) for _ in range(1000)]
    return f" ± {ratio * np.std(draws) / (np.median(a) / np.median(b)):.2f}"


def table(args, report, variant):
    s = report["settings"]
    tr = report["trazo"]
    lines = [
        f"# trazo against Mitsuba 3 on bench/suite/, {report['date']}",
        "",
        f"trazo {tr['commit'][:10]}{' (sources differ from it)' if tr['dirty'] else ''}; Mitsuba "
        f"{report['mitsuba']['version']} `{variant}`; {report['machine']['cores']} cores; "
        f"{s['res']}×{s['res']} pixels, {s['spp']} spp; each renderer {s.get('seeds', 1)} seeds × {s['repeat']} runs, taking turns; "
        f"time: the best run; error: the median over the seeds.",
        "",
        f"Times: trazo's own render time (scene loading and BVH build not counted); Mitsuba's renders after "
        f"loading the scene and a warm-up render, in passes of at most {MAX_PASS} spp, each converted to a NumPy "
        f"array inside the timed region. Error: relative MSE (the formula of `trazo diff`) against Mitsuba at "
        f"{s['reference_spp']} spp (reference noise: its own relative MSE, from its two halves). Equal error: "
        f"(t_trazo · err_trazo) / (t_Mitsuba · err_Mitsuba), the ratio of the times to reach the same error; "
        f"below 1, trazo is faster; ± is its standard error from the spread of the errors over the seeds. "
        f"Mean: seed 0's image's mean over channels against the reference's.",
        "",
        "| scene | trazo time | Mitsuba time | trazo rel. MSE | Mitsuba rel. MSE | reference noise | trazo mean / ref. | Mitsuba mean / ref. | time at equal error, trazo / Mitsuba |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    ratios, clean = [], []
    notes = []
    for e in report["scenes"]:
        if "failed" in e:
            lines.append(f"| {e['name']} | {e['failed']} | | | | | | | |")
            continue
        t, m = e["trazo"], e["mitsuba"]
        noise = e["reference"].get("noise_relmse")

        def mean_ratio(side):
            if "mean" not in side:
                return "–"
            return f"{np.mean(side['mean']) / max(np.mean(side['reference_mean']), 1e-30):.4f}"

        ratio = e.get("equal_error_ratio")
        mark = " ¹" if e["warnings"] else ""
        cells = [
            e["name"] + mark,
            fmt_t(t.get("best_s")) if "failed" not in t else f"failed: {t['failed']}",
            fmt_t(m.get("best_s")) if "failed" not in m else f"failed: {m['failed']}",
            fmt_e(t.get("relmse")), fmt_e(m.get("relmse")), fmt_e(noise), mean_ratio(t), mean_ratio(m),
            (f"{ratio:.3f}" + uncertainty(t, m, ratio)) if ratio is not None else "–",
        ]
        lines.append("| " + " | ".join(cells) + " |")
        if ratio is not None:
            ratios.append((ratio, e["name"]))
            if not e["warnings"]:
                clean.append((ratio, e["name"]))
        if e["warnings"]:
            notes.append((e["name"], e["warnings"]))
    lines.append("")
    if ratios:
        worst = max(ratios)
        lines.append(f"Time at equal error, trazo / Mitsuba: geometric mean {geomean([r for r, _ in ratios]):.3f} "
                     f"over {len(ratios)} scenes, maximum {worst[0]:.3f} ({worst[1]}).")
        if notes and clean:
            worst = max(clean)
            lines.append(f"Without the scenes trazo warned on: geometric mean {geomean([r for r, _ in clean]):.3f} "
                         f"over {len(clean)} scenes, maximum {worst[0]:.3f} ({worst[1]}).")
    if notes:
        lines.append("")
        lines.append("¹ trazo warned (it rendered a different scene from Mitsuba's):")
        for name, warnings in notes:
            shown = warnings[:3] + ([f"… and {len(warnings) - 3} more"] if len(warnings) > 3 else [])
            lines.append(f"- {name}: " + "; ".join(shown))
    return lines


if __name__ == "__main__":
    if len(sys.argv) == 3 and sys.argv[1] == "--worker":
        with open(sys.argv[2]) as f:
            worker(json.load(f))
    else:
        raise SystemExit("run through bench/compare --suite")
