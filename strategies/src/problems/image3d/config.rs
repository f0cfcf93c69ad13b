//! A multi-view inversion's settings: how many maps, the start, the strategy, the splat,
//! the loss and the hull, with defaults and checks that name the field to change.

use ifslab::chaos::ChaosGame;
use ifslab::loss::MsMse;
use ifslab::model::ProbabilityRule;
use ifslab::model::map3::{Affine3, SvdMap3};
use ifslab::render::splat3d::MultiViewConfig;
use serde::{Deserialize, Serialize};
use std::path::PathBuf;

use crate::error::{Error, Result};
use crate::optim::adam::AdamConfig;
use crate::problems::image3d::hull::HullConfig;
use crate::strategy_config::StrategyConfig;

/// Where the fit starts.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Start3d {
    /// EM in 3-D on points of the visual hull (the baseline; the default until the collage
    /// start).
    Hull,
    /// Random SVD maps drawn from the seed.
    Random,
    /// The collage search in space ([`crate::problems::image3d::collage`]): affine copies
    /// of the hull inside the hull, the cover whose silhouettes match the views best — or
    /// the hull's EM code where its silhouettes match them better. The default: on the
    /// tuning split's eight random 4-map codes it raised the fits' mean voxel IoU from
    /// 0.636 to 0.984 (README, "In 3-D").
    #[default]
    Collage,
    /// A code of space read from a file (`start_code`): a previous fit's `code.json`, or
    /// the truth, to see whether the loss keeps it.
    Code,
}

/// How the chaos game picks the maps of a code that carries no probabilities: in the
/// fit's renders, its point cloud, its turntable and its scores.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum MapChoice {
    /// Every map equally likely.
    Uniform,
    /// `pᵢ ∝ max(|det Mᵢ| / Σ|det M|, 0.01)`, renormalised: the library's rule for codes
    /// without probabilities (`ProbabilityRule::default`, what 2-D codes are drawn with).
    /// A fern's frond map, applied again and again up its tip, is drawn by it about as
    /// often as the fern's own probabilities draw it; uniformly, its tip is left with
    /// too few points to ink the views or fill the voxels (the true fern scores 0.56
    /// against itself, drawn uniformly).
    #[default]
    Determinant,
}

impl MapChoice {
    /// The probabilities of maps with the absolute determinants `abs_dets` (`None`:
    /// uniform).
    pub fn resolve(self, abs_dets: &[f64]) -> Option<Vec<f64>> {
        match self {
            MapChoice::Uniform => None,
            MapChoice::Determinant => ProbabilityRule::default().resolve(abs_dets).ok(),
        }
    }

    /// [`MapChoice::resolve`] for SVD maps.
    pub fn for_svd(self, maps: &[SvdMap3]) -> Option<Vec<f64>> {
        let dets: Vec<f64> = maps
            .iter()
            .map(|m| m.singular_values().iter().map(|s| s.abs()).product())
            .collect();
        self.resolve(&dets)
    }

    /// [`MapChoice::resolve`] for affine maps.
    pub fn for_affine(self, maps: &[Affine3]) -> Option<Vec<f64>> {
        let dets: Vec<f64> = maps.iter().map(|m| m.m.determinant().abs()).collect();
        self.resolve(&dets)
    }
}

/// The multi-view splat's settings for a fit.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Render3dConfig {
    /// Supersampling factor per side.
    pub supersample: usize,
    /// σ (supersampled pixels) at the start.
    pub sigma: f64,
    /// σ at the end, reached geometrically (coarse to fine); `None`: σ fixed.
    pub sigma_final: Option<f64>,
    /// Chaos-game trajectories per step; `None`: by the views' size
    /// ([`Render3dConfig::trajectories_for`]).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub trajectories: Option<usize>,
    /// Steps per trajectory.
    pub length: usize,
    /// Steps dropped at the start of each trajectory.
    pub warmup: usize,
}

