//! The random test suite: making it (deterministic, resumable), scoring codes on its views
//! (invariant to where a code's attractor lies, which is what lets a recovered code — in its
//! own coordinates — be compared), and runs whose target is a suite code.

use std::path::Path;

mod common;
use common::ifslab_in;

use ifslab::model::{Affine2, IfsCode};
use ifslab_experiments::progress::Silent;
use ifslab_experiments::suite::{self, SuiteSpec, Tier};
use ifslab_strategies::problems::image::Fitted;

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

    let same = suite::score_maps(
        tmp.path(),
        &m,
        0,
        &Fitted::with_probabilities(maps.clone(), probs.clone()).unwrap(),
        None,
    )
    .unwrap();
    assert_eq!(same.views.len(), 7);
    assert!(same.iou == 1.0 && same.f1 == 1.0, "{same:?}");

    // Moved and scaled by 3: every view is found again (up to rounding; views stored in
    // the code's own coordinates would miss all six patches).
    let moved = conjugate(&maps, 3.0, [5.0, -2.0]);
    let s = suite::score_maps(
        tmp.path(),
        &m,
        0,
        &Fitted::with_probabilities(moved, probs.clone()).unwrap(),
        None,
    )
    .unwrap();
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

/// The suite's ground truths against another program's renders of the same codes:
/// `flam3-render` (Draves' flam3, a chaos game written independently of this project),
/// given each code as a flame of linear transforms with the code's probabilities as weights
/// and the view's window as its camera. A pixel is foreground in either picture when any
/// point landed in it; the masks must agree (IoU ≥ 0.9 on the full view and on a 2× patch)
/// — a wrong window, a flipped axis, a wrong probability or a skipped map in the suite's
/// renderer would not. Needs flam3-render, which scripts/test.sh installs: without it this
/// test fails rather than pass unchecked.
#[test]
fn suite_truths_agree_with_flam3_renders_of_the_same_codes() {
    use ifslab::model::flame::{flame_from_affine, write_flames};
    use ifslab::render::image_io::load_grey;
    use std::process::Command;

    assert!(
        Command::new("flam3-render")
            .arg("--version")
            .output()
            .is_ok(),
        "flam3-render is not installed: `apt-get install flam3-utils flam3-palette` \
         (scripts/test.sh does it); this test checks the suite's truths against it"
    );
    let tmp = tempfile::tempdir().unwrap();
    let m = smoke(tmp.path(), 3);
    let size = m.spec.tier.size();
    for c in &m.codes {
        let code = IfsCode::load(tmp.path().join(&c.code)).unwrap();
        let maps = code.affine2().unwrap();
        let probs = code.evaluation_probabilities().unwrap();
        let [ww, wh] = c.window.size();
        // The full view and the least-zoomed patch (flam3 draws the whole attractor, so a
        // patch zoomed f× needs f² times the samples for the same points in view).
        let patch = c.views[1..]
            .iter()
            .min_by(|a, b| a.factor.total_cmp(&b.factor))
            .unwrap();
        for v in [&c.views[0], patch] {
            let mut flame =
                flame_from_affine(None, &maps, &probs, [size as u32, size as u32]).unwrap();
            // One colour for every map, the palette's white end: flam3 pictures colour, and
            // a point coloured near the grey palette's black end would vanish in the mask.
            for x in &mut flame.xforms {
                x.color = 1.0;
            }
            flame.center = [
                c.window.min[0] + v.center[0] * ww,
                c.window.min[1] + v.center[1] * wh,
            ];
            flame.scale = size as f64 * v.factor / ww;
            flame.quality = 400.0 * v.factor * v.factor;
            flame.supersample = 1;
            flame.estimator_radius = 0.0;
            flame.filter = 0.0;
            flame.gamma = 1.0;
            flame.brightness = 1000.0;
            let dir = tmp.path().join(format!("flam3-{}-{}", c.index, v.name));
            std::fs::create_dir_all(&dir).unwrap();
            let (file, png) = (dir.join("code.flame"), dir.join("flam3.png"));
            write_flames(&file, std::slice::from_ref(&flame)).unwrap();
            let out = Command::new("flam3-render")
                .env("in", &file)
                .env("out", &png)
                .env("nthreads", "1")
                .env("isaac_seed", "1")
                .env("verbose", "0")
                .output()
                .unwrap();
            assert!(
                out.status.success(),
                "flam3-render: {}",
                String::from_utf8_lossy(&out.stderr)
            );
            let theirs = load_grey(&png).unwrap();
            let ours = load_grey(&tmp.path().join(&v.truth)).unwrap();
            assert_eq!(
                (theirs.width as usize, theirs.height as usize),
                (size, size)
            );
            // flam3's camera has +y down: its row r is the suite's row size − 1 − r.
            let mask_theirs: Vec<bool> = (0..size * size)
                .map(|i| {
                    let (r, x) = (i / size, i % size);
                    theirs.values[(size - 1 - r) * size + x] > 0.0
                })
                .collect();
            let mask_ours: Vec<bool> = ours.values.iter().map(|&p| p > 0.0).collect();
            let iou = ifslab::metrics::iou(&mask_ours, &mask_theirs).unwrap();
            let count = |m: &[bool]| m.iter().filter(|&&b| b).count();
            let both = mask_ours
                .iter()
                .zip(&mask_theirs)
                .filter(|(a, b)| **a && **b)
                .count();
            let covered = both as f64 / count(&mask_ours) as f64;
            eprintln!(
                "code {} view {} (×{:.2}): IoU {iou:.3}, {:.1} % of the truth's foreground \
                 in flam3's",
                c.index,
                v.name,
                v.factor,
                100.0 * covered
            );
            assert!(
                covered >= 0.95,
                "code {} view {}: only {:.1} % of the truth's foreground is in flam3's picture",
                c.index,
                v.name,
                100.0 * covered
            );
            assert!(
                iou >= 0.9,
                "code {} view {} (×{:.2}): the suite's truth and flam3-render's picture \
                 share IoU {iou:.3} of their foreground",
                c.index,
                v.name,
                v.factor
            );
        }
    }
}
