//! One texture's part of the reproduction: its codes at both presets, the 1× and hold-out
//! reconstructions, the one-choice-at-a-time variants and the timings, measured and
//! returned for the tables.

use super::*;

/// Everything the reproduction does for one texture: Table I and hold-out rows, figures,
/// timing and the one-choice-at-a-time results.
pub(super) fn one_texture(
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
pub(super) fn holdout_psnr(
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
pub(super) fn collage_sse(src: &Texture, code: &FractalCode) -> f64 {
    let rec = decode(code, 1).expect("a 1× decode of a valid code");
    let sse: f64 = rec
        .data()
        .iter()
        .zip(src.data())
        .map(|(a, b)| f64::from(a - b).powi(2))
        .sum();
    sse / (code.width() * code.height()) as f64
}
