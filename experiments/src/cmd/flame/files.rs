//! `ifslab flame random`, `info` and `convert`: making, describing and converting `.flame`
//! files.

use std::path::PathBuf;

use anyhow::{Context, bail};
use ifslab::model::flame::{
    RandomFlameConfig, VariationKind, estimate_bounds, flame_from_affine, read_flames, write_flames,
};
use ifslab::render::flame::draft::usable_random_flame;

#[derive(clap::Args, Debug)]
pub struct RandomArgs {
    /// Seed of the first genome (the others use seed + 1, seed + 2, …).
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Variations to draw from, by name or flam3 number, comma-separated (all 99 if absent).
    #[arg(long, value_delimiter = ',')]
    pub variations: Vec<String>,
    /// Number of transforms (flam3's random 2–6, maybe with a final transform, if absent).
    #[arg(long)]
    pub xforms: Option<usize>,
    /// Number of flames in the file.
    #[arg(long, default_value_t = 1)]
    pub count: usize,
    /// Image size WIDTH HEIGHT written into the genomes.
    #[arg(long, num_args = 2, value_names = ["WIDTH", "HEIGHT"], default_values_t = [512, 512])]
    pub size: Vec<u32>,
    /// Samples per pixel written into the genomes.
    #[arg(long, default_value_t = 100.0)]
    pub quality: f64,
    /// Drafts tried per genome before giving up on flam3-genome's brightness test (mean
    /// grey ≥ 20/255, ≥ 1 % black and ≤ 5 % white pixels on a quick 100² render).
    #[arg(long, default_value_t = 10)]
    pub tries: u32,
    /// Output .flame file.
    #[arg(short, long, default_value = "random.flame")]
    pub output: PathBuf,
}

#[derive(clap::Args, Debug)]
pub struct InfoArgs {
    /// The .flame file (optional with --variations).
    pub file: Option<PathBuf>,
    /// List the 99 supported variations and their parameters with flam3's defaults.
    #[arg(long)]
    pub variations: bool,
}

#[derive(clap::Args, Debug)]
pub struct ConvertArgs {
    /// The affine code: a JSON code file or a built-in code's name.
    pub code: String,
    /// Output .flame file.
    #[arg(short, long, default_value = "code.flame")]
    pub output: PathBuf,
    /// Image size WIDTH HEIGHT.
    #[arg(long, num_args = 2, value_names = ["WIDTH", "HEIGHT"], default_values_t = [512, 512])]
    pub size: Vec<u32>,
}

pub(super) fn parse_variation(s: &str) -> anyhow::Result<VariationKind> {
    let s = s.trim();
    if let Ok(n) = s.parse::<usize>() {
        return VariationKind::from_index(n)
            .with_context(|| format!("variation number {n} does not exist (0–98)"));
    }
    VariationKind::from_name(s)
        .with_context(|| format!("unknown variation `{s}` (see `ifslab flame info --variations`)"))
}

pub(super) fn random(a: RandomArgs) -> anyhow::Result<()> {
    let variations = a
        .variations
        .iter()
        .filter(|s| !s.trim().is_empty())
        .map(|s| parse_variation(s))
        .collect::<anyhow::Result<Vec<_>>>()?;
    if a.count == 0 {
        bail!("--count must be at least 1");
    }
    if a.tries == 0 {
        bail!("--tries must be at least 1");
    }
    let cfg = RandomFlameConfig {
        variations,
        xforms: a.xforms,
        size: [a.size[0], a.size[1]],
        quality: a.quality,
    };
    let mut flames = Vec::with_capacity(a.count);
    for k in 0..a.count as u64 {
        let seed = a.seed.wrapping_add(k);
        let (mut f, passed) = usable_random_flame(seed, &cfg, a.tries as u64)?;
        if !passed {
            eprintln!(
                "warning: genome {k}: no draft passed the brightness test in {} tries; \
                 keeping the last",
                a.tries
            );
        }
        f.name = Some(format!("random-{seed}"));
        flames.push(f);
    }
    write_flames(&a.output, &flames)?;
    eprintln!("wrote {} flame(s) to {}", flames.len(), a.output.display());
    Ok(())
}

