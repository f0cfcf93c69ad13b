//! The SDF raster: its tiled branch-and-bound gives exactly the brute-force minimum over all
//! leaf primitives, the same bits on any thread count, and a reverse pass whose gradient
//! with respect to the control points equals central finite differences in f64, for every
//! primitive kind.

use ifslab::model::segment::{BaseFigure, Pattern, PrimitiveKind, builtin};
use ifslab::render::sdf::primitive::{distance, distance_grad};
use ifslab::render::sdf::{NONE, SdfRaster, SdfRenderConfig, SdfView};

/// Koch's structure at slightly moved points (no two distances tie by symmetry), with the
/// base figure of the given kind on p₀, p₄.
fn bent_koch(kind: PrimitiveKind) -> Pattern {
    let k = builtin("koch").unwrap();
    let mut th = k.flat_points();
    let bumps = [
        0.01, -0.02, 0.013, 0.004, -0.011, 0.017, 0.009, -0.006, -0.015, 0.008,
    ];
    for (v, b) in th.iter_mut().zip(bumps) {
        *v += b;
    }
    let p = k.with_flat_points(&th).unwrap();
    Pattern::new(
        "bent",
        p.points().to_vec(),
        p.pairs().to_vec(),
        Some(BaseFigure {
            kind,
            points: [0, 4],
        }),
    )
    .unwrap()
}

fn view(size: usize) -> SdfView {
    SdfView::around([-0.05, -0.1], [1.05, 0.4], size, 0.8)
}

/// The figure small in the middle: most pixels far from it (where whole subtrees are kept
/// as candidates and descended per pixel).
fn far_view(size: usize) -> SdfView {
    SdfView::around([-0.05, -0.1], [1.05, 0.4], size, 0.15)
}

#[test]
fn tiles_find_the_same_minimum_as_brute_force() {
    for kind in [
        PrimitiveKind::Segment,
        PrimitiveKind::Disk,
        PrimitiveKind::Box,
    ] {
        let p = bent_koch(kind);
        for (cutoff, v) in [
            (None, view(70)), // not a multiple of the tile size
            (Some(3.0), view(70)),
            (None, far_view(90)),
        ] {
            let r = SdfRaster::render(&p, &v, &SdfRenderConfig { depth: 4, cutoff }).unwrap();
            let leaves = r.tree().leaves();
            assert_eq!(leaves.len(), 256);
            for i in 0..v.height {
                for j in 0..v.width {
                    let c = v.centre(i, j);
                    let brute = leaves
                        .iter()
                        .map(|[a, b]| distance(kind, c, *a, *b))
                        .fold(f64::INFINITY, f64::min)
                        / v.pixel;
                    let got = r.distances()[i * v.width + j];
                    match cutoff {
                        Some(cut) if brute >= cut => {
                            assert_eq!(got, f64::INFINITY);
                            assert_eq!(r.nearest()[i * v.width + j], NONE);
                        }
                        _ => assert_eq!(got, brute, "{kind:?} pixel ({i}, {j})"),
                    }
                }
            }
            // Far fewer candidates than pixels × primitives.
            let s = r.stats();
            assert!(s.block_candidates < s.blocks * s.primitives / 8, "{s:?}");
        }
    }
}

#[test]
fn the_same_bits_on_any_thread_count() {
    let p = bent_koch(PrimitiveKind::Segment);
    let v = view(96);
    let run = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| {
            let r = SdfRaster::render(
                &p,
                &v,
                &SdfRenderConfig {
                    depth: 5,
                    cutoff: None,
                },
            )
            .unwrap();
            let g: Vec<f64> = r.distances().iter().map(|d| (d * 0.37).sin()).collect();
            let grad = r.backward(&p, &g).unwrap();
            (r.distances().to_vec(), r.nearest().to_vec(), grad)
        })
    };
    let one = run(1);
    for t in [2, 3, 5] {
        let other = run(t);
        assert!(
            one.0
                .iter()
                .zip(&other.0)
                .all(|(a, b)| a.to_bits() == b.to_bits())
        );
        assert_eq!(one.1, other.1);
        assert!(
            one.2
                .iter()
                .zip(&other.2)
                .all(|(a, b)| a.to_bits() == b.to_bits()),
            "{t} threads"
        );
    }
}

