//! Learnable flames (Bannister & Nowrouzezahrai): the parameters of the differentiable
//! flame pipeline of [`crate::render::flame_diff`], their flat layout θ, a seeded start
//! in the authors' style, and the export of a learned flame to a flam3 genome.
//!
//! A [`LearnableFlame`] is one layer of the paper's Fig. 3: a *sampler* (generators — flame
//! transforms without random variations — applied in a fixed random order), a *splatter*
//! (the final affine transform, and the quality-blend parameter κ > 1 of Eq. 2) and a
//! *painter* (one RGBA colour per generator). A [`FlameStack`] composites one or more layers
//! over a fixed or learnable background (the *compositor*).
//!
//! ## θ, layer after layer, then the background
//! For each layer:
//! 1. each generator: its six pre-affine coefficients `a b c d e f` (flam3's convention
//!    `x' = a·x + c·y + e`, `y' = b·x + d·y + f`); then its variation weights if
//!    [`Learn::weights`]; then its six post-affine coefficients if [`Learn::post`];
//! 2. the final transform's six coefficients (same convention);
//! 3. `β` with κ = 1 + e^β (the authors' constraint κ > 1);
//! 4. the colours: four logits per generator (RGBA = logistic(logit)).
//!
//! Then the background's three logits when it is learned.

use rand::{Rng, SeedableRng};
use rand_xoshiro::Xoshiro256PlusPlus;
use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};
use crate::model::flame::genome::Flame;
use crate::model::flame::palette::Palette;
use crate::model::flame::variation::{Variation, VariationKind};
use crate::model::flame::xform::{Coefs, IDENTITY, Xform};

/// Which parts of the generators are learned besides their pre-affine maps.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Learn {
    /// The variation weights.
    pub weights: bool,
    /// The post-affine maps.
    pub post: bool,
}

/// One layer: generators, final transform, κ, colours.
#[derive(Clone, Debug, PartialEq)]
pub struct LearnableFlame {
    /// The generators (deterministic flame transforms; selection is uniform).
    pub generators: Vec<Xform>,
    /// The final affine transform (flam3 order), applied before the points are splatted
    /// onto the view `[−1, 1]²`.
    pub final_coefs: Coefs,
    /// `β`, with the quality blend κ = 1 + e^β.
    pub kappa_raw: f64,
    /// RGBA logits per generator.
    pub color_logits: Vec<[f64; 4]>,
    /// What θ holds.
    pub learn: Learn,
}

/// How the start is drawn (the authors' `initialize_parameters_randomly`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct LearnableInit {
    /// Translations uniform in `[−t, t]²` (authors: 1.25).
    pub translation: f64,
    /// Linear parts `v·I` with `v` uniform in `[−s, s]` (authors: 0.75).
    pub scale: f64,
    /// Final-transform translation uniform in `[−f, f]²` (authors: 0.5).
    pub final_translation: f64,
    /// The quality blend κ at the start (> 1; authors: 2).
    pub kappa: f64,
}

impl Default for LearnableInit {
    fn default() -> Self {
        LearnableInit {
            translation: 1.25,
            scale: 0.75,
            final_translation: 0.5,
            kappa: 2.0,
        }
    }
}

/// logistic(x) = 1 / (1 + e^{−x}).
#[inline(always)]
pub fn logistic(x: f64) -> f64 {
    1.0 / (1.0 + (-x).exp())
}

/// κ from its raw parameter.
#[inline(always)]
pub fn kappa_of(raw: f64) -> f64 {
    1.0 + raw.exp()
}

/// The raw parameter of κ (> 1).
pub fn kappa_raw_of(kappa: f64) -> Result<f64> {
    if !(kappa.is_finite() && kappa > 1.0) {
        return Err(Error::param(
            "kappa",
            format!("the quality blend κ must be a finite number > 1, got {kappa}"),
        ));
    }
    Ok((kappa - 1.0).ln())
}

