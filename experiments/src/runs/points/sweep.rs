//! The pool sweep (the paper's Fig. 5b): the proportion of seeded runs that converge
//! (v_D ≥ the threshold) per pre-selection pool size. The fits run in parallel, each
//! checkpointed as it ends; the merged tables depend only on the seeds.

use std::path::Path;
use std::time::Instant;

use crate::error::Context;
use ifslab::chaos::mix_seed;
use ifslab_strategies::problems::em::{EmConfig, fit};
use rayon::prelude::*;
use serde_json::json;

use super::fits::{self, Finished};
use super::outputs::write_json;
use super::truth::{RIGHT_AGREEMENT, Truth};
use super::{Data, PointsConfig, PointsSummary, PoolResult};
use crate::plot::{Series, line_chart};
use crate::progress::Progress;

/// The label of repeat `r` of pool size `p` under `fits/`.
fn label(p: usize, r: usize) -> String {
    format!("pool-{p:03}-repeat-{r:03}")
}

/// Runs the sweep of `cfg` (its `sweep_pool` × `repeats` fits) into `dir`.
pub(super) fn sweep(
    cfg: &PointsConfig,
    dir: &Path,
    data: &Data,
    truth: Option<&Truth>,
    started: Instant,
    progress: &dyn Progress,
) -> crate::Result<PointsSummary> {
    let (train, heldout) = (&data.train, data.heldout());
    let mut jobs: Vec<(String, EmConfig)> = Vec::new();
    for &p in &cfg.sweep_pool {
        for r in 0..cfg.repeats {
            let seed = mix_seed(cfg.seed, (p as u64) << 20 | r as u64);
            jobs.push((label(p, r), cfg.em_config(seed, p)));
        }
    }
    let mut done: Vec<Option<Finished>> = jobs
        .iter()
        .map(|(l, em)| fits::load(dir, l, em))
        .collect::<crate::Result<_>>()?;
    let resumed = done.iter().filter(|d| d.is_some()).count();
    if resumed > 0 {
        progress.message(&format!(
            "{resumed} of {} fits read from the checkpoints in {}",
            jobs.len(),
            dir.join(fits::FITS_DIR).display()
        ));
    }
    progress.start("runs", jobs.len() as u64);
    progress.inc(resumed as u64);
    let t0 = Instant::now();
    let missing: Vec<usize> = (0..jobs.len()).filter(|&i| done[i].is_none()).collect();
    let fresh: Vec<(usize, Finished)> = missing
        .par_iter()
        .map(|&i| -> crate::Result<(usize, Finished)> {
            let (l, em) = &jobs[i];
            let t = Instant::now();
            let r = fit(train, heldout, em, &mut |_| {}).map_err(|e| e.to_string());
            let secs = t.elapsed().as_secs_f64();
            fits::save(dir, l, em, &r, secs)?;
            progress.inc(1);
            Ok((i, (r, secs)))
        })
        .collect::<crate::Result<_>>()?;
    progress.finish();
    for (i, f) in fresh {
        done[i] = Some(f);
    }
    let secs = t0.elapsed().as_secs_f64();

    let mut csv = String::from(
        "pool,repeat,seed,converged,deepest_weight,mean_depth,heldout_log_likelihood,scales,truth_agreement,truth_scale_error\n",
    );
    let mut pools = Vec::new();
    let mut curve = Vec::new();
    let mut failed = 0;
    for (pi, &p) in cfg.sweep_pool.iter().enumerate() {
        let (mut conv, mut right, mut both) = (0, 0, 0);
        let mut lls = Vec::new();
        for r in 0..cfg.repeats {
            let i = pi * cfg.repeats + r;
            let seed = jobs[i].1.seed;
            match &done[i].as_ref().context("every fit finished")?.0 {
                Ok(f) => {
                    let ll = heldout
                        .map(|h| f.model.mean_log_likelihood(h))
                        .transpose()?
                        .unwrap_or(f64::NAN);
                    let against = truth.map(|t| t.compare(&f.model)).transpose()?;
                    let is_right = against.is_some_and(|a| a.is_right());
                    conv += usize::from(f.converged);
                    right += usize::from(is_right);
                    both += usize::from(is_right && f.converged);
                    lls.push(ll);
                    let mut scales: Vec<f64> = f.model.components.iter().map(|c| c.s).collect();
                    scales.sort_by(f64::total_cmp);
                    let scales: Vec<String> = scales.iter().map(|v| format!("{v:.5}")).collect();
                    csv.push_str(&format!(
                        "{p},{r},{seed},{},{},{},{ll},{},{},{}\n",
                        f.converged,
                        f.model.deepest_weight(),
                        f.model.mean_depth(),
                        scales.join(";"),
                        against.map_or(String::new(), |a| a.agreement.to_string()),
                        against.map_or(String::new(), |a| a.scale_error.to_string()),
                    ));
                }
                Err(e) => {
                    failed += 1;
                    progress.message(&format!("pool {p}, repeat {r}: {e}"));
                    csv.push_str(&format!("{p},{r},{seed},false,,,,,,\n"));
                }
            }
        }
        let prop = conv as f64 / cfg.repeats as f64;
        lls.sort_by(f64::total_cmp);
        let median = lls.get(lls.len() / 2).copied().unwrap_or(f64::NAN);
        progress.message(&format!(
            "pool {p:>3}: {conv}/{} converged ({prop:.3}){}, median held-out {median:.4}",
            cfg.repeats,
            if truth.is_some() {
                format!(", {right} right (agreement ≥ {RIGHT_AGREEMENT}), {both} both")
            } else {
                String::new()
            }
        ));
        curve.push((p as f64, prop));
        pools.push(PoolResult {
            pool: p,
            converged: conv,
            repeats: cfg.repeats,
            proportion: prop,
            median_heldout_log_likelihood: median,
            right: truth.map(|_| right),
            converged_and_right: truth.map(|_| both),
        });
    }
    ifslab::io::write_atomic(&dir.join("pool_sweep.csv"), csv.as_bytes())?;
    let resolved = cfg.resolved()?;
    write_json(
        &dir.join("pool_sweep.json"),
        &json!({"source": data.source, "k": cfg.k, "depth": cfg.depth, "iterations": cfg.iterations,
                "batch": cfg.batch, "preselect_depth": cfg.preselect_depth,
                "preselect_iterations": cfg.preselect_iterations, "update": resolved.update,
                "em": cfg.em_config(cfg.seed, cfg.sweep_pool[0]), "truth": cfg.truth,
                "right_agreement": RIGHT_AGREEMENT, "results": pools, "seconds": secs,
                "resumed_fits": resumed, "total_seconds": started.elapsed().as_secs_f64()}),
    )?;
    line_chart(
        &dir.join("pool_sweep.png"),
        &format!("proportion converged ({} runs per pool size)", cfg.repeats),
        "pool size",
        "proportion converged",
        &[Series {
            name: "converged",
            points: curve,
        }],
        false,
    )?;
    if failed > 0 {
        progress.message(&format!("{failed} fit(s) failed; see above"));
    }
    progress.message(&format!("sweep: {} runs in {secs:.1} s", jobs.len()));
    Ok(PointsSummary {
        source: data.source.clone(),
        dim: data.all.dim(),
        points: [data.all.len(), data.train.len(), data.test.len()],
        fits: jobs.len(),
        resumed_fits: resumed,
        failed_fits: failed,
        converged_fits: pools.iter().map(|p| p.converged).sum(),
        seconds: 0.0,
        best: None,
        sweep: pools,
    })
}
