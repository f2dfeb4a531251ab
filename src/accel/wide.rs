//! Four- and eight-wide BVHs, collapsed from the binary SAH tree.
//!
//! Each node stores the boxes of up to `W` children in structure-of-arrays
//! form, so that one ray is tested against four boxes at a time with the
//! same few vector instructions (the "multi-BVH" layout of Ernst and Greiner
//! 2008 and Wald et al. 2008, which Embree uses). Collapsing follows the
//! usual greedy rule: a node adopts the children of its largest interior
//! child until it has `W`. Leaves keep the binary tree's primitive
//! ranges, so callers store primitives in the order [`Bvh::build`] gives.

use super::bvh::{Bvh, BvhNode};
use crate::geometry::Ray;
use crate::geometry::bounds::gamma;
use arrayvec::ArrayVec;
use glam::Vec4;

/// Widening of the slab test's far distance that makes it conservative
/// under rounding (pbrt-v4, section 6.8.2).
const SLAB_ROUNDING: f32 = 1.0 + 2.0 * gamma(3);

/// Widest node supported.
const MAX_WIDTH: usize = 8;

/// Traversal stack depth: a collapsed tree is at most as deep as its
/// binary tree (64) and each level pushes at most `W − 1` entries.
const STACK: usize = (MAX_WIDTH - 1) * 64 + MAX_WIDTH;

/// One node: `W` child boxes and what each child is.
#[derive(Clone, Copy, Debug)]
#[repr(C, align(64))]
pub struct WideNode<const W: usize> {
    /// Box bounds of the children, one array per coordinate and side.
    bounds: [[f32; W]; 6],
    /// Interior child: node index. Leaf child: first primitive position.
    child: [u32; W],
    /// Leaf child: number of primitives; interior child or empty slot: 0.
    count: [u32; W],
}

const _: () = assert!(std::mem::size_of::<WideNode<4>>() == 128);
const _: () = assert!(std::mem::size_of::<WideNode<8>>() == 256);

const MIN_X: usize = 0;
const MIN_Y: usize = 1;
const MIN_Z: usize = 2;
const MAX_X: usize = 3;
const MAX_Y: usize = 4;
const MAX_Z: usize = 5;

impl<const W: usize> WideNode<W> {
    const EMPTY: WideNode<W> = WideNode {
        bounds: [
            [f32::INFINITY; W],
            [f32::INFINITY; W],
            [f32::INFINITY; W],
            [f32::NEG_INFINITY; W],
            [f32::NEG_INFINITY; W],
            [f32::NEG_INFINITY; W],
        ],
        child: [0; W],
        count: [0; W],
    };
}

/// A `W`-wide BVH (`W` = 4 or 8) over primitives numbered as in the binary
/// tree it was collapsed from.
#[derive(Clone, Debug)]
pub struct WideBvh<const W: usize> {
    nodes: Vec<WideNode<W>>,
    /// A tree with a single leaf and no interior node.
    root_leaf: Option<(u32, u32)>,
}

/// Four children a node: one SSE/NEON register of boxes per test.
pub type Bvh4 = WideBvh<4>;
/// Eight children a node: shallower trees, two registers per test.
pub type Bvh8 = WideBvh<8>;

impl<const W: usize> Default for WideBvh<W> {
    fn default() -> Self {
        WideBvh {
            nodes: Vec::new(),
            root_leaf: None,
        }
    }
}

/// One entry of the traversal stack.
#[derive(Clone, Copy, Default)]
struct StackEntry {
    /// Node index or first primitive.
    child: u32,
    /// Primitive count, or 0 for a node.
    count: u32,
    /// Where the ray enters the child's box.
    t_enter: f32,
}

impl<const W: usize> WideBvh<W> {
    const VALID_WIDTH: () = assert!(W == 4 || W == 8);

