//! `ifslab flame render` (flam3-render's job, layers composited on request) and
//! `ifslab flame compare`.

use std::path::{Path, PathBuf};

use anyhow::{Context, bail};
use ifslab::model::flame::{Flame, read_flames};
use ifslab::render::flame::{Composite, Depth, FlameRenderConfig, render_flame};

use crate::bars::{self as progress, Bar};

#[derive(clap::Args, Debug)]
pub struct RenderArgs {
    /// The .flame file (flam3, Apophysis and JWildfire's flam3 subset).
    pub file: PathBuf,
    /// Output PNG; with several flames, `-N` (the flame's index) is added before `.png`.
    #[arg(short, long, default_value = "flame.png")]
    pub output: PathBuf,
    /// Only the flame with this name.
    #[arg(long)]
    pub name: Option<String>,
    /// Output size WIDTH HEIGHT; the framing is kept (pixels per unit scale with the height,
    /// as a flam3 template does).
    #[arg(long, num_args = 2, value_names = ["WIDTH", "HEIGHT"])]
    pub size: Option<Vec<u32>>,
    /// Samples per output pixel (the flame's `quality`).
    #[arg(long)]
    pub quality: Option<f64>,
    /// Histogram supersampling per side (the flame's `supersample`).
    #[arg(long)]
    pub supersample: Option<u32>,
    /// Seed of the chaos game (the same seed gives the same image on any thread count).
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// 16 bits per channel.
    #[arg(long)]
    pub sixteen_bit: bool,
    /// Keep transparency (alpha channel) instead of compositing onto the background.
    #[arg(long)]
    pub alpha: bool,
    /// Composite every flame of the file into one picture, first at the bottom, each drawn
    /// with transparency and laid "over" the first flame's background (a learned flame
    /// stack's layers, as `ifslab flame learn` writes them).
    #[arg(long, conflicts_with = "alpha")]
    pub composite: bool,
}

#[derive(clap::Args, Debug)]
pub struct CompareArgs {
    /// First image.
    pub a: PathBuf,
    /// Second image, same size.
    pub b: PathBuf,
}

pub(super) fn render(a: RenderArgs) -> anyhow::Result<()> {
    let flames = read_flames(&a.file)?;
    let chosen: Vec<(usize, Flame)> = match &a.name {
        Some(n) => {
            let found: Vec<_> = flames
                .into_iter()
                .enumerate()
                .filter(|(_, f)| f.name.as_deref() == Some(n.as_str()))
                .collect();
            if found.is_empty() {
                bail!("no flame named `{n}` in {}", a.file.display());
            }
            found
        }
        None => flames.into_iter().enumerate().collect(),
    };
    let several = chosen.len() > 1 && !a.composite;
    let cfg = FlameRenderConfig {
        seed: a.seed,
        transparent: a.alpha || a.composite,
        ..FlameRenderConfig::default()
    };
    // The composite: over the first flame's background.
    let mut composite: Option<Composite> = None;
    for (i, mut flame) in chosen {
        apply_overrides(&mut flame, a.size.as_deref(), a.quality, a.supersample)?;
        let out = output_for(&a.output, i, several);
        let pb = progress::bar(0, "samples");
        let img = render_flame(&flame, &cfg, Some(&Bar::of(pb.clone())))
            .with_context(|| format!("rendering {} of {}", flame.label(), a.file.display()))?;
        pb.finish_and_clear();
        let depth = if a.sixteen_bit {
            Depth::Sixteen
        } else {
            Depth::Eight
        };
        if a.composite {
            composite
                .get_or_insert_with(|| Composite::new(img.width, img.height, flame.background))
                .over(&img)
                .with_context(|| a.file.display().to_string())?;
        } else {
            img.save_png(&out, depth, a.alpha)?;
        }
        let s = &img.stats;
        let bad = s.badvals as f64 / s.samples.max(1) as f64;
        eprintln!(
            "{}: {}×{}, {} samples in {:.2} s ({:.1} M/s), badvals {:.3e} → {}",
            flame.label(),
            img.width,
            img.height,
            s.samples,
            s.seconds,
            s.samples as f64 / s.seconds / 1e6,
            bad,
            out.display()
        );
        if bad > 0.01 {
            eprintln!(
                "warning: {:.1}% of the steps left the plane (NaN or beyond ±1e10) and restarted \
                 from a random point: the flame's orbit diverges",
                100.0 * bad
            );
        }
    }
    if let Some(c) = composite {
        c.into_image()?.save_png(&a.output)?;
        eprintln!("composite → {}", a.output.display());
    }
    Ok(())
}

pub(super) fn compare(a: CompareArgs) -> anyhow::Result<()> {
    let ga = ifslab::render::image_io::load_grey(&a.a)?;
    let gb = ifslab::render::image_io::load_grey(&a.b)?;
    if (ga.width, ga.height) != (gb.width, gb.height) {
        bail!(
            "{} is {}×{} but {} is {}×{}",
            a.a.display(),
            ga.width,
            ga.height,
            a.b.display(),
            gb.width,
            gb.height
        );
    }
    let (w, h) = (ga.width as usize, ga.height as usize);
    let ssim = ifslab::metrics::ssim(&ga.values, &gb.values, w, h)?;
    let psnr = ifslab::metrics::psnr(&ga.values, &gb.values, 1.0)?;
    println!("ssim {ssim:.4} psnr {psnr:.2} dB");
    Ok(())
}

/// `flame` with its size and quality overridden as the command line asks.
pub fn apply_overrides(
    flame: &mut Flame,
    size: Option<&[u32]>,
    quality: Option<f64>,
    supersample: Option<u32>,
) -> anyhow::Result<()> {
    if let Some(s) = size {
        let (w, h) = (s[0], s[1]);
        if w == 0 || h == 0 {
            bail!("--size must be at least 1×1, got {w}×{h}");
        }
        flame.scale *= h as f64 / flame.size[1] as f64;
        flame.size = [w, h];
    }
    if let Some(q) = quality {
        if !(q.is_finite() && q > 0.0) {
            bail!("--quality must be > 0, got {q}");
        }
        flame.quality = q;
    }
    if let Some(s) = supersample {
        flame.supersample = s;
    }
    Ok(())
}

pub(super) fn output_for(base: &Path, index: usize, several: bool) -> PathBuf {
    if !several {
        return base.to_owned();
    }
    let stem = base
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "flame".into());
    base.with_file_name(format!("{stem}-{index}.png"))
}
