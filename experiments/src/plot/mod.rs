//! Plots with plotters on a bundled font (the machine may have no system fonts).
//!
//! Every figure goes through [`ensure_font`], which registers DejaVu Sans (shipped in
//! `experiments/assets`, licence beside it) as plotters' "sans-serif".

use std::path::Path;
use std::sync::Once;

use crate::error::Context;
use plotters::coord::Shift;
use plotters::coord::types::RangedCoordf64;
use plotters::prelude::*;
use plotters::style::FontStyle;
mod fields;
pub use fields::{Field, Heat, heatmaps, vector_fields};

static FONT: &[u8] = include_bytes!("../../assets/DejaVuSans.ttf");
static REGISTER: Once = Once::new();

/// Registers the bundled font once per process.
pub fn ensure_font() {
    REGISTER.call_once(|| {
        // The font is compiled in and valid; a failure here would be a build defect.
        let _ = plotters::style::register_font("sans-serif", FontStyle::Normal, FONT);
    });
}

/// One named series of (x, y) points.
pub struct Series<'a> {
    /// Legend label.
    pub name: &'a str,
    /// The (x, y) points, in drawing order.
    pub points: Vec<(f64, f64)>,
}

/// A line chart of one or more series; `log_y` plots log10 of positive values.
pub fn line_chart(
    path: &Path,
    title: &str,
    x_label: &str,
    y_label: &str,
    series: &[Series<'_>],
    log_y: bool,
) -> crate::Result<()> {
    ensure_font();
    let tf = |y: f64| if log_y { y.max(1e-300).log10() } else { y };
    let all: Vec<(f64, f64)> = series
        .iter()
        .flat_map(|s| s.points.iter().map(|&(x, y)| (x, tf(y))))
        .filter(|(x, y)| x.is_finite() && y.is_finite())
        .collect();
    if all.is_empty() {
        crate::error::bail!("nothing to plot in {title}");
    }
    let (x0, x1) = min_max(all.iter().map(|p| p.0));
    let (y0, y1) = min_max(all.iter().map(|p| p.1));
    let pad = ((y1 - y0) * 0.05).max(1e-9);
    plot_png(path, (900, 560), |root| {
        root.fill(&WHITE)?;
        let y_desc = if log_y {
            format!("log10 {y_label}")
        } else {
            y_label.to_owned()
        };
        let mut chart = ChartBuilder::on(root)
            .caption(title, ("sans-serif", 24))
            .margin(12)
            .x_label_area_size(40)
            .y_label_area_size(70)
            .build_cartesian_2d(x0..x1.max(x0 + 1e-9), (y0 - pad)..(y1 + pad))?;
        chart
            .configure_mesh()
            .x_desc(x_label)
            .y_desc(y_desc)
            .label_style(("sans-serif", 14))
            .draw()?;
        for (i, s) in series.iter().enumerate() {
            let color = Palette99::pick(i).to_rgba();
            chart
                .draw_series(LineSeries::new(
                    s.points
                        .iter()
                        .map(|&(x, y)| (x, tf(y)))
                        .filter(|(x, y)| x.is_finite() && y.is_finite()),
                    color.stroke_width(2),
                ))?
                .label(s.name)
                .legend(move |(x, y)| {
                    PathElement::new(vec![(x, y), (x + 20, y)], color.stroke_width(2))
                });
        }
        if series.len() > 1 {
            legend(&mut chart)?;
        }
        Ok(())
    })
}

/// A 2-D scatter of several point sets, each in its own colour.
pub fn scatter(
    path: &Path,
    title: &str,
    sets: &[Series<'_>],
    point_size: u32,
) -> crate::Result<()> {
    ensure_font();
    let all: Vec<(f64, f64)> = sets.iter().flat_map(|s| s.points.iter().copied()).collect();
    if all.is_empty() {
        crate::error::bail!("nothing to plot in {title}");
    }
    let (x0, x1) = min_max(all.iter().map(|p| p.0));
    let (y0, y1) = min_max(all.iter().map(|p| p.1));
    let span = (x1 - x0).max(y1 - y0).max(1e-9) * 0.55;
    let (cx, cy) = (0.5 * (x0 + x1), 0.5 * (y0 + y1));
    plot_png(path, (720, 760), |root| {
        root.fill(&WHITE)?;
        let mut chart = ChartBuilder::on(root)
            .caption(title, ("sans-serif", 22))
            .margin(12)
            .x_label_area_size(30)
            .y_label_area_size(50)
            .build_cartesian_2d((cx - span)..(cx + span), (cy - span)..(cy + span))?;
        chart
            .configure_mesh()
            .label_style(("sans-serif", 12))
            .draw()?;
        for (i, s) in sets.iter().enumerate() {
            let color = Palette99::pick(i).mix(0.6);
            chart
                .draw_series(
                    s.points
                        .iter()
                        .map(|&(x, y)| Circle::new((x, y), point_size, color.filled())),
                )?
                .label(s.name)
                .legend(move |(x, y)| Circle::new((x + 10, y), 4, color.filled()));
        }
        legend(&mut chart)?;
        Ok(())
    })
}

/// A metric per category (the values of a sweep axis): every run as a dot, the mean of
/// each category as a bar behind its dots.
pub fn category_chart(
    path: &Path,
    title: &str,
    y_label: &str,
    categories: &[String],
    points: &[(usize, f64)],
) -> crate::Result<()> {
    ensure_font();
    let finite: Vec<(usize, f64)> = points
        .iter()
        .copied()
        .filter(|(c, v)| v.is_finite() && *c < categories.len())
        .collect();
    if finite.is_empty() || categories.is_empty() {
        crate::error::bail!("nothing to plot in {title}");
    }
    let (y0, y1) = min_max(finite.iter().map(|p| p.1));
    let lo = y0.min(0.0);
    let pad = ((y1 - lo) * 0.08).max(1e-9);
    let n = categories.len();
    // Room for labels like `random_3000it/hybrid` under each bar.
    let width = (160 + 150 * n as u32).clamp(520, 2600);
    plot_png(path, (width, 520), |root| {
        root.fill(&WHITE)?;
        let mut chart = ChartBuilder::on(root)
            .caption(title, ("sans-serif", 22))
            .margin(12)
            .x_label_area_size(60)
            .y_label_area_size(70)
            .build_cartesian_2d(-0.5f64..(n as f64 - 0.5), lo..(y1 + pad))?;
        let cats = categories.to_vec();
        chart
            .configure_mesh()
            .disable_x_mesh()
            .x_labels(n)
            .x_label_formatter(&move |x: &f64| {
                let k = x.round();
                if (x - k).abs() < 1e-6 && k >= 0.0 && (k as usize) < cats.len() {
                    cats[k as usize].clone()
                } else {
                    String::new()
                }
            })
            .y_desc(y_label)
            .label_style(("sans-serif", 13))
            .draw()?;
        for c in 0..n {
            let vs: Vec<f64> = finite.iter().filter(|p| p.0 == c).map(|p| p.1).collect();
            if vs.is_empty() {
                continue;
            }
            let mean = vs.iter().sum::<f64>() / vs.len() as f64;
            let x = c as f64;
            chart.draw_series(std::iter::once(Rectangle::new(
                [(x - 0.3, lo), (x + 0.3, mean)],
                Palette99::pick(c).mix(0.35).filled(),
            )))?;
        }
        chart.draw_series(finite.iter().enumerate().map(|(i, &(c, v))| {
            // A small deterministic spread so that equal values stay visible.
            let dx = ((i % 5) as f64 - 2.0) * 0.05;
            Circle::new((c as f64 + dx, v), 4, BLACK.filled())
        }))?;
        Ok(())
    })
}

/// Draws a figure of `size` pixels with `draw` (on a white canvas) and writes it to `path`
/// as a PNG, atomically, at the encoder's best compression: plots are mostly flat colour,
/// and plotters' own writer leaves them 3–4 times larger.
fn plot_png(
    path: &Path,
    size: (u32, u32),
    draw: impl FnOnce(&DrawingArea<BitMapBackend<'_>, Shift>) -> crate::Result<()>,
) -> crate::Result<()> {
    let mut buf = vec![255u8; size.0 as usize * size.1 as usize * 3];
    {
        let root = BitMapBackend::with_buffer(&mut buf, size).into_drawing_area();
        draw(&root)?;
        root.present()?;
    }
    write_rgb_png(path, size, &buf).with_context(|| format!("writing {}", path.display()))
}

/// Writes an RGB8 buffer as a PNG at the best compression, atomically (figures and reports;
/// renders keep the fast encoder).
pub fn write_rgb_png(path: &Path, (w, h): (u32, u32), rgb: &[u8]) -> crate::Result<()> {
    use image::ImageEncoder;
    use image::codecs::png::{CompressionType, FilterType, PngEncoder};
    let mut bytes = Vec::new();
    PngEncoder::new_with_quality(&mut bytes, CompressionType::Best, FilterType::Adaptive)
        .write_image(rgb, w, h, image::ExtendedColorType::Rgb8)?;
    ifslab::io::write_atomic(path, &bytes)?;
    Ok(())
}

/// The series' labels in a box at the top right of a chart of two real axes.
fn legend<'a>(
    chart: &mut ChartContext<'a, BitMapBackend<'a>, Cartesian2d<RangedCoordf64, RangedCoordf64>>,
) -> crate::Result<()> {
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .label_font(("sans-serif", 14))
        .draw()?;
    Ok(())
}

fn min_max(it: impl Iterator<Item = f64>) -> (f64, f64) {
    it.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
        (a.min(v), b.max(v))
    })
}
