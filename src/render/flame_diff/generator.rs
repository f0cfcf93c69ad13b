//! One generator of a learnable flame, ready for the hot loops: its forward map and its
//! vector–Jacobian products with respect to the point and to its θ entries.
//!
//! The map is `s ↦ post(Σᵥ wᵥ·Vᵥ(A·s + t))` with flam3's variation formulas. The reverse
//! pass evaluates every variation once in forward-mode dual numbers over `(tx, ty, w)` —
//! the 2×2 Jacobian at the pre-affine point and the derivative in the weight — and applies
//! the chain rule through the two affine maps by hand. A lone `linear` variation (the
//! linear flames of the paper) skips the dual numbers altogether. Variations that read the
//! pre-affine coefficients themselves (waves, popcorn, rings, fan) fall back to the
//! transform's general [`Xform::vjp_params`].

use crate::isa::IsaLevel;
use crate::model::flame::learnable::Learn;
use crate::model::flame::scalar::{Dual, FlameScalar};
use crate::model::flame::variation::VariationKind;
use crate::model::flame::variations::{Pre, eval_on};
use crate::model::flame::xform::{Coefs, NoRng, PreparedVar, Xform, affine, sum_variations};

/// A generator prepared for sampling and differentiation.
#[derive(Clone, Debug)]
pub(crate) struct Generator {
    coefs: Coefs,
    post: Option<Coefs>,
    /// `Some(w)` for a lone linear variation of weight `w`.
    linear: Option<f64>,
    radius: bool,
    reads_coefs: bool,
    /// Every variation, zero weights included (their weights may be learned).
    vars: Vec<PreparedVar>,
    learn: Learn,
    xform: Xform,
}

impl Generator {
    pub(crate) fn new(x: &Xform, learn: Learn) -> Self {
        let vars: Vec<PreparedVar> = x.variations.iter().map(PreparedVar::of).collect();
        let linear = match vars.as_slice() {
            [v] if v.kind == VariationKind::Linear => Some(v.weight),
            _ => None,
        };
        let post = if x.has_post() || learn.post {
            Some(x.post)
        } else {
            None
        };
        Generator {
            coefs: x.coefs,
            post,
            linear,
            radius: vars.iter().any(|v| v.kind.uses_radius()),
            reads_coefs: vars.iter().any(|v| v.kind.reads_coefs()),
            vars,
            learn,
            xform: x.clone(),
        }
    }

    /// Whether the generator is an affine map (a lone linear variation, no post map).
    pub(crate) fn is_linear(&self) -> bool {
        self.linear.is_some() && self.post.is_none()
    }

    /// `Σᵥ wᵥ·Vᵥ(t)` at the pre-affine point `t`, on instruction set `I`.
    #[inline(always)]
    fn variations<I: IsaLevel>(&self, isa: I, tx: f64, ty: f64) -> [f64; 2] {
        if let Some(w) = self.linear {
            return [w * tx, w * ty];
        }
        let f = if self.radius {
            Pre::new(tx, ty)
        } else {
            Pre::without_radius(tx, ty)
        };
        let (x, y) = sum_variations(isa, &self.vars, &self.coefs, &f, &mut NoRng);
        [x, y]
    }

    /// The generator applied to `s`, on instruction set `I`.
    #[inline(always)]
    pub(crate) fn apply<I: IsaLevel>(&self, isa: I, s: [f64; 2]) -> [f64; 2] {
        let (tx, ty) = affine(&self.coefs, s[0], s[1]);
        let v = self.variations(isa, tx, ty);
        match &self.post {
            Some(p) => {
                let (a, b) = affine(p, v[0], v[1]);
                [a, b]
            }
            None => v,
        }
    }

    /// Adds `(∂f/∂θ_g)(s)ᵀ·λ` to `grad` (the generator's θ entries, in
    /// [`crate::model::flame::learnable`]'s order) and returns `(∂f/∂s)(s)ᵀ·λ`, on
    /// instruction set `I`.
    #[inline(always)]
    pub(crate) fn vjp<I: IsaLevel>(
        &self,
        isa: I,
        s: [f64; 2],
        lambda: [f64; 2],
        grad: &mut [f64],
    ) -> [f64; 2] {
        if self.reads_coefs {
            return self.vjp_general(s, lambda, grad);
        }
        let c = &self.coefs;
        let (tx, ty) = affine(c, s[0], s[1]);
        // ρ = ∂L/∂v (v = Σ wᵥ Vᵥ(t)), through the post map's linear part.
        let rho = match &self.post {
            Some(p) => [
                p[0] * lambda[0] + p[1] * lambda[1],
                p[2] * lambda[0] + p[3] * lambda[1],
            ],
            None => lambda,
        };
        let mut k = 6;
        let (mu, v) = if let Some(w) = self.linear {
            if self.learn.weights {
                grad[k] += rho[0] * tx + rho[1] * ty;
                k += 1;
            }
            ([w * rho[0], w * rho[1]], [w * tx, w * ty])
        } else {
            let dx = Dual::<3>::var(tx, 0);
            let dy = Dual::<3>::var(ty, 1);
            let f = if self.radius {
                Pre::new(dx, dy)
            } else {
                Pre::without_radius(dx, dy)
            };
            let cc = c.map(<Dual<3> as FlameScalar>::cst);
            let mut mu = [0.0; 2];
            let mut v = [0.0; 2];
            for var in &self.vars {
                let w = Dual::<3>::var(var.weight, 2);
                let p = var.params.map(<Dual<3> as FlameScalar>::cst);
                let d = var.derived.map(<Dual<3> as FlameScalar>::cst);
                let (ox, oy) = eval_on(isa, var.kind, w, &p, &d, &cc, &f, &mut NoRng);
                v[0] += ox.v;
                v[1] += oy.v;
                mu[0] += rho[0] * ox.d[0] + rho[1] * oy.d[0];
                mu[1] += rho[0] * ox.d[1] + rho[1] * oy.d[1];
                if self.learn.weights {
                    grad[k] += rho[0] * ox.d[2] + rho[1] * oy.d[2];
                    k += 1;
                }
            }
            (mu, v)
        };
        let lam_s = pre_affine_vjp(c, s, mu, grad);
        if self.learn.post {
            grad[k] += lambda[0] * v[0];
            grad[k + 1] += lambda[1] * v[0];
            grad[k + 2] += lambda[0] * v[1];
            grad[k + 3] += lambda[1] * v[1];
            grad[k + 4] += lambda[0];
            grad[k + 5] += lambda[1];
        }
        lam_s
    }

