//! `trazo._trazo`: the renderer as a Python extension module. The Python
//! package (`python/trazo/__init__.py`) wraps it with keyword arguments,
//! progress bars and dictionary scenes; this module maps those calls onto
//! the library's and its results onto NumPy arrays.
//!
//! A render runs on a thread of its own while the calling thread waits
//! without the GIL, waking every 20 ms to let Python see Ctrl-C: an
//! interrupt cancels the render (which stops within a tile row) and is
//! raised as `KeyboardInterrupt` once the render has stopped.

use numpy::ndarray::Array3;
use numpy::{IntoPyArray, PyArray3, PyReadonlyArray3, PyUntypedArrayMethods};
use pyo3::create_exception;
use pyo3::exceptions::{PyException, PyKeyboardInterrupt};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use std::path::{Path, PathBuf};
use std::sync::Mutex;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;
use trazo::film::{Aov, Film, Image};
use trazo::render::{Control, RenderOptions, RenderStats, render_controlled};
use trazo::scene::{self, SceneDesc};
use trazo::settings::{IntegratorKind, PathSampling, Tonemap};

create_exception!(
    _trazo,
    TrazoError,
    PyException,
    "A scene, image or setting trazo cannot use; the message names the file, line, column and key where there is one."
);

/// trazo's error as a Python exception, after the warnings it carries.
fn error(e: trazo::Error) -> PyErr {
    let mut text = String::new();
    for w in e.warnings() {
        text.push_str(&format!("warning: {w}\n"));
    }
    text.push_str(&e.to_string());
    TrazoError::new_err(text)
}

/// A loaded scene description; each render builds it with its overrides.
#[pyclass(module = "trazo._trazo", frozen)]
struct Scene {
    desc: SceneDesc,
    /// Where it came from, for `repr`.
    origin: String,
}

#[pymethods]
impl Scene {
    /// Image width in pixels.
    #[getter]
    fn width(&self) -> u32 {
        self.desc.settings.width
    }

    /// Image height in pixels.
    #[getter]
    fn height(&self) -> u32 {
        self.desc.settings.height
    }

    /// Samples per pixel the scene asks for.
    #[getter]
    fn spp(&self) -> u32 {
        self.desc.settings.spp
    }

    /// The algorithm the scene asks for.
    #[getter]
    fn integrator(&self) -> &'static str {
        self.desc.settings.integrator.name()
    }

    /// What the reader could not honour, one line each.
    #[getter]
    fn warnings(&self) -> Vec<String> {
        self.desc.warnings.clone()
    }

    fn __repr__(&self) -> String {
        let s = &self.desc.settings;
        format!(
            "<trazo.Scene {}: {}×{}, {} spp, {}>",
            self.origin,
            s.width,
            s.height,
            s.spp,
            s.integrator.name()
        )
    }
}

/// Loads a scene file (any format `trazo render` reads) with `$name`
/// parameters.
#[pyfunction]
fn load(path: PathBuf, defines: Vec<(String, String)>) -> PyResult<Scene> {
    let desc = scene::load(&path, &defines).map_err(error)?;
    Ok(Scene {
        desc,
        origin: path.display().to_string(),
    })
}

/// Parses a scene in trazo's TOML format; `name` stands for its file in
/// messages, and relative file names are resolved against its folder.
#[pyfunction]
fn load_toml(text: &str, name: &str) -> PyResult<Scene> {
    let desc = scene::native::parse(text, Path::new(name)).map_err(error)?;
    Ok(Scene {
        desc,
        origin: name.to_string(),
    })
}

/// The built-in Cornell box (`trazo render` without a scene).
#[pyfunction]
fn builtin() -> Scene {
    Scene {
        desc: scene::builtin::cornell_box(),
        origin: "built-in Cornell box".into(),
    }
}

