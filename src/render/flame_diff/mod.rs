//! The differentiable flame pipeline of Bannister & Nowrouzezahrai (*Learnable Fractal
//! Flames*, their Fig. 3) as one fused op with a hand-written reverse pass: sampler →
//! splatter → painter → compositor → RGB image, and back to every parameter of a
//! [`FlameStack`].
//!
//! Forward, per layer:
//! 1. **Sampler**: `b` trajectories of `l` steps from the origin, `s_j = f_{g_j}(s_{j−1})`,
//!    with the generator order `G` drawn once ([`GeneratorOrder`], uniform over the
//!    generators; redrawing it is the caller's choice). A point that leaves the plane (NaN or
//!    beyond ±10¹⁰) restarts its trajectory at the origin.
//! 2. **Quality** (Eq. 2): `q_j = e_{g_j} + q_{j−1}/κ`, the whole history (the authors' code
//!    keeps the last 10 terms: a difference of κ⁻¹⁰ ≈ 0.1 % at κ = 2). The painter needs
//!    only `w = Σ q` and `Σᵢ cᵢ·qᵢ` (colours `cᵢ` RGBA), so each sample carries those five
//!    numbers, whatever the number of generators: `W_j = 1 + W_{j−1}/κ`,
//!    `C_j = c_{g_j} + C_{j−1}/κ`.
//! 3. **Splatter**: after `m` warm-up steps each sample goes through the final affine
//!    transform onto the view `[−1, 1]²` (+y up; pixel centres at integer coordinates
//!    `u = (y + 1)·size/2`) and is splatted into the 3×3 pixels around its nearest pixel
//!    with weight `e^{−2d²}`.
//! 4. **Painter** (Eq. 3, as the authors' code computes it): `α_w = log(1 + w)/log(1 +
//!    w_max)`, `rgba = α_w·C/(1 + w)`, colour premultiplied by alpha.
//!
//! Then the **compositor** lays the layers "over" the background, first layer at the bottom.
//! [`mse`] is the authors' loss (squared error summed over the three channels, averaged
//! over pixels). The reverse pass takes any `∂L/∂image`, so other image losses compose.
//!
//! Layout: `footprint` (where a sample lands and the splat's weights, forward and
//! reverse, vectorised), `generator` (each generator's map and vector–Jacobian product;
//! all-linear layers as flat affine maps with loops of their own). The hot loops are
//! compiled twice, portable and AVX2+FMA, chosen at run time ([`forward_with_isa`] picks
//! one), with the same operations in both: the same bits.
//!
//! [`FlameRenderer`] is the pipeline as a [`Renderer`](crate::render::Renderer): a stack to
//! three RGB planes, the generator order its sampling state, drawn once per run.
//!
//! Determinism: trajectories are processed in a fixed number of contiguous chunks
//! ([`DiffFlameConfig::chunks`]), each into its own buffer, and chunk results are summed in
//! chunk order, so images and gradients are bit-identical for any thread count.

mod footprint;
mod generator;
mod renderer;

use rand::{Rng, SeedableRng};
use rand_xoshiro::Xoshiro256PlusPlus;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};
use crate::isa::{FmaIsa, Isa, IsaLevel, PortableIsa};
use crate::model::flame::learnable::{Background, FlameStack, LearnableFlame, logistic};
use crate::model::flame::xform::is_bad_value;
use footprint::{footprint, to_screen};
use generator::{Generator, LinearMaps, Maps};
pub use renderer::FlameRenderer;

/// The sampling and image settings of the op.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct DiffFlameConfig {
    /// Image side in pixels (the image is square, the view `[−1, 1]²`).
    pub size: usize,
    /// Parallel trajectories per layer (authors: 1000).
    pub trajectories: usize,
    /// Steps per trajectory (authors: 1000; 10⁶ samples per layer).
    pub steps: usize,
    /// Steps before a trajectory's samples are splatted (authors: 20).
    pub warmup: usize,
    /// Fixed work split of the trajectories (results do not depend on the thread count,
    /// only on this).
    pub chunks: usize,
}

