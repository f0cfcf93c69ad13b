//! Where a sample lands: its 3×3 footprint of pixels and the splat weights `e^{−2d²}`.
//!
//! Both passes compute a footprint for every one of the 10⁶ samples of a layer, so the
//! weights are the hot spot of the op: six exponentials a sample (three offsets per axis).
//! They are taken together by [`exp_lanes`], a branch-free exponential written lane by lane
//! so that the compiler turns it into vector instructions; libm's `exp`, one call at a
//! time, took a quarter of an iteration.

use crate::isa::{Isa, IsaLevel};

/// The 3×3 footprint of a sample at screen position `u`: its centre pixel and the
/// separable weights `e^{−2(u − p)²}` per axis.
#[derive(Clone, Copy)]
pub(super) struct Footprint {
    pub cx: i64,
    pub cy: i64,
    pub wx: [f64; 3],
    pub wy: [f64; 3],
    /// `u − p` per axis and offset.
    pub dx: [f64; 3],
    pub dy: [f64; 3],
}

/// The footprint of a sample at screen position `u` on a `size²` image, or `None` when no
/// cell of it can fall on the image (also for NaN). The instruction set's token `_isa`
/// picks the AVX2+FMA exponential ([`exp_lanes_avx2`]; the same bits as [`exp_lanes`]) where
/// it is [`FmaIsa`](crate::isa::FmaIsa), which exists only on a CPU that has them.
#[inline(always)]
pub(super) fn footprint<I: IsaLevel>(_isa: I, u: [f64; 2], size: usize) -> Option<Footprint> {
    let hi = size as f64 + 1.0;
    if !(u[0] > -2.0 && u[1] > -2.0 && u[0] < hi && u[1] < hi) {
        return None;
    }
    // floor(u + 0.5) by truncation of a positive number (no libm call).
    let cx = ((u[0] + 2.5) as i64 - 2) as f64;
    let cy = ((u[1] + 2.5) as i64 - 2) as f64;
    let fx = u[0] - cx;
    let fy = u[1] - cy;
    let dx = [fx + 1.0, fx, fx - 1.0];
    let dy = [fy + 1.0, fy, fy - 1.0];
    // e^{−2(f ± 1)²} = e^{−2f²}·e^{∓4f}·e^{−2}: four exponentials, one vector.
    let arg = [-2.0 * fx * fx, -2.0 * fy * fy, 4.0 * fx, 4.0 * fy];
    let e = if matches!(I::ISA, Isa::Fma) {
        #[cfg(target_arch = "x86_64")]
        // SAFETY: `I` is `FmaIsa`, whose values exist only after the CPU was found to have
        // AVX2 and FMA.
        unsafe {
            exp4_lanes_avx2(arg)
        }
        #[cfg(not(target_arch = "x86_64"))]
        exp_lanes(arg)
    } else {
        exp_lanes(arg)
    };
    let ax = e[0] * E_M2;
    let ay = e[1] * E_M2;
    Some(Footprint {
        cx: cx as i64,
        cy: cy as i64,
        wx: [ax / e[2], e[0], ax * e[2]],
        wy: [ay / e[3], e[1], ay * e[3]],
        dx,
        dy,
    })
}

/// The lanes of a run of three pixels in the buffers' layout (five channels a pixel: four
/// colour sums and the weight sum): lane `l` is channel `l % 5` of pixel `l / 5`; lane 15
/// belongs to the next pixel and is given weight zero.
const RUN: usize = 16;

impl Footprint {
    /// The top-left pixel of the footprint when the three runs of 16 lanes from its rows
    /// lie on the image (nearly every footprint; the last column and the border take the
    /// cell-by-cell path).
    #[inline(always)]
    fn run_start(&self, size: usize) -> Option<usize> {
        let n = size as i64;
        (self.cx >= 1 && self.cy >= 1 && self.cx <= n - 3 && self.cy <= n - 2)
            // Footprint row jj is image row size − 1 − (cy + jj − 1); row 2 is the top one.
            .then(|| ((n - 1 - (self.cy + 1)) * n + self.cx - 1) as usize)
    }

