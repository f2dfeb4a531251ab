//! Bounding volume hierarchy: binned surface-area-heuristic build and
//! stack-based, front-to-back traversal.
//!
//! The build follows Wald 2007 ("On fast Construction of SAH-based Bounding
//! Volume Hierarchies"): primitives are binned by centroid along each axis
//! and the split minimising the SAH cost
//! `C_trav + (A_L·N_L + A_R·N_R) / A` is taken; large subtrees are built in
//! parallel. Nodes are 32 bytes and laid out depth first, so the first
//! child of an interior node is the next node.

use crate::geometry::{Aabb, Ray};
use glam::Vec3;

/// One node: its box, and either two children or a run of primitives.
#[derive(Clone, Copy, Debug)]
#[repr(C)]
pub struct BvhNode {
    /// Box minimum.
    pub min: Vec3,
    /// Leaf: index of the first primitive. Interior: index of the second child.
    pub offset: u32,
    /// Box maximum.
    pub max: Vec3,
    /// Number of primitives (0 for an interior node).
    pub count: u16,
    /// Split axis of an interior node (0, 1, 2).
    pub axis: u16,
}

const _: () = assert!(std::mem::size_of::<BvhNode>() == 32);

/// A BVH over primitives numbered `0..n` in the order that
/// [`Bvh::build`] returns.
#[derive(Clone, Debug, Default)]
pub struct Bvh {
    nodes: Vec<BvhNode>,
}

/// Bins per axis in the SAH sweep.
const BINS: usize = 16;
/// The surface-area heuristic's prices (Goldsmith and Salmon 1987;
/// MacDonald and Booth 1990), relative to one leaf test.
#[derive(Clone, Copy, Debug)]
pub struct SahCosts {
    /// Cost of visiting a node.
    pub traversal: f32,
    /// Primitives of one kind tested together in one leaf test: 1 when
    /// they are tested one at a time, 4 for blocks of four triangles, 8 for
    /// the eight-lane blocks of a scene's top level, whose test costs about
    /// what one primitive's does. Primitives of kind [`ALONE`] are always
    /// tested one at a time.
    pub block: u32,
    /// Blocks of one kind a leaf may hold (primitives tested alone: at most
    /// `MAX_LEAF`).
    pub leaf_blocks: u32,
}

/// Kinds of primitive the build tells apart: a leaf test covers up to
/// [`SahCosts::block`] primitives of one kind `1..KINDS` at once, and one
/// of kind [`ALONE`] by itself.
pub const KINDS: usize = 4;
/// The kind of a primitive tested by itself (an instance, say).
pub const ALONE: u8 = 0;

impl SahCosts {
    /// Primitives tested one at a time, a node visit an eighth of a test.
    pub const ONE_AT_A_TIME: SahCosts = SahCosts {
        traversal: 0.125,
        block: 1,
        leaf_blocks: 2,
    };
    /// Blocks of four triangles: a leaf of one to four triangles costs one
    /// block test, so leaves come out fuller (more rays per second and a
    /// faster build than leaves priced one triangle at a time, `trazo bench
    /// rays` on a 1 M-triangle mesh; commit 3b77bf7).
    pub const BLOCKS_OF_FOUR: SahCosts = SahCosts {
        traversal: 0.5,
        block: 4,
        leaf_blocks: 2,
    };

    /// The prices of a build where every primitive is of one kind.
    fn uniform(&self) -> Prices<1> {
        Prices {
            traversal: self.traversal,
            block: [self.block],
            leaf_blocks: self.leaf_blocks,
        }
    }

    /// The prices of a build over [`KINDS`] kinds, [`ALONE`] tested one at
    /// a time and the others in blocks of [`SahCosts::block`].
    fn kinded(&self) -> Prices<KINDS> {
        let mut block = [self.block; KINDS];
        block[ALONE as usize] = 1;
        Prices {
            traversal: self.traversal,
            block,
            leaf_blocks: self.leaf_blocks,
        }
    }
}

/// The prices the build works with: a node visit, and per kind of
/// primitive how many one leaf test covers. A build over one kind (a mesh)
/// is its own instance, so that it counts nothing per kind.
#[derive(Clone, Copy)]
struct Prices<const K: usize> {
    traversal: f32,
    block: [u32; K],
    leaf_blocks: u32,
}

impl<const K: usize> Prices<K> {
    /// The price of a leaf holding `counts[k]` primitives of each kind.
    #[inline]
    fn leaf(&self, counts: &[u32; K]) -> f32 {
        counts
            .iter()
            .zip(&self.block)
            .map(|(&n, &b)| n.div_ceil(b))
            .sum::<u32>() as f32
    }

