//! A flame transform ("xform"): pre-affine map, weighted variations, optional post-affine
//! map, and the colour and selection attributes the renderer uses.
//!
//! The map is `x ↦ post(Σᵢ wᵢ·Vᵢ(pre(x)))` with the affine maps in flam3's coefficient
//! convention `coefs = "a b c d e f"`: `x' = a·x + c·y + e`, `y' = b·x + d·y + f`.
//! Variations are evaluated in flam3's order (by variation number) and summed from zero, as
//! flam3 does, so the result agrees with flam3 to rounding.
//!
//! ## Derivatives
//!
//! [`Xform::jacobian`], [`Xform::vjp_point`] and [`Xform::vjp_params`] give the exact
//! derivatives of a transform without random variations (forward-mode dual numbers run
//! through the same formula code as the forward pass). The flat parameter vector θ of a
//! transform is, in order:
//!
//! 1. the six pre-affine coefficients `a b c d e f`;
//! 2. for each variation in [`Xform::variations`] order: its weight, then its parameters in
//!    the order of [`VariationKind::params`];
//! 3. the six post-affine coefficients `a b c d e f` (present even when the post map is the
//!    identity).
//!
//! Colour, colour speed, opacity and selection weight are not part of θ: they do not move
//! points.

use rand::RngCore;

use crate::error::{Error, Result};
use crate::isa::{FmaIsa, IsaLevel, PortableIsa};
use crate::model::flame::scalar::{Dual, FlameScalar};
use crate::model::flame::variation::{MAX_PARAMS, Variation, VariationKind, derive};
use crate::model::flame::variations::{Pre, eval_detected, eval_on, pre_blur};

/// Six affine coefficients in flam3's order `a b c d e f` (`x' = a·x + c·y + e`,
/// `y' = b·x + d·y + f`).
pub type Coefs = [f64; 6];

/// The coefficients of an affine map in flam3's order (`M = [[a, c], [b, d]]`, `t = (e, f)`).
pub fn coefs_of(m: &crate::model::Affine2) -> Coefs {
    [
        m.m[(0, 0)],
        m.m[(1, 0)],
        m.m[(0, 1)],
        m.m[(1, 1)],
        m.b[0],
        m.b[1],
    ]
}

/// The affine map of coefficients in flam3's order (the inverse of [`coefs_of`]).
pub fn affine_of(c: &Coefs) -> crate::model::Affine2 {
    crate::model::Affine2::new(c[0], c[2], c[1], c[3], c[4], c[5])
}

/// The identity map in flam3's coefficient order.
pub const IDENTITY: Coefs = [1.0, 0.0, 0.0, 1.0, 0.0, 0.0];

/// `c` applied to `(x, y)`, in flam3's evaluation order.
#[inline(always)]
pub fn affine<T: FlameScalar>(c: &[T; 6], x: T, y: T) -> (T, T) {
    (c[0] * x + c[2] * y + c[4], c[1] * x + c[3] * y + c[5])
}

/// flam3's test for a point that left the plane: NaN or beyond ±10¹⁰ in a coordinate.
#[inline(always)]
pub fn is_bad_value(v: f64) -> bool {
    v.is_nan() || !(-1e10..=1e10).contains(&v)
}

/// One transform of a flame.
#[derive(Clone, Debug, PartialEq)]
pub struct Xform {
    /// Pre-affine coefficients (flam3 `coefs`).
    pub coefs: Coefs,
    /// Post-affine coefficients (flam3 `post`; [`IDENTITY`] when absent).
    pub post: Coefs,
    /// The weighted variations, in flam3's order (see [`Xform::sort_variations`]).
    pub variations: Vec<Variation>,
    /// Selection weight (flam3 `weight`; unused for a final transform).
    pub weight: f64,
    /// Colour index in [0, 1] blended into the point's colour.
    pub color: f64,
    /// How far the point's colour moves towards [`Xform::color`] (flam3 `color_speed`;
    /// `symmetry = s` in older files means `color_speed = (1 − s)/2`).
    pub color_speed: f64,
    /// flam3's `animate` flag (kept for files; the renderer ignores it).
    pub animate: f64,
    /// Opacity in [0, 1]: how strongly points this transform produced are drawn.
    pub opacity: f64,
    /// Xaos row: relative weights of the transforms that may follow this one (missing
    /// entries are 1).
    pub chaos: Vec<f64>,
    /// Attributes of the file's `<xform>` element this crate does not interpret, kept in
    /// order and written back.
    pub extra: Vec<(String, String)>,
    /// Added by a `<symmetry>` element rather than written as an `<xform>` (not written
    /// back: the element is).
    pub from_symmetry: bool,
}