    /// Calls `f(ii, jj, pixel)` for every cell `(ii, jj)` (x and y offsets 0..3) on a
    /// `size²` image, `pixel` its row-major index (rows top-down).
    #[inline(always)]
    fn cells(&self, size: usize, mut f: impl FnMut(usize, usize, usize)) {
        let n = size as i64;
        for jj in 0..3 {
            for ii in 0..3 {
                let px = self.cx + ii as i64 - 1;
                let py = self.cy + jj as i64 - 1;
                if px >= 0 && py >= 0 && px < n && py < n {
                    f(ii, jj, ((n - 1 - py) * n + px) as usize);
                }
            }
        }
    }

    /// The splat of one sample, `b += wx·wy·cw` over the footprint's cells (`cw` = the four
    /// colour sums and the weight sum), computed as `wy·(wx·cw)` with a fused multiply–add
    /// into the buffer. Inside the image each footprint row is one run of 16 lanes: four
    /// vector operations with the [`FmaIsa`](crate::isa::FmaIsa) token (the same operations
    /// lane by lane: the same bits).
    #[inline(always)]
    pub fn splat<I: IsaLevel>(&self, _isa: I, size: usize, buf: &mut [[f64; 5]], cw: &[f64; 5]) {
        let Some(top) = self.run_start(size) else {
            self.cells(size, |ii, jj, px| {
                let b = &mut buf[px];
                for k in 0..5 {
                    b[k] = self.wy[jj].mul_add(self.wx[ii] * cw[k], b[k]);
                }
            });
            return;
        };
        let flat = buf.as_flattened_mut();
        #[cfg(target_arch = "x86_64")]
        if matches!(I::ISA, Isa::Fma) {
            // SAFETY: `I` is `FmaIsa` (the CPU has AVX2 and FMA, as for `footprint`);
            // `run_start` keeps the three runs inside `flat`.
            unsafe { splat_runs_avx2(self, top, size, flat, cw) };
            return;
        }
        let q = lanes(&self.wx, cw);
        for jj in 0..3 {
            let run = &mut flat[5 * (top + (2 - jj) * size)..][..RUN];
            for l in 0..RUN {
                run[l] = self.wy[jj].mul_add(q[l], run[l]);
            }
        }
    }

    /// The reverse of [`Footprint::splat`] against the buffer adjoints `adj`: returns
    /// `Σ wx·wy·adj` per channel and the gradient of `Σ wx·wy·(adj·cw)` in the screen
    /// position (`∂wt/∂u = −4·d·wt` per axis).
    #[inline(always)]
    pub fn gather<I: IsaLevel>(
        &self,
        _isa: I,
        size: usize,
        adj: &[[f64; 5]],
        cw: &[f64; 5],
    ) -> ([f64; 5], [f64; 2]) {
        let mut rows = [[0.0f64; RUN]; 3];
        match self.run_start(size) {
            Some(top) => {
                let flat = adj.as_flattened();
                #[cfg(target_arch = "x86_64")]
                if matches!(I::ISA, Isa::Fma) {
                    // SAFETY: as in `splat`; the runs lie inside `flat`.
                    return unsafe { gather_runs_avx2(self, top, size, flat, cw) };
                }
                for (jj, row) in rows.iter_mut().enumerate() {
                    row.copy_from_slice(&flat[5 * (top + (2 - jj) * size)..][..RUN]);
                }
            }
            None => self.cells(size, |ii, jj, px| {
                rows[jj][5 * ii..5 * ii + 5].copy_from_slice(&adj[px]);
            }),
        }
        // S = Σ_jj wy·A, T = Σ_jj wy·dy·A, lane by lane.
        let mut sum = [0.0f64; RUN];
        let mut tsum = [0.0f64; RUN];
        for (jj, row) in rows.iter().enumerate() {
            let ydy = self.wy[jj] * self.dy[jj];
            for l in 0..RUN {
                sum[l] = self.wy[jj].mul_add(row[l], sum[l]);
                tsum[l] = ydy.mul_add(row[l], tsum[l]);
            }
        }
        let wxl = lanes(&self.wx, &[1.0; 5]);
        let wxdx = [
            self.wx[0] * self.dx[0],
            self.wx[1] * self.dx[1],
            self.wx[2] * self.dx[2],
        ];
        let cwd = lanes(&wxdx, cw);
        let q = lanes(&self.wx, cw);
        let mut x = [0.0f64; RUN];
        let mut u = [0.0f64; 4];
        let mut v = [0.0f64; 4];
        for l in 0..RUN {
            x[l] = wxl[l] * sum[l];
        }
        for i in 0..4 {
            for m in 0..4 {
                let l = 4 * i + m;
                u[m] = cwd[l].mul_add(sum[l], u[m]);
                v[m] = q[l].mul_add(tsum[l], v[m]);
            }
        }
        reduce(&x, &u, &v)
    }
}

