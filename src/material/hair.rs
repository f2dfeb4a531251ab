//! Hair: the scattering model of Chiang, Bitterli, Tappan and Burley
//! (2016, "A Practical and Controllable Hair and Fur Model for Production
//! Path Tracing"), as pbrt-v4's `HairBxDF` evaluates and samples it.
//!
//! A hair is a dielectric cylinder of index η whose interior absorbs with
//! σa per unit of the fibre's diameter. Light leaves it after p internal
//! paths: reflected at the surface (p = 0, R), through it (p = 1, TT),
//! after one internal reflection (p = 2, TRT), and the rest (p ≥ 3). Each
//! term is a product of a longitudinal lobe Mp (a von Mises–Fisher-like
//! distribution of width v from βm, its centre tilted by the cuticle
//! scales' angle α), an attenuation Ap (Fresnel and absorption) and an
//! azimuthal lobe Np (a trimmed logistic of scale s from βn around the
//! exit angle of a ray entering at offset h).
//!
//! Frame: x runs along the hair (the surface's ∂p/∂u) and the azimuth φ
//! is measured in the y–z plane; h ∈ [−1, 1] is where across the fibre
//! the ray met it (−1 + 2v on a curve). The model scatters into every
//! direction: it reflects and transmits.

use super::bsdf::{BsdfSample, TransportMode};
use super::optics::fresnel_dielectric;
use crate::color::Rgb;
use glam::{Vec2, Vec3};
use std::f32::consts::PI;

/// Scattering orders tabulated before the remainder.
const P_MAX: usize = 3;

/// A fibre's parameters (pbrt-v4's `hair` material), the same at every
/// point; the BSDF at a point adds where across the fibre it is.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HairParams {
    /// Absorption per unit diameter.
    pub sigma_a: Rgb,
    /// Index of refraction of the fibre.
    pub eta: f32,
    /// Longitudinal roughness, in [0, 1].
    pub beta_m: f32,
    /// Azimuthal roughness, in [0, 1].
    pub beta_n: f32,
    /// Tilt of the cuticle scales, in degrees.
    pub alpha: f32,
}

impl HairParams {
    /// The BSDF at offset `h` ∈ [−1, 1] across the fibre.
    pub fn bsdf(&self, h: f32) -> HairBsdf {
        HairBsdf::new(h, self.eta, self.sigma_a, self.beta_m, self.beta_n, self.alpha)
    }
}

/// The hair BSDF at one point.
#[derive(Clone, Copy, Debug)]
pub struct HairBsdf {
    /// Offset across the fibre, in [−1, 1].
    h: f32,
    /// Index of refraction of the fibre.
    eta: f32,
    /// Absorption per unit diameter.
    sigma_a: Rgb,
    /// Longitudinal variances per order.
    v: [f32; P_MAX + 1],
    /// Azimuthal logistic scale.
    s: f32,
    /// sin and cos of 2^k α, k = 0, 1, 2.
    sin_2k_alpha: [f32; P_MAX],
    cos_2k_alpha: [f32; P_MAX],
}

fn safe_sqrt(x: f32) -> f32 {
    x.max(0.0).sqrt()
}

fn safe_asin(x: f32) -> f32 {
    x.clamp(-1.0, 1.0).asin()
}

/// The modified Bessel function of the first kind I0, by its series.
fn bessel_i0(x: f32) -> f32 {
    let mut value = 0.0f32;
    let mut x2i = 1.0f32;
    let mut factorial = 1.0f32;
    let mut four_i = 1.0f32;
    for i in 0..10 {
        if i > 1 {
            factorial *= i as f32;
        }
        value += x2i / (four_i * factorial * factorial);
        x2i *= x * x;
        four_i *= 4.0;
    }
    value
}

fn log_bessel_i0(x: f32) -> f32 {
    if x > 12.0 {
        x + 0.5 * (-(2.0 * PI).ln() + (1.0 / x).ln() + 1.0 / (8.0 * x))
    } else {
        bessel_i0(x).ln()
    }
}

/// The longitudinal scattering function Mp (d'Eon et al. 2011), in its
/// logarithmic form for narrow lobes where the direct one overflows.
fn longitudinal(cos_i: f32, cos_o: f32, sin_i: f32, sin_o: f32, v: f32) -> f32 {
    let a = cos_i * cos_o / v;
    let b = sin_i * sin_o / v;
    if v <= 0.1 {
        (log_bessel_i0(a) - b - 1.0 / v + std::f32::consts::LN_2 + (1.0 / (2.0 * v)).ln()).exp()
    } else {
        ((-b).exp() * bessel_i0(a)) / ((1.0 / v).sinh() * 2.0 * v)
    }
}

