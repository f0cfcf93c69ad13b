//! Issue 39's core: maps of space and their vector–Jacobian products, the 3-D chaos game
//! with its tape, cameras, the multi-view splat through the `Renderer` trait, and the 3-D
//! scores (voxel IoU with a tolerance, Chamfer distance).
//!
//! Gradients are checked in f64 against central differences on problems small enough to
//! be exact; invariants (contractivity, thread-count independence) by property tests.

#[path = "common/renderer_check.rs"]
mod renderer_check;

use std::path::Path;

use ifslab::Error;
use ifslab::chaos::{ChaosGame, Tape3, points3};
use ifslab::metrics3d::{VoxelBox, chamfer_distance, nearest_distances, voxel_iou, voxel_iou_in};
use ifslab::model::map3::{
    Affine3, DiffMap3, Map, SVD3_PARAMS, Similitude3, SvdMap3, flat_params, set_flat_params,
    sierpinski_tetrahedron, vjp_check,
};
use ifslab::render::splat::Blend;
use ifslab::render::splat3d::{
    Camera, Lens, MultiViewConfig, MultiViewSplat, parse_transforms, turntable,
};
use ifslab::render::{Draws, Renderer};
use proptest::prelude::*;
use renderer_check::reverse_pass_matches_finite_differences;

/// A θ of an SVD map of space: quaternions, raw singular values, raw offsets.
fn svd_theta(k: usize) -> Vec<f64> {
    (0..SVD3_PARAMS)
        .map(|i| ((i * 7 + k * 13) as f64 * 0.618_033_988_7).fract() * 2.0 - 1.0)
        .collect()
}

fn assert_vjps_match<M: DiffMap3>(name: &str, map: &M) {
    for (x, lambda) in [
        ([0.3, -0.7, 1.1], [1.0, -0.5, 0.25]),
        ([-1.2, 0.4, 0.05], [-0.3, 0.8, 1.4]),
    ] {
        let c = vjp_check(map, x, lambda, 1e-6);
        let tol = 1e-8 * (1.0 + c.scale);
        assert!(c.point < tol, "{name}: ∂/∂x off by {}", c.point);
        assert!(c.params < tol, "{name}: ∂/∂θ off by {}", c.params);
        assert!(c.fused < 1e-12, "{name}: fused vjp differs by {}", c.fused);
        assert!(c.scale > 0.1, "{name}: the check should see a gradient");
    }
}

/// `λᵀ∂f/∂x` and `λᵀ∂f/∂θ` of the three map types against central differences: for the
/// affine map `∂(λᵀ(Mx + b))/∂M = λxᵀ`, `∂/∂b = λ`, `∂/∂x = Mᵀλ`; for the SVD map the chain
/// through both quaternions, the sigmoid and tanh; for the similitude through s, q and t.
#[test]
fn the_maps_of_space_have_exact_vector_jacobian_products() {
    assert_vjps_match(
        "affine",
        &Affine3::new(
            [[0.4, -0.1, 0.2], [0.05, 0.3, -0.2], [0.1, 0.1, 0.5]],
            [0.2, -0.3, 0.1],
        ),
    );
    for reflect in [false, true] {
        for k in 0..3 {
            let m = SvdMap3::new(&svd_theta(k), reflect).unwrap();
            assert_vjps_match(&format!("svd {k}, reflect {reflect}"), &m);
        }
        assert_vjps_match(
            &format!("similitude, reflect {reflect}"),
            &Similitude3::new(0.6, [0.3, -1.2, 0.8, 0.4], reflect, [0.1, 0.2, -0.4]),
        );
    }
}

