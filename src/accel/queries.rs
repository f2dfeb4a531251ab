//! Ray queries against a bare triangle mesh: closest hit and any hit over a
//! batch of rays, on all cores. This is what `trazo bench rays` measures
//! and what a library user who only needs visibility (ambient occlusion,
//! baking, collision) calls; the renderer's aggregate uses the same BVH.
//!
//! The ray file format is the one Embree's benchmarks and the project's
//! bench/compare script share: per ray six little-endian `f32`
//! (`ox oy oz dx dy dz`), directions not necessarily normalised. The hit
//! file holds 8 bytes per ray: the hit parameter `t` (`f32`, `+inf` for a
//! miss) and the primitive number (`u32`, `u32::MAX` for a miss).

use super::bvh::SahCosts;
use super::{Bvh, Bvh8};
use crate::geometry::triangle::{Triangle4, TriangleRay};
use crate::geometry::{Ray, TriangleMesh};
use glam::Vec3;
use rayon::prelude::*;

/// Queries accept hits with `t` in `(T_MIN, ∞)`.
pub const T_MIN: f32 = 1e-4;

/// Bytes per ray in a ray file.
pub const RAY_BYTES: usize = 24;
/// Bytes per ray in a hit file.
pub const HIT_BYTES: usize = 8;
/// The primitive number of a miss.
pub const MISS: u32 = u32::MAX;

/// A BVH over triangles copied, leaf by leaf, into blocks of four that one
/// ray tests at once; a leaf of the tree names its blocks.
#[derive(Clone, Debug)]
pub struct TriangleBvh {
    /// Eight-wide, as Embree's default on AVX machines: half the depth of
    /// dependent node loads an incoherent ray waits on in a tree larger than
    /// the cache, where ray throughput matters most; on a mesh that fits in
    /// the cache four-wide nodes can be as fast (commits d9b72c9, cd23ee6).
    bvh: Bvh8,
    /// Each leaf's triangles, four to a block.
    blocks: Vec<Triangle4>,
    /// Number of triangles.
    triangles: usize,
}

/// The closest hit of a ray.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct QueryHit {
    /// Ray parameter of the hit (a distance if the direction is normalised);
    /// `+inf` for a miss.
    pub t: f32,
    /// The primitive's number, or [`MISS`].
    pub prim: u32,
}

impl QueryHit {
    /// No hit.
    pub const NONE: QueryHit = QueryHit {
        t: f32::INFINITY,
        prim: MISS,
    };
}

impl TriangleBvh {
    /// Builds over the triangles of `mesh`; triangle `i` is reported as
    /// `ids[i]` (its own index when `ids` is `None`).
    pub fn build(mesh: &TriangleMesh, ids: Option<&[u32]>) -> TriangleBvh {
        let bounds: Vec<_> = (0..mesh.len())
            .into_par_iter()
            .map(|i| mesh.triangle_bounds(i))
            .collect();
        let (binary, order) = Bvh::build_with(&bounds, SahCosts::BLOCKS_OF_FOUR);
        drop(bounds);
        let mut bvh = Bvh8::from_binary(&binary);
        drop(binary);
        // Leaves hold at most a few blocks' worth of triangles; a leaf's
        // last block may be partly empty.
        let mut blocks = Vec::with_capacity(mesh.len() / 3 + 1);
        let mut lane_data = Vec::with_capacity(4);
        bvh.remap_leaves(|first, count| {
            let start = blocks.len() as u32;
            for chunk in order[first as usize..(first + count) as usize].chunks(4) {
                lane_data.clear();
                lane_data.extend(
                    chunk
                        .iter()
                        .map(|&i| (mesh.vertices(i as usize), ids.map_or(i, |ids| ids[i as usize]))),
                );
                blocks.push(Triangle4::new(&lane_data));
            }
            (start, blocks.len() as u32 - start)
        });
        TriangleBvh {
            bvh,
            blocks,
            triangles: mesh.len(),
        }
    }

