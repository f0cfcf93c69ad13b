//! The evaluation renderer as `ifslab render` drives it (`experiments/src/cmd/render.rs`):
//! the same [`RenderConfig`] from the same settings, deep zoom on unless asked otherwise,
//! and the same refusal of a window that no point reached.

use ifslab::render::{RenderConfig, RenderMode, View, Zoom, render as draw};
use numpy::{IntoPyArray, PyArray2, PyArrayMethods};
use pyo3::prelude::*;

use crate::errors::IntoPy;
use crate::progress::PyProgress;

/// Renders `code` (JSON text when `is_json`, else a file or built-in name); the image as
/// float32 `(height, width)` in [0, 1] (1 = attractor, row 0 at the top), and the render's
/// statistics as JSON text.
#[pyfunction]
#[pyo3(signature = (code, is_json, width, height, points, supersample, density, zoom, center, seed, min_hits, max_points, time_limit, plain_zoom, allow_empty, progress=None))]
#[allow(clippy::too_many_arguments)]
pub fn render<'py>(
    py: Python<'py>,
    code: &str,
    is_json: bool,
    width: u32,
    height: u32,
    points: u64,
    supersample: u32,
    density: bool,
    zoom: Option<f64>,
    center: Option<[f64; 2]>,
    seed: u64,
    min_hits: u64,
    max_points: u64,
    time_limit: Option<f64>,
    plain_zoom: bool,
    allow_empty: bool,
    progress: Option<Py<PyAny>>,
) -> PyResult<(Bound<'py, PyArray2<f32>>, String)> {
    let code = crate::code::resolve(code, is_json).py()?;
    let maps = code
        .affine2()
        .map_err(anyhow::Error::from)
        .map_err(|e| e.context("the evaluation renderer draws 2-D codes only"))
        .py()?;
    let probs = code.evaluation_probabilities().py()?;
    let cfg = RenderConfig {
        width,
        height,
        points,
        supersample,
        mode: if density {
            RenderMode::Density
        } else {
            RenderMode::Coverage
        },
        seed,
        view: code.framing.map_or(View::Fit, View::Window),
        // A centre without a zoom pans the window (zoom 1).
        zoom: (zoom.is_some() || center.is_some()).then(|| Zoom {
            factor: zoom.unwrap_or(1.0),
            center,
        }),
        min_hits,
        max_points,
        time_limit,
        deep_zoom: !plain_zoom,
        ..RenderConfig::default()
    };
    let watch = PyProgress::new(progress, false);
    let reporter = watch.boxed();
    let raster = py.detach(move || draw(&maps, &probs, &cfg, Some(reporter.as_ref())));
    let raster = watch.finish(raster.py())?;
    let s = &raster.stats;
    if s.points_in_window == 0 && !allow_empty {
        // The command line's words (`ifslab render`), with the keyword for --allow-empty.
        return Err(crate::errors::IfslabError::new_err(format!(
            "none of the {} points landed in the window x [{}, {}] y [{}, {}]: the zoom or \
             centre misses the attractor (nothing written; --allow-empty writes the empty \
             image; from Python: allow_empty=True)",
            s.points_generated, s.window.min[0], s.window.max[0], s.window.min[1], s.window.max[1]
        )));
    }
    let stats = serde_json::to_string(&raster.stats).py()?;
    let (w, h) = (raster.width as usize, raster.height as usize);
    let image = raster.image.values.into_pyarray(py).reshape([h, w])?;
    Ok((image, stats))
}
