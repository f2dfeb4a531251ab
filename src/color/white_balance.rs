//! White balance, as pbrt-v4's RGB film applies its `whitebalance`
//! (`PixelSensor`, `WhiteBalance` in pbrt-v4's film.cpp and color.cpp): the
//! image is taken to have been lit by an illuminant of colour temperature
//! T, and its colours are adapted so that that illuminant's white becomes
//! the output space's (sRGB's D65, `color::space`), by von Kries scaling in the Bradford cone
//! space (Lam 1985):
//!
//! ```text
//! M = RGB←XYZ · B⁻¹ · diag(B·W_D65 / B·W_T) · B · XYZ←RGB
//! ```
//!
//! with B the Bradford matrix and W the whites' XYZ at Y = 1. The white of
//! T is pbrt-v4's: the CIE daylight illuminant D of correlated colour
//! temperature T·1.4388/1.4380 (the locus of CIE 15:2004, eq. 3.3–3.4), and
//! below 4000 K, where D is not defined, a blackbody of that temperature.

use crate::color::space::{ColorSpace, adapt, xyz_of};
use glam::{DMat3, DVec3, Mat3};

/// The range of temperatures, in kelvin, that white balance accepts.
pub const WHITE_BALANCE_RANGE: std::ops::RangeInclusive<f32> = 1000.0..=25000.0;

/// The chromaticity of the illuminant pbrt-v4 takes for `kelvin`.
pub fn illuminant_xy(kelvin: f64) -> (f64, f64) {
    let cct = kelvin * 1.4388 / 1.4380;
    if cct < 4000.0 {
        return crate::color::spectrum::blackbody_xy(cct);
    }
    let x = if cct <= 7000.0 {
        -4.6070e9 / cct.powi(3) + 2.9678e6 / (cct * cct) + 0.09911e3 / cct + 0.244063
    } else {
        -2.0064e9 / cct.powi(3) + 1.9018e6 / (cct * cct) + 0.24748e3 / cct + 0.237040
    };
    (x, -3.0 * x * x + 2.870 * x - 0.275)
}

/// Linear sRGB of the colour of chromaticity (x, y) at luminance Y = 1.
pub fn rgb_of_chromaticity(xy: (f64, f64)) -> glam::Vec3 {
    (xyz_from_rgb().inverse() * xyz_of(xy)).as_vec3()
}

fn xyz_from_rgb() -> DMat3 {
    ColorSpace::Srgb.xyz_from_rgb()
}

/// The matrix taking linear sRGB rendered under an illuminant of `kelvin`
/// to linear sRGB balanced for D65; `None` for 0 (no white balance).
pub fn white_balance(kelvin: f32) -> Option<Mat3> {
    output_transform(ColorSpace::Srgb, kelvin)
}

/// The matrix taking the film's linear sRGB to the linear RGB of the
/// image it writes in `space`, balanced for `kelvin` (0: not), as pbrt-v4's
/// `outputRGBFromSensorRGB` for the CIE 1931 sensor: the white of `kelvin`
/// becomes the output space's white. `None` for the identity.
pub fn output_transform(space: ColorSpace, kelvin: f32) -> Option<Mat3> {
    if kelvin == 0.0 {
        return space.from_srgb();
    }
    let to_xyz = adapt(xyz_of(illuminant_xy(kelvin as f64)), space.xyz_from_rgb() * DVec3::ONE) * xyz_from_rgb();
    Some((space.xyz_from_rgb().inverse() * to_xyz).as_mat3())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The white of T becomes the output space's white: its sRGB,
    /// balanced, is RGB (1, 1, 1) of that space.
    #[test]
    fn the_illuminants_white_becomes_the_outputs_white() {
        for space in ColorSpace::PBRT_NAMES
            .iter()
            .map(|n| ColorSpace::from_pbrt_name(n).unwrap())
        {
            for kelvin in [1500.0f32, 2856.0, 3500.0, 4000.0, 5003.0, 6504.0, 9000.0, 20000.0] {
                let m = output_transform(space, kelvin).unwrap();
                let white = rgb_of_chromaticity(illuminant_xy(kelvin as f64));
                let out = m * white;
                assert!(
                    (out - glam::Vec3::ONE).abs().max_element() < 1e-5,
                    "{space:?}, {kelvin} K: {out}"
                );
            }
        }
    }

    /// D65 is daylight at 6504 K (CIE 15): balancing for it changes
    /// little; a warm illuminant makes greys blue, a cool one yellow.
    #[test]
    fn warm_and_cool_illuminants_turn_greys_the_other_way() {
        let (x, y) = illuminant_xy(6504.0);
        assert!((x - 0.3127).abs() < 5e-4 && (y - 0.3290).abs() < 5e-4, "{x} {y}");
        let near = white_balance(6504.0).unwrap();
        assert!((near * glam::Vec3::ONE - glam::Vec3::ONE).abs().max_element() < 5e-3);
        let warm = white_balance(3000.0).unwrap() * glam::Vec3::ONE;
        assert!(warm.z > 1.5 * warm.x, "{warm}");
        let cool = white_balance(12000.0).unwrap() * glam::Vec3::ONE;
        assert!(cool.x > cool.z, "{cool}");
        // Illuminant A (2856 K) is a blackbody: its published chromaticity.
        let (ax, ay) = illuminant_xy(2856.0 * 1.4380 / 1.4388);
        assert!((ax - 0.44757).abs() < 1e-3 && (ay - 0.40745).abs() < 1e-3, "{ax} {ay}");
        assert!(white_balance(0.0).is_none());
    }
}
