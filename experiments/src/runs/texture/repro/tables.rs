//! The Markdown tables of the reproduction: the paper's published Table I beside ours, the
//! hold-out, the one-choice-at-a-time ablation and the decoding timings.

use ifslab_strategies::problems::fractal_coding::MAX_TOTAL_CANDIDATES;

use super::{
    PAPER_SISALFLOOR_BASELINES, PAPER_TABLE_I, TextureDone, TimingRow, Variant, VariantResult,
};

pub(super) fn cap_name(c: Option<usize>) -> String {
    c.map_or("all".into(), |n| n.to_string())
}

pub(super) fn paper_table() -> String {
    let mut s = String::from("| texture (paper) | PSNR 1× |\n|---|---|\n");
    for (n, v) in PAPER_TABLE_I {
        s.push_str(&format!("| {n} | {v:.2} |\n"));
    }
    for (n, v) in PAPER_SISALFLOOR_BASELINES {
        s.push_str(&format!("| sisalfloor, {n} | {v:.2} |\n"));
    }
    s
}

pub(super) fn append_tables(table1: &mut String, holdout: &mut String, d: &TextureDone) {
    let (name, rows, base) = (&d.name, &d.rows, &d.baselines);
    if table1.is_empty() {
        table1.push_str(
            "| texture | method | PSNR 1× | PSNR 1× (packed 8-bit) | offset step | mean collage SSE | Ω per texel (mean / most) | encode s | refine s |\n|---|---|---|---|---|---|---|---|---|\n",
        );
        holdout.push_str(
            "| texture | method | ½ size → 2× | ¼ size → 4× | var. of Laplacian at 8× |\n|---|---|---|---|---|\n",
        );
    }
    let size = format!(
        "{name} {}²{}",
        d.size[0],
        if d.size[2] == 3 { " RGB" } else { "" }
    );
    for r in rows {
        table1.push_str(&format!(
            "| {size} | {} | {:.2} | {:.2} | {} | {:.2} | {} | {:.2} | {:.2} |\n",
            r.label(),
            r.psnr_1x,
            r.psnr_1x_packed,
            r.offset_step,
            r.mean_sse,
            if r.refined {
                format!(
                    "{:.1} / {}",
                    r.stats.mean_candidates, r.stats.most_candidates
                )
            } else {
                "—".into()
            },
            r.encode_seconds,
            r.refine_seconds
        ));
        holdout.push_str(&format!(
            "| {size} | {} | {:.2} | {:.2} | {:.1} |\n",
            r.label(),
            r.psnr_holdout_2x,
            r.psnr_holdout_4x,
            r.lapvar_8x
        ));
    }
    for b in base {
        table1.push_str(&format!(
            "| {size} | R upsampled 2×, {} | {:.2} | — | — | — | — | — | — |\n",
            b.filter, b.psnr_1x_from_r
        ));
        holdout.push_str(&format!(
            "| {size} | {} | {:.2} | {:.2} | {:.1} |\n",
            b.filter, b.psnr_holdout_2x, b.psnr_holdout_4x, b.lapvar_8x
        ));
    }
}

pub(super) fn ablation_table(
    names: &[String],
    variants: &[Variant],
    res: &[Vec<VariantResult>],
) -> String {
    let mut s = String::from("| group | setting |");
    for n in names {
        s.push_str(&format!(" {n} |"));
    }
    s.push_str(" mean Ω per texel (first texture) | s (first texture) |\n|---|---|");
    for _ in names {
        s.push_str("---|");
    }
    s.push_str("---|---|\n");
    for (v, r) in variants.iter().zip(res) {
        s.push_str(&format!("| {} | {} |", v.group, v.label));
        for x in r {
            if x.refused.is_some() {
                s.push_str(" Ω too large¹ |");
            } else {
                s.push_str(&format!(" {:.2} |", x.psnr_1x.unwrap_or(f64::NAN)));
            }
        }
        let first = r.first().filter(|x| x.refused.is_none());
        s.push_str(&format!(
            " {} | {} |\n",
            first.map_or("—".into(), |x| {
                format!("{:.1}", x.mean_candidates.unwrap_or(f64::NAN))
            }),
            first.map_or("—".into(), |x| format!("{:.1}", x.seconds)),
        ));
    }
    if res.iter().flatten().any(|x| x.refused.is_some()) {
        s.push_str(&format!(
            "\n¹ The candidate sets would hold more than {MAX_TOTAL_CANDIDATES} candidates; the \
             encoder refuses rather than exhaust memory.\n"
        ));
    }
    s
}

pub(super) fn timing_table(rows: &[TimingRow]) -> String {
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
