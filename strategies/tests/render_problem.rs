//! A problem built outside the crate from the one image problem: a renderer, a model and a
//! loss written here (Gaussian blobs on a grey image, θ = their centres in a coordinate of
//! the test's choosing, a prior on the blobs' spread), made a [`RenderProblem`] — so it is
//! `Differentiable` and `Anneal` with nothing more —, its gradient checked against central
//! differences, and fitted by strategies looked up in the registry, through the driver every
//! run of the crate uses.

use std::borrow::Cow;

use ifslab::render::Renderer;
use ifslab_strategies::driver::plan::execute;
use ifslab_strategies::driver::{CsvLog, Differentiable, JsonCheckpoint, RunSpec};
use ifslab_strategies::optim::annealing::Anneal;
use ifslab_strategies::problems::render_problem::{
    Moment, PlaneLoss, RenderProblem, SceneModel, Terms,
};
use ifslab_strategies::registry;

#[path = "../../tests/common/blobs.rs"]
mod blobs;
use blobs::Blobs;

/// θ = blob centres in units of the image side (centre of the image at 0; the scene is
/// `(x, y, 1)` per blob in pixels, the amplitude held at 1), the blobs wide
/// at the start of a run and narrow at its end; a prior `w·Σ|c − mean|²` (pixels²) on the
/// spread of the centres.
struct BlobModel {
    renderer: Blobs,
    /// Width at progress 0 (the renderer's is the final one).
    s_start: f64,
    iterations: u64,
    spread: f64,
}

impl BlobModel {
    fn width(&self, frac: f64) -> f64 {
        let f = frac.clamp(0.0, 1.0);
        self.s_start * (self.renderer.s / self.s_start).powf(f)
    }
}

impl SceneModel for BlobModel {
    type Renderer = Blobs;
    type Scene = Vec<f64>;

    fn scene(&self, theta: &[f64], _: Moment) -> ifslab_strategies::Result<Vec<f64>> {
        let half = self.renderer.size as f64 / 2.0;
        Ok(theta
            .chunks_exact(2)
            .flat_map(|c| [half + c[0] * 2.0 * half, half + c[1] * 2.0 * half, 1.0])
            .collect())
    }

    fn renderer(&self, _: &Vec<f64>, at: Moment) -> ifslab_strategies::Result<Cow<'_, Blobs>> {
        let frac = match at {
            Moment::Iteration(t) => t as f64 / self.iterations as f64,
            Moment::Progress { frac, .. } => frac,
        };
        Ok(Cow::Owned(Blobs {
            s: self.width(frac),
            ..self.renderer.clone()
        }))
    }

    fn draw(&self, _: Moment) -> u64 {
        0
    }

    fn priors(
        &self,
        centres: &Vec<f64>,
        terms: &mut Terms,
        grad: Option<&mut [f64]>,
    ) -> ifslab_strategies::Result<()> {
        let k = (centres.len() / 3) as f64;
        let mean = [0, 1].map(|a| centres.iter().skip(a).step_by(3).sum::<f64>() / k);
        let mut v = 0.0;
        for c in centres.chunks_exact(3) {
            v += (c[0] - mean[0]).powi(2) + (c[1] - mean[1]).powi(2);
        }
        terms.set("spread", v, self.spread);
        if let Some(g) = grad {
            for (g, c) in g.chunks_exact_mut(3).zip(centres.chunks_exact(3)) {
                g[0] += self.spread * 2.0 * (c[0] - mean[0]);
                g[1] += self.spread * 2.0 * (c[1] - mean[1]);
            }
        }
        Ok(())
    }

    /// Centres in pixels → θ in units of the side (the amplitudes' entries dropped).
    fn pull_back(
        &self,
        _: &[f64],
        _: &Vec<f64>,
        grad: Vec<f64>,
    ) -> ifslab_strategies::Result<Vec<f64>> {
        let side = self.renderer.size as f64;
        Ok(grad
            .chunks_exact(3)
            .flat_map(|g| [g[0] * side, g[1] * side])
            .collect())
    }
}

/// Half the squared error against a target.
struct HalfSse(Vec<f64>);

