//! What the segment-pattern examples share: the Koch curve they fit, renders on the unit
//! square, IoU, and the gallery picture (tiles side by side).
#![allow(dead_code)] // each example uses a part

use std::path::Path;

use ifslab::model::segment::{Pattern, SegmentMap, builtin};
use ifslab::render::image_io::{BitDepth, save_grey_png};
use ifslab::render::sdf::{SdfRaster, SdfRenderConfig, SdfView};

/// The Koch curve from (0.15, 0.4) to (0.85, 0.4) in the unit square (as the tests).
pub fn koch_truth() -> Pattern {
    let to = SegmentMap::between([0.0, 0.0], [1.0, 0.0], [0.15, 0.4], [0.85, 0.4]).unwrap();
    builtin("koch").unwrap().transformed(&to).unwrap()
}

/// `p` drawn on the unit square at `size²`, to `depth`, with width `sigma` pixels.
pub fn render(p: &Pattern, size: usize, depth: usize, sigma: f64) -> Vec<f64> {
    SdfRaster::render(
        p,
        &SdfView::unit_square(size),
        &SdfRenderConfig {
            depth,
            cutoff: None,
        },
    )
    .unwrap()
    .image(sigma)
}

/// IoU of the ink above ½ (1 for two blank images).
pub fn iou(a: &[f64], b: &[f64]) -> f64 {
    let (mut i, mut u) = (0usize, 0usize);
    for (x, y) in a.iter().zip(b) {
        let (x, y) = (*x > 0.5, *y > 0.5);
        i += (x && y) as usize;
        u += (x || y) as usize;
    }
    if u == 0 { 1.0 } else { i as f64 / u as f64 }
}

/// Tiles of `w × h` pixels (row-major, ink in [0, 1]) side by side in one 8-bit grey PNG.
pub fn save_gallery(path: &Path, tiles: &[Vec<f64>], w: usize, h: usize) {
    let width = tiles.len() * w;
    let mut px = vec![0f32; width * h];
    for (c, tile) in tiles.iter().enumerate() {
        for r in 0..h {
            for x in 0..w {
                px[r * width + c * w + x] = tile[r * w + x] as f32;
            }
        }
    }
    if let Some(parent) = path.parent() {
        std::fs::create_dir_all(parent).unwrap();
    }
    save_grey_png(path, &px, width as u32, h as u32, BitDepth::Eight, false).unwrap();
}
