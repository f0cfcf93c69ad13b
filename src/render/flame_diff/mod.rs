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
//! Determinism: trajectories are processed in a fixed number of contiguous chunks
//! ([`DiffFlameConfig::chunks`]), each into its own buffer, and chunk results are summed in
//! chunk order, so images and gradients are bit-identical for any thread count.

mod generator;

use rand::{Rng, SeedableRng};
use rand_xoshiro::Xoshiro256PlusPlus;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::chaos::Isa;
use crate::error::{Error, Result};
use crate::model::flame::learnable::{Background, FlameStack, LearnableFlame, logistic};
use crate::model::flame::xform::is_bad_value;
use generator::Generator;

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
    colors: Vec<[f64; 4]>,
    kappa: f64,
    fin: [f64; 6],
    offsets: Vec<usize>,
}

impl Prepared {
    fn new(layer: &LearnableFlame) -> Self {
        let lay = layer.layout();
        Prepared {
            gens: layer
                .generators
                .iter()
                .map(|g| Generator::new(g, layer.learn))
                .collect(),
            colors: (0..layer.len()).map(|i| layer.color(i)).collect(),
            kappa: layer.kappa(),
            fin: layer.final_coefs,
            offsets: lay.generators,
        }
    }
}

/// The 3×3 footprint of a sample at screen position `u`: its centre pixel and the
/// separable weights `e^{−2(u − p)²}` per axis.
#[derive(Clone, Copy)]
struct Footprint {
    cx: i64,
    cy: i64,
    wx: [f64; 3],
    wy: [f64; 3],
    /// `u − p` per axis and offset.
    dx: [f64; 3],
    dy: [f64; 3],
}

/// `e^{−2}`: the weight factor between a footprint's centre and its neighbours.
const E_M2: f64 = 0.135_335_283_236_612_7;

/// The footprint of a sample at screen position `u` on a `size²` image, or `None` when no
/// cell of it can fall on the image (also for NaN).
#[inline(always)]
fn footprint(u: [f64; 2], size: usize) -> Option<Footprint> {
    let hi = size as f64 + 1.0;
    if !(u[0] > -2.0 && u[1] > -2.0 && u[0] < hi && u[1] < hi) {
        return None;
    }
    // floor(u + 0.5) by truncation of a positive number (no libm call).
    let cx = ((u[0] + 2.5) as i64 - 2) as f64;
    let cy = ((u[1] + 2.5) as i64 - 2) as f64;
    let fx = u[0] - cx;
    let fy = u[1] - cy;
    // e^{−2(f ± 1)²} = e^{−2f²}·e^{∓4f}·e^{−2}: two exponentials per axis instead of three.
    let axis = |f: f64| -> [f64; 3] {
        let a = (-2.0 * f * f).exp();
        let b = (4.0 * f).exp();
        let ae = a * E_M2;
        [ae / b, a, ae * b]
    };
    Some(Footprint {
        cx: cx as i64,
        cy: cy as i64,
        wx: axis(fx),
        wy: axis(fy),
        dx: [fx + 1.0, fx, fx - 1.0],
        dy: [fy + 1.0, fy, fy - 1.0],
    })
}

impl Footprint {
    /// Calls `f(ii, jj, pixel)` for every cell `(ii, jj)` (x and y offsets 0..3) on a
    /// `size²` image, `pixel` its row-major index (rows top-down). Footprints wholly
    /// inside the image, nearly all of them, take a branch-free path over three runs of
    /// three pixels.
    #[inline(always)]
    fn cells(&self, size: usize, mut f: impl FnMut(usize, usize, usize)) {
        let n = size as i64;
        if self.cx >= 1 && self.cy >= 1 && self.cx <= n - 2 && self.cy <= n - 2 {
            // Footprint row jj is image row size − 1 − (cy + jj − 1).
            let top = ((n - 1 - (self.cy + 1)) * n + self.cx - 1) as usize;
            for jj in 0..3 {
                let row = top + (2 - jj) * size;
                for ii in 0..3 {
                    f(ii, jj, row + ii);
                }
            }
        } else {
            for jj in 0..3 {
                for ii in 0..3 {
                    let px = self.cx + ii as i64 - 1;
                    let py = self.cy + jj as i64 - 1;
                    if px >= 0 && py >= 0 && px < n && py < n {
                        f(ii, jj, ((n - 1 - py) * n + px) as usize);
                    }
                }
            }
        }
    }
}

/// Screen position of a state through the final transform.
#[inline(always)]
fn to_screen(fin: &[f64; 6], s: [f64; 2], half: f64) -> [f64; 2] {
    let y = [
        fin[0] * s[0] + fin[2] * s[1] + fin[4],
        fin[1] * s[0] + fin[3] * s[1] + fin[5],
    ];
    [(y[0] + 1.0) * half, (y[1] + 1.0) * half]
}

