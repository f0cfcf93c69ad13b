//! A segment pattern: control points, the symmetry pairs that turn them into maps, and the
//! base figure the renderer draws at the leaves.

use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};
use crate::model::segment::complex::{abs, sub};
use crate::model::segment::map::SegmentMap;

/// One element of the symmetry pattern: the map taking segment `source` onto segment
/// `target`, each an ordered pair of control-point indices (`source[0] ↦ target[0]`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Pair {
    /// Endpoints of the segment the map starts from.
    pub source: [usize; 2],
    /// Endpoints of the segment it lands on.
    pub target: [usize; 2],
}

/// The shape of the base figure, built on two control points `a`, `b`.
///
/// Every kind is determined by the two points and maps to the same kind under a similitude
/// (the images of `a` and `b` define the image), so the renderer keeps two points per
/// primitive whatever the kind, and the gradient reaches the control points through them.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum PrimitiveKind {
    /// The segment `[a, b]` (the paper's choice for the Koch curve).
    #[default]
    Segment,
    /// The filled disk with diameter `[a, b]`.
    Disk,
    /// The filled square with diagonal `[a, b]`.
    Box,
}

impl PrimitiveKind {
    /// The name files use.
    pub fn name(self) -> &'static str {
        match self {
            PrimitiveKind::Segment => "segment",
            PrimitiveKind::Disk => "disk",
            PrimitiveKind::Box => "box",
        }
    }
}

/// The base figure: a primitive on two control points. By default the segment the first
/// pair maps from (the paper's Koch construction starts from `{p₀, p₄}`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BaseFigure {
    /// Segment, disk or box.
    #[serde(default)]
    pub kind: PrimitiveKind,
    /// The two control points it is built on.
    pub points: [usize; 2],
}

/// Control points `P`, symmetry pairs `L` and a base figure: the paper's `(P, L, D)`.
///
/// The points are the parameters; pairs and base figure are structure. Built with
/// [`Pattern::new`], which refuses anything that cannot define an IFS (see there).
#[derive(Clone, Debug, PartialEq)]
pub struct Pattern {
    name: String,
    points: Vec<[f64; 2]>,
    pairs: Vec<Pair>,
    base: BaseFigure,
}

/// Relative length below which a segment counts as degenerate (of the points' extent).
const DEGENERATE: f64 = 1e-12;

impl Pattern {
    /// A validated pattern. Refused, with the offending element named: no points or no
    /// pairs, a non-finite coordinate, an index out of range, a zero-length segment (a
    /// source segment defines no map; a target one a map that collapses everything), and a
    /// non-contractive map (scale `≥ 1`). `base` defaults to a segment on the first pair's
    /// source.
    pub fn new(
        name: impl Into<String>,
        points: Vec<[f64; 2]>,
        pairs: Vec<Pair>,
        base: Option<BaseFigure>,
    ) -> Result<Self> {
        let p = Pattern::new_any_scale(name, points, pairs, base)?;
        for (i, m) in p.maps()?.iter().enumerate() {
            let s = m.scale();
            if s >= 1.0 {
                let pr = p.pairs[i];
                return Err(Error::Pattern(format!(
                    "map {i} (pair {i}: {:?} → {:?}) is not contractive: its scale is {s:.6} (must be < 1); \
                     the target segment must be shorter than the source segment",
                    pr.source, pr.target
                )));
            }
        }
        Ok(p)
    }

    /// [`Pattern::new`] without the contractivity check: for an optimiser's intermediate
    /// patterns (as [`Pattern::with_flat_points`]), which the renderer draws to a finite
    /// depth whatever their scales.
    pub fn new_any_scale(
        name: impl Into<String>,
        points: Vec<[f64; 2]>,
        pairs: Vec<Pair>,
        base: Option<BaseFigure>,
    ) -> Result<Self> {
        if points.is_empty() {
            return Err(Error::Pattern("the pattern has no control points".into()));
        }
        if pairs.is_empty() {
            return Err(Error::Pattern(
                "the pattern has no pairs; each (source, target) pair of segments defines one map"
                    .into(),
            ));
        }
        let base = base.unwrap_or(BaseFigure {
            kind: PrimitiveKind::Segment,
            points: pairs[0].source,
        });
        let n = points.len();
        for (i, pr) in pairs.iter().enumerate() {
            for (role, seg) in [("source", pr.source), ("target", pr.target)] {
                if let Some(&k) = seg.iter().find(|&&k| k >= n) {
                    return Err(Error::Pattern(format!(
                        "pair {i}: {role} segment {seg:?} names point {k}, but there are only {n} points (indices 0..{})",
                        n - 1
                    )));
                }
            }
        }
        if let Some(&k) = base.points.iter().find(|&&k| k >= n) {
            return Err(Error::Pattern(format!(
                "base figure: names point {k}, but there are only {n} points (indices 0..{})",
                n - 1
            )));
        }
        let p = Pattern {
            name: name.into(),
            points,
            pairs,
            base,
        };
        p.check_points(&p.points)?;
        Ok(p)
    }

