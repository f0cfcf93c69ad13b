//! The multi-view image problem (issue 39): its gradient against finite differences, the
//! visual hull of a known shape, views written and read back, and bad views refused with a
//! message that says what is wrong.

use std::path::Path;

use ifslab::chaos::ChaosGame;
use ifslab::image::Image;
use ifslab::loss::MsMse;
use ifslab::model::map3::{SvdMap3, flat_params, sierpinski_tetrahedron};
use ifslab::render::splat3d::{Camera, Lens, MultiViewConfig, turntable};
use ifslab_strategies::driver::Differentiable;
use ifslab_strategies::problems::image3d::{
    HullConfig, Image3dProblem, TurntableFile, Views, encode_start, load_views, render_code,
    visual_hull, write_views,
};

fn small_render() -> MultiViewConfig {
    MultiViewConfig {
        supersample: 2,
        sigma: 1.3,
        game: ChaosGame {
            trajectories: 24,
            length: 60,
            warmup: 5,
            start_half_width: 1.0,
            seed: 0,
        },
        ..MultiViewConfig::default()
    }
}

fn small_cameras(w: usize, h: usize) -> Vec<Camera> {
    turntable(
        3,
        25.0,
        3.5,
        Lens::pinhole_fov(55f64.to_radians(), w, h),
        w,
        h,
    )
    .unwrap()
}

/// The problem's loss is the mean over views of the per-view loss (here MS-MSE with two
/// poolings) of the splat's planes plus `0.05·Σᵢ |det Mᵢ|` (`|det M| = Π_k c·sigmoid σ_k`,
/// so `∂|det M|/∂σ_k = |det M|·(1 − sigmoid σ_k)`), so `∂L/∂θ_k` must equal the central difference
/// `(L(θ + h·e_k) − L(θ − h·e_k))/2h` on the same trajectories (same stream), for every
/// entry of θ (two SVD maps: quaternions, singular values, offsets), in f64.
/// Every component of the reverse pass's gradient `grad` at `theta` against the central
/// difference of the cost on the same stream `iter`, within 2e-4 of the largest `scale`.
fn assert_central_differences(
    problem: &Image3dProblem<f64>,
    theta: &[f64],
    iter: u64,
    grad: &[f64],
    scale: f64,
) {
    let step = 1e-6;
    for k in 0..theta.len() {
        let mut plus = theta.to_vec();
        plus[k] += step;
        let mut minus = theta.to_vec();
        minus[k] -= step;
        let fd = (problem.cost(&plus, iter, 0.0).unwrap()
            - problem.cost(&minus, iter, 0.0).unwrap())
            / (2.0 * step);
        assert!(
            (fd - grad[k]).abs() <= 2e-4 * scale,
            "θ[{k}]: reverse pass {} against central difference {fd} (scale {scale})",
            grad[k]
        );
    }
}

/// Three small views of the Sierpiński tetrahedron and a start of two of its maps, their
/// linear parts scaled by `m` and their offsets by `b`.
fn tetrahedron_views_and_start(m: f64, b: f64) -> (Views, Vec<SvdMap3>) {
    let cams = small_cameras(20, 16);
    let truth = sierpinski_tetrahedron();
    let target = render_code(&truth, &cams, &small_render(), None, 9).unwrap();
    let views = Views::new(cams, target).unwrap();
    let start = truth[..2]
        .iter()
        .map(|map| {
            let mut map = *map;
            map.m *= m;
            map.b *= b;
            encode_start(&map).unwrap()
        })
        .collect();
    (views, start)
}

#[test]
fn the_gradient_matches_central_differences() {
    let (views, start) = tetrahedron_views_and_start(1.2, 0.7);
    let problem = Image3dProblem::<f64>::new(&start, &views, small_render(), MsMse::new(2), 5)
        .unwrap()
        .with_volume(0.05)
        .unwrap();
    let theta = flat_params(&start);
    let iter = 3;
    let eval = problem.evaluate(&theta, iter).unwrap();
    assert_eq!(eval.grad.len(), 28);
    let scale = eval.grad.iter().fold(0.0f64, |m, g| m.max(g.abs()));
    assert!(
        scale > 1e-3,
        "the loss should depend on θ (largest |∂L/∂θ| {scale})"
    );
    assert_central_differences(&problem, &theta, iter, &eval.grad, scale);
    // The loss the evaluation reports is the cost on the same stream, and its terms are the
    // views' loss and the volume.
    let cost = problem.cost(&theta, iter, 0.0).unwrap();
    assert!((cost - eval.loss).abs() <= 1e-12 * (1.0 + cost));
    let volume: f64 = start
        .iter()
        .map(|m| m.singular_values().iter().product::<f64>())
        .sum();
    assert_eq!(eval.terms[1], ("volume", volume));
    assert!((eval.terms[0].1 + 0.05 * volume - eval.loss).abs() <= 1e-12);
}

