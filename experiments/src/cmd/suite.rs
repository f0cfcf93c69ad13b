//! `ifslab suite`: the chaotic-splatting paper's random test suite — make it, score a code
//! against it.

use std::path::PathBuf;

use ifslab::loss::lpips::Lpips;
use ifslab::model::IfsCode;
use ifslab_experiments::suite::{self, SuiteSpec, Tier};

use crate::bars::Bar;

#[derive(clap::Args, Debug)]
pub struct Args {
    #[command(subcommand)]
    pub command: Command,
}

#[derive(clap::Subcommand, Debug)]
pub enum Command {
    /// Draw the codes (Anderson–Farrell, N uniform in 3..=10) and render their ground truth:
    /// the full view and six zoomed-in patches (2× to 8×) each. Re-running the same command
    /// completes an interrupted suite.
    Make(MakeArgs),
    /// Score a code file against one code of a suite: the paper's metrics on every view.
    Score(ScoreArgs),
}

#[derive(clap::Args, Debug)]
pub struct MakeArgs {
    /// Number of codes (the paper: 100).
    #[arg(long, default_value_t = 100)]
    pub codes: usize,
    /// Seed of the suite.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// smoke (64², 1 M points a view), medium (256², 10 M) or full (the paper: 1024², 50 M).
    #[arg(long, default_value = "medium")]
    pub tier: Tier,
    /// Zoomed-in patches per code.
    #[arg(long, default_value_t = 6)]
    pub patches: usize,
    /// Largest zoom factor of a patch.
    #[arg(long, default_value_t = 8.0)]
    pub max_zoom: f64,
    /// The suite folder.
    #[arg(short, long)]
    pub output: PathBuf,
}

#[derive(clap::Args, Debug)]
pub struct ScoreArgs {
    /// The suite folder.
    pub suite: PathBuf,
    /// Which code of the suite the file recovers.
    #[arg(long)]
    pub index: usize,
    /// The recovered code (ifslab-code/1 JSON).
    pub code: PathBuf,
    /// Print the score as JSON (every view) instead of one line.
    #[arg(long)]
    pub json: bool,
}

pub fn run(a: Args) -> anyhow::Result<()> {
    match a.command {
        Command::Make(m) => {
            let spec = SuiteSpec {
                patches: m.patches,
                max_zoom: m.max_zoom,
                ..SuiteSpec::paper(m.codes, m.seed, m.tier)
            };
            let manifest = suite::make(&spec, &m.output, &Bar::default())?;
            let incomplete = manifest
                .codes
                .iter()
                .flat_map(|c| &c.views)
                .filter(|v| !v.complete)
                .count();
            eprintln!(
                "{}: {} codes, {} views ({incomplete} below the tier's point count in their window)",
                m.output.join(suite::MANIFEST).display(),
                manifest.codes.len(),
                manifest.codes.iter().map(|c| c.views.len()).sum::<usize>()
            );
            Ok(())
        }
        Command::Score(s) => {
            let manifest = suite::load(&s.suite)?;
            let code = IfsCode::load(&s.code)?;
            let net = Lpips::try_load_default()?;
            let score = suite::score_code(&s.suite, &manifest, s.index, &code, net.as_ref())?;
            if s.json {
                println!("{}", serde_json::to_string_pretty(&score)?);
            } else {
                let lpips = score
                    .lpips
                    .map_or_else(String::new, |v| format!(", LPIPS {v:.3}"));
                println!(
                    "code {} over {} views: F1 {:.3}, IoU {:.3}, PSNR {:.2} dB, SSIM {:.3}{lpips}",
                    s.index,
                    score.views.len(),
                    score.f1,
                    score.iou,
                    score.psnr,
                    score.ssim
                );
            }
            Ok(())
        }
    }
}