/// `lanes[l] = wx[l / 5]·cw[l % 5]` over a run, lane 15 zero.
#[inline(always)]
fn lanes(wx: &[f64; 3], cw: &[f64; 5]) -> [f64; RUN] {
    let mut q = [0.0; RUN];
    for l in 0..15 {
        q[l] = wx[l / 5] * cw[l % 5];
    }
    q
}

/// The end of [`Footprint::gather`], shared by both paths: channel sums of `x`, and
/// `−4·Σ u`, `−4·Σ v` summed in a fixed order.
#[inline(always)]
fn reduce(x: &[f64; RUN], u: &[f64; 4], v: &[f64; 4]) -> ([f64; 5], [f64; 2]) {
    let mut dc = [0.0; 5];
    for k in 0..5 {
        dc[k] = (x[k] + x[5 + k]) + x[10 + k];
    }
    let gu = [
        -4.0 * ((u[0] + u[1]) + (u[2] + u[3])),
        -4.0 * ((v[0] + v[1]) + (v[2] + v[3])),
    ];
    (dc, gu)
}

/// The four vectors of a run's lane pattern: `W ⊙ P`, `W` the pixel weights `wx` spread
/// over the lanes of their pixel, `P` the five channels `cw` repeated (lane 15 zero).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
#[inline]
fn lanes_avx2(wx: &[f64; 3], cw: &[f64; 5]) -> [std::arch::x86_64::__m256d; 4] {
    use std::arch::x86_64::*;
    // SAFETY: the load reads cw[0..4].
    let c = unsafe { _mm256_loadu_pd(cw.as_ptr()) };
    let w = _mm256_set1_pd(cw[4]);
    let zero = _mm256_setzero_pd();
    let p = [
        c,
        _mm256_blend_pd::<0b0001>(_mm256_permute4x64_pd::<0x90>(c), w),
        _mm256_blend_pd::<0b0010>(_mm256_permute4x64_pd::<0x4F>(c), w),
        _mm256_blend_pd::<0b1000>(
            _mm256_blend_pd::<0b0100>(_mm256_permute4x64_pd::<0xFE>(c), w),
            zero,
        ),
    ];
    let x = _mm256_set_pd(0.0, wx[2], wx[1], wx[0]);
    let wl = [
        _mm256_permute4x64_pd::<0x00>(x),
        _mm256_permute4x64_pd::<0x54>(x),
        _mm256_permute4x64_pd::<0xA5>(x),
        _mm256_permute4x64_pd::<0xEA>(x),
    ];
    [
        _mm256_mul_pd(wl[0], p[0]),
        _mm256_mul_pd(wl[1], p[1]),
        _mm256_mul_pd(wl[2], p[2]),
        _mm256_mul_pd(wl[3], p[3]),
    ]
}

/// [`Footprint::splat`]'s runs with AVX2 and FMA.
///
/// # Safety
/// The CPU must have AVX2 and FMA; the three runs of 16 lanes from `top` lie in `flat`.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
#[inline]
unsafe fn splat_runs_avx2(
    fp: &Footprint,
    top: usize,
    size: usize,
    flat: &mut [f64],
    cw: &[f64; 5],
) {
    use std::arch::x86_64::*;
    let q = lanes_avx2(&fp.wx, cw);
    for jj in 0..3 {
        let y = _mm256_set1_pd(fp.wy[jj]);
        let start = 5 * (top + (2 - jj) * size);
        debug_assert!(start + RUN <= flat.len());
        // SAFETY: the caller guarantees the run lies in `flat`.
        unsafe {
            let ptr = flat.as_mut_ptr().add(start);
            for (i, qi) in q.iter().enumerate() {
                let at = ptr.add(4 * i);
                _mm256_storeu_pd(at, _mm256_fmadd_pd(y, *qi, _mm256_loadu_pd(at)));
            }
        }
    }
}