#[test]
fn an_svd_map_decodes_as_documented_and_encodes_back() {
    let theta = svd_theta(1);
    let m = SvdMap3::new(&theta, false).unwrap();
    let a = m.to_affine();
    let mut sv = m.singular_values();
    sv.sort_by(|x, y| y.total_cmp(x));
    let got = a.singular_values();
    for k in 0..3 {
        assert!(
            (sv[k] - got[k]).abs() < 1e-12,
            "singular values {sv:?} vs {got:?}"
        );
    }
    assert!(a.m.determinant() > 0.0);
    for r in 0..3 {
        assert!((a.b[r] - theta[11 + r].tanh()).abs() < 1e-15);
    }
    let mirrored = SvdMap3::new(&theta, true).unwrap().to_affine();
    assert!(
        mirrored.m.determinant() < 0.0,
        "reflect negates the determinant"
    );

    // Encoding a code, mirrored maps included, gives back the same maps.
    let mut code = sierpinski_tetrahedron();
    code.push(Affine3::new(
        [[0.3, 0.1, 0.0], [-0.1, 0.4, 0.2], [0.0, 0.2, -0.35]],
        [0.1, -0.5, 0.3],
    ));
    let svd = SvdMap3::from_code(&code, 1e-9).unwrap();
    assert_eq!(
        svd.iter().map(|m| m.reflect()).collect::<Vec<_>>(),
        [false, false, false, false, true]
    );
    for (a, m) in code.iter().zip(&svd) {
        let b = m.to_affine();
        assert!((a.m - b.m).abs().max() < 1e-9 && (a.b - b.b).abs().max() < 1e-9);
    }
    // Normalising the quaternions keeps the map.
    let mut n = SvdMap3::new(&svd_theta(2), false).unwrap();
    let before = n.to_affine();
    n.normalise_rotations();
    assert!((n.to_affine().m - before.m).abs().max() < 1e-14);

    // Refusals name the map and say what to do.
    let wide = Affine3::homothety(1.2, [0.0; 3]);
    let e = SvdMap3::from_code(&[code[0], wide], 1e-9).unwrap_err();
    assert!(matches!(e, Error::NonContractive { index: 1, .. }), "{e}");
    let far = Affine3::new(
        [[0.5, 0.0, 0.0], [0.0, 0.5, 0.0], [0.0, 0.0, 0.5]],
        [0.0, 1.5, 0.0],
    );
    let e = SvdMap3::from_code(&[far], 1e-9).unwrap_err().to_string();
    assert!(e.contains("map 0") && e.contains("(−1, 1)³"), "{e}");
    let e = SvdMap3::new(&[0.0; 13], false).unwrap_err().to_string();
    assert!(e.contains("14 parameters"), "{e}");
    let mut bad = svd_theta(0);
    bad[9] = f64::NAN;
    assert!(
        SvdMap3::new(&bad, false)
            .unwrap_err()
            .to_string()
            .contains("entry 9")
    );
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(300))]

    /// Every finite θ — quaternions of any length, the zero one included, raw singular
    /// values and offsets far into the sigmoid's and tanh's saturation — decodes to a
    /// contraction (largest singular value < 1) with its offset in (−1, 1)³.
    #[test]
    fn every_theta_decodes_to_a_contraction(
        q in prop::collection::vec(prop_oneof![Just(0.0), -1e3..1e3f64], 8),
        rest in prop::collection::vec(-60.0..60.0f64, 6),
        reflect in any::<bool>(),
    ) {
        let theta: Vec<f64> = q.iter().chain(&rest).copied().collect();
        let a = SvdMap3::new(&theta, reflect).unwrap().to_affine();
        prop_assert!(a.is_finite());
        prop_assert!(a.sigma_max() < 1.0, "σ_max = {}", a.sigma_max());
        prop_assert!(a.b.iter().all(|b| b.abs() <= 1.0));
        // And the map's own vjps hold there (away from exact zeros of a quaternion, where
        // R is defined but not differentiable).
        if q[..4].iter().any(|v| v.abs() > 1e-3) && q[4..].iter().any(|v| v.abs() > 1e-3)
            && rest[..3].iter().all(|s| s.abs() < 20.0)
        {
            let m = SvdMap3::new(&theta, reflect).unwrap();
            let c = vjp_check(&m, [0.3, -0.2, 0.5], [0.7, 0.1, -0.4], 1e-6);
            prop_assert!(c.params < 1e-7 * (1.0 + c.scale), "{c:?}");
        }
    }
}

fn small_game(trajectories: usize, length: usize) -> ChaosGame {
    ChaosGame {
        trajectories,
        length,
        warmup: 5,
        start_half_width: 1.0,
        seed: 3,
    }
}

/// The backward scan of the 3-D tape against central differences of `L = Σ wⱼ·pⱼ` over the
/// kept points on the same trajectories: `∂L/∂θ` through every step of every trajectory.
#[test]
fn the_tape_scans_back_to_exact_map_gradients() {
    let maps: Vec<SvdMap3> = (0..3)
        .map(|k| SvdMap3::new(&svd_theta(k), k == 2).unwrap())
        .collect();
    let game = small_game(20, 30);
    let probs = [0.5, 0.3, 0.2];
    let tape = Tape3::run(&game, &maps, Some(&probs), 9).unwrap();
    let w: Vec<[f64; 3]> = (0..tape.kept_len())
        .map(|j| std::array::from_fn(|k| ((j * 3 + k) as f64 * 0.618_034).fract() - 0.45))
        .collect();
    let grad = tape.backward(&maps, &w).unwrap();
    let loss = |t: &[f64]| {
        let mut m = maps.clone();
        set_flat_params(&mut m, t).unwrap();
        let pts = Tape3::run(&game, &m, Some(&probs), 9)
            .unwrap()
            .kept_points();
        pts.iter()
            .zip(&w)
            .map(|(p, w)| p[0] * w[0] + p[1] * w[1] + p[2] * w[2])
            .sum::<f64>()
    };
    let theta = flat_params(&maps);
    let h = 1e-6;
    for k in 0..theta.len() {
        let (mut up, mut down) = (theta.clone(), theta.clone());
        up[k] += h;
        down[k] -= h;
        let fd = (loss(&up) - loss(&down)) / (2.0 * h);
        assert!(
            (fd - grad[k]).abs() < 1e-6 * (1.0 + fd.abs()),
            "θ[{k}]: {} vs {fd}",
            grad[k]
        );
    }
    // Wrong shapes are refused.
    assert!(tape.backward(&maps[..2], &w).is_err());
    assert!(tape.backward(&maps, &w[1..]).is_err());
}

