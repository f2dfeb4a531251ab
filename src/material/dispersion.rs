//! Indices of refraction that vary with wavelength: glass disperses white
//! light into its colours. A path that meets such a glass draws one
//! wavelength (`color::spectrum::sample_visible_wavelength`) and keeps it,
//! as pbrt-v4 terminates a spectral path's secondary wavelengths at a
//! dispersive interface.

use crate::color::spectrum::SigmoidSpectrum;

/// An index of refraction as a function of wavelength.
#[derive(Clone, Debug, PartialEq)]
pub enum IorSpectrum {
    /// Sellmeier's equation n²(λ) = 1 + Σ Bᵢλ²/(λ² − Cᵢ), λ in µm (the form
    /// in which Schott publishes its glasses).
    Sellmeier {
        /// B₁, B₂, B₃.
        b: [f64; 3],
        /// C₁, C₂, C₃, in µm².
        c: [f64; 3],
    },
    /// Samples (wavelength in nm ascending, index), linearly interpolated
    /// and held constant beyond the first and last.
    Sampled(Vec<(f32, f32)>),
    /// `scale` times a smooth spectrum in (0, 1): pbrt-v4's
    /// `RGBUnboundedSpectrum`, which an index given as an RGB colour is.
    Smooth {
        /// The spectrum.
        spectrum: SigmoidSpectrum,
        /// Its factor.
        scale: f32,
    },
}

/// The wavelength of the sodium d line, at which a glass's catalogue index
/// is given.
pub const D_LINE_NM: f32 = 587.56;

impl IorSpectrum {
    /// pbrt-v4's named glass spectra (`"glass-BK7"` …; its F5, F10 and F11
    /// are Schott's SF5, SF10 and SF11), by Schott's Sellmeier
    /// coefficients, which reproduce pbrt-v4's tables (taken from
    /// refractiveindex.info) to 4·10⁻⁵.
    pub fn named_glass(name: &str) -> Option<IorSpectrum> {
        let (b, c) = match name {
            "glass-BK7" => (
                [1.03961212, 0.231792344, 1.01046945],
                [0.00600069867, 0.0200179144, 103.560653],
            ),
            "glass-BAF10" => (
                [1.5851495, 0.143559385, 1.08521269],
                [0.00926681282, 0.0424489805, 105.613573],
            ),
            "glass-FK51A" => (
                [0.971247817, 0.216901417, 0.904651666],
                [0.00472301995, 0.0153575612, 168.68133],
            ),
            "glass-LASF9" => (
                [2.00029547, 0.298926886, 1.80691843],
                [0.0121426017, 0.0538736236, 156.530829],
            ),
            "glass-F5" => (
                [1.52481889, 0.187085527, 1.42729015],
                [0.011254756, 0.0588995392, 129.141675],
            ),
            "glass-F10" => (
                [1.62153902, 0.256287842, 1.64447552],
                [0.0122241457, 0.0595736775, 147.468793],
            ),
            "glass-F11" => (
                [1.73759695, 0.313747346, 1.89878101],
                [0.013188707, 0.0623068142, 155.23629],
            ),
            _ => return None,
        };
        Some(IorSpectrum::Sellmeier { b, c })
    }

    /// The index at `nm` nanometres.
    pub fn at(&self, nm: f32) -> f32 {
        match self {
            IorSpectrum::Sellmeier { b, c } => {
                let l2 = (nm as f64 * 1e-3).powi(2);
                let n2 = 1.0 + (0..3).map(|i| b[i] * l2 / (l2 - c[i])).sum::<f64>();
                n2.max(0.0).sqrt() as f32
            }
            IorSpectrum::Smooth { spectrum, scale } => scale * spectrum.at(nm as f64) as f32,
            IorSpectrum::Sampled(s) => {
                let (first, last) = (s[0], s[s.len() - 1]);
                if nm <= first.0 {
                    return first.1;
                }
                if nm >= last.0 {
                    return last.1;
                }
                let k = s.partition_point(|x| x.0 <= nm).clamp(1, s.len() - 1);
                let ((l0, n0), (l1, n1)) = (s[k - 1], s[k]);
                if l1 > l0 {
                    n0 + (nm - l0) / (l1 - l0) * (n1 - n0)
                } else {
                    n1
                }
            }
        }
    }

