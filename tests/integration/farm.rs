//! Sharded renders: the films of a render's shards, merged in any order,
//! are the film of the render on one machine, bit for bit.

use trazo::film::Film;
use trazo::render::{RenderOptions, RenderStats, Shard, render};
use trazo::scene::builtin::cornell_box;
use trazo::settings::{Filter, IntegratorKind};

fn film_of(desc: &trazo::scene::SceneDesc, threads: usize, shard: Option<Shard>, aovs: bool) -> (Film, RenderStats) {
    let scene = trazo::scene::build(desc).unwrap();
    let out = render(
        &scene,
        &RenderOptions {
            threads: Some(threads),
            tile_size: 8,
            aovs,
            shard,
            ..RenderOptions::default()
        },
    )
    .unwrap();
    (out.film, out.stats)
}

fn check_shards_merge_exactly(desc: &trazo::scene::SceneDesc, count: u32, aovs: bool) {
    let (whole, stats) = film_of(desc, 2, None, aovs);
    assert_eq!(stats.spp, desc.settings.spp);
    let mut parts: Vec<(Film, RenderStats)> = (0..count)
        .map(|index| film_of(desc, 1 + index as usize % 2, Some(Shard { index, count }), aovs))
        .collect();
    let spp: u32 = parts.iter().map(|p| p.1.spp).sum();
    assert_eq!(spp, desc.settings.spp);
    // Any order of merging.
    parts.reverse();
    let mut merged = Film::new(whole.width, whole.height);
    if aovs {
        merged.aovs = Some(vec![Default::default(); whole.pixels.len()]);
    }
    if desc.settings.gbuffer.is_some() {
        merged.gbuffer = Some(vec![Default::default(); whole.pixels.len()]);
    }
    for (film, _) in &parts {
        // A shard alone is a whole image: every pixel has samples.
        assert!(film.pixels.iter().all(|p| p.weight() > 0.0));
        merged.merge(film).unwrap();
    }
    assert!(merged == whole, "the merged film differs from the single render's");
    assert_eq!(merged.to_image(), whole.to_image());
    // Fewer shards are a noisier image of the same scene, not another.
    let mut two = parts[0].0.clone();
    two.merge(&parts[1].0).unwrap();
    let (a, b) = (two.to_image().mean(), whole.to_image().mean());
    assert!((a - b).abs().max_element() < 0.1 * b.max_element(), "{a} vs {b}");
}

#[test]
fn shards_of_a_path_traced_render_merge_into_it() {
    let mut desc = cornell_box();
    desc.settings.width = 24;
    desc.settings.height = 20;
    desc.settings.spp = 40;
    check_shards_merge_exactly(&desc, 4, true);
}

/// A G-buffer film's sums merge as exactly as the pixels'.
#[test]
fn shards_of_a_gbuffer_film_merge_into_it() {
    let mut desc = cornell_box();
    desc.settings.width = 20;
    desc.settings.height = 16;
    desc.settings.spp = 12;
    desc.settings.gbuffer = Some(trazo::settings::GBufferSpace::Camera);
    check_shards_merge_exactly(&desc, 3, false);
    let (film, _) = film_of(&desc, 2, None, false);
    let channels = film.gbuffer_channels().expect("a G-buffer");
    // The box lies ahead of the camera (the columns beside its walls see
    // nothing: 0).
    let z = &channels[5];
    let seen = z.iter().filter(|&&z| z > 0.0).count();
    assert!(
        z.iter().all(|&z| z >= 0.0) && seen > z.len() / 2,
        "P.Z {seen} of {}: {z:?}",
        z.len()
    );
}

#[test]
fn shards_merge_exactly_with_a_splatting_filter() {
    let mut desc = cornell_box();
    desc.settings.width = 20;
    desc.settings.height = 16;
    desc.settings.spp = 24;
    desc.settings.filter = Filter::Gaussian {
        stddev: 0.5,
        radius: 2.0,
    };
    check_shards_merge_exactly(&desc, 3, false);
}