#[test]
fn the_tape_is_the_same_bits_on_any_thread_count() {
    let maps: Vec<SvdMap3> = (0..4)
        .map(|k| SvdMap3::new(&svd_theta(k), false).unwrap())
        .collect();
    let game = small_game(100, 60);
    let run = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| {
            let tape = Tape3::run(&game, &maps, None, 21).unwrap();
            let w: Vec<[f64; 3]> = (0..tape.kept_len())
                .map(|j| [1.0, (j % 7) as f64, -0.5])
                .collect();
            let grad = tape.backward(&maps, &w).unwrap();
            (tape.states, tape.indices, grad)
        })
    };
    let one = run(1);
    let three = run(3);
    assert_eq!(one.0, three.0);
    assert_eq!(one.1, three.1);
    assert_eq!(
        one.2.iter().map(|v| v.to_bits()).collect::<Vec<_>>(),
        three.2.iter().map(|v| v.to_bits()).collect::<Vec<_>>()
    );
    // Another seed, other trajectories.
    assert_ne!(Tape3::run(&game, &maps, None, 22).unwrap().states, one.0);
}

#[test]
fn the_game_draws_maps_as_asked_and_refuses_divergence() {
    let maps = sierpinski_tetrahedron();
    let game = small_game(50, 2005);
    let probs = [0.55, 0.25, 0.15, 0.05];
    let tape = Tape3::run(&game, &maps, Some(&probs), 1).unwrap();
    let n = tape.indices.len() as f64;
    for (i, p) in probs.iter().enumerate() {
        let f = tape.indices.iter().filter(|&&k| k as usize == i).count() as f64 / n;
        assert!(
            (f - p).abs() < 0.01,
            "map {i}: frequency {f}, probability {p}"
        );
    }
    // Every kept point of the tetrahedron's game lies in the tetrahedron (|x|+|y|+|z| ≤ 2.4
    // bounds it, each coordinate within ±0.8).
    for p in points3(&game, &maps, None).unwrap() {
        assert!(p.iter().all(|v| v.abs() <= 0.8 + 1e-9), "{p:?}");
    }
    let wide = vec![Affine3::homothety(3.0, [1.0, 0.0, 0.0])];
    let e = Tape3::run(&small_game(2, 1000), &wide, None, 0).unwrap_err();
    assert!(matches!(e, Error::Divergent { .. }), "{e}");
    assert!(Tape3::run(&game, &maps, Some(&[0.5, 0.5]), 0).is_err());
    assert!(Tape3::run::<Affine3>(&game, &[], None, 0).is_err());
}

fn lens() -> Lens {
    Lens::pinhole_fov(40f64.to_radians(), 24, 20)
}

