//! What a finished image run recovered, as its model draws it: the fitted maps of any
//! family behind [`Recovered`] — their evaluation render, their probabilities, the point a
//! zoom strip closes in on, their affine form where they have one, whether they contract.
//! The file that keeps θ with the model that decodes it is [`FitFile`](super::fit::FitFile).

use ifslab::model::{Affine2, AffinePart, IfsCode, ProbabilityRule};
use ifslab::render::{Raster, RenderConfig, render};

use crate::error::{Error, Result};

/// The maps a run recovered, of whatever family, as its outputs need them. Made by
/// [`AnyModel::recovered`](crate::problems::image::AnyModel::recovered) for a θ, or by
/// [`Fitted`] for maps in hand.
pub trait Recovered: Send + Sync {
    /// The number of maps.
    fn n_maps(&self) -> usize;

    /// The evaluation renderer's probabilities: ∝ |det| of each map's affine part with the
    /// evaluation floor ([`ProbabilityRule::default`]), or the code's own.
    fn probabilities(&self) -> &[f64];

    /// The maps as affine maps, where they are affine (the code file, the IoU polish and
    /// the deep zoom need them).
    fn affine(&self) -> Option<&[Affine2]>;

    /// The maps drawn by the evaluation renderer (the chaos game: any map type).
    fn render(&self, cfg: &RenderConfig) -> Result<Raster>;

    /// A point of the attractor with detail around it: the fixed point of `f₀∘f₁` (of `f₀`
    /// for one map), where it exists.
    fn detail_point(&self) -> Option<[f64; 2]>;

    /// Whether every map contracts: the affine maps' largest singular value below 1, or,
    /// for non-linear maps, their affine parts' (the bound the regulariser keeps).
    fn contractive(&self) -> bool;
}

impl std::fmt::Debug for dyn Recovered {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Recovered")
            .field("maps", &self.n_maps())
            .field("probabilities", &self.probabilities())
            .field("affine", &self.affine())
            .finish()
    }
}

/// Maps of one type with their evaluation probabilities: the one [`Recovered`].
#[derive(Clone, Debug)]
pub struct Fitted<M> {
    maps: Vec<M>,
    probs: Vec<f64>,
    affine: Option<Vec<Affine2>>,
}

impl<M: AffinePart + Send + Sync> Fitted<M> {
    /// `maps` with the evaluation probabilities of their affine parts.
    pub fn new(maps: Vec<M>) -> Result<Self> {
        Fitted::with(maps, None)
    }

    /// `maps` drawn with the probabilities `probs` (a code file's own).
    pub fn with_probabilities(maps: Vec<M>, probs: Vec<f64>) -> Result<Self> {
        if probs.len() != maps.len() {
            return Err(Error::InvalidInput(format!(
                "{} probabilities for {} maps",
                probs.len(),
                maps.len()
            )));
        }
        Fitted::with(maps, Some(probs))
    }

    fn with(maps: Vec<M>, probs: Option<Vec<f64>>) -> Result<Self> {
        if maps.is_empty() {
            return Err(Error::InvalidInput("a recovered code has no maps".into()));
        }
        let affine: Option<Vec<Affine2>> = maps.iter().map(Affine2::of_map).collect();
        let probs = match (probs, &affine) {
            (Some(p), _) => p,
            // Through the code type, as the code file computes them (the same bits).
            (None, Some(a)) => unchecked_code(a).evaluation_probabilities()?,
            (None, None) => ProbabilityRule::default().resolve(
                &maps
                    .iter()
                    .map(|m| m.affine_part().det().abs())
                    .collect::<Vec<_>>(),
            )?,
        };
        Ok(Fitted {
            maps,
            probs,
            affine,
        })
    }

    /// The maps.
    pub fn maps(&self) -> &[M] {
        &self.maps
    }
}

/// A code of `maps` without its validation (the probabilities of an expanding map are still
/// defined; [`Recovered::contractive`] says whether it is an IFS).
fn unchecked_code(maps: &[Affine2]) -> IfsCode {
    IfsCode {
        name: None,
        maps: maps.iter().map(Affine2::to_affine_n).collect(),
        probabilities: None,
        framing: None,
        allow_non_contractive: true,
        meta: Default::default(),
    }
}