    /// Whether a leaf may hold `counts[k]` primitives of each kind: of each,
    /// at most `leaf_blocks` blocks or [`MAX_LEAF`], whichever is more.
    #[inline]
    fn leaf_fits(&self, counts: &[u32; K]) -> bool {
        counts
            .iter()
            .zip(&self.block)
            .all(|(&n, &b)| n <= (MAX_LEAF as u32).max(self.leaf_blocks * b))
    }
}

/// Leaves never hold more primitives tested alone than this (unless they
/// are identical).
const MAX_LEAF: usize = 8;
/// Subtrees with more primitives than this are built on another thread.
const PARALLEL_THRESHOLD: usize = 16 * 1024;
/// Depth of the traversal stack; a binned build over f32 boxes cannot go
/// deeper than this in practice, and the build enforces it.
const MAX_DEPTH: usize = 64;

/// Build input for one primitive.
#[derive(Clone, Copy)]
struct PrimInfo {
    bounds: Aabb,
    centroid: Vec3,
    /// The primitive's number, its kind in the top [`KIND_BITS`] bits (so
    /// that the record stays 40 bytes: the build moves it around a lot).
    index_and_kind: u32,
}

/// Bits of [`PrimInfo::index_and_kind`] that hold the kind.
const KIND_BITS: u32 = 2;
const _: () = assert!(KINDS <= 1 << KIND_BITS);
/// More primitives than this cannot be numbered next to their kind.
const MAX_PRIMITIVES: usize = 1 << (32 - KIND_BITS);

impl PrimInfo {
    #[inline]
    fn index(&self) -> u32 {
        self.index_and_kind & (u32::MAX >> KIND_BITS)
    }

    #[inline]
    fn kind(&self) -> usize {
        (self.index_and_kind >> (32 - KIND_BITS)) as usize
    }
}

impl Bvh {
    /// Builds a BVH over boxes. Returns the tree and the order in which the
    /// caller must store its primitives: leaf ranges index into that order
    /// (`order[k]` is the input index of the primitive at position `k`).
    pub fn build(bounds: &[Aabb]) -> (Bvh, Vec<u32>) {
        Bvh::build_with(bounds, SahCosts::ONE_AT_A_TIME)
    }

    /// [`Bvh::build`] with the given SAH prices, every primitive of one
    /// kind tested in blocks of [`SahCosts::block`].
    pub fn build_with(bounds: &[Aabb], costs: SahCosts) -> (Bvh, Vec<u32>) {
        Bvh::build_prices(bounds, |_| 0, &costs.uniform())
    }

    /// [`Bvh::build_with`] where primitive `i` is of kind `kind(i)` (below
    /// [`KINDS`]; [`ALONE`]: tested by itself), and a leaf is priced by the
    /// blocks of each kind it holds.
    pub fn build_kinds(bounds: &[Aabb], kind: impl Fn(usize) -> u8, costs: SahCosts) -> (Bvh, Vec<u32>) {
        Bvh::build_prices(bounds, kind, &costs.kinded())
    }

    fn build_prices<const K: usize>(
        bounds: &[Aabb],
        kind: impl Fn(usize) -> u8,
        prices: &Prices<K>,
    ) -> (Bvh, Vec<u32>) {
        if bounds.is_empty() {
            return (Bvh::default(), Vec::new());
        }
        assert!(
            bounds.len() <= MAX_PRIMITIVES,
            "a BVH holds at most {MAX_PRIMITIVES} primitives"
        );
        let mut prims: Vec<PrimInfo> = bounds
            .iter()
            .enumerate()
            .map(|(i, b)| {
                let k = kind(i);
                assert!((k as usize) < K, "primitive kind {k} out of range");
                PrimInfo {
                    bounds: *b,
                    centroid: b.centroid(),
                    index_and_kind: i as u32 | (k as u32) << (32 - KIND_BITS),
                }
            })
            .collect();
        let nodes = build_recursive(&mut prims, 0, 0, prices);
        let order = prims.iter().map(PrimInfo::index).collect();
        (Bvh { nodes }, order)
    }

    /// The nodes, root first.
    pub fn nodes(&self) -> &[BvhNode] {
        &self.nodes
    }

    /// Number of nodes.
    pub fn node_count(&self) -> usize {
        self.nodes.len()
    }

    /// Bytes used by the nodes.
    pub fn memory_bytes(&self) -> usize {
        self.nodes.len() * std::mem::size_of::<BvhNode>()
    }

