//! Random flames in flam3-genome's style, flames from affine codes, and flam3's attractor
//! bounding box.
//!
//! [`random_flame`] follows flam3 3.1.1's `flam3_random` with its probabilities: 2–6
//! transforms (2 to 6 with weights 4, 4, 3, 2, 1), a final transform 15 % of the time,
//! pre-affine coefficients uniform in [−1, 1], an identity post map 60 % of the time (else
//! one random post map shared by every transform or one per transform), either one
//! variation for all transforms, one random variation per transform, the same random mix
//! for all, or a random mix per transform (at least two draws, one more with probability
//! ½ each, weights normalised to 1), flam3's ranges for the parameters of parametric
//! variations, a symmetry 25 % of the time when there is no final transform, and a random
//! palette of flam3's library (hue-rotated 1/8 of the time). Then, like flam3-genome, at
//! most five variations are kept per transform (the largest) and the camera is centred on
//! the attractor's box with pixels per unit = width / box width. flam3-genome's colour
//! improvement (`improve_colors`) is not done. The draws come from our own seeded
//! generator, so the same seed gives the same genome here, not the one flam3 makes.
//!
//! [`estimate_bounds`] is `flam3_estimate_bounding_box`: the box holding all but a
//! fraction `eps` of a chaos-game orbit on each side.
//!
//! ## References
//! - flam3 3.1.1 (`flam3.c`: `flam3_random`, `flam3_add_symmetry`,
//!   `flam3_estimate_bounding_box`; `flam3-genome.c`).

use rand::{Rng, RngCore, SeedableRng};
use rand_xoshiro::Xoshiro256PlusPlus;

use crate::error::{Error, Result};
use crate::model::Affine2;
use crate::model::flame::format::symmetry_xforms;
use crate::model::flame::genome::Flame;
use crate::model::flame::palette::Palette;
use crate::model::flame::variation::{Variation, VariationKind};
use crate::model::flame::variations::{rand01, rand11};
use crate::model::flame::xform::{IDENTITY, Xform, coefs_of};

/// What [`random_flame`] may choose from.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct RandomFlameConfig {
    /// Variations to draw from (flam3-genome's `use_vars`); all 99 when empty.
    pub variations: Vec<VariationKind>,
    /// Number of transforms; flam3's random 2–6 (and maybe a final transform) when `None`.
    pub xforms: Option<usize>,
    /// Image size.
    pub size: [u32; 2],
    /// Samples per pixel.
    pub quality: f64,
}

/// flam3's `xform_distrib`.
const XFORM_DISTRIB: [usize; 14] = [2, 2, 2, 2, 3, 3, 3, 3, 4, 4, 4, 5, 5, 6];
/// flam3's `sym_distrib`.
const SYM_DISTRIB: [i32; 15] = [-4, -3, -2, -2, -2, -1, -1, -1, 2, 2, 2, 3, 3, 4, 4];

fn bit<R: RngCore>(rng: &mut R) -> bool {
    rng.next_u32() & 1 == 1
}

fn pick<R: RngCore, T: Copy>(rng: &mut R, from: &[T]) -> T {
    from[rng.random_range(0..from.len())]
}