/// The ink guard: two of the tetrahedron's four maps, shrunk, draw less ink than its views
/// hold, so the term `w·mean_v max(0, 1 − s − inkᵥ/targetᵥ)²` is positive and its
/// gradient (a constant per view's pixels, through the splat's reverse pass) must match
/// central differences like the rest of the loss; with the slack above the missing
/// fraction it is 0 and so is its gradient.
#[test]
fn the_ink_guard_gradient_matches_central_differences() {
    let (views, start) = tetrahedron_views_and_start(0.8, 1.0);
    let make = |ink: f64, slack: f64| {
        Image3dProblem::<f64>::new(&start, &views, small_render(), MsMse::new(0), 5)
            .unwrap()
            .with_ink(ink, slack)
            .unwrap()
    };
    let theta = flat_params(&start);
    let iter = 3;
    let plain = make(0.0, 0.0).evaluate(&theta, iter).unwrap();
    let problem = make(2.0, 0.0);
    let eval = problem.evaluate(&theta, iter).unwrap();
    let ink = eval.terms[2].1;
    assert!(ink > 0.05, "two shrunk maps should lack ink: term {ink}");
    assert!((plain.terms[0].1 + 2.0 * ink - eval.loss).abs() <= 1e-12);
    let scale = eval.grad.iter().fold(0.0f64, |m, g| m.max(g.abs()));
    assert_central_differences(&problem, &theta, iter, &eval.grad, scale);
    // The guard pushes ink out: its gradient differs from the plain loss's.
    let moved = eval
        .grad
        .iter()
        .zip(&plain.grad)
        .fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
    assert!(
        moved > 1e-3 * scale,
        "the ink term left the gradient as it was"
    );
    // A slack of 0.95 forgives the missing ink: the same loss and gradient as without.
    let forgiven = make(2.0, 0.95).evaluate(&theta, iter).unwrap();
    assert_eq!(forgiven.terms[2].1, 0.0);
    assert_eq!(forgiven.grad, plain.grad);
    assert!(make(0.0, 0.0).with_ink(1.0, 1.0).is_err());
    assert!(make(0.0, 0.0).with_ink(f64::NAN, 0.0).is_err());
}

