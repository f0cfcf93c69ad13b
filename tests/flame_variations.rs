//! Every flam3 variation against values recorded from libflam3 itself.
//!
//! `tests/fixtures/flame/variations.json` was written by `record_variations.c` (same
//! folder; `scripts/flame_fixtures.sh` rebuilds it) linked against Debian's libflam3 3.1.1:
//! for 16 random cases per variation (random pre- and post-affine maps, weights, parameters,
//! points) plus 60 two-variation mixtures, flam3's `apply_xform` output, its colour and
//! opacity, its bad-value flag, and the raw random numbers its generator had queued. A
//! random variation here replays those numbers, so random variations are checked exactly
//! too. flam3 is built with `-ffast-math`, so agreement is to rounding (≤ 1e-11 relative;
//! measured: ≤ 3e-14),
//! except where a tiny difference crosses one of a formula's own jumps (floor, fmod,
//! a comparison), which the test reports and bounds.

use std::collections::BTreeMap;

use ifslab::model::flame::{Variation, VariationKind, Xform};
use rand::RngCore;
use serde::Deserialize;

#[derive(Deserialize)]
struct Fixture {
    flam3_version: String,
    cases: Vec<Case>,
}

#[derive(Deserialize)]
struct Case {
    vars: Vec<(usize, f64)>,
    params: BTreeMap<String, f64>,
    coefs: [f64; 6],
    post: Option<[f64; 6]>,
    color: f64,
    color_speed: f64,
    opacity: f64,
    p: [f64; 3],
    draws: Vec<u32>,
    q: [f64; 4],
    bad: u8,
}

/// Hands out flam3's recorded draws in order.
struct Replay {
    draws: Vec<u32>,
    next: usize,
}

impl RngCore for Replay {
    fn next_u32(&mut self) -> u32 {
        let v = self.draws[self.next];
        self.next += 1;
        v
    }
    fn next_u64(&mut self) -> u64 {
        self.next_u32() as u64
    }
    fn fill_bytes(&mut self, dst: &mut [u8]) {
        for b in dst {
            *b = self.next_u32() as u8;
        }
    }
}

fn load() -> Fixture {
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/tests/fixtures/flame/variations.json"
    );
    serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap()
}

fn xform_of(c: &Case) -> Xform {
    let vars = c
        .vars
        .iter()
        .map(|&(k, w)| {
            let mut v = Variation::new(VariationKind::from_index(k).unwrap(), w);
            for (name, &value) in &c.params {
                if VariationKind::param_owner(name).map(|(o, _)| o) == Some(v.kind()) {
                    v.set_param(name, value).unwrap();
                }
            }
            v
        })
        .collect();
    let mut x = Xform::new(c.coefs, vars);
    if let Some(p) = c.post {
        x.post = p;
    }
    x.color = c.color;
    x.color_speed = c.color_speed;
    x.opacity = c.opacity;
    x
}

fn close(a: f64, b: f64, tol: f64) -> bool {
    (a - b).abs() <= tol * 1f64.max(a.abs()).max(b.abs())
}

#[test]
fn every_variation_matches_libflam3() {
    let fx = load();
    assert!(fx.flam3_version.contains("3.1.1"), "{}", fx.flam3_version);
    // Every one of the 99 variations is exercised.
    let mut seen = [false; 99];
    for c in &fx.cases {
        for &(k, _) in &c.vars {
            seen[k] = true;
        }
    }
    assert!(seen.iter().all(|&s| s), "fixture misses variations");

    let mut failures = Vec::new();
    let mut jumps = BTreeMap::<&'static str, usize>::new();
    let mut per_kind = BTreeMap::<&'static str, (usize, f64)>::new();
    for (i, c) in fx.cases.iter().enumerate() {
        let x = xform_of(c);
        let mut rng = Replay {
            draws: c.draws.clone(),
            next: 0,
        };
        let out = x.apply([c.p[0], c.p[1]], &mut rng);
        let name = VariationKind::from_index(c.vars[c.vars.len() - 1].0)
            .unwrap()
            .name();
        // Colour and opacity: exact formulas.
        assert!(
            close(x.blend_color(c.p[2]), c.q[2], 1e-15),
            "case {i}: colour"
        );
        assert!(close(x.visibility(), c.q[3], 1e-12), "case {i}: opacity");
        if c.bad == 1 {
            // flam3 replaced the point by a random one: both must have flagged it.
            if !out.bad {
                failures.push(format!(
                    "case {i} ({name}): flam3 flagged a bad value, we got {:?}",
                    out.point
                ));
            }
            continue;
        }
        if out.bad {
            failures.push(format!(
                "case {i} ({name}): we flagged a bad value, flam3 got {:?}",
                c.q
            ));
            continue;
        }
        let err = ((out.point[0] - c.q[0]).abs() / 1f64.max(c.q[0].abs()))
            .max((out.point[1] - c.q[1]).abs() / 1f64.max(c.q[1].abs()));
        let e = per_kind.entry(name).or_default();
        e.0 += 1;
        e.1 = e.1.max(err);
        if err > 1e-11 {
            // A rounding-level difference that crossed a jump of the formula shows as a
            // large error in a variation that has jumps; count those, fail on the rest.
            if has_jumps(c) {
                *jumps.entry(name).or_default() += 1;
            } else {
                failures.push(format!(
                    "case {i} ({name}): ours {:?}, flam3 {:?} (relative error {err:.2e})",
                    out.point,
                    &c.q[..2]
                ));
            }
        }
    }
    let total_jumps: usize = jumps.values().sum();
    eprintln!(
        "cases: {}, jump crossings: {total_jumps} {jumps:?}",
        fx.cases.len()
    );
    for (k, (n, e)) in &per_kind {
        eprintln!("{k:>16}: {n:>3} cases, max relative error {e:.1e}");
    }
    assert!(
        failures.is_empty(),
        "{} mismatches:\n{}",
        failures.len(),
        failures.join("\n")
    );
    // Jump crossings are rare events: at most one case in a hundred.
    assert!(
        total_jumps * 100 <= fx.cases.len(),
        "too many jump crossings: {jumps:?}"
    );
}

/// Whether a case's variations have discontinuities (floor, fmod, rounding, comparisons)
/// where rounding-level differences may flip a branch.
fn has_jumps(c: &Case) -> bool {
    use VariationKind as V;
    c.vars.iter().any(|&(k, _)| {
        matches!(
            VariationKind::from_index(k).unwrap(),
            V::Fan
                | V::Fan2
                | V::Rings
                | V::Rings2
                | V::Ngon
                | V::Rectangles
                | V::Cell
                | V::Boarders
                | V::Modulus
                | V::Stripes
                | V::Wedge
                | V::WedgeJulia
                | V::WedgeSph
                | V::Split
                | V::Oscilloscope
                | V::Lazysusan
                | V::Whorl
                | V::Bipolar
                | V::Pie
                | V::Julian
                | V::Juliascope
                | V::Cpow
                | V::Secant2
                | V::Twintrian
        )
    })
}