/// A random flame in flam3-genome's style (see the module docs).
pub fn random_flame(seed: u64, cfg: &RandomFlameConfig) -> Result<Flame> {
    if cfg.xforms == Some(0) {
        return Err(Error::param(
            "xforms",
            "a flame needs at least one transform",
        ));
    }
    if cfg.size[0] == 0 || cfg.size[1] == 0 {
        return Err(Error::param("size", "the image needs at least 1×1 pixels"));
    }
    if !(cfg.quality.is_finite() && cfg.quality > 0.0) {
        return Err(Error::param(
            "quality",
            format!("must be > 0, got {}", cfg.quality),
        ));
    }
    let mut rng = Xoshiro256PlusPlus::seed_from_u64(seed);
    let all: Vec<VariationKind> = VariationKind::ALL.to_vec();
    let specified = !cfg.variations.is_empty();
    let pool: &[VariationKind] = if specified { &cfg.variations } else { &all };

    let hue = if rng.next_u32() & 7 != 0 {
        0.0
    } else {
        rand01(&mut rng)
    };
    let palette = random_palette(&mut rng, hue);

    let (nxforms, has_final) = match cfg.xforms {
        Some(k) => (k, false),
        None => (pick(&mut rng, &XFORM_DISTRIB), rand01(&mut rng) < 0.15),
    };
    // One variation for every transform, or mixes.
    let single = if !specified && bit(&mut rng) {
        Some(pick(&mut rng, &all))
    } else {
        None
    };
    let same_mix = bit(&mut rng);
    let one_each = bit(&mut rng);
    let post_identity = rand01(&mut rng) < 0.6;
    let same_post = bit(&mut rng);

    let total = nxforms + has_final as usize;
    let mut xforms: Vec<Xform> = Vec::with_capacity(total);
    let mut first_post = IDENTITY;
    for i in 0..total {
        let is_final = has_final && i == nxforms;
        let mut x = Xform {
            weight: 1.0 / total as f64,
            color: (i & 1) as f64,
            color_speed: 0.5,
            ..Xform::default()
        };
        for c in x.coefs.iter_mut() {
            *c = rand11(&mut rng);
        }
        let mut weights = vec![0.0; VariationKind::ALL.len()];
        let mut copied = false;
        if is_final {
            let n = 1 + bit(&mut rng) as usize;
            for _ in 0..n {
                weights[pick(&mut rng, pool).index()] = rand01(&mut rng);
            }
            normalise(&mut weights, &mut rng, pool);
        } else {
            if !post_identity {
                if same_post || i == 0 {
                    for c in x.post.iter_mut() {
                        *c = rand11(&mut rng);
                    }
                    if i == 0 {
                        first_post = x.post;
                    }
                } else {
                    x.post = first_post;
                }
            }
            if let Some(v) = single {
                weights[v.index()] = 1.0;
            } else if one_each && !specified {
                weights[pick(&mut rng, &all).index()] = 1.0;
            } else if same_mix && i > 0 {
                x.variations = xforms[i - 1].variations.clone();
                copied = true;
            } else {
                let mut n = 2;
                while bit(&mut rng) && n < pool.len().max(2) {
                    n += 1;
                }
                for _ in 0..n {
                    weights[pick(&mut rng, pool).index()] = rand01(&mut rng);
                }
                normalise(&mut weights, &mut rng, pool);
            }
        }
        if !copied {
            x.variations = weights
                .iter()
                .enumerate()
                .filter(|(_, w)| **w > 0.0)
                .map(|(k, &w)| {
                    let kind = VariationKind::from_index(k).expect("index of ALL");
                    let mut v = Variation::new(kind, w);
                    random_params(&mut v, &mut rng);
                    v
                })
                .collect();
        }
        truncate_variations(&mut x, 5);
        x.sort_variations();
        xforms.push(x);
    }
    let final_xform = if has_final {
        let mut f = xforms.pop().expect("final pushed last");
        f.weight = 0.0;
        Some(f)
    } else {
        None
    };
    let mut symmetry = None;
    if !has_final && rng.next_u32() % 4 == 0 {
        let kind = if bit(&mut rng) {
            pick(&mut rng, &SYM_DISTRIB)
        } else if rng.next_u32() & 31 != 0 {
            rng.random_range(-6..=6)
        } else {
            rng.random_range(-25..=25)
        };
        let extra = symmetry_xforms(kind);
        if !extra.is_empty() {
            xforms.extend(extra);
            symmetry = Some(kind);
        }
    }
    let mut flame = Flame {
        name: Some(format!("random-{seed}")),
        size: cfg.size,
        quality: cfg.quality,
        palette,
        xforms,
        final_xform,
        symmetry,
        ..Flame::default()
    };
    frame(&mut flame, seed)?;
    Ok(flame)
}

/// Weights divided by their sum; one random variation with weight 1 when all are 0.
fn normalise<R: RngCore>(w: &mut [f64], rng: &mut R, pool: &[VariationKind]) {
    let sum: f64 = w.iter().sum();
    if sum == 0.0 {
        w[pick(rng, pool).index()] = 1.0;
    } else {
        w.iter_mut().for_each(|v| *v /= sum);
    }
}

/// flam3-genome's `truncate_variations`: keep the `max` largest weights.
fn truncate_variations(x: &mut Xform, max: usize) {
    if x.variations.len() > max {
        x.variations
            .sort_by(|a, b| b.weight.total_cmp(&a.weight).then(a.kind().cmp(&b.kind())));
        x.variations.truncate(max);
    }
}

