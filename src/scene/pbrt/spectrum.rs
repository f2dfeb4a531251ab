//! Spectral quantities of pbrt-v4 reduced to trazo's linear sRGB colours:
//! blackbody emitters and the named spectra that pbrt-v4 ships
//! (`GetNamedSpectrum` in pbrt-v4's spectrum.cpp).

use crate::color::spectrum::{SpectrumUse, piecewise_linear, planck, sampled_to_rgb, spectrum_xyz, xyz_to_linear_srgb};
use crate::color::{Rgb, luminance};

/// Wien's displacement constant in nm·K: a blackbody peaks at this / T.
const WIEN_NM_K: f64 = 2.897_772_1e6;

/// pbrt-v4's `BlackbodySpectrum` of `kelvin` at `nm`: Planck's law divided
/// by its value at the peak wavelength, so at most 1.
fn peak_normalized_planck(nm: f64, kelvin: f64) -> f64 {
    let peak = planck(WIEN_NM_K / kelvin, kelvin);
    if peak > 0.0 { planck(nm, kelvin) / peak } else { 0.0 }
}

/// The linear sRGB an RGB film records of the spectrum `value` seen
/// directly (CIE 1931 observer, the tables of `color::spectrum`), out-of-
/// gamut components clipped to 0.
fn emitted_rgb(value: impl Fn(f64) -> f64) -> Rgb {
    let [r, g, b] = xyz_to_linear_srgb(spectrum_xyz(value, false)).map(|c| c.max(0.0) as f32);
    Rgb::new(r, g, b)
}

/// `c` scaled to luminance 1, or black if it has none.
fn unit_luminance(c: Rgb) -> Option<Rgb> {
    let lum = luminance(c);
    (lum > 0.0 && lum.is_finite()).then(|| c / lum)
}

/// Linear sRGB colour of a blackbody at `kelvin`, scaled to luminance 1.
///
/// pbrt-v4 divides an emitter's spectrum by its luminance
/// (`SpectrumToPhotometric`), so a `blackbody` light of any temperature has
/// luminance equal to its `scale`; this reproduces that, as pbrt-v4's RGB
/// film with its default CIE 1931 sensor records it: Planck's law
/// integrated over 360–830 nm against the CIE 1931 colour-matching
/// functions, then XYZ to linear sRGB. Components outside the sRGB gamut
/// (very low temperatures) are clipped to 0 before normalising.
pub fn blackbody_rgb(kelvin: f32) -> Rgb {
    let t = kelvin as f64;
    // Below about 400 K nothing visible is emitted; a dim red is the
    // honest limit of the hue.
    unit_luminance(emitted_rgb(|l| peak_normalized_planck(l, t))).unwrap_or(Rgb::new(1.0 / 0.2126, 0.0, 0.0))
}

/// Linear sRGB colour of pbrt-v4's `BlackbodySpectrum` of `kelvin` (see
/// [`peak_normalized_planck`]) as an emitted spectrum: its luminance is
/// ∫B̂ȳ/∫ȳ, as an RGB film records it (not normalised to luminance 1 as
/// emitters' `blackbody` is).
pub fn peak_normalized_blackbody_rgb(kelvin: f32) -> Rgb {
    let t = kelvin as f64;
    emitted_rgb(|l| peak_normalized_planck(l, t))
}

/// pbrt-v4's `BlackbodySpectrum` of `kelvin` used as a reflectance (see
/// [`factor_rgb`]).
pub fn blackbody_reflectance_rgb(kelvin: f32) -> Rgb {
    let t = kelvin as f64;
    factor_rgb(|l| peak_normalized_planck(l, t), true).0
}

/// The colour of a spectrum that multiplies light (a reflectance where
/// `bounded`, else a scattering coefficient or a texture's factor): the
/// colour it gives sRGB's white (D65) as an RGB film records it, divided
/// channel by channel by that of a flat spectrum of 1, so that a flat
/// spectrum keeps its value exactly, as it does at every wavelength of
/// pbrt-v4's spectral rendering. Also says whether a channel was clipped
/// to [0, 1] (reflectances) or to 0 (out of gamut).
pub fn factor_rgb(value: impl Fn(f64) -> f64, bounded: bool) -> (Rgb, bool) {
    let white = xyz_to_linear_srgb(spectrum_xyz(|_| 1.0, true));
    let rgb = xyz_to_linear_srgb(spectrum_xyz(value, true));
    let high = if bounded { 1.0 } else { f64::INFINITY };
    let c: [f64; 3] = std::array::from_fn(|i| rgb[i] / white[i]);
    // Rounding of a flat spectrum's own ratio is not clipping.
    let clipped = c.iter().any(|&x| x < -1e-9 || x > high + 1e-9);
    let [r, g, b] = c.map(|x| x.clamp(0.0, high) as f32);
    (Rgb::new(r, g, b), clipped)
}

/// [`factor_rgb`] of a sampled spectrum (wavelengths ascending, at least
/// two; linearly interpolated, zero outside them).
pub fn sampled_factor_rgb(samples: &[(f32, f32)], bounded: bool) -> (Rgb, bool) {
    factor_rgb(|l| piecewise_linear(samples, l), bounded)
}

