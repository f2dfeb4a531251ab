//! Convergence plots: the error of each algorithm's image against render
//! time, on log–log axes, with the 1/√t line that an unbiased Monte Carlo
//! estimator's error follows (its variance falls as 1/samples). The
//! course's comparison of algorithms as a graph, written by
//! `trazo compare --reference`.
//!
//! The axes, curves and legend are laid out by plotters once, for two
//! backends: plotters' SVG backend (text as SVG text) and a raster one
//! here that draws text in trazo's own 5×7 font ([`super::text`]), so
//! neither needs a font file or a font library.

use super::text::{GLYPH_H, text_pixels, text_width};
use crate::error::{Error, Result};
use plotters::prelude::*;
use plotters_backend::text_anchor::{HPos, VPos};
use plotters_backend::{BackendColor, BackendCoord, BackendTextStyle, DrawingErrorKind};

/// Width of a plot in pixels (SVG user units).
pub const PLOT_WIDTH: u32 = 720;
/// Height of a plot.
pub const PLOT_HEIGHT: u32 = 480;

/// One algorithm's measurements: its label and (seconds, error) points.
#[derive(Clone, Debug, PartialEq)]
pub struct Curve {
    /// The algorithm, as the legend names it.
    pub label: String,
    /// Render time in seconds and the error reached in it.
    pub points: Vec<(f64, f64)>,
}

/// The plot as an SVG document.
pub fn convergence_svg(curves: &[Curve], y_label: &str) -> Result<String> {
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, (PLOT_WIDTH, PLOT_HEIGHT)).into_drawing_area();
        draw(root, curves, y_label).map_err(|e| Error::Invalid(format!("cannot draw the plot: {e}")))?;
    }
    Ok(svg)
}

/// The plot as 8-bit sRGB pixels, row by row (`PLOT_WIDTH` × `PLOT_HEIGHT`).
pub fn convergence_rgb8(curves: &[Curve], y_label: &str) -> Result<Vec<u8>> {
    let mut pixels = vec![255u8; (PLOT_WIDTH * PLOT_HEIGHT * 3) as usize];
    {
        let canvas = Canvas {
            pixels: &mut pixels,
            width: PLOT_WIDTH,
            height: PLOT_HEIGHT,
        };
        draw(canvas.into_drawing_area(), curves, y_label)
            .map_err(|e| Error::Invalid(format!("cannot draw the plot: {e}")))?;
    }
    Ok(pixels)
}

/// The plot as PNG bytes.
pub fn convergence_png(curves: &[Curve], y_label: &str) -> Result<Vec<u8>> {
    let pixels = convergence_rgb8(curves, y_label)?;
    let mut out = Vec::new();
    use ::image::ImageEncoder;
    ::image::codecs::png::PngEncoder::new(&mut out)
        .write_image(&pixels, PLOT_WIDTH, PLOT_HEIGHT, ::image::ExtendedColorType::Rgb8)
        .map_err(|e| Error::Invalid(format!("PNG encoding failed: {e}")))?;
    Ok(out)
}

/// Distinct line colours, one per curve (repeating after eight).
const COLORS: [RGBColor; 8] = [
    RGBColor(31, 119, 180),
    RGBColor(214, 39, 40),
    RGBColor(44, 160, 44),
    RGBColor(148, 103, 189),
    RGBColor(255, 127, 14),
    RGBColor(140, 86, 75),
    RGBColor(227, 119, 194),
    RGBColor(23, 190, 207),
];

/// A number on a log axis: short, as 0.01, 3, 2e-05.
fn axis_number(v: f64) -> String {
    if (1e-3..1e4).contains(&v.abs()) {
        let s = format!("{v:.3}");
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    } else {
        format!("{v:.0e}")
    }
}

/// The points of a curve that a log–log plot can show (positive and finite).
fn plottable(points: &[(f64, f64)]) -> impl Iterator<Item = (f64, f64)> + '_ {
    points
        .iter()
        .copied()
        .filter(|&(t, e)| t.is_finite() && e.is_finite() && t > 0.0 && e > 0.0)
}

