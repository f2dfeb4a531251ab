//! Light sources: point, spot, directional, and area lights (emissive
//! shapes), plus the background seen by rays that escape the scene.
//!
//! ```toml
//! [[light]]
//! type = "point"
//! position = [0, 1.9, 0]
//! intensity = [5, 5, 5]     # W/sr
//! falloff = true            # inverse-square law (false: classic constant light)
//! ```
//!
//! Every light answers one question for a shading point: which direction
//! to look in for light, how much arrives, and with what probability the
//! direction was chosen ([`Light::sample_li`]).

use crate::accel::aggregate::{Aggregate, EmitterArea, EmitterRef};
use crate::color::Rgb;
use glam::{Vec2, Vec3};

/// A light source.
#[derive(Clone, Debug)]
pub enum Light {
    /// An isotropic point light.
    Point {
        /// Position.
        position: Vec3,
        /// Radiant intensity (W/sr).
        intensity: Rgb,
        /// Inverse-square falloff; without it the light delivers
        /// `intensity` as irradiance at every distance.
        falloff: bool,
    },
    /// A point light restricted to a cone, fading smoothly between an inner
    /// and an outer angle.
    Spot {
        /// Position.
        position: Vec3,
        /// Unit axis of the cone (the direction light travels).
        direction: Vec3,
        /// Radiant intensity on the axis (W/sr).
        intensity: Rgb,
        /// Cosine of the angle inside which the intensity is full.
        cos_inner: f32,
        /// Cosine of the angle outside which there is no light.
        cos_outer: f32,
        /// Inverse-square falloff.
        falloff: bool,
    },
    /// Parallel light from infinitely far away, like the sun.
    Directional {
        /// Unit direction in which the light travels.
        direction: Vec3,
        /// Irradiance on a surface facing the light (W/m²).
        irradiance: Rgb,
    },
    /// An emissive shape or mesh.
    Area {
        /// The emitting geometry.
        emitter: EmitterRef,
        /// Emitted radiance from the front side.
        radiance: Rgb,
        /// Area data for sampling.
        area: EmitterArea,
    },
}

/// Where a shadow ray must go to test a light sample's visibility.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ShadowTarget {
    /// A point on the light (segment test).
    Point(Vec3),
    /// Infinitely far along the sampled direction.
    Infinity,
}

/// Light arriving at a shading point from one sampled direction.
#[derive(Clone, Copy, Debug)]
pub struct LightSample {
    /// Unit direction from the shading point toward the light.
    pub wi: Vec3,
    /// Incident radiance along `wi` (for delta lights: the irradiance the
    /// light delivers to a surface facing it, with pdf 1).
    pub li: Rgb,
    /// Density of `wi` per unit solid angle; 1 for delta lights.
    pub pdf: f32,
    /// Whether the light is a delta distribution (point, spot, directional).
    pub is_delta: bool,
    /// What the shadow ray must reach.
    pub target: ShadowTarget,
}

/// GLSL's smoothstep: 0 below `a`, 1 above `b`, a cubic ramp between.
#[inline]
fn smoothstep(a: f32, b: f32, x: f32) -> f32 {
    if a == b {
        return if x < a { 0.0 } else { 1.0 };
    }
    let t = ((x - a) / (b - a)).clamp(0.0, 1.0);
    t * t * (3.0 - 2.0 * t)
}

impl Light {
    /// Samples light arriving at point `p`; `u_pick` and `u` are uniform
    /// numbers (the first picks a triangle of a mesh emitter). Returns
    /// `None` when no light can arrive (behind a spot, on the back of an
    /// emitter, or at the emitter itself).
    pub fn sample_li(&self, geometry: &Aggregate, p: Vec3, u_pick: f32, u: Vec2) -> Option<LightSample> {
        match self {
            Light::Point {
                position,
                intensity,
                falloff,
            } => {
                let d = *position - p;
                let dist2 = d.length_squared();
                if dist2 == 0.0 {
                    return None;
                }
                let scale = if *falloff { 1.0 / dist2 } else { 1.0 };
                Some(LightSample {
                    wi: d / dist2.sqrt(),
                    li: *intensity * scale,
                    pdf: 1.0,
                    is_delta: true,
                    target: ShadowTarget::Point(*position),
                })
            }
            Light::Spot {
                position,
                direction,
                intensity,
                cos_inner,
                cos_outer,
                falloff,
            } => {
                let d = *position - p;
                let dist2 = d.length_squared();
                if dist2 == 0.0 {
                    return None;
                }
                let wi = d / dist2.sqrt();
                let cos = direction.dot(-wi);
                let cone = smoothstep(*cos_outer, *cos_inner, cos);
                if cone <= 0.0 {
                    return None;
                }
                let scale = if *falloff { 1.0 / dist2 } else { 1.0 };
                Some(LightSample {
                    wi,
                    li: *intensity * (cone * scale),
                    pdf: 1.0,
                    is_delta: true,
                    target: ShadowTarget::Point(*position),
                })
            }
            Light::Directional { direction, irradiance } => Some(LightSample {
                wi: -*direction,
                li: *irradiance,
                pdf: 1.0,
                is_delta: true,
                target: ShadowTarget::Infinity,
            }),
            Light::Area {
                emitter,
                radiance,
                area,
            } => {
                let s = geometry.sample_emitter(*emitter, area, u_pick, u)?;
                let d = s.p - p;
                let dist2 = d.length_squared();
                if dist2 == 0.0 || s.pdf_area.is_nan() || s.pdf_area <= 0.0 {
                    return None;
                }
                let wi = d / dist2.sqrt();
                // Emission leaves the front side only.
                let cos_light = s.n.dot(-wi);
                if cos_light <= 0.0 {
                    return None;
                }
                // Area density to solid-angle density: p_ω = p_A · d² / cosθ_l.
                let pdf = s.pdf_area * dist2 / cos_light;
                if !pdf.is_finite() {
                    return None;
                }
                Some(LightSample {
                    wi,
                    li: *radiance,
                    pdf,
                    is_delta: false,
                    target: ShadowTarget::Point(s.p),
                })
            }
        }
    }

