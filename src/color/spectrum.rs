//! Sampled spectra as RGB, as Mitsuba 3's RGB variants convert them
//! (its `spectrum_list_to_srgb`): the spectrum, linearly interpolated
//! between its samples and zero outside them, integrated against the CIE
//! 1931 2° colour-matching functions (times the D65 illuminant for
//! reflectances, so that a flat spectrum is grey) by 1000 evenly spaced
//! samples over 360–830 nm, scaled by 1 / ∫ȳ, then taken from XYZ to linear
//! sRGB.

use super::Rgb;

/// First and last wavelength of the tables, in nm.
const LAMBDA_MIN: f64 = 360.0;
const LAMBDA_MAX: f64 = 830.0;
/// Samples of the integration.
const STEPS: usize = 1000;
/// 1 / ∫ȳ(λ) dλ over the tables (CIE 1931, 1 nm), which makes Y the
/// spectrum's luminance.
const CIE_Y_NORMALIZATION: f64 = 1.0 / 106.7502593;

/// Every 5 nm from 360 to 830 nm: x̄, ȳ, z̄ (CIE 1931 2° standard observer)
/// and the D65 illuminant's relative power (1 near 560 nm).
const CIE_5NM: [[f64; 4]; 95] = [
    [1.298999996e-04, 3.916999958e-06, 6.061000167e-04, 4.711062610e-01], // 360 nm
    [2.321000065e-04, 6.965000011e-06, 1.086000004e-03, 4.986362457e-01], // 365 nm
    [4.148999869e-04, 1.238999994e-05, 1.946000033e-03, 5.261662602e-01], // 370 nm
    [7.416000008e-04, 2.201999996e-05, 3.486000001e-03, 5.154912472e-01], // 375 nm
    [1.368000056e-03, 3.899999865e-05, 6.450001150e-03, 5.048161745e-01], // 380 nm
    [2.236000029e-03, 6.399999984e-05, 1.054999046e-02, 5.284157991e-01], // 385 nm
    [4.242999945e-03, 1.199999970e-04, 2.005000971e-02, 5.520164371e-01], // 390 nm
    [7.650000043e-03, 2.169999934e-04, 3.621000051e-02, 6.939726472e-01], // 395 nm
    [1.431000046e-02, 3.959999885e-04, 6.785000861e-02, 8.359298706e-01], // 400 nm
    [2.318999916e-02, 6.399999838e-04, 1.102000028e-01, 8.800269961e-01], // 405 nm
    [4.351000115e-02, 1.210000017e-03, 2.073999941e-01, 9.241251349e-01], // 410 nm
    [7.762999833e-02, 2.180000069e-03, 3.713000119e-01, 9.339526296e-01], // 415 nm
    [1.343799978e-01, 4.000000190e-03, 6.456000209e-01, 9.437801838e-01], // 420 nm
    [2.147700042e-01, 7.300000172e-03, 1.039050102e+00, 9.096903801e-01], // 425 nm
    [2.838999927e-01, 1.159999985e-02, 1.385599971e+00, 8.756015897e-01], // 430 nm
    [3.285000026e-01, 1.683999971e-02, 1.622959971e+00, 9.674353004e-01], // 435 nm
    [3.482800126e-01, 2.300000004e-02, 1.747059941e+00, 1.059270024e+00], // 440 nm
    [3.480600119e-01, 2.979999967e-02, 1.782600045e+00, 1.120594859e+00], // 445 nm
    [3.361999989e-01, 3.799999878e-02, 1.772109985e+00, 1.181929827e+00], // 450 nm
    [3.186999857e-01, 4.800000042e-02, 1.744099975e+00, 1.185990572e+00], // 455 nm
    [2.908000052e-01, 5.999999866e-02, 1.669199944e+00, 1.190051198e+00], // 460 nm
    [2.511000037e-01, 7.389999926e-02, 1.528100014e+00, 1.175141811e+00], // 465 nm
    [1.953600049e-01, 9.098000079e-02, 1.287639976e+00, 1.160242438e+00], // 470 nm
    [1.421000063e-01, 1.125999987e-01, 1.041900039e+00, 1.165606141e+00], // 475 nm
    [9.564000368e-02, 1.390199959e-01, 8.129500747e-01, 1.170969963e+00], // 480 nm
    [5.795000866e-02, 1.693000048e-01, 6.161999702e-01, 1.135049820e+00], // 485 nm
    [3.201000020e-02, 2.080200016e-01, 4.651800096e-01, 1.099129677e+00], // 490 nm
    [1.470000017e-02, 2.585999966e-01, 3.533000052e-01, 1.101867199e+00], // 495 nm
    [4.900000058e-03, 3.230000138e-01, 2.720000148e-01, 1.104614615e+00], // 500 nm
    [2.400000114e-03, 4.072999954e-01, 2.123000026e-01, 1.096776128e+00], // 505 nm
    [9.300000034e-03, 5.030000210e-01, 1.581999958e-01, 1.088937521e+00], // 510 nm
    [2.910000086e-02, 6.082000136e-01, 1.116999984e-01, 1.073724985e+00], // 515 nm
    [6.327000260e-02, 7.099999785e-01, 7.824999094e-02, 1.058512449e+00], // 520 nm
    [1.096000001e-01, 7.932000160e-01, 5.725001171e-02, 1.073149204e+00], // 525 nm
    [1.655000001e-01, 8.619999886e-01, 4.216000065e-02, 1.087796092e+00], // 530 nm
    [2.257498950e-01, 9.148501158e-01, 2.983999997e-02, 1.071209788e+00], // 535 nm
    [2.903999984e-01, 9.539999962e-01, 2.030000091e-02, 1.054623485e+00], // 540 nm
    [3.596999943e-01, 9.803000093e-01, 1.339999959e-02, 1.052805185e+00], // 545 nm
    [4.334498942e-01, 9.949501157e-01, 8.749999106e-03, 1.050997138e+00], // 550 nm
    [5.120500922e-01, 1.000000000e+00, 5.749999080e-03, 1.030562282e+00], // 555 nm
    [5.945000052e-01, 9.950000048e-01, 3.899999894e-03, 1.010127306e+00], // 560 nm
    [6.783999801e-01, 9.786000252e-01, 2.749999054e-03, 9.916127324e-01], // 565 nm
    [7.620999813e-01, 9.520000219e-01, 2.099999925e-03, 9.730980992e-01], // 570 nm
    [8.424999714e-01, 9.154000282e-01, 1.799999969e-03, 9.703394175e-01], // 575 nm
    [9.162999988e-01, 8.700000048e-01, 1.650001039e-03, 9.675807953e-01], // 580 nm
    [9.786000252e-01, 8.162999749e-01, 1.399999950e-03, 9.317091703e-01], // 585 nm
    [1.026299953e+00, 7.570000291e-01, 1.099999994e-03, 8.958375454e-01], // 590 nm
    [1.056699991e+00, 6.948999763e-01, 1.000000047e-03, 9.025074244e-01], // 595 nm
    [1.062199950e+00, 6.309999824e-01, 7.999999798e-04, 9.091773033e-01], // 600 nm
    [1.045600057e+00, 5.667999983e-01, 6.000000285e-04, 9.071205854e-01], // 605 nm
    [1.002599955e+00, 5.030000210e-01, 3.399999987e-04, 9.050650001e-01], // 610 nm
    [9.383999705e-01, 4.411999881e-01, 2.399999939e-04, 8.954668045e-01], // 615 nm
    [8.544499278e-01, 3.810000122e-01, 1.900000061e-04, 8.858685493e-01], // 620 nm
    [7.513999939e-01, 3.210000098e-01, 9.999999747e-05, 8.635942340e-01], // 625 nm
    [6.424000263e-01, 2.649999857e-01, 4.999999146e-05, 8.413209319e-01], // 630 nm
    [5.418999791e-01, 2.169999927e-01, 2.999999924e-05, 8.433946967e-01], // 635 nm
    [4.478999972e-01, 1.749999970e-01, 1.999999949e-05, 8.454685807e-01], // 640 nm
    [3.607999980e-01, 1.381999999e-01, 9.999999747e-06, 8.269205689e-01], // 645 nm
    [2.834999859e-01, 1.070000008e-01, 0.000000000e+00, 8.083726168e-01], // 650 nm
    [2.187000066e-01, 8.160000294e-02, 0.000000000e+00, 8.093211055e-01], // 655 nm
    [1.649000049e-01, 6.100000069e-02, 0.000000000e+00, 8.102695942e-01], // 660 nm
    [1.212000027e-01, 4.458000138e-02, 0.000000000e+00, 8.206900954e-01], // 665 nm
    [8.739999682e-02, 3.200000152e-02, 0.000000000e+00, 8.311105967e-01], // 670 nm
    [6.360000372e-02, 2.319999970e-02, 0.000000000e+00, 8.109403253e-01], // 675 nm
    [4.676999897e-02, 1.700000092e-02, 0.000000000e+00, 7.907701731e-01], // 680 nm
    [3.290000185e-02, 1.192000043e-02, 0.000000000e+00, 7.475215197e-01], // 685 nm
    [2.270000055e-02, 8.209999651e-03, 0.000000000e+00, 7.042739391e-01], // 690 nm
    [1.583999954e-02, 5.723000038e-03, 0.000000000e+00, 7.138085365e-01], // 695 nm
    [1.135915983e-02, 4.102000035e-03, 0.000000000e+00, 7.233431339e-01], // 700 nm
    [8.110916242e-03, 2.928999951e-03, 0.000000000e+00, 7.371808290e-01], // 705 nm
    [5.790345836e-03, 2.091000089e-03, 0.000000000e+00, 7.510195971e-01], // 710 nm
    [4.109457135e-03, 1.484000008e-03, 0.000000000e+00, 6.866492629e-01], // 715 nm
    [2.899327083e-03, 1.047000056e-03, 0.000000000e+00, 6.222788692e-01], // 720 nm
    [2.049189992e-03, 7.399999886e-04, 0.000000000e+00, 6.641061902e-01], // 725 nm
    [1.439971034e-03, 5.200000014e-04, 0.000000000e+00, 7.059335709e-01], // 730 nm
    [9.999492904e-04, 3.611000138e-04, 0.000000000e+00, 7.322039008e-01], // 735 nm
    [6.900785957e-04, 2.492000058e-04, 0.000000000e+00, 7.584742904e-01], // 740 nm
    [4.760212905e-04, 1.718999993e-04, 0.000000000e+00, 7.004202604e-01], // 745 nm
    [3.323011042e-04, 1.199999970e-04, 0.000000000e+00, 6.423673034e-01], // 750 nm
    [2.348261041e-04, 8.479999815e-05, 0.000000000e+00, 5.556246042e-01], // 755 nm
    [1.661504939e-04, 5.999999848e-05, 0.000000000e+00, 4.688829482e-01], // 760 nm
    [1.174130011e-04, 4.239999907e-05, 0.000000000e+00, 5.718513131e-01], // 765 nm
    [8.307526878e-05, 2.999999924e-05, 0.000000000e+00, 6.748195887e-01], // 770 nm
    [5.870651876e-05, 2.119999954e-05, 0.000000000e+00, 6.575333476e-01], // 775 nm
    [4.150993846e-05, 1.498999973e-05, 0.000000000e+00, 6.402470469e-01], // 780 nm
    [2.935325938e-05, 1.059999977e-05, 0.000000000e+00, 6.448996663e-01], // 785 nm
    [2.067382957e-05, 7.465700037e-06, 0.000000000e+00, 6.495522857e-01], // 790 nm
    [1.455976962e-05, 5.257799785e-06, 0.000000000e+00, 6.250455976e-01], // 795 nm
    [1.025397978e-05, 3.702899903e-06, 0.000000000e+00, 6.005399227e-01], // 800 nm
    [7.221456144e-06, 2.607800070e-06, 0.000000000e+00, 5.626955032e-01], // 805 nm
    [5.085867997e-06, 1.836599949e-06, 0.000000000e+00, 5.248520970e-01], // 810 nm
    [3.581651981e-06, 1.293400032e-06, 0.000000000e+00, 5.525376201e-01], // 815 nm
    [2.522524937e-06, 9.109299981e-07, 0.000000000e+00, 5.802232623e-01], // 820 nm
    [1.776508952e-06, 6.415299936e-07, 0.000000000e+00, 5.947276354e-01], // 825 nm
    [1.251141043e-06, 4.518099956e-07, 0.000000000e+00, 6.092330813e-01], // 830 nm
];

