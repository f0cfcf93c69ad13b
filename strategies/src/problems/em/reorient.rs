//! Re-orientation search: for each component in turn, try turning its piece of the attractor
//! in place and keep the orientation with the highest likelihood.
//!
//! EM moves a component's rotation only locally, and an attractor that is nearly symmetric
//! makes a wrongly turned piece a stable optimum: on the Sierpiński triangle with vertices
//! (0,0), (1,0), (0.5,1) a map rotated by ±120° covers its corner almost as well as the
//! right one, and EM from a random start stopped there in most runs. Here component k is
//! replaced by `S_k ∘ Q_c` for each rotation Q of a fixed set, where `Q_c(x) = Q(x − c) + c`
//! turns the model's attractor about the mean c of its invariant measure: the piece
//! `S_k(A)` stays where it is and only its content turns. Each candidate is scored by the
//! mean log-likelihood of a fixed set of evaluation points; a candidate is taken when it
//! beats the current model by more than [`MIN_GAIN`] nats per point. Components are visited
//! in order, each against the model with the earlier ones already turned (coordinate
//! ascent), so the likelihood on the evaluation points never falls.
//!
//! The rotation set is a regular grid of angles in 2-D and seeded Haar-random rotations in
//! higher dimensions (SO(1) is trivial, so there is nothing to try in 1-D). The candidates
//! of one component are scored in parallel and chosen by (likelihood, index), so the result
//! does not depend on the thread count. A set of more than [`SCREEN_ABOVE`] is screened on
//! an eighth of the points first, its best [`SCREEN_KEEP`] scored on all.
//!
//! This step is not in the paper; `paper_repro/ifs_em/README.md` measures what it changes.

use nalgebra::{DMatrix, DVector};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use ifslab::chaos::trajectory_rng;
use ifslab::model::Similitude;
use ifslab::model::similitude::random_rotation;

use crate::error::{Error, Result};
use crate::problems::em::data::PointSet;
use crate::problems::em::model::EmModel;

/// A turned component must beat the current model by this much (mean nats per evaluation
/// point), so that noise-level differences do not move it.
pub const MIN_GAIN: f64 = 1e-3;

/// With more candidate orientations than this (mirror images counted; 128 keeps the
/// default 36 and their mirrors, and every committed run, unscreened), every one is first
/// scored on a strided [`SCREEN_SHARE`]-th of the evaluation points and only the best
/// [`SCREEN_KEEP`] on all of them: a wrong orientation of a piece costs nats per point, far
/// above the screening's noise, so a large set costs about an eighth of scoring it in full.
pub const SCREEN_ABOVE: usize = 128;
/// The share of the evaluation points (one in this many) that screens a large set.
pub const SCREEN_SHARE: usize = 8;
/// Orientations kept from the screening and scored on every evaluation point.
pub const SCREEN_KEEP: usize = 16;

/// How the re-orientation search runs.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ReorientConfig {
    /// Orientations per component, the current one included: in 2-D the turns by
    /// `360°·j/n`, in higher dimensions n − 1 random rotations. 0 turns the search off.
    pub rotations: usize,
    /// In the main run, search after every this many iterations (0: never in the main run;
    /// the pre-selection candidates are searched at every depth of their curriculum).
    pub every: usize,
    /// Run the word search ([`crate::problems::em::words`]) before each search of the main
    /// run (not in pre-selection).
    pub words: bool,
}

impl Default for ReorientConfig {
    fn default() -> Self {
        ReorientConfig {
            rotations: 12,
            every: 100,
            words: true,
        }
    }
}

impl ReorientConfig {
    /// Off: no re-orientation anywhere (the paper's algorithm).
    pub fn off() -> Self {
        ReorientConfig {
            rotations: 0,
            every: 0,
            words: false,
        }
    }

    /// Whether the orientation search runs at all.
    pub fn enabled(&self) -> bool {
        self.rotations >= 2
    }

    /// Checks the fields; the error names the one to change.
    pub fn validate(&self) -> Result<()> {
        if self.rotations == 1 {
            return Err(Error::param(
                "reorient.rotations",
                "1 would only try the current orientation; use 0 (off) or at least 2",
            ));
        }
        Ok(())
    }
}