    /// Bounds of everything in the tree.
    pub fn bounds(&self) -> Aabb {
        self.nodes
            .first()
            .map_or(Aabb::EMPTY, |n| Aabb { min: n.min, max: n.max })
    }

    /// Visits, front to back, every leaf whose box the ray enters within
    /// `[t_min, t_max]`, calling `test(k, ray)` for each primitive position
    /// `k` there. `test` intersects primitive `k`, shrinks `ray.t_max` on a
    /// hit and returns whether it hit. With `any_hit`, traversal stops at
    /// the first hit. Returns whether anything was hit.
    #[inline]
    pub fn traverse<F: FnMut(u32, &mut Ray) -> bool>(&self, ray: &mut Ray, any_hit: bool, mut test: F) -> bool {
        if self.nodes.is_empty() {
            return false;
        }
        let inv_dir = ray.dir.recip();
        let dir_neg = [inv_dir.x < 0.0, inv_dir.y < 0.0, inv_dir.z < 0.0];
        let mut stack = [0u32; MAX_DEPTH];
        let mut sp = 0usize;
        let mut current = 0u32;
        let mut hit = false;
        loop {
            let node = &self.nodes[current as usize];
            let b = Aabb {
                min: node.min,
                max: node.max,
            };
            if b.intersect(ray, inv_dir).is_some() {
                if node.count > 0 {
                    let start = node.offset;
                    for k in start..start + node.count as u32 {
                        if test(k, ray) {
                            hit = true;
                            if any_hit {
                                return true;
                            }
                        }
                    }
                } else {
                    // Visit the near child first.
                    let (first, second) = if dir_neg[node.axis as usize] {
                        (node.offset, current + 1)
                    } else {
                        (current + 1, node.offset)
                    };
                    stack[sp] = second;
                    sp += 1;
                    current = first;
                    continue;
                }
            }
            if sp == 0 {
                break;
            }
            sp -= 1;
            current = stack[sp];
        }
        hit
    }
}

/// Builds the subtree over `prims` (whose first element is at global
/// position `base`) and returns its nodes with indices relative to the
/// subtree's root at index 0.
fn build_recursive<const K: usize>(
    prims: &mut [PrimInfo],
    base: usize,
    depth: usize,
    costs: &Prices<K>,
) -> Vec<BvhNode> {
    let mut nodes = Vec::with_capacity(2 * prims.len());
    build_into(&mut nodes, prims, base, depth, costs);
    nodes
}

fn make_leaf(nodes: &mut Vec<BvhNode>, bounds: Aabb, base: usize, count: usize) {
    nodes.push(BvhNode {
        min: bounds.min,
        offset: base as u32,
        max: bounds.max,
        count: count as u16,
        axis: 0,
    });
}

fn build_into<const K: usize>(
    nodes: &mut Vec<BvhNode>,
    prims: &mut [PrimInfo],
    base: usize,
    depth: usize,
    costs: &Prices<K>,
) {
    let n = prims.len();
    let bounds = prims.iter().fold(Aabb::EMPTY, |b, p| b.union(&p.bounds));
    if n == 1 {
        make_leaf(nodes, bounds, base, n);
        return;
    }
    let centroid_bounds = prims.iter().fold(Aabb::EMPTY, |b, p| b.union_point(p.centroid));

    let split = find_split(prims, &bounds, &centroid_bounds, costs);
    // Past this depth only median splits are taken, which bound the rest
    // of the tree's depth by log2(n) and so protect the traversal stack.
    let deep = depth + (usize::BITS - n.leading_zeros()) as usize + 2 >= MAX_DEPTH;
    let (axis, mid) = match split {
        Some((axis, bin, cost)) if !deep => {
            // (Counted only where a leaf could hold them all.)
            let leaf = n <= costs.leaf_blocks.max(2) as usize * MAX_LEAF * K && {
                let counts = kind_counts(prims.iter());
                costs.leaf_fits(&counts) && costs.leaf(&counts) <= cost
            };
            if leaf {
                make_leaf(nodes, bounds, base, n);
                return;
            }
            let (lo, scale) = bin_mapping(&centroid_bounds, axis);
            let m = partition(prims, |p| bin_of(p.centroid[axis], lo, scale) <= bin);
            if m == 0 || m == n {
                (axis, median_split(prims, axis))
            } else {
                (axis, m)
            }
        }
        _ => {
            // All centroids coincide (no split separates them), or the tree
            // is too deep: split at the median of the longest axis.
            if n <= MAX_LEAF {
                make_leaf(nodes, bounds, base, n);
                return;
            }
            let axis = centroid_bounds.longest_axis();
            (axis, median_split(prims, axis))
        }
    };

    let me = nodes.len();
    nodes.push(BvhNode {
        min: bounds.min,
        offset: 0,
        max: bounds.max,
        count: 0,
        axis: axis as u16,
    });
    let (left, right) = prims.split_at_mut(mid);
    if n > PARALLEL_THRESHOLD {
        let (ln, rn) = rayon::join(
            || build_recursive(left, base, depth + 1, costs),
            || build_recursive(right, base + mid, depth + 1, costs),
        );
        append_subtree(nodes, ln);
        nodes[me].offset = nodes.len() as u32;
        append_subtree(nodes, rn);
    } else {
        build_into(nodes, left, base, depth + 1, costs);
        nodes[me].offset = nodes.len() as u32;
        build_into(nodes, right, base + mid, depth + 1, costs);
    }
}

