//! What an image inversion fits: a flat θ ↔ maps of one type that the fused splat op renders
//! and differentiates.
//!
//! A model is an [`ImageModel`]: its map type (any [`DiffMap2`](ifslab::model::DiffMap2)
//! with an [`AffinePart`](ifslab::model::AffinePart) for the regulariser), how θ decodes
//! into maps, the chain rule back to θ, a projection, and how
//! a start given as affine maps (a random code, an EM fit, a code file) becomes θ. The
//! [`ImageProblem`](super::ImageProblem) holds a model behind [`AnyModel`], type-erased once
//! per evaluation (never per point: the splat is monomorphised for `M::Map`), so a new map
//! type reaches every strategy, checkpoint, resume and `ifslab run` by one entry in
//! [`MODELS`]. Models are named in a config by `[model] family = "…"`.
//!
//! Three families ship: `affine` (general affine maps under a [`Parameterisation`], the
//! paper's model), `similitude` (direct similitudes `x ↦ s·R(φ)·x + t`, θ = (s, φ, tₓ, t_y)
//! per map — the worked example of adding a map type: [`SimilitudeModel`] is ~60 lines) and
//! `flame` (flam3 transforms with the `linear` and `sinusoidal` variations, [`FlameModel`]:
//! maps that are not affine, whose runs show the same outputs from their fit file,
//! [`result`](super::result)).

use candle_core::Tensor;
use ifslab::loss::{LossBreakdown, Objective};
use ifslab::model::diff_map::Similitude2;
use ifslab::model::flame::{SmoothXform, Variation, VariationKind, Xform, coefs_of};
use ifslab::model::{Affine2, Parameterisation};
use ifslab::render::Renderer;
use ifslab::render::splat;

use ifslab::model::ParamKind;
use serde::{Deserialize, Serialize};

use crate::driver::Evaluation;
use crate::error::{Error, Result};
use crate::problems::image::instance::{self, ImageRendering, splat_problem};
// The trait a model implements and the probability rule live with the instance they
// parameterise; they keep their paths here.
pub use crate::problems::image::instance::{ImageModel, MapProbabilities};
use crate::problems::image::result::{Fitted, Recovered};
use crate::problems::render_problem::Moment;

/// Any [`ImageModel`], its map type erased: what the image problem holds. Implemented for
/// every model; each call builds the problem's instance of the model's map type
/// ([`SplatProblem`](super::instance::SplatProblem)) or its parts, monomorphised inside.
pub trait AnyModel: Send + Sync {
    /// The loss at θ, its terms and its gradient with respect to θ at iteration `iter` of a
    /// run drawing θ as `rendering` says, scored by `objective`
    /// ([`instance::evaluate`](super::instance::evaluate): the one image problem's pass, or
    /// the fused GPU pass where it applies).
    fn evaluate(
        &self,
        theta: &[f64],
        rendering: &ImageRendering,
        objective: &Objective,
        iter: u64,
    ) -> Result<Evaluation>;

    /// The objective's MS-MSE of a render of θ at `at` computed on the GPU (only the scalar
    /// comes back), or `None` where that route does not apply ([`splat::render_msmse`]).
    fn render_msmse(
        &self,
        theta: &[f64],
        rendering: &ImageRendering,
        objective: &Objective,
        at: Moment,
    ) -> Result<Option<f64>>;

    /// The splat render of θ at `at` (no gradient; the maps as decoded, not rounded).
    fn render(&self, theta: &[f64], rendering: &ImageRendering, at: Moment) -> Result<Vec<f32>>;

    /// The loss terms of a render `pred` of θ (the regulariser sees θ's maps).
    fn breakdown(
        &self,
        theta: &[f64],
        pred: &Tensor,
        objective: &Objective,
    ) -> Result<LossBreakdown>;

    /// See [`ImageModel::project`].
    fn project(&self, theta: &mut [f64]);

    /// See [`ImageModel::encode`].
    fn encode(&self, start: &[Affine2]) -> Result<Vec<f64>>;

    /// θ's maps as affine maps (an error for a family whose maps are not affine).
    fn affine_maps(&self, theta: &[f64]) -> Result<Vec<Affine2>>;

    /// θ's maps as a run's outputs need them: the evaluation render, probabilities, the
    /// zoom strip's point, the affine form where there is one ([`Recovered`]).
    fn recovered(&self, theta: &[f64]) -> Result<Box<dyn Recovered>>;

    /// The number of maps θ describes.
    fn n_maps(&self, theta: &[f64]) -> Result<usize>;

