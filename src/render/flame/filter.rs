//! flam3's filters: the spatial filter that turns the supersampled accumulator into output
//! pixels, and the density-estimation kernels that blur sparse regions more than dense
//! ones (flam3's `filters.c`, re-derived).

use std::f64::consts::PI;

use crate::error::{Error, Result};
use crate::model::flame::Kernel;

/// Support (half-width at filter radius 1) of each kernel.
pub fn support(k: Kernel) -> f64 {
    match k {
        Kernel::Gaussian | Kernel::Bell | Kernel::Quadratic => 1.5,
        Kernel::Hermite | Kernel::Triangle | Kernel::Blackman => 1.0,
        Kernel::Hanning | Kernel::Hamming => 1.0,
        Kernel::Box => 0.5,
        Kernel::BSpline | Kernel::Mitchell | Kernel::Catrom | Kernel::Lanczos2 => 2.0,
        Kernel::Lanczos3 => 3.0,
    }
}

fn sinc(x: f64) -> f64 {
    let x = x * PI;
    if x != 0.0 { x.sin() / x } else { 1.0 }
}

/// flam3's Gaussian kernel exp(−2x²)·√(2/π).
pub fn gaussian(x: f64) -> f64 {
    (-2.0 * x * x).exp() * (2.0 / PI).sqrt()
}

/// The kernel's value at `x`.
pub fn eval(k: Kernel, x: f64) -> f64 {
    const B: f64 = 1.0 / 3.0;
    const C: f64 = 1.0 / 3.0;
    match k {
        Kernel::Gaussian => gaussian(x),
        Kernel::Hermite => {
            let t = x.abs();
            if t < 1.0 {
                (2.0 * t - 3.0) * t * t + 1.0
            } else {
                0.0
            }
        }
        Kernel::Box => {
            if x > -0.5 && x <= 0.5 {
                1.0
            } else {
                0.0
            }
        }
        Kernel::Triangle => {
            let t = x.abs();
            if t < 1.0 { 1.0 - t } else { 0.0 }
        }
        Kernel::Bell => {
            let t = x.abs();
            if t < 0.5 {
                0.75 - t * t
            } else if t < 1.5 {
                let t = t - 1.5;
                0.5 * t * t
            } else {
                0.0
            }
        }
        Kernel::BSpline => {
            let t = x.abs();
            if t < 1.0 {
                let tt = t * t;
                0.5 * tt * t - tt + 2.0 / 3.0
            } else if t < 2.0 {
                let t = 2.0 - t;
                t * t * t / 6.0
            } else {
                0.0
            }
        }
        Kernel::Mitchell => {
            let tt = x * x;
            let t = x.abs();
            if t < 1.0 {
                ((12.0 - 9.0 * B - 6.0 * C) * (t * tt)
                    + (-18.0 + 12.0 * B + 6.0 * C) * tt
                    + (6.0 - 2.0 * B))
                    / 6.0
            } else if t < 2.0 {
                ((-B - 6.0 * C) * (t * tt)
                    + (6.0 * B + 30.0 * C) * tt
                    + (-12.0 * B - 48.0 * C) * t
                    + (8.0 * B + 24.0 * C))
                    / 6.0
            } else {
                0.0
            }
        }
        Kernel::Blackman => sinc(x) * (0.42 + 0.5 * (PI * x).cos() + 0.08 * (2.0 * PI * x).cos()),
        Kernel::Catrom => {
            if x < -2.0 {
                0.0
            } else if x < -1.0 {
                0.5 * (4.0 + x * (8.0 + x * (5.0 + x)))
            } else if x < 0.0 {
                0.5 * (2.0 + x * x * (-5.0 - 3.0 * x))
            } else if x < 1.0 {
                0.5 * (2.0 + x * x * (-5.0 + 3.0 * x))
            } else if x < 2.0 {
                0.5 * (4.0 + x * (-8.0 + x * (5.0 - x)))
            } else {
                0.0
            }
        }
        Kernel::Hanning => sinc(x) * (0.5 + 0.5 * (PI * x).cos()),
        Kernel::Hamming => sinc(x) * (0.54 + 0.46 * (PI * x).cos()),
        Kernel::Lanczos3 => {
            let t = x.abs();
            let l = if t < 3.0 {
                sinc(t) * sinc(t / 3.0)
            } else {
                0.0
            };
            l * sinc(x / 3.0)
        }
        Kernel::Lanczos2 => {
            let t = x.abs();
            let l = if t < 2.0 {
                sinc(t) * sinc(t / 2.0)
            } else {
                0.0
            };
            l * sinc(x / 2.0)
        }
        Kernel::Quadratic => {
            if x < -1.5 {
                0.0
            } else if x < -0.5 {
                0.5 * (x + 1.5) * (x + 1.5)
            } else if x < 0.5 {
                0.75 - x * x
            } else if x < 1.5 {
                0.5 * (x - 1.5) * (x - 1.5)
            } else {
                0.0
            }
        }
    }
}

