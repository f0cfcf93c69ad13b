//! Running a flame fit: the target, the start, solver from the registry, argmin `Executor`
//! with the shared checkpoint and CSV log, resume.

use std::path::{Path, PathBuf};
use std::time::Instant;

use argmin::core::State;
use argmin::core::observers::Observe;
use ifslab::image::Image;
use ifslab::model::flame::learnable::{FlameStack, LearnableFlame};

use crate::driver::GradState;
use crate::driver::plan::{RunPlan, START_FILE};
use crate::error::{Error, Result};
use crate::problems::flame::config::FlameLearnConfig;
use crate::problems::flame::problem::{FLAME_TERMS, FlameProblem};

/// What a fit produced.
#[derive(Clone, Debug)]
pub struct FlameOutcome {
    /// θ returned: the last iterate, or the start when the start scores lower on the
    /// configured loss.
    pub theta: Vec<f64>,
    /// Which of the two (`last`, `start`).
    pub returned: &'static str,
    /// The start.
    pub start: Vec<f64>,
    /// MSE of the start.
    pub start_loss: f64,
    /// Iterations completed (including those before a resume).
    pub iterations: u64,
    /// The authors' MSE of the returned θ (generator order of the last iteration).
    pub loss: f64,
    /// The returned θ as a flame stack.
    pub stack: FlameStack,
    /// Its render at the training size (three planes, generator order of the last
    /// iteration).
    pub image: Vec<f64>,
    /// Wall-clock seconds of this process's part of the run.
    pub seconds: f64,
    /// The CSV log.
    pub log: PathBuf,
}

/// Loads an RGB target of `size × size` pixels (the whole picture resized, as the authors
/// do), transparent pixels composited over `background`; a note says what was done to it.
pub fn load_rgb_target(
    path: &Path,
    size: usize,
    background: [f64; 3],
) -> Result<(Image, Option<String>)> {
    load_rgb_picture(path, size, Some(background), false)
}

/// Loads an RGB target of `size × size` pixels. Transparent pixels are composited over
/// `background`, or — `None` — over black or white, whichever stands out more from the
/// picture's opaque pixels (a white logo on a clear background is learned on black). With
/// `frame`, the picture is first cut to the box of what differs from its background (the
/// border's median colour; differences within four robust standard deviations of the
/// border's own are noise) with a tenth of that box's side as margin, then padded with the
/// background colour to a square, so that shapes small in a corner or on a wide canvas are
/// learned at the size of the picture, undistorted. A note says what was done.
pub fn load_rgb_picture(
    path: &Path,
    size: usize,
    background: Option<[f64; 3]>,
    frame: bool,
) -> Result<(Image, Option<String>)> {
    let bytes = std::fs::read(path).map_err(|e| Error::file(path, e))?;
    let img = image::load_from_memory(&bytes)
        .map_err(|e| Error::file(path, format!("not a readable image ({e})")))?;
    let colour = img.color();
    let mut notes: Vec<String> = Vec::new();
    if !colour.has_color() {
        notes.push("the target is greyscale: learned as RGB with three equal channels".into());
    }
    let rgba = img.to_rgba32f();
    let (w, h) = rgba.dimensions();
    if w == 0 || h == 0 {
        return Err(Error::file(path, "image has no pixels"));
    }
    // Composite first, at the picture's own size.
    let bg = match background {
        Some(c) => c,
        None => {
            let (mut sum, mut n) = (0.0f64, 0.0f64);
            for p in rgba.pixels() {
                let a = p.0[3] as f64;
                sum += a * (0.2126 * p.0[0] + 0.7152 * p.0[1] + 0.0722 * p.0[2]) as f64;
                n += a;
            }
            if n > 0.0 && sum / n > 0.5 {
                [0.0; 3]
            } else {
                [1.0; 3]
            }
        }
    };
    if colour.has_alpha() {
        notes.push(format!(
            "the target has an alpha channel: composited over [{:.2}, {:.2}, {:.2}]",
            bg[0], bg[1], bg[2]
        ));
    }
    let (w, h) = (w as usize, h as usize);
    let mut planes = vec![0.0f32; 3 * w * h];
    for (i, p) in rgba.pixels().enumerate() {
        let a = p.0[3].clamp(0.0, 1.0);
        for ch in 0..3 {
            planes[ch * w * h + i] = (p.0[ch] * a + bg[ch] as f32 * (1.0 - a)).clamp(0.0, 1.0);
        }
    }
    let (mut planes, mut w, mut h) = (planes, w, h);
    if frame && let Some((framed, fw, fh, what)) = frame_rgb(&planes, w, h) {
        notes.push(what);
        (planes, w, h) = (framed, fw, fh);
    }
    let buf: image::ImageBuffer<image::Rgb<f32>, Vec<f32>> =
        image::ImageBuffer::from_fn(w as u32, h as u32, |x, y| {
            let i = y as usize * w + x as usize;
            image::Rgb([planes[i], planes[w * h + i], planes[2 * w * h + i]])
        });
    let resized = image::imageops::resize(
        &buf,
        size as u32,
        size as u32,
        image::imageops::FilterType::Triangle,
    );
    let n = size * size;
    let mut out = vec![0.0f32; 3 * n];
    for (i, p) in resized.pixels().enumerate() {
        for ch in 0..3 {
            out[ch * n + i] = p.0[ch].clamp(0.0, 1.0);
        }
    }
    let note = if notes.is_empty() {
        None
    } else {
        Some(notes.join("; "))
    };
    let side = u32::try_from(size).map_err(|_| Error::param("size", "too large"))?;
    Ok((Image::new(side, side, 3, out)?, note))
}

