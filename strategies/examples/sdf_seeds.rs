//! How often a Koch fit converges from jittered starts, with and without the self-crossing
//! penalty (`paper_repro/differentiable_ifs/`, the local-optima gallery of Scott's Fig. 4).
//!
//! For every jitter and crossing weight, fits seeds `0..N` of the best-fit-line start plus
//! Gaussian noise (the run's seed) against the Koch curve drawn by the renderer, and counts
//! the fits whose control points end within 1e-2 of the truth (up to the curve's reversal)
//! and those with IoU ≥ 0.95 of the ink above ½. Prints one CSV row per fit and a summary per
//! setting; with `--gallery DIR`, writes one PNG per setting: for each seed, the start above
//! the fit (white ink on black). The CSV rows also give the crossing penalty (words of
//! length 3) of the start and of the fit. `--sigma-start S` draws with a width shrinking from
//! S pixels to the final 1.5 over the fit (coarse to fine), or over its first
//! `--sigma-iterations K` steps.
//!
//! ```text
//! cargo run --profile ci -p ifslab-strategies --example sdf_seeds -- \
//!     --seeds 10 --jitters 0.05,0.15 --weights 0,1 --gallery paper_repro/differentiable_ifs/results
//! ```

use std::path::PathBuf;
use std::time::Instant;

use ifslab::image::Image;
use ifslab_strategies::optim::adam::AdamConfig;
use ifslab_strategies::problems::image::StrategyConfig;
use ifslab_strategies::problems::sdf::{
    SdfConfig, SdfInit, SdfLossConfig, crossing_penalty, run_sdf,
};

mod common;
use common::{iou, koch_truth, render, save_gallery};

struct Args {
    seeds: u64,
    jitters: Vec<f64>,
    weights: Vec<f64>,
    size: usize,
    depth: usize,
    iterations: u64,
    crossing_depth: usize,
    sigma_start: Option<f64>,
    sigma_iterations: Option<u64>,
    gallery: Option<PathBuf>,
}

fn parse_list(flag: &str, v: &str) -> Vec<f64> {
    v.split(',')
        .map(|x| {
            x.trim()
                .parse()
                .unwrap_or_else(|e| panic!("{flag}: `{x}` is not a number ({e})"))
        })
        .collect()
}

fn parse_args() -> Args {
    let mut a = Args {
        seeds: 10,
        jitters: vec![0.05, 0.15],
        weights: vec![0.0, 1.0],
        size: 64,
        depth: 4,
        iterations: 400,
        crossing_depth: 1,
        sigma_start: None,
        sigma_iterations: None,
        gallery: None,
    };
    let mut it = std::env::args().skip(1);
    while let Some(flag) = it.next() {
        let v = it.next().unwrap_or_else(|| panic!("{flag} needs a value"));
        let num = |v: &str| -> u64 {
            v.parse()
                .unwrap_or_else(|e| panic!("{flag}: `{v}` is not a count ({e})"))
        };
        match flag.as_str() {
            "--seeds" => a.seeds = num(&v),
            "--jitters" => a.jitters = parse_list(&flag, &v),
            "--weights" => a.weights = parse_list(&flag, &v),
            "--size" => a.size = num(&v) as usize,
            "--depth" => a.depth = num(&v) as usize,
            "--iterations" => a.iterations = num(&v),
            "--crossing-depth" => a.crossing_depth = num(&v) as usize,
            "--sigma-start" => {
                a.sigma_start = Some(
                    v.parse()
                        .unwrap_or_else(|e| panic!("{flag}: `{v}` is not a number ({e})")),
                )
            }
            "--sigma-iterations" => a.sigma_iterations = Some(num(&v)),
            "--gallery" => a.gallery = Some(PathBuf::from(v)),
            other => panic!(
                "unknown flag {other}; flags: --seeds --jitters --weights --size --depth --iterations --crossing-depth --sigma-start --sigma-iterations --gallery"
            ),
        }
    }
    a
}

