//! The [`Renderer`] trait, used generically: one function, generic over `R: Renderer`,
//! checks a renderer's reverse pass against central finite differences in f64 — for the
//! splat (affine maps, fitted framing, coverage), the SDF raster (intensity and distance
//! planes) and the differentiable flame pipeline (a stack of two layers on a learned
//! background), and for a renderer defined here, outside the crate (Gaussian blobs), the way
//! a newcomer adds one.
//!
//! The loss is linear in the image, `L = Σ wₖ·imageₖ` with fixed weights, so
//! `∂L/∂image = w` and `∂L/∂θ` is exactly the vector–Jacobian product the renderer's reverse
//! pass computes; its central difference `(L(θ + h·eᵢ) − L(θ − h·eᵢ))/2h` is taken on the
//! same sampling state (the same trajectories, the same generator order).

use ifslab::chaos::ChaosGame;
use ifslab::model::Affine2;
use ifslab::model::diff_map::{flat_params, set_flat_params};
use ifslab::model::flame::VariationKind as V;
use ifslab::model::flame::learnable::{
    Background, FlameStack, Learn, LearnableFlame, LearnableInit,
};
use ifslab::model::segment::{Pattern, builtin};
use ifslab::render::flame_diff::{DiffFlameConfig, FlameRenderer};
use ifslab::render::sdf::{SdfRenderConfig, SdfRenderer, SdfView};
use ifslab::render::splat::{Blend, Splat, SplatConfig};
use ifslab::render::{Draws, Planes, Renderer, Sampler};

#[path = "common/blobs.rs"]
mod blobs;
#[path = "common/renderer_check.rs"]
mod renderer_check;
use blobs::Blobs;
use renderer_check::reverse_pass_matches_finite_differences;

/// `∂L/∂θ` of the splat of three affine maps (18 parameters: `∂L/∂M` row-major, then
/// `∂L/∂b`, per map) through the chaos game, the fitted framing and coverage blending.
#[test]
fn the_splat_through_the_trait() {
    let maps = vec![
        Affine2::new(0.45, 0.1, -0.05, 0.5, -0.4, -0.3),
        Affine2::new(0.5, -0.12, 0.08, 0.42, 0.45, -0.2),
        Affine2::new(0.38, 0.05, 0.1, 0.4, 0.05, 0.5),
    ];
    // 32 × 28, 2× supersampling, 24 trajectories of 100 kept points (as tests/custom_map.rs).
    let splat = Splat::<Affine2, f64>::new(SplatConfig {
        width: 32,
        height: 28,
        supersample: 2,
        sigma: 1.3,
        blend: Blend::Coverage,
        game: ChaosGame {
            trajectories: 24,
            length: 110,
            warmup: 10,
            start_half_width: 2.0,
            seed: 0,
        },
        ..SplatConfig::default()
    });
    assert_eq!(<Splat<Affine2, f64> as Renderer>::DRAWS, Draws::EveryCall);
    // A fresh stream every draw.
    assert_ne!(splat.sampling(&maps, 11, 0), splat.sampling(&maps, 11, 1));
    let scene_at = |t: &[f64]| {
        let mut m = maps.clone();
        set_flat_params(&mut m, t).unwrap();
        m
    };
    let scale = reverse_pass_matches_finite_differences(
        "splat",
        &splat,
        &flat_params(&maps),
        scene_at,
        1e-7,
        2e-4,
    );
    assert!(scale > 1e-2, "the loss should depend on the maps ({scale})");
}

/// Koch's structure at slightly moved points, so that no two distances tie by symmetry.
fn bent_koch() -> Pattern {
    let k = builtin("koch").unwrap();
    let mut th = k.flat_points();
    let bumps = [
        0.01, -0.02, 0.013, 0.004, -0.011, 0.017, 0.009, -0.006, -0.015, 0.008,
    ];
    for (v, b) in th.iter_mut().zip(bumps) {
        *v += b;
    }
    k.with_flat_points(&th).unwrap()
}

