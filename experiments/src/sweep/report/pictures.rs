//! The report's pictures: loss curves of the runs grouped by an axis, and a grid of the runs' renders.

use super::*;

/// The pictures of a run folder the grid shows: its target (the truth where there is one)
/// and its result.
pub(super) const GRID_PICTURES: [&str; 3] = ["truth.png", "target.png", "render.png"];

/// A run's loss curve with the position of its label on the axis.
pub(super) type Curve<'a> = (usize, &'a Row, Vec<(f64, f64)>);

/// The loss curves of the finished runs, one colour per value of `axis`: every run's curve
/// when there are at most 12, else the mean curve of each value.
pub(super) fn loss_curves(
    c: &Collected,
    group: &[String],
    cats: &[String],
    out: &Path,
) -> crate::Result<Option<String>> {
    let axis = group.join(" × ");
    let curves: Vec<Curve<'_>> = c
        .rows
        .iter()
        .filter_map(|r| {
            let curve = r.loss_curve()?;
            Some((cats.iter().position(|x| *x == c.key(group, r))?, r, curve))
        })
        .collect();
    if curves.is_empty() {
        return Ok(None);
    }
    let names: Vec<String>;
    let mut series = Vec::new();
    if curves.len() <= 12 {
        names = curves.iter().map(|(_, r, _)| r.name.clone()).collect();
        for ((_, _, pts), n) in curves.iter().zip(&names) {
            series.push(Series {
                name: n,
                points: pts.clone(),
            });
        }
    } else {
        names = cats.iter().map(|v| format!("{v} (mean)")).collect();
        for (ci, n) in names.iter().enumerate() {
            let mine: Vec<&Vec<(f64, f64)>> =
                curves.iter().filter(|x| x.0 == ci).map(|x| &x.2).collect();
            let Some(shortest) = mine.iter().map(|p| p.len()).min() else {
                continue;
            };
            let points = (0..shortest)
                .map(|i| {
                    let y = mine.iter().map(|p| p[i].1).sum::<f64>() / mine.len() as f64;
                    (mine[0][i].0, y)
                })
                .collect();
            series.push(Series { name: n, points });
        }
    }
    let file = format!("loss_by_{}.png", file_word(&group.join("+")));
    line_chart(
        &out.join(&file),
        &format!("loss by {axis}"),
        "iteration",
        "loss",
        &series,
        true,
    )?;
    Ok(Some(file))
}

/// A grid with one row per finished run (at most `max`): its target (or ground truth) and
/// its result, captioned with its name. `None` when no run has pictures.
pub(super) fn picture_grid(
    c: &Collected,
    path: &Path,
    max: usize,
) -> crate::Result<Option<String>> {
    const TILE: u32 = 128;
    const CAPTION: u32 = 220;
    const GAP: u32 = 4;
    let load = |p: PathBuf| -> Option<GrayImage> {
        let img = image::open(&p).ok()?.to_luma8();
        Some(image::imageops::resize(
            &img,
            TILE,
            TILE,
            image::imageops::FilterType::Triangle,
        ))
    };
    let mut rows: Vec<(String, Option<GrayImage>, Option<GrayImage>)> = Vec::new();
    for r in c.rows.iter().filter(|r| r.dir.is_some()).take(max) {
        let d = r.dir.as_deref().unwrap_or(Path::new(""));
        let [truth, target, result] = GRID_PICTURES.map(|f| d.join(f));
        let target = load(truth).or_else(|| load(target));
        let result = load(result);
        if target.is_some() || result.is_some() {
            rows.push((r.name.clone(), target, result));
        }
    }
    if rows.is_empty() {
        return Ok(None);
    }
    let w = CAPTION + 2 * (TILE + GAP);
    let h = 24 + rows.len() as u32 * (TILE + GAP);
    let mut img = RgbImage::from_pixel(w, h, image::Rgb([255, 255, 255]));
    for (i, (_, t, r)) in rows.iter().enumerate() {
        let y0 = 24 + i as u32 * (TILE + GAP);
        for (j, tile) in [t, r].into_iter().enumerate() {
            let Some(tile) = tile else { continue };
            let x0 = CAPTION + j as u32 * (TILE + GAP);
            for (x, y, p) in tile.enumerate_pixels() {
                img.put_pixel(x0 + x, y0 + y, image::Rgb([p[0], p[0], p[0]]));
            }
        }
    }
    let mut buf = img.into_raw();
    ensure_font();
    {
        let root = BitMapBackend::with_buffer(&mut buf, (w, h)).into_drawing_area();
        let font = ("sans-serif", 14).into_font().color(&BLACK);
        root.draw(&Text::new("target", (CAPTION as i32 + 4, 4), font.clone()))?;
        root.draw(&Text::new(
            "result",
            ((CAPTION + TILE + GAP) as i32 + 4, 4),
            font.clone(),
        ))?;
        for (i, (name, _, _)) in rows.iter().enumerate() {
            let y = 24 + i as i32 * (TILE + GAP) as i32 + TILE as i32 / 2 - 7;
            let mut n = name.clone();
            if n.chars().count() > 34 {
                n = n.chars().take(33).collect::<String>() + "…";
            }
            root.draw(&Text::new(n, (6, y), font.clone()))?;
        }
        root.present()?;
    }
    crate::plot::write_rgb_png(path, (w, h), &buf)?;
    Ok(path.file_name().map(|f| f.to_string_lossy().into_owned()))
}
