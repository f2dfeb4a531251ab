//! Acceleration structures: the bounding volume hierarchy and the scene
//! aggregate that puts all geometry under it.

pub mod aggregate;
pub(crate) mod blocks;
pub mod bvh;
pub mod queries;
pub mod wide;

pub use aggregate::{Aggregate, BLOCK_TREE_MIN_TRIANGLES};
pub use bvh::{Bvh, BvhNode};
pub use queries::{QueryHit, TriangleBvh};
pub use wide::{Bvh4, Bvh8, WideBvh};
