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
mod tables;
mod timing;

use ablation::ablation_variants;
use figures::figures;
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

/// Everything the reproduction does for one texture: Table I and hold-out rows, figures,
/// timing and the one-choice-at-a-time results.
fn one_texture(
    a: &ReproConfig,
    name: &str,
    presets: &[Preset],
    variants: &[Variant],
    progress: &dyn Progress,
) -> crate::Result<TextureDone> {
    let path = a.data.join(format!("{name}.png"));
    let src = Texture::load(&path, false).with_context(|| format!("loading {}", path.display()))?;
    progress.message(&format!(
        "== {name}: {}×{}×{}",
        src.width(),
        src.height(),
        src.channels()
    ));
    let half = src.reduce()?;
    let quarter = half.reduce()?;

    let mut rows = Vec::new();
    let mut codes: Vec<(Preset, bool, FractalCode)> = Vec::new();
    let mut snapshots: Vec<(Preset, Vec<(usize, FractalCode)>)> = Vec::new();
    let mut objectives = Vec::new();
    for &preset in presets {
        for refined in [false, true] {
            let cfg = preset.encoder(refined);
            let passes = if refined { preset.refine().passes } else { 0 };
            let enc = encode(&src, &cfg)?;
            let mut code = enc.code.clone();
            let mut refine_seconds = 0.0;
            if refined {
                // One pass at a time, keeping the snapshots of Fig. 6; the code of the
                // preset's pass count is the "refined" row.
                let max_passes = passes.max(*FIG6_PASSES.last().expect("passes"));
                let mut snaps = vec![(0, code.clone())];
                let mut objective = vec![laplacian_variance(&decode(&code, 1)?)];
                let mut work = code.clone();
                for p in 1..=max_passes {
                    let rep = refine(&mut work, &enc.candidates, &RefineConfig { passes: 1 })?;
                    if p <= passes {
                        refine_seconds += rep.seconds;
                    }
                    objective.push(*rep.objective.last().expect("one pass"));
                    if FIG6_PASSES.contains(&p) {
                        snaps.push((p, work.clone()));
                    }
                    if p == passes {
                        code = work.clone();
                    }
                }
                progress.message(&format!(
                    "   {preset}: Ω {:.1}/texel (most {}), encode {:.2} s; objective per pass {:?}",
                    enc.stats.mean_candidates,
                    enc.stats.most_candidates,
                    enc.stats.seconds,
                    objective
                        .iter()
                        .map(|v| format!("{v:.1}"))
                        .collect::<Vec<_>>()
                ));
                objectives.push((preset, objective));
                snapshots.push((preset, snaps));
            }
            let storage = preset.coord_storage();
            let rec = decode(&code, 1)?;
            let label = format!(
                "{name}-{preset}-{}",
                if refined { "refined" } else { "plain" }
            );
            let dir = a.out.join("codes").join(&label);
            let err = save_dir(
                &code,
                &dir,
                storage,
                json!({"texture": name, "preset": preset, "encoder": cfg, "passes": passes}),
            )?;
            let (packed, _) = load_dir(&dir)?;
            crate::error::ensure!(
                packed.coords() == code.coords(),
                "the packed coordinates of {label} did not round-trip"
            );
            let rec_packed = decode(&packed, 1)?;
            if name != "brick" {
                // Keep one example of the packed files in the results, not all of them.
                std::fs::remove_dir_all(&dir).ok();
            }
            let ho = holdout_psnr(&src, &half, &quarter, &cfg, passes)?;
            rows.push(CodeRow {
                preset,
                refined,
                encoder: cfg.clone(),
                passes,
                coord_storage: storage,
                encode_seconds: enc.stats.seconds,
                refine_seconds,
                mean_sse: collage_sse(&src, &code),
                stats: enc.stats.clone(),
                psnr_1x: psnr(&rec, &src)?,
                psnr_1x_packed: psnr(&rec_packed, &src)?,
                offset_step: err.offset_step,
                objective_t1: laplacian_variance(&rec),
                lapvar_8x: laplacian_variance(&decode(&code, 8)?),
                psnr_holdout_2x: ho.0,
                psnr_holdout_4x: ho.1,
            });
            codes.push((preset, refined, code));
        }
    }
    let reduced = codes[0].2.reduced().clone();
    let mut baselines = Vec::new();
    for f in [Filter::Bilinear, Filter::Bicubic, Filter::Lanczos] {
        baselines.push(BaselineRow {
            filter: f.name().into(),
            psnr_1x_from_r: psnr(&upsample(&reduced, 2, f)?, &src)?,
            psnr_holdout_2x: psnr(&upsample(&half, 2, f)?, &src)?,
            psnr_holdout_4x: psnr(&upsample(&quarter, 4, f)?, &src)?,
            lapvar_8x: laplacian_variance(&upsample(&src, 8, f)?),
        });
    }
    for r in &rows {
        progress.message(&format!(
            "   {:<18} 1× {:.2} dB (packed {:.2}), hold-out 2× {:.2} dB",
            r.label(),
            r.psnr_1x,
            r.psnr_1x_packed,
            r.psnr_holdout_2x
        ));
    }

    let mut timings = Vec::new();
    if !a.tables_only {
        figures(&a.out, name, &src, &codes, &snapshots)?;
        let default_plain = &codes
            .iter()
            .find(|(p, r, _)| *p == Preset::default() && !r)
            .expect("both presets encoded")
            .2;
        for row in timing(name, &src, default_plain, a.timing_reps)? {
            progress.message(&format!(
                "   timing ({} thread(s)): fractal {:.1} ms, bilinear {:.1} ms, ratio {:.2}",
                row.threads, row.fractal_ms, row.bilinear_ms, row.ratio
            ));
            timings.push(row);
        }
    }
    progress.inc(1);

    let mut ablation = Vec::new();
    if !a.skip_ablation {
        for v in variants {
            let t0 = Instant::now();
            let enc = match encode(&src, &v.encoder) {
                Ok(e) => e,
                Err(e) => {
                    progress.message(&format!("   {} / {}: refused ({e})", v.group, v.label));
                    ablation.push(VariantResult {
                        texture: name.into(),
                        refused: Some(e.to_string()),
                        psnr_1x: None,
                        mean_sse: None,
                        mean_candidates: None,
                        most_candidates: 0,
                        seconds: t0.elapsed().as_secs_f64(),
                    });
                    continue;
                }
            };
            let mut code = enc.code;
            if v.passes > 0 {
                refine(
                    &mut code,
                    &enc.candidates,
                    &RefineConfig { passes: v.passes },
                )?;
            }
            ablation.push(VariantResult {
                texture: name.into(),
                refused: None,
                psnr_1x: Some(psnr(&decode(&code, 1)?, &src)?),
                mean_sse: Some(collage_sse(&src, &code)),
                mean_candidates: Some(enc.stats.mean_candidates),
                most_candidates: enc.stats.most_candidates,
                seconds: t0.elapsed().as_secs_f64(),
            });
        }
        progress.inc(1);
    }
    Ok(TextureDone {
        settings: (a.tables_only, a.skip_ablation, a.timing_reps),
        name: name.into(),
        size: [src.width(), src.height(), src.channels()],
        rows,
        baselines,
        objectives,
        timings,
        ablation,
    })
}

/// PSNR of the half-size texture upsampled 2× and the quarter-size one 4×, against `src`.
fn holdout_psnr(
    src: &Texture,
    half: &Texture,
    quarter: &Texture,
    cfg: &EncoderConfig,
    passes: usize,
) -> crate::Result<(f64, f64)> {
    let mut out = [0.0; 2];
    for (i, (s, factor)) in [(half, 2u32), (quarter, 4)].into_iter().enumerate() {
        let e = encode(s, cfg)?;
        let mut code = e.code;
        if passes > 0 {
            refine(&mut code, &e.candidates, &RefineConfig { passes })?;
        }
        out[i] = psnr(&decode(&code, factor)?, src)?;
    }
    Ok((out[0], out[1]))
}

/// Mean collage SSE per range block of a code: ‖S(2c + δ) − R(C(c) + δ) − O(c)‖² (the error
/// of the 1× reconstruction before rounding).
fn collage_sse(src: &Texture, code: &FractalCode) -> f64 {
    let rec = decode(code, 1).expect("a 1× decode of a valid code");
    let sse: f64 = rec
        .data()
        .iter()
        .zip(src.data())
        .map(|(a, b)| f64::from(a - b).powi(2))
        .sum();
    sse / (code.width() * code.height()) as f64
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
