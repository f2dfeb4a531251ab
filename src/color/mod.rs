//! Linear RGB colour and the sRGB transfer functions.
//!
//! trazo renders in linear RGB with Rec. 709 / sRGB primaries (the same
//! convention as Mitsuba's `rgb` variants); colours in scene files are linear
//! unless they come from an 8-bit image, which is decoded from sRGB.

pub mod space;
pub mod spectrum;
pub mod white_balance;

/// A linear RGB triple. An alias of `glam::Vec3`, so that colour arithmetic
/// is the vector arithmetic that glam already provides.
pub type Rgb = glam::Vec3;

/// Luminance of a linear Rec. 709 colour.
#[inline]
pub fn luminance(c: Rgb) -> f32 {
    0.2126 * c.x + 0.7152 * c.y + 0.0722 * c.z
}

/// How the integer values of an image file map to linear ones.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Encoding {
    /// The sRGB transfer function (IEC 61966-2-1).
    Srgb,
    /// Stored linearly.
    Linear,
    /// A pure power law: linear = stored^γ (pbrt-v4's `"gamma γ"`).
    Gamma(f32),
}

impl Encoding {
    /// The linear value of a stored value in [0, 1].
    #[inline]
    pub fn to_linear(self, v: f32) -> f32 {
        match self {
            Encoding::Srgb => srgb_to_linear(v),
            Encoding::Linear => v,
            Encoding::Gamma(g) => v.max(0.0).powf(g),
        }
    }
}

/// sRGB-encoded value in [0, 1] to linear.
#[inline]
pub fn srgb_to_linear(v: f32) -> f32 {
    if v <= 0.04045 {
        v / 12.92
    } else {
        ((v + 0.055) / 1.055).powf(2.4)
    }
}

/// Linear value to sRGB encoding (input clamped to [0, 1]).
#[inline]
pub fn linear_to_srgb(v: f32) -> f32 {
    let v = v.clamp(0.0, 1.0);
    if v <= 0.003_130_8 {
        12.92 * v
    } else {
        1.055 * v.powf(1.0 / 2.4) - 0.055
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn srgb_round_trip_and_known_values() {
        for i in 0..=255 {
            let v = i as f32 / 255.0;
            assert!((linear_to_srgb(srgb_to_linear(v)) - v).abs() < 1e-5);
        }
        assert!((srgb_to_linear(0.5) - 0.214_041).abs() < 1e-5);
        assert!((linear_to_srgb(2.0) - 1.0).abs() < 1e-6);
        assert!((luminance(Rgb::ONE) - 1.0).abs() < 1e-6);
    }
}
