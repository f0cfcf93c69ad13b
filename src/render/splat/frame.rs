//! Framing of the fused op: world → supersampled pixel coordinates, and its reverse pass.
//!
//! Fitted framing centres the points' bounding box and scales it so its limiting side spans
//! `fill` of the frame: `u = (x − c_x)·k + W/2`, `v = H/2 − (y − c_y)·k` with
//! `c = (lo + hi)/2` and `k = fill·min(W / (hi_x − lo_x), H / (hi_y − lo_y))`. The reverse
//! pass sends the gradients of `c` and `k` to the extreme points that define the box.

use num_traits::Float;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};
use crate::model::code::Window;
use crate::render::view::FIT_FILL;

/// Points per chunk in reductions; fixed so sums have a fixed order.
const CHUNK: usize = 4096;

/// The fused op's view: which window its points are framed in — fitted to them with an
/// adjustable fill (differentiably), or fixed. (The evaluation renderer's is
/// [`View`](crate::render::View), whose fit always uses [`FIT_FILL`].)
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum SplatView {
    /// Fit the bounding box with its limiting side spanning `fill` of the frame.
    Fit {
        /// Fraction of the frame (the papers use 0.75).
        fill: f64,
    },
    /// A fixed window of the plane.
    Window(Window),
}

/// [`SplatView`]'s former name.
#[deprecated(note = "renamed `SplatView`")]
pub type SplatFraming = SplatView;

impl Default for SplatView {
    fn default() -> Self {
        SplatView::Fit { fill: FIT_FILL }
    }
}

impl SplatView {
    /// Checks the view's numbers.
    pub fn validate(&self) -> Result<()> {
        match self {
            SplatView::Fit { fill } if !(*fill > 0.0 && *fill <= 1.0) => Err(Error::param(
                "fill",
                format!("must lie in (0, 1], got {fill}"),
            )),
            SplatView::Window(w) => w.validate(),
            _ => Ok(()),
        }
    }
}

/// A resolved framing, with what its reverse pass needs.
#[derive(Clone, Debug)]
pub struct FrameState {
    /// Centre in world coordinates.
    pub center: [f64; 2],
    /// Supersampled pixels per world unit.
    pub scale: f64,
    /// Grid size in supersampled pixels.
    pub grid: [f64; 2],
    /// For fitted framing: indices of the points at min x, max x, min y, max y, and which
    /// axis limits the scale (0 = x, 1 = y).
    fit: Option<([usize; 4], usize, [f64; 2], f64)>,
}

/// Resolves the framing for `points` on a `grid_w × grid_h` supersampled grid.
pub fn fit(
    framing: &SplatView,
    points: &[[f64; 2]],
    grid_w: usize,
    grid_h: usize,
) -> Result<FrameState> {
    let grid = [grid_w as f64, grid_h as f64];
    match framing {
        SplatView::Window(w) => {
            let size = w.size();
            // Keep pixels square: the window's aspect is used as is when it matches.
            let scale = (grid[0] / size[0]).min(grid[1] / size[1]);
            Ok(FrameState {
                center: w.center(),
                scale,
                grid,
                fit: None,
            })
        }
        SplatView::Fit { fill } => {
            if points.is_empty() {
                return Err(Error::Empty("no points to frame".into()));
            }
            // Arg-extrema with a fixed reduction order (first index wins ties).
            let ext = points
                .par_chunks(CHUNK)
                .enumerate()
                .map(|(c, ch)| {
                    let mut e = [c * CHUNK; 4];
                    for (i, p) in ch.iter().enumerate() {
                        let gi = c * CHUNK + i;
                        if p[0] < points[e[0]][0] {
                            e[0] = gi;
                        }
                        if p[0] > points[e[1]][0] {
                            e[1] = gi;
                        }
                        if p[1] < points[e[2]][1] {
                            e[2] = gi;
                        }
                        if p[1] > points[e[3]][1] {
                            e[3] = gi;
                        }
                    }
                    e
                })
                .collect::<Vec<_>>();
            let mut e = ext[0];
            for c in &ext[1..] {
                if points[c[0]][0] < points[e[0]][0] {
                    e[0] = c[0];
                }
                if points[c[1]][0] > points[e[1]][0] {
                    e[1] = c[1];
                }
                if points[c[2]][1] < points[e[2]][1] {
                    e[2] = c[2];
                }
                if points[c[3]][1] > points[e[3]][1] {
                    e[3] = c[3];
                }
            }
            let lo = [points[e[0]][0], points[e[2]][1]];
            let hi = [points[e[1]][0], points[e[3]][1]];
            let ext_w = [(hi[0] - lo[0]).max(1e-12), (hi[1] - lo[1]).max(1e-12)];
            let kx = fill * grid[0] / ext_w[0];
            let ky = fill * grid[1] / ext_w[1];
            let (scale, axis) = if kx <= ky { (kx, 0) } else { (ky, 1) };
            Ok(FrameState {
                center: [0.5 * (lo[0] + hi[0]), 0.5 * (lo[1] + hi[1])],
                scale,
                grid,
                fit: Some((e, axis, ext_w, *fill)),
            })
        }
    }
}

impl FrameState {
    /// Supersampled pixel coordinates `(u, v)` of a world point (v grows downwards).
    #[inline]
    pub fn project<T: Float>(&self, p: &[f64; 2]) -> [T; 2] {
        let u = (p[0] - self.center[0]) * self.scale + 0.5 * self.grid[0];
        let v = 0.5 * self.grid[1] - (p[1] - self.center[1]) * self.scale;
        [
            T::from(u).unwrap_or(T::nan()),
            T::from(v).unwrap_or(T::nan()),
        ]
    }

    /// `∂L/∂points` (world) from `∂L/∂(u, v)`.
    pub fn backward(&self, points: &[[f64; 2]], guv: &[[f64; 2]]) -> Vec<[f64; 2]> {
        let k = self.scale;
        let mut g: Vec<[f64; 2]> = guv.par_iter().map(|g| [k * g[0], -k * g[1]]).collect();
        let Some((ext, axis, ext_w, _)) = self.fit else {
            return g;
        };
        // ∂L/∂k = Σ gu·(x − cx) − gv·(y − cy);  ∂L/∂c = (−k Σ gu, k Σ gv).
        let partial: Vec<[f64; 3]> = points
            .par_chunks(CHUNK)
            .zip(guv.par_chunks(CHUNK))
            .map(|(ps, gs)| {
                let mut a = [0.0; 3];
                for (p, q) in ps.iter().zip(gs) {
                    a[0] += q[0] * (p[0] - self.center[0]) - q[1] * (p[1] - self.center[1]);
                    a[1] += q[0];
                    a[2] += q[1];
                }
                a
            })
            .collect();
        let mut s = [0.0; 3];
        for a in partial {
            for c in 0..3 {
                s[c] += a[c];
            }
        }
        let gk = s[0];
        let gc = [-k * s[1], k * s[2]];
        // c = (lo + hi) / 2.
        g[ext[0]][0] += 0.5 * gc[0];
        g[ext[1]][0] += 0.5 * gc[0];
        g[ext[2]][1] += 0.5 * gc[1];
        g[ext[3]][1] += 0.5 * gc[1];
        // k = fill·G / (hi − lo) on the limiting axis: ∂k/∂hi = −k/(hi − lo) = −∂k/∂lo.
        let dk = -k / ext_w[axis];
        let (lo_i, hi_i) = if axis == 0 {
            (ext[0], ext[1])
        } else {
            (ext[2], ext[3])
        };
        g[hi_i][axis] += gk * dk;
        g[lo_i][axis] -= gk * dk;
        g
    }
}