#[test]
fn turntable_cameras_look_at_the_origin_with_z_up() {
    let cams = turntable(8, 30.0, 4.0, lens(), 24, 20).unwrap();
    assert_eq!(cams.len(), 8);
    for (k, c) in cams.iter().enumerate() {
        let p = c.position();
        let d = (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt();
        assert!((d - 4.0).abs() < 1e-12, "view {k} at distance {d}");
        assert!((p[2] - 4.0 * 30f64.to_radians().sin()).abs() < 1e-12);
        let o = c.project([0.0; 3]).unwrap();
        assert!(
            (o[0] - 12.0).abs() < 1e-9 && (o[1] - 10.0).abs() < 1e-9,
            "{o:?}"
        );
        // World +z is up in the picture: a point above the origin has a smaller v.
        let up = c.project([0.0, 0.0, 0.5]).unwrap();
        assert!(up[1] < o[1] - 1.0 && (up[0] - o[0]).abs() < 1e-9, "{up:?}");
    }
    // View 0 is on the +x side: +y appears to the right.
    let right = cams[0].project([0.0, 0.5, 0.0]).unwrap();
    assert!(right[0] > 12.0 + 1.0);
    // A pinhole does not see behind itself; an orthographic camera sees everything.
    assert!(cams[0].project([8.0, 0.0, 4.0]).is_none());
    let ortho = Lens::orthographic(3.0, 24, 20);
    let c = Camera::look_at([0.0, 0.0, 5.0], [0.0; 3], [0.0, 1.0, 0.0], ortho, 24, 20).unwrap();
    let p = c.project([1.5, 0.0, 20.0]).unwrap();
    assert!(
        (p[0] - 24.0).abs() < 1e-9 && (p[1] - 10.0).abs() < 1e-9,
        "{p:?}"
    );
}

/// `∂(u, v)/∂p` of both lenses against central differences.
#[test]
fn projections_have_exact_jacobians() {
    let cams = [
        turntable(3, 20.0, 3.0, lens(), 24, 20).unwrap().remove(1),
        Camera::look_at(
            [1.0, -2.0, 3.0],
            [0.1, 0.0, 0.2],
            [0.0, 0.0, 1.0],
            Lens::orthographic(2.0, 24, 20),
            24,
            20,
        )
        .unwrap(),
    ];
    for c in &cams {
        let p = [0.3, -0.2, 0.4];
        let (uv, j) = c.project_with_jacobian(p).unwrap();
        assert_eq!(Some(uv), c.project(p));
        let h = 1e-6;
        for k in 0..3 {
            let (mut a, mut b) = (p, p);
            a[k] += h;
            b[k] -= h;
            let (pa, pb) = (c.project(a).unwrap(), c.project(b).unwrap());
            for r in 0..2 {
                let fd = (pa[r] - pb[r]) / (2.0 * h);
                assert!(
                    (fd - j[r][k]).abs() < 1e-6 * (1.0 + fd.abs()),
                    "{fd} vs {}",
                    j[r][k]
                );
            }
        }
    }
}

#[test]
fn degenerate_cameras_are_refused_with_the_reason() {
    let id = [
        [1.0, 0.0, 0.0, 0.0],
        [0.0, 1.0, 0.0, 0.0],
        [0.0, 0.0, 1.0, 3.0],
        [0.0, 0.0, 0.0, 1.0],
    ];
    assert!(Camera::new(lens(), id, 24, 20).is_ok());
    let mut nan = id;
    nan[1][2] = f64::NAN;
    let mut scaled = id;
    scaled[0][0] = 2.0;
    let mut flat = id;
    flat[2][2] = 0.0;
    let mut mirrored = id;
    mirrored[2][2] = -1.0;
    let mut bottom = id;
    bottom[3][2] = 0.5;
    for (pose, words) in [
        (nan, "non-finite value (NaN) at row 1, column 2"),
        (scaled, "not orthonormal"),
        (flat, "not orthonormal"),
        (mirrored, "mirrors"),
        (bottom, "bottom row"),
    ] {
        let e = Camera::new(lens(), pose, 24, 20).unwrap_err().to_string();
        assert!(e.contains(words), "{e}");
    }
    let bad_lens = Lens::Pinhole {
        fx: 0.0,
        fy: 10.0,
        cx: 12.0,
        cy: 10.0,
    };
    assert!(
        Camera::new(bad_lens, id, 24, 20)
            .unwrap_err()
            .to_string()
            .contains("focal")
    );
    let nan_lens = Lens::Pinhole {
        fx: 10.0,
        fy: 10.0,
        cx: f64::NAN,
        cy: 10.0,
    };
    assert!(
        Camera::new(nan_lens, id, 24, 20)
            .unwrap_err()
            .to_string()
            .contains("principal")
    );
    assert!(Camera::new(lens(), id, 0, 20).is_err());
    let e = Camera::look_at([0.0, 0.0, 2.0], [0.0; 3], [0.0, 0.0, 1.0], lens(), 24, 20);
    assert!(e.unwrap_err().to_string().contains("up direction"));
    assert!(Camera::look_at([1.0; 3], [1.0; 3], [0.0, 0.0, 1.0], lens(), 24, 20).is_err());
    assert!(turntable(0, 30.0, 4.0, lens(), 24, 20).is_err());
    assert!(turntable(4, 90.0, 4.0, lens(), 24, 20).is_err());
    assert!(turntable(4, 30.0, f64::NAN, lens(), 24, 20).is_err());
}

const TRANSFORMS: &str = r#"{
  "camera_angle_x": 0.6911112070083618,
  "frames": [
    {"file_path": "./train/r_0", "rotation": 0.012566370614359171,
     "transform_matrix": [[-0.9999021887779236, 0.004192245192825794, -0.013345719315111637, -0.05379832163453102],
                          [-0.013988681137561798, -0.2996590733528137, 0.95394366979599, 3.845470428466797],
                          [-4.656612873077393e-10, 0.9540371894836426, 0.29968830943107605, 1.2080823183059692],
                          [0.0, 0.0, 0.0, 1.0]]},
    {"file_path": "./train/r_1",
     "transform_matrix": [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 4], [0, 0, 0, 1]]}
  ]
}"#;

