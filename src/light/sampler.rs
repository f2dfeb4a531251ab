//! Choosing the light for next-event estimation: a bounding volume
//! hierarchy over the lights (Conty Estevez and Kulla 2018, "Importance
//! Sampling of Many Lights with Adaptive Tree Splitting"; as pbrt-v4's
//! `BVHLightSampler`, §12.6.3).
//!
//! Each node bounds its lights' positions, their emitted power and the cone
//! of directions they emit into. At a shading point the tree is walked from
//! the root, each child taken with a probability proportional to an
//! importance that bounds what its lights can deliver there (power over
//! squared distance, times the best cosines at the light and at the
//! surface the bounds allow). A light that cannot reach the point from any
//! part of its bounds is never chosen, and one close by is chosen often, so
//! a room lit by hundreds of small lights is sampled nearly as well as one
//! lit by one. Lights without bounds (the environment, directional lights)
//! are chosen apart from the tree: the tree as a whole counts as one more
//! light, so with one environment each gets half the samples (pbrt-v4's
//! `pInfinite`), and the unbounded ones share theirs in proportion to
//! power. Their power, measured over the scene's bounding sphere, says
//! little about what reaches a given point: by power, an environment of
//! radiance 0.1 around a 6-unit wall took 98 % of the samples from the one
//! spot light that lit it.
//!
//! Only the probabilities depend on the point, never whether a light that
//! can contribute is reachable: an importance is zero only where the bounds
//! prove the light delivers nothing, so the estimate stays unbiased.

use crate::geometry::Aabb;
use crate::sampling::Distribution1D;
use glam::Vec3;
use std::f32::consts::PI;

/// What a light (or a group of lights) can emit, and where: the bounds of
/// its points, its power, and the cone of its emission (pbrt-v4
/// `LightBounds`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LightBounds {
    /// Where the emitting points lie.
    pub bounds: Aabb,
    /// Power (any consistent unit: only ratios matter).
    pub phi: f32,
    /// Axis of the cone of normals.
    pub w: Vec3,
    /// Cosine of the cone's half-angle around `w` holding every normal.
    pub cos_theta_o: f32,
    /// Cosine of the angle beyond a normal at which no light leaves (π/2
    /// for area lights).
    pub cos_theta_e: f32,
    /// Whether light leaves both sides of the surfaces.
    pub two_sided: bool,
}

impl LightBounds {
    /// A point emitting in every direction (a point light).
    pub fn point(p: Vec3, phi: f32) -> Self {
        LightBounds {
            bounds: Aabb::from_point(p),
            phi,
            w: Vec3::Z,
            cos_theta_o: -1.0,
            cos_theta_e: 0.0,
            two_sided: false,
        }
    }

    /// The union of two bounds.
    fn union(&self, o: &LightBounds) -> LightBounds {
        if self.phi == 0.0 {
            return *o;
        }
        if o.phi == 0.0 {
            return *self;
        }
        let (w, cos_theta_o) = cone_union((self.w, self.cos_theta_o), (o.w, o.cos_theta_o));
        LightBounds {
            bounds: self.bounds.union(&o.bounds),
            phi: self.phi + o.phi,
            w,
            cos_theta_o,
            cos_theta_e: self.cos_theta_e.min(o.cos_theta_e),
            two_sided: self.two_sided || o.two_sided,
        }
    }

    /// An upper bound, up to a common factor, on the light these bounds
    /// can deliver to a point `p` whose surface normal is `n` (zero: no
    /// surface, every direction counts) — pbrt-v4's
    /// `LightBounds::Importance`.
    pub fn importance(&self, p: Vec3, n: Vec3) -> f32 {
        let mut lanes = BoundsLanes::default();
        lanes.set(0, self);
        lanes.importance(p, n)[0]
    }
}

#[inline]
fn safe_sqrt(x: f32) -> f32 {
    x.max(0.0).sqrt()
}

/// cos and sin of max(0, a − b) for angles a, b in [0, π] given by their
/// cosines and sines.
#[inline(always)]
fn angle_minus((cos_a, sin_a): (f32, f32), (cos_b, sin_b): (f32, f32)) -> (f32, f32) {
    let (c, s) = (cos_a * cos_b + sin_a * sin_b, sin_a * cos_b - cos_a * sin_b);
    let inside = cos_a > cos_b;
    (if inside { 1.0 } else { c }, if inside { 0.0 } else { s })
}