impl Default for DiffFlameConfig {
    fn default() -> Self {
        DiffFlameConfig {
            size: 100,
            trajectories: 1000,
            steps: 1000,
            warmup: 20,
            chunks: 8,
        }
    }
}

impl DiffFlameConfig {
    /// Checks the numbers, naming the field.
    pub fn validate(&self) -> Result<()> {
        let positive = |name: &'static str, v: usize| {
            if v == 0 {
                Err(Error::param(name, "must be ≥ 1"))
            } else {
                Ok(())
            }
        };
        positive("size", self.size)?;
        positive("trajectories", self.trajectories)?;
        positive("chunks", self.chunks)?;
        if self.size > 8192 {
            return Err(Error::param(
                "size",
                format!("at most 8192, got {}", self.size),
            ));
        }
        if self.steps <= self.warmup + 1 {
            return Err(Error::param(
                "steps",
                format!(
                    "must exceed warmup + 1 = {} so that samples are drawn, got {}",
                    self.warmup + 1,
                    self.steps
                ),
            ));
        }
        Ok(())
    }

    /// Samples splatted per layer.
    pub fn samples(&self) -> usize {
        self.trajectories * (self.steps - self.warmup - 1)
    }
}

/// The generator order `G` of every layer: `trajectories × steps` indices each (index 0 of
/// a trajectory is unused: its first state is the origin), drawn for a stack's generator
/// counts and checked against them in O(1) per layer when used.
#[derive(Clone, Debug, PartialEq)]
pub struct GeneratorOrder {
    /// Per layer, row-major by trajectory.
    layers: Vec<Vec<u8>>,
    /// Per layer, the number of generators the indices were drawn for.
    generators: Vec<usize>,
}

impl GeneratorOrder {
    /// Uniform draws for every layer of `stack`, seeded.
    pub fn draw(stack: &FlameStack, cfg: &DiffFlameConfig, seed: u64) -> Self {
        let layers = stack
            .layers
            .iter()
            .enumerate()
            .map(|(l, layer)| {
                let n = layer.len() as u32;
                let mut rng = Xoshiro256PlusPlus::seed_from_u64(
                    seed ^ (l as u64 + 1).wrapping_mul(0x9e37_79b9_7f4a_7c15),
                );
                (0..cfg.trajectories * cfg.steps)
                    .map(|_| rng.random_range(0..n) as u8)
                    .collect()
            })
            .collect();
        GeneratorOrder {
            layers,
            generators: stack.layers.iter().map(|l| l.len()).collect(),
        }
    }
}

/// One layer's splat buffer: per pixel (row-major, row 0 at the top) `Σ wt·C` (RGBA) and
/// `Σ wt·W`.
#[derive(Clone, Debug)]
pub struct LayerBuffer {
    /// `[C_r, C_g, C_b, C_a, W]` per pixel.
    pub pixels: Vec<[f64; 5]>,
    /// The largest `W` and where it is (first such pixel).
    pub w_max: f64,
    argmax: usize,
    /// Every trajectory's states (NaN where a trajectory restarted at the origin), for the
    /// reverse pass; empty for layers of linear generators, whose reverse pass recomputes
    /// them.
    states: Vec<[f64; 2]>,
}

/// What the forward pass produced.
#[derive(Clone, Debug)]
pub struct FlameFrame {
    /// The composited RGB image: three planes of `size × size`, row 0 at the top.
    pub image: Vec<f64>,
    /// Each layer's splat buffer (kept for the reverse pass).
    pub layers: Vec<LayerBuffer>,
    /// Each layer's painted RGBA (premultiplied), four planes.
    pub painted: Vec<Vec<f64>>,
}

/// A layer prepared for the loops.
struct Prepared {
    gens: Vec<Generator>,
    /// The generators as flat affine maps when they all are.
    linear: Option<LinearMaps>,
    colors: Vec<[f64; 4]>,
    kappa: f64,
    fin: [f64; 6],
    offsets: Vec<usize>,
}

