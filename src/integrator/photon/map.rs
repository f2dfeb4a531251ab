//! The photon map: photons stored in a balanced kd-tree (Jensen 2001,
//! "Realistic Image Synthesis Using Photon Mapping", §6.3; Bentley 1975),
//! with the two queries density estimation needs: the k nearest photons
//! within a maximum distance, and every photon within a fixed radius.
//!
//! The tree is implicit: for a range of the array, the node is its middle
//! element, the median of the range along the axis of its largest extent;
//! the left half holds the photons below it, the right half those above.
//! No pointers, one byte per photon for the split axis, and the build
//! (median selection, O(n log n)) splits into independent halves that run
//! on all cores. A photon is 32 bytes: position, power, and the incoming
//! direction and surface normal in 32-bit octahedral encodings.

use crate::color::Rgb;
use glam::{Vec2, Vec3};

/// A photon: light arriving at a surface.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Photon {
    /// Where it landed.
    pub p: Vec3,
    /// Flux it carries (W).
    pub power: Rgb,
    wi: u32,
    n: u32,
}

impl Photon {
    /// A photon at `p` carrying `power`, which arrived from direction `wi`
    /// (unit, pointing back toward where it came from) on a surface of
    /// geometric normal `n` (unit).
    pub fn new(p: Vec3, power: Rgb, wi: Vec3, n: Vec3) -> Photon {
        Photon {
            p,
            power,
            wi: oct_encode(wi),
            n: oct_encode(n),
        }
    }

    /// Unit direction toward where the photon came from.
    #[inline]
    pub fn wi(&self) -> Vec3 {
        oct_decode(self.wi)
    }

    /// Geometric normal of the surface it landed on.
    #[inline]
    pub fn normal(&self) -> Vec3 {
        oct_decode(self.n)
    }
}

/// A unit vector as two 16-bit coordinates of the octahedral map (Meyer et
/// al. 2010, "On Floating-Point Normal Vectors"): the angular error is
/// below 1e-4 radians, ample for a kernel's normal test and a BSDF lookup.
pub fn oct_encode(v: Vec3) -> u32 {
    let l1 = v.x.abs() + v.y.abs() + v.z.abs();
    if l1 == 0.0 {
        return oct_quantize(Vec2::ZERO);
    }
    let mut p = Vec2::new(v.x, v.y) / l1;
    if v.z < 0.0 {
        let s = Vec2::new(sign(p.x), sign(p.y));
        p = (Vec2::ONE - Vec2::new(p.y.abs(), p.x.abs())) * s;
    }
    oct_quantize(p)
}

#[inline]
fn sign(x: f32) -> f32 {
    if x < 0.0 { -1.0 } else { 1.0 }
}

#[inline]
fn oct_quantize(p: Vec2) -> u32 {
    let q = |x: f32| ((x.clamp(-1.0, 1.0) * 0.5 + 0.5) * 65535.0).round() as u32;
    q(p.x) | (q(p.y) << 16)
}

/// Inverse of [`oct_encode`].
#[inline]
pub fn oct_decode(e: u32) -> Vec3 {
    let d = |b: u32| (b & 0xffff) as f32 / 65535.0 * 2.0 - 1.0;
    let (x, y) = (d(e), d(e >> 16));
    let z = 1.0 - x.abs() - y.abs();
    let t = (-z).max(0.0);
    let v = Vec3::new(x - t * sign(x), y - t * sign(y), z);
    v.normalize()
}

/// What a [`PhotonMap`] stores: anything with a position. Photon mapping
/// stores [`Photon`]s; vertex merging stores light-path vertices with the
/// quantities its weights need.
pub trait Located: Send {
    /// Where it lies.
    fn position(&self) -> Vec3;
}

impl Located for Photon {
    #[inline]
    fn position(&self) -> Vec3 {
        self.p
    }
}

/// Photons (or other [`Located`] records) in a balanced kd-tree.
#[derive(Clone, Debug)]
pub struct PhotonMap<P = Photon> {
    photons: Vec<P>,
    axes: Vec<u8>,
}

