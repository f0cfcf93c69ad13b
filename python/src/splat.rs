//! The differentiable splat ([`Splat`], through the [`Renderer`] trait) as a NumPy forward
//! and vector–Jacobian product: affine maps `(n, 6)` — `[a, b, c, d, e, f]` for
//! `x ↦ [[a, b], [c, d]]·x + [e, f]` — or θ of a parameterisation in, a grey f64 image out;
//! `∂L/∂image` in, `∂L/∂maps` (or `∂L/∂θ`) out.

use std::sync::Mutex;

use anyhow::Context;
use ifslab::model::Affine2;
use ifslab::model::param::ParamKind;
use ifslab::render::Renderer;
use ifslab::render::splat::{Splat, SplatConfig};
use numpy::{IntoPyArray, PyArray1, PyArray2, PyArrayMethods, PyReadonlyArray1, PyReadonlyArray2};
use pyo3::prelude::*;

use crate::errors::IntoPy;

type AffineSplat = Splat<Affine2, f64>;

/// What the reverse pass of one forward call needs: the renderer, the scene, its sampling
/// state and the tape (and θ with its parameterisation when the call took θ).
#[pyclass(frozen, module = "ifslab._ifslab")]
pub struct SplatForward {
    splat: AffineSplat,
    maps: Vec<Affine2>,
    seed: u64,
    tape: Mutex<<AffineSplat as Renderer>::Tape>,
    theta: Option<(Vec<f64>, ParamKind)>,
}

#[pymethods]
impl SplatForward {
    /// The maps drawn, `(n, 6)`.
    fn maps<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        maps_array(py, &self.maps)
    }

    /// The chaos game's seed this call drew (stream `draw` of the run's seed).
    #[getter]
    fn sampling_seed(&self) -> u64 {
        self.seed
    }
}

fn maps_array<'py>(py: Python<'py>, maps: &[Affine2]) -> PyResult<Bound<'py, PyArray2<f64>>> {
    let flat: Vec<f64> = maps.iter().flat_map(Affine2::coefficients).collect();
    flat.into_pyarray(py).reshape([maps.len(), 6])
}

fn maps_from(array: &PyReadonlyArray2<'_, f64>) -> anyhow::Result<Vec<Affine2>> {
    let a = array.as_array();
    anyhow::ensure!(
        a.ncols() == 6 && a.nrows() > 0,
        "maps must be an (n, 6) array of [a, b, c, d, e, f] rows, got shape {:?}",
        a.shape()
    );
    let maps: Vec<Affine2> = a
        .rows()
        .into_iter()
        .map(|r| Affine2::new(r[0], r[1], r[2], r[3], r[4], r[5]))
        .collect();
    for (i, m) in maps.iter().enumerate() {
        if let Some(v) = m.coefficients().iter().find(|v| !v.is_finite()) {
            anyhow::bail!("map {i} has a non-finite coefficient ({v})");
        }
    }
    Ok(maps)
}

fn param_kind(name: &str) -> anyhow::Result<ParamKind> {
    serde_json::from_value(serde_json::Value::String(name.into()))
        .with_context(|| format!("unknown parameterisation `{name}`: use svd, naive or rsr"))
}

/// The splat's settings from their JSON text (the fields of [`SplatConfig`]), validated.
fn splat_of(config: &str, probabilities: Option<Vec<f64>>) -> anyhow::Result<AffineSplat> {
    let cfg: SplatConfig = serde_json::from_str(config).context("splat settings")?;
    cfg.validate()?;
    Ok(AffineSplat::new(cfg).with_probabilities(probabilities))
}