    /// Visits the triangles the ray may hit, nearest boxes first, calling
    /// `on_hit(id, t, barycentrics, ray)` for the nearest hit of each block
    /// of four within the ray's interval; `on_hit` shrinks `ray.t_max` and
    /// returns `true` to accept. With `any_hit`, the first accepted hit ends
    /// the search. The scene aggregate traces large meshes this way.
    #[inline]
    pub fn traverse(
        &self,
        ray: &mut Ray,
        pre: &TriangleRay,
        any_hit: bool,
        mut on_hit: impl FnMut(u32, f32, [f32; 3], &mut Ray) -> bool,
    ) -> bool {
        self.bvh.traverse_leaves(&self.blocks, ray, any_hit, |k, r| {
            let block = &self.blocks[k as usize];
            match block.intersect_barycentric(r, pre) {
                Some((lane, t, b)) => on_hit(block.ids[lane], t, b, r),
                None => false,
            }
        })
    }

    /// Number of tree nodes.
    pub fn node_count(&self) -> usize {
        self.bvh.node_count()
    }

    /// Number of triangles.
    pub fn len(&self) -> usize {
        self.triangles
    }

    /// Whether there are no triangles.
    pub fn is_empty(&self) -> bool {
        self.triangles == 0
    }

    /// Bytes held: nodes and triangle blocks (with their ids).
    pub fn memory_bytes(&self) -> usize {
        self.bvh.memory_bytes() + self.blocks.len() * std::mem::size_of::<Triangle4>()
    }

    /// The closest hit along `ray` within its interval.
    #[inline]
    pub fn closest_hit(&self, ray: &Ray) -> QueryHit {
        self.closest_hit_with::<false>(ray)
    }

    /// [`TriangleBvh::closest_hit`]; with `AVX` (only where the processor
    /// has it) eight-wide boxes are tested in one AVX register.
    #[inline(always)]
    #[allow(unsafe_code)]
    fn closest_hit_with<const AVX: bool>(&self, ray: &Ray) -> QueryHit {
        let Some(pre) = TriangleRay::new(ray) else {
            return QueryHit::NONE;
        };
        let mut r = ray.copy_by_field();
        let mut best = MISS;
        let test = |k: u32, r: &mut Ray| match self.blocks[k as usize].intersect(r, &pre) {
            Some((lane, t)) => {
                r.t_max = t;
                best = self.blocks[k as usize].ids[lane];
                true
            }
            None => false,
        };
        #[cfg(target_arch = "x86_64")]
        if AVX {
            // SAFETY: `AVX` is set only where the processor has AVX.
            unsafe { self.bvh.traverse_leaves_avx(&self.blocks, &mut r, false, test) };
        } else {
            self.bvh.traverse_leaves(&self.blocks, &mut r, false, test);
        }
        #[cfg(not(target_arch = "x86_64"))]
        self.bvh.traverse_leaves(&self.blocks, &mut r, false, test);
        if best == MISS {
            QueryHit::NONE
        } else {
            QueryHit { t: r.t_max, prim: best }
        }
    }

    /// Whether anything lies along `ray` within its interval. (Testing
    /// the boxes in AVX, as closest hits do, made any-hit queries a little
    /// slower: they sort nothing.)
    #[inline]
    pub fn any_hit(&self, ray: &Ray) -> bool {
        let Some(pre) = TriangleRay::new(ray) else {
            return false;
        };
        let mut r = ray.copy_by_field();
        self.bvh.traverse_leaves(&self.blocks, &mut r, true, |k, r| {
            self.blocks[k as usize].intersect(r, &pre).is_some()
        })
    }