/// flam3's random parameters for the parametric variations (`flam3_random`'s ranges);
/// other variations keep flam3's defaults.
fn random_params<R: RngCore>(v: &mut Variation, rng: &mut R) {
    use VariationKind as K;
    let mut u = || rand01(rng);
    let pi = std::f64::consts::PI;
    let set = |v: &mut Variation, name: &str, value: f64| {
        v.set_param(name, value).expect("flam3 parameter name");
    };
    match v.kind() {
        K::Blob => {
            set(v, "blob_low", 0.2 + 0.5 * u());
            set(v, "blob_high", 0.8 + 0.4 * u());
            set(v, "blob_waves", (2.0 + 5.0 * u()).trunc());
        }
        K::Pdj => {
            for p in ["pdj_a", "pdj_b", "pdj_c", "pdj_d"] {
                set(v, p, 3.0 * (2.0 * u() - 1.0));
            }
        }
        K::Fan2 => {
            set(v, "fan2_x", 2.0 * u() - 1.0);
            set(v, "fan2_y", 2.0 * u() - 1.0);
        }
        K::Rings2 => set(v, "rings2_val", 2.0 * u()),
        K::Perspective => {
            set(v, "perspective_angle", u());
            set(v, "perspective_dist", 2.0 * u() + 1.0);
        }
        K::Julian | K::Juliascope => {
            let n = v.kind().name();
            set(v, &format!("{n}_power"), (5.0 * u() + 2.0).trunc());
            set(v, &format!("{n}_dist"), 1.0);
        }
        K::RadialBlur => set(v, "radial_blur_angle", 2.0 * u() - 1.0),
        K::Pie => {
            set(v, "pie_slices", (10.0 * u()).trunc());
            set(v, "pie_thickness", u());
            set(v, "pie_rotation", 2.0 * pi * (2.0 * u() - 1.0));
        }
        K::Ngon => {
            // flam3 writes `(int) flam3_random01() * 10 + 3`: the cast binds first, so 3.
            let _ = u();
            set(v, "ngon_sides", 3.0);
            set(v, "ngon_power", 3.0 * u() + 1.0);
            let circle = 3.0 * u();
            set(v, "ngon_circle", circle);
            set(v, "ngon_corners", 2.0 * u() * circle);
        }
        K::Curl => {
            set(v, "curl_c1", u());
            set(v, "curl_c2", u());
        }
        K::Rectangles => {
            set(v, "rectangles_x", u());
            set(v, "rectangles_y", u());
        }
        K::Disc2 => {
            set(v, "disc2_rot", 0.5 * u());
            set(v, "disc2_twist", 0.5 * u());
        }
        K::SuperShape => {
            set(v, "super_shape_rnd", u());
            // `(int) flam3_random01() * 6`: 0, as in flam3.
            let _ = u();
            set(v, "super_shape_m", 0.0);
            set(v, "super_shape_n1", 40.0 * u());
            let n2 = 20.0 * u();
            set(v, "super_shape_n2", n2);
            set(v, "super_shape_n3", n2);
            set(v, "super_shape_holes", 0.0);
        }
        K::Flower => {
            set(v, "flower_petals", 4.0 * u());
            set(v, "flower_holes", u());
        }
        K::Conic => {
            set(v, "conic_eccentricity", u());
            set(v, "conic_holes", u());
        }
        K::Parabola => {
            set(v, "parabola_height", 0.5 + u());
            set(v, "parabola_width", 0.5 + u());
        }
        K::Bent2 => {
            set(v, "bent2_x", 3.0 * (u() - 0.5));
            set(v, "bent2_y", 3.0 * (u() - 0.5));
        }
        K::Bipolar => set(v, "bipolar_shift", 2.0 * u() - 1.0),
        K::Cell => set(v, "cell_size", 2.0 * u() + 0.5),
        K::Cpow => {
            set(v, "cpow_r", 3.0 * u());
            set(v, "cpow_i", u() - 0.5);
            set(v, "cpow_power", (5.0 * u()).trunc());
        }
        K::Curve => {
            set(v, "curve_xamp", 5.0 * (u() - 0.5));
            set(v, "curve_yamp", 4.0 * (u() - 0.5));
            set(v, "curve_xlength", 2.0 * (u() + 0.5));
            set(v, "curve_ylength", 2.0 * (u() + 0.5));
        }
        K::Escher => set(v, "escher_beta", pi * (2.0 * u() - 1.0)),
        K::Lazysusan => {
            set(v, "lazysusan_x", 2.0 * (2.0 * u() - 1.0));
            set(v, "lazysusan_y", 2.0 * (2.0 * u() - 1.0));
            set(v, "lazysusan_spin", pi * (2.0 * u() - 1.0));
            set(v, "lazysusan_space", 2.0 * (2.0 * u() - 1.0));
            set(v, "lazysusan_twist", 2.0 * (2.0 * u() - 1.0));
        }
        K::Modulus => {
            set(v, "modulus_x", 2.0 * u() - 1.0);
            set(v, "modulus_y", 2.0 * u() - 1.0);
        }
        K::Oscilloscope => {
            set(v, "oscilloscope_separation", 1.0 + (2.0 * u() - 1.0));
            set(v, "oscilloscope_frequency", pi * (2.0 * u() - 1.0));
            set(v, "oscilloscope_amplitude", 1.0 + 2.0 * u());
            set(v, "oscilloscope_damping", u());
        }
        K::Popcorn2 => {
            set(v, "popcorn2_x", 0.2 * u());
            set(v, "popcorn2_y", 0.2 * u());
            set(v, "popcorn2_c", 5.0 * u());
        }
        K::Separation => {
            set(v, "separation_x", 1.0 + (2.0 * u() - 1.0));
            set(v, "separation_y", 1.0 + (2.0 * u() - 1.0));
            set(v, "separation_xinside", 2.0 * u() - 1.0);
            set(v, "separation_yinside", 2.0 * u() - 1.0);
        }
        K::Split => {
            set(v, "split_xsize", 2.0 * u() - 1.0);
            set(v, "split_ysize", 2.0 * u() - 1.0);
        }
        K::Splits => {
            set(v, "splits_x", 2.0 * u() - 1.0);
            set(v, "splits_y", 2.0 * u() - 1.0);
        }
        K::Stripes => {
            set(v, "stripes_space", u());
            set(v, "stripes_warp", 5.0 * u());
        }
        K::Wedge | K::WedgeSph => {
            let n = v.kind().name();
            set(v, &format!("{n}_angle"), pi * u());
            set(v, &format!("{n}_hole"), 0.5 * (2.0 * u() - 1.0));
            set(v, &format!("{n}_count"), (5.0 * u()).floor() + 1.0);
            set(v, &format!("{n}_swirl"), u());
        }
        K::WedgeJulia => {
            set(v, "wedge_julia_power", (5.0 * u() + 2.0).trunc());
            set(v, "wedge_julia_dist", 1.0);
            set(v, "wedge_julia_count", (3.0 * u() + 1.0).trunc());
            set(v, "wedge_julia_angle", pi * u());
        }
        K::Whorl => {
            set(v, "whorl_inside", u());
            set(v, "whorl_outside", u());
        }
        K::Waves2 => {
            set(v, "waves2_scalex", 0.5 + u());
            set(v, "waves2_scaley", 0.5 + u());
            set(v, "waves2_freqx", 4.0 * u());
            set(v, "waves2_freqy", 4.0 * u());
        }
        K::Auger => {
            set(v, "auger_sym", 0.0);
            set(v, "auger_weight", 0.5 + u() / 2.0);
            set(v, "auger_freq", (5.0 * u()).floor() + 1.0);
            set(v, "auger_scale", u());
        }
        K::Flux => set(v, "flux_spread", 0.5 + u() / 2.0),
        K::Mobius => {
            for p in [
                "re_a", "im_a", "re_b", "im_b", "re_c", "im_c", "re_d", "im_d",
            ] {
                set(v, &format!("mobius_{p}"), 2.0 * u() - 1.0);
            }
        }
        _ => {}
    }
}