    /// Collapses a binary tree.
    pub fn from_binary(bvh: &Bvh) -> WideBvh<W> {
        #[allow(clippy::let_unit_value)]
        let () = Self::VALID_WIDTH;
        let nodes = bvh.nodes();
        if nodes.is_empty() {
            return WideBvh::default();
        }
        if nodes[0].count > 0 {
            return WideBvh {
                nodes: Vec::new(),
                root_leaf: Some((nodes[0].offset, nodes[0].count as u32)),
            };
        }
        let mut wide = Vec::with_capacity(nodes.len() / 3 + 1);
        collapse(nodes, 0, &mut wide);
        WideBvh {
            nodes: wide,
            root_leaf: None,
        }
    }

    /// The first item and the number of items of the tree's one leaf,
    /// where the tree is a single leaf.
    #[inline]
    pub fn root_leaf(&self) -> Option<(u32, u32)> {
        self.root_leaf
    }

    /// Renumbers every leaf: `f(first, count)` gives the leaf's new first
    /// position and count, which [`WideBvh::traverse`] then hands to its test.
    /// Leaves are visited in the order of their primitives, so a caller can
    /// repack a leaf's primitives into blocks (four triangles a block, say)
    /// and number the blocks instead.
    pub fn remap_leaves(&mut self, mut f: impl FnMut(u32, u32) -> (u32, u32)) {
        if let Some((first, count)) = self.root_leaf {
            self.root_leaf = Some(f(first, count));
            return;
        }
        let mut leaves: Vec<(usize, usize)> = Vec::new();
        for (n, node) in self.nodes.iter().enumerate() {
            for slot in 0..W {
                if node.count[slot] > 0 {
                    leaves.push((n, slot));
                }
            }
        }
        leaves.sort_unstable_by_key(|&(n, slot)| self.nodes[n].child[slot]);
        for (n, slot) in leaves {
            let node = &mut self.nodes[n];
            let (first, count) = f(node.child[slot], node.count[slot]);
            node.child[slot] = first;
            node.count[slot] = count;
        }
    }

    /// Number of nodes.
    pub fn node_count(&self) -> usize {
        self.nodes.len()
    }

    /// Bytes used by the nodes.
    pub fn memory_bytes(&self) -> usize {
        self.nodes.len() * std::mem::size_of::<WideNode<W>>()
    }

    /// Visits the leaves whose boxes the ray enters within its interval,
    /// nearest box first, calling `test(k, ray)` for each primitive
    /// position `k`; `test` shrinks `ray.t_max` on a hit and returns
    /// whether it hit. With `any_hit`, stops at the first hit. Returns
    /// whether anything was hit.
    #[inline]
    pub fn traverse<F: FnMut(u32, &mut Ray) -> bool>(&self, ray: &mut Ray, any_hit: bool, test: F) -> bool {
        self.traverse_impl::<false, false, false, (), F>(&[], ray, any_hit, test)
    }

    /// [`WideBvh::traverse`] for a large tree whose primitive positions
    /// index `leaves` (the blocks of a mesh tree, say): when a node pushes
    /// the children a ray enters, the node or first leaf item of each
    /// child visited after the nearest is prefetched.
    #[inline]
    pub fn traverse_leaves<L, F: FnMut(u32, &mut Ray) -> bool>(
        &self,
        leaves: &[L],
        ray: &mut Ray,
        any_hit: bool,
        test: F,
    ) -> bool {
        self.traverse_impl::<false, true, false, L, F>(leaves, ray, any_hit, test)
    }

    /// [`WideBvh::traverse_leaves`] with an eight-wide node's boxes tested
    /// in one AVX register instead of two SSE ones (the same arithmetic,
    /// so the same hits).
    ///
    /// # Safety
    ///
    /// The processor must have AVX.
    #[cfg(target_arch = "x86_64")]
    #[inline]
    #[allow(unsafe_code)]
    pub unsafe fn traverse_leaves_avx<L, F: FnMut(u32, &mut Ray) -> bool>(
        &self,
        leaves: &[L],
        ray: &mut Ray,
        any_hit: bool,
        test: F,
    ) -> bool {
        self.traverse_impl::<false, true, true, L, F>(leaves, ray, any_hit, test)
    }