/// [`Footprint::gather`]'s runs with AVX2 and FMA: the same operations lane by lane.
///
/// # Safety
/// The CPU must have AVX2 and FMA; the three runs of 16 lanes from `top` lie in `flat`.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
#[inline]
unsafe fn gather_runs_avx2(
    fp: &Footprint,
    top: usize,
    size: usize,
    flat: &[f64],
    cw: &[f64; 5],
) -> ([f64; 5], [f64; 2]) {
    use std::arch::x86_64::*;
    let mut sum = [_mm256_setzero_pd(); 4];
    let mut tsum = [_mm256_setzero_pd(); 4];
    for jj in 0..3 {
        let y = _mm256_set1_pd(fp.wy[jj]);
        let ydy = _mm256_set1_pd(fp.wy[jj] * fp.dy[jj]);
        let start = 5 * (top + (2 - jj) * size);
        debug_assert!(start + RUN <= flat.len());
        for i in 0..4 {
            // SAFETY: the caller guarantees the run lies in `flat`.
            let a = unsafe { _mm256_loadu_pd(flat.as_ptr().add(start + 4 * i)) };
            sum[i] = _mm256_fmadd_pd(y, a, sum[i]);
            tsum[i] = _mm256_fmadd_pd(ydy, a, tsum[i]);
        }
    }
    let wxl = lanes_avx2(&fp.wx, &[1.0; 5]);
    let wxdx = [
        fp.wx[0] * fp.dx[0],
        fp.wx[1] * fp.dx[1],
        fp.wx[2] * fp.dx[2],
    ];
    let cwd = lanes_avx2(&wxdx, cw);
    let q = lanes_avx2(&fp.wx, cw);
    let mut x = [0.0f64; RUN];
    let mut u = _mm256_setzero_pd();
    let mut v = _mm256_setzero_pd();
    for i in 0..4 {
        // SAFETY: x has 16 lanes.
        unsafe { _mm256_storeu_pd(x.as_mut_ptr().add(4 * i), _mm256_mul_pd(wxl[i], sum[i])) };
        u = _mm256_fmadd_pd(cwd[i], sum[i], u);
        v = _mm256_fmadd_pd(q[i], tsum[i], v);
    }
    let (mut ua, mut va) = ([0.0f64; 4], [0.0f64; 4]);
    // SAFETY: four lanes each.
    unsafe {
        _mm256_storeu_pd(ua.as_mut_ptr(), u);
        _mm256_storeu_pd(va.as_mut_ptr(), v);
    }
    reduce(&x, &ua, &va)
}

/// Screen position of a state through the final transform.
#[inline(always)]
pub(super) fn to_screen(fin: &[f64; 6], s: [f64; 2], half: f64) -> [f64; 2] {
    let y = [
        fin[0] * s[0] + fin[2] * s[1] + fin[4],
        fin[1] * s[0] + fin[3] * s[1] + fin[5],
    ];
    [(y[0] + 1.0) * half, (y[1] + 1.0) * half]
}

/// `e^{−2}`: the weight factor between a footprint's centre and its neighbours.
const E_M2: f64 = 0.135_335_283_236_612_7;

/// `1.5·2⁵²`: adding it rounds a number of magnitude below 2⁵¹ to an integer, which then
/// sits in the low bits of the sum.
const ROUND: f64 = 6_755_399_441_055_744.0;
/// ln 2 in two parts (fdlibm's): `k·LN2_HI` is exact for `|k| < 2¹¹`.
const LN2_HI: f64 = f64::from_bits(0x3fe6_2e42_fee0_0000);
const LN2_LO: f64 = f64::from_bits(0x3dea_39ef_3579_3c76);