fn draw<DB: DrawingBackend>(
    root: DrawingArea<DB, plotters::coord::Shift>,
    curves: &[Curve],
    y_label: &str,
) -> std::result::Result<(), DrawingAreaErrorKind<DB::ErrorType>> {
    root.fill(&WHITE)?;
    let all: Vec<(f64, f64)> = curves.iter().flat_map(|c| plottable(&c.points)).collect();
    let bounds = |f: fn(&(f64, f64)) -> f64| {
        let lo = all.iter().map(f).fold(f64::INFINITY, f64::min);
        let hi = all.iter().map(f).fold(f64::NEG_INFINITY, f64::max);
        if lo.is_finite() {
            (lo / 1.5, hi * 1.5)
        } else {
            (0.1, 10.0)
        }
    };
    let (t0, t1) = bounds(|p| p.0);
    let (e0, e1) = bounds(|p| p.1);
    let mut chart = ChartBuilder::on(&root)
        .caption(format!("{y_label} against render time"), ("sans-serif", 28))
        .margin(14)
        .x_label_area_size(44)
        .y_label_area_size(76)
        .build_cartesian_2d((t0..t1).log_scale(), (e0..e1).log_scale())?;
    chart
        .configure_mesh()
        .x_desc("render time (s)")
        .y_desc(y_label)
        .x_label_formatter(&|v| axis_number(*v))
        .y_label_formatter(&|v| axis_number(*v))
        .light_line_style(WHITE.mix(0.0))
        .draw()?;
    for (i, curve) in curves.iter().enumerate() {
        let color = COLORS[i % COLORS.len()];
        chart
            .draw_series(LineSeries::new(plottable(&curve.points), color.stroke_width(2)))?
            .label(curve.label.as_str())
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 24, y)], color.stroke_width(2)));
        chart.draw_series(plottable(&curve.points).map(|p| Circle::new(p, 3, color.filled())))?;
    }
    // The 1/√t slope, through the last point of the first curve.
    if let Some(&(ta, ea)) = curves
        .first()
        .and_then(|c| plottable(&c.points).last().as_ref().copied())
        .as_ref()
    {
        let line = [t0, t1].map(|t| (t, ea * (ta / t).sqrt()));
        chart
            .draw_series(DashedLineSeries::new(line, 6, 4, BLACK.mix(0.6).stroke_width(1)))?
            .label("1/sqrt(t)")
            .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 24, y)], BLACK.mix(0.6)));
    }
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::UpperRight)
        .background_style(WHITE.mix(0.9))
        .border_style(BLACK.mix(0.4))
        .label_font(("sans-serif", 14))
        .draw()?;
    root.present()
}

/// A raster drawing backend over 8-bit RGB pixels, whose text is trazo's
/// bitmap font.
struct Canvas<'a> {
    pixels: &'a mut [u8],
    width: u32,
    height: u32,
}

/// The canvas cannot fail.
#[derive(Debug)]
struct CanvasError;

impl std::fmt::Display for CanvasError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("canvas error")
    }
}

impl std::error::Error for CanvasError {}

/// The bitmap font's scale for a text of `size` pixels: the largest whose
/// glyphs (6 pixels a character at scale 1) are no wider than plotters'
/// own estimate for the font size (0.455·size a character), by which it
/// sizes the legend's box.
fn glyph_scale(size: f64) -> u32 {
    ((0.455 * size / 6.0).floor() as u32).max(1)
}