/// An image as an H×W×C float32 array, moved into NumPy without a copy.
fn array<'py>(py: Python<'py>, image: &Image, channels: usize) -> Bound<'py, PyArray3<f32>> {
    let mut values = Vec::with_capacity(image.pixels.len() * channels);
    for p in &image.pixels {
        values.extend_from_slice(&[p.x, p.y, p.z][..channels]);
    }
    let shape = (image.height as usize, image.width as usize, channels);
    Array3::from_shape_vec(shape, values)
        .expect("the shape fits the values")
        .into_pyarray(py)
}

/// Renders `scene` with the overrides given; returns the image and, for
/// each name in `aovs`, its auxiliary image. `progress(done, total)` is
/// called after every pass with samples per pixel.
#[pyfunction]
#[pyo3(signature = (scene, spp=None, integrator=None, sampling=None, seed=None, threads=None, width=None, height=None, max_depth=None, aovs=Vec::new(), progress=None))]
#[allow(clippy::too_many_arguments)]
fn render<'py>(
    py: Python<'py>,
    scene: &Scene,
    spp: Option<u32>,
    integrator: Option<&str>,
    sampling: Option<&str>,
    seed: Option<u64>,
    threads: Option<usize>,
    width: Option<u32>,
    height: Option<u32>,
    max_depth: Option<u32>,
    aovs: Vec<String>,
    progress: Option<Py<PyAny>>,
) -> PyResult<(Bound<'py, PyArray3<f32>>, Bound<'py, PyDict>)> {
    let bad = |what: &str, value: &str, names: &[&str]| {
        TrazoError::new_err(format!(
            "unknown {what} \"{value}\": expected one of {}",
            names.join(", ")
        ))
    };
    let mut desc = scene.desc.clone();
    let s = &mut desc.settings;
    if let Some(v) = integrator {
        s.integrator = IntegratorKind::from_name(v).ok_or_else(|| bad("integrator", v, &IntegratorKind::NAMES))?;
    }
    if let Some(v) = sampling {
        s.sampling = PathSampling::from_name(v).ok_or_else(|| bad("sampling", v, &PathSampling::NAMES))?;
    }
    let aovs: Vec<Aov> = aovs
        .iter()
        .map(|a| Aov::from_name(a).ok_or_else(|| bad("auxiliary image", a, &Aov::NAMES)))
        .collect::<PyResult<_>>()?;
    for (value, name, max) in [
        (spp, "spp", trazo::settings::MAX_SPP),
        (width, "width", trazo::settings::MAX_IMAGE_SIDE),
        (height, "height", trazo::settings::MAX_IMAGE_SIDE),
    ] {
        if value.is_some_and(|v| v == 0 || v > max) {
            return Err(TrazoError::new_err(format!("{name} must be from 1 to {max}")));
        }
    }
    if max_depth.is_some_and(|d| d > trazo::settings::MAX_DEPTH) {
        return Err(TrazoError::new_err(format!(
            "max_depth must be at most {}",
            trazo::settings::MAX_DEPTH
        )));
    }
    s.spp = spp.unwrap_or(s.spp);
    s.seed = seed.unwrap_or(s.seed);
    s.width = width.unwrap_or(s.width);
    s.height = height.unwrap_or(s.height);
    s.max_depth = max_depth.unwrap_or(s.max_depth);
    let limits = scene::BuildLimits {
        max_memory: Some(scene::memory::default_limit()),
        aovs: !aovs.is_empty(),
    };
    let built = scene::build_limited(&desc, &limits).map_err(error)?;
    let options = RenderOptions {
        threads,
        aovs: !aovs.is_empty(),
        ..RenderOptions::default()
    };
    let total = built.settings.spp;
    let cancel = AtomicBool::new(false);
    let callback_error: Mutex<Option<PyErr>> = Mutex::new(None);
    let interrupted = AtomicBool::new(false);

    let out = py.detach(|| {
        std::thread::scope(|threads| {
            let worker = threads.spawn(|| {
                let mut report = |_: &Film, stats: &RenderStats| {
                    let Some(callback) = &progress else { return };
                    Python::attach(|py| {
                        if let Err(e) = callback.call1(py, (stats.spp, total)) {
                            *callback_error.lock().expect("not poisoned") = Some(e);
                            cancel.store(true, Ordering::Relaxed);
                        }
                    });
                };
                let mut control = Control {
                    cancel: Some(&cancel),
                    on_pass: Some(&mut report),
                    ..Control::default()
                };
                render_controlled(&built, &options, &mut control)
            });
            while !worker.is_finished() {
                std::thread::sleep(Duration::from_millis(20));
                // Ctrl-C is seen only by the main thread, holding the GIL.
                if Python::attach(|py| py.check_signals().is_err()) {
                    interrupted.store(true, Ordering::Relaxed);
                    cancel.store(true, Ordering::Relaxed);
                }
            }
            worker.join().expect("the render thread does not panic")
        })
    });
    if interrupted.load(Ordering::Relaxed) {
        return Err(PyKeyboardInterrupt::new_err("the render was interrupted"));
    }
    if let Some(e) = callback_error.into_inner().expect("not poisoned") {
        return Err(e);
    }
    let out = out.map_err(error)?;
    // The scene's exposure, as the command line applies it to the image
    // files it writes (the same product, so the same bits).
    let scale = trazo::film::io::exposure_scale(built.settings.exposure);
    let mut image = out.film.to_image();
    if scale != 1.0 {
        image.pixels.iter_mut().for_each(|p| *p *= scale);
    }
    let image = array(py, &image, 3);
    let extra = PyDict::new(py);
    for aov in aovs {
        let img = out.film.aov_image(aov).expect("recorded");
        let channels = if matches!(aov, Aov::Depth | Aov::Steps) { 1 } else { 3 };
        extra.set_item(aov.name(), array(py, &img, channels))?;
    }
    Ok((image, extra))
}

