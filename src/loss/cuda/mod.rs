//! MS-MSE and D-SSIM on an NVIDIA GPU (the `cuda` feature): value and gradient of the image
//! terms the inversion uses without LPIPS, on an image that is already on the GPU (the
//! splat's, in `render::splat::iteration`) or, for checks, on two host images
//! ([`GpuLoss::value_and_grad`]).
//!
//! The definitions are the CPU's ([`MsMse`], [`DSsim`]: the same pyramid with its partial
//! border blocks, the same zero-padded 11-tap window, constants and weights), and so is the
//! arithmetic: every per-pixel quantity is computed with the CPU's operations in the CPU's
//! order, and the kernels ([`SOURCE`], `loss.cu`) are compiled without fused multiply-adds,
//! so the per-pixel gradients are the CPU's bit for bit. The sums over pixels are f64 in a
//! fixed tree (deterministic: the same image gives the same bits on every run), in another
//! order than the CPU's, so values agree to f64 rounding.
//!
//! Per evaluation at 1024²: MS-MSE is a difference, ten 2×2 poolings, one reduction over the
//! pyramid and one gradient kernel (each pixel walks up its ancestors); D-SSIM is a
//! horizontal and a vertical blur of the five moments with the per-pixel SSIM and its
//! derivatives, a reduction, and a horizontal and a vertical blur of the three derivative
//! maps with the gradient. Only the sums (one f64 per pyramid level, one for SSIM) come back.

use std::collections::HashMap;
use std::sync::{Arc, OnceLock};

use cudarc::driver::{
    CudaFunction, CudaSlice, CudaStream, DeviceRepr, LaunchConfig, PushKernelArg,
};
use cudarc::nvrtc::{CompileOptions, compile_ptx_with_opts};

use crate::error::{Error, Result};
use crate::loss::{DSsim, MsMse, Real, check_pair, cst, f64_of};
use crate::render::splat::cuda::{self as gpu, GpuScalar, Marks, mark};

/// The kernels' CUDA C++ source.
pub const SOURCE: &str = include_str!("loss.cu");

/// NVRTC options besides the architecture: no contraction into fused multiply-adds, so the
/// per-pixel arithmetic is the CPU's.
const OPTIONS: [&str; 1] = ["--fmad=false"];

const BLOCK: u32 = 256;
/// `MAX_LEVELS` in `loss.cu`.
const MAX_LEVELS: usize = 32;
/// `MAX_WINDOW` in `loss.cu`.
const MAX_WINDOW: usize = 63;

/// `Segments` in `loss.cu`.
#[repr(C)]
#[derive(Clone, Copy)]
struct Segments {
    off: [i64; MAX_LEVELS + 1],
    count: i32,
}

/// `Levels` in `loss.cu`.
#[repr(C)]
#[derive(Clone, Copy)]
struct Levels {
    off: [i64; MAX_LEVELS + 1],
    w: [i32; MAX_LEVELS],
    h: [i32; MAX_LEVELS],
    c: [f64; MAX_LEVELS],
    count: i32,
}

/// `Window` in `loss.cu`.
#[repr(C)]
#[derive(Clone, Copy)]
struct Window {
    k: [f64; MAX_WINDOW],
    len: i32,
}

// SAFETY: plain `#[repr(C)]` data laid out as the structs of the same names in `loss.cu`
// (passed to kernels by value).
unsafe impl DeviceRepr for Segments {}
// SAFETY: as above.
unsafe impl DeviceRepr for Levels {}
// SAFETY: as above.
unsafe impl DeviceRepr for Window {}

struct Kernels {
    functions: HashMap<String, CudaFunction>,
}

static KERNELS: OnceLock<std::result::Result<Kernels, String>> = OnceLock::new();

