//! Crisp views of a random code of space, drawn the way `scripts/render3d_views.py` draws
//! them, for the multi-view tests.

use ifslab::chaos::{ChaosGame, points3};
use ifslab::image::Image;
use ifslab::model::map3::Affine3;
use ifslab::render::splat3d::{Camera, Lens, turntable};
use ifslab_strategies::problems::image3d::Views;

pub const SIDE: usize = 64;

/// `random:13` of `scripts/render3d_views.py` (rounded to 4 decimals).
pub fn truth() -> Vec<Affine3> {
    vec![
        Affine3::new(
            [
                [-0.5273, 0.0787, 0.1666],
                [-0.1556, 0.0459, -0.5264],
                [0.0786, 0.5443, 0.0111],
            ],
            [0.3054, 0.34, -0.3917],
        ),
        Affine3::new(
            [
                [0.3156, -0.2187, 0.351],
                [-0.2616, 0.2866, 0.1442],
                [0.2875, 0.3768, -0.1555],
            ],
            [-0.4575, -0.1173, 0.0461],
        ),
        Affine3::new(
            [
                [0.248, -0.2841, -0.1632],
                [-0.0512, -0.122, 0.3043],
                [-0.3058, -0.2628, -0.0793],
            ],
            [-0.238, -0.4165, 0.5257],
        ),
        Affine3::new(
            [
                [0.0926, -0.225, 0.3812],
                [-0.4601, 0.1715, 0.2131],
                [-0.2561, -0.3542, -0.1467],
            ],
            [0.1133, -0.1885, -0.3234],
        ),
    ]
}

/// Crisp coverage of `points` through `camera`: a cell of the 4× grid is inked when a
/// point falls in it, 4 × 4 cells averaged (the NumPy renderer's rasteriser).
fn crisp_view(points: &[[f64; 3]], camera: &Camera) -> Vec<f32> {
    let ss = 4;
    let n = SIDE * ss;
    let mut grid = vec![false; n * n];
    for &p in points {
        if let Some([u, v]) = camera.project(p) {
            let (i, j) = ((u * ss as f64).floor(), (v * ss as f64).floor());
            if i >= 0.0 && j >= 0.0 && (i as usize) < n && (j as usize) < n {
                grid[j as usize * n + i as usize] = true;
            }
        }
    }
    let mut out = vec![0.0f32; SIDE * SIDE];
    for y in 0..n {
        for x in 0..n {
            if grid[y * n + x] {
                out[(y / ss) * SIDE + x / ss] += 1.0 / (ss * ss) as f32;
            }
        }
    }
    out
}

/// 8 turntable views of `maps` at 64² (25° elevation, distance 2.6, a 50° pinhole), each
/// drawn crisply ([`crisp_view`]) from 400 000 points of the attractor (maps uniformly).
pub fn crisp_turntable(maps: &[Affine3]) -> Views {
    let game = ChaosGame {
        trajectories: 4000,
        length: 100,
        warmup: 20,
        start_half_width: 1.0,
        seed: 3,
    };
    let points = points3(&game, maps, None).unwrap();
    let cameras = turntable(
        8,
        25.0,
        2.6,
        Lens::pinhole_fov(50f64.to_radians(), SIDE, SIDE),
        SIDE,
        SIDE,
    )
    .unwrap();
    let planes: Vec<f32> = cameras
        .iter()
        .flat_map(|c| crisp_view(&points, c))
        .collect();
    let n = cameras.len() as u32;
    let planes = Image::new(SIDE as u32, SIDE as u32, n, planes).unwrap();
    Views::new(cameras, planes).unwrap()
}
