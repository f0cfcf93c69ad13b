//! Flame-learning runs (`problem = "flame"`, `ifslab flame learn`): config → run folder with
//! the resolved config, the target as the fit sees it, checkpoints and `log.csv` as it goes,
//! then the learned render at the training size and at `eval_size`, the target and render
//! side by side, the learned flame as a `.flame` file for flam3 and the flame artists' tools,
//! the loss plot and `summary.json`.

use std::path::Path;
use std::time::Instant;

use anyhow::Context;
use ifslab::image::Image;
use ifslab::model::flame::write_flames;
use ifslab::render::flame_diff::{DiffFlameConfig, GeneratorOrder, forward};
use ifslab_strategies::problems::flame::{
    BackgroundConfig, FlameLearnConfig, load_rgb_target, run_flame,
};
use ifslab_strategies::problems::image::ensure_new_run_dir;
use serde::Serialize;

use crate::progress::{Progress, ProgressObserver};
use crate::runs::inversion::{CONFIG_FILE, loss_plot};

/// The learned flame inside a run folder.
pub const LEARNED_FLAME_FILE: &str = "learned.flame";

/// What `summary.json` holds.
#[derive(Clone, Debug, Serialize)]
pub struct FlameSummary {
    /// The strategy.
    pub strategy: String,
    /// Iterations completed.
    pub iterations: u64,
    /// Wall-clock seconds of this process's part of the run.
    pub seconds: f64,
    /// Seconds per iteration of this process's part.
    pub seconds_per_iteration: f64,
    /// The authors' MSE (squared error summed over RGB, averaged over pixels) at the start.
    pub start_mse: f64,
    /// The same at the returned θ.
    pub mse: f64,
    /// `last` or `start`.
    pub returned: String,
    /// Layers × generators.
    pub generators: Vec<usize>,
    /// What was done to the target (greyscale, alpha), if anything.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub target_note: Option<String>,
}

impl FlameSummary {
    /// A line for the terminal.
    pub fn headline(&self) -> String {
        format!(
            "{} iterations of {} in {:.1} s ({:.1} ms/iteration), MSE {:.4} → {:.4}",
            self.iterations,
            self.strategy,
            self.seconds,
            1e3 * self.seconds_per_iteration,
            self.start_mse,
            self.mse
        )
    }
}

fn save_rgb(path: &Path, planes: &[f64], size: usize) -> anyhow::Result<()> {
    let v: Vec<f32> = planes.iter().map(|&x| x as f32).collect();
    Image::new(size as u32, size as u32, 3, v)?.save_png(path)?;
    Ok(())
}

/// Target and render side by side (a 4-pixel white gap).
fn side_by_side(target: &[f32], render: &[f64], size: usize) -> Vec<f64> {
    let gap = 4;
    let w = 2 * size + gap;
    let mut out = vec![1.0; 3 * w * size];
    for ch in 0..3 {
        for y in 0..size {
            for x in 0..size {
                let i = ch * size * size + y * size + x;
                out[ch * w * size + y * w + x] = target[i] as f64;
                out[ch * w * size + y * w + size + gap + x] = render[i];
            }
        }
    }
    out
}

/// Runs (or resumes) the fit of `cfg` into `dir` and writes every output.
pub fn run(
    cfg: &FlameLearnConfig,
    dir: &Path,
    resume: bool,
    progress: Box<dyn Progress>,
) -> anyhow::Result<FlameSummary> {
    cfg.validate()?;
    let size = cfg.sampler.size;
    // Transparent targets are laid over the fixed background colour (white for `auto`
    // and `learned`).
    let bg = match &cfg.background {
        BackgroundConfig::Rgb(c) => *c,
        BackgroundConfig::Named(n) if n == "black" => [0.0; 3],
        BackgroundConfig::Named(_) => [1.0; 3],
    };
    let (target, note) = load_rgb_target(&cfg.target, size, bg)?;
    if !resume {
        ensure_new_run_dir(dir)?;
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
        let resolved = crate::runs::RunConfig::Flame(Box::new(cfg.clone())).to_table()?;
        ifslab::io::write_atomic(
            &dir.join(CONFIG_FILE),
            toml::to_string_pretty(&resolved)?.as_bytes(),
        )?;
    }
    let t64: Vec<f64> = target.iter().map(|&v| v as f64).collect();
    save_rgb(&dir.join("target.png"), &t64, size)?;
    let done_before = if resume {
        ifslab_strategies::driver::checkpoint_iteration(dir)?
    } else {
        0
    };
    progress.start(cfg.strategy.name(), cfg.iterations);
    let clock = Instant::now();
    let out = run_flame(
        cfg,
        target.clone(),
        dir,
        resume,
        vec![Box::new(ProgressObserver::new(progress))],
    )?;
    let seconds = clock.elapsed().as_secs_f64();
    let stack = &out.stack;
    save_rgb(&dir.join("render.png"), &out.image, size)?;
    let w = 2 * size + 4;
    let cmp: Vec<f32> = side_by_side(&target, &out.image, size)
        .iter()
        .map(|&v| v as f32)
        .collect();
    Image::new(w as u32, size as u32, 3, cmp)?.save_png(&dir.join("compare.png"))?;
    if cfg.eval_size > 0 {
        // The same sample density per pixel at the larger size, at most 16× the
        // training samples.
        let scale = (cfg.eval_size as f64 / size as f64).powi(2).min(16.0);
        let ecfg = DiffFlameConfig {
            size: cfg.eval_size,
            trajectories: ((cfg.sampler.trajectories as f64 * scale).ceil() as usize).max(1),
            ..cfg.sampler.clone()
        };
        let order = GeneratorOrder::draw(stack, &ecfg, cfg.seed ^ 0x5eed);
        let f = forward(stack, &ecfg, &order)?;
        save_rgb(
            &dir.join(format!("render_{}.png", cfg.eval_size)),
            &f.image,
            cfg.eval_size,
        )?;
    }
    let flames = stack.to_flames(cfg.eval_size.max(size) as u32, "ifslab-learned");
    write_flames(&dir.join(LEARNED_FLAME_FILE), &flames)?;
    loss_plot(&out.log, &dir.join("loss.png"))?;
    let fresh = out.iterations.saturating_sub(done_before).max(1);
    let summary = FlameSummary {
        strategy: cfg.strategy.name().to_owned(),
        iterations: out.iterations,
        seconds,
        seconds_per_iteration: out.seconds / fresh as f64,
        start_mse: out.start_loss,
        mse: out.loss,
        returned: out.returned.to_owned(),
        generators: stack.layers.iter().map(|l| l.len()).collect(),
        target_note: note,
    };
    ifslab::io::write_atomic(
        &dir.join("summary.json"),
        serde_json::to_string_pretty(&summary)?.as_bytes(),
    )?;
    Ok(summary)
}
