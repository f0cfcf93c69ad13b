//! The random test suite: making it (deterministic, resumable), scoring codes on its views
//! (invariant to where a code's attractor lies, which is what lets a recovered code — in its
//! own coordinates — be compared), and runs whose target is a suite code.

use std::path::Path;

mod common;
use common::ifslab_in;

use ifslab::model::{Affine2, IfsCode};
use ifslab_experiments::progress::Silent;
use ifslab_experiments::suite::{self, SuiteSpec, Tier};

fn smoke(dir: &Path, codes: usize) -> suite::Manifest {
    suite::make(&SuiteSpec::paper(codes, 7, Tier::Smoke), dir, &Silent).unwrap()
}

#[test]
fn a_suite_is_deterministic_resumable_and_refuses_another_spec_in_its_folder() {
    let tmp = tempfile::tempdir().unwrap();
    let (a, b) = (tmp.path().join("a"), tmp.path().join("b"));
    let m = smoke(&a, 3);
    assert_eq!(m.codes.len(), 3);
    for c in &m.codes {
        assert!((3..=10).contains(&c.maps), "{}", c.maps);
        assert_eq!(c.views.len(), 7);
        assert_eq!(c.views[0].name, "full");
        for v in &c.views[1..] {
            assert!((2.0..=8.0).contains(&v.factor), "{}", v.factor);
        }
        assert!(c.views.iter().all(|v| a.join(&v.truth).is_file()));
        let code = IfsCode::load(a.join(&c.code)).unwrap();
        assert_eq!(code.maps.len(), c.maps);
    }
    assert_eq!(suite::load(&a).unwrap(), m);

    // The same spec elsewhere: the same suite, byte for byte.
    let m2 = smoke(&b, 3);
    assert_eq!(m2, m);
    for v in &m.codes[2].views {
        assert_eq!(
            std::fs::read(a.join(&v.truth)).unwrap(),
            std::fs::read(b.join(&v.truth)).unwrap()
        );
    }

    // An interrupted make (a code folder missing, a partial one left) completes to the same.
    std::fs::remove_dir_all(b.join("001")).unwrap();
    std::fs::create_dir_all(b.join(".002.partial")).unwrap();
    std::fs::write(b.join(".002.partial/junk"), b"x").unwrap();
    assert_eq!(smoke(&b, 3), m);

    let other = SuiteSpec::paper(4, 7, Tier::Smoke);
    let e = suite::make(&other, &a, &Silent).unwrap_err().to_string();
    assert!(e.contains("different suite"), "{e}");
}

/// g∘f∘g⁻¹ for g(x) = s·x + t: the same attractor, scaled and moved.
fn conjugate(maps: &[Affine2], s: f64, t: [f64; 2]) -> Vec<Affine2> {
    let t = nalgebra::Vector2::new(t[0], t[1]);
    maps.iter()
        .map(|f| Affine2 {
            m: f.m,
            b: s * f.b + t - f.m * t,
        })
        .collect()
}

#[test]
fn scores_depend_on_the_shape_not_on_where_the_code_puts_it() {
    let tmp = tempfile::tempdir().unwrap();
    let m = smoke(tmp.path(), 2);
    let code = IfsCode::load(tmp.path().join(&m.codes[0].code)).unwrap();
    let maps = code.affine2().unwrap();
    let probs = code.evaluation_probabilities().unwrap();

    let same = suite::score_maps(tmp.path(), &m, 0, &maps, &probs, None).unwrap();
    assert_eq!(same.views.len(), 7);
    assert!(same.iou == 1.0 && same.f1 == 1.0, "{same:?}");

    // Moved and scaled by 3: every view is found again (up to rounding; views stored in
    // the code's own coordinates would miss all six patches).
    let moved = conjugate(&maps, 3.0, [5.0, -2.0]);
    let s = suite::score_maps(tmp.path(), &m, 0, &moved, &probs, None).unwrap();
    for v in &s.views {
        assert!(v.iou > 0.9, "{} {v:?}", v.name);
    }

    // Another code of the suite does much worse.
    let other = IfsCode::load(tmp.path().join(&m.codes[1].code)).unwrap();
    let o = suite::score_code(tmp.path(), &m, 0, &other, None).unwrap();
    assert!(o.iou < s.iou - 0.2, "{} vs {}", o.iou, s.iou);

    let e = suite::score_code(tmp.path(), &m, 5, &other, None)
        .unwrap_err()
        .to_string();
    assert!(e.contains("no code 5"), "{e}");
}

#[test]
fn a_run_on_a_suite_code_is_scored_on_its_views() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    let (ok, msg) = ifslab_in(
        dir,
        &[
            "suite", "make", "--codes", "2", "--tier", "smoke", "--seed", "3", "-o", "s",
        ],
    );
    assert!(ok, "{msg}");
    assert!(msg.contains("2 codes, 14 views"), "{msg}");
    let base = "seed = 1\niterations = 5\n[model]\nmaps = 10\n\
                [generator]\ntrajectories = 100\nlength = 40\n[target]\nsize = 32\n";
    std::fs::write(
        dir.join("run.toml"),
        format!("{base}suite = \"s\"\nindex = 1\n"),
    )
    .unwrap();
    let (ok, msg) = ifslab_in(dir, &["run", "run.toml", "-o", "out"]);
    assert!(ok, "{msg}");
    assert!(msg.contains("over the suite's 7 views"), "{msg}");
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("out/summary.json")).unwrap())
            .unwrap();
    let s = &summary["suite"];
    assert_eq!(s["index"], 1);
    assert_eq!(s["views"].as_array().unwrap().len(), 7);
    assert!((0.0..=1.0).contains(&s["iou"].as_f64().unwrap()), "{s}");

    // The truth scores perfectly through the command line too.
    let (ok, msg) = ifslab_in(
        dir,
        &["suite", "score", "s", "--index", "1", "s/001/code.json"],
    );
    assert!(ok && msg.contains("IoU 1.000"), "{msg}");

    for (target, want) in [
        ("suite = \"s\"\n", "`suite` and `index` go together"),
        ("suite = \"s\"\nindex = 9\n", "no code 9"),
        ("suite = \"nowhere\"\nindex = 0\n", "ifslab suite make"),
        (
            "suite = \"s\"\nindex = 0\ncode = \"fern\"\n",
            "one of `image`, `code` and `suite`",
        ),
    ] {
        std::fs::write(dir.join("bad.toml"), format!("{base}{target}")).unwrap();
        let (ok, msg) = ifslab_in(dir, &["run", "bad.toml", "-o", "bad"]);
        assert!(!ok && msg.contains(want), "{target}: {msg}");
        assert!(
            !dir.join("bad").exists(),
            "{target}: a failed start left a folder"
        );
    }
}
