//! Invariants of the model layer: sampled and parameterised maps are contractive, code
//! files round-trip exactly, and each kind of bad file gets its own error.

use std::path::Path;

use ifslab::Error;
use ifslab::model::param::{Naive, Parameterisation, Svd};
use ifslab::model::random::{sample_code, sigma_factor, sigma_factor_bounds};
use ifslab::model::{Affine2, IfsCode, library};
use proptest::prelude::*;

proptest! {
    #![proptest_config(ProptestConfig::with_cases(200))]

    /// Every sampled code is contractive (σ₁ < 1 for every map), its σ-factor
    /// Σ(σ₁ + 2σ₂) equals the drawn target and the target lies in [(5+n)/2, (6+n)/2].
    #[test]
    fn sampler_codes_are_contractive_with_sigma_factor_in_bounds(n in 2usize..16, seed in any::<u64>()) {
        let c = sample_code(n, seed).unwrap();
        prop_assert_eq!(c.maps.len(), n);
        let (lo, hi) = sigma_factor_bounds(n);
        prop_assert!(c.sigma_factor >= lo && c.sigma_factor <= hi, "target {} outside [{lo}, {hi}]", c.sigma_factor);
        prop_assert!((sigma_factor(&c.maps) - c.sigma_factor).abs() < 1e-9);
        for (m, &(s1, s2)) in c.maps.iter().zip(&c.singular_values) {
            let (a, b) = m.singular_values();
            prop_assert!(a < 1.0, "σ₁ = {a}");
            prop_assert!((a - s1).abs() < 1e-9 && (b - s2).abs() < 1e-9);
            prop_assert!(m.b[0].abs() <= 1.0 && m.b[1].abs() <= 1.0);
        }
        // Same seed, same code.
        let again = sample_code(n, seed).unwrap();
        prop_assert_eq!(c.maps, again.maps);
    }

    /// Every raw θ, however wild, decodes through the SVD parameterisation to maps with
    /// largest singular value < 1 and offsets in (−1, 1)².
    #[test]
    fn svd_parameterisation_is_always_contractive(theta in prop::collection::vec(-50.0f64..50.0, 12 * 3)) {
        let maps = Svd::default().decode(&theta).unwrap();
        for m in maps {
            prop_assert!(m.sigma_max() < 1.0, "σmax = {}", m.sigma_max());
            prop_assert!(m.b.iter().all(|b| b.abs() <= 1.0));
        }
    }

    /// The SVD chain rule agrees with central finite differences of
    /// L(θ) = Σ G ⊙ decode(θ) (so ∂L/∂maps = G) for random θ and G.
    #[test]
    fn svd_chain_rule_matches_finite_differences(
        theta in prop::collection::vec(-2.0f64..2.0, 24),
        g in prop::collection::vec(-1.0f64..1.0, 12),
    ) {
        let p = Svd::default();
        // Keep away from the (measure-zero) degenerate raw U or V with a near-zero column.
        for t in theta.chunks(12) {
            prop_assume!((t[0].hypot(t[2])) > 0.1 && (t[4].hypot(t[6])) > 0.1);
        }
        let gm: Vec<Affine2> = g.chunks(6).map(Affine2::from_coefficients).collect();
        let loss = |th: &[f64]| -> f64 {
            p.decode(th).unwrap().iter().zip(&gm)
                .map(|(m, g)| m.coefficients().iter().zip(g.coefficients()).map(|(a, b)| a * b).sum::<f64>())
                .sum()
        };
        let grad = p.backward(&theta, &gm).unwrap();
        for i in 0..theta.len() {
            let h = 1e-6;
            let mut tp = theta.clone();
            let mut tm = theta.clone();
            tp[i] += h;
            tm[i] -= h;
            let fd = (loss(&tp) - loss(&tm)) / (2.0 * h);
            prop_assert!((fd - grad[i]).abs() < 1e-5 * (1.0 + fd.abs()), "θ[{i}]: analytic {} fd {fd}", grad[i]);
        }
    }

    /// Naive θ ↔ maps is the identity both ways.
    #[test]
    fn naive_round_trip(theta in prop::collection::vec(-3.0f64..3.0, 18)) {
        let p = Naive;
        prop_assert_eq!(p.encode(&p.decode(&theta).unwrap()).unwrap(), theta);
    }

    /// A code written to JSON and read back is bit-identical, probabilities and framing included.
    #[test]
    fn code_files_round_trip_exactly(n in 2usize..12, seed in any::<u64>(), with_p in any::<bool>()) {
        let s = sample_code(n, seed).unwrap();
        let mut code = IfsCode::from_affine2(Some("rt"), &s.maps).unwrap();
        if with_p {
            let p = code.evaluation_probabilities().unwrap();
            let total: f64 = p.iter().sum();
            code = code.with_probabilities(p.iter().map(|x| x / total).collect()).unwrap();
        }
        code.framing = Some(ifslab::model::Window { min: [-1.5, -2.0 / 3.0], max: [1.0 / 7.0, 2.25] });
        code.meta.insert("seed".into(), seed.into());
        let back = IfsCode::from_json(&code.to_json(), Path::new("mem")).unwrap();
        prop_assert_eq!(back, code);
    }
}