/// One component turned by the search.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Reorientation {
    /// The component.
    pub component: usize,
    /// Index of the rotation in the set that won.
    pub rotation: usize,
    /// Mean log-likelihood gained on the evaluation points (nats per point).
    pub gain: f64,
}

/// The alternatives to the identity the search tries in dimension `h`: `n − 1` turns by
/// `360°·j/n` in 2-D, `n − 1` Haar-random rotations from a generator seeded by `seed` in
/// higher dimensions, none in 1-D or when `n < 2`.
pub fn rotation_set(h: usize, n: usize, seed: u64) -> Vec<DMatrix<f64>> {
    if n < 2 || h < 2 {
        return Vec::new();
    }
    if h == 2 {
        return (1..n)
            .map(|j| {
                let a = std::f64::consts::TAU * j as f64 / n as f64;
                let (s, c) = a.sin_cos();
                DMatrix::from_row_slice(2, 2, &[c, -s, s, c])
            })
            .collect();
    }
    let mut rng = trajectory_rng(seed, 0);
    (1..n).map(|_| random_rotation(h, &mut rng)).collect()
}

/// [`rotation_set`], and with `reflections` every orientation mirrored as well (the
/// identity's mirror image included): the set a search over orthogonal maps of either
/// determinant tries.
pub fn orientation_set(h: usize, n: usize, seed: u64, reflections: bool) -> Vec<DMatrix<f64>> {
    let turns = rotation_set(h, n, seed);
    if !reflections || turns.is_empty() {
        return turns;
    }
    let mut flip = DMatrix::<f64>::identity(h, h);
    flip[(h - 1, h - 1)] = -1.0;
    let mirrored: Vec<DMatrix<f64>> = std::iter::once(flip.clone())
        .chain(turns.iter().map(|q| q * &flip))
        .collect();
    turns.into_iter().chain(mirrored).collect()
}

/// The mean log-likelihood of `points` under `model` with component `k` replaced by
/// `candidate`; −∞ where it is not finite, so that such a candidate is never chosen.
pub(crate) fn replaced_score(
    model: &EmModel,
    k: usize,
    candidate: &Similitude,
    points: &PointSet,
) -> Result<f64> {
    let mut m = model.clone();
    m.components[k] = candidate.clone();
    let ll = m.mean_log_likelihood(points)?;
    Ok(if ll.is_finite() {
        ll
    } else {
        f64::NEG_INFINITY
    })
}

/// `S ∘ Q_c`: the similitude `s` preceded by the rotation `q` about `c`.
fn turned(s: &Similitude, q: &DMatrix<f64>, c: &DVector<f64>) -> Similitude {
    let shift = c - q * c;
    Similitude {
        s: s.s,
        r: &s.r * q,
        t: &s.t + (&s.r * shift) * s.s,
    }
}