/// Renders `maps` (`(n, 6)`), or θ (`theta`, 1-D, with `param`), with the chaos game of
/// stream `draw` of `seed`: the image `(height, width)` and what the reverse pass needs.
#[pyfunction]
#[pyo3(signature = (config, maps=None, theta=None, param="svd", probabilities=None, seed=0, draw=0))]
#[allow(clippy::too_many_arguments)]
pub fn splat_forward<'py>(
    py: Python<'py>,
    config: &str,
    maps: Option<PyReadonlyArray2<'py, f64>>,
    theta: Option<PyReadonlyArray1<'py, f64>>,
    param: &str,
    probabilities: Option<Vec<f64>>,
    seed: u64,
    draw: u64,
) -> PyResult<(Bound<'py, PyArray2<f64>>, SplatForward)> {
    let splat = splat_of(config, probabilities).py()?;
    let (maps, theta) = match (maps, theta) {
        (Some(m), None) => (maps_from(&m).py()?, None),
        (None, Some(t)) => {
            let kind = param_kind(param).py()?;
            let theta = t.as_array().to_vec();
            let maps = kind.build().decode(&theta).py()?;
            (maps, Some((theta, kind)))
        }
        _ => {
            return Err(crate::errors::IfslabError::new_err(
                "give the splat either maps or theta",
            ));
        }
    };
    let sampling = splat.sampling(&maps, seed, draw);
    let (image, tape) = py.detach(|| splat.forward(&maps, &sampling)).py()?;
    let planes = splat.planes();
    let image = image
        .into_pyarray(py)
        .reshape([planes.height, planes.width])?;
    Ok((
        image,
        SplatForward {
            splat,
            maps,
            seed: sampling,
            tape: Mutex::new(tape),
            theta,
        },
    ))
}

/// The vector–Jacobian product of a forward call: `∂L/∂image` `(height, width)` in,
/// `∂L/∂maps` `(n, 6)` out — or `∂L/∂θ` (1-D) when the forward call took θ.
#[pyfunction]
pub fn splat_backward<'py>(
    py: Python<'py>,
    forward: &SplatForward,
    grad_image: PyReadonlyArray2<'py, f64>,
) -> PyResult<Bound<'py, PyAny>> {
    let planes = forward.splat.planes();
    let g = grad_image.as_array();
    if g.shape() != [planes.height, planes.width] {
        return Err(crate::errors::IfslabError::new_err(format!(
            "the image gradient has shape {:?}, the image ({}, {})",
            g.shape(),
            planes.height,
            planes.width
        )));
    }
    let g: Vec<f64> = g.iter().copied().collect();
    let tape = forward
        .tape
        .lock()
        .map_err(|_| crate::errors::IfslabError::new_err("the tape is poisoned"))?;
    let grad = py
        .detach(|| {
            forward
                .splat
                .backward(&forward.maps, &forward.seed, &tape, &g)
        })
        .py()?;
    match &forward.theta {
        None => Ok(grad
            .into_pyarray(py)
            .reshape([forward.maps.len(), 6])?
            .into_any()),
        Some((theta, kind)) => {
            let grad_maps: Vec<Affine2> = grad.chunks(6).map(Affine2::from_coefficients).collect();
            let g = kind.build().backward(theta, &grad_maps).py()?;
            Ok(g.into_pyarray(py).into_any())
        }
    }
}

/// θ of `param` that decodes to `maps` (`(n, 6)`).
#[pyfunction]
pub fn encode_maps<'py>(
    py: Python<'py>,
    maps: PyReadonlyArray2<'py, f64>,
    param: &str,
) -> PyResult<Bound<'py, PyArray1<f64>>> {
    let maps = maps_from(&maps).py()?;
    let theta = param_kind(param).py()?.build().encode(&maps).py()?;
    Ok(theta.into_pyarray(py))
}

/// The maps θ of `param` decodes to, `(n, 6)`.
#[pyfunction]
pub fn decode_theta<'py>(
    py: Python<'py>,
    theta: PyReadonlyArray1<'py, f64>,
    param: &str,
) -> PyResult<Bound<'py, PyArray2<f64>>> {
    let theta = theta.as_array().to_vec();
    let maps = param_kind(param).py()?.build().decode(&theta).py()?;
    maps_array(py, &maps)
}

/// The default splat settings ([`SplatConfig::default`], the paper's) as JSON text.
#[pyfunction]
pub fn splat_defaults() -> PyResult<String> {
    serde_json::to_string(&SplatConfig::default()).py()
}