/// The colour-matching functions and D65 at `lambda` (within the tables),
/// linearly interpolated.
fn cie_at(lambda: f64) -> [f64; 4] {
    let x = ((lambda - LAMBDA_MIN) / 5.0).clamp(0.0, 94.0);
    let i = (x as usize).min(93);
    let t = x - i as f64;
    let (a, b) = (CIE_5NM[i], CIE_5NM[i + 1]);
    std::array::from_fn(|k| a[k] + t * (b[k] - a[k]))
}

/// CIE XYZ of the spectrum `value(λ)` (λ in nm), times D65 where `d65`
/// asks: integrated by the tables' [`STEPS`] samples over 360–830 nm and
/// scaled by 1 / ∫ȳ, so that Y is the spectrum's luminance (a flat
/// spectrum of 1 weighted by D65 has Y = 1).
pub fn spectrum_xyz(value: impl Fn(f64) -> f64, d65: bool) -> [f64; 3] {
    let mut xyz = [0.0f64; 3];
    for i in 0..STEPS {
        let lambda = LAMBDA_MIN + (i as f64 / (STEPS - 1) as f64) * (LAMBDA_MAX - LAMBDA_MIN);
        let [x, y, z, illuminant] = cie_at(lambda);
        let v = value(lambda) * if d65 { illuminant } else { 1.0 };
        xyz[0] += x * v;
        xyz[1] += y * v;
        xyz[2] += z * v;
    }
    let scale = (LAMBDA_MAX - LAMBDA_MIN) / STEPS as f64 * CIE_Y_NORMALIZATION;
    xyz.map(|c| c * scale)
}

