//! The naive parameterisation: θ holds each map's six coefficients `[a, b, c, d, e, f]`.
//! Nothing keeps the maps contractive; strategies that use it must check or penalise.

use crate::error::Result;
use crate::model::affine::Affine2;
use crate::model::param::Parameterisation;

/// Six unconstrained numbers per map.
#[derive(Clone, Copy, Debug, Default)]
pub struct Naive;

impl Parameterisation for Naive {
    fn name(&self) -> &'static str {
        "naive"
    }

    fn params_per_map(&self) -> usize {
        6
    }

    fn decode(&self, theta: &[f64]) -> Result<Vec<Affine2>> {
        self.n_maps(theta)?;
        Ok(theta
            .chunks_exact(6)
            .map(Affine2::from_coefficients)
            .collect())
    }

    fn encode(&self, maps: &[Affine2]) -> Result<Vec<f64>> {
        Ok(maps.iter().flat_map(|m| m.coefficients()).collect())
    }

    fn backward(&self, theta: &[f64], grad_maps: &[Affine2]) -> Result<Vec<f64>> {
        let n = self.n_maps(theta)?;
        debug_assert_eq!(n, grad_maps.len());
        Ok(grad_maps.iter().flat_map(|g| g.coefficients()).collect())
    }
}
