//! The ink guard keeps a fit from shrinking (issue 39). A random 4-map code of space (the
//! NumPy renderer's `random:13`, written out), seen by 8 turntable views drawn the way
//! `scripts/render3d_views.py` draws them — points binned into a 4× supersampled grid, a
//! cell inked when a point falls in it, 4 × 4 cells averaged — is inverted twice from the
//! visual hull's EM start with the same settings, without and with the ink guard. Without
//! it the fit lowers the image loss by drawing fewer, denser clumps than the views hold and
//! its attractor moves away from the truth; with it the renders keep the views' ink and the
//! attractor ends nearer the truth than both that fit and the hull + EM baseline.

use ifslab::chaos::{ChaosGame, points3};
use ifslab::image::Image;
use ifslab::metrics3d::voxel_iou;
use ifslab::model::map3::Affine3;
use ifslab::progress::Silent;
use ifslab::render::splat3d::{Camera, Lens, turntable};
use ifslab_strategies::problems::image3d::{
    Image3dConfig, MapChoice, Render3dConfig, Views, attractor, run_image3d,
};

const SIDE: usize = 64;

/// `random:13` of `scripts/render3d_views.py` (rounded to 4 decimals).
fn truth() -> Vec<Affine3> {
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

#[test]
fn the_ink_guard_keeps_a_fit_from_shrinking() {
    let truth = truth();
    let game = ChaosGame {
        trajectories: 4000,
        length: 100,
        warmup: 20,
        start_half_width: 1.0,
        seed: 3,
    };
    let points = points3(&game, &truth, None).unwrap();
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
    let views = Views::new(cameras, planes).unwrap();
    let truth_points = attractor(&truth, None, 1).unwrap();
    let fit = |ink: f64| {
        let cfg = Image3dConfig {
            iterations: 150,
            render: Render3dConfig {
                supersample: 4,
                sigma: 1.5,
                sigma_final: Some(1.0),
                trajectories: 400,
                ..Render3dConfig::default()
            },
            ink,
            // The setting the guard was measured at: maps drawn uniformly.
            probabilities: MapChoice::Uniform,
            ..Image3dConfig::default()
        };
        let dir = tempfile::tempdir().unwrap();
        let out = run_image3d(&cfg, &views, dir.path(), &Silent, Vec::new()).unwrap();
        let iou = |maps: &[Affine3]| {
            voxel_iou(&truth_points, &attractor(maps, None, 0).unwrap(), 64, 1).unwrap()
        };
        (iou(&out.baseline), iou(&out.maps), out.ink_ratio[1])
    };
    let (baseline, plain, plain_ink) = fit(0.0);
    let (_, guarded, guarded_ink) = fit(3.0);
    println!(
        "baseline {baseline:.3}; without the guard {plain:.3} (ink ×{plain_ink:.2}); \
         with it {guarded:.3} (ink ×{guarded_ink:.2})"
    );
    assert!(
        plain_ink < 0.9,
        "without the guard the fit was meant to shrink (ink ×{plain_ink:.2})"
    );
    assert!(
        guarded_ink > 0.95,
        "the guard must keep the views' ink (×{guarded_ink:.2})"
    );
    assert!(
        guarded > plain + 0.03 && guarded > baseline,
        "with the guard the attractor must end nearer the truth: {guarded:.3} against \
         {plain:.3} without and the baseline's {baseline:.3}"
    );
}