#[test]
fn nerf_transforms_are_read_and_bad_ones_refused() {
    let path = Path::new("views/transforms.json");
    let frames = parse_transforms(TRANSFORMS, path, Some((800, 800))).unwrap();
    assert_eq!(frames.len(), 2);
    assert_eq!(frames[0].file_path, "./train/r_0");
    let f = 400.0 / (0.6911112070083618f64 / 2.0).tan();
    match frames[1].camera.lens() {
        Lens::Pinhole { fx, fy, cx, cy } => {
            assert!((fx - f).abs() < 1e-9 && fx == fy && cx == 400.0 && cy == 400.0);
        }
        l => panic!("{l:?}"),
    }
    // NeRF's synthetic scenes are seen from about 4 units away and look at the origin.
    let o = frames[0].camera.project([0.0; 3]).unwrap();
    assert!(
        (o[0] - 400.0).abs() < 20.0 && (o[1] - 400.0).abs() < 20.0,
        "{o:?}"
    );
    // instant-ngp's keys give the size and intrinsics.
    let ngp = r#"{"fl_x": 100, "fl_y": 90, "cx": 30, "cy": 20, "w": 64, "h": 48,
        "frames": [{"file_path": "a.png", "transform_matrix": [[1,0,0,0],[0,1,0,0],[0,0,1,4],[0,0,0,1]]}]}"#;
    let c = &parse_transforms(ngp, path, None).unwrap()[0].camera;
    assert_eq!((c.width(), c.height()), (64, 48));
    assert_eq!(
        c.lens(),
        Lens::Pinhole {
            fx: 100.0,
            fy: 90.0,
            cx: 30.0,
            cy: 20.0
        }
    );

    let frame =
        r#"{"file_path": "a", "transform_matrix": [[1,0,0,0],[0,1,0,0],[0,0,1,4],[0,0,0,1]]}"#;
    for (text, size, words) in [
        ("not json", Some((8, 8)), "not JSON"),
        ("[1, 2]", Some((8, 8)), "top level"),
        (r#"{"frames": []}"#, Some((8, 8)), "camera_angle_x"),
        (r#"{"camera_angle_x": 0.7}"#, Some((8, 8)), "no `frames`"),
        (
            r#"{"camera_angle_x": 0.7, "frames": {}}"#,
            Some((8, 8)),
            "must be a list",
        ),
        (
            r#"{"camera_angle_x": 0.7, "frames": []}"#,
            Some((8, 8)),
            "is empty",
        ),
        (
            r#"{"camera_angle_x": "wide", "frames": []}"#,
            Some((8, 8)),
            "`camera_angle_x` must be a finite number",
        ),
        (
            r#"{"camera_angle_x": 4.0, "frames": []}"#,
            Some((8, 8)),
            "(0, π)",
        ),
        (
            &format!(r#"{{"camera_angle_x": 0.7, "frames": [{frame}]}}"#),
            None,
            "no image size",
        ),
        (
            r#"{"camera_angle_x": 0.7, "w": 6.5, "h": 8, "frames": []}"#,
            None,
            "`w` must be a whole number",
        ),
        (
            r#"{"camera_angle_x": 0.7, "frames": [{"transform_matrix": []}]}"#,
            Some((8, 8)),
            "frames[0] has no `file_path`",
        ),
        (
            r#"{"camera_angle_x": 0.7, "frames": [{"file_path": "a"}]}"#,
            Some((8, 8)),
            "no `transform_matrix`",
        ),
        (
            r#"{"camera_angle_x": 0.7, "frames": [{"file_path": "a", "transform_matrix": [[1,0,0],[0,1,0,0],[0,0,1,4],[0,0,0,1]]}]}"#,
            Some((8, 8)),
            "row 0 must be a list of 4 numbers",
        ),
        (
            r#"{"camera_angle_x": 0.7, "frames": [{"file_path": "a", "transform_matrix": [[1,0,0,0],[0,1,"x",0],[0,0,1,4],[0,0,0,1]]}]}"#,
            Some((8, 8)),
            "transform_matrix[1][2] must be a number",
        ),
        (
            r#"{"camera_angle_x": 0.7, "frames": [{"file_path": "a", "transform_matrix": [[2,0,0,0],[0,1,0,0],[0,0,1,4],[0,0,0,1]]}]}"#,
            Some((8, 8)),
            "frames[0] (a): invalid camera",
        ),
    ] {
        let e = parse_transforms(text, path, size).unwrap_err().to_string();
        assert!(
            e.contains(words) && e.contains("views/transforms.json"),
            "{text}: {e}"
        );
    }
}

/// Three views — two pinholes of a turntable and an orthographic camera — of 24 × 20 at 2×
/// supersampling, 30 trajectories of 80 kept points.
fn small_splat<M: DiffMap3>(blend: Blend) -> MultiViewSplat<M, f64> {
    let mut cams = turntable(2, 25.0, 3.5, lens(), 24, 20).unwrap();
    cams.push(
        Camera::look_at(
            [0.5, 0.5, 4.0],
            [0.0; 3],
            [0.0, 1.0, 0.0],
            Lens::orthographic(2.5, 24, 20),
            24,
            20,
        )
        .unwrap(),
    );
    let cfg = MultiViewConfig {
        supersample: 2,
        sigma: 1.3,
        blend,
        game: ChaosGame {
            trajectories: 30,
            length: 85,
            warmup: 5,
            start_half_width: 1.0,
            seed: 0,
        },
        ..MultiViewConfig::default()
    };
    MultiViewSplat::new(cfg, cams).unwrap()
}

/// `∂L/∂θ` of the multi-view splat through the `Renderer` trait, against central
/// differences: per view the kernel's reverse pass, the projection's Jacobian, summed over
/// views, then the tape's scan to the maps' θ — for SVD maps (one mirrored) with coverage
/// and additive blending, and for similitudes.
#[test]
fn the_multi_view_splat_through_the_trait() {
    let maps: Vec<SvdMap3> = (0..3)
        .map(|k| SvdMap3::new(&svd_theta(k), k == 1).unwrap())
        .collect();
    for blend in [Blend::Coverage, Blend::Additive] {
        let splat = small_splat::<SvdMap3>(blend);
        assert_eq!(
            <MultiViewSplat<SvdMap3, f64> as Renderer>::DRAWS,
            Draws::EveryCall
        );
        assert_eq!(splat.planes().channels, 3);
        assert_ne!(splat.sampling(&maps, 11, 0), splat.sampling(&maps, 11, 1));
        let scene_at = |t: &[f64]| {
            let mut m = maps.clone();
            set_flat_params(&mut m, t).unwrap();
            m
        };
        let scale = reverse_pass_matches_finite_differences(
            &format!("multi-view splat, svd maps, {blend:?}"),
            &splat,
            &flat_params(&maps),
            scene_at,
            1e-7,
            2e-4,
        );
        assert!(scale > 1e-2, "the loss should depend on the maps ({scale})");
    }
    let sims = vec![
        Similitude3::new(0.5, [1.0, 0.2, 0.0, 0.1], false, [0.3, 0.0, -0.2]),
        Similitude3::new(0.45, [0.9, 0.0, 0.3, 0.0], true, [-0.3, 0.2, 0.1]),
        Similitude3::new(0.4, [1.0, -0.1, 0.1, 0.4], false, [0.0, -0.3, 0.3]),
    ];
    let splat = small_splat::<Similitude3>(Blend::Coverage);
    let scene_at = |t: &[f64]| {
        let mut m = sims.clone();
        set_flat_params(&mut m, t).unwrap();
        m
    };
    let scale = reverse_pass_matches_finite_differences(
        "multi-view splat, similitudes",
        &splat,
        &flat_params(&sims),
        scene_at,
        1e-7,
        2e-4,
    );
    assert!(scale > 1e-2);
}

#[test]
fn the_views_differ_and_are_the_same_bits_on_any_thread_count() {
    let maps = SvdMap3::from_code(&sierpinski_tetrahedron(), 1e-9).unwrap();
    let splat = MultiViewSplat::<SvdMap3, f32>::new(
        MultiViewConfig {
            game: small_game(200, 105),
            ..MultiViewConfig::default()
        },
        turntable(4, 30.0, 3.0, Lens::pinhole_fov(0.7, 32, 32), 32, 32).unwrap(),
    )
    .unwrap();
    let run = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| {
            let seed = splat.sampling(&maps, 5, 2);
            let (image, tape) = splat.forward(&maps, &seed).unwrap();
            let g: Vec<f32> = (0..image.len()).map(|k| (k % 5) as f32 - 2.0).collect();
            let grad = splat.backward(&maps, &seed, &tape, &g).unwrap();
            (image, grad)
        })
    };
    let (one, three) = (run(1), run(3));
    assert_eq!(one.0, three.0);
    assert_eq!(one.1, three.1);
    let px = 32 * 32;
    let ink: Vec<f32> = one.0.chunks(px).map(|p| p.iter().sum()).collect();
    assert!(
        ink.iter().all(|&s| s > 5.0),
        "every view sees the tetrahedron: {ink:?}"
    );
    // A turntable at 90° steps sees the tetrahedron's two edge-on profiles alternately.
    assert_ne!(&one.0[..px], &one.0[px..2 * px]);
    assert!(one.0.iter().all(|v| (0.0..=1.0).contains(v)));

    // Bad inputs.
    let e = MultiViewSplat::<SvdMap3, f32>::new(
        MultiViewConfig::default(),
        vec![
            turntable(1, 30.0, 3.0, lens(), 24, 20).unwrap().remove(0),
            turntable(1, 30.0, 3.0, lens(), 20, 20).unwrap().remove(0),
        ],
    )
    .unwrap_err()
    .to_string();
    assert!(e.contains("view 1 is 20×20 but view 0 is 24×20"), "{e}");
    assert!(MultiViewSplat::<SvdMap3, f32>::new(MultiViewConfig::default(), vec![]).is_err());
    let e = MultiViewSplat::<SvdMap3, f32>::new(
        MultiViewConfig {
            sigma: -1.0,
            ..MultiViewConfig::default()
        },
        turntable(1, 30.0, 3.0, lens(), 24, 20).unwrap(),
    )
    .unwrap_err()
    .to_string();
    assert!(e.contains("sigma"), "{e}");
    let seed = splat.sampling(&maps, 5, 2);
    let (_, tape) = splat.forward(&maps, &seed).unwrap();
    assert!(splat.backward(&maps, &seed, &tape, &[0.0; 10]).is_err());
}