impl<M: AffinePart + Send + Sync> Recovered for Fitted<M> {
    fn n_maps(&self) -> usize {
        self.maps.len()
    }

    fn probabilities(&self) -> &[f64] {
        &self.probs
    }

    fn affine(&self) -> Option<&[Affine2]> {
        self.affine.as_deref()
    }

    fn render(&self, cfg: &RenderConfig) -> Result<Raster> {
        // Affine maps are drawn as `Affine2`s: the renderer's tuned path and the deep zoom.
        Ok(match &self.affine {
            Some(a) => render(a, &self.probs, cfg, None)?,
            None => render(&self.maps, &self.probs, cfg, None)?,
        })
    }

    fn detail_point(&self) -> Option<[f64; 2]> {
        if let Some(a) = &self.affine {
            return match a.as_slice() {
                [f, g, ..] => f.compose(g).fixed_point(),
                [f] => f.fixed_point(),
                [] => None,
            };
        }
        // Non-linear maps: iterate f₀∘f₁ from its affine parts' fixed point (a contraction
        // converges; one that wanders off has no point to show).
        let (f, g) = match self.maps.as_slice() {
            [f, g, ..] => (f, g),
            [f] => (f, f),
            [] => return None,
        };
        let mut x = f
            .affine_part()
            .compose(&g.affine_part())
            .fixed_point()
            .unwrap_or([0.0, 0.0]);
        for _ in 0..200 {
            x = f.apply(g.apply(x));
        }
        let next = f.apply(g.apply(x));
        let close = (next[0] - x[0]).hypot(next[1] - x[1]) <= 1e-9 * (1.0 + x[0].hypot(x[1]));
        (x.iter().all(|v| v.is_finite()) && close).then_some(x)
    }

    fn contractive(&self) -> bool {
        match &self.affine {
            Some(a) => IfsCode::from_affine2(None, a).is_ok(),
            None => self.maps.iter().all(|m| {
                let a = m.affine_part();
                a.coefficients().iter().all(|v| v.is_finite()) && a.singular_values().0 < 1.0
            }),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::problems::image::FlameModel;
    use crate::problems::image::model::ImageModel;
    use ifslab::model::{Map, library};

    #[test]
    fn affine_results_keep_the_code_files_numbers() {
        let code = library::builtin("fern").unwrap();
        let maps = code.affine2().unwrap();
        let fit = Fitted::new(maps.clone()).unwrap();
        assert_eq!(fit.affine(), Some(maps.as_slice()));
        assert_eq!(
            fit.probabilities(),
            IfsCode::from_affine2(None, &maps)
                .unwrap()
                .evaluation_probabilities()
                .unwrap()
        );
        assert_eq!(fit.detail_point(), maps[0].compose(&maps[1]).fixed_point());
        assert!(fit.contractive());
        let mut expanding = maps;
        expanding[1].m *= 1.5;
        assert!(!Fitted::new(expanding).unwrap().contractive());
        assert!(Fitted::<Affine2>::new(vec![]).is_err());
    }

    #[test]
    fn non_linear_results_find_their_own_fixed_point() {
        let start = library::builtin("sierpinski").unwrap().affine2().unwrap();
        let mut theta = ImageModel::encode(&FlameModel, &start).unwrap();
        // Bend every map: w_lin 0.7, w_sin 0.3.
        for p in theta.chunks_exact_mut(FlameModel::PARAMS) {
            (p[6], p[7]) = (0.7, 0.3);
        }
        let maps = FlameModel.decode(&theta).unwrap();
        let fit = Fitted::new(maps.clone()).unwrap();
        assert!(fit.affine().is_none() && fit.contractive());
        let x = fit.detail_point().expect("a contraction has one");
        let y = maps[0].apply(maps[1].apply(x));
        assert!((x[0] - y[0]).abs() < 1e-9 && (x[1] - y[1]).abs() < 1e-9);
        // Not where the affine steps alone would put it.
        let affine = start[0].compose(&start[1]).fixed_point().unwrap();
        assert!((x[0] - affine[0]).hypot(x[1] - affine[1]) > 1e-3);
        // The probabilities are the affine steps' (the evaluation rule).
        let dets: Vec<f64> = start.iter().map(|m| m.det().abs()).collect();
        assert_eq!(
            fit.probabilities(),
            ProbabilityRule::default().resolve(&dets).unwrap()
        );
    }
}
