//! The image losses as candle operations, so they compose as tensors.
//!
//! [`LossOp`] wraps any [`ImageLoss`] as a candle [`CustomOp2`] `(pred, target) → scalar`:
//! `cpu_fwd` runs the hand-written loss on the tensors' storage (F32 or F64) and, when the
//! prediction takes part in autograd, also keeps the gradient it computed on the way, so
//! `bwd` is a multiplication by the incoming scalar gradient. The target is a constant
//! (`bwd` returns no gradient for it). [`apply_loss`] is the checked entry point:
//!
//! ```
//! use candle_core::{Device, Tensor, Var};
//! use ifslab::loss::{DSsim, MsMse, apply_loss};
//!
//! let dev = Device::Cpu;
//! let target = Tensor::rand(0f32, 1f32, (24, 20), &dev)?;
//! let pred = Var::rand(0f32, 1f32, (24, 20), &dev)?;
//! let total = ((apply_loss(MsMse::default(), pred.as_tensor(), &target)? * 10.0)?
//!     + apply_loss(DSsim::default(), pred.as_tensor(), &target)?)?;
//! let grads = total.backward()?;
//! assert_eq!(grads.get(pred.as_tensor()).unwrap().dims(), &[24, 20]);
//! # Ok::<(), ifslab::Error>(())
//! ```
//!
//! Images are `(H, W)` tensors (leading dimensions of size 1 are accepted), row 0 at the top.
//! [`Downsample2x`] exposes the mip pyramid's 2×2 average pooling as a differentiable
//! [`CustomOp1`] (used to evaluate LPIPS at a coarser level).
//!
//! ## References
//! - candle's custom-op API (`candle_core::CustomOp1`, `CustomOp2`), huggingface/candle.

use std::sync::Mutex;

use candle_core::backend::BackendStorage;
use candle_core::{CpuStorage, CustomOp1, CustomOp2, DType, Layout, Shape, Tensor};

use crate::error::{Error, Result};
use crate::loss::msmse::{downsample2x, downsample2x_adjoint};
use crate::loss::{ImageLoss, Real};

/// A gradient kept from the forward pass.
enum Cached {
    F32(Vec<f32>),
    F64(Vec<f64>),
}

/// An [`ImageLoss`] as a candle [`CustomOp2`] `(pred, target) → scalar` (see the module docs).
pub struct LossOp<L> {
    loss: L,
    keep_grad: bool,
    cache: Mutex<Option<Cached>>,
}

impl<L: ImageLoss> LossOp<L> {
    /// The op; `keep_grad` computes the gradient during the forward pass for `bwd`.
    pub fn new(loss: L, keep_grad: bool) -> Self {
        LossOp {
            loss,
            keep_grad,
            cache: Mutex::new(None),
        }
    }

    fn store(&self, c: Cached) {
        *self.cache.lock().unwrap_or_else(|e| e.into_inner()) = Some(c);
    }
}

/// `(channels, height, width)` of an image tensor: `(H, W)` is one channel, `(C, H, W)` holds
/// `C` planes one after the other (channel-major, as candle stores images); leading dimensions
/// of size 1 are allowed. A loss on a `C`-channel image is the mean of its per-channel values
/// (see [`LossOp`]).
pub fn image_chw(dims: &[usize]) -> std::result::Result<(usize, usize, usize), String> {
    match dims {
        [h, w] => Ok((1, *h, *w)),
        [lead @ .., c, h, w] if *c > 0 && lead.iter().all(|&d| d == 1) => Ok((*c, *h, *w)),
        _ => Err(format!(
            "expected an image tensor of shape (H, W) or (C, H, W), C ≥ 1 (leading dimensions of size 1 \
             allowed), got {dims:?}"
        )),
    }
}

/// The loss of a `c`-plane image pair: per plane, then the mean over planes (the gradient
/// scaled by `1/c`). One plane is the loss itself, bit for bit (the grey fast path).
fn planes<L: ImageLoss, T: Real>(
    loss: &L,
    (a, b): (&[T], &[T]),
    (c, h, w): (usize, usize, usize),
    grad: bool,
) -> Result<(T, Option<Vec<T>>)> {
    let n = h * w;
    if c == 1 || n == 0 {
        return Ok(if grad {
            let (v, g) = loss.value_and_grad(a, b, w, h)?;
            (v, Some(g))
        } else {
            (loss.value(a, b, w, h)?, None)
        });
    }
    let inv = crate::loss::cst::<T>(1.0 / c as f64);
    let mut total = T::zero();
    let mut g_all = grad.then(|| Vec::with_capacity(c * n));
    for (pa, pb) in a.chunks_exact(n).zip(b.chunks_exact(n)) {
        match g_all.as_mut() {
            Some(g_all) => {
                let (v, g) = loss.value_and_grad(pa, pb, w, h)?;
                total = total + v;
                g_all.extend(g.into_iter().map(|x| x * inv));
            }
            None => total = total + loss.value(pa, pb, w, h)?,
        }
    }
    Ok((total * inv, g_all))
}

