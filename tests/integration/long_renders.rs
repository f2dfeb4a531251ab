//! Long renders through the command line: Ctrl-C and SIGTERM, checkpoints,
//! `--resume`, `--time-limit`, `kill -9` during writes, and the memory
//! limit. Signals are sent with the system's `kill`, so most tests are
//! Unix-only.

use assert_cmd::Command;
use std::path::{Path, PathBuf};
use std::process::{Child, Stdio};
use std::time::{Duration, Instant};
use trazo::render::checkpoint::Checkpoint;

fn trazo() -> Command {
    Command::cargo_bin("trazo").unwrap()
}

fn trazo_bin() -> PathBuf {
    assert_cmd::cargo::cargo_bin("trazo")
}

fn spawn(args: &[&str]) -> Child {
    std::process::Command::new(trazo_bin())
        .args(args)
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap()
}

#[cfg(unix)]
fn signal(child: &Child, sig: &str) {
    let status = std::process::Command::new("kill")
        .args([sig, &child.id().to_string()])
        .status()
        .unwrap();
    assert!(status.success());
}

/// Waits for `path` to exist (the first checkpoint: one pass is done).
fn wait_for(path: &Path, child: &mut Child) {
    let start = Instant::now();
    while !path.exists() {
        assert!(
            child.try_wait().unwrap().is_none(),
            "trazo ended before writing {}",
            path.display()
        );
        assert!(
            start.elapsed() < Duration::from_secs(60),
            "no {} after 60 s",
            path.display()
        );
        std::thread::sleep(Duration::from_millis(2));
    }
}

/// Waits for the child to end; returns its status code and stderr.
fn finish(mut child: Child, within: Duration) -> (Option<i32>, String) {
    let start = Instant::now();
    loop {
        if let Some(status) = child.try_wait().unwrap() {
            let mut err = String::new();
            use std::io::Read;
            child.stderr.take().unwrap().read_to_string(&mut err).unwrap();
            assert!(!err.contains("panicked"), "{err}");
            return (status.code(), err);
        }
        if start.elapsed() > within {
            let _ = child.kill();
            panic!("trazo did not end within {within:?}");
        }
        std::thread::sleep(Duration::from_millis(5));
    }
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// Ctrl-C: within seconds, the image of the passes done, a checkpoint that
/// holds the same film, and exit status 130; `--resume` then finishes with
/// the same image, bit for bit, as a render that was never interrupted, and
/// removes the checkpoint.
#[cfg(unix)]
#[test]
fn ctrl_c_keeps_the_passes_done_and_resume_finishes_them_identically() {
    let dir = tempfile::tempdir().unwrap();
    let full = dir.path().join("full.pfm");
    let common = ["--width", "64", "--height", "48", "--spp", "256", "--seed", "7", "-q"];
    let out = trazo().args(["render", "-o", s(&full)]).args(common).output().unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));

    let part = dir.path().join("part.pfm");
    let checkpoint = dir.path().join("part.pfm.trazo-checkpoint");
    let mut child = spawn(&[&["render", "-o", s(&part), "--checkpoint-every", "0"], &common[..]].concat());
    wait_for(&checkpoint, &mut child);
    let sent = Instant::now();
    signal(&child, "-INT");
    let (code, err) = finish(child, Duration::from_secs(20));
    assert!(sent.elapsed() < Duration::from_secs(5), "took {:?}", sent.elapsed());
    assert_eq!(code, Some(130), "{err}");
    let c = Checkpoint::read(&checkpoint).unwrap();
    let spp = c.stats.spp;
    assert!((1..256).contains(&spp), "{spp}");
    assert!(
        err.contains(&format!("interrupted: rendered 64×48 at {spp} of 256 spp")),
        "{err}"
    );
    assert!(err.contains("--resume"), "{err}");
    // The image is the checkpoint's film.
    let img = trazo::film::io::read_image(&part).unwrap();
    assert_eq!(img, c.film.to_image());
    assert!(c.job_values("arg").any(|a| a == "--seed=7"), "{:?}", c.job);

    // Resume (only run-control flags may be given) → identical to `full`.
    resume_matches_uninterrupted(&checkpoint, &part, &full, "rendered 64×48 at 256 spp");
}

