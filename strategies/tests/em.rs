//! Behaviour of the EM strategy: likelihood ascent, recovery of a known code, proper
//! rotations in several dimensions, the E-step against brute force, determinism, code files.

use nalgebra::{DMatrix, DVector};
use rand::SeedableRng;
use rand_distr::{Distribution, StandardNormal};
use rand_xoshiro::Xoshiro256PlusPlus;

use ifslab::chaos::{ChaosGame, generate_nd, trajectory_rng};
use ifslab::model::similitude::random_rotation;
use ifslab::model::{IfsCode, Similitude, library};
use ifslab_strategies::problems::em::model::inverse;
use ifslab_strategies::problems::em::*;

/// `n` points of a built-in code's attractor, from many short chaos-game trajectories.
fn cloud(name: &str, n: usize, seed: u64) -> PointSet {
    let code = library::builtin(name).unwrap();
    let probs = code.evaluation_probabilities().unwrap();
    let game = ChaosGame {
        trajectories: n / 20,
        length: 40,
        warmup: 20,
        start_half_width: 1.0,
        seed,
    };
    PointSet::new(code.dim(), generate_nd(&game, &code.maps, &probs).unwrap()).unwrap()
}

/// Runs full-batch EM and returns the batch log-likelihood before every step, the number of
/// accepted component updates, and the final model.
fn full_batch(
    mut model: EmModel,
    data: &PointSet,
    cfg: &MStepConfig,
    iterations: usize,
) -> (Vec<f64>, usize, EmModel) {
    let mut rng = trajectory_rng(5, 0);
    let mut lls = Vec::new();
    let mut accepted = 0;
    for _ in 0..iterations {
        let (next, info) = em_step(&model, data, cfg, &mut rng).unwrap();
        assert!(
            info.degeneracies
                .iter()
                .all(|d| !matches!(d, Degeneracy::DeadComponent { .. })),
            "no component should die on this data: {:?}",
            info.degeneracies
        );
        lls.push(info.log_likelihood);
        accepted += usize::from(info.accepted);
        model = next;
    }
    lls.push(model.mean_log_likelihood(data).unwrap());
    (lls, accepted, model)
}

fn assert_non_decreasing(lls: &[f64], what: &str) {
    for (t, w) in lls.windows(2).enumerate() {
        // "Within floating error": the sums run over a few hundred points, and the weight
        // floor of 1e−12 perturbs the exact maximiser by about that much.
        let tol = 1e-10 * (1.0 + w[0].abs());
        assert!(
            w[1] >= w[0] - tol,
            "{what}: mean log-likelihood fell from {} to {} at iteration {t}",
            w[0],
            w[1]
        );
    }
}

#[test]
fn loglik_never_decreases_at_depth_one_without_safeguard() {
    // At D = 1 every code holds one map, so each M-step block is an exact maximiser of the
    // EM objective (an ECM step) and the likelihood must not fall — for both update rules.
    let data = cloud("sierpinski", 400, 1);
    for update in [ComponentUpdate::Outermost, ComponentUpdate::AllPositions] {
        for seed in 0..3 {
            let mut rng = trajectory_rng(seed, 0);
            let m = init::random_model(3, 1, 0.5, init::normalising_post(&data), &mut rng).unwrap();
            let cfg = MStepConfig {
                update,
                ..MStepConfig::default()
            };
            let (lls, accepted, _) = full_batch(m, &data, &cfg, 40);
            assert_eq!(accepted, 40);
            assert_non_decreasing(&lls, &format!("{update:?}, seed {seed}"));
            assert!(
                lls[40] > lls[0] + 0.1,
                "EM should improve: {} → {}",
                lls[0],
                lls[40]
            );
        }
    }
}

#[test]
fn loglik_never_decreases_over_full_batch_em_at_fixed_depth() {
    // At D = 4 the component update is not an exact maximisation (a map appears at several
    // places in a code); the monotone safeguard falls back to the exact blocks when needed.
    // The sequence must never fall, and the safeguard must rarely be needed (else it, not the
    // M-step, would be doing the work).
    for (name, k) in [("sierpinski", 3), ("tetrahedron", 4)] {
        let data = cloud(name, 300, 2);
        for seed in 0..2 {
            let mut rng = trajectory_rng(seed, 1);
            let m = init::random_model(k, 4, 0.5, init::normalising_post(&data), &mut rng).unwrap();
            let cfg = MStepConfig {
                monotone: true,
                ..MStepConfig::default()
            };
            let (lls, accepted, model) = full_batch(m, &data, &cfg, 50);
            assert_non_decreasing(&lls, &format!("{name}, seed {seed}"));
            assert!(
                accepted >= 45,
                "{name}: only {accepted}/50 component updates kept"
            );
            assert!(lls[50] > lls[0] + 0.5, "{name}: {} → {}", lls[0], lls[50]);
            assert!(model.validate().is_ok());
        }
    }
}

