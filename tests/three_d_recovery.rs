//! End to end in 3-D: the Sierpiński tetrahedron's four maps, perturbed, are fitted back from
//! 8 turntable views of 64² rendered by the multi-view splat, by plain Adam steps on the
//! mean squared error over the views — and the fitted attractor must match the truth's
//! (voxel IoU ≥ 0.8 at 64³ within one voxel), where the perturbed start does not.

use ifslab::chaos::{ChaosGame, points3};
use ifslab::metrics3d::voxel_iou;
use ifslab::model::map3::{SvdMap3, flat_params, set_flat_params, sierpinski_tetrahedron};
use ifslab::render::splat3d::{Lens, MultiViewConfig, MultiViewSplat, turntable};
use ifslab::render::{Renderer, value_and_grad};

const SIDE: usize = 64;

/// How a fit runs: the splat's supersampling, σ from `sigma_start` down to `sigma_end`
/// (geometrically over the first 70 % of the steps), trajectories of 150 kept points per
/// step, Adam's steps and rate.
#[derive(Clone, Copy, Debug)]
struct Fit {
    supersample: usize,
    sigma_start: f64,
    sigma_end: f64,
    trajectories: usize,
    iterations: usize,
    lr: f64,
}

fn splat(fit: &Fit, sigma: f64, trajectories: usize) -> MultiViewSplat<SvdMap3, f32> {
    let cams = turntable(
        8,
        25.0,
        4.0,
        Lens::pinhole_fov(50f64.to_radians(), SIDE, SIDE),
        SIDE,
        SIDE,
    )
    .unwrap();
    MultiViewSplat::new(
        MultiViewConfig {
            supersample: fit.supersample,
            sigma,
            game: ChaosGame {
                trajectories,
                length: 160,
                warmup: 10,
                start_half_width: 1.0,
                seed: 0,
            },
            ..MultiViewConfig::default()
        },
        cams,
    )
    .unwrap()
}

/// The attractor of `maps` as 100 000 points.
fn attractor(maps: &[SvdMap3]) -> Vec<[f64; 3]> {
    let game = ChaosGame {
        trajectories: 500,
        length: 220,
        warmup: 20,
        start_half_width: 1.0,
        seed: 77,
    };
    let affine: Vec<_> = maps.iter().map(|m| m.to_affine()).collect();
    points3(&game, &affine, None).unwrap()
}

#[test]
fn the_sierpinski_tetrahedron_is_recovered_from_eight_views() {
    // Measured: from this start and three others (the perturbation's phase moved by 3, 7.5
    // and 11) the fit ends at IoU 0.999–1.000 from 0.16–0.20, in 8–10 s on a loaded 2-core
    // machine; 100 steps reach 0.99.
    let fit = Fit {
        supersample: 1,
        sigma_start: 1.5,
        sigma_end: 0.8,
        trajectories: 100,
        iterations: 150,
        lr: 0.03,
    };
    let clock = std::time::Instant::now();
    let truth = SvdMap3::from_code(&sierpinski_tetrahedron(), 1e-9).unwrap();
    let truth_points = attractor(&truth);
    // The target: the truth's views drawn with more points than a step uses, at the final σ.
    let target_splat = splat(&fit, fit.sigma_end, 4 * fit.trajectories);
    let seed = target_splat.sampling(&truth, 1, 0);
    let target = target_splat.forward(&truth, &seed).unwrap().0;

    // A start some way off: every parameter moved by a fixed pseudo-random amount.
    let theta0 = flat_params(&truth);
    let mut theta: Vec<f64> = theta0
        .iter()
        .enumerate()
        .map(|(k, v)| {
            let r = ((k as f64 + 1.0) * 0.618_033_988_7).fract() * 2.0 - 1.0;
            let amp = match k % 14 {
                0..8 => 0.15, // quaternions
                8..11 => 0.5, // raw singular values
                _ => 0.25,    // raw offsets
            };
            v + amp * r
        })
        .collect();
    let mut maps = truth.clone();
    set_flat_params(&mut maps, &theta).unwrap();
    let start_iou = voxel_iou(&truth_points, &attractor(&maps), 64, 1).unwrap();
    assert!(start_iou < 0.6, "the start should be off (IoU {start_iou})");

    // Plain Adam on the mean squared error over all views.
    let (b1, b2, eps) = (0.9, 0.999, 1e-8);
    let (mut m, mut v) = (vec![0.0; theta.len()], vec![0.0; theta.len()]);
    let mut last = f64::NAN;
    let decay = (fit.sigma_end / fit.sigma_start).ln() / (0.7 * fit.iterations as f64);
    for it in 0..fit.iterations as i32 {
        let sigma = (fit.sigma_start * (decay * it as f64).exp()).max(fit.sigma_end);
        let r = splat(&fit, sigma, fit.trajectories);
        let seed = r.sampling(&maps, 2, it as u64);
        let n = target.len() as f32;
        let (loss, grad) = value_and_grad(&r, &maps, &seed, |image| {
            let mut l = 0.0f64;
            let g: Vec<f32> = image
                .iter()
                .zip(&target)
                .map(|(y, t)| {
                    l += ((y - t) * (y - t)) as f64;
                    2.0 * (y - t) / n
                })
                .collect();
            Ok::<_, ifslab::Error>((l / n as f64, g))
        })
        .unwrap();
        last = loss;
        let t = it + 1;
        for k in 0..theta.len() {
            m[k] = b1 * m[k] + (1.0 - b1) * grad[k];
            v[k] = b2 * v[k] + (1.0 - b2) * grad[k] * grad[k];
            let mh = m[k] / (1.0 - b1.powi(t));
            let vh = v[k] / (1.0 - b2.powi(t));
            theta[k] -= fit.lr * mh / (vh.sqrt() + eps);
        }
        set_flat_params(&mut maps, &theta).unwrap();
    }
    let iou = voxel_iou(&truth_points, &attractor(&maps), 64, 1).unwrap();
    println!(
        "{fit:?}: voxel IoU {start_iou:.3} → {iou:.3}, last loss {last:.5}, {:.1} s",
        clock.elapsed().as_secs_f64()
    );
    assert!(
        iou >= 0.8,
        "voxel IoU {iou} after {} steps (start {start_iou}, last loss {last})",
        fit.iterations
    );
}