/// The contiguous data of one operand.
fn slice<'a, T: candle_core::WithDType>(
    s: &'a [T],
    l: &Layout,
    what: &str,
) -> candle_core::Result<&'a [T]> {
    match l.contiguous_offsets() {
        Some((a, b)) => Ok(&s[a..b]),
        None => candle_core::bail!("{what} must be contiguous; call .contiguous() first"),
    }
}

fn to_candle(e: Error) -> candle_core::Error {
    candle_core::Error::wrap(e)
}

impl<L: ImageLoss + 'static> CustomOp2 for LossOp<L> {
    fn name(&self) -> &'static str {
        self.loss.name()
    }

    fn cpu_fwd(
        &self,
        s1: &CpuStorage,
        l1: &Layout,
        s2: &CpuStorage,
        l2: &Layout,
    ) -> candle_core::Result<(CpuStorage, Shape)> {
        let chw = image_chw(l1.dims()).map_err(candle_core::Error::Msg)?;
        if l1.dims() != l2.dims() {
            candle_core::bail!(
                "{}: prediction {:?} and target {:?} differ in shape",
                self.name(),
                l1.dims(),
                l2.dims()
            );
        }
        let out = match (s1, s2) {
            (CpuStorage::F32(a), CpuStorage::F32(b)) => {
                let ab = (slice(a, l1, "pred")?, slice(b, l2, "target")?);
                let (v, g) = planes(&self.loss, ab, chw, self.keep_grad).map_err(to_candle)?;
                if let Some(g) = g {
                    self.store(Cached::F32(g));
                }
                CpuStorage::F32(vec![v])
            }
            (CpuStorage::F64(a), CpuStorage::F64(b)) => {
                let ab = (slice(a, l1, "pred")?, slice(b, l2, "target")?);
                let (v, g) = planes(&self.loss, ab, chw, self.keep_grad).map_err(to_candle)?;
                if let Some(g) = g {
                    self.store(Cached::F64(g));
                }
                CpuStorage::F64(vec![v])
            }
            _ => candle_core::bail!(
                "{}: needs two f32 or two f64 tensors, got {:?} and {:?}",
                self.name(),
                s1.dtype(),
                s2.dtype()
            ),
        };
        Ok((out, Shape::from(())))
    }

    fn bwd(
        &self,
        arg1: &Tensor,
        arg2: &Tensor,
        _res: &Tensor,
        grad_res: &Tensor,
    ) -> candle_core::Result<(Option<Tensor>, Option<Tensor>)> {
        let chw = image_chw(arg1.dims()).map_err(candle_core::Error::Msg)?;
        // The kept gradient is handed over, not copied; a second backward pass through the
        // same graph (or an op built with keep_grad = false) recomputes it.
        let cached = self.cache.lock().unwrap_or_else(|e| e.into_inner()).take();
        let cached = match cached {
            Some(c) => c,
            None => match arg1.dtype() {
                DType::F32 => {
                    let (a, b) = (flat::<f32>(arg1)?, flat::<f32>(arg2)?);
                    let (_, g) = planes(&self.loss, (&a, &b), chw, true).map_err(to_candle)?;
                    Cached::F32(g.unwrap_or_default())
                }
                DType::F64 => {
                    let (a, b) = (flat::<f64>(arg1)?, flat::<f64>(arg2)?);
                    let (_, g) = planes(&self.loss, (&a, &b), chw, true).map_err(to_candle)?;
                    Cached::F64(g.unwrap_or_default())
                }
                d => candle_core::bail!("{}: unsupported dtype {d:?}", self.name()),
            },
        };
        let g = match cached {
            Cached::F32(g) => Tensor::from_vec(g, arg1.shape(), arg1.device())?,
            Cached::F64(g) => Tensor::from_vec(g, arg1.shape(), arg1.device())?,
        };
        Ok((Some(g.broadcast_mul(grad_res)?), None))
    }
}

