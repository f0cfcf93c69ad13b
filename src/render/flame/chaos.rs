//! The flame chaos game and its histogram: flam3's iteration (transform choice through a
//! 16384-entry table with optional xaos rows, bad-value restarts, the final transform
//! applied for plotting only, colour blending) and the colour + density accumulation.

use rand::RngCore;

use crate::error::{Error, Result};
use crate::isa::{Isa, IsaLevel, PortableIsa};
use crate::model::flame::variations::{rand01, rand11};
use crate::model::flame::{Flame, PaletteMode, PreparedXform};

/// Entries of flam3's transform-choice table (`CHOOSE_XFORM_GRAIN`).
pub(crate) const GRAIN: usize = 16384;

/// Transform choice: row 0 by the weights, row `k + 1` by the weights times transform
/// `k`'s xaos row (when any xaos entry differs from 1).
pub(crate) struct Selector {
    table: Vec<u16>,
    chaos: bool,
}

impl Selector {
    pub(crate) fn new(flame: &Flame) -> Result<Self> {
        let n = flame.xforms.len();
        if n > u16::MAX as usize {
            return Err(Error::param(
                "xforms",
                format!("{n} transforms; at most {} are supported", u16::MAX),
            ));
        }
        let weights: Vec<f64> = flame.xforms.iter().map(|x| x.weight).collect();
        let chaos = flame
            .xforms
            .iter()
            .any(|x| x.chaos.iter().any(|&c| (c - 1.0).abs() > 1e-10));
        let rows = if chaos { n + 1 } else { 1 };
        let mut table = Vec::with_capacity(rows * GRAIN);
        for row in 0..rows {
            let w: Vec<f64> = if row == 0 {
                weights.clone()
            } else {
                let c = &flame.xforms[row - 1].chaos;
                weights
                    .iter()
                    .enumerate()
                    .map(|(j, &w)| w * c.get(j).copied().unwrap_or(1.0))
                    .collect()
            };
            fill_row(&w, &mut table).map_err(|m| {
                Error::param(
                    "chaos",
                    format!(
                        "{}: {m}",
                        if row == 0 {
                            "transform weights".to_string()
                        } else {
                            format!("xaos row of xform {}", row - 1)
                        }
                    ),
                )
            })?;
        }
        Ok(Selector { table, chaos })
    }

    /// The transform to apply after transform `last` (`None` before the first step), from
    /// one 32-bit draw.
    #[inline(always)]
    pub(crate) fn pick(&self, last: Option<usize>, draw: u32) -> usize {
        let row = match (self.chaos, last) {
            (true, Some(k)) => k + 1,
            _ => 0,
        };
        self.table[row * GRAIN + (draw as usize & (GRAIN - 1))] as usize
    }
}

/// flam3's `flam3_create_chaos_distrib`: entry i holds the transform whose cumulative
/// weight interval contains i/GRAIN of the total.
fn fill_row(w: &[f64], table: &mut Vec<u16>) -> std::result::Result<(), String> {
    let total: f64 = w.iter().sum();
    if w.iter().any(|&d| d < 0.0) {
        return Err("weights must be ≥ 0".into());
    }
    if total == 0.0 {
        return Err("every weight is 0, so no transform can be chosen".into());
    }
    let dr = total / GRAIN as f64;
    let mut j = 0usize;
    let mut t = w[0];
    let mut r = 0.0;
    for _ in 0..GRAIN {
        while r >= t && j + 1 < w.len() {
            j += 1;
            t += w[j];
        }
        table.push(j as u16);
        r += dr;
    }
    Ok(())
}

/// Where a flame point lands in the histogram (flam3's camera: centre, pixels per unit,
/// rotation about the centre, +y down, a gutter of cells around the image for the filters).
#[derive(Clone, Debug)]
pub(crate) struct Camera {
    bounds: [f64; 4],
    rot: Option<[f64; 4]>,
    rot_center: [f64; 2],
    ws0: f64,
    wb0s0: f64,
    hs1: f64,
    hb1s1: f64,
    /// Histogram width and height in cells.
    pub width: usize,
    pub height: usize,
}