/// The same for Metropolis light transport, whose state is its chains,
/// BDPT, whose state is its sums, and SPPM, whose state is every pixel's
/// statistics: Ctrl-C keeps the iterations done and `--resume` finishes
/// them identically; a shard is refused.
#[cfg(unix)]
#[test]
fn ctrl_c_and_resume_work_for_progressive_renders() {
    let dir = tempfile::tempdir().unwrap();
    for integrator in ["mlt", "bdpt", "sppm", "vcm"] {
        let full = dir.path().join(format!("{integrator}-full.pfm"));
        let common = [
            "--width",
            "64",
            "--height",
            "48",
            "--spp",
            "400",
            "--seed",
            "3",
            "-q",
            "--integrator",
            integrator,
        ];
        let out = trazo().args(["render", "-o", s(&full)]).args(common).output().unwrap();
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
        let part = dir.path().join(format!("{integrator}-part.pfm"));
        let checkpoint = dir.path().join(format!("{integrator}-part.pfm.trazo-checkpoint"));
        let mut child = spawn(&[&["render", "-o", s(&part), "--checkpoint-every", "0"], &common[..]].concat());
        wait_for(&checkpoint, &mut child);
        signal(&child, "-INT");
        let (code, err) = finish(child, Duration::from_secs(20));
        assert_eq!(code, Some(130), "{err}");
        let c = Checkpoint::read(&checkpoint).unwrap();
        assert!(
            (1..400).contains(&c.stats.spp) && !c.state.is_empty(),
            "{}",
            c.stats.spp
        );
        resume_matches_uninterrupted(&checkpoint, &part, &full, "rendered 64×48 at 400 spp");
        let o = trazo()
            .args([
                "render",
                "-o",
                s(&dir.path().join("shard.trazo-part")),
                "--shard",
                "1/2",
            ])
            .args(common)
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{err}");
        assert!(err.contains("cannot be sharded"), "{err}");
    }
}

/// Resumes from `checkpoint` (writing `part`), expects `finished` in the
/// report, an image byte-identical to the uninterrupted render `full`, and
/// the checkpoint removed.
fn resume_matches_uninterrupted(checkpoint: &Path, part: &Path, full: &Path, finished: &str) {
    let out = trazo()
        .args(["render", "--resume", s(checkpoint), "--threads", "1"])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    assert!(err.contains(finished), "{err}");
    assert_eq!(std::fs::read(part).unwrap(), std::fs::read(full).unwrap());
    assert!(!checkpoint.exists(), "the stale checkpoint is removed");
}

/// SIGTERM is handled like Ctrl-C; a second signal ends trazo at once with
/// status 131, writing nothing.
#[cfg(unix)]
#[test]
fn sigterm_stops_gracefully_and_a_second_signal_aborts() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("t.png");
    let checkpoint = dir.path().join("t.png.trazo-checkpoint");
    let args = [
        "render",
        "-o",
        s(&out),
        "--width",
        "96",
        "--height",
        "96",
        "--spp",
        "100000",
    ];
    let mut child = spawn(&[&args[..], &["--checkpoint-every", "0"]].concat());
    wait_for(&checkpoint, &mut child);
    signal(&child, "-TERM");
    let (code, err) = finish(child, Duration::from_secs(20));
    assert_eq!(code, Some(130), "{err}");
    assert!(out.exists());

    // A second signal while the first is being handled (here: while the
    // large image is encoded) ends the process at once.
    let out2 = dir.path().join("u.png");
    let checkpoint2 = dir.path().join("u.png.trazo-checkpoint");
    let args = [
        "render",
        "-o",
        s(&out2),
        "--integrator",
        "whitted",
        "--width",
        "1536",
        "--height",
        "1536",
        "--spp",
        "100000",
        "--checkpoint-every",
        "0",
    ];
    let mut child = spawn(&args);
    wait_for(&checkpoint2, &mut child);
    let pid = child.id().to_string();
    // Signals of one kind are not queued: two sent while the process waits
    // for a core (the suite runs tests side by side) arrive as one. So
    // keep signalling every 5 ms; the second one delivered aborts.
    let status = std::process::Command::new("sh")
        .args([
            "-c",
            &format!("for i in $(seq 20); do kill -INT {pid} 2>/dev/null || exit 0; sleep 0.005; done"),
        ])
        .status()
        .unwrap();
    assert!(status.success());
    let (code, err) = finish(child, Duration::from_secs(20));
    assert_eq!(code, Some(131), "{err}");
    assert!(!out2.exists(), "no image is written after a second signal");
    assert_eq!(
        temporary_files(dir.path()),
        Vec::<String>::new(),
        "nor is a temporary file left"
    );
}