/// A palette of flam3's library chosen at random (`flam3_palette_random`), or, where the
/// library is not installed, a random smooth ramp through four random HSV colours.
fn random_palette<R: RngCore>(rng: &mut R, hue: f64) -> Palette {
    if let Ok(path) = crate::model::flame::palette::palette_library_path()
        && let Ok(lib) = crate::model::flame::palette::PaletteLibrary::load(&path)
        && !lib.palettes.is_empty()
    {
        let k = rng.random_range(0..lib.palettes.len());
        let number = lib.palettes[k].0;
        if let Some(p) = lib.get(number, hue) {
            return p;
        }
    }
    let keys: Vec<[f64; 3]> = (0..4)
        .map(|_| {
            crate::model::flame::palette::hsv_to_rgb([
                6.0 * rand01(rng),
                0.5 + 0.5 * rand01(rng),
                0.4 + 0.6 * rand01(rng),
            ])
        })
        .collect();
    Palette {
        colors: (0..Palette::LEN)
            .map(|i| {
                let t = i as f64 / 255.0 * 3.0;
                let k = (t as usize).min(2);
                let f = t - k as f64;
                let c: [f64; 3] =
                    std::array::from_fn(|j| 255.0 * (keys[k][j] * (1.0 - f) + keys[k + 1][j] * f));
                [c[0], c[1], c[2], 255.0]
            })
            .collect(),
    }
}

