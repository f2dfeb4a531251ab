//! RGB colour spaces other than trazo's own (linear sRGB), as pbrt-v4 names
//! them (`RGBColorSpace::GetNamed`): the colours a scene file gives in one
//! are converted to linear sRGB where they are read, and a film may write
//! its image in one.
//!
//! A space is its primaries and white point as CIE 1931 chromaticities;
//! its matrix to XYZ follows from them (SMPTE RP 177-1993): the primaries'
//! XYZ at Y = 1 as columns, each scaled so that RGB (1, 1, 1) is the white
//! at Y = 1.
//!
//! pbrt-v4 turns an RGB reflectance into a smooth spectrum whose colour
//! under the space's illuminant is that RGB (Jakob and Hanika 2019), and an
//! emitted RGB into that spectrum times the illuminant. Seen by trazo's
//! D65-white renderer, the emitted colour is therefore the XYZ of the RGB
//! in its space, converted to sRGB as it is; a reflectance keeps white
//! white, which a von Kries adaptation of the space's white to D65 in the
//! Bradford cone space (Lam 1985) does. For the spaces with a D65 white
//! (Rec. 2020, DCI-P3) the two agree.

use glam::{DMat3, DVec3, Mat3};

/// The colour spaces of pbrt-v4's `ColorSpace` directive.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum ColorSpace {
    /// Rec. 709 primaries, D65 white: trazo's own.
    #[default]
    Srgb,
    /// ITU-R BT.2020 primaries, D65 white.
    Rec2020,
    /// DCI-P3 primaries with a D65 white (as pbrt-v4's `dci-p3`).
    DciP3,
    /// ACES2065-1: the AP0 primaries, the ACES white (≈ D60).
    Aces2065_1,
}

/// D65's chromaticity (CIE 15:2004).
pub(crate) const D65_XY: (f64, f64) = (0.3127, 0.3290);

impl ColorSpace {
    /// The space pbrt-v4 calls `name`, or `None`.
    pub fn from_pbrt_name(name: &str) -> Option<ColorSpace> {
        match name {
            "srgb" => Some(ColorSpace::Srgb),
            "rec2020" => Some(ColorSpace::Rec2020),
            "dci-p3" => Some(ColorSpace::DciP3),
            "aces2065-1" => Some(ColorSpace::Aces2065_1),
            _ => None,
        }
    }

    /// pbrt-v4's name of the space.
    pub fn pbrt_name(self) -> &'static str {
        match self {
            ColorSpace::Srgb => "srgb",
            ColorSpace::Rec2020 => "rec2020",
            ColorSpace::DciP3 => "dci-p3",
            ColorSpace::Aces2065_1 => "aces2065-1",
        }
    }

    /// The names pbrt-v4 knows, for error messages.
    pub const PBRT_NAMES: &'static [&'static str] = &["srgb", "rec2020", "dci-p3", "aces2065-1"];

    /// Chromaticities of the red, green and blue primaries and the white.
    fn chromaticities(self) -> [(f64, f64); 4] {
        match self {
            ColorSpace::Srgb => [(0.64, 0.33), (0.30, 0.60), (0.15, 0.06), D65_XY],
            ColorSpace::Rec2020 => [(0.708, 0.292), (0.170, 0.797), (0.131, 0.046), D65_XY],
            ColorSpace::DciP3 => [(0.68, 0.32), (0.265, 0.690), (0.15, 0.06), D65_XY],
            ColorSpace::Aces2065_1 => [(0.7347, 0.2653), (0.0, 1.0), (0.0001, -0.0770), (0.32168, 0.33767)],
        }
    }

    /// The chromaticities of the red, green and blue primaries and the
    /// white, as an OpenEXR file's `chromaticities` attribute holds them.
    pub fn primaries_and_white(self) -> [(f32, f32); 4] {
        self.chromaticities().map(|(x, y)| (x as f32, y as f32))
    }

    /// The space whose primaries and white are `c` (red, green, blue,
    /// white), each coordinate within a relative 10⁻³ as pbrt-v4's
    /// `RGBColorSpace::Lookup` matches them; `None` for another space.
    pub fn from_primaries_and_white(c: [(f32, f32); 4]) -> Option<ColorSpace> {
        let close = |a: f32, b: f64| a as f64 == b || ((a as f64 - b) / b).abs() < 1e-3;
        [
            ColorSpace::Aces2065_1,
            ColorSpace::DciP3,
            ColorSpace::Rec2020,
            ColorSpace::Srgb,
        ]
        .into_iter()
        .find(|s| {
            s.chromaticities()
                .iter()
                .zip(c)
                .all(|(&(x, y), (cx, cy))| close(cx, x) && close(cy, y))
        })
    }

    /// The XYZ of the space's white at Y = 1.
    fn white_xyz(self) -> DVec3 {
        xyz_of(self.chromaticities()[3])
    }

    /// XYZ from the space's linear RGB.
    pub(crate) fn xyz_from_rgb(self) -> DMat3 {
        let [r, g, b, _] = self.chromaticities();
        let primaries = DMat3::from_cols(xyz_of(r), xyz_of(g), xyz_of(b));
        let scale = primaries.inverse() * self.white_xyz();
        primaries * DMat3::from_diagonal(scale)
    }

    /// Linear sRGB of a colour given in this space: emitted light
    /// (`emitted`: its XYZ kept) or a reflectance or other factor (its
    /// white made sRGB's white). The identity for sRGB itself.
    pub fn to_srgb(self, emitted: bool) -> Mat3 {
        if self == ColorSpace::Srgb {
            return Mat3::IDENTITY;
        }
        let srgb = ColorSpace::Srgb;
        let to_xyz = if emitted {
            self.xyz_from_rgb()
        } else {
            adapt(self.white_xyz(), srgb.white_xyz()) * self.xyz_from_rgb()
        };
        (srgb.xyz_from_rgb().inverse() * to_xyz).as_mat3()
    }

    /// What a film writing in this space outputs for linear sRGB, its XYZ
    /// kept (pbrt-v4's `outputRGBFromSensorRGB` for the CIE 1931 sensor):
    /// `None` for sRGB itself.
    pub fn from_srgb(self) -> Option<Mat3> {
        (self != ColorSpace::Srgb).then(|| (self.xyz_from_rgb().inverse() * ColorSpace::Srgb.xyz_from_rgb()).as_mat3())
    }
}