impl Default for Xform {
    /// flam3's defaults for a new transform: identity affine, linear with weight 1, colour
    /// 0, colour speed 0.5, opacity 1, weight 0.
    fn default() -> Self {
        Xform {
            coefs: IDENTITY,
            post: IDENTITY,
            variations: vec![Variation::new(VariationKind::Linear, 1.0)],
            weight: 0.0,
            color: 0.0,
            color_speed: 0.5,
            animate: 1.0,
            opacity: 1.0,
            chaos: Vec::new(),
            extra: Vec::new(),
            from_symmetry: false,
        }
    }
}

/// What one application of a transform produced.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Applied {
    /// The new point.
    pub point: [f64; 2],
    /// Whether a coordinate was NaN or beyond ±10¹⁰ (flam3's "bad value").
    pub bad: bool,
}

/// A transform ready for the render loop: zero-weight variations dropped, pre_blur and
/// the post map resolved, opacity turned into flam3's drawing visibility.
#[derive(Clone, Debug)]
pub struct PreparedXform {
    coefs: Coefs,
    post: Option<Coefs>,
    pre_blur: f64,
    radius: bool,
    vars: Vec<PreparedVar>,
    /// Colour index.
    pub color: f64,
    /// Colour speed.
    pub color_speed: f64,
    /// flam3's visibility (`10^(log₂ opacity)`).
    pub visibility: f64,
}

/// One weighted variation ready for evaluation (what [`PreparedXform`] and the learnable
/// flames' generators loop over).
#[derive(Clone, Copy, Debug)]
pub(crate) struct PreparedVar {
    pub(crate) kind: VariationKind,
    pub(crate) weight: f64,
    pub(crate) params: [f64; MAX_PARAMS],
    pub(crate) derived: [f64; crate::model::flame::variation::MAX_DERIVED],
}

impl PreparedVar {
    pub(crate) fn of(v: &Variation) -> Self {
        PreparedVar {
            kind: v.kind(),
            weight: v.weight,
            params: *v.param_array(),
            derived: *v.derived(),
        }
    }
}

/// `Σᵥ wᵥ·Vᵥ(t)` in flam3's order: the variations of a transform summed from zero at the
/// pre-affine point `f`, each through instruction set `I`'s copy of the formulas.
#[inline(always)]
pub(crate) fn sum_variations<I: IsaLevel, R: RngCore + ?Sized>(
    isa: I,
    vars: &[PreparedVar],
    coefs: &Coefs,
    f: &Pre<f64>,
    rng: &mut R,
) -> (f64, f64) {
    let (mut x, mut y) = (0.0, 0.0);
    for v in vars {
        let (dx, dy) = eval_on(isa, v.kind, v.weight, &v.params, &v.derived, coefs, f, rng);
        x += dx;
        y += dy;
    }
    (x, y)
}

impl PreparedXform {
    /// The transform applied to `p` (flam3's `apply_xform`, without the colour), on the
    /// instruction set this CPU has best.
    #[inline]
    pub fn apply<R: RngCore + ?Sized>(&self, p: [f64; 2], rng: &mut R) -> Applied {
        match FmaIsa::detect() {
            Some(isa) => self.apply_on(isa, p, rng),
            None => self.apply_on(PortableIsa, p, rng),
        }
    }

