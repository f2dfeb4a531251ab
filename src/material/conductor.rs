//! Conductors (metals): a perfect mirror when smooth, a GGX microfacet
//! surface (Walter et al. 2007) sampled by visible normals (Heitz 2018)
//! when rough. The Fresnel term comes from a complex index of refraction
//! η + ik per colour channel, from Schlick's approximation of a colour at
//! normal incidence, or is a constant reflectance (an ideal mirror).
//! Two-sided.

use super::bsdf::{BsdfSample, TransportMode, flip_z, reflect_local, same_hemisphere};
use super::microfacet::Microfacet;
use super::optics::{fresnel_conductor, fresnel_schlick};
use crate::color::Rgb;
use glam::{Vec2, Vec3};

/// How a conductor's reflectance depends on the angle.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ConductorFresnel {
    /// Complex index of refraction per channel, relative to the outside.
    Complex {
        /// Real part η.
        eta: Rgb,
        /// Imaginary part k (absorption).
        k: Rgb,
    },
    /// Schlick's approximation from the reflectance at normal incidence.
    Schlick(Rgb),
    /// The same reflectance at every angle (an ideal mirror).
    Constant(Rgb),
}

impl ConductorFresnel {
    /// Reflectance for incidence cosine `cos`.
    #[inline]
    pub fn eval(&self, cos: f32) -> Rgb {
        match *self {
            ConductorFresnel::Complex { eta, k } => Rgb::new(
                fresnel_conductor(cos, eta.x, k.x),
                fresnel_conductor(cos, eta.y, k.y),
                fresnel_conductor(cos, eta.z, k.z),
            ),
            ConductorFresnel::Schlick(f0) => Rgb::new(
                fresnel_schlick(cos, f0.x),
                fresnel_schlick(cos, f0.y),
                fresnel_schlick(cos, f0.z),
            ),
            ConductorFresnel::Constant(r) => r,
        }
    }
}

/// A smooth or rough conductor.
#[derive(Clone, Copy, Debug)]
pub struct ConductorBsdf {
    /// Reflectance model.
    pub fresnel: ConductorFresnel,
    /// Colour multiplier (Mitsuba's `specular_reflectance`).
    pub tint: Rgb,
    /// Microfacet roughness; smooth below [`super::microfacet::SMOOTH_ALPHA`].
    pub microfacet: Microfacet,
}

impl ConductorBsdf {
    pub(crate) fn eval(&self, wo: Vec3, wi: Vec3, _mode: TransportMode) -> Rgb {
        if self.microfacet.is_smooth() || !same_hemisphere(wo, wi) {
            return Rgb::ZERO;
        }
        let (wo, wi) = if wo.z < 0.0 { (flip_z(wo), flip_z(wi)) } else { (wo, wi) };
        let h = wo + wi;
        if h.length_squared() == 0.0 {
            return Rgb::ZERO;
        }
        let h = h.normalize();
        let d = self.microfacet.d(h);
        let g = self.microfacet.g(wo, wi);
        self.tint * self.fresnel.eval(wo.dot(h)) * (d * g / (4.0 * wo.z * wi.z))
    }

    pub(crate) fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        if self.microfacet.is_smooth() || !same_hemisphere(wo, wi) {
            return 0.0;
        }
        let (wo, wi) = if wo.z < 0.0 { (flip_z(wo), flip_z(wi)) } else { (wo, wi) };
        let h = wo + wi;
        if h.length_squared() == 0.0 {
            return 0.0;
        }
        let h = h.normalize();
        // Reflection maps normals to directions with Jacobian 1/(4 |wo·h|).
        self.microfacet.pdf_visible_normal(wo, h) / (4.0 * wo.dot(h).abs())
    }

    pub(crate) fn sample(&self, wo: Vec3, u_lobe: f32, u: Vec2, mode: TransportMode) -> Option<BsdfSample> {
        if self.microfacet.is_smooth() {
            return self.sample_delta(wo, u_lobe, mode);
        }
        if wo.z == 0.0 {
            return None;
        }
        let flip = wo.z < 0.0;
        let wo_up = if flip { flip_z(wo) } else { wo };
        let h = self.microfacet.sample_visible_normal(wo_up, u);
        let wi_up = 2.0 * wo_up.dot(h) * h - wo_up;
        if wi_up.z <= 0.0 {
            return None;
        }
        let wi = if flip { flip_z(wi_up) } else { wi_up };
        let pdf = self.pdf(wo, wi);
        if pdf <= 0.0 {
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
        if self.microfacet.is_smooth() { 1.0 } else { 0.0 }
    }

    pub(crate) fn sample_delta(&self, wo: Vec3, _u: f32, _mode: TransportMode) -> Option<BsdfSample> {
        if !self.microfacet.is_smooth() || wo.z == 0.0 {
            return None;
        }
        let wi = reflect_local(wo);
        Some(BsdfSample {
            wi,
            f: self.tint * self.fresnel.eval(wo.z.abs()) / wi.z.abs(),
            pdf: 1.0,
            delta: true,
            eta: 1.0,
        })
    }

    pub(crate) fn has_smooth(&self) -> bool {
        !self.microfacet.is_smooth()
    }

    pub(crate) fn albedo(&self) -> Rgb {
        (self.tint * self.fresnel.eval(1.0)).min(Rgb::ONE)
    }
}

