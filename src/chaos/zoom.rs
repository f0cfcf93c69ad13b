//! Deep zoom: the words of a code whose images of the attractor meet a window.
//!
//! A zoomed render that keeps only the chaos-game points falling in its window pays for
//! every point outside it: at zoom `Z` about `1/Z²` of them land (none at all at 2²⁰). The
//! attractor's self-similarity gives the points of the window directly. For any complete set
//! of words `W` (every infinite map sequence has exactly one prefix in `W`) the invariant
//! measure is `μ = Σ_{w∈W} p_w · (f_w)_# μ`, with `f_w = f_{w₁} ∘ … ∘ f_{wₖ}` and `p_w` the
//! product of the words' map probabilities. [`WindowWords`] builds such a set by walking the
//! word tree from the empty word: a word whose image of a disk holding the attractor misses
//! the window is dropped (its part of `μ` lies outside), a word whose image is no larger than
//! the window (or lies inside it) is kept, any other word is replaced by its children. A
//! point `x` of the ordinary chaos game (`x ~ μ`) sent through a kept word drawn with
//! probability ∝ `p_w` is then distributed as `μ` on the window, up to a constant: the same
//! picture the plain game gives, from about as many points as the full view needs.
//!
//! **The bounding disk.** With `c` the mean of the maps' fixed points and `sᵢ = σ_max(Mᵢ) <
//! 1`, the disk `B(c, R)`, `R = maxᵢ |fᵢ(c) − c| / (1 − sᵢ)`, is mapped into itself by every
//! map (`|fᵢ(x) − c| ≤ sᵢR + |fᵢ(c) − c| ≤ R`), so it holds the attractor, and `f_w(B)` lies
//! in the disk of centre `f_w(c)` and radius `σ_max(M_w)·R`.
//!
//! **Which word.** [`WindowWords::map`] draws the word from the point itself: a 64-bit hash
//! of its coordinates' bits picks from an alias table. The point is a function of the run's
//! seed and its place in its trajectory, so the word is too, and a render stays the same
//! whatever the number of threads (the hash is independent of where the point lies, for the
//! purpose of the draw, as a fresh random number would be).
//!
//! **How deep.** Words are composed in f64, so a window keeps its meaning while its side is
//! well above the rounding of the composed maps' offsets, about `1e-16 · R · depth`: windows
//! down to ~10⁻¹³ of the attractor's size (zoom ~2⁴³). Probabilities are kept as logarithms,
//! so deep words' weights do not underflow. Codes whose maps overlap heavily keep more words
//! per window; the walk stops with an error past [`WindowWords::new`]'s `max_words`.

use crate::chaos::sampler::MapSampler;
use crate::chaos::stream::PointSink;
use crate::error::{Error, Result};
use crate::model::affine::Affine2;
use crate::model::code::Window;
use crate::model::probs::validate_probabilities;

/// The words of a code that cover a window (see the module docs).
#[derive(Clone, Debug)]
pub struct WindowWords {
    words: Vec<Affine2>,
    sampler: MapSampler,
    /// Σ p_w of the kept words: the part of μ in their images, an upper bound of μ(window).
    mass: f64,
    depth: usize,
}

/// A word being walked: its map, log-probability, length.
struct Node {
    map: Affine2,
    log_p: f64,
    depth: usize,
}

