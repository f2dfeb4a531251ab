//! `trazo bench rays`: its hit file must agree with a brute-force
//! reference written independently here (Möller–Trumbore in f64 over every
//! face), and bad inputs must fail cleanly.

use assert_cmd::Command;
use std::fs;
use std::path::Path;

/// A bumpy height field of `n × n` quads (each a PLY face of 4 vertices,
/// so face numbers differ from triangle numbers), as binary PLY.
fn height_field(n: usize) -> (Vec<[f64; 3]>, Vec<[u32; 4]>) {
    let mut v = Vec::new();
    for j in 0..=n {
        for i in 0..=n {
            let (x, y) = (i as f64 / n as f64 * 2.0 - 1.0, j as f64 / n as f64 * 2.0 - 1.0);
            let z = 0.3 * (3.0 * x).sin() * (2.0 * y).cos();
            v.push([x as f32 as f64, y as f32 as f64, z as f32 as f64]);
        }
    }
    let mut f = Vec::new();
    for j in 0..n as u32 {
        for i in 0..n as u32 {
            let a = j * (n as u32 + 1) + i;
            f.push([a, a + 1, a + n as u32 + 2, a + n as u32 + 1]);
        }
    }
    (v, f)
}

fn write_ply(path: &Path, v: &[[f64; 3]], f: &[[u32; 4]]) {
    let mut b = format!(
        "ply\nformat binary_little_endian 1.0\nelement vertex {}\nproperty float x\nproperty float y\nproperty float z\n\
         element face {}\nproperty list uchar int vertex_indices\nend_header\n",
        v.len(),
        f.len()
    )
    .into_bytes();
    for p in v {
        for c in p {
            b.extend_from_slice(&(*c as f32).to_le_bytes());
        }
    }
    for q in f {
        b.push(4);
        for i in q {
            b.extend_from_slice(&i.to_le_bytes());
        }
    }
    fs::write(path, b).unwrap();
}

/// A small deterministic generator (SplitMix64), independent of trazo's.
struct Rng(u64);
impl Rng {
    fn next(&mut self) -> f64 {
        self.0 = self.0.wrapping_add(0x9E3779B97F4A7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58476D1CE4E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D049BB133111EB);
        ((z ^ (z >> 31)) >> 11) as f64 / (1u64 << 53) as f64
    }
}

fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}
fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}
fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// Möller and Trumbore 1997; returns t.
fn intersect(o: [f64; 3], d: [f64; 3], p0: [f64; 3], p1: [f64; 3], p2: [f64; 3]) -> Option<f64> {
    let (e1, e2) = (sub(p1, p0), sub(p2, p0));
    let p = cross(d, e2);
    let det = dot(e1, p);
    if det.abs() < 1e-300 {
        return None;
    }
    let s = sub(o, p0);
    let u = dot(s, p) / det;
    let q = cross(s, e1);
    let v = dot(d, q) / det;
    if u < 0.0 || v < 0.0 || u + v > 1.0 {
        return None;
    }
    let t = dot(e2, q) / det;
    (t > 1e-4).then_some(t)
}