/// Linear sRGB of CIE XYZ (the matrix of Mitsuba 3's `xyz_to_srgb`),
/// unclamped.
pub fn xyz_to_linear_srgb([x, y, z]: [f64; 3]) -> [f64; 3] {
    [
        3.2404790 * x - 1.5371500 * y - 0.4985350 * z,
        -0.9692560 * x + 1.8759910 * y + 0.0415560 * z,
        0.0556480 * x - 0.2040430 * y + 1.0573110 * z,
    ]
}

/// Planck's law at `nm` for `kelvin`, up to a constant factor; 0 where
/// it underflows.
pub fn planck(nm: f64, kelvin: f64) -> f64 {
    // Second radiation constant hc/k in nm·K.
    const C2: f64 = 1.438_776_9e7;
    let b = 1.0 / (nm.powi(5) * (C2 / (nm * kelvin)).exp_m1());
    if b.is_finite() { b } else { 0.0 }
}

/// The chromaticity (x, y) of a blackbody at `kelvin`: Planck's law
/// integrated against the colour-matching functions of the tables.
pub fn blackbody_xy(kelvin: f64) -> (f64, f64) {
    // Normalised at the peak (Wien's law) first: cold blackbodies are far
    // below f64's range in absolute units.
    const WIEN_NM_K: f64 = 2.897_772_1e6;
    let peak = planck(WIEN_NM_K / kelvin, kelvin);
    let xyz = spectrum_xyz(|l| planck(l, kelvin) / peak, false);
    let sum = xyz[0] + xyz[1] + xyz[2];
    (xyz[0] / sum, xyz[1] / sum)
}