impl WindowWords {
    /// The words of `maps` (drawn with `probs`) whose images of the attractor meet `window`,
    /// each no larger than `refine` times the window's longer side (0.5 is a good choice:
    /// a kept word's image is about half the window, so most of its points land inside).
    /// `None` when the window misses the attractor (an empty view, not an error). An error
    /// if the code is not contractive or `window` is empty or not finite, and
    /// [`Error::TooManyWords`] if more than `max_words` words would be kept (or eight times
    /// as many looked at).
    pub fn new(
        maps: &[Affine2],
        probs: &[f64],
        window: &Window,
        refine: f64,
        max_words: usize,
    ) -> Result<Option<Self>> {
        if maps.is_empty() {
            return Err(Error::Empty("the code has no maps".into()));
        }
        validate_probabilities(probs, maps.len())?;
        let [w, h] = window.size();
        let finite = window.min.iter().chain(&window.max).all(|v| v.is_finite());
        if !(finite && w > 0.0 && h > 0.0) {
            return Err(Error::param(
                "window",
                format!(
                    "a zoom window needs a finite, positive size, got {:?} to {:?}",
                    window.min, window.max
                ),
            ));
        }
        if !(refine.is_finite() && refine > 0.0) {
            return Err(Error::param(
                "refine",
                format!("must be finite and > 0, got {refine}"),
            ));
        }
        let (centre, radius) = bounding_disk(maps)?;
        let stop = refine * w.max(h);
        let log_p: Vec<f64> = probs.iter().map(|p| p.ln()).collect();
        let mut kept: Vec<(Affine2, f64)> = Vec::new();
        let mut depth = 0;
        let mut stack = vec![Node {
            map: Affine2::new(1.0, 0.0, 0.0, 1.0, 0.0, 0.0),
            log_p: 0.0,
            depth: 0,
        }];
        // Words looked at: a code whose maps overlap heavily can have many large words that
        // meet the window; the walk stops at as many as the words it may keep, times 8.
        let mut visited = 0usize;
        while let Some(node) = stack.pop() {
            visited += 1;
            if visited > max_words.saturating_mul(8) {
                return Err(Error::TooManyWords { max_words });
            }
            let c = apply(&node.map, centre);
            let r = node.map.sigma_max() * radius;
            let (near, inside) = disk_and_window(c, r, window);
            if !near || node.log_p == f64::NEG_INFINITY {
                continue;
            }
            if r <= stop || inside {
                if kept.len() == max_words {
                    return Err(Error::TooManyWords { max_words });
                }
                depth = depth.max(node.depth);
                kept.push((node.map, node.log_p));
                continue;
            }
            // Children in reverse, so the walk (and the kept words' order) is by map index.
            for (i, m) in maps.iter().enumerate().rev() {
                stack.push(Node {
                    map: node.map.compose(m),
                    log_p: node.log_p + log_p[i],
                    depth: node.depth + 1,
                });
            }
        }
        if kept.is_empty() {
            return Ok(None);
        }
        let top = kept.iter().map(|k| k.1).fold(f64::NEG_INFINITY, f64::max);
        let rel: Vec<f64> = kept.iter().map(|k| (k.1 - top).exp()).collect();
        let total: f64 = rel.iter().sum();
        let weights: Vec<f64> = rel.iter().map(|v| v / total).collect();
        Ok(Some(WindowWords {
            words: kept.into_iter().map(|k| k.0).collect(),
            sampler: MapSampler::new(&weights)?,
            mass: (top + total.ln()).exp(),
            depth,
        }))
    }

    /// The kept words' maps, in the walk's order (by map index, depth first).
    pub fn words(&self) -> &[Affine2] {
        &self.words
    }

    /// How many words were kept.
    pub fn len(&self) -> usize {
        self.words.len()
    }

    /// Whether no word was kept (never: [`WindowWords::new`] gives `None` for a window that
    /// misses).
    pub fn is_empty(&self) -> bool {
        self.words.is_empty()
    }

    /// The longest kept word.
    pub fn depth(&self) -> usize {
        self.depth
    }

    /// Σ p_w over the kept words: the share of the chaos game's points the plain render would
    /// spend on their images (≥ the share that lands in the window).
    pub fn mass(&self) -> f64 {
        self.mass
    }

    /// `p` sent through the word its coordinates pick (see the module docs).
    #[inline]
    pub fn map(&self, p: [f64; 2]) -> [f64; 2] {
        let h = hash(p[0].to_bits() ^ hash(p[1].to_bits()));
        apply(&self.words[self.sampler.pick(h)], p)
    }
}

/// A [`PointSink`] that sends each point through a word of [`WindowWords`] before `inner`.
pub struct WordSink<'a, S> {
    words: &'a WindowWords,
    inner: S,
}

impl<'a, S> WordSink<'a, S> {
    /// `inner` fed the points of the words' window.
    pub fn new(words: &'a WindowWords, inner: S) -> Self {
        WordSink { words, inner }
    }

    /// The inner sink back.
    pub fn into_inner(self) -> S {
        self.inner
    }
}

impl<S: PointSink> PointSink for WordSink<'_, S> {
    #[inline(always)]
    fn put(&mut self, p: [f64; 2]) {
        self.inner.put(self.words.map(p))
    }
}