/// Rotation angle of a 2-D rotation matrix, in degrees.
fn angle(r: &DMatrix<f64>) -> f64 {
    r[(1, 0)].atan2(r[(0, 0)]).to_degrees()
}

#[test]
fn perturbed_sierpinski_code_converges_back() {
    // Start from the Sierpiński code with every scale, rotation and translation disturbed,
    // written in the model frame of the data's normalising post-transform; EM at depth 6
    // must come back. Tolerances: |Δs| < 0.01, |Δangle| < 1°, ‖Δt‖ < 0.01 (the attractor
    // spans 1), weights within 0.03 of 1/3.
    let truth = library::builtin("sierpinski").unwrap();
    let data = cloud("sierpinski", 3000, 3);
    let post = init::normalising_post(&data);
    let inv = inverse(&post);
    let perturb: [(f64, f64, [f64; 2]); 3] = [
        (0.04, 6.0, [0.03, -0.02]),
        (-0.03, -5.0, [-0.02, 0.03]),
        (0.03, 4.0, [0.03, 0.03]),
    ];
    let components: Vec<Similitude> = truth
        .maps
        .iter()
        .zip(perturb)
        .map(|(m, (ds, da, dt))| {
            let s = Similitude::from_affine(m, 1e-9).unwrap();
            let a = da.to_radians();
            let rot = DMatrix::from_row_slice(2, 2, &[a.cos(), -a.sin(), a.sin(), a.cos()]);
            let disturbed = Similitude {
                s: s.s + ds,
                r: rot * &s.r,
                t: &s.t + DVector::from_row_slice(&dt),
            };
            inv.compose(&disturbed.compose(&post))
        })
        .collect();
    let start = EmModel::new(components, vec![0.4, 0.35, 0.25], vec![1.0 / 7.0; 7], post).unwrap();
    let schedule = Schedule {
        iterations: 60,
        batch_size: 500,
        stream: 11,
        heldout: None,
        reorient: None,
    };
    let (model, _) = train(
        start,
        &data,
        &MStepConfig::default(),
        &schedule,
        &mut |_| {},
    )
    .unwrap();
    assert!(
        model.is_converged(0.95),
        "depth weights {:?}",
        model.depth_weights
    );
    let fitted = model.data_space_maps();
    for (i, m) in truth.maps.iter().enumerate() {
        let want = Similitude::from_affine(m, 1e-9).unwrap();
        let (j, err) = fitted
            .iter()
            .enumerate()
            .map(|(j, f)| (j, (&f.t - &want.t).norm()))
            .min_by(|a, b| a.1.total_cmp(&b.1))
            .unwrap();
        let f = &fitted[j];
        assert!(
            err < 0.01,
            "map {i}: translation off by {err} ({:?})",
            f.t.as_slice()
        );
        assert!((f.s - want.s).abs() < 0.01, "map {i}: scale {}", f.s);
        let da = (angle(&f.r) - angle(&want.r) + 540.0) % 360.0 - 180.0;
        assert!(da.abs() < 1.0, "map {i}: rotation off by {da}°");
        assert!(
            (model.weights[j] - 1.0 / 3.0).abs() < 0.03,
            "weights {:?}",
            model.weights
        );
    }
}

