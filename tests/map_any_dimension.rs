//! One map type written once for every dimension, trained by both splats.
//!
//! The map traits take the dimension as a const parameter (`Map<D>`, `DiffMap<D>`), so a map
//! family whose formula does not care about the dimension is one `impl<const D: usize>`:
//! here a homothety `x ↦ s·x + t` (parameters `[s, t₀, …, t_{D−1}]`), defined outside the
//! crate. At `D = 2` it is a map of the plane that the 2-D splat renders and differentiates;
//! at `D = 3` a map of space that the multi-view splat does. Checked: its vector–Jacobian
//! products against finite differences in both dimensions (the core's one `vjp_check`), both
//! splats' reverse passes against central differences through the `Renderer` trait, and the
//! 2-D splat of homotheties drawing the same bits as the splat of the same maps written as
//! `Affine2`s (so the generic traits cost the 2-D path nothing it did not already do).

use ifslab::chaos::ChaosGame;
use ifslab::model::map::{DiffMap, Map, flat_params, set_flat_params, vjp_check};
use ifslab::model::map3::DiffMap3;
use ifslab::model::{Affine2, DiffMap2};
use ifslab::render::Renderer;
use ifslab::render::splat::{Blend, Splat, SplatConfig};
use ifslab::render::splat3d::{Lens, MultiViewConfig, MultiViewSplat, turntable};

#[path = "common/renderer_check.rs"]
mod renderer_check;
use renderer_check::reverse_pass_matches_finite_differences;

/// `x ↦ s·x + t` in `R^D`.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Homothety<const D: usize> {
    s: f64,
    t: [f64; D],
}

impl<const D: usize> Map<D> for Homothety<D> {
    #[inline(always)]
    fn apply(&self, p: [f64; D]) -> [f64; D] {
        std::array::from_fn(|k| self.s.mul_add(p[k], self.t[k]))
    }

    fn affine(&self) -> Option<([[f64; D]; D], [f64; D])> {
        let m = std::array::from_fn(|r| std::array::from_fn(|c| if r == c { self.s } else { 0.0 }));
        Some((m, self.t))
    }
}

impl<const D: usize> DiffMap<D> for Homothety<D> {
    const PARAMS: Option<usize> = Some(D + 1);

    fn n_params(&self) -> usize {
        D + 1
    }

    fn write_params(&self, out: &mut [f64]) {
        out[0] = self.s;
        out[1..].copy_from_slice(&self.t);
    }

    fn set_params(&mut self, p: &[f64]) {
        self.s = p[0];
        self.t.copy_from_slice(&p[1..]);
    }

    /// `s·λ`.
    fn vjp_point(&self, _x: [f64; D], lambda: [f64; D]) -> [f64; D] {
        lambda.map(|l| self.s * l)
    }

    /// `∂/∂s = ⟨λ, x⟩`, `∂/∂t = λ`.
    fn vjp_params(&self, x: [f64; D], lambda: [f64; D], grad: &mut [f64]) {
        grad[0] += (0..D).map(|k| lambda[k] * x[k]).sum::<f64>();
        for k in 0..D {
            grad[1 + k] += lambda[k];
        }
    }
}

/// Bounds written with the dimension's names accept the map: the renderers' bounds.
fn is_a_map_of_the_plane<M: DiffMap2>(_: &M) {}
fn is_a_map_of_space<M: DiffMap3>(_: &M) {}

fn plane_maps() -> Vec<Homothety<2>> {
    vec![
        Homothety {
            s: 0.5,
            t: [-0.4, -0.3],
        },
        Homothety {
            s: 0.45,
            t: [0.45, -0.2],
        },
        Homothety {
            s: 0.5,
            t: [0.05, 0.5],
        },
    ]
}

fn space_maps() -> Vec<Homothety<3>> {
    vec![
        Homothety {
            s: 0.5,
            t: [0.4, 0.0, -0.3],
        },
        Homothety {
            s: 0.45,
            t: [-0.4, 0.3, 0.0],
        },
        Homothety {
            s: 0.5,
            t: [0.0, -0.35, 0.35],
        },
        Homothety {
            s: 0.4,
            t: [0.0, 0.1, 0.0],
        },
    ]
}