/// The smallest cone holding two cones given by (axis, cosine of the
/// half-angle) (pbrt-v4 `Union(DirectionCone, DirectionCone)`).
fn cone_union(a: (Vec3, f32), b: (Vec3, f32)) -> (Vec3, f32) {
    let (theta_a, theta_b) = (a.1.clamp(-1.0, 1.0).acos(), b.1.clamp(-1.0, 1.0).acos());
    let theta_d = a.0.dot(b.0).clamp(-1.0, 1.0).acos();
    if (theta_d + theta_b).min(PI) <= theta_a {
        return a;
    }
    if (theta_d + theta_a).min(PI) <= theta_b {
        return b;
    }
    let theta_o = 0.5 * (theta_a + theta_d + theta_b);
    let axis = a.0.cross(b.0);
    if theta_o >= PI || axis.length_squared() == 0.0 {
        return (Vec3::Z, -1.0);
    }
    // a's axis turned toward b's by θ_o − θ_a (Rodrigues, axis ⊥ a.0).
    let k = axis.normalize();
    let theta_r = theta_o - theta_a;
    let w = (a.0 * theta_r.cos() + k.cross(a.0) * theta_r.sin()).normalize();
    // Rounding may leave an end of either cone a hair outside: widen a
    // little rather than lose a light.
    (w, (theta_o + 1e-4).min(PI).cos())
}

/// pbrt-v4's build cost of a node: power × the solid angle its cone of
/// emission spreads over × the surface area of its bounds, with a penalty
/// `kr` for thin slabs across the split axis.
fn build_cost(b: &LightBounds, kr: f32) -> f32 {
    let theta_o = b.cos_theta_o.clamp(-1.0, 1.0).acos();
    let theta_e = b.cos_theta_e.clamp(-1.0, 1.0).acos();
    let theta_w = (theta_o + theta_e).min(PI);
    let sin_o = safe_sqrt(1.0 - b.cos_theta_o * b.cos_theta_o);
    let m_omega = 2.0 * PI * (1.0 - b.cos_theta_o)
        + PI / 2.0 * (2.0 * theta_w * sin_o - (theta_o - 2.0 * theta_w).cos() - 2.0 * theta_o * sin_o + b.cos_theta_o);
    b.phi * m_omega * kr * b.bounds.surface_area().max(f32::MIN_POSITIVE)
}

/// Children of a node of the tree.
const WIDTH: usize = 8;

/// The bounds of up to eight lights or groups, one a lane, in the form the
/// importance reads (what does not depend on the shading point computed
/// once). Empty lanes have no power.
#[derive(Clone, Copy, Debug, Default)]
struct BoundsLanes {
    centre: [[f32; WIDTH]; 3],
    /// Radius of the bounding sphere of the box, and its square.
    r: [f32; WIDTH],
    r2: [f32; WIDTH],
    w: [[f32; WIDTH]; 3],
    phi: [f32; WIDTH],
    cos_o: [f32; WIDTH],
    sin_o: [f32; WIDTH],
    cos_e: [f32; WIDTH],
    two_sided: [bool; WIDTH],
}

impl BoundsLanes {
    fn set(&mut self, lane: usize, b: &LightBounds) {
        let c = b.bounds.centroid();
        for k in 0..3 {
            self.centre[k][lane] = c[k];
            self.w[k][lane] = b.w[k];
        }
        self.r2[lane] = 0.25 * b.bounds.extent().length_squared();
        self.r[lane] = self.r2[lane].sqrt();
        self.phi[lane] = b.phi;
        self.cos_o[lane] = b.cos_theta_o;
        self.sin_o[lane] = safe_sqrt(1.0 - b.cos_theta_o * b.cos_theta_o);
        self.cos_e[lane] = b.cos_theta_e;
        self.two_sided[lane] = b.two_sided;
    }

