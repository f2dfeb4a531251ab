//! Small scenes without a tree: every primitive tested, eight at a time.
//!
//! A room like the Cornell box is a few dozen planar primitives whose walls
//! span the whole scene, so a BVH over them saves few tests and costs a
//! stack, box tests and a branch per node on every query. Packed eight to
//! a block in structure-of-arrays form (Embree's "triangle8" layout), the
//! same primitives are each tested by a few AVX instructions, with no
//! branch that depends on the ray. [`Aggregate`](super::Aggregate) traces scenes
//! of [`FLAT_MIN_PRIMITIVES`] to [`FLAT_MAX_PRIMITIVES`] rectangles and
//! triangles this way where the processor has AVX and the primitives are
//! large for the space they fill ([`flat_pays`]), and through
//! its tree otherwise. `cargo bench --bench kernels -- "small scene"` measures both
//! (commits 6de6629, c8ebadd): on the smallest clutters a tree of one or two
//! leaves of scalar tests is faster, on larger cluttered rooms the blocks.
//! Up to eight blocks take one eight-lane test of their boxes, up to sixteen
//! two.
//!
//! A block's lanes compute what the one-primitive tests compute: the
//! rectangle test's operations in the same order (the same distances), and
//! the watertight triangle test of [`Triangle4`](crate::geometry::triangle::Triangle4).

use crate::geometry::Aabb;
#[cfg(not(target_arch = "x86_64"))]
use crate::geometry::{Ray, Rectangle};
#[cfg(not(target_arch = "x86_64"))]
use glam::Vec3;

/// Scenes of at least this many rectangles and triangles (and at most
/// [`FLAT_MAX_PRIMITIVES`]) are traced without a tree: two blocks, so that
/// the Mitsuba Cornell box, 18 rectangles (walls, light, two cubes' faces),
/// is traced in three blocks, which take fewer instructions than its tree
/// (commit 69b9d1a); smaller clutters fail [`flat_pays`] anyway.
pub const FLAT_MIN_PRIMITIVES: usize = 16;

/// Scenes of at most this many rectangles and triangles (sixteen blocks of
/// eight) are traced without a tree.
pub const FLAT_MAX_PRIMITIVES: usize = 128;

/// Scenes are traced through their tree where their number of primitives
/// times [`expected_hits`] (how many of the primitives' boxes a ray through
/// the scene's box meets on average) is below this: the tree skips nearly
/// every primitive there, and the blocks cannot. A room's walls span the
/// room: 30 primitives × 3.0 on the Cornell box with its cubes as
/// triangles.
///
/// Fitted to `cargo bench --bench kernels -- "small"` (commit 1d2dd18):
/// clutters of 24 to 128 small primitives in cubes of side 1 to 8, flat
/// against tree. The threshold lies between the largest product where the
/// tree was faster and the smallest where the blocks were as fast or
/// faster; the expected hits alone did not separate them, as fewer
/// primitives need more overlap before the blocks pay.
pub const FLAT_MIN_HITS_TIMES_PRIMITIVES: f32 = 16.0;

/// Whether `primitives` whose boxes a ray through the scene's box meets
/// `expected_hits` of on average are traced faster in blocks than through
/// a tree (see [`FLAT_MIN_HITS_TIMES_PRIMITIVES`]).
pub fn flat_pays(primitives: usize, expected_hits: f32) -> bool {
    primitives as f32 * expected_hits >= FLAT_MIN_HITS_TIMES_PRIMITIVES
}

/// How many of the boxes a random ray through their union meets on
/// average: the sum of their surface areas over the union's (0 for an
/// empty or degenerate union). By Cauchy's formula, as in the SAH, a
/// random line through a convex body meets a convex body inside it with
/// probability equal to the ratio of their surface areas.
pub fn expected_hits(boxes: &[Aabb]) -> f32 {
    let union = boxes.iter().fold(Aabb::EMPTY, |u, b| u.union(b));
    let area = union.surface_area();
    if boxes.is_empty() || area.is_nan() || area <= 0.0 {
        return 0.0;
    }
    boxes.iter().map(|b| b.surface_area()).sum::<f32>() / area
}