/// The hidden temporary files (`.NAME.PID.tmp.EXT`) in `dir`.
fn temporary_files(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().into_string().unwrap())
        .filter(|n| n.starts_with('.') && n.contains(".tmp."))
        .collect();
    v.sort();
    v
}

/// A new render to an output whose checkpoint holds an unfinished render
/// refuses before it loads or writes anything (status 2, one line that
/// says how to continue or restart), leaving checkpoint and image as they
/// were; `--restart` renders afresh and removes the checkpoint.
#[test]
fn a_new_render_never_deletes_an_unfinished_one() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("w.pfm");
    let checkpoint = dir.path().join("w.pfm.trazo-checkpoint");
    let common = ["--width", "16", "--height", "16", "-o", s(&out), "-q"];
    trazo()
        .args(["render", "--spp", "64", "--time-limit", "0"])
        .args(common)
        .assert()
        .success();
    let (image, saved) = (std::fs::read(&out).unwrap(), std::fs::read(&checkpoint).unwrap());
    let o = trazo().args(["render", "--spp", "4"]).args(common).output().unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert_eq!(err.lines().count(), 1, "{err}");
    assert!(
        err.contains("holds an unfinished render") && err.contains("--resume") && err.contains("--restart"),
        "{err}"
    );
    assert_eq!(std::fs::read(&out).unwrap(), image);
    assert_eq!(std::fs::read(&checkpoint).unwrap(), saved);

    let o = trazo()
        .args(["render", "--spp", "4", "--restart"])
        .args(common)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(!checkpoint.exists());
    assert_ne!(std::fs::read(&out).unwrap(), image);
    // --restart is a new render's flag, not a resume's.
    let o = trazo()
        .args(["render", "--resume", s(&checkpoint), "--restart"])
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(2));
}

/// A time-limited render without --spp resumes for the same time again and
/// ends; with a scene file that states its samples per pixel, the time
/// limit only caps them.
#[test]
fn time_limited_renders_resume_and_end() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("t.pfm");
    let checkpoint = dir.path().join("t.pfm.trazo-checkpoint");
    let o = trazo()
        .args([
            "render",
            "--width",
            "32",
            "--height",
            "32",
            "--time-limit",
            "0.5",
            "-o",
            s(&out),
        ])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success() && err.contains("time limit reached"), "{err}");
    let first = Checkpoint::read(&checkpoint).unwrap().stats.spp;
    let start = Instant::now();
    let o = trazo()
        .args(["render", "--resume", s(&checkpoint)])
        .timeout(Duration::from_secs(60))
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success() && err.contains("time limit reached"), "{err}");
    assert!(start.elapsed() < Duration::from_secs(30), "{:?}", start.elapsed());
    assert!(Checkpoint::read(&checkpoint).unwrap().stats.spp > first);

    let scene = dir.path().join("s.toml");
    std::fs::write(
        &scene,
        "[render]\nwidth = 8\nheight = 8\nspp = 3\n\n[[shape]]\ntype = \"sphere\"\ncenter = [0, 0, 0]\nradius = 1\n",
    )
    .unwrap();
    let o = trazo()
        .args([
            "render",
            s(&scene),
            "--time-limit",
            "600",
            "-o",
            s(&dir.path().join("s.pfm")),
        ])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success() && err.contains("rendered 8×8 at 3 spp"), "{err}");
}

