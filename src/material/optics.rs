//! Geometric optics at a smooth interface: mirror reflection, Snell's law
//! and the Fresnel equations for dielectrics.
//!
//! Directions point away from the surface (both the incident and the
//! outgoing one), as in pbrt-v4.

use crate::geometry::simd::{Floats, Vec3s};
use glam::Vec3;

/// Mirror reflection of `w` about the normal `n`: `2(w·n)n − w`.
#[inline]
pub fn reflect(w: Vec3, n: Vec3) -> Vec3 {
    reflect_lanes(Vec3s::<f32>::splat(w), Vec3s::splat(n)).lane(0)
}

/// [`reflect`] over lanes.
#[inline(always)]
pub fn reflect_lanes<F: Floats>(w: Vec3s<F>, n: Vec3s<F>) -> Vec3s<F> {
    n.scale(F::splat(2.0) * w.dot(n)) - w
}

/// Refraction of `wi` through an interface with normal `n` and relative
/// index of refraction `eta` = η_transmitted / η_incident, measured on the
/// side `n` points to. If `wi` is on the other side, the interface is
/// crossed the other way (η → 1/η). Returns the refracted direction and the
/// relative index actually used, or `None` on total internal reflection.
///
/// Snell's law η_i sinθ_i = η_t sinθ_t, in vector form (pbrt-v4, eq. 9.4).
#[inline]
pub fn refract(wi: Vec3, n: Vec3, eta: f32) -> Option<(Vec3, f32)> {
    let cos = n.dot(wi);
    let (cos_i, eta, cos_t) = snell(cos, eta);
    let n = if cos < 0.0 { -n } else { n };
    Some((refracted(wi, n, cos_i, eta, cos_t?), eta))
}

/// Snell's law for light arriving with cosine `cos_i` (negative: from the
/// inside) at an interface of relative index `eta` = η_t / η_i: |cos θ_i|,
/// the relative index of this crossing (`eta`, or 1/`eta` from the inside)
/// and |cos θ_t|, `None` under total internal reflection. What
/// [`refract`] and [`fresnel_dielectric`] share, so that a smooth
/// dielectric that needs both computes it once.
#[inline]
pub fn snell(cos_i: f32, eta: f32) -> (f32, f32, Option<f32>) {
    let (cos_i, eta, cos_t, crosses) = snell_lanes(cos_i, eta);
    (cos_i, eta, crosses.then_some(cos_t))
}

/// [`snell`] over lanes: |cos θ_i|, the relative index of the crossing,
/// |cos θ_t| and the lanes where light crosses (elsewhere it is totally
/// reflected, and |cos θ_t| is 0).
#[inline(always)]
pub fn snell_lanes<F: Floats>(cos_i: F, eta: F) -> (F, F, F, F::Mask) {
    let (zero, one) = (F::splat(0.0), F::splat(1.0));
    // Divisions by the index only, which is known before the cosine, so
    // that they run ahead of the cosine's arithmetic instead of after it.
    let inv_eta = one / eta;
    let inside = zero.gt(cos_i);
    let (cos_i, eta, inv_eta) = (
        F::select(inside, zero - cos_i, cos_i),
        F::select(inside, inv_eta, eta),
        F::select(inside, eta, inv_eta),
    );
    let sin2_t = (one - cos_i * cos_i).max(zero) * (inv_eta * inv_eta);
    let crosses = one.gt(sin2_t);
    (cos_i, eta, (one - sin2_t).max(zero).sqrt(), crosses)
}

/// The direction `wi` refracts into, from [`snell`]'s cosines and index,
/// `n` the normal on `wi`'s side (pbrt-v4, eq. 9.4).
#[inline]
pub fn refracted(wi: Vec3, n: Vec3, cos_i: f32, eta: f32, cos_t: f32) -> Vec3 {
    refracted_lanes(Vec3s::<f32>::splat(wi), Vec3s::splat(n), cos_i, eta, cos_t).lane(0)
}

/// [`refracted`] over lanes.
#[inline(always)]
pub fn refracted_lanes<F: Floats>(wi: Vec3s<F>, n: Vec3s<F>, cos_i: F, eta: F, cos_t: F) -> Vec3s<F> {
    // (The reciprocal, as in `snell`, ahead of the cosines.)
    let inv_eta = F::splat(1.0) / eta;
    n.scale(cos_i * inv_eta - cos_t) - wi.scale(inv_eta)
}