/// The spatial filter: a `width × width` kernel over supersampled accumulator cells,
/// normalised to sum 1 (`filter[i + j·width]`).
#[derive(Clone, Debug)]
pub struct SpatialFilter {
    /// Side in accumulator cells (same parity as the supersampling).
    pub width: usize,
    /// Row-major coefficients.
    pub coefs: Vec<f64>,
}

impl SpatialFilter {
    /// flam3's `flam3_create_spatial_filter` for kernel `k`, supersampling `ss` and radius
    /// `radius` (output pixels), square pixels.
    pub fn new(k: Kernel, ss: u32, radius: f64) -> Result<Self> {
        let supp = support(k);
        let fw = 2.0 * supp * ss as f64 * radius;
        let mut width = fw as usize + 1;
        if (width ^ ss as usize) & 1 == 1 {
            width += 1;
        }
        let adjust = if fw > 0.0 {
            supp * width as f64 / fw
        } else {
            1.0
        };
        let mut coefs = vec![0.0; width * width];
        for j in 0..width {
            for i in 0..width {
                let ii = ((2.0 * i as f64 + 1.0) / width as f64 - 1.0) * adjust;
                let jj = ((2.0 * j as f64 + 1.0) / width as f64 - 1.0) * adjust;
                coefs[i + j * width] = eval(k, ii) * eval(k, jj);
            }
        }
        let sum: f64 = coefs.iter().sum();
        if sum == 0.0 {
            return Err(Error::param(
                "filter",
                format!("spatial filter radius {radius} gives a kernel of zero weight; raise it"),
            ));
        }
        for c in &mut coefs {
            *c /= sum;
        }
        Ok(SpatialFilter { width, coefs })
    }
}

/// flam3's density estimation threshold: hit counts up to it get a kernel each.
pub const DE_THRESH: f64 = 100.0;

/// The density-estimation kernels: one Gaussian disc per density level, narrowing from
/// `max_rad·ss + 1` cells for a single hit to `min_rad·ss + 1` (flam3's
/// `flam3_create_de_filters`). Only the octant `0 ≤ dx ≤ dy` of each kernel is stored.
#[derive(Clone, Debug)]
pub struct DensityFilters {
    /// Kernels index above which densities share the last kernel.
    pub max_filtered_counts: f64,
    /// Index of the narrowest kernel.
    pub max_filter_index: usize,
    /// Coefficients per kernel (the octant, row by row).
    pub kernel_size: usize,
    /// Radius of each kernel in cells.
    pub widths: Vec<f64>,
    /// `kernel_size` coefficients per kernel.
    pub coefs: Vec<f64>,
    /// The curve exponent.
    pub curve: f64,
}