/// Linear sRGB colour of a sampled emission spectrum (pairs of wavelength
/// in nm and value, linearly interpolated and zero outside, as pbrt-v4's
/// `PiecewiseLinearSpectrum`), scaled to luminance 1 as pbrt-v4 scales
/// emitters; black if nothing visible is emitted.
pub fn sampled_rgb(samples: &[(f32, f32)]) -> Rgb {
    if samples.len() < 2 {
        return Rgb::ZERO;
    }
    unit_luminance(sampled_to_rgb(samples, SpectrumUse::Emission).0).unwrap_or(Rgb::ZERO)
}

/// η and k at trazo's three wavelengths (650, 550 and 450 nm, see
/// [`spectrum_at_rgb_wavelengths`]) of pbrt-v4's named spectra of brass,
/// magnesium oxide and titanium dioxide (`metal-CuZn-eta` …), which
/// pbrt-v4 tabulates from refractiveindex.info (CC0), interpolated
/// linearly there. Its other metals (Au, Ag, Cu, Al) are in
/// [`crate::material::conductor::metal_ior`].
pub fn pbrt_only_metal_ior(name: &str) -> Option<(Rgb, Rgb)> {
    let (eta, k) = match name {
        "CuZn" => ([0.444, 0.527, 1.094], [3.695, 2.765, 1.829]),
        "MgO" => ([1.7337, 1.7405, 1.7524], [0.0; 3]),
        "TiO2" => ([2.8599, 2.955, 3.165], [0.0; 3]),
        _ => return None,
    };
    Some((Rgb::from_array(eta), Rgb::from_array(k)))
}

/// The metal of a named pbrt-v4 conductor spectrum: `"metal-Au-eta"` →
/// (`"Au"`, true), `"metal-Cu-k"` → (`"Cu"`, false).
pub fn metal_of(name: &str) -> Option<(&str, bool)> {
    let rest = name.strip_prefix("metal-")?;
    if let Some(m) = rest.strip_suffix("-eta") {
        Some((m, true))
    } else {
        rest.strip_suffix("-k").map(|m| (m, false))
    }
}

/// The colour of a named illuminant spectrum used as an emitter's
/// spectrum, normalised to luminance 1 as pbrt-v4 normalises emitters.
/// D65 is sRGB's white; illuminant A is a 2856 K blackbody; D50 is CIE
/// daylight of 5000 K (nominal; 5003 K on today's temperature scale), whose
/// chromaticity the CIE daylight locus gives. Returns `None` for names that
/// are not illuminants, and `(colour, exact)` otherwise.
pub fn illuminant_rgb(name: &str) -> Option<(Rgb, bool)> {
    use crate::color::white_balance::{illuminant_xy, rgb_of_chromaticity};
    match name {
        "stdillum-D65" => Some((Rgb::ONE, true)),
        "stdillum-A" => Some((blackbody_rgb(2856.0), true)),
        "stdillum-D50" => Some((rgb_of_chromaticity(illuminant_xy(5000.0)), true)),
        // pbrt-v4 normalises a light's spectrum to luminance 1, and its RGB
        // film records a spectrum's XYZ, which for the CIE 1931 observer
        // its chromaticity at Y = 1 gives: the F series' published
        // chromaticities (CIE 15:2004) and the ACES white.
        n => {
            let xy = match n {
                "stdillum-F1" => (0.3131, 0.3373),
                "stdillum-F2" => (0.3721, 0.3751),
                "stdillum-F3" => (0.4091, 0.3941),
                "stdillum-F4" => (0.4402, 0.4031),
                "stdillum-F5" => (0.3138, 0.3452),
                "stdillum-F6" => (0.3779, 0.3882),
                "stdillum-F7" => (0.3129, 0.3292),
                "stdillum-F8" => (0.3458, 0.3586),
                "stdillum-F9" => (0.3741, 0.3727),
                "stdillum-F10" => (0.3458, 0.3588),
                "stdillum-F11" => (0.3805, 0.3769),
                "stdillum-F12" => (0.4370, 0.4042),
                "illum-acesD60" => (0.32168, 0.33767),
                _ if n.starts_with("stdillum-") || n.starts_with("illum-") => return Some((Rgb::ONE, false)),
                _ => return None,
            };
            Some((rgb_of_chromaticity(xy), true))
        }
    }
}

/// The wavelengths (nm) at which trazo's metals are tabulated
/// ([`crate::material::conductor::metal_ior`]): red, green, blue.
pub const RGB_WAVELENGTHS_NM: [f32; 3] = [650.0, 550.0, 450.0];

/// A sampled spectrum (wavelengths increasing) at `nm`, interpolated
/// linearly and held constant beyond its ends.
pub fn sample_spectrum(pairs: &[(f32, f32)], nm: f32) -> f32 {
    match pairs.iter().position(|&(l, _)| l >= nm) {
        None => pairs.last().map_or(0.0, |p| p.1),
        Some(0) => pairs[0].1,
        Some(i) => {
            let ((l0, v0), (l1, v1)) = (pairs[i - 1], pairs[i]);
            v0 + (v1 - v0) * (nm - l0) / (l1 - l0)
        }
    }
}