/// Orthographic views of a solid ball of radius 0.5 at the origin: every view's silhouette
/// is a disc of radius 0.5. The hull must hold the ball (every voxel whose centre lies
/// within 0.45 of the origin) and lie inside the cylinders the views cut: nothing further
/// than 0.5 plus a voxel's diagonal from any view's axis through the origin. With 8 views
/// at 25° elevation its volume is within 1.6 times the ball's.
#[test]
fn the_visual_hull_of_a_ball_is_a_ball() {
    let side = 64;
    let extent = 2.4;
    let cams = turntable(
        8,
        25.0,
        4.0,
        Lens::orthographic(extent, side, side),
        side,
        side,
    )
    .unwrap();
    let px = extent / side as f64;
    let disc: Vec<f32> = (0..side * side)
        .map(|i| {
            let (x, y) = ((i % side) as f64 + 0.5, (i / side) as f64 + 0.5);
            let (u, v) = ((x - side as f64 / 2.0) * px, (y - side as f64 / 2.0) * px);
            if u * u + v * v <= 0.25 { 1.0 } else { 0.0 }
        })
        .collect();
    let planes: Vec<f32> = (0..cams.len()).flat_map(|_| disc.iter().copied()).collect();
    let planes = Image::new(side as u32, side as u32, cams.len() as u32, planes).unwrap();
    let views = Views::new(cams.clone(), planes).unwrap();
    let cfg = HullConfig {
        resolution: 48,
        ..HullConfig::default()
    };
    let hull = visual_hull(&views, &cfg).unwrap();
    let voxel = hull.voxel();
    let centres = hull.centres();
    let r = |p: &[f64; 3]| (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt();
    // Containment: every voxel of the ball is kept.
    let n = cfg.resolution;
    let mut inside = 0;
    for i in 0..n * n * n {
        let c = [i % n, (i / n) % n, i / (n * n)].map(|j| -1.0 + (j as f64 + 0.5) * voxel);
        if r(&c) <= 0.45 {
            inside += 1;
            assert!(
                hull.kept.binary_search(&i).is_ok(),
                "voxel at {c:?} (r {:.3}) was carved",
                r(&c)
            );
        }
    }
    // Tightness: within each view's cylinder, up to the voxel test's slack.
    let slack = 0.5 + 3f64.sqrt() * voxel + px;
    for c in &centres {
        for cam in &cams {
            let e = cam.position();
            let d = r(&e);
            let a = [e[0] / d, e[1] / d, e[2] / d];
            let along = c[0] * a[0] + c[1] * a[1] + c[2] * a[2];
            let off = (r(c).powi(2) - along * along).max(0.0).sqrt();
            assert!(
                off <= slack,
                "kept voxel {c:?} is {off:.3} from a view's axis"
            );
        }
    }
    let ball = 4.0 / 3.0 * std::f64::consts::PI * 0.125;
    let volume = centres.len() as f64 * voxel.powi(3);
    assert!(inside > 1000);
    assert!(
        volume < 1.6 * ball,
        "hull volume {volume:.4} against the ball's {ball:.4}"
    );
}

fn tetra_views(dir: &Path, side: usize) -> TurntableFile {
    let spec = TurntableFile {
        views: 4,
        elevation_deg: 25.0,
        distance: 4.0,
        fov_x_deg: Some(50.0),
        orthographic_extent: None,
        files: None,
    };
    let cams = spec.cameras(side, side).unwrap();
    let planes = render_code(&sierpinski_tetrahedron(), &cams, &small_render(), None, 1).unwrap();
    write_views(dir, &spec, &planes).unwrap();
    spec
}

/// Views written as PNGs with a turntable.json read back as the same cameras and, within
/// 8-bit rounding, the same planes (the PNG holds dark ink on white; the reader turns it
/// round).
#[test]
fn written_views_read_back() {
    let dir = tempfile::tempdir().unwrap();
    let side = 24;
    let spec = tetra_views(dir.path(), side);
    let views = load_views(dir.path()).unwrap();
    assert_eq!(views.cameras, spec.cameras(side, side).unwrap());
    let cams = spec.cameras(side, side).unwrap();
    let planes = render_code(&sierpinski_tetrahedron(), &cams, &small_render(), None, 1).unwrap();
    let ink = planes.values.iter().cloned().fold(0.0f32, f32::max);
    let worst = views
        .image
        .values
        .iter()
        .zip(&planes.values)
        .map(|(a, b)| (a - b / ink).abs())
        .fold(0.0f32, f32::max);
    assert!(worst < 0.02, "read back off by {worst}");
}

fn refusal(dir: &Path) -> String {
    match load_views(dir) {
        Ok(v) => panic!("{} views were accepted", v.len()),
        Err(e) => e.to_string(),
    }
}

#[test]
fn bad_views_are_refused_with_a_reason() {
    let side = 24;
    // No camera file.
    let d = tempfile::tempdir().unwrap();
    tetra_views(d.path(), side);
    std::fs::remove_file(d.path().join("turntable.json")).unwrap();
    assert!(
        refusal(d.path()).contains("no cameras"),
        "{}",
        refusal(d.path())
    );

    // No picture at all.
    let d = tempfile::tempdir().unwrap();
    std::fs::write(
        d.path().join("turntable.json"),
        r#"{"views": 8, "elevation_deg": 25, "distance": 4, "fov_x_deg": 50}"#,
    )
    .unwrap();
    assert!(
        refusal(d.path()).contains("no PNG"),
        "{}",
        refusal(d.path())
    );

    // A missing picture.
    let d = tempfile::tempdir().unwrap();
    tetra_views(d.path(), side);
    std::fs::remove_file(d.path().join("view_002.png")).unwrap();
    let m = refusal(d.path());
    assert!(m.contains("view_002.png") && m.contains("missing"), "{m}");

    // Views of different sizes.
    let d = tempfile::tempdir().unwrap();
    tetra_views(d.path(), side);
    ifslab::image::Image::grey(30, 24, vec![1.0; 30 * 24])
        .unwrap()
        .save_png(&d.path().join("view_001.png"))
        .unwrap();
    let m = refusal(d.path());
    assert!(m.contains("30×24") && m.contains("same size"), "{m}");

    // NeRF transforms with a NaN, a scaled (degenerate) pose, a missing file.
    let d = tempfile::tempdir().unwrap();
    tetra_views(d.path(), side);
    std::fs::remove_file(d.path().join("turntable.json")).unwrap();
    let nerf = |m: &str, file: &str| {
        format!(
            r#"{{"camera_angle_x": 0.87, "frames": [
                {{"file_path": "view_000", "transform_matrix": [[1,0,0,0],[0,1,0,0],[0,0,1,4],[0,0,0,1]]}},
                {{"file_path": "{file}", "transform_matrix": {m}}}]}}"#
        )
    };
    let path = d.path().join("transforms.json");
    std::fs::write(
        &path,
        nerf("[[1,0,0,0],[0,1,0,0],[0,0,1,NaN],[0,0,0,1]]", "view_001"),
    )
    .unwrap();
    let m = refusal(d.path());
    assert!(m.contains("transforms.json"), "{m}");
    std::fs::write(
        &path,
        nerf("[[2,0,0,0],[0,2,0,0],[0,0,2,4],[0,0,0,1]]", "view_001"),
    )
    .unwrap();
    let m = refusal(d.path());
    assert!(m.contains("frames[1]") && m.contains("orthonormal"), "{m}");
    std::fs::write(
        &path,
        nerf("[[1,0,0,0],[0,1,0,0],[0,0,1,4],[0,0,0,1]]", "nowhere"),
    )
    .unwrap();
    let m = refusal(d.path());
    assert!(m.contains("nowhere") && m.contains("missing"), "{m}");
    // And the good file is read.
    std::fs::write(
        &path,
        nerf("[[0,0,1,4],[1,0,0,0],[0,1,0,0],[0,0,0,1]]", "view_001"),
    )
    .unwrap();
    assert_eq!(load_views(d.path()).unwrap().len(), 2);

    // A turntable with a degenerate lens.
    let d = tempfile::tempdir().unwrap();
    tetra_views(d.path(), side);
    std::fs::write(
        d.path().join("turntable.json"),
        r#"{"views": 4, "elevation_deg": 25, "distance": 4, "fov_x_deg": 0}"#,
    )
    .unwrap();
    assert!(
        refusal(d.path()).contains("fov_x_deg"),
        "{}",
        refusal(d.path())
    );
    // A turntable with more views than pictures.
    std::fs::write(
        d.path().join("turntable.json"),
        r#"{"views": 6, "elevation_deg": 25, "distance": 4, "fov_x_deg": 50}"#,
    )
    .unwrap();
    assert!(
        refusal(d.path()).contains("6 views but 4 pictures"),
        "{}",
        refusal(d.path())
    );
}

