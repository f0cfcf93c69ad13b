//! Figs. 4–6 of the reproduction: 8× crops against the interpolating filters, one region
//! at 1×–8×, and the refinement passes, as montages and the objective per pass.

use std::path::Path;

use ifslab_strategies::problems::fractal_coding::{
    Filter, FractalCode, Preset, Texture, decode, upsample,
};

/// A row of panels of equal height with 4-texel white gaps (grey if every panel is grey).
pub(super) fn montage(panels: &[Texture]) -> crate::Result<Texture> {
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
pub(super) fn region(src: &Texture) -> (usize, usize, usize) {
    let side = (src.width().min(src.height()) / 2).min(32);
    ((src.width() - side) / 2, (src.height() - side) / 2, side)
}

pub(super) fn figures(
    out: &Path,
    name: &str,
    src: &Texture,
    codes: &[(Preset, bool, FractalCode)],
    snapshots: &[(Preset, Vec<(usize, FractalCode)>)],
) -> crate::Result<()> {
    let (x0, y0, side) = region(src);
    let crop8 = |t: &Texture| t.crop(8 * x0, 8 * y0, 8 * side, 8 * side);
    let code = |p: Preset, refined: bool| {
        &codes
            .iter()
            .find(|(q, r, _)| *q == p && *r == refined)
            .expect("every preset and variant encoded")
            .2
    };
    // Fig. 5: 1× (texel replication), 2×, 4×, 8× of the same region, default preset refined.
    let mut panels = vec![src.crop(x0, y0, side, side)?.scale_nearest(8)?];
    for f in [2usize, 4, 8] {
        let up = decode(code(Preset::default(), true), f as u32)?;
        panels.push(
            up.crop(f * x0, f * y0, f * side, f * side)?
                .scale_nearest(8 / f)?,
        );
    }
    montage(&panels)?.save_png(&out.join(format!("fig5_{name}.png")))?;
    // Fig. 4: bilinear, bicubic, Lanczos, then paper plain / refined, ifslab plain / refined.
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
    for p in [Preset::Paper, Preset::Ifslab] {
        for refined in [false, true] {
            panels.push(crop8(&decode(code(p, refined), 8)?)?);
        }
    }
    montage(&panels)?.save_png(&out.join(format!("fig4_{name}.png")))?;
    // Fig. 6: each preset at 8× after 0, 1, 2, 3, 4, 8 refinement passes.
    for (p, snaps) in snapshots {
        let panels: Vec<Texture> = snaps
            .iter()
            .map(|(_, c)| decode(c, 8).and_then(|t| crop8(&t)))
            .collect::<Result<_, _>>()?;
        montage(&panels)?.save_png(&out.join(format!("fig6_{name}_{p}.png")))?;
    }
    Ok(())
}
