//! `ifslab serve`'s density tiles share one tone map: neighbouring tiles of a level agree
//! along their shared edge, a tile's mean density per unit area is its four children's, and
//! a tile 2²⁰ deep is still drawn.

use ifslab::progress::Progress;
use ifslab_experiments::serve::{
    Site, TileMode, TileOptions, TileRenderer, TileRequest, TileSource, View,
};

/// A progress that never cancels.
struct Quiet;
impl Progress for Quiet {}

/// The code view of a built-in code, `points` per tile.
fn site(name: &str, points: u64) -> Site {
    Site::load(
        name,
        TileOptions {
            points,
            flame_samples: points,
            seed: 0,
        },
    )
    .unwrap()
}

fn renderer(site: &Site) -> &TileRenderer {
    match site.views.last().unwrap() {
        View::Tiles {
            renderer: TileSource::Code(r),
            ..
        } => r,
        _ => panic!("a code's tiled view"),
    }
}

fn request(site: &Site, level: u32, x: u64, y: u64) -> TileRequest {
    TileRequest::parse(
        &format!("level={level}&x={x}&y={y}&mode=density&cmap=grey"),
        &site.tiling,
        &[TileMode::Coverage, TileMode::Density],
    )
    .unwrap()
}

/// A density tile's tones in [0, 1] (`None`: not inked), read back from the grey map
/// (grey = 255 · (¼ + ¾ · tone)).
fn tones(r: &TileRenderer, req: &TileRequest) -> Vec<Option<f64>> {
    let rgba = r.render_rgba(req, &Quiet).unwrap();
    rgba.chunks_exact(4)
        .map(|px| (px[3] == 255).then(|| (px[0] as f64 / 255.0 - 0.25) / 0.75))
        .collect()
}

/// Neighbouring tiles drawn apart meet without a seam: along every shared edge of the
/// fern's level-2 and level-3 tiles that both sides ink (16 rows or more), the mean tone of
/// the left tile's last column is the right tile's first column's, within 0.05 (Poisson
/// noise of a million points a tile and the density's change over one pixel). Each tile
/// normalised by its own brightest pixel (the viewer before its shared tone map) missed by
/// 0.133 here (level 3, tiles (2, 5) and (3, 5)).
#[test]
fn neighbouring_density_tiles_agree_along_their_edge() {
    let s = site("fern", 1_000_000);
    let r = renderer(&s);
    let mut worst = (0.0f64, String::new());
    let mut edges = 0;
    for level in [2u32, 3] {
        let n = 1u64 << level;
        for y in 0..n {
            let row: Vec<Vec<Option<f64>>> = (0..n)
                .map(|x| tones(r, &request(&s, level, x, y)))
                .collect();
            let side = 256;
            for x in 0..n as usize - 1 {
                let (left, right) = (&row[x], &row[x + 1]);
                let pairs: Vec<(f64, f64)> = (0..side)
                    .filter_map(|i| Some((left[i * side + side - 1]?, right[i * side]?)))
                    .collect();
                if pairs.len() < 16 {
                    continue;
                }
                edges += 1;
                let mean = |f: fn(&(f64, f64)) -> f64| {
                    pairs.iter().map(f).sum::<f64>() / pairs.len() as f64
                };
                let gap = (mean(|p| p.0) - mean(|p| p.1)).abs();
                if gap > worst.0 {
                    worst = (
                        gap,
                        format!(
                            "level {level}, tiles ({x}, {y}) and ({}, {y}), {} rows",
                            x + 1,
                            pairs.len()
                        ),
                    );
                }
            }
        }
    }
    eprintln!(
        "{edges} shared edges; the largest gap {:.3} at {}",
        worst.0, worst.1
    );
    assert!(edges >= 4, "{edges} shared edges inked on both sides");
    assert!(worst.0 < 0.05, "tone gap {:.3} at {}", worst.0, worst.1);
}

/// A tile's mean density per unit area is its four children's: the level-0 tile's mass
/// (its density summed over its area) against its four level-1 tiles' (drawn through the
/// deep-zoom words, whose mass the sampler reports), and one level-2 tile's against its
/// four level-3 tiles', for the Sierpiński triangle and the fern (unequal probabilities),
/// within 1 % (measured: 0.24 % at most).
#[test]
fn a_tiles_mean_density_is_its_four_childrens() {
    for (name, level, x, y) in [
        ("sierpinski", 0u32, 0u64, 0u64),
        ("fern", 0, 0, 0),
        ("fern", 2, 1, 1),
    ] {
        let s = site(name, 1_000_000);
        let r = renderer(&s);
        let tile =
            |l: u32, x: u64, y: u64| r.render_density(&request(&s, l, x, y), &Quiet).unwrap();
        let parent = tile(level, x, y);
        let summed: f64 = parent.density.iter().sum::<f64>() * parent.pixel_area;
        assert!(
            (summed - parent.mass).abs() <= 1e-9 * parent.mass,
            "{name}: the densities sum to the mass ({summed} against {})",
            parent.mass
        );
        let children: f64 = (0..4)
            .map(|k| tile(level + 1, 2 * x + k % 2, 2 * y + k / 2).mass)
            .sum();
        // The same area: the parent's mean density over its four children's.
        let ratio = parent.mass / children;
        eprintln!(
            "{name} level {level} ({x}, {y}): mass {:.5}, children {children:.5}, ratio {ratio:.4}",
            parent.mass
        );
        assert!(
            parent.mass > 0.01,
            "{name}: the tile holds part of the attractor"
        );
        assert!(
            (ratio - 1.0).abs() < 0.01,
            "{name} level {level}: ratio {ratio}"
        );
    }
}