/// How a sampled spectrum is used, which decides its conversion.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SpectrumUse {
    /// Emitted radiance: integrated without D65, kept non-negative.
    Emission,
    /// A reflectance or other value in [0, 1]: weighted by D65, clamped to [0, 1].
    Bounded,
    /// Another unbounded value (an index of refraction): weighted by D65,
    /// kept non-negative.
    Unbounded,
}

/// The linear sRGB colour of the spectrum given by `(wavelength in nm,
/// value)` pairs sorted by wavelength (at least two). Also says whether a
/// channel had to be clamped (out of gamut), which Mitsuba warns about.
pub fn sampled_to_rgb(samples: &[(f32, f32)], usage: SpectrumUse) -> (Rgb, bool) {
    let rgb = linear_rgb(samples, usage);
    let high = if usage == SpectrumUse::Bounded {
        1.0
    } else {
        f64::INFINITY
    };
    let clamped = rgb.iter().any(|&c| c < 0.0 || c > high);
    let [r, g, b] = rgb.map(|c| c.clamp(0.0, high) as f32);
    (Rgb::new(r, g, b), clamped)
}

/// What each sample of a spectrum at `wavelengths` (nm, ascending, at
/// least two) adds to its colour: the colour of a spectrum is
/// Σ value_j · weight_j before clamping, since the conversion is linear.
pub fn sample_weights(wavelengths: &[f32], usage: SpectrumUse) -> Vec<Rgb> {
    (0..wavelengths.len())
        .map(|j| {
            let hat: Vec<(f32, f32)> = wavelengths
                .iter()
                .enumerate()
                .map(|(i, &l)| (l, if i == j { 1.0 } else { 0.0 }))
                .collect();
            let [r, g, b] = linear_rgb(&hat, usage).map(|c| c as f32);
            Rgb::new(r, g, b)
        })
        .collect()
}

/// The unclamped linear sRGB of a sampled spectrum.
fn linear_rgb(samples: &[(f32, f32)], usage: SpectrumUse) -> [f64; 3] {
    xyz_to_linear_srgb(spectrum_xyz(
        |lambda| piecewise_linear(samples, lambda),
        usage != SpectrumUse::Emission,
    ))
}

