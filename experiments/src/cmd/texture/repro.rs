//! `ifslab texture repro`: Kominami & Mukai's Table I, Fig. 4–6 and timing comparison on the
//! project's textures, written as tables, figures and `results.json` into one folder.
//!
//! - Table I: PSNR of the 1× reconstruction from R (plain and refined code, in memory and
//!   through the packed 8-bit files), against interpolating R back to the source size.
//! - Hold-out: the half-size texture upsampled 2× (and the quarter-size 4×) against the real
//!   full-size texture — a ground truth the paper's figures have no number for.
//! - Fig. 4: 8× crops, bilinear / bicubic / Lanczos against ours (plain and refined).
//! - Fig. 5: the same source region at 1× (texel replication), 2×, 4× and 8×.
//! - Fig. 6: 8× crops after 0, 1, 2, 4, 8 refinement passes, and the objective per pass.
//! - Timing: decoding 8× against bilinear upsampling to the same size, per frame, on all
//!   threads and on one.

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::Context;
use ifslab_strategies::fractal_coding::{
    Candidates, EncoderConfig, Filter, FractalCode, RefineConfig, Texture, bilinear_into, decode,
    decode_into, encode, laplacian_variance, load_dir, output_size, psnr, refine, save_dir,
    upsample,
};
use serde::Serialize;
use serde_json::json;

use crate::plot::{Series, line_chart};
use crate::progress;

#[derive(clap::Args, Debug)]
pub struct Args {
    /// Output folder (tables, figures, results.json).
    #[arg(short, long, default_value = "paper_repro/texture_upsampling/results")]
    pub out: PathBuf,
    /// Folder with brick.png, grass.png, gravel.png (grey) and wood.png (colour).
    #[arg(long, default_value = "data/textures")]
    pub data: PathBuf,
    /// Only these textures (comma-separated names without .png).
    #[arg(long, value_delimiter = ',')]
    pub textures: Option<Vec<String>>,
    /// Search window (the paper: 255).
    #[arg(long, default_value_t = 255)]
    pub window: u32,
    /// β of the refined code's candidate search.
    #[arg(long, default_value_t = super::REFINE_BETA)]
    pub beta: f32,
    /// ΔE_max of the refined code's candidate search.
    #[arg(long, default_value_t = super::REFINE_DELTA_E_MAX)]
    pub delta_e_max: f32,
    /// Most candidates per texel for the refinement.
    #[arg(long, default_value_t = super::REFINE_MAX_CANDIDATES)]
    pub max_candidates: usize,
    /// Refinement passes of the "refined" code (Fig. 6 shows 0, 1, 2, 4 and 8).
    #[arg(long, default_value_t = 4)]
    pub passes: usize,
    /// Repetitions of each timed decode (the median is reported).
    #[arg(long, default_value_t = 9)]
    pub timing_reps: usize,
    /// Skip figures and timing (for parameter sweeps).
    #[arg(long)]
    pub tables_only: bool,
}

/// The row of Table I and the hold-out table for one texture and one code.
#[derive(Serialize, Debug, Clone)]
struct CodeRow {
    label: String,
    encode_seconds: f64,
    refine_seconds: f64,
    mean_sse: f64,
    psnr_1x: f64,
    psnr_1x_packed: f64,
    offset_step: f32,
    objective_t1: f64,
    lapvar_8x: f64,
    psnr_holdout_2x: f64,
    psnr_holdout_4x: f64,
}

#[derive(Serialize, Debug, Clone)]
struct BaselineRow {
    filter: String,
    psnr_1x_from_r: f64,
    psnr_holdout_2x: f64,
    psnr_holdout_4x: f64,
    lapvar_8x: f64,
}

#[derive(Serialize, Debug, Clone)]
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