fn flat<T: candle_core::WithDType>(t: &Tensor) -> candle_core::Result<Vec<T>> {
    t.flatten_all()?.to_vec1::<T>()
}

/// `loss(pred, target)` as a scalar tensor of `pred`'s dtype, differentiable with respect
/// to `pred` (the target is a constant).
///
/// Both tensors must be `(H, W)` or `(C, H, W)` images (leading dimensions of size 1
/// allowed) of the same shape and dtype (`f32` or `f64`) on the CPU; a `C`-channel loss is
/// the mean of the per-channel losses. When `pred` does not take part in autograd
/// the gradient is not computed at all.
pub fn apply_loss<L: ImageLoss + 'static>(
    loss: L,
    pred: &Tensor,
    target: &Tensor,
) -> Result<Tensor> {
    image_chw(pred.dims()).map_err(Error::Shape)?;
    if pred.dims() != target.dims() {
        return Err(Error::Shape(format!(
            "{}: prediction {:?} and target {:?} differ in shape",
            loss.name(),
            pred.dims(),
            target.dims()
        )));
    }
    if pred.dtype() != target.dtype() {
        return Err(Error::Shape(format!(
            "{}: prediction is {:?} but target is {:?}; convert one with .to_dtype()",
            loss.name(),
            pred.dtype(),
            target.dtype()
        )));
    }
    let (pred, target) = (pred.contiguous()?, target.contiguous()?);
    let target = target.detach();
    Ok(if pred.track_op() {
        pred.apply_op2(&target, LossOp::new(loss, true))?
    } else {
        pred.apply_op2_no_bwd(&target, &LossOp::new(loss, false))?
    })
}

/// 2×2 average pooling of an image tensor as a differentiable [`CustomOp1`]: an `(H, W)`
/// image becomes `(⌈H/2⌉, ⌈W/2⌉)` exactly as in the MS-MSE pyramid
/// ([`crate::loss::msmse::downsample2x`]), a `(C, H, W)` image plane by plane; leading
/// dimensions of size 1 are kept.
#[derive(Clone, Copy, Debug, Default)]
pub struct Downsample2x;

/// `f` applied to each `n`-value plane of `v`, the results one after the other.
fn per_plane<T: Copy>(v: &[T], n: usize, f: impl Fn(&[T]) -> Vec<T>) -> Vec<T> {
    v.chunks_exact(n).flat_map(f).collect()
}

fn halved_shape(dims: &[usize]) -> Shape {
    let mut d = dims.to_vec();
    let n = d.len();
    d[n - 2] = d[n - 2].div_ceil(2);
    d[n - 1] = d[n - 1].div_ceil(2);
    Shape::from(d)
}

impl CustomOp1 for Downsample2x {
    fn name(&self) -> &'static str {
        "downsample2x"
    }

    fn cpu_fwd(&self, s: &CpuStorage, l: &Layout) -> candle_core::Result<(CpuStorage, Shape)> {
        let (_, h, w) = image_chw(l.dims()).map_err(candle_core::Error::Msg)?;
        let out = match s {
            CpuStorage::F32(v) => CpuStorage::F32(per_plane(slice(v, l, "image")?, h * w, |p| {
                downsample2x(p, w, h).0
            })),
            CpuStorage::F64(v) => CpuStorage::F64(per_plane(slice(v, l, "image")?, h * w, |p| {
                downsample2x(p, w, h).0
            })),
            _ => candle_core::bail!("downsample2x: needs f32 or f64, got {:?}", s.dtype()),
        };
        Ok((out, halved_shape(l.dims())))
    }

    fn bwd(
        &self,
        arg: &Tensor,
        _res: &Tensor,
        grad_res: &Tensor,
    ) -> candle_core::Result<Option<Tensor>> {
        let (_, h, w) = image_chw(arg.dims()).map_err(candle_core::Error::Msg)?;
        let half = h.div_ceil(2) * w.div_ceil(2);
        let g = match grad_res.dtype() {
            DType::F32 => Tensor::from_vec(
                per_plane(&flat::<f32>(grad_res)?, half, |p| {
                    downsample2x_adjoint(p, w, h)
                }),
                arg.shape(),
                arg.device(),
            )?,
            DType::F64 => Tensor::from_vec(
                per_plane(&flat::<f64>(grad_res)?, half, |p| {
                    downsample2x_adjoint(p, w, h)
                }),
                arg.shape(),
                arg.device(),
            )?,
            d => candle_core::bail!("downsample2x: unsupported dtype {d:?}"),
        };
        Ok(Some(g))
    }
}