/// Unpolarised Fresnel reflectance of a dielectric interface for light
/// arriving with cosine `cos_i` (negative: from the inside) and relative
/// index `eta` = η_t / η_i. Returns 1 under total internal reflection.
#[inline]
pub fn fresnel_dielectric(cos_i: f32, eta: f32) -> f32 {
    match snell(cos_i.clamp(-1.0, 1.0), eta) {
        (cos_i, eta, Some(cos_t)) => fresnel_of_cosines(cos_i, eta, cos_t),
        (_, _, None) => 1.0,
    }
}

/// The Fresnel reflectance from [`snell`]'s cosines and index: the mean
/// of the parallel and perpendicular polarisations' (pbrt-v4, eq. 9.6).
#[inline(always)]
pub fn fresnel_of_cosines<F: Floats>(cos_i: F, eta: F, cos_t: F) -> F {
    let r_parl = (eta * cos_i - cos_t) / (eta * cos_i + cos_t);
    let r_perp = (cos_i - eta * cos_t) / (cos_i + eta * cos_t);
    F::splat(0.5) * (r_parl * r_parl + r_perp * r_perp)
}

/// A complex number, for the Fresnel equations of conductors.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Complex {
    re: f32,
    im: f32,
}

impl Complex {
    fn new(re: f32, im: f32) -> Self {
        Complex { re, im }
    }
    fn add(self, o: Complex) -> Complex {
        Complex::new(self.re + o.re, self.im + o.im)
    }
    fn sub(self, o: Complex) -> Complex {
        Complex::new(self.re - o.re, self.im - o.im)
    }
    fn mul(self, o: Complex) -> Complex {
        Complex::new(self.re * o.re - self.im * o.im, self.re * o.im + self.im * o.re)
    }
    fn div(self, o: Complex) -> Complex {
        let d = o.re * o.re + o.im * o.im;
        Complex::new(
            (self.re * o.re + self.im * o.im) / d,
            (self.im * o.re - self.re * o.im) / d,
        )
    }
    fn norm(self) -> f32 {
        self.re * self.re + self.im * self.im
    }
    /// Principal square root.
    fn sqrt(self) -> Complex {
        let n = self.norm().sqrt();
        if n == 0.0 {
            return Complex::new(0.0, 0.0);
        }
        let t1 = (0.5 * (n + self.re.abs())).sqrt();
        let t2 = 0.5 * self.im / t1;
        if self.re >= 0.0 {
            Complex::new(t1, t2)
        } else {
            Complex::new(t2.abs(), t1.copysign(self.im))
        }
    }
}

/// Unpolarised Fresnel reflectance of a conductor with complex index of
/// refraction η + i·k (relative to the outside) for light arriving with
/// cosine `cos_i` ≥ 0 (pbrt-v4, section 9.4.2: the dielectric formula with
/// complex arithmetic).
#[inline]
pub fn fresnel_conductor(cos_i: f32, eta: f32, k: f32) -> f32 {
    let cos_i = cos_i.clamp(0.0, 1.0);
    let eta_c = Complex::new(eta, k);
    let sin2_i = 1.0 - cos_i * cos_i;
    let sin2_t = Complex::new(sin2_i, 0.0).div(eta_c.mul(eta_c));
    let cos_t = Complex::new(1.0, 0.0).sub(sin2_t).sqrt();
    let ci = Complex::new(cos_i, 0.0);
    let r_parl = eta_c.mul(ci).sub(cos_t).div(eta_c.mul(ci).add(cos_t));
    let r_perp = ci.sub(eta_c.mul(cos_t)).div(ci.add(eta_c.mul(cos_t)));
    0.5 * (r_parl.norm() + r_perp.norm())
}

/// Schlick's approximation F₀ + (1 − F₀)(1 − cos θ)⁵, for conductors given
/// by their colour at normal incidence.
#[inline]
pub fn fresnel_schlick(cos_i: f32, f0: f32) -> f32 {
    let m = (1.0 - cos_i.clamp(0.0, 1.0)).max(0.0);
    let m2 = m * m;
    f0 + (1.0 - f0) * m2 * m2 * m
}

