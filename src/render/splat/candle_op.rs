//! The fused splat op as a candle `CustomOp1`: map parameters → image `(height, width)`.
//!
//! For affine maps ([`SplatOp::new`]) the argument is `(n, 6)`, each row `[a, b, c, d, e, f]`
//! (`M = [[a, b], [c, d]]`, offset `(e, f)`). For any other [`DiffMap2`] there are two
//! layouts:
//! - [`SplatOp::uniform`]: every map has the structure of one prototype (`P` parameters);
//!   the argument is `(n, P)`, one map per row, and `n` is read from the tensor.
//! - [`SplatOp::with_maps`]: the maps are given (their structure may differ: a flame
//!   transform with three variations beside one with five); the argument holds their
//!   parameters map after map ([`params_to_tensor`]), in any shape with that many elements.
//!
//! The op keeps its forward tape so `bwd` runs the hand-written reverse pass, and returns
//! the gradient in the argument's shape; F32 and F64 tensors are supported on the CPU.
//! The GPU backend (`cuda` feature, `SplatConfig::device`) runs inside `cpu_fwd`/`bwd`: the
//! tensors stay on candle's CPU device (candle's own CUDA device needs nvcc to build), the
//! points and the image cross to and from the GPU in the op. `cuda_fwd` keeps candle's
//! default "not supported".

use std::sync::Mutex;

use candle_core::backend::BackendStorage;
use candle_core::{CpuStorage, CustomOp1, DType, Device, Layout, Shape, Tensor};

use super::{SplatConfig, SplatTape, backward, forward_with_probabilities};
use crate::model::affine::Affine2;
use crate::model::map::{DiffMap2, flat_params, param_offsets};

enum Tape {
    F32(SplatTape<f32>),
    F64(SplatTape<f64>),
}

/// How the op's argument becomes maps.
enum Maps<M> {
    /// `(n, P)`, every map a copy of the prototype with its row of parameters.
    Uniform(M),
    /// These maps, parameters map after map.
    Given(Vec<M>),
}

/// One call of the fused op (one seed: one set of trajectories), for maps of type `M`.
pub struct SplatOp<M: DiffMap2 = Affine2> {
    cfg: SplatConfig,
    seed: u64,
    probs: Option<Vec<f64>>,
    maps: Maps<M>,
    state: Mutex<Option<(Vec<M>, Tape)>>,
}

impl SplatOp<Affine2> {
    /// An op rendering affine maps `(n, 6)` with `cfg`, trajectories seeded by `seed`.
    pub fn new(cfg: SplatConfig, seed: u64) -> Self {
        SplatOp::uniform(cfg, seed, Affine2::new(0.0, 0.0, 0.0, 0.0, 0.0, 0.0))
    }
}

impl<M: DiffMap2> SplatOp<M> {
    /// An op whose argument is `(n, P)`: row `i` holds the parameters of map `i`, which
    /// otherwise has the structure of `prototype` (`P = prototype.n_params()`).
    pub fn uniform(cfg: SplatConfig, seed: u64, prototype: M) -> Self {
        SplatOp {
            cfg,
            seed,
            probs: None,
            maps: Maps::Uniform(prototype),
            state: Mutex::new(None),
        }
    }

    /// An op for these maps: the argument holds their parameters map after map (the
    /// values in `maps` are replaced by the argument's; their structure is kept).
    pub fn with_maps(cfg: SplatConfig, seed: u64, maps: Vec<M>) -> Self {
        SplatOp {
            cfg,
            seed,
            probs: None,
            maps: Maps::Given(maps),
            state: Mutex::new(None),
        }
    }

    /// The same op with the chaos game drawing map `i` with probability `probs[i]`.
    pub fn with_probabilities(mut self, probs: Vec<f64>) -> Self {
        self.probs = Some(probs);
        self
    }

    /// The maps the argument `v` (with dimensions `dims`) describes.
    fn decode(&self, v: &[f64], dims: &[usize]) -> candle_core::Result<Vec<M>> {
        let mut maps = match &self.maps {
            Maps::Uniform(proto) => {
                let p = proto.n_params();
                if dims.len() != 2 || dims[1] != p {
                    return Err(candle_core::Error::Msg(format!(
                        "splat op expects maps of shape (n, {p}), got {dims:?}"
                    )));
                }
                vec![proto.clone(); dims[0]]
            }
            Maps::Given(maps) => {
                let total = param_offsets(maps)[maps.len()];
                if v.len() != total {
                    return Err(candle_core::Error::Msg(format!(
                        "splat op expects the {total} parameters of its {} maps, got a tensor \
                         of shape {dims:?}",
                        maps.len()
                    )));
                }
                maps.clone()
            }
        };
        let off = param_offsets(&maps);
        for (i, m) in maps.iter_mut().enumerate() {
            m.set_params(&v[off[i]..off[i + 1]]);
        }
        Ok(maps)
    }
}