    /// Whether the light is a delta distribution.
    pub fn is_delta(&self) -> bool {
        !matches!(self, Light::Area { .. })
    }
}

/// What rays that leave the scene see.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Background {
    /// One colour in every direction.
    Constant(Rgb),
    /// A vertical blend from `bottom` (looking straight down) to `top`
    /// (straight up).
    Gradient {
        /// Colour looking straight up.
        top: Rgb,
        /// Colour looking straight down.
        bottom: Rgb,
    },
}

impl Default for Background {
    fn default() -> Self {
        Background::Constant(Rgb::ZERO)
    }
}

impl Background {
    /// Radiance arriving from direction `dir` (need not be normalised).
    #[inline]
    pub fn eval(&self, dir: Vec3) -> Rgb {
        match *self {
            Background::Constant(c) => c,
            Background::Gradient { top, bottom } => {
                let y = dir.normalize_or_zero().y;
                let t = 0.5 * (y + 1.0);
                bottom * (1.0 - t) + top * t
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn point_light_inverse_square() {
        let l = Light::Point {
            position: Vec3::new(0.0, 2.0, 0.0),
            intensity: Rgb::splat(8.0),
            falloff: true,
        };
        let s = l.sample_li(&Aggregate::default(), Vec3::ZERO, 0.0, Vec2::ZERO).unwrap();
        assert_eq!(s.wi, Vec3::Y);
        assert!((s.li.x - 2.0).abs() < 1e-6);
        assert!(s.is_delta && s.pdf == 1.0);
        assert_eq!(s.target, ShadowTarget::Point(Vec3::new(0.0, 2.0, 0.0)));
        let flat = Light::Point {
            position: Vec3::new(0.0, 2.0, 0.0),
            intensity: Rgb::splat(8.0),
            falloff: false,
        };
        let s = flat
            .sample_li(&Aggregate::default(), Vec3::ZERO, 0.0, Vec2::ZERO)
            .unwrap();
        assert_eq!(s.li.x, 8.0);
    }

    #[test]
    fn spot_light_cone() {
        let l = Light::Spot {
            position: Vec3::new(0.0, 1.0, 0.0),
            direction: -Vec3::Y,
            intensity: Rgb::ONE,
            cos_inner: 20f32.to_radians().cos(),
            cos_outer: 30f32.to_radians().cos(),
            falloff: false,
        };
        let g = Aggregate::default();
        let on_axis = l.sample_li(&g, Vec3::ZERO, 0.0, Vec2::ZERO).unwrap();
        assert_eq!(on_axis.li, Rgb::ONE);
        let at = |deg: f32| Vec3::new(deg.to_radians().tan(), 0.0, 0.0);
        assert!(l.sample_li(&g, at(35.0), 0.0, Vec2::ZERO).is_none());
        let mid = l.sample_li(&g, at(25.0), 0.0, Vec2::ZERO).unwrap();
        assert!(mid.li.x > 0.0 && mid.li.x < 1.0);
        assert!(l.sample_li(&g, Vec3::new(0.0, 2.0, 0.0), 0.0, Vec2::ZERO).is_none());
    }

    #[test]
    fn directional_light() {
        let l = Light::Directional {
            direction: -Vec3::Y,
            irradiance: Rgb::splat(3.0),
        };
        let s = l.sample_li(&Aggregate::default(), Vec3::ZERO, 0.0, Vec2::ZERO).unwrap();
        assert_eq!(s.wi, Vec3::Y);
        assert_eq!(s.target, ShadowTarget::Infinity);
    }

    #[test]
    fn gradient_background() {
        let b = Background::Gradient {
            top: Rgb::ONE,
            bottom: Rgb::ZERO,
        };
        assert_eq!(b.eval(Vec3::Y * 3.0), Rgb::ONE);
        assert_eq!(b.eval(-Vec3::Y), Rgb::ZERO);
        assert_eq!(b.eval(Vec3::X), Rgb::splat(0.5));
    }
}
