"""trazo from Python against the command line: the same scene, seed and
samples per pixel give the same arrays, bit for bit, as `trazo render`."""

import os
import pathlib
import signal
import subprocess
import threading
import time

import numpy as np
import pytest

import trazo

ROOT = pathlib.Path(__file__).resolve().parents[2]
TRAZO = os.environ.get("TRAZO_BIN", str(ROOT / "target" / "release" / "trazo"))


def cli(tmp_path, *args, name="cli.pfm"):
    out = tmp_path / name
    subprocess.run([TRAZO, "render", *map(str, args), "-q", "-o", str(out)], check=True)
    return out


def test_the_builtin_scene_matches_the_command_line(tmp_path):
    image = trazo.render(trazo.load(), spp=8, width=32, height=24, threads=2)
    assert image.dtype == np.float32 and image.shape == (24, 32, 3)
    assert image.flags["C_CONTIGUOUS"]
    ref = trazo.read(cli(tmp_path, "--spp", 8, "--width", 32, "--height", 24))
    assert np.array_equal(image, ref)
    # One thread or two: the same bits.
    assert np.array_equal(trazo.render(trazo.load(), spp=8, width=32, height=24, threads=1), ref)


def test_a_scene_file_with_overrides_and_aovs_matches_the_command_line(tmp_path):
    scene = ROOT / "scenes" / "materials.toml"
    out = trazo.render(str(scene), spp=4, width=40, height=30, seed=7, max_depth=4,
                       aovs=["albedo", "depth"])
    assert set(out) == {"color", "albedo", "depth"}
    assert out["depth"].shape == (30, 40, 1)
    path = cli(tmp_path, scene, "--spp", 4, "--width", 40, "--height", 30, "--seed", 7,
               "--max-depth", 4, "--aov", "albedo,depth", name="m.exr")
    assert np.array_equal(out["color"], trazo.read(path))
    assert np.array_equal(out["albedo"], trazo.read(tmp_path / "m.albedo.exr"))
    assert np.array_equal(out["depth"][..., 0], trazo.read(tmp_path / "m.depth.exr")[..., 0])
    # Another integrator, chosen by name.
    whitted = trazo.render(trazo.load(scene), spp=1, width=16, height=12, integrator="whitted")
    ref = trazo.read(cli(tmp_path, scene, "--spp", 1, "--width", 16, "--height", 12,
                         "--integrator", "whitted"))
    assert np.array_equal(whitted, ref)


def test_a_dictionary_scene_is_the_same_as_its_toml_file(tmp_path):
    scene = {
        "render": {"width": 24, "height": 16, "spp": 4},
        "camera": {"from": [0.0, 1.0, 4.0], "to": [0, 0.5, 0], "fov": 40},
        "material": [{"name": "red", "diffuse": [0.8, 0.1, 0.1]}],
        "shape": [
            {"type": "sphere", "center": [0, 0.5, 0], "radius": 0.5, "material": "red"},
            {"type": "plane", "point": [0, 0, 0], "normal": [0, 1, 0]},
        ],
        "light": [{"type": "point", "position": [2, 3, 2], "intensity": 20}],
    }
    toml = tmp_path / "s.toml"
    toml.write_text(trazo._to_toml(scene))
    assert np.array_equal(trazo.render(trazo.load(scene)), trazo.read(cli(tmp_path, toml)))


def test_write_and_read_round_trip(tmp_path):
    image = np.random.default_rng(3).random((5, 7, 3), dtype=np.float32)
    trazo.write(tmp_path / "a.exr", image)
    assert np.array_equal(trazo.read(tmp_path / "a.exr"), image)
    trazo.write(tmp_path / "a.png", image, tonemap="aces", exposure=1.0)
    assert trazo.read(tmp_path / "a.png").shape == (5, 7, 3)
    with pytest.raises(trazo.TrazoError, match="H×W×3"):
        trazo.write(tmp_path / "b.exr", np.zeros((4, 4, 2), dtype=np.float32))
    with pytest.raises(trazo.TrazoError, match="b.tiff"):
        trazo.write(tmp_path / "b.tiff", image)


def test_errors_name_the_file_line_and_key(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text('[render]\nwidth = 16\n\n[[shape]]\ntype = "sphere"\nradius = -1\n')
    with pytest.raises(trazo.TrazoError, match=r"bad\.toml:6:\d+: `shape\[0\]\.radius`"):
        trazo.load(bad)
    with pytest.raises(trazo.TrazoError, match="missing.xml"):
        trazo.load(tmp_path / "missing.xml")
    with pytest.raises(trazo.TrazoError, match="unknown integrator \"upbp\""):
        trazo.render(trazo.load(), integrator="upbp", spp=1, width=4, height=4)
    with pytest.raises(trazo.TrazoError, match="spp must be"):
        trazo.render(trazo.load(), spp=0)
    with pytest.raises(trazo.TrazoError, match="finite"):
        trazo.load({"render": {"width": float("nan")}})


def test_progress_is_reported_after_every_pass():
    seen = []
    trazo.render(trazo.load(), spp=20, width=8, height=8, progress=lambda done, total: seen.append((done, total)))
    assert seen[-1] == (20, 20)
    assert [d for d, _ in seen] == sorted(d for d, _ in seen) and len(seen) >= 4

    def fail(done, total):
        raise RuntimeError("stop here")

    with pytest.raises(RuntimeError, match="stop here"):
        trazo.render(trazo.load(), spp=20, width=8, height=8, progress=fail)


def test_ctrl_c_stops_the_render():
    # Python's own handler, which a shell that starts it in the background
    # replaces by "ignore".
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    started = threading.Event()

    def first_pass_done(done, total):
        started.set()

    timer = threading.Thread(target=lambda: started.wait(30) and os.kill(os.getpid(), signal.SIGINT))
    timer.start()
    start = time.monotonic()
    try:
        # About ten seconds of work on one core, were the interrupt ignored.
        with pytest.raises(KeyboardInterrupt):
            trazo.render(trazo.load(), spp=20000, width=32, height=32, threads=1, progress=first_pass_done)
    finally:
        signal.signal(signal.SIGINT, previous)
        timer.join()
    assert time.monotonic() - start < 5