impl Default for Render3dConfig {
    /// The setting chosen on the tuning split of views drawn by another program
    /// (`scripts/render3d_views.py`: crisp cells, 8 views × 64²): 4× supersampling, σ 1.5 →
    /// 0.5, 400 trajectories of 150 kept points per 64² of a view (as many points per view
    /// pixel at any size: [`Render3dConfig::trajectories_for`]). σ ending at 1 drew thin parts twice as
    /// wide as such views hold them (the true fern's renders carry 2.0× the views' ink at
    /// σ 1, 1.4× at 0.5), so the loss preferred other codes; ending at 0.5 raised the
    /// tuning split's random codes from 0.564 to 0.648 (mean voxel IoU, maps drawn ∝
    /// |det|). Views drawn by this library's own blurred splat (`--render-views`, σ 0.8 at
    /// 1×) are fitted best at 1×, σ 1.5 → 0.8, 100 trajectories, without the ink guard
    /// (`tests/three_d_recovery.rs`).
    fn default() -> Self {
        Render3dConfig {
            supersample: 4,
            sigma: 1.5,
            sigma_final: Some(0.5),
            trajectories: None,
            length: 160,
            warmup: 10,
        }
    }
}

/// Trajectories per step for every 64² of a view's pixels, where the trajectories are not
/// named ([`Render3dConfig::trajectories_for`]).
pub const TRAJECTORIES_PER_64X64: usize = 400;

impl Render3dConfig {
    /// The trajectories per step for views of `w × h` pixels: the number named, else
    /// [`TRAJECTORIES_PER_64X64`] for every 64² of a view (1600 at 128²), so that a render
    /// holds as many points per view pixel as where the defaults were chosen. With 400 at
    /// 128², a correct code's renders at σ 0.5 hold 0.63–0.73 of the views' ink, the ink
    /// guard charges them, and the fit swells (the tuning split's tetrahedron: voxel IoU
    /// 0.98 at the start, 0.23 at the end; 1.000 with 1600).
    pub fn trajectories_for(&self, (w, h): (usize, usize)) -> usize {
        self.trajectories
            .unwrap_or_else(|| (TRAJECTORIES_PER_64X64 * w * h).div_ceil(64 * 64).max(1))
    }

    /// The multi-view splat's config (σ at the start) for views of `size` pixels.
    pub fn multi_view(&self, size: (usize, usize)) -> MultiViewConfig {
        MultiViewConfig {
            supersample: self.supersample,
            sigma: self.sigma,
            game: ChaosGame {
                trajectories: self.trajectories_for(size),
                length: self.length,
                warmup: self.warmup,
                start_half_width: 1.0,
                seed: 0,
            },
            ..MultiViewConfig::default()
        }
    }
}

fn default_strategy() -> StrategyConfig {
    StrategyConfig::new(&AdamConfig {
        lr: 0.03,
        ..AdamConfig::default()
    })
}

/// A multi-view inversion (see [`crate::problems::image3d`]).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Image3dConfig {
    /// Number of maps.
    pub maps: usize,
    /// Strategy iterations.
    pub iterations: u64,
    /// Seed of the hull's points, EM, the random start and every step's trajectories.
    pub seed: u64,
    /// Where the fit starts.
    pub start: Start3d,
    /// The code a `start = "code"` fit starts from (a 3-D code file).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub start_code: Option<PathBuf>,
    /// How the chaos game picks the maps of the fit and of the baseline (their renders,
    /// point clouds and scores).
    pub probabilities: MapChoice,
    /// Any registered strategy (default: Adam, rate 0.03).
    #[serde(default = "default_strategy")]
    pub strategy: StrategyConfig,
    /// The splat.
    pub render: Render3dConfig,
    /// Poolings of the multi-scale MSE on each view (0: the plain MSE).
    pub loss_levels: usize,
    /// Weight of `Σᵢ |det Mᵢ|` in the loss (`Image3dProblem::with_volume`; 0: off). The
    /// default 0.01 turns the Sierpiński tetrahedron's fit from 8 views of 64² from a solid
    /// (voxel IoU 0.46 with 0) into the tetrahedron (0.994–1.000 over 4 seeds).
    pub volume: f64,
    /// Weight of the ink guard (`Image3dProblem::with_ink`: the mean over views of
    /// `max(0, 1 − slack − ink of the render / ink of the view)²`; 0: off). The default 3
    /// was chosen on the tuning split (mean voxel IoU of 4 random codes and the fern 0.583
    /// against 0.450 without it, 0.558 with 1, 0.531 with 10).
    pub ink: f64,
    /// Fraction of a view's ink a render may lack before the ink guard charges, in [0, 1).
    pub ink_slack: f64,
    /// Views held out of the fit (and of the hull), spread evenly around the list
    /// (`Views::hold_out`): the summary scores baseline and fit on them (0: none).
    pub hold_out: usize,
    /// The visual hull and its EM fit.
    pub hull: HullConfig,
    /// Checkpoint every this many iterations (0: never).
    pub checkpoint_every: u64,
}