    /// [`WideBvh::traverse`] with the root's children tested before the
    /// loop instead of the root being pushed and popped. In a small tree
    /// (a scene's top level, of which a ray visits three or four nodes)
    /// the root is a good part of the visits, and skipping its push and
    /// pop saves instructions and mispredicted branches. In a large mesh's
    /// tree, where one visit in twenty is the root's, the same code traced
    /// fewer rays per second, so those keep the plain loop (commit e8dc360).
    #[inline]
    pub fn traverse_small<F: FnMut(u32, &mut Ray) -> bool>(&self, ray: &mut Ray, any_hit: bool, test: F) -> bool {
        self.traverse_impl::<true, false, false, (), F>(&[], ray, any_hit, test)
    }

    /// `AVX`: eight-wide boxes in one AVX register; only where the
    /// processor has AVX.
    #[inline(always)]
    #[allow(unsafe_code)]
    fn traverse_impl<
        const ROOT_FIRST: bool,
        const PREFETCH: bool,
        const AVX: bool,
        L,
        F: FnMut(u32, &mut Ray) -> bool,
    >(
        &self,
        leaves: &[L],
        ray: &mut Ray,
        any_hit: bool,
        mut test: F,
    ) -> bool {
        if let Some((first, count)) = self.root_leaf {
            let mut hit = false;
            for k in first..first + count {
                if test(k, ray) {
                    hit = true;
                    if any_hit {
                        return true;
                    }
                }
            }
            return hit;
        }
        if self.nodes.is_empty() {
            return false;
        }
        let (org, dir, _) = ray.read_by_field();
        let inv = dir.recip();
        let (ox, oy, oz) = (Vec4::splat(org.x), Vec4::splat(org.y), Vec4::splat(org.z));
        let (ix, iy, iz) = (Vec4::splat(inv.x), Vec4::splat(inv.y), Vec4::splat(inv.z));
        // Per ray, pick which side of each box is entered first, so that a
        // box test is two subtractions and multiplications per axis.
        // As arithmetic on the sign bits, so that the compiler sees every
        // plane index below 6 and checks none of them.
        let (sx, sy, sz) = (
            (inv.x < 0.0) as usize * 3,
            (inv.y < 0.0) as usize * 3,
            (inv.z < 0.0) as usize * 3,
        );
        let (near_x, far_x) = (MIN_X + sx, MAX_X - sx);
        let (near_y, far_y) = (MIN_Y + sy, MAX_Y - sy);
        let (near_z, far_z) = (MIN_Z + sz, MAX_Z - sz);

        // An ArrayVec, not an array: a zeroed 2 KiB stack per ray cost
        // more than the traversal of a small scene.
        let mut stack: ArrayVec<StackEntry, STACK> = ArrayVec::new();
        // The box test of a node's children and the push of those hit, as
        // a macro so that the root's visit and the loop's share it with no
        // call between them.
        macro_rules! visit_node {
            ($index:expr) => {{
                let node = &self.nodes[$index as usize];
                let b = &node.bounds;
                // Four slab tests at once: glam's Vec4 is an SSE register
                // on x86-64 (and NEON on aarch64), so this is a dozen vector
                // instructions without `unsafe`. `max`/`min` return their
                // second operand when the first is NaN (0·∞ for a ray in a
                // box's face plane), as the scalar slab test does.
                let mut hits = 0;
                let mut t_enter = [0.0f32; W];
                #[cfg(target_arch = "x86_64")]
                let boxes_done = AVX && W == 8 && {
                    let row = |plane: usize| -> &[f32; 8] { b[plane].as_slice().try_into().expect("eight-wide") };
                    let out: &mut [f32; 8] = t_enter.as_mut_slice().try_into().expect("eight-wide");
                    // SAFETY: AVX traversals run where the processor has
                    // AVX (the contract of `traverse_leaves_avx`).
                    hits = unsafe {
                        boxes_avx(
                            [
                                row(near_x),
                                row(near_y),
                                row(near_z),
                                row(far_x),
                                row(far_y),
                                row(far_z),
                            ],
                            org,
                            inv,
                            (ray.t_min, ray.t_max),
                            out,
                        )
                    };
                    true
                };
                #[cfg(not(target_arch = "x86_64"))]
                let boxes_done = false;
                for c in 0..if boxes_done { 0 } else { W / 4 } {
                    let lanes = |plane: usize| Vec4::from_slice(&b[plane][4 * c..4 * c + 4]);
                    let tx0 = (lanes(near_x) - ox) * ix;
                    let ty0 = (lanes(near_y) - oy) * iy;
                    let tz0 = (lanes(near_z) - oz) * iz;
                    let tx1 = (lanes(far_x) - ox) * ix;
                    let ty1 = (lanes(far_y) - oy) * iy;
                    let tz1 = (lanes(far_z) - oz) * iz;
                    let t0 = tx0.max(ty0).max(tz0.max(Vec4::splat(ray.t_min)));
                    let t1 = tx1.min(ty1).min(tz1.min(Vec4::splat(ray.t_max))) * SLAB_ROUNDING;
                    hits |= t0.cmple(t1).bitmask() << (4 * c);
                    t0.write_to_slice(&mut t_enter[4 * c..4 * c + 4]);
                }
                if hits != 0 {
                    // Push the children that were hit, farthest first, so that the
                    // nearest is visited next.
                    let base = stack.len();
                    for (i, &t) in t_enter.iter().enumerate() {
                        if hits & (1 << i) != 0 {
                            let e = StackEntry {
                                child: node.child[i],
                                count: node.count[i],
                                t_enter: t,
                            };
                            let mut j = stack.len();
                            stack.push(e);
                            // A shadow ray stops at any hit: no order to keep.
                            if any_hit {
                                continue;
                            }
                            // Insertion sort by decreasing entry distance.
                            while j > base && stack[j - 1].t_enter < e.t_enter {
                                stack[j] = stack[j - 1];
                                j -= 1;
                            }
                            stack[j] = e;
                        }
                    }
                    // Start loading the children visited later (all but
                    // the nearest, which is read next anyway): in a large
                    // tree they are rarely in the cache, and their loads
                    // then overlap the nearest child's subtree. Trees that
                    // stay in the cache are left without (commit 76dd728).
                    if PREFETCH {
                        for e in &stack[base..stack.len() - 1] {
                            if e.count == 0 {
                                prefetch(&self.nodes[e.child as usize], 4);
                            } else if let Some(first) = leaves.get(e.child as usize) {
                                prefetch(first, 4);
                            }
                        }
                    }
                }
            }};
        }
        if ROOT_FIRST {
            visit_node!(0);
        } else {
            stack.push(StackEntry {
                child: 0,
                count: 0,
                t_enter: ray.t_min,
            });
        }
        let mut hit = false;
        while let Some(entry) = stack.pop() {
            if entry.t_enter > ray.t_max {
                continue;
            }
            if entry.count > 0 {
                for k in entry.child..entry.child + entry.count {
                    if test(k, ray) {
                        hit = true;
                        if any_hit {
                            return true;
                        }
                    }
                }
                continue;
            }
            visit_node!(entry.child);
        }
        hit
    }
}