impl Prepared {
    fn new(layer: &LearnableFlame) -> Self {
        let lay = layer.layout();
        let gens: Vec<Generator> = layer
            .generators
            .iter()
            .map(|g| Generator::new(g, layer.learn))
            .collect();
        Prepared {
            linear: LinearMaps::of(&gens),
            gens,
            colors: (0..layer.len()).map(|i| layer.color(i)).collect(),
            kappa: layer.kappa(),
            fin: layer.final_coefs,
            offsets: lay.generators,
        }
    }
}

fn chunk_ranges(cfg: &DiffFlameConfig) -> Vec<(usize, usize)> {
    let k = cfg.chunks.min(cfg.trajectories);
    (0..k)
        .map(|c| (c * cfg.trajectories / k, (c + 1) * cfg.trajectories / k))
        .collect()
}

fn splat_layer(p: &Prepared, order: &[u8], cfg: &DiffFlameConfig, isa: Isa) -> LayerBuffer {
    // Non-linear generators are costly to re-apply: their layers keep the states for the
    // reverse pass (16 bytes a sample); linear ones recompute them, which is cheaper than
    // writing and reading them back.
    let keep = p.gens.iter().any(|g| !g.is_linear());
    let mut states = vec![
        [0.0f64; 2];
        if keep {
            cfg.trajectories * cfg.steps
        } else {
            0
        }
    ];
    let ranges = chunk_ranges(cfg);
    let mut slices: Vec<&mut [[f64; 2]]> = Vec::with_capacity(ranges.len());
    let mut rest: &mut [[f64; 2]] = &mut states;
    for &(t0, t1) in &ranges {
        let n = if keep { (t1 - t0) * cfg.steps } else { 0 };
        let (head, tail) = rest.split_at_mut(n);
        slices.push(head);
        rest = tail;
    }
    let parts: Vec<Vec<[f64; 5]>> = ranges
        .into_par_iter()
        .zip(slices)
        .map(|((t0, t1), st)| match (isa, &p.linear) {
            #[cfg(target_arch = "x86_64")]
            // SAFETY: `isa` is `Fma` only after `Isa::checked` found AVX2, FMA and BMI1/2.
            (Isa::Fma, Some(lin)) => unsafe { splat_chunk_fma(p, lin, order, cfg, t0, t1, st) },
            #[cfg(target_arch = "x86_64")]
            // SAFETY: as above.
            (Isa::Fma, None) => unsafe {
                splat_chunk_fma(p, p.gens.as_slice(), order, cfg, t0, t1, st)
            },
            (_, Some(lin)) => splat_chunk(PortableIsa, p, lin, order, cfg, t0, t1, st),
            (_, None) => splat_chunk(PortableIsa, p, p.gens.as_slice(), order, cfg, t0, t1, st),
        })
        .collect();
    let mut it = parts.into_iter();
    let mut pixels = it.next().expect("at least one chunk");
    for part in it {
        for (a, b) in pixels.iter_mut().zip(&part) {
            for k in 0..5 {
                a[k] += b[k];
            }
        }
    }
    let (mut w_max, mut argmax) = (0.0, 0);
    for (i, px) in pixels.iter().enumerate() {
        if px[4] > w_max {
            w_max = px[4];
            argmax = i;
        }
    }
    LayerBuffer {
        pixels,
        w_max,
        argmax,
        states,
    }
}

/// [`splat_chunk`] compiled with AVX2 and FMA (no contraction: the same bits).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma,bmi1,bmi2")]
fn splat_chunk_fma<M: Maps + ?Sized>(
    p: &Prepared,
    maps: &M,
    order: &[u8],
    cfg: &DiffFlameConfig,
    t0: usize,
    t1: usize,
    states: &mut [[f64; 2]],
) -> Vec<[f64; 5]> {
    // SAFETY: this copy runs only where `Isa::checked` found AVX2, FMA and BMI1/2.
    let isa = unsafe { FmaIsa::new_unchecked() };
    splat_chunk(isa, p, maps, order, cfg, t0, t1, states)
}

