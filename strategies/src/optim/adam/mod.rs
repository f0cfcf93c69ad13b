//! Adam: first-order steps scaled by running estimates of the gradient's first and second
//! moments, `θ ← θ − lr·m̂/(√v̂ + ε)`. argmin 0.11 ships no Adam, so it is written here as an
//! argmin [`Solver`] and reused by the hybrid and noisy-gradient strategies.
//!
//! Each iteration evaluates the loss and gradient at the current θ (the logged cost is that
//! of θ before the step), steps, then projects θ (the SVD parameterisation re-orthonormalises
//! U and V).
//!
//! ## References
//! - Kingma & Ba, *Adam: A Method for Stochastic Optimization*, ICLR 2015.

use argmin::core::{Error as ArgminError, KV, Problem, Solver, State};
use serde::{Deserialize, Serialize};

use crate::driver::{Differentiable, GradState, Params, kv_of, to_argmin};
use crate::error::{Error, Result};

/// Adam's hyper-parameters (defaults: the chaotic-splatting paper's lr 1e-2).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct AdamConfig {
    /// Learning rate.
    pub lr: f64,
    /// Decay of the first-moment estimate.
    pub beta1: f64,
    /// Decay of the second-moment estimate.
    pub beta2: f64,
    /// Denominator guard.
    pub eps: f64,
    /// The learning rate decays linearly to `lr·final_lr_factor` over the run (1: constant,
    /// as in the paper).
    pub final_lr_factor: f64,
}

impl Default for AdamConfig {
    fn default() -> Self {
        AdamConfig {
            lr: 1e-2,
            beta1: 0.9,
            beta2: 0.999,
            eps: 1e-8,
            final_lr_factor: 1.0,
        }
    }
}

impl Params for AdamConfig {
    const KIND: &'static str = "adam";
    const STATS: &'static [&'static str] = &[];
    /// Checks every field; the error names the one to change.
    fn validate(&self) -> Result<()> {
        if !(self.lr.is_finite() && self.lr > 0.0) {
            return Err(Error::param("lr", format!("must be > 0, got {}", self.lr)));
        }
        for (name, b) in [("beta1", self.beta1), ("beta2", self.beta2)] {
            if !(0.0..1.0).contains(&b) {
                return Err(Error::param(name, format!("must lie in [0, 1), got {b}")));
            }
        }
        if !(self.eps.is_finite() && self.eps > 0.0) {
            return Err(Error::param(
                "eps",
                format!("must be > 0, got {}", self.eps),
            ));
        }
        Ok(())
    }
}

/// The Adam optimiser state.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Adam {
    config: AdamConfig,
    m: Vec<f64>,
    v: Vec<f64>,
    t: u64,
}

impl Adam {
    /// A fresh optimiser (moments zero).
    pub fn new(config: AdamConfig) -> Result<Self> {
        config.validate()?;
        Ok(Adam {
            config,
            m: Vec::new(),
            v: Vec::new(),
            t: 0,
        })
    }

    /// The hyper-parameters.
    pub fn config(&self) -> &AdamConfig {
        &self.config
    }

    /// Forgets the moment estimates (a "fresh Adam").
    pub fn reset(&mut self) {
        self.m.clear();
        self.v.clear();
        self.t = 0;
    }

    /// One update of θ along `grad` with the base learning rate.
    pub fn step(&mut self, theta: &mut [f64], grad: &[f64]) -> Result<()> {
        self.step_scaled(theta, grad, 1.0)
    }

    /// One update of θ along `grad` with the learning rate scaled by `lr_scale`.
    pub fn step_scaled(&mut self, theta: &mut [f64], grad: &[f64], lr_scale: f64) -> Result<()> {
        self.step_with_rates(theta, grad, lr_scale, None)
    }