/// The content of an RGB picture (three `w × h` planes) cut to its box with a margin and
/// padded to a square with the border's colour (see [`load_rgb_picture`]); `None` when
/// nothing needs doing (the content already fills a square picture) or nothing stands out.
fn frame_rgb(planes: &[f32], w: usize, h: usize) -> Option<(Vec<f32>, usize, usize, String)> {
    let n = w * h;
    let ring: Vec<usize> = (0..n)
        .filter(|&i| {
            let (x, y) = (i % w, i / w);
            x < 2 || y < 2 || x + 2 >= w || y + 2 >= h
        })
        .collect();
    let median = |mut v: Vec<f32>| -> f32 {
        let k = v.len() / 2;
        *v.select_nth_unstable_by(k, f32::total_cmp).1
    };
    let border: [f32; 3] =
        std::array::from_fn(|ch| median(ring.iter().map(|&i| planes[ch * n + i]).collect()));
    let dist = |i: usize| -> f32 {
        (0..3)
            .map(|ch| (planes[ch * n + i] - border[ch]).abs())
            .fold(0.0, f32::max)
    };
    let noise = 1.4826 * median(ring.iter().map(|&i| dist(i)).collect());
    let level = (4.0 * noise).max(0.08);
    let (mut x0, mut x1, mut y0, mut y1) = (w, 0, h, 0);
    for y in 0..h {
        for x in 0..w {
            if dist(y * w + x) > level {
                x0 = x0.min(x);
                x1 = x1.max(x);
                y0 = y0.min(y);
                y1 = y1.max(y);
            }
        }
    }
    if x0 > x1 {
        return None;
    }
    let side = (x1 - x0 + 1).max(y1 - y0 + 1);
    let margin = side / 10 + 1;
    let out_side = side + 2 * margin;
    if out_side >= w.max(h) && w == h {
        return None;
    }
    let (cx, cy) = ((x0 + x1) as f64 / 2.0, (y0 + y1) as f64 / 2.0);
    let ox = (cx - (out_side as f64 - 1.0) / 2.0).round() as isize;
    let oy = (cy - (out_side as f64 - 1.0) / 2.0).round() as isize;
    let m = out_side * out_side;
    let mut out = vec![0.0f32; 3 * m];
    for y in 0..out_side {
        for x in 0..out_side {
            let (sx, sy) = (ox + x as isize, oy + y as isize);
            let inside = sx >= 0 && sy >= 0 && (sx as usize) < w && (sy as usize) < h;
            for ch in 0..3 {
                out[ch * m + y * out_side + x] = if inside {
                    planes[ch * n + sy as usize * w + sx as usize]
                } else {
                    border[ch]
                };
            }
        }
    }
    let what = format!(
        "framed: the {}×{} box of what differs from the background, with a margin, padded to \
         a {out_side}² square",
        x1 - x0 + 1,
        y1 - y0 + 1
    );
    Some((out, out_side, out_side, what))
}