/// `samples` (wavelengths ascending, at least two) at `lambda`: linearly
/// interpolated, zero outside them (as Mitsuba's and pbrt-v4's
/// piecewise-linear spectra).
pub fn piecewise_linear(samples: &[(f32, f32)], lambda: f64) -> f64 {
    let (first, last) = (samples[0].0 as f64, samples[samples.len() - 1].0 as f64);
    if lambda < first || lambda > last {
        return 0.0;
    }
    let segment = samples
        .partition_point(|s| (s.0 as f64) <= lambda)
        .clamp(1, samples.len() - 1)
        - 1;
    let ((w0, v0), (w1, v1)) = (samples[segment], samples[segment + 1]);
    let (w0, v0, w1, v1) = (w0 as f64, v0 as f64, w1 as f64, v1 as f64);
    if w1 > w0 {
        v0 + (lambda - w0) / (w1 - w0) * (v1 - v0)
    } else {
        v1
    }
}

/// A wavelength drawn for a path whose transport from then on depends on
/// it (a dispersive glass), and the RGB weight that keeps the path's
/// estimate unbiased in every channel.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WavelengthSample {
    /// The wavelength, in nm.
    pub nm: f32,
    /// The path's throughput is multiplied by this, channel by channel:
    /// the share of the channel's response that falls at `nm` over the
    /// density of `nm`. Its expectation is (1, 1, 1).
    pub weight: Rgb,
    /// The 1-nm bin `nm` was drawn in, which names the weight
    /// ([`visible_wavelength_weight`]) where a record must stay small.
    pub bin: u16,
}

/// Wavelength bins of 1 nm over the tables' range.
const WAVELENGTH_BINS: usize = 470;

/// The distribution [`sample_visible_wavelength`] draws from: per bin, its
/// cumulative probability and its weight.
struct VisibleWavelengths {
    /// `cdf[i]`: the probability of the bins before bin i (`cdf[BINS]` = 1).
    cdf: Vec<f32>,
    weight: Vec<Rgb>,
}

fn visible_wavelengths() -> &'static VisibleWavelengths {
    static TABLE: std::sync::OnceLock<VisibleWavelengths> = std::sync::OnceLock::new();
    TABLE.get_or_init(|| {
        // A channel's response to light of one wavelength carrying a
        // D65-shaped spectrum: the sRGB channel of the colour-matching
        // functions times D65. Each channel is normalised so that its
        // bins sum to 1: light that is the same at every wavelength keeps
        // its colour, and an RGB path's channels are read as
        // D65-weighted spectra, as pbrt-v4's RGB illuminants are.
        let response: Vec<[f64; 3]> = (0..WAVELENGTH_BINS)
            .map(|i| {
                let [x, y, z, d65] = cie_at(LAMBDA_MIN + i as f64 + 0.5);
                xyz_to_linear_srgb([x * d65, y * d65, z * d65])
            })
            .collect();
        let sums = response
            .iter()
            .fold([0.0f64; 3], |s, r| std::array::from_fn(|k| s[k] + r[k]));
        let response: Vec<[f64; 3]> = response
            .iter()
            .map(|r| std::array::from_fn(|k| r[k] / sums[k]))
            .collect();
        // Bins drawn in proportion to the channels' summed magnitude, so
        // that no weight grows far beyond the others.
        let density: Vec<f64> = response.iter().map(|r| r.iter().map(|c| c.abs()).sum()).collect();
        let total: f64 = density.iter().sum();
        let mut cdf = Vec::with_capacity(WAVELENGTH_BINS + 1);
        let mut acc = 0.0f64;
        cdf.push(0.0f32);
        for d in &density {
            acc += d / total;
            cdf.push(acc as f32);
        }
        cdf[WAVELENGTH_BINS] = 1.0;
        let weight = response
            .iter()
            .zip(&density)
            .map(|(r, d)| {
                let p = d / total;
                Rgb::new((r[0] / p) as f32, (r[1] / p) as f32, (r[2] / p) as f32)
            })
            .collect();
        VisibleWavelengths { cdf, weight }
    })
}

/// A wavelength over 360–830 nm for the uniform number `u` (the spectral
/// sampling of a path that meets dispersion: pbrt-v4 terminates its
/// secondary wavelengths there, trazo draws its one wavelength there),
/// with the weight that turns the path's RGB throughput into its share
/// at that wavelength.
pub fn sample_visible_wavelength(u: f32) -> WavelengthSample {
    let table = visible_wavelengths();
    let u = u.clamp(0.0, 1.0);
    let bin = (table.cdf.partition_point(|&c| c <= u).max(1) - 1).min(WAVELENGTH_BINS - 1);
    let (lo, hi) = (table.cdf[bin], table.cdf[bin + 1]);
    let within = if hi > lo {
        ((u - lo) / (hi - lo)).clamp(0.0, 1.0)
    } else {
        0.5
    };
    WavelengthSample {
        nm: LAMBDA_MIN as f32 + bin as f32 + within,
        weight: table.weight[bin],
        bin: bin as u16,
    }
}