fn logistic(x: f32, s: f32) -> f32 {
    let x = x.abs();
    let e = (-x / s).exp();
    e / (s * (1.0 + e) * (1.0 + e))
}

fn logistic_cdf(x: f32, s: f32) -> f32 {
    1.0 / (1.0 + (-x / s).exp())
}

/// The logistic distribution restricted to [−π, π].
fn trimmed_logistic(x: f32, s: f32) -> f32 {
    logistic(x, s) / (logistic_cdf(PI, s) - logistic_cdf(-PI, s))
}

fn sample_trimmed_logistic(u: f32, s: f32) -> f32 {
    let (a, b) = (logistic_cdf(-PI, s), logistic_cdf(PI, s));
    let u = a + u * (b - a);
    (-s * (1.0 / u - 1.0).ln()).clamp(-PI, PI)
}

/// The azimuth at which order p leaves a fibre entered at γo.
fn exit_azimuth(p: usize, gamma_o: f32, gamma_t: f32) -> f32 {
    2.0 * p as f32 * gamma_t - 2.0 * gamma_o + p as f32 * PI
}

/// The azimuthal scattering function Np.
fn azimuthal(phi: f32, p: usize, s: f32, gamma_o: f32, gamma_t: f32) -> f32 {
    let mut d = phi - exit_azimuth(p, gamma_o, gamma_t);
    while d > PI {
        d -= 2.0 * PI;
    }
    while d < -PI {
        d += 2.0 * PI;
    }
    trimmed_logistic(d, s)
}

/// Angles of a direction in the hair's frame: sin θ, cos θ, φ.
fn hair_angles(w: Vec3) -> (f32, f32, f32) {
    let sin_theta = w.x;
    (sin_theta, safe_sqrt(1.0 - sin_theta * sin_theta), w.z.atan2(w.y))
}

impl HairBsdf {
    /// The model at offset `h` for a fibre of index `eta`, absorption
    /// `sigma_a`, longitudinal and azimuthal roughness `beta_m`, `beta_n`
    /// (clamped to [0.01, 1] as pbrt-v4 does) and scale tilt `alpha_deg`.
    pub fn new(h: f32, eta: f32, sigma_a: Rgb, beta_m: f32, beta_n: f32, alpha_deg: f32) -> HairBsdf {
        let bm = beta_m.clamp(0.01, 1.0);
        let bn = beta_n.clamp(0.01, 1.0);
        let v0 = {
            let x = 0.726 * bm + 0.812 * bm * bm + 3.7 * bm.powi(20);
            x * x
        };
        let v = [v0, 0.25 * v0, 4.0 * v0, 4.0 * v0];
        // √(π/8)
        let s = 0.626_657_07 * (0.265 * bn + 1.194 * bn * bn + 5.372 * bn.powi(22));
        let mut sin_2k_alpha = [0.0; P_MAX];
        let mut cos_2k_alpha = [0.0; P_MAX];
        sin_2k_alpha[0] = alpha_deg.to_radians().sin();
        cos_2k_alpha[0] = safe_sqrt(1.0 - sin_2k_alpha[0] * sin_2k_alpha[0]);
        for i in 1..P_MAX {
            sin_2k_alpha[i] = 2.0 * cos_2k_alpha[i - 1] * sin_2k_alpha[i - 1];
            cos_2k_alpha[i] = cos_2k_alpha[i - 1] * cos_2k_alpha[i - 1] - sin_2k_alpha[i - 1] * sin_2k_alpha[i - 1];
        }
        HairBsdf {
            h: h.clamp(-1.0, 1.0),
            eta,
            sigma_a: sigma_a.max(Rgb::ZERO),
            v,
            s,
            sin_2k_alpha,
            cos_2k_alpha,
        }
    }

    /// σa of a fibre with eumelanin and pheomelanin concentrations `ce`,
    /// `cp` (Donner and Jensen's pigment absorptions, as pbrt-v4).
    pub fn sigma_a_from_concentration(ce: f32, cp: f32) -> Rgb {
        Rgb::new(0.419, 0.697, 1.37) * ce + Rgb::new(0.187, 0.4, 1.05) * cp
    }