pub fn run(a: Args) -> anyhow::Result<()> {
    let t_all = Instant::now();
    std::fs::create_dir_all(&a.out).with_context(|| format!("creating {}", a.out.display()))?;
    let names: Vec<String> = a.textures.clone().unwrap_or_else(|| {
        ["brick", "grass", "gravel", "wood"]
            .iter()
            .map(|s| s.to_string())
            .collect()
    });
    let plain_cfg = EncoderConfig {
        window: a.window,
        ..EncoderConfig::default()
    };
    let cand_cfg = EncoderConfig {
        window: a.window,
        beta: a.beta,
        delta_e_max: a.delta_e_max,
        max_candidates: a.max_candidates,
    };
    cand_cfg.validate()?;
    let fig6_passes: Vec<usize> = [0usize, 1, 2, 4, 8]
        .into_iter()
        .filter(|&p| p <= a.passes.max(8))
        .collect();
    let max_passes = a.passes.max(*fig6_passes.last().unwrap_or(&0));

    let mut results = serde_json::Map::new();
    let mut table1 = String::new();
    let mut holdout = String::new();
    let mut objective_series: Vec<(String, Vec<(f64, f64)>)> = Vec::new();
    let mut timings: Vec<TimingRow> = Vec::new();

    let pb = progress::bar(names.len() as u64, "textures");
    for name in &names {
        let path = a.data.join(format!("{name}.png"));
        let src =
            Texture::load(&path, false).with_context(|| format!("loading {}", path.display()))?;
        pb.println(format!(
            "== {name}: {}×{}×{}",
            src.width(),
            src.height(),
            src.channels()
        ));

        // Codes: plain, and refined snapshots after each pass count of Fig. 6.
        let plain = encode(&src, &plain_cfg)?;
        let cand = encode(&src, &cand_cfg)?;
        let mut refined_code = cand.code.clone();
        let mut snapshots: Vec<(usize, FractalCode)> = vec![(0, refined_code.clone())];
        let mut objective = vec![laplacian_variance(&decode(&refined_code, 1)?)];
        let mut refine_seconds = 0.0;
        let mut refined_at_passes = None;
        for p in 1..=max_passes {
            let rep = refine(
                &mut refined_code,
                &cand.candidates,
                &RefineConfig { passes: 1 },
            )?;
            refine_seconds += rep.seconds;
            objective.push(*rep.objective.last().expect("one pass"));
            if fig6_passes.contains(&p) {
                snapshots.push((p, refined_code.clone()));
            }
            if p == a.passes {
                refined_at_passes = Some((refined_code.clone(), refine_seconds));
            }
        }
        let (refined, refined_secs) = refined_at_passes.unwrap_or((cand.code.clone(), 0.0));
        pb.println(format!(
            "   plain {:.2} s, candidates {:.2} s ({:.1}/texel), refinement {:.2} s for {max_passes} passes; objective {:?}",
            plain.stats.seconds,
            cand.stats.seconds,
            cand.stats.mean_candidates,
            refine_seconds,
            objective
                .iter()
                .map(|v| format!("{v:.1}"))
                .collect::<Vec<_>>()
        ));
        objective_series.push((
            name.clone(),
            objective
                .iter()
                .enumerate()
                .map(|(i, &v)| (i as f64, v / objective[0]))
                .collect(),
        ));

        // Hold-out sources: the texture halved (and quartered) by the same box filter.
        let half = src.reduce()?;
        let quarter = half.reduce()?;
        let holdout_codes =
            |cfg: &EncoderConfig, passes: usize| -> anyhow::Result<[FractalCode; 2]> {
                let mut out = Vec::new();
                for s in [&half, &quarter] {
                    let e = encode(s, cfg)?;
                    let mut code = e.code;
                    if passes > 0 {
                        refine(&mut code, &e.candidates, &RefineConfig { passes })?;
                    }
                    out.push(code);
                }
                Ok([out.remove(0), out.remove(0)])
            };
        let ho_plain = holdout_codes(&plain_cfg, 0)?;
        let ho_ref = holdout_codes(&cand_cfg, a.passes)?;

        let mut rows = Vec::new();
        for (label, code, enc_secs, ref_secs, sse, ho) in [
            (
                "fractal (plain)",
                &plain.code,
                plain.stats.seconds,
                0.0,
                plain.stats.mean_sse,
                &ho_plain,
            ),
            (
                "fractal (refined)",
                &refined,
                cand.stats.seconds,
                refined_secs,
                mean_sse_of(&refined, &cand.candidates),
                &ho_ref,
            ),
        ] {
            let rec = decode(code, 1)?;
            let dir = a.out.join("codes").join(format!("{name}-{}", slug(label)));
            let err = save_dir(code, &dir, json!({"texture": name, "label": label}))?;
            let (packed, _) = load_dir(&dir)?;
            let rec_packed = decode(&packed, 1)?;
            if name != "brick" {
                // Keep one example of the packed files in the results, not all of them.
                std::fs::remove_dir_all(&dir).ok();
            }
            let up8 = decode(code, 8)?;
            rows.push(CodeRow {
                label: label.into(),
                encode_seconds: enc_secs,
                refine_seconds: ref_secs,
                mean_sse: sse,
                psnr_1x: psnr(&rec, &src)?,
                psnr_1x_packed: psnr(&rec_packed, &src)?,
                offset_step: err.offset_step,
                objective_t1: laplacian_variance(&rec),
                lapvar_8x: laplacian_variance(&up8),
                psnr_holdout_2x: psnr(&decode(&ho[0], 2)?, &src)?,
                psnr_holdout_4x: psnr(&decode(&ho[1], 4)?, &src)?,
            });
        }
        let mut base_rows = Vec::new();
        for f in [Filter::Bilinear, Filter::Bicubic, Filter::Lanczos] {
            base_rows.push(BaselineRow {
                filter: f.name().into(),
                psnr_1x_from_r: psnr(&upsample(plain.code.reduced(), 2, f)?, &src)?,
                psnr_holdout_2x: psnr(&upsample(&half, 2, f)?, &src)?,
                psnr_holdout_4x: psnr(&upsample(&quarter, 4, f)?, &src)?,
                lapvar_8x: laplacian_variance(&upsample(&src, 8, f)?),
            });
        }
        append_tables(&mut table1, &mut holdout, name, &src, &rows, &base_rows);

        if !a.tables_only {
            figures(&a.out, name, &src, &plain.code, &refined, &snapshots)?;
            for row in timing(name, &src, &plain.code, a.timing_reps)? {
                pb.println(format!(
                    "   timing ({} thread(s)): fractal {:.1} ms, bilinear {:.1} ms, ratio {:.2}",
                    row.threads, row.fractal_ms, row.bilinear_ms, row.ratio
                ));
                timings.push(row);
            }
        }
        results.insert(
            name.clone(),
            json!({
                "size": [src.width(), src.height(), src.channels()],
                "codes": rows,
                "baselines": base_rows,
                "objective_per_pass": objective,
                "candidates_per_texel": cand.stats.mean_candidates,
            }),
        );
        pb.inc(1);
    }
    pb.finish_and_clear();

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
    let timing_md = timing_table(&timings);
    let config = json!({
        "command": std::env::args().collect::<Vec<_>>().join(" "),
        "window": a.window,
        "refine": {"beta": a.beta, "delta_e_max": a.delta_e_max,
                   "max_candidates": a.max_candidates, "passes": a.passes},
        "threads": rayon::current_num_threads(),
        "cpu": cpu_name(),
        "seconds": t_all.elapsed().as_secs_f64(),
    });
    results.insert("config".into(), config.clone());
    results.insert("timing".into(), serde_json::to_value(&timings)?);
    write(
        &a.out.join("results.json"),
        &serde_json::to_vec_pretty(&results)?,
    )?;
    let md = format!(
        "# Results (written by `ifslab texture repro`)\n\nConfig: `{}`\n\n## Table I — PSNR (dB) of the 1× reconstruction\n\n{table1}\n## Hold-out upsampling — PSNR (dB) against the real full-size texture\n\n{holdout}\n## Timing — 8× upsampling, per frame (median of {} runs)\n\n{timing_md}\nTotal run time {:.0} s.\n",
        serde_json::to_string(&config)?,
        a.timing_reps,
        t_all.elapsed().as_secs_f64()
    );
    write(&a.out.join("tables.md"), md.as_bytes())?;
    eprintln!("{}", md);
    Ok(())
}