fn to_candle(e: crate::Error) -> candle_core::Error {
    candle_core::Error::Msg(e.to_string())
}

fn maps_of(v: &[f64]) -> Vec<Affine2> {
    v.chunks_exact(6).map(Affine2::from_coefficients).collect()
}

/// A `(n, 6)` tensor from affine maps.
pub fn maps_to_tensor(
    maps: &[Affine2],
    dtype: DType,
    device: &Device,
) -> candle_core::Result<Tensor> {
    let flat: Vec<f64> = maps.iter().flat_map(|m| m.coefficients()).collect();
    Tensor::from_vec(flat, (maps.len(), 6), device)?.to_dtype(dtype)
}

/// Affine maps from a `(n, 6)` tensor (or its gradient).
pub fn maps_from_tensor(t: &Tensor) -> candle_core::Result<Vec<Affine2>> {
    let v: Vec<f64> = t.to_dtype(DType::F64)?.flatten_all()?.to_vec1()?;
    Ok(maps_of(&v))
}

/// The parameters of `maps`, map after map, as a 1-D tensor (the argument of
/// [`SplatOp::with_maps`]).
pub fn params_to_tensor<M: DiffMap2>(
    maps: &[M],
    dtype: DType,
    device: &Device,
) -> candle_core::Result<Tensor> {
    Tensor::new(flat_params(maps), device)?.to_dtype(dtype)
}

fn contiguous<'a, T: Copy>(data: &'a [T], layout: &Layout) -> candle_core::Result<&'a [T]> {
    match layout.contiguous_offsets() {
        Some((a, b)) => Ok(&data[a..b]),
        None => Err(candle_core::Error::Msg(
            "splat op needs a contiguous maps tensor".into(),
        )),
    }
}

impl<M: DiffMap2> CustomOp1 for SplatOp<M> {
    fn name(&self) -> &'static str {
        "ifslab-splat"
    }

    fn cpu_fwd(
        &self,
        storage: &CpuStorage,
        layout: &Layout,
    ) -> candle_core::Result<(CpuStorage, Shape)> {
        let dims = layout.shape().dims();
        let shape = Shape::from((self.cfg.height, self.cfg.width));
        let (out, maps, tape) = match storage {
            CpuStorage::F32(v) => {
                let flat: Vec<f64> = contiguous(v, layout)?.iter().map(|&x| x as f64).collect();
                let maps = self.decode(&flat, dims)?;
                let (img, tape) = forward_with_probabilities::<f32>(
                    &self.cfg,
                    &maps,
                    self.probs.as_deref(),
                    self.seed,
                )
                .map_err(to_candle)?;
                (CpuStorage::F32(img), maps, Tape::F32(tape))
            }
            CpuStorage::F64(v) => {
                let maps = self.decode(contiguous(v, layout)?, dims)?;
                let (img, tape) = forward_with_probabilities::<f64>(
                    &self.cfg,
                    &maps,
                    self.probs.as_deref(),
                    self.seed,
                )
                .map_err(to_candle)?;
                (CpuStorage::F64(img), maps, Tape::F64(tape))
            }
            other => {
                return Err(candle_core::Error::Msg(format!(
                    "splat op supports f32 and f64 maps, got {:?}",
                    other.dtype()
                )));
            }
        };
        *self.state.lock().expect("splat tape lock") = Some((maps, tape));
        Ok((out, shape))
    }

    fn bwd(
        &self,
        arg: &Tensor,
        _res: &Tensor,
        grad_res: &Tensor,
    ) -> candle_core::Result<Option<Tensor>> {
        let guard = self.state.lock().expect("splat tape lock");
        let (maps, tape) = guard
            .as_ref()
            .ok_or_else(|| candle_core::Error::Msg("splat op: backward before forward".into()))?;
        let grads = match tape {
            Tape::F32(t) => {
                let g: Vec<f32> = grad_res.to_dtype(DType::F32)?.flatten_all()?.to_vec1()?;
                backward(&self.cfg, maps, t, &g).map_err(to_candle)?
            }
            Tape::F64(t) => {
                let g: Vec<f64> = grad_res.to_dtype(DType::F64)?.flatten_all()?.to_vec1()?;
                backward(&self.cfg, maps, t, &g).map_err(to_candle)?
            }
        };
        Ok(Some(
            Tensor::from_vec(grads, arg.shape(), arg.device())?.to_dtype(arg.dtype())?,
        ))
    }
}
