//! # ifslab from Python
//!
//! The extension module `ifslab._ifslab` behind the `ifslab` Python package
//! (`python/ifslab/`): thin bindings over the library, no run logic of its own. Runs go
//! through [`RunConfig::run`](ifslab_experiments::runs::RunConfig::run), the entry the
//! command line and the sweeps call; renders through the evaluation renderer as
//! `ifslab render` configures it; the differentiable splat through its
//! [`Renderer`](ifslab::render::Renderer) impl. Long work releases the GIL, reports to an
//! optional Python callback and stops on Ctrl-C through the library's interrupt flag
//! ([`progress`]); errors are Python exceptions with the library's words ([`errors`]).
#![warn(missing_docs)]

mod code;
mod errors;
mod flame;
mod progress;
mod render;
mod runs;
mod splat;
mod sweep;

use pyo3::prelude::*;

// As the `ifslab` binary: the splat allocates and frees ~100 MiB of tape per call, which
// glibc hands back to the kernel each time (BENCHMARKS.md §2).
#[global_allocator]
static GLOBAL: mimalloc::MiMalloc = mimalloc::MiMalloc;

#[pymodule]
fn _ifslab(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("IfslabError", m.py().get_type::<errors::IfslabError>())?;
    m.add_function(wrap_pyfunction!(code::code_json, m)?)?;
    m.add_function(wrap_pyfunction!(code::load_code, m)?)?;
    m.add_function(wrap_pyfunction!(code::save_code, m)?)?;
    m.add_function(wrap_pyfunction!(code::builtin_codes, m)?)?;
    m.add_function(wrap_pyfunction!(render::render, m)?)?;
    m.add_function(wrap_pyfunction!(runs::run, m)?)?;
    m.add_function(wrap_pyfunction!(runs::resolve_config, m)?)?;
    m.add_function(wrap_pyfunction!(flame::flame_render, m)?)?;
    m.add_class::<splat::SplatForward>()?;
    m.add_function(wrap_pyfunction!(splat::splat_forward, m)?)?;
    m.add_function(wrap_pyfunction!(splat::splat_backward, m)?)?;
    m.add_function(wrap_pyfunction!(splat::encode_maps, m)?)?;
    m.add_function(wrap_pyfunction!(splat::decode_theta, m)?)?;
    m.add_function(wrap_pyfunction!(splat::splat_defaults, m)?)?;
    m.add_function(wrap_pyfunction!(sweep::suite_score, m)?)?;
    m.add_function(wrap_pyfunction!(sweep::sweep, m)?)?;
    m.add_function(wrap_pyfunction!(sweep::sweep_dry_run, m)?)?;
    m.add_function(wrap_pyfunction!(sweep::sweep_adopt, m)?)?;
    m.add_function(wrap_pyfunction!(sweep::sweep_slurm, m)?)?;
    m.add_function(wrap_pyfunction!(sweep::collect_sweep, m)?)?;
    m.add_function(wrap_pyfunction!(save_png, m)?)?;
    m.add_function(wrap_pyfunction!(load_image, m)?)?;
    m.add_function(wrap_pyfunction!(interrupt_requested, m)?)?;
    Ok(())
}

/// Writes a grey image (float `(height, width)` in [0, 1]) or a colour one (`(height,
/// width, 3 or 4)`) as a PNG, as the library writes its pictures: what a NumPy target
/// becomes before a run reads it.
#[pyfunction]
fn save_png(image: numpy::PyReadonlyArrayDyn<'_, f32>, path: &str) -> PyResult<()> {
    use errors::IntoPy;
    let a = image.as_array();
    let shape = a.shape().to_vec();
    let values: Vec<f32> = a.iter().copied().collect();
    match shape.as_slice() {
        [h, w] => ifslab::render::image_io::save_grey_png(
            std::path::Path::new(path),
            &values,
            *w as u32,
            *h as u32,
            ifslab::render::image_io::BitDepth::Sixteen,
            false,
        )
        .py(),
        [h, w, c @ (3 | 4)] => {
            // Channel-major planes, as `Image` holds them.
            let (h, w, c) = (*h, *w, *c);
            let mut planes = vec![0.0f32; values.len()];
            for (i, v) in values.iter().enumerate() {
                let (p, ch) = (i / c, i % c);
                planes[ch * h * w + p] = *v;
            }
            ifslab::image::Image::new(w as u32, h as u32, c as u32, planes)
                .and_then(|img| img.save_png(std::path::Path::new(path)))
                .py()
        }
        other => Err(errors::IfslabError::new_err(format!(
            "an image is (height, width) grey or (height, width, 3 or 4) colour, got shape {other:?}"
        ))),
    }
}

/// Reads a picture as the library reads targets ([`ifslab::image::Image::load`]): grey
/// `(height, width)`, or with `rgb` `(height, width, 3)`, float32 in [0, 1].
#[pyfunction]
fn load_image<'py>(
    py: Python<'py>,
    path: &str,
    rgb: bool,
) -> PyResult<Bound<'py, numpy::PyArrayDyn<f32>>> {
    use errors::IntoPy;
    use numpy::{IntoPyArray, PyArrayMethods};
    let img = ifslab::image::Image::load(std::path::Path::new(path), rgb).py()?;
    let (w, h, c) = (
        img.width as usize,
        img.height as usize,
        img.channels as usize,
    );
    // Channel-major planes to (height, width, channels).
    let values: Vec<f32> = if c == 1 {
        img.values.clone()
    } else {
        (0..h * w)
            .flat_map(|p| (0..c).map(move |ch| (p, ch)))
            .map(|(p, ch)| img.values[ch * h * w + p])
            .collect()
    };
    let shape: Vec<usize> = if c == 1 { vec![h, w] } else { vec![h, w, c] };
    values.into_pyarray(py).reshape(shape)
}

/// Whether the library's stop flag is set (a run was interrupted in this process).
#[pyfunction]
fn interrupt_requested() -> bool {
    ifslab::interrupt::requested()
}