impl Camera {
    pub(crate) fn new(flame: &Flame, width: usize, height: usize, gutter: usize) -> Self {
        let os = flame.supersample as f64;
        let ppu = flame.pixels_per_unit();
        let (iw, ih) = (flame.size[0] as f64, flame.size[1] as f64);
        let t0 = gutter as f64 / (os * ppu);
        let t1 = gutter as f64 / (os * ppu);
        let corner0 = flame.center[0] - iw / ppu / 2.0;
        let corner1 = flame.center[1] - ih / ppu / 2.0;
        let bounds = [
            corner0 - t0,
            corner1 - t1,
            corner0 + iw / ppu + t0,
            corner1 + ih / ppu + t1,
        ];
        let size0 = 1.0 / (bounds[2] - bounds[0]);
        let size1 = 1.0 / (bounds[3] - bounds[1]);
        let a = flame.rotate * 2.0 * std::f64::consts::PI / 360.0;
        let rot = (flame.rotate != 0.0).then(|| {
            let (s, c) = a.sin_cos();
            [c, -s, s, c]
        });
        let ws0 = width as f64 * size0;
        let hs1 = height as f64 * size1;
        Camera {
            bounds,
            rot,
            rot_center: flame.center,
            ws0,
            wb0s0: ws0 * bounds[0],
            hs1,
            hb1s1: hs1 * bounds[1],
            width,
            height,
        }
    }

    /// The histogram cell of a point, or `None` outside (NaN included).
    #[inline(always)]
    pub(crate) fn locate(&self, p: [f64; 2]) -> Option<usize> {
        let (p0, p1) = match &self.rot {
            Some(r) => {
                let (x, y) = (p[0] - self.rot_center[0], p[1] - self.rot_center[1]);
                (
                    x * r[0] + y * r[1] + self.rot_center[0],
                    x * r[2] + y * r[3] + self.rot_center[1],
                )
            }
            None => (p[0], p[1]),
        };
        let b = &self.bounds;
        if p0 >= b[0] && p1 >= b[1] && p0 <= b[2] && p1 <= b[3] {
            let i = ((self.ws0 * p0 - self.wb0s0) as usize).min(self.width - 1);
            let j = ((self.hs1 * p1 - self.hb1s1) as usize).min(self.height - 1);
            Some(i + self.width * j)
        } else {
            None
        }
    }
}

/// The palette as the accumulation adds it: flam3's colours × 255, and their integer
/// parts for the common case (opacity 1, step mode).
pub(crate) struct Colors {
    dmap: Vec<[f64; 4]>,
    dmap_int: Vec<[u32; 4]>,
    linear: bool,
}

impl Colors {
    pub(crate) fn new(flame: &Flame) -> Self {
        let dmap: Vec<[f64; 4]> = flame
            .palette
            .flam3_colors()
            .iter()
            .map(|c| c.map(|v| v * 255.0))
            .collect();
        let dmap_int = dmap.iter().map(|c| c.map(|v| v as u32)).collect();
        Colors {
            dmap,
            dmap_int,
            linear: flame.palette_mode == PaletteMode::Linear,
        }
    }

    /// Whether every palette alpha is 1, so the alpha sum doubles as the hit count.
    pub(crate) fn opaque(&self) -> bool {
        self.dmap.iter().all(|c| c[3] == 255.0)
    }
}

/// The colour + density histogram at the supersampled resolution: integer sums of the
/// palette colour (× 255) of every point, as flam3's 32-bit buckets. The hit count (255 per
/// point) is the alpha sum unless the palette has transparent entries.
pub(crate) struct Histogram {
    pub rgba: Vec<[u32; 4]>,
    pub count: Option<Vec<u32>>,
}

impl Histogram {
    pub(crate) fn new(cells: usize, separate_count: bool) -> Self {
        Histogram {
            rgba: vec![[0; 4]; cells],
            count: separate_count.then(|| vec![0; cells]),
        }
    }

    /// Adds `other` (saturating, so the sum does not depend on the order).
    pub(crate) fn merge(&mut self, other: &Histogram) {
        for (a, b) in self.rgba.iter_mut().zip(&other.rgba) {
            for k in 0..4 {
                a[k] = a[k].saturating_add(b[k]);
            }
        }
        if let (Some(a), Some(b)) = (&mut self.count, &other.count) {
            for (x, y) in a.iter_mut().zip(b) {
                *x = x.saturating_add(*y);
            }
        }
    }

    /// The hit count of a cell (× 255).
    #[inline(always)]
    pub(crate) fn hits(&self, i: usize) -> u32 {
        match &self.count {
            Some(c) => c[i],
            None => self.rgba[i][3],
        }
    }

