//! The malformed-input corpus (tests/malformed/FORMAT/*): every broken file
//! gives either a clear one-line error with exit status 2 (after the
//! warnings given before it, if any), or a documented
//! fallback with a warning — never a panic. Truncations of valid files at
//! every length never panic either, and never allocate by a count the file
//! cannot back (a counting allocator watches the largest request).
//! docs/robustness.md lists the cases and their behaviour.

use assert_cmd::Command;
use std::alloc::{GlobalAlloc, Layout, System};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};

/// Records the largest single allocation, to catch allocations sized by an
/// untrusted count.
struct CountingAllocator;

static LARGEST_ALLOCATION: AtomicUsize = AtomicUsize::new(0);

unsafe impl GlobalAlloc for CountingAllocator {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        LARGEST_ALLOCATION.fetch_max(layout.size(), Ordering::Relaxed);
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        LARGEST_ALLOCATION.fetch_max(new_size, Ordering::Relaxed);
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static ALLOCATOR: CountingAllocator = CountingAllocator;

fn corpus(rel: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/malformed").join(rel)
}

/// What a corpus file must give.
enum Expect {
    /// Exit status 2 and one error line containing all of these (after the
    /// warnings given before the error, if any).
    Error(&'static [&'static str]),
    /// A rendered image and a warning containing this.
    Warning(&'static str),
}
use Expect::*;

/// Every file of the corpus (a file that another includes is listed with
/// the outcome of the including file's case, under its own name only if it
/// is a case itself).
const CASES: &[(&str, Expect)] = &[
    // trazo TOML
    (
        "native/truncated.toml",
        Error(&["truncated.toml:", "TOML syntax error"]),
    ),
    ("native/wrong-type.toml", Error(&["shape[0].radius", "number"])),
    ("native/nan-radius.toml", Error(&["shape[0].radius", "finite"])),
    ("native/infinite-center.toml", Error(&["shape[0].center", "finite"])),
    (
        "native/bilinear-missing-corner.toml",
        Error(&[
            "bilinear-missing-corner.toml:11:1",
            "shape[0].p11",
            "missing required key",
        ]),
    ),
    (
        "native/bilinear-nan-corner.toml",
        Error(&["bilinear-nan-corner.toml:16:7", "shape[0].p11", "finite"]),
    ),
    ("native/overflowing-number.toml", Error(&["shape[0].radius", "finite"])),
    (
        "native/subdivision-bad-index.toml",
        Error(&[
            "subdivision-bad-index.toml:14:9",
            "shape[0].faces",
            "index 4 is out of range",
        ]),
    ),
    (
        "native/bezier-fifteen-points.toml",
        Error(&[
            "bezier-fifteen-points.toml:13:10",
            "shape[0].points",
            "16 control points, got 15",
        ]),
    ),
    (
        "native/cloud-infinite-frequency.toml",
        Error(&["cloud-infinite-frequency.toml:11:13", "medium[0].frequency", "finite"]),
    ),
    (
        "native/motion-times-backwards.toml",
        Error(&[
            "motion-times-backwards.toml:6:",
            "shape[0].motion_times",
            "must increase",
        ]),
    ),
    (
        "native/camera-end-no-view.toml",
        Error(&[
            "camera-end-no-view.toml:4:12",
            "camera.from_end",
            "do not define a view",
        ]),
    ),
    (
        "native/shutter-backwards.toml",
        Error(&["shutter-backwards.toml:2:", "camera.shutter", "closes before it opens"]),
    ),
    ("native/negative-radius.toml", Error(&["shape[0].radius", "positive"])),
    ("native/zero-radius.toml", Error(&["shape[0].radius", "positive"])),
    ("native/zero-size-box.toml", Error(&["shape[0].max", "greater"])),
    (
        "native/degenerate-triangles.toml",
        Warning("1 of 2 triangles have zero area"),
    ),
    ("native/zero-area-light.toml", Error(&["shape[0].edge_v", "zero area"])),
    (
        "native/zero-area-emissive-mesh.toml",
        Warning("zero area and emits no light"),
    ),
    ("native/ior-zero.toml", Error(&["material[0].ior", "positive"])),
    ("native/ior-negative.toml", Error(&["material[0].ior", "positive"])),
    ("native/index-out-of-range.toml", Error(&["shape[0].indices", "7"])),
    ("native/negative-index.toml", Error(&["shape[0].indices"])),
    ("native/absurd-width.toml", Error(&["render.width", "65536"])),
    (
        "native/absurd-pixels.toml",
        Error(&["render.width", "larger than the limit"]),
    ),
    ("native/absurd-spp.toml", Error(&["render.spp"])),
    (
        "native/filter-foreign-parameter.toml",
        Error(&["filter-foreign-parameter.toml:5:", "filter_tau", "lanczos"]),
    ),
    (
        "native/filter-narrow-lanczos-window.toml",
        Error(&["filter-narrow-lanczos-window.toml:5:", "filter_tau", "at least 0.1"]),
    ),
    (
        "native/filter-wide-lanczos.toml",
        Error(&["filter-wide-lanczos.toml:5:", "filter_radius", "negative lobes"]),
    ),
    (
        "native/filter-wide-y-radius.toml",
        Error(&[
            "filter-wide-y-radius.toml:5:17",
            "filter_y_radius",
            "at most 16 pixels, got 20",
        ]),
    ),
    (
        "native/absurd-sphere-mesh.toml",
        Error(&["shape[0].segments", "50 million"]),
    ),
    ("native/missing-material.toml", Error(&["shape[0].material", "chrome"])),
    ("native/missing-mesh-file.toml", Error(&["shape[0].file", "teapot.obj"])),
    ("native/missing-texture.toml", Error(&["texture[0].file", "wood.png"])),
    (
        "native/nan-texture.toml",
        Warning("texels are NaN, infinite or negative"),
    ),
    (
        "native/nan-environment.toml",
        Warning("texels are NaN, infinite or negative"),
    ),
    ("native/not-utf8.toml", Error(&["not-utf8.toml:1:1", "UTF-8"])),
    (
        "native/sdf-negative-box.toml",
        Error(&["sdf-negative-box.toml:13:42", "shape[0].sdf.union[1].box", "positive"]),
    ),
    ("native/sdf-two-kinds.toml", Error(&["shape[0].sdf", "one kind"])),
    ("native/sdf-unbounded.toml", Error(&["shape[0].sdf", "unbounded"])),
    (
        "native/sdf-overlapping-repeat.toml",
        Error(&["shape[0].sdf.repeat", "overlap"]),
    ),
    (
        "native/sdf-absurd-iterations.toml",
        Error(&["shape[0].sdf.iterations", "64"]),
    ),
    ("native/sdf-nan-rate.toml", Error(&["shape[0].sdf.twist", "finite"])),
    ("native/sdf-absurd-steps.toml", Error(&["shape[0].max_steps"])),
    (
        "native/sdf-too-deep.toml",
        Error(&["sdf-too-deep.toml:13:", "nest at most 64"]),
    ),
    (
        "native/implicit-unknown-name.toml",
        Error(&["implicit-unknown-name.toml:13:25", "shape[0].equation", "\"w\""]),
    ),
    (
        "native/implicit-flat-bounds.toml",
        Error(&["shape[0].bounds", "min below max"]),
    ),
    ("native/implicit-no-bounds.toml", Error(&["shape[0].bounds", "missing"])),
    (
        "native/implicit-unclosed.toml",
        Error(&["shape[0].equation", "expected ')'"]),
    ),
    // Mitsuba 3 XML
    ("mitsuba/truncated.xml", Error(&["truncated.xml:"])),
    ("mitsuba/wrong-type.xml", Error(&["wrong-type.xml:", "radius"])),
    ("mitsuba/nan-radius.xml", Error(&["nan-radius.xml:", "radius"])),
    (
        "mitsuba/infinite-radius.xml",
        Error(&["infinite-radius.xml:", "radius"]),
    ),
    (
        "mitsuba/negative-radius.xml",
        Error(&["negative-radius.xml:", "radius"]),
    ),
    ("mitsuba/ior-zero.xml", Error(&["ior-zero.xml:", "ior"])),
    ("mitsuba/ior-negative.xml", Error(&["ior-negative.xml:", "ior"])),
    (
        "mitsuba/missing-reference.xml",
        Error(&["missing-reference.xml:", "gold"]),
    ),
    (
        "mitsuba/absurd-resolution.xml",
        Error(&["absurd-resolution.xml:", "width"]),
    ),
    (
        "mitsuba/absurd-spp.xml",
        Error(&["absurd-spp.xml:3:33", "sample_count", "-5"]),
    ),
    ("mitsuba/missing-mesh-file.xml", Error(&["teapot.obj"])),
    (
        "mitsuba/zero-area-light.xml",
        Error(&["zero-area-light.xml:", "transform"]),
    ),
    ("mitsuba/include-loop.xml", Error(&["include loop"])),
    (
        "mitsuba/unknown-plugin.xml",
        Error(&[
            "unknown-plugin.xml:6:3",
            "unknown plugin type \"spherez\"",
            "\"sphere\"?",
        ]),
    ),
    (
        "mitsuba/duplicate-id.xml",
        Error(&["duplicate-id.xml:7:3", "duplicate id \"white\"", "duplicate-id.xml:6:3"]),
    ),
    ("mitsuba/include-loop-b.xml", Error(&["include loop"])),
    (
        "mitsuba/undefined-parameter.xml",
        Error(&["undefined-parameter.xml:", "$radius"]),
    ),
    // pbrt-v4
    ("pbrt/truncated.pbrt", Error(&["truncated.pbrt:"])),
    ("pbrt/wrong-type.pbrt", Error(&["wrong-type.pbrt:", "radius"])),
    ("pbrt/nan-radius.pbrt", Error(&["nan-radius.pbrt:"])),
    ("pbrt/infinite-translate.pbrt", Error(&["infinite-translate.pbrt:"])),
    ("pbrt/negative-radius.pbrt", Error(&["negative-radius.pbrt:", "radius"])),
    ("pbrt/zero-radius.pbrt", Error(&["zero-radius.pbrt:", "radius"])),
    (
        "pbrt/degenerate-triangles.pbrt",
        Warning("1 of 2 triangles have zero area"),
    ),
    (
        "pbrt/index-out-of-range.pbrt",
        Error(&["index-out-of-range.pbrt:", "9"]),
    ),
    ("pbrt/zero-area-light.pbrt", Warning("zero area and emits no light")),
    ("pbrt/ior-zero.pbrt", Error(&["ior-zero.pbrt:", "eta"])),
    ("pbrt/ior-negative.pbrt", Error(&["ior-negative.pbrt:", "eta"])),
    ("pbrt/missing-material.pbrt", Error(&["missing-material.pbrt:", "gold"])),
    ("pbrt/missing-instance.pbrt", Error(&["missing-instance.pbrt:", "tree"])),
    ("pbrt/missing-mesh-file.pbrt", Error(&["bunny.ply"])),
    (
        "pbrt/missing-measured-file.pbrt",
        Error(&["missing-measured-file.pbrt:7:", "paint.bsdf"]),
    ),
    (
        "pbrt/curve-too-few-points.pbrt",
        Error(&["curve-too-few-points.pbrt:8:", "3 control points", "4 + n·3"]),
    ),
    (
        "pbrt/ribbon-without-normals.pbrt",
        Error(&["ribbon-without-normals.pbrt:7:", "normals"]),
    ),
    (
        "pbrt/projection-without-image.pbrt",
        Error(&["projection-without-image.pbrt:6:", "filename"]),
    ),
    ("pbrt/projection-missing-image.pbrt", Error(&["slide.png"])),
    (
        "pbrt/absurd-resolution.pbrt",
        Error(&["absurd-resolution.pbrt:", "resolution"]),
    ),
    ("pbrt/absurd-spp.pbrt", Error(&["absurd-spp.pbrt:", "pixelsamples"])),
    (
        "pbrt/transform-times-backwards.pbrt",
        Error(&[
            "transform-times-backwards.pbrt:1:1",
            "TransformTimes",
            "start time before the end",
        ]),
    ),
    ("pbrt/include-loop.pbrt", Error(&["include-loop.pbrt:", "loop"])),
    ("pbrt/include-loop-a.pbrt", Error(&["loop"])),
    ("pbrt/include-loop-b.pbrt", Error(&["loop"])),
    // OBJ (lone models)
    ("obj/index-out-of-range.obj", Error(&["index-out-of-range.obj"])),
    (
        "obj/negative-index-out-of-range.obj",
        Error(&["negative-index-out-of-range.obj"]),
    ),
    ("obj/zero-index.obj", Error(&["zero-index.obj"])),
    ("obj/huge-index.obj", Error(&["huge-index.obj"])),
    ("obj/nan-vertex.obj", Error(&["nan-vertex.obj", "NaN or infinite"])),
    (
        "obj/infinite-vertex.obj",
        Error(&["infinite-vertex.obj", "NaN or infinite"]),
    ),
    ("obj/wrong-type.obj", Error(&["wrong-type.obj"])),
    ("obj/truncated.obj", Error(&["truncated.obj"])),
    ("obj/no-faces.obj", Error(&["no-faces.obj", "no faces"])),
    (
        "obj/degenerate-triangles.obj",
        Warning("1 of 2 triangles have zero area"),
    ),
    ("obj/missing-mtl.obj", Warning("MTL")),
    ("obj/bad-mtl.obj", Warning("wood.png")),
    ("obj/bad-mtl.mtl", Error(&["unknown scene format"])),
    // PLY (lone models)
    // Mitsuba's serialized meshes, rendered as models
    ("serialized/good-triangle.serialized", Warning("")),
    // Its table names a second mesh past the end; the first renders.
    ("serialized/offset-past-the-end.serialized", Warning("")),
    (
        "serialized/index-out-of-range.serialized",
        Error(&["index-out-of-range.serialized:", "face 0 uses vertex 9"]),
    ),
    (
        "serialized/lying-counts.serialized",
        Error(&["lying-counts.serialized:", "the data ends in the positions"]),
    ),
    (
        "serialized/nan-position.serialized",
        Error(&["nan-position.serialized:", "NaN or infinite"]),
    ),
    (
        "serialized/not-zlib.serialized",
        Error(&["not-zlib.serialized:", "zlib"]),
    ),
    (
        "serialized/truncated-header.serialized",
        Error(&["truncated-header.serialized:", "ends before the mesh header"]),
    ),
    ("ply/valid.ply", Warning("")),
    ("ply/truncated.ply", Error(&["truncated.ply:"])),
    ("ply/wrong-type.ply", Error(&["wrong-type.ply:", "zero"])),
    ("ply/nan-vertex.ply", Error(&["nan-vertex.ply"])),
    ("ply/index-out-of-range.ply", Error(&["index-out-of-range.ply", "7"])),
    ("ply/negative-index.ply", Error(&["negative-index.ply"])),
    (
        "ply/degenerate-triangles.ply",
        Warning("1 of 2 triangles have zero area"),
    ),
    ("ply/absurd-count.ply", Error(&["absurd-count.ply:"])),
    ("ply/negative-list-count.ply", Error(&["negative-list-count.ply:"])),
    ("ply/binary-valid.ply", Warning("")),
    ("ply/binary-truncated.ply", Error(&["binary-truncated.ply"])),
    ("ply/binary-absurd-list.ply", Error(&["binary-absurd-list.ply"])),
    ("ply/binary-absurd-count.ply", Error(&["binary-absurd-count.ply"])),
    ("ply/binary-infinite-vertex.ply", Error(&["binary-infinite-vertex.ply"])),
    ("ply/not-ply.ply", Error(&["not-ply.ply"])),
    // glTF 2.0
    ("gltf/valid.glb", Warning("")),
    ("gltf/valid.gltf", Warning("")),
    ("gltf/truncated.gltf", Error(&["truncated.gltf:"])),
    ("gltf/truncated.glb", Error(&["truncated.glb"])),
    ("gltf/absurd-count.glb", Error(&["absurd-count.glb", "accessors[0]"])),
    ("gltf/index-out-of-range.glb", Error(&["index-out-of-range.glb", "9"])),
    ("gltf/nan-vertex.glb", Error(&["nan-vertex.glb"])),
    ("gltf/zero-area-light.glb", Warning("zero area and emits no light")),
    (
        "gltf/ior-negative.glb",
        Warning("index of refraction -1 is unsupported: 1.5 is used"),
    ),
    (
        "gltf/wrong-type.glb",
        Error(&["wrong-type.glb (JSON chunk):1:", "invalid type"]),
    ),
    ("gltf/missing-buffer.gltf", Error(&["missing-buffer.gltf", "mesh.bin"])),
    ("gltf/node-cycle.glb", Error(&["node-cycle.glb", "cycle"])),
    (
        "gltf/version-1.gltf",
        Error(&["version-1.gltf:3:", "asset.version", "glTF 1.0 is not supported"]),
    ),
    (
        "gltf/position-ubyte.gltf",
        Error(&[
            "position-ubyte.gltf:",
            "accessors[0].componentType",
            "POSITION cannot have components of type UNSIGNED_BYTE",
        ]),
    ),
    (
        "gltf/missing-material.glb",
        Error(&["missing-material.glb", "material"]),
    ),
    (
        "gltf/absurd-chunk-length.glb",
        Error(&["absurd-chunk-length.glb", "chunk"]),
    ),
];

/// Signed distance grids (`.vol`), each rendered as the `sdfgrid` of a
/// Mitsuba scene: their errors.
const VOLUME_CASES: &[(&str, Option<&[&str]>)] = &[
    ("sdfgrid/sphere.vol", None),
    (
        "sdfgrid/all-positive.vol",
        Some(&["all-positive.vol", "all of one sign"]),
    ),
    ("sdfgrid/nan-value.vol", Some(&["nan-value.vol", "NaN or infinite"])),
    (
        "sdfgrid/inf-and-zero.vol",
        Some(&["inf-and-zero.vol", "NaN or infinite"]),
    ),
    ("sdfgrid/one-value-wide.vol", Some(&["one-value-wide.vol", "no cells"])),
    ("sdfgrid/huge-header.vol", Some(&["huge-header.vol", "more than"])),
];

#[test]
fn malformed_measured_bsdfs_are_errors_naming_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("paint.pbrt");
    let mut failures = Vec::new();
    for (rel, parts) in MEASURED_CASES {
        let file = corpus(rel);
        std::fs::write(
            &scene,
            format!(
                "WorldBegin\nMaterial \"measured\" \"string filename\" \"{}\"\nShape \"sphere\"\n",
                file.display()
            ),
        )
        .unwrap();
        let args = [
            "render",
            "paint.pbrt",
            "-o",
            "out.png",
            "--width",
            "8",
            "--height",
            "8",
            "--spp",
            "1",
            "-q",
        ];
        let (code, err) = run(&args, dir.path());
        if !(code == Some(2) && err.starts_with("error: ") && parts.iter().all(|p| err.contains(p))) {
            failures.push(format!("{rel}: expected exit 2 with {parts:?}, got {code:?}: {err}"));
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

/// Damaged measured BSDF files (tests/malformed/measured) and what the
/// error must say, besides the scene's line and the file's name.
const MEASURED_CASES: &[(&str, &[&str])] = &[
    (
        "measured/not-a-tensor.bsdf",
        &["paint.pbrt:2:", "not-a-tensor.bsdf", "not a tensor file"],
    ),
    (
        "measured/truncated-header.bsdf",
        &["truncated-header.bsdf", "truncated"],
    ),
    (
        "measured/field-past-end.bsdf",
        &["field-past-end.bsdf", "\"theta_i\" lies past the end"],
    ),
    (
        "measured/missing-fields.bsdf",
        &["missing-fields.bsdf", "no \"phi_i\" field"],
    ),
];

#[test]
fn malformed_sdf_grids_are_errors_naming_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("grid.xml");
    let mut failures = Vec::new();
    for (rel, expect) in VOLUME_CASES {
        let file = corpus(rel);
        std::fs::write(
            &scene,
            format!(
                r#"<scene version="3.0.0"><shape type="sdfgrid"><string name="filename" value="{}"/></shape></scene>"#,
                file.display()
            ),
        )
        .unwrap();
        let args = [
            "render", "grid.xml", "-o", "out.png", "--width", "8", "--height", "8", "--spp", "1", "-q",
        ];
        let (code, err) = run(&args, dir.path());
        match expect {
            None if code != Some(0) => failures.push(format!("{rel}: expected to render, got {code:?}: {err}")),
            Some(parts)
                if !(code == Some(2) && err.starts_with("error: ") && parts.iter().all(|p| err.contains(p))) =>
            {
                failures.push(format!("{rel}: expected exit 2 with {parts:?}, got {code:?}: {err}"))
            }
            _ => {}
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

/// NanoVDB files, read as the density of a pbrt-v4 `nanovdb` medium: each
/// an error (exit 2) naming the scene's line, the file and the problem.
const NANOVDB_CASES: &[(&str, &[&str])] = &[
    ("nanovdb/blosc.nvdb", &["blosc.nvdb", "Blosc"]),
    (
        "nanovdb/version-29.nvdb",
        &["version-29.nvdb", "version 29.3.0 is unsupported"],
    ),
    (
        "nanovdb/bad-child-offset.nvdb",
        &["bad-child-offset.nvdb", "points outside"],
    ),
    ("nanovdb/huge-grid-size.nvdb", &["huge-grid-size.nvdb", "more than"]),
    ("nanovdb/doubles.nvdb", &["doubles.nvdb", "double values"]),
    ("nanovdb/corrupt-zip.nvdb", &["corrupt-zip.nvdb", "corrupt"]),
    ("nanovdb/truncated.nvdb", &["truncated.nvdb", "ends inside"]),
    ("nanovdb/not-nanovdb.nvdb", &["not-nanovdb.nvdb", "not a NanoVDB file"]),
];

#[test]
fn malformed_nanovdb_files_are_errors_naming_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("smoke.pbrt");
    let mut failures = Vec::new();
    for (rel, parts) in NANOVDB_CASES {
        std::fs::write(
            &scene,
            format!(
                "WorldBegin\nMakeNamedMedium \"s\" \"string type\" \"nanovdb\" \"string filename\" \"{}\"\nShape \"sphere\"\n",
                corpus(rel).display()
            ),
        )
        .unwrap();
        let args = [
            "render",
            "smoke.pbrt",
            "-o",
            "out.png",
            "--width",
            "8",
            "--height",
            "8",
            "--spp",
            "1",
            "-q",
        ];
        let (code, err) = run(&args, dir.path());
        if !(code == Some(2)
            && err.starts_with("error: ")
            && err.contains("smoke.pbrt:2:")
            && parts.iter().all(|p| err.contains(p)))
        {
            failures.push(format!("{rel}: expected exit 2 with {parts:?}, got {code:?}: {err}"));
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

/// Image files, read by `trazo diff FILE FILE`: their errors.
const IMAGE_CASES: &[(&str, Option<&[&str]>)] = &[
    ("image/valid.png", None),
    ("image/valid.pfm", None),
    ("image/nan-pixels.pfm", None),
    ("image/truncated.png", Some(&["truncated.png"])),
    (
        "image/absurd-size.png",
        Some(&["absurd-size.png", "larger than the limit"]),
    ),
    ("image/truncated.pfm", Some(&["truncated.pfm", "need"])),
    ("image/absurd-size.pfm", Some(&["absurd-size.pfm", "need"])),
    ("image/negative-size.pfm", Some(&["negative-size.pfm", "width"])),
    ("image/truncated.hdr", Some(&["truncated.hdr"])),
    (
        "image/absurd-size.hdr",
        Some(&["absurd-size.hdr", "larger than the limit"]),
    ),
    ("image/garbage.exr", Some(&["garbage.exr", "OpenEXR"])),
    ("image/valid.exr", None),
    ("image/empty.pfm", Some(&["empty.pfm", "no pixels"])),
    ("image/truncated.exr", Some(&["truncated.exr", "OpenEXR"])),
    (
        "image/absurd-size.exr",
        Some(&["absurd-size.exr", "larger than the limit"]),
    ),
    (
        "image/lying-size.exr",
        Some(&["lying-size.exr", "more than a file of 562 bytes can hold"]),
    ),
];

fn trazo() -> Command {
    Command::cargo_bin("trazo").unwrap()
}

/// Runs trazo; returns (exit status, stderr) after checking it did not panic.
fn run(args: &[&str], cwd: &Path) -> (Option<i32>, String) {
    let out = trazo().current_dir(cwd).args(args).output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr).into_owned();
    assert!(!err.contains("panicked"), "trazo {args:?} panicked: {err}");
    (out.status.code(), err)
}

#[test]
fn every_malformed_scene_gives_a_clear_error_or_a_warned_fallback() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out.png");
    let out = out.to_str().unwrap();
    let mut failures = Vec::new();
    for (rel, expect) in CASES {
        let file = corpus(rel);
        let file = file.to_str().unwrap();
        let args = [
            "render",
            file,
            "-o",
            out,
            "--width",
            "8",
            "--height",
            "8",
            "--spp",
            "1",
            "-q",
            "--max-memory",
            "1G",
        ];
        let (code, err) = run(&args, dir.path());
        let lines: Vec<&str> = err.lines().filter(|l| !l.trim().is_empty()).collect();
        match expect {
            Error(parts) => {
                // One error line, last; the warnings given before the
                // error, if any, come first.
                let (error, before) = lines.split_last().unwrap_or((&"", &[]));
                let ok = code == Some(2)
                    && error.starts_with("error: ")
                    && parts.iter().all(|p| error.contains(p))
                    && before.iter().all(|l| l.starts_with("warning: "));
                if !ok {
                    failures.push(format!(
                        "{rel}: expected exit 2 and one error line with {parts:?} (after any warnings), got {code:?}: {err}"
                    ));
                }
            }
            Warning(part) => {
                let ok = code == Some(0) && err.lines().any(|l| l.starts_with("warning: ") && l.contains(part))
                    || part.is_empty() && code == Some(0);
                if !ok {
                    failures.push(format!(
                        "{rel}: expected an image and a warning with {part:?}, got {code:?}: {err}"
                    ));
                }
            }
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

#[test]
fn malformed_images_are_errors_naming_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let mut failures = Vec::new();
    for (rel, expect) in IMAGE_CASES {
        let file = corpus(rel);
        let file = file.to_str().unwrap();
        let (code, err) = run(&["diff", file, file], dir.path());
        match expect {
            None if code != Some(0) => failures.push(format!("{rel}: expected to read, got {code:?}: {err}")),
            Some(parts)
                if !(code == Some(2) && err.starts_with("error: ") && parts.iter().all(|p| err.contains(p))) =>
            {
                failures.push(format!("{rel}: expected exit 2 with {parts:?}, got {code:?}: {err}"))
            }
            _ => {}
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

#[test]
fn the_corpus_and_the_table_agree() {
    let listed: std::collections::HashSet<&str> = CASES
        .iter()
        .map(|c| c.0)
        .chain(IMAGE_CASES.iter().map(|c| c.0))
        .chain(VOLUME_CASES.iter().map(|c| c.0))
        .chain(MEASURED_CASES.iter().map(|c| c.0))
        .chain(NANOVDB_CASES.iter().map(|c| c.0))
        .collect();
    for dir in std::fs::read_dir(corpus("")).unwrap() {
        let dir = dir.unwrap().path();
        for f in std::fs::read_dir(&dir).unwrap() {
            let f = f.unwrap().path();
            let rel = format!(
                "{}/{}",
                dir.file_name().unwrap().to_str().unwrap(),
                f.file_name().unwrap().to_str().unwrap()
            );
            assert!(
                listed.contains(rel.as_str()),
                "{rel} has no expected outcome in tests/integration/malformed.rs"
            );
        }
    }
}

/// Valid files of each format, cut at many lengths and fed to the fuzzing
/// entry points (which read, build and render what parses).
#[test]
fn truncated_files_never_panic_or_allocate_by_untrusted_counts() {
    let files: &[(&str, trazo::fuzz::Target)] = &[
        ("../../scenes/cornell-box.toml", trazo::fuzz::native),
        ("../../tools/crosscheck/scenes/cornell-box.xml", trazo::fuzz::mitsuba),
        ("../../scenes/pbrt/cornell-box.pbrt", trazo::fuzz::pbrt),
        ("obj/degenerate-triangles.obj", trazo::fuzz::obj),
        ("ply/valid.ply", trazo::fuzz::ply),
        ("ply/binary-valid.ply", trazo::fuzz::ply),
        ("gltf/valid.glb", trazo::fuzz::gltf),
        ("gltf/valid.gltf", trazo::fuzz::gltf),
        ("serialized/good-triangle.serialized", trazo::fuzz::serialized),
        ("sdfgrid/sphere.vol", trazo::fuzz::sdfgrid),
        ("../data/nanovdb/smoke.nvdb", trazo::fuzz::nanovdb),
    ];
    for (rel, read) in files {
        let bytes = std::fs::read(corpus(rel)).unwrap();
        let step = (bytes.len() / 97).max(1);
        for len in (0..bytes.len()).step_by(step).chain([bytes.len()]) {
            LARGEST_ALLOCATION.store(0, Ordering::Relaxed);
            read(&bytes[..len]);
            let largest = LARGEST_ALLOCATION.load(Ordering::Relaxed);
            assert!(
                largest < 64 << 20,
                "{rel} cut to {len} bytes made an allocation of {largest} bytes"
            );
            assert!(len < bytes.len() || largest > 0, "the allocator is not watched");
        }
    }
    for rel in [
        "image/valid.png",
        "image/valid.pfm",
        "image/nan-pixels.pfm",
        "image/valid.exr",
    ] {
        let bytes = std::fs::read(corpus(rel)).unwrap();
        for len in 0..bytes.len() {
            for format in 0..5u8 {
                let mut input = vec![format];
                input.extend_from_slice(&bytes[..len]);
                trazo::fuzz::image(&input);
            }
        }
    }
}
