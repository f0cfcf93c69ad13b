//! Refinement of a fractal code by block-coordinate descent.
//!
//! Plain fractal coding picks, for each texel, the single best-matching block; on semi-random
//! textures many blocks match almost as well, and the arbitrary choice among them leaves seams
//! between neighbouring range blocks that the recursive decoder magnifies. The refinement
//! (i) scores candidates with the spatial-proximity term β·(|x − x₀| + |y − y₀|) (the paper's
//! Eq. 11–12) and keeps the set Ω of those below the best's score plus ΔE_max (Eq. 13; done by
//! the encoder, see [`EncoderConfig`](crate::problems::fractal_coding::encoder::EncoderConfig)), then
//! (ii) visits the texels one block at a time and gives each the candidate of Ω that minimises
//! the variance of the Laplacian of the synthesised texture (Eq. 14–15), holding the other
//! blocks fixed, with the candidate's own offset (Eq. 4 for that block); a pass visits every
//! texel once, in raster order.
//!
//! The synthesised texture is the factor-1 decoding T₁ (the source-resolution synthesis from R
//! that every higher level magnifies). A block's candidate sets only the 2×2 texels
//! T₁(2c + δ), so the change of the objective is computed exactly from the twelve Laplacian
//! values around the block. The Laplacian is the 4-neighbour one with wrap-around (textures
//! are tiled, as with GL_REPEAT); on a torus the Laplacian sums to zero, so its variance is
//! the mean of its squares and a block's move changes it by the local difference only. A move
//! is taken only when it lowers that sum, so the objective never increases.

use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};
use crate::problems::fractal_coding::code::FractalCode;
use crate::problems::fractal_coding::decoder::decode;
use crate::problems::fractal_coding::encoder::Candidates;
use crate::problems::fractal_coding::texture::Texture;

/// Refinement settings.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct RefineConfig {
    /// Block-coordinate descent passes over all texels (0 leaves the code as encoded).
    pub passes: usize,
}

impl Default for RefineConfig {
    fn default() -> Self {
        RefineConfig { passes: 4 }
    }
}

/// What the refinement did.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct RefineReport {
    /// The objective (variance of the Laplacian of T₁, summed over channels) before the first
    /// pass and after each pass.
    pub objective: Vec<f64>,
    /// Texels whose candidate changed, per pass.
    pub changes: Vec<usize>,
    /// Wall-clock seconds.
    pub seconds: f64,
}

/// Variance of the wrap-around 4-neighbour Laplacian of a texture, summed over channels.
pub fn laplacian_variance(t: &Texture) -> f64 {
    let (w, h, ch) = (t.width(), t.height(), t.channels());
    let d = t.data();
    let at = |x: usize, y: usize, k: usize| f64::from(d[(y * w + x) * ch + k]);
    let n = (w * h) as f64;
    let mut total = 0.0;
    for k in 0..ch {
        let (mut s1, mut s2) = (0.0f64, 0.0f64);
        for y in 0..h {
            let (yu, yd) = ((y + h - 1) % h, (y + 1) % h);
            for x in 0..w {
                let (xl, xr) = ((x + w - 1) % w, (x + 1) % w);
                let l =
                    at(xl, y, k) + at(xr, y, k) + at(x, yu, k) + at(x, yd, k) - 4.0 * at(x, y, k);
                s1 += l;
                s2 += l * l;
            }
        }
        total += s2 / n - (s1 / n) * (s1 / n);
    }
    total
}