    /// Whether the family's maps are affine maps: read off the map a contracting affine
    /// start (x ↦ x/2) becomes, so a config can be checked before a run has a θ.
    fn maps_are_affine(&self) -> Result<bool> {
        let probe = self.encode(&[Affine2::new(0.5, 0.0, 0.0, 0.5, 0.0, 0.0)])?;
        Ok(self.affine_maps(&probe).is_ok())
    }
}

impl<M: ImageModel> AnyModel for M {
    fn evaluate(
        &self,
        theta: &[f64],
        rendering: &ImageRendering,
        objective: &Objective,
        iter: u64,
    ) -> Result<Evaluation> {
        instance::evaluate(&splat_problem(self, rendering, objective), theta, iter)
    }

    fn render_msmse(
        &self,
        theta: &[f64],
        rendering: &ImageRendering,
        objective: &Objective,
        at: Moment,
    ) -> Result<Option<f64>> {
        let maps = self.decode(theta)?;
        let (renderer, seed) = rendering.drawn(&maps, at)?;
        Ok(splat::render_msmse(
            &renderer.cfg,
            &maps,
            renderer.probs.as_deref(),
            rendering.clamp,
            seed,
            objective,
        )?)
    }

    fn render(&self, theta: &[f64], rendering: &ImageRendering, at: Moment) -> Result<Vec<f32>> {
        let maps = self.decode(theta)?;
        let (renderer, seed) = rendering.drawn(&maps, at)?;
        let mut img = renderer.forward(&maps, &seed)?.0;
        if rendering.clamp {
            img.iter_mut().for_each(|v| *v = v.min(1.0));
        }
        Ok(img)
    }

    fn breakdown(
        &self,
        theta: &[f64],
        pred: &Tensor,
        objective: &Objective,
    ) -> Result<LossBreakdown> {
        let maps = self.decode(theta)?;
        Ok(objective.evaluate_params(pred, &maps)?.breakdown)
    }

    fn project(&self, theta: &mut [f64]) {
        ImageModel::project(self, theta)
    }

    fn encode(&self, start: &[Affine2]) -> Result<Vec<f64>> {
        ImageModel::encode(self, start)
    }

    fn affine_maps(&self, theta: &[f64]) -> Result<Vec<Affine2>> {
        self.decode(theta)?
            .iter()
            .enumerate()
            .map(|(i, m)| {
                Affine2::of_map(m).ok_or_else(|| {
                    Error::InvalidInput(format!(
                        "map {i} of this model is not affine (it has no affine form)"
                    ))
                })
            })
            .collect()
    }

    fn recovered(&self, theta: &[f64]) -> Result<Box<dyn Recovered>> {
        Ok(Box::new(Fitted::new(self.decode(theta)?)?))
    }

    fn n_maps(&self, theta: &[f64]) -> Result<usize> {
        Ok(self.decode(theta)?.len())
    }
}

/// General affine maps under a [`Parameterisation`] (`family = "affine"`, the default).
pub struct AffineModel(pub Box<dyn Parameterisation>);

impl ImageModel for AffineModel {
    type Map = Affine2;

    fn decode(&self, theta: &[f64]) -> Result<Vec<Affine2>> {
        Ok(self.0.decode(theta)?)
    }

    fn backward(&self, theta: &[f64], grad_params: &[f64]) -> Result<Vec<f64>> {
        let g: Vec<Affine2> = grad_params
            .chunks_exact(6)
            .map(Affine2::from_coefficients)
            .collect();
        Ok(self.0.backward(theta, &g)?)
    }

    fn project(&self, theta: &mut [f64]) {
        self.0.project(theta)
    }

    fn encode(&self, start: &[Affine2]) -> Result<Vec<f64>> {
        Ok(self.0.encode(start)?)
    }
}

/// Direct similitudes `x ↦ s·R(φ)·x + t` (`family = "similitude"`): θ = (s, φ, tₓ, t_y) per
/// map, `s` kept in [[`SimilitudeModel::MIN_SCALE`], [`SimilitudeModel::MAX_SCALE`]] so every
/// map contracts. Reflections are not in the family (a start map with det < 0 becomes the
/// nearest rotation-scale map).
pub struct SimilitudeModel;

impl SimilitudeModel {
    /// The smallest scale θ may hold.
    pub const MIN_SCALE: f64 = 1e-3;
    /// The largest scale θ may hold.
    pub const MAX_SCALE: f64 = 0.999;
}

impl ImageModel for SimilitudeModel {
    type Map = Similitude2;