fn chunk_ranges(cfg: &DiffFlameConfig) -> Vec<(usize, usize)> {
    let k = cfg.chunks.min(cfg.trajectories);
    (0..k)
        .map(|c| (c * cfg.trajectories / k, (c + 1) * cfg.trajectories / k))
        .collect()
}

fn splat_layer(p: &Prepared, order: &[u8], cfg: &DiffFlameConfig) -> LayerBuffer {
    let isa = Isa::detect();
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
        .map(|((t0, t1), st)| match isa {
            #[cfg(target_arch = "x86_64")]
            // SAFETY: `Isa::detect` returned `Fma` only after finding AVX2, FMA and BMI1/2.
            Isa::Fma => unsafe { splat_chunk_fma(p, order, cfg, t0, t1, st) },
            _ => splat_chunk(p, order, cfg, t0, t1, st),
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
fn splat_chunk_fma(
    p: &Prepared,
    order: &[u8],
    cfg: &DiffFlameConfig,
    t0: usize,
    t1: usize,
    states: &mut [[f64; 2]],
) -> Vec<[f64; 5]> {
    splat_chunk(p, order, cfg, t0, t1, states)
}

/// Trajectories `t0..t1` splatted into a buffer of their own.
#[inline(always)]
fn splat_chunk(
    p: &Prepared,
    order: &[u8],
    cfg: &DiffFlameConfig,
    t0: usize,
    t1: usize,
    states: &mut [[f64; 2]],
) -> Vec<[f64; 5]> {
    let half = cfg.size as f64 / 2.0;
    let npix = cfg.size * cfg.size;
    let inv_k = 1.0 / p.kappa;
    let mut buf = vec![[0.0f64; 5]; npix];
    for t in t0..t1 {
        let g = &order[t * cfg.steps..(t + 1) * cfg.steps];
        let st: &mut [[f64; 2]] = if states.is_empty() {
            &mut []
        } else {
            &mut states[(t - t0) * cfg.steps..(t - t0 + 1) * cfg.steps]
        };
        let mut s = [0.0f64; 2];
        let mut c = [0.0f64; 4];
        let mut w = 0.0f64;
        for (j, &gi) in g.iter().enumerate().skip(1) {
            let gi = gi as usize;
            s = p.gens[gi].apply(s);
            let bad = is_bad_value(s[0]) || is_bad_value(s[1]);
            if bad {
                s = [0.0, 0.0];
            }
            if let Some(slot) = st.get_mut(j) {
                // A NaN on the tape marks the restart for the reverse pass.
                *slot = if bad { [f64::NAN, f64::NAN] } else { s };
            }
            let col = &p.colors[gi];
            for k in 0..4 {
                c[k] = col[k] + c[k] * inv_k;
            }
            w = 1.0 + w * inv_k;
            if j <= cfg.warmup {
                continue;
            }
            let Some(fp) = footprint(to_screen(&p.fin, s, half), cfg.size) else {
                continue;
            };
            fp.cells(cfg.size, |ii, jj, px| {
                let wt = fp.wx[ii] * fp.wy[jj];
                let b = &mut buf[px];
                b[0] += wt * c[0];
                b[1] += wt * c[1];
                b[2] += wt * c[2];
                b[3] += wt * c[3];
                b[4] += wt * w;
            });
        }
    }
    buf
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
    cfg.validate()?;
    stack.validate()?;
    check_order(stack, cfg, order)?;
    let npix = cfg.size * cfg.size;
    let layers: Vec<LayerBuffer> = stack
        .layers
        .iter()
        .zip(&order.layers)
        .map(|(layer, o)| splat_layer(&Prepared::new(layer), o, cfg))
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
    let isa = Isa::detect();
    let parts: Vec<Vec<f64>> = chunk_ranges(cfg)
        .into_par_iter()
        .map(|(t0, t1)| match isa {
            #[cfg(target_arch = "x86_64")]
            // SAFETY: `Isa::detect` returned `Fma` only after finding AVX2, FMA and BMI1/2.
            Isa::Fma => unsafe { backward_chunk_fma(&pass, t0, t1) },
            _ => backward_chunk(&pass, t0, t1),
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
fn backward_chunk_fma(pass: &LayerPass<'_>, t0: usize, t1: usize) -> Vec<f64> {
    backward_chunk(pass, t0, t1)
}

/// The θ gradient of trajectories `t0..t1`.
#[inline(always)]
fn backward_chunk(pass: &LayerPass<'_>, t0: usize, t1: usize) -> Vec<f64> {
    let LayerPass {
        layer,
        p,
        order,
        cfg,
        adj,
        states,
    } = *pass;
    let lay = layer.layout();
    let half = cfg.size as f64 / 2.0;
    let kappa = p.kappa;
    let inv_k = 1.0 / kappa;
    let steps = cfg.steps;
    let mut grad = vec![0.0; lay.len];
    // Per-generator sums of the colour adjoints (σ' applied once at the end) and the final
    // transform's gradient, kept out of `grad` in the hot loop.
    let mut col_acc = vec![[0.0f64; 4]; p.gens.len()];
    let mut fin_acc = [0.0f64; 6];
    let ranges: Vec<(usize, usize)> = (0..p.gens.len())
        .map(|g| (p.offsets[g], p.offsets[g] + layer.generator_params(g)))
        .collect();
    // The trajectory's tape, one cache line per step.
    let mut tape = vec![Step::default(); steps];
    let mut kappa_bar = 0.0;
    for t in t0..t1 {
        let g = &order[t * steps..(t + 1) * steps];
        // Tape: the states the forward pass kept, the quality sums again (five
        // multiply–adds a step, not worth keeping).
        let st: &[[f64; 2]] = if states.is_empty() {
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
            let bad = match st.get(j) {
                Some(kept) => {
                    s = *kept;
                    s[0].is_nan()
                }
                None => {
                    s = p.gens[gi].apply(s);
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
        // Backward scan.
        let mut lam = [0.0f64; 2];
        let mut lam_c = [0.0f64; 4];
        let mut lam_w = 0.0f64;
        for j in (1..steps).rev() {
            let (prev, cur) = tape.split_at(j);
            let step = &cur[0];
            let prev = &prev[j - 1];
            let s = step.s;
            let mut dc = [0.0f64; 4];
            let mut dw = 0.0f64;
            if j > cfg.warmup
                && let Some(fp) = footprint(to_screen(&p.fin, s, half), cfg.size)
            {
                let c = &step.c;
                let wq = step.w;
                let mut gu = [0.0f64; 2];
                fp.cells(cfg.size, |ii, jj, px| {
                    let a = &adj[px];
                    let wt = fp.wx[ii] * fp.wy[jj];
                    for k in 0..4 {
                        dc[k] += wt * a[k];
                    }
                    dw += wt * a[4];
                    let val = a[0] * c[0] + a[1] * c[1] + a[2] * c[2] + a[3] * c[3] + a[4] * wq;
                    let f = -4.0 * val * wt;
                    gu[0] += f * fp.dx[ii];
                    gu[1] += f * fp.dy[jj];
                });
                let yb = [gu[0] * half, gu[1] * half];
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
            for k in 0..4 {
                lam_c[k] += dc[k];
            }
            lam_w += dw;
            let gi = g[j] as usize;
            let acc = &mut col_acc[gi];
            for k in 0..4 {
                acc[k] += lam_c[k];
            }
            let prev_c = &prev.c;
            let prev_w = prev.w;
            kappa_bar -= (lam_c[0] * prev_c[0]
                + lam_c[1] * prev_c[1]
                + lam_c[2] * prev_c[2]
                + lam_c[3] * prev_c[3]
                + lam_w * prev_w)
                * inv_k
                * inv_k;
            for l in &mut lam_c {
                *l *= inv_k;
            }
            lam_w *= inv_k;
            // The map s_j = f_{g_j}(s_{j−1}).
            if step.reset {
                lam = [0.0, 0.0];
                continue;
            }
            let (a, b) = ranges[gi];
            lam = p.gens[gi].vjp(prev.s, lam, &mut grad[a..b]);
        }
    }
    grad[lay.kappa_at] += kappa_bar * (kappa - 1.0);
    for (k, v) in fin_acc.iter().enumerate() {
        grad[lay.final_at + k] += v;
    }
    for (g, acc) in col_acc.iter().enumerate() {
        let col = &p.colors[g];
        for k in 0..4 {
            grad[lay.colors_at + 4 * g + k] += acc[k] * col[k] * (1.0 - col[k]);
        }
    }
    grad
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn footprint_centre_is_the_nearest_pixel() {
        for u in [-1.4, -0.6, -0.4, 0.0, 0.49, 0.51, 7.3, 99.5] {
            let fp = footprint([u, u], 200).unwrap();
            assert_eq!(fp.cx as f64, (u + 0.5).floor(), "u = {u}");
            assert!((fp.wx[1] - (-2.0 * (u - fp.cx as f64).powi(2)).exp()).abs() < 1e-13);
        }
    }
}
