//! Fractal flames from Python: a `.flame` file (or its text) rendered by flam3's algorithm
//! as `ifslab flame render` renders it (`experiments/src/cmd/flame/render.rs`).

use std::path::Path;

use anyhow::{Context, bail};
use ifslab::model::flame::{Flame, parse_flames, read_flames};
use ifslab::render::flame::{FlameRenderConfig, render_flame};
use numpy::{IntoPyArray, PyArray3, PyArrayMethods};
use pyo3::prelude::*;

use crate::errors::IntoPy;
use crate::progress::PyProgress;

/// The flames of a file (`is_text` false) or of `.flame` text; `name` picks one by name,
/// else the `index`-th.
fn pick(source: &str, is_text: bool, name: Option<&str>, index: usize) -> anyhow::Result<Flame> {
    let flames = if is_text {
        parse_flames(source, Path::new("the flame text"))?
    } else {
        read_flames(Path::new(source))?
    };
    match name {
        Some(n) => flames
            .into_iter()
            .find(|f| f.name.as_deref() == Some(n))
            .with_context(|| format!("no flame named `{n}` in {source}")),
        None => {
            let count = flames.len();
            flames.into_iter().nth(index).with_context(|| {
                format!(
                    "flame {index} asked for; the file holds {count} (0 to {})",
                    count - 1
                )
            })
        }
    }
}

/// `ifslab flame render`'s overrides of a flame's size, quality and supersampling (the
/// same rule: the scale follows the height, so the picture keeps its framing).
fn apply_overrides(
    flame: &mut Flame,
    size: Option<[u32; 2]>,
    quality: Option<f64>,
    supersample: Option<u32>,
) -> anyhow::Result<()> {
    if let Some([w, h]) = size {
        if w == 0 || h == 0 {
            bail!("size must be at least 1×1, got {w}×{h}");
        }
        flame.scale *= h as f64 / flame.size[1] as f64;
        flame.size = [w, h];
    }
    if let Some(q) = quality {
        if !(q.is_finite() && q > 0.0) {
            bail!("quality must be > 0, got {q}");
        }
        flame.quality = q;
    }
    if let Some(s) = supersample {
        flame.supersample = s;
    }
    Ok(())
}

/// Renders one flame: float32 `(height, width, 4)`, RGB in [0, 255] and alpha in [0, 1]
/// (the library's [`FlameImage`](ifslab::render::flame::FlameImage)), and the statistics as
/// JSON text.
#[pyfunction]
#[pyo3(signature = (source, is_text, name=None, index=0, size=None, quality=None, supersample=None, seed=0, transparent=false, progress=None))]
#[allow(clippy::too_many_arguments)]
pub fn flame_render<'py>(
    py: Python<'py>,
    source: &str,
    is_text: bool,
    name: Option<&str>,
    index: usize,
    size: Option<[u32; 2]>,
    quality: Option<f64>,
    supersample: Option<u32>,
    seed: u64,
    transparent: bool,
    progress: Option<Py<PyAny>>,
) -> PyResult<(Bound<'py, PyArray3<f32>>, String)> {
    let mut flame = pick(source, is_text, name, index).py()?;
    apply_overrides(&mut flame, size, quality, supersample).py()?;
    let cfg = FlameRenderConfig {
        seed,
        transparent,
        ..FlameRenderConfig::default()
    };
    let watch = PyProgress::new(progress, false);
    let reporter = watch.boxed();
    let label = flame.label();
    let img = py.detach(move || {
        render_flame(&flame, &cfg, Some(reporter.as_ref()))
            .with_context(|| format!("rendering {label}"))
    });
    let img = watch.finish(img.py())?;
    let stats = serde_json::to_string(&img.stats).py()?;
    let (w, h) = (img.width as usize, img.height as usize);
    let flat: Vec<f32> = img.pixels.into_iter().flatten().collect();
    Ok((flat.into_pyarray(py).reshape([h, w, 4])?, stats))
}