/// A segment of points along `x` at height `y`, `z` in the voxel grid of side 64 over
/// [0, 64]³ (one voxel per unit).
fn line(y: f64, z: f64) -> Vec<[f64; 3]> {
    (0..640).map(|i| [i as f64 * 0.1, y, z]).collect()
}

#[test]
fn voxel_iou_tolerates_one_voxel_as_defined() {
    let bx = VoxelBox {
        origin: [0.0; 3],
        side: 64.0,
        resolution: 64,
    };
    // A line and the same line one voxel over: plain IoU 0, within one voxel 1.
    let (a, b) = (line(10.5, 20.5), line(11.5, 20.5));
    assert_eq!(voxel_iou_in(&bx, &a, &b, 0), 0.0);
    assert_eq!(voxel_iou_in(&bx, &a, &b, 1), 1.0);
    // Two voxels over is outside the tolerance.
    assert_eq!(voxel_iou_in(&bx, &a, &line(12.5, 20.5), 1), 0.0);
    // Diagonal neighbours count (Chebyshev distance).
    assert_eq!(voxel_iou_in(&bx, &a, &line(11.5, 21.5), 1), 1.0);
    // Half of B's voxels near A: |A| = 64, |B| = 128 (two lines), I = (64 + 64)/2 = 64,
    // IoU = 64/(64 + 128 − 64) = 0.5.
    let mut b2 = line(11.5, 20.5);
    b2.extend(line(40.5, 40.5));
    assert!((voxel_iou_in(&bx, &a, &b2, 1) - 0.5).abs() < 1e-15);
    // At t = 0 it is the plain IoU: 64 shared of 64 + 128 − 64.
    let mut a2 = line(11.5, 20.5);
    a2.extend(line(30.5, 30.5));
    let mut b3 = line(11.5, 20.5);
    b3.extend(line(50.5, 50.5));
    b3.extend(line(52.5, 52.5));
    assert!((voxel_iou_in(&bx, &a2, &b3, 0) - 64.0 / (128.0 + 192.0 - 64.0)).abs() < 1e-15);

    // The shared box: a set against itself is 1, against a far copy 0.
    let t = points3(&small_game(50, 205), &sierpinski_tetrahedron(), None).unwrap();
    assert_eq!(voxel_iou(&t, &t, 64, 1).unwrap(), 1.0);
    let far: Vec<[f64; 3]> = t.iter().map(|p| [p[0] + 3.0, p[1], p[2]]).collect();
    assert_eq!(voxel_iou(&t, &far, 64, 1).unwrap(), 0.0);
    assert_eq!(voxel_iou(&t, &[], 64, 1).unwrap(), 0.0);
    assert!(voxel_iou(&[], &[], 64, 1).is_err());
    assert!(
        voxel_iou(&t, &[[f64::NAN, 0.0, 0.0]], 64, 1)
            .unwrap_err()
            .to_string()
            .contains("point 0")
    );
    assert!(voxel_iou(&t, &t, 0, 1).is_err());
}