/// A disk every map sends into itself (see the module docs).
fn bounding_disk(maps: &[Affine2]) -> Result<([f64; 2], f64)> {
    let mut c = [0.0, 0.0];
    for (i, m) in maps.iter().enumerate() {
        let s = m.sigma_max();
        if !(m.is_finite() && s < 1.0) {
            return Err(Error::param(
                "maps",
                format!("map {i} is not contractive (σ_max {s}): a zoom needs a contractive code"),
            ));
        }
        let f = m.fixed_point().ok_or_else(|| {
            Error::param(
                "maps",
                format!("map {i} has no fixed point: not contractive"),
            )
        })?;
        c[0] += f[0] / maps.len() as f64;
        c[1] += f[1] / maps.len() as f64;
    }
    let r = maps
        .iter()
        .map(|m| {
            let d = apply(m, c);
            (d[0] - c[0]).hypot(d[1] - c[1]) / (1.0 - m.sigma_max())
        })
        .fold(0.0, f64::max);
    // A little slack for rounding, so points on the attractor's rim stay inside.
    Ok((c, r * (1.0 + 1e-9) + 1e-300))
}

/// Whether the disk meets the window, and whether it lies inside it.
fn disk_and_window(c: [f64; 2], r: f64, w: &Window) -> (bool, bool) {
    let dx = (w.min[0] - c[0]).max(c[0] - w.max[0]).max(0.0);
    let dy = (w.min[1] - c[1]).max(c[1] - w.max[1]).max(0.0);
    let near = dx * dx + dy * dy <= r * r;
    let inside = c[0] - r >= w.min[0]
        && c[0] + r <= w.max[0]
        && c[1] - r >= w.min[1]
        && c[1] + r <= w.max[1];
    (near, inside)
}

#[inline(always)]
fn apply(m: &Affine2, p: [f64; 2]) -> [f64; 2] {
    [
        m.m[(0, 0)] * p[0] + m.m[(0, 1)] * p[1] + m.b[0],
        m.m[(1, 0)] * p[0] + m.m[(1, 1)] * p[1] + m.b[1],
    ]
}