fn kernels() -> Result<&'static Kernels> {
    KERNELS
        .get_or_init(|| {
            let (stream, capability) = gpu::device().map_err(|e| e.to_string())?;
            let mut options = vec![format!(
                "--gpu-architecture=compute_{}{}",
                capability.0, capability.1
            )];
            options.extend(OPTIONS.iter().map(|o| o.to_string()));
            let opts = CompileOptions {
                options,
                name: Some("ifslab_loss.cu".into()),
                ..Default::default()
            };
            let ptx = compile_ptx_with_opts(SOURCE, opts)
                .map_err(|e| format!("NVRTC could not compile the loss kernels: {e:?}"))?;
            let module = stream
                .context()
                .load_module(ptx)
                .map_err(|e| format!("the driver could not load the loss kernels: {e}"))?;
            let mut functions = HashMap::new();
            let mut names = vec!["reduce_finish".to_string()];
            for k in [
                "loss_diff",
                "loss_down",
                "loss_partials",
                "msmse_grad",
                "ssim_h5",
                "ssim_v5",
                "ssim_h3",
                "ssim_v3",
            ] {
                names.push(format!("{k}_f32"));
                names.push(format!("{k}_f64"));
            }
            for name in names {
                let f = module
                    .load_function(&name)
                    .map_err(|e| format!("kernel {name} is missing: {e}"))?;
                functions.insert(name, f);
            }
            Ok(Kernels { functions })
        })
        .as_ref()
        .map_err(|e| Error::Device(e.clone()))
}

impl Kernels {
    fn get<T: GpuScalar>(&self, name: &str) -> &CudaFunction {
        &self.functions[&format!("{name}_{}", T::SUFFIX)]
    }
}

/// Compiles the loss kernels with NVRTC for `arch` (e.g. `"compute_90"`) without a GPU, as
/// `splat::cuda::compile_only` does for the splat's. Returns the PTX's length.
pub fn compile_only(arch: &str) -> Result<usize> {
    // SAFETY: the probe opens the library with `dlopen` and closes it again.
    if !unsafe { cudarc::nvrtc::sys::is_culib_present() } {
        return Err(Error::Device("libnvrtc.so.13 was not found".into()));
    }
    let mut options = vec![format!("--gpu-architecture={arch}")];
    options.extend(OPTIONS.iter().map(|o| o.to_string()));
    let opts = CompileOptions {
        options,
        ..Default::default()
    };
    compile_ptx_with_opts(SOURCE, opts)
        .map(|p| p.to_src().len())
        .map_err(|e| Error::Device(format!("NVRTC: {e:?}")))
}

/// The image terms computed on the GPU, each with its weight in the objective; a term whose
/// weight is 0 is not computed.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GpuLoss {
    /// The multi-scale MSE's pyramid and reduction.
    pub msmse: MsMse,
    /// Its weight.
    pub msmse_weight: f64,
    /// The D-SSIM window.
    pub dssim: DSsim,
    /// Its weight.
    pub dssim_weight: f64,
}

/// What [`GpuLoss`] computes: each term's unweighted value (`None`: weight 0) and the
/// weighted total. Values are rounded to the image's precision, as the candle route's
/// scalar tensors are.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct GpuLossValue {
    /// Multi-scale MSE.
    pub msmse: Option<f64>,
    /// 1 − SSIM.
    pub dssim: Option<f64>,
    /// `msmse_weight·msmse + dssim_weight·dssim`.
    pub total: f64,
}

fn launch_1d(n: usize) -> LaunchConfig {
    LaunchConfig {
        grid_dim: ((n as u64).div_ceil(BLOCK as u64).max(1) as u32, 1, 1),
        block_dim: (BLOCK, 1, 1),
        shared_mem_bytes: 0,
    }
}

/// Blocks per segment of a reduction over segments of at most `longest` values: a fixed
/// function of the sizes, so the reduction's order is too.
fn reduce_blocks(longest: usize) -> u32 {
    (longest as u64).div_ceil(BLOCK as u64 * 8).clamp(1, 256) as u32
}

impl GpuLoss {
    /// The MS-MSE alone (weight 1), as the annealing candidates are scored.
    pub fn msmse_only(msmse: MsMse) -> Self {
        GpuLoss {
            msmse,
            msmse_weight: 1.0,
            dssim: DSsim::default(),
            dssim_weight: 0.0,
        }
    }

    /// Refuses what the kernels do not cover (a window over 63 pixels), naming the field.
    pub fn check(&self) -> Result<()> {
        if self.dssim_weight > 0.0 {
            self.dssim.kernel()?;
            if self.dssim.window > MAX_WINDOW {
                return Err(Error::param(
                    "window",
                    format!(
                        "the GPU's SSIM window is at most {MAX_WINDOW} pixels, got {}",
                        self.dssim.window
                    ),
                ));
            }
        }
        if self.msmse.levels >= MAX_LEVELS {
            return Err(Error::param(
                "msmse_levels",
                format!(
                    "the GPU's MS-MSE takes at most {} levels, got {}",
                    MAX_LEVELS - 1,
                    self.msmse.levels
                ),
            ));
        }
        Ok(())
    }