impl Default for Image3dConfig {
    fn default() -> Self {
        Image3dConfig {
            maps: 4,
            iterations: 150,
            seed: 0,
            start: Start3d::Collage,
            start_code: None,
            probabilities: MapChoice::Determinant,
            strategy: default_strategy(),
            render: Render3dConfig::default(),
            loss_levels: 0,
            volume: 0.01,
            ink: 3.0,
            ink_slack: 0.0,
            hold_out: 0,
            hull: HullConfig::default(),
            checkpoint_every: 0,
        }
    }
}

impl Image3dConfig {
    /// The loss on each view.
    pub fn loss(&self) -> MsMse {
        MsMse::new(self.loss_levels)
    }

    /// Checks every field; the error names the one to change.
    pub fn validate(&self) -> Result<()> {
        if !(1..=32).contains(&self.maps) {
            return Err(Error::param(
                "maps",
                format!("must lie in 1..=32, got {}", self.maps),
            ));
        }
        match (self.start, &self.start_code) {
            (Start3d::Code, None) => {
                return Err(Error::param(
                    "start_code",
                    "a fit that starts from a code needs the code's file",
                ));
            }
            (Start3d::Hull | Start3d::Random | Start3d::Collage, Some(_)) => {
                return Err(Error::param(
                    "start_code",
                    "is read only when the fit starts from a code (start = \"code\")",
                ));
            }
            _ => {}
        }
        if self.iterations == 0 {
            return Err(Error::param("iterations", "must be at least 1"));
        }
        if let Some(s) = self.render.sigma_final
            && !(s.is_finite() && s > 0.0)
        {
            return Err(Error::param(
                "render.sigma_final",
                format!("must be finite and > 0, got {s}"),
            ));
        }
        if self.loss_levels > 16 {
            return Err(Error::param(
                "loss_levels",
                format!("must be at most 16, got {}", self.loss_levels),
            ));
        }
        if !(self.volume.is_finite() && self.volume >= 0.0) {
            return Err(Error::param(
                "volume",
                format!("must be finite and ≥ 0, got {}", self.volume),
            ));
        }
        if !(self.ink.is_finite() && self.ink >= 0.0) {
            return Err(Error::param(
                "ink",
                format!("must be finite and ≥ 0, got {}", self.ink),
            ));
        }
        if !(0.0..1.0).contains(&self.ink_slack) {
            return Err(Error::param(
                "ink_slack",
                format!("must lie in [0, 1), got {}", self.ink_slack),
            ));
        }
        if self.render.trajectories == Some(0) {
            return Err(Error::param("render.trajectories", "must be at least 1"));
        }
        self.render.multi_view((64, 64)).validate()?;
        self.strategy.validate()?;
        self.hull.validate()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn unnamed_trajectories_follow_the_views_pixels() {
        let auto = Render3dConfig::default();
        assert_eq!(auto.trajectories_for((64, 64)), 400);
        assert_eq!(auto.trajectories_for((128, 128)), 1600);
        assert_eq!(auto.trajectories_for((128, 64)), 800);
        assert_eq!(auto.trajectories_for((8, 8)), 7);
        assert_eq!(auto.trajectories_for((1, 1)), 1);
        assert_eq!(auto.multi_view((128, 128)).game.trajectories, 1600);
        let named = Render3dConfig {
            trajectories: Some(100),
            ..Render3dConfig::default()
        };
        assert_eq!(named.trajectories_for((128, 128)), 100);
    }

    /// A saved config that names its trajectories keeps them; one that does not is written
    /// without the key and reads back as "by the views' size".
    #[test]
    fn trajectories_round_trip_through_toml() {
        let old: Render3dConfig = toml::from_str("trajectories = 400\nsupersample = 1").unwrap();
        assert_eq!(old.trajectories, Some(400));
        let text = toml::to_string(&Render3dConfig::default()).unwrap();
        assert!(!text.contains("trajectories"), "{text}");
        let back: Render3dConfig = toml::from_str(&text).unwrap();
        assert_eq!(back, Render3dConfig::default());
        let zero = Image3dConfig {
            render: Render3dConfig {
                trajectories: Some(0),
                ..Render3dConfig::default()
            },
            ..Image3dConfig::default()
        };
        assert!(zero.validate().is_err());
    }
}
