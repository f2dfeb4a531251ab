//! Participating media: volumes that absorb, scatter and emit light
//! (fog, smoke, milk), and the surfaces that bound them.
//!
//! A medium has, at every point, an absorption coefficient σa and a
//! scattering coefficient σs (per unit length, per RGB channel; their sum
//! is the extinction σt), a phase function, and optionally an emitted
//! radiance Le. Light crossing a distance d of it in one channel keeps the
//! fraction T = exp(−∫σt), the Beer–Lambert law.
//!
//! A homogeneous medium has the same coefficients everywhere; a grid
//! medium reads them from voxel grids ([`grid::VoxelGrid`]) placed in the
//! world by a transform, and is empty outside their box. Both are sampled
//! by the same null-scattering formulation (Miller, Georgiev and Jarosz
//! 2019; pbrt-v4 section 14.2): distances are drawn against a majorant
//! σ_maj ≥ σt, which for a homogeneous medium is σt itself, and for a grid
//! the largest value of its grid; at each tentative collision the
//! integrator decides between absorption, real scattering and a null
//! collision (σn = σ_maj − σt) that leaves the path unchanged.
//!
//! Surfaces carry a [`MediumInterface`]: the media on their inside and
//! outside. A ray that crosses such a surface enters the medium on the
//! side it goes to; a surface without one leaves the ray in its medium.

pub mod grid;
pub mod measured;
pub mod nanovdb;
pub mod phase;

pub use grid::{GridEdge, VoxelGrid};
pub use phase::{Phase, PhaseSample};

use crate::color::Rgb;
use crate::geometry::{Aabb, Ray, Transform};
use crate::sampling::rng::Pcg32;
use glam::Vec3;
use std::sync::Arc;

/// A medium property: one value everywhere, or a voxel grid.
#[derive(Clone, Debug, PartialEq)]
pub enum Field {
    /// The same value everywhere.
    Constant(Rgb),
    /// A grid over a unit cube, with the map from the world to that cube.
    Grid(Arc<VoxelGrid>, Transform),
    /// pbrt-v4's procedural cloud: a value times a density in [0, 1].
    Cloud(Box<CloudField>),
}

/// pbrt-v4's `CloudMedium` density (Physically Based Rendering, 4th ed.,
/// §11.3.3): octaves of Perlin noise at a point perturbed by the noise's
/// gradient (its wispiness), thinning with height, in the box [p0, p1] of
/// the medium's space; the value there is `value` times the density.
#[derive(Clone, Debug, PartialEq)]
pub struct CloudField {
    /// The value where the density is 1 (σt).
    pub value: Rgb,
    /// Scale of the noise's sum (pbrt-v4's `density`).
    pub density: f32,
    /// How much the noise's gradient perturbs the lookup point.
    pub wispiness: f32,
    /// Scale of the lookup point.
    pub frequency: f32,
    /// The medium's box, in its own space.
    pub bounds: Aabb,
    /// From the world to the medium's space.
    pub to_local: Transform,
}

impl CloudField {
    /// The density at point `p` of the medium's space (0 outside its box).
    pub fn density_at(&self, p: Vec3) -> f32 {
        use crate::texture::noise::{dnoise, noise};
        if p.cmplt(self.bounds.min).any() || p.cmpgt(self.bounds.max).any() {
            return 0.0;
        }
        let mut pp = self.frequency * p;
        if self.wispiness > 0.0 {
            let (mut omega, mut lambda) = (0.05 * self.wispiness, 10.0);
            for _ in 0..2 {
                pp += omega * dnoise(lambda * pp);
                omega *= 0.5;
                lambda *= 1.99;
            }
        }
        let (mut d, mut omega, mut lambda) = (0.0, 0.5, 1.0);
        for _ in 0..5 {
            d += omega * noise(lambda * pp);
            omega *= 0.5;
            lambda *= 1.99;
        }
        let d = ((1.0 - p.y) * 4.5 * self.density * d).clamp(0.0, 1.0) + 2.0 * (0.5 - p.y).max(0.0);
        if d.is_nan() { 0.0 } else { d.clamp(0.0, 1.0) }
    }
}

