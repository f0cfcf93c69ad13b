//! The reproduction of Kominami & Mukai's Table I, Fig. 4–6 and timing comparison on the
//! project's textures, for both presets (`paper`, `ifslab`), written as tables, figures and
//! `results.json` into one folder.
//!
//! - Table I: PSNR of the 1× reconstruction from R (plain and refined codes of both presets,
//!   in memory and through the packed 8-bit files), against interpolating R back to the
//!   source size; the paper's published numbers for its own textures beside them.
//! - One choice at a time: 1× PSNR as each choice of one preset is switched to the other's
//!   (matching criterion, search grid, window, distance centre, ΔE_max, cap, passes).
//! - Hold-out: the half-size texture upsampled 2× (and the quarter-size 4×) against the real
//!   full-size texture — a ground truth the paper's figures have no number for.
//! - Fig. 4: 8× crops, bilinear / bicubic / Lanczos against both presets (plain and refined).
//! - Fig. 5: the same source region at 1× (texel replication), 2×, 4× and 8× (default preset).
//! - Fig. 6: 8× crops after 0, 1, 2, 3, 4, 8 refinement passes of each preset, and the
//!   objective per pass.
//! - Timing: decoding 8× against bilinear upsampling to the same size, per frame, on all
//!   threads and on one.
//!
//! `mod.rs` runs the whole reproduction, resumable per texture; `one.rs` measures one
//! texture; `tables.rs`, `figures.rs`, `timing.rs` and `ablation.rs` write the results.

use std::path::{Path, PathBuf};
use std::time::Instant;

use crate::error::{Context, IoContext};
use ifslab_strategies::problems::fractal_coding::{
    CoordStorage, EncodeStats, EncoderConfig, Filter, FractalCode, Preset, RefineConfig, Texture,
    decode, encode, laplacian_variance, load_dir, psnr, refine, save_dir, upsample,
};
use serde::{Deserialize, Serialize};
use serde_json::json;

use crate::plot::{Series, line_chart};
use crate::progress::Progress;

mod ablation;
mod figures;
mod one;
mod tables;
mod timing;

use ablation::ablation_variants;
use figures::figures;
use one::one_texture;
use tables::{ablation_table, append_tables, paper_table, timing_table};
use timing::timing;

/// What to reproduce, and where.
#[derive(Clone, Debug, Serialize)]
pub struct ReproConfig {
    /// Output folder (tables, figures, results.json).
    pub out: PathBuf,
    /// Folder with brick.png, grass.png, gravel.png (grey) and wood.png (colour).
    pub data: PathBuf,
    /// Only these textures (names without .png); all four when `None`.
    pub textures: Option<Vec<String>>,
    /// Repetitions of each timed decode (the median is reported).
    pub timing_reps: usize,
    /// Skip figures and timing.
    pub tables_only: bool,
    /// Skip the one-choice-at-a-time table (the longest part).
    pub skip_ablation: bool,
}

/// The paper's Table I (PSNR of the 1× reconstruction, its own textures, not available to us).
const PAPER_TABLE_I: [(&str, f64); 4] = [
    ("sisalfloor", 23.3032),
    ("leaf", 29.1015),
    ("brickwall", 23.0404),
    ("rotatetile", 34.4637),
];
/// The paper's §V: bilinear interpolation and LapSRN on sisalfloor at 1×.
const PAPER_SISALFLOOR_BASELINES: [(&str, f64); 2] = [("bilinear", 28.46), ("LapSRN", 30.29)];

/// One row of Table I and the hold-out table: one texture, one preset, plain or refined.
#[derive(Serialize, Deserialize, Debug, Clone)]
struct CodeRow {
    preset: Preset,
    refined: bool,
    encoder: EncoderConfig,
    passes: usize,
    coord_storage: CoordStorage,
    encode_seconds: f64,
    refine_seconds: f64,
    stats: EncodeStats,
    mean_sse: f64,
    psnr_1x: f64,
    psnr_1x_packed: f64,
    offset_step: f32,
    objective_t1: f64,
    lapvar_8x: f64,
    psnr_holdout_2x: f64,
    psnr_holdout_4x: f64,
}

impl CodeRow {
    fn label(&self) -> String {
        format!(
            "{} ({})",
            self.preset,
            if self.refined { "refined" } else { "plain" }
        )
    }
}