    fn decode(&self, theta: &[f64]) -> Result<Vec<Similitude2>> {
        if theta.is_empty() || !theta.len().is_multiple_of(4) {
            return Err(Error::InvalidInput(format!(
                "a similitude code needs 4 parameters per map, θ has {}",
                theta.len()
            )));
        }
        if let Some(i) = theta.iter().position(|v| !v.is_finite()) {
            return Err(Error::Numerical(format!(
                "map {}, parameter {} is {}",
                i / 4,
                i % 4,
                theta[i]
            )));
        }
        Ok(theta
            .chunks_exact(4)
            .map(|p| Similitude2::new(p[0], p[1], false, [p[2], p[3]]))
            .collect())
    }

    fn backward(&self, _theta: &[f64], grad_params: &[f64]) -> Result<Vec<f64>> {
        Ok(grad_params.to_vec())
    }

    fn project(&self, theta: &mut [f64]) {
        for p in theta.chunks_exact_mut(4) {
            p[0] = p[0].clamp(Self::MIN_SCALE, Self::MAX_SCALE);
        }
    }

    /// The rotation-scale part of `M` (its conformal part `(M + cof M)/2`), offset kept.
    fn encode(&self, start: &[Affine2]) -> Result<Vec<f64>> {
        let mut theta = Vec::with_capacity(4 * start.len());
        for m in start {
            let (a, b) = (
                0.5 * (m.m[(0, 0)] + m.m[(1, 1)]),
                0.5 * (m.m[(1, 0)] - m.m[(0, 1)]),
            );
            theta.extend_from_slice(&[a.hypot(b), b.atan2(a), m.b[0], m.b[1]]);
        }
        ImageModel::project(self, &mut theta);
        Ok(theta)
    }
}

/// Flame transforms `x ↦ w_lin·(A·x + b) + w_sin·sin(A·x + b)` (flam3's `linear` and
/// `sinusoidal` variations after a pre-affine step, no post-affine; `family = "flame"`):
/// θ = (flam3's `a b c d e f`, w_lin, w_sin) per map, the weights kept at
/// |w_lin| + |w_sin| ≤ 1 so that a contracting affine step makes a contracting map (sine is
/// 1-Lipschitz per coordinate). A start's affine maps become pure `linear` transforms. The
/// family's maps are not affine maps (`SmoothXform` has no affine form, even at `w_sin = 0`):
/// its runs write their fit file, not an affine code file.
pub struct FlameModel;

impl FlameModel {
    /// Parameters per map.
    pub const PARAMS: usize = 8;
}

impl ImageModel for FlameModel {
    type Map = SmoothXform;

    fn decode(&self, theta: &[f64]) -> Result<Vec<SmoothXform>> {
        if theta.is_empty() || !theta.len().is_multiple_of(Self::PARAMS) {
            return Err(Error::InvalidInput(format!(
                "a flame code needs {} parameters per map, θ has {}",
                Self::PARAMS,
                theta.len()
            )));
        }
        if let Some(i) = theta.iter().position(|v| !v.is_finite()) {
            return Err(Error::Numerical(format!(
                "map {}, parameter {} is {}",
                i / Self::PARAMS,
                i % Self::PARAMS,
                theta[i]
            )));
        }
        theta
            .chunks_exact(Self::PARAMS)
            .map(|p| {
                let coefs = [p[0], p[1], p[2], p[3], p[4], p[5]];
                let variations = vec![
                    Variation::new(VariationKind::Linear, p[6]),
                    Variation::new(VariationKind::Sinusoidal, p[7]),
                ];
                Ok(SmoothXform::new(Xform::new(coefs, variations))?)
            })
            .collect()
    }

    /// The transform's parameters are θ's followed by the post-affine step's six, which
    /// stay the identity.
    fn backward(&self, _theta: &[f64], grad_params: &[f64]) -> Result<Vec<f64>> {
        Ok(grad_params
            .chunks_exact(Self::PARAMS + 6)
            .flat_map(|g| g[..Self::PARAMS].iter().copied())
            .collect())
    }

    fn project(&self, theta: &mut [f64]) {
        for p in theta.chunks_exact_mut(Self::PARAMS) {
            let total = p[6].abs() + p[7].abs();
            if total > 1.0 {
                p[6] /= total;
                p[7] /= total;
            }
        }
    }

    fn encode(&self, start: &[Affine2]) -> Result<Vec<f64>> {
        Ok(start
            .iter()
            .flat_map(|m| {
                let mut p = [0.0; Self::PARAMS];
                p[..6].copy_from_slice(&coefs_of(m));
                // Pure `linear`: the start's own affine map.
                p[6] = 1.0;
                p
            })
            .collect())
    }
}