#[test]
fn hits_agree_with_brute_force() {
    let dir = tempfile::tempdir().unwrap();
    let (v, faces) = height_field(24);
    write_ply(&dir.path().join("field.ply"), &v, &faces);

    let mut rng = Rng(42);
    let mut rays = Vec::new();
    let mut bytes = Vec::new();
    for k in 0..3000 {
        let o = [rng.next() * 3.0 - 1.5, rng.next() * 3.0 - 1.5, rng.next() * 2.0 - 1.0];
        // Half the rays aim down at the surface, half go anywhere;
        // directions are deliberately not normalised.
        let d = if k % 2 == 0 {
            [rng.next() - 0.5, rng.next() - 0.5, -0.5 - rng.next() * 2.0]
        } else {
            [rng.next() * 4.0 - 2.0, rng.next() * 4.0 - 2.0, rng.next() * 4.0 - 2.0]
        };
        let o = o.map(|x| x as f32 as f64);
        let d = d.map(|x| x as f32 as f64);
        for c in o.iter().chain(d.iter()) {
            bytes.extend_from_slice(&(*c as f32).to_le_bytes());
        }
        rays.push((o, d));
    }
    fs::write(dir.path().join("rays.bin"), &bytes).unwrap();

    let out = Command::cargo_bin("trazo")
        .unwrap()
        .current_dir(dir.path())
        .args([
            "bench",
            "rays",
            "--mesh",
            "field.ply",
            "--rays",
            "rays.bin",
            "--hits",
            "hits.bin",
        ])
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let lines: Vec<&str> = stdout.lines().collect();
    assert_eq!(lines.len(), 3, "{stdout}");
    assert!(lines[0].starts_with("build: ") && lines[0].ends_with(" s"), "{stdout}");
    assert!(
        lines[1].starts_with("closest-hit: ") && lines[1].ends_with(" rays/s"),
        "{stdout}"
    );
    assert!(
        lines[2].starts_with("any-hit: ") && lines[2].ends_with(" rays/s"),
        "{stdout}"
    );

    let hits = fs::read(dir.path().join("hits.bin")).unwrap();
    assert_eq!(hits.len(), rays.len() * 8);
    let (mut n_hit, mut disagreements) = (0, 0);
    for (k, (o, d)) in rays.iter().enumerate() {
        let t = f32::from_le_bytes(hits[8 * k..8 * k + 4].try_into().unwrap()) as f64;
        let face = u32::from_le_bytes(hits[8 * k + 4..8 * k + 8].try_into().unwrap());
        // Brute force: every face, split into two triangles as a fan.
        let mut best: Option<(f64, u32)> = None;
        for (fi, q) in faces.iter().enumerate() {
            for [a, b, c] in [[q[0], q[1], q[2]], [q[0], q[2], q[3]]] {
                if let Some(t) = intersect(*o, *d, v[a as usize], v[b as usize], v[c as usize]) {
                    if best.is_none_or(|(bt, _)| t < bt) {
                        best = Some((t, fi as u32));
                    }
                }
            }
        }
        match best {
            None => {
                if face != u32::MAX || t != f64::INFINITY {
                    disagreements += 1;
                }
            }
            Some((bt, bf)) => {
                n_hit += 1;
                let close = (t - bt).abs() <= 1e-4 * bt.max(1.0);
                // A ray through a shared edge may be given either face.
                if !close || (face != bf && !faces[face as usize].iter().any(|i| faces[bf as usize].contains(i))) {
                    disagreements += 1;
                }
            }
        }
    }
    assert!(
        n_hit > 300 && n_hit < 2900,
        "{n_hit} hits: the rays should both hit and miss"
    );
    // f32 against f64 arithmetic may differ for a ray that grazes an edge
    // of the mesh's silhouette; with 3000 random rays that is at most a
    // handful.
    assert!(disagreements <= 3, "{disagreements} of {} rays disagree", rays.len());
}

#[test]
fn bad_inputs_fail_with_status_2() {
    let dir = tempfile::tempdir().unwrap();
    let (v, faces) = height_field(2);
    write_ply(&dir.path().join("m.ply"), &v, &faces);
    fs::write(dir.path().join("bad.bin"), [0u8; 25]).unwrap();
    let run = |args: &[&str]| {
        let out = Command::cargo_bin("trazo")
            .unwrap()
            .current_dir(dir.path())
            .args(args)
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&out.stderr).into_owned();
        assert_eq!(out.status.code(), Some(2), "{args:?}: {err}");
        assert_eq!(err.trim().lines().count(), 1, "{err}");
        err
    };
    assert!(run(&["bench", "rays", "--mesh", "m.ply", "--rays", "bad.bin"]).contains("bad.bin"));
    assert!(run(&["bench", "rays", "--mesh", "missing.ply", "--rays", "bad.bin"]).contains("missing.ply"));
    assert!(run(&["bench", "rays", "--mesh", "m.stl", "--rays", "bad.bin"]).contains("m.stl"));
}