/// `--time-limit`: stops on time with the image of whole passes (as many
/// samples as the time allowed) and a checkpoint to continue from.
#[test]
fn a_time_limit_writes_whole_passes_on_time() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("t.exr");
    let start = Instant::now();
    let o = trazo()
        .args([
            "render",
            "-o",
            s(&out),
            "--width",
            "64",
            "--height",
            "64",
            "--time-limit",
            "1.5",
        ])
        .output()
        .unwrap();
    let took = start.elapsed();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    assert!(took < Duration::from_secs(8), "{took:?}");
    assert!(err.contains("time limit reached: rendered 64×64 at "), "{err}");
    let c = Checkpoint::read(&dir.path().join("t.exr.trazo-checkpoint")).unwrap();
    assert!(c.stats.spp >= 1);
    assert!(c.film.pixels.iter().all(|p| p.sum().weight == c.stats.spp as f64));
    assert!(err.contains(&format!("at {} spp", c.stats.spp)), "{err}");
    // A render that finishes within its time limit is simply complete.
    let out2 = dir.path().join("u.png");
    let o = trazo()
        .args([
            "render",
            "-o",
            s(&out2),
            "--width",
            "16",
            "--height",
            "16",
            "--spp",
            "4",
        ])
        .args(["--time-limit", "600"])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success() && err.contains("at 4 spp"), "{err}");
    assert!(!dir.path().join("u.png.trazo-checkpoint").exists());
}

/// `kill -9` at any moment, even in the middle of writing a checkpoint,
/// leaves a whole checkpoint (or none) and the old image untouched: never a
/// truncated file.
#[cfg(unix)]
#[test]
fn kill_9_during_writes_leaves_whole_files() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("big.pfm");
    let checkpoint = dir.path().join("big.pfm.trazo-checkpoint");
    // An old image that must survive.
    trazo()
        .args([
            "render",
            "-o",
            s(&out),
            "--width",
            "8",
            "--height",
            "8",
            "--spp",
            "1",
            "-q",
        ])
        .assert()
        .success();
    let old = std::fs::read(&out).unwrap();
    // Whitted at 1 spp per pass on a large film: most of the time goes to
    // writing the 40 MB checkpoint after each pass.
    let args = [
        "render",
        "-o",
        s(&out),
        "--integrator",
        "whitted",
        "--width",
        "1024",
        "--height",
        "1024",
        "--spp",
        "100000",
        "--checkpoint-every",
        "0",
        // Each run replaces the checkpoint the one before left.
        "--restart",
        "-q",
    ];
    let mut kills = 0;
    for delay_ms in [150u64, 500, 900, 1400, 3000] {
        let mut child = spawn(&args);
        std::thread::sleep(Duration::from_millis(delay_ms));
        let _ = child.kill(); // SIGKILL
        let _ = child.wait();
        kills += 1;
        if checkpoint.exists() {
            let c = Checkpoint::read(&checkpoint).unwrap_or_else(|e| panic!("after kill at {delay_ms} ms: {e}"));
            assert_eq!((c.film.width, c.film.height), (1024, 1024));
        }
        assert_eq!(std::fs::read(&out).unwrap(), old);
    }
    assert_eq!(kills, 5);
    // On a loaded machine no pass may have ended within those delays: one
    // more run is killed only once its first checkpoint is there, so that
    // the file whose wholeness is checked exists on any machine.
    if !checkpoint.exists() {
        let mut child = spawn(&args);
        let started = Instant::now();
        while !checkpoint.exists() && started.elapsed() < Duration::from_secs(300) {
            std::thread::sleep(Duration::from_millis(20));
        }
        let _ = child.kill();
        let _ = child.wait();
    }
    assert!(checkpoint.exists(), "some checkpoint was completed within 300 s");
    let c = Checkpoint::read(&checkpoint).unwrap_or_else(|e| panic!("after the last kill: {e}"));
    assert_eq!((c.film.width, c.film.height), (1024, 1024));
    assert_eq!(std::fs::read(&out).unwrap(), old);
    // The temporary files of the killed processes go with the next render.
    trazo()
        .args([
            "render",
            "-o",
            s(&out),
            "--width",
            "8",
            "--height",
            "8",
            "--spp",
            "1",
            "--restart",
            "-q",
        ])
        .assert()
        .success();
    assert_eq!(temporary_files(dir.path()), Vec::<String>::new());
}

/// Renders `scene` to `out` with a zero time limit (so only the first of
/// 64 samples per pixel); returns the checkpoint left behind, read back.
fn render_first_pass(scene: &Path, out: &Path) -> (PathBuf, Checkpoint) {
    trazo()
        .args([
            "render",
            s(scene),
            "-o",
            s(out),
            "--time-limit",
            "0",
            "--spp",
            "64",
            "-q",
        ])
        .assert()
        .success();
    let checkpoint = PathBuf::from(format!("{}.trazo-checkpoint", out.display()));
    let c = Checkpoint::read(&checkpoint).unwrap();
    (checkpoint, c)
}