    /// [`LightBounds::importance`] of every lane. Written as one simple
    /// loop over the lanes per step, selects instead of branches, so that
    /// each step compiles to vector code.
    #[inline(always)]
    fn importance(&self, p: Vec3, n: Vec3) -> [f32; WIDTH] {
        let mut wi = [[0.0f32; WIDTH]; 3];
        let mut d2 = [0.0f32; WIDTH];
        let mut inv_d = [0.0f32; WIDTH];
        let mut outside = [false; WIDTH];
        for i in 0..WIDTH {
            let d = [
                p.x - self.centre[0][i],
                p.y - self.centre[1][i],
                p.z - self.centre[2][i],
            ];
            let d2_true = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
            outside[i] = d2_true > self.r2[i];
            // Inside (or near) the bounds distance bounds nothing: clamp it.
            d2[i] = d2_true.max(self.r2[i]).max(f32::MIN_POSITIVE);
            let inv = 1.0 / d2_true.sqrt();
            inv_d[i] = if d2_true > 0.0 { inv } else { 0.0 };
            for k in 0..3 {
                wi[k][i] = d[k] * inv_d[i];
            }
        }
        // The cone from p holding the bounding sphere: sin θ_b = r/d.
        let mut cos_b = [0.0f32; WIDTH];
        let mut sin_b = [0.0f32; WIDTH];
        for i in 0..WIDTH {
            let (c, s) = (safe_sqrt(1.0 - self.r2[i] / d2[i]), self.r[i] * inv_d[i]);
            cos_b[i] = if outside[i] { c } else { -1.0 };
            sin_b[i] = if outside[i] { s } else { 0.0 };
        }
        // θ' = max(0, θ_w − θ_o − θ_b): the least angle between the
        // direction toward p and a normal the bounds allow.
        let mut cos_p = [0.0f32; WIDTH];
        for i in 0..WIDTH {
            let cos_w = self.w[0][i] * wi[0][i] + self.w[1][i] * wi[1][i] + self.w[2][i] * wi[2][i];
            let cos_w = if self.two_sided[i] { cos_w.abs() } else { cos_w };
            let sin_w = safe_sqrt(1.0 - cos_w * cos_w);
            let (cos_x, sin_x) = angle_minus((cos_w, sin_w), (self.cos_o[i], self.sin_o[i]));
            cos_p[i] = angle_minus((cos_x, sin_x), (cos_b[i], sin_b[i])).0;
        }
        // The best cosine at the surface over the subtended cone.
        let mut surface = [1.0f32; WIDTH];
        if n != Vec3::ZERO {
            for i in 0..WIDTH {
                let cos_i = (wi[0][i] * n.x + wi[1][i] * n.y + wi[2][i] * n.z).abs();
                let sin_i = safe_sqrt(1.0 - cos_i * cos_i);
                surface[i] = angle_minus((cos_i, sin_i), (cos_b[i], sin_b[i])).0;
            }
        }
        let mut out = [0.0f32; WIDTH];
        for i in 0..WIDTH {
            let importance = (self.phi[i] * cos_p[i] / d2[i] * surface[i]).max(0.0);
            out[i] = if cos_p[i] > self.cos_e[i] { importance } else { 0.0 };
        }
        out
    }
}

/// What a child slot of a node holds.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Child {
    Empty,
    Node(u32),
    Light(u32),
}

#[derive(Clone, Copy, Debug)]
struct Node {
    bounds: BoundsLanes,
    children: [Child; WIDTH],
    /// Slots in use. A node of one child (the root of a tree of one light)
    /// passes to it without computing its importance: its share is 1
    /// wherever it can light the point, and choosing it where it cannot
    /// costs a light sample that finds nothing, not bias.
    count: u8,
    /// The parent node and this node's slot there (the root's is its own).
    parent: (u32, u8),
}

/// A node of the binary tree the build makes before it is collapsed into
/// nodes of eight.
enum BuildNode {
    Leaf(u32, LightBounds),
    Inner(Box<BuildNode>, Box<BuildNode>, LightBounds),
}

impl BuildNode {
    fn bounds(&self) -> &LightBounds {
        match self {
            BuildNode::Leaf(_, b) | BuildNode::Inner(_, _, b) => b,
        }
    }
}