/// Trajectories `t0..t1` splatted into a buffer of their own (generators applied on
/// instruction set `I`).
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn splat_chunk<M: Maps + ?Sized, I: IsaLevel>(
    isa: I,
    p: &Prepared,
    maps: &M,
    order: &[u8],
    cfg: &DiffFlameConfig,
    t0: usize,
    t1: usize,
    states: &mut [[f64; 2]],
) -> Vec<[f64; 5]> {
    let npix = cfg.size * cfg.size;
    let mut buf = vec![[0.0f64; 5]; npix];
    let mut t = t0;
    while t + SPLAT_LANES <= t1 {
        splat_group::<M, I, SPLAT_LANES>(isa, p, maps, order, cfg, t, t0, states, &mut buf);
        t += SPLAT_LANES;
    }
    while t < t1 {
        splat_group::<M, I, 1>(isa, p, maps, order, cfg, t, t0, states, &mut buf);
        t += 1;
    }
    buf
}

/// Trajectories the forward loop runs side by side: independent chains for the CPU to
/// overlap (one trajectory's step waits on its previous one).
const SPLAT_LANES: usize = 8;

/// Trajectories `t..t + L` (of a chunk starting at `t0`) splatted into `buf`, step by step
/// side by side.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn splat_group<M: Maps + ?Sized, I: IsaLevel, const L: usize>(
    isa: I,
    p: &Prepared,
    maps: &M,
    order: &[u8],
    cfg: &DiffFlameConfig,
    t: usize,
    t0: usize,
    states: &mut [[f64; 2]],
    buf: &mut [[f64; 5]],
) {
    let steps = cfg.steps;
    let half = cfg.size as f64 / 2.0;
    let inv_k = 1.0 / p.kappa;
    let keep = !states.is_empty();
    let mut s = [[0.0f64; 2]; L];
    let mut c = [[0.0f64; 4]; L];
    let mut w = [0.0f64; L];
    for j in 1..steps {
        for l in 0..L {
            let gi = order[(t + l) * steps + j] as usize;
            let mut x = maps.apply(isa, gi, s[l]);
            let bad = is_bad_value(x[0]) || is_bad_value(x[1]);
            if bad {
                x = [0.0, 0.0];
            }
            s[l] = x;
            if keep {
                // A NaN on the tape marks the restart for the reverse pass.
                states[(t + l - t0) * steps + j] = if bad { [f64::NAN, f64::NAN] } else { x };
            }
            let col = &p.colors[gi];
            for k in 0..4 {
                c[l][k] = col[k] + c[l][k] * inv_k;
            }
            w[l] = 1.0 + w[l] * inv_k;
        }
        if j <= cfg.warmup {
            continue;
        }
        for l in 0..L {
            let Some(fp) = footprint(isa, to_screen(&p.fin, s[l], half), cfg.size) else {
                continue;
            };
            let cw = [c[l][0], c[l][1], c[l][2], c[l][3], w[l]];
            fp.splat(isa, cfg.size, buf, &cw);
        }
    }
}

/// The painter's scale `s = log(1 + w)/((1 + w)·log(1 + w_max))` (0 on an empty layer).
#[inline(always)]
fn paint_scale(w: f64, w_max: f64) -> f64 {
    if w_max <= 0.0 {
        0.0
    } else {
        (1.0 + w).ln() / ((1.0 + w) * (1.0 + w_max).ln())
    }
}

fn check_order(stack: &FlameStack, cfg: &DiffFlameConfig, order: &GeneratorOrder) -> Result<()> {
    if order.layers.len() != stack.layers.len() {
        return Err(Error::Shape(format!(
            "a generator order for {} layers, the stack has {}",
            order.layers.len(),
            stack.layers.len()
        )));
    }
    for (l, ((o, &n), layer)) in order
        .layers
        .iter()
        .zip(&order.generators)
        .zip(&stack.layers)
        .enumerate()
    {
        if o.len() != cfg.trajectories * cfg.steps {
            return Err(Error::Shape(format!(
                "layer {l}: generator order of {} entries for {} trajectories × {} steps",
                o.len(),
                cfg.trajectories,
                cfg.steps
            )));
        }
        if n != layer.len() {
            return Err(Error::Shape(format!(
                "layer {l}: generator order drawn for {n} generators, the layer has {}",
                layer.len()
            )));
        }
    }
    Ok(())
}