#[test]
fn chamfer_distance_is_exact_and_symmetric() {
    let a: Vec<[f64; 3]> = (0..700)
        .map(|i| {
            let t = i as f64;
            [
                (t * 0.37).sin(),
                (t * 0.61).cos() * 0.5,
                ((t * 0.13).fract() - 0.5) * 2.0,
            ]
        })
        .collect();
    let b: Vec<[f64; 3]> = (0..500)
        .map(|i| {
            let t = i as f64 * 1.7 + 0.3;
            [
                (t * 0.29).cos() * 1.3,
                (t * 0.47).sin(),
                (t * 0.07).fract() * 0.4 + 1.5,
            ]
        })
        .collect();
    let brute = |x: &[[f64; 3]], y: &[[f64; 3]]| {
        x.iter()
            .map(|p| {
                y.iter()
                    .map(|q| {
                        ((p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2) + (p[2] - q[2]).powi(2))
                            .sqrt()
                    })
                    .fold(f64::INFINITY, f64::min)
            })
            .sum::<f64>()
            / x.len() as f64
    };
    let want = 0.5 * (brute(&a, &b) + brute(&b, &a));
    let got = chamfer_distance(&a, &b).unwrap();
    assert!((got - want).abs() < 1e-12, "{got} vs {want}");
    assert_eq!(chamfer_distance(&b, &a).unwrap(), got);
    assert_eq!(chamfer_distance(&a, &a).unwrap(), 0.0);
    // One point against one point: their distance.
    assert!((chamfer_distance(&[[0.0; 3]], &[[3.0, 4.0, 0.0]]).unwrap() - 5.0).abs() < 1e-15);
    assert!(chamfer_distance(&a, &[]).is_err());
    assert!(chamfer_distance(&[[f64::INFINITY, 0.0, 0.0]], &a).is_err());
}