/// Hemispherical average of the dielectric Fresnel reflectance,
/// 2∫₀¹ F(μ, η) μ dμ, by the midpoint rule on 1024 intervals: the fraction
/// of diffuse light that an interface reflects back.
pub fn fresnel_diffuse_reflectance(eta: f32) -> f32 {
    let n = 1024;
    let mut sum = 0.0f64;
    for i in 0..n {
        let mu = (i as f32 + 0.5) / n as f32;
        sum += (fresnel_dielectric(mu, eta) * mu) as f64;
    }
    (2.0 * sum / n as f64) as f32
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mirror_reflection() {
        let w = Vec3::new(1.0, 1.0, 0.0).normalize();
        let r = reflect(w, Vec3::Y);
        assert!((r - Vec3::new(-1.0, 1.0, 0.0).normalize()).length() < 1e-6);
    }

    #[test]
    fn snell_law_holds() {
        let eta = 1.5;
        for deg in [0.0f32, 10.0, 30.0, 60.0, 89.0] {
            let th = deg.to_radians();
            let wi = Vec3::new(th.sin(), th.cos(), 0.0);
            let (wt, used) = refract(wi, Vec3::Y, eta).unwrap();
            assert_eq!(used, eta);
            assert!((wt.length() - 1.0).abs() < 1e-5);
            assert!(wt.y < 0.0 && wt.x <= 0.0, "transmitted ray continues through");
            let sin_t = (wt.x * wt.x + wt.z * wt.z).sqrt();
            assert!((th.sin() - eta * sin_t).abs() < 1e-5, "{deg}°");
        }
    }

    #[test]
    fn total_internal_reflection_beyond_the_critical_angle() {
        // From glass (η = 1.5) to air: critical angle asin(1/1.5) ≈ 41.81°.
        let critical = (1.0f32 / 1.5).asin();
        let n = Vec3::Y;
        for (deg, tir) in [(30.0f32, false), (41.0, false), (42.0, true), (70.0, true)] {
            let th = deg.to_radians();
            // wi on the inside (below the surface): cos < 0.
            let wi = Vec3::new(th.sin(), -th.cos(), 0.0);
            assert_eq!(refract(wi, n, 1.5).is_none(), tir, "{deg}°");
            assert_eq!(fresnel_dielectric(-th.cos(), 1.5) == 1.0, tir, "{deg}°");
            assert_eq!(th > critical, tir);
        }
    }

    #[test]
    fn fresnel_known_values() {
        // Normal incidence: ((η − 1)/(η + 1))² = 0.04 for η = 1.5.
        assert!((fresnel_dielectric(1.0, 1.5) - 0.04).abs() < 1e-6);
        // Same from the inside.
        assert!((fresnel_dielectric(-1.0, 1.5) - 0.04).abs() < 1e-6);
        // Grazing incidence reflects everything.
        assert!(fresnel_dielectric(1e-6, 1.5) > 0.999);
        // Brewster's angle atan(1.5): the parallel component vanishes, so
        // F = r_perp²/2 with r_perp = (cos_i − η cos_t)/(cos_i + η cos_t).
        let b = 1.5f32.atan();
        let (ci, ct) = (b.cos(), (1.0 - (b.sin() / 1.5).powi(2)).sqrt());
        let rp = (ci - 1.5 * ct) / (ci + 1.5 * ct);
        assert!((fresnel_dielectric(ci, 1.5) - 0.5 * rp * rp).abs() < 1e-6);
        // Index matching: no reflection.
        assert!(fresnel_dielectric(0.3, 1.0).abs() < 1e-7);
    }

    #[test]
    fn conductor_fresnel_reduces_to_known_cases() {
        // k = 0: the dielectric formula.
        for cos in [0.1f32, 0.5, 0.9, 1.0] {
            assert!((fresnel_conductor(cos, 1.5, 0.0) - fresnel_dielectric(cos, 1.5)).abs() < 1e-5);
        }
        // Normal incidence: ((η−1)² + k²)/((η+1)² + k²).
        let (eta, k) = (0.2f32, 3.9f32);
        let expect = ((eta - 1.0).powi(2) + k * k) / ((eta + 1.0).powi(2) + k * k);
        assert!((fresnel_conductor(1.0, eta, k) - expect).abs() < 1e-5);
        // Grazing: everything reflects.
        assert!(fresnel_conductor(0.0, eta, k) > 0.999);
        assert!((fresnel_schlick(1.0, 0.3) - 0.3).abs() < 1e-7 && fresnel_schlick(0.0, 0.3) == 1.0);
    }

    #[test]
    fn diffuse_fresnel_reflectance_known_value() {
        // Egan and Hilgeman's fit for η = 1.5 gives about 0.092 from outside;
        // from inside (η = 1/1.5) total internal reflection raises it to about 0.596.
        assert!(
            (fresnel_diffuse_reflectance(1.5) - 0.092).abs() < 0.003,
            "{}",
            fresnel_diffuse_reflectance(1.5)
        );
        assert!(
            (fresnel_diffuse_reflectance(1.0 / 1.5) - 0.596).abs() < 0.005,
            "{}",
            fresnel_diffuse_reflectance(1.0 / 1.5)
        );
    }
}