/// How many of `prims` are of each kind.
fn kind_counts<'a, const K: usize>(prims: impl Iterator<Item = &'a PrimInfo>) -> [u32; K] {
    let mut counts = [0u32; K];
    for p in prims {
        counts[p.kind()] += 1;
    }
    counts
}

/// Orders `prims` around the median centroid on `axis`; returns n/2.
fn median_split(prims: &mut [PrimInfo], axis: usize) -> usize {
    let mid = prims.len() / 2;
    prims.select_nth_unstable_by(mid, |a, b| a.centroid[axis].total_cmp(&b.centroid[axis]));
    mid
}

/// Appends a subtree built with local indices, relocating its child links.
fn append_subtree(nodes: &mut Vec<BvhNode>, sub: Vec<BvhNode>) {
    let shift = nodes.len() as u32;
    nodes.extend(sub.into_iter().map(|mut node| {
        if node.count == 0 {
            node.offset += shift;
        }
        node
    }));
}

#[inline]
fn bin_mapping(cb: &Aabb, axis: usize) -> (f32, f32) {
    let extent = cb.max[axis] - cb.min[axis];
    (cb.min[axis], BINS as f32 * (1.0 - 1e-6) / extent)
}

#[inline]
fn bin_of(c: f32, lo: f32, scale: f32) -> usize {
    (((c - lo) * scale) as usize).min(BINS - 1)
}

/// The best (axis, last bin of the left side, SAH cost relative to one leaf
/// test) over all three axes, or `None` if all centroids coincide.
fn find_split<const K: usize>(
    prims: &[PrimInfo],
    bounds: &Aabb,
    cb: &Aabb,
    costs: &Prices<K>,
) -> Option<(usize, usize, f32)> {
    let area = bounds.surface_area().max(f32::MIN_POSITIVE);
    let mut best: Option<(usize, usize, f32)> = None;
    for axis in 0..3 {
        let extent = cb.max[axis] - cb.min[axis];
        if extent <= 0.0 || !extent.is_finite() {
            continue;
        }
        let (lo, scale) = bin_mapping(cb, axis);
        let mut bin_bounds = [Aabb::EMPTY; BINS];
        let mut bin_count = [[0u32; K]; BINS];
        for p in prims {
            let b = bin_of(p.centroid[axis], lo, scale);
            bin_bounds[b] = bin_bounds[b].union(&p.bounds);
            bin_count[b][p.kind()] += 1;
        }
        let add = |a: &mut [u32; K], b: &[u32; K]| a.iter_mut().zip(b).for_each(|(a, b)| *a += b);
        // Sweep from the right to get the cost of every right side.
        let mut right_area = [0f32; BINS];
        let mut right_count = [[0u32; K]; BINS];
        let mut acc = Aabb::EMPTY;
        let mut cnt = [0u32; K];
        for i in (1..BINS).rev() {
            acc = acc.union(&bin_bounds[i]);
            add(&mut cnt, &bin_count[i]);
            right_area[i] = acc.surface_area();
            right_count[i] = cnt;
        }
        let mut acc = Aabb::EMPTY;
        let mut cnt = [0u32; K];
        for i in 0..BINS - 1 {
            acc = acc.union(&bin_bounds[i]);
            add(&mut cnt, &bin_count[i]);
            let (nl, nr) = (&cnt, &right_count[i + 1]);
            if nl.iter().sum::<u32>() == 0 || nr.iter().sum::<u32>() == 0 {
                continue;
            }
            let cost =
                costs.traversal + (acc.surface_area() * costs.leaf(nl) + right_area[i + 1] * costs.leaf(nr)) / area;
            if best.is_none_or(|(_, _, c)| cost < c) {
                best = Some((axis, i, cost));
            }
        }
    }
    best
}