#[test]
fn nearest_distances_are_exact_on_flat_sets_and_far_queries() {
    // A flat set (z = 0, as 2-D clouds are measured) whose points crowd into one corner
    // but for a far few, and queries around it and far away: the grid of the reference
    // set is mostly empty cells, the case where the ring search once ran for minutes.
    let mut reference: Vec<[f64; 3]> = (0..3000)
        .map(|i| {
            let t = i as f64;
            [(t * 0.37).sin() * 0.01, (t * 0.61).cos() * 0.01, 0.0]
        })
        .collect();
    reference.extend([[50.0, 40.0, 0.0], [-30.0, 60.0, 0.0]]);
    let queries: Vec<[f64; 3]> = (0..2000)
        .map(|i| {
            let t = i as f64 * 1.3;
            [(t * 0.29).cos() * 20.0, (t * 0.47).sin() * 20.0, 0.0]
        })
        .chain([[1e4, -1e4, 0.0], [0.0, 0.0, 5.0]])
        .collect();
    let got = nearest_distances(&queries, &reference).unwrap();
    for (q, d) in queries.iter().zip(&got) {
        let want = reference
            .iter()
            .map(|p| ((p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2) + (p[2] - q[2]).powi(2)).sqrt())
            .fold(f64::INFINITY, f64::min);
        assert!((d - want).abs() < 1e-12, "{q:?}: {d} vs {want}");
    }
    assert!(nearest_distances(&queries, &[]).is_err());
}

#[test]
fn the_sierpinski_tetrahedron_is_four_half_scale_maps() {
    let code = sierpinski_tetrahedron();
    assert_eq!(code.len(), 4);
    for m in &code {
        assert!((m.sigma_max() - 0.5).abs() < 1e-15);
        // Each map fixes its vertex.
        let v = m.b.map(|b| 2.0 * b);
        let f = m.apply([v[0], v[1], v[2]]);
        assert!((0..3).all(|k| (f[k] - v[k]).abs() < 1e-15));
    }
}

/// A code of space is written as an `ifslab-code/1` file with `"dim": 3` and read back
/// exactly; a 2-D code and a non-contractive map are refused.
#[test]
fn codes_of_space_go_through_code_files() {
    use ifslab::model::IfsCode;
    let maps = sierpinski_tetrahedron();
    let code = Affine3::to_code(Some("sierpinski-tetrahedron"), &maps).unwrap();
    let text = code.to_json();
    assert!(text.contains("\"dim\": 3"), "{text}");
    let back = IfsCode::from_json(&text, Path::new("tetra.json")).unwrap();
    assert_eq!(Affine3::from_code(&back).unwrap(), maps);
    let flat = IfsCode::from_affine2(
        None,
        &[ifslab::model::Affine2::new(0.5, 0.0, 0.0, 0.5, 0.0, 0.0)],
    )
    .unwrap();
    assert!(
        Affine3::from_code(&flat)
            .unwrap_err()
            .to_string()
            .contains("2-dimensional")
    );
    let e = Affine3::to_code(None, &[Affine3::homothety(1.1, [0.0; 3])]).unwrap_err();
    assert!(matches!(e, Error::NonContractive { index: 0, .. }), "{e}");
}

/// The 3-D fern: contractive maps, its attractor inside [−0.9, 0.9]³ with the stem along
/// +z, and a code the SVD parameterisation encodes.
#[test]
fn the_3d_fern_stands_in_the_unit_cube() {
    use ifslab::model::map3::fern_3d;
    let (maps, probs) = fern_3d();
    assert!(maps.iter().all(|m| m.sigma_max() < 0.86));
    let pts = points3(&small_game(100, 1005), &maps, Some(&probs)).unwrap();
    let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
    for p in &pts {
        for k in 0..3 {
            lo[k] = lo[k].min(p[k]);
            hi[k] = hi[k].max(p[k]);
        }
    }
    assert!(
        lo.iter().chain(&hi).all(|v| v.abs() <= 0.9 + 1e-9),
        "{lo:?} {hi:?}"
    );
    assert!(hi[2] - lo[2] > 1.5, "the stem is tall: {lo:?} {hi:?}");
    assert!(
        hi[0] - lo[0] < hi[2] - lo[2] && hi[1] - lo[1] > 0.05,
        "{lo:?} {hi:?}"
    );
    let svd = SvdMap3::from_code(&maps, 1e-9).unwrap();
    for (a, m) in maps.iter().zip(&svd) {
        assert!((a.m - m.to_affine().m).abs().max() < 1e-8);
        assert!((a.b - m.to_affine().b).abs().max() < 1e-9);
    }
}