/// The nearest primitive a ray meets in a [`FlatScene`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum FlatHit {
    /// The rectangle the caller numbered `id`.
    Rectangle {
        /// The caller's number.
        id: u32,
        /// Ray parameter.
        t: f32,
    },
    /// The triangle the caller numbered `id`.
    Triangle {
        /// The caller's number.
        id: u32,
        /// Ray parameter.
        t: f32,
        /// Barycentrics.
        b: [f32; 3],
    },
}

#[cfg(target_arch = "x86_64")]
pub use avx::FlatScene;

#[cfg(target_arch = "x86_64")]
mod avx {
    use super::FlatHit;
    use crate::geometry::bounds::gamma;

    /// Widening of the slab test's far distance that makes it conservative
    /// under rounding (pbrt-v4, section 6.8.2), as in the trees.
    const SLAB_ROUNDING: f32 = 1.0 + 2.0 * gamma(3);
    use crate::accel::blocks::{RayLanes, Rectangle8, Triangle8, nearest_lane, pack, pack_ids};
    use crate::accel::bvh::{Bvh, BvhNode};
    use crate::geometry::lanes::{F8, LANES, Lanes, avx_available};
    use crate::geometry::triangle::TriangleRay;
    use crate::geometry::{Aabb, Ray, Rectangle};
    use glam::Vec3;

    /// Most blocks in a flat scene: two eight-lane box tests at the root.
    const MAX_BLOCKS: usize = 2 * LANES;

    /// Scenes of rectangles alone in at most this many blocks (a room: its
    /// walls and what stands in it) test every block on every ray and skip
    /// the boxes' slab test. In a room most rays start inside and enter
    /// most blocks, so the slab test and the branches on its result cost
    /// more than the block tests they skip. Clutters of four and five
    /// blocks with triangles were slower tested that way, so they keep the
    /// slab test (commit 834b673).
    const TEST_EVERY_BLOCK_UP_TO: usize = 3;

    /// The primitives of a flat scene, in blocks of eight, and the blocks'
    /// boxes: a two-level tree whose root has a lane per block.
    #[derive(Clone, Debug)]
    pub struct FlatScene {
        /// Block `8g + b`'s box in lane `b` of `bounds[g]`: `[min x, y, z,
        /// max x, y, z]`. The rectangle blocks come first, then the
        /// triangle blocks; unused lanes hold empty boxes.
        bounds: [[Lanes; 6]; 2],
        /// Whether there are more than eight blocks, so `bounds[1]` is
        /// tested too (scenes of up to eight blocks skip it in one
        /// predictable branch).
        second_group: bool,
        /// Whether every ray tests every block, without the boxes' slab
        /// test (see [`TEST_EVERY_BLOCK_UP_TO`]).
        pub(super) test_every_block: bool,
        rectangles: Vec<Rectangle8>,
        triangles: Vec<Triangle8>,
    }

    /// How primitives are grouped into blocks.
    #[derive(Clone, Copy, PartialEq)]
    enum Grouping {
        /// The largest subtrees with at most eight primitives: tight boxes,
        /// but blocks may be part empty.
        Subtrees,
        /// Runs of eight in the tree's order: full blocks, looser boxes.
        Full,
    }

    /// Groups of at most eight primitives that lie near each other, from a
    /// binary SAH tree over their boxes.
    fn spatial_groups(bounds: &[Aabb], grouping: Grouping) -> Vec<Vec<usize>> {
        if bounds.is_empty() {
            return Vec::new();
        }
        let (bvh, order) = Bvh::build(bounds);
        if grouping == Grouping::Full {
            return order
                .chunks(LANES)
                .map(|c| c.iter().map(|&k| k as usize).collect())
                .collect();
        }
        let nodes = bvh.nodes();
        // Primitives under each node (interior: first child next, second
        // at `offset`), then the groups top-down.
        fn size(nodes: &[BvhNode], i: usize, sizes: &mut [usize]) -> usize {
            let n = &nodes[i];
            sizes[i] = if n.count > 0 {
                n.count as usize
            } else {
                size(nodes, i + 1, sizes) + size(nodes, n.offset as usize, sizes)
            };
            sizes[i]
        }
        fn collect(nodes: &[BvhNode], i: usize, sizes: &[usize], first: usize, out: &mut Vec<(usize, usize)>) {
            if sizes[i] <= LANES {
                out.push((first, sizes[i]));
            } else {
                collect(nodes, i + 1, sizes, first, out);
                collect(nodes, nodes[i].offset as usize, sizes, first + sizes[i + 1], out);
            }
        }
        let mut sizes = vec![0; nodes.len()];
        size(nodes, 0, &mut sizes);
        let mut ranges = Vec::new();
        collect(nodes, 0, &sizes, 0, &mut ranges);
        ranges
            .into_iter()
            .map(|(first, n)| order[first..first + n].iter().map(|&k| k as usize).collect())
            .collect()
    }

