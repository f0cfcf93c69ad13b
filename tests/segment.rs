//! Segment maps: the segment-to-segment similitude lands where it should, its chain rule and
//! the pattern's (maps → control points) agree with central finite differences in f64, the
//! built-in patterns are the paper's, and bad pattern files are refused with errors that
//! name the offending pair, map or point.

use std::path::Path;

use ifslab::model::diff_map::vjp_check;
use ifslab::model::segment::{
    BaseFigure, Pattern, PatternFile, PrimitiveKind, SegmentMap, builtin, resolve_pattern,
};
use ifslab::model::{DiffMap, Map};
use proptest::prelude::*;

fn pt() -> impl Strategy<Value = [f64; 2]> {
    [-2.0f64..2.0, -2.0f64..2.0]
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(200))]

    /// `between(e1, e2, p1, p2)` sends e1 to p1 and e2 to p2, with scale |p2 − p1|/|e2 − e1|.
    #[test]
    fn the_map_takes_the_source_segment_onto_the_target(e1 in pt(), e2 in pt(), p1 in pt(), p2 in pt()) {
        prop_assume!((e1[0] - e2[0]).hypot(e1[1] - e2[1]) > 1e-3);
        let f = SegmentMap::between(e1, e2, p1, p2).unwrap();
        for (x, y) in [(e1, p1), (e2, p2)] {
            let z = f.apply(x);
            prop_assert!((z[0] - y[0]).abs() < 1e-9 && (z[1] - y[1]).abs() < 1e-9);
        }
        let s = (p2[0] - p1[0]).hypot(p2[1] - p1[1]) / (e2[0] - e1[0]).hypot(e2[1] - e1[1]);
        prop_assert!((f.scale() - s).abs() < 1e-9 * (1.0 + s));
    }

    /// For `L = ⟨g_w, w⟩ + ⟨g_t, t⟩`, `∂L/∂(e1, e2, p1, p2)` from `between_backward` equals
    /// central differences of L (h = 1e-6, f64).
    #[test]
    fn the_segment_chain_rule_matches_finite_differences(
        e1 in pt(), e2 in pt(), p1 in pt(), p2 in pt(), gw in pt(), gt in pt()
    ) {
        prop_assume!((e1[0] - e2[0]).hypot(e1[1] - e2[1]) > 0.2);
        let loss = |x: &[[f64; 2]; 4]| {
            let f = SegmentMap::between(x[0], x[1], x[2], x[3]).unwrap();
            gw[0] * f.w[0] + gw[1] * f.w[1] + gt[0] * f.t[0] + gt[1] * f.t[1]
        };
        let g = SegmentMap::between_backward(e1, e2, p1, p2, gw, gt);
        let x0 = [e1, e2, p1, p2];
        let h = 1e-6;
        for k in 0..4 {
            for c in 0..2 {
                let (mut up, mut down) = (x0, x0);
                up[k][c] += h;
                down[k][c] -= h;
                let fd = (loss(&up) - loss(&down)) / (2.0 * h);
                prop_assert!((fd - g[k][c]).abs() < 1e-6 * (1.0 + fd.abs()),
                    "point {k} coordinate {c}: chain rule {} vs FD {fd}", g[k][c]);
            }
        }
    }

    /// The map's own vector–Jacobian products (what the splatter would use).
    #[test]
    fn segment_map_vjps_match_finite_differences(w in pt(), t in pt(), x in pt(), l in pt()) {
        let f = SegmentMap { w, t };
        let r = vjp_check(&f, x, l, 1e-6);
        prop_assert!(r.point < 1e-8 * (1.0 + r.scale) && r.params < 1e-8 * (1.0 + r.scale), "{r:?}");
        prop_assert_eq!(f.n_params(), 4);
    }
}