/// Writes an H×W×3 (or H×W×1) float32 array as an image file; the format
/// follows the extension (PNG tone-mapped, EXR, HDR, PFM linear).
#[pyfunction]
#[pyo3(signature = (path, image, tonemap="clamp", exposure=0.0))]
fn write(path: PathBuf, image: PyReadonlyArray3<'_, f32>, tonemap: &str, exposure: f32) -> PyResult<()> {
    let shape = image.shape();
    let (h, w, c) = (shape[0], shape[1], shape[2]);
    if !(c == 1 || c == 3) || h == 0 || w == 0 {
        return Err(TrazoError::new_err(format!(
            "expected an image of H×W×3 or H×W×1 values, got {h}×{w}×{c}"
        )));
    }
    let tonemap = Tonemap::from_name(tonemap).ok_or_else(|| {
        TrazoError::new_err(format!(
            "unknown tone mapping \"{tonemap}\": expected clamp, reinhard or aces"
        ))
    })?;
    let values = image.as_array();
    let mut img = Image::new(w as u32, h as u32);
    for y in 0..h {
        for x in 0..w {
            let v = |k: usize| values[[y, x, if c == 1 { 0 } else { k }]];
            img.pixels[y * w + x] = trazo::Rgb::new(v(0), v(1), v(2));
        }
    }
    trazo::film::io::write_image(&path, &img, tonemap, exposure).map_err(error)
}

/// Reads an image file (PNG, JPEG, BMP, EXR, HDR, PFM) as an H×W×3
/// float32 array of linear values.
#[pyfunction]
fn read<'py>(py: Python<'py>, path: PathBuf) -> PyResult<Bound<'py, PyArray3<f32>>> {
    let image = trazo::film::io::read_image(&path).map_err(error)?;
    Ok(array(py, &image, 3))
}

#[pymodule]
fn _trazo(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<Scene>()?;
    m.add_function(wrap_pyfunction!(load, m)?)?;
    m.add_function(wrap_pyfunction!(load_toml, m)?)?;
    m.add_function(wrap_pyfunction!(builtin, m)?)?;
    m.add_function(wrap_pyfunction!(render, m)?)?;
    m.add_function(wrap_pyfunction!(write, m)?)?;
    m.add_function(wrap_pyfunction!(read, m)?)?;
    m.add("TrazoError", m.py().get_type::<TrazoError>())?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}