/// Issue 39's speed setting, measured (not asserted; run with `--ignored --nocapture`):
/// one iteration — forward and reverse — of the multi-view splat at 8 views × 128², 100 000
/// points (400 trajectories of 250 kept), 4× supersampling, σ 1, in f32, with the time
/// split between the chaos game, the splats and the reverse pass.
#[test]
#[ignore = "a measurement: cargo test --release --test three_d_recovery -- --ignored --nocapture"]
fn multi_view_iteration_time() {
    use std::time::Instant;
    let side = 128;
    let cams = turntable(
        8,
        25.0,
        4.0,
        Lens::pinhole_fov(50f64.to_radians(), side, side),
        side,
        side,
    )
    .unwrap();
    let r = MultiViewSplat::<SvdMap3, f32>::new(MultiViewConfig::default(), cams).unwrap();
    assert_eq!(r.config().game.total_points(), 100_000);
    let maps = SvdMap3::from_code(&sierpinski_tetrahedron(), 1e-9).unwrap();
    let g = vec![1e-3f32; r.planes().len()];
    let (mut fwd, mut bwd, mut game) = (Vec::new(), Vec::new(), Vec::new());
    for it in 0..25 {
        let seed = r.sampling(&maps, 0, it);
        let t0 = Instant::now();
        let tape = ifslab::chaos::Tape3::run(&r.config().game, &maps, None, seed).unwrap();
        game.push(t0.elapsed().as_secs_f64());
        drop(tape);
        let t0 = Instant::now();
        let (image, tape) = r.forward(&maps, &seed).unwrap();
        fwd.push(t0.elapsed().as_secs_f64());
        let t0 = Instant::now();
        let grad = r.backward(&maps, &seed, &tape, &g).unwrap();
        bwd.push(t0.elapsed().as_secs_f64());
        assert!(image.iter().any(|&v| v > 0.0) && grad.iter().all(|v| v.is_finite()));
    }
    let med = |v: &mut Vec<f64>| {
        v.sort_by(f64::total_cmp);
        v[v.len() / 2] * 1e3
    };
    let (f, b, c) = (med(&mut fwd), med(&mut bwd), med(&mut game));
    println!(
        "8 views × {side}², 100k points, 4× supersampling, σ 1, f32, {} threads: forward {f:.1} ms \
         (of which chaos game {c:.1} ms), backward {b:.1} ms, iteration {:.1} ms (medians of 25)",
        rayon::current_num_threads(),
        f + b
    );
}
