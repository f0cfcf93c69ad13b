//! Parameterisations: how a flat raw vector θ (what strategies step, perturb and mutate)
//! becomes concrete maps, and back.
//!
//! Each parameterisation also carries its chain rule ([`Parameterisation::backward`]:
//! a gradient with respect to the maps becomes a gradient with respect to θ) and the
//! projection applied after every optimiser update ([`Parameterisation::project`]).
//!
//! - [`Naive`]: the six coefficients of each map, unconstrained.
//! - [`Svd`]: `M = U·diag(sigmoid σ)·Vᵀ` with U, V re-orthonormalised and `b = tanh(raw)`;
//!   every θ decodes to a contractive map (the chaotic-splatting paper's choice).
//! - [`Rsr`]: `M = R(θ₁)·diag(sigmoid σ)·R(θ₂)·diag(sign d)`, raw offsets (Learning Fractals,
//!   Tu et al., the Table 3 baseline).

mod naive;
mod rsr;
mod svd;

pub use naive::Naive;
pub use rsr::Rsr;
pub use svd::Svd;

use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};
use crate::model::affine::Affine2;

/// A map from raw parameter vectors θ to 2-D affine maps.
pub trait Parameterisation: Send + Sync {
    /// Short name used in configs and files.
    fn name(&self) -> &'static str;

    /// Raw numbers per map.
    fn params_per_map(&self) -> usize;

    /// Decodes θ (length `n · params_per_map`) into `n` maps.
    fn decode(&self, theta: &[f64]) -> Result<Vec<Affine2>>;

    /// A θ that decodes to `maps` (exactly where the parameterisation can represent them).
    fn encode(&self, maps: &[Affine2]) -> Result<Vec<f64>>;

    /// Chain rule: given ∂L/∂maps (each [`Affine2`] holding ∂L/∂M and ∂L/∂b), returns ∂L/∂θ.
    fn backward(&self, theta: &[f64], grad_maps: &[Affine2]) -> Result<Vec<f64>>;

    /// Brings θ back onto the parameterisation's canonical set after an update
    /// (re-orthonormalising U and V for [`Svd`]); a no-op by default.
    fn project(&self, _theta: &mut [f64]) {}

    /// Number of maps θ describes.
    fn n_maps(&self, theta: &[f64]) -> Result<usize> {
        let k = self.params_per_map();
        if theta.is_empty() || !theta.len().is_multiple_of(k) {
            return Err(Error::Shape(format!(
                "θ has {} entries; the {} parameterisation needs a positive multiple of {k}",
                theta.len(),
                self.name()
            )));
        }
        if let Some((i, v)) = theta.iter().enumerate().find(|(_, v)| !v.is_finite()) {
            return Err(Error::NonFinite {
                what: "θ".into(),
                location: format!("entry {i} (map {})", i / k),
                value: *v,
            });
        }
        Ok(theta.len() / k)
    }
}

/// The parameterisations by name, for configs.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ParamKind {
    /// [`Naive`].
    Naive,
    /// [`Svd`].
    #[default]
    Svd,
    /// [`Rsr`].
    Rsr,
}

impl ParamKind {
    /// The parameterisation object.
    pub fn build(self) -> Box<dyn Parameterisation> {
        match self {
            ParamKind::Naive => Box::new(Naive),
            ParamKind::Svd => Box::new(Svd::default()),
            ParamKind::Rsr => Box::new(Rsr),
        }
    }
}