    impl FlatScene {
        /// Packs rectangles and triangles, each with the caller's number,
        /// into blocks of neighbours (whole subtrees where that fits in
        /// sixteen blocks, else full blocks); `None` where the processor
        /// lacks AVX or they need more than sixteen blocks.
        pub fn new(rectangles: &[(Rectangle, u32)], triangles: &[([Vec3; 3], u32)]) -> Option<FlatScene> {
            if !avx_available() {
                return None;
            }
            let rectangle_bounds: Vec<Aabb> = rectangles.iter().map(|(r, _)| r.bounds()).collect();
            let triangle_bounds: Vec<Aabb> = triangles.iter().map(|(t, _)| Aabb::from_points(*t)).collect();
            let group = |grouping| {
                (
                    spatial_groups(&rectangle_bounds, grouping),
                    spatial_groups(&triangle_bounds, grouping),
                )
            };
            let mut groups = group(Grouping::Subtrees);
            if groups.0.len() + groups.1.len() > MAX_BLOCKS {
                groups = group(Grouping::Full);
            }
            let (rectangle_groups, triangle_groups) = groups;
            let blocks = rectangle_groups.len() + triangle_groups.len();
            if blocks > MAX_BLOCKS {
                return None;
            }
            let empty = [
                Lanes([f32::INFINITY; LANES]),
                Lanes([f32::INFINITY; LANES]),
                Lanes([f32::INFINITY; LANES]),
                Lanes([f32::NEG_INFINITY; LANES]),
                Lanes([f32::NEG_INFINITY; LANES]),
                Lanes([f32::NEG_INFINITY; LANES]),
            ];
            let mut scene = FlatScene {
                bounds: [empty; 2],
                second_group: blocks > LANES,
                test_every_block: triangle_groups.is_empty() && blocks <= TEST_EVERY_BLOCK_UP_TO,
                rectangles: Vec::new(),
                triangles: Vec::new(),
            };
            let mut set_bounds = |block: usize, boxes: &[Aabb], members: &[usize]| {
                let b = members.iter().fold(Aabb::EMPTY, |b, &k| b.union(&boxes[k]));
                let (group, lane) = (block / LANES, block % LANES);
                for axis in 0..3 {
                    scene.bounds[group][axis].0[lane] = b.min[axis];
                    scene.bounds[group][3 + axis].0[lane] = b.max[axis];
                }
            };
            for (block, group) in rectangle_groups.iter().enumerate() {
                set_bounds(block, &rectangle_bounds, group);
            }
            for (i, group) in triangle_groups.iter().enumerate() {
                set_bounds(rectangle_groups.len() + i, &triangle_bounds, group);
            }
            scene.rectangles = rectangle_groups
                .iter()
                .map(|group| {
                    let members: Vec<&(Rectangle, u32)> = group.iter().map(|&k| &rectangles[k]).collect();
                    Rectangle8 {
                        v: pack(&members.iter().map(|(r, _)| r.test_frame()).collect::<Vec<_>>()),
                        ids: pack_ids(&members),
                    }
                })
                .collect();
            scene.triangles = triangle_groups
                .iter()
                .map(|group| {
                    let members: Vec<&([Vec3; 3], u32)> = group.iter().map(|&k| &triangles[k]).collect();
                    Triangle8 {
                        v: pack(&members.iter().map(|(t, _)| *t).collect::<Vec<_>>()),
                        ids: pack_ids(&members),
                    }
                })
                .collect();
            Some(scene)
        }

        /// Number of blocks of eight.
        pub fn blocks(&self) -> usize {
            self.rectangles.len() + self.triangles.len()
        }

