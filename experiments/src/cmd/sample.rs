//! `ifslab sample`: random codes from the Anderson–Farrell sampler.

use std::path::PathBuf;

use anyhow::Context;
use ifslab::model::IfsCode;
use ifslab::model::random::sample_code;

#[derive(clap::Args, Debug)]
pub struct Args {
    /// Maps per code.
    #[arg(long, default_value_t = 10)]
    pub maps: usize,
    /// Seed of the first code (code k of a suite uses seed + k).
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Number of codes; with more than one, OUTPUT is a folder.
    #[arg(long, default_value_t = 1)]
    pub count: usize,
    /// Output code file (or folder with --count > 1).
    #[arg(short, long)]
    pub output: PathBuf,
}

pub fn run(a: Args) -> anyhow::Result<()> {
    if a.count == 0 {
        anyhow::bail!("--count must be at least 1");
    }
    for k in 0..a.count {
        let seed = a.seed + k as u64;
        let s = sample_code(a.maps, seed)?;
        let name = format!("random-{}maps-seed{seed}", a.maps);
        let mut code = IfsCode::from_affine2(Some(&name), &s.maps)?;
        code.meta
            .insert("sampler".into(), "anderson-farrell".into());
        code.meta.insert("seed".into(), seed.into());
        code.meta
            .insert("sigma_factor".into(), s.sigma_factor.into());
        let path = if a.count == 1 {
            a.output.clone()
        } else {
            std::fs::create_dir_all(&a.output)
                .with_context(|| format!("creating {}", a.output.display()))?;
            a.output.join(format!("{name}.json"))
        };
        code.save(&path)?;
        eprintln!("{} (σ-factor {:.4})", path.display(), s.sigma_factor);
    }
    Ok(())
}