impl Field {
    /// The value at world point `p`.
    #[inline]
    pub fn at(&self, p: Vec3) -> Rgb {
        match self {
            Field::Constant(c) => *c,
            Field::Grid(g, to_local) => g.lookup(to_local.point(p)),
            Field::Cloud(c) => c.value * c.density_at(c.to_local.point(p)),
        }
    }

    /// A bound on every value, per channel.
    pub fn max(&self) -> Rgb {
        match self {
            Field::Constant(c) => *c,
            Field::Grid(g, _) => g.max(),
            Field::Cloud(c) => c.value,
        }
    }
}

/// The coefficients of a medium at one point.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MediumPoint {
    /// Absorption coefficient σa.
    pub sigma_a: Rgb,
    /// Scattering coefficient σs.
    pub sigma_s: Rgb,
    /// Emitted radiance (zero where the medium does not emit).
    pub le: Rgb,
}

/// A participating medium.
#[derive(Clone, Debug, PartialEq)]
pub struct Medium {
    /// The world box outside which the medium is empty (a grid's box);
    /// `None`: it is everywhere the surfaces that bound it say it is.
    pub bounds: Option<Aabb>,
    /// Extinction coefficient σt (before `scale`).
    pub sigma_t: Field,
    /// Single-scattering albedo σs/σt.
    pub albedo: Field,
    /// Emitted radiance, if the medium emits (pbrt-v4's convention: the
    /// source term is σa·Le).
    pub emission: Option<Field>,
    /// Multiplier of σt, per channel.
    pub scale: Rgb,
    /// Phase function.
    pub phase: Phase,
    /// σ_maj: a bound on σt everywhere, per channel.
    majorant: Rgb,
}

impl Medium {
    /// A homogeneous medium of extinction `sigma_t` and albedo `albedo`.
    pub fn homogeneous(sigma_t: Rgb, albedo: Rgb, phase: Phase) -> Medium {
        Medium::new(
            None,
            Field::Constant(sigma_t),
            Field::Constant(albedo),
            None,
            Rgb::ONE,
            phase,
        )
    }

    /// A medium of any kind; its majorant is computed from the fields.
    pub fn new(
        bounds: Option<Aabb>,
        sigma_t: Field,
        albedo: Field,
        emission: Option<Field>,
        scale: Rgb,
        phase: Phase,
    ) -> Medium {
        let majorant = (sigma_t.max() * scale).max(Rgb::ZERO);
        Medium {
            bounds,
            sigma_t,
            albedo,
            emission,
            scale,
            phase,
            majorant,
        }
    }

    /// The majorant σ_maj.
    #[inline]
    pub fn majorant(&self) -> Rgb {
        self.majorant
    }

    /// Whether σt varies from channel to channel (a chromatic medium,
    /// where one channel's distance sampling suits the others poorly).
    pub fn is_chromatic(&self) -> bool {
        let m = self.majorant;
        m.x != m.y || m.y != m.z
    }

    /// σt (with the scale) where it is the same everywhere the medium has
    /// density: then the transmittance of a segment is exp(−σt·length).
    #[inline]
    pub fn constant_extinction(&self) -> Option<Rgb> {
        match self.sigma_t {
            Field::Constant(c) => Some((c * self.scale).max(Rgb::ZERO)),
            Field::Grid(..) | Field::Cloud(..) => None,
        }
    }

    /// The coefficients at world point `p`.
    #[inline]
    pub fn point(&self, p: Vec3) -> MediumPoint {
        let sigma_t = (self.sigma_t.at(p) * self.scale).max(Rgb::ZERO);
        let albedo = self.albedo.at(p).clamp(Rgb::ZERO, Rgb::ONE);
        let sigma_s = sigma_t * albedo;
        MediumPoint {
            sigma_a: sigma_t - sigma_s,
            sigma_s,
            le: self.emission.as_ref().map_or(Rgb::ZERO, |e| e.at(p)),
        }
    }

