//! Word search: a component that settled on a piece of the attractor one level too deep is
//! replaced by the map that piece is made of.
//!
//! EM has a second kind of stable wrong answer besides a wrongly turned piece (which
//! [`crate::problems::em::reorient`] handles): a component that fits a *word* of the true
//! code instead of a map of it. With true maps `S_1, S_2`, a model `{S_1∘S_1, S_2}` covers
//! the piece `S_1(A)` by its sub-piece `S_1(S_1(A))` and the rest by wide shallow-depth
//! Gaussians; its depth weight then sits at depths 1–3 and nothing pulls the component
//! back up, because every step towards `S_1` first moves the sub-piece away from the
//! points it covers. On the robustness suite's 3-D clouds this was the commonest failure:
//! fitted maps equal to `S_1∘S_1` (exactly, to 10⁻³) or to `S_3∘S_1` beside a correct
//! `S_1` (robustness/README.md).
//!
//! For component k the search tries the maps it would be made of if it were such a word:
//!
//! - `S_j⁻¹∘S_k` and `S_k∘S_j⁻¹` for every other component j (if `S_k = S_j∘X` or
//!   `S_k = X∘S_j`, these are X), where the scale `s_k/s_j` is a valid one;
//! - the square roots of `S_k` (if `S_k = X∘X`): `√s_k·Q` with `Q² = R_k` (the principal
//!   root, and `−Q` where it is allowed), about the same fixed point.
//!
//! Each candidate is scored like a re-orientation, by the mean log-likelihood of the
//! evaluation points with the other components unchanged. The best candidate of all
//! components is taken when it beats the current model by more than [`MIN_GAIN`], and the
//! search repeats (at most K times) until none does. Best first, not component by
//! component: with one component on a word, unwinding a *correct* one can also pay, and a
//! component made too large by it has no move back (visited in order, a test code lost
//! its right `S_1` that way before its wrong `S_2` was reached). The likelihood on the
//! evaluation points never falls; candidates are scored in parallel and chosen by
//! (likelihood, index), independent of the thread count.
//!
//! The search runs in the main run only, before each re-orientation search there (every
//! 100 iterations by default), where the model has its full depth. Pre-selection does not
//! run it: at depths 1–3 the likelihood also pays for unwinding right maps, and with the
//! search there too, the robustness suite's first tuning split lost two 3-D clouds that
//! the main-run search alone keeps.
//!
//! This step is not in the paper; `robustness/README.md` measures what it changes.

use nalgebra::DMatrix;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use ifslab::model::Similitude;

use crate::error::{Error, Result};
use crate::problems::em::data::PointSet;
use crate::problems::em::model::{EmModel, inverse};
use crate::problems::em::mstep::nearest_orthogonal;
pub use crate::problems::em::reorient::MIN_GAIN;
use crate::problems::em::reorient::replaced_score;

/// What the candidates may be: the scale bound and whether orthogonal parts may reflect.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WordMoves {
    /// Largest scale of a candidate (the M-step's bound).
    pub max_scale: f64,
    /// Whether a candidate's orthogonal part may have determinant −1.
    pub reflections: bool,
}

/// How a component was replaced.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Unwind {
    /// By `S_j⁻¹∘S_k` (the component was `S_j∘X`).
    After(usize),
    /// By `S_k∘S_j⁻¹` (the component was `X∘S_j`).
    Before(usize),
    /// By a square root (the component was `X∘X`): 0 the principal root `Q`, 1 `−Q`, 2
    /// (3-D) `Q` followed by the half turn about its axis, 3 that root negated.
    Root(usize),
}

/// One component replaced by the search.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Unwinding {
    /// The component.
    pub component: usize,
    /// What replaced it.
    pub by: Unwind,
    /// Mean log-likelihood gained on the evaluation points (nats per point).
    pub gain: f64,
}