    /// [`PreparedXform::apply`] on instruction set `I` (what the render loop's copies call).
    #[inline(always)]
    pub(crate) fn apply_on<I: IsaLevel, R: RngCore + ?Sized>(
        &self,
        isa: I,
        p: [f64; 2],
        rng: &mut R,
    ) -> Applied {
        let (mut tx, mut ty) = affine(&self.coefs, p[0], p[1]);
        if self.pre_blur != 0.0 {
            pre_blur(self.pre_blur, &mut tx, &mut ty, rng);
        }
        let f = if self.radius {
            Pre::new(tx, ty)
        } else {
            Pre::without_radius(tx, ty)
        };
        let (x, y) = sum_variations(isa, &self.vars, &self.coefs, &f, rng);
        let point = match &self.post {
            Some(post) => {
                let (a, b) = affine(post, x, y);
                [a, b]
            }
            None => [x, y],
        };
        Applied {
            point,
            bad: is_bad_value(point[0]) || is_bad_value(point[1]),
        }
    }

    /// The colour coordinate after this transform, from the one before.
    #[inline(always)]
    pub fn blend_color(&self, c: f64) -> f64 {
        self.color_speed * self.color + (1.0 - self.color_speed) * c
    }
}

impl Xform {
    /// A transform with the given pre-affine map and variations (sorted into flam3's
    /// order), weight 1 and flam3's other defaults.
    pub fn new(coefs: Coefs, variations: Vec<Variation>) -> Self {
        let mut x = Xform {
            coefs,
            variations,
            weight: 1.0,
            ..Xform::default()
        };
        x.sort_variations();
        x
    }

    /// Puts the variations in flam3's evaluation order (by variation number). Call after
    /// pushing variations by hand.
    pub fn sort_variations(&mut self) {
        self.variations.sort_by_key(|v| v.kind());
    }

    /// Whether a post-affine map is set.
    pub fn has_post(&self) -> bool {
        self.post != IDENTITY
    }

    /// The variation of `kind`, if present.
    pub fn variation(&self, kind: VariationKind) -> Option<&Variation> {
        self.variations.iter().find(|v| v.kind() == kind)
    }

    /// Whether any variation with a non-zero weight draws random numbers.
    pub fn is_random(&self) -> bool {
        self.variations
            .iter()
            .any(|v| v.weight != 0.0 && v.kind().is_random())
    }

    /// flam3's drawing opacity: `10^(log₂ opacity)` (0 stays 0).
    pub fn visibility(&self) -> f64 {
        if self.opacity == 0.0 {
            0.0
        } else {
            10f64.powf(-(1.0 / self.opacity).ln() / std::f64::consts::LN_2)
        }
    }

    /// The colour coordinate after this transform, from the one before.
    #[inline(always)]
    pub fn blend_color(&self, c: f64) -> f64 {
        self.color_speed * self.color + (1.0 - self.color_speed) * c
    }

    /// The transform applied to `p`, random variations drawing from `rng`. Zero-weight
    /// variations are skipped, as in flam3. (Renderers apply a [`PreparedXform`], which
    /// does the same without re-reading the variation list.)
    pub fn apply<R: RngCore + ?Sized>(&self, p: [f64; 2], rng: &mut R) -> Applied {
        self.prepare().apply(p, rng)
    }

    /// The transform in the form the render loop evaluates.
    pub fn prepare(&self) -> PreparedXform {
        let pre_blur = self
            .variation(VariationKind::PreBlur)
            .map_or(0.0, |v| v.weight);
        PreparedXform {
            coefs: self.coefs,
            post: self.has_post().then_some(self.post),
            pre_blur,
            radius: self
                .variations
                .iter()
                .any(|v| v.weight != 0.0 && v.kind().uses_radius()),
            vars: self
                .variations
                .iter()
                .filter(|v| v.weight != 0.0 && v.kind() != VariationKind::PreBlur)
                .map(PreparedVar::of)
                .collect(),
            color: self.color,
            color_speed: self.color_speed,
            visibility: self.visibility(),
        }
    }