/// The forward pass: the stack rendered with generator order `order`.
pub fn forward(
    stack: &FlameStack,
    cfg: &DiffFlameConfig,
    order: &GeneratorOrder,
) -> Result<FlameFrame> {
    forward_with_isa(stack, cfg, order, Isa::detect())
}

/// [`forward`] with the hot loops compiled for `isa` (an error when this CPU cannot run
/// it). Every instruction set gives the same bits.
pub fn forward_with_isa(
    stack: &FlameStack,
    cfg: &DiffFlameConfig,
    order: &GeneratorOrder,
    isa: Isa,
) -> Result<FlameFrame> {
    let isa = isa.checked()?;
    cfg.validate()?;
    stack.validate()?;
    check_order(stack, cfg, order)?;
    let npix = cfg.size * cfg.size;
    let layers: Vec<LayerBuffer> = stack
        .layers
        .iter()
        .zip(&order.layers)
        .map(|(layer, o)| splat_layer(&Prepared::new(layer), o, cfg, isa))
        .collect();
    let painted: Vec<Vec<f64>> = layers
        .iter()
        .map(|b| {
            let mut out = vec![0.0; 4 * npix];
            for (i, px) in b.pixels.iter().enumerate() {
                let s = paint_scale(px[4], b.w_max);
                let a = px[3] * s;
                out[i] = px[0] * s * a;
                out[npix + i] = px[1] * s * a;
                out[2 * npix + i] = px[2] * s * a;
                out[3 * npix + i] = a;
            }
            out
        })
        .collect();
    let bg = stack.background.rgb();
    let mut image = vec![0.0; 3 * npix];
    for i in 0..npix {
        for ch in 0..3 {
            let mut col = bg[ch];
            for p in &painted {
                col = col * (1.0 - p[3 * npix + i]).max(0.0) + p[ch * npix + i];
            }
            image[ch * npix + i] = col;
        }
    }
    Ok(FlameFrame {
        image,
        layers,
        painted,
    })
}

/// The authors' loss: `Σ_pixels Σ_channels (image − target)² / pixels`, and its gradient
/// with respect to the image. `target` is three planes like the image.
pub fn mse(image: &[f64], target: &[f32]) -> Result<(f64, Vec<f64>)> {
    if image.len() != target.len() || !image.len().is_multiple_of(3) {
        return Err(Error::Shape(format!(
            "an image of {} values against a target of {}",
            image.len(),
            target.len()
        )));
    }
    let n = (image.len() / 3) as f64;
    let mut loss = 0.0;
    let grad = image
        .iter()
        .zip(target)
        .map(|(&a, &b)| {
            let d = a - b as f64;
            loss += d * d;
            2.0 * d / n
        })
        .collect();
    Ok((loss / n, grad))
}

/// The reverse pass: `∂L/∂θ` (θ of [`FlameStack::params`]) from `grad_image` = `∂L/∂image`
/// of the frame `forward` returned for the same stack, settings and order.
pub fn backward(
    stack: &FlameStack,
    cfg: &DiffFlameConfig,
    order: &GeneratorOrder,
    frame: &FlameFrame,
    grad_image: &[f64],
) -> Result<Vec<f64>> {
    backward_with_isa(stack, cfg, order, frame, grad_image, Isa::detect())
}