/// The weight of a wavelength drawn in bin `bin` of
/// [`sample_visible_wavelength`] (its [`WavelengthSample::weight`]).
pub fn visible_wavelength_weight(bin: u16) -> Rgb {
    visible_wavelengths().weight[(bin as usize).min(WAVELENGTH_BINS - 1)]
}

/// A smooth spectrum `s(λ) = σ(c₀t² + c₁t + c₂)`, t = (λ − 360 nm)/470 nm
/// and σ(x) = ½ + x / (2√(1 + x²)): the space Jakob and Hanika (2019, "A
/// Low-Dimensional Function Space for Efficient Spectral Upsampling") lift
/// RGB colours into, as pbrt-v4's `RGBSigmoidPolynomial` (which writes the
/// polynomial in λ itself).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SigmoidSpectrum {
    /// c₀, c₁, c₂.
    pub coeffs: [f64; 3],
}

/// Newton steps per point of the continuation of [`SigmoidSpectrum::fit`].
const FIT_STEPS: usize = 12;
/// Points on the way from grey to the target colour.
const FIT_STAGES: usize = 16;

impl SigmoidSpectrum {
    /// Its value at `nm` nanometres, in (0, 1).
    pub fn at(&self, nm: f64) -> f64 {
        sigmoid(self.polynomial((nm - LAMBDA_MIN) / (LAMBDA_MAX - LAMBDA_MIN)))
    }

    fn polynomial(&self, t: f64) -> f64 {
        let [c0, c1, c2] = self.coeffs;
        (c0 * t + c1) * t + c2
    }

    /// The spectrum whose colour as a reflectance under D65 (as
    /// [`sampled_to_rgb`] takes one, [`SpectrumUse::Bounded`]) is `rgb`,
    /// linear sRGB with every channel in (0, 1): the solution of the three
    /// equations in three unknowns by Newton's method, followed from grey
    /// (σ ≡ ½) to `rgb` in [`FIT_STAGES`] steps as Jakob and Hanika's
    /// optimiser follows its table from the centre outward. `None` where
    /// no sigmoid spectrum has that colour (to 10⁻⁶).
    pub fn fit(rgb: [f64; 3]) -> Option<SigmoidSpectrum> {
        if !rgb.iter().all(|&c| c > 0.0 && c < 1.0) {
            return None;
        }
        let mut s = SigmoidSpectrum { coeffs: [0.0; 3] };
        let (grey, _) = s.rgb_and_jacobian();
        for stage in 1..=FIT_STAGES {
            let f = stage as f64 / FIT_STAGES as f64;
            let target: [f64; 3] = std::array::from_fn(|k| grey[k] + f * (rgb[k] - grey[k]));
            for _ in 0..FIT_STEPS {
                let (now, jacobian) = s.rgb_and_jacobian();
                let residual: [f64; 3] = std::array::from_fn(|k| target[k] - now[k]);
                if residual.iter().all(|r| r.abs() < 1e-12) {
                    break;
                }
                let step = solve3(jacobian, residual)?;
                s.coeffs = std::array::from_fn(|k| s.coeffs[k] + step[k]);
            }
        }
        let (now, _) = s.rgb_and_jacobian();
        let fits = (0..3).all(|k| (now[k] - rgb[k]).abs() < 1e-6) && s.coeffs.iter().all(|c| c.is_finite());
        fits.then_some(s)
    }

    /// The linear sRGB of the spectrum as a reflectance under D65, and its
    /// derivatives by the coefficients (`jacobian[channel][coefficient]`).
    fn rgb_and_jacobian(&self) -> ([f64; 3], [[f64; 3]; 3]) {
        let mut xyz = [0.0f64; 3];
        let mut d_xyz = [[0.0f64; 3]; 3];
        for i in 0..STEPS {
            let t = i as f64 / (STEPS - 1) as f64;
            let lambda = LAMBDA_MIN + t * (LAMBDA_MAX - LAMBDA_MIN);
            let [x, y, z, d65] = cie_at(lambda);
            let p = self.polynomial(t);
            let (v, dv) = (sigmoid(p), sigmoid_derivative(p));
            let powers = [t * t, t, 1.0];
            for (k, w) in [x, y, z].into_iter().enumerate() {
                xyz[k] += w * d65 * v;
                for (c, power) in powers.iter().enumerate() {
                    d_xyz[k][c] += w * d65 * dv * power;
                }
            }
        }
        let scale = (LAMBDA_MAX - LAMBDA_MIN) / STEPS as f64 * CIE_Y_NORMALIZATION;
        let rgb = xyz_to_linear_srgb(xyz.map(|c| c * scale));
        let columns: [[f64; 3]; 3] =
            std::array::from_fn(|c| xyz_to_linear_srgb([d_xyz[0][c], d_xyz[1][c], d_xyz[2][c]].map(|d| d * scale)));
        (rgb, std::array::from_fn(|k| std::array::from_fn(|c| columns[c][k])))
    }
}

