//! # trazo
//!
//! A physically based renderer that implements the classical ray-tracing
//! curriculum as real software: Whitted's recursive ray tracer, Kajiya's
//! path tracer (from the uniform-hemisphere estimator to next-event
//! estimation with multiple importance sampling), a volumetric path tracer
//! for participating media, and Jensen's photon mapping and progressive
//! photon mapping (SPPM); over robust ray–shape intersection (spheres,
//! planes, rectangles, disks, boxes, cylinders, triangle meshes, Loop
//! subdivision surfaces, signed distance grids), affine transforms and
//! instancing, a wide SAH bounding volume hierarchy, and perspective,
//! thin-lens and orthographic cameras. It reads trazo's TOML scenes,
//! Mitsuba 3 XML, pbrt-v4, glTF 2.0, OBJ and PLY.
//!
//! Data flows one way:
//!
//! ```text
//! scene file ─► scene::load ─► SceneDesc ─► scene::build ─► Scene ─► render::render ─► Film ─► film::io
//! ```
//!
//! Load a scene file, render it, write the image:
//!
//! ```
//! use trazo::{film::io::write_image, render::{RenderOptions, render}, scene};
//! use std::path::Path;
//!
//! let mut desc = scene::load(Path::new("scenes/cornell-box.toml"), &[])?;
//! (desc.settings.width, desc.settings.height, desc.settings.spp) = (32, 32, 4);
//! let out = render(&scene::build(&desc)?, &RenderOptions::default())?;
//! let path = std::env::temp_dir().join("trazo-doc-cornell-box.png");
//! write_image(&path, &out.film.to_image(), desc.settings.tonemap, desc.settings.exposure)?;
//! # Ok::<(), trazo::Error>(())
//! ```
//!
//! A scene can also be described in code and rendered to memory:
//!
//! ```
//! use trazo::scene::desc::*;
//! use trazo::{Rgb, Vec3};
//!
//! let mut desc = SceneDesc::default();
//! desc.settings.width = 32;
//! desc.settings.height = 24;
//! desc.settings.spp = 1;
//! desc.lights.push(LightDesc {
//!     kind: LightKind::Point { position: Vec3::new(0.0, 4.0, 4.0), intensity: Rgb::splat(20.0), falloff: true },
//!     locs: Locs::default(),
//! });
//! desc.shapes.push(ShapeDesc::new(ShapeKind::Sphere { center: Vec3::ZERO, radius: 1.0 }, None));
//! let scene = trazo::scene::build(&desc).unwrap();
//! let image = trazo::render::render_image(&scene).unwrap();
//! assert!(image.get(16, 12).x > 0.0); // the sphere is lit
//! ```

// Unsafe code is denied everywhere but where a module or function allows
// it, with the reason beside it: the vector intrinsics of geometry::lanes
// and the AVX entry points that call them, and the C library loaded at run
// time (film::denoise::oidn).
#![deny(unsafe_code)]
#![warn(missing_docs)]

pub mod accel;
pub mod camera;
pub mod cli;
pub mod color;
pub mod error;
pub mod files;
pub mod film;
pub mod fuzz;
pub mod geometry;
pub mod integrator;
pub mod light;
pub mod material;
pub mod math;
pub mod media;
pub mod render;
pub mod sampling;
pub mod scene;
pub mod settings;
pub mod texture;

pub use color::Rgb;
pub use error::{Error, Result};
pub use glam::{Vec2, Vec3};
