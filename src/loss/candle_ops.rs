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
use crate::loss::ImageLoss;
use crate::loss::msmse::{downsample2x, downsample2x_adjoint};

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

/// `(height, width)` of an image tensor: the last two dimensions, every other one of size 1.
pub fn image_hw(dims: &[usize]) -> std::result::Result<(usize, usize), String> {
    match dims {
        [lead @ .., h, w] if lead.iter().all(|&d| d == 1) => Ok((*h, *w)),
        _ => Err(format!(
            "expected an image tensor of shape (H, W) (leading dimensions of size 1 allowed), got {dims:?}"
        )),
    }
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
        let (h, w) = image_hw(l1.dims()).map_err(candle_core::Error::Msg)?;
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
                let (a, b) = (slice(a, l1, "pred")?, slice(b, l2, "target")?);
                let v = if self.keep_grad {
                    let (v, g) = self.loss.value_and_grad(a, b, w, h).map_err(to_candle)?;
                    self.store(Cached::F32(g));
                    v
                } else {
                    self.loss.value(a, b, w, h).map_err(to_candle)?
                };
                CpuStorage::F32(vec![v])
            }
            (CpuStorage::F64(a), CpuStorage::F64(b)) => {
                let (a, b) = (slice(a, l1, "pred")?, slice(b, l2, "target")?);
                let v = if self.keep_grad {
                    let (v, g) = self.loss.value_and_grad(a, b, w, h).map_err(to_candle)?;
                    self.store(Cached::F64(g));
                    v
                } else {
                    self.loss.value(a, b, w, h).map_err(to_candle)?
                };
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
        let (h, w) = image_hw(arg1.dims()).map_err(candle_core::Error::Msg)?;
        // The kept gradient is handed over, not copied; a second backward pass through the
        // same graph (or an op built with keep_grad = false) recomputes it.
        let cached = self.cache.lock().unwrap_or_else(|e| e.into_inner()).take();
        let cached = match cached {
            Some(c) => c,
            None => match arg1.dtype() {
                DType::F32 => {
                    let (a, b) = (flat::<f32>(arg1)?, flat::<f32>(arg2)?);
                    Cached::F32(self.loss.value_and_grad(&a, &b, w, h).map_err(to_candle)?.1)
                }
                DType::F64 => {
                    let (a, b) = (flat::<f64>(arg1)?, flat::<f64>(arg2)?);
                    Cached::F64(self.loss.value_and_grad(&a, &b, w, h).map_err(to_candle)?.1)
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
/// Both tensors must be `(H, W)` images (leading dimensions of size 1 allowed) of the same
/// shape and dtype (`f32` or `f64`) on the CPU. When `pred` does not take part in autograd
/// the gradient is not computed at all.
pub fn apply_loss<L: ImageLoss + 'static>(
    loss: L,
    pred: &Tensor,
    target: &Tensor,
) -> Result<Tensor> {
    image_hw(pred.dims()).map_err(Error::Shape)?;
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
/// ([`crate::loss::msmse::downsample2x`]); leading dimensions of size 1 are kept.
#[derive(Clone, Copy, Debug, Default)]
pub struct Downsample2x;

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
        let (h, w) = image_hw(l.dims()).map_err(candle_core::Error::Msg)?;
        let out = match s {
            CpuStorage::F32(v) => CpuStorage::F32(downsample2x(slice(v, l, "image")?, w, h).0),
            CpuStorage::F64(v) => CpuStorage::F64(downsample2x(slice(v, l, "image")?, w, h).0),
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
        let (h, w) = image_hw(arg.dims()).map_err(candle_core::Error::Msg)?;
        let g = match grad_res.dtype() {
            DType::F32 => Tensor::from_vec(
                downsample2x_adjoint(&flat::<f32>(grad_res)?, w, h),
                arg.shape(),
                arg.device(),
            )?,
            DType::F64 => Tensor::from_vec(
                downsample2x_adjoint(&flat::<f64>(grad_res)?, w, h),
                arg.shape(),
                arg.device(),
            )?,
            d => candle_core::bail!("downsample2x: unsupported dtype {d:?}"),
        };
        Ok(Some(g))
    }
}