    /// Checks numbers and variations; `what` names the transform in the error
    /// (e.g. `flame "x", xform 2`).
    pub fn validate(&self, what: &str) -> Result<()> {
        let finite = |name: &str, v: f64| -> Result<()> {
            if v.is_finite() {
                Ok(())
            } else {
                Err(Error::NonFinite {
                    what: what.to_string(),
                    location: name.to_string(),
                    value: v,
                })
            }
        };
        for (i, &c) in self.coefs.iter().enumerate() {
            finite(&format!("coefs[{i}]"), c)?;
        }
        for (i, &c) in self.post.iter().enumerate() {
            finite(&format!("post[{i}]"), c)?;
        }
        finite("weight", self.weight)?;
        finite("color", self.color)?;
        finite("color_speed", self.color_speed)?;
        finite("opacity", self.opacity)?;
        for (i, &c) in self.chaos.iter().enumerate() {
            finite(&format!("chaos[{i}]"), c)?;
            if c < 0.0 {
                return Err(Error::param(
                    "chaos",
                    format!("{what}: xaos entry {i} is {c}; entries must be ≥ 0"),
                ));
            }
        }
        if self.weight < 0.0 {
            return Err(Error::param(
                "weight",
                format!("{what}: weight is {}; it must be ≥ 0", self.weight),
            ));
        }
        for v in &self.variations {
            finite(v.kind().name(), v.weight)?;
            for ((name, _), &p) in v.kind().params().iter().zip(v.params()) {
                finite(name, p)?;
            }
        }
        for w in self.variations.windows(2) {
            if w[0].kind() >= w[1].kind() {
                return Err(Error::param(
                    "variations",
                    format!(
                        "{what}: variation `{}` appears twice or out of flam3's order; \
                         call sort_variations and merge duplicates",
                        w[1].kind().name()
                    ),
                ));
            }
        }
        Ok(())
    }

    /// Length of the flat parameter vector θ (see the module documentation for its order).
    pub fn n_params(&self) -> usize {
        12 + self
            .variations
            .iter()
            .map(|v| 1 + v.kind().params().len())
            .sum::<usize>()
    }

    /// The flat parameter vector θ.
    pub fn params(&self) -> Vec<f64> {
        let mut out = Vec::with_capacity(self.n_params());
        out.extend_from_slice(&self.coefs);
        for v in &self.variations {
            out.push(v.weight);
            out.extend_from_slice(v.params());
        }
        out.extend_from_slice(&self.post);
        out
    }

    /// Sets the transform from a flat parameter vector θ of length [`Xform::n_params`].
    pub fn set_params(&mut self, theta: &[f64]) -> Result<()> {
        if theta.len() != self.n_params() {
            return Err(Error::Shape(format!(
                "{} parameters for a transform with {}",
                theta.len(),
                self.n_params()
            )));
        }
        self.coefs.copy_from_slice(&theta[..6]);
        let mut k = 6;
        for v in &mut self.variations {
            v.weight = theta[k];
            k += 1;
            for i in 0..v.kind().params().len() {
                v.set_param_index(i, theta[k]);
                k += 1;
            }
        }
        self.post.copy_from_slice(&theta[k..k + 6]);
        Ok(())
    }

    fn require_deterministic(&self) -> Result<()> {
        if let Some(v) = self
            .variations
            .iter()
            .find(|v| v.weight != 0.0 && v.kind().is_random())
        {
            return Err(Error::param(
                "variations",
                format!(
                    "`{}` draws random numbers, so the transform has no Jacobian \
                     (random variations are forward-only)",
                    v.kind().name()
                ),
            ));
        }
        Ok(())
    }

    /// The 2×2 Jacobian `∂f/∂p` at `p` (`j[r][c] = ∂f_r/∂p_c`). Refused for transforms
    /// with random variations.
    pub fn jacobian(&self, p: [f64; 2]) -> Result<[[f64; 2]; 2]> {
        self.require_deterministic()?;
        let x = Dual::<2>::var(p[0], 0);
        let y = Dual::<2>::var(p[1], 1);
        let c = self.coefs.map(Dual::cst);
        let (tx, ty) = affine(&c, x, y);
        let f = Pre::new(tx, ty);
        let (mut ox, mut oy) = (Dual::cst(0.0), Dual::cst(0.0));
        for v in &self.variations {
            let (dx, dy) = eval_const(v, &c, &f);
            ox = ox + dx;
            oy = oy + dy;
        }
        let post = self.post.map(Dual::cst);
        let (qx, qy) = affine(&post, ox, oy);
        Ok([qx.d, qy.d])
    }