/// The slab tests of eight boxes, whose near and far planes along x, y
/// and z are `planes` (as the ray enters them), in one AVX register: the
/// SSE test's arithmetic in the same order, so the same bits. Returns the
/// mask of the boxes the ray's interval `(t_min, t_max)` meets and writes
/// where it enters each.
#[cfg(target_arch = "x86_64")]
#[inline]
#[target_feature(enable = "avx")]
fn boxes_avx(
    planes: [&[f32; 8]; 6],
    org: glam::Vec3,
    inv: glam::Vec3,
    (t_min, t_max): (f32, f32),
    t_enter: &mut [f32; 8],
) -> u32 {
    use crate::geometry::lanes::F8;
    let slab = |plane: &[f32; 8], o: f32, i: f32| F8::load_unaligned(plane).sub(F8::splat(o)).mul(F8::splat(i));
    let tx0 = slab(planes[0], org.x, inv.x);
    let ty0 = slab(planes[1], org.y, inv.y);
    let tz0 = slab(planes[2], org.z, inv.z);
    let tx1 = slab(planes[3], org.x, inv.x);
    let ty1 = slab(planes[4], org.y, inv.y);
    let tz1 = slab(planes[5], org.z, inv.z);
    let t0 = tx0.max(ty0).max(tz0.max(F8::splat(t_min)));
    let t1 = tx1
        .min(ty1)
        .min(tz1.min(F8::splat(t_max)))
        .mul(F8::splat(SLAB_ROUNDING));
    t0.store_unaligned(t_enter);
    t0.le(t1).bits()
}