    /// The part of the ray `origin + t·dir` (`dir` unit length), t in
    /// [0, t_max], where the medium can have density.
    #[inline]
    pub fn segment(&self, origin: Vec3, dir: Vec3, t_max: f32) -> Option<(f32, f32)> {
        let Some(b) = &self.bounds else {
            return Some((0.0, t_max));
        };
        let inv = dir.recip();
        let t0 = (b.min - origin) * inv;
        let t1 = (b.max - origin) * inv;
        // NaN (a zero direction component on a slab's plane) is passed over
        // by max/min, which keep the other operand.
        let near = t0.min(t1).max_element().max(0.0);
        let far = t0.max(t1).min_element().min(t_max);
        (near <= far).then_some((near, far))
    }
}

/// exp(−d·σ) per channel, 1 where σ is 0 (also for an infinite d).
#[inline]
pub fn transmittance(distance: f32, sigma: Rgb) -> Rgb {
    let f = |s: f32| if s == 0.0 { 1.0 } else { (-distance * s).exp() };
    Rgb::new(f(sigma.x), f(sigma.y), f(sigma.z))
}

/// Samples tentative collisions along `ray` (unit direction) for t in
/// [0, `ray.t_max`] (its `t_min` is not read), against the medium's majorant in channel
/// `channel` (pbrt-v4's `SampleT_maj`). At each collision, `visit` gets
/// the point, the medium's coefficients there, σ_maj and the majorant
/// transmittance T_maj from the previous collision (or the start), and
/// `rng` for its own choices; it returns whether to go on. The first
/// distance is drawn with `u`, later ones with `rng`. Returns T_maj from the last collision to the end of
/// the segment, or ones where `visit` stopped.
#[inline]
pub fn sample_majorant(
    medium: &Medium,
    ray: &Ray,
    channel: usize,
    u: f32,
    rng: &mut Pcg32,
    mut visit: impl FnMut(Vec3, &MediumPoint, Rgb, Rgb, &mut Pcg32) -> bool,
) -> Rgb {
    let (origin, dir) = (ray.origin, ray.dir);
    let Some((t_start, t_end)) = medium.segment(origin, dir, ray.t_max) else {
        return Rgb::ONE;
    };
    let sigma_maj = medium.majorant;
    if sigma_maj[channel] <= 0.0 {
        return transmittance(t_end - t_start, sigma_maj);
    }
    let mut t = t_start;
    let mut u = u;
    loop {
        let step = -(1.0 - u).ln() / sigma_maj[channel];
        let t_next = t + step;
        if t_next >= t_end || !t_next.is_finite() {
            return transmittance(t_end - t, sigma_maj);
        }
        let p = origin + dir * t_next;
        let mp = medium.point(p);
        if !visit(p, &mp, sigma_maj, transmittance(step, sigma_maj), rng) {
            return Rgb::ONE;
        }
        t = t_next;
        u = rng.next_f32();
    }
}

/// The media on the two sides of a surface.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct MediumInterface {
    /// The medium behind the surface (against its geometric normal);
    /// `None`: vacuum.
    pub inside: Option<u32>,
    /// The medium in front of it (along its geometric normal).
    pub outside: Option<u32>,
}

