//! Rays, bounding boxes, affine transforms, shapes and the intersection
//! record.

pub mod bezier;
pub mod bilinear;
pub mod bounds;
pub mod catmull_clark;
pub mod curve;
pub mod displacement;
pub mod implicit;
pub mod interaction;
#[cfg(target_arch = "x86_64")]
pub(crate) mod lanes;
pub mod mesh;
pub mod motion;
pub mod quadric;
pub mod ray;
pub(crate) mod real;
pub(crate) mod roots;
pub mod sdf;
pub mod sdf_grid;
pub mod shape;
pub(crate) mod simd;
pub mod subdivision;
pub mod transform;
pub mod triangle;

pub use bounds::Aabb;
pub use interaction::SurfaceHit;
pub use mesh::TriangleMesh;
pub use ray::Ray;
pub use shape::{Cuboid, Cylinder, Disk, DiskUv, Plane, Rectangle, Shape, Sphere};
pub use transform::Transform;