/// Starts loading the cache lines of `value` (at most `lines`), where the
/// processor has a prefetch hint that trazo uses (x86-64); elsewhere
/// nothing.
#[inline(always)]
fn prefetch<T>(value: &T, lines: usize) {
    #[cfg(target_arch = "x86_64")]
    crate::geometry::lanes::prefetch(value, lines);
    #[cfg(not(target_arch = "x86_64"))]
    let _ = (value, lines);
}

/// Writes the wide node for binary interior node `index` (and, depth
/// first, its subtree); returns its index in `wide`.
fn collapse<const W: usize>(nodes: &[BvhNode], index: usize, wide: &mut Vec<WideNode<W>>) -> u32 {
    // Gather up to `W` children: open the largest interior child until
    // there are `W` or only leaves remain.
    let node = &nodes[index];
    let mut kids: Vec<usize> = vec![index + 1, node.offset as usize];
    while kids.len() < W {
        let open = kids
            .iter()
            .enumerate()
            .filter(|(_, k)| nodes[**k].count == 0)
            .max_by(|a, b| area(&nodes[*a.1]).total_cmp(&area(&nodes[*b.1])))
            .map(|(i, _)| i);
        let Some(i) = open else { break };
        let k = kids.swap_remove(i);
        kids.push(k + 1);
        kids.push(nodes[k].offset as usize);
    }
    let me = wide.len();
    wide.push(WideNode::EMPTY);
    let mut out = WideNode::EMPTY;
    for (slot, &k) in kids.iter().enumerate() {
        let n = &nodes[k];
        out.bounds[MIN_X][slot] = n.min.x;
        out.bounds[MIN_Y][slot] = n.min.y;
        out.bounds[MIN_Z][slot] = n.min.z;
        out.bounds[MAX_X][slot] = n.max.x;
        out.bounds[MAX_Y][slot] = n.max.y;
        out.bounds[MAX_Z][slot] = n.max.z;
        if n.count > 0 {
            out.child[slot] = n.offset;
            out.count[slot] = n.count as u32;
        } else {
            out.child[slot] = collapse(nodes, k, wide);
        }
    }
    wide[me] = out;
    me as u32
}