/// Bad checkpoints and mismatched resumes are errors (status 2, one line).
#[test]
fn bad_checkpoints_and_resumes_are_clear_errors() {
    let dir = tempfile::tempdir().unwrap();
    let fails = |args: &[&str]| {
        let o = trazo().args(args).output().unwrap();
        let err = String::from_utf8_lossy(&o.stderr).into_owned();
        assert_eq!(o.status.code(), Some(2), "{args:?}: {err}");
        assert_eq!(err.lines().count(), 1, "{err}");
        assert!(!err.contains("panicked"));
        err
    };
    let garbage = dir.path().join("g.trazo-checkpoint");
    std::fs::write(&garbage, b"TRAZOCKP\x01\0\0\0garbage").unwrap();
    let e = fails(&["render", "--resume", s(&garbage)]);
    assert!(
        e.contains("g.trazo-checkpoint") && e.contains("invalid checkpoint"),
        "{e}"
    );
    let e = fails(&["render", "--resume", s(&dir.path().join("none"))]);
    assert!(e.contains("not found"), "{e}");
    // Flags that change the image cannot be combined with --resume.
    let o = trazo()
        .args(["render", "--resume", s(&garbage), "--spp", "4"])
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("cannot be used with"));

    // A scene edited after the interruption.
    let scene = dir.path().join("s.toml");
    std::fs::write(
        &scene,
        "[render]\nwidth = 8\nheight = 8\n\n[[shape]]\ntype = \"sphere\"\ncenter = [0, 0, 0]\nradius = 1\n",
    )
    .unwrap();
    let (checkpoint, c) = render_first_pass(&scene, &dir.path().join("s.png"));
    assert_eq!(c.stats.spp, 1, "a zero time limit still renders the first pass");
    std::fs::write(
        &scene,
        std::fs::read_to_string(&scene)
            .unwrap()
            .replace("radius = 1", "radius = 2"),
    )
    .unwrap();
    let e = fails(&["render", "--resume", s(&checkpoint)]);
    assert!(e.contains("has changed"), "{e}");
    // A truncated checkpoint.
    let bytes = std::fs::read(&checkpoint).unwrap();
    std::fs::write(&checkpoint, &bytes[..bytes.len() - 100]).unwrap();
    let e = fails(&["render", "--resume", s(&checkpoint)]);
    assert!(e.contains("checksum"), "{e}");
}

/// A resume refuses a scene whose referenced files (here an OBJ mesh)
/// changed since the checkpoint, naming the file; the same bytes again, even
/// rewritten, resume.
#[test]
fn resume_notices_an_edited_mesh_file() {
    let dir = tempfile::tempdir().unwrap();
    let obj = dir.path().join("quad.obj");
    let quad = "v -1 -1 0\nv 1 -1 0\nv 1 1 0\nv -1 1 0\nf 1 2 3 4\n";
    std::fs::write(&obj, quad).unwrap();
    let scene = dir.path().join("m.toml");
    std::fs::write(
        &scene,
        "[render]\nwidth = 8\nheight = 8\n\n[camera]\nfrom = [0, 0, 4]\nto = [0, 0, 0]\n\n[world]\nambient = 0.2\n\n\
         [[mesh]]\nname = \"quad\"\nfile = \"quad.obj\"\n\n\
         [[shape]]\ntype = \"mesh\"\nmesh = \"quad\"\n",
    )
    .unwrap();
    let out = dir.path().join("m.png");
    let (checkpoint, c) = render_first_pass(&scene, &out);
    let files: Vec<&str> = c.job_values("file").collect();
    assert_eq!(files.len(), 2, "the scene and its mesh: {files:?}");
    assert!(files.iter().any(|f| f.ends_with("quad.obj")), "{files:?}");

    std::fs::write(&obj, quad.replace("v 1 1 0", "v 1 1.5 0")).unwrap();
    let o = trazo().args(["render", "--resume", s(&checkpoint)]).output().unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert_eq!(err.lines().count(), 1, "{err}");
    assert!(err.contains("quad.obj has changed"), "{err}");
    assert!(checkpoint.exists(), "a refused resume keeps the checkpoint");

    std::fs::write(&obj, quad).unwrap();
    trazo()
        .args(["render", "--resume", s(&checkpoint), "-q"])
        .assert()
        .success();
    assert!(out.exists() && !checkpoint.exists());
}