/// The top tile keeps the look it had when each tile was normalised by its own brightest
/// pixel: the shared tone map is set by it (its floor one point in a pixel, its top the
/// densest pixel), so its colours are those of the renderer's density values.
#[test]
fn the_top_tile_is_the_renderers_density_picture() {
    let s = site("fern", 1_000_000);
    let r = renderer(&s);
    let req = request(&s, 0, 0, 0);
    let rgba = r.render_rgba(&req, &Quiet).unwrap();
    let cfg = ifslab::render::RenderConfig {
        width: 256,
        height: 256,
        points: 1_000_000,
        mode: ifslab::render::RenderMode::Density,
        view: ifslab::render::View::Window(s.tiling.base()),
        zoom: Some(s.tiling.zoom(0, 0, 0)),
        deep_zoom: true,
        ..Default::default()
    };
    let code = ifslab::model::library::builtin("fern").unwrap();
    let maps = code.affine2().unwrap();
    let probs = code.evaluation_probabilities().unwrap();
    let raster = ifslab::render::render(&maps, &probs, &cfg, None).unwrap();
    let mut off = 0;
    for (px, &v) in rgba.chunks_exact(4).zip(&raster.values) {
        assert_eq!(px[3] == 255, v > 0.0, "inked alike");
        if v > 0.0 {
            let g = (255.0 * (0.25 + 0.75 * v as f64)).round();
            off = off.max((px[0] as f64 - g).abs() as u32);
        }
    }
    assert!(off <= 1, "grey levels off by {off}");
    // The map's ends: one point in a pixel, and the densest pixel's count of points.
    let tone = r.tone_map(&Quiet).unwrap();
    let top = raster.stats.max_count as f64;
    assert!(
        (tone.top / tone.floor - top).abs() <= 1e-9 * top,
        "{tone:?}: {top} points at the top"
    );
}

/// Deep tiles are drawn: 2¹² and 2²⁰ deep on the fern and the triangle, a tile is inked,
/// its densities finite and positive where inked, its mass finite, positive and below the
/// whole's.
#[test]
fn deep_density_tiles_are_inked_and_finite() {
    let h = 3f64.sqrt() / 2.0;
    let t = 0.3141592653589793;
    for (name, level, p) in [
        ("sierpinski", 20u32, [0.5 * t, h * t]),
        ("sierpinski", 12, [0.5 * t, h * t]),
        ("fern", 12, [0.0, 0.0]),
    ] {
        let s = site(name, 1_000_000);
        let r = renderer(&s);
        let p = match name {
            // A point of the fern: its stem's map's fixed point's image under the big map.
            "fern" => {
                let code = ifslab::model::library::builtin("fern").unwrap();
                let maps = code.affine2().unwrap();
                let mut q = [0.0, 0.0];
                for i in 0..60 {
                    q = ifslab::model::Map::apply(&maps[[1, 1, 2, 1, 3][i % 5]], q);
                }
                q
            }
            _ => p,
        };
        let base = s.tiling.base();
        let ts = base.size()[0] / (level as f64).exp2();
        let (x, y) = (
            ((p[0] - base.min[0]) / ts).floor() as u64,
            ((base.max[1] - p[1]) / ts).floor() as u64,
        );
        let req = request(&s, level, x, y);
        let tile = r.render_density(&req, &Quiet).unwrap();
        let inked = tile.density.iter().filter(|&&d| d > 0.0).count();
        assert!(inked >= 100, "{name} level {level}: {inked} pixels inked");
        assert!(
            tile.density.iter().all(|d| d.is_finite() && *d >= 0.0),
            "{name} level {level}"
        );
        assert!(
            tile.mass.is_finite() && tile.mass > 0.0 && tile.mass < 1e-3,
            "{name} level {level}: mass {}",
            tile.mass
        );
        let rgba = r.render_rgba(&req, &Quiet).unwrap();
        let n = rgba.chunks_exact(4).filter(|px| px[3] == 255).count();
        assert_eq!(
            n, inked,
            "{name} level {level}: the picture inks the pixels with points"
        );
        eprintln!(
            "{name} level {level} ({x}, {y}): {inked} pixels, mass {:.3e}",
            tile.mass
        );
    }
}
