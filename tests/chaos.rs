//! The chaos game and the evaluation renderer are deterministic whatever the thread count,
//! and a diverging trajectory is reported, never drawn.

use ifslab::Error;
use ifslab::chaos::{ChaosGame, generate_nd};
use ifslab::model::random::sample_code;
use ifslab::model::{Affine2, library};
use ifslab::render::{RenderConfig, RenderMode, render};

fn with_threads<T: Send>(n: usize, f: impl FnOnce() -> T + Send) -> T {
    rayon::ThreadPoolBuilder::new()
        .num_threads(n)
        .build()
        .unwrap()
        .install(f)
}

#[test]
fn chaos_game_points_do_not_depend_on_thread_count() {
    let code = sample_code(6, 11).unwrap();
    let probs = vec![1.0 / 6.0; 6];
    let game = ChaosGame {
        trajectories: 333,
        length: 120,
        warmup: 10,
        start_half_width: 5.0,
        seed: 42,
    };
    let one = with_threads(1, || game.generate(&code.maps, &probs).unwrap());
    let two = with_threads(2, || game.generate(&code.maps, &probs).unwrap());
    let three = with_threads(3, || game.generate(&code.maps, &probs).unwrap());
    assert_eq!(one.data.len(), 333 * 110);
    assert_eq!(one.data, two.data);
    assert_eq!(one.data, three.data);
    // A different seed moves the points.
    let other = ChaosGame { seed: 43, ..game };
    assert_ne!(other.generate(&code.maps, &probs).unwrap().data, one.data);
}

#[test]
fn renders_do_not_depend_on_thread_count() {
    let code = sample_code(10, 5).unwrap();
    let probs = ifslab::model::IfsCode::from_affine2(None, &code.maps)
        .unwrap()
        .evaluation_probabilities()
        .unwrap();
    for mode in [RenderMode::Coverage, RenderMode::Density] {
        let cfg = RenderConfig {
            width: 96,
            height: 80,
            points: 300_000,
            supersample: 3,
            mode,
            seed: 9,
            ..RenderConfig::default()
        };
        let a = with_threads(1, || render(&code.maps, &probs, &cfg, None).unwrap());
        let b = with_threads(2, || render(&code.maps, &probs, &cfg, None).unwrap());
        assert_eq!(a.values, b.values, "{mode:?}");
        assert_eq!(a.stats.points_in_window, b.stats.points_in_window);
    }
}

#[test]
fn n_dimensional_game_is_deterministic_and_on_the_attractor() {
    let t = library::builtin("tetrahedron").unwrap();
    let probs = vec![0.25; 4];
    let game = ChaosGame {
        trajectories: 64,
        length: 200,
        warmup: 40,
        start_half_width: 1.0,
        seed: 1,
    };
    let a = with_threads(1, || generate_nd(&game, &t.maps, &probs).unwrap());
    let b = with_threads(2, || generate_nd(&game, &t.maps, &probs).unwrap());
    assert_eq!(a, b);
    // The tetrahedron lies in the convex hull of its vertices: |x|+|y|+|z| ≤ 3 ⋯ and
    // each coordinate within [−1, 1].
    assert!(a.iter().all(|v| v.abs() <= 1.0 + 1e-9));
}

#[test]
fn divergent_trajectories_are_reported() {
    // σmax = 3: every trajectory runs off to infinity.
    let maps = [
        Affine2::new(3.0, 0.0, 0.0, 3.0, 1.0, 0.0),
        Affine2::new(3.0, 0.0, 0.0, 3.0, -1.0, 0.0),
    ];
    let probs = [0.5, 0.5];
    let game = ChaosGame {
        trajectories: 4,
        length: 2000,
        warmup: 10,
        start_half_width: 1.0,
        seed: 0,
    };
    match game.generate(&maps, &probs) {
        Err(Error::Divergent { step, .. }) => assert!(step > 100 && step < 2000, "step {step}"),
        other => panic!("expected Divergent, got {:?}", other.map(|p| p.data.len())),
    }
    let cfg = RenderConfig {
        width: 32,
        height: 32,
        points: 10_000,
        view: ifslab::render::View::Window(ifslab::model::Framing {
            min: [-1.0, -1.0],
            max: [1.0, 1.0],
        }),
        ..RenderConfig::default()
    };
    assert!(matches!(
        render(&maps, &probs, &cfg, None),
        Err(Error::Divergent { .. })
    ));
}