/// The model: which map type, how many maps, how θ is parameterised, how it starts.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ModelConfig {
    /// The map type: a name in [`models`](crate::problems::image::models) (`affine`, the
    /// default; `similitude`).
    pub family: String,
    /// Number of maps.
    pub maps: usize,
    /// Parameterisation of θ (affine maps).
    pub parameterisation: ParamKind,
    /// How the initial code is chosen (`random`, `em` or `collage`) when `init_code` is not
    /// given.
    pub init: InitKind,
    /// Seed of the initial code (Anderson–Farrell sampler, EM); default: the run's seed.
    pub init_seed: Option<u64>,
    /// Start from this code instead (a code file or built-in name; it must have `maps` maps).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub init_code: Option<String>,
    /// Standard deviation of Gaussian noise added to the initial θ.
    pub init_noise: f64,
    /// Let the EM start's similitudes reflect as well as rotate (a code whose maps mirror
    /// is then within the start's reach; also the EM rival of the collage start). Written
    /// only when on.
    #[serde(skip_serializing_if = "std::ops::Not::not")]
    pub em_reflections: bool,
    /// Rounds of [`moment_refine`](crate::problems::image::init::moment_refine) after the
    /// EM start: its similitudes become affine maps matching each piece's second moments
    /// (0: off). Written only when on.
    #[serde(skip_serializing_if = "is_zero")]
    pub em_affine: usize,
    /// The side (pixels) at which the collage start reads a picture target: the picture is
    /// framed again at this size for the start alone, so that thin detail the fit's
    /// `target.size` blurs away still shapes the maps (the fit runs at `target.size`).
    /// None: `target.size`. Picture targets only (a config that sets it for a code target is
    /// refused). Written only when set.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub start_size: Option<usize>,
    /// Rounds of the collage start's closest-point refinement of each cover
    /// ([`CollageSearch::refine`](crate::problems::image::collage::CollageSearch::refine);
    /// 0: off, the default). It raises the start's score but not the fitted code's
    /// (measured in robustness/README.md), so no recipe sets it. Written only when on.
    #[serde(skip_serializing_if = "is_zero")]
    pub collage_refine: usize,
    /// Rounds of the IoU polish after the fit
    /// ([`polish`](crate::problems::image::polish): the fitted maps moved to raise their
    /// attractor's IoU with the picture's ink read at 256², 0: off). Written only when on.
    #[serde(skip_serializing_if = "is_zero")]
    pub polish: usize,
    /// Which of the collage search's starts the run takes, best first
    /// ([`ranked_starts`](crate::problems::image::init::ranked_starts): 0, the default, is
    /// the collage start or the EM start, whichever matches the ink better; 1, 2, … the
    /// next distinct ones by the same score). Set per run by `best_of_starts = "ranked"`.
    /// Written only when not 0.
    #[serde(skip_serializing_if = "is_zero")]
    pub start_rank: usize,
    /// How the chaos game of the differentiable renderer picks maps: `uniform` (the
    /// chaotic-splatting paper's generator) or `determinant` (∝ |det M|, no floor: Learning
    /// Fractals). Evaluation renders always use |det| with a 1% floor.
    #[serde(skip_serializing_if = "MapProbabilities::is_uniform")]
    pub probabilities: MapProbabilities,
}

fn is_zero(v: &usize) -> bool {
    *v == 0
}

impl ModelConfig {
    /// The model this config names (its `family`, with its `parameterisation`).
    pub fn build(&self) -> Result<Box<dyn crate::problems::image::AnyModel>> {
        let entry = crate::problems::image::find_model(&self.family)?;
        // Only affine maps have parameterisations; a non-default one elsewhere would be
        // silently ignored, so it is refused.
        if self.family != "affine"
            && self.parameterisation != ModelConfig::default().parameterisation
        {
            return Err(Error::InvalidInput(format!(
                "`parameterisation = \"{}\"` applies to affine maps; family `{}` has its own \
                 (remove the key)",
                self.parameterisation.build().name(),
                self.family
            )));
        }
        Ok((entry.build)(self))
    }
}

impl Default for ModelConfig {
    fn default() -> Self {
        ModelConfig {
            family: "affine".into(),
            maps: 3,
            parameterisation: ParamKind::Svd,
            init: InitKind::Random,
            init_seed: None,
            init_code: None,
            init_noise: 0.0,
            em_reflections: false,
            em_affine: 0,
            start_size: None,
            collage_refine: 0,
            polish: 0,
            start_rank: 0,
            probabilities: MapProbabilities::Uniform,
        }
    }
}