/// [`backward`] with the hot loops compiled for `isa` (an error when this CPU cannot run
/// it). Every instruction set gives the same bits.
pub fn backward_with_isa(
    stack: &FlameStack,
    cfg: &DiffFlameConfig,
    order: &GeneratorOrder,
    frame: &FlameFrame,
    grad_image: &[f64],
    isa: Isa,
) -> Result<Vec<f64>> {
    let isa = isa.checked()?;
    check_order(stack, cfg, order)?;
    let npix = cfg.size * cfg.size;
    if grad_image.len() != 3 * npix || frame.layers.len() != stack.layers.len() {
        return Err(Error::Shape(format!(
            "an image gradient of {} values for a {}² RGB frame",
            grad_image.len(),
            cfg.size
        )));
    }
    let nl = stack.layers.len();
    // Compositor and painters, pixel by pixel: ∂L/∂(C, W) per layer.
    let mut adj: Vec<Vec<[f64; 5]>> = vec![vec![[0.0; 5]; npix]; nl];
    let mut wmax_bar = vec![0.0; nl];
    let mut bg_bar = [0.0; 3];
    let bg = stack.background.rgb();
    let mut under = vec![[0.0f64; 3]; nl];
    for i in 0..npix {
        // Colours under each layer.
        let mut col = bg;
        for (l, p) in frame.painted.iter().enumerate() {
            under[l] = col;
            let a = p[3 * npix + i];
            for ch in 0..3 {
                col[ch] = col[ch] * (1.0 - a).max(0.0) + p[ch * npix + i];
            }
        }
        let mut g = [
            grad_image[i],
            grad_image[npix + i],
            grad_image[2 * npix + i],
        ];
        for l in (0..nl).rev() {
            let p = &frame.painted[l];
            let a = p[3 * npix + i];
            let open = 1.0 - a;
            let a_bar = if open > 0.0 {
                -(g[0] * under[l][0] + g[1] * under[l][1] + g[2] * under[l][2])
            } else {
                0.0
            };
            let rgb_bar = g;
            for gc in &mut g {
                *gc *= open.max(0.0);
            }
            // Painter: a = C_a·s, rgb = C_rgb·C_a·s².
            let buf = &frame.layers[l];
            let px = &buf.pixels[i];
            let s = paint_scale(px[4], buf.w_max);
            if s == 0.0 && px[3] == 0.0 {
                continue;
            }
            let s2 = s * s;
            let ad = &mut adj[l][i];
            let mut dot = 0.0;
            for ch in 0..3 {
                ad[ch] = rgb_bar[ch] * px[3] * s2;
                dot += rgb_bar[ch] * px[ch];
            }
            ad[3] = dot * s2 + a_bar * s;
            let s_bar = dot * px[3] * 2.0 * s + a_bar * px[3];
            if buf.w_max > 0.0 {
                let lw = (1.0 + px[4]).ln();
                let lm = (1.0 + buf.w_max).ln();
                let opw = 1.0 + px[4];
                ad[4] = s_bar * (1.0 - lw) / (opw * opw * lm);
                wmax_bar[l] += s_bar * (-lw / (opw * lm * lm * (1.0 + buf.w_max)));
            }
        }
        for ch in 0..3 {
            bg_bar[ch] += g[ch];
        }
    }
    for l in 0..nl {
        if frame.layers[l].w_max > 0.0 {
            adj[l][frame.layers[l].argmax][4] += wmax_bar[l];
        }
    }
    let offsets = stack.offsets();
    let mut grad = vec![0.0; stack.n_params()];
    for (l, layer) in stack.layers.iter().enumerate() {
        let g = backward_layer(
            layer,
            &order.layers[l],
            cfg,
            &adj[l],
            &frame.layers[l].states,
            isa,
        );
        grad[offsets[l]..offsets[l + 1]].copy_from_slice(&g);
    }
    if let Background::Learned(logits) = stack.background {
        let k = offsets[nl];
        for ch in 0..3 {
            let b = logistic(logits[ch]);
            grad[k + ch] = bg_bar[ch] * b * (1.0 - b);
        }
    }
    Ok(grad)
}