impl MediumInterface {
    /// The medium a ray leaving the surface in direction `w` enters, for
    /// geometric normal `ng`.
    #[inline]
    pub fn toward(&self, w: Vec3, ng: Vec3) -> Option<u32> {
        if w.dot(ng) > 0.0 { self.outside } else { self.inside }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The probability that a homogeneous slab lets a path through,
    /// estimated by delta tracking against the majorant, is Beer–Lambert's
    /// exp(−σt·d); and ratio tracking's mean weight is the same.
    #[test]
    fn tracking_through_a_grid_matches_beer_lambert() {
        // A 4×1×1 grid of densities 0.5, 1, 2, 0.25 stretched over x in [0, 4]:
        // trilinear between voxel centres, so the exact optical depth along
        // x is the integral of the piecewise-linear profile.
        let grid = VoxelGrid::new([4, 1, 1], 1, vec![0.5, 1.0, 2.0, 0.25]).unwrap();
        let to_world = Transform::scale(Vec3::new(4.0, 1.0, 1.0)).unwrap();
        let medium = Medium::new(
            Some(Aabb::new(Vec3::ZERO, Vec3::new(4.0, 1.0, 1.0))),
            Field::Grid(Arc::new(grid), to_world.inverse()),
            Field::Constant(Rgb::ZERO),
            None,
            Rgb::ONE,
            Phase::Isotropic,
        );
        // Optical depth: edges clamp to the first and last centres (at 0.5
        // and 3.5), linear between.
        let depth: f64 = 0.5 * 0.5 + (0.5 + 1.0) / 2.0 + (1.0 + 2.0) / 2.0 + (2.0 + 0.25) / 2.0 + 0.25 * 0.5;
        let exact = (-depth).exp();
        let origin = Vec3::new(-1.0, 0.5, 0.5);
        let dir = Vec3::X;
        let mut choices = Pcg32::new(3, 1);
        let n = 100_000;
        let (mut passed, mut ratio) = (0u32, 0.0f64);
        for i in 0..n {
            // Delta tracking: a real collision (σt/σ_maj) ends the walk.
            let mut steps = Pcg32::new(i, 2);
            let mut survived = true;
            let u = steps.next_f32();
            sample_majorant(
                &medium,
                &Ray::with_interval(origin, dir, 0.0, 10.0),
                0,
                u,
                &mut steps,
                |_, mp, maj, _, _| {
                    let sigma_t = mp.sigma_a.x + mp.sigma_s.x;
                    if choices.next_f32() < sigma_t / maj.x {
                        survived = false;
                        return false;
                    }
                    true
                },
            );
            passed += survived as u32;
            // Ratio tracking: the weight is the product of σn/σ_maj.
            let mut steps = Pcg32::new(i, 3);
            let mut w = 1.0f64;
            let u = steps.next_f32();
            sample_majorant(
                &medium,
                &Ray::with_interval(origin, dir, 0.0, 10.0),
                0,
                u,
                &mut steps,
                |_, mp, maj, _, _| {
                    w *= (1.0 - (mp.sigma_a.x + mp.sigma_s.x) / maj.x) as f64;
                    true
                },
            );
            ratio += w;
        }
        let p = passed as f64 / n as f64;
        // Binomial standard error: sqrt(p(1−p)/n) ≈ 0.0009; allow 5σ.
        assert!(
            (p - exact).abs() < 5.0 * (exact * (1.0 - exact) / n as f64).sqrt(),
            "{p} vs {exact}"
        );
        // Ratio tracking's weights lie in [0, 1] with a smaller variance.
        assert!((ratio / n as f64 - exact).abs() < 5.0 * (exact * (1.0 - exact) / n as f64).sqrt());
    }

    #[test]
    fn a_grid_medium_is_empty_outside_its_box() {
        let m = Medium::new(
            Some(Aabb::new(Vec3::ZERO, Vec3::ONE)),
            Field::Constant(Rgb::ONE),
            Field::Constant(Rgb::ONE),
            None,
            Rgb::ONE,
            Phase::Isotropic,
        );
        assert_eq!(m.segment(Vec3::new(-1.0, 0.5, 0.5), Vec3::X, 10.0), Some((1.0, 2.0)));
        assert_eq!(m.segment(Vec3::new(-1.0, 2.5, 0.5), Vec3::X, 10.0), None);
        assert_eq!(m.segment(Vec3::new(-1.0, 0.5, 0.5), Vec3::X, 0.5), None);
        let h = Medium::homogeneous(Rgb::ONE, Rgb::ONE, Phase::Isotropic);
        assert_eq!(h.segment(Vec3::ZERO, Vec3::X, 3.0), Some((0.0, 3.0)));
        assert_eq!(
            transmittance(f32::INFINITY, Rgb::new(0.0, 1.0, 2.0)),
            Rgb::new(1.0, 0.0, 0.0)
        );
    }
}