fn slug(label: &str) -> String {
    label
        .chars()
        .filter_map(|c| match c {
            'a'..='z' => Some(c),
            ' ' => Some('-'),
            _ => None,
        })
        .collect()
}

fn write(path: &Path, bytes: &[u8]) -> anyhow::Result<()> {
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

/// Mean collage SSE of a code whose texels each use one of their candidates.
fn mean_sse_of(code: &FractalCode, cands: &Candidates) -> f64 {
    let ch = code.channels();
    let mut sum = 0.0;
    for c in 0..cands.texels() {
        let k = code.coords()[c];
        let off = &code.offsets()[c * ch..(c + 1) * ch];
        for i in 0..cands.count(c) {
            let (kk, o, sse, _) = cands.get(c, i);
            if kk == k && o == off {
                sum += f64::from(sse);
                break;
            }
        }
    }
    sum / cands.texels() as f64
}

fn append_tables(
    table1: &mut String,
    holdout: &mut String,
    name: &str,
    src: &Texture,
    rows: &[CodeRow],
    base: &[BaselineRow],
) {
    if table1.is_empty() {
        table1.push_str(
            "| texture | method | PSNR 1× | PSNR 1× (packed 8-bit) | offset step | mean collage SSE | encode s | refine s |\n|---|---|---|---|---|---|---|---|\n",
        );
        holdout.push_str(
            "| texture | method | ½ size → 2× | ¼ size → 4× | var. of Laplacian at 8× |\n|---|---|---|---|---|\n",
        );
    }
    let size = format!(
        "{name} {}²{}",
        src.width(),
        if src.channels() == 3 { " RGB" } else { "" }
    );
    for r in rows {
        table1.push_str(&format!(
            "| {size} | {} | {:.2} | {:.2} | {} | {:.2} | {:.2} | {:.2} |\n",
            r.label,
            r.psnr_1x,
            r.psnr_1x_packed,
            r.offset_step,
            r.mean_sse,
            r.encode_seconds,
            r.refine_seconds
        ));
        holdout.push_str(&format!(
            "| {size} | {} | {:.2} | {:.2} | {:.1} |\n",
            r.label, r.psnr_holdout_2x, r.psnr_holdout_4x, r.lapvar_8x
        ));
    }
    for b in base {
        table1.push_str(&format!(
            "| {size} | R upsampled 2×, {} | {:.2} | — | — | — | — | — |\n",
            b.filter, b.psnr_1x_from_r
        ));
        holdout.push_str(&format!(
            "| {size} | {} | {:.2} | {:.2} | {:.1} |\n",
            b.filter, b.psnr_holdout_2x, b.psnr_holdout_4x, b.lapvar_8x
        ));
    }
}

/// A row of panels of equal height with 4-texel white gaps (grey if every panel is grey).
fn montage(panels: &[Texture]) -> anyhow::Result<Texture> {
    let gap = 4;
    let ch = panels.iter().map(|p| p.channels()).max().unwrap_or(1);
    let h = panels.iter().map(|p| p.height()).max().unwrap_or(1);
    let w: usize =
        panels.iter().map(|p| p.width()).sum::<usize>() + gap * panels.len().saturating_sub(1);
    let mut data = vec![255.0f32; w * h * ch];
    let mut x0 = 0;
    for p in panels {
        for y in 0..p.height() {
            for x in 0..p.width() {
                let t = p.texel(x, y);
                let i = (y * w + x0 + x) * ch;
                for k in 0..ch {
                    data[i + k] = t[k.min(t.len() - 1)];
                }
            }
        }
        x0 += p.width() + gap;
    }
    Ok(Texture::new(w, h, ch, data)?)
}

/// The source region the figures show: `side` texels square, centred (32² source texels,
/// 256² output texels at 8×).
fn region(src: &Texture) -> (usize, usize, usize) {
    let side = (src.width().min(src.height()) / 2).min(32);
    ((src.width() - side) / 2, (src.height() - side) / 2, side)
}

fn figures(
    out: &Path,
    name: &str,
    src: &Texture,
    plain: &FractalCode,
    refined: &FractalCode,
    snapshots: &[(usize, FractalCode)],
) -> anyhow::Result<()> {
    let (x0, y0, side) = region(src);
    let crop8 = |t: &Texture| t.crop(8 * x0, 8 * y0, 8 * side, 8 * side);
    // Fig. 5: 1× (texel replication), 2×, 4×, 8× of the same region.
    let mut panels = vec![src.crop(x0, y0, side, side)?.scale_nearest(8)?];
    for f in [2usize, 4, 8] {
        let up = decode(plain, f as u32)?;
        panels.push(
            up.crop(f * x0, f * y0, f * side, f * side)?
                .scale_nearest(8 / f)?,
        );
    }
    montage(&panels)?.save_png(&out.join(format!("fig5_{name}.png")))?;
    // Fig. 4: bilinear, bicubic, Lanczos, ours plain, ours refined at 8×.
    let mut panels = Vec::new();
    for f in [Filter::Bilinear, Filter::Bicubic, Filter::Lanczos] {
        // Interpolate a margin around the region so its border sees real neighbours.
        let (mx, my) = (x0.saturating_sub(4), y0.saturating_sub(4));
        let (mw, mh) = (
            (side + 8).min(src.width() - mx),
            (side + 8).min(src.height() - my),
        );
        let up = upsample(&src.crop(mx, my, mw, mh)?, 8, f)?;
        panels.push(up.crop(8 * (x0 - mx), 8 * (y0 - my), 8 * side, 8 * side)?);
    }
    panels.push(crop8(&decode(plain, 8)?)?);
    panels.push(crop8(&decode(refined, 8)?)?);
    montage(&panels)?.save_png(&out.join(format!("fig4_{name}.png")))?;
    // Fig. 6: ours at 8× after 0, 1, 2, 4, 8 refinement passes.
    let panels: Vec<Texture> = snapshots
        .iter()
        .map(|(_, c)| decode(c, 8).and_then(|t| crop8(&t)))
        .collect::<Result<_, _>>()?;
    montage(&panels)?.save_png(&out.join(format!("fig6_{name}.png")))?;
    Ok(())
}

/// Median seconds of `reps` runs of `f`.
fn median_secs(reps: usize, mut f: impl FnMut() -> anyhow::Result<()>) -> anyhow::Result<f64> {
    f()?; // warm-up (caches, page faults of the output buffer)
    let mut t = Vec::with_capacity(reps);
    for _ in 0..reps.max(1) {
        let t0 = Instant::now();
        f()?;
        t.push(t0.elapsed().as_secs_f64());
    }
    t.sort_by(f64::total_cmp);
    Ok(t[t.len() / 2])
}

fn timing(
    name: &str,
    src: &Texture,
    code: &FractalCode,
    reps: usize,
) -> anyhow::Result<Vec<TimingRow>> {
    let factor = 8;
    let (_, w, h) = output_size(code, factor)?;
    let mut rows = Vec::new();
    let all = rayon::current_num_threads();
    for threads in [all, 1] {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()?;
        let (ours, bil) = pool.install(|| -> anyhow::Result<(f64, f64)> {
            let mut buf = vec![0.0f32; w * h * src.channels()];
            let ours = median_secs(reps, || Ok(decode_into(code, factor, &mut buf)?))?;
            let bil = median_secs(reps, || Ok(bilinear_into(src, factor, &mut buf)?))?;
            Ok((ours, bil))
        })?;
        let lib = if threads == 1 {
            Some(median_secs(reps.min(3), || {
                upsample(src, factor, Filter::Bilinear)?;
                Ok(())
            })?)
        } else {
            None
        };
        let texels = (w * h) as f64;
        rows.push(TimingRow {
            texture: name.into(),
            threads,
            output: format!("{w}×{h}×{}", src.channels()),
            fractal_ms: ours * 1e3,
            bilinear_ms: bil * 1e3,
            ratio: ours / bil,
            fractal_mtexels_s: texels / ours / 1e6,
            bilinear_mtexels_s: texels / bil / 1e6,
            image_crate_bilinear_ms: lib.map(|s| s * 1e3),
        });
    }
    Ok(rows)
}

fn timing_table(rows: &[TimingRow]) -> String {
    let mut s = String::from(
        "| texture | output | threads | fractal decode ms | bilinear ms | ratio | fractal Mtexel/s | bilinear Mtexel/s | `image` crate bilinear ms |\n|---|---|---|---|---|---|---|---|---|\n",
    );
    for r in rows {
        s.push_str(&format!(
            "| {} | {} | {} | {:.1} | {:.1} | {:.2} | {:.0} | {:.0} | {} |\n",
            r.texture,
            r.output,
            r.threads,
            r.fractal_ms,
            r.bilinear_ms,
            r.ratio,
            r.fractal_mtexels_s,
            r.bilinear_mtexels_s,
            r.image_crate_bilinear_ms
                .map_or("—".into(), |v| format!("{v:.0}"))
        ));
    }
    s
}