    /// Checks finiteness and non-degenerate segments of `points` for this pattern.
    fn check_points(&self, points: &[[f64; 2]]) -> Result<()> {
        if points.len() != self.points.len() {
            return Err(Error::Shape(format!(
                "{} control points given to a pattern of {}",
                points.len(),
                self.points.len()
            )));
        }
        for (k, p) in points.iter().enumerate() {
            for (c, v) in p.iter().enumerate() {
                if !v.is_finite() {
                    return Err(Error::NonFinite {
                        what: "segment pattern".into(),
                        location: format!("point {k}, coordinate {}", ["x", "y"][c]),
                        value: *v,
                    });
                }
            }
        }
        let extent = points
            .iter()
            .map(|p| abs(sub(*p, points[0])))
            .fold(0.0, f64::max)
            .max(f64::MIN_POSITIVE);
        let short =
            |seg: [usize; 2]| abs(sub(points[seg[1]], points[seg[0]])) <= DEGENERATE * extent;
        for (i, pr) in self.pairs.iter().enumerate() {
            for (role, seg) in [("source", pr.source), ("target", pr.target)] {
                if short(seg) {
                    return Err(Error::Pattern(format!(
                        "pair {i}: {role} segment {seg:?} has zero length (points {} and {} coincide at {:?}); \
                         a segment needs two distinct endpoints",
                        seg[0], seg[1], points[seg[0]]
                    )));
                }
            }
        }
        if short(self.base.points) {
            return Err(Error::Pattern(format!(
                "base figure: segment {:?} has zero length",
                self.base.points
            )));
        }
        Ok(())
    }

    /// The pattern's name (`koch`, a file's stem, …).
    pub fn name(&self) -> &str {
        &self.name
    }

    /// The control points.
    pub fn points(&self) -> &[[f64; 2]] {
        &self.points
    }

    /// The symmetry pairs.
    pub fn pairs(&self) -> &[Pair] {
        &self.pairs
    }

    /// The base figure.
    pub fn base(&self) -> BaseFigure {
        self.base
    }

    /// The number of maps (one per pair).
    pub fn n_maps(&self) -> usize {
        self.pairs.len()
    }

    /// The control points as a flat `[x₀, y₀, x₁, y₁, …]`: the parameter vector θ.
    pub fn flat_points(&self) -> Vec<f64> {
        self.points.iter().flat_map(|p| *p).collect()
    }

    /// The same structure with other control points (flat `[x₀, y₀, …]`). Checks length,
    /// finiteness and non-degenerate segments but not contractivity: an optimiser may pass
    /// through non-contractive patterns, which the renderer draws to a finite depth all
    /// the same.
    pub fn with_flat_points(&self, flat: &[f64]) -> Result<Pattern> {
        if flat.len() != 2 * self.points.len() {
            return Err(Error::Shape(format!(
                "{} numbers given for {} control points (2 each)",
                flat.len(),
                self.points.len()
            )));
        }
        let points: Vec<[f64; 2]> = flat.chunks_exact(2).map(|c| [c[0], c[1]]).collect();
        self.check_points(&points)?;
        Ok(Pattern {
            points,
            ..self.clone()
        })
    }

    /// The same pattern under another name.
    pub fn renamed(mut self, name: impl Into<String>) -> Pattern {
        self.name = name.into();
        self
    }

    /// The maps, pair by pair.
    pub fn maps(&self) -> Result<Vec<SegmentMap>> {
        let p = &self.points;
        self.pairs
            .iter()
            .enumerate()
            .map(|(i, pr)| {
                SegmentMap::between(
                    p[pr.source[0]],
                    p[pr.source[1]],
                    p[pr.target[0]],
                    p[pr.target[1]],
                )
                .ok_or_else(|| {
                    Error::Pattern(format!(
                        "pair {i}: source segment {:?} has zero length",
                        pr.source
                    ))
                })
            })
            .collect()
    }

    /// The base figure's two points.
    pub fn base_points(&self) -> [[f64; 2]; 2] {
        [
            self.points[self.base.points[0]],
            self.points[self.base.points[1]],
        ]
    }

    /// The chain rule from the maps to the control points: `grad_maps[i]` is
    /// `[∂L/∂w_re, ∂L/∂w_im, ∂L/∂t_x, ∂L/∂t_y]` of map `i`; the result is `∂L/∂θ` in the
    /// flat layout of [`Pattern::flat_points`], accumulated into `out`.
    pub fn maps_backward(&self, grad_maps: &[[f64; 4]], out: &mut [f64]) {
        let p = &self.points;
        for (pr, g) in self.pairs.iter().zip(grad_maps) {
            let idx = [pr.source[0], pr.source[1], pr.target[0], pr.target[1]];
            let gs = SegmentMap::between_backward(
                p[idx[0]],
                p[idx[1]],
                p[idx[2]],
                p[idx[3]],
                [g[0], g[1]],
                [g[2], g[3]],
            );
            for (k, gk) in idx.iter().zip(gs) {
                out[2 * k] += gk[0];
                out[2 * k + 1] += gk[1];
            }
        }
    }

    /// A copy with every point mapped by `f` (framing a pattern into a window); the result is
    /// validated again.
    pub fn transformed(&self, f: &SegmentMap) -> Result<Pattern> {
        use crate::model::map::Map;
        Pattern::new(
            self.name.clone(),
            self.points.iter().map(|&p| f.apply(p)).collect(),
            self.pairs.clone(),
            Some(self.base),
        )
    }
}