fn sigmoid(x: f64) -> f64 {
    if x.is_infinite() {
        return if x > 0.0 { 1.0 } else { 0.0 };
    }
    0.5 + x / (2.0 * (1.0 + x * x).sqrt())
}

fn sigmoid_derivative(x: f64) -> f64 {
    0.5 / (1.0 + x * x).powf(1.5)
}

/// `m⁻¹ b` by Cramer's rule; `None` for a singular `m`.
fn solve3(m: [[f64; 3]; 3], b: [f64; 3]) -> Option<[f64; 3]> {
    let det3 = |a: [[f64; 3]; 3]| {
        a[0][0] * (a[1][1] * a[2][2] - a[1][2] * a[2][1]) - a[0][1] * (a[1][0] * a[2][2] - a[1][2] * a[2][0])
            + a[0][2] * (a[1][0] * a[2][1] - a[1][1] * a[2][0])
    };
    let det = det3(m);
    if det == 0.0 || !det.is_finite() {
        return None;
    }
    Some(std::array::from_fn(|c| {
        let mut mc = m;
        for (row, value) in mc.iter_mut().zip(b) {
            row[c] = value;
        }
        det3(mc) / det
    }))
}

/// The samples of a spectrum file (pbrt-v4's `.spd`, Mitsuba 3's
/// spectrum files): whitespace-separated pairs of wavelength (nm,
/// increasing) and value; `#` starts a comment.
pub fn parse_spd(text: &str) -> Result<Vec<(f32, f32)>, String> {
    let mut numbers = Vec::new();
    for (line_no, line) in text.lines().enumerate() {
        let line = line.split('#').next().unwrap_or("");
        for word in line.split_whitespace() {
            let x: f32 = word
                .parse()
                .map_err(|_| format!("line {}: \"{word}\" is not a number", line_no + 1))?;
            if !x.is_finite() {
                return Err(format!("line {}: {word} is not finite", line_no + 1));
            }
            numbers.push(x);
        }
    }
    if numbers.len() < 2 || numbers.len() % 2 != 0 {
        return Err(format!(
            "needs pairs of wavelength and value, found {} numbers",
            numbers.len()
        ));
    }
    let pairs: Vec<(f32, f32)> = numbers.chunks_exact(2).map(|c| (c[0], c[1])).collect();
    if let Some(w) = pairs.windows(2).find(|w| w[1].0 <= w[0].0) {
        return Err(format!("wavelengths must increase, but {} follows {}", w[1].0, w[0].0));
    }
    Ok(pairs)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn spectrum_files_are_increasing_pairs() {
        let s = parse_spd("# gold\n400 1.0\n500 3.0 # comment\n600 2.0\n").unwrap();
        assert_eq!(s, vec![(400.0, 1.0), (500.0, 3.0), (600.0, 2.0)]);
        for (bad, why) in [
            ("400 1 500", "found 3 numbers"),
            ("400 1 x 2", "line 1: \"x\" is not a number"),
            ("500 1\n400 2", "wavelengths must increase"),
            ("400 inf 500 1", "line 1: inf is not finite"),
            ("", "found 0 numbers"),
        ] {
            let e = parse_spd(bad).unwrap_err();
            assert!(e.contains(why), "{bad}: {e}");
        }
    }

    fn close(a: Rgb, b: [f32; 3], tol: f32) -> bool {
        (a - Rgb::new(b[0], b[1], b[2])).abs().max_element() <= tol * b.iter().fold(1.0f32, |m, &x| m.max(x))
    }

    /// Mitsuba 3.9.1's own conversions (`scalar_rgb`, read back from
    /// loaded scenes with `mi.traverse`).
    #[test]
    fn sampled_spectra_convert_as_mitsuba_converts_them() {
        let (light, _) = sampled_to_rgb(
            &[(400.0, 0.0), (500.0, 8.0), (600.0, 15.6), (700.0, 18.4)],
            SpectrumUse::Emission,
        );
        assert!(close(light, [20.7108, 10.8546, 2.77115], 1e-4), "{light}");
        let (grey, clamped) = sampled_to_rgb(&[(400.0, 0.78), (700.0, 0.78)], SpectrumUse::Bounded);
        assert!(close(grey, [0.776367, 0.77981, 0.776029], 1e-4) && !clamped, "{grey}");
        let (tinted, _) = sampled_to_rgb(
            &[(400.0, 0.1), (500.0, 0.5), (600.0, 0.9), (700.0, 0.3)],
            SpectrumUse::Bounded,
        );
        assert!(close(tinted, [0.854797, 0.68754, 0.265015], 1e-4), "{tinted}");
        // Out of gamut: a narrow green line clamps its red and blue.
        let (line, clamped) = sampled_to_rgb(&[(520.0, 0.0), (525.0, 1.0), (530.0, 0.0)], SpectrumUse::Bounded);
        assert!(clamped && line.x == 0.0 && line.z == 0.0 && line.y > 0.0, "{line}");
    }

    #[test]
    fn wavelength_weights_average_to_white() {
        // The expectation over u of the weight is exactly (1, 1, 1): each
        // bin's weight times its probability sums to 1 per channel.
        let table = visible_wavelengths();
        let mut mean = [0.0f64; 3];
        for (i, w) in table.weight.iter().enumerate() {
            let p = (table.cdf[i + 1] - table.cdf[i]) as f64;
            for k in 0..3 {
                mean[k] += p * w[k] as f64;
            }
        }
        for m in mean {
            assert!((m - 1.0).abs() < 1e-4, "{mean:?}");
        }
        // And so does a plain average over evenly spaced u.
        let n = 200_000;
        let sum = (0..n).fold(Rgb::ZERO, |s, i| {
            s + sample_visible_wavelength((i as f32 + 0.5) / n as f32).weight
        });
        let avg = sum / n as f32;
        assert!((avg - Rgb::ONE).abs().max_element() < 2e-3, "{avg}");
    }

    #[test]
    fn sampled_wavelengths_cover_the_visible_range_in_order() {
        let mut last = 0.0;
        for i in 0..=1000 {
            let s = sample_visible_wavelength(i as f32 / 1000.0);
            assert!((360.0..=830.0).contains(&s.nm) && s.nm >= last, "{} at {i}", s.nm);
            assert!(s.weight.is_finite());
            last = s.nm;
        }
        // Red light is red: 650 nm weighs red, 450 nm blue, 530 nm green.
        let at = |nm: f32| {
            let t = visible_wavelengths();
            t.weight[(nm - 360.0) as usize]
        };
        let (r, g, b) = (at(650.0), at(530.0), at(450.0));
        assert!(r.x > 0.0 && r.x > 10.0 * r.y.abs() && r.x > 10.0 * r.z.abs(), "{r}");
        assert!(g.y > g.x.abs() && g.y > g.z.abs(), "{g}");
        assert!(b.z > b.x.abs() && b.z > b.y.abs(), "{b}");
    }

    #[test]
    fn sigmoid_spectra_reproduce_the_colours_they_are_fitted_to() {
        for rgb in [
            [0.5, 0.5, 0.5],
            [0.468, 0.484, 0.5],
            [0.25, 0.5, 0.25],
            [0.5, 0.1, 0.05],
            [0.05, 0.2, 0.5],
            [0.9, 0.9, 0.02],
            [0.02, 0.6, 0.9],
        ] {
            let s = SigmoidSpectrum::fit(rgb).unwrap_or_else(|| panic!("no fit for {rgb:?}"));
            // Its colour, integrated independently of the fit's Jacobian.
            let back = xyz_to_linear_srgb(spectrum_xyz(|l| s.at(l), true));
            for k in 0..3 {
                assert!((back[k] - rgb[k]).abs() < 1e-6, "{rgb:?}: {back:?} ({:?})", s.coeffs);
            }
            assert!((360..=830).all(|nm| (0.0..=1.0).contains(&s.at(nm as f64))));
        }
        // Grey is nearly flat (D65 is sRGB's white to the tables' precision
        // only); colours beyond the sigmoids' reach are refused.
        let grey = SigmoidSpectrum::fit([0.5, 0.5, 0.5]).expect("grey");
        assert!(
            (360..=830).all(|nm| (grey.at(nm as f64) - 0.5).abs() < 1e-3),
            "{:?}",
            grey.coeffs
        );
        assert_eq!(SigmoidSpectrum::fit([0.0, 0.5, 0.5]), None);
        assert_eq!(SigmoidSpectrum::fit([1.2, 0.5, 0.5]), None);
    }
}