    /// The general path for variations that read the pre-affine coefficients.
    fn vjp_general(&self, s: [f64; 2], lambda: [f64; 2], grad: &mut [f64]) -> [f64; 2] {
        let x = &self.xform;
        let mut full = vec![0.0; x.n_params()];
        x.vjp_params(s, lambda, &mut full)
            .expect("learnable generators are deterministic");
        for i in 0..6 {
            grad[i] += full[i];
        }
        let mut k = 6;
        let mut src = 6;
        for v in &x.variations {
            if self.learn.weights {
                grad[k] += full[src];
                k += 1;
            }
            src += 1 + v.kind().params().len();
        }
        if self.learn.post {
            for i in 0..6 {
                grad[k + i] += full[src + i];
            }
        }
        x.vjp_point(s, lambda)
            .expect("learnable generators are deterministic")
    }
}

/// The generators of a layer as the hot loops see them: the map of generator `g` and its
/// vector–Jacobian product, on the instruction set of the loop's copy (`I`).
pub(crate) trait Maps: Sync {
    /// Generator `g` applied to `s`.
    fn apply<I: IsaLevel>(&self, isa: I, g: usize, s: [f64; 2]) -> [f64; 2];
    /// [`Generator::vjp`] of generator `g`.
    fn vjp<I: IsaLevel>(
        &self,
        isa: I,
        g: usize,
        s: [f64; 2],
        lambda: [f64; 2],
        grad: &mut [f64],
    ) -> [f64; 2];
}

impl Maps for [Generator] {
    #[inline(always)]
    fn apply<I: IsaLevel>(&self, isa: I, g: usize, s: [f64; 2]) -> [f64; 2] {
        self[g].apply(isa, s)
    }

    #[inline(always)]
    fn vjp<I: IsaLevel>(
        &self,
        isa: I,
        g: usize,
        s: [f64; 2],
        lambda: [f64; 2],
        grad: &mut [f64],
    ) -> [f64; 2] {
        self[g].vjp(isa, s, lambda, grad)
    }
}

/// A layer whose generators are all affine maps (a lone `linear` variation, no post map:
/// the paper's linear flames), as flat coefficients. The loops over such a layer hold no
/// variation code, which leaves the compiler the registers for the splat; the arithmetic
/// is [`Generator`]'s, operation for operation (the same bits).
#[derive(Clone, Debug)]
pub(crate) struct LinearMaps {
    /// Pre-affine coefficients and the variation weight, per generator.
    gens: Vec<([f64; 6], f64)>,
    /// Whether the variation weights are learned (one θ entry after the coefficients).
    weights: bool,
}

impl LinearMaps {
    /// The layer's generators as affine maps, or `None` when one of them is not.
    pub(crate) fn of(gens: &[Generator]) -> Option<Self> {
        let lin = gens
            .iter()
            .map(|g| match (g.linear, g.is_linear()) {
                (Some(w), true) => Some((g.coefs, w)),
                _ => None,
            })
            .collect::<Option<Vec<_>>>()?;
        Some(LinearMaps {
            gens: lin,
            weights: gens.first().is_some_and(|g| g.learn.weights),
        })
    }
}

impl Maps for LinearMaps {
    #[inline(always)]
    fn apply<I: IsaLevel>(&self, _isa: I, g: usize, s: [f64; 2]) -> [f64; 2] {
        let (c, w) = &self.gens[g];
        let (tx, ty) = affine(c, s[0], s[1]);
        [w * tx, w * ty]
    }

    #[inline(always)]
    fn vjp<I: IsaLevel>(
        &self,
        _isa: I,
        g: usize,
        s: [f64; 2],
        lambda: [f64; 2],
        grad: &mut [f64],
    ) -> [f64; 2] {
        let (c, w) = &self.gens[g];
        if self.weights {
            let (tx, ty) = affine(c, s[0], s[1]);
            grad[6] += lambda[0] * tx + lambda[1] * ty;
        }
        pre_affine_vjp(c, s, [w * lambda[0], w * lambda[1]], grad)
    }
}

/// The pre-affine map `t = (a·x + c·y + e, b·x + d·y + f)` in reverse: adds `μ`'s products
/// with `(s, 1)` to the six coefficients' entries `grad[0..6]` and returns `(∂t/∂s)ᵀ·μ`.
#[inline(always)]
fn pre_affine_vjp(c: &Coefs, s: [f64; 2], mu: [f64; 2], grad: &mut [f64]) -> [f64; 2] {
    grad[0] += mu[0] * s[0];
    grad[1] += mu[1] * s[0];
    grad[2] += mu[0] * s[1];
    grad[3] += mu[1] * s[1];
    grad[4] += mu[0];
    grad[5] += mu[1];
    [c[0] * mu[0] + c[1] * mu[1], c[2] * mu[0] + c[3] * mu[1]]
}
