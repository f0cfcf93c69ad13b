//! Flame-learning runs (`problem = "flame"`, `ifslab flame learn`): config → run folder with
//! the resolved config, the target as the fit sees it, checkpoints and `log.csv` as it goes,
//! then the learned render at the training size and at `eval_size`, the target and render
//! side by side, the learned flame as a `.flame` file for flam3 and the flame artists' tools,
//! the loss plot and `summary.json`.

use std::path::Path;
use std::time::Instant;

use crate::error::IoContext;
use ifslab::image::Image;
use ifslab::model::flame::write_flames;
use ifslab::render::flame_diff::{DiffFlameConfig, GeneratorOrder, forward};
use ifslab_strategies::problems::flame::{
    BackgroundConfig, FlameLearnConfig, load_rgb_picture, run_flame,
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
    /// The MSE of the best flat colour (the target's mean colour): what a fit must beat to
    /// have learned anything of the picture.
    pub flat_mse: f64,
    /// The returned render's MSE (the authors' measure, computed from the image) over
    /// `flat_mse`: below 1 the flame draws more of the picture than a flat colour does.
    pub mse_ratio: f64,
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
            "{} iterations of {} in {:.1} s ({:.1} ms/iteration), MSE {:.4} → {:.4} \
             ({:.2} of a flat colour's {:.4})",
            self.iterations,
            self.strategy,
            self.seconds,
            1e3 * self.seconds_per_iteration,
            self.start_mse,
            self.mse,
            self.mse_ratio,
            self.flat_mse
        )
    }
}

fn save_rgb(path: &Path, planes: &[f64], size: usize) -> crate::Result<()> {
    let v: Vec<f32> = planes.iter().map(|&x| x as f32).collect();
    Image::new(size as u32, size as u32, 3, v)?.save_png(path)?;
    Ok(())
}

/// The authors' MSE of two RGB images (three planes): squared error summed over the
/// channels, averaged over the pixels.
fn rgb_mse(a: &[f64], b: &[f32]) -> f64 {
    let pixels = (a.len() / 3).max(1);
    a.iter()
        .zip(b)
        .map(|(&x, &y)| (x - y as f64).powi(2))
        .sum::<f64>()
        / pixels as f64
}

/// The same MSE for the best flat colour, the target's mean colour: its variance summed
/// over the channels.
fn flat_colour_mse(target: &[f32], size: usize) -> f64 {
    let n = size * size;
    (0..3)
        .map(|ch| {
            let plane = &target[ch * n..(ch + 1) * n];
            let mean = plane.iter().map(|&v| v as f64).sum::<f64>() / n as f64;
            plane
                .iter()
                .map(|&v| (v as f64 - mean).powi(2))
                .sum::<f64>()
                / n as f64
        })
        .sum()
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
) -> crate::Result<FlameSummary> {
    cfg.validate()?;
    let _lock = crate::runs::lock::lock_run_dir(dir)?;
    let size = cfg.sampler.size;
    // Transparent targets are laid over the fixed background colour; for `auto` and
    // `learned` over black or white, whichever their opaque pixels stand out from.
    let bg = match &cfg.background {
        BackgroundConfig::Rgb(c) => Some(*c),
        BackgroundConfig::Named(n) if n == "black" => Some([0.0; 3]),
        BackgroundConfig::Named(n) if n == "white" => Some([1.0; 3]),
        BackgroundConfig::Named(_) if cfg.paper => Some([1.0; 3]),
        BackgroundConfig::Named(_) => None,
    };
    let (target, note) = load_rgb_picture(&cfg.target, size, bg, cfg.frame)?;
    if !resume {
        ensure_new_run_dir(dir)?;
        std::fs::create_dir_all(dir).doing("creating", dir)?;
        let resolved = crate::runs::RunConfig::Flame(Box::new(cfg.clone())).to_table()?;
        ifslab::io::write_atomic(
            &dir.join(CONFIG_FILE),
            toml::to_string_pretty(&resolved)?.as_bytes(),
        )?;
    }
    let t64 = target.widened().values;
    save_rgb(&dir.join("target.png"), &t64, size)?;
    let done_before = if resume {
        ifslab_strategies::driver::plan::checkpoint_iteration(dir)?
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
    let cmp: Vec<f32> = side_by_side(&target.values, &out.image, size)
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
    let flat_mse = flat_colour_mse(&target.values, size);
    let summary = FlameSummary {
        strategy: cfg.strategy.name().to_owned(),
        iterations: out.iterations,
        seconds,
        seconds_per_iteration: out.seconds / fresh as f64,
        start_mse: out.start_loss,
        mse: out.loss,
        flat_mse,
        mse_ratio: rgb_mse(&out.image, &target.values) / flat_mse.max(f64::MIN_POSITIVE),
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