/// Chooses a light for a shading point: the tree over the bounded lights
/// (nodes of eight children, whose importances are computed together), and
/// the lights without bounds by power.
#[derive(Clone, Debug, Default)]
pub struct LightSampler {
    nodes: Vec<Node>,
    /// Per light: its node and slot there, if it is in the tree.
    leaf_of: Vec<Option<(u32, u8)>>,
    /// The lights without bounds, and how to choose among them.
    unbounded: Vec<u32>,
    unbounded_choice: Distribution1D,
    /// Which unbounded light each light is, if any.
    unbounded_slot: Vec<Option<u32>>,
    /// Probability of choosing from the unbounded lights.
    p_unbounded: f32,
    /// The same two for estimators that let lights sample incompletely
    /// (pbrt-v4's `allowIncompletePDF`), which leave out the unbounded
    /// lights that then draw nothing (a constant environment).
    unbounded_choice_incomplete: Distribution1D,
    p_unbounded_incomplete: f32,
}

/// Levels after which a build splits at the median, which bounds the
/// depth of the tree whatever the lights.
const MEDIAN_AFTER_DEPTH: u32 = 28;

impl LightSampler {
    /// A sampler over `lights`: each one's bounds (`None`: no bounds, like
    /// the environment) and its power for the choice among the unbounded.
    pub fn new(lights: &[(Option<LightBounds>, f32)]) -> Self {
        let mut s = LightSampler {
            leaf_of: vec![None; lights.len()],
            unbounded_slot: vec![None; lights.len()],
            ..Default::default()
        };
        let mut bounded = Vec::new();
        let mut unbounded_powers = Vec::new();
        for (i, (bounds, power)) in lights.iter().enumerate() {
            match bounds {
                Some(b) if b.phi > 0.0 && b.phi.is_finite() && !b.bounds.is_empty() => {
                    bounded.push((i as u32, *b));
                }
                Some(_) => {} // no power: never chosen
                None => {
                    s.unbounded_slot[i] = Some(s.unbounded.len() as u32);
                    s.unbounded.push(i as u32);
                    let p = if power.is_finite() { power.max(0.0) } else { 0.0 };
                    unbounded_powers.push(p);
                }
            }
        }
        let p_unbounded = |powers: &[f32]| {
            let n_unbounded = powers.iter().filter(|&&p| p > 0.0).count();
            match (bounded.is_empty(), n_unbounded) {
                (true, _) => 1.0,
                (false, 0) => 0.0,
                (false, n) => n as f32 / (n + 1) as f32,
            }
        };
        s.unbounded_choice = Distribution1D::new(&unbounded_powers);
        s.p_unbounded = p_unbounded(&unbounded_powers);
        s.p_unbounded_incomplete = s.p_unbounded;
        s.unbounded_choice_incomplete = s.unbounded_choice.clone();
        if !bounded.is_empty() {
            let root = build(&mut bounded, 0);
            s.collapse(&root, (0, 0));
        }
        s
    }

    /// Leaves the unbounded lights `silent` out of the choice for
    /// estimators that sample incompletely: lights whose compensated
    /// density is zero everywhere, which would draw nothing there (pbrt-v4
    /// chooses them and gets no sample; leaving them out gives their share
    /// to the lights that do sample).
    pub fn leave_out_when_incomplete(&mut self, silent: &[usize]) {
        let powers: Vec<f32> = self
            .unbounded
            .iter()
            .enumerate()
            .map(|(slot, &light)| {
                if silent.contains(&(light as usize)) {
                    0.0
                } else {
                    self.unbounded_choice.pmf(slot)
                }
            })
            .collect();
        let n_unbounded = powers.iter().filter(|&&p| p > 0.0).count();
        self.p_unbounded_incomplete = match (self.nodes.is_empty(), n_unbounded) {
            (_, 0) => 0.0,
            (true, _) => 1.0,
            (false, n) => n as f32 / (n + 1) as f32,
        };
        self.unbounded_choice_incomplete = Distribution1D::new(&powers);
    }

    /// Whether no light can be chosen.
    pub fn is_empty(&self) -> bool {
        self.nodes.is_empty() && self.unbounded.is_empty()
    }