#[test]
fn shards_of_a_photon_mapped_render_merge_into_it() {
    let mut desc = cornell_box();
    desc.settings.width = 16;
    desc.settings.height = 16;
    desc.settings.spp = 8;
    desc.settings.integrator = IntegratorKind::Photon;
    desc.settings.photon.photons = 20_000;
    check_shards_merge_exactly(&desc, 2, false);
}

#[test]
fn progressive_photon_mapping_cannot_be_sharded() {
    let mut desc = cornell_box();
    desc.settings.width = 8;
    desc.settings.height = 8;
    desc.settings.spp = 4;
    desc.settings.integrator = IntegratorKind::Sppm;
    let scene = trazo::scene::build(&desc).unwrap();
    let options = RenderOptions {
        shard: Some(Shard { index: 0, count: 2 }),
        ..RenderOptions::default()
    };
    assert!(render(&scene, &options).is_err());
}

// ---- The command line: `trazo render --shard` and `trazo merge`. ----

use assert_cmd::Command;
use std::path::Path;

fn trazo(dir: &Path) -> Command {
    let mut c = Command::cargo_bin("trazo").unwrap();
    c.current_dir(dir);
    c
}

/// A small render of the textured scene (a Gaussian filter: splatting) at
/// 24 spp: 1, 1, 2, 4, 8 and 8 samples per pass.
const RENDER: [&str; 8] = [
    "--width",
    "24",
    "--height",
    "16",
    "--spp",
    "24",
    "--aov",
    "albedo,depth",
];

/// scenes/materials.toml with a Gaussian filter, a white balance and an
/// output colour space (which `trazo merge` must apply as the whole render
/// does), written into `dir`.
fn scene_in(dir: &Path) -> String {
    let text = std::fs::read_to_string(format!("{}/scenes/materials.toml", env!("CARGO_MANIFEST_DIR"))).unwrap();
    let text = text
        .replacen(
            "[render]\n",
            "[render]\nfilter = \"gaussian\"\nwhite_balance = 4500\ncolor_space = \"rec2020\"\n",
            1,
        )
        .replace(
            "\"textures/",
            &format!("\"{}/scenes/textures/", env!("CARGO_MANIFEST_DIR")),
        );
    assert!(text.contains("filter = \"gaussian\""));
    let path = dir.join("materials.toml");
    std::fs::write(&path, text).unwrap();
    path.to_string_lossy().into_owned()
}

fn render_shard(dir: &Path, k: u32, n: u32) {
    trazo(dir)
        .args(["render", &scene_in(dir)])
        .args(RENDER)
        .args([
            "--shard",
            &format!("{k}/{n}"),
            "-q",
            "-o",
            &format!("part{k}.trazo-part"),
        ])
        .assert()
        .success();
}

fn merge(dir: &Path, parts: &[&str], extra: &[&str]) -> std::process::Output {
    trazo(dir).arg("merge").args(parts).args(extra).output().unwrap()
}

#[test]
fn merged_shards_write_the_single_render_file_bit_for_bit() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    trazo(d)
        .args(["render", &scene_in(d)])
        .args(RENDER)
        .args(["-q", "-o", "whole.exr"])
        .assert()
        .success();
    for k in [3, 1, 4, 2] {
        render_shard(d, k, 4);
    }
    let parts = [
        "part4.trazo-part",
        "part2.trazo-part",
        "part1.trazo-part",
        "part3.trazo-part",
    ];
    let out = merge(d, &parts, &["-o", "merged.exr"]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    for (a, b) in [
        ("merged.exr", "whole.exr"),
        ("merged.albedo.exr", "whole.albedo.exr"),
        ("merged.depth.exr", "whole.depth.exr"),
    ] {
        assert!(
            std::fs::read(d.join(a)).unwrap() == std::fs::read(d.join(b)).unwrap(),
            "{a} and {b} differ"
        );
    }
    // --status: every shard done, every sample there.
    let out = merge(d, &parts, &["--status"]);
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success());
    assert!(
        text.contains("4 of 4 shards done; the parts hold 24 of 24 samples per pixel (100.0 %)"),
        "{text}"
    );
    assert_eq!(text.lines().filter(|l| l.contains(" done ")).count(), 4, "{text}");
}