    /// Asks for a cell's cache line when its point is buffered, so that by the time the
    /// batch is added (up to [`HIT_BATCH`] points later) the line is in the core's cache
    /// instead of a random read of the histogram each (7–10 % of a 1-thread render's CPU
    /// time on the bench flames).
    #[inline(always)]
    fn prefetch(&self, cell: usize) {
        #[cfg(target_arch = "x86_64")]
        {
            use std::arch::x86_64::{_MM_HINT_T0, _mm_prefetch};
            // SAFETY: a prefetch is a hint; it reads nothing and cannot fault, and `cell`
            // is inside the histogram anyway.
            unsafe {
                _mm_prefetch::<_MM_HINT_T0>(self.rgba.as_ptr().wrapping_add(cell).cast());
                if let Some(c) = &self.count {
                    _mm_prefetch::<_MM_HINT_T0>(c.as_ptr().wrapping_add(cell).cast());
                }
            }
        }
        #[cfg(not(target_arch = "x86_64"))]
        let _ = cell;
    }

    #[inline(always)]
    fn add(&mut self, cell: usize, c: &Colors, color: f64, vis: f64) {
        let ci = color * 256.0;
        let ci0 = ci as i32;
        if !c.linear && vis == 1.0 {
            let idx = ci0.clamp(0, 255) as usize;
            let d = &c.dmap_int[idx];
            let b = &mut self.rgba[cell];
            for k in 0..4 {
                b[k] = b[k].saturating_add(d[k]);
            }
            if let Some(cnt) = &mut self.count {
                cnt[cell] = cnt[cell].saturating_add(255);
            }
            return;
        }
        let col: [f64; 4] = if c.linear {
            let (i0, frac) = if ci0 < 0 {
                (0usize, 0.0)
            } else if ci0 >= 255 {
                (254usize, 1.0)
            } else {
                (ci0 as usize, ci - ci0 as f64)
            };
            let (a, b) = (&c.dmap[i0], &c.dmap[i0 + 1]);
            std::array::from_fn(|k| a[k] * (1.0 - frac) + b[k] * frac)
        } else {
            c.dmap[ci0.clamp(0, 255) as usize]
        };
        let b = &mut self.rgba[cell];
        if vis == 1.0 {
            for k in 0..4 {
                b[k] = b[k].saturating_add(col[k] as u32);
            }
            if let Some(cnt) = &mut self.count {
                cnt[cell] = cnt[cell].saturating_add(255);
            }
        } else {
            for k in 0..4 {
                b[k] = b[k].saturating_add((vis * col[k]) as u32);
            }
            if let Some(cnt) = &mut self.count {
                cnt[cell] = cnt[cell].saturating_add((vis * 255.0) as u32);
            }
        }
    }
}

/// What trajectories did.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct GameStats {
    /// Points plotted into the histogram.
    pub hits: u64,
    /// flam3's bad values: steps whose result was NaN or beyond ±10¹⁰ (each replaced by a
    /// random point).
    pub badvals: u64,
}

impl std::ops::AddAssign for GameStats {
    fn add_assign(&mut self, o: Self) {
        self.hits += o.hits;
        self.badvals += o.badvals;
    }
}

/// One flame's chaos game, ready to run trajectories.
pub(crate) struct Game<'a> {
    pub xforms: &'a [PreparedXform],
    pub final_xform: Option<&'a PreparedXform>,
    pub final_opacity: f64,
    pub selector: &'a Selector,
    pub camera: &'a Camera,
    pub colors: &'a Colors,
    /// Steps run before plotting starts.
    pub fuse: usize,
    /// The instruction set the trajectories run on (checked available).
    pub isa: Isa,
}