/// The principal square root of a rotation `r` by the Denman–Beavers iteration, made
/// exactly orthogonal; `None` when `r` has −1 as an eigenvalue (a half turn has no
/// principal root) or the iteration does not settle.
pub fn rotation_sqrt(r: &DMatrix<f64>) -> Option<DMatrix<f64>> {
    let h = r.nrows();
    let mut y = r.clone();
    let mut z = DMatrix::<f64>::identity(h, h);
    for _ in 0..60 {
        let yi = y.clone().try_inverse()?;
        let zi = z.clone().try_inverse()?;
        let ny = (&y + zi) * 0.5;
        let nz = (&z + yi) * 0.5;
        let step = (&ny - &y).amax();
        y = ny;
        z = nz;
        if step < 1e-13 {
            break;
        }
    }
    let q = nearest_orthogonal(&y)?;
    ((&q * &q - r).amax() < 1e-6 && q.determinant() > 0.0).then_some(q)
}

/// The square roots of `Q²` tried, from its principal root `q`: `q` and `−q`, and in 3-D
/// also `q·H` and `−q·H` with `H = 2aaᵀ − I` the half turn about `q`'s axis `a` (if `R`
/// turns by φ, its proper roots turn by φ/2 and φ/2 + π about the same axis).
fn roots(q: DMatrix<f64>) -> Vec<(Unwind, DMatrix<f64>)> {
    let mut out = vec![(Unwind::Root(1), -&q)];
    if q.nrows() == 3 {
        // The axis: Q − Qᵀ = 2 sin θ [a]ₓ (near θ = 0 there is no axis to turn about).
        let w = &q - q.transpose();
        let a = nalgebra::Vector3::new(w[(2, 1)], w[(0, 2)], w[(1, 0)]);
        if a.norm() > 1e-9 {
            let a = a.normalize();
            let h = DMatrix::from_fn(3, 3, |i, j| {
                2.0 * a[i] * a[j] - if i == j { 1.0 } else { 0.0 }
            });
            let qh = &q * h;
            out.push((Unwind::Root(2), qh.clone()));
            out.push((Unwind::Root(3), -qh));
        }
    }
    out.insert(0, (Unwind::Root(0), q));
    out
}

/// `x ↦ s·Q·x + u` with the fixed point of `k`: the square root of `k` with orthogonal
/// part `q` (`q² = R_k`).
fn root_with(k: &Similitude, q: DMatrix<f64>) -> Option<Similitude> {
    let h = k.dim();
    let s = k.s.sqrt();
    // (s·Q + I)·u = t: X(X(x)) = s²Q²x + (sQ + I)u.
    let a = &q * s + DMatrix::<f64>::identity(h, h);
    let u = a.lu().solve(&k.t)?;
    Some(Similitude { s, r: q, t: u })
}

/// Every candidate replacement of component `k` of `model`, with how it was made.
pub fn candidates(model: &EmModel, k: usize, moves: &WordMoves) -> Vec<(Unwind, Similitude)> {
    let comps = &model.components;
    let sk = &comps[k];
    let allowed = |c: &Similitude| -> bool {
        c.s.is_finite()
            && c.s > 0.0
            && c.s <= moves.max_scale
            && c.r.iter().chain(c.t.iter()).all(|v| v.is_finite())
            && (moves.reflections || c.r.determinant() > 0.0)
    };
    let mut out = Vec::new();
    for (j, sj) in comps.iter().enumerate() {
        if j == k {
            continue;
        }
        let inv = inverse(sj);
        out.push((Unwind::After(j), inv.compose(sk)));
        out.push((Unwind::Before(j), sk.compose(&inv)));
    }
    if sk.r.determinant() > 0.0
        && let Some(q) = rotation_sqrt(&sk.r)
    {
        for (by, root) in roots(q) {
            if let Some(x) = root_with(sk, root) {
                out.push((by, x));
            }
        }
    }
    out.retain(|(_, c)| allowed(c));
    out
}

