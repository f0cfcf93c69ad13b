//! The classic IFS codes, by name: the targets every paper in the field starts from.

use nalgebra::{DMatrix, DVector};

use crate::error::{Error, Result};
use crate::model::affine::{Affine2, AffineN};
use crate::model::code::IfsCode;

/// One entry of the library.
struct Entry {
    name: &'static str,
    about: &'static str,
    build: fn() -> IfsCode,
}

const ENTRIES: &[Entry] = &[
    Entry {
        name: "sierpinski",
        about: "Sierpiński triangle: 3 maps of ratio 1/2 (dimension log 3 / log 2 ≈ 1.585)",
        build: sierpinski,
    },
    Entry {
        name: "fern",
        about: "Barnsley fern: 4 affine maps with Barnsley's probabilities",
        build: fern,
    },
    Entry {
        name: "koch",
        about: "Koch curve: 4 similitudes of ratio 1/3 (dimension log 4 / log 3 ≈ 1.262)",
        build: koch,
    },
    Entry {
        name: "carpet",
        about: "Sierpiński carpet: 8 maps of ratio 1/3 (dimension log 8 / log 3 ≈ 1.893)",
        build: carpet,
    },
    Entry {
        name: "dragon",
        about: "Heighway dragon: 2 similitudes of ratio 1/√2",
        build: dragon,
    },
    Entry {
        name: "levy",
        about: "Lévy C curve: 2 similitudes of ratio 1/√2",
        build: levy,
    },
    Entry {
        name: "maple",
        about: "maple leaf: 4 affine maps (Barnsley)",
        build: maple,
    },
    Entry {
        name: "pentagon",
        about: "Sierpiński pentagon: 5 maps of ratio (3 − √5)/2",
        build: pentagon,
    },
    Entry {
        name: "vicsek",
        about: "Vicsek fractal: 5 maps of ratio 1/3 in a cross",
        build: vicsek,
    },
    Entry {
        name: "spiral",
        about: "spiral: 3 affine maps (Bourke), one nearly a rotation",
        build: spiral,
    },
    Entry {
        name: "tree",
        about: "binary tree: 4 affine maps (Bourke)",
        build: tree,
    },
    Entry {
        name: "twindragon",
        about: "twin dragon: the base-(1+i) tile, 2 maps of ratio 1/√2 (dimension 2)",
        build: twindragon,
    },
    Entry {
        name: "tetrahedron",
        about: "3-D Sierpiński tetrahedron: 4 maps of ratio 1/2 (for point-cloud fitting)",
        build: tetrahedron,
    },
];

/// Names of every built-in code, in library order.
pub fn names() -> Vec<&'static str> {
    ENTRIES.iter().map(|e| e.name).collect()
}

/// `(name, one-line description)` of every built-in code.
pub fn catalogue() -> Vec<(&'static str, &'static str)> {
    ENTRIES.iter().map(|e| (e.name, e.about)).collect()
}

/// The built-in code called `name` (case-insensitive).
pub fn builtin(name: &str) -> Result<IfsCode> {
    let lower = name.to_ascii_lowercase();
    ENTRIES
        .iter()
        .find(|e| e.name == lower)
        .map(|e| (e.build)())
        .ok_or_else(|| Error::UnknownCode {
            name: name.to_owned(),
            known: names().join(", "),
        })
}

fn code2(name: &str, maps: &[Affine2], probs: Option<Vec<f64>>) -> IfsCode {
    let code = IfsCode::from_affine2(Some(name), maps).expect("built-in codes are valid");
    match probs {
        Some(p) => code
            .with_probabilities(p)
            .expect("built-in probabilities are valid"),
        None => code,
    }
}

fn sierpinski() -> IfsCode {
    let h = 3f64.sqrt() / 2.0;
    code2(
        "sierpinski",
        &[
            Affine2::new(0.5, 0.0, 0.0, 0.5, 0.0, 0.0),
            Affine2::new(0.5, 0.0, 0.0, 0.5, 0.5, 0.0),
            Affine2::new(0.5, 0.0, 0.0, 0.5, 0.25, 0.5 * h),
        ],
        None,
    )
}

fn fern() -> IfsCode {
    code2(
        "fern",
        &[
            Affine2::new(0.0, 0.0, 0.0, 0.16, 0.0, 0.0),
            Affine2::new(0.85, 0.04, -0.04, 0.85, 0.0, 1.6),
            Affine2::new(0.2, -0.26, 0.23, 0.22, 0.0, 1.6),
            Affine2::new(-0.15, 0.28, 0.26, 0.24, 0.0, 0.44),
        ],
        Some(vec![0.01, 0.85, 0.07, 0.07]),
    )
}

fn koch() -> IfsCode {
    let third = 1.0 / 3.0;
    let pi3 = std::f64::consts::FRAC_PI_3;
    code2(
        "koch",
        &[
            Affine2::similitude(third, 0.0, false, [0.0, 0.0]),
            Affine2::similitude(third, pi3, false, [third, 0.0]),
            Affine2::similitude(third, -pi3, false, [0.5, 3f64.sqrt() / 6.0]),
            Affine2::similitude(third, 0.0, false, [2.0 * third, 0.0]),
        ],
        None,
    )
}