        /// Bytes held by the blocks.
        pub fn memory_bytes(&self) -> usize {
            std::mem::size_of::<[[Lanes; 6]; 2]>()
                + self.rectangles.len() * std::mem::size_of::<Rectangle8>()
                + self.triangles.len() * std::mem::size_of::<Triangle8>()
        }

        /// The nearest hit within the ray's interval; with `any_hit`, some
        /// hit.
        #[inline]
        #[allow(unsafe_code)]
        pub fn intersect(&self, ray: &Ray, any_hit: bool) -> Option<FlatHit> {
            // SAFETY: a `FlatScene` exists only where the processor has AVX.
            unsafe {
                if self.test_every_block {
                    self.intersect_every_block(ray, any_hit)
                } else {
                    self.intersect_avx(ray, any_hit)
                }
            }
        }

        /// [`FlatScene::intersect`] where every block is tested.
        #[target_feature(enable = "avx")]
        fn intersect_every_block(&self, ray: &Ray, any_hit: bool) -> Option<FlatHit> {
            self.test_blocks(ray, any_hit, u32::MAX, |_, _| true)
        }

        /// [`FlatScene::intersect`] where the blocks' boxes are tested first.
        #[target_feature(enable = "avx")]
        fn intersect_avx(&self, ray: &Ray, any_hit: bool) -> Option<FlatHit> {
            let (entered, t_enter) = self.enter_blocks(ray);
            if entered == 0 {
                return None;
            }
            self.test_blocks(ray, any_hit, entered, |block, t_max| {
                entered & (1 << block) != 0 && t_enter[block] <= t_max
            })
        }

        /// The primitive tests of the blocks for which `enter(block, t_max)`
        /// holds; `entered` has a bit for each block that may hold a hit.
        #[inline]
        #[target_feature(enable = "avx")]
        fn test_blocks(
            &self,
            ray: &Ray,
            any_hit: bool,
            entered: u32,
            enter: impl Fn(usize, f32) -> bool,
        ) -> Option<FlatHit> {
            let mut t_max = ray.t_max;
            let mut best = None;
            for (block, rectangles) in self.rectangles.iter().enumerate() {
                if !enter(block, t_max) {
                    continue;
                }
                let (mask, t) = rectangles.intersect(ray, t_max);
                if let Some(lane) = nearest_lane(mask, &t.to_array(), &mut t_max) {
                    best = Some(FlatHit::Rectangle {
                        id: rectangles.ids[lane],
                        t: t_max,
                    });
                    if any_hit {
                        return best;
                    }
                }
            }
            // Most rays in a room meet only walls: they enter no triangle
            // block, and skip the loop over them.
            let first = self.rectangles.len();
            if self.triangles.is_empty() || entered >> first == 0 {
                return best;
            }
            // The triangle test's set-up, made when a triangle block is
            // entered within the interval.
            let mut ray_lanes = None;
            let mut best_triangle = None;
            for (i, triangles) in self.triangles.iter().enumerate() {
                if !enter(first + i, t_max) {
                    continue;
                }
                if ray_lanes.is_none() {
                    match TriangleRay::new(ray) {
                        Some(pre) => ray_lanes = Some(RayLanes::new(ray, &pre)),
                        None => break,
                    }
                }
                let Some(ray_lanes) = &ray_lanes else { break };
                let (mask, t, edges) = triangles.intersect(ray_lanes, F8::splat(t_max));
                if let Some(lane) = nearest_lane(mask, &t.to_array(), &mut t_max) {
                    best_triangle = Some((triangles.ids[lane], edges.barycentrics(lane)));
                    if any_hit {
                        break;
                    }
                }
            }
            match best_triangle {
                Some((id, b)) => Some(FlatHit::Triangle { id, t: t_max, b }),
                None => best,
            }
        }

