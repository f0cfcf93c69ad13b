//! Scores of 3-D attractors as point sets: voxel IoU with a tolerance, and the symmetric
//! Chamfer distance.
//!
//! Both take point clouds (a chaos game's kept points, [`crate::chaos::points3`]) rather
//! than codes, so a recovered code, a ground truth and a point cloud from elsewhere are
//! scored alike.

use rayon::prelude::*;

use crate::error::{Error, Result};

/// The voxel grid of [`voxel_iou`]: `resolution³` cubic voxels filling the cube of side
/// `side` whose lowest corner is `origin`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct VoxelBox {
    /// The cube's lowest corner.
    pub origin: [f64; 3],
    /// The cube's side.
    pub side: f64,
    /// Voxels per side.
    pub resolution: usize,
}

impl VoxelBox {
    /// The box both sets share: the cube centred on the axis-aligned bounding box of the two
    /// sets together, its side that box's longest extent (grown by 1e-9 of itself so
    /// the extreme points fall inside, and at least 1e-12 for a single point).
    pub fn around(a: &[[f64; 3]], b: &[[f64; 3]], resolution: usize) -> Result<VoxelBox> {
        let mut lo = [f64::INFINITY; 3];
        let mut hi = [f64::NEG_INFINITY; 3];
        for p in a.iter().chain(b) {
            for k in 0..3 {
                lo[k] = lo[k].min(p[k]);
                hi[k] = hi[k].max(p[k]);
            }
        }
        if lo[0] > hi[0] {
            return Err(Error::Empty("both point sets are empty".into()));
        }
        let ext = (0..3).map(|k| hi[k] - lo[k]).fold(0.0f64, f64::max);
        let side = (ext * (1.0 + 1e-9)).max(1e-12);
        let origin = std::array::from_fn(|k| 0.5 * (lo[k] + hi[k]) - 0.5 * side);
        Ok(VoxelBox {
            origin,
            side,
            resolution,
        })
    }

    /// The voxel holding `p` (points on the far faces go to the last voxel, points outside
    /// the cube to the nearest voxel).
    #[inline]
    pub fn voxel(&self, p: [f64; 3]) -> [usize; 3] {
        let n = self.resolution;
        std::array::from_fn(|k| {
            let t = (p[k] - self.origin[k]) / self.side * n as f64;
            (t.max(0.0) as usize).min(n - 1)
        })
    }

    /// The occupancy of `points`: one flag per voxel, `x` fastest.
    pub fn occupancy(&self, points: &[[f64; 3]]) -> Vec<bool> {
        let n = self.resolution;
        let mut occ = vec![false; n * n * n];
        for &p in points {
            let [x, y, z] = self.voxel(p);
            occ[(z * n + y) * n + x] = true;
        }
        occ
    }
}

/// `occ` dilated by `t` voxels in the Chebyshev (∞-norm) sense: a voxel is set when some
/// set voxel lies within `t` steps along every axis (a `(2t + 1)³` cube), done axis by axis.
fn dilate(occ: &[bool], n: usize, t: usize) -> Vec<bool> {
    if t == 0 {
        return occ.to_vec();
    }
    let mut cur = occ.to_vec();
    for stride in [1, n, n * n] {
        let mut next = vec![false; cur.len()];
        for (i, slot) in next.iter_mut().enumerate() {
            let c = (i / stride) % n;
            let lo = c.saturating_sub(t);
            let hi = (c + t).min(n - 1);
            let base = i - c * stride;
            *slot = (lo..=hi).any(|k| cur[base + k * stride]);
        }
        cur = next;
    }
    cur
}