    /// `(∂f/∂p)ᵀ·g` at `p`.
    pub fn vjp_point(&self, p: [f64; 2], g: [f64; 2]) -> Result<[f64; 2]> {
        let j = self.jacobian(p)?;
        Ok([
            j[0][0] * g[0] + j[1][0] * g[1],
            j[0][1] * g[0] + j[1][1] * g[1],
        ])
    }

    /// `grad += (∂f/∂θ)ᵀ·g` at `p`, θ in the documented order; `grad` has
    /// [`Xform::n_params`] entries.
    pub fn vjp_params(&self, p: [f64; 2], g: [f64; 2], grad: &mut [f64]) -> Result<()> {
        self.require_deterministic()?;
        if grad.len() != self.n_params() {
            return Err(Error::Shape(format!(
                "gradient of length {} for a transform with {} parameters",
                grad.len(),
                self.n_params()
            )));
        }
        // The post map's linear part carries every upstream derivative to the output.
        let pl = &self.post;
        let through_post = |dx: f64, dy: f64| -> f64 {
            // gᵀ · L_post · (dx, dy)
            let ox = pl[0] * dx + pl[2] * dy;
            let oy = pl[1] * dx + pl[3] * dy;
            g[0] * ox + g[1] * oy
        };

        // Pre-affine coefficients: through t = pre(p) and through the variations that read
        // them (waves, popcorn, rings, fan).
        let c6: [Dual<6>; 6] = std::array::from_fn(|k| Dual::var(self.coefs[k], k));
        let (tx, ty) = affine(&c6, Dual::cst(p[0]), Dual::cst(p[1]));
        let f6 = Pre::new(tx, ty);
        let (mut sx, mut sy) = (Dual::<6>::cst(0.0), Dual::<6>::cst(0.0));
        for v in &self.variations {
            let (dx, dy) = eval_const(v, &c6, &f6);
            sx = sx + dx;
            sy = sy + dy;
        }
        for (k, g) in grad[..6].iter_mut().enumerate() {
            *g += through_post(sx.d[k], sy.d[k]);
        }

        // Each variation's weight and parameters.
        let (tx, ty) = affine(&self.coefs, p[0], p[1]);
        let c9 = self.coefs.map(Dual::<9>::cst);
        let f9 = Pre::new(Dual::cst(tx), Dual::cst(ty));
        let mut k = 6;
        for v in &self.variations {
            let np = v.kind().params().len();
            let w = Dual::<9>::var(v.weight, 0);
            let params: [Dual<9>; MAX_PARAMS] = std::array::from_fn(|i| {
                if i < np {
                    Dual::var(v.param_array()[i], i + 1)
                } else {
                    Dual::cst(0.0)
                }
            });
            let d = derive(v.kind(), &params);
            let (dx, dy) = eval_detected(v.kind(), w, &params, &d, &c9, &f9, &mut NoRng);
            for i in 0..=np {
                grad[k + i] += through_post(dx.d[i], dy.d[i]);
            }
            k += 1 + np;
        }

        // Post-affine: q = post(s) with s the sum of the variations.
        let f = Pre::new(tx, ty);
        let (mut s0, mut s1) = (0.0, 0.0);
        for v in &self.variations {
            let (dx, dy) = eval_detected(
                v.kind(),
                v.weight,
                v.param_array(),
                v.derived(),
                &self.coefs,
                &f,
                &mut NoRng,
            );
            s0 += dx;
            s1 += dy;
        }
        // ∂q/∂(a b c d e f): q₀ = a·s₀ + c·s₁ + e, q₁ = b·s₀ + d·s₁ + f.
        grad[k] += g[0] * s0;
        grad[k + 1] += g[1] * s0;
        grad[k + 2] += g[0] * s1;
        grad[k + 3] += g[1] * s1;
        grad[k + 4] += g[0];
        grad[k + 5] += g[1];
        Ok(())
    }
}