/// How the initial code is chosen when no `init_code` is given.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum InitKind {
    /// An Anderson–Farrell random code (the paper's start).
    Random,
    /// EM on points sampled from the target image.
    #[default]
    Em,
    /// Affine copies of the target found inside the target, assembled into a cover
    /// ([`collage`](crate::problems::image::collage)), or the EM start where its attractor
    /// matches the target better ([`collage_or_em`](crate::problems::image::init::collage_or_em)):
    /// ifslab's recipe.
    Collage,
}

/// One model family a config can name.
pub struct ModelEntry {
    /// Its name in `[model] family`.
    pub name: &'static str,
    /// One line for the docs.
    pub about: &'static str,
    /// The model for a (validated) model config.
    pub build: fn(&ModelConfig) -> Box<dyn AnyModel>,
}

/// Every model family, by name. Adding a map type to image inversion is one entry here (and
/// its [`ImageModel`]).
pub const MODELS: &[ModelEntry] = &[
    ModelEntry {
        name: "affine",
        about: "general affine maps under `parameterisation` (the paper's model)",
        build: |c| Box::new(AffineModel(c.parameterisation.build())),
    },
    ModelEntry {
        name: "similitude",
        about: "direct similitudes s·R(φ)·x + t, θ = (s, φ, tx, ty) per map",
        build: |_| Box::new(SimilitudeModel),
    },
    ModelEntry {
        name: "flame",
        about: "flame transforms w_lin·(A·x + b) + w_sin·sin(A·x + b), θ = (a…f, w_lin, w_sin) per \
                map (not affine: the run writes fit.json)",
        build: |_| Box::new(FlameModel),
    },
];

/// Model families registered from outside this crate ([`register_model`]).
static REGISTERED: std::sync::RwLock<Vec<&'static ModelEntry>> = std::sync::RwLock::new(Vec::new());

/// Every model family a config can name: [`MODELS`], then the registered ones.
pub fn models() -> Vec<&'static ModelEntry> {
    let registered = REGISTERED.read().unwrap_or_else(|e| e.into_inner());
    MODELS.iter().chain(registered.iter().copied()).collect()
}

/// Makes a model family defined outside this crate (its [`ImageModel`] behind
/// `build`) available to `[model] family = "…"` for the rest of the process. A name that
/// is taken is refused.
pub fn register_model(entry: ModelEntry) -> Result<()> {
    // Checked and added under one lock: two threads registering one name cannot both win.
    let mut registered = REGISTERED.write().unwrap_or_else(|e| e.into_inner());
    if MODELS
        .iter()
        .chain(registered.iter().copied())
        .any(|m| m.name == entry.name)
    {
        return Err(Error::InvalidInput(format!(
            "a model family called `{}` is already registered",
            entry.name
        )));
    }
    // Registered once per process and kept to its end: a 'static entry like MODELS'.
    registered.push(Box::leak(Box::new(entry)));
    Ok(())
}

/// The entry named `name`, or an error listing the known ones.
pub fn find_model(name: &str) -> Result<&'static ModelEntry> {
    let all = models();
    all.iter().find(|m| m.name == name).copied().ok_or_else(|| {
        Error::InvalidInput(format!(
            "unknown model family `{name}` (known: {})",
            all.iter().map(|m| m.name).collect::<Vec<_>>().join(", ")
        ))
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use ifslab::model::Map;

    #[test]
    fn similitude_encoding_keeps_similitudes_and_projects_the_rest() {
        let s = Similitude2::new(0.5, 0.7, false, [0.2, -0.1]);
        let th = ImageModel::encode(&SimilitudeModel, &[s.to_affine()]).unwrap();
        let back = SimilitudeModel.decode(&th).unwrap();
        let (p, q) = (back[0].apply([0.3, 0.9]), s.apply([0.3, 0.9]));
        assert!((p[0] - q[0]).abs() < 1e-12 && (p[1] - q[1]).abs() < 1e-12);
        // An expanding map is brought back to a contraction.
        let th = ImageModel::encode(
            &SimilitudeModel,
            &[Affine2::new(2.0, 0.0, 0.0, 2.0, 0.0, 0.0)],
        )
        .unwrap();
        assert_eq!(th[0], SimilitudeModel::MAX_SCALE);
    }

    #[test]
    fn bad_theta_is_refused_with_its_place() {
        let e = SimilitudeModel.decode(&[0.5, 0.0, 0.0]).unwrap_err();
        assert!(e.to_string().contains("4 parameters per map"), "{e}");
        let e = SimilitudeModel
            .decode(&[0.5, 0.0, 0.0, 0.0, 0.5, f64::NAN, 0.0, 0.0])
            .unwrap_err();
        assert!(e.to_string().contains("map 1, parameter 1"), "{e}");
        assert!(find_model("nope").is_err());
    }
}