        /// The blocks whose boxes the ray enters within its interval, as a
        /// bit per block, and where it enters each: the slab test of
        /// `WideBvh` on eight lanes, for the second eight blocks only
        /// where there are more than eight (one predictable branch).
        #[inline]
        #[target_feature(enable = "avx")]
        fn enter_blocks(&self, ray: &Ray) -> (u32, [f32; MAX_BLOCKS]) {
            let inv = ray.dir.recip();
            let mut slabs = [(0, 0, F8::splat(0.0), F8::splat(0.0)); 3];
            for (axis, slab) in slabs.iter_mut().enumerate() {
                let (near, far) = if inv[axis] < 0.0 {
                    (3 + axis, axis)
                } else {
                    (axis, 3 + axis)
                };
                *slab = (near, far, F8::splat(ray.origin[axis]), F8::splat(inv[axis]));
            }
            let mut t_enter = [f32::INFINITY; MAX_BLOCKS];
            let (mut entered, t) = enter_group(&self.bounds[0], &slabs, ray);
            t_enter[..LANES].copy_from_slice(&t.to_array());
            if self.second_group {
                let (second, t) = enter_group(&self.bounds[1], &slabs, ray);
                entered |= second << LANES;
                t_enter[LANES..].copy_from_slice(&t.to_array());
            }
            (entered, t_enter)
        }
    }

    /// The slab test of eight boxes: the lanes the ray enters within its
    /// interval, and where. `slabs` holds, per axis, the near and far
    /// planes' rows in `bounds`, the origin and the inverse direction.
    #[inline]
    #[target_feature(enable = "avx")]
    fn enter_group(bounds: &[Lanes; 6], slabs: &[(usize, usize, F8, F8); 3], ray: &Ray) -> (u32, F8) {
        let mut t0 = F8::splat(ray.t_min);
        let mut t1 = F8::splat(ray.t_max);
        for &(near, far, o, i) in slabs {
            // `max`/`min` return their second operand for NaN (0·∞ for a
            // ray in a box's face plane), as the tree's test does.
            t0 = F8::load(&bounds[near]).sub(o).mul(i).max(t0);
            t1 = F8::load(&bounds[far]).sub(o).mul(i).min(t1);
        }
        let t1 = t1.mul(F8::splat(SLAB_ROUNDING));
        (t0.le(t1).bits(), t0)
    }
}

/// Where the processor is not x86-64 there are no flat scenes: the tree is
/// used (the lane code is written for AVX, and measured only there).
#[cfg(not(target_arch = "x86_64"))]
#[derive(Clone, Debug)]
pub struct FlatScene(std::convert::Infallible);

#[cfg(not(target_arch = "x86_64"))]
impl FlatScene {
    /// Always `None` on this processor.
    pub fn new(_rectangles: &[(Rectangle, u32)], _triangles: &[([Vec3; 3], u32)]) -> Option<FlatScene> {
        None
    }

    /// Number of blocks of eight.
    pub fn blocks(&self) -> usize {
        match self.0 {}
    }

    /// Bytes held by the blocks.
    pub fn memory_bytes(&self) -> usize {
        match self.0 {}
    }

    /// The nearest hit within the ray's interval.
    pub fn intersect(&self, _ray: &Ray, _any_hit: bool) -> Option<FlatHit> {
        match self.0 {}
    }
}

#[cfg(all(test, target_arch = "x86_64"))]
mod tests {
    use super::*;
    use crate::geometry::lanes::avx_available;
    use crate::geometry::triangle::intersect_triangle;
    use crate::geometry::triangle::tests::{DIAGONAL_QUAD, assert_diagonal_is_watertight};
    use crate::geometry::{Ray, Rectangle};
    use crate::sampling::rng::Pcg32;
    use glam::Vec3;

    fn random_point(rng: &mut Pcg32) -> Vec3 {
        Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 2.0 - 1.0
    }

    /// The nearest hit by the one-primitive tests, numbered as the flat
    /// scene numbers them (rectangles by their number, triangles by theirs
    /// plus 1000).
    fn brute_force(rectangles: &[(Rectangle, u32)], triangles: &[([Vec3; 3], u32)], ray: &Ray) -> Option<(u32, f32)> {
        let hits = rectangles
            .iter()
            .filter_map(|(r, id)| r.intersect(ray).map(|t| (*id, t)))
            .chain(
                triangles
                    .iter()
                    .filter_map(|(v, id)| intersect_triangle(ray, v[0], v[1], v[2]).map(|h| (*id, h.t))),
            );
        hits.min_by(|a, b| a.1.total_cmp(&b.1))
    }