/// The start `cfg` describes: each layer drawn in the authors' style from the run's seed.
pub fn initial_stack(cfg: &FlameLearnConfig, target: &[f32]) -> Result<FlameStack> {
    let layers = cfg
        .flames
        .iter()
        .enumerate()
        .map(|(i, spec)| {
            LearnableFlame::random(
                &spec.generators()?,
                cfg.learn,
                &cfg.init,
                cfg.seed.wrapping_add(1 + i as u64),
            )
            .map_err(Error::from)
        })
        .collect::<Result<Vec<_>>>()?;
    let stack = FlameStack {
        layers,
        background: cfg.background(target)?,
    };
    stack.validate()?;
    Ok(stack)
}

/// The problem `cfg` describes for `target`.
pub fn flame_problem(cfg: &FlameLearnConfig, target: Image) -> Result<FlameProblem> {
    FlameProblem::new(
        initial_stack(cfg, &target.values)?,
        cfg.sampler.clone(),
        target,
        cfg.seed,
        cfg.redraw_every,
        &cfg.rates,
        cfg.loss.clone(),
    )
}

/// Runs the fit `cfg` describes against `target` (RGB, `size × size`), writing
/// `start.json`, `checkpoint.json` and `log.csv` into `dir`. With `resume`, continues from
/// the checkpoint there; every step is deterministic, so the result is bit-identical to an
/// uninterrupted run.
pub fn run_flame(
    cfg: &FlameLearnConfig,
    target: Image,
    dir: &Path,
    resume: bool,
    observers: Vec<Box<dyn Observe<GradState> + Send>>,
) -> Result<FlameOutcome> {
    cfg.validate()?;
    let plan = RunPlan {
        dir,
        resume,
        strategy: (cfg.strategy.name(), cfg.strategy.params()),
        iterations: cfg.iterations,
        seed: cfg.seed,
        checkpoint_every: cfg.checkpoint_every,
        terms: &FLAME_TERMS,
    };
    let resume_from = plan.prepare()?;
    let problem = flame_problem(cfg, target)?;
    let start = plan
        .start(resume_from, || Ok(problem.initial_params()))?
        .ok_or_else(|| Error::file(dir.join(START_FILE), "cannot resume: the start is missing"))?;
    let clock = Instant::now();
    let (problem, state) = plan.execute(problem, &start, resume_from, observers)?;
    let seconds = clock.elapsed().as_secs_f64();
    let last = state
        .get_param()
        .cloned()
        .ok_or_else(|| Error::Numerical("the run ended without parameters".into()))?;
    let at = state.get_iter();
    // Judged by the objective the run minimised; the MSE is reported beside it.
    let (start_cost, start_loss, start_image) = problem.scores(&start, at)?;
    let last_scores = problem.scores(&last, at).ok();
    let (theta, returned, loss, image) = match last_scores {
        Some((cost, mse, image)) if cost <= start_cost => (last, "last", mse, image),
        _ => (start.clone(), "start", start_loss, start_image),
    };
    Ok(FlameOutcome {
        stack: problem.stack_at(&theta)?,
        theta,
        returned,
        start,
        start_loss,
        iterations: at,
        loss,
        image,
        seconds,
        log: plan.log_path(),
    })
}