    /// Turns the binary subtree `root` into nodes of up to eight children:
    /// the inner child of most power is opened until eight slots are used.
    fn collapse(&mut self, root: &BuildNode, parent: (u32, u8)) -> u32 {
        let mut open: Vec<&BuildNode> = match root {
            BuildNode::Leaf(..) => vec![root],
            BuildNode::Inner(a, b, _) => vec![a, b],
        };
        while open.len() < WIDTH {
            let widest = open
                .iter()
                .enumerate()
                .filter(|(_, c)| matches!(c, BuildNode::Inner(..)))
                .max_by(|a, b| a.1.bounds().phi.total_cmp(&b.1.bounds().phi))
                .map(|(i, _)| i);
            let Some(i) = widest else { break };
            let BuildNode::Inner(a, b, _) = open[i] else {
                unreachable!()
            };
            open[i] = a;
            open.insert(i + 1, b);
        }
        let index = self.nodes.len() as u32;
        let parent = if index == 0 { (0, 0) } else { parent };
        self.nodes.push(Node {
            bounds: BoundsLanes::default(),
            children: [Child::Empty; WIDTH],
            count: open.len() as u8,
            parent,
        });
        for (slot, child) in open.into_iter().enumerate() {
            self.nodes[index as usize].bounds.set(slot, child.bounds());
            let c = match child {
                BuildNode::Leaf(light, _) => {
                    self.leaf_of[*light as usize] = Some((index, slot as u8));
                    Child::Light(*light)
                }
                BuildNode::Inner(..) => Child::Node(self.collapse(child, (index, slot as u8))),
            };
            self.nodes[index as usize].children[slot] = c;
        }
        index
    }

    /// The choice among the unbounded lights and its probability, for
    /// complete or `incomplete` sampling.
    #[inline]
    fn unbounded_for(&self, incomplete: bool) -> (&Distribution1D, f32) {
        if incomplete {
            (&self.unbounded_choice_incomplete, self.p_unbounded_incomplete)
        } else {
            (&self.unbounded_choice, self.p_unbounded)
        }
    }

    /// A light for the point `p` with surface normal `n` (zero where the
    /// point is in no surface) chosen with `u` ∈ [0, 1), and the probability
    /// of choosing it; `None` where no light can reach the point. With
    /// `incomplete`, the lights [`LightSampler::leave_out_when_incomplete`]
    /// names are not chosen.
    #[allow(unsafe_code)]
    pub fn sample(&self, p: Vec3, n: Vec3, u: f32, incomplete: bool) -> Option<(usize, f32)> {
        #[cfg(target_arch = "x86_64")]
        if crate::geometry::lanes::avx_available() {
            // SAFETY: the processor has AVX.
            return unsafe { self.sample_avx(p, n, u, incomplete) };
        }
        self.sample_here(p, n, u, incomplete)
    }

    /// [`LightSampler::sample`] built for AVX, where a node's eight
    /// importances take one register a step rather than two (IEEE
    /// operations lane by lane: the same bits).
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx")]
    fn sample_avx(&self, p: Vec3, n: Vec3, u: f32, incomplete: bool) -> Option<(usize, f32)> {
        self.sample_here(p, n, u, incomplete)
    }

    #[inline(always)]
    fn sample_here(&self, p: Vec3, n: Vec3, u: f32, incomplete: bool) -> Option<(usize, f32)> {
        let (unbounded_choice, p_unbounded) = self.unbounded_for(incomplete);
        if u < p_unbounded {
            if self.unbounded.is_empty() || p_unbounded == 0.0 {
                return None;
            }
            let (i, pmf, _) = unbounded_choice.sample((u / p_unbounded).min(ONE_MINUS_EPSILON));
            if pmf <= 0.0 {
                return None;
            }
            return Some((self.unbounded[i] as usize, p_unbounded * pmf));
        }
        if self.nodes.is_empty() {
            return None;
        }
        let mut u = ((u - p_unbounded) / (1.0 - p_unbounded)).clamp(0.0, ONE_MINUS_EPSILON);
        let mut pmf = 1.0 - p_unbounded;
        let mut node = &self.nodes[0];
        loop {
            if node.count == 1 {
                match node.children[0] {
                    Child::Light(light) => return Some((light as usize, pmf)),
                    Child::Node(i) => {
                        node = &self.nodes[i as usize];
                        continue;
                    }
                    Child::Empty => return None,
                }
            }
            let importance = node.bounds.importance(p, n);
            let total: f32 = importance.iter().sum();
            if total <= 0.0 {
                return None;
            }
            // The slot whose share of the total holds u.
            let target = u * total;
            let (mut slot, mut below, mut last) = (WIDTH, 0.0, 0);
            for (i, &x) in importance.iter().enumerate() {
                if x > 0.0 {
                    if below + x > target {
                        slot = i;
                        break;
                    }
                    below += x;
                    last = i;
                }
            }
            if slot == WIDTH {
                // Rounding left the target at the very top: the last slot.
                slot = last;
                below -= importance[last];
            }
            let share = importance[slot] / total;
            u = ((target - below) / importance[slot]).clamp(0.0, ONE_MINUS_EPSILON);
            pmf *= share;
            match node.children[slot] {
                Child::Light(light) => return Some((light as usize, pmf)),
                Child::Node(i) => node = &self.nodes[i as usize],
                Child::Empty => return None,
            }
        }
    }