/// Voxel IoU of two point sets with a tolerance of `tolerance` voxels.
///
/// Both sets are voxelised in the same `resolution³` grid ([`VoxelBox::around`]: the cube
/// around both sets together), giving occupied-voxel sets `A` and `B`. With `D_t(X)` the
/// voxels within Chebyshev distance `t` of a voxel of `X` (X dilated by a `(2t + 1)³`
/// cube), a voxel of `A` is *matched* when it lies in `D_t(B)`, and one of `B` when it
/// lies in `D_t(A)`; with `I_t = (|A ∩ D_t(B)| + |B ∩ D_t(A)|)/2` the matched count,
///
/// `IoU_t = I_t / (|A| + |B| − I_t)`.
///
/// At `t = 0` this is the plain IoU `|A ∩ B|/|A ∪ B|`; for any `t` it lies in `[0, 1]` and
/// is 1 exactly when every occupied voxel of each set has one of the other within `t`
/// voxels — so a thin structure shifted by one voxel (a 3-D fern's stalk) scores 1 at
/// `t = 1`, where its plain IoU can be 0. Issue 39 scores at `resolution = 64`,
/// `tolerance = 1`. Two empty sets are refused; one empty set scores 0.
pub fn voxel_iou(
    a: &[[f64; 3]],
    b: &[[f64; 3]],
    resolution: usize,
    tolerance: usize,
) -> Result<f64> {
    if resolution == 0 || resolution > 1024 {
        return Err(Error::param(
            "resolution",
            format!("must lie in 1..=1024 voxels per side, got {resolution}"),
        ));
    }
    check_points("first set", a)?;
    check_points("second set", b)?;
    if a.is_empty() || b.is_empty() {
        return if a.is_empty() && b.is_empty() {
            Err(Error::Empty("both point sets are empty".into()))
        } else {
            Ok(0.0)
        };
    }
    let bx = VoxelBox::around(a, b, resolution)?;
    Ok(voxel_iou_in(&bx, a, b, tolerance))
}

/// [`voxel_iou`] in a given grid (to score several sets against one truth in one box).
pub fn voxel_iou_in(bx: &VoxelBox, a: &[[f64; 3]], b: &[[f64; 3]], tolerance: usize) -> f64 {
    let n = bx.resolution;
    let (oa, ob) = (bx.occupancy(a), bx.occupancy(b));
    let (da, db) = (dilate(&oa, n, tolerance), dilate(&ob, n, tolerance));
    let count = |x: &[bool]| x.iter().filter(|&&v| v).count() as f64;
    let matched = |x: &[bool], d: &[bool]| x.iter().zip(d).filter(|(x, d)| **x && **d).count();
    let (na, nb) = (count(&oa), count(&ob));
    if na + nb == 0.0 {
        return 1.0;
    }
    let i = 0.5 * (matched(&oa, &db) + matched(&ob, &da)) as f64;
    i / (na + nb - i)
}

fn check_points(what: &str, p: &[[f64; 3]]) -> Result<()> {
    if let Some((i, q)) = p
        .iter()
        .enumerate()
        .find(|(_, q)| q.iter().any(|v| !v.is_finite()))
    {
        return Err(Error::NonFinite {
            what: format!("the {what} of points"),
            location: format!("point {i}"),
            value: q
                .iter()
                .copied()
                .find(|v| !v.is_finite())
                .unwrap_or(f64::NAN),
        });
    }
    Ok(())
}

/// A uniform grid of cells over a point set, for nearest-neighbour queries.
struct CellGrid<'a> {
    points: &'a [[f64; 3]],
    lo: [f64; 3],
    h: f64,
    n: [usize; 3],
    start: Vec<usize>,
    order: Vec<u32>,
}

impl<'a> CellGrid<'a> {
    /// About two points per cell along the set's bounding box.
    fn new(points: &'a [[f64; 3]]) -> Self {
        let mut lo = [f64::INFINITY; 3];
        let mut hi = [f64::NEG_INFINITY; 3];
        for p in points {
            for k in 0..3 {
                lo[k] = lo[k].min(p[k]);
                hi[k] = hi[k].max(p[k]);
            }
        }
        let ext: [f64; 3] = std::array::from_fn(|k| (hi[k] - lo[k]).max(0.0));
        let vol = ext.iter().map(|e| e.max(1e-12)).product::<f64>();
        let cells = (points.len() as f64 / 2.0).max(1.0);
        let h = (vol / cells)
            .cbrt()
            .max(ext.iter().fold(0.0f64, |a, &e| a.max(e)) / 256.0)
            .max(1e-12);
        // h ≥ the longest extent / 256: at most 257 cells a side, each point inside its cell.
        let n: [usize; 3] = std::array::from_fn(|k| (ext[k] / h) as usize + 1);
        let cell_of = |p: &[f64; 3]| -> usize {
            let c: [usize; 3] =
                std::array::from_fn(|k| (((p[k] - lo[k]) / h) as usize).min(n[k] - 1));
            (c[2] * n[1] + c[1]) * n[0] + c[0]
        };
        let mut start = vec![0usize; n[0] * n[1] * n[2] + 1];
        for p in points {
            start[cell_of(p) + 1] += 1;
        }
        for i in 1..start.len() {
            start[i] += start[i - 1];
        }
        let mut fill = start.clone();
        let mut order = vec![0u32; points.len()];
        for (j, p) in points.iter().enumerate() {
            let c = cell_of(p);
            order[fill[c]] = j as u32;
            fill[c] += 1;
        }
        CellGrid {
            points,
            lo,
            h,
            n,
            start,
            order,
        }
    }