/// The memory estimate refuses, before allocating, a render above
/// `--max-memory`: a huge film, a huge mesh, or huge photon maps.
#[test]
fn renders_above_the_memory_limit_are_refused_before_they_start() {
    let dir = tempfile::tempdir().unwrap();
    let run = |args: &[&str]| {
        let start = Instant::now();
        let o = trazo().current_dir(dir.path()).args(args).output().unwrap();
        (
            o.status.code(),
            String::from_utf8_lossy(&o.stderr).into_owned(),
            start.elapsed(),
        )
    };
    let (code, err, took) = run(&["render", "--width", "60000", "--height", "4000", "--max-memory", "1G"]);
    assert_eq!(code, Some(2), "{err}");
    assert!(
        err.starts_with("error: the render needs about 59.0 GiB (film 59.0 GiB")
            && err.contains("more than the memory limit of 1.0 GiB"),
        "{err}"
    );
    assert!(took < Duration::from_secs(5));
    let (code, err, _) = run(&[
        "render",
        "--width",
        "64",
        "--height",
        "64",
        "--aov",
        "albedo",
        "--max-memory",
        "1M",
    ]);
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("auxiliary images 1.6 MiB"), "{err}");
    let scene = dir.path().join("m.toml");
    std::fs::write(
        &scene,
        "[[shape]]\ntype = \"mesh\"\ngenerate = \"uv_sphere\"\nsegments = 7000\nrings = 7000\n",
    )
    .unwrap();
    let (code, err, took) = run(&["render", s(&scene), "--max-memory", "2G"]);
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("geometry 13.9 GiB"), "{err}");
    assert!(took < Duration::from_secs(5), "refused before building: {took:?}");
    // Photon maps: 10⁸ photons would need tens of gigabytes.
    let (code, err, took) = run(&[
        "render",
        "--integrator",
        "photon",
        "--photons",
        "100000000",
        "--max-memory",
        "1G",
    ]);
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("photon maps 24.3 GiB"), "{err}");
    assert!(took < Duration::from_secs(5), "refused before tracing: {took:?}");
    let (code, err, _) = run(&["render", "--max-memory", "12X"]);
    assert_eq!(code, Some(2));
    assert!(err.contains("unit"), "{err}");
    // Under the limit, the same kind of render goes ahead.
    let (code, err, _) = run(&[
        "render",
        "--width",
        "16",
        "--height",
        "16",
        "--spp",
        "1",
        "--max-memory",
        "64M",
        "-o",
        "x.png",
    ]);
    assert_eq!(code, Some(0), "{err}");
}

/// Photon mapping obeys Ctrl-C like the path tracer: the image of whole
/// camera passes, a checkpoint, status 130; `--resume` traces the same
/// photon maps again and ends with the image of a render that never
/// stopped, bit for bit.
#[cfg(unix)]
#[test]
fn photon_mapping_stops_on_ctrl_c_and_resumes_identically() {
    let dir = tempfile::tempdir().unwrap();
    let full = dir.path().join("full.pfm");
    let common = [
        "--integrator",
        "photon",
        "--photons",
        "20000",
        "--final-gather",
        "4",
        "--width",
        "48",
        "--height",
        "36",
        "--spp",
        "256",
        "--seed",
        "3",
        "-q",
    ];
    let out = trazo().args(["render", "-o", s(&full)]).args(common).output().unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));

    let part = dir.path().join("part.pfm");
    let checkpoint = dir.path().join("part.pfm.trazo-checkpoint");
    let mut child = spawn(&[&["render", "-o", s(&part), "--checkpoint-every", "0"], &common[..]].concat());
    wait_for(&checkpoint, &mut child);
    signal(&child, "-INT");
    let (code, err) = finish(child, Duration::from_secs(20));
    assert_eq!(code, Some(130), "{err}");
    let c = Checkpoint::read(&checkpoint).unwrap();
    let spp = c.stats.spp;
    assert!((1..256).contains(&spp), "{spp}");
    assert!(
        err.contains(&format!("interrupted: rendered 48×36 at {spp} of 256 spp with photon")),
        "{err}"
    );
    assert_eq!(trazo::film::io::read_image(&part).unwrap(), c.film.to_image());
    assert!(c.job_values("arg").any(|a| a == "--photons=20000"), "{:?}", c.job);

    resume_matches_uninterrupted(&checkpoint, &part, &full, "rendered 48×36 at 256 spp with photon");

    // Ctrl-C during a long photon pass (20 M photons take many seconds)
    // ends it at once, with no image.
    let none = dir.path().join("none.png");
    let child = spawn(&[
        "render",
        "-o",
        s(&none),
        "--integrator",
        "photon",
        "--photons",
        "20000000",
        "--width",
        "8",
        "--height",
        "8",
    ]);
    std::thread::sleep(Duration::from_millis(800));
    let sent = Instant::now();
    signal(&child, "-INT");
    let (code, err) = finish(child, Duration::from_secs(20));
    assert!(sent.elapsed() < Duration::from_secs(2), "took {:?}", sent.elapsed());
    assert_eq!(code, Some(130), "{err}");
    assert!(err.contains("nothing was written"), "{err}");
    assert!(!none.exists());
}