#[derive(Serialize, Deserialize, Debug, Clone)]
struct BaselineRow {
    filter: String,
    psnr_1x_from_r: f64,
    psnr_holdout_2x: f64,
    psnr_holdout_4x: f64,
    lapvar_8x: f64,
}

/// A setting of the one-choice-at-a-time table.
#[derive(Serialize, Debug, Clone)]
struct Variant {
    group: &'static str,
    label: String,
    encoder: EncoderConfig,
    passes: usize,
}

#[derive(Serialize, Deserialize, Debug, Clone)]
struct VariantResult {
    texture: String,
    /// Why the setting could not be run (the encoder's refusal), if it could not.
    refused: Option<String>,
    psnr_1x: Option<f64>,
    mean_sse: Option<f64>,
    mean_candidates: Option<f64>,
    most_candidates: usize,
    seconds: f64,
}

#[derive(Serialize, Deserialize, Debug, Clone)]
struct TimingRow {
    texture: String,
    threads: usize,
    output: String,
    fractal_ms: f64,
    bilinear_ms: f64,
    ratio: f64,
    fractal_mtexels_s: f64,
    bilinear_mtexels_s: f64,
    image_crate_bilinear_ms: Option<f64>,
}

/// Pass counts shown in Fig. 6.
const FIG6_PASSES: [usize; 6] = [0, 1, 2, 3, 4, 8];

/// What one texture contributed, saved under `partial/` as soon as it is done so that a
/// reproduction killed part-way continues with the next texture (`resume`).
#[derive(Serialize, Deserialize, Debug, Clone)]
struct TextureDone {
    /// The parts of the config that shape a texture's results; a saved texture made with
    /// other ones is done again.
    settings: (bool, bool, usize),
    name: String,
    size: [usize; 3],
    rows: Vec<CodeRow>,
    baselines: Vec<BaselineRow>,
    /// The objective per refinement pass of each preset.
    objectives: Vec<(Preset, Vec<f64>)>,
    timings: Vec<TimingRow>,
    /// One result per variant of the one-choice-at-a-time table (empty when skipped).
    ablation: Vec<VariantResult>,
}

/// The folder of an output folder that holds finished textures until the reproduction ends.
pub const PARTIAL_DIR: &str = "partial";