impl plotters_backend::DrawingBackend for Canvas<'_> {
    type ErrorType = CanvasError;

    fn get_size(&self) -> (u32, u32) {
        (self.width, self.height)
    }

    fn ensure_prepared(&mut self) -> std::result::Result<(), DrawingErrorKind<CanvasError>> {
        Ok(())
    }

    fn present(&mut self) -> std::result::Result<(), DrawingErrorKind<CanvasError>> {
        Ok(())
    }

    fn draw_pixel(
        &mut self,
        (x, y): BackendCoord,
        color: BackendColor,
    ) -> std::result::Result<(), DrawingErrorKind<CanvasError>> {
        if x < 0 || y < 0 || x >= self.width as i32 || y >= self.height as i32 {
            return Ok(());
        }
        let i = 3 * (y as usize * self.width as usize + x as usize);
        let a = color.alpha.clamp(0.0, 1.0);
        let (r, g, b) = color.rgb;
        for (p, c) in self.pixels[i..i + 3].iter_mut().zip([r, g, b]) {
            *p = (*p as f64 * (1.0 - a) + c as f64 * a).round() as u8;
        }
        Ok(())
    }

    fn draw_text<S: BackendTextStyle>(
        &mut self,
        text: &str,
        style: &S,
        (x, y): BackendCoord,
    ) -> std::result::Result<(), DrawingErrorKind<CanvasError>> {
        let scale = glyph_scale(style.size());
        let (w, h) = (text_width(text, scale) as i32, (GLYPH_H * scale) as i32);
        let anchor = style.anchor();
        let dx = match anchor.h_pos {
            HPos::Left => 0,
            HPos::Center => -w / 2,
            HPos::Right => -w,
        };
        let dy = match anchor.v_pos {
            VPos::Top => 0,
            VPos::Center => -h / 2,
            VPos::Bottom => -h,
        };
        let transform = style.transform();
        let color = style.color();
        for (px, py) in text_pixels(text, scale) {
            let (tx, ty) = transform.transform(px as i32 + dx, py as i32 + dy);
            self.draw_pixel((x + tx, y + ty), color)?;
        }
        Ok(())
    }

    fn estimate_text_size<S: BackendTextStyle>(
        &self,
        text: &str,
        style: &S,
    ) -> std::result::Result<(u32, u32), DrawingErrorKind<CanvasError>> {
        let scale = glyph_scale(style.size());
        Ok((text_width(text, scale), GLYPH_H * scale))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn curves() -> Vec<Curve> {
        vec![
            Curve {
                label: "path:mis".into(),
                points: vec![(0.1, 0.04), (0.2, 0.028), (0.4, 0.02)],
            },
            Curve {
                label: "path:uniform".into(),
                // A point a log axis cannot show is left out, not drawn at 0.
                points: vec![(0.1, 0.3), (0.2, 0.0), (0.4, 0.15)],
            },
        ]
    }

    #[test]
    fn svg_names_every_curve_and_the_reference_slope() {
        let svg = convergence_svg(&curves(), "RMS relative error").unwrap();
        assert!(svg.starts_with("<svg"), "{}", &svg[..svg.len().min(80)]);
        for text in [
            "path:mis",
            "path:uniform",
            "1/sqrt(t)",
            "render time (s)",
            "RMS relative error",
        ] {
            assert!(svg.contains(text), "the SVG lacks {text}");
        }
        // Each curve is a polyline in its colour.
        assert!(
            svg.contains("#1F77B4") && svg.contains("#D62728"),
            "curve colours missing"
        );
    }

    #[test]
    fn png_has_the_curves_and_text_in_their_colours() {
        let px = convergence_rgb8(&curves(), "RMS relative error").unwrap();
        let count = |rgb: [u8; 3]| px.chunks_exact(3).filter(|p| *p == rgb).count();
        // Both curves drawn (solid pixels of their exact colours), and
        // black text and axes.
        assert!(count([31, 119, 180]) > 50, "first curve missing");
        assert!(count([214, 39, 40]) > 50, "second curve missing");
        assert!(count([0, 0, 0]) > 500, "axes and labels missing");
        let png = convergence_png(&curves(), "RMS relative error").unwrap();
        let img = ::image::load_from_memory(&png).unwrap();
        assert_eq!((img.width(), img.height()), (PLOT_WIDTH, PLOT_HEIGHT));
    }

    #[test]
    fn no_plottable_point_still_gives_an_empty_plot() {
        let none = [Curve {
            label: "x".into(),
            points: vec![(0.0, 1.0), (1.0, f64::NAN)],
        }];
        assert!(convergence_svg(&none, "e").is_ok());
        assert!(convergence_rgb8(&none, "e").is_ok());
    }

    #[test]
    fn axis_numbers_are_short() {
        assert_eq!(axis_number(0.5), "0.5");
        assert_eq!(axis_number(20.0), "20");
        assert_eq!(axis_number(2e-5), "2e-5");
    }
}
