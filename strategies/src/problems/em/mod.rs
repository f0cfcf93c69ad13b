//! Expectation–maximisation for IFSs of similitudes fitted to point clouds in any dimension
//! (Bloem & de Rooij).
//!
//! An IFS of K similitudes `S_k(x) = s_k·R_k·x + t_k` with weights w defines, at depth D, a
//! Gaussian mixture: every code `c` of length 0 … D pushes the standard Gaussian through
//! `P ∘ S_c` (P a post-transform from the model frame to data space) and weighs it by
//! `v_|c|·Π_j w_{c_j}` (v the depth weights). EM alternates
//!
//! 1. **E-step** ([`estep`]): the responsibility of every code for every point of a minibatch
//!    of N′ points, in log space, parallel over points, reduced to per-code sums;
//! 2. **M-step** ([`mstep`]): weights and depth weights as responsibility shares; each
//!    component by a weighted similitude Procrustes fit (translation from weighted means,
//!    rotation from the SVD of the weighted cross-covariance with a determinant fix, scale
//!    from its stationarity equation); then the post-transform the same way.
//!
//! [`init`] draws K random fixed points on the unit sphere with scale ½ and Haar rotations;
//! [`preselect`] trains a pool of such starts briefly — by default through depths 1, 2, 3
//! in turn — and keeps the best; [`fit()`] then trains it at depth D. [`reorient`]
//! turns each component's piece in place to the orientation with the highest likelihood,
//! between pre-selection stages and every 100 main iterations: EM itself only moves
//! rotations locally, and nearly symmetric attractors trap it with a piece turned the wrong
//! way. A run has converged when at least 95% of the depth weight sits on depth D.
//! [`EmConfig::paper`] is the paper's algorithm; the defaults add the re-orientation search
//! and [`EmModel::recentred`], which measurably make far more runs converge, and differ in
//! three pre-selection and M-step choices (`paper_repro/ifs_em/README.md` measures each).
//! [`gmm`] fits isotropic
//! and full-covariance Gaussian mixtures as held-out likelihood baselines; [`data`] loads CSV
//! and `.npy` point clouds of any dimension.
//!
//! ```no_run
//! use ifslab_strategies::problems::em::{EmConfig, PointSet, fit};
//! let data = PointSet::load("points.csv")?;
//! let (train, test) = data.split(0.1, 0)?;
//! let cfg = EmConfig { components: 3, depth: 6, ..EmConfig::default() };
//! let result = fit(&train, Some(&test), &cfg, &mut |_| {})?;
//! println!("held-out: {} nats/point", result.model.mean_log_likelihood(&test)?);
//! result.model.to_code(Some("fit"))?.save("fit.json")?;
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
//!
//! ## References
//! - P. Bloem and S. de Rooij, *An Expectation-Maximization Algorithm for the Fractal
//!   Inverse Problem*, arXiv:1706.03149, 2017.
//! - S. Umeyama, *Least-squares estimation of transformation parameters between two point
//!   patterns*, IEEE TPAMI 13(4), 1991.

pub mod config;
pub mod data;
pub mod estep;
pub mod fit;
pub mod gmm;
pub mod init;
pub mod model;
pub mod mstep;
pub mod preselect;
pub mod reorient;
pub mod train;
pub mod words;

pub use config::{EmConfig, MAX_CODES, PreselectBy, code_count};
pub use data::PointSet;
pub use fit::{EmFit, Event, check_data, fit, fit_all};
pub use gmm::{Covariance, Gmm, GmmConfig};
pub use model::{CodeTable, EmModel};
pub use mstep::{
    ComponentUpdate, Degeneracy, MStepConfig, Part, nearest_orthogonal, proper_rotation,
};
pub use preselect::Candidate;
pub use reorient::{ReorientConfig, Reorientation};
pub use train::{IterationRecord, ReorientStep, Schedule, StepInfo, em_step, train};
pub use words::{Unwind, Unwinding, WordMoves};