    /// The value and `∂total/∂pred` for two row-major `width × height` host images: both
    /// go up, the gradient comes down. For checks against the CPU loss; the inversion keeps
    /// its image on the GPU (`render::splat::iteration`).
    pub fn value_and_grad<T: Real + GpuScalar>(
        &self,
        pred: &[T],
        target: &[T],
        width: usize,
        height: usize,
    ) -> Result<(GpuLossValue, Vec<T>)> {
        let (v, g) = self.on_host(pred, target, width, height, true)?;
        Ok((v, g.unwrap_or_default()))
    }

    /// The value alone for two host images.
    pub fn value<T: Real + GpuScalar>(
        &self,
        pred: &[T],
        target: &[T],
        width: usize,
        height: usize,
    ) -> Result<GpuLossValue> {
        Ok(self.on_host(pred, target, width, height, false)?.0)
    }

    fn on_host<T: Real + GpuScalar>(
        &self,
        pred: &[T],
        target: &[T],
        width: usize,
        height: usize,
        grad: bool,
    ) -> Result<(GpuLossValue, Option<Vec<T>>)> {
        check_pair(pred, target, width, height)?;
        let (st, _) = gpu::device()?;
        gpu::bind(st)?;
        let up = |v: &[T]| st.clone_htod(v).map_err(gpu::driver("uploading an image"));
        let (p, t) = (up(pred)?, up(target)?);
        let (value, g) = self.on_device(st, &p, &t, width, height, grad, &mut None)?;
        let g = match g {
            Some(g) => Some(
                st.clone_dtoh(&g)
                    .map_err(gpu::driver("downloading the gradient"))?,
            ),
            None => None,
        };
        st.synchronize().map_err(gpu::driver("synchronising"))?;
        Ok((value, g))
    }