    /// The distance from `q` to the nearest point: cells in growing Chebyshev rings around
    /// `q`'s (clamped) cell, stopping once the best distance is within the ring's reach
    /// (a point in ring `r + 1` or beyond is at least `r·h` away) or the rings have covered
    /// the grid. Only a ring's cells inside the grid are visited (its faces in full, its
    /// inner rows at their two ends), so a query far from the points, or a flat set, costs
    /// at most one pass over the cells.
    fn nearest(&self, q: [f64; 3]) -> f64 {
        let n: [i64; 3] = std::array::from_fn(|k| self.n[k] as i64);
        let c: [i64; 3] = std::array::from_fn(|k| {
            (((q[k] - self.lo[k]) / self.h).floor() as i64).clamp(0, n[k] - 1)
        });
        // The smallest squared distance from `q` to a point of cell (x, y, z).
        let cell_min = |x: i64, y: i64, z: i64| {
            let cell = ((z as usize * self.n[1] + y as usize) * self.n[0]) + x as usize;
            self.order[self.start[cell]..self.start[cell + 1]]
                .iter()
                .map(|&j| {
                    let p = self.points[j as usize];
                    (0..3).map(|k| (p[k] - q[k]) * (p[k] - q[k])).sum::<f64>()
                })
                .fold(f64::INFINITY, f64::min)
        };
        let mut best = f64::INFINITY;
        // The farthest ring that still holds a cell of the grid.
        let last = (0..3).map(|k| c[k].max(n[k] - 1 - c[k])).max().unwrap_or(0);
        for r in 0..=last {
            let lo: [i64; 3] = std::array::from_fn(|k| (c[k] - r).max(0));
            let hi: [i64; 3] = std::array::from_fn(|k| (c[k] + r).min(n[k] - 1));
            for z in lo[2]..=hi[2] {
                let z_face = (z - c[2]).abs() == r;
                for y in lo[1]..=hi[1] {
                    if z_face || (y - c[1]).abs() == r {
                        for x in lo[0]..=hi[0] {
                            best = best.min(cell_min(x, y, z));
                        }
                    } else {
                        for x in [c[0] - r, c[0] + r] {
                            if (0..n[0]).contains(&x) {
                                best = best.min(cell_min(x, y, z));
                            }
                        }
                    }
                }
            }
            if best.is_finite() && best.sqrt() <= r as f64 * self.h {
                break;
            }
        }
        best.sqrt()
    }
}

/// The symmetric Chamfer distance of two point sets, in the points' units:
///
/// `CD(A, B) = ½·(mean_{a∈A} min_{b∈B} |a − b| + mean_{b∈B} min_{a∈A} |a − b|)`
///
/// (Euclidean distances, not squared, so it reads as "how far apart, on average"). Exact
/// nearest neighbours through a uniform grid of cells. Refuses empty and non-finite sets.
pub fn chamfer_distance(a: &[[f64; 3]], b: &[[f64; 3]]) -> Result<f64> {
    check_points("first set", a)?;
    check_points("second set", b)?;
    if a.is_empty() || b.is_empty() {
        return Err(Error::Empty(
            "the Chamfer distance needs two non-empty point sets".into(),
        ));
    }
    let one_way = |from: &[[f64; 3]], to: &[[f64; 3]]| {
        nearest_among(from, to).iter().sum::<f64>() / from.len() as f64
    };
    Ok(0.5 * (one_way(a, b) + one_way(b, a)))
}

/// For each point of `from`, the distance to its nearest point of `to` (exact, through a
/// uniform grid of cells), in `from`'s order. Refuses an empty `to` and non-finite points.
pub fn nearest_distances(from: &[[f64; 3]], to: &[[f64; 3]]) -> Result<Vec<f64>> {
    check_points("query points", from)?;
    check_points("reference points", to)?;
    if to.is_empty() {
        return Err(Error::Empty(
            "nearest distances need at least one reference point".into(),
        ));
    }
    Ok(nearest_among(from, to))
}

/// [`nearest_distances`] of checked, non-empty sets.
fn nearest_among(from: &[[f64; 3]], to: &[[f64; 3]]) -> Vec<f64> {
    let grid = CellGrid::new(to);
    from.par_iter()
        .with_min_len(1024)
        .map(|&q| grid.nearest(q))
        .collect()
}