fn carpet() -> IfsCode {
    let t = 1.0 / 3.0;
    let mut maps = Vec::new();
    for j in 0..3 {
        for i in 0..3 {
            if i != 1 || j != 1 {
                maps.push(Affine2::new(t, 0.0, 0.0, t, i as f64 * t, j as f64 * t));
            }
        }
    }
    code2("carpet", &maps, None)
}

fn dragon() -> IfsCode {
    code2(
        "dragon",
        &[
            Affine2::new(0.5, -0.5, 0.5, 0.5, 0.0, 0.0),
            Affine2::new(-0.5, -0.5, 0.5, -0.5, 1.0, 0.0),
        ],
        None,
    )
}

fn levy() -> IfsCode {
    code2(
        "levy",
        &[
            Affine2::new(0.5, -0.5, 0.5, 0.5, 0.0, 0.0),
            Affine2::new(0.5, 0.5, -0.5, 0.5, 0.5, 0.5),
        ],
        None,
    )
}

fn maple() -> IfsCode {
    code2(
        "maple",
        &[
            Affine2::new(0.14, 0.01, 0.0, 0.51, -0.08, -1.31),
            Affine2::new(0.43, 0.52, -0.45, 0.5, 1.49, -0.75),
            Affine2::new(0.45, -0.49, 0.47, 0.47, -1.62, -0.74),
            Affine2::new(0.49, 0.0, 0.0, 0.51, 0.02, 1.62),
        ],
        Some(vec![0.1, 0.35, 0.35, 0.2]),
    )
}

fn pentagon() -> IfsCode {
    let r = (3.0 - 5f64.sqrt()) / 2.0;
    let maps: Vec<Affine2> = (0..5)
        .map(|k| {
            let a = std::f64::consts::FRAC_PI_2 + k as f64 * 2.0 * std::f64::consts::PI / 5.0;
            Affine2::new(r, 0.0, 0.0, r, (1.0 - r) * a.cos(), (1.0 - r) * a.sin())
        })
        .collect();
    code2("pentagon", &maps, None)
}

fn vicsek() -> IfsCode {
    let t = 1.0 / 3.0;
    let cells = [(1, 1), (0, 1), (2, 1), (1, 0), (1, 2)];
    let maps: Vec<Affine2> = cells
        .iter()
        .map(|&(i, j)| Affine2::new(t, 0.0, 0.0, t, i as f64 * t, j as f64 * t))
        .collect();
    code2("vicsek", &maps, None)
}

fn spiral() -> IfsCode {
    code2(
        "spiral",
        &[
            Affine2::new(0.787879, -0.424242, 0.242424, 0.859848, 1.758647, 1.408065),
            Affine2::new(-0.121212, 0.257576, 0.151515, 0.05303, -6.721654, 1.377236),
            Affine2::new(0.181818, -0.136364, 0.090909, 0.181818, 6.086107, 1.568035),
        ],
        Some(vec![0.9, 0.05, 0.05]),
    )
}

fn tree() -> IfsCode {
    code2(
        "tree",
        &[
            Affine2::new(0.0, 0.0, 0.0, 0.5, 0.0, 0.0),
            Affine2::new(0.42, -0.42, 0.42, 0.42, 0.0, 0.2),
            Affine2::new(0.42, 0.42, -0.42, 0.42, 0.0, 0.2),
            Affine2::new(0.1, 0.0, 0.0, 0.1, 0.0, 0.2),
        ],
        Some(vec![0.05, 0.4, 0.4, 0.15]),
    )
}

fn twindragon() -> IfsCode {
    code2(
        "twindragon",
        &[
            Affine2::new(0.5, 0.5, -0.5, 0.5, 0.0, 0.0),
            Affine2::new(0.5, 0.5, -0.5, 0.5, 0.5, -0.5),
        ],
        None,
    )
}

fn tetrahedron() -> IfsCode {
    let v = [
        [1.0, 1.0, 1.0],
        [1.0, -1.0, -1.0],
        [-1.0, 1.0, -1.0],
        [-1.0, -1.0, 1.0],
    ];
    let maps = v
        .iter()
        .map(|p| AffineN {
            m: DMatrix::identity(3, 3) * 0.5,
            b: DVector::from_row_slice(&[0.5 * p[0], 0.5 * p[1], 0.5 * p[2]]),
        })
        .collect();
    let code = IfsCode {
        name: Some("tetrahedron".into()),
        maps,
        probabilities: None,
        framing: None,
        allow_non_contractive: false,
        meta: Default::default(),
    };
    code.validate().expect("built-in codes are valid");
    code
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_builtin_is_valid_and_findable() {
        for name in names() {
            let c = builtin(name).unwrap();
            c.validate().unwrap();
            assert_eq!(c.name.as_deref(), Some(name));
        }
        assert!(matches!(builtin("nope"), Err(Error::UnknownCode { .. })));
        assert!(builtin("FERN").is_ok());
    }
}
