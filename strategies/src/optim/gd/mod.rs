//! Plain gradient descent, `θ ← θ − η_t·rᵢ·∇L` (`rᵢ` the problem's per-entry rate
//! multipliers, 1 unless it sets them), with an optional momentum term and a linear
//! learning-rate decay: the optimiser of the learnable-fractal-flames paper, and the
//! smallest complete strategy in this crate — the worked example of adding one
//! (`docs/ARCHITECTURE.md`): this file plus one line in [`crate::registry::strategies`].
//!
//! ## References
//! - Bannister & Nowrouzezahrai, *Learnable Fractal Flames* (plain gradient descent).

use argmin::core::{Error as ArgminError, KV, KvValue, Problem, Solver, State};
use serde::{Deserialize, Serialize};

use crate::driver::{Differentiable, GradState, Params, kv_of, to_argmin};
use crate::error::{Error, Result};

/// Hyper-parameters of gradient descent.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct GdConfig {
    /// Learning rate η at t = 0.
    pub lr: f64,
    /// Heavy-ball momentum μ ∈ [0, 1) (0: plain gradient descent).
    pub momentum: f64,
    /// η at the end of the run as a fraction of `lr` (linear decay; 1: constant).
    pub final_lr_factor: f64,
}

impl Default for GdConfig {
    fn default() -> Self {
        GdConfig {
            lr: 1e-3,
            momentum: 0.0,
            final_lr_factor: 1.0,
        }
    }
}

impl Params for GdConfig {
    const KIND: &'static str = "gd";
    const STATS: &'static [&'static str] = &["grad_norm"];
    fn validate(&self) -> Result<()> {
        if !(self.lr.is_finite() && self.lr > 0.0) {
            return Err(Error::param("lr", format!("must be > 0, got {}", self.lr)));
        }
        if !(0.0..1.0).contains(&self.momentum) {
            return Err(Error::param(
                "momentum",
                format!("must lie in [0, 1), got {}", self.momentum),
            ));
        }
        if !(self.final_lr_factor.is_finite() && self.final_lr_factor >= 0.0) {
            return Err(Error::param(
                "final_lr_factor",
                format!("must be ≥ 0, got {}", self.final_lr_factor),
            ));
        }
        Ok(())
    }
}

/// Gradient descent's state: the velocity of the momentum term.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct GradientDescent {
    config: GdConfig,
    velocity: Vec<f64>,
}

impl GradientDescent {
    /// A fresh optimiser.
    pub fn new(config: GdConfig) -> Result<Self> {
        config.validate()?;
        Ok(GradientDescent {
            config,
            velocity: Vec::new(),
        })
    }
}

impl<O: Differentiable> Solver<O, GradState> for GradientDescent {
    fn name(&self) -> &str {
        "GradientDescent"
    }

    fn next_iter(
        &mut self,
        problem: &mut Problem<O>,
        mut state: GradState,
    ) -> std::result::Result<(GradState, Option<KV>), ArgminError> {
        let iter = state.get_iter();
        let mut theta = state
            .take_param()
            .ok_or_else(|| ArgminError::msg("no initial parameters"))?;
        let eval = problem.problem("loss_and_gradient", |p| {
            p.evaluate(&theta, iter).map_err(to_argmin)
        })?;
        if !eval.loss.is_finite() {
            return Err(to_argmin(Error::Numerical(format!(
                "loss became {} at iteration {iter}",
                eval.loss
            ))));
        }
        let c = &self.config;
        let frac = (iter as f64 / state.get_max_iters().max(1) as f64).min(1.0);
        let lr = c.lr * (1.0 - (1.0 - c.final_lr_factor) * frac);
        self.velocity.resize(theta.len(), 0.0);
        let rates = problem
            .problem
            .as_ref()
            .and_then(|p| p.rate_multipliers(iter));
        for (i, ((t, v), g)) in theta
            .iter_mut()
            .zip(&mut self.velocity)
            .zip(&eval.grad)
            .enumerate()
        {
            *v = c.momentum * *v + g;
            *t -= lr * rates.as_ref().map_or(1.0, |r| r[i]) * *v;
        }
        problem.problem("project", |p| {
            p.project(&mut theta);
            Ok(())
        })?;
        let mut kv = kv_of(&eval);
        let norm = eval.grad.iter().map(|g| g * g).sum::<f64>().sqrt();
        kv.insert("grad_norm", KvValue::Float(norm));
        Ok((
            state.param(theta).gradient(eval.grad).cost(eval.loss),
            Some(kv),
        ))
    }
}

#[cfg(test)]
mod tests {
    use argmin::core::Executor;

    use super::*;
    use crate::driver::Evaluation;

    /// ½‖θ − c‖².
    struct Bowl(Vec<f64>);

    impl Differentiable for Bowl {
        fn evaluate(&self, theta: &[f64], _iter: u64) -> Result<Evaluation> {
            let grad: Vec<f64> = theta.iter().zip(&self.0).map(|(t, c)| t - c).collect();
            let loss = 0.5 * grad.iter().map(|g| g * g).sum::<f64>();
            Ok(Evaluation {
                loss,
                grad,
                terms: vec![],
            })
        }
    }

    #[test]
    fn descends_a_quadratic_with_and_without_momentum() {
        for momentum in [0.0, 0.5] {
            let gd = GradientDescent::new(GdConfig {
                lr: 0.1,
                momentum,
                ..GdConfig::default()
            })
            .unwrap();
            let res = Executor::new(Bowl(vec![1.0, -2.0]), gd)
                .configure(|s| s.param(vec![0.0, 0.0]).max_iters(200))
                .run()
                .unwrap();
            let theta = res.state().get_param().unwrap();
            assert!(
                (theta[0] - 1.0).abs() < 1e-6 && (theta[1] + 2.0).abs() < 1e-6,
                "{theta:?}"
            );
        }
    }

    #[test]
    fn invalid_hyper_parameters_are_named() {
        let e = GradientDescent::new(GdConfig {
            momentum: 1.0,
            ..GdConfig::default()
        })
        .unwrap_err();
        assert!(e.to_string().contains("momentum"), "{e}");
    }
}
