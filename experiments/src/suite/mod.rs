//! The random test suite of the chaotic-splatting paper (§5, "Setup" and "Metrics"): codes
//! from the Anderson–Farrell sampler with N drawn from 3..=10, each with ground-truth renders
//! of the full view and of six seeded zoomed-in patches (up to 8×), and the evaluation that
//! renders any recovered code at the same views and scores it with the paper's metrics.
//!
//! A suite is a folder:
//!
//! ```text
//! SUITE/suite.json          the manifest (tier, seeds, every code and view)
//! SUITE/000/code.json       the code (ifslab-code/1)
//! SUITE/000/views.json      its views and how their truths were rendered
//! SUITE/000/full.png        ground truth, 16-bit grey, coverage in [0, 1]
//! SUITE/000/zoom1.png …     the zoomed-in patches
//! ```
//!
//! A view is stored relative to the *full view's window* (its centre as fractions of the
//! window's width and height, its zoom factor), not in the code's coordinates: a recovered
//! code lives in its own coordinates, and what makes it comparable is that an inversion frames
//! its attractor the way the target was framed (bounding box centred, longest side 75% of the
//! frame). So a code is scored by fitting *its* full-view window and taking each view at the
//! same fractions of it.
//!
//! Making a suite is resumable: each code is written to `.NNN.partial/` and renamed when all
//! its files are there, and a code folder that exists is kept.

mod make;
mod score;
mod spec;

pub use make::make;
pub use score::{SuiteScore, ViewScore, score_code, score_maps};
pub use spec::{CodeEntry, Manifest, SuiteSpec, Tier, ViewEntry, load};

/// The manifest's file name inside a suite folder.
pub const MANIFEST: &str = "suite.json";
/// The manifest's format tag.
pub const FORMAT: &str = "ifslab-suite/1";
/// PSNR reported for a view the code reproduces exactly (the metric is infinite there, and
/// JSON and means have no room for that).
pub const PSNR_CAP: f64 = 99.0;
