//! The self-crossing penalty Scott proposes but did not build: the local optima of the
//! paper's Fig. 4 and 7 are figures that cross themselves, so a term that is zero unless two
//! copies of the base figure cross, and grows with how deep they cross, pushes the descent
//! away from them.
//!
//! The copies are the base figure's images under every word of length `depth` (depth 1: one
//! per map; for the Koch pattern these are the four segments of the polyline
//! `p₀ p₁ p₂ p₃ p₄`). Each copy is read as the segment between its two points (for a disk
//! or box base, its diameter or diagonal). Two segments `AB`, `CD` cross when `C`, `D` lie
//! strictly on opposite sides of line `AB` and `A`, `B` on opposite sides of line `CD`; the
//! depth of the crossing is then the smallest of the four endpoints' distances to the other
//! segment's line — how far one endpoint must move to undo it — and the penalty is the sum
//! of the squared depths over all pairs of copies. It is continuous (a depth is zero where a
//! crossing begins or ends, and copies that share an endpoint have depth zero) and
//! differentiable wherever the smallest distance is unique; its gradient reaches the control
//! points through [`WordTree::backward`] and [`Pattern::maps_backward`], as the renderer's.

use ifslab::model::segment::Pattern;
use ifslab::render::sdf::WordTree;

use crate::error::{Error, Result};

/// Largest word length whose copies are compared (`m^depth` copies, pairs quadratic).
pub const MAX_CROSSING_DEPTH: usize = 3;

/// The value and gradient of the squared distance from `p` to the line through `a` and `b`:
/// `h² = cross(b − a, p − a)² / |b − a|²`, with `[∂/∂p, ∂/∂a, ∂/∂b]`.
fn line_dist2(p: [f64; 2], a: [f64; 2], b: [f64; 2]) -> (f64, [[f64; 2]; 3]) {
    let u = [b[0] - a[0], b[1] - a[1]];
    let v = [p[0] - a[0], p[1] - a[1]];
    let o = u[0] * v[1] - u[1] * v[0];
    let uu = u[0] * u[0] + u[1] * u[1];
    if uu == 0.0 {
        return (0.0, [[0.0; 2]; 3]);
    }
    let h2 = o * o / uu;
    // ∂o/∂u = (v_y, −v_x), ∂o/∂v = (−u_y, u_x).
    let c = 2.0 * o / uu;
    let d = 2.0 * h2 / uu;
    let gu = [c * v[1] - d * u[0], -c * v[0] - d * u[1]];
    let gv = [-c * u[1], c * u[0]];
    // u = b − a, v = p − a.
    let gp = gv;
    let gb = gu;
    let ga = [-gu[0] - gv[0], -gu[1] - gv[1]];
    (h2, [gp, ga, gb])
}

/// Signed `cross(b − a, p − a)`: which side of line `ab` the point `p` is on.
fn side(p: [f64; 2], a: [f64; 2], b: [f64; 2]) -> f64 {
    (b[0] - a[0]) * (p[1] - a[1]) - (b[1] - a[1]) * (p[0] - a[0])
}

/// The squared crossing depth of segments `s = [A, B]` and `t = [C, D]` (zero when they do
/// not cross) and its gradient `[G_A, G_B, G_C, G_D]`.
pub fn crossing_depth2(s: [[f64; 2]; 2], t: [[f64; 2]; 2]) -> (f64, [[f64; 2]; 4]) {
    let [a, b] = s;
    let [c, d] = t;
    let crosses = side(c, a, b) * side(d, a, b) < 0.0 && side(a, c, d) * side(b, c, d) < 0.0;
    if !crosses {
        return (0.0, [[0.0; 2]; 4]);
    }
    let cands = [
        line_dist2(c, a, b),
        line_dist2(d, a, b),
        line_dist2(a, c, d),
        line_dist2(b, c, d),
    ];
    let (k, (v, g)) = cands
        .iter()
        .enumerate()
        .min_by(|x, y| x.1.0.total_cmp(&y.1.0))
        .expect("four candidates");
    // Map the candidate's [∂p, ∂line_a, ∂line_b] onto [A, B, C, D].
    let idx = match k {
        0 => [2, 0, 1],
        1 => [3, 0, 1],
        2 => [0, 2, 3],
        _ => [1, 2, 3],
    };
    let mut out = [[0.0; 2]; 4];
    for (slot, gi) in idx.iter().zip(g) {
        out[*slot][0] += gi[0];
        out[*slot][1] += gi[1];
    }
    (*v, out)
}

/// The self-crossing penalty of `pattern` over the copies of its base figure under the words
/// of length `depth`, and its gradient with respect to the control points (flat, as
/// [`Pattern::flat_points`]) when `grad`.
pub fn crossing_penalty(pattern: &Pattern, depth: usize, grad: bool) -> Result<(f64, Vec<f64>)> {
    if !(1..=MAX_CROSSING_DEPTH).contains(&depth) {
        return Err(Error::param(
            "loss.crossing_depth",
            format!("must be between 1 and {MAX_CROSSING_DEPTH}, got {depth}"),
        ));
    }
    let tree = WordTree::new(&pattern.maps()?, pattern.base_points(), depth)?;
    let leaves = tree.leaves();
    let mut value = 0.0;
    let mut leaf_grad = vec![[0.0; 4]; leaves.len()];
    for i in 0..leaves.len() {
        for j in i + 1..leaves.len() {
            let (v, g) = crossing_depth2(leaves[i], leaves[j]);
            if v == 0.0 {
                continue;
            }
            value += v;
            if grad {
                for (c, gc) in leaf_grad[i].iter_mut().zip(g[0].iter().chain(&g[1])) {
                    *c += gc;
                }
                for (c, gc) in leaf_grad[j].iter_mut().zip(g[2].iter().chain(&g[3])) {
                    *c += gc;
                }
            }
        }
    }
    let mut out = vec![0.0; 2 * pattern.points().len()];
    if grad && value > 0.0 {
        let (g_maps, g_base) = tree.backward(&leaf_grad);
        pattern.maps_backward(&g_maps, &mut out);
        for (k, g) in pattern.base().points.iter().zip(g_base) {
            out[2 * k] += g[0];
            out[2 * k + 1] += g[1];
        }
    }
    Ok((value, out))
}