    /// Blocks of rectangles and triangles find what testing each one finds:
    /// the same rectangle at the same distance (its lanes compute the
    /// one-rectangle test's operations), the same triangle at a distance
    /// equal to the last bits, and a hit for any-hit queries exactly when
    /// there is one.
    #[test]
    fn blocks_agree_with_one_primitive_at_a_time() {
        if !avx_available() {
            return;
        }
        let mut rng = Pcg32::new(31, 7);
        let (mut hits, mut triangle_hits, mut every_block_hits) = (0, 0, 0);
        for case in 0..300 {
            let n_rect = case % 13;
            let n_tri = (case * 7) % 29;
            let rectangles: Vec<(Rectangle, u32)> = (0..n_rect)
                .map(|i| {
                    let c = random_point(&mut rng);
                    let (u, v) = (random_point(&mut rng) * 0.8, random_point(&mut rng) * 0.8);
                    (Rectangle::new(c, u, v), i as u32)
                })
                .collect();
            let triangles: Vec<([Vec3; 3], u32)> = (0..n_tri)
                .map(|i| {
                    let c = random_point(&mut rng);
                    let v = [c, c + random_point(&mut rng) * 0.7, c + random_point(&mut rng) * 0.7];
                    (v, 1000 + i as u32)
                })
                .collect();
            let Some(scene) = FlatScene::new(&rectangles, &triangles) else {
                // More than eight blocks: the tree's case.
                continue;
            };
            for k in 0..60 {
                let origin = random_point(&mut rng) * 3.0;
                let target = random_point(&mut rng) * 0.8;
                let t_max = if k % 4 == 0 { 0.6 } else { f32::INFINITY };
                let ray = Ray::with_interval(origin, target - origin, 1e-4, t_max);
                let expected = brute_force(&rectangles, &triangles, &ray);
                let got = scene.intersect(&ray, false).map(|h| match h {
                    FlatHit::Rectangle { id, t } => (id, t),
                    FlatHit::Triangle { id, t, .. } => (id, t),
                });
                match (got, expected) {
                    (None, None) => {}
                    (Some((id, t)), Some((id_e, t_e))) => {
                        hits += 1;
                        triangle_hits += (id >= 1000) as u32;
                        every_block_hits += scene.test_every_block as u32;
                        let tolerance = if id >= 1000 || id_e >= 1000 { 1e-5 * t_e } else { 0.0 };
                        assert!((t - t_e).abs() <= tolerance, "case {case}: t {t} vs {t_e}");
                        // Two primitives this close along the ray may
                        // swap; otherwise the same one.
                        assert!(
                            id == id_e || (t - t_e).abs() <= 1e-5 * t_e,
                            "case {case}: {id} vs {id_e}"
                        );
                    }
                    _ => panic!("case {case}: {got:?} vs {expected:?}"),
                }
                assert_eq!(scene.intersect(&ray, true).is_some(), expected.is_some(), "case {case}");
            }
        }
        assert!(
            hits > 2000 && triangle_hits > 500 && every_block_hits > 100,
            "{hits} hits, {triangle_hits} on triangles, {every_block_hits} in scenes without the slab test"
        );
    }

    /// Rays parallel to a rectangle (a zero denominator: t is ±∞ or NaN)
    /// miss it, in its plane or beside it, with an unbounded interval or
    /// not, as the one-rectangle test has them; and a ray across hits.
    #[test]
    fn rays_parallel_to_a_rectangle_miss_it() {
        if !avx_available() {
            return;
        }
        let floor = Rectangle::new(Vec3::ZERO, Vec3::X, Vec3::Z);
        let wall = Rectangle::new(Vec3::new(0.0, 0.0, 2.0), Vec3::X, Vec3::Y);
        let rectangles = [(floor, 0), (wall, 1)];
        let scene = FlatScene::new(&rectangles, &[]).unwrap();
        assert!(scene.test_every_block);
        for t_max in [f32::INFINITY, 10.0] {
            for origin in [
                Vec3::new(-1.0, 0.0, 0.5),
                Vec3::new(-1.0, 0.25, 0.5),
                Vec3::new(-1.0, 0.5, 2.0),
            ] {
                // Along +x, parallel to both: in the floor's plane across
                // it, above it, in the wall's plane across it.
                let ray = Ray::with_interval(origin, Vec3::X, 1e-4, t_max);
                assert!(scene.intersect(&ray, false).is_none(), "{origin} {t_max}");
                assert!(floor.intersect(&ray).is_none() && wall.intersect(&ray).is_none());
            }
            // Along +z from above the floor: parallel to it, into the wall.
            let ray = Ray::with_interval(Vec3::new(0.5, 0.25, -1.0), Vec3::Z, 1e-4, t_max);
            match scene.intersect(&ray, false) {
                Some(FlatHit::Rectangle { id: 1, t }) => assert_eq!(t, 3.0),
                other => panic!("{other:?}"),
            }
        }
    }