/// `e^x` for each lane, to within 3 ulp, for `−700 < x < 700` (the footprint's arguments lie
/// in `[−4.5, 0]`; nothing outside that range is checked). `x = k·ln 2 + r` with `|r| ≤
/// ln 2/2`, `e^r` by its Taylor polynomial of degree 12 (remainder < 2·10⁻¹⁶, evaluated by
/// Estrin's scheme: a short dependency chain), `2^k` put
/// into the exponent bits. No branch, no table, no call: the lanes become vector
/// instructions, and `mul_add` one fused instruction in the AVX2+FMA copies of the loops
/// (an exactly rounded routine otherwise: the same bits either way).
#[inline(always)]
pub(crate) fn exp_lanes<const N: usize>(x: [f64; N]) -> [f64; N] {
    let mut out = [0.0; N];
    for i in 0..N {
        let t = x[i].mul_add(std::f64::consts::LOG2_E, ROUND);
        let k = t - ROUND;
        let r = (-k).mul_add(LN2_LO, (-k).mul_add(LN2_HI, x[i]));
        // Estrin's scheme: four levels of fused multiply–adds instead of Horner's twelve.
        let c = &TAYLOR;
        let r2 = r * r;
        let r4 = r2 * r2;
        let r8 = r4 * r4;
        let q0 = c[3].mul_add(r, c[2]).mul_add(r2, c[1].mul_add(r, c[0]));
        let q1 = c[7].mul_add(r, c[6]).mul_add(r2, c[5].mul_add(r, c[4]));
        let q2 = c[11].mul_add(r, c[10]).mul_add(r2, c[9].mul_add(r, c[8]));
        let p = c[12].mul_add(r4, q2).mul_add(r8, q1.mul_add(r4, q0));
        let ki = (t.to_bits() as i64).wrapping_sub(ROUND.to_bits() as i64);
        let scale = f64::from_bits((ki.wrapping_add(1023) as u64) << 52);
        out[i] = p * scale;
    }
    out
}

/// `1/n!` for `n = 0..=12`.
const TAYLOR: [f64; 13] = [
    1.0,
    1.0,
    1.0 / 2.0,
    1.0 / 6.0,
    1.0 / 24.0,
    1.0 / 120.0,
    1.0 / 720.0,
    1.0 / 5040.0,
    1.0 / 40_320.0,
    1.0 / 362_880.0,
    1.0 / 3_628_800.0,
    1.0 / 39_916_800.0,
    1.0 / 479_001_600.0,
];

/// [`exp_lanes`] on four lanes with AVX2 and FMA instructions.
///
/// # Safety
/// The CPU must have AVX2 and FMA.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
#[inline]
pub(crate) unsafe fn exp4_lanes_avx2(x: [f64; 4]) -> [f64; 4] {
    use std::arch::x86_64::*;
    // SAFETY: the load and store are unaligned ones from and into arrays of four f64.
    unsafe {
        let v = exp4_avx2(_mm256_loadu_pd(x.as_ptr()));
        let mut out = [0.0; 4];
        _mm256_storeu_pd(out.as_mut_ptr(), v);
        out
    }
}