    /// The sampled spectrum `samples` (at least two, wavelengths
    /// ascending), or `None` where every index is the same: no dispersion.
    pub fn sampled(samples: &[(f32, f32)]) -> Option<IorSpectrum> {
        let varies = samples.windows(2).any(|w| w[0].1 != w[1].1);
        (samples.len() >= 2 && varies).then(|| IorSpectrum::Sampled(samples.to_vec()))
    }

    /// The index that an RGB colour of positive channels stands for, as
    /// pbrt-v4 reads `"rgb eta"` (its `RGBUnboundedSpectrum`): twice the
    /// largest channel times the smooth spectrum whose colour as a
    /// reflectance is the colour over that ([`SigmoidSpectrum::fit`]), so
    /// that the colour stays the spectrum's own. `None` for grey, the same
    /// index (the channels') at every wavelength, and where no smooth
    /// spectrum has the colour.
    pub fn from_rgb(rgb: [f32; 3]) -> Option<IorSpectrum> {
        if rgb[0] == rgb[1] && rgb[1] == rgb[2] {
            return None;
        }
        let scale = 2.0 * rgb[0].max(rgb[1]).max(rgb[2]);
        let spectrum = SigmoidSpectrum::fit(rgb.map(|c| (c / scale) as f64))?;
        Some(IorSpectrum::Smooth { spectrum, scale })
    }

    /// The smallest and largest index over the visible range (360–830
    /// nm), for checking that every index is physical.
    pub fn visible_range(&self) -> (f32, f32) {
        (0..=470)
            .map(|i| self.at(360.0 + i as f32))
            .fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), n| (lo.min(n), hi.max(n)))
    }
}

/// A dielectric's dispersion: the index inside, which varies, over the
/// constant index outside.
#[derive(Clone, Debug, PartialEq)]
pub struct Dispersion {
    /// The index of the inside.
    pub inside: IorSpectrum,
    /// The index of the outside.
    pub outside: f32,
}

impl Dispersion {
    /// The relative index (inside over outside) at `nm` nanometres.
    #[inline]
    pub fn eta(&self, nm: f32) -> f32 {
        self.inside.at(nm) / self.outside
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Values of pbrt-v4's glass tables (src/pbrt/util/spectrum.cpp).
    #[test]
    fn named_glasses_match_pbrt_v4_tables() {
        for (name, nm, n) in [
            ("glass-BK7", 300.0, 1.5527702635739),
            ("glass-BK7", 586.0, 1.516865556749),
            ("glass-BK7", 916.0, 1.5087426727363),
            ("glass-BAF10", 350.0, 1.7126880848268),
            ("glass-FK51A", 290.0, 1.5145777204082),
            ("glass-LASF9", 583.0, 1.8508658556),
            ("glass-F5", 583.0, 1.6731928929908),
            ("glass-F10", 592.0, 1.7277151818026),
            ("glass-F11", 583.0, 1.7854266026774),
        ] {
            let got = IorSpectrum::named_glass(name).unwrap().at(nm);
            assert!((got - n as f32).abs() < 4e-5, "{name} at {nm}: {got}, pbrt-v4 {n}");
        }
        let bk7 = IorSpectrum::named_glass("glass-BK7").unwrap();
        assert!((bk7.at(D_LINE_NM) - 1.5168).abs() < 1e-4);
        // Normal dispersion: blue bends more than red.
        assert!(bk7.at(450.0) > bk7.at(550.0) && bk7.at(550.0) > bk7.at(650.0));
        assert!(IorSpectrum::named_glass("glass-XYZ").is_none());
    }

    #[test]
    fn sampled_indices_interpolate_and_hold_at_the_ends() {
        let s = IorSpectrum::sampled(&[(400.0, 1.6), (700.0, 1.5)]).unwrap();
        assert_eq!(s.at(300.0), 1.6);
        assert_eq!(s.at(800.0), 1.5);
        assert!((s.at(550.0) - 1.55).abs() < 1e-6);
        assert_eq!(s.visible_range(), (1.5, 1.6));
        assert!(IorSpectrum::sampled(&[(400.0, 1.5), (700.0, 1.5)]).is_none());
    }
}