    /// σa that gives a fibre of azimuthal roughness `beta_n` the colour
    /// `c` after multiple scattering (Chiang et al. 2016, eq. 9).
    pub fn sigma_a_from_reflectance(c: Rgb, beta_n: f32) -> Rgb {
        let b = beta_n;
        let d = 5.969 - 0.215 * b + 2.532 * b * b - 10.73 * b.powi(3) + 5.574 * b.powi(4) + 0.245 * b.powi(5);
        let channel = |x: f32| {
            let l = x.clamp(1e-4, 1.0).ln() / d;
            l * l
        };
        Rgb::new(channel(c.x), channel(c.y), channel(c.z))
    }

    /// sin and cos of θo tilted by the scales for order p.
    fn tilted(&self, p: usize, sin_o: f32, cos_o: f32) -> (f32, f32) {
        let (sa, ca) = (&self.sin_2k_alpha, &self.cos_2k_alpha);
        let (s, c) = match p {
            0 => (sin_o * ca[1] - cos_o * sa[1], cos_o * ca[1] + sin_o * sa[1]),
            1 => (sin_o * ca[0] + cos_o * sa[0], cos_o * ca[0] - sin_o * sa[0]),
            2 => (sin_o * ca[2] + cos_o * sa[2], cos_o * ca[2] - sin_o * sa[2]),
            _ => (sin_o, cos_o),
        };
        (s, c.abs())
    }

    /// γt of the refracted ray, and the transmittance of one crossing.
    fn refracted(&self, sin_o: f32, cos_o: f32) -> (f32, Rgb) {
        let sin_t = sin_o / self.eta;
        let cos_t = safe_sqrt(1.0 - sin_t * sin_t);
        let etap = safe_sqrt(self.eta * self.eta - sin_o * sin_o) / cos_o;
        let sin_gamma_t = self.h / etap;
        let cos_gamma_t = safe_sqrt(1.0 - sin_gamma_t * sin_gamma_t);
        let t = (-(self.sigma_a * (2.0 * cos_gamma_t / cos_t))).exp();
        (safe_asin(sin_gamma_t), t)
    }

    /// The attenuations Ap of each order.
    fn attenuations(&self, cos_o: f32, t: Rgb) -> [Rgb; P_MAX + 1] {
        let cos_gamma_o = safe_sqrt(1.0 - self.h * self.h);
        let f = fresnel_dielectric(cos_o * cos_gamma_o, self.eta);
        let mut ap = [Rgb::ZERO; P_MAX + 1];
        ap[0] = Rgb::splat(f);
        ap[1] = t * (1.0 - f) * (1.0 - f);
        for p in 2..P_MAX {
            ap[p] = ap[p - 1] * t * f;
        }
        let rest = Rgb::ONE - t * f;
        ap[P_MAX] = Rgb::new(
            if rest.x != 0.0 {
                ap[P_MAX - 1].x * f * t.x / rest.x
            } else {
                0.0
            },
            if rest.y != 0.0 {
                ap[P_MAX - 1].y * f * t.y / rest.y
            } else {
                0.0
            },
            if rest.z != 0.0 {
                ap[P_MAX - 1].z * f * t.z / rest.z
            } else {
                0.0
            },
        );
        ap
    }

    /// The probability of sampling each order: its share of the mean
    /// attenuation.
    fn order_pdf(&self, sin_o: f32, cos_o: f32) -> [f32; P_MAX + 1] {
        let (_, t) = self.refracted(sin_o, cos_o);
        let ap = self.attenuations(cos_o, t);
        let mean = ap.map(|a| (a.x + a.y + a.z) / 3.0);
        let sum: f32 = mean.iter().sum();
        if sum > 0.0 {
            mean.map(|m| m / sum)
        } else {
            [1.0, 0.0, 0.0, 0.0]
        }
    }

    pub(crate) fn eval(&self, wo: Vec3, wi: Vec3, _mode: TransportMode) -> Rgb {
        let (sin_o, cos_o, phi_o) = hair_angles(wo);
        let (sin_i, cos_i, phi_i) = hair_angles(wi);
        let gamma_o = safe_asin(self.h);
        let (gamma_t, t) = self.refracted(sin_o, cos_o);
        let phi = phi_i - phi_o;
        let ap = self.attenuations(cos_o, t);
        let mut sum = Rgb::ZERO;
        for (p, a) in ap.iter().enumerate().take(P_MAX) {
            let (s, c) = self.tilted(p, sin_o, cos_o);
            sum += *a * (longitudinal(cos_i, c, sin_i, s, self.v[p]) * azimuthal(phi, p, self.s, gamma_o, gamma_t));
        }
        sum += ap[P_MAX] * (longitudinal(cos_i, cos_o, sin_i, sin_o, self.v[P_MAX]) / (2.0 * PI));
        if wi.z != 0.0 {
            sum /= wi.z.abs();
        }
        if sum.is_finite() { sum } else { Rgb::ZERO }
    }

