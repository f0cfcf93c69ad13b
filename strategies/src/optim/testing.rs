//! Test problems and a runner shared by the value-only strategies' tests.

use argmin::core::{Executor, Solver, State};

use crate::driver::{Differentiable, Evaluation, GradState};
use crate::error::{Error, Result};
use crate::optim::annealing::Anneal;

/// A shifted sphere, minimum at `opt`, with a little stream-dependent noise (`noise` at
/// most), like the image problem's cost on different random streams.
pub(crate) struct NoisySphere {
    pub opt: Vec<f64>,
    pub noise: f64,
}

impl NoisySphere {
    /// Minimum at (1, −2, 0.5, 3), noise below 10⁻⁴.
    pub fn standard() -> Self {
        NoisySphere {
            opt: vec![1.0, -2.0, 0.5, 3.0],
            noise: 1e-4,
        }
    }
}

impl Differentiable for NoisySphere {
    fn evaluate(&self, _theta: &[f64], _iter: u64) -> Result<Evaluation> {
        Err(Error::InvalidInput("value-only test problem".into()))
    }
}

impl Anneal for NoisySphere {
    fn anneal_cost(&self, theta: &[f64], stream: u64, _frac: f64) -> Result<f64> {
        let noise = (ifslab::chaos::mix_seed(stream, 7) % 1000) as f64 * 1e-3 * self.noise;
        Ok(theta
            .iter()
            .zip(&self.opt)
            .map(|(t, o)| (t - o).powi(2))
            .sum::<f64>()
            + noise)
    }
}

/// Runs `solver` on `problem` from `start` for `iters` iterations: the final θ, its cost
/// and the solver afterwards.
pub(crate) fn run<P, S>(problem: P, solver: S, start: Vec<f64>, iters: u64) -> (Vec<f64>, f64, S)
where
    S: Solver<P, GradState> + Clone,
{
    let res = Executor::new(problem, solver)
        .configure(|s| s.param(start).max_iters(iters))
        .run()
        .unwrap();
    let st = res.state();
    (
        st.get_param().unwrap().clone(),
        st.get_cost(),
        res.solver().clone(),
    )
}
