//! Log-density scaling with density estimation: each histogram cell's colour is scaled by
//! `k1·ln(1 + k2·a)/a` (a its alpha sum) and spread over a Gaussian disc whose radius
//! shrinks as the local density grows (flam3's `de_thread`), into a float accumulator.
//!
//! Cells are processed in bands of rows; each band scatters into its own buffer and the
//! buffers are added in band order, so the result does not depend on the thread count.

use rayon::prelude::*;

use super::chaos::Histogram;
use super::filter::DensityFilters;

/// Rows of source cells per band.
const BAND: usize = 64;

/// The float accumulator (flam3's `abucket` of 32-bit floats): r, g, b, alpha.
pub(crate) type Accum = Vec<[f32; 4]>;

#[inline(always)]
fn bump(a: &mut [f32; 4], c: &[f64; 4]) {
    for k in 0..4 {
        a[k] = (a[k] as f64 + c[k]) as f32;
    }
}

/// Adds `c` to cell `(x, y)` of a band buffer starting at row `top`, if inside the image.
#[inline(always)]
fn put_cell(
    buf: &mut [[f32; 4]],
    width: usize,
    height: usize,
    top: usize,
    x: isize,
    y: isize,
    c: &[f64; 4],
) {
    if x >= 0 && (x as usize) < width && y >= 0 && (y as usize) < height {
        let row = y as usize - top;
        bump(&mut buf[row * width + x as usize], c);
    }
}

/// Adds the log-scaled histogram to `acc` without density estimation.
pub(crate) fn log_scale(hist: &Histogram, acc: &mut Accum, k1: f64, k2: f64) {
    acc.par_iter_mut()
        .zip(hist.rgba.par_iter())
        .for_each(|(a, b)| {
            let c3 = b[3] as f64;
            if c3 == 0.0 {
                return;
            }
            let ls = (k1 * (1.0 + c3 * k2).ln()) / c3;
            let c = b.map(|v| v as f64 * ls);
            bump(a, &c);
        });
}

/// Adds the log-scaled, density-estimated histogram (`width × height` cells,
/// supersampling `os`) to `acc`.
#[allow(clippy::too_many_arguments)]
pub(crate) fn estimate(
    hist: &Histogram,
    acc: &mut Accum,
    width: usize,
    height: usize,
    os: usize,
    de: &DensityFilters,
    k1: f64,
    k2: f64,
) {
    let ss = os / 2;
    let even = os.is_multiple_of(2);
    let scfact = (os as f64 / (os as f64 + 1.0)).powi(2);
    let lo = os - 1;
    if width <= 2 * lo || height <= 2 * lo {
        return;
    }
    let (j0, j1) = (lo, height - lo);
    let (i0, i1) = (lo, width - lo);
    // Widest kernel reach in cells.
    let reach = de
        .widths
        .iter()
        .take(de.max_filter_index + 1)
        .map(|w| (w.ceil() as usize).saturating_sub(1))
        .max()
        .unwrap_or(0);
    let bands: Vec<usize> = (j0..j1).step_by(BAND).collect();
    let parts: Vec<(usize, usize, Vec<[f32; 4]>)> = bands
        .par_iter()
        .map(|&start| {
            let end = (start + BAND).min(j1);
            // Buffer rows [top, bottom) of the accumulator.
            let top = start.saturating_sub(reach);
            let bottom = (end + reach).min(height);
            let mut buf = vec![[0f32; 4]; (bottom - top) * width];
            let mut put =
                |x: isize, y: isize, c: &[f64; 4]| put_cell(&mut buf, width, height, top, x, y, c);
            for j in start..end {
                for i in i0..i1 {
                    let cell = i + j * width;
                    let b = &hist.rgba[cell];
                    if hist.hits(cell) == 0 || b[3] == 0 {
                        continue;
                    }
                    let mut f = 0.0;
                    for jj in j - ss..=j + ss {
                        for ii in i - ss..=i + ss {
                            f += hist.hits(ii + jj * width) as f64 / 255.0;
                        }
                    }
                    if even {
                        f *= scfact;
                    }
                    let sel = de.select(f);
                    let fw = (de.widths[sel].ceil() as usize).saturating_sub(1);
                    let c = b.map(|v| v as f64);
                    let base_ls = (k1 * (1.0 + c[3] * k2).ln()) / c[3];
                    let mut idx = sel * de.kernel_size;
                    let (x, y) = (i as isize, j as isize);
                    for jj in 0..=fw as isize {
                        for ii in 0..=jj {
                            let coef = de.coefs[idx];
                            idx += 1;
                            if coef == 0.0 {
                                continue;
                            }
                            let ls = coef * base_ls;
                            let v = c.map(|ch| ch * ls);
                            if jj == 0 {
                                put(x, y, &v);
                            } else if ii == 0 {
                                put(x + jj, y, &v);
                                put(x - jj, y, &v);
                                put(x, y + jj, &v);
                                put(x, y - jj, &v);
                            } else if ii == jj {
                                put(x + ii, y + jj, &v);
                                put(x - ii, y + jj, &v);
                                put(x + ii, y - jj, &v);
                                put(x - ii, y - jj, &v);
                            } else {
                                put(x + ii, y + jj, &v);
                                put(x - ii, y + jj, &v);
                                put(x + ii, y - jj, &v);
                                put(x - ii, y - jj, &v);
                                put(x + jj, y + ii, &v);
                                put(x - jj, y + ii, &v);
                                put(x + jj, y - ii, &v);
                                put(x - jj, y - ii, &v);
                            }
                        }
                    }
                }
            }
            (top, bottom, buf)
        })
        .collect();
    for (top, bottom, buf) in parts {
        acc[top * width..bottom * width]
            .par_iter_mut()
            .zip(buf.par_iter())
            .for_each(|(a, b)| {
                for k in 0..4 {
                    a[k] += b[k];
                }
            });
    }
}
