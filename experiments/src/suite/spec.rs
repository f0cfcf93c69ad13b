//! A suite's spec and manifest: the tiers, the spec a suite is made to, the entry of each
//! code and its views, and reading a made suite back.

use std::path::{Path, PathBuf};
use std::str::FromStr;

use crate::error::{Context, IoContext, bail, bail_config};
use ifslab::model::Window;
use ifslab::render::RenderConfig;
use serde::{Deserialize, Serialize};

use super::{FORMAT, MANIFEST};

/// How big a suite's renders are: the paper's setting, and two a 2-core machine can finish.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Tier {
    /// 64², 1 M points per view: seconds per code, for tests.
    Smoke,
    /// 256², 10 M points per view (zoomed views: until 10 M land in the window, at most
    /// 640 M generated).
    Medium,
    /// The paper's setting: 1024², 50 M points per view.
    Full,
}

impl Tier {
    /// Side of every view, in pixels.
    pub fn size(self) -> usize {
        match self {
            Tier::Smoke => 64,
            Tier::Medium => 256,
            Tier::Full => 1024,
        }
    }

    /// Points per view that should land in its window.
    pub fn points(self) -> u64 {
        match self {
            Tier::Smoke => 1_000_000,
            Tier::Medium => 10_000_000,
            Tier::Full => 50_000_000,
        }
    }

    /// The name used on the command line and in the manifest.
    pub fn name(self) -> &'static str {
        match self {
            Tier::Smoke => "smoke",
            Tier::Medium => "medium",
            Tier::Full => "full",
        }
    }
}

impl FromStr for Tier {
    type Err = crate::Error;
    fn from_str(s: &str) -> crate::Result<Self> {
        Ok(match s {
            "smoke" => Tier::Smoke,
            "medium" => Tier::Medium,
            "full" => Tier::Full,
            _ => bail!("unknown tier `{s}` (known: smoke, medium, full)"),
        })
    }
}

/// What to draw: the suite's parameters. Everything else follows from them.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SuiteSpec {
    /// Number of codes.
    pub codes: usize,
    /// Seed of the whole suite.
    pub seed: u64,
    /// Render size and point budget.
    pub tier: Tier,
    /// Zoomed-in patches per code (the paper: 6).
    pub patches: usize,
    /// Largest zoom factor of a patch (the paper: 8); factors are uniform in [2, max_zoom].
    pub max_zoom: f64,
    /// Fewest and most maps of a code (the paper: 3 and 10), drawn uniformly.
    pub maps: [usize; 2],
    /// Binary supersampling per side of every render (the paper: 8).
    pub supersample: u32,
}

impl SuiteSpec {
    /// The paper's suite at `tier`: `codes` codes, N ∈ 3..=10, six patches up to 8×, 8×8
    /// binary supersampling.
    pub fn paper(codes: usize, seed: u64, tier: Tier) -> Self {
        SuiteSpec {
            codes,
            seed,
            tier,
            patches: 6,
            max_zoom: 8.0,
            maps: [3, 10],
            supersample: 8,
        }
    }

    pub(super) fn validate(&self) -> crate::Result<()> {
        if !(1..=100_000).contains(&self.codes) {
            bail!("--codes must lie in 1..=100000, got {}", self.codes);
        }
        if self.patches > 64 {
            bail!("at most 64 patches per code, got {}", self.patches);
        }
        if !(self.max_zoom.is_finite() && self.max_zoom >= 2.0) {
            bail!("--max-zoom must be at least 2, got {}", self.max_zoom);
        }
        let [lo, hi] = self.maps;
        if !(2 <= lo && lo <= hi && hi <= 64) {
            bail!("map counts must satisfy 2 ≤ min ≤ max ≤ 64, got {lo}..={hi}");
        }
        if !(1..=16).contains(&self.supersample) {
            bail!("supersampling must lie in 1..=16, got {}", self.supersample);
        }
        Ok(())
    }

    /// How every view of this suite is rendered (truths and scored codes alike).
    pub fn render_config(&self, seed: u64) -> RenderConfig {
        let size = self.tier.size() as u32;
        RenderConfig {
            width: size,
            height: size,
            points: self.tier.points(),
            supersample: self.supersample,
            seed,
            min_hits: self.tier.points(),
            max_points: 64 * self.tier.points(),
            ..RenderConfig::default()
        }
    }
}

/// One view of a code.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ViewEntry {
    /// `full`, `zoom1`, `zoom2`, …
    pub name: String,
    /// Magnification against the full view (1 for it).
    pub factor: f64,
    /// Centre as fractions of the full view's window (x from its left, y from its bottom).
    pub center: [f64; 2],
    /// The ground-truth render, relative to the suite folder.
    pub truth: PathBuf,
    /// Points of the truth render that landed in the window.
    pub points_in_window: u64,
    /// Whether the truth reached the tier's point count in the window (the paper marks the
    /// views that did not with ▲; here the cap is 64× the count generated, not a time).
    pub complete: bool,
}

/// One code of a suite.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CodeEntry {
    /// Position in the suite.
    pub index: usize,
    /// Number of maps.
    pub maps: usize,
    /// Seed the Anderson–Farrell sampler drew it with.
    pub seed: u64,
    /// The code file, relative to the suite folder.
    pub code: PathBuf,
    /// Seed of its renders.
    pub render_seed: u64,
    /// The full view's window in the code's coordinates.
    pub window: Window,
    /// The full view first, then the patches.
    pub views: Vec<ViewEntry>,
}

/// The manifest, `suite.json`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Manifest {
    /// [`FORMAT`].
    pub format: String,
    /// What was drawn.
    pub spec: SuiteSpec,
    /// Every code, by index.
    pub codes: Vec<CodeEntry>,
}

impl Manifest {
    /// Entry `index`, or an error naming the suite's size.
    pub fn entry(&self, index: usize) -> crate::Result<&CodeEntry> {
        self.codes.get(index).with_context(|| {
            format!(
                "the suite has codes 0..{}, there is no code {index}",
                self.codes.len()
            )
        })
    }
}

/// Loads and checks `DIR/suite.json`.
pub fn load(dir: &Path) -> crate::Result<Manifest> {
    let path = dir.join(MANIFEST);
    let text = std::fs::read_to_string(&path).io_context(&path, || {
        format!(
            "reading {} (make a suite with `ifslab suite make -o {}`)",
            path.display(),
            dir.display()
        )
    })?;
    let m: Manifest = serde_json::from_str(&text)
        .config_context(&path, || format!("parsing {}", path.display()))?;
    if m.format != FORMAT {
        bail_config!(
            &path,
            "{}: format `{}`, expected `{FORMAT}`",
            path.display(),
            m.format
        );
    }
    for (i, c) in m.codes.iter().enumerate() {
        if c.index != i || c.views.is_empty() {
            bail_config!(&path, "{}: code entry {i} is malformed", path.display());
        }
    }
    Ok(m)
}
