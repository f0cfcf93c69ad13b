//! Scott's Fig. 3: the loss gradient at one control point of the Koch pattern over a grid of
//! positions, the others held at the truth — fine-scale MSE against multi-scale MSE against
//! the direction to the optimum (`paper_repro/differentiable_ifs/`).
//!
//! The Koch curve from (0.15, 0.4) to (0.85, 0.4) drawn by the renderer (`--size`², depth 5,
//! σ 1.5 px) is the target; p₂ (the apex) moves over a `--grid`² lattice of the square of
//! half-side `--half` around its true place. Each panel draws the descent direction −∇ at
//! p₂ (only the direction); the counts printed are how many grid points have a descent
//! direction within 90° of the way to the optimum, and the mean cosine (a zero gradient
//! counts as cosine 0).
//!
//! ```text
//! cargo run --profile ci -p ifslab-experiments --example sdf_gradient_field -- OUT.png
//! ```

use std::path::PathBuf;

use anyhow::Context;
use ifslab::model::segment::{SegmentMap, builtin};
use ifslab::render::sdf::{SdfRaster, SdfRenderConfig, SdfView};
use ifslab_experiments::plot::{Field, vector_fields};
use ifslab_strategies::problems::sdf::{SdfLossConfig, SdfProblem};

fn main() -> anyhow::Result<()> {
    let mut out = PathBuf::from("fig3_gradient_field.png");
    let (mut size, mut grid, mut half) = (128usize, 15usize, 0.15f64);
    let mut args = std::env::args().skip(1);
    while let Some(a) = args.next() {
        let mut val = || args.next().with_context(|| format!("{a} needs a value"));
        match a.as_str() {
            "--size" => size = val()?.parse()?,
            "--grid" => grid = val()?.parse()?,
            "--half" => half = val()?.parse()?,
            _ if !a.starts_with("--") => out = PathBuf::from(a),
            _ => anyhow::bail!("unknown flag {a}; flags: --size N --grid N --half H, OUT.png"),
        }
    }
    anyhow::ensure!(grid >= 2, "--grid must be at least 2");
    anyhow::ensure!(half > 0.0 && half.is_finite(), "--half must be > 0");
    let (depth, sigma) = (5, 1.5);
    let to = SegmentMap::between([0.0, 0.0], [1.0, 0.0], [0.15, 0.4], [0.85, 0.4]).unwrap();
    let truth = builtin("koch")?.transformed(&to)?;
    let view = SdfView::unit_square(size);
    let target = SdfRaster::render(
        &truth,
        &view,
        &SdfRenderConfig {
            depth,
            cutoff: None,
        },
    )?
    .to_image(sigma);
    let theta0 = truth.flat_points();
    let opt = (theta0[4], theta0[5]);
    let step = 2.0 * half / (grid - 1) as f64;
    let positions: Vec<(f64, f64)> = (0..grid)
        .flat_map(|r| (0..grid).map(move |c| (c, r)))
        .map(|(c, r)| {
            (
                opt.0 - half + c as f64 * step,
                opt.1 - half + r as f64 * step,
            )
        })
        .collect();
    let toward: Vec<(f64, f64, f64, f64)> = positions
        .iter()
        .map(|&(x, y)| (x, y, opt.0 - x, opt.1 - y))
        .collect();
    let mut panels = Vec::new();
    for (name, levels) in [
        ("fine scale (levels 0)", 0usize),
        ("multi-scale (levels 4)", 4),
    ] {
        let problem = SdfProblem::new(
            truth.clone(),
            target.clone(),
            view,
            depth,
            sigma,
            SdfLossConfig {
                levels,
                ..SdfLossConfig::default()
            },
        )?;
        let mut arrows = Vec::new();
        let (mut agree, mut zero, mut cos_sum) = (0usize, 0usize, 0.0f64);
        for &(x, y) in &positions {
            let mut theta = theta0.clone();
            theta[4] = x;
            theta[5] = y;
            let g = problem.eval(&theta, true)?.grad.unwrap_or_default();
            let d = (-g[4], -g[5]);
            let to_opt = (opt.0 - x, opt.1 - y);
            let (nd, nt) = (d.0.hypot(d.1), to_opt.0.hypot(to_opt.1));
            if nd == 0.0 {
                zero += 1;
            } else if nt > 0.0 {
                let c = (d.0 * to_opt.0 + d.1 * to_opt.1) / (nd * nt);
                cos_sum += c;
                agree += (c > 0.0) as usize;
            }
            arrows.push((x, y, d.0, d.1));
        }
        let n = positions.len();
        println!(
            "{name}: {agree} of {n} grid points descend toward the optimum (within 90°), {zero} have a zero gradient, mean cosine {:.3}",
            cos_sum / n as f64
        );
        panels.push((name, arrows));
    }
    let fields: Vec<Field<'_>> = std::iter::once(Field {
        title: "toward the optimum",
        arrows: &toward,
        colour: 4,
    })
    .chain(panels.iter().enumerate().map(|(i, (name, arrows))| Field {
        title: name,
        arrows,
        // Fine scale blue, multi-scale green (the paper's colours).
        colour: [3, 1][i],
    }))
    .collect();
    vector_fields(
        &out,
        &format!(
            "Koch, p2 moved, others at the truth ({size}², depth {depth}, σ {sigma} px): descent directions"
        ),
        (
            (opt.0 - half - step, opt.0 + half + step),
            (opt.1 - half - step, opt.1 + half + step),
        ),
        0.7 * step,
        &fields,
        &[("p2*", opt.0, opt.1)],
    )?;
    println!("wrote {}", out.display());
    Ok(())
}
