//! # trazo
//!
//! A physically based renderer that implements the classical ray-tracing
//! curriculum as real software: Whitted's recursive ray tracer with shadow
//! rays, Phong shading, reflection and refraction, on a core of robust
//! ray–shape intersection, affine transforms, a SAH bounding volume
//! hierarchy, perspective and orthographic cameras and supersampling.
//!
//! Data flows one way:
//!
//! ```text
//! scene file ─► scene::load ─► SceneDesc ─► scene::build ─► Scene ─► render::render ─► Film ─► film::io
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

// Unsafe code is denied everywhere but in the one module that calls a C
// library loaded at run time (film::denoise::oidn), which allows it.
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
pub mod media;
pub mod render;
pub mod sampling;
pub mod scene;
pub mod settings;
pub mod texture;

pub use color::Rgb;
pub use error::{Error, Result};
pub use glam::{Vec2, Vec3};