    /// The density of `wi` given `wo`, with the order pdf given.
    fn pdf_with(&self, wo: Vec3, wi: Vec3, order: &[f32; P_MAX + 1]) -> f32 {
        let (sin_o, cos_o, phi_o) = hair_angles(wo);
        let (sin_i, cos_i, phi_i) = hair_angles(wi);
        let gamma_o = safe_asin(self.h);
        let (gamma_t, _) = self.refracted(sin_o, cos_o);
        let phi = phi_i - phi_o;
        let mut pdf = 0.0;
        for (p, w) in order.iter().enumerate().take(P_MAX) {
            let (s, c) = self.tilted(p, sin_o, cos_o);
            pdf += longitudinal(cos_i, c, sin_i, s, self.v[p]) * w * azimuthal(phi, p, self.s, gamma_o, gamma_t);
        }
        pdf += longitudinal(cos_i, cos_o, sin_i, sin_o, self.v[P_MAX]) * order[P_MAX] / (2.0 * PI);
        if pdf.is_finite() { pdf } else { 0.0 }
    }

    pub(crate) fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        let (sin_o, cos_o, _) = hair_angles(wo);
        self.pdf_with(wo, wi, &self.order_pdf(sin_o, cos_o))
    }

    pub(crate) fn sample(&self, wo: Vec3, u_lobe: f32, u: Vec2, mode: TransportMode) -> Option<BsdfSample> {
        let (sin_o, cos_o, phi_o) = hair_angles(wo);
        let gamma_o = safe_asin(self.h);
        let order = self.order_pdf(sin_o, cos_o);
        // Choose the order, and reuse what is left of u_lobe for Δφ.
        let mut p = P_MAX;
        let mut uc = u_lobe;
        let mut below = 0.0;
        for (k, w) in order.iter().enumerate() {
            if uc < below + w || k == P_MAX {
                p = k;
                uc = if *w > 0.0 {
                    ((uc - below) / w).clamp(0.0, crate::sampling::rng::ONE_MINUS_EPSILON)
                } else {
                    0.5
                };
                break;
            }
            below += w;
        }
        let (s, c) = self.tilted(p, sin_o, cos_o);
        // Mp by inverting its CDF in cos θ (d'Eon et al.'s sampling).
        let v = self.v[p];
        let cos_theta = 1.0 + v * (u.x.max(1e-5) + (1.0 - u.x) * (-2.0 / v).exp()).ln();
        let sin_theta = safe_sqrt(1.0 - cos_theta * cos_theta);
        let cos_phi = (2.0 * PI * u.y).cos();
        let sin_i = -cos_theta * s + sin_theta * cos_phi * c;
        let cos_i = safe_sqrt(1.0 - sin_i * sin_i);
        let (gamma_t, _) = self.refracted(sin_o, cos_o);
        let dphi = if p < P_MAX {
            exit_azimuth(p, gamma_o, gamma_t) + sample_trimmed_logistic(uc, self.s)
        } else {
            2.0 * PI * uc
        };
        let phi_i = phi_o + dphi;
        let wi = Vec3::new(sin_i, cos_i * phi_i.cos(), cos_i * phi_i.sin());
        let pdf = self.pdf_with(wo, wi, &order);
        if pdf.is_nan() || pdf <= 0.0 {
            return None;
        }
        Some(BsdfSample {
            wi,
            f: self.eval(wo, wi, mode),
            pdf,
            delta: false,
            eta: 1.0,
        })
    }

    pub(crate) fn delta_probability(&self, _wo: Vec3) -> f32 {
        0.0
    }

    pub(crate) fn sample_delta(&self, _wo: Vec3, _u: f32, _mode: TransportMode) -> Option<BsdfSample> {
        None
    }

    pub(crate) fn has_smooth(&self) -> bool {
        true
    }

    pub(crate) fn albedo(&self) -> Rgb {
        // The colour multiple scattering gives (the inverse of
        // `sigma_a_from_reflectance` at βn = 0.3).
        let d = 5.969 - 0.215 * 0.3 + 2.532 * 0.09 - 10.73 * 0.027 + 5.574 * 0.0081 + 0.245 * 0.00243;
        let c = |s: f32| (-s.sqrt() * d).exp();
        Rgb::new(c(self.sigma_a.x), c(self.sigma_a.y), c(self.sigma_a.z))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::rng::Pcg32;
    use crate::sampling::warp::sample_sphere_uniform;

    fn random_hair(rng: &mut Pcg32, sigma_a: Rgb) -> HairBsdf {
        let beta_m = 0.1 + 0.9 * rng.next_f32();
        let beta_n = 0.1 + 0.9 * rng.next_f32();
        HairBsdf::new(-1.0 + 2.0 * rng.next_f32(), 1.55, sigma_a, beta_m, beta_n, 2.0)
    }

    /// Without absorption a fibre loses nothing: ∫ f |cos θi| dωi = 1
    /// (pbrt-v4's white furnace test; uniform directions over the sphere,
    /// 300 000 of them, standard error well under 1 %).
    #[test]
    fn a_fibre_without_absorption_keeps_all_the_light() {
        let mut rng = Pcg32::new(1, 0);
        for _ in 0..6 {
            let hair = random_hair(&mut rng, Rgb::ZERO);
            let wo = sample_sphere_uniform(Vec2::new(rng.next_f32(), rng.next_f32()));
            let n = 300_000;
            let mut sum = 0.0f64;
            for _ in 0..n {
                let wi = sample_sphere_uniform(Vec2::new(rng.next_f32(), rng.next_f32()));
                sum += (hair.eval(wo, wi, TransportMode::Radiance).y * wi.z.abs()) as f64;
            }
            let albedo = sum / n as f64 * 4.0 * std::f64::consts::PI;
            assert!((albedo - 1.0).abs() < 0.05, "albedo {albedo} for {hair:?}");
        }
    }

    /// Sampling: the weight f·|cos|/pdf is 1 without absorption (pbrt-v4's
    /// test), the pdf is `pdf`'s, and the pdf integrates to 1.
    #[test]
    fn sampling_is_exact_without_absorption_and_matches_the_density() {
        let mut rng = Pcg32::new(2, 0);
        for _ in 0..6 {
            let hair = random_hair(&mut rng, Rgb::ZERO);
            let wo = sample_sphere_uniform(Vec2::new(rng.next_f32(), rng.next_f32()));
            for _ in 0..2000 {
                let u = Vec2::new(rng.next_f32(), rng.next_f32());
                let Some(s) = hair.sample(wo, rng.next_f32(), u, TransportMode::Radiance) else {
                    continue;
                };
                let w = s.weight();
                assert!((w.y - 1.0).abs() < 1e-3, "weight {w} for {hair:?}");
                let pdf = hair.pdf(wo, s.wi);
                assert!((s.pdf - pdf).abs() <= 1e-4 * pdf.max(1.0), "{} against {pdf}", s.pdf);
            }
            let n = 300_000;
            let mut sum = 0.0f64;
            for _ in 0..n {
                let wi = sample_sphere_uniform(Vec2::new(rng.next_f32(), rng.next_f32()));
                sum += hair.pdf(wo, wi) as f64;
            }
            let integral = sum / n as f64 * 4.0 * std::f64::consts::PI;
            assert!((integral - 1.0).abs() < 0.05, "∫ pdf = {integral}");
        }
    }

    /// Absorption darkens in proportion to the path inside; pigments and
    /// reflectance give pbrt-v4's coefficients.
    #[test]
    fn absorption_and_its_parameterisations() {
        let dark = HairBsdf::sigma_a_from_concentration(1.3, 0.0);
        assert!(
            (dark - Rgb::new(0.5447, 0.9061, 1.781)).abs().max_element() < 1e-3,
            "{dark}"
        );
        // Reflectance → σa → the colour back (the approximation's inverse).
        let c = Rgb::new(0.7, 0.5, 0.2);
        let s = HairBsdf::sigma_a_from_reflectance(c, 0.3);
        let back = HairBsdf::new(0.0, 1.55, s, 0.3, 0.3, 2.0).albedo();
        assert!((back - c).abs().max_element() < 1e-3, "{back}");
        // A dark fibre scatters less than a clear one.
        let wo = Vec3::new(0.2, 0.5, 0.84).normalize();
        let wi = Vec3::new(-0.1, -0.6, -0.79).normalize();
        let clear = HairBsdf::new(0.3, 1.55, Rgb::ZERO, 0.3, 0.3, 2.0).eval(wo, wi, TransportMode::Radiance);
        let brown = HairBsdf::new(0.3, 1.55, dark, 0.3, 0.3, 2.0).eval(wo, wi, TransportMode::Radiance);
        assert!(brown.z < brown.x && brown.x < clear.x, "{brown} {clear}");
    }
}