    /// One update with the learning rate scaled by `lr_scale` and, per entry, by `rates`
    /// (see [`Differentiable::rate_multipliers`]).
    pub fn step_with_rates(
        &mut self,
        theta: &mut [f64],
        grad: &[f64],
        lr_scale: f64,
        rates: Option<&[f64]>,
    ) -> Result<()> {
        if let Some(r) = rates
            && r.len() != theta.len()
        {
            return Err(Error::InvalidInput(format!(
                "{} rate multipliers for {} parameters",
                r.len(),
                theta.len()
            )));
        }
        if grad.len() != theta.len() {
            return Err(Error::InvalidInput(format!(
                "gradient has {} entries for {} parameters",
                grad.len(),
                theta.len()
            )));
        }
        if let Some(i) = grad.iter().position(|g| !g.is_finite()) {
            return Err(Error::Numerical(format!(
                "gradient entry {i} is {}; lower the learning rate or check the target",
                grad[i]
            )));
        }
        if self.m.len() != theta.len() {
            self.m = vec![0.0; theta.len()];
            self.v = vec![0.0; theta.len()];
            self.t = 0;
        }
        let c = &self.config;
        self.t += 1;
        let b1t = 1.0 - c.beta1.powi(self.t as i32);
        let b2t = 1.0 - c.beta2.powi(self.t as i32);
        for i in 0..theta.len() {
            self.m[i] = c.beta1 * self.m[i] + (1.0 - c.beta1) * grad[i];
            self.v[i] = c.beta2 * self.v[i] + (1.0 - c.beta2) * grad[i] * grad[i];
            let mh = self.m[i] / b1t;
            let vh = self.v[i] / b2t;
            let rate = rates.map_or(1.0, |r| r[i]);
            theta[i] -= rate * lr_scale * c.lr * mh / (vh.sqrt() + c.eps);
        }
        Ok(())
    }
}

/// One gradient step of `adam` on `problem` at iteration `iter`; shared by the strategies
/// built on Adam. `perturb` may change the gradient before the step (noisy gradients).
pub(crate) fn adam_iteration<O: Differentiable>(
    adam: &mut Adam,
    problem: &mut Problem<O>,
    mut state: GradState,
    perturb: impl FnOnce(&mut [f64]),
) -> Result<(GradState, KV), ArgminError> {
    let iter = state.get_iter();
    let mut theta = state.take_param().ok_or_else(|| {
        ArgminError::msg("no initial parameters: configure the state with param(θ)")
    })?;
    let mut eval = problem.problem("loss_and_gradient", |p| {
        p.evaluate(&theta, iter).map_err(to_argmin)
    })?;
    if !eval.loss.is_finite() {
        return Err(to_argmin(Error::Numerical(format!(
            "loss became {} at iteration {iter}",
            eval.loss
        ))));
    }
    perturb(&mut eval.grad);
    let frac = iter as f64 / state.get_max_iters().max(1) as f64;
    let lr_scale = 1.0 - (1.0 - adam.config.final_lr_factor) * frac.min(1.0);
    let rates = problem
        .problem
        .as_ref()
        .and_then(|p| p.rate_multipliers(iter));
    adam.step_with_rates(&mut theta, &eval.grad, lr_scale, rates.as_deref())
        .map_err(to_argmin)?;
    problem.problem("project", |p| {
        p.project(&mut theta);
        Ok(())
    })?;
    let kv = kv_of(&eval);
    Ok((state.param(theta).gradient(eval.grad).cost(eval.loss), kv))
}

impl<O: Differentiable> Solver<O, GradState> for Adam {
    fn name(&self) -> &str {
        "Adam"
    }

    fn next_iter(
        &mut self,
        problem: &mut Problem<O>,
        state: GradState,
    ) -> Result<(GradState, Option<KV>), ArgminError> {
        let (state, kv) = adam_iteration(self, problem, state, |_| {})?;
        Ok((state, Some(kv)))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::driver::Evaluation;
    use argmin::core::{Executor, State};

    /// f(θ) = Σ (θᵢ − i)², ∇f = 2(θ − i): Adam must find θᵢ = i.
    struct Bowl;

    impl Differentiable for Bowl {
        fn evaluate(&self, theta: &[f64], _iter: u64) -> Result<Evaluation> {
            let loss = theta
                .iter()
                .enumerate()
                .map(|(i, t)| (t - i as f64).powi(2))
                .sum();
            let grad = theta
                .iter()
                .enumerate()
                .map(|(i, t)| 2.0 * (t - i as f64))
                .collect();
            Ok(Evaluation {
                loss,
                grad,
                terms: vec![],
            })
        }
    }

    #[test]
    fn adam_minimises_a_quadratic() {
        let adam = Adam::new(AdamConfig {
            lr: 0.05,
            ..AdamConfig::default()
        })
        .unwrap();
        let res = Executor::new(Bowl, adam)
            .configure(|s| s.param(vec![3.0, -2.0, 5.0]).max_iters(2000))
            .run()
            .unwrap();
        let theta = res.state().get_param().unwrap();
        for (i, t) in theta.iter().enumerate() {
            assert!((t - i as f64).abs() < 1e-3, "θ{i} = {t}");
        }
    }

    #[test]
    fn invalid_hyper_parameters_are_named() {
        let e = Adam::new(AdamConfig {
            lr: -1.0,
            ..AdamConfig::default()
        })
        .unwrap_err();
        assert!(e.to_string().contains("lr"), "{e}");
    }
}