/// `∂L/∂(control points)` of the SDF raster's two planes, the intensity `exp(−d²/σ²)` and
/// the distance in units of the image side, through each pixel's nearest primitive.
#[test]
fn the_sdf_raster_through_the_trait() {
    let pattern = bent_koch();
    let view = SdfView::around([-0.05, -0.1], [1.05, 0.4], 40, 0.8);
    let cfg = SdfRenderConfig {
        depth: 3,
        cutoff: None,
    };
    let both = SdfRenderer {
        distance: true,
        ..SdfRenderer::new(view, cfg, 1.7)
    };
    assert_eq!(<SdfRenderer as Renderer>::DRAWS, Draws::Never);
    assert_eq!(
        both.planes(),
        Planes {
            channels: 2,
            height: 40,
            width: 40
        }
    );
    let scene_at = |t: &[f64]| pattern.with_flat_points(t).unwrap();
    let theta = pattern.flat_points();
    for (name, r) in [
        ("sdf intensity", SdfRenderer::new(view, cfg, 1.7)),
        ("sdf intensity + distance", both),
        (
            "sdf distance",
            SdfRenderer {
                intensity: false,
                ..both
            },
        ),
    ] {
        let scale = reverse_pass_matches_finite_differences(name, &r, &theta, scene_at, 1e-7, 1e-4);
        assert!(scale > 0.1, "{name}: the loss should depend on the points");
    }
}

/// `∂L/∂θ` of a stack of a non-linear and a linear layer on a learned background: generators
/// (pre-affine, variation weights, post-affine), final transform, κ, colours, background.
#[test]
fn the_flame_pipeline_through_the_trait() {
    let init = LearnableInit {
        translation: 0.6,
        scale: 0.6,
        final_translation: 0.2,
        kappa: 2.0,
    };
    let learn = Learn {
        weights: true,
        post: true,
    };
    let gens = [
        vec![V::Linear],
        vec![V::Spherical],
        vec![V::Handkerchief, V::Swirl],
        vec![V::Disc, V::Heart],
    ];
    let mut nonlinear = LearnableFlame::random(&gens, learn, &init, 3).unwrap();
    for (i, g) in nonlinear.generators.iter_mut().enumerate() {
        g.post = [0.9, 0.05 * i as f64, -0.1, 0.8, 0.02, -0.03];
    }
    let linear = LearnableFlame::random(
        &[vec![V::Linear], vec![V::Linear]],
        Learn::default(),
        &init,
        4,
    )
    .unwrap();
    let stack = FlameStack {
        layers: vec![nonlinear, linear],
        background: Background::Learned([0.2, -0.4, 0.1]),
    };
    let flame = FlameRenderer {
        cfg: DiffFlameConfig {
            size: 12,
            trajectories: 18,
            steps: 40,
            warmup: 3,
            chunks: 2,
        },
    };
    assert_eq!(<FlameRenderer as Renderer>::DRAWS, Draws::PerRun);
    // The same order for the same run and epoch, another for the next epoch.
    assert_eq!(flame.sampling(&stack, 11, 0), flame.sampling(&stack, 11, 0));
    assert_ne!(flame.sampling(&stack, 11, 0), flame.sampling(&stack, 11, 1));
    let scene_at = |t: &[f64]| {
        let mut s = stack.clone();
        s.set_params(t).unwrap();
        s
    };
    let scale = reverse_pass_matches_finite_differences(
        "flame",
        &flame,
        &stack.params(),
        scene_at,
        1e-6,
        1e-3,
    );
    assert!(
        scale > 1e-2,
        "the loss should depend on the stack ({scale})"
    );
}

#[test]
fn a_renderer_defined_outside_the_crate() {
    let blobs = Blobs { size: 16, s: 2.5 };
    let theta = [4.2, 5.1, 0.8, 11.3, 9.7, -0.5, 7.5, 12.2, 1.3];
    let scale = reverse_pass_matches_finite_differences(
        "blobs",
        &blobs,
        &theta,
        |t| t.to_vec(),
        1e-6,
        1e-6,
    );
    assert!(scale > 1e-2);
}