/// Where a flame's orbit lies: the box holding all but a fraction `eps` of it on each side.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Bounds {
    /// Smallest x and y.
    pub min: [f64; 2],
    /// Largest x and y.
    pub max: [f64; 2],
    /// Steps that produced a bad value (NaN or beyond ±10¹⁰) and restarted.
    pub badvals: usize,
    /// Steps iterated.
    pub samples: usize,
}

/// flam3's `flam3_estimate_bounding_box`: `samples` points of one orbit (after 20
/// unplotted steps, final transform applied), and the box that leaves out a fraction
/// `eps` of them on each side (3 × the bad-value fraction when that is larger, at most
/// 0.3).
pub fn estimate_bounds(flame: &Flame, eps: f64, samples: usize, seed: u64) -> Result<Bounds> {
    if flame.xforms.is_empty() {
        return Err(Error::Empty(format!("{} has no transform", flame.label())));
    }
    let mut rng = Xoshiro256PlusPlus::seed_from_u64(seed);
    let samples = if samples == 0 { 10_000 } else { samples };
    let prepared: Vec<_> = flame.xforms.iter().map(|x| x.prepare()).collect();
    let fin = flame.final_xform.as_ref().map(|x| x.prepare());
    let weights: Vec<f64> = flame.xforms.iter().map(|x| x.weight).collect();
    let rows: Vec<Vec<f64>> = (0..=flame.xforms.len())
        .map(|r| {
            let mut c = 0.0;
            weights
                .iter()
                .enumerate()
                .map(|(j, &w)| {
                    let x = if r == 0 {
                        1.0
                    } else {
                        flame.xforms[r - 1].chaos.get(j).copied().unwrap_or(1.0)
                    };
                    c += w * x;
                    c
                })
                .collect()
        })
        .collect();
    if rows
        .iter()
        .any(|r| r.last().is_none_or(|&t| t.is_nan() || t <= 0.0))
    {
        return Err(Error::param(
            "weight",
            format!(
                "{}: no transform can be chosen (weights or xaos all 0)",
                flame.label()
            ),
        ));
    }
    let mut p = [rand11(&mut rng), rand11(&mut rng)];
    let mut pts = Vec::with_capacity(samples);
    let mut bad = 0usize;
    let mut row = 0usize;
    let mut i = 0usize;
    while pts.len() < samples {
        let cum = &rows[row];
        let r = rand01(&mut rng) * cum[cum.len() - 1];
        let k = cum.partition_point(|&c| c <= r).min(cum.len() - 1);
        let out = prepared[k].apply(p, &mut rng);
        if flame.xforms.iter().any(|x| !x.chaos.is_empty()) {
            row = k + 1;
        }
        if out.bad {
            bad += 1;
            p = [rand11(&mut rng), rand11(&mut rng)];
        } else {
            p = out.point;
        }
        i += 1;
        if i > 20 {
            let q = match &fin {
                Some(f) => {
                    let o = f.apply(p, &mut rng);
                    if o.bad { p } else { o.point }
                }
                None => p,
            };
            pts.push(q);
        }
    }
    let n = pts.len();
    let mut e = eps;
    if bad as f64 / n as f64 > e {
        e = 3.0 * bad as f64 / n as f64;
    }
    let e = e.min(0.3);
    let lo = (n as f64 * e) as usize;
    let hi = n - lo;
    let mut b = Bounds {
        min: [f64::INFINITY; 2],
        max: [f64::NEG_INFINITY; 2],
        badvals: bad,
        samples: i,
    };
    for d in 0..2 {
        if lo == 0 {
            for q in &pts {
                b.min[d] = b.min[d].min(q[d]);
                b.max[d] = b.max[d].max(q[d]);
            }
        } else {
            let mut v: Vec<f64> = pts.iter().map(|q| q[d]).collect();
            v.sort_by(f64::total_cmp);
            b.min[d] = v[lo];
            b.max[d] = v[hi.min(n - 1)];
        }
    }
    Ok(b)
}