/// Runs the reproduction into `cfg.out`: `tables.md`, `results.json`, the figures and a
/// packed code of each preset for brick. Textures are the unit of work: each is saved under
/// `partial/` when done, and with `resume` the saved ones are not done again (their timings
/// are the ones measured then). Returns the Markdown of `tables.md`.
pub fn run(cfg: &ReproConfig, resume: bool, progress: &dyn Progress) -> crate::Result<String> {
    let t_all = Instant::now();
    let a = cfg;
    std::fs::create_dir_all(&a.out).doing("creating", &a.out)?;
    let names: Vec<String> = a.textures.clone().unwrap_or_else(|| {
        ["brick", "grass", "gravel", "wood"]
            .iter()
            .map(|s| s.to_string())
            .collect()
    });
    let presets = [Preset::Paper, Preset::Ifslab];
    let variants = ablation_variants();
    let settings = (a.tables_only, a.skip_ablation, a.timing_reps);
    let partial = a.out.join(PARTIAL_DIR);
    if !resume && partial.exists() {
        std::fs::remove_dir_all(&partial).doing("removing", &partial)?;
    }

    let steps = names.len() * if a.skip_ablation { 1 } else { 2 };
    progress.start("steps", steps as u64);
    let mut done = Vec::new();
    let mut reused = 0;
    for name in &names {
        let saved = partial.join(format!("{name}.json"));
        if resume
            && let Some(d) = std::fs::read(&saved)
                .ok()
                .and_then(|b| serde_json::from_slice::<TextureDone>(&b).ok())
                .filter(|d| d.settings == settings && d.name == *name)
        {
            progress.message(&format!(
                "== {name}: done before (from {})",
                saved.display()
            ));
            progress.inc(if a.skip_ablation { 1 } else { 2 });
            done.push(d);
            reused += 1;
            continue;
        }
        let d = one_texture(a, name, &presets, &variants, progress)?;
        write(&saved, &serde_json::to_vec(&d)?)?;
        done.push(d);
    }
    progress.finish();

    let mut results = serde_json::Map::new();
    let mut table1 = String::new();
    let mut holdout = String::new();
    let mut objective_series: Vec<(String, Vec<(f64, f64)>)> = Vec::new();
    let mut timings: Vec<TimingRow> = Vec::new();
    let mut ablation: Vec<Vec<VariantResult>> = vec![Vec::new(); variants.len()];
    for d in &done {
        append_tables(&mut table1, &mut holdout, d);
        let mut objectives = serde_json::Map::new();
        for (preset, objective) in &d.objectives {
            objective_series.push((
                format!("{} {preset}", d.name),
                objective
                    .iter()
                    .enumerate()
                    .map(|(i, &v)| (i as f64, v / objective[0]))
                    .collect(),
            ));
            objectives.insert(preset.name().into(), json!(objective));
        }
        timings.extend(d.timings.iter().cloned());
        for (out, r) in ablation.iter_mut().zip(&d.ablation) {
            out.push(r.clone());
        }
        results.insert(
            d.name.clone(),
            json!({
                "size": d.size,
                "codes": d.rows,
                "baselines": d.baselines,
                "objective_per_pass": objectives,
            }),
        );
    }

    if !a.tables_only {
        let series: Vec<Series<'_>> = objective_series
            .iter()
            .map(|(n, pts)| Series {
                name: n,
                points: pts.clone(),
            })
            .collect();
        line_chart(
            &a.out.join("fig6_objective.png"),
            "Refinement: variance of the Laplacian of T1 (relative to pass 0)",
            "pass",
            "objective / objective at pass 0",
            &series,
            false,
        )?;
    }
    let ablation_md = if a.skip_ablation {
        String::from("(skipped)\n")
    } else {
        ablation_table(&names, &variants, &ablation)
    };
    let timing_md = timing_table(&timings);
    let config = json!({
        "run": a,
        "presets": presets.iter().map(|p| json!({
            "preset": p,
            "encoder_refined": p.encoder(true),
            "refine": p.refine(),
            "coord_storage": p.coord_storage(),
        })).collect::<Vec<_>>(),
        "default_preset": Preset::default(),
        "threads": rayon::current_num_threads(),
        "cpu": cpu_name(),
        "seconds": t_all.elapsed().as_secs_f64(),
    });
    results.insert("config".into(), config.clone());
    results.insert("timing".into(), serde_json::to_value(&timings)?);
    results.insert(
        "one_choice_at_a_time".into(),
        json!(
            variants
                .iter()
                .zip(&ablation)
                .map(|(v, r)| json!({"variant": v, "results": r}))
                .collect::<Vec<_>>()
        ),
    );
    write(
        &a.out.join("results.json"),
        &serde_json::to_vec_pretty(&results)?,
    )?;
    let md = format!(
        "# Results (written by `ifslab texture repro`)\n\nConfig: `{}`\n\n\
         ## Table I — PSNR (dB) of the 1× reconstruction\n\n{table1}\n\
         The paper's Table I (its own colour textures, which are not available to us):\n\n{}\n\
         ## One choice at a time — PSNR (dB) of the 1× reconstruction\n\n{ablation_md}\n\
         ## Hold-out upsampling — PSNR (dB) against the real full-size texture\n\n{holdout}\n\
         ## Timing — 8× upsampling ({} preset, plain code), per frame (median of {} runs)\n\n{timing_md}\n\
         Total run time {:.0} s{}.\n",
        serde_json::to_string(&config)?,
        paper_table(),
        Preset::default(),
        a.timing_reps,
        t_all.elapsed().as_secs_f64(),
        if reused == 0 {
            String::new()
        } else {
            format!(
                " (this process; the {reused} texture(s) done before the resume are not counted)"
            )
        }
    );
    write(&a.out.join("tables.md"), md.as_bytes())?;
    std::fs::remove_dir_all(&partial).doing("removing", &partial)?;
    Ok(md)
}

fn write(path: &Path, bytes: &[u8]) -> crate::Result<()> {
    ifslab::io::write_atomic(path, bytes).with_context(|| format!("writing {}", path.display()))
}

fn cpu_name() -> String {
    std::fs::read_to_string("/proc/cpuinfo")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("model name"))
                .and_then(|l| l.split(':').nth(1))
                .map(|v| v.trim().to_string())
        })
        .unwrap_or_else(|| "unknown".into())
}
