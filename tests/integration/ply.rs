//! PLY models on the command line: a lone `.ply` is framed and rendered, a
//! scene's mesh `file` may be a `.ply`, and missing or broken PLY files exit
//! with status 2 and a one-line message naming the file and the place.

use assert_cmd::Command;
use std::fs;
use std::path::{Path, PathBuf};

fn trazo() -> Command {
    Command::cargo_bin("trazo").unwrap()
}

/// Runs trazo expecting failure with status 2 and one line on stderr;
/// returns that line.
fn fails(args: &[&str]) -> String {
    let out = trazo().args(args).output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr).into_owned();
    assert_eq!(out.status.code(), Some(2), "args {args:?}, stderr: {err}");
    let lines: Vec<&str> = err.lines().filter(|l| !l.trim().is_empty()).collect();
    assert_eq!(lines.len(), 1, "one line expected, got: {err}");
    assert!(!err.contains("panicked"), "{err}");
    lines[0].to_string()
}

/// A unit cube of six quads as binary little-endian PLY, with a colour
/// property per vertex that trazo skips.
fn cube_binary() -> Vec<u8> {
    let mut out = b"ply\nformat binary_little_endian 1.0\ncomment a cube\nelement vertex 8\n\
        property float x\nproperty float y\nproperty float z\nproperty uchar red\n\
        element face 6\nproperty list uchar int vertex_indices\nend_header\n"
        .to_vec();
    for i in 0..8u8 {
        for axis in 0..3 {
            let v = if i & (1 << axis) != 0 { 0.5f32 } else { -0.5 };
            out.extend_from_slice(&v.to_le_bytes());
        }
        out.push(i * 30);
    }
    // Counter-clockwise seen from outside.
    let quads: [[i32; 4]; 6] = [
        [0, 2, 3, 1],
        [4, 5, 7, 6],
        [0, 1, 5, 4],
        [2, 6, 7, 3],
        [0, 4, 6, 2],
        [1, 3, 7, 5],
    ];
    for q in quads {
        out.push(4);
        for i in q {
            out.extend_from_slice(&i.to_le_bytes());
        }
    }
    out
}

fn write(dir: &Path, name: &str, bytes: &[u8]) -> PathBuf {
    let p = dir.join(name);
    fs::write(&p, bytes).unwrap();
    p
}

#[test]
fn renders_a_lone_ply_model() {
    let dir = tempfile::tempdir().unwrap();
    let model = write(dir.path(), "model.ply", &cube_binary());
    let out = dir.path().join("out.png");
    let o = trazo()
        .args(["render"])
        .arg(&model)
        .arg("-o")
        .arg(&out)
        .args(["--width", "32", "--height", "32", "--spp", "1", "-q"])
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{stderr}");
    let img = image::open(&out).unwrap().to_rgb8();
    assert_eq!(img.dimensions(), (32, 32));
    // The model is framed: the centre pixel shows it, not the background.
    assert_ne!(img.get_pixel(16, 16), img.get_pixel(0, 0));
    // The skipped colour is reported, with the header line that declares it.
    assert!(
        stderr.contains("model.ply:8:1: vertex property `red` is unsupported"),
        "{stderr}"
    );
}

const SCENE: &str = r#"[render]
width = 24
height = 16
spp = 1

[camera]
from = [0, 1, 4]
to = [0, 0, 0]

[[light]]
type = "point"
position = [0, 3, 3]
intensity = 10

[[mesh]]
name = "cube"
file = "models/cube.ply"

[[shape]]
type = "mesh"
mesh = "cube"

[[shape]]
type = "mesh"
mesh = "cube"
transform = [{ translate = [1.5, 0, 0] }]

[[shape]]
type = "mesh"
file = "models/tri.ply"
"#;

const ASCII_TRIANGLE: &str = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n\
    property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n\
    -2 -1 -1\n2 -1 -1\n0 -1 -3\n3 0 1 2\n";

#[test]
fn a_scene_mesh_file_may_be_ply() {
    let dir = tempfile::tempdir().unwrap();
    fs::create_dir(dir.path().join("models")).unwrap();
    write(dir.path(), "models/cube.ply", &cube_binary());
    write(dir.path(), "models/tri.ply", ASCII_TRIANGLE.as_bytes());
    let scene = write(dir.path(), "scene.toml", SCENE.as_bytes());
    let out = dir.path().join("out.png");
    let o = trazo().arg("render").arg(&scene).arg("-o").arg(&out).output().unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let img = image::open(&out).unwrap().to_rgb8();
    assert_eq!(img.dimensions(), (24, 16));
    // The cube in front of the camera is lit; the corners see black.
    assert_ne!(img.get_pixel(12, 8), img.get_pixel(0, 0));
    // Broken PLY meshes are named by the scene's key and the PLY's place.
    let mut bad = cube_binary();
    bad.truncate(bad.len() - 10);
    write(dir.path(), "models/cube.ply", &bad);
    let e = fails(&["render", "-o", out.to_str().unwrap(), scene.to_str().unwrap()]);
    assert!(
        e.contains("scene.toml:17:8: `mesh[0].file`:")
            && e.contains("cube.ply: byte offset ")
            && e.contains("`face[5].vertex_indices`"),
        "{e}"
    );
    write(
        dir.path(),
        "models/tri.ply",
        ASCII_TRIANGLE.replace("0 -1 -3", "0 -1 -3 4").as_bytes(),
    );
    write(dir.path(), "models/cube.ply", &cube_binary());
    let e = fails(&["render", "-o", out.to_str().unwrap(), scene.to_str().unwrap()]);
    assert!(
        e.contains("`shape[2].file`:") && e.contains("tri.ply:12:9: `vertex[2]`: unexpected `4`"),
        "{e}"
    );
}

#[test]
fn missing_ply_files_exit_with_status_2_and_name_the_path() {
    let dir = tempfile::tempdir().unwrap();
    let missing = dir.path().join("no/such/model.ply");
    let e = fails(&["render", missing.to_str().unwrap()]);
    assert!(e.contains(missing.to_str().unwrap()) && e.contains("not found"), "{e}");
    let scene = write(
        dir.path(),
        "scene.toml",
        SCENE.replace("models/cube.ply", "models/gone.ply").as_bytes(),
    );
    let e = fails(&["render", scene.to_str().unwrap()]);
    assert!(
        e.contains("`mesh[0].file`")
            && e.contains(&dir.path().join("models/gone.ply").display().to_string())
            && e.contains("not found"),
        "{e}"
    );
    // Other mesh extensions are refused by name.
    let scene = write(
        dir.path(),
        "scene.toml",
        SCENE.replace("models/cube.ply", "models/cube.stl").as_bytes(),
    );
    let e = fails(&["render", scene.to_str().unwrap()]);
    assert!(
        e.contains("cube.stl: unsupported mesh format") && e.contains(".obj and .ply"),
        "{e}"
    );
}

#[test]
fn a_lone_ply_with_an_absurd_count_fails_at_once() {
    let dir = tempfile::tempdir().unwrap();
    let model = write(
        dir.path(),
        "huge.ply",
        b"ply\nformat binary_big_endian 1.0\nelement vertex 1000000000000\nproperty float x\n\
          property float y\nproperty float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n\
          \x00\x00\x00\x00",
    );
    let e = fails(&["render", model.to_str().unwrap()]);
    assert!(
        e.contains("huge.ply:3:16: `element vertex`: 1000000000000 entries need at least"),
        "{e}"
    );
}