impl Game<'_> {
    /// One trajectory of `n` plotted samples (after `fuse` unplotted steps), as flam3's
    /// `flam3_iterate` followed by the bucket accumulation. Points are buffered and added
    /// to the histogram in batches, as flam3 does, each cell prefetched as its point is
    /// buffered: the adds of a batch then find their lines in cache instead of stalling
    /// the iteration.
    ///
    /// The loop is compiled once per instruction set ([`crate::isa`]) and runs on
    /// `self.isa`; both copies plot the same points.
    pub(crate) fn run<R: RngCore>(
        &self,
        rng: &mut R,
        n: u64,
        hist: &mut Histogram,
        buf: &mut Vec<Hit>,
    ) -> GameStats {
        match self.isa {
            #[cfg(target_arch = "x86_64")]
            // SAFETY: `isa` is `Fma` only after `Isa::detect` or `Isa::checked` found AVX2,
            // FMA and BMI1/2 on this CPU.
            Isa::Fma => unsafe { self.run_fma(rng, n, hist, buf) },
            _ => self.run_portable(rng, n, hist, buf),
        }
    }

    /// The portable copy of the loop.
    ///
    /// Never inlined: inlined into the thread's closure, the loop was compiled with other
    /// register choices and ran 12 % slower on a linear flame (measured when the trig
    /// functions changed and the compiler's inlining decision changed with them).
    #[inline(never)]
    fn run_portable<R: RngCore>(
        &self,
        rng: &mut R,
        n: u64,
        hist: &mut Histogram,
        buf: &mut Vec<Hit>,
    ) -> GameStats {
        self.run_on(PortableIsa, rng, n, hist, buf)
    }

    /// The loop compiled with AVX2, FMA and BMI1/2: the variations' trigonometry (through
    /// this instruction set's copy of the formulas) and `pre_blur` use single-instruction
    /// fused multiply–adds.
    #[cfg(target_arch = "x86_64")]
    #[inline(never)]
    #[target_feature(enable = "avx2,fma,bmi1,bmi2")]
    fn run_fma<R: RngCore>(
        &self,
        rng: &mut R,
        n: u64,
        hist: &mut Histogram,
        buf: &mut Vec<Hit>,
    ) -> GameStats {
        // SAFETY: this copy runs only where the CPU has the features (see `run`).
        let isa = unsafe { crate::isa::FmaIsa::new_unchecked() };
        self.run_on(isa, rng, n, hist, buf)
    }

    /// The loop, variations on instruction set `I`.
    #[inline(always)]
    fn run_on<I: IsaLevel, R: RngCore>(
        &self,
        isa: I,
        rng: &mut R,
        n: u64,
        hist: &mut Histogram,
        buf: &mut Vec<Hit>,
    ) -> GameStats {
        let mut st = GameStats::default();
        let mut p = [rand11(rng), rand11(rng)];
        let mut color = rand01(rng);
        // flam3 also draws a starting opacity, overwritten before it is read.
        let _ = rand01(rng);
        let mut vis;
        let mut last: Option<usize> = None;
        let mut consec = 0u32;
        let total = n + self.fuse as u64;
        let mut i = 0u64;
        buf.clear();
        while i < total {
            let k = self.selector.pick(last, rng.next_u32());
            let xf = &self.xforms[k];
            let out = xf.apply_on(isa, p, rng);
            let q_color = xf.blend_color(color);
            let q_vis = xf.visibility;
            if out.bad {
                st.badvals += 1;
                consec += 1;
                let q = [rand11(rng), rand11(rng)];
                if consec < 5 {
                    p = q;
                    color = q_color;
                    continue;
                }
                consec = 0;
                p = q;
            } else {
                consec = 0;
                p = out.point;
            }
            last = Some(k);
            color = q_color;
            vis = q_vis;
            let (plot, plot_color) = match self.final_xform {
                Some(fx) if self.final_opacity == 1.0 || rand01(rng) < self.final_opacity => {
                    let f = fx.apply_on(isa, p, rng);
                    let fp = if f.bad {
                        [rand11(rng), rand11(rng)]
                    } else {
                        f.point
                    };
                    (fp, fx.blend_color(color))
                }
                _ => (p, color),
            };
            if i >= self.fuse as u64
                && vis != 0.0
                && let Some(cell) = self.camera.locate(plot)
            {
                hist.prefetch(cell);
                buf.push(Hit {
                    cell: cell as u32,
                    color: plot_color,
                    vis,
                });
                if buf.len() == HIT_BATCH {
                    st.hits += self.flush(buf, hist);
                }
            }
            i += 1;
        }
        st.hits += self.flush(buf, hist);
        st
    }

    fn flush(&self, buf: &mut Vec<Hit>, hist: &mut Histogram) -> u64 {
        let n = buf.len() as u64;
        for h in buf.iter() {
            hist.add(h.cell as usize, self.colors, h.color, h.vis);
        }
        buf.clear();
        n
    }
}

/// Points buffered before they are added to the histogram.
pub(crate) const HIT_BATCH: usize = 2048;

/// A plotted point waiting for the histogram.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Hit {
    cell: u32,
    color: f64,
    vis: f64,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn choice_table_follows_the_weights() {
        let mut t = Vec::new();
        fill_row(&[1.0, 3.0], &mut t).unwrap();
        let ones = t.iter().filter(|&&k| k == 1).count();
        assert_eq!(ones, 3 * GRAIN / 4);
        assert!(fill_row(&[0.0, 0.0], &mut Vec::new()).is_err());
        // A zero weight is never chosen.
        let mut t = Vec::new();
        fill_row(&[0.0, 1.0, 0.0], &mut t).unwrap();
        assert!(t.iter().all(|&k| k == 1));
    }
}