impl<P> Default for PhotonMap<P> {
    fn default() -> Self {
        PhotonMap {
            photons: Vec::new(),
            axes: Vec::new(),
        }
    }
}

/// Subtrees larger than this are built on another thread.
const PARALLEL_BUILD: usize = 1 << 14;

/// Deepest traversal stack: a balanced tree of 2³² photons is 32 deep.
const STACK: usize = 64;

impl<P: Located> PhotonMap<P> {
    /// Builds the tree; the photons are reordered.
    pub fn build(mut photons: Vec<P>) -> PhotonMap<P> {
        assert!(photons.len() < u32::MAX as usize, "too many photons for one map");
        let mut axes = vec![0u8; photons.len()];
        build_range(&mut photons, &mut axes);
        PhotonMap { photons, axes }
    }

    /// Number of photons.
    pub fn len(&self) -> usize {
        self.photons.len()
    }

    /// Whether the map holds no photon.
    pub fn is_empty(&self) -> bool {
        self.photons.is_empty()
    }

    /// The photons, in tree order.
    pub fn photons(&self) -> &[P] {
        &self.photons
    }

    /// Bytes held by the map.
    pub fn bytes(&self) -> usize {
        self.photons.len() * (std::mem::size_of::<P>() + 1)
    }

    /// Calls `visit(photon, d²)` for every photon within distance √`r2` of `p`.
    #[inline]
    pub fn for_each_within(&self, p: Vec3, r2: f32, mut visit: impl FnMut(&P, f32)) {
        self.traverse(p, r2, |ph, d2, _| {
            visit(ph, d2);
            r2
        });
    }

    /// The (at most) `k` photons nearest to `p` within distance √`max_r2`,
    /// into `out` (any order). Returns the squared distance of the farthest
    /// one found, or `None` if none was.
    pub fn nearest(&self, p: Vec3, k: usize, max_r2: f32, out: &mut Nearest) -> Option<f32> {
        out.entries.clear();
        if k == 0 {
            return None;
        }
        let heap = &mut out.entries;
        self.traverse(p, max_r2, |_, d2, index| {
            if heap.len() < k {
                heap_push(heap, (d2, index));
                if heap.len() == k { heap[0].0 } else { max_r2 }
            } else {
                if d2 < heap[0].0 {
                    heap[0] = (d2, index);
                    sift_down(heap, 0);
                }
                heap[0].0
            }
        });
        heap.first().map(|e| e.0)
    }

    /// The photon at `index` (an index reported by [`Nearest::iter`]).
    #[inline]
    pub fn photon(&self, index: u32) -> &P {
        &self.photons[index as usize]
    }

    /// Visits the photons within √`r2` of `p`; `visit` returns the (possibly
    /// smaller) squared radius that the search continues with.
    #[inline]
    fn traverse(&self, p: Vec3, mut r2: f32, mut visit: impl FnMut(&P, f32, u32) -> f32) {
        if self.photons.is_empty() || r2.is_nan() {
            return;
        }
        let mut stack = [(0u32, 0u32, 0.0f32); STACK];
        stack[0] = (0, self.photons.len() as u32, 0.0);
        let mut sp = 1;
        while sp > 0 {
            sp -= 1;
            let (mut lo, mut hi, plane_d2) = stack[sp];
            if plane_d2 > r2 {
                continue;
            }
            while lo < hi {
                let mid = lo + (hi - lo) / 2;
                let ph = &self.photons[mid as usize];
                let at = ph.position();
                let d2 = (at - p).length_squared();
                if d2 <= r2 {
                    r2 = visit(ph, d2, mid);
                }
                if hi - lo == 1 {
                    break;
                }
                let axis = self.axes[mid as usize] as usize;
                let delta = p[axis] - at[axis];
                let (near, far) = if delta < 0.0 {
                    ((lo, mid), (mid + 1, hi))
                } else {
                    ((mid + 1, hi), (lo, mid))
                };
                let delta2 = delta * delta;
                if far.0 < far.1 && delta2 <= r2 && sp < STACK {
                    stack[sp] = (far.0, far.1, delta2);
                    sp += 1;
                }
                (lo, hi) = near;
            }
        }
    }
}

