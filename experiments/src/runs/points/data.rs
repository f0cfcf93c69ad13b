//! The point cloud a run fits: read from a file (or a code's samples), its rows checked, and what it was read from.

use super::*;

/// The data of a run: all points, the training and held-out parts, and where they came from.
pub struct Data {
    /// Every point.
    pub all: PointSet,
    /// The training points.
    pub train: PointSet,
    /// The held-out points (may be empty).
    pub test: PointSet,
    /// Where the points came from, in words.
    pub source: String,
}

impl Data {
    /// The held-out points, if any.
    pub fn heldout(&self) -> Option<&PointSet> {
        (!self.test.is_empty()).then_some(&self.test)
    }
}

/// Loads the config's point cloud or samples it from a code, and splits it.
pub fn load_data(cfg: &PointsConfig) -> crate::Result<Data> {
    let (all, source) = if let Some(spec) = cfg.data.strip_prefix("ifs:") {
        let code = resolve_code(spec).with_context(|| format!("`data` {}", cfg.data))?;
        let probs = code.evaluation_probabilities()?;
        // Many short trajectories: points close to independent draws from the measure.
        let per = 50usize;
        let game = ChaosGame {
            trajectories: cfg.points.div_ceil(per),
            length: per + 30,
            warmup: 30,
            start_half_width: 1.0,
            seed: mix_seed(cfg.seed, 0xda7a),
        };
        let pts = generate_nd(&game, &code.maps, &probs)?;
        let all = PointSet::new(code.dim(), pts)?;
        let src = format!(
            "{} points sampled from `{spec}` by the chaos game (seed {})",
            cfg.points, cfg.seed
        );
        (all.head(cfg.points), src)
    } else {
        let p =
            PointSet::load(&cfg.data).with_context(|| format!("`data`: reading {}", cfg.data))?;
        (p, cfg.data.clone())
    };
    let (all, source) = if cfg.trim_outliers() {
        let (kept, removed) = all.without_outliers(8, 4.0, 0.05);
        let source = if removed > 0 {
            format!("{source}; {removed} isolated point(s) left out")
        } else {
            source
        };
        (kept, source)
    } else {
        (all, source)
    };
    let (train, test) = all.split(cfg.heldout, cfg.seed)?;
    if train.len() < cfg.k {
        bail!(
            "{} training points (after holding out {}) for k = {}: give at least as many \
             points as components, or lower `k` / `heldout`",
            train.len(),
            test.len(),
            cfg.k
        );
    }
    Ok(Data {
        all,
        train,
        test,
        source,
    })
}