/// Moves the elements satisfying `pred` to the front; returns their count.
fn partition<T, F: Fn(&T) -> bool>(v: &mut [T], pred: F) -> usize {
    let mut first = 0;
    for i in 0..v.len() {
        if pred(&v[i]) {
            v.swap(first, i);
            first += 1;
        }
    }
    first
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::shape::{Shape, Sphere};
    use crate::sampling::rng::Pcg32;

    fn random_spheres(n: usize, seed: u64) -> Vec<Shape> {
        let mut r = Pcg32::new(seed, 0);
        (0..n)
            .map(|_| {
                Shape::Sphere(Sphere::new(
                    Vec3::new(r.next_f32(), r.next_f32(), r.next_f32()) * 20.0 - 10.0,
                    0.05 + r.next_f32() * 0.6,
                ))
            })
            .collect()
    }

    fn closest_brute(shapes: &[Shape], ray: &Ray) -> Option<(usize, f32)> {
        let mut best: Option<(usize, f32)> = None;
        let mut r = *ray;
        for (i, s) in shapes.iter().enumerate() {
            if let Some(t) = s.intersect(&r) {
                r.t_max = t;
                best = Some((i, t));
            }
        }
        best
    }

    #[test]
    fn bvh_matches_brute_force_on_random_scenes() {
        for (seed, n) in [(1u64, 1usize), (2, 7), (3, 300), (4, 5000)] {
            let shapes = random_spheres(n, seed);
            let bounds: Vec<Aabb> = shapes.iter().map(|s| s.bounds().unwrap()).collect();
            let (bvh, order) = Bvh::build(&bounds);
            let ordered: Vec<Shape> = order.iter().map(|&i| shapes[i as usize].clone()).collect();
            let mut rng = Pcg32::new(seed + 100, 0);
            for _ in 0..2000 {
                let o = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 30.0 - 15.0;
                let d = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 2.0 - 1.0;
                let ray = Ray::new(o, d);
                let expect = closest_brute(&shapes, &ray);
                let mut r = ray;
                let mut got: Option<usize> = None;
                bvh.traverse(&mut r, false, |k, r| match ordered[k as usize].intersect(r) {
                    Some(t) => {
                        r.t_max = t;
                        got = Some(order[k as usize] as usize);
                        true
                    }
                    None => false,
                });
                match expect {
                    None => assert!(got.is_none()),
                    Some((i, t)) => {
                        assert_eq!(r.t_max, t);
                        // Ties between touching spheres may pick either.
                        let gi = got.unwrap();
                        assert!(gi == i || shapes[gi].intersect(&ray) == Some(t));
                    }
                }
                let mut r2 = ray;
                let any = bvh.traverse(&mut r2, true, |k, r| ordered[k as usize].intersect(r).is_some());
                assert_eq!(any, expect.is_some());
            }
        }
    }

    #[test]
    fn structure_is_consistent() {
        let shapes = random_spheres(20_000, 9);
        let bounds: Vec<Aabb> = shapes.iter().map(|s| s.bounds().unwrap()).collect();
        let (bvh, order) = Bvh::build(&bounds);
        // Every primitive is in exactly one leaf, inside its node's box.
        let mut seen = vec![false; shapes.len()];
        for node in bvh.nodes() {
            if node.count > 0 {
                for k in node.offset..node.offset + node.count as u32 {
                    let i = order[k as usize] as usize;
                    assert!(!seen[i]);
                    seen[i] = true;
                    let b = bounds[i];
                    assert!(b.min.cmpge(node.min).all() && b.max.cmple(node.max).all());
                }
            } else {
                assert!(node.offset as usize > 0 && (node.offset as usize) < bvh.node_count());
            }
        }
        assert!(seen.iter().all(|&s| s));
        assert!(bvh.node_count() < 2 * shapes.len());
        assert_eq!(bvh.memory_bytes(), bvh.node_count() * 32);
    }

    #[test]
    fn identical_primitives_and_empty_input() {
        let bounds = vec![Aabb::new(Vec3::ZERO, Vec3::ONE); 100];
        let (bvh, order) = Bvh::build(&bounds);
        assert_eq!(order.len(), 100);
        let mut r = Ray::new(Vec3::splat(0.5) - Vec3::Z * 3.0, Vec3::Z);
        let mut visited = 0;
        bvh.traverse(&mut r, false, |_, _| {
            visited += 1;
            false
        });
        assert_eq!(visited, 100);
        let (empty, order) = Bvh::build(&[]);
        assert!(order.is_empty());
        let mut r = Ray::new(Vec3::ZERO, Vec3::Z);
        assert!(!empty.traverse(&mut r, false, |_, _| true));
    }
}
