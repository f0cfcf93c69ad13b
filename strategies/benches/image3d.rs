//! One iteration of the multi-view fit (issue 39's speed goal): 8 turntable views of 128²,
//! 100 000 points in all (400 trajectories of 260 steps, 10 dropped), 4× supersampling,
//! σ = 1, coverage, `invert3d`'s default loss and terms — `Image3dProblem::evaluate`, the loss
//! and its gradient the way the driver calls it — and its stages: the 3-D chaos game with its tape,
//! the multi-view forward (projection and the 2-D kernel per view), and the reverse pass.
//!
//! ```sh
//! cargo bench -p ifslab-strategies --bench image3d
//! ```
//!
//! The maps are the 3-D fern's (four maps, one of them nearly flat); the views are the
//! Sierpiński tetrahedron's, drawn by the same splat with another seed.
//!
//! Group `collage3_64`: the start of an `invert3d` fit on those views — the visual hull
//! carved at 64³ (`hull`) and the collage search in space for four maps at its defaults
//! (`collage_search`: 4000 candidate maps, 150 Adam steps each, ten greedy covers scored
//! by their silhouettes).

use std::hint::black_box;

use criterion::{Criterion, criterion_group, criterion_main};
use ifslab::image::Image;
use ifslab::model::map3::{DiffMap, SvdMap3, fern_3d, sierpinski_tetrahedron};
use ifslab::render::Renderer;
use ifslab::render::splat3d::{Lens, MultiViewConfig, MultiViewSplat, turntable};
use ifslab_strategies::driver::Differentiable;
use ifslab_strategies::problems::image3d::{
    CollageSearch3, HullConfig, Image3dConfig, Image3dProblem, Views, collage_covers3, visual_hull,
};

#[global_allocator]
static GLOBAL: mimalloc::MiMalloc = mimalloc::MiMalloc;

const SIDE: usize = 128;
const VIEWS: usize = 8;

fn bench_image3d(c: &mut Criterion) {
    let cameras = turntable(
        VIEWS,
        25.0,
        2.6,
        Lens::pinhole_fov(50f64.to_radians(), SIDE, SIDE),
        SIDE,
        SIDE,
    )
    .unwrap();
    let cfg = MultiViewConfig::default();
    let truth = SvdMap3::from_code(&sierpinski_tetrahedron(), 1e-6).unwrap();
    let target = MultiViewSplat::<SvdMap3, f32>::new(cfg.clone(), cameras.clone())
        .unwrap()
        .forward(&truth, &99)
        .unwrap()
        .0;
    let n = cameras.len() as u32;
    let target = Image::new(SIDE as u32, SIDE as u32, n, target).unwrap();
    let views = Views::new(cameras.clone(), target).unwrap();
    let (fern, _) = fern_3d();
    let maps = SvdMap3::from_code(&fern, 1e-6).unwrap();
    let theta: Vec<f64> = maps.iter().flat_map(|m| m.params()).collect();
    // The fit's terms as `invert3d` sets them by default (ink guard, volume term, maps drawn
    // as its defaults draw them), at the issue's render setting.
    let defaults = Image3dConfig::default();
    let problem = Image3dProblem::<f32>::new(&maps, &views, cfg.clone(), defaults.loss(), 0)
        .unwrap()
        .with_ink(defaults.ink, defaults.ink_slack)
        .unwrap()
        .with_volume(defaults.volume)
        .unwrap()
        .with_map_choice(defaults.probabilities);
    let splat = MultiViewSplat::<SvdMap3, f32>::new(cfg.clone(), cameras).unwrap();

    let mut g = c.benchmark_group("image3d_8x128_100k");
    g.sample_size(20);
    g.bench_function("chaos_game", |b| {
        b.iter(|| {
            black_box(
                ifslab::chaos::Tape3::run(&cfg.game, &maps, None, 1)
                    .unwrap()
                    .kept_points()
                    .len(),
            )
        })
    });
    g.bench_function("forward", |b| {
        b.iter(|| black_box(splat.forward(&maps, &1).unwrap().0.len()))
    });
    let (image, tape) = splat.forward(&maps, &1).unwrap();
    let grad: Vec<f32> = image
        .iter()
        .zip(&views.image.values)
        .map(|(a, t)| a - t)
        .collect();
    g.bench_function("backward", |b| {
        b.iter(|| black_box(splat.backward(&maps, &1, &tape, &grad).unwrap().len()))
    });
    g.bench_function("iteration", |b| {
        b.iter(|| black_box(problem.evaluate(&theta, 3).unwrap().loss))
    });
    g.finish();

    let hull_cfg = HullConfig::default();
    let mut g = c.benchmark_group("collage3_64");
    g.sample_size(10);
    g.bench_function("hull", |b| {
        b.iter(|| black_box(visual_hull(&views, &hull_cfg).unwrap().kept.len()))
    });
    let hull = visual_hull(&views, &hull_cfg).unwrap();
    let search = CollageSearch3::default();
    g.bench_function("collage_search", |b| {
        b.iter(|| black_box(collage_covers3(&hull, &views, 4, 0, &search).unwrap()[0].score))
    });
    g.finish();
}

criterion_group!(benches, bench_image3d);
criterion_main!(benches);