#[test]
fn merge_refuses_parts_that_do_not_belong_together() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    for k in 1..=3 {
        render_shard(d, k, 3);
    }
    let err = |out: std::process::Output| {
        assert_eq!(out.status.code(), Some(2));
        String::from_utf8_lossy(&out.stderr).trim().to_string()
    };
    // A missing shard is named, and --partial writes the noisier image.
    let e = err(merge(d, &["part1.trazo-part", "part3.trazo-part"], &["-o", "m.png"]));
    assert!(e.contains("no part of shard 2/3") && e.contains("--partial"), "{e}");
    assert!(!d.join("m.png").exists());
    let out = merge(
        d,
        &["part1.trazo-part", "part3.trazo-part"],
        &["-o", "m.png", "--partial"],
    );
    assert!(out.status.success() && d.join("m.png").exists());
    let status = merge(d, &["part1.trazo-part", "part3.trazo-part"], &["--status"]);
    let text = String::from_utf8_lossy(&status.stdout);
    assert!(
        text.contains("2 of 3 shards done") && text.contains("no part of 2/3"),
        "{text}"
    );
    // The same shard twice.
    std::fs::copy(d.join("part1.trazo-part"), d.join("copy.trazo-part")).unwrap();
    let e = err(merge(
        d,
        &["part1.trazo-part", "copy.trazo-part", "part2.trazo-part"],
        &["-o", "m.png"],
    ));
    assert!(e.contains("is shard 1/3 again"), "{e}");
    // Another render's shard: another size, another seed.
    trazo(d)
        .args(["render", &scene_in(d), "--width", "20", "--height", "16", "--spp", "24"])
        .args([
            "--aov",
            "albedo,depth",
            "--shard",
            "2/3",
            "-q",
            "-o",
            "other.trazo-part",
        ])
        .assert()
        .success();
    let e = err(merge(d, &["part1.trazo-part", "other.trazo-part"], &["-o", "m.png"]));
    assert!(
        e.contains("other.trazo-part: is not a shard of the same render") && e.contains("image sizes"),
        "{e}"
    );
    trazo(d)
        .args(["render", &scene_in(d)])
        .args(RENDER)
        .args(["--seed", "9", "--shard", "2/3", "-q", "-o", "seed.trazo-part"])
        .assert()
        .success();
    let e = err(merge(d, &["part1.trazo-part", "seed.trazo-part"], &["-o", "m.png"]));
    assert!(e.contains("render settings differ"), "{e}");
    // Split differently.
    trazo(d)
        .args(["render", &scene_in(d)])
        .args(RENDER)
        .args(["--shard", "2/2", "-q", "-o", "half.trazo-part"])
        .assert()
        .success();
    let e = err(merge(d, &["part1.trazo-part", "half.trazo-part"], &["-o", "m.png"]));
    assert!(e.contains("different numbers of shards"), "{e}");
    // A damaged part, and an image given as a part.
    let mut bytes = std::fs::read(d.join("part3.trazo-part")).unwrap();
    bytes.truncate(bytes.len() / 2);
    std::fs::write(d.join("cut.trazo-part"), bytes).unwrap();
    let e = err(merge(d, &["part1.trazo-part", "cut.trazo-part"], &["-o", "m.png"]));
    assert!(e.contains("cut.trazo-part") && e.contains("truncated"), "{e}");
    let e = err(merge(d, &["m.png"], &["-o", "x.png"]));
    assert!(e.contains("m.png"), "{e}");
}