/// The result of a k-nearest query: a max-heap of (squared distance,
/// photon index). Reuse one per thread: queries then never allocate.
#[derive(Clone, Debug, Default)]
pub struct Nearest {
    entries: Vec<(f32, u32)>,
}

impl Nearest {
    /// An empty result with room for `k` photons.
    pub fn with_capacity(k: usize) -> Nearest {
        Nearest {
            entries: Vec::with_capacity(k),
        }
    }

    /// (squared distance, photon index) of each photon found.
    pub fn iter(&self) -> impl Iterator<Item = (f32, u32)> + '_ {
        self.entries.iter().copied()
    }

    /// Number of photons found.
    pub fn len(&self) -> usize {
        self.entries.len()
    }

    /// Whether none was found.
    pub fn is_empty(&self) -> bool {
        self.entries.is_empty()
    }
}

fn heap_push(heap: &mut Vec<(f32, u32)>, e: (f32, u32)) {
    heap.push(e);
    let mut i = heap.len() - 1;
    while i > 0 {
        let parent = (i - 1) / 2;
        if heap[parent].0 >= heap[i].0 {
            break;
        }
        heap.swap(parent, i);
        i = parent;
    }
}

fn sift_down(heap: &mut [(f32, u32)], mut i: usize) {
    loop {
        let (l, r) = (2 * i + 1, 2 * i + 2);
        let mut largest = i;
        if l < heap.len() && heap[l].0 > heap[largest].0 {
            largest = l;
        }
        if r < heap.len() && heap[r].0 > heap[largest].0 {
            largest = r;
        }
        if largest == i {
            return;
        }
        heap.swap(i, largest);
        i = largest;
    }
}