/// The pattern's chain rule: for `L = Σ_i ⟨G_i, (w_i, t_i)⟩` over Koch's maps at perturbed
/// control points, `maps_backward` equals central differences of L in every coordinate.
#[test]
fn pattern_maps_backward_matches_finite_differences() {
    let koch = builtin("koch").unwrap();
    let mut theta = koch.flat_points();
    for (k, v) in theta.iter_mut().enumerate() {
        *v += 0.01 * ((k * 7 + 3) % 5) as f64 - 0.02;
    }
    let g: Vec<[f64; 4]> = (0..4)
        .map(|i| {
            let i = i as f64;
            [0.3 - i * 0.1, 0.7 * i - 1.0, 0.2 + i, -0.5 * i]
        })
        .collect();
    let loss = |th: &[f64]| {
        let p = koch.with_flat_points(th).unwrap();
        p.maps()
            .unwrap()
            .iter()
            .zip(&g)
            .map(|(m, g)| g[0] * m.w[0] + g[1] * m.w[1] + g[2] * m.t[0] + g[3] * m.t[1])
            .sum::<f64>()
    };
    let p = koch.with_flat_points(&theta).unwrap();
    let mut grad = vec![0.0; theta.len()];
    p.maps_backward(&g, &mut grad);
    let h = 1e-6;
    for k in 0..theta.len() {
        let (mut up, mut down) = (theta.clone(), theta.clone());
        up[k] += h;
        down[k] -= h;
        let fd = (loss(&up) - loss(&down)) / (2.0 * h);
        assert!(
            (fd - grad[k]).abs() < 1e-6 * (1.0 + fd.abs()),
            "θ[{k}]: chain rule {} vs FD {fd}",
            grad[k]
        );
    }
}

/// Koch's maps are the paper's Eq. 1: T₁ = diag(1/3), T₂ = rotation by 60° scaled by 1/3 at
/// (1/3, 0), T₄ = diag(1/3) at (2/3, 0); T₃ has T₂'s linear part turned by −120° (the
/// paper's printed translation (1/3, 0) for T₃ would disconnect the curve: the piece must
/// start at the apex (1/2, √3/6), which is where ours starts).
#[test]
fn koch_maps_are_the_papers() {
    let maps = builtin("koch").unwrap().maps().unwrap();
    let r3 = 3f64.sqrt();
    let expect = [
        [1.0 / 3.0, 0.0, 0.0, 1.0 / 3.0, 0.0, 0.0],
        [1.0 / 6.0, -r3 / 6.0, r3 / 6.0, 1.0 / 6.0, 1.0 / 3.0, 0.0],
        [1.0 / 6.0, r3 / 6.0, -r3 / 6.0, 1.0 / 6.0, 0.5, r3 / 6.0],
        [1.0 / 3.0, 0.0, 0.0, 1.0 / 3.0, 2.0 / 3.0, 0.0],
    ];
    for (i, (m, e)) in maps.iter().zip(expect).enumerate() {
        let c = m.to_affine().coefficients();
        for k in 0..6 {
            assert!((c[k] - e[k]).abs() < 1e-12, "T{}: {c:?} vs {e:?}", i + 1);
        }
    }
}

/// The carpet's 8 maps each scale by 1/3, land on the 8 outer cells (their images of the
/// unit square's centre are the cells' centres), and skip the centre cell.
#[test]
fn carpet_maps_land_on_the_eight_outer_cells() {
    for name in ["carpet", "carpet-square"] {
        let p = builtin(name).unwrap();
        assert_eq!(p.points().len(), 16);
        let maps = p.maps().unwrap();
        assert_eq!(maps.len(), 8);
        let mut centres: Vec<(i64, i64)> = maps
            .iter()
            .map(|m| {
                assert!((m.scale() - 1.0 / 3.0).abs() < 1e-12);
                let c = m.apply([0.5, 0.5]);
                ((c[0] * 6.0).round() as i64, (c[1] * 6.0).round() as i64)
            })
            .collect();
        centres.sort();
        let mut want: Vec<(i64, i64)> = (0..3)
            .flat_map(|i| (0..3).map(move |j| (2 * j + 1, 2 * i + 1)))
            .filter(|&c| c != (3, 3))
            .collect();
        want.sort();
        assert_eq!(centres, want, "{name}");
    }
    assert_eq!(
        builtin("carpet-square").unwrap().base().kind,
        PrimitiveKind::Box
    );
}

