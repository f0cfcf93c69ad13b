//! Loss landscapes: the image objective on a 2-D slice of parameter space through a code,
//! `L(θ* + α·d₁ + β·d₂)` on a grid of `(α, β)`.
//!
//! Directions are either two random ones, **filter-normalised** per map (each map's block of
//! the direction is scaled to the norm of that map's block of θ*, Li et al. 2018, so a step
//! of 1 means "as large as the map itself" whatever the map), or two raw coordinates of θ.
//! Every grid point renders on the *same* trajectories (common random numbers), so the slice
//! shows the objective's shape and not the chaos game's noise; averaging over several random
//! streams shows how much of it survives the noise the optimiser actually sees.
//!
//! This is what makes the case for annealing visible: around a recovered code the slice has
//! one basin; through a random start it is a plateau with narrow wells.
//!
//! ## References
//! - Li, Xu, Taylor, Studer, Goldstein, *Visualizing the Loss Landscape of Neural Nets*,
//!   NeurIPS 2018 (filter normalisation).

use rand::SeedableRng;
use rand_distr::{Distribution, StandardNormal};
use rand_xoshiro::Xoshiro256PlusPlus;
use serde::{Deserialize, Serialize};

use super::ImageProblem;
use crate::error::{Error, Result};

/// The plane the slice lies in.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub enum Directions {
    /// Two Gaussian directions, filter-normalised per map.
    Random {
        /// Seed of the draw.
        seed: u64,
    },
    /// Unit steps along two raw coordinates of θ.
    Coordinates {
        /// Index of the first (α) coordinate.
        i: usize,
        /// Index of the second (β) coordinate.
        j: usize,
    },
}

/// How the slice is sampled.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct LandscapeConfig {
    /// Grid points per side (odd, so θ* itself is on the grid).
    pub resolution: usize,
    /// The grid spans `[−extent, extent]²` in units of the directions.
    pub extent: f64,
    /// The plane.
    pub directions: Directions,
    /// Random streams averaged per grid point (1: one fixed set of trajectories).
    pub streams: u64,
}

impl Default for LandscapeConfig {
    fn default() -> Self {
        LandscapeConfig {
            resolution: 41,
            extent: 1.0,
            directions: Directions::Random { seed: 0 },
            streams: 1,
        }
    }
}

impl LandscapeConfig {
    /// Checks every field; the error names the one to change.
    pub fn validate(&self, theta_len: usize) -> Result<()> {
        if self.resolution < 3 || self.resolution > 1001 || self.resolution.is_multiple_of(2) {
            return Err(Error::param(
                "resolution",
                format!("must be odd and in 3..=1001, got {}", self.resolution),
            ));
        }
        if !(self.extent.is_finite() && self.extent > 0.0) {
            return Err(Error::param(
                "extent",
                format!("must be > 0, got {}", self.extent),
            ));
        }
        if self.streams == 0 {
            return Err(Error::param("streams", "must be at least 1"));
        }
        if let Directions::Coordinates { i, j } = self.directions
            && (i >= theta_len || j >= theta_len || i == j)
        {
            return Err(Error::param(
                "directions",
                format!(
                    "coordinates must be two different indices below {theta_len}, got {i} and {j}"
                ),
            ));
        }
        Ok(())
    }
}

/// The sampled slice. Grids are row-major with `β` along rows and `α` along columns.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Landscape {
    /// Steps along the first direction (columns).
    pub alphas: Vec<f64>,
    /// Steps along the second direction (rows).
    pub betas: Vec<f64>,
    /// The full objective (the run's loss weights) at every grid point.
    pub total: Vec<f64>,
    /// The multi-scale MSE term alone (what annealing accepts on); for segment-map fits,
    /// the pixel term.
    pub msmse: Vec<f64>,
    /// The two directions in θ space.
    pub d1: Vec<f64>,
    /// See `d1`.
    pub d2: Vec<f64>,
    /// Grid points with no loss (the render failed, e.g. a divergent chaos game), with why;
    /// their values are NaN.
    pub failed: Vec<String>,
}

impl Landscape {
    /// The objective at θ* (the grid's centre).
    pub fn centre_total(&self) -> f64 {
        let n = self.alphas.len();
        self.total[(n / 2) * n + n / 2]
    }

    /// The grid point with the smallest objective: `(α, β, value)`.
    pub fn minimum(&self) -> (f64, f64, f64) {
        let n = self.alphas.len();
        let (k, v) = self
            .total
            .iter()
            .enumerate()
            .filter(|(_, v)| v.is_finite())
            .fold(
                (0, f64::INFINITY),
                |acc, (k, &v)| if v < acc.1 { (k, v) } else { acc },
            );
        (self.alphas[k % n], self.betas[k / n], v)
    }
}