/// The hull of views that share no ink (cameras that do not belong to the pictures) is
/// refused, saying what to check.
#[test]
fn an_empty_hull_is_refused() {
    let cams = small_cameras(16, 16);
    let mut planes = vec![0.0f32; 3 * 256];
    planes[0] = 1.0; // one inked corner pixel in the first view only
    let views = Views::new(cams, Image::new(16, 16, 3, planes).unwrap()).unwrap();
    let e = visual_hull(&views, &HullConfig::default())
        .unwrap_err()
        .to_string();
    assert!(e.contains("visual hull is empty"), "{e}");
}

/// Views held out of a fit are spread around the turntable, the rest are fitted, and a
/// split that leaves nothing to fit (or names a view past the last) is refused.
#[test]
fn held_out_views_are_spread_and_checked() {
    let (w, h) = (12, 10);
    let cams = turntable(
        8,
        25.0,
        3.5,
        Lens::pinhole_fov(55f64.to_radians(), w, h),
        w,
        h,
    )
    .unwrap();
    let planes: Vec<f32> = (0..8 * w * h).map(|i| (i / (w * h)) as f32 / 8.0).collect();
    let views = Views::new(cams, Image::new(w as u32, h as u32, 8, planes).unwrap()).unwrap();
    let (fit, held) = views.hold_out(2).unwrap();
    assert_eq!(held, vec![2, 6]);
    assert_eq!(fit, vec![0, 1, 3, 4, 5, 7]);
    let sub = views.subset(&held).unwrap();
    assert_eq!(sub.len(), 2);
    assert_eq!(sub.plane(1), views.plane(6));
    assert_eq!(sub.cameras[0].pose(), views.cameras[2].pose());
    assert!(
        views
            .hold_out(8)
            .unwrap_err()
            .to_string()
            .contains("hold_out")
    );
    assert!(
        views
            .subset(&[1, 8])
            .unwrap_err()
            .to_string()
            .contains("view 8")
    );
}
