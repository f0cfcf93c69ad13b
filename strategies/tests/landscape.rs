//! Loss landscapes: a slice through the true code has its minimum there, is deterministic,
//! and bad requests are refused.

use ifslab::chaos::ChaosGame;
use ifslab::image::Image;
use ifslab::loss::LossConfig;
use ifslab::model::{ParamKind, library};
use ifslab::render::splat::{self, SplatConfig};
use ifslab_strategies::problems::image::{
    AffineModel, Directions, ImageProblem, LandscapeConfig, landscape,
};

fn problem(size: usize) -> (ImageProblem, Vec<f64>) {
    let maps = library::builtin("sierpinski").unwrap().affine2().unwrap();
    let splat = SplatConfig {
        width: size,
        height: size,
        supersample: 1,
        sigma: 1.0,
        game: ChaosGame {
            trajectories: 400,
            length: 60,
            warmup: 10,
            ..ChaosGame::default()
        },
        ..SplatConfig::default()
    };
    // The target: the true code through the same renderer, on other trajectories.
    let target = splat::forward::<f32>(&splat, &maps, 12345).unwrap().0;
    let target = Image::square(size, target).unwrap();
    let loss = LossConfig {
        lpips_weight: 0.0,
        ..LossConfig::default()
    };
    let p = ImageProblem::new(
        Box::new(AffineModel(ParamKind::Svd.build())),
        splat,
        loss,
        target,
        3,
    )
    .unwrap();
    let theta = p.model().encode(&maps).unwrap();
    (p, theta)
}

#[test]
fn slice_through_the_true_code_has_its_minimum_there() {
    let (p, theta) = problem(48);
    for seed in [0, 1] {
        let cfg = LandscapeConfig {
            resolution: 5,
            extent: 0.3,
            directions: Directions::Random { seed },
            streams: 2,
        };
        let l = landscape(&p, &theta, &cfg, &|| {}).unwrap();
        assert!(l.failed.is_empty(), "{:?}", l.failed);
        assert_eq!(l.total.len(), 25);
        let (a, b, v) = l.minimum();
        assert_eq!(
            (a, b),
            (0.0, 0.0),
            "minimum {v} off-centre; grid {:?}",
            l.total
        );
        // Far from the code the objective is clearly worse, not flat.
        let corner = l.total[0].min(l.total[4]).min(l.total[20]).min(l.total[24]);
        assert!(
            corner > 1.5 * l.centre_total(),
            "{corner} vs {}",
            l.centre_total()
        );
    }
}

#[test]
fn slices_are_deterministic_and_coordinate_slices_move_one_coordinate() {
    let (p, theta) = problem(32);
    let cfg = LandscapeConfig {
        resolution: 3,
        extent: 0.2,
        directions: Directions::Coordinates { i: 4, j: 5 },
        streams: 1,
    };
    let a = landscape(&p, &theta, &cfg, &|| {}).unwrap();
    let b = landscape(&p, &theta, &cfg, &|| {}).unwrap();
    assert_eq!(a.total, b.total);
    assert_eq!(a.d1.iter().filter(|v| **v != 0.0).count(), 1);
    assert_eq!(a.d1[4], 1.0);
    assert_eq!(a.d2[5], 1.0);
}

#[test]
fn bad_requests_are_refused_with_the_field_named() {
    let (p, theta) = problem(16);
    let bad = |cfg: LandscapeConfig, field: &str| {
        let msg = landscape(&p, &theta, &cfg, &|| {}).unwrap_err().to_string();
        assert!(msg.contains(field), "{msg}");
    };
    let ok = LandscapeConfig::default();
    bad(
        LandscapeConfig {
            resolution: 4,
            ..ok.clone()
        },
        "resolution",
    );
    bad(
        LandscapeConfig {
            extent: f64::NAN,
            ..ok.clone()
        },
        "extent",
    );
    bad(
        LandscapeConfig {
            directions: Directions::Coordinates { i: 0, j: 999 },
            ..ok.clone()
        },
        "directions",
    );
    let mut nan = theta.clone();
    nan[2] = f64::NAN;
    let msg = landscape(&p, &nan, &ok, &|| {}).unwrap_err().to_string();
    assert!(msg.contains("non-finite"), "{msg}");
}
