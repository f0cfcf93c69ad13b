//! From the accumulator to pixels: flam3's spatial filter, then gamma with a linear range
//! below `gamma_threshold`, vibrancy, highlight power and the background (flam3's
//! `flam3_calc_alpha`, `flam3_calc_newrgb` and the final loop of `render_rectangle`).

use rayon::prelude::*;

use super::density::Accum;
use super::filter::SpatialFilter;
use crate::model::flame::palette::{hsv_to_rgb, rgb_to_hsv};

/// flam3's `PREFILTER_WHITE`.
const WHITE: f64 = 255.0;

/// Gamma with a linear segment below `linrange` (flam3's `flam3_calc_alpha`).
pub(crate) fn calc_alpha(density: f64, g: f64, linrange: f64) -> f64 {
    if density > 0.0 {
        if density < linrange {
            let funcval = linrange.powf(g);
            let frac = density / linrange;
            (1.0 - frac) * density * (funcval / linrange) + frac * density.powf(g)
        } else {
            density.powf(g)
        }
    } else {
        0.0
    }
}

/// The vibrant colour: the accumulated colour scaled by `ls`, with over-bright colours
/// desaturated by `highpow` (flam3's `flam3_calc_newrgb`).
pub(crate) fn calc_newrgb(c: &[f64; 4], ls: f64, highpow: f64) -> [f64; 3] {
    if ls == 0.0 || (c[0] == 0.0 && c[1] == 0.0 && c[2] == 0.0) {
        return [0.0; 3];
    }
    let (mut maxa, mut maxc) = (-1.0, 0.0);
    for &v in &c[..3] {
        let a = ls * (v / WHITE);
        if a > maxa {
            maxa = a;
            maxc = v / WHITE;
        }
    }
    let newls = 255.0 / maxc;
    if maxa > 255.0 && highpow >= 0.0 {
        let lsratio = (newls / ls).powf(highpow);
        let rgb = [
            newls * (c[0] / WHITE) / 255.0,
            newls * (c[1] / WHITE) / 255.0,
            newls * (c[2] / WHITE) / 255.0,
        ];
        let mut hsv = rgb_to_hsv(rgb);
        hsv[1] *= lsratio;
        hsv_to_rgb(hsv).map(|v| v * 255.0)
    } else {
        let mut adjhlp = -highpow;
        if adjhlp > 1.0 {
            adjhlp = 1.0;
        }
        if maxa <= 255.0 {
            adjhlp = 1.0;
        }
        let s = (1.0 - adjhlp) * newls + adjhlp * ls;
        [s * (c[0] / WHITE), s * (c[1] / WHITE), s * (c[2] / WHITE)]
    }
}

/// Tone-mapping settings of a flame.
pub(crate) struct Tone {
    pub gamma: f64,
    pub linrange: f64,
    pub vibrancy: f64,
    pub highpow: f64,
    /// Background × 256 (flam3's scale).
    pub background: [f64; 3],
    /// Keep alpha (un-premultiply) instead of compositing onto the background.
    pub transparent: bool,
}

/// Filters the accumulator down to `iw × ih` pixels and tone-maps them: RGB in [0, 255]
/// and alpha in [0, 1], rows top (smallest y) first.
#[allow(clippy::too_many_arguments)]
pub(crate) fn finish(
    acc: &Accum,
    acc_width: usize,
    iw: usize,
    ih: usize,
    os: usize,
    offset: usize,
    filter: &SpatialFilter,
    tone: &Tone,
) -> Vec<[f32; 4]> {
    let g = 1.0 / tone.gamma;
    let fw = filter.width;
    let mut out = vec![[0f32; 4]; iw * ih];
    out.par_chunks_mut(iw).enumerate().for_each(|(j, row)| {
        let y = offset + j * os;
        for (i, px) in row.iter_mut().enumerate() {
            let x = offset + i * os;
            let mut t = [0.0f64; 4];
            for jj in 0..fw {
                let arow = (y + jj) * acc_width + x;
                for ii in 0..fw {
                    let k = filter.coefs[ii + jj * fw];
                    let a = &acc[arow + ii];
                    for c in 0..4 {
                        t[c] += k * a[c] as f64;
                    }
                }
            }
            let tmp = t[3] / WHITE;
            let (alpha, ls) = if t[3] <= 0.0 {
                (0.0, 0.0)
            } else {
                let alpha = calc_alpha(tmp, g, tone.linrange);
                (alpha.clamp(0.0, 1.0), tone.vibrancy * 256.0 * alpha / tmp)
            };
            let newrgb = calc_newrgb(&t, ls, tone.highpow);
            let mut o = [0f32; 4];
            for c in 0..3 {
                let mut a = newrgb[c] + (1.0 - tone.vibrancy) * 256.0 * (t[c] / WHITE).powf(g);
                if !tone.transparent {
                    a += (1.0 - alpha) * tone.background[c];
                } else if alpha > 0.0 {
                    a /= alpha;
                } else {
                    a = 0.0;
                }
                // A negative filtered channel makes `powf` NaN (even when multiplied by a
                // zero `1 − vibrancy`); flam3's clamps, built with -ffast-math, turn it
                // into 255, which shows as white fringes with negative-lobed filters.
                o[c] = if a.is_nan() {
                    255.0
                } else {
                    a.clamp(0.0, 255.0)
                } as f32;
            }
            o[3] = alpha.clamp(0.0, 1.0) as f32;
            *px = o;
        }
    });
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gamma_is_linear_below_the_threshold_and_continuous_at_it() {
        let (g, lin) = (1.0 / 4.0, 0.01);
        // Continuity at the threshold.
        let below = calc_alpha(lin * (1.0 - 1e-9), g, lin);
        let above = calc_alpha(lin * (1.0 + 1e-9), g, lin);
        assert!((below - above).abs() < 1e-6);
        // Far below, the blend tends to the straight line through the origin with slope
        // lin^g / lin (x^g alone would be infinitely steep there): at x = 1e-12 the x^g
        // part weighs x / lin = 1e-10 and contributes 0.3 % of the value.
        let x = 1e-12;
        let line = x * lin.powf(g) / lin;
        assert!((calc_alpha(x, g, lin) - line).abs() < 1e-2 * line);
        assert!(calc_alpha(x, g, lin) < x.powf(g) / 100.0);
        assert_eq!(calc_alpha(0.0, g, lin), 0.0);
    }

    #[test]
    fn highlight_power_desaturates_only_over_bright_pixels() {
        let c = [255.0, 127.5, 0.0, 255.0];
        // Not saturated: plain scaling.
        let n = calc_newrgb(&c, 100.0, 1.0);
        assert!((n[0] - 100.0).abs() < 1e-12 && (n[1] - 50.0).abs() < 1e-12);
        // Saturated with highlight power ≥ 0: the top channel is clipped to 255, the others
        // pulled towards it.
        let s = calc_newrgb(&c, 1000.0, 1.0);
        assert!((s[0] - 255.0).abs() < 1e-9);
        assert!(s[1] > 127.5 && s[2] > 0.0);
    }
}