#[test]
fn one_impl_has_exact_vjps_in_the_plane_and_in_space() {
    let p = Homothety {
        s: 0.6,
        t: [0.3, -0.2],
    };
    let q = Homothety {
        s: -0.45,
        t: [0.1, 0.7, -0.4],
    };
    is_a_map_of_the_plane(&p);
    is_a_map_of_space(&q);
    let c2 = vjp_check(&p, [0.7, -1.3], [0.4, 0.9], 1e-6);
    let c3 = vjp_check(&q, [0.2, -0.5, 1.1], [-0.3, 0.8, 0.5], 1e-6);
    for (name, c) in [("D = 2", c2), ("D = 3", c3)] {
        assert!(c.scale > 0.1, "{name}: {c:?}");
        assert!(
            c.point < 1e-8 && c.params < 1e-8 && c.fused == 0.0,
            "{name}: {c:?}"
        );
    }
    // The flat layout is the same functions in both dimensions.
    let mut maps = space_maps();
    let mut flat = flat_params(&maps);
    assert_eq!(flat.len(), 16);
    flat[4] = 0.3;
    set_flat_params(&mut maps, &flat).unwrap();
    assert_eq!(maps[1].s, 0.3);
    flat[9] = f64::NAN;
    let e = set_flat_params(&mut maps, &flat).unwrap_err().to_string();
    assert!(e.contains("map 2, parameter 1"), "{e}");
}

/// `renderer`'s reverse pass through `maps` against central differences (the loss must
/// depend on them).
fn trains<const D: usize, R>(name: &str, renderer: &R, maps: &[Homothety<D>])
where
    R: Renderer<Scene = [Homothety<D>], Pixel = f64>,
{
    let scene_at = |t: &[f64]| {
        let mut m = maps.to_vec();
        set_flat_params(&mut m, t).unwrap();
        m
    };
    let theta = flat_params(maps);
    let scale =
        reverse_pass_matches_finite_differences(name, renderer, &theta, scene_at, 1e-7, 2e-4);
    assert!(
        scale > 1e-2,
        "{name}: the loss should depend on the maps ({scale})"
    );
}

fn splat_config() -> SplatConfig {
    SplatConfig {
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
    }
}

#[test]
fn the_plane_splat_trains_it_and_draws_the_bits_of_the_affine_form() {
    let maps = plane_maps();
    let splat = Splat::<Homothety<2>, f64>::new(splat_config());
    trains("2-D splat of homotheties", &splat, &maps);

    // The same maps as affine maps: the same trajectories, so the same image, bit for bit.
    let affine: Vec<Affine2> = maps
        .iter()
        .map(|m| Affine2::new(m.s, 0.0, 0.0, m.s, m.t[0], m.t[1]))
        .collect();
    let as_affine = Splat::<Affine2, f64>::new(splat_config());
    let sampling = splat.sampling(&maps, 5, 0);
    assert_eq!(sampling, as_affine.sampling(&affine, 5, 0));
    let (a, _) = splat.forward(&maps, &sampling).unwrap();
    let (b, _) = as_affine.forward(&affine, &sampling).unwrap();
    assert!(a.iter().any(|&v| v > 0.0));
    assert!(
        a.iter().zip(&b).all(|(x, y)| x.to_bits() == y.to_bits()),
        "the homotheties' image differs from their affine form's"
    );
}

#[test]
fn the_multi_view_splat_trains_the_same_impl_in_space() {
    let cams = turntable(
        3,
        25.0,
        3.5,
        Lens::pinhole_fov(40f64.to_radians(), 24, 20),
        24,
        20,
    )
    .unwrap();
    let cfg = MultiViewConfig {
        supersample: 2,
        sigma: 1.3,
        blend: Blend::Coverage,
        game: ChaosGame {
            trajectories: 30,
            length: 85,
            warmup: 5,
            start_half_width: 1.0,
            seed: 0,
        },
        ..MultiViewConfig::default()
    };
    let splat = MultiViewSplat::<Homothety<3>, f64>::new(cfg, cams).unwrap();
    trains("multi-view splat of homotheties", &splat, &space_maps());
}