impl PlaneLoss<f64> for HalfSse {
    fn value_and_grad(
        &self,
        planes: &[f64],
        grad: bool,
        terms: &mut Terms,
    ) -> ifslab_strategies::Result<Option<Vec<f64>>> {
        let d: Vec<f64> = planes.iter().zip(&self.0).map(|(p, t)| p - t).collect();
        terms.set("sse", 0.5 * d.iter().map(|v| v * v).sum::<f64>(), 1.0);
        Ok(grad.then_some(d))
    }
}

const TERMS: [&str; 2] = ["sse", "spread"];
const ITERATIONS: u64 = 150;

fn problem(spread: f64) -> (RenderProblem<BlobModel, HalfSse>, Vec<f64>) {
    let renderer = Blobs { size: 24, s: 2.0 };
    let truth = [-0.2, -0.15, 0.18, 0.1];
    let model = BlobModel {
        renderer: renderer.clone(),
        s_start: 4.0,
        iterations: ITERATIONS,
        spread,
    };
    let centres = model.scene(&truth, Moment::Iteration(0)).unwrap();
    let target = renderer.forward(&centres, &()).unwrap().0;
    (
        RenderProblem::from_parts(model, HalfSse(target), 0, &TERMS),
        truth.to_vec(),
    )
}

#[test]
fn its_gradient_is_the_loss_s_through_renderer_prior_and_pull_back() {
    let (p, truth) = problem(0.01);
    let theta: Vec<f64> = truth.iter().map(|t| t + 0.03).collect();
    for iter in [0, ITERATIONS / 2, ITERATIONS] {
        let e = p.evaluate(&theta, iter).unwrap();
        assert_eq!(e.terms.iter().map(|t| t.0).collect::<Vec<_>>(), TERMS);
        assert!(e.terms[1].1 > 0.0, "the prior is on");
        let frac = iter as f64 / ITERATIONS as f64;
        for i in 0..theta.len() {
            let h = 1e-6;
            let mut up = theta.clone();
            up[i] += h;
            let mut down = theta.clone();
            down[i] -= h;
            // The annealing cost at the same progress is the same loss.
            let fd = (p.anneal_cost(&up, 0, frac).unwrap()
                - p.anneal_cost(&down, 0, frac).unwrap())
                / (2.0 * h);
            assert!(
                (fd - e.grad[i]).abs() <= 1e-5 * (1.0 + fd.abs()),
                "iteration {iter}, θ[{i}]: finite differences {fd}, gradient {}",
                e.grad[i]
            );
        }
        // The loss is the weighted sum of the logged terms.
        assert!((e.loss - (e.terms[0].1 + 0.01 * e.terms[1].1)).abs() < 1e-12);
    }
}

#[test]
fn registered_strategies_recover_the_blobs_through_the_driver() {
    let dir = tempfile::tempdir().unwrap();
    // Gradient-based, gradient with annealing, value-only.
    for (kind, params) in [
        ("adam", "lr = 0.01"),
        ("hybrid", "adam = { lr = 0.01 }"),
        ("cmaes", ""),
    ] {
        let (p, truth) = problem(0.0);
        let start: Vec<f64> = truth
            .iter()
            .zip([0.06, -0.05, -0.05, 0.06])
            .map(|(t, d)| t + d)
            .collect();
        let before = p.anneal_cost(&start, 0, 1.0).unwrap();
        let entry = registry::find::<RenderProblem<BlobModel, HalfSse>>(kind).unwrap();
        let params: toml::Table = params.parse().unwrap();
        let solver = entry
            .build(
                &params,
                &RunSpec {
                    iterations: ITERATIONS,
                    seed: 3,
                },
            )
            .unwrap();
        let log = CsvLog::open(dir.path().join(format!("{kind}.csv")), &TERMS, None).unwrap();
        let ckpt = JsonCheckpoint::new(dir.path().join(format!("{kind}.json")), 0, false, 0);
        let (p, state) = execute(p, solver, start, ITERATIONS, ckpt, log, Vec::new()).unwrap();
        let theta = state.best_param.clone().or(state.param.clone()).unwrap();
        let after = p.anneal_cost(&theta, 0, 1.0).unwrap();
        let off = theta
            .iter()
            .zip(&truth)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        assert!(
            after < 0.05 * before && off < 0.01,
            "{kind}: loss {before} → {after}, θ {theta:?} against {truth:?}"
        );
    }
}