/// Largest coordinate error up to the reversal symmetry of the Koch pattern.
fn koch_error(theta: &[f64], truth: &[f64]) -> f64 {
    let n = truth.len() / 2;
    let direct = (0..2 * n)
        .map(|k| (theta[k] - truth[k]).abs())
        .fold(0.0, f64::max);
    let reversed = (0..n)
        .flat_map(|i| (0..2).map(move |c| (i, c)))
        .map(|(i, c)| (theta[2 * i + c] - truth[2 * (n - 1 - i) + c]).abs())
        .fold(0.0, f64::max);
    direct.min(reversed)
}

fn main() {
    let args = parse_args();
    let sigma = 1.5;
    let truth = koch_truth();
    let truth_theta = truth.flat_points();
    let target = render(&truth, args.size, args.depth, sigma);
    let picture = Image::square(args.size, target.clone()).expect("a target");
    println!("jitter,weight,seed,error,iou,converged,seconds,start_crossing,end_crossing");
    let mut summary = Vec::new();
    for &jitter in &args.jitters {
        for &weight in &args.weights {
            let mut tiles: Vec<Vec<f64>> = Vec::new();
            let (mut conv, mut good_iou) = (0, 0);
            let t_all = Instant::now();
            for seed in 0..args.seeds {
                let dir = tempfile::tempdir().unwrap();
                let mut cfg = SdfConfig::paper(dir.path().join("unused.png"), "koch");
                cfg.size = args.size;
                cfg.depth = args.depth;
                cfg.sigma = sigma;
                cfg.sigma_start = args.sigma_start;
                cfg.sigma_iterations = args.sigma_iterations;
                cfg.iterations = args.iterations;
                cfg.checkpoint_every = 0;
                cfg.seed = seed;
                cfg.init.kind = SdfInit::Line;
                cfg.init.jitter = jitter;
                cfg.loss = SdfLossConfig {
                    crossing: weight,
                    crossing_depth: args.crossing_depth,
                    ..SdfLossConfig::default()
                };
                cfg.strategy = StrategyConfig::new(&AdamConfig {
                    lr: 2e-3,
                    final_lr_factor: 0.05,
                    ..AdamConfig::default()
                });
                let t = Instant::now();
                let out = run_sdf(&cfg, picture.clone(), None, dir.path(), false, vec![]).unwrap();
                let secs = t.elapsed().as_secs_f64();
                let fit = truth.with_flat_points(&out.theta).unwrap();
                let img = render(&fit, args.size, args.depth, sigma);
                let err = koch_error(&out.theta, &truth_theta);
                let q = iou(&img, &target);
                let ok = err < 1e-2;
                conv += ok as usize;
                good_iou += (q >= 0.95) as usize;
                let start: Vec<f64> =
                    serde_json::from_slice(&std::fs::read(dir.path().join("start.json")).unwrap())
                        .unwrap();
                let s = truth.with_flat_points(&start).unwrap();
                // The penalty with words of length 3 (what any crossing depth up to 3 sees).
                let c0 = crossing_penalty(&s, 3, false).unwrap().0;
                let c1 = crossing_penalty(&fit, 3, false).unwrap().0;
                println!(
                    "{jitter},{weight},{seed},{err:.5},{q:.4},{ok},{secs:.2},{c0:.2e},{c1:.2e}"
                );
                if args.gallery.is_some() {
                    tiles.push(
                        render(&s, args.size, args.depth, sigma)
                            .into_iter()
                            .chain(img)
                            .collect(),
                    );
                }
            }
            summary.push((
                jitter,
                weight,
                conv,
                good_iou,
                t_all.elapsed().as_secs_f64() / args.seeds.max(1) as f64,
            ));
            if let Some(g) = &args.gallery {
                // Seeds side by side: start in the top half, fit in the bottom half.
                let path = g.join(format!("koch_seeds_jitter{jitter}_crossing{weight}.png"));
                save_gallery(&path, &tiles, args.size, 2 * args.size);
            }
        }
    }
    println!("\njitter,weight,converged,iou>=0.95,seeds,seconds_per_fit");
    for (j, w, c, q, s) in summary {
        println!("{j},{w},{c},{q},{},{s:.2}", args.seeds);
    }
}