/// One layer's θ gradient from its buffer adjoints, trajectory by trajectory: a tape of the
/// states (those the forward pass kept, or recomputed for linear layers) and the quality
/// sums, scanned backwards.
fn backward_layer(
    layer: &LearnableFlame,
    order: &[u8],
    cfg: &DiffFlameConfig,
    adj: &[[f64; 5]],
    states: &[[f64; 2]],
    isa: Isa,
) -> Vec<f64> {
    let p = Prepared::new(layer);
    let pass = LayerPass {
        layer,
        p: &p,
        order,
        cfg,
        adj,
        states,
    };
    let parts: Vec<Vec<f64>> = chunk_ranges(cfg)
        .into_par_iter()
        .map(|(t0, t1)| match (isa, &p.linear) {
            #[cfg(target_arch = "x86_64")]
            // SAFETY: `isa` is `Fma` only after `Isa::checked` found AVX2, FMA and BMI1/2.
            (Isa::Fma, Some(lin)) => unsafe { backward_chunk_fma(&pass, lin, t0, t1) },
            #[cfg(target_arch = "x86_64")]
            // SAFETY: as above.
            (Isa::Fma, None) => unsafe { backward_chunk_fma(&pass, p.gens.as_slice(), t0, t1) },
            (_, Some(lin)) => backward_chunk(PortableIsa, &pass, lin, t0, t1),
            (_, None) => backward_chunk(PortableIsa, &pass, p.gens.as_slice(), t0, t1),
        })
        .collect();
    let mut it = parts.into_iter();
    let mut grad = it.next().expect("at least one chunk");
    for part in it {
        for (a, b) in grad.iter_mut().zip(&part) {
            *a += b;
        }
    }
    grad
}

/// What the reverse pass of one layer reads.
#[derive(Clone, Copy)]
struct LayerPass<'a> {
    layer: &'a LearnableFlame,
    p: &'a Prepared,
    order: &'a [u8],
    cfg: &'a DiffFlameConfig,
    /// `∂L/∂(C, W)` per pixel.
    adj: &'a [[f64; 5]],
    /// The kept forward states (empty: recompute).
    states: &'a [[f64; 2]],
}

/// One step of a trajectory's tape: the state, the quality sums, whether it restarted.
#[derive(Clone, Copy, Debug, Default)]
#[repr(align(64))]
struct Step {
    s: [f64; 2],
    c: [f64; 4],
    w: f64,
    reset: bool,
}

/// [`backward_chunk`] compiled with AVX2 and FMA (no contraction: the same bits).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma,bmi1,bmi2")]
fn backward_chunk_fma<M: Maps + ?Sized>(
    pass: &LayerPass<'_>,
    maps: &M,
    t0: usize,
    t1: usize,
) -> Vec<f64> {
    // SAFETY: this copy runs only where `Isa::checked` found AVX2, FMA and BMI1/2.
    let isa = unsafe { FmaIsa::new_unchecked() };
    backward_chunk(isa, pass, maps, t0, t1)
}

/// The θ gradient of trajectories `t0..t1`.
#[inline(always)]
fn backward_chunk<M: Maps + ?Sized, I: IsaLevel>(
    isa: I,
    pass: &LayerPass<'_>,
    maps: &M,
    t0: usize,
    t1: usize,
) -> Vec<f64> {
    let LayerPass { layer, p, cfg, .. } = *pass;
    let lay = layer.layout();
    let mut acc = Sums {
        grad: vec![0.0; lay.len],
        col: vec![[0.0f64; 4]; p.gens.len()],
        fin: [0.0f64; 6],
        kappa: 0.0,
        ranges: (0..p.gens.len())
            .map(|g| (p.offsets[g], p.offsets[g] + layer.generator_params(g)))
            .collect(),
    };
    // The trajectory's tape, one cache line per step.
    let mut tape = vec![Step::default(); cfg.steps];
    for t in t0..t1 {
        backward_trajectory::<M, I>(isa, pass, maps, t, &mut tape, &mut acc);
    }
    let mut grad = acc.grad;
    grad[lay.kappa_at] += acc.kappa * (p.kappa - 1.0);
    for (k, v) in acc.fin.iter().enumerate() {
        grad[lay.final_at + k] += v;
    }
    for (g, sum) in acc.col.iter().enumerate() {
        let col = &p.colors[g];
        for k in 0..4 {
            grad[lay.colors_at + 4 * g + k] += sum[k] * col[k] * (1.0 - col[k]);
        }
    }
    grad
}

/// A chunk's gradient sums: θ, and the per-generator colour adjoints (σ' applied once at
/// the end), the final transform's gradient and `∂L/∂(1/κ)` kept out of `grad` in the hot
/// loop.
struct Sums {
    grad: Vec<f64>,
    col: Vec<[f64; 4]>,
    fin: [f64; 6],
    kappa: f64,
    /// Each generator's θ range.
    ranges: Vec<(usize, usize)>,
}