#[test]
fn procrustes_rotations_are_proper_in_2_3_and_5_dimensions() {
    let mut rng = Xoshiro256PlusPlus::seed_from_u64(17);
    for h in [2, 3, 5] {
        for trial in 0..20 {
            // Cross-covariances of both determinant signs, and a rank-deficient one.
            let mut c = DMatrix::<f64>::from_fn(h, h, |_, _| StandardNormal.sample(&mut rng));
            if trial % 5 == 4 {
                c.column_mut(0).fill(0.0);
            }
            let r = proper_rotation(&c).unwrap();
            let orth = (r.transpose() * &r - DMatrix::<f64>::identity(h, h)).amax();
            assert!(orth < 1e-10, "H = {h}: RᵀR ≠ I ({orth})");
            assert!(
                (r.determinant() - 1.0).abs() < 1e-10,
                "H = {h}: det {}",
                r.determinant()
            );
            // R maximises tr(RᵀC) over SO(H): no random proper rotation does better.
            let best = (r.transpose() * &c).trace();
            for _ in 0..50 {
                let q = random_rotation(h, &mut rng);
                assert!((q.transpose() * &c).trace() <= best + 1e-9);
            }
        }
    }
}

#[test]
fn m_step_keeps_every_rotation_proper_in_2_3_and_5_dimensions() {
    // Data from a random IFS of similitudes in R^H; with the paper's M-step every rotation it
    // produces — components and post-transform — must be orthogonal with determinant +1. With
    // reflections allowed (the default) a component may mirror (determinant ±1) but the
    // post-transform, a change of frame, stays proper.
    for h in [2usize, 3, 5] {
        let mut rng = trajectory_rng(40 + h as u64, 0);
        let gen_post = Similitude::identity(h);
        let generator = init::random_model(2, 8, 0.45, gen_post, &mut rng).unwrap();
        let data = generator.sample(600, 1).unwrap();
        let start = init::random_model(2, 3, 0.5, init::normalising_post(&data), &mut rng).unwrap();
        for reflections in [false, true] {
            for update in [ComponentUpdate::Outermost, ComponentUpdate::AllPositions] {
                let cfg = MStepConfig {
                    update,
                    reflections,
                    ..MStepConfig::default()
                };
                let mut m = start.clone();
                for _ in 0..10 {
                    m = em_step(&m, &data, &cfg, &mut rng).unwrap().0;
                    let post = std::iter::once((&m.post.r, true));
                    let parts = m.components.iter().map(|c| (&c.r, !reflections));
                    for (r, proper) in parts.chain(post) {
                        let orth = (r.transpose() * r - DMatrix::<f64>::identity(h, h)).amax();
                        assert!(orth < 1e-9, "H = {h}: RᵀR ≠ I ({orth})");
                        let det = r.determinant();
                        let ok = if proper {
                            (det - 1.0).abs() < 1e-9
                        } else {
                            (det.abs() - 1.0).abs() < 1e-9
                        };
                        assert!(ok, "H = {h}, reflections {reflections}: det {det}");
                    }
                }
            }
        }
    }
}

#[test]
fn e_step_density_matches_brute_force_and_does_not_underflow() {
    // ln p(x) from the code table and log-sum-exp against an explicit sum over composed
    // similitudes (depth 3), then a depth-9 model far from the data still gives finite values.
    let mut rng = trajectory_rng(3, 3);
    let post = Similitude {
        s: 2.0,
        r: random_rotation(3, &mut rng),
        t: DVector::from_row_slice(&[1.0, -1.0, 0.5]),
    };
    let mut m = init::random_model(2, 3, 0.5, post, &mut rng).unwrap();
    m.weights = vec![0.3, 0.7];
    m.depth_weights = vec![0.1, 0.2, 0.3, 0.4];
    let pts = PointSet::from_rows(&[
        vec![1.0, -1.0, 0.5],
        vec![2.0, 0.0, 0.0],
        vec![-3.0, 4.0, 1.0],
    ])
    .unwrap();
    let got = m.log_densities(&pts).unwrap();
    for (i, p) in pts.iter().enumerate() {
        let x = DVector::from_row_slice(p);
        let mut total = 0.0;
        let mut codes: Vec<(Vec<usize>, Similitude)> = vec![(vec![], Similitude::identity(3))];
        for d in 0..=3 {
            let mut next = Vec::new();
            for (code, s) in &codes {
                let full = m.post.compose(s);
                let prior =
                    m.depth_weights[d] * code.iter().map(|&k| m.weights[k]).product::<f64>();
                let var = full.s * full.s;
                let d2 = (&x - &full.t).norm_squared();
                total +=
                    prior * (-0.5 * d2 / var).exp() / (2.0 * std::f64::consts::PI * var).powf(1.5);
                for k in 0..2 {
                    let mut c = vec![k];
                    c.extend(code);
                    next.push((c, m.components[k].compose(s)));
                }
            }
            codes = next;
        }
        assert!(
            (got[i] - total.ln()).abs() < 1e-10,
            "point {i}: {} vs {}",
            got[i],
            total.ln()
        );
    }
    let deep = m.with_depth(9);
    let far = PointSet::from_rows(&[vec![30.0, -20.0, 10.0]]).unwrap();
    let ll = deep.log_densities(&far).unwrap()[0];
    assert!(ll.is_finite() && ll < -50.0, "ln p = {ll}");
    // And the E-step's responsibilities still sum to one per point.
    let table = CodeTable::build(&deep, false);
    let stats = estep::expectation(&deep, &table, &far);
    assert!((stats.weight.iter().sum::<f64>() - 1.0).abs() < 1e-12);
}