/// A sampled spectrum's value at each of [`RGB_WAVELENGTHS_NM`], as trazo's
/// metals are tabulated.
pub fn spectrum_at_rgb_wavelengths(pairs: &[(f32, f32)]) -> Rgb {
    let [r, g, b] = RGB_WAVELENGTHS_NM.map(|nm| sample_spectrum(pairs, nm));
    Rgb::new(r, g, b)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::color::spectrum::parse_spd;

    #[test]
    fn spd_files_are_pairs_sampled_linearly() {
        let s = parse_spd("# gold\n400 1.0\n500 3.0 # comment\n600 2.0\n").unwrap();
        assert_eq!(s, vec![(400.0, 1.0), (500.0, 3.0), (600.0, 2.0)]);
        assert_eq!(sample_spectrum(&s, 450.0), 2.0);
        assert_eq!(sample_spectrum(&s, 300.0), 1.0);
        assert_eq!(sample_spectrum(&s, 700.0), 2.0);
        assert_eq!(spectrum_at_rgb_wavelengths(&s), Rgb::new(2.0, 2.5, 2.0));
    }

    #[test]
    fn blackbody_colours_follow_temperature() {
        for t in [1500.0, 2700.0, 4000.0, 6500.0, 10000.0] {
            let c = blackbody_rgb(t);
            assert!((luminance(c) - 1.0).abs() < 1e-4, "{t}: {c}");
            assert!(c.min_element() >= 0.0);
        }
        // Incandescent light is orange: red > green > blue.
        let warm = blackbody_rgb(2700.0);
        assert!(warm.x > warm.y && warm.y > warm.z, "{warm}");
        // 6500 K is close to sRGB's white point (D65).
        let white = blackbody_rgb(6500.0);
        assert!((white - Rgb::ONE).abs().max_element() < 0.12, "{white}");
        // Hot stars are blue.
        let hot = blackbody_rgb(15000.0);
        assert!(hot.z > hot.x, "{hot}");
        // Deep red at very low temperatures, never NaN.
        let cold = blackbody_rgb(300.0);
        assert!(cold.is_finite() && cold.x > 0.0);
    }

    #[test]
    fn sampled_spectra_become_colours() {
        // A flat emitted spectrum is (nearly) white: its white point is E,
        // not D65.
        let flat = sampled_rgb(&[(300.0, 2.0), (900.0, 2.0)]);
        assert!((luminance(flat) - 1.0).abs() < 1e-4);
        assert!(flat.max_element() / flat.min_element() < 1.4, "{flat}");
        // Long wavelengths only: red.
        let red = sampled_rgb(&[(600.0, 1.0), (700.0, 1.0)]);
        assert!(red.x > 2.0 * red.y && red.x > 2.0 * red.z, "{red}");
        assert_eq!(sampled_rgb(&[(100.0, 1.0), (200.0, 1.0)]), Rgb::ZERO);
    }

    #[test]
    fn named_spectra() {
        assert_eq!(metal_of("metal-Au-eta"), Some(("Au", true)));
        assert_eq!(metal_of("metal-CuZn-k"), Some(("CuZn", false)));
        assert_eq!(metal_of("glass-BK7"), None);
        assert_eq!(illuminant_rgb("stdillum-D65"), Some((Rgb::ONE, true)));
        // D50's published chromaticity (CIE 15:2004), (0.34567, 0.35850),
        // in linear sRGB at luminance 1.
        let (d50, exact) = illuminant_rgb("stdillum-D50").unwrap();
        let want = crate::color::white_balance::rgb_of_chromaticity((0.34567, 0.35850));
        assert!(exact && (d50 - want).abs().max_element() < 2e-3, "{d50} vs {want}");
        assert!((luminance(d50) - 1.0).abs() < 1e-3);
        assert!(illuminant_rgb("metal-Au-k").is_none());
        // The fluorescent F2 (cool white, 4230 K) is warmer than D65;
        // F7 (D65 simulator) nearly white; the ACES white is the colour
        // space's, at luminance 1.
        let (f2, exact) = illuminant_rgb("stdillum-F2").unwrap();
        assert!(
            exact && f2.x > f2.y && f2.y > f2.z && (luminance(f2) - 1.0).abs() < 1e-3,
            "{f2}"
        );
        let (f7, _) = illuminant_rgb("stdillum-F7").unwrap();
        assert!((f7 - Rgb::ONE).abs().max_element() < 0.01, "{f7}");
        let aces = crate::color::space::ColorSpace::Aces2065_1.to_srgb(true) * Rgb::ONE;
        let (d60, exact) = illuminant_rgb("illum-acesD60").unwrap();
        assert!(exact && (d60 - aces).abs().max_element() < 1e-5, "{d60} vs {aces}");
        assert_eq!(illuminant_rgb("stdillum-F13"), Some((Rgb::ONE, false)));
    }
}