/// SPPM obeys Ctrl-C and the time limit between iterations: the image is
/// that of whole iterations (the same as a render asked for that many),
/// the status that of the path tracer, and a checkpoint is left to resume
/// from (resuming: `ctrl_c_and_resume_work_for_progressive_renders`);
/// shards are refused up front (status 2).
#[cfg(unix)]
#[test]
fn sppm_stops_after_whole_iterations() {
    let dir = tempfile::tempdir().unwrap();
    let part = dir.path().join("part.pfm");
    let common = [
        "--integrator",
        "sppm",
        "--sppm-photons",
        "2000",
        "--width",
        "32",
        "--height",
        "24",
        "--seed",
        "5",
        "--threads",
        "2",
        // Samples that do not depend on --spp, so that N iterations of a
        // long render are those of a render asked for N.
        "--sampler",
        "independent",
    ];
    let child = spawn(&[&["render", "-o", s(&part), "--spp", "1000000"], &common[..]].concat());
    std::thread::sleep(Duration::from_millis(1500));
    let sent = Instant::now();
    signal(&child, "-INT");
    let (code, err) = finish(child, Duration::from_secs(20));
    assert!(sent.elapsed() < Duration::from_secs(5), "took {:?}", sent.elapsed());
    assert_eq!(code, Some(130), "{err}");
    let done: u32 = err
        .split("interrupted: rendered 32×24 at ")
        .nth(1)
        .and_then(|rest| rest.split(" of ").next())
        .and_then(|n| n.parse().ok())
        .unwrap_or_else(|| panic!("{err}"));
    assert!(done >= 1, "{err}");
    assert!(err.contains("--resume"), "{err}");
    assert!(dir.path().join("part.pfm.trazo-checkpoint").exists());
    let whole = dir.path().join("whole.pfm");
    let o = trazo()
        .args(["render", "-q", "-o", s(&whole), "--spp", &done.to_string()])
        .args(common)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let (a, b) = (
        trazo::film::io::read_image(&part).unwrap(),
        trazo::film::io::read_image(&whole).unwrap(),
    );
    assert!(a == b, "the interrupted image is not that of {done} whole iterations");

    // A time limit alone: as many iterations as fit, then a normal exit.
    let timed = dir.path().join("timed.png");
    let start = Instant::now();
    let o = trazo()
        .args(["render", "-o", s(&timed), "--time-limit", "1"])
        .args(common)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    assert!(start.elapsed() < Duration::from_secs(8), "{:?}", start.elapsed());
    assert!(err.contains("time limit reached: rendered 32×24 at "), "{err}");
    assert!(timed.exists() && dir.path().join("timed.png.trazo-checkpoint").exists());

    // Shards are refused before anything is rendered.
    let o = trazo()
        .args(["render", "-o", s(&dir.path().join("c.trazo-part")), "--shard", "1/2"])
        .args(common)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(err.contains("cannot be sharded"), "{err}");
    assert_eq!(err.lines().count(), 1, "{err}");
    assert!(!dir.path().join("c.trazo-part").exists());
}