#[test]
fn same_seed_same_fit_whatever_the_thread_count() {
    let data = cloud("sierpinski", 1000, 4);
    let cfg = EmConfig {
        components: 3,
        depth: 4,
        iterations: 15,
        batch_size: 200,
        pool: 3,
        preselect_iterations: 5,
        seed: 42,
        ..EmConfig::default()
    };
    let run = |threads: usize| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| fit(&data, None, &cfg, &mut |_| {}).unwrap())
    };
    let (a, b) = (run(1), run(3));
    assert_eq!(a.model, b.model);
    assert_eq!(a.chosen, b.chosen);
    assert_eq!(a.history, b.history);
}

#[test]
fn fitted_model_round_trips_through_the_code_file() {
    let data = cloud("sierpinski", 600, 6);
    let cfg = EmConfig {
        components: 3,
        depth: 3,
        iterations: 10,
        batch_size: 0,
        pool: 1,
        ..EmConfig::default()
    };
    let f = fit(&data, None, &cfg, &mut |_| {}).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("fit.json");
    f.model.to_code(Some("fit")).unwrap().save(&path).unwrap();
    let code = IfsCode::load(&path).unwrap();
    let back = EmModel::from_code(&code, 6).unwrap();
    assert_eq!(back, f.model);
    // The file's maps are the conjugated similitudes in data space, with the weights.
    for (a, m) in f.model.data_space_maps().iter().zip(&code.maps) {
        assert!((a.to_affine().m - &m.m).amax() < 1e-15);
    }
    assert_eq!(code.probabilities.as_ref().unwrap(), &f.model.weights);
    assert_eq!(
        f.model.log_densities(&data).unwrap(),
        back.log_densities(&data).unwrap()
    );
}

#[test]
fn degenerate_cases_are_repaired_and_reported_never_nan() {
    let finite = |m: &EmModel| {
        m.validate().is_ok()
            && m.components
                .iter()
                .chain([&m.post])
                .all(|c| c.s.is_finite() && c.r.iter().chain(c.t.iter()).all(|v| v.is_finite()))
    };
    // A component far from every point gets no responsibility: it is re-seeded from the
    // heaviest one, with the weights shared.
    let data = cloud("sierpinski", 400, 8);
    let mut rng = trajectory_rng(8, 0);
    let mut m = init::random_model(3, 3, 0.5, init::normalising_post(&data), &mut rng).unwrap();
    m.components[2].t = DVector::from_row_slice(&[60.0, -60.0]);
    m.components[2].s = 0.01;
    let (next, info) = em_step(&m, &data, &MStepConfig::default(), &mut rng).unwrap();
    assert!(
        info.degeneracies
            .iter()
            .any(|d| matches!(d, Degeneracy::DeadComponent { component: 2, .. })),
        "{:?}",
        info.degeneracies
    );
    assert!(
        finite(&next) && next.weights[2] > 0.05,
        "weights {:?}",
        next.weights
    );

    // All points at one place: the scales' stationary points are 0; they are clamped.
    let same = PointSet::from_rows(&vec![vec![1.0, 2.0]; 50]).unwrap();
    let mut m = init::random_model(2, 2, 0.5, init::normalising_post(&same), &mut rng).unwrap();
    let mut clamped = false;
    for _ in 0..5 {
        let (next, info) = em_step(&m, &same, &MStepConfig::default(), &mut rng).unwrap();
        clamped |= info
            .degeneracies
            .iter()
            .any(|d| matches!(d, Degeneracy::ScaleClamped { .. }));
        assert!(finite(&next));
        assert!(info.log_likelihood.is_finite());
        m = next;
    }
    assert!(clamped);
}