#[test]
fn shard_flags_are_checked_before_rendering() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let fails = |args: &[&str]| {
        let out = trazo(d).args(args).output().unwrap();
        assert_eq!(out.status.code(), Some(2), "{args:?}");
        String::from_utf8_lossy(&out.stderr).into_owned()
    };
    assert!(fails(&["render", "--shard", "0/4"]).contains("expected K/N"));
    assert!(fails(&["render", "--shard", "5/4"]).contains("expected K/N"));
    assert!(fails(&["render", "--shard", "1/4", "-o", "x.png"]).contains("NAME.trazo-part"));
    let e = fails(&[
        "render", "--shard", "1/9", "--spp", "64", "--width", "8", "--height", "8",
    ]);
    assert!(e.contains("at most 8 shards"), "{e}");
    let e = fails(&["render", "--shard", "1/2", "--time-limit", "3"]);
    assert!(e.contains("cannot be used with"), "{e}");
    let e = fails(&[
        "render",
        "--shard",
        "1/2",
        "--integrator",
        "sppm",
        "--width",
        "8",
        "--height",
        "8",
    ]);
    assert!(e.contains("sharded"), "{e}");
    // The default part name follows the scene.
    trazo(d)
        .args([
            "render", "--shard", "2/2", "--spp", "2", "--width", "8", "--height", "8", "-q",
        ])
        .assert()
        .success();
    assert!(d.join("cornell-box.shard-2-of-2.trazo-part").is_file());
    // A part is not overwritten unless asked.
    let e = fails(&[
        "render", "--shard", "2/2", "--spp", "2", "--width", "8", "--height", "8",
    ]);
    assert!(e.contains("--resume") && e.contains("--restart"), "{e}");
}

/// A shard interrupted (its part written at the end of a pass) and
/// resumed ends with the part an uninterrupted shard writes.
#[test]
fn an_interrupted_shard_resumes_to_the_same_part() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let args = [
        "render", "--width", "32", "--height", "32", "--spp", "4096", "--shard", "1/2",
    ];
    let mut child = std::process::Command::new(assert_cmd::cargo::cargo_bin("trazo"))
        .current_dir(d)
        .args(args)
        .args(["-q", "-o", "a.trazo-part", "--checkpoint-every", "0"])
        .spawn()
        .unwrap();
    // Once the part of the first passes is on disk.
    let start = std::time::Instant::now();
    while !d.join("a.trazo-part").exists() && start.elapsed().as_secs() < 30 {
        std::thread::sleep(std::time::Duration::from_millis(5));
    }
    interrupt(child.id());
    let status = child.wait().unwrap();
    assert!(start.elapsed().as_secs() < 60);
    assert_eq!(status.code(), Some(130));
    let out = merge(d, &["a.trazo-part"], &["--status"]);
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(text.contains("unfinished"), "{text}");
    trazo(d)
        .args(["render", "--resume", "a.trazo-part", "-q"])
        .assert()
        .success();
    trazo(d)
        .args(args)
        .args(["-q", "-o", "b.trazo-part"])
        .assert()
        .success();
    let (a, b) = (
        Checkpoint::read(&d.join("a.trazo-part")).unwrap(),
        Checkpoint::read(&d.join("b.trazo-part")).unwrap(),
    );
    assert!(a.film == b.film, "the resumed shard's film differs");
    assert_eq!(a.stats.spp, 2048);
}

use trazo::render::checkpoint::Checkpoint;

/// Sends SIGINT, as Ctrl-C does.
fn interrupt(pid: u32) {
    std::process::Command::new("kill")
        .args(["-INT", &pid.to_string()])
        .status()
        .unwrap();
}

// ---- The farms' scripts and manifests. ----

fn repo_file(path: &str) -> String {
    std::fs::read_to_string(format!("{}/{path}", env!("CARGO_MANIFEST_DIR"))).unwrap()
}

/// The value of the first `key: value` line whose key is `key`, at any
/// depth (list items' dashes left out), unquoted.
fn yaml_value<'a>(text: &'a str, key: &str) -> Option<&'a str> {
    text.lines()
        .filter(|l| !l.trim_start().starts_with('#'))
        .map(|l| l.trim_start().trim_start_matches("- "))
        .find_map(|l| l.strip_prefix(&format!("{key}:")))
        .map(|v| v.trim().trim_matches('"'))
}

/// The shell command of a Job's container: the item after `args:`.
fn job_command(text: &str) -> String {
    let mut lines = text.lines().skip_while(|l| l.trim() != "args:");
    lines.next().expect("an args: list");
    lines
        .next()
        .expect("one command")
        .trim()
        .trim_start_matches("- ")
        .to_string()
}