    /// Closest hits of a batch of rays, on all cores, in ray order. The
    /// iterator is indexed, so rayon's workers write each hit straight to
    /// its place in the result (a `flat_map_iter` over chunks builds a
    /// vector per chunk and then joins them; commit eba9c13).
    #[allow(unsafe_code)]
    pub fn closest_hits(&self, rays: &[Ray]) -> Vec<QueryHit> {
        let avx = avx_available();
        rays.par_iter()
            .with_min_len(CHUNK)
            .map(|r| {
                #[cfg(target_arch = "x86_64")]
                if avx {
                    // SAFETY: the processor has AVX.
                    return unsafe { self.closest_hit_avx(r) };
                }
                let _ = avx;
                self.closest_hit(r)
            })
            .collect()
    }

    /// Occlusion of a batch of rays, on all cores; returns how many hit.
    pub fn count_any_hits(&self, rays: &[Ray]) -> usize {
        rays.par_chunks(CHUNK)
            .map(|c| c.iter().filter(|r| self.any_hit(r)).count())
            .sum()
    }

    /// [`TriangleBvh::closest_hit`] built for AVX.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx")]
    fn closest_hit_avx(&self, ray: &Ray) -> QueryHit {
        self.closest_hit_with::<true>(ray)
    }
}

/// Whether closest-hit batches may take their AVX form.
fn avx_available() -> bool {
    #[cfg(target_arch = "x86_64")]
    return crate::geometry::lanes::avx_available();
    #[cfg(not(target_arch = "x86_64"))]
    false
}

/// Rays per parallel work item: large enough to amortise scheduling,
/// small enough to balance two to a hundred cores.
const CHUNK: usize = 4096;

/// Decodes a ray file (see the module documentation). Every ray gets the
/// interval `(T_MIN, ∞)`. Fails, naming the problem, if the size is not a
/// multiple of 24 bytes or a value is not finite or a direction is zero.
pub fn parse_rays(bytes: &[u8]) -> Result<Vec<Ray>, String> {
    if bytes.len() % RAY_BYTES != 0 {
        return Err(format!(
            "{} bytes is not a whole number of rays ({RAY_BYTES} bytes each: ox oy oz dx dy dz as little-endian f32)",
            bytes.len()
        ));
    }
    bytes
        .chunks_exact(RAY_BYTES)
        .enumerate()
        .map(|(i, c)| {
            let f = |k: usize| f32::from_le_bytes([c[4 * k], c[4 * k + 1], c[4 * k + 2], c[4 * k + 3]]);
            let origin = Vec3::new(f(0), f(1), f(2));
            let dir = Vec3::new(f(3), f(4), f(5));
            if !origin.is_finite() || !dir.is_finite() {
                return Err(format!("ray {i} (byte {}): a value is not finite", i * RAY_BYTES));
            }
            if dir == Vec3::ZERO {
                return Err(format!("ray {i} (byte {}): the direction is zero", i * RAY_BYTES));
            }
            Ok(Ray::with_interval(origin, dir, T_MIN, f32::INFINITY))
        })
        .collect()
}

/// Encodes hits as a hit file (see the module documentation).
pub fn encode_hits(hits: &[QueryHit]) -> Vec<u8> {
    let mut out = Vec::with_capacity(hits.len() * HIT_BYTES);
    for h in hits {
        out.extend_from_slice(&h.t.to_le_bytes());
        out.extend_from_slice(&h.prim.to_le_bytes());
    }
    out
}