/// Runs `cfg.passes` passes of block-coordinate descent over the candidate lists of
/// `candidates` (from the encoder run that produced `code`), changing `code` in place.
pub fn refine(
    code: &mut FractalCode,
    candidates: &Candidates,
    cfg: &RefineConfig,
) -> Result<RefineReport> {
    let t0 = std::time::Instant::now();
    let (wr, hr, ch) = (code.width(), code.height(), code.channels());
    if candidates.shape() != (wr, hr, ch) {
        let (cw, chh, cc) = candidates.shape();
        return Err(Error::InvalidInput(format!(
            "candidates for a {cw}×{chh}×{cc} reduced texture do not fit a {wr}×{hr}×{ch} code: \
             pass the candidates of the encoder run that produced this code"
        )));
    }
    let synth = decode(code, 1)?;
    let mut report = RefineReport {
        objective: vec![laplacian_variance(&synth)],
        changes: Vec::new(),
        seconds: 0.0,
    };
    let (w, h) = (2 * wr, 2 * hr);
    let mut t = synth.into_data();
    let r = code.reduced().clone();
    let mut block = [[0.0f32; 3]; 4];
    for _ in 0..cfg.passes {
        let mut changes = 0;
        for c in 0..wr * hr {
            let (cx, cy) = (c % wr, c / wr);
            let (bx, by) = (2 * cx, 2 * cy);
            let current = local_energy(&t, w, h, ch, bx, by, None);
            let mut best: Option<(f64, usize)> = None;
            let cur_coord = code.coords()[c];
            let cur_off = &code.offsets()[c * ch..(c + 1) * ch];
            for k in 0..candidates.count(c) {
                let (coord, off, _, _) = candidates.get(c, k);
                if coord == cur_coord && off == cur_off {
                    continue;
                }
                fill_block(&r, coord as usize, off, &mut block);
                let e = local_energy(&t, w, h, ch, bx, by, Some(&block));
                if e < best.map_or(current, |b| b.0) {
                    best = Some((e, k));
                }
            }
            if let Some((_, k)) = best {
                let (coord, off, _, _) = candidates.get(c, k);
                fill_block(&r, coord as usize, off, &mut block);
                for (j, v) in block.iter().enumerate() {
                    let p = ((by + j / 2) * w + bx + j % 2) * ch;
                    t[p..p + ch].copy_from_slice(&v[..ch]);
                }
                code.set(c, coord, off);
                changes += 1;
            }
        }
        let tex = Texture::new(w, h, ch, t)?;
        report.objective.push(laplacian_variance(&tex));
        report.changes.push(changes);
        t = tex.into_data();
        if changes == 0 {
            break;
        }
    }
    report.seconds = t0.elapsed().as_secs_f64();
    Ok(report)
}

/// T₁ over the block of a candidate: R(C + δ) + O, in the decoder's order of addition.
fn fill_block(r: &Texture, coord: usize, off: &[f32], out: &mut [[f32; 3]; 4]) {
    let w = r.width();
    let (x, y) = (coord % w, coord / w);
    for (j, v) in out.iter_mut().enumerate() {
        for (k, o) in off.iter().enumerate() {
            v[k] = o + r.get(x + j % 2, y + j / 2, k);
        }
    }
}

/// Σ L² over the twelve texels whose Laplacian depends on the 2×2 block at (bx, by), with
/// the block replaced by `block` when given.
fn local_energy(
    t: &[f32],
    w: usize,
    h: usize,
    ch: usize,
    bx: usize,
    by: usize,
    block: Option<&[[f32; 3]; 4]>,
) -> f64 {
    let get = |x: usize, y: usize, k: usize| -> f64 {
        if let Some(b) = block {
            let (dx, dy) = (x.wrapping_sub(bx), y.wrapping_sub(by));
            if dx < 2 && dy < 2 {
                return f64::from(b[dy * 2 + dx][k]);
            }
        }
        f64::from(t[(y * w + x) * ch + k])
    };
    let l = |x: usize, y: usize, k: usize| -> f64 {
        let (xl, xr) = ((x + w - 1) % w, (x + 1) % w);
        let (yu, yd) = ((y + h - 1) % h, (y + 1) % h);
        get(xl, y, k) + get(xr, y, k) + get(x, yu, k) + get(x, yd, k) - 4.0 * get(x, y, k)
    };
    let (xl, xr) = ((bx + w - 1) % w, (bx + 2) % w);
    let (yu, yd) = ((by + h - 1) % h, (by + 2) % h);
    let positions = [
        (bx, by),
        (bx + 1, by),
        (bx, by + 1),
        (bx + 1, by + 1),
        (xl, by),
        (xl, by + 1),
        (xr, by),
        (xr, by + 1),
        (bx, yu),
        (bx + 1, yu),
        (bx, yd),
        (bx + 1, yd),
    ];
    let mut e = 0.0;
    for k in 0..ch {
        for &(x, y) in &positions {
            let v = l(x, y, k);
            e += v * v;
        }
    }
    e
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn laplacian_variance_of_a_constant_is_zero_and_of_a_checkerboard_is_known() {
        let c = Texture::from_fn(8, 6, 1, |_, _, _| 7.0).unwrap();
        assert_eq!(laplacian_variance(&c), 0.0);
        // Checkerboard ±1: L = −8·v at every texel, so L² = 64 and the mean of L is 0.
        let cb =
            Texture::from_fn(8, 6, 1, |x, y, _| if (x + y) % 2 == 0 { 1.0 } else { -1.0 }).unwrap();
        assert!((laplacian_variance(&cb) - 64.0).abs() < 1e-12);
    }
}
