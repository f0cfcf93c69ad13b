//! The word search: a component that fits a two-map word of the true code (`S_a∘S_a`,
//! `S_a∘S_b`) is replaced by the map it is made of, and the true code is left alone.

use nalgebra::DVector;
use rand::{Rng, SeedableRng};
use rand_xoshiro::Xoshiro256PlusPlus as Seeded;

use ifslab::model::Similitude;
use ifslab::model::similitude::random_rotation;
use ifslab_strategies::problems::em::words::{WordMoves, unwind};
use ifslab_strategies::problems::em::{EmModel, PointSet};

/// A 3-D code of three similitudes with reflections among them (what random similitude
/// codes have), drawn from a fixed seed.
fn code() -> Vec<Similitude> {
    let mut rng = Seeded::seed_from_u64(11);
    let scales = [0.45, 0.38, 0.32];
    let centres = [[0.0, 0.0, 1.0], [0.9, 0.0, -0.4], [-0.5, 0.8, -0.4]];
    scales
        .iter()
        .zip(centres)
        .enumerate()
        .map(|(k, (&s, c))| {
            let mut r = random_rotation(3, &mut rng);
            if k == 1 {
                // A mirror image: det R = −1.
                r.column_mut(2).neg_mut();
            }
            Similitude {
                s,
                r,
                t: DVector::from_row_slice(&c) * (1.0 - s),
            }
        })
        .collect()
}

/// 4,000 points of the code's attractor by a plain chaos game (its own generator, not the
/// model's sampler), equal weights, 50 steps of burn-in.
fn points(maps: &[Similitude]) -> PointSet {
    let mut rng = Seeded::seed_from_u64(5);
    let mut x = DVector::<f64>::zeros(3);
    let mut data = Vec::new();
    for i in 0..4050 {
        x = maps[rng.random_range(0..maps.len())].apply(&x);
        if i >= 50 {
            data.extend(x.iter());
        }
    }
    PointSet::new(3, data).unwrap()
}

/// The code at depth 6 with most depth weight deep (a fit that has settled), its base
/// Gaussian on the invariant measure's moments.
fn model(components: Vec<Similitude>) -> EmModel {
    let k = components.len();
    let depth_weights = vec![0.02, 0.02, 0.02, 0.02, 0.02, 0.1, 0.8];
    EmModel::new(
        components,
        vec![1.0 / k as f64; k],
        depth_weights,
        Similitude::identity(3),
    )
    .unwrap()
    .recentred()
}

fn same(a: &Similitude, b: &Similitude) -> bool {
    (a.s - b.s).abs() < 1e-9 && (&a.r - &b.r).amax() < 1e-9 && (&a.t - &b.t).amax() < 1e-9
}

const MOVES: WordMoves = WordMoves {
    max_scale: 0.99,
    reflections: true,
};

#[test]
fn a_component_on_a_word_of_the_code_is_replaced_by_its_map() {
    let truth = code();
    let data = points(&truth);
    let true_ll = model(truth.clone()).mean_log_likelihood(&data).unwrap();
    // S_0∘S_0 in place of S_0; S_2∘S_0 in place of S_2 (beside a correct S_0); S_1∘S_2 in
    // place of S_1 (beside a correct S_2): each a stable wrong answer of EM.
    let traps = [
        (0, truth[0].compose(&truth[0])),
        (2, truth[2].compose(&truth[0])),
        (1, truth[1].compose(&truth[2])),
    ];
    for (k, word) in traps {
        let mut comps = truth.clone();
        comps[k] = word;
        let trapped = model(comps);
        let before = trapped.mean_log_likelihood(&data).unwrap();
        let (fixed, changes) = unwind(&trapped, &data, &MOVES).unwrap();
        let after = fixed.mean_log_likelihood(&data).unwrap();
        assert!(
            after > before + 0.5,
            "component {k}: {before:.3} → {after:.3} nats/point ({changes:?})"
        );
        let maps = fixed.data_space_maps();
        assert!(
            same(&maps[k], &truth[k]),
            "component {k} became {:?} ({changes:?})",
            maps[k]
        );
        // Every other component is untouched.
        for (j, (a, b)) in maps.iter().zip(&truth).enumerate() {
            assert!(j == k || same(a, b), "component {j} moved: {changes:?}");
        }
        assert!(
            after > true_ll - 0.5,
            "{after:.3} nats/point, the truth {true_ll:.3}"
        );
    }
    // The true code has nothing to unwind.
    let settled = model(truth.clone());
    let (same_model, none) = unwind(&settled, &data, &MOVES).unwrap();
    assert!(none.is_empty(), "the true code was changed: {none:?}");
    assert_eq!(same_model, settled);
}

#[test]
fn candidates_keep_to_the_scale_bound_and_the_reflection_rule() {
    let truth = code();
    let data = points(&truth);
    // S_1 reflects; with reflections off, S_1∘S_0 may not be unwound into S_1.
    let mut comps = truth.clone();
    comps[1] = truth[1].compose(&truth[0]);
    let trapped = model(comps);
    let rotations_only = WordMoves {
        max_scale: 0.99,
        reflections: false,
    };
    let (fixed, changes) = unwind(&trapped, &data, &rotations_only).unwrap();
    for c in &changes {
        let r = &fixed.components[c.component].r;
        assert!(r.determinant() > 0.0, "{c:?} gave a reflection");
    }
    assert!(!same(&fixed.data_space_maps()[1], &truth[1]));
    // No candidate above the scale bound: with a bound of 0.4, S_0 (0.45) is out of reach.
    let mut comps = truth.clone();
    comps[0] = truth[0].compose(&truth[0]);
    let tight = WordMoves {
        max_scale: 0.4,
        reflections: true,
    };
    let (fixed, _) = unwind(&model(comps), &data, &tight).unwrap();
    assert!(fixed.components.iter().all(|c| c.s <= 0.4 + 1e-12));
    // No points, no search.
    let empty = PointSet::new(3, vec![]).unwrap();
    assert!(unwind(&fixed, &empty, &MOVES).is_err());
}
