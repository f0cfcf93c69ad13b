//! Pictures of 2-D slices: heat maps of scalar fields (loss landscapes) and arrow plots of vector fields (their gradients).

use super::*;

/// One heat-map panel: values on a row-major `ys.len() × xs.len()` grid (rows along y).
pub struct Heat<'a> {
    /// Panel title.
    pub title: &'a str,
    /// Row-major values.
    pub values: &'a [f64],
}

/// Side-by-side heat maps over the same `(x, y)` grid, each coloured by log10 of its values
/// on its own scale (viridis-like ramp; non-finite cells grey), with `marks` drawn as
/// labelled crosses on every panel.
pub fn heatmaps(
    path: &Path,
    title: &str,
    axes: (&str, &str),
    xs: &[f64],
    ys: &[f64],
    panels: &[Heat<'_>],
    marks: &[(&str, f64, f64)],
) -> crate::Result<()> {
    ensure_font();
    crate::error::ensure!(
        !panels.is_empty() && xs.len() > 1 && ys.len() > 1,
        "nothing to plot"
    );
    plot_png(path, (620 * panels.len() as u32, 640), |root| {
        root.fill(&WHITE)?;
        let root = root.titled(title, ("sans-serif", 24))?;
        let (hx, hy) = (0.5 * (xs[1] - xs[0]).abs(), 0.5 * (ys[1] - ys[0]).abs());
        for (area, panel) in root.split_evenly((1, panels.len())).iter().zip(panels) {
            crate::error::ensure!(
                panel.values.len() == xs.len() * ys.len(),
                "grid size mismatch"
            );
            let logs: Vec<f64> = panel
                .values
                .iter()
                .map(|&v| if v > 0.0 { v.log10() } else { f64::NAN })
                .collect();
            let (lo, hi) = min_max(logs.iter().copied().filter(|v| v.is_finite()));
            let span = if hi > lo { hi - lo } else { 1.0 };
            let mut chart = ChartBuilder::on(area)
                .caption(
                    format!("{}  (log10: {lo:.2} … {hi:.2})", panel.title),
                    ("sans-serif", 16),
                )
                .margin(10)
                .x_label_area_size(36)
                .y_label_area_size(44)
                .build_cartesian_2d(
                    (xs[0] - hx)..(xs[xs.len() - 1] + hx),
                    (ys[0] - hy)..(ys[ys.len() - 1] + hy),
                )?;
            chart
                .configure_mesh()
                .disable_mesh()
                .x_desc(axes.0)
                .y_desc(axes.1)
                .label_style(("sans-serif", 12))
                .draw()?;
            chart.draw_series(ys.iter().enumerate().flat_map(|(r, &y)| {
                let logs = &logs;
                xs.iter().enumerate().map(move |(c, &x)| {
                    let v = logs[r * xs.len() + c];
                    let color = if v.is_finite() {
                        ramp((v - lo) / span)
                    } else {
                        RGBColor(150, 150, 150)
                    };
                    Rectangle::new([(x - hx, y - hy), (x + hx, y + hy)], color.filled())
                })
            }))?;
            for &(label, x, y) in marks {
                chart.draw_series(std::iter::once(Cross::new(
                    (x, y),
                    7,
                    WHITE.stroke_width(2),
                )))?;
                chart.draw_series(std::iter::once(Text::new(
                    label.to_owned(),
                    (x + hx, y + hy),
                    ("sans-serif", 14).into_font().color(&WHITE),
                )))?;
            }
        }
        Ok(())
    })
}

/// A perceptually ordered dark-blue → green → yellow ramp for `t` in [0, 1].
pub(super) fn ramp(t: f64) -> RGBColor {
    const STOPS: [(f64, [f64; 3]); 5] = [
        (0.0, [68.0, 1.0, 84.0]),
        (0.25, [59.0, 82.0, 139.0]),
        (0.5, [33.0, 145.0, 140.0]),
        (0.75, [94.0, 201.0, 98.0]),
        (1.0, [253.0, 231.0, 37.0]),
    ];
    let t = t.clamp(0.0, 1.0);
    let k = STOPS
        .iter()
        .rposition(|s| s.0 <= t)
        .unwrap_or(0)
        .min(STOPS.len() - 2);
    let (t0, c0) = STOPS[k];
    let (t1, c1) = STOPS[k + 1];
    let u = (t - t0) / (t1 - t0);
    let ch = |i: usize| (c0[i] + u * (c1[i] - c0[i])).round() as u8;
    RGBColor(ch(0), ch(1), ch(2))
}

/// One panel of [`vector_fields`]: an arrow per grid point.
pub struct Field<'a> {
    /// Panel title.
    pub title: &'a str,
    /// `(x, y, dx, dy)` per arrow; only the direction is drawn (every arrow has the same
    /// length), zero vectors as a dot.
    pub arrows: &'a [(f64, f64, f64, f64)],
    /// Colour index (plotters' 99-colour palette).
    pub colour: usize,
}

/// Side-by-side direction fields over the same square window, each arrow `arrow` long (plane
/// units) with a dot at its head, and `marks` drawn as labelled crosses on every panel.
pub fn vector_fields(
    path: &Path,
    title: &str,
    window: ((f64, f64), (f64, f64)),
    arrow: f64,
    panels: &[Field<'_>],
    marks: &[(&str, f64, f64)],
) -> crate::Result<()> {
    ensure_font();
    crate::error::ensure!(!panels.is_empty(), "nothing to plot");
    plot_png(path, (520 * panels.len() as u32, 560), |root| {
        root.fill(&WHITE)?;
        let root = root.titled(title, ("sans-serif", 22))?;
        let ((x0, x1), (y0, y1)) = window;
        for (area, panel) in root.split_evenly((1, panels.len())).iter().zip(panels) {
            let colour = Palette99::pick(panel.colour).to_rgba();
            let mut chart = ChartBuilder::on(area)
                .caption(panel.title, ("sans-serif", 16))
                .margin(10)
                .x_label_area_size(30)
                .y_label_area_size(44)
                .build_cartesian_2d(x0..x1, y0..y1)?;
            chart
                .configure_mesh()
                .disable_mesh()
                .label_style(("sans-serif", 12))
                .draw()?;
            for &(x, y, dx, dy) in panel.arrows {
                let n = dx.hypot(dy);
                if !(n.is_finite() && n > 0.0) {
                    chart.draw_series(std::iter::once(Circle::new((x, y), 1, colour.filled())))?;
                    continue;
                }
                let head = (x + arrow * dx / n, y + arrow * dy / n);
                chart.draw_series(std::iter::once(PathElement::new(
                    vec![(x, y), head],
                    colour.stroke_width(2),
                )))?;
                chart.draw_series(std::iter::once(Circle::new(head, 2, colour.filled())))?;
            }
            for &(label, x, y) in marks {
                chart.draw_series(std::iter::once(Cross::new(
                    (x, y),
                    7,
                    BLACK.stroke_width(2),
                )))?;
                chart.draw_series(std::iter::once(Text::new(
                    label.to_owned(),
                    (x, y),
                    ("sans-serif", 14),
                )))?;
            }
        }
        Ok(())
    })
}