/// Four lanes of [`exp_lanes`].
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
#[inline]
fn exp4_avx2(v: std::arch::x86_64::__m256d) -> std::arch::x86_64::__m256d {
    use std::arch::x86_64::*;
    let round = _mm256_set1_pd(ROUND);
    let t = _mm256_fmadd_pd(v, _mm256_set1_pd(std::f64::consts::LOG2_E), round);
    let k = _mm256_sub_pd(t, round);
    let r = _mm256_fnmadd_pd(
        k,
        _mm256_set1_pd(LN2_LO),
        _mm256_fnmadd_pd(k, _mm256_set1_pd(LN2_HI), v),
    );
    let c = |i: usize| _mm256_set1_pd(TAYLOR[i]);
    let fma = |a, b, c| _mm256_fmadd_pd(a, b, c);
    let r2 = _mm256_mul_pd(r, r);
    let r4 = _mm256_mul_pd(r2, r2);
    let r8 = _mm256_mul_pd(r4, r4);
    let q0 = fma(fma(c(3), r, c(2)), r2, fma(c(1), r, c(0)));
    let q1 = fma(fma(c(7), r, c(6)), r2, fma(c(5), r, c(4)));
    let q2 = fma(fma(c(11), r, c(10)), r2, fma(c(9), r, c(8)));
    let p = fma(fma(c(12), r4, q2), r8, fma(q1, r4, q0));
    let bias = _mm256_set1_epi64x(1023 - ROUND.to_bits() as i64);
    let e = _mm256_slli_epi64::<52>(_mm256_add_epi64(_mm256_castpd_si256(t), bias));
    _mm256_mul_pd(p, _mm256_castsi256_pd(e))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::isa::PortableIsa;

    #[test]
    fn footprint_centre_is_the_nearest_pixel() {
        for u in [-1.4, -0.6, -0.4, 0.0, 0.49, 0.51, 7.3, 99.5] {
            let fp = footprint(PortableIsa, [u, u], 200).unwrap();
            assert_eq!(fp.cx as f64, (u + 0.5).floor(), "u = {u}");
            for k in 0..3 {
                let d = u - (fp.cx + k as i64 - 1) as f64;
                assert_eq!(fp.dx[k], d);
                assert!((fp.wx[k] - (-2.0 * d * d).exp()).abs() < 1e-15, "u = {u}");
                assert_eq!(fp.wy[k], fp.wx[k]);
            }
        }
    }

    #[test]
    fn exp_lanes_matches_libm_within_three_ulp() {
        let mut worst = 0.0f64;
        for i in 0..=200_000 {
            let x = -50.0 + 60.0 * i as f64 / 200_000.0;
            let got = exp_lanes([x, -x, x / 7.0, 0.0])[..3].to_vec();
            for (g, x) in got.iter().zip([x, -x, x / 7.0]) {
                let want = x.exp();
                let ulp = (g - want).abs() / (want * f64::EPSILON);
                worst = worst.max(ulp);
            }
        }
        assert!(worst <= 3.0, "worst error {worst} ulp");
        assert_eq!(exp_lanes([0.0])[0], 1.0);
    }

    /// `Σ_cells wx·wy·v` the plain way.
    fn naive(fp: &Footprint, size: usize, mut f: impl FnMut(usize, f64, f64, f64)) {
        fp.cells(size, |ii, jj, px| {
            f(px, fp.wx[ii] * fp.wy[jj], fp.dx[ii], fp.dy[jj])
        });
    }

    #[test]
    fn splat_and_gather_match_the_cell_by_cell_formulas() {
        let size = 9;
        let adj: Vec<[f64; 5]> = (0..size * size)
            .map(|i| std::array::from_fn(|k| ((i * 5 + k) * 7919 % 103) as f64 / 50.0 - 1.0))
            .collect();
        let cw = [0.3, -0.7, 1.1, 0.4, 2.5];
        // Inside, on the last column, across every border, half off the image.
        for u in [
            [4.2, 3.7],
            [7.6, 4.4],
            [0.3, 0.2],
            [8.8, 8.9],
            [-1.2, 4.0],
            [4.0, 9.6],
        ] {
            let fp = footprint(PortableIsa, u, size).unwrap();
            let mut buf = vec![[0.0; 5]; size * size];
            fp.splat(PortableIsa, size, &mut buf, &cw);
            let mut want = vec![[0.0; 5]; size * size];
            let (mut sums, mut gu) = ([0.0; 5], [0.0; 2]);
            naive(&fp, size, |px, wt, dx, dy| {
                let mut val = 0.0;
                for k in 0..5 {
                    want[px][k] += wt * cw[k];
                    sums[k] += wt * adj[px][k];
                    val += adj[px][k] * cw[k];
                }
                gu[0] += -4.0 * dx * wt * val;
                gu[1] += -4.0 * dy * wt * val;
            });
            for (b, w) in buf.iter().zip(&want) {
                for k in 0..5 {
                    assert!((b[k] - w[k]).abs() < 1e-14, "splat at {u:?}");
                }
            }
            let (s, g) = fp.gather(PortableIsa, size, &adj, &cw);
            for k in 0..5 {
                assert!((s[k] - sums[k]).abs() < 1e-13, "gather at {u:?}");
            }
            for a in 0..2 {
                assert!((g[a] - gu[a]).abs() < 1e-12, "position gradient at {u:?}");
            }
        }
    }

    #[test]
    #[cfg(target_arch = "x86_64")]
    fn avx2_exponential_gives_the_portable_bits() {
        // On a CPU without AVX2+FMA only the portable half can be checked (against libm);
        // with them, the vector path must give the portable bits.
        let avx = crate::isa::FmaIsa::detect();
        for i in 0..40_000 {
            let x: [f64; 4] = std::array::from_fn(|k| -9.0 + (i * 4 + k) as f64 * 7.3e-5);
            let portable = exp_lanes(x);
            for (p, x) in portable.iter().zip(x) {
                assert!((p - x.exp()).abs() <= 3.0 * f64::EPSILON * x.exp(), "{x}");
            }
            if let Some(isa) = avx {
                // SAFETY: the CPU has AVX2 and FMA (checked above).
                let v = unsafe { exp4_lanes_avx2(x) };
                assert_eq!(v.map(f64::to_bits), portable.map(f64::to_bits), "{x:?}");
                assert!(footprint(isa, [x[0] + 50.0, x[1] + 50.0], 100).is_some());
            }
        }
    }
}