    /// The probability that [`LightSampler::sample`] at (`p`, `n`) with
    /// the same `incomplete` chooses `light`: the product of its branches'
    /// shares, from its leaf up.
    #[allow(unsafe_code)]
    pub fn pmf(&self, p: Vec3, n: Vec3, light: usize, incomplete: bool) -> f32 {
        #[cfg(target_arch = "x86_64")]
        if crate::geometry::lanes::avx_available() {
            // SAFETY: the processor has AVX.
            return unsafe { self.pmf_avx(p, n, light, incomplete) };
        }
        self.pmf_here(p, n, light, incomplete)
    }

    /// [`LightSampler::pmf`] built for AVX, as [`LightSampler::sample_avx`].
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx")]
    fn pmf_avx(&self, p: Vec3, n: Vec3, light: usize, incomplete: bool) -> f32 {
        self.pmf_here(p, n, light, incomplete)
    }

    #[inline(always)]
    fn pmf_here(&self, p: Vec3, n: Vec3, light: usize, incomplete: bool) -> f32 {
        let (unbounded_choice, p_unbounded) = self.unbounded_for(incomplete);
        if let Some(slot) = self.unbounded_slot[light] {
            if p_unbounded == 0.0 {
                return 0.0;
            }
            return p_unbounded * unbounded_choice.pmf(slot as usize);
        }
        let Some((mut node, mut slot)) = self.leaf_of[light] else {
            return 0.0;
        };
        let mut pmf = 1.0 - p_unbounded;
        loop {
            let nd = &self.nodes[node as usize];
            if nd.count > 1 {
                let importance = nd.bounds.importance(p, n);
                let total: f32 = importance.iter().sum();
                if total <= 0.0 {
                    return 0.0;
                }
                pmf *= importance[slot as usize] / total;
            }
            if node == 0 {
                return pmf;
            }
            (node, slot) = nd.parent;
        }
    }
}

const ONE_MINUS_EPSILON: f32 = 1.0 - f32::EPSILON / 2.0;

/// The binary tree over `lights`, split where the build cost is least.
fn build(lights: &mut [(u32, LightBounds)], depth: u32) -> BuildNode {
    if let [(light, bounds)] = lights {
        return BuildNode::Leaf(*light, *bounds);
    }
    let mid = if depth < MEDIAN_AFTER_DEPTH {
        best_split(lights)
    } else {
        None
    }
    .unwrap_or_else(|| {
        // No useful split (or too deep): halves along the widest spread of centres.
        let centres = lights
            .iter()
            .fold(Aabb::default(), |b, (_, l)| b.union_point(l.bounds.centroid()));
        let axis = centres.longest_axis();
        let half = lights.len() / 2;
        lights.select_nth_unstable_by(half, |a, b| {
            a.1.bounds.centroid()[axis].total_cmp(&b.1.bounds.centroid()[axis])
        });
        half
    });
    let (left, right) = lights.split_at_mut(mid);
    let a = build(left, depth + 1);
    let b = build(right, depth + 1);
    let union = a.bounds().union(b.bounds());
    BuildNode::Inner(Box::new(a), Box::new(b), union)
}