/// Runs the search once over every component of `model` (see the module docs), scoring on
/// `points`. Returns the new model and the components it turned.
pub fn reorient(
    model: &EmModel,
    points: &PointSet,
    rotations: &[DMatrix<f64>],
) -> Result<(EmModel, Vec<Reorientation>)> {
    if points.is_empty() {
        return Err(Error::InvalidInput(
            "the re-orientation search needs at least one evaluation point".into(),
        ));
    }
    let h = model.dim();
    if let Some(bad) = rotations
        .iter()
        .position(|q| q.nrows() != h || q.ncols() != h)
    {
        return Err(Error::InvalidInput(format!(
            "rotation {bad} of the re-orientation set is {}×{}, the model is {h}-dimensional",
            rotations[bad].nrows(),
            rotations[bad].ncols()
        )));
    }
    let mut model = model.clone();
    let mut changes = Vec::new();
    if rotations.is_empty() {
        return Ok((model, changes));
    }
    let screen = (rotations.len() > SCREEN_ABOVE && points.len() >= SCREEN_SHARE * SCREEN_KEEP)
        .then(|| {
            let idx: Vec<usize> = (0..points.len()).step_by(SCREEN_SHARE).collect();
            points.select(&idx)
        });
    let mut base = model.mean_log_likelihood(points)?;
    for k in 0..model.k() {
        let Some((centre, _)) = model.invariant_moments() else {
            break;
        };
        let score = |q: &DMatrix<f64>, on: &PointSet| -> Result<(f64, Similitude)> {
            let candidate = turned(&model.components[k], q, &centre);
            Ok((replaced_score(&model, k, &candidate, on)?, candidate))
        };
        // The orientations scored on every point: all of them, or the screening's best.
        let finalists: Vec<usize> = match &screen {
            Some(few) => {
                let mut screened: Vec<(f64, usize)> = rotations
                    .par_iter()
                    .enumerate()
                    .map(|(j, q)| Ok((score(q, few)?.0, j)))
                    .collect::<Result<_>>()?;
                screened.sort_by(|a, b| b.0.total_cmp(&a.0).then(a.1.cmp(&b.1)));
                let mut keep: Vec<usize> =
                    screened.iter().take(SCREEN_KEEP).map(|&(_, j)| j).collect();
                keep.sort_unstable();
                keep
            }
            None => (0..rotations.len()).collect(),
        };
        let trials: Vec<(f64, Similitude)> = finalists
            .par_iter()
            .map(|&j| score(&rotations[j], points))
            .collect::<Result<_>>()?;
        let best = trials
            .iter()
            .enumerate()
            .max_by(|a, b| a.1.0.total_cmp(&b.1.0).then(b.0.cmp(&a.0)));
        if let Some((i, (ll, candidate))) = best
            && *ll > base + MIN_GAIN
        {
            changes.push(Reorientation {
                component: k,
                rotation: finalists[i],
                gain: ll - base,
            });
            model.components[k] = candidate.clone();
            base = *ll;
        }
    }
    Ok((model, changes))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn planar_set_is_a_grid_of_proper_rotations() {
        let set = rotation_set(2, 12, 0);
        assert_eq!(set.len(), 11);
        for (j, q) in set.iter().enumerate() {
            let angle = q[(1, 0)].atan2(q[(0, 0)]).to_degrees().rem_euclid(360.0);
            assert!((angle - 30.0 * (j + 1) as f64).abs() < 1e-9, "{angle}");
            assert!((q.determinant() - 1.0).abs() < 1e-12);
        }
        assert!(rotation_set(1, 12, 0).is_empty());
        assert!(rotation_set(3, 0, 0).is_empty());
        let three = rotation_set(3, 5, 9);
        assert_eq!(three.len(), 4);
        assert_eq!(three, rotation_set(3, 5, 9));
    }

    #[test]
    fn turning_keeps_the_piece_in_place() {
        // S ∘ Q_c maps the centre c where S does, whatever Q.
        let s = Similitude {
            s: 0.4,
            r: rotation_set(2, 8, 0)[0].clone(),
            t: DVector::from_row_slice(&[0.3, -0.2]),
        };
        let c = DVector::from_row_slice(&[0.1, 0.7]);
        for q in rotation_set(2, 7, 0) {
            let t = turned(&s, &q, &c);
            assert!((t.apply(&c) - s.apply(&c)).norm() < 1e-12);
            assert!((t.s - s.s).abs() < 1e-15);
        }
    }

    #[test]
    fn orientation_sets_with_reflections_hold_the_mirror_images() {
        let turns = orientation_set(2, 6, 0, false);
        assert_eq!(turns.len(), 5);
        assert!(turns.iter().all(|q| (q.determinant() - 1.0).abs() < 1e-12));
        let both = orientation_set(3, 6, 4, true);
        // Five turns, the mirror itself, and the five turns mirrored.
        assert_eq!(both.len(), 11);
        let mirrored = both.iter().filter(|q| q.determinant() < 0.0).count();
        assert_eq!(mirrored, 6);
        for q in &both {
            let e = (q.transpose() * q - DMatrix::<f64>::identity(3, 3)).amax();
            assert!(e < 1e-12);
        }
        assert!(orientation_set(2, 0, 0, true).is_empty());
    }
}