/// Each primitive's distance gradient with respect to its two points equals central
/// differences (at points off the primitive, where the distance is smooth).
#[test]
fn primitive_gradients_match_finite_differences() {
    let a = [0.2, -0.1];
    let b = [0.9, 0.4];
    let h = 1e-7;
    for kind in [
        PrimitiveKind::Segment,
        PrimitiveKind::Disk,
        PrimitiveKind::Box,
    ] {
        for p in [
            [1.5, 0.3],
            [-0.4, 0.2],
            [0.5, 0.9],
            [0.55, -0.6],
            [1.0, 1.0],
        ] {
            let (d, ga, gb) = distance_grad(kind, p, a, b);
            assert!(d > 0.0 && (d - distance(kind, p, a, b)).abs() < 1e-15);
            let g = [ga, gb];
            for (k, c) in [(0, 0), (0, 1), (1, 0), (1, 1)] {
                let mut pts = [a, b];
                pts[k][c] += h;
                let up = distance(kind, p, pts[0], pts[1]);
                pts[k][c] -= 2.0 * h;
                let down = distance(kind, p, pts[0], pts[1]);
                let fd = (up - down) / (2.0 * h);
                assert!(
                    (fd - g[k][c]).abs() < 1e-6,
                    "{kind:?} at {p:?}: point {k}.{c}: {} vs {fd}",
                    g[k][c]
                );
            }
        }
    }
}

/// For `L = Σ_p c_p·exp(−d_p²/σ²)` (fixed pseudo-random weights c), the reverse pass equals
/// central differences of L in every control-point coordinate (h = 1e-7, f64), for the three
/// primitive kinds, with and without a cut-off.
#[test]
fn the_reverse_pass_matches_finite_differences() {
    let sigma = 1.7;
    let size = 40;
    let v = view(size);
    let weights: Vec<f64> = (0..size * size)
        .map(|k| ((k as f64) * 0.618_033_988_7).fract() - 0.4)
        .collect();
    for kind in [
        PrimitiveKind::Segment,
        PrimitiveKind::Disk,
        PrimitiveKind::Box,
    ] {
        for cutoff in [None, Some(8.0)] {
            let p = bent_koch(kind);
            let cfg = SdfRenderConfig { depth: 3, cutoff };
            let loss = |th: &[f64]| {
                let q = p.with_flat_points(th).unwrap();
                let r = SdfRaster::render(&q, &v, &cfg).unwrap();
                r.image(sigma)
                    .iter()
                    .zip(&weights)
                    .map(|(x, c)| x * c)
                    .sum::<f64>()
            };
            let r = SdfRaster::render(&p, &v, &cfg).unwrap();
            let g_img = weights.clone();
            let g_d = r.image_backward(sigma, &g_img);
            let grad = r.backward(&p, &g_d).unwrap();
            let th = p.flat_points();
            let h = 1e-7;
            let mut scale = 0.0f64;
            let mut worst = 0.0f64;
            for k in 0..th.len() {
                let (mut up, mut down) = (th.clone(), th.clone());
                up[k] += h;
                down[k] -= h;
                let fd = (loss(&up) - loss(&down)) / (2.0 * h);
                scale = scale.max(fd.abs());
                worst = worst.max((fd - grad[k]).abs());
            }
            assert!(
                scale > 1.0,
                "{kind:?}: the loss should depend on the points"
            );
            assert!(
                worst < 1e-4 * scale,
                "{kind:?} cutoff {cutoff:?}: worst error {worst} of {scale}"
            );
        }
    }
}

#[test]
fn bad_views_and_depths_are_refused() {
    let p = builtin("koch").unwrap();
    let cfg = SdfRenderConfig {
        depth: 3,
        cutoff: None,
    };
    let mut v = SdfView::unit_square(16);
    v.pixel = 0.0;
    assert!(
        SdfRaster::render(&p, &v, &cfg)
            .unwrap_err()
            .to_string()
            .contains("pixel size")
    );
    let e = SdfRaster::render(
        &p,
        &SdfView::unit_square(16),
        &SdfRenderConfig {
            depth: 30,
            cutoff: None,
        },
    )
    .unwrap_err()
    .to_string();
    assert!(e.contains("lower the depth"), "{e}");
    let e = SdfRaster::render(
        &p,
        &SdfView::unit_square(16),
        &SdfRenderConfig {
            depth: 2,
            cutoff: Some(-1.0),
        },
    )
    .unwrap_err()
    .to_string();
    assert!(e.contains("cutoff"), "{e}");
    let r = SdfRaster::render(&p, &SdfView::unit_square(16), &cfg).unwrap();
    assert!(r.backward(&p, &[0.0; 3]).is_err());
}