/// A variation with constant weight and parameters evaluated at a dual point.
fn eval_const<const K: usize>(
    v: &Variation,
    c: &[Dual<K>; 6],
    f: &Pre<Dual<K>>,
) -> (Dual<K>, Dual<K>) {
    let w = Dual::cst(v.weight);
    let p = v.param_array().map(Dual::cst);
    let d = v.derived().map(Dual::cst);
    eval_detected(v.kind(), w, &p, &d, c, f, &mut NoRng)
}

/// The generator handed to deterministic variations, which never draw.
pub(crate) struct NoRng;

impl RngCore for NoRng {
    fn next_u32(&mut self) -> u32 {
        0
    }
    fn next_u64(&mut self) -> u64 {
        0
    }
    fn fill_bytes(&mut self, dst: &mut [u8]) {
        dst.fill(0);
    }
}

/// A transform without random variations, as a plain map of the plane: what the
/// existing generators iterate ([`Map2`]) and what gradient code differentiates.
#[derive(Clone, Debug, PartialEq)]
pub struct SmoothXform(Xform);

impl SmoothXform {
    /// Wraps `x`, refusing transforms with random variations.
    pub fn new(x: Xform) -> Result<Self> {
        x.require_deterministic()?;
        Ok(SmoothXform(x))
    }

    /// The transform.
    pub fn xform(&self) -> &Xform {
        &self.0
    }

    /// `(∂f/∂p)ᵀ·g` at `p`.
    pub fn vjp_point(&self, p: [f64; 2], g: [f64; 2]) -> [f64; 2] {
        self.0.vjp_point(p, g).expect("checked deterministic")
    }

    /// `grad += (∂f/∂θ)ᵀ·g` at `p` (`grad` of length [`SmoothXform::n_params`]).
    pub fn vjp_params(&self, p: [f64; 2], g: [f64; 2], grad: &mut [f64]) {
        assert_eq!(grad.len(), self.n_params(), "gradient length");
        self.0
            .vjp_params(p, g, grad)
            .expect("checked deterministic and length");
    }

    /// Length of θ.
    pub fn n_params(&self) -> usize {
        self.0.n_params()
    }
}

impl crate::model::map::Map<2> for SmoothXform {
    fn apply(&self, p: [f64; 2]) -> [f64; 2] {
        self.0.apply(p, &mut NoRng).point
    }
}

/// A deterministic flame transform is a differentiable map of the plane: its θ is the
/// transform's flat parameter vector ([`Xform::params`]), its products the exact
/// forward-mode derivatives of the same formula code as the forward pass.
impl crate::model::map::DiffMap<2> for SmoothXform {
    fn n_params(&self) -> usize {
        self.0.n_params()
    }

    fn write_params(&self, out: &mut [f64]) {
        out.copy_from_slice(&self.0.params());
    }

    fn set_params(&mut self, p: &[f64]) {
        self.0
            .set_params(p)
            .expect("a parameter vector of the transform's own length");
    }

    fn vjp_point(&self, x: [f64; 2], lambda: [f64; 2]) -> [f64; 2] {
        SmoothXform::vjp_point(self, x, lambda)
    }

    fn vjp_params(&self, x: [f64; 2], lambda: [f64; 2], grad: &mut [f64]) {
        SmoothXform::vjp_params(self, x, lambda, grad)
    }
}

/// The regulariser acts on the pre-affine step (θ's first six entries, flam3's `a b c d e f`:
/// `x' = a·x + c·y + e`, `y' = b·x + d·y + f`).
impl crate::model::diff_map::AffinePart for SmoothXform {
    fn affine_part(&self) -> crate::model::Affine2 {
        affine_of(&self.0.coefs)
    }

    fn affine_part_backward(&self, g: &crate::model::Affine2, grad: &mut [f64]) {
        let m = &g.m;
        for (k, v) in [m[(0, 0)], m[(1, 0)], m[(0, 1)], m[(1, 1)], g.b[0], g.b[1]]
            .into_iter()
            .enumerate()
        {
            grad[k] += v;
        }
    }
}
