//! Intel Open Image Denoise (OIDN 2), loaded at run time.
//!
//! OIDN is a C++ library with a C API; it is not in Debian, and the `oidn`
//! crate needs it at build time. trazo instead opens the shared library when
//! asked to denoise, so that it always builds and runs, and denoises with
//! OIDN wherever the library is present. `tools/oidn/setup` installs it from
//! PyPI (the `pyoidn` wheel ships `libOpenImageDenoise` with its CPU device
//! and TBB) and prints its path.
//!
//! The library is looked for, in order:
//!
//! 1. at `$TRAZO_OIDN` (the library file, or the folder holding it);
//! 2. in `tools/oidn/.venv` of the source tree trazo was built from;
//! 3. by the system's loader (`libOpenImageDenoise.so.2`, e.g. an OIDN
//!    release unpacked and put on `LD_LIBRARY_PATH`).
//!
//! This module is trazo's only unsafe code: calling a C function through
//! a pointer read from a shared library cannot be checked by the compiler.
//! The calls follow OIDN's documented C API (`oidn.h` of OIDN 2.x): the
//! eleven functions below, with the image buffers owned by this function
//! and alive until the filter has run.

#![allow(unsafe_code)]

use super::{DenoiseInput, Denoised};
use crate::color::Rgb;
use crate::error::{Error, Result};
use crate::film::Image;
use std::ffi::{CStr, c_char, c_int, c_void};
use std::path::{Path, PathBuf};

#[cfg(target_os = "windows")]
const LIB_NAMES: [&str; 1] = ["OpenImageDenoise.dll"];
#[cfg(target_os = "macos")]
const LIB_NAMES: [&str; 2] = ["libOpenImageDenoise.2.dylib", "libOpenImageDenoise.dylib"];
#[cfg(not(any(target_os = "windows", target_os = "macos")))]
const LIB_NAMES: [&str; 2] = ["libOpenImageDenoise.so.2", "libOpenImageDenoise.so"];

/// The environment variable that names the library (or its folder).
pub const ENV_VAR: &str = "TRAZO_OIDN";

/// `OIDN_DEVICE_TYPE_CPU`: shared host buffers need the CPU device.
const DEVICE_CPU: c_int = 1;
/// `OIDN_FORMAT_FLOAT3`.
const FORMAT_FLOAT3: c_int = 3;
/// `OIDN_ERROR_NONE`.
const ERROR_NONE: c_int = 0;

/// An opened Open Image Denoise library.
pub struct Library {
    lib: libloading::Library,
    path: PathBuf,
}

impl std::fmt::Debug for Library {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Library").field("path", &self.path).finish()
    }
}

/// Where the library may be, in the order tried.
pub fn candidates() -> Vec<PathBuf> {
    if let Some(v) = std::env::var_os(ENV_VAR) {
        let p = PathBuf::from(v);
        return if p.is_dir() {
            LIB_NAMES.iter().map(|n| p.join(n)).collect()
        } else {
            vec![p]
        };
    }
    let mut v = Vec::new();
    let venv_lib = Path::new(env!("CARGO_MANIFEST_DIR")).join("tools/oidn/.venv/lib");
    if let Ok(entries) = std::fs::read_dir(&venv_lib) {
        let mut pythons: Vec<PathBuf> = entries.filter_map(|e| e.ok().map(|e| e.path())).collect();
        pythons.sort();
        for py in pythons {
            let dir = py.join("site-packages/pyoidn/oidn/lib");
            v.extend(LIB_NAMES.iter().map(|n| dir.join(n)));
        }
    }
    v.extend(LIB_NAMES.iter().map(PathBuf::from));
    v
}

impl Library {
    /// Opens the first library found among [`candidates`].
    pub fn find() -> Result<Library> {
        let mut tried = Vec::new();
        for path in candidates() {
            // A bare name goes to the system's loader; a path must exist.
            if path.components().count() > 1 && !path.exists() {
                tried.push(format!("{} (absent)", path.display()));
                continue;
            }
            // SAFETY: opening runs the library's initialisers; OIDN's do not
            // depend on anything of ours.
            match unsafe { libloading::Library::new(&path) } {
                Ok(lib) => return Ok(Library { lib, path }),
                Err(e) => tried.push(format!("{}: {e}", path.display())),
            }
        }
        Err(Error::Invalid(format!(
            "Intel Open Image Denoise was not found: run tools/oidn/setup (it installs the library from PyPI), \
             or set {ENV_VAR} to libOpenImageDenoise; for the built-in filter use --denoise=atrous (in `trazo compare`, the suffix +atrous) (tried: {})",
            tried.join("; ")
        )))
    }

    /// Where the library was found.
    pub fn path(&self) -> &Path {
        &self.path
    }
}

type Device = *mut c_void;
type Filter = *mut c_void;