impl LearnableFlame {
    /// A layer with one generator per entry of `variations`: the pre-affine map followed by
    /// that entry's variations (weight 1 each), started as the authors start (with `init`'s
    /// defaults): translations uniform in `[−1.25, 1.25]²`, linear parts `v·I` with
    /// `v ~ U(−0.75, 0.75)`, final transform the identity plus a translation in
    /// `[−0.5, 0.5]²`, κ = 2, colours' RGB logits uniform in [0, 1] and alpha logits 0.
    pub fn random(
        variations: &[Vec<VariationKind>],
        learn: Learn,
        init: &LearnableInit,
        seed: u64,
    ) -> Result<Self> {
        if variations.is_empty() {
            return Err(Error::param(
                "xforms",
                "a flame needs at least one generator",
            ));
        }
        let kappa_raw = kappa_raw_of(init.kappa)?;
        let mut rng = Xoshiro256PlusPlus::seed_from_u64(seed);
        let mut generators = Vec::with_capacity(variations.len());
        for (i, kinds) in variations.iter().enumerate() {
            if kinds.is_empty() {
                return Err(Error::param(
                    "variations",
                    format!("generator {i} has no variation"),
                ));
            }
            let mut kinds = kinds.clone();
            kinds.sort();
            kinds.dedup();
            let tx = init.translation * (2.0 * rng.random::<f64>() - 1.0);
            let ty = init.translation * (2.0 * rng.random::<f64>() - 1.0);
            let v = init.scale * (2.0 * rng.random::<f64>() - 1.0);
            let vars = kinds.iter().map(|&k| Variation::new(k, 1.0)).collect();
            let mut x = Xform::new([v, 0.0, 0.0, v, tx, ty], vars);
            x.weight = 1.0;
            generators.push(x);
        }
        let fx = init.final_translation * (2.0 * rng.random::<f64>() - 1.0);
        let fy = init.final_translation * (2.0 * rng.random::<f64>() - 1.0);
        let color_logits = (0..variations.len())
            .map(|_| {
                [
                    rng.random::<f64>(),
                    rng.random::<f64>(),
                    rng.random::<f64>(),
                    0.0,
                ]
            })
            .collect();
        let f = LearnableFlame {
            generators,
            final_coefs: [1.0, 0.0, 0.0, 1.0, fx, fy],
            kappa_raw,
            color_logits,
            learn,
        };
        f.validate()?;
        Ok(f)
    }

    /// Number of generators.
    pub fn len(&self) -> usize {
        self.generators.len()
    }

    /// Whether the layer has no generator (never, once validated).
    pub fn is_empty(&self) -> bool {
        self.generators.is_empty()
    }

    /// κ.
    pub fn kappa(&self) -> f64 {
        kappa_of(self.kappa_raw)
    }

    /// The painter's RGBA colour of generator `i`.
    pub fn color(&self, i: usize) -> [f64; 4] {
        self.color_logits[i].map(logistic)
    }

    /// θ entries of generator `g`.
    pub fn generator_params(&self, g: usize) -> usize {
        6 + if self.learn.weights {
            self.generators[g].variations.len()
        } else {
            0
        } + if self.learn.post { 6 } else { 0 }
    }

    /// Where each generator's θ starts, then the final transform, β and the colours (the
    /// layer's length last).
    pub fn layout(&self) -> LayerLayout {
        let mut generators = Vec::with_capacity(self.len());
        let mut k = 0;
        for g in 0..self.len() {
            generators.push(k);
            k += self.generator_params(g);
        }
        let final_at = k;
        LayerLayout {
            generators,
            final_at,
            kappa_at: final_at + 6,
            colors_at: final_at + 7,
            len: final_at + 7 + 4 * self.len(),
        }
    }

    /// Length of the layer's θ.
    pub fn n_params(&self) -> usize {
        self.layout().len
    }

    /// Appends the layer's θ to `out`.
    pub fn write_params(&self, out: &mut Vec<f64>) {
        for g in &self.generators {
            out.extend_from_slice(&g.coefs);
            if self.learn.weights {
                out.extend(g.variations.iter().map(|v| v.weight));
            }
            if self.learn.post {
                out.extend_from_slice(&g.post);
            }
        }
        out.extend_from_slice(&self.final_coefs);
        out.push(self.kappa_raw);
        for c in &self.color_logits {
            out.extend_from_slice(c);
        }
    }