/// A renderer that only counts its draws, drawing as `D` says (0: every call, 1: once per
/// run, else never); its sampling state is `(seed, draw, how many draws so far)`.
struct Counting<const D: u8>(std::cell::Cell<u32>);

impl<const D: u8> Renderer for Counting<D> {
    type Scene = ();
    type Pixel = f64;
    type Sampling = (u64, u64, u32);
    type Tape = ();

    const DRAWS: Draws = match D {
        0 => Draws::EveryCall,
        1 => Draws::PerRun,
        _ => Draws::Never,
    };

    fn planes(&self) -> Planes {
        Planes {
            channels: 1,
            height: 1,
            width: 1,
        }
    }

    fn sampling(&self, _: &(), seed: u64, draw: u64) -> (u64, u64, u32) {
        self.0.set(self.0.get() + 1);
        (seed, draw, self.0.get())
    }

    fn forward(&self, _: &(), _: &(u64, u64, u32)) -> ifslab::Result<(Vec<f64>, ())> {
        Ok((vec![0.0], ()))
    }

    fn backward(&self, _: &(), _: &(u64, u64, u32), _: &(), _: &[f64]) -> ifslab::Result<Vec<f64>> {
        Ok(Vec::new())
    }
}

#[test]
fn the_sampler_draws_as_each_renderer_says() {
    // Every call: a fresh draw each time, of the index asked for.
    let r = Counting::<0>(Default::default());
    let s = Sampler::new(5);
    assert_eq!(*s.sampling(&r, &(), 3), (5, 3, 1));
    assert_eq!(*s.sampling(&r, &(), 3), (5, 3, 2));
    assert_eq!(*s.sampling(&r, &(), 4), (5, 4, 3));

    // Once per run: kept while the same index is asked for, redrawn for another (and for
    // an earlier one again); a clone shares the kept draw.
    let r = Counting::<1>(Default::default());
    let s = Sampler::new(5);
    let first = s.sampling(&r, &(), 0);
    assert_eq!(*first, (5, 0, 1));
    assert!(std::sync::Arc::ptr_eq(&first, &s.sampling(&r, &(), 0)));
    assert!(std::sync::Arc::ptr_eq(
        &first,
        &s.clone().sampling(&r, &(), 0)
    ));
    assert_eq!(*s.sampling(&r, &(), 1), (5, 1, 2));
    assert_eq!(*s.sampling(&r, &(), 1), (5, 1, 2));
    assert_eq!(*s.sampling(&r, &(), 0), (5, 0, 3));

    // Never: draw 0 whatever is asked, nothing kept.
    let r = Counting::<2>(Default::default());
    let s = Sampler::new(5);
    assert_eq!(*s.sampling(&r, &(), 7), (5, 0, 1));
    assert_eq!(*s.sampling(&r, &(), 9), (5, 0, 2));

    // The three renderers: exactly their own draws.
    let maps = vec![Affine2::new(0.5, 0.0, 0.0, 0.5, 0.0, 0.0)];
    let splat = Splat::<Affine2, f32>::new(SplatConfig::default());
    let s = Sampler::new(11);
    for draw in [0, 1, 7] {
        assert_eq!(
            *s.sampling(&splat, &maps, draw),
            splat.sampling(&maps, 11, draw)
        );
    }
    let stack = FlameStack {
        layers: vec![
            LearnableFlame::random(
                &[vec![V::Spherical], vec![V::Linear]],
                Learn::default(),
                &LearnableInit::default(),
                4,
            )
            .unwrap(),
        ],
        background: Background::Fixed([1.0; 3]),
    };
    let flame = FlameRenderer {
        cfg: DiffFlameConfig {
            size: 12,
            trajectories: 18,
            steps: 40,
            warmup: 3,
            chunks: 2,
        },
    };
    let s = Sampler::new(11);
    for draw in [0, 0, 2, 1] {
        assert_eq!(
            *s.sampling(&flame, &stack, draw),
            flame.sampling(&stack, 11, draw)
        );
    }
}