/// Denoises with OIDN's "RT" filter (HDR colour, albedo and normal guides).
pub fn denoise(input: &DenoiseInput) -> Result<Denoised> {
    let lib = Library::find()?;
    let (w, h) = (input.color.width as usize, input.color.height as usize);
    let flat = |img: &Image| -> Vec<f32> { img.pixels.iter().flat_map(|p| [p.x, p.y, p.z]).collect() };
    let mut color = flat(input.color);
    // OIDN expects finite, non-negative HDR colour.
    for v in &mut color {
        if !v.is_finite() || *v < 0.0 {
            *v = 0.0;
        }
    }
    let mut albedo = flat(input.albedo);
    for v in &mut albedo {
        *v = v.clamp(0.0, 1.0);
    }
    let mut normal = flat(input.normal);
    let mut output = vec![0.0f32; w * h * 3];
    let (version, result) = run_filter(&lib, w, h, &mut color, &mut albedo, &mut normal, &mut output)?;
    result?;
    Ok(Denoised {
        image: Image {
            width: input.color.width,
            height: input.color.height,
            pixels: output.chunks_exact(3).map(|c| Rgb::new(c[0], c[1], c[2])).collect(),
        },
        denoiser: format!(
            "Intel Open Image Denoise {}.{}.{} ({})",
            version / 10000,
            version / 100 % 100,
            version % 100,
            lib.path().display()
        ),
    })
}

fn symbol_error(e: libloading::Error) -> Error {
    Error::Invalid(format!("Open Image Denoise library without an expected function: {e}"))
}

/// Runs the filter; returns OIDN's version and the outcome of the run.
#[allow(clippy::too_many_arguments)]
fn run_filter(
    lib: &Library,
    w: usize,
    h: usize,
    color: &mut [f32],
    albedo: &mut [f32],
    normal: &mut [f32],
    output: &mut [f32],
) -> Result<(i32, Result<()>)> {
    // SAFETY: each signature is the one declared in oidn.h (OIDN 2.x); the
    // handles are used only between their creation and release below; the
    // buffers hold w·h·3 floats, outlive the filter's execution, and only
    // `output` is written to.
    unsafe {
        let l = &lib.lib;
        let new_device: libloading::Symbol<unsafe extern "C" fn(c_int) -> Device> =
            l.get(b"oidnNewDevice\0").map_err(symbol_error)?;
        let commit_device: libloading::Symbol<unsafe extern "C" fn(Device)> =
            l.get(b"oidnCommitDevice\0").map_err(symbol_error)?;
        let release_device: libloading::Symbol<unsafe extern "C" fn(Device)> =
            l.get(b"oidnReleaseDevice\0").map_err(symbol_error)?;
        let get_device_int: libloading::Symbol<unsafe extern "C" fn(Device, *const c_char) -> c_int> =
            l.get(b"oidnGetDeviceInt\0").map_err(symbol_error)?;
        let get_error: libloading::Symbol<unsafe extern "C" fn(Device, *mut *const c_char) -> c_int> =
            l.get(b"oidnGetDeviceError\0").map_err(symbol_error)?;
        let new_filter: libloading::Symbol<unsafe extern "C" fn(Device, *const c_char) -> Filter> =
            l.get(b"oidnNewFilter\0").map_err(symbol_error)?;
        #[allow(clippy::type_complexity)]
        let set_image: libloading::Symbol<
            unsafe extern "C" fn(Filter, *const c_char, *mut c_void, c_int, usize, usize, usize, usize, usize),
        > = l.get(b"oidnSetSharedFilterImage\0").map_err(symbol_error)?;
        let set_bool: libloading::Symbol<unsafe extern "C" fn(Filter, *const c_char, bool)> =
            l.get(b"oidnSetFilterBool\0").map_err(symbol_error)?;
        let commit_filter: libloading::Symbol<unsafe extern "C" fn(Filter)> =
            l.get(b"oidnCommitFilter\0").map_err(symbol_error)?;
        let execute_filter: libloading::Symbol<unsafe extern "C" fn(Filter)> =
            l.get(b"oidnExecuteFilter\0").map_err(symbol_error)?;
        let release_filter: libloading::Symbol<unsafe extern "C" fn(Filter)> =
            l.get(b"oidnReleaseFilter\0").map_err(symbol_error)?;

        let check = |device: Device| -> Result<()> {
            let mut message: *const c_char = std::ptr::null();
            let code = get_error(device, &mut message);
            if code == ERROR_NONE {
                return Ok(());
            }
            let text = if message.is_null() {
                String::from("no message")
            } else {
                CStr::from_ptr(message).to_string_lossy().into_owned()
            };
            Err(Error::Invalid(format!(
                "Open Image Denoise failed (error {code}): {text}"
            )))
        };

        let device = new_device(DEVICE_CPU);
        if device.is_null() {
            return Err(Error::Invalid(
                "Open Image Denoise could not create a CPU device".into(),
            ));
        }
        commit_device(device);
        if let Err(e) = check(device) {
            release_device(device);
            return Err(e);
        }
        let version = get_device_int(device, c"version".as_ptr());
        let filter = new_filter(device, c"RT".as_ptr());
        let outcome = if filter.is_null() {
            check(device).and(Err(Error::Invalid(
                "Open Image Denoise could not create its RT filter".into(),
            )))
        } else {
            for (name, buf) in [
                (c"color", color.as_mut_ptr()),
                (c"albedo", albedo.as_mut_ptr()),
                (c"normal", normal.as_mut_ptr()),
                (c"output", output.as_mut_ptr()),
            ] {
                set_image(filter, name.as_ptr(), buf.cast(), FORMAT_FLOAT3, w, h, 0, 0, 0);
            }
            set_bool(filter, c"hdr".as_ptr(), true);
            commit_filter(filter);
            let r = check(device).and_then(|_| {
                execute_filter(filter);
                check(device)
            });
            release_filter(filter);
            r
        };
        release_device(device);
        Ok((version, outcome))
    }
}