    /// Sets the layer from its θ (`theta.len() == self.n_params()`); refuses non-finite
    /// values, naming them.
    pub fn set_params(&mut self, theta: &[f64]) -> Result<()> {
        let lay = self.layout();
        if theta.len() != lay.len {
            return Err(Error::Shape(format!(
                "{} parameters for a flame layer with {}",
                theta.len(),
                lay.len
            )));
        }
        if let Some(i) = theta.iter().position(|v| !v.is_finite()) {
            return Err(Error::NonFinite {
                what: "learnable flame".into(),
                location: format!("θ[{i}]"),
                value: theta[i],
            });
        }
        let learn = self.learn;
        for (g, x) in self.generators.iter_mut().enumerate() {
            let mut k = lay.generators[g];
            x.coefs.copy_from_slice(&theta[k..k + 6]);
            k += 6;
            if learn.weights {
                for v in &mut x.variations {
                    v.weight = theta[k];
                    k += 1;
                }
            }
            if learn.post {
                x.post.copy_from_slice(&theta[k..k + 6]);
            }
        }
        self.final_coefs
            .copy_from_slice(&theta[lay.final_at..lay.final_at + 6]);
        self.kappa_raw = theta[lay.kappa_at];
        for (i, c) in self.color_logits.iter_mut().enumerate() {
            c.copy_from_slice(&theta[lay.colors_at + 4 * i..lay.colors_at + 4 * i + 4]);
        }
        Ok(())
    }

    /// Checks the layer: generators present and deterministic, finite numbers, one colour
    /// per generator.
    pub fn validate(&self) -> Result<()> {
        if self.generators.is_empty() {
            return Err(Error::param(
                "xforms",
                "a flame needs at least one generator",
            ));
        }
        if self.generators.len() > 255 {
            return Err(Error::param(
                "xforms",
                format!("at most 255 generators per flame, got {}", self.len()),
            ));
        }
        if self.color_logits.len() != self.generators.len() {
            return Err(Error::Shape(format!(
                "{} colours for {} generators",
                self.color_logits.len(),
                self.generators.len()
            )));
        }
        for (i, g) in self.generators.iter().enumerate() {
            let what = format!("generator {i}");
            g.validate(&what)?;
            if let Some(v) = g.variations.iter().find(|v| v.kind().is_random()) {
                return Err(Error::param(
                    "variations",
                    format!(
                        "{what}: `{}` draws random numbers and has no derivative",
                        v.kind().name()
                    ),
                ));
            }
        }
        let mut theta = Vec::new();
        self.write_params(&mut theta);
        if let Some(i) = theta.iter().position(|v| !v.is_finite()) {
            return Err(Error::NonFinite {
                what: "learnable flame".into(),
                location: format!("θ[{i}]"),
                value: theta[i],
            });
        }
        Ok(())
    }
}

/// Offsets of a layer's parts in its θ.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct LayerLayout {
    /// Start of each generator's entries.
    pub generators: Vec<usize>,
    /// Start of the final transform.
    pub final_at: usize,
    /// Index of β.
    pub kappa_at: usize,
    /// Start of the colour logits.
    pub colors_at: usize,
    /// The layer's length.
    pub len: usize,
}

/// The compositor's background.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Background {
    /// A fixed colour (RGB in [0, 1]).
    Fixed([f64; 3]),
    /// Learned: RGB = logistic(logits).
    Learned([f64; 3]),
}

impl Background {
    /// The colour.
    pub fn rgb(&self) -> [f64; 3] {
        match self {
            Background::Fixed(c) => *c,
            Background::Learned(l) => l.map(logistic),
        }
    }
}

/// Several layers composited "over" a background, first layer at the bottom.
#[derive(Clone, Debug, PartialEq)]
pub struct FlameStack {
    /// The layers.
    pub layers: Vec<LearnableFlame>,
    /// The background.
    pub background: Background,
}

impl FlameStack {
    /// Where each layer's θ starts (the background's logits, when learned, follow the last).
    pub fn offsets(&self) -> Vec<usize> {
        let mut off = Vec::with_capacity(self.layers.len() + 1);
        let mut k = 0;
        off.push(0);
        for l in &self.layers {
            k += l.n_params();
            off.push(k);
        }
        off
    }

    /// Length of θ.
    pub fn n_params(&self) -> usize {
        self.offsets()[self.layers.len()]
            + match self.background {
                Background::Learned(_) => 3,
                Background::Fixed(_) => 0,
            }
    }

    /// θ.
    pub fn params(&self) -> Vec<f64> {
        let mut out = Vec::with_capacity(self.n_params());
        for l in &self.layers {
            l.write_params(&mut out);
        }
        if let Background::Learned(b) = self.background {
            out.extend_from_slice(&b);
        }
        out
    }