#[test]
fn builtin_codes_round_trip_through_files() {
    let dir = tempfile::tempdir().unwrap();
    for name in library::names() {
        let code = library::builtin(name).unwrap();
        let path = dir.path().join(format!("{name}.json"));
        code.save(&path).unwrap();
        assert_eq!(IfsCode::load(&path).unwrap(), code, "{name}");
    }
}

fn parse(text: &str) -> Result<IfsCode, Error> {
    IfsCode::from_json(text, Path::new("bad.json"))
}

const GOOD_MAP: &str = r#"{"matrix": [[0.5, 0.0], [0.0, 0.5]], "offset": [0.0, 0.0]}"#;

#[test]
fn each_kind_of_bad_file_gets_its_error() {
    let doc = |maps: &str, extra: &str| {
        format!(r#"{{"format": "ifslab-code/1", "dim": 2, "maps": [{maps}]{extra}}}"#)
    };
    // Valid baseline.
    parse(&doc(GOOD_MAP, "")).unwrap();

    // Not JSON at all.
    assert!(matches!(
        parse("this is not json"),
        Err(Error::Parse { .. })
    ));
    // Unknown field (a typo) is refused, not ignored.
    assert!(matches!(
        parse(&doc(GOOD_MAP, r#", "probabilties": [1.0]"#)),
        Err(Error::Parse { .. })
    ));
    // NaN and infinity, as Python's json module writes them.
    let nan = doc(
        r#"{"matrix": [[NaN, 0.0], [0.0, 0.5]], "offset": [0.0, 0.0]}"#,
        "",
    );
    match parse(&nan) {
        Err(Error::NonFinite { location, .. }) => {
            assert!(location.contains("line 1"), "{location}")
        }
        other => panic!("expected NonFinite, got {other:?}"),
    }
    let inf = doc(
        r#"{"matrix": [[0.5, 0.0], [0.0, 0.5]], "offset": [1e999, 0.0]}"#,
        "",
    );
    assert!(matches!(parse(&inf), Err(Error::NonFinite { .. })));
    // Wrong lengths.
    let short_row = doc(
        r#"{"matrix": [[0.5], [0.0, 0.5]], "offset": [0.0, 0.0]}"#,
        "",
    );
    assert!(matches!(parse(&short_row), Err(Error::Shape(m)) if m.contains("map 0")));
    let long_offset = doc(
        r#"{"matrix": [[0.5, 0.0], [0.0, 0.5]], "offset": [0.0, 0.0, 1.0]}"#,
        "",
    );
    assert!(matches!(parse(&long_offset), Err(Error::Shape(m)) if m.contains("offset")));
    // Probabilities: wrong count, wrong sum, negative.
    let two = format!("{GOOD_MAP}, {GOOD_MAP}");
    assert!(matches!(
        parse(&doc(&two, r#", "probabilities": [1.0]"#)),
        Err(Error::Probabilities(_))
    ));
    assert!(
        matches!(parse(&doc(&two, r#", "probabilities": [0.5, 0.6]"#)), Err(Error::Probabilities(m)) if m.contains("sum"))
    );
    assert!(
        matches!(parse(&doc(&two, r#", "probabilities": [1.5, -0.5]"#)), Err(Error::Probabilities(m)) if m.contains("negative"))
    );
    // Non-contractive map: names the map and its largest singular value.
    let big =
        format!(r#"{GOOD_MAP}, {{"matrix": [[1.2, 0.0], [0.0, 0.3]], "offset": [0.0, 0.0]}}"#);
    match parse(&doc(&big, "")) {
        Err(Error::NonContractive { index, sigma_max }) => {
            assert_eq!(index, 1);
            assert!((sigma_max - 1.2).abs() < 1e-12);
        }
        other => panic!("expected NonContractive, got {other:?}"),
    }
    // ... unless explicitly allowed (flame-like codes).
    parse(&doc(&big, r#", "allow_non_contractive": true"#)).unwrap();
    // No maps at all.
    assert!(matches!(parse(&doc("", "")), Err(Error::Empty(_))));
    // Wrong format tag.
    let tagged = doc(GOOD_MAP, "").replace("ifslab-code/1", "something-else");
    assert!(matches!(parse(&tagged), Err(Error::Shape(m)) if m.contains("format")));
    // Degenerate framing.
    assert!(
        parse(&doc(
            GOOD_MAP,
            r#", "framing": {"min": [0, 0], "max": [0, 1]}"#
        ))
        .is_err()
    );
    // A missing file names the file.
    match IfsCode::load("/nonexistent/code.json") {
        Err(e @ Error::Io { .. }) => assert!(e.to_string().contains("/nonexistent/code.json")),
        other => panic!("expected Io, got {other:?}"),
    }
}

#[test]
fn three_dimensional_codes_are_first_class() {
    let t = library::builtin("tetrahedron").unwrap();
    assert_eq!(t.dim(), 3);
    assert!(
        t.affine2().is_err(),
        "a 3-D code must refuse to become 2-D maps"
    );
    let back = IfsCode::from_json(&t.to_json(), Path::new("mem")).unwrap();
    assert_eq!(back, t);
}
