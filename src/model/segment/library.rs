//! Built-in patterns by name: the paper's Koch curve and Sierpiński carpet, and the carpet
//! with a square base figure.
//!
//! The paper's supplementary A ("unit-square gallery") is not a pattern: it shows what the
//! Koch pattern converges to when fitted to a picture of the unit square, from starts the
//! paper does not give. It is reproduced by fitting `koch` to such a target, not listed here.

use std::path::Path;

use crate::error::{Error, Result};
use crate::model::segment::pattern::{BaseFigure, Pair, Pattern, PrimitiveKind};

/// Name and one-line description of every built-in pattern.
pub const BUILTIN_PATTERNS: &[(&str, &str)] = &[
    (
        "koch",
        "Koch curve: 5 points, {p0,p4} → {p_i,p_i+1}, segment base (the paper's Eq. 1)",
    ),
    (
        "carpet",
        "Sierpiński carpet: 16 grid points, the diagonal {p11,p44} → the diagonals of the 8 outer cells, segment base (supplementary B)",
    ),
    (
        "carpet-square",
        "the carpet's pairs with a filled square on the diagonal as base figure: square-to-square maps whose leaves tile the carpet",
    ),
];

/// The Koch curve from `(0, 0)` to `(1, 0)`: `p₂` is the apex `(1/2, √3/6)`.
pub fn koch() -> Pattern {
    let h = 3f64.sqrt() / 6.0;
    let points = vec![
        [0.0, 0.0],
        [1.0 / 3.0, 0.0],
        [0.5, h],
        [2.0 / 3.0, 0.0],
        [1.0, 0.0],
    ];
    let pairs = (0..4)
        .map(|i| Pair {
            source: [0, 4],
            target: [i, i + 1],
        })
        .collect();
    Pattern::new("koch", points, pairs, None).expect("the Koch pattern is valid")
}

/// Index of the paper's `p_{i,j}` (1-based row `i`, column `j`) in the carpet's points.
fn pij(i: usize, j: usize) -> usize {
    (i - 1) * 4 + (j - 1)
}

/// The carpet of supplementary B on the unit square: `p_{i,j} = ((j − 1)/3, (i − 1)/3)`,
/// the diagonal `{p₁₁, p₄₄}` mapped onto the diagonals `{p_{i,j}, p_{i+1,j+1}}` of the eight
/// outer cells (the centre cell `{p₂₂, p₃₃}` left out).
fn carpet_with(kind: PrimitiveKind, name: &str) -> Pattern {
    let points = (1..=4)
        .flat_map(|i| (1..=4).map(move |j| [(j - 1) as f64 / 3.0, (i - 1) as f64 / 3.0]))
        .collect();
    let cells = [
        (1, 1),
        (1, 2),
        (1, 3),
        (2, 1),
        (2, 3),
        (3, 1),
        (3, 2),
        (3, 3),
    ];
    let pairs = cells
        .iter()
        .map(|&(i, j)| Pair {
            source: [pij(1, 1), pij(4, 4)],
            target: [pij(i, j), pij(i + 1, j + 1)],
        })
        .collect();
    let base = BaseFigure {
        kind,
        points: [pij(1, 1), pij(4, 4)],
    };
    Pattern::new(name, points, pairs, Some(base)).expect("the carpet pattern is valid")
}

/// The paper's carpet pattern with a segment base figure.
pub fn carpet() -> Pattern {
    carpet_with(PrimitiveKind::Segment, "carpet")
}

/// The carpet pattern with a filled square (diagonal `{p₁₁, p₄₄}`) as base figure.
pub fn carpet_square() -> Pattern {
    carpet_with(PrimitiveKind::Box, "carpet-square")
}

/// The built-in pattern called `name`.
pub fn builtin(name: &str) -> Result<Pattern> {
    match name {
        "koch" => Ok(koch()),
        "carpet" => Ok(carpet()),
        "carpet-square" => Ok(carpet_square()),
        other => Err(Error::Pattern(format!(
            "unknown built-in pattern `{other}`; known: {}, or a pattern file (.json)",
            BUILTIN_PATTERNS
                .iter()
                .map(|(n, _)| *n)
                .collect::<Vec<_>>()
                .join(", ")
        ))),
    }
}

/// A built-in name, or else the path of a pattern file.
pub fn resolve_pattern(spec: &str) -> Result<Pattern> {
    if BUILTIN_PATTERNS.iter().any(|(n, _)| *n == spec) {
        return builtin(spec);
    }
    let path = Path::new(spec);
    if path.exists() || spec.ends_with(".json") {
        return Pattern::load(path);
    }
    builtin(spec)
}
