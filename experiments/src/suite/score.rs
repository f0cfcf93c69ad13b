//! Scoring a code against a suite entry: the paper's metrics on every view.

use std::path::Path;

use crate::error::Context;
use ifslab::loss::lpips::{LPIPS_MIN_SIDE, Lpips};
use ifslab::metrics::{EVAL_BORDER_FRACTION, cropped_metrics};
use ifslab::model::IfsCode;
use ifslab::render::image_io::load_grey;
use ifslab_strategies::problems::image::{Fitted, Recovered};
use serde::{Deserialize, Serialize};

use super::make::view_config;
use super::{CodeEntry, Manifest, PSNR_CAP};

/// The metrics of one view.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ViewScore {
    /// The view's name (`full`, `zoom1`, …).
    pub name: String,
    /// Its zoom factor.
    pub factor: f64,
    /// F1 (Dice) of the `> 0` masks.
    pub f1: f64,
    /// IoU of the `> 0` masks.
    pub iou: f64,
    /// PSNR on the foreground, capped at [`PSNR_CAP`].
    pub psnr: f64,
    /// SSIM on the foreground.
    pub ssim: f64,
    /// LPIPS (AlexNet), when the weights are there.
    pub lpips: Option<f64>,
    /// PSNR over every pixel of the crop, background included (capped like `psnr`; absent
    /// from scores made before it was reported).
    #[serde(default)]
    pub psnr_crop: Option<f64>,
    /// SSIM over every pixel of the crop, background included.
    #[serde(default)]
    pub ssim_crop: Option<f64>,
}

/// A code's score on one suite entry: the means over its views (what the paper's Table 3
/// averages over 700 images), and every view.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SuiteScore {
    /// The entry's index in the suite.
    pub index: usize,
    /// Mean F1 over the views.
    pub f1: f64,
    /// Mean IoU over the views.
    pub iou: f64,
    /// Mean PSNR over the views.
    pub psnr: f64,
    /// Mean SSIM over the views.
    pub ssim: f64,
    /// Mean LPIPS over the views (absent without weights).
    pub lpips: Option<f64>,
    /// Mean PSNR over the views, every pixel of each crop (see [`ViewScore::psnr_crop`]).
    #[serde(default)]
    pub psnr_crop: Option<f64>,
    /// Mean SSIM over the views, every pixel of each crop.
    #[serde(default)]
    pub ssim_crop: Option<f64>,
    /// Seconds the renders and metrics took.
    pub seconds: f64,
    /// Every view.
    pub views: Vec<ViewScore>,
}

/// Scores the code file `code` against entry `index` of the suite in `dir`.
pub fn score_code(
    dir: &Path,
    manifest: &Manifest,
    index: usize,
    code: &IfsCode,
    net: Option<&Lpips>,
) -> crate::Result<SuiteScore> {
    let maps = code.affine2().context("a suite scores 2-D codes")?;
    let fit = Fitted::with_probabilities(maps, code.evaluation_probabilities()?)?;
    score_maps(dir, manifest, index, &fit, net)
}

/// Renders `fit` (maps of any family, [`Recovered`]) at every view of entry `index` — its own full-view window
/// fitted the way an inversion frames it, each patch at the same fractions of that window —
/// and scores each against the stored truth: the full view with the paper's border crop
/// (12.5% a side, empty by construction), the patches whole.
pub fn score_maps(
    dir: &Path,
    manifest: &Manifest,
    index: usize,
    fit: &dyn Recovered,
    net: Option<&Lpips>,
) -> crate::Result<SuiteScore> {
    let started = std::time::Instant::now();
    let entry: &CodeEntry = manifest.entry(index)?;
    let spec = &manifest.spec;
    let size = spec.tier.size();
    let net = net.filter(|_| size - 2 * border(size) >= LPIPS_MIN_SIDE);
    let full = fit.render(&spec.render_config(entry.render_seed))?;
    let window = full.stats.window;
    let mut views = Vec::with_capacity(entry.views.len());
    for v in &entry.views {
        let truth_path = dir.join(&v.truth);
        let truth = load_grey(&truth_path)
            .with_context(|| format!("loading the suite's truth {}", truth_path.display()))?;
        if truth.width as usize != size || truth.height as usize != size {
            crate::error::bail!(
                "{} is {}×{}, the suite's tier renders {size}²",
                truth_path.display(),
                truth.width,
                truth.height
            );
        }
        let pred = if v.factor == 1.0 && v.center == [0.5, 0.5] {
            full.values.clone()
        } else {
            fit.render(&view_config(
                spec,
                &window,
                v.factor,
                v.center,
                entry.render_seed,
            ))?
            .image
            .values
        };
        let fraction = if v.factor == 1.0 {
            EVAL_BORDER_FRACTION
        } else {
            0.0
        };
        let m = cropped_metrics(&pred, &truth.values, size, size, fraction, net)
            .with_context(|| format!("scoring view {} of code {index}", v.name))?;
        views.push(ViewScore {
            name: v.name.clone(),
            factor: v.factor,
            f1: m.f1,
            iou: m.iou,
            psnr: m.psnr.min(PSNR_CAP),
            ssim: m.ssim,
            lpips: m.lpips,
            psnr_crop: Some(m.psnr_crop.min(PSNR_CAP)),
            ssim_crop: Some(m.ssim_crop),
        });
    }
    let mean = |f: fn(&ViewScore) -> f64| views.iter().map(f).sum::<f64>() / views.len() as f64;
    let mean_of = |f: fn(&ViewScore) -> Option<f64>| {
        views
            .iter()
            .map(f)
            .collect::<Option<Vec<f64>>>()
            .map(|l| l.iter().sum::<f64>() / l.len() as f64)
    };
    let lpips = mean_of(|v| v.lpips);
    Ok(SuiteScore {
        index,
        f1: mean(|v| v.f1),
        iou: mean(|v| v.iou),
        psnr: mean(|v| v.psnr),
        ssim: mean(|v| v.ssim),
        lpips,
        psnr_crop: mean_of(|v| v.psnr_crop),
        ssim_crop: mean_of(|v| v.ssim_crop),
        seconds: started.elapsed().as_secs_f64(),
        views,
    })
}

/// Pixels the full view's crop leaves out on each side.
fn border(size: usize) -> usize {
    (EVAL_BORDER_FRACTION * size as f64).round() as usize
}