/// The Kubernetes manifests run the commands the Slurm test proves
/// (tools/farm/slurm/ci-test, run by .ci/run): the shards through
/// render-shard with the Indexed Job's index, the merge through
/// merge-parts, both on the one shared volume.
#[test]
fn the_kubernetes_jobs_run_the_commands_the_slurm_test_proves() {
    let render = repo_file("tools/farm/k8s/render-job.yaml");
    let merge = repo_file("tools/farm/k8s/merge-job.yaml");
    let volume = repo_file("tools/farm/k8s/volume.yaml");
    for m in [&render, &merge] {
        assert_eq!(yaml_value(m, "apiVersion"), Some("batch/v1"));
        assert_eq!(yaml_value(m, "kind"), Some("Job"));
        assert_eq!(yaml_value(m, "restartPolicy"), Some("Never"));
        assert_eq!(yaml_value(m, "mountPath"), Some("/render"));
        assert_eq!(yaml_value(m, "claimName"), yaml_value(&volume, "name"));
    }
    assert_eq!(yaml_value(&volume, "kind"), Some("PersistentVolumeClaim"));
    assert!(volume.contains("accessModes: [ReadWriteMany]"));
    // One pod per shard, the index from 0: shard index + 1 of N.
    assert_eq!(yaml_value(&render, "completionMode"), Some("Indexed"));
    let n = yaml_value(&render, "completions").unwrap();
    assert_eq!(yaml_value(&render, "parallelism"), Some(n));
    let shards_env = render.split("name: SHARDS").nth(1).expect("a SHARDS variable");
    assert_eq!(yaml_value(shards_env, "value"), Some(n));
    let shard = job_command(&render);
    assert!(
        shard.starts_with(r#"exec /opt/trazo/tools/farm/render-shard "$((JOB_COMPLETION_INDEX + 1))" "$SHARDS" "#),
        "{shard}"
    );
    let words: Vec<&str> = shard.split_whitespace().collect();
    let at = words.iter().position(|w| *w == "\"$SHARDS\"").unwrap();
    let parts = words[at + 2];
    assert!(parts.starts_with("/render/"), "{shard}");
    let merged = job_command(&merge);
    assert_eq!(
        merged.split_whitespace().take(3).collect::<Vec<_>>(),
        ["exec", "/opt/trazo/tools/farm/merge-parts", parts]
    );
    // The container has the scripts where the jobs look for them.
    let docker = repo_file("tools/farm/k8s/Dockerfile");
    assert!(docker.contains("COPY tools/farm /opt/trazo/tools/farm"));
    assert!(docker.contains("/usr/local/bin/trazo"));
    // And Slurm's scripts run the same two.
    let sbatch = repo_file("tools/farm/slurm/shard.sbatch");
    assert!(sbatch.contains(r#"exec "$farm/render-shard" "$k" "$n" "$@""#));
    assert!(repo_file("tools/farm/slurm/merge.sbatch").contains(r#"exec "$farm/merge-parts" "$@""#));
    let ci = repo_file("tools/farm/slurm/ci-test");
    assert!(ci.contains("tools/farm/slurm/shard.sbatch") && ci.contains("tools/farm/slurm/merge.sbatch"));
    assert!(repo_file(".ci/run").contains("tools/farm/slurm/ci-test"));
}

/// render-shard, as every farm runs it: shard K of N into its part, and
/// the unfinished part continued, not restarted, when the task reruns.
#[test]
fn render_shard_writes_and_continues_the_part() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let script = format!("{}/tools/farm/render-shard", env!("CARGO_MANIFEST_DIR"));
    let bin = assert_cmd::cargo::cargo_bin("trazo");
    let scene = scene_in(d);
    let run = |scene: &str| {
        std::process::Command::new("bash")
            .arg(&script)
            .args(["2", "3", scene, "parts", "--spp", "24", "--width", "8", "--height", "8"])
            .current_dir(d)
            .env("TRAZO", &bin)
            .output()
            .unwrap()
    };
    let out = run(&scene);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let part = d.join("parts/shard-2-of-3.trazo-part");
    let first = Checkpoint::read(&part).unwrap();
    assert_eq!(first.job_value("shard"), Some("2/3"));
    // Run again: the finished part is resumed (nothing to add), not refused.
    let out = run(&scene);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    assert!(Checkpoint::read(&part).unwrap().film == first.film);
}