    /// A hit triangle's barycentrics put the hit point where the ray is.
    #[test]
    fn triangle_hits_carry_their_barycentrics() {
        if !avx_available() {
            return;
        }
        let tris = [
            ([Vec3::ZERO, Vec3::X, Vec3::Y], 0),
            (
                [
                    Vec3::new(0.0, 0.0, -1.0),
                    Vec3::new(2.0, 0.0, -1.0),
                    Vec3::new(0.0, 2.0, -1.0),
                ],
                1,
            ),
        ];
        let scene = FlatScene::new(&[], &tris).unwrap();
        let ray = Ray::new(Vec3::new(0.2, 0.3, 2.0), -Vec3::Z);
        let Some(FlatHit::Triangle { id: 0, t, b }) = scene.intersect(&ray, false) else {
            panic!("the nearer triangle is hit");
        };
        assert!((t - 2.0).abs() < 1e-6);
        let p = tris[0].0[0] * b[0] + tris[0].0[1] * b[1] + tris[0].0[2] * b[2];
        assert!((p - ray.at(t)).length() < 1e-6, "{p} vs {}", ray.at(t));
        // Beyond t_max nothing is hit; behind the first, the second is.
        assert_eq!(
            scene.intersect(&Ray::with_interval(ray.origin, ray.dir, 0.0, 1.5), false),
            None
        );
        let from_inside = Ray::new(Vec3::new(0.2, 0.3, -0.5), -Vec3::Z);
        assert!(matches!(
            scene.intersect(&from_inside, false),
            Some(FlatHit::Triangle { id: 1, .. })
        ));
    }

    /// Rays through the diagonal shared by two triangles of a block hit
    /// one of them, as with the one-triangle test.
    #[test]
    fn blocks_are_watertight() {
        if !avx_available() {
            return;
        }
        let q = DIAGONAL_QUAD;
        let scene = FlatScene::new(&[], &[([q[0], q[1], q[2]], 0), ([q[0], q[2], q[3]], 1)]).unwrap();
        assert_diagonal_is_watertight(13, |r| scene.intersect(r, false).is_some());
    }

    /// The expected number of boxes a ray through their union meets.
    #[test]
    fn expected_hits_is_the_ratio_of_surface_areas() {
        let unit = Aabb::from_points([Vec3::ZERO, Vec3::ONE]);
        assert_eq!(expected_hits(&[]), 0.0);
        assert!((expected_hits(&[unit, unit]) - 2.0).abs() < 1e-6);
        // Two unit cubes at opposite corners of a cube of side 10.
        let far = Aabb::from_points([Vec3::splat(9.0), Vec3::splat(10.0)]);
        assert!((expected_hits(&[unit, far]) - 2.0 / 100.0).abs() < 1e-6);
        // A wall of a room (a flat box) counts its area twice, as a ray
        // through the room's box meets it with that probability.
        let floor = Aabb::from_points([Vec3::ZERO, Vec3::new(1.0, 0.0, 1.0)]);
        assert!((expected_hits(&[floor, unit]) - (2.0 + 6.0) / 6.0).abs() < 1e-6);
    }

    /// More than sixteen blocks' worth of primitives is left to the tree.
    #[test]
    fn more_than_sixteen_blocks_are_refused() {
        if !avx_available() {
            return;
        }
        let row: Vec<(Rectangle, u32)> = (0..136)
            .map(|i| (Rectangle::new(Vec3::X * (10.0 * i as f32), Vec3::Y, Vec3::Z), i))
            .collect();
        let sixteen_blocks = FlatScene::new(&row[..128], &[]).expect("128 in a row fill sixteen blocks");
        assert_eq!(sixteen_blocks.blocks(), 16);
        assert!(FlatScene::new(&row, &[]).is_none());
    }
}