/// The split of least build cost over 12 buckets on each axis (pbrt-v4
/// `BVHLightSampler::buildBVH`), the lights reordered so that the first
/// part comes first; `None` if every centre is in one bucket.
fn best_split(lights: &mut [(u32, LightBounds)]) -> Option<usize> {
    const BUCKETS: usize = 12;
    let bounds = lights.iter().fold(Aabb::default(), |b, (_, l)| b.union(&l.bounds));
    let centres = lights
        .iter()
        .fold(Aabb::default(), |b, (_, l)| b.union_point(l.bounds.centroid()));
    let diagonal = bounds.extent();
    let mut best: Option<(f32, usize, usize)> = None; // cost, axis, bucket
    for axis in 0..3 {
        let (lo, hi) = (centres.min[axis], centres.max[axis]);
        if hi <= lo || diagonal[axis] <= 0.0 {
            continue;
        }
        let bucket_of = |l: &LightBounds| {
            let t = (l.bounds.centroid()[axis] - lo) / (hi - lo);
            ((t * BUCKETS as f32) as usize).min(BUCKETS - 1)
        };
        let mut buckets: [Option<LightBounds>; BUCKETS] = [None; BUCKETS];
        for (_, l) in lights.iter() {
            let b = &mut buckets[bucket_of(l)];
            *b = Some(b.map_or(*l, |b| b.union(l)));
        }
        let kr = diagonal.max_element() / diagonal[axis];
        let side = |range: std::ops::Range<usize>| {
            buckets[range]
                .iter()
                .flatten()
                .fold(None, |acc: Option<LightBounds>, b| Some(acc.map_or(*b, |a| a.union(b))))
        };
        for split in 1..BUCKETS {
            let (Some(a), Some(b)) = (side(0..split), side(split..BUCKETS)) else {
                continue;
            };
            let cost = build_cost(&a, kr) + build_cost(&b, kr);
            if best.is_none_or(|(c, ..)| cost < c) {
                best = Some((cost, axis, split));
            }
        }
    }
    let (_, axis, split) = best?;
    let (lo, hi) = (centres.min[axis], centres.max[axis]);
    let mut mid = 0;
    for i in 0..lights.len() {
        let t = (lights[i].1.bounds.centroid()[axis] - lo) / (hi - lo);
        if ((t * BUCKETS as f32) as usize).min(BUCKETS - 1) < split {
            lights.swap(i, mid);
            mid += 1;
        }
    }
    (mid > 0 && mid < lights.len()).then_some(mid)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::rng::Pcg32;

    fn random_lights(r: &mut Pcg32, n: usize) -> Vec<(Option<LightBounds>, f32)> {
        (0..n)
            .map(|i| {
                let c = Vec3::new(r.next_f32(), r.next_f32(), r.next_f32()) * 10.0;
                let phi = 0.1 + 5.0 * r.next_f32();
                match i % 4 {
                    0 => (Some(LightBounds::point(c, phi)), phi),
                    3 if i % 8 == 3 => (None, phi), // like an environment
                    _ => {
                        // A small panel facing a random way.
                        let w = Vec3::new(r.next_f32() - 0.5, r.next_f32() - 0.5, r.next_f32() - 0.5).normalize();
                        let b = LightBounds {
                            bounds: Aabb::new(c, c + Vec3::splat(0.2)),
                            phi,
                            w,
                            cos_theta_o: 1.0,
                            cos_theta_e: 0.0,
                            two_sided: i % 3 == 0,
                        };
                        (Some(b), phi)
                    }
                }
            })
            .collect()
    }

    /// Σ pmf ≤ 1 and stratified draws follow the pmf, for complete choices
    /// and for incomplete ones that leave some unbounded lights out (those
    /// then have probability 0 and are never drawn).
    #[test]
    fn pmf_sums_to_one_and_matches_sampling() {
        let mut r = Pcg32::new(11, 7);
        for n in [1, 2, 3, 7, 12, 100] {
            let lights = random_lights(&mut r, n);
            let mut sampler = LightSampler::new(&lights);
            // Every other unbounded light draws nothing when incomplete.
            let silent: Vec<usize> = (0..n).filter(|&i| lights[i].0.is_none() && i % 16 == 3).collect();
            sampler.leave_out_when_incomplete(&silent);
            for incomplete in [false, true] {
                for _ in 0..20 {
                    let p = Vec3::new(r.next_f32(), r.next_f32(), r.next_f32()) * 12.0 - 1.0;
                    let nrm = if r.next_f32() < 0.3 {
                        Vec3::ZERO
                    } else {
                        Vec3::new(r.next_f32() - 0.5, r.next_f32() - 0.5, r.next_f32() - 0.5).normalize()
                    };
                    let total: f32 = (0..n).map(|i| sampler.pmf(p, nrm, i, incomplete)).sum();
                    // Below 1 where a node's bounds admit light that none of its
                    // children's do: `sample` then finds no light.
                    assert!(total <= 1.0 + 1e-4, "{n} lights: Σ pmf = {total}");
                    if n == 1 {
                        assert_eq!(total, 1.0);
                    }
                    for &i in &silent {
                        assert_eq!(sampler.pmf(p, nrm, i, true), 0.0);
                    }
                    let draws = 4000;
                    let mut counts = vec![0u32; n];
                    for k in 0..draws {
                        let u = (k as f32 + r.next_f32()) / draws as f32;
                        if let Some((i, pmf)) = sampler.sample(p, nrm, u, incomplete) {
                            let expected = sampler.pmf(p, nrm, i, incomplete);
                            assert!(
                                (pmf - expected).abs() <= 1e-5 * expected.max(1e-3),
                                "{pmf} vs {expected}"
                            );
                            counts[i] += 1;
                        }
                    }
                    // Stratified draws: each count is within a few of its expectation.
                    for (i, &c) in counts.iter().enumerate() {
                        let e = sampler.pmf(p, nrm, i, incomplete) * draws as f32;
                        assert!(
                            (c as f32 - e).abs() <= 2.0 + 0.02 * e,
                            "light {i}: {c} draws, expected {e}"
                        );
                    }
                }
            }
            if !silent.is_empty() {
                // The lights left out give their share to the others.
                let p = Vec3::splat(5.0);
                let kept = |incomplete| -> f32 {
                    (0..n)
                        .filter(|i| !silent.contains(i))
                        .map(|i| sampler.pmf(p, Vec3::ZERO, i, incomplete))
                        .sum()
                };
                assert!(kept(true) > kept(false), "{} against {}", kept(true), kept(false));
            }
        }
    }

    #[test]
    fn a_light_that_can_reach_a_point_is_never_given_zero_probability() {
        // Panels facing +y at y = 0 light the half-space above them only.
        let mut r = Pcg32::new(3, 3);
        let lights: Vec<_> = (0..64)
            .map(|_| {
                let c = Vec3::new(10.0 * r.next_f32(), 0.0, 10.0 * r.next_f32());
                let b = LightBounds {
                    bounds: Aabb::new(c, c + Vec3::new(0.1, 0.0, 0.1)),
                    phi: 1.0,
                    w: Vec3::Y,
                    cos_theta_o: 1.0,
                    cos_theta_e: 0.0,
                    two_sided: false,
                };
                (Some(b), 1.0)
            })
            .collect();
        let sampler = LightSampler::new(&lights);
        for _ in 0..500 {
            let p = Vec3::new(
                12.0 * r.next_f32() - 1.0,
                4.0 * r.next_f32() - 2.0,
                12.0 * r.next_f32() - 1.0,
            );
            let n = Vec3::new(r.next_f32() - 0.5, r.next_f32() - 0.5, r.next_f32() - 0.5).normalize();
            for (i, (b, _)) in lights.iter().enumerate() {
                let b = b.unwrap();
                // A corner of the panel that p sees from its front side, off
                // the plane of p's surface, can light p.
                let corners = [
                    b.bounds.min,
                    b.bounds.max,
                    Vec3::new(b.bounds.min.x, 0.0, b.bounds.max.z),
                ];
                let reaches = p.y > 1e-3 && corners.iter().any(|&q| (q - p).normalize().dot(n).abs() > 1e-3);
                if reaches {
                    assert!(
                        sampler.pmf(p, n, i, false) > 0.0,
                        "light {i} can reach {p} but has probability 0"
                    );
                }
            }
            if p.y < -0.1 {
                // Behind every panel and outside the bounding sphere of each
                // (radius 0.071): nothing can be chosen.
                assert!(sampler.sample(p, n, 0.5, false).is_none());
            }
        }
    }

    #[test]
    fn near_lights_are_chosen_more_often_than_far_ones() {
        let lights: Vec<_> = (0..100)
            .map(|i| (Some(LightBounds::point(Vec3::new(i as f32, 0.0, 0.0), 1.0)), 1.0))
            .collect();
        let sampler = LightSampler::new(&lights);
        let p = Vec3::new(0.0, 1.0, 0.0);
        assert!(sampler.pmf(p, Vec3::ZERO, 0, false) > 20.0 * sampler.pmf(p, Vec3::ZERO, 99, false));
        // A power distribution would give each 1/100.
        assert!(sampler.pmf(p, Vec3::ZERO, 0, false) > 0.1);
    }
}
