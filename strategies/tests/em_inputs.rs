//! Bad inputs to the EM strategy get their own clear errors.

use std::path::Path;

use ifslab_strategies::Error;
use ifslab_strategies::problems::em::{EmConfig, PointSet, fit};

fn write(dir: &Path, name: &str, bytes: &[u8]) -> std::path::PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, bytes).unwrap();
    p
}

fn message(r: Result<PointSet, Error>) -> String {
    match r {
        Ok(p) => panic!("expected an error, got {} points", p.len()),
        Err(e) => e.to_string(),
    }
}

/// A `.npy` file with the given header dict and body.
fn npy(dict: &str, body: &[u8]) -> Vec<u8> {
    let mut b = b"\x93NUMPY\x01\x00".to_vec();
    b.extend_from_slice(&(dict.len() as u16).to_le_bytes());
    b.extend_from_slice(dict.as_bytes());
    b.extend_from_slice(body);
    b
}

#[test]
fn malformed_csv_names_line_and_field() {
    let d = tempfile::tempdir().unwrap();
    let p = write(d.path(), "a.csv", b"x,y\n1,2\n3,abc\n");
    let m = message(PointSet::load(&p));
    assert!(
        m.contains("line 3") && m.contains("`abc`") && m.contains("a.csv"),
        "{m}"
    );
}

#[test]
fn mixed_dimensions_are_refused() {
    let d = tempfile::tempdir().unwrap();
    let p = write(d.path(), "b.csv", b"1,2\n3,4\n5,6,7\n");
    let m = message(PointSet::load(&p));
    assert!(
        m.contains("line 3") && m.contains("3 values") && m.contains("same dimension"),
        "{m}"
    );
    let rows = PointSet::from_rows(&[vec![1.0, 2.0], vec![1.0]]);
    assert!(matches!(rows, Err(Error::InvalidInput(_))));
}

#[test]
fn nan_and_infinite_rows_are_refused() {
    let d = tempfile::tempdir().unwrap();
    let p = write(d.path(), "c.csv", b"1 2\nNaN 4\n");
    let m = message(PointSet::load(&p));
    assert!(m.contains("line 2") && m.contains("NaN"), "{m}");
    let p = write(d.path(), "c2.txt", b"1;2\n3;inf\n");
    assert!(message(PointSet::load(&p)).contains("line 2"));
    let mut body = Vec::new();
    for v in [1.0f64, 2.0, f64::NAN, 4.0] {
        body.extend_from_slice(&v.to_le_bytes());
    }
    let p = write(
        d.path(),
        "n.npy",
        &npy(
            "{'descr': '<f8', 'fortran_order': False, 'shape': (2, 2), }",
            &body,
        ),
    );
    let m = message(PointSet::load(&p));
    assert!(m.contains("row 1") && m.contains("non-finite"), "{m}");
}

#[test]
fn malformed_npy_files_are_refused() {
    let d = tempfile::tempdir().unwrap();
    let cases: [(&str, Vec<u8>, &str); 4] = [
        (
            "dtype.npy",
            npy(
                "{'descr': '<c16', 'fortran_order': False, 'shape': (1, 1), }",
                &[0; 16],
            ),
            "not supported",
        ),
        (
            "shape.npy",
            npy(
                "{'descr': '<f8', 'fortran_order': False, 'shape': (2, 2, 2), }",
                &[0; 64],
            ),
            "1-D (N) or 2-D",
        ),
        (
            "short.npy",
            npy(
                "{'descr': '<f8', 'fortran_order': False, 'shape': (3, 2), }",
                &[0; 16],
            ),
            "truncated",
        ),
        ("magic.npy", b"hello".to_vec(), "not a NumPy"),
    ];
    for (name, bytes, want) in cases {
        let p = write(d.path(), name, &bytes);
        let m = message(PointSet::load(&p));
        assert!(m.contains(want) && m.contains(name), "{name}: {m}");
    }
}

#[test]
fn empty_and_missing_files_are_refused() {
    let d = tempfile::tempdir().unwrap();
    let p = write(d.path(), "e.csv", b"# only a comment\n\n");
    assert!(message(PointSet::load(&p)).contains("no data lines"));
    let m = message(PointSet::load(d.path().join("missing.csv")));
    assert!(m.contains("missing.csv"), "{m}");
}

#[test]
fn fewer_points_than_components_is_refused() {
    let data = PointSet::from_rows(&[vec![0.0, 0.0], vec![1.0, 0.0]]).unwrap();
    let cfg = EmConfig {
        components: 3,
        ..EmConfig::default()
    };
    let e = fit(&data, None, &cfg, &mut |_| {}).unwrap_err();
    let m = e.to_string();
    assert!(
        matches!(e, Error::InvalidInput(_)) && m.contains("2 training points for 3 components"),
        "{m}"
    );
}

#[test]
fn held_out_points_of_another_dimension_are_refused() {
    let data = PointSet::from_rows(&[vec![0.0, 0.0], vec![1.0, 0.0], vec![0.0, 1.0]]).unwrap();
    let other = PointSet::from_rows(&[vec![0.0, 0.0, 1.0]]).unwrap();
    let cfg = EmConfig {
        components: 2,
        ..EmConfig::default()
    };
    let m = fit(&data, Some(&other), &cfg, &mut |_| {})
        .unwrap_err()
        .to_string();
    assert!(
        m.contains("3-dimensional") && m.contains("2-dimensional"),
        "{m}"
    );
}

#[test]
fn invalid_hyper_parameters_name_the_field() {
    let data = PointSet::from_rows(&[vec![0.0], vec![1.0], vec![2.0]]).unwrap();
    for (cfg, field) in [
        (
            EmConfig {
                components: 0,
                ..EmConfig::default()
            },
            "k",
        ),
        (
            EmConfig {
                depth: 0,
                ..EmConfig::default()
            },
            "depth",
        ),
        (
            EmConfig {
                pool: 0,
                ..EmConfig::default()
            },
            "pool",
        ),
        (
            EmConfig {
                convergence: 1.5,
                ..EmConfig::default()
            },
            "convergence",
        ),
        (
            EmConfig {
                components: 8,
                depth: 9,
                ..EmConfig::default()
            },
            "depth",
        ),
    ] {
        match fit(&data, None, &cfg, &mut |_| {}) {
            Err(Error::InvalidParameter { name, .. }) => assert_eq!(name, field),
            other => panic!("{field}: expected an invalid-parameter error, got {other:?}"),
        }
    }
}