impl DensityFilters {
    /// The kernels for `estimator_radius = max_rad`, `estimator_minimum = min_rad`,
    /// `estimator_curve = curve` and supersampling `ss`.
    pub fn new(max_rad: f64, min_rad: f64, curve: f64, ss: u32) -> Result<Self> {
        if curve <= 0.0 {
            return Err(Error::param(
                "estimator_curve",
                format!("must be > 0, got {curve}"),
            ));
        }
        if max_rad < min_rad {
            return Err(Error::param(
                "estimator_minimum",
                format!("{min_rad} exceeds estimator_radius {max_rad}"),
            ));
        }
        let keep_thresh = 100usize;
        let comp_max = max_rad * ss as f64 + 1.0;
        let comp_min = min_rad * ss as f64 + 1.0;
        let num_d = (comp_max / comp_min).powf(1.0 / curve);
        if num_d > 1e7 {
            return Err(Error::param(
                "estimator_curve",
                format!(
                    "radius {max_rad}, minimum {min_rad} and curve {curve} need {num_d:.3e} kernels; \
                     raise the curve or the minimum"
                ),
            ));
        }
        let num = num_d.ceil() as usize;
        let (max_ind, max_filtered_counts) = if num > keep_thresh {
            let ind = (DE_THRESH + (num as f64 - DE_THRESH).powf(curve)).ceil() as usize + 1;
            let mfc = ((ind as f64 - DE_THRESH).powf(1.0 / curve) as i64) as f64 + DE_THRESH;
            (ind, mfc)
        } else {
            (num, num as f64)
        };
        let row = (2.0 * comp_max.ceil() - 1.0) as usize;
        let half = (row - 1) / 2;
        let kernel_size = (half + 1) * (2 + half) / 2;
        let mut coefs = vec![0.0; max_ind * kernel_size];
        let mut widths = vec![0.0; max_ind];
        let mut max_filter_index = 0usize;
        let gs = support(Kernel::Gaussian);
        for (fl, width) in widths.iter_mut().enumerate() {
            let mut h = if fl < keep_thresh {
                comp_max / ((fl + 1) as f64).powf(curve)
            } else {
                let adj = ((fl - keep_thresh) as f64).powf(1.0 / curve) + keep_thresh as f64;
                comp_max / (adj + 1.0).powf(curve)
            };
            if h <= comp_min {
                h = comp_min;
                max_filter_index = fl;
            }
            *width = h;
            let hi = half as i64;
            let mut sum = 0.0;
            for j in -hi..=hi {
                for k in -hi..=hi {
                    let d = ((j * j + k * k) as f64).sqrt() / h;
                    if d <= 1.0 {
                        sum += gaussian(gs * d);
                    }
                }
            }
            let mut idx = fl * kernel_size;
            for j in 0..=half {
                for k in 0..=j {
                    let d = ((j * j + k * k) as f64).sqrt() / h;
                    coefs[idx] = if d > 1.0 { 0.0 } else { gaussian(gs * d) / sum };
                    idx += 1;
                }
            }
            if max_filter_index > 0 {
                break;
            }
        }
        if max_filter_index == 0 {
            max_filter_index = max_ind - 1;
        }
        Ok(DensityFilters {
            max_filtered_counts,
            max_filter_index,
            kernel_size,
            widths,
            coefs,
            curve,
        })
    }

    /// Which kernel a (supersampling-normalised) density `f` selects.
    #[inline]
    pub fn select(&self, f: f64) -> usize {
        let idx = if f > self.max_filtered_counts {
            self.max_filter_index as i64
        } else if f <= DE_THRESH {
            f.ceil() as i64 - 1
        } else {
            DE_THRESH as i64 + (f - DE_THRESH).powf(self.curve).floor() as i64
        };
        idx.clamp(0, self.max_filter_index as i64) as usize
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn spatial_filter_is_normalised_with_the_parity_of_the_supersampling() {
        for ss in 1..=4 {
            let f = SpatialFilter::new(Kernel::Gaussian, ss, 0.5).unwrap();
            assert_eq!(f.width % 2, ss as usize % 2);
            let s: f64 = f.coefs.iter().sum();
            assert!((s - 1.0).abs() < 1e-12);
        }
        // flam3's default (Gaussian, radius 0.5, no supersampling): a 3×3 kernel.
        assert_eq!(
            SpatialFilter::new(Kernel::Gaussian, 1, 0.5).unwrap().width,
            3
        );
    }

    #[test]
    fn density_kernels_narrow_with_density() {
        let d = DensityFilters::new(9.0, 0.0, 0.4, 1).unwrap();
        assert!(d.widths[0] > d.widths[d.max_filter_index]);
        assert_eq!(d.widths[0], 10.0);
        assert_eq!(d.select(1.0), 0);
        assert!(d.select(50.0) > d.select(2.0));
        assert_eq!(d.select(1e12), d.max_filter_index);
    }
}