fn koch_file() -> PatternFile {
    PatternFile::of(&builtin("koch").unwrap(), None)
}

fn error_of(doc: &PatternFile) -> String {
    doc.pattern(Path::new("bad.json")).unwrap_err().to_string()
}

#[test]
fn bad_patterns_are_refused_with_the_culprit_named() {
    // Index out of range, naming the pair.
    let mut d = koch_file();
    d.pairs[2].target = [2, 7];
    let e = error_of(&d);
    assert!(
        e.contains("pair 2") && e.contains("point 7") && e.contains("only 5 points"),
        "{e}"
    );
    // A zero-length segment.
    let mut d = koch_file();
    d.points[3] = d.points[2];
    let e = error_of(&d);
    assert!(e.contains("pair 2") && e.contains("zero length"), "{e}");
    // A non-contractive map, naming map and scale.
    let mut d = koch_file();
    d.points[2] = [0.5, 2.0];
    let e = error_of(&d);
    assert!(
        e.contains("map 1") && e.contains("not contractive") && e.contains("scale is 2.0"),
        "{e}"
    );
    // Empty patterns.
    let mut d = koch_file();
    d.pairs.clear();
    assert!(error_of(&d).contains("no pairs"));
    let e = Pattern::new("x", vec![], vec![], None)
        .unwrap_err()
        .to_string();
    assert!(e.contains("no control points"), "{e}");
    // A NaN coordinate, naming the point.
    let mut pts = builtin("koch").unwrap().points().to_vec();
    pts[1][1] = f64::NAN;
    let e = Pattern::new("x", pts, builtin("koch").unwrap().pairs().to_vec(), None)
        .unwrap_err()
        .to_string();
    assert!(e.contains("point 1, coordinate y"), "{e}");
    // A base figure out of range.
    let mut d = koch_file();
    d.base = Some(BaseFigure {
        kind: PrimitiveKind::Disk,
        points: [0, 9],
    });
    assert!(error_of(&d).contains("base figure"));
}

#[test]
fn pattern_files_round_trip_and_bad_text_is_named() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("k.json");
    let koch = builtin("koch").unwrap();
    PatternFile::of(&koch, Some(serde_json::json!({"depth": 5})))
        .save(&path)
        .unwrap();
    let back = Pattern::load(&path).unwrap();
    assert_eq!(
        back, koch,
        "a file written and read back is the same pattern"
    );
    assert_eq!(PatternFile::load(&path).unwrap().meta.unwrap()["depth"], 5);
    assert_eq!(resolve_pattern(path.to_str().unwrap()).unwrap(), koch);
    // A bare NaN token (as Python writes it), with its line.
    let text = std::fs::read_to_string(&path)
        .unwrap()
        .replacen("0.5", "NaN", 1);
    let e = PatternFile::from_json(&text, &path)
        .unwrap_err()
        .to_string();
    assert!(e.contains("non-finite") && e.contains("line"), "{e}");
    // A wrong format tag, an unknown field, an unknown built-in.
    let text = std::fs::read_to_string(&path)
        .unwrap()
        .replace("ifslab-pattern/1", "x/2");
    let e = PatternFile::from_json(&text, &path)
        .unwrap_err()
        .to_string();
    assert!(e.contains("expected `ifslab-pattern/1`"), "{e}");
    let e = PatternFile::from_json(
        r#"{"format":"ifslab-pattern/1","points":[],"pairs":[],"bogus":1}"#,
        &path,
    )
    .unwrap_err()
    .to_string();
    assert!(e.contains("bogus"), "{e}");
    let e = resolve_pattern("kosh").unwrap_err().to_string();
    assert!(
        e.contains("unknown built-in pattern `kosh`") && e.contains("koch"),
        "{e}"
    );
    // A pair without its target.
    let e = PatternFile::from_json(
        r#"{"format":"ifslab-pattern/1","points":[[0,0],[1,0]],"pairs":[{"source":[0,1]}]}"#,
        &path,
    )
    .unwrap_err()
    .to_string();
    assert!(e.contains("missing field `target`"), "{e}");
}
