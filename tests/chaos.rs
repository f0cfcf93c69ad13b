//! The chaos game and the evaluation renderer are deterministic whatever the thread count
//! and instruction set, and a diverging trajectory is reported, never drawn.

use ifslab::Error;
use ifslab::chaos::{ChaosGame, Isa, MapSampler, PointStream, Trajectory, generate_nd};
use ifslab::model::random::sample_code;
use ifslab::model::{Affine2, Map, Map2, library};
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
    // Both instruction sets give the same bits (the FMA copy's `mul_add`s are instructions,
    // the portable copy's calls to the runtime's `fma`).
    let portable = game
        .generate_with_isa(&code.maps, &probs, Isa::Portable)
        .unwrap();
    assert_eq!(bits(&portable.data), bits(&one.data));
    if Isa::Fma.is_available() {
        let fma = game
            .generate_with_isa(&code.maps, &probs, Isa::Fma)
            .unwrap();
        assert_eq!(bits(&fma.data), bits(&one.data));
    } else {
        assert!(
            game.generate_with_isa(&code.maps, &probs, Isa::Fma)
                .is_err()
        );
    }
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
        view: ifslab::render::View::Window(ifslab::model::Window {
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

/// A 10-map random code with its evaluation (area-weighted, non-uniform) probabilities.
fn random_code(seed: u64) -> (Vec<Affine2>, Vec<f64>) {
    let code = sample_code(10, seed).unwrap();
    let probs = ifslab::model::IfsCode::from_affine2(None, &code.maps)
        .unwrap()
        .evaluation_probabilities()
        .unwrap();
    (code.maps, probs)
}

fn bits(points: &[[f64; 2]]) -> Vec<[u64; 2]> {
    points
        .iter()
        .map(|p| [p[0].to_bits(), p[1].to_bits()])
        .collect()
}

/// Every point a stream hands out, in order.
fn stream_points<M: Map2>(stream: &PointStream<'_, M>, first: u64, kept: &[u64]) -> Vec<[f64; 2]> {
    let mut out = Vec::new();
    stream.run(first, kept, &mut |p| out.push(p)).unwrap();
    out
}

/// An affine map evaluated with separate multiplies and adds (two roundings per term).
struct Unfused(Affine2);

impl Map<2> for Unfused {
    fn apply(&self, p: [f64; 2]) -> [f64; 2] {
        let m = &self.0.m;
        [
            m[(0, 0)] * p[0] + (m[(0, 1)] * p[1] + self.0.b[0]),
            m[(1, 0)] * p[0] + (m[(1, 1)] * p[1] + self.0.b[1]),
        ]
    }
}

#[test]
fn point_streams_are_the_trajectories_bit_for_bit_on_every_isa() {
    let (maps, probs) = random_code(7);
    let sampler = MapSampler::new(&probs).unwrap();
    let (seed, hw, warmup) = (13, 1.0, 25);
    let portable = PointStream::new(&maps, &sampler, seed, hw, warmup)
        .unwrap()
        .with_isa(Isa::Portable)
        .unwrap();
    let detected = PointStream::new(&maps, &sampler, seed, hw, warmup).unwrap();
    assert_eq!(detected.isa(), Isa::detect());
    // One trajectory at a time: exactly `Trajectory` with the warm-up dropped.
    for index in [0u64, 5, 1_000_003] {
        let mut tr = Trajectory::new(&maps, &sampler, seed, index, hw);
        tr.skip_steps(warmup);
        let want: Vec<[f64; 2]> = (0..2000).map(|_| tr.step()).collect();
        for stream in [&portable, &detected] {
            let got = stream_points(stream, index, &[2000]);
            assert_eq!(
                bits(&got),
                bits(&want),
                "trajectory {index} on {:?}",
                stream.isa()
            );
        }
    }
    // Lanes of unequal length, more than one group of lanes: the same points in the same
    // order on both instruction sets, and the same multiset as one trajectory at a time.
    let kept = [0u64, 1, 700, 699, 701, 3, 250];
    let a = stream_points(&portable, 40, &kept);
    let b = stream_points(&detected, 40, &kept);
    assert_eq!(a.len() as u64, kept.iter().sum::<u64>());
    assert_eq!(bits(&a), bits(&b));
    let mut one_by_one: Vec<[u64; 2]> = kept
        .iter()
        .enumerate()
        .flat_map(|(l, &n)| bits(&stream_points(&portable, 40 + l as u64, &[n])))
        .collect();
    let mut lanes = bits(&a);
    one_by_one.sort_unstable();
    lanes.sort_unstable();
    assert_eq!(lanes, one_by_one);
    // The comparison can tell: evaluating the maps without fusing changes the points.
    let unfused: Vec<Unfused> = maps.iter().map(|m| Unfused(*m)).collect();
    let plain = PointStream::new(&unfused, &sampler, seed, hw, warmup).unwrap();
    assert_ne!(bits(&stream_points(&plain, 40, &kept)), bits(&a));
}

#[test]
fn point_streams_refuse_bad_input_and_report_divergence() {
    let (maps, probs) = random_code(2);
    let sampler = MapSampler::new(&probs).unwrap();
    assert!(matches!(
        PointStream::new(&maps[..9], &sampler, 0, 1.0, 10),
        Err(Error::Shape(_))
    ));
    assert!(matches!(
        PointStream::new(&maps, &sampler, 0, f64::NAN, 10),
        Err(Error::InvalidParameter { .. })
    ));
    let none: [Affine2; 0] = [];
    assert!(matches!(
        PointStream::new(&none, &sampler, 0, 1.0, 10),
        Err(Error::Empty(_))
    ));
    // σmax = 3: the trajectory leaves ±1e100 after ≈ 210 steps; the step is where it did.
    let far = [
        Affine2::new(3.0, 0.0, 0.0, 3.0, 1.0, 0.0),
        Affine2::new(3.0, 0.0, 0.0, 3.0, -1.0, 0.0),
    ];
    let half = MapSampler::new(&[0.5, 0.5]).unwrap();
    let stream = PointStream::new(&far, &half, 0, 1.0, 10).unwrap();
    // Trajectory 8 stops after 15 steps, still bounded; 9 and 10 run off.
    match stream.run(8, &[5, 2000, 1000], &mut |_| {}) {
        Err(Error::Divergent { trajectory, step }) => {
            assert_eq!(trajectory, 9);
            let mut tr = Trajectory::new(&far, &half, 0, 9, 1.0);
            let first_bad = (0..)
                .find(|_| !ifslab::chaos::is_bounded(&tr.step()))
                .unwrap();
            assert_eq!(step, first_bad);
            assert!(step > 100 && step < 1000, "step {step}");
        }
        other => panic!("expected Divergent, got {other:?}"),
    }
}