    /// Sets every layer and the background from θ.
    pub fn set_params(&mut self, theta: &[f64]) -> Result<()> {
        if theta.len() != self.n_params() {
            return Err(Error::Shape(format!(
                "{} parameters for a flame stack with {}",
                theta.len(),
                self.n_params()
            )));
        }
        let off = self.offsets();
        for (i, l) in self.layers.iter_mut().enumerate() {
            l.set_params(&theta[off[i]..off[i + 1]])?;
        }
        if let Background::Learned(b) = &mut self.background {
            let k = off[off.len() - 1];
            b.copy_from_slice(&theta[k..k + 3]);
        }
        Ok(())
    }

    /// Checks every layer.
    pub fn validate(&self) -> Result<()> {
        if self.layers.is_empty() {
            return Err(Error::param("flames", "a stack needs at least one flame"));
        }
        for l in &self.layers {
            l.validate()?;
        }
        if let Some(v) = self.background.rgb().iter().find(|v| !v.is_finite()) {
            return Err(Error::NonFinite {
                what: "background".into(),
                location: "rgb".into(),
                value: *v,
            });
        }
        Ok(())
    }

    /// The layers as flam3 genomes of `size × size` pixels (see [`LearnableFlame::to_flame`]).
    pub fn to_flames(&self, size: u32, name: &str) -> Vec<Flame> {
        self.layers
            .iter()
            .enumerate()
            .map(|(i, l)| {
                let mut f = l.to_flame(size, self.background.rgb());
                f.name = Some(if self.layers.len() == 1 {
                    name.to_string()
                } else {
                    format!("{name}-layer{i}")
                });
                f
            })
            .collect()
    }
}

impl LearnableFlame {
    /// The layer as a flam3 genome that draws the same points in the same place:
    ///
    /// - generators → `<xform>`s with weight 1 (the order was drawn uniformly), their
    ///   variations and post maps as learned;
    /// - the final transform followed by a y flip (the view `[−1, 1]²` has +y up, flam3's
    ///   image +y down) → a linear `<finalxform>` with colour speed 0, and the camera:
    ///   centre 0, `scale = size/2` pixels per unit;
    /// - colours: κ becomes flam3's colour speed `1 − 1/κ` — flam3's colour coordinate
    ///   `c ← s·cᵢ + (1 − s)·c` is the same exponential blend as the painter's quality vector,
    ///   but over colour *indices* looked up in a palette, where the painter mixes the
    ///   colours themselves. The two agree exactly when the palette is a straight line in
    ///   RGB through the colours, so each generator's index is its colour's position along
    ///   the colours' principal axis (rescaled to [0, 1]) and the palette is the
    ///   piecewise-linear ramp through the colours in that order: mixtures along the axis
    ///   come out right, mixtures across it are projected onto the ramp. The learned alpha
    ///   becomes the xform's opacity;
    /// - tone map: flam3's log-density with gamma 1 and the background colour; flam3's
    ///   k₁/k₂ constants and the painter's `log(1 + w)/log(1 + w_max)` are both log-density
    ///   maps, not the same one, so brightness differs (see `paper_repro/fractal_flames`).
    pub fn to_flame(&self, size: u32, background: [f64; 3]) -> Flame {
        let n = self.len();
        let colors: Vec<[f64; 4]> = (0..n).map(|i| self.color(i)).collect();
        let (index, knots) = color_ramp(&colors);
        let entries: Vec<[f64; 4]> = (0..256)
            .map(|e| {
                let c = e as f64 / 255.0;
                let rgb = ramp_at(&knots, c);
                [255.0 * rgb[0], 255.0 * rgb[1], 255.0 * rgb[2], 255.0]
            })
            .collect();
        let speed = 1.0 - 1.0 / self.kappa();
        let xforms = self
            .generators
            .iter()
            .enumerate()
            .map(|(i, g)| {
                let mut x = g.clone();
                x.weight = 1.0;
                x.color = index[i];
                x.color_speed = speed;
                x.opacity = colors[i][3];
                x
            })
            .collect();
        let c = self.final_coefs;
        // y flip after the final map: (x, y) ↦ (x, −y) negates b, d, f.
        let mut fin = Xform::new(
            [c[0], -c[1], c[2], -c[3], c[4], -c[5]],
            vec![Variation::new(VariationKind::Linear, 1.0)],
        );
        fin.post = IDENTITY;
        fin.color_speed = 0.0;
        Flame {
            size: [size, size],
            center: [0.0, 0.0],
            scale: size as f64 / 2.0,
            supersample: 2,
            filter: 0.5,
            quality: 500.0,
            gamma: 1.0,
            brightness: 4.0,
            vibrancy: 1.0,
            background,
            estimator_radius: 0.0,
            palette: Palette { colors: entries },
            xforms,
            final_xform: Some(fin),
            ..Flame::default()
        }
    }
}