/// Centres the camera on the attractor's box and fits its width, as flam3-genome does for
/// random genomes (the box from 100 000 points, `eps` = 0.01).
pub fn frame(flame: &mut Flame, seed: u64) -> Result<()> {
    let b = estimate_bounds(flame, 0.01, 100_000, seed)?;
    let w = b.max[0] - b.min[0];
    if !(w.is_finite() && w > 0.0 && b.min.iter().chain(&b.max).all(|v| v.is_finite())) {
        // A degenerate attractor (a point, a vertical line): keep the default camera.
        return Ok(());
    }
    flame.center = [0.5 * (b.min[0] + b.max[0]), 0.5 * (b.min[1] + b.max[1])];
    flame.scale = flame.size[0] as f64 / w;
    Ok(())
}

/// An affine IFS as a flame: each map a linear transform with flam3's coefficients
/// (x' = a·x + c·y + e, y' = b·x + d·y + f), its probability as weight, colours spread
/// over the palette (grey), the camera fitted to the whole attractor. The flame's camera
/// has +y down, so a code drawn with +y up appears upside down.
pub fn flame_from_affine(
    name: Option<&str>,
    maps: &[Affine2],
    probabilities: &[f64],
    size: [u32; 2],
) -> Result<Flame> {
    if maps.is_empty() {
        return Err(Error::Empty("the code has no maps".into()));
    }
    if probabilities.len() != maps.len() {
        return Err(Error::param(
            "probabilities",
            format!(
                "{} probabilities for {} maps",
                probabilities.len(),
                maps.len()
            ),
        ));
    }
    let n = maps.len();
    let xforms = maps
        .iter()
        .zip(probabilities)
        .enumerate()
        .map(|(i, (m, &p))| Xform {
            coefs: coefs_of(m),
            weight: p,
            color: if n > 1 {
                i as f64 / (n - 1) as f64
            } else {
                0.0
            },
            ..Xform::default()
        })
        .collect();
    let mut flame = Flame {
        name: name.map(str::to_owned),
        size,
        quality: 100.0,
        xforms,
        ..Flame::default()
    };
    // The whole attractor (a contraction's orbit has no outliers), both sides fitted with a
    // 5 % margin.
    let b = estimate_bounds(&flame, 0.0, 100_000, 0)?;
    let (w, h) = (b.max[0] - b.min[0], b.max[1] - b.min[1]);
    if w.is_finite() && h.is_finite() && w.max(h) > 0.0 {
        flame.center = [0.5 * (b.min[0] + b.max[0]), 0.5 * (b.min[1] + b.max[1])];
        let sx = if w > 0.0 {
            size[0] as f64 / w
        } else {
            f64::INFINITY
        };
        let sy = if h > 0.0 {
            size[1] as f64 / h
        } else {
            f64::INFINITY
        };
        flame.scale = 0.95 * sx.min(sy);
    }
    flame.validate()?;
    Ok(flame)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_affine_map_keeps_its_action_as_a_linear_flame() {
        // x' = 0.5x − 0.2y + 0.1, y' = 0.3x + 0.4y − 0.2
        let m = Affine2::new(0.5, -0.2, 0.3, 0.4, 0.1, -0.2);
        let f = flame_from_affine(None, &[m], &[1.0], [64, 64]).unwrap();
        let p = f.xforms[0].apply([2.0, 3.0], &mut Xoshiro256PlusPlus::seed_from_u64(0));
        let want = [0.5 * 2.0 - 0.2 * 3.0 + 0.1, 0.3 * 2.0 + 0.4 * 3.0 - 0.2];
        assert!((p.point[0] - want[0]).abs() < 1e-12 && (p.point[1] - want[1]).abs() < 1e-12);
    }

    #[test]
    fn the_box_of_the_sierpinski_triangle_is_its_hull() {
        let maps = [
            Affine2::new(0.5, 0.0, 0.0, 0.5, 0.0, 0.0),
            Affine2::new(0.5, 0.0, 0.0, 0.5, 0.5, 0.0),
            Affine2::new(0.5, 0.0, 0.0, 0.5, 0.0, 0.5),
        ];
        let f = flame_from_affine(None, &maps, &[1.0; 3], [64, 64]).unwrap();
        let b = estimate_bounds(&f, 0.0, 20_000, 1).unwrap();
        for d in 0..2 {
            assert!(b.min[d] >= 0.0 && b.min[d] < 0.01, "{b:?}");
            assert!(b.max[d] <= 1.0 && b.max[d] > 0.99, "{b:?}");
        }
        assert_eq!(b.badvals, 0);
        assert!((f.center[0] - 0.5).abs() < 0.01 && (f.scale - 0.95 * 64.0).abs() < 1.0);
    }
}