pub(super) fn info(a: InfoArgs) -> anyhow::Result<()> {
    if a.variations {
        for k in VariationKind::ALL {
            let params: Vec<String> = k.params().iter().map(|(n, d)| format!("{n}={d}")).collect();
            println!(
                "{:2} {:<14} {}{}",
                k.index(),
                k.name(),
                if k.is_random() { "(random) " } else { "" },
                params.join(" ")
            );
        }
    }
    let Some(file) = &a.file else {
        if !a.variations {
            bail!("give a .flame file, or --variations");
        }
        return Ok(());
    };
    let flames = read_flames(file)?;
    for (i, f) in flames.iter().enumerate() {
        println!(
            "[{i}] {}: {}×{}, centre ({}, {}), scale {}, zoom {}, rotate {}°, quality {}, \
             supersample {}",
            f.label(),
            f.size[0],
            f.size[1],
            f.center[0],
            f.center[1],
            f.scale,
            f.zoom,
            f.rotate,
            f.quality,
            f.supersample
        );
        let describe = |x: &ifslab::model::flame::Xform| {
            let vars: Vec<String> = x
                .variations
                .iter()
                .map(|v| {
                    let ps: Vec<String> = v
                        .kind()
                        .params()
                        .iter()
                        .zip(v.params())
                        .map(|((n, _), p)| format!("{n}={p}"))
                        .collect();
                    if ps.is_empty() {
                        format!("{} {}", v.kind().name(), v.weight)
                    } else {
                        format!("{} {} ({})", v.kind().name(), v.weight, ps.join(", "))
                    }
                })
                .collect();
            let c = &x.coefs;
            format!(
                "color {} speed {} opacity {}; coefs [{} {} {} {} {} {}]{}; {}",
                x.color,
                x.color_speed,
                x.opacity,
                c[0],
                c[1],
                c[2],
                c[3],
                c[4],
                c[5],
                if x.has_post() { " + post" } else { "" },
                vars.join(", ")
            )
        };
        for (k, x) in f.xforms.iter().enumerate() {
            println!(
                "  xform {k}{}: weight {}, {}{}",
                if x.from_symmetry { " (symmetry)" } else { "" },
                x.weight,
                describe(x),
                if x.chaos.is_empty() {
                    String::new()
                } else {
                    format!(", xaos {:?}", x.chaos)
                }
            );
        }
        if let Some(x) = &f.final_xform {
            println!("  final: {}", describe(x));
        }
        match estimate_bounds(f, 0.01, 100_000, 1) {
            Ok(b) => println!(
                "  attractor box (98 % of 100 000 orbit points): x {:.6} … {:.6}, y {:.6} … {:.6}; \
                 bad values {:.2} %",
                b.min[0],
                b.max[0],
                b.min[1],
                b.max[1],
                100.0 * b.badvals as f64 / b.samples.max(1) as f64
            ),
            Err(e) => println!("  attractor box: {e}"),
        }
    }
    Ok(())
}

pub(super) fn convert(a: ConvertArgs) -> anyhow::Result<()> {
    let code = crate::cmd::resolve_code(&a.code)?;
    if code.dim() != 2 {
        bail!("{} is a {}-D code; flames are 2-D", a.code, code.dim());
    }
    let maps = code.affine2()?;
    let probs = code.evaluation_probabilities()?;
    let flame = flame_from_affine(code.name.as_deref(), &maps, &probs, [a.size[0], a.size[1]])?;
    write_flames(&a.output, std::slice::from_ref(&flame))?;
    eprintln!(
        "wrote {} ({} linear transforms) to {}",
        flame.label(),
        flame.xforms.len(),
        a.output.display()
    );
    Ok(())
}