/// splitmix64's finaliser.
#[inline(always)]
fn hash(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::chaos::PointStream;
    use crate::model::library::builtin;
    use crate::model::map::Map;

    fn sierpinski() -> (Vec<Affine2>, Vec<f64>) {
        let maps = builtin("sierpinski").unwrap().affine2().unwrap();
        let n = maps.len();
        (maps, vec![1.0 / n as f64; n])
    }

    /// Points of the plain chaos game (`n` trajectories of `len` kept points).
    fn points(maps: &[Affine2], probs: &[f64], n: u64, len: u64) -> Vec<[f64; 2]> {
        let sampler = MapSampler::new(probs).unwrap();
        let stream = PointStream::new(maps, &sampler, 7, 1.0, 30).unwrap();
        let mut out = Vec::new();
        stream
            .run(0, &vec![len; n as usize], &mut |p: [f64; 2]| out.push(p))
            .unwrap();
        out
    }

    /// A point of the attractor: a long word applied to a point near it.
    fn on_attractor(maps: &[Affine2]) -> [f64; 2] {
        let mut c = [0.0, 0.0];
        for i in 0..60 {
            c = maps[(i * 7 + 3) % maps.len()].apply(c);
        }
        c
    }

    fn square(c: [f64; 2], half: f64) -> Window {
        Window {
            min: [c[0] - half, c[1] - half],
            max: [c[0] + half, c[1] + half],
        }
    }

    fn inside(p: [f64; 2], w: &Window) -> bool {
        p[0] >= w.min[0] && p[0] <= w.max[0] && p[1] >= w.min[1] && p[1] <= w.max[1]
    }

    #[test]
    fn a_window_around_the_whole_attractor_keeps_the_empty_word() {
        let (maps, probs) = sierpinski();
        let ww = WindowWords::new(&maps, &probs, &square([0.5, 0.5], 10.0), 0.5, 100)
            .unwrap()
            .unwrap();
        assert_eq!((ww.len(), ww.depth()), (1, 0));
        assert!((ww.mass() - 1.0).abs() < 1e-12);
        assert_eq!(ww.map([0.3, 0.2]), [0.3, 0.2]);
    }

    #[test]
    fn a_zoom_of_two_to_the_twenty_fills_its_window() {
        let (maps, probs) = sierpinski();
        let c = on_attractor(&maps);
        let span = 1.0 / f64::powi(2.0, 20);
        let win = square(c, span / 2.0);
        let ww = WindowWords::new(&maps, &probs, &win, 0.5, 10_000)
            .unwrap()
            .unwrap();
        assert!(ww.len() <= 64, "{} words", ww.len());
        assert!(ww.depth() >= 19, "depth {}", ww.depth());
        let pts = points(&maps, &probs, 64, 1000);
        let plain = pts.iter().filter(|&&p| inside(p, &win)).count();
        let zoomed = pts.iter().filter(|&&p| inside(ww.map(p), &win)).count();
        // The plain game puts about one point in 10¹² there; the words put a good share.
        assert_eq!(plain, 0);
        assert!(
            zoomed * 10 >= pts.len(),
            "{zoomed} of {} in the window",
            pts.len()
        );
    }

    #[test]
    fn the_zoomed_points_have_the_plain_games_density() {
        // A fern-like code with unequal probabilities and a window at 8× zoom.
        let code = builtin("fern").unwrap();
        let maps = code.affine2().unwrap();
        let probs = code
            .probabilities
            .clone()
            .unwrap_or_else(|| vec![1.0 / maps.len() as f64; maps.len()]);
        let pts = points(&maps, &probs, 256, 4000);
        let (lo, hi) = crate::chaos::bbox(&pts);
        let c = [(lo[0] + hi[0]) / 2.0, lo[1] + 0.55 * (hi[1] - lo[1])];
        let win = square(c, (hi[1] - lo[1]) / 16.0);
        let ww = WindowWords::new(&maps, &probs, &win, 0.5, 10_000)
            .unwrap()
            .unwrap();
        const G: usize = 8;
        let hist = |it: &mut dyn Iterator<Item = [f64; 2]>| {
            let mut h = vec![0.0f64; G * G];
            let mut n = 0.0;
            for p in it {
                if inside(p, &win) {
                    let gx =
                        (((p[0] - win.min[0]) / (win.max[0] - win.min[0])) * G as f64) as usize;
                    let gy =
                        (((p[1] - win.min[1]) / (win.max[1] - win.min[1])) * G as f64) as usize;
                    h[gy.min(G - 1) * G + gx.min(G - 1)] += 1.0;
                    n += 1.0;
                }
            }
            (h.into_iter().map(|v| v / n).collect::<Vec<_>>(), n)
        };
        let (plain, n_plain) = hist(&mut pts.iter().copied());
        let (zoomed, n_zoomed) = hist(&mut pts.iter().map(|&p| ww.map(p)));
        assert!(
            n_plain > 5_000.0 && n_zoomed > 5.0 * n_plain,
            "{n_plain} {n_zoomed}"
        );
        let tv: f64 = plain
            .iter()
            .zip(&zoomed)
            .map(|(a, b)| (a - b).abs())
            .sum::<f64>()
            / 2.0;
        assert!(tv < 0.05, "total variation {tv}");
    }

    #[test]
    fn bad_windows_and_codes_are_refused_with_the_reason() {
        let (maps, probs) = sierpinski();
        let far = square([50.0, 50.0], 1.0);
        assert!(
            WindowWords::new(&maps, &probs, &far, 0.5, 100)
                .unwrap()
                .is_none()
        );
        let nan = Window {
            min: [0.0, f64::NAN],
            max: [1.0, 1.0],
        };
        assert!(WindowWords::new(&maps, &probs, &nan, 0.5, 100).is_err());
        let deep = square(on_attractor(&maps), 1e-9);
        let e = WindowWords::new(&maps, &probs, &deep, 1e-6, 50).unwrap_err();
        assert!(e.to_string().contains("more than 50 words"), "{e}");
        assert!(matches!(e, Error::TooManyWords { max_words: 50 }));
        let mut big = maps.clone();
        big[0].m *= 2.5;
        let e = WindowWords::new(&big, &probs, &square([0.5, 0.5], 1.0), 0.5, 100).unwrap_err();
        assert!(e.to_string().contains("not contractive"), "{e}");
    }
}