fn build_range<P: Located>(photons: &mut [P], axes: &mut [u8]) {
    let n = photons.len();
    if n <= 1 {
        return;
    }
    let (mut lo, mut hi) = (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY));
    for ph in photons.iter() {
        lo = lo.min(ph.position());
        hi = hi.max(ph.position());
    }
    let e = hi - lo;
    let axis = if e.x >= e.y && e.x >= e.z {
        0
    } else if e.y >= e.z {
        1
    } else {
        2
    };
    let mid = n / 2;
    photons.select_nth_unstable_by(mid, |a, b| a.position()[axis].total_cmp(&b.position()[axis]));
    axes[mid] = axis as u8;
    let (left, rest) = photons.split_at_mut(mid);
    let (left_axes, rest_axes) = axes.split_at_mut(mid);
    let (right, right_axes) = (&mut rest[1..], &mut rest_axes[1..]);
    if n > PARALLEL_BUILD {
        rayon::join(|| build_range(left, left_axes), || build_range(right, right_axes));
    } else {
        build_range(left, left_axes);
        build_range(right, right_axes);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::rng::Pcg32;

    fn random_photons(n: usize, seed: u64) -> Vec<Photon> {
        let mut r = Pcg32::new(seed, 0);
        let mut v: Vec<Photon> = (0..n)
            .map(|i| {
                // Half uniform in a box, half in a tight cluster, so the
                // tree meets both sparse and dense regions.
                let p = if i % 2 == 0 {
                    Vec3::new(r.next_f32(), r.next_f32() * 0.5, r.next_f32() * 2.0)
                } else {
                    Vec3::new(0.3, 0.2, 0.7) + (Vec3::new(r.next_f32(), r.next_f32(), r.next_f32()) - 0.5) * 0.02
                };
                Photon::new(p, Rgb::splat(i as f32), Vec3::Z, Vec3::Y)
            })
            .collect();
        // Exact duplicates and points on one plane.
        for k in 0..50 {
            v.push(Photon::new(Vec3::splat(0.5), Rgb::splat(-(k as f32)), Vec3::Z, Vec3::Y));
            v.push(Photon::new(
                Vec3::new(0.25, 0.1, k as f32 / 25.0),
                Rgb::splat(1e6 + k as f32),
                Vec3::Z,
                Vec3::Y,
            ));
        }
        v
    }

    #[test]
    fn queries_agree_with_brute_force() {
        let photons = random_photons(40_000, 1);
        let map = PhotonMap::build(photons.clone());
        assert_eq!(map.len(), photons.len());
        let mut r = Pcg32::new(2, 0);
        let mut found = Nearest::default();
        for q in 0..300 {
            let p = if q % 3 == 0 {
                Vec3::new(0.3, 0.2, 0.7) + (Vec3::new(r.next_f32(), r.next_f32(), r.next_f32()) - 0.5) * 0.03
            } else {
                Vec3::new(r.next_f32() * 1.2 - 0.1, r.next_f32() * 0.6, r.next_f32() * 2.2 - 0.1)
            };
            let mut all: Vec<f32> = photons.iter().map(|ph| (ph.p - p).length_squared()).collect();
            all.sort_by(f32::total_cmp);
            for (k, max_r2) in [(1usize, f32::INFINITY), (10, 0.01), (64, f32::INFINITY), (200, 0.002)] {
                let far = map.nearest(p, k, max_r2, &mut found);
                let expect: Vec<f32> = all.iter().copied().filter(|&d| d <= max_r2).take(k).collect();
                let mut got: Vec<f32> = found.iter().map(|(d, _)| d).collect();
                got.sort_by(f32::total_cmp);
                assert_eq!(got, expect, "query {q}, k {k}");
                assert_eq!(far, expect.last().copied());
                for (d2, i) in found.iter() {
                    assert_eq!((map.photon(i).p - p).length_squared(), d2);
                }
            }
            for r2 in [0.0001f32, 0.003, 0.05] {
                let mut got = Vec::new();
                map.for_each_within(p, r2, |ph, d2| got.push((d2, ph.power.x)));
                let mut expect: Vec<(f32, f32)> = photons
                    .iter()
                    .map(|ph| ((ph.p - p).length_squared(), ph.power.x))
                    .filter(|&(d, _)| d <= r2)
                    .collect();
                got.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.total_cmp(&b.1)));
                expect.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.total_cmp(&b.1)));
                assert_eq!(got, expect, "query {q}, radius² {r2}");
            }
        }
    }

    #[test]
    fn empty_and_tiny_maps() {
        let mut found = Nearest::default();
        let empty: PhotonMap = PhotonMap::build(Vec::new());
        assert_eq!(empty.nearest(Vec3::ZERO, 5, f32::INFINITY, &mut found), None);
        let one = PhotonMap::build(vec![Photon::new(Vec3::X, Rgb::ONE, Vec3::Y, Vec3::Y)]);
        assert_eq!(one.nearest(Vec3::ZERO, 5, f32::INFINITY, &mut found), Some(1.0));
        assert_eq!(one.nearest(Vec3::ZERO, 5, 0.5, &mut found), None);
        assert_eq!(one.nearest(Vec3::ZERO, 0, 2.0, &mut found), None);
    }

    #[test]
    fn build_is_deterministic() {
        let photons = random_photons(100_000, 7);
        let a = PhotonMap::build(photons.clone());
        let b = rayon::ThreadPoolBuilder::new()
            .num_threads(1)
            .build()
            .unwrap()
            .install(|| PhotonMap::build(photons));
        assert_eq!(a.photons, b.photons);
        assert_eq!(a.axes, b.axes);
    }

    #[test]
    fn octahedral_directions_round_trip() {
        let mut r = Pcg32::new(3, 0);
        for i in 0..10_000 {
            let v = if i < 6 {
                [Vec3::X, -Vec3::X, Vec3::Y, -Vec3::Y, Vec3::Z, -Vec3::Z][i]
            } else {
                crate::sampling::warp::sample_sphere_uniform(Vec2::new(r.next_f32(), r.next_f32()))
            };
            let back = oct_decode(oct_encode(v));
            assert!(back.dot(v) > 0.0 && back.cross(v).length() < 1e-4, "{v} → {back}");
        }
    }
}