/// The two directions for `theta` (one block of `block` raw values per map).
pub fn directions(theta: &[f64], block: usize, dirs: &Directions) -> (Vec<f64>, Vec<f64>) {
    match *dirs {
        Directions::Coordinates { i, j } => {
            let mut d1 = vec![0.0; theta.len()];
            let mut d2 = vec![0.0; theta.len()];
            d1[i] = 1.0;
            d2[j] = 1.0;
            (d1, d2)
        }
        Directions::Random { seed } => {
            let mut rng = Xoshiro256PlusPlus::seed_from_u64(seed);
            let mut draw = || -> Vec<f64> {
                let mut d: Vec<f64> = (0..theta.len())
                    .map(|_| StandardNormal.sample(&mut rng))
                    .collect();
                for (dk, tk) in d.chunks_mut(block.max(1)).zip(theta.chunks(block.max(1))) {
                    let nd = dk.iter().map(|v| v * v).sum::<f64>().sqrt();
                    let nt = tk.iter().map(|v| v * v).sum::<f64>().sqrt();
                    let s = if nd > 0.0 { nt.max(1e-3) / nd } else { 0.0 };
                    dk.iter_mut().for_each(|v| *v *= s);
                }
                d
            };
            let d1 = draw();
            let d2 = draw();
            (d1, d2)
        }
    }
}

/// Samples the slice of `problem`'s objective through `theta`. `tick` is called once per
/// grid point (a progress bar). Points are evaluated in a fixed order, each on streams
/// `0..streams`, so the result does not depend on the thread count.
pub fn landscape(
    problem: &ImageProblem,
    theta: &[f64],
    cfg: &LandscapeConfig,
    tick: &(dyn Fn() + Sync),
) -> Result<Landscape> {
    cfg.validate(theta.len())?;
    let maps = problem.model().n_maps(theta)?.max(1);
    let block = theta.len() / maps;
    let eval = |th: &[f64], stream: u64| -> Result<(f64, f64)> {
        let mut th = th.to_vec();
        problem.model().project(&mut th);
        let br = problem.loss_breakdown(&th, stream)?;
        Ok((br.total, br.msmse.unwrap_or(f64::NAN)))
    };
    slice(theta, block, cfg, &eval, tick)
}

/// An objective on a slice: `(θ, stream) → (objective, one of its terms)`.
pub type SliceObjective<'a> = dyn Fn(&[f64], u64) -> Result<(f64, f64)> + Sync + 'a;

/// Samples any objective on the slice `cfg` describes through `theta` (random directions
/// filter-normalised per block of `block` values). `eval(θ, stream)` gives the objective
/// and one term of it (the second heat map); it is called on streams `u64::MAX - s` for
/// `s` in `0..streams` (streams no optimisation iteration uses). A failed point away from
/// the centre is recorded in `failed` with NaN values; a failure at the centre is an error.
pub fn slice(
    theta: &[f64],
    block: usize,
    cfg: &LandscapeConfig,
    eval: &SliceObjective<'_>,
    tick: &(dyn Fn() + Sync),
) -> Result<Landscape> {
    cfg.validate(theta.len())?;
    if let Some(i) = theta.iter().position(|v| !v.is_finite()) {
        return Err(Error::InvalidInput(format!(
            "θ has a non-finite value at index {i}"
        )));
    }
    let (d1, d2) = directions(theta, block, &cfg.directions);
    let n = cfg.resolution;
    let steps: Vec<f64> = (0..n)
        .map(|k| cfg.extent * (2.0 * k as f64 / (n - 1) as f64 - 1.0))
        .collect();
    let mut total = Vec::with_capacity(n * n);
    let mut msmse = Vec::with_capacity(n * n);
    let mut failed = Vec::new();
    for &b in &steps {
        for &a in &steps {
            let th: Vec<f64> = theta
                .iter()
                .zip(d1.iter().zip(&d2))
                .map(|(t, (u, v))| t + a * u + b * v)
                .collect();
            let centre = a == 0.0 && b == 0.0;
            let (mut t_sum, mut m_sum) = (0.0, 0.0);
            for s in 0..cfg.streams {
                match eval(&th, u64::MAX - s) {
                    Ok((t, m)) => {
                        t_sum += t;
                        m_sum += m;
                    }
                    // Away from θ* a step can leave the valid set (e.g. a non-contractive
                    // code whose chaos game diverges): that point has no loss, and the
                    // count is reported.
                    Err(e) if !centre => {
                        failed.push(format!("α = {a:.3}, β = {b:.3}: {e}"));
                        t_sum = f64::NAN;
                        m_sum = f64::NAN;
                        break;
                    }
                    Err(e) => return Err(e),
                }
            }
            total.push(t_sum / cfg.streams as f64);
            msmse.push(m_sum / cfg.streams as f64);
            tick();
        }
    }
    Ok(Landscape {
        alphas: steps.clone(),
        betas: steps,
        total,
        msmse,
        d1,
        d2,
        failed,
    })
}
