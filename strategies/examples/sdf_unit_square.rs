//! The Koch symmetry pattern fitted to the unit square (Scott's supplementary Fig. 5: "the
//! same symmetry pattern as the Koch curve, but with the unit square as target image").
//!
//! The target is a filled square (ink inside `[m, 1 − m]²` of the unit-square view); every
//! fit starts from the paper's best-fit-line start plus Gaussian noise of `--jitter` (the
//! run's seed: for a square the best-fit line is no guide, so the noise makes the starts
//! differ) and runs Adam on the five control points, optionally with the barrier on the
//! maps' scales (`--barrier W`: without it some maps grow past 1). Prints one CSV row per seed (IoU of
//! the fit's ink above ½ against the square, the fit's loss, the four maps' contraction
//! ratios, seconds) and writes a gallery: the target, then for each seed the start above the
//! fit (white ink on black, drawn at `--tile` pixels one level deeper than the fit).
//!
//! ```text
//! cargo run --profile ci -p ifslab-strategies --example sdf_unit_square -- \
//!     --seeds 8 --gallery paper_repro/differentiable_ifs/results/unit_square.png
//! ```

use std::path::PathBuf;
use std::time::Instant;

use ifslab::image::Image;
use ifslab::model::segment::builtin;
use ifslab::render::sdf::SdfView;
use ifslab_strategies::optim::adam::AdamConfig;
use ifslab_strategies::problems::image::StrategyConfig;
use ifslab_strategies::problems::sdf::{SdfConfig, SdfInit, SdfLossConfig, run_sdf};

mod common;
use common::{iou, render, save_gallery};

struct Args {
    seeds: u64,
    jitter: f64,
    margin: f64,
    size: usize,
    depth: usize,
    iterations: u64,
    sigma: f64,
    sigma_start: Option<f64>,
    distance: f64,
    barrier: f64,
    tile: usize,
    gallery: Option<PathBuf>,
}

fn parse_args() -> Args {
    let mut a = Args {
        seeds: 8,
        jitter: 0.1,
        margin: 0.2,
        size: 64,
        depth: 5,
        iterations: 600,
        sigma: 1.5,
        sigma_start: Some(6.0),
        distance: 0.0,
        barrier: 0.0,
        tile: 128,
        gallery: None,
    };
    let mut it = std::env::args().skip(1);
    while let Some(flag) = it.next() {
        let v = it.next().unwrap_or_else(|| panic!("{flag} needs a value"));
        let num = |v: &str| -> f64 {
            v.parse()
                .unwrap_or_else(|e| panic!("{flag}: `{v}` is not a number ({e})"))
        };
        match flag.as_str() {
            "--seeds" => a.seeds = num(&v) as u64,
            "--jitter" => a.jitter = num(&v),
            "--margin" => a.margin = num(&v),
            "--size" => a.size = num(&v) as usize,
            "--depth" => a.depth = num(&v) as usize,
            "--iterations" => a.iterations = num(&v) as u64,
            "--sigma" => a.sigma = num(&v),
            "--sigma-start" => a.sigma_start = (num(&v) > 0.0).then(|| num(&v)),
            "--distance" => a.distance = num(&v),
            "--barrier" => a.barrier = num(&v),
            "--tile" => a.tile = num(&v) as usize,
            "--gallery" => a.gallery = Some(PathBuf::from(v)),
            other => panic!(
                "unknown flag {other}; flags: --seeds --jitter --margin --size --depth --iterations --sigma --sigma-start --distance --barrier --tile --gallery"
            ),
        }
    }
    a
}

/// The filled square `[m, 1 − m]²` on the unit-square view (pixel centres, rows top-down).
fn square(size: usize, m: f64) -> Vec<f64> {
    let view = SdfView::unit_square(size);
    (0..size * size)
        .map(|i| {
            let [x, y] = view.centre(i / size, i % size);
            (x >= m && x <= 1.0 - m && y >= m && y <= 1.0 - m) as u8 as f64
        })
        .collect()
}

fn main() {
    let args = parse_args();
    let target = square(args.size, args.margin);
    let picture = Image::square(args.size, target.clone()).expect("a target");
    let koch = builtin("koch").unwrap();
    println!("seed,iou,loss,ratio_min,ratio_max,seconds");
    let mut tiles: Vec<Vec<f64>> = Vec::new();
    let mut ious = Vec::new();
    let t_all = Instant::now();
    for seed in 0..args.seeds {
        let dir = tempfile::tempdir().unwrap();
        let mut cfg = SdfConfig::paper(dir.path().join("unused.png"), "koch");
        cfg.size = args.size;
        cfg.depth = args.depth;
        cfg.sigma = args.sigma;
        cfg.sigma_start = args.sigma_start;
        cfg.iterations = args.iterations;
        cfg.checkpoint_every = 0;
        cfg.seed = seed;
        cfg.init.kind = SdfInit::Line;
        cfg.init.jitter = args.jitter;
        cfg.loss = SdfLossConfig {
            distance: args.distance,
            scale_barrier: args.barrier,
            ..SdfLossConfig::default()
        };
        cfg.strategy = StrategyConfig::new(&AdamConfig {
            lr: 2e-3,
            final_lr_factor: 0.05,
            ..AdamConfig::default()
        });
        let t = Instant::now();
        let out = match run_sdf(&cfg, picture.clone(), None, dir.path(), false, vec![]) {
            Ok(o) => o,
            Err(e) => {
                println!("{seed},,,,,{:.2} # {e}", t.elapsed().as_secs_f64());
                continue;
            }
        };
        let secs = t.elapsed().as_secs_f64();
        let fit = koch.with_flat_points(&out.theta).unwrap();
        let ratios: Vec<f64> = fit.maps().unwrap().iter().map(|m| m.scale()).collect();
        let img = render(&fit, args.size, args.depth, args.sigma);
        let q = iou(&img, &target);
        ious.push(q);
        println!(
            "{seed},{q:.4},{:.5},{:.3},{:.3},{secs:.2}",
            out.loss,
            ratios.iter().cloned().fold(f64::INFINITY, f64::min),
            ratios.iter().cloned().fold(0.0, f64::max),
        );
        // Gallery tiles at `--tile` pixels, one level deeper, σ 1 px.
        let start = koch.with_flat_points(&out.start).unwrap();
        tiles.push(
            render(&start, args.tile, args.depth + 1, 1.0)
                .into_iter()
                .chain(render(&fit, args.tile, args.depth + 1, 1.0))
                .collect(),
        );
    }
    let n = ious.len().max(1) as f64;
    let mean = ious.iter().sum::<f64>() / n;
    println!(
        "\n# {} fits, IoU mean {mean:.3}, min {:.3}, max {:.3}; {:.2} s per fit",
        ious.len(),
        ious.iter().cloned().fold(f64::INFINITY, f64::min),
        ious.iter().cloned().fold(0.0, f64::max),
        t_all.elapsed().as_secs_f64() / args.seeds.max(1) as f64
    );
    if let Some(g) = &args.gallery {
        // The target (twice, to fill the column), then each seed: start above fit.
        let (s, h) = (args.tile, 2 * args.tile);
        let big = square(args.tile, args.margin);
        let mut cols = vec![big.iter().chain(&big).cloned().collect::<Vec<f64>>()];
        cols.extend(tiles);
        save_gallery(g, &cols, s, h);
    }
}