fn area(n: &BvhNode) -> f32 {
    let d = n.max - n.min;
    d.x * d.y + d.y * d.z + d.z * d.x
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::{Aabb, TriangleMesh};
    use crate::sampling::rng::Pcg32;
    use crate::sampling::warp::sample_sphere_uniform;
    use glam::{Vec2, Vec3};

    /// Primitive positions hit by the binary and the wide tree must agree,
    /// for closest and any hit, on boxes as primitives.
    #[test]
    fn wide_tree_finds_what_the_binary_tree_finds() {
        let mut rng = Pcg32::new(11, 2);
        for n in [1usize, 2, 3, 7, 100, 2000] {
            let boxes: Vec<Aabb> = (0..n)
                .map(|_| {
                    let c = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 10.0;
                    let h = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 0.3 + Vec3::splat(0.01);
                    Aabb::new(c - h, c + h)
                })
                .collect();
            let (bvh, order) = Bvh::build(&boxes);
            let wide = Bvh4::from_binary(&bvh);
            let wide8 = Bvh8::from_binary(&bvh);
            let prim = |k: u32| boxes[order[k as usize] as usize];
            for _ in 0..300 {
                let o = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 12.0 - Vec3::ONE;
                let d = sample_sphere_uniform(Vec2::new(rng.next_f32(), rng.next_f32()));
                let test = |k: u32, r: &mut Ray| {
                    let b = prim(k);
                    match b.intersect(r, r.dir.recip()) {
                        Some((t0, _)) if t0 > r.t_min => {
                            r.t_max = t0;
                            true
                        }
                        _ => false,
                    }
                };
                let mut r1 = Ray::with_interval(o, d, 1e-4, f32::INFINITY);
                let mut r2 = r1;
                let h1 = bvh.traverse(&mut r1, false, test);
                let h2 = wide.traverse(&mut r2, false, test);
                assert_eq!(h1, h2, "n = {n}");
                assert_eq!(r1.t_max, r2.t_max, "n = {n}");
                let mut r3 = Ray::with_interval(o, d, 1e-4, f32::INFINITY);
                assert_eq!(wide.traverse(&mut r3, true, test), h1);
                let mut r4 = Ray::with_interval(o, d, 1e-4, f32::INFINITY);
                assert_eq!(wide8.traverse(&mut r4, false, test), h1, "n = {n}");
                assert_eq!(r4.t_max, r1.t_max, "n = {n}");
                let mut r5 = Ray::with_interval(o, d, 1e-4, f32::INFINITY);
                assert_eq!(wide8.traverse(&mut r5, true, test), h1);
                // The root visited before the loop finds the same.
                let mut r6 = Ray::with_interval(o, d, 1e-4, f32::INFINITY);
                assert_eq!(wide.traverse_small(&mut r6, false, test), h1, "n = {n}");
                assert_eq!(r6.t_max, r1.t_max, "n = {n}");
                let mut r7 = Ray::with_interval(o, d, 1e-4, f32::INFINITY);
                assert_eq!(wide.traverse_small(&mut r7, true, test), h1);
                // Eight-wide boxes in one AVX register: the same boxes, in
                // the same order, so the same hits.
                #[cfg(target_arch = "x86_64")]
                if crate::geometry::lanes::avx_available() {
                    for any_hit in [false, true] {
                        let mut r8 = Ray::with_interval(o, d, 1e-4, f32::INFINITY);
                        let mut r9 = r8;
                        let mut order_plain = Vec::new();
                        let mut order_avx = Vec::new();
                        let plain = wide8.traverse_leaves(&[(); 0], &mut r8, any_hit, |k, r| {
                            order_plain.push(k);
                            test(k, r)
                        });
                        // SAFETY: the processor has AVX.
                        #[allow(unsafe_code)]
                        let avx = unsafe {
                            wide8.traverse_leaves_avx(&[(); 0], &mut r9, any_hit, |k, r| {
                                order_avx.push(k);
                                test(k, r)
                            })
                        };
                        assert_eq!((plain, r8.t_max), (avx, r9.t_max), "n = {n}");
                        assert_eq!(order_plain, order_avx, "n = {n}");
                    }
                }
            }
        }
    }

    /// Every primitive in exactly one leaf; a `W`-wide node replaces at
    /// most `W − 1` binary interior nodes.
    fn check_collapse<const W: usize>(bvh: &Bvh, primitives: usize) {
        let wide = WideBvh::<W>::from_binary(bvh);
        let mut seen = vec![0u32; primitives];
        for n in &wide.nodes {
            for slot in 0..W {
                for k in n.child[slot]..n.child[slot] + n.count[slot] {
                    seen[k as usize] += 1;
                }
            }
        }
        assert!(seen.iter().all(|&c| c == 1), "W = {W}");
        let interior = bvh.nodes().iter().filter(|n| n.count == 0).count();
        assert!(
            wide.node_count() <= interior && wide.node_count() * (W - 1) >= interior,
            "W = {W}: {} nodes for {interior}",
            wide.node_count()
        );
    }

    #[test]
    fn leaves_cover_every_primitive_once_in_fewer_nodes() {
        let mesh = TriangleMesh::uv_sphere(Vec3::ZERO, 1.0, 64, 32);
        let bounds: Vec<Aabb> = (0..mesh.len()).map(|i| mesh.triangle_bounds(i)).collect();
        let (bvh, _) = Bvh::build(&bounds);
        check_collapse::<4>(&bvh, mesh.len());
        check_collapse::<8>(&bvh, mesh.len());
        assert!(Bvh8::from_binary(&bvh).node_count() < Bvh4::from_binary(&bvh).node_count());
    }
}
