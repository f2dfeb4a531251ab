//! Geometric optics at a smooth interface: mirror reflection, Snell's law
//! and the Fresnel equations for dielectrics.
//!
//! Directions point away from the surface (both the incident and the
//! outgoing one), as in pbrt-v4.

use glam::Vec3;

/// Mirror reflection of `w` about the normal `n`: `2(w·n)n − w`.
#[inline]
pub fn reflect(w: Vec3, n: Vec3) -> Vec3 {
    2.0 * w.dot(n) * n - w
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
    let mut cos_i = n.dot(wi);
    let (mut eta, mut n) = (eta, n);
    if cos_i < 0.0 {
        eta = 1.0 / eta;
        cos_i = -cos_i;
        n = -n;
    }
    let sin2_i = (1.0 - cos_i * cos_i).max(0.0);
    let sin2_t = sin2_i / (eta * eta);
    if sin2_t >= 1.0 {
        return None;
    }
    let cos_t = (1.0 - sin2_t).sqrt();
    Some((-wi / eta + (cos_i / eta - cos_t) * n, eta))
}

/// Unpolarised Fresnel reflectance of a dielectric interface for light
/// arriving with cosine `cos_i` (negative: from the inside) and relative
/// index `eta` = η_t / η_i. Returns 1 under total internal reflection.
#[inline]
pub fn fresnel_dielectric(cos_i: f32, eta: f32) -> f32 {
    let mut cos_i = cos_i.clamp(-1.0, 1.0);
    let mut eta = eta;
    if cos_i < 0.0 {
        eta = 1.0 / eta;
        cos_i = -cos_i;
    }
    let sin2_t = (1.0 - cos_i * cos_i) / (eta * eta);
    if sin2_t >= 1.0 {
        return 1.0;
    }
    let cos_t = (1.0 - sin2_t).max(0.0).sqrt();
    let r_parl = (eta * cos_i - cos_t) / (eta * cos_i + cos_t);
    let r_perp = (cos_i - eta * cos_t) / (cos_i + eta * cos_t);
    0.5 * (r_parl * r_parl + r_perp * r_perp)
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
}