/// Complex indices of refraction (η, k) of conductors by name, at the
/// red, green and blue primaries: the spectra of Mitsuba 3's `data/ior`
/// collection (Palik's handbook and others) projected to linear sRGB as
/// Mitsuba's RGB variants do, so that `metal = "Au"` in trazo's format and
/// Mitsuba's `<string name="material">` give Mitsuba's colours. The
/// `_palik` variants Mitsuba also names are listed where their data differ.
pub fn metal_ior(name: &str) -> Option<(Rgb, Rgb)> {
    let name = match name {
        "gold" => "Au",
        "silver" => "Ag",
        "copper" => "Cu",
        "aluminium" | "aluminum" => "Al",
        n => n,
    };
    let find = |name: &str| NAMED_CONDUCTORS.iter().find(|(n, _, _)| *n == name);
    find(name)
        .or_else(|| name.strip_suffix("_palik").and_then(find))
        .map(|&(_, eta, k)| (Rgb::from_array(eta), Rgb::from_array(k)))
}

/// (name, η, k) of [`metal_ior`].
#[rustfmt::skip]
const NAMED_CONDUCTORS: [(&str, [f32; 3], [f32; 3]); 41] = [
    ("Ag", [0.1553, 0.1167, 0.1384], [4.828, 3.122, 2.147]),
    ("Al", [1.658, 0.8804, 0.5212], [9.224, 6.27, 4.837]),
    ("AlAs", [3.605, 3.233, 2.216], [0.0006794, 0.0, 0.007513]),
    ("AlSb", [0.0, 4.139, 4.669], [0.0, 0.09401, 1.301]),
    ("Au", [0.143, 0.3753, 1.442], [3.983, 2.386, 1.603]),
    ("Be", [4.185, 3.185, 2.784], [3.835, 3.01, 2.869]),
    ("Cr", [4.37, 2.917, 1.655], [5.207, 4.231, 3.755]),
    ("CsI", [2.145, 1.702, 1.662], [0.0, 0.0, 0.0]),
    ("Cu", [0.201, 0.9237, 1.102], [3.913, 2.453, 2.142]),
    ("Cu2O", [3.552, 2.95, 2.752], [0.1142, 0.1939, 0.6061]),
    ("CuO", [3.248, 2.448, 2.21], [0.5211, 0.57, 0.7222]),
    ("Cu_palik", [0.2132, 0.9197, 1.102], [3.922, 2.457, 2.137]),
    ("Hg", [2.399, 1.44, 0.9096], [6.328, 4.372, 3.422]),
    ("HgTe", [4.779, 3.231, 2.66], [1.632, 1.581, 1.729]),
    ("Ir", [3.086, 2.082, 1.618], [5.592, 4.067, 3.267]),
    ("K", [0.06404, 0.04641, 0.03818], [2.104, 1.349, 0.9131]),
    ("Li", [0.2658, 0.1956, 0.2209], [3.54, 2.311, 1.669]),
    ("MgO", [2.09, 1.651, 1.595], [4.333e-12, 0.0, 2.499e-11]),
    ("Mo", [4.484, 3.525, 2.776], [4.111, 3.421, 3.151]),
    ("Na_palik", [0.06027, 0.05614, 0.06199], [3.179, 2.112, 1.579]),
    ("Nb", [3.42, 2.79, 2.396], [3.441, 2.738, 2.58]),
    ("Ni_palik", [2.367, 1.663, 1.467], [4.499, 3.05, 2.345]),
    ("Rh", [2.586, 1.86, 1.554], [6.782, 4.703, 3.976]),
    ("Se", [4.058, 2.843, 2.821], [0.754, 0.6384, 0.5218]),
    ("Se-e", [5.723, 4.166, 4.081], [0.8711, 1.105, 1.565]),
    ("SiC", [3.172, 2.526, 2.479], [7.538e-07, 0.0, 1.019e-05]),
    ("SnTe", [4.524, 1.982, 1.282], [0.0, 0.0, 0.0]),
    ("Ta", [2.063, 2.393, 2.628], [2.408, 1.741, 1.947]),
    ("Te", [7.39, 4.482, 2.637], [3.256, 3.527, 3.292]),
    ("Te-e", [7.509, 4.296, 2.37], [5.584, 4.947, 3.998]),
    ("ThF4", [1.831, 1.442, 1.388], [0.0, 0.0, 0.0]),
    ("TiC", [3.701, 2.837, 2.582], [3.266, 2.352, 2.173]),
    ("TiN", [1.648, 1.151, 1.38], [3.368, 1.943, 1.102]),
    ("TiO2", [3.457, 2.802, 2.905], [0.0001053, 0.0, 0.0006529]),
    ("TiO2-e", [3.107, 2.513, 2.582], [2.975e-05, 0.0, 0.0001827]),
    ("VC", [3.658, 2.753, 2.533], [3.068, 2.199, 1.963]),
    ("VN", [2.866, 2.119, 1.94], [3.032, 2.056, 1.616]),
    ("V_palik", [4.278, 3.513, 2.761], [3.491, 2.889, 3.112]),
    ("W", [4.371, 3.3, 2.998], [3.501, 2.605, 2.273]),
    ("a-C", [2.944, 2.227, 1.968], [0.8875, 0.7993, 0.8153]),
    ("d-C", [2.709, 2.319, 2.229], [0.0, 0.0, 0.0]),
];

/// The metals trazo's own format names (`metal = "Au"`); [`metal_ior`]
/// knows more.
pub const METAL_NAMES: [&str; 4] = ["Au", "Ag", "Cu", "Al"];