    /// The value and, when `grad`, `∂total/∂pred` (weighted) of `pred` against `target`,
    /// both `width × height` on the GPU, on `st`. Returns once the value is on the host; the
    /// gradient is left on the GPU.
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn on_device<T: Real + GpuScalar>(
        &self,
        st: &Arc<CudaStream>,
        pred: &CudaSlice<T>,
        target: &CudaSlice<T>,
        width: usize,
        height: usize,
        grad: bool,
        marks: &mut Marks,
    ) -> Result<(GpuLossValue, Option<CudaSlice<T>>)> {
        self.check()?;
        let n = width
            .checked_mul(height)
            .filter(|&n| n > 0 && n < i32::MAX as usize)
            .ok_or_else(|| {
                Error::Shape(format!(
                    "the GPU loss takes 1 to 2^31 pixels, got {width}×{height}"
                ))
            })?;
        if pred.len() != n || target.len() != n {
            return Err(Error::Shape(format!(
                "prediction has {} and target {} values; a {width}×{height} image has {n}",
                pred.len(),
                target.len()
            )));
        }
        let k = kernels()?;
        let err = gpu::driver;
        let (w, h) = (width as i32, height as i32);
        let do_msmse = self.msmse_weight > 0.0;
        let do_dssim = self.dssim_weight > 0.0;
        let sizes = self.msmse.level_sizes(width, height);
        let levels = if do_msmse { sizes.len() } else { 0 };
        // One f64 per pyramid level, then SSIM's sum.
        let mut sums = st
            .alloc_zeros::<f64>(levels + 1)
            .map_err(err("allocating the loss sums"))?;
        let mut g = if grad {
            Some(
                st.alloc_zeros::<T>(n)
                    .map_err(err("allocating the image gradient"))?,
            )
        } else {
            None
        };
        if do_msmse {
            let weight = self.msmse_weight_per_level(levels);
            let mut lv = Levels {
                off: [0; MAX_LEVELS + 1],
                w: [0; MAX_LEVELS],
                h: [0; MAX_LEVELS],
                c: [0.0; MAX_LEVELS],
                count: levels as i32,
            };
            for (l, &(lw, lh)) in sizes.iter().enumerate() {
                lv.off[l + 1] = lv.off[l] + (lw * lh) as i64;
                lv.w[l] = lw as i32;
                lv.h[l] = lh as i32;
                // msmse.rs: c_l = 2·w_l/N_l, in f64, rounded to T in the kernel.
                lv.c[l] = 2.0 * weight / (lw * lh) as f64;
            }
            let total = lv.off[levels] as usize;
            let mut pyr = st
                .alloc_zeros::<T>(total)
                .map_err(err("allocating the MS-MSE pyramid"))?;
            let n64 = n as i64;
            let mut b = st.launch_builder(k.get::<T>("loss_diff"));
            b.arg(pred).arg(target).arg(&mut pyr).arg(&n64);
            // SAFETY: `loss_diff(p, t, d, n)`: three buffers of at least n values.
            unsafe { b.launch(launch_1d(n)) }.map_err(err("launching loss_diff"))?;
            for l in 1..levels {
                let (pw, ph) = sizes[l - 1];
                let (src, dst) = (lv.off[l - 1] as usize, lv.off[l] as usize);
                let (lo, mut hi) = pyr.split_at_mut(dst);
                let src_view = lo.slice(src..);
                let (pw, ph) = (pw as i32, ph as i32);
                let mut b = st.launch_builder(k.get::<T>("loss_down"));
                b.arg(&src_view).arg(&mut hi).arg(&pw).arg(&ph);
                let (cw, ch) = sizes[l];
                // SAFETY: `loss_down(src, dst, w, h)`: `src` holds level l − 1 (pw·ph values),
                // `dst` level l (⌈pw/2⌉·⌈ph/2⌉) onwards.
                unsafe { b.launch(launch_1d(cw * ch)) }.map_err(err("launching loss_down"))?;
            }
            let seg = Segments {
                off: lv.off,
                count: levels as i32,
            };
            self.reduce(st, k, &pyr, seg, n, true, &mut sums, 0)?;
            if let Some(g) = g.as_mut() {
                let wt = cst::<T>(self.msmse_weight);
                let acc = 0i32;
                let mut b = st.launch_builder(k.get::<T>("msmse_grad"));
                b.arg(&pyr).arg(&lv).arg(&wt).arg(&acc).arg(g);
                // SAFETY: `msmse_grad(pyr, lv, weight, accumulate, grad)`: `pyr` laid out as
                // `lv` says, `grad` n values.
                unsafe { b.launch(launch_1d(n)) }.map_err(err("launching msmse_grad"))?;
            }
            mark(st, marks, "loss: MS-MSE")?;
        }
        if do_dssim {
            let kern = self.dssim.kernel()?;
            let mut win = Window {
                k: [0.0; MAX_WINDOW],
                len: kern.len() as i32,
            };
            win.k[..kern.len()].copy_from_slice(&kern);
            let mut tmp = st
                .alloc_zeros::<T>(5 * n)
                .map_err(err("allocating the SSIM moments"))?;
            let mut smap = st
                .alloc_zeros::<T>(n)
                .map_err(err("allocating the SSIM map"))?;
            let mut deriv = st
                .alloc_zeros::<T>(3 * n)
                .map_err(err("allocating the SSIM derivatives"))?;
            let mut b = st.launch_builder(k.get::<T>("ssim_h5"));
            b.arg(pred)
                .arg(target)
                .arg(&mut tmp)
                .arg(&w)
                .arg(&h)
                .arg(&win);
            // SAFETY: `ssim_h5(x, y, tmp, w, h, win)`: images of n values, `tmp` 5n.
            unsafe { b.launch(launch_1d(n)) }.map_err(err("launching ssim_h5"))?;
            let mut b = st.launch_builder(k.get::<T>("ssim_v5"));
            b.arg(&tmp)
                .arg(&mut smap)
                .arg(&mut deriv)
                .arg(&w)
                .arg(&h)
                .arg(&win);
            // SAFETY: `ssim_v5(tmp, smap, deriv, w, h, win)`: 5n, n and 3n values.
            unsafe { b.launch(launch_1d(n)) }.map_err(err("launching ssim_v5"))?;
            let mut seg = Segments {
                off: [0; MAX_LEVELS + 1],
                count: 1,
            };
            seg.off[1] = n as i64;
            self.reduce(st, k, &smap, seg, n, false, &mut sums, levels)?;
            if let Some(g) = g.as_mut() {
                let mut b = st.launch_builder(k.get::<T>("ssim_h3"));
                b.arg(&deriv).arg(&mut tmp).arg(&w).arg(&h).arg(&win);
                // SAFETY: `ssim_h3(deriv, tmp, w, h, win)`: 3n values each (tmp holds 5n).
                unsafe { b.launch(launch_1d(n)) }.map_err(err("launching ssim_h3"))?;
                let scale = -1.0 / n as f64;
                let wt = cst::<T>(self.dssim_weight);
                let acc = i32::from(do_msmse);
                let mut b = st.launch_builder(k.get::<T>("ssim_v3"));
                b.arg(&tmp)
                    .arg(pred)
                    .arg(target)
                    .arg(&w)
                    .arg(&h)
                    .arg(&win)
                    .arg(&scale)
                    .arg(&wt)
                    .arg(&acc)
                    .arg(g);
                // SAFETY: `ssim_v3(tmp, x, y, w, h, win, scale, weight, accumulate, grad)`:
                // `tmp` 3n values, the images and `grad` n.
                unsafe { b.launch(launch_1d(n)) }.map_err(err("launching ssim_v3"))?;
            }
            mark(st, marks, "loss: D-SSIM")?;
        }
        let host = st
            .clone_dtoh(&sums)
            .map_err(err("downloading the loss sums"))?;
        mark(st, marks, "loss: download the sums")?;
        // As the CPU and the candle route combine them: each term's value rounded to T, the
        // total summed in f64 in term order.
        let round = |v: f64| f64_of(cst::<T>(v));
        let mut value = GpuLossValue::default();
        if do_msmse {
            let weight = self.msmse_weight_per_level(levels);
            let v: f64 = sizes
                .iter()
                .zip(&host)
                .map(|(&(lw, lh), &s)| weight * s / (lw * lh) as f64)
                .sum();
            let v = round(v);
            value.msmse = Some(v);
            value.total += self.msmse_weight * v;
        }
        if do_dssim {
            let v = round(1.0 - host[levels] / n as f64);
            value.dssim = Some(v);
            value.total += self.dssim_weight * v;
        }
        Ok((value, g))
    }