/// The XYZ of chromaticity (x, y) at Y = 1.
pub(crate) fn xyz_of((x, y): (f64, f64)) -> DVec3 {
    DVec3::new(x / y, 1.0, (1.0 - x - y) / y)
}

/// The von Kries adaptation in the Bradford cone space (Lam 1985) that
/// takes the white `from` (XYZ) to the white `to`.
pub(crate) fn adapt(from: DVec3, to: DVec3) -> DMat3 {
    // The Bradford cone response matrix (rows L, M, S).
    let b = DMat3::from_cols_array(&[
        0.8951, -0.7502, 0.0389, //
        0.2664, 1.7135, -0.0685, //
        -0.1614, 0.0367, 1.0296,
    ]);
    b.inverse() * DMat3::from_diagonal((b * to) / (b * from)) * b
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: glam::Vec3, b: glam::Vec3, tol: f32) -> bool {
        (a - b).abs().max_element() <= tol
    }

    #[test]
    fn spaces_are_found_by_their_chromaticities() {
        for s in [
            ColorSpace::Srgb,
            ColorSpace::Rec2020,
            ColorSpace::DciP3,
            ColorSpace::Aces2065_1,
        ] {
            assert_eq!(ColorSpace::from_primaries_and_white(s.primaries_and_white()), Some(s));
            // Within pbrt-v4's tolerance, and not beyond it.
            let mut near = s.primaries_and_white();
            near[0].0 *= 1.0005;
            assert_eq!(ColorSpace::from_primaries_and_white(near), Some(s));
            near[0].0 *= 1.002;
            assert_eq!(ColorSpace::from_primaries_and_white(near), None);
        }
        // Adobe RGB (1998) is none of them.
        let adobe = [(0.64, 0.33), (0.21, 0.71), (0.15, 0.06), (0.3127, 0.329)];
        assert_eq!(ColorSpace::from_primaries_and_white(adobe), None);
    }

    /// The matrices derived from the chromaticities are the published
    /// ones: sRGB's of IEC 61966-2-1, Rec. 2020's of ITU-R BT.2087 (to
    /// and from Rec. 709) and ACES2065-1's of SMPTE ST 2065-1.
    #[test]
    fn matrices_are_the_published_ones() {
        let srgb = ColorSpace::Srgb.xyz_from_rgb().as_mat3();
        assert!(close(srgb.row(0), glam::Vec3::new(0.4124, 0.3576, 0.1805), 1e-4));
        assert!(close(srgb.row(1), glam::Vec3::new(0.2126, 0.7152, 0.0722), 1e-4));
        assert!(close(srgb.row(2), glam::Vec3::new(0.0193, 0.1192, 0.9505), 1e-4));
        let to_2020 = ColorSpace::Rec2020.from_srgb().unwrap();
        assert!(close(to_2020.row(0), glam::Vec3::new(0.6274, 0.3293, 0.0433), 2e-4));
        assert!(close(to_2020.row(1), glam::Vec3::new(0.0691, 0.9195, 0.0114), 2e-4));
        assert!(close(to_2020.row(2), glam::Vec3::new(0.0164, 0.0880, 0.8956), 2e-4));
        let aces = ColorSpace::Aces2065_1.xyz_from_rgb();
        let published = [
            DVec3::new(0.9525523959, 0.0, 0.0000936786),
            DVec3::new(0.3439664498, 0.7281660966, -0.0721325464),
            DVec3::new(0.0, 0.0, 1.0088251844),
        ];
        for (i, row) in published.into_iter().enumerate() {
            assert!((aces.row(i) - row).abs().max_element() < 1e-6, "{}", aces.row(i));
        }
    }

    /// Reflectances keep white white in every space; emitted white is the
    /// space's white (ACES's a little warmer than D65), at luminance 1;
    /// from sRGB and back is the identity.
    #[test]
    fn whites_and_round_trips() {
        for name in ColorSpace::PBRT_NAMES {
            let cs = ColorSpace::from_pbrt_name(name).unwrap();
            assert_eq!(cs.pbrt_name(), *name);
            let white = cs.to_srgb(false) * glam::Vec3::ONE;
            assert!(close(white, glam::Vec3::ONE, 1e-5), "{name}: {white}");
            let emitted = cs.to_srgb(true) * glam::Vec3::ONE;
            assert!(
                (crate::color::luminance(emitted) - 1.0).abs() < 1e-3,
                "{name}: {emitted}"
            );
            if let Some(out) = cs.from_srgb() {
                let back = out * (cs.to_srgb(true) * glam::Vec3::new(0.2, 0.5, 0.9));
                assert!(close(back, glam::Vec3::new(0.2, 0.5, 0.9), 1e-5), "{name}: {back}");
            }
        }
        let aces_white = ColorSpace::Aces2065_1.to_srgb(true) * glam::Vec3::ONE;
        assert!(aces_white.x > 1.0 && aces_white.z < 0.95, "{aces_white}");
        assert!(ColorSpace::from_pbrt_name("p3").is_none());
        assert_eq!(ColorSpace::Srgb.to_srgb(true), Mat3::IDENTITY);
    }
}
