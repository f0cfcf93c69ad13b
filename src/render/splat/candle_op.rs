//! The fused splat op as a candle `CustomOp1`: maps `(n, 6)` → image `(height, width)`.
//!
//! Each map row is `[a, b, c, d, e, f]` (`M = [[a, b], [c, d]]`, offset `(e, f)`). The op
//! keeps its forward tape so `bwd` runs the hand-written reverse pass; F32 and F64 tensors
//! are supported on the CPU. `cuda_fwd` keeps candle's default "not supported" until a
//! kernel lands behind a `cuda` feature.

use std::sync::Mutex;

use candle_core::backend::BackendStorage;
use candle_core::{CpuStorage, CustomOp1, DType, Device, Layout, Shape, Tensor};

use super::{SplatConfig, SplatTape, backward, forward};
use crate::model::affine::Affine2;

enum Tape {
    F32(SplatTape<f32>),
    F64(SplatTape<f64>),
}

/// One call of the fused op (one seed: one set of trajectories).
pub struct SplatOp {
    cfg: SplatConfig,
    seed: u64,
    state: Mutex<Option<(Vec<Affine2>, Tape)>>,
}

impl SplatOp {
    /// An op rendering with `cfg`, trajectories seeded by `seed`.
    pub fn new(cfg: SplatConfig, seed: u64) -> Self {
        SplatOp {
            cfg,
            seed,
            state: Mutex::new(None),
        }
    }
}

fn to_candle(e: crate::Error) -> candle_core::Error {
    candle_core::Error::Msg(e.to_string())
}

fn maps_of(v: &[f64]) -> Vec<Affine2> {
    v.chunks_exact(6).map(Affine2::from_coefficients).collect()
}

/// A `(n, 6)` tensor from maps.
pub fn maps_to_tensor(
    maps: &[Affine2],
    dtype: DType,
    device: &Device,
) -> candle_core::Result<Tensor> {
    let flat: Vec<f64> = maps.iter().flat_map(|m| m.coefficients()).collect();
    Tensor::from_vec(flat, (maps.len(), 6), device)?.to_dtype(dtype)
}

/// Maps from a `(n, 6)` tensor.
pub fn maps_from_tensor(t: &Tensor) -> candle_core::Result<Vec<Affine2>> {
    let v: Vec<f64> = t.to_dtype(DType::F64)?.flatten_all()?.to_vec1()?;
    Ok(maps_of(&v))
}

fn contiguous<'a, T: Copy>(data: &'a [T], layout: &Layout) -> candle_core::Result<&'a [T]> {
    match layout.contiguous_offsets() {
        Some((a, b)) => Ok(&data[a..b]),
        None => Err(candle_core::Error::Msg(
            "splat op needs a contiguous maps tensor".into(),
        )),
    }
}

impl CustomOp1 for SplatOp {
    fn name(&self) -> &'static str {
        "ifslab-splat"
    }

    fn cpu_fwd(
        &self,
        storage: &CpuStorage,
        layout: &Layout,
    ) -> candle_core::Result<(CpuStorage, Shape)> {
        let dims = layout.shape().dims();
        if dims.len() != 2 || dims[1] != 6 {
            return Err(candle_core::Error::Msg(format!(
                "splat op expects maps of shape (n, 6), got {dims:?}"
            )));
        }
        let shape = Shape::from((self.cfg.height, self.cfg.width));
        let (out, maps, tape) = match storage {
            CpuStorage::F32(v) => {
                let maps = maps_of(
                    &contiguous(v, layout)?
                        .iter()
                        .map(|&x| x as f64)
                        .collect::<Vec<_>>(),
                );
                let (img, tape) = forward::<f32>(&self.cfg, &maps, self.seed).map_err(to_candle)?;
                (CpuStorage::F32(img), maps, Tape::F32(tape))
            }
            CpuStorage::F64(v) => {
                let maps = maps_of(contiguous(v, layout)?);
                let (img, tape) = forward::<f64>(&self.cfg, &maps, self.seed).map_err(to_candle)?;
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
        Ok(Some(maps_to_tensor(&grads, arg.dtype(), arg.device())?))
    }
}