/// Each colour's index in [0, 1] along the colours' principal axis, and the ramp's knots
/// `(index, rgb)` sorted by index (see [`LearnableFlame::to_flame`]).
fn color_ramp(colors: &[[f64; 4]]) -> (Vec<f64>, Vec<(f64, [f64; 3])>) {
    let n = colors.len();
    let mean: [f64; 3] =
        std::array::from_fn(|k| colors.iter().map(|c| c[k]).sum::<f64>() / n as f64);
    let mut cov = [[0.0f64; 3]; 3];
    for c in colors {
        for i in 0..3 {
            for j in 0..3 {
                cov[i][j] += (c[i] - mean[i]) * (c[j] - mean[j]);
            }
        }
    }
    // Principal axis by power iteration (the covariance is 3×3 and symmetric).
    let mut v = [0.577, 0.578, 0.576];
    for _ in 0..100 {
        let w: [f64; 3] = std::array::from_fn(|i| (0..3).map(|j| cov[i][j] * v[j]).sum());
        let norm = w.iter().map(|x| x * x).sum::<f64>().sqrt();
        if norm < 1e-300 {
            break;
        }
        v = w.map(|x| x / norm);
    }
    let proj: Vec<f64> = colors
        .iter()
        .map(|c| (0..3).map(|k| (c[k] - mean[k]) * v[k]).sum())
        .collect();
    let (lo, hi) = proj
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &p| {
            (a.min(p), b.max(p))
        });
    let index: Vec<f64> = if hi - lo > 1e-12 {
        proj.iter().map(|p| (p - lo) / (hi - lo)).collect()
    } else if n == 1 {
        vec![0.0]
    } else {
        (0..n).map(|i| i as f64 / (n - 1) as f64).collect()
    };
    let mut knots: Vec<(f64, [f64; 3])> = index
        .iter()
        .zip(colors)
        .map(|(&i, c)| (i, [c[0], c[1], c[2]]))
        .collect();
    knots.sort_by(|a, b| a.0.total_cmp(&b.0));
    (index, knots)
}

/// The piecewise-linear ramp through `knots` (sorted by index) at `x`.
fn ramp_at(knots: &[(f64, [f64; 3])], x: f64) -> [f64; 3] {
    let first = knots[0];
    let last = knots[knots.len() - 1];
    if x <= first.0 {
        return first.1;
    }
    if x >= last.0 {
        return last.1;
    }
    let k = knots.partition_point(|kn| kn.0 <= x).max(1);
    let (x0, c0) = knots[k - 1];
    let (x1, c1) = knots[k];
    let t = if x1 > x0 { (x - x0) / (x1 - x0) } else { 0.0 };
    std::array::from_fn(|ch| c0[ch] * (1.0 - t) + c1[ch] * t)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn colours_on_a_line_give_a_palette_where_index_mixtures_are_colour_mixtures() {
        // Three colours on one line in RGB: flam3's index blend equals the painter's
        // colour blend.
        let c = [
            [0.1, 0.2, 0.3, 1.0],
            [0.9, 0.6, 0.5, 1.0],
            [0.5, 0.4, 0.4, 1.0],
        ];
        let (index, knots) = color_ramp(&c);
        let w = [0.5, 0.3, 0.2];
        let mixed_index: f64 = index.iter().zip(&w).map(|(i, w)| i * w).sum();
        let via_palette = ramp_at(&knots, mixed_index);
        for ch in 0..3 {
            let direct: f64 = c.iter().zip(&w).map(|(c, w)| c[ch] * w).sum();
            assert!((via_palette[ch] - direct).abs() < 1e-12, "{via_palette:?}");
        }
    }
}