/// The reverse pass of trajectory `t`: its tape (the states the forward pass kept or
/// recomputed, the quality sums again: five multiply–adds a step, not worth keeping),
/// then the scan backwards. (Running several trajectories side by side, which pays in the
/// forward pass, measured slower here: 37 ms per iteration with one, 39 with two, 41 with
/// four.)
#[inline(always)]
fn backward_trajectory<M: Maps + ?Sized, I: IsaLevel>(
    isa: I,
    pass: &LayerPass<'_>,
    maps: &M,
    t: usize,
    tape: &mut [Step],
    acc: &mut Sums,
) {
    let LayerPass {
        p,
        order,
        cfg,
        adj,
        states,
        ..
    } = *pass;
    let steps = cfg.steps;
    let half = cfg.size as f64 / 2.0;
    let inv_k = 1.0 / p.kappa;
    let g = &order[t * steps..(t + 1) * steps];
    let kept: &[[f64; 2]] = if states.is_empty() {
        &[]
    } else {
        &states[t * steps..(t + 1) * steps]
    };
    let mut s = [0.0f64; 2];
    let mut c = [0.0f64; 4];
    let mut w = 0.0f64;
    tape[0] = Step::default();
    for j in 1..steps {
        let gi = g[j] as usize;
        let bad = match kept.get(j) {
            Some(k) => {
                s = *k;
                s[0].is_nan()
            }
            None => {
                s = maps.apply(isa, gi, s);
                is_bad_value(s[0]) || is_bad_value(s[1])
            }
        };
        if bad {
            s = [0.0, 0.0];
        }
        let col = &p.colors[gi];
        for k in 0..4 {
            c[k] = col[k] + c[k] * inv_k;
        }
        w = 1.0 + w * inv_k;
        tape[j] = Step {
            s,
            c,
            w,
            reset: bad,
        };
    }
    let mut lam = [0.0f64; 2];
    let mut lam_c = [0.0f64; 4];
    let mut lam_w = 0.0f64;
    for j in (1..steps).rev() {
        let step = &tape[j];
        let prev = &tape[j - 1];
        let s = step.s;
        if j > cfg.warmup
            && let Some(fp) = footprint(isa, to_screen(&p.fin, s, half), cfg.size)
        {
            let cw = [step.c[0], step.c[1], step.c[2], step.c[3], step.w];
            let (sums, gu) = fp.gather(isa, cfg.size, adj, &cw);
            for k in 0..4 {
                lam_c[k] += sums[k];
            }
            lam_w += sums[4];
            let yb = [gu[0] * half, gu[1] * half];
            let fin_acc = &mut acc.fin;
            fin_acc[0] += yb[0] * s[0];
            fin_acc[1] += yb[1] * s[0];
            fin_acc[2] += yb[0] * s[1];
            fin_acc[3] += yb[1] * s[1];
            fin_acc[4] += yb[0];
            fin_acc[5] += yb[1];
            let fin = &p.fin;
            lam[0] += fin[0] * yb[0] + fin[1] * yb[1];
            lam[1] += fin[2] * yb[0] + fin[3] * yb[1];
        }
        // Quality recurrences: C_j = c_{g_j} + C_{j−1}/κ, W_j = 1 + W_{j−1}/κ.
        let gi = g[j] as usize;
        let col = &mut acc.col[gi];
        for k in 0..4 {
            col[k] += lam_c[k];
        }
        let prev_c = &prev.c;
        acc.kappa -= (lam_c[0] * prev_c[0]
            + lam_c[1] * prev_c[1]
            + lam_c[2] * prev_c[2]
            + lam_c[3] * prev_c[3]
            + lam_w * prev.w)
            * inv_k
            * inv_k;
        for v in lam_c.iter_mut() {
            *v *= inv_k;
        }
        lam_w *= inv_k;
        // The map s_j = f_{g_j}(s_{j−1}).
        if step.reset {
            lam = [0.0, 0.0];
            continue;
        }
        let (a, b) = acc.ranges[gi];
        lam = maps.vjp(isa, gi, prev.s, lam, &mut acc.grad[a..b]);
    }
}
