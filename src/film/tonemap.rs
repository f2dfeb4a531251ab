//! Tone mapping: from linear radiance to displayable [0, 1] values, applied
//! only when writing 8-bit images.

use crate::color::Rgb;
use crate::settings::Tonemap;

impl Tonemap {
    /// Maps a linear colour to [0, 1]³.
    #[inline]
    pub fn apply(&self, c: Rgb) -> Rgb {
        let c = c.max(Rgb::ZERO);
        match self {
            Tonemap::Clamp => c.min(Rgb::ONE),
            Tonemap::Reinhard => {
                let l = crate::color::luminance(c);
                if l <= 0.0 {
                    return Rgb::ZERO;
                }
                (c * (1.0 / (1.0 + l))).min(Rgb::ONE)
            }
            Tonemap::Aces => {
                let (a, b, cc, d, e) = (2.51, 0.03, 2.43, 0.59, 0.14);
                ((c * (a * c + b)) / (c * (cc * c + d) + e)).clamp(Rgb::ZERO, Rgb::ONE)
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn operators_map_into_unit_range_and_keep_black() {
        for t in [Tonemap::Clamp, Tonemap::Reinhard, Tonemap::Aces] {
            assert_eq!(t.apply(Rgb::ZERO), Rgb::ZERO);
            for v in [0.1f32, 1.0, 10.0, 1e6] {
                let c = t.apply(Rgb::new(v, v * 0.5, v * 0.1));
                assert!(c.cmpge(Rgb::ZERO).all() && c.cmple(Rgb::ONE).all(), "{t:?} {c}");
            }
            assert_eq!(Tonemap::from_name(t.name()), Some(t));
        }
        assert_eq!(Tonemap::Clamp.apply(Rgb::splat(0.25)), Rgb::splat(0.25));
        // Reinhard keeps hue: ratios between channels are preserved.
        let c = Tonemap::Reinhard.apply(Rgb::new(0.4, 0.2, 0.1));
        assert!((c.x / c.y - 2.0).abs() < 1e-5);
        assert!(Tonemap::Aces.apply(Rgb::splat(0.5)).x > 0.5);
    }
}