/// Runs the search on `model` (see the module docs), scoring on `points`. Returns the new
/// model and the replacements, in the order they were made.
pub fn unwind(
    model: &EmModel,
    points: &PointSet,
    moves: &WordMoves,
) -> Result<(EmModel, Vec<Unwinding>)> {
    if points.is_empty() {
        return Err(Error::InvalidInput(
            "the word search needs at least one evaluation point".into(),
        ));
    }
    let mut model = model.clone();
    let mut changes = Vec::new();
    let mut base = model.mean_log_likelihood(points)?;
    for _ in 0..model.k() {
        let trials: Vec<(f64, usize, Unwind, Similitude)> = (0..model.k())
            .flat_map(|k| {
                candidates(&model, k, moves)
                    .into_iter()
                    .map(move |(by, c)| (k, by, c))
            })
            .collect::<Vec<_>>()
            .into_par_iter()
            .map(|(k, by, candidate)| {
                let ll = replaced_score(&model, k, &candidate, points)?;
                Ok((ll, k, by, candidate))
            })
            .collect::<Result<_>>()?;
        let best = trials
            .iter()
            .enumerate()
            .max_by(|a, b| a.1.0.total_cmp(&b.1.0).then(b.0.cmp(&a.0)));
        let Some((_, (ll, k, by, candidate))) = best else {
            break;
        };
        if *ll <= base + MIN_GAIN {
            break;
        }
        changes.push(Unwinding {
            component: *k,
            by: *by,
            gain: ll - base,
        });
        model.components[*k] = candidate.clone();
        base = *ll;
    }
    Ok((model, changes))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::problems::em::reorient::rotation_set;
    use nalgebra::DVector;

    fn sim(s: f64, r: DMatrix<f64>, t: &[f64]) -> Similitude {
        Similitude {
            s,
            r,
            t: DVector::from_row_slice(t),
        }
    }

    fn model(components: Vec<Similitude>) -> EmModel {
        let k = components.len();
        EmModel::new(
            components,
            vec![1.0 / k as f64; k],
            vec![0.2; 5],
            Similitude::identity(3),
        )
        .unwrap()
    }

    fn close(a: &Similitude, b: &Similitude) -> bool {
        (a.s - b.s).abs() < 1e-9 && (&a.r - &b.r).amax() < 1e-9 && (&a.t - &b.t).amax() < 1e-9
    }

    #[test]
    fn the_principal_root_of_a_rotation_squares_back() {
        for (h, seed) in [(2, 0), (3, 1), (3, 2), (4, 3)] {
            for r in rotation_set(h, 6, seed) {
                if let Some(q) = rotation_sqrt(&r) {
                    assert!((&q * &q - &r).amax() < 1e-9);
                    assert!((q.determinant() - 1.0).abs() < 1e-9);
                }
            }
        }
        // A half turn has no principal root.
        let half = DMatrix::from_row_slice(2, 2, &[-1.0, 0.0, 0.0, -1.0]);
        assert!(rotation_sqrt(&half).is_none());
    }

    #[test]
    fn words_of_the_maps_unwind_to_the_maps() {
        let r3 = rotation_set(3, 4, 7);
        let a = sim(0.5, r3[0].clone(), &[0.3, -0.1, 0.2]);
        let b = sim(0.4, r3[1].clone(), &[-0.4, 0.2, 0.1]);
        let moves = WordMoves {
            max_scale: 0.99,
            reflections: true,
        };
        let has = |cands: &[(Unwind, Similitude)], want: &Similitude| {
            cands.iter().any(|(_, c)| close(c, want))
        };
        // {a∘a, b}: a square root of the first component is a.
        let square = a.compose(&a);
        let m = model(vec![square, b.clone()]);
        assert!(has(&candidates(&m, 0, &moves), &a));
        // {b∘a, a} and {a∘b, a}: component 0 unwinds to b either way.
        for word in [b.compose(&a), a.compose(&b)] {
            let m = model(vec![word, a.clone()]);
            assert!(has(&candidates(&m, 0, &moves), &b));
        }
        // Candidates past the scale bound are left out: b∘a unwound by a map of scale 0.1
        // would have scale 2.
        let small = sim(0.1, r3[2].clone(), &[0.0, 0.0, 0.0]);
        let m = model(vec![b.compose(&a), small]);
        assert!(candidates(&m, 0, &moves).iter().all(|(_, c)| c.s <= 0.99));
    }
}