/// Encodes rays as a ray file.
pub fn encode_rays(rays: &[Ray]) -> Vec<u8> {
    let mut out = Vec::with_capacity(rays.len() * RAY_BYTES);
    for r in rays {
        for v in [r.origin, r.dir] {
            for x in v.to_array() {
                out.extend_from_slice(&x.to_le_bytes());
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::triangle::intersect_triangle;
    use crate::sampling::rng::Pcg32;
    use crate::sampling::warp::sample_sphere_uniform;
    use glam::Vec2;

    /// The closest hit found by testing every triangle.
    fn brute_force(mesh: &TriangleMesh, ray: &Ray) -> QueryHit {
        let mut best = QueryHit::NONE;
        let mut r = *ray;
        for i in 0..mesh.len() {
            let [p0, p1, p2] = mesh.vertices(i);
            if let Some(h) = intersect_triangle(&r, p0, p1, p2) {
                r.t_max = h.t;
                best = QueryHit { t: h.t, prim: i as u32 };
            }
        }
        best
    }

    fn random_rays(n: usize, rng: &mut Pcg32) -> Vec<Ray> {
        (0..n)
            .map(|_| {
                let o = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 4.0 - 2.0;
                let d = sample_sphere_uniform(Vec2::new(rng.next_f32(), rng.next_f32())) * (0.5 + rng.next_f32());
                Ray::with_interval(o, d, T_MIN, f32::INFINITY)
            })
            .collect()
    }

    #[test]
    fn queries_agree_with_brute_force() {
        let mut mesh = TriangleMesh::uv_sphere(Vec3::ZERO, 1.0, 24, 12);
        mesh = mesh.transformed(&crate::geometry::Transform::scale(Vec3::new(1.5, 1.0, 0.7)).unwrap());
        let bvh = TriangleBvh::build(&mesh, None);
        let mut rng = Pcg32::new(7, 1);
        let rays = random_rays(2000, &mut rng);
        let hits = bvh.closest_hits(&rays);
        let mut n_hit = 0;
        for (r, h) in rays.iter().zip(&hits) {
            let b = brute_force(&mesh, r);
            assert_eq!(h.prim == MISS, b.prim == MISS, "{r:?}");
            if b.prim != MISS {
                n_hit += 1;
                // Ties between triangles sharing an edge may pick either.
                assert!((h.t - b.t).abs() <= 1e-5 * b.t.max(1.0), "{} vs {}", h.t, b.t);
            }
            assert_eq!(bvh.any_hit(r), b.prim != MISS);
        }
        assert!(
            n_hit > 200 && n_hit < 1900,
            "{n_hit} hits: rays should both hit and miss"
        );
        assert_eq!(bvh.count_any_hits(&rays), n_hit);
    }

    #[test]
    fn ids_map_back_to_the_callers_numbers() {
        let mesh = TriangleMesh::uv_sphere(Vec3::ZERO, 1.0, 8, 4);
        let ids: Vec<u32> = (0..mesh.len() as u32).map(|i| 1000 + i).collect();
        let bvh = TriangleBvh::build(&mesh, Some(&ids));
        let r = Ray::with_interval(Vec3::new(0.1, 0.2, -5.0), Vec3::Z, T_MIN, f32::INFINITY);
        let h = bvh.closest_hit(&r);
        assert_eq!(h.prim, 1000 + brute_force(&mesh, &r).prim);
    }

    #[test]
    fn ray_and_hit_files_round_trip_and_reject_bad_data() {
        let mut rng = Pcg32::new(3, 3);
        let rays = random_rays(10, &mut rng);
        assert_eq!(parse_rays(&encode_rays(&rays)).unwrap(), rays);
        assert!(parse_rays(&[0u8; 25]).unwrap_err().contains("whole number"));
        let zero = encode_rays(&[Ray::new(Vec3::ZERO, Vec3::ZERO)]);
        assert!(parse_rays(&zero).unwrap_err().contains("direction is zero"));
        let nan = encode_rays(&[Ray::new(Vec3::new(f32::NAN, 0.0, 0.0), Vec3::X)]);
        assert!(parse_rays(&nan).unwrap_err().contains("not finite"));
        let bytes = encode_hits(&[QueryHit::NONE, QueryHit { t: 2.0, prim: 5 }]);
        assert_eq!(bytes.len(), 16);
        assert_eq!(f32::from_le_bytes(bytes[0..4].try_into().unwrap()), f32::INFINITY);
        assert_eq!(u32::from_le_bytes(bytes[4..8].try_into().unwrap()), MISS);
        assert_eq!(f32::from_le_bytes(bytes[8..12].try_into().unwrap()), 2.0);
        assert_eq!(u32::from_le_bytes(bytes[12..16].try_into().unwrap()), 5);
    }
}