    /// The per-level weight `w_l` of the MS-MSE reduction (msmse.rs `level_weight`).
    fn msmse_weight_per_level(&self, n_levels: usize) -> f64 {
        match self.msmse.reduction {
            crate::loss::MsMseReduction::Sum => 1.0,
            crate::loss::MsMseReduction::Mean => 1.0 / n_levels as f64,
        }
    }

    /// `sums[at + s] = Σ f64(v)` (or `f64(v·v)`, `square`) over each segment `s` of `v`
    /// (each at most `longest` values), in a fixed order.
    #[allow(clippy::too_many_arguments)]
    fn reduce<T: GpuScalar>(
        &self,
        st: &Arc<CudaStream>,
        k: &Kernels,
        v: &CudaSlice<T>,
        seg: Segments,
        longest: usize,
        square: bool,
        sums: &mut CudaSlice<f64>,
        at: usize,
    ) -> Result<()> {
        let err = gpu::driver;
        let nb = reduce_blocks(longest);
        let count = seg.count as u32;
        let mut partials = st
            .alloc_zeros::<f64>(nb as usize * count as usize)
            .map_err(err("allocating partial sums"))?;
        let sq = i32::from(square);
        let mut b = st.launch_builder(k.get::<T>("loss_partials"));
        b.arg(v).arg(&seg).arg(&sq).arg(&mut partials);
        let cfg = LaunchConfig {
            grid_dim: (nb, count, 1),
            block_dim: (BLOCK, 1, 1),
            shared_mem_bytes: 0,
        };
        // SAFETY: `loss_partials(v, seg, square, partials)`: `seg` lies inside `v`,
        // `partials` holds nb·count values.
        unsafe { b.launch(cfg) }.map_err(err("launching loss_partials"))?;
        let nb32 = nb as i32;
        let mut out = sums.slice_mut(at..at + count as usize);
        let mut b = st.launch_builder(&k.functions["reduce_finish"]);
        b.arg(&partials).arg(&nb32).arg(&mut out);
        let cfg = LaunchConfig {
            grid_dim: (count, 1, 1),
            block_dim: (BLOCK, 1, 1),
            shared_mem_bytes: 0,
        };
        // SAFETY: `reduce_finish(partials, nb, sums)`: count blocks, count sums.
        unsafe { b.launch(cfg) }.map_err(err("launching reduce_finish"))?;
        Ok(())
    }
}
