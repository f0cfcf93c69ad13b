//! Fractal-coding texture upsampling: the paper preset's encoder and refinement against a
//! brute-force transcription of the paper's equations, exactness on self-similar textures, the
//! decoder's definition and order independence, the packed format's round trip (both
//! coordinate layouts), and the refinement's monotone objective.

use std::path::{Path, PathBuf};

use ifslab_strategies::problems::fractal_coding::{
    CoordStorage, DistanceCentre, EncoderConfig, FractalCode, HALF_MAX, HALF_MIN, Matching, Preset,
    RefineConfig, SearchGrid, Texture, decode, decode_into, decode_serial, decode_texel, encode,
    encode_refined, laplacian_variance, levels_for_factor, load_dir, pack, psnr, refine, save_dir,
    unpack,
};
use proptest::prelude::*;
use rand::{Rng, SeedableRng};
use rand_xoshiro::Xoshiro256PlusPlus;

fn data(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../data/textures")
        .join(name)
}

fn noise(w: usize, h: usize, ch: usize, seed: u64) -> Texture {
    let mut rng = Xoshiro256PlusPlus::seed_from_u64(seed);
    let v: Vec<f32> = (0..w * h * ch)
        .map(|_| rng.random_range(0..256) as f32)
        .collect();
    Texture::new(w, h, ch, v).unwrap()
}

/// A texture that is exactly self-similar: pick R (whole grey levels) and a block C(c) for
/// every texel, set O(c) = R(c) − mean(R's block at C(c)) and S(2c + δ) = R(C(c) + δ) + O(c).
/// Then every range block of S is a block of R plus a constant, and the 2×2 means of S give
/// back R exactly, so the encoder's R is this R.
fn self_similar(wr: usize, hr: usize, ch: usize, window: usize, seed: u64) -> Texture {
    let mut rng = Xoshiro256PlusPlus::seed_from_u64(seed);
    // Values below 64 keep every intermediate (multiples of 1/16) exact in f32.
    let r: Vec<f32> = (0..wr * hr * ch)
        .map(|_| rng.random_range(0..64) as f32)
        .collect();
    let rv = |x: usize, y: usize, k: usize| r[(y * wr + x) * ch + k];
    let mut s = vec![0.0f32; 4 * wr * hr * ch];
    for cy in 0..hr {
        for cx in 0..wr {
            let kx = rng.random_range(cx.saturating_sub(window)..=(cx + window).min(wr - 2));
            let ky = rng.random_range(cy.saturating_sub(window)..=(cy + window).min(hr - 2));
            for k in 0..ch {
                let block = [
                    rv(kx, ky, k),
                    rv(kx + 1, ky, k),
                    rv(kx, ky + 1, k),
                    rv(kx + 1, ky + 1, k),
                ];
                let o = rv(cx, cy, k) - 0.25 * block.iter().sum::<f32>();
                for (j, b) in block.iter().enumerate() {
                    let (x, y) = (2 * cx + j % 2, 2 * cy + j / 2);
                    s[(y * 2 * wr + x) * ch + k] = b + o;
                }
            }
        }
    }
    Texture::new(2 * wr, 2 * hr, ch, s).unwrap()
}

#[test]
fn an_exactly_self_similar_texture_is_reproduced_exactly_at_1x() {
    for (ch, window) in [(1, 3usize), (3, 5), (1, 255)] {
        let s = self_similar(20, 14, ch, window.min(20), 11 + ch as u64);
        let enc = encode(
            &s,
            &EncoderConfig {
                window: window as u32,
                ..EncoderConfig::default()
            },
        )
        .unwrap();
        assert!(
            enc.stats.mean_sse == 0.0,
            "every range block has an exact match, got mean SSE {}",
            enc.stats.mean_sse
        );
        let rec = decode(&enc.code, 1).unwrap();
        assert_eq!(
            rec, s,
            "1× reconstruction of a self-similar texture (ch {ch})"
        );
    }
}

#[test]
fn the_1x_output_is_the_reconstruction_definition() {
    let s = noise(24, 16, 3, 5);
    let code = encode(&s, &EncoderConfig::default()).unwrap().code;
    let (w, ch) = (code.width(), code.channels());
    let rec = decode(&code, 1).unwrap();
    let r = code.reduced();
    for cy in 0..code.height() {
        for cx in 0..w {
            let k = code.coords()[cy * w + cx] as usize;
            let (kx, ky) = (k % w, k / w);
            for (dx, dy) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
                for c in 0..ch {
                    // T₁(2c + δ) = R(C(c) + δ) + O(c)
                    let want = code.offsets()[(cy * w + cx) * ch + c] + r.get(kx + dx, ky + dy, c);
                    assert_eq!(rec.get(2 * cx + dx, 2 * cy + dy, c), want);
                }
            }
        }
    }
}

#[test]
fn the_2x_output_follows_the_chain_of_the_definition() {
    let s = noise(16, 12, 1, 9);
    let code = encode(
        &s,
        &EncoderConfig {
            window: 4,
            ..EncoderConfig::default()
        },
    )
    .unwrap()
    .code;
    let w = code.width();
    let up = decode(&code, 2).unwrap();
    assert_eq!((up.width(), up.height()), (32, 24));
    for y in 0..24 {
        for x in 0..32 {
            // n = 2: c₀ = p >> 2, c₁ = C(c₀) + Δ₁, c₂ = C(c₁) + Δ₂, T = R(c₂) + O(c₀) + O(c₁).
            let c0 = (y >> 2) * w + (x >> 2);
            let c1 = code.coords()[c0] as usize + ((x >> 1) & 1) + ((y >> 1) & 1) * w;
            let c2 = code.coords()[c1] as usize + (x & 1) + (y & 1) * w;
            let want = (code.offsets()[c0] + code.offsets()[c1]) + code.reduced().data()[c2];
            assert_eq!(up.get(x, y, 0), want, "texel ({x}, {y})");
            assert_eq!(decode_texel(&code, 2, x, y).unwrap(), vec![want]);
        }
    }
}

#[test]
fn texels_do_not_depend_on_the_order_they_are_computed_in() {
    for ch in [1, 3] {
        let s = noise(20, 12, ch, 21);
        let code = encode(&s, &EncoderConfig::default()).unwrap().code;
        for factor in [1, 2, 4, 8, 16, 512] {
            let par = decode(&code, factor).unwrap();
            let ser = decode_serial(&code, factor).unwrap();
            assert_eq!(
                par, ser,
                "parallel vs scrambled serial, ch {ch}, factor {factor}"
            );
        }
        // And whatever the thread count.
        let one = rayon::ThreadPoolBuilder::new()
            .num_threads(1)
            .build()
            .unwrap()
            .install(|| decode(&code, 8).unwrap());
        assert_eq!(one, decode(&code, 8).unwrap());
    }
}

#[test]
fn box_filtering_an_output_gives_the_previous_level_within_rs_rounding() {
    // reduce(T_{n+1}) = T_n up to R's rounding to whole grey levels (≤ ½ at the base of the
    // chain, carried unchanged up the levels).
    let s = Texture::load(&data("gravel.png"), false)
        .unwrap()
        .crop(100, 60, 64, 48)
        .unwrap();
    let code = encode(&s, &EncoderConfig::default()).unwrap().code;
    let mut prev = decode(&code, 1).unwrap();
    for factor in [2, 4, 8] {
        let next = decode(&code, factor).unwrap();
        let (w, h) = (prev.width(), prev.height());
        for y in 0..h {
            for x in 0..w {
                let m = 0.25
                    * (next.get(2 * x, 2 * y, 0)
                        + next.get(2 * x + 1, 2 * y, 0)
                        + next.get(2 * x, 2 * y + 1, 0)
                        + next.get(2 * x + 1, 2 * y + 1, 0));
                assert!(
                    (m - prev.get(x, y, 0)).abs() <= 0.5 + 1e-3,
                    "factor {factor}, texel ({x}, {y}): {m} vs {}",
                    prev.get(x, y, 0)
                );
            }
        }
        prev = next;
    }
    // The 1× level's 2×2 means are exactly the unrounded R, so rounding them gives R.
    let rec = decode(&code, 1).unwrap();
    assert_eq!(rec.reduce().unwrap().data(), code.reduced().data());
}

#[test]
fn encoding_does_not_depend_on_the_thread_count() {
    let s = noise(40, 24, 3, 2);
    let capped = EncoderConfig {
        window: 9,
        beta: 0.5,
        delta_e_max: 300.0,
        max_candidates: Some(6),
        ..EncoderConfig::default()
    };
    let grey = Texture::load(&data("gravel.png"), false)
        .unwrap()
        .crop(0, 0, 96, 64)
        .unwrap();
    for (tex, cfg) in [
        (&s, capped),
        (&s, Preset::Paper.encoder(true)),
        (&grey, Preset::Paper.encoder(true)),
        (&grey, Preset::Ifslab.encoder(true)),
    ] {
        let many = encode(tex, &cfg).unwrap();
        let one = rayon::ThreadPoolBuilder::new()
            .num_threads(1)
            .build()
            .unwrap()
            .install(|| encode(tex, &cfg).unwrap());
        assert_eq!(many.code, one.code);
        assert_eq!(many.candidates, one.candidates);
    }
}

#[test]
fn the_packed_format_round_trips_through_png_files() {
    let dir = tempfile::tempdir().unwrap();
    for (name, grey) in [
        ("brick.png", false),
        ("wood.png", false),
        ("wood.png", true),
    ] {
        let s = Texture::load(&data(name), grey).unwrap();
        let s = s.crop(0, 0, s.width().min(96), s.height().min(64)).unwrap();
        let code = encode(&s, &EncoderConfig::default()).unwrap().code;
        let path = dir.path().join(format!("{name}-{grey}"));
        let err = save_dir(
            &code,
            &path,
            CoordStorage::SignMagnitude,
            serde_json::json!({"test": true}),
        )
        .unwrap();
        let (back, manifest) = load_dir(&path).unwrap();
        assert_eq!(manifest.channels, s.channels());
        assert_eq!((manifest.width, manifest.height), (s.width(), s.height()));
        // R and C are exact; every offset moves by at most half the step.
        assert_eq!(back.reduced(), code.reduced());
        assert_eq!(back.coords(), code.coords());
        assert_eq!(err.max_reduced_error, 0.0);
        for (a, b) in back.offsets().iter().zip(code.offsets()) {
            assert!((a - b).abs() <= err.offset_step / 2.0);
        }
        assert!(err.max_offset_error <= err.offset_step / 2.0);
        // A texel decoded with n levels moves by at most n·step/2.
        for factor in [1u32, 4] {
            let n = levels_for_factor(factor).unwrap() as f32;
            let (a, b) = (
                decode(&code, factor).unwrap(),
                decode(&back, factor).unwrap(),
            );
            let worst = a
                .data()
                .iter()
                .zip(b.data())
                .map(|(x, y)| (x - y).abs())
                .fold(0.0f32, f32::max);
            assert!(worst <= n * err.offset_step / 2.0 + 1e-3, "{name}: {worst}");
        }
        if err.offset_step == 0.25 {
            assert_eq!(
                back, code,
                "step ¼ holds every offset of an 8-bit source exactly"
            );
        }
    }
}

#[test]
fn small_offsets_pack_losslessly() {
    // Offsets of an 8-bit source are multiples of ¼; with |O| ≤ 31.875 the step is ¼.
    let s = Texture::from_fn(32, 32, 1, |x, y, _| ((x * 5 + y * 3) % 16) as f32 + 100.0).unwrap();
    let code = encode(&s, &EncoderConfig::default()).unwrap().code;
    let (p, err) = pack(&code, CoordStorage::SignMagnitude).unwrap();
    assert_eq!(err.offset_step, 0.25);
    assert_eq!(unpack(&p).unwrap(), code);
}

#[test]
fn refinement_never_increases_the_variance_of_the_laplacian() {
    let s = Texture::load(&data("brick.png"), false)
        .unwrap()
        .crop(200, 120, 96, 80)
        .unwrap();
    let wood = Texture::load(&data("wood.png"), false)
        .unwrap()
        .crop(0, 0, 64, 48)
        .unwrap();
    for tex in [s, wood] {
        let enc_cfg = EncoderConfig {
            window: 16,
            beta: 1.0,
            delta_e_max: 500.0,
            max_candidates: Some(12),
            ..EncoderConfig::default()
        };
        let (enc, report) = encode_refined(&tex, &enc_cfg, &RefineConfig { passes: 6 }).unwrap();
        let obj = &report.objective;
        assert!(obj.len() >= 2);
        for w in obj.windows(2) {
            assert!(w[1] <= w[0] * (1.0 + 1e-12), "objective rose: {obj:?}");
        }
        assert!(
            obj.last().unwrap() < &obj[0],
            "refinement changed nothing: {obj:?}"
        );
        // The reported objective is that of the refined code's synthesis.
        let last = laplacian_variance(&decode(&enc.code, 1).unwrap());
        assert!((last - obj.last().unwrap()).abs() <= 1e-9 * last.max(1.0));
        // Every refined code is one of the texel's candidates.
        for c in 0..enc.candidates.texels() {
            let k = enc.code.coords()[c];
            assert!((0..enc.candidates.count(c)).any(|i| enc.candidates.get(c, i).0 == k));
        }
    }
}

#[test]
fn refinement_with_a_single_candidate_changes_nothing() {
    let s = noise(24, 24, 1, 4);
    let mut enc = encode(&s, &EncoderConfig::default()).unwrap();
    let before = enc.code.clone();
    let rep = refine(&mut enc.code, &enc.candidates, &RefineConfig { passes: 3 }).unwrap();
    assert_eq!(enc.code, before);
    assert_eq!(rep.changes, vec![0]);
    // Candidates of another texture's encoding are refused, not trusted.
    let other = encode(&noise(48, 12, 1, 4), &EncoderConfig::default()).unwrap();
    assert_eq!(other.candidates.texels(), enc.candidates.texels());
    assert!(
        refine(
            &mut enc.code,
            &other.candidates,
            &RefineConfig { passes: 1 }
        )
        .is_err()
    );
}

#[test]
fn bad_inputs_get_clear_errors() {
    let odd = noise(9, 8, 1, 1);
    let e = encode(&odd, &EncoderConfig::default())
        .unwrap_err()
        .to_string();
    assert!(e.contains("even sides"), "{e}");
    let tiny = noise(2, 2, 1, 1);
    assert!(encode(&tiny, &EncoderConfig::default()).is_err());
    let code = encode(&noise(8, 8, 1, 1), &EncoderConfig::default())
        .unwrap()
        .code;
    let e = decode(&code, 3).unwrap_err().to_string();
    assert!(e.contains("power of two"), "{e}");
    assert!(decode(&code, 0).is_err());
    let mut wrong = vec![0.0; 5];
    assert!(decode_into(&code, 2, &mut wrong).is_err());
    assert!(Texture::from_image_bytes(b"not an image", false).is_err());
    let dir = tempfile::tempdir().unwrap();
    let e = load_dir(dir.path()).unwrap_err().to_string();
    assert!(e.contains("code.json"), "{e}");
    // A block that leaves R is refused.
    let (r, mut coords, offsets) = code.into_parts();
    coords[0] = 3 * 4 + 3; // (3, 3) in a 4×4 R: its 2×2 block leaves R
    assert!(FractalCode::new(r, coords, offsets).is_err());
}

#[test]
fn real_textures_reconstruct_well_at_1x() {
    // The cross-scale self-similarity of a natural texture: on a 128² crop of gravel the 1×
    // reconstruction from R is far better than upsampling R by interpolation.
    let s = Texture::load(&data("gravel.png"), false)
        .unwrap()
        .crop(0, 0, 128, 128)
        .unwrap();
    let code = encode(&s, &EncoderConfig::default()).unwrap().code;
    let ours = psnr(&decode(&code, 1).unwrap(), &s).unwrap();
    let bil = psnr(
        &ifslab_strategies::problems::fractal_coding::upsample(
            code.reduced(),
            2,
            ifslab_strategies::problems::fractal_coding::Filter::Bilinear,
        )
        .unwrap(),
        &s,
    )
    .unwrap();
    assert!(
        ours > bil + 5.0,
        "fractal {ours:.2} dB vs bilinear {bil:.2} dB"
    );
}

fn arb_code() -> impl Strategy<Value = (FractalCode, bool)> {
    (2usize..9, 2usize..9, prop::bool::ANY, any::<u64>(), 0u32..3).prop_map(
        |(w, h, rgb, seed, spread)| {
            let ch = if rgb { 3 } else { 1 };
            let mut rng = Xoshiro256PlusPlus::seed_from_u64(seed);
            let r = Texture::new(
                w,
                h,
                ch,
                (0..w * h * ch)
                    .map(|_| rng.random_range(0..256) as f32)
                    .collect(),
            )
            .unwrap();
            let coords = (0..w * h)
                .map(|_| (rng.random_range(0..h - 1) * w + rng.random_range(0..w - 1)) as u32)
                .collect();
            // Offsets are quarters, within ±31.875 (lossless) or up to ±255 (lossy).
            let lim = [127i32, 1020, 600][spread as usize];
            let offsets = (0..w * h * ch)
                .map(|_| rng.random_range(-lim..=lim) as f32 / 4.0)
                .collect();
            (FractalCode::new(r, coords, offsets).unwrap(), spread == 0)
        },
    )
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    /// Packing then unpacking keeps R and C exactly and every offset within step/2 (exactly
    /// when every offset fits the ¼ step).
    #[test]
    fn packing_round_trips((code, small) in arb_code()) {
        let (p, err) = pack(&code, CoordStorage::SignMagnitude).unwrap();
        let back = unpack(&p).unwrap();
        prop_assert_eq!(back.reduced(), code.reduced());
        prop_assert_eq!(back.coords(), code.coords());
        for (a, b) in back.offsets().iter().zip(code.offsets()) {
            prop_assert!((a - b).abs() <= err.offset_step / 2.0);
        }
        if small {
            prop_assert_eq!(err.offset_step, 0.25);
            prop_assert_eq!(back, code);
        }
    }
}

// ---------------------------------------------------------------------------------------
// The paper preset against the paper's equations.

/// A block of R, by its top-left texel, and its dissimilarity E.
type Candidate = ((usize, usize), i64);

/// One texel's search, transcribed from the paper by brute force in integers: the raw SSE of
/// Eq. 3 (summed over channels), the proximity term of Eq. 12 with β = 1 measured from 2c (as
/// printed) when `refined`, over the even-index blocks of §IV (x, y even, half relative
/// coordinate x/2 − ⌊c_x/2⌋ in [−125, 126], |x − c_x| ≤ 255). Returns every candidate as
/// ((x, y), E) and the minimum E.
fn paper_search(s: &Texture, cx: usize, cy: usize, refined: bool) -> (Vec<Candidate>, i64) {
    let r = s.reduce().unwrap();
    let (wr, hr, nc) = (r.width(), r.height(), r.channels());
    let allowed = |c: usize, x: usize| {
        let half = (x / 2) as i64 - (c / 2) as i64;
        x.is_multiple_of(2) && (-125..=126).contains(&half) && x.abs_diff(c) <= 255
    };
    let mut all = Vec::new();
    for y in 0..hr - 1 {
        for x in 0..wr - 1 {
            if !allowed(cx, x) || !allowed(cy, y) {
                continue;
            }
            let mut e = 0i64;
            for (dx, dy) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
                for k in 0..nc {
                    let t = s.get(2 * cx + dx, 2 * cy + dy, k) as i64;
                    let d = r.get(x + dx, y + dy, k) as i64;
                    e += (t - d) * (t - d);
                }
            }
            if refined {
                e += (x.abs_diff(2 * cx) + y.abs_diff(2 * cy)) as i64;
            }
            all.push(((x, y), e));
        }
    }
    let min = all.iter().map(|a| a.1).min().unwrap();
    (all, min)
}

/// Eq. 4: the mean of the approximation error of the virtual range at (x, y), per channel.
fn paper_offset(s: &Texture, cx: usize, cy: usize, x: usize, y: usize) -> Vec<f32> {
    let r = s.reduce().unwrap();
    (0..s.channels())
        .map(|k| {
            let sum: i64 = [(0, 0), (1, 0), (0, 1), (1, 1)]
                .iter()
                .map(|&(dx, dy)| {
                    s.get(2 * cx + dx, 2 * cy + dy, k) as i64 - r.get(x + dx, y + dy, k) as i64
                })
                .sum();
            sum as f32 / 4.0
        })
        .collect()
}

#[test]
fn the_paper_preset_encodes_as_the_papers_equations_say() {
    // Grey and RGB noise, and a real texture; coarse grey levels make ties likely.
    let coarse = Texture::from_fn(30, 26, 1, |x, y, _| {
        ((x * 7 + y * 3 + x * y) % 5) as f32 * 60.0
    })
    .unwrap();
    let real = Texture::load(&data("brick.png"), false)
        .unwrap()
        .crop(300, 40, 40, 36)
        .unwrap();
    for s in [noise(28, 24, 1, 31), noise(26, 22, 3, 32), coarse, real] {
        let plain = encode(&s, &Preset::Paper.encoder(false)).unwrap();
        let cand = encode(&s, &Preset::Paper.encoder(true)).unwrap();
        let w = plain.code.width();
        for c in 0..w * plain.code.height() {
            let (cx, cy) = (c % w, c / w);
            // Eq. 2–3: the plain code's block minimises the raw SSE over even-index blocks …
            let (all, min) = paper_search(&s, cx, cy, false);
            let k = plain.code.coords()[c] as usize;
            let (x, y) = (k % w, k / w);
            let e = all.iter().find(|a| a.0 == (x, y)).map(|a| a.1);
            assert_eq!(
                e,
                Some(min),
                "texel ({cx}, {cy}): ({x}, {y}) is not an Eq. 2 minimiser"
            );
            // … and its offset is Eq. 4's, computed afterwards from that block.
            let ch = s.channels();
            assert_eq!(
                &plain.code.offsets()[c * ch..(c + 1) * ch],
                paper_offset(&s, cx, cy, x, y).as_slice()
            );
            // Eq. 11–13: Ω is every even-index block with E < E* + 100 (E with |x − 2c|).
            let (all, min) = paper_search(&s, cx, cy, true);
            let mut want: Vec<(usize, usize)> = all
                .iter()
                .filter(|a| a.1 < min + 100)
                .map(|a| a.0)
                .collect();
            let mut got: Vec<(usize, usize)> = (0..cand.candidates.count(c))
                .map(|i| {
                    let k = cand.candidates.get(c, i).0 as usize;
                    (k % w, k / w)
                })
                .collect();
            assert!(got.iter().all(|&(x, y)| x % 2 == 0 && y % 2 == 0));
            let best = got[0];
            assert_eq!(all.iter().find(|a| a.0 == best).unwrap().1, min);
            want.sort();
            got.sort();
            assert_eq!(got, want, "Ω of texel ({cx}, {cy})");
        }
    }
}

#[test]
fn raw_matching_is_not_mean_removed_matching() {
    // R holds a dark copy of a range block (exact up to an offset) and a bright block that
    // is close in raw values but of a different shape: the paper's raw SSE picks the bright
    // one, mean-removed matching the dark copy.
    let mut s = Texture::from_fn(12, 12, 1, |_, _, _| 200.0)
        .unwrap()
        .into_data();
    // Range block at source (0, 0), i.e. texel (0, 0) of R: a diagonal pattern 240/200.
    s[0] = 240.0;
    s[12 + 1] = 240.0;
    // R(3..5, 3..5) = 60/20 in the same pattern (each a 2×2 source block): a dark copy.
    for (rx, ry, v) in [(3, 3, 60.0), (4, 3, 20.0), (3, 4, 20.0), (4, 4, 60.0)] {
        for (dx, dy) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
            s[(2 * ry + dy) * 12 + 2 * rx + dx] = v;
        }
    }
    let s = Texture::new(12, 12, 1, s).unwrap();
    let r = s.reduce().unwrap();
    assert_eq!(
        [
            r.get(3, 3, 0),
            r.get(4, 3, 0),
            r.get(3, 4, 0),
            r.get(4, 4, 0)
        ],
        [60.0, 20.0, 20.0, 60.0]
    );
    let cfg = |matching| EncoderConfig {
        matching,
        grid: SearchGrid::All,
        ..EncoderConfig::default()
    };
    let raw = encode(&s, &cfg(Matching::Raw)).unwrap().code;
    let mr = encode(&s, &cfg(Matching::MeanRemoved)).unwrap().code;
    assert_eq!(
        mr.coords()[0],
        3 * 6 + 3,
        "mean-removed finds the exact dark copy"
    );
    assert_eq!(mr.offsets()[0], 220.0 - 40.0);
    let k = raw.coords()[0] as usize;
    assert!(
        r.get(k % 6, k / 6, 0) >= 190.0,
        "raw SSE prefers a bright block, got {k}"
    );
}

#[test]
fn the_paper_refinement_stays_in_omega_and_updates_offsets_by_eq_4() {
    let s = Texture::load(&data("gravel.png"), false)
        .unwrap()
        .crop(200, 100, 48, 40)
        .unwrap();
    let cfg = Preset::Paper.encoder(true);
    let (enc, report) = encode_refined(&s, &cfg, &Preset::Paper.refine()).unwrap();
    assert_eq!(Preset::Paper.refine().passes, 3);
    for w in report.objective.windows(2) {
        assert!(w[1] <= w[0], "objective rose: {:?}", report.objective);
    }
    let plain = encode(&s, &cfg).unwrap().code;
    let w = enc.code.width();
    let mut moved = 0;
    for c in 0..w * enc.code.height() {
        let (cx, cy) = (c % w, c / w);
        let k = enc.code.coords()[c] as usize;
        let (x, y) = (k % w, k / w);
        // The refined block satisfies Eq. 13 with the |x − 2c| term of Eq. 12 …
        let (all, min) = paper_search(&s, cx, cy, true);
        let e = all
            .iter()
            .find(|a| a.0 == (x, y))
            .expect("an even-index block")
            .1;
        assert!(
            e < min + 100,
            "texel ({cx}, {cy}): E {e} ≥ E* + ΔE = {}",
            min + 100
        );
        // … and its offset is Eq. 4's for the refined block.
        assert_eq!(enc.code.offsets()[c], paper_offset(&s, cx, cy, x, y)[0]);
        moved += usize::from(enc.code.coords()[c] != plain.coords()[c]);
    }
    assert!(moved > 0, "the refinement moved no block");
}

#[test]
fn the_distance_centre_changes_the_candidate_sets() {
    // |x − 2c| and |x − c| agree only at c = 0: Ω must differ elsewhere.
    let s = Texture::load(&data("grass.png"), false)
        .unwrap()
        .crop(0, 0, 64, 64)
        .unwrap();
    let range = encode(&s, &Preset::Paper.encoder(true)).unwrap();
    let domain = encode(
        &s,
        &EncoderConfig {
            distance: DistanceCentre::Domain,
            ..Preset::Paper.encoder(true)
        },
    )
    .unwrap();
    assert_eq!(range.code.coords()[0], domain.code.coords()[0]);
    assert_ne!(range.candidates, domain.candidates);
    // Each centre pulls the chosen blocks towards itself: measured from 2c, the range-centred
    // code's blocks are nearer; measured from c, the domain-centred code's.
    let mean_dist = |code: &FractalCode, scale: usize| {
        let w = code.width();
        let sum: usize = (0..code.coords().len())
            .map(|c| {
                let k = code.coords()[c] as usize;
                (k % w).abs_diff(scale * (c % w)) + (k / w).abs_diff(scale * (c / w))
            })
            .sum();
        sum as f64 / code.coords().len() as f64
    };
    assert!(mean_dist(&range.code, 2) < mean_dist(&domain.code, 2));
    assert!(mean_dist(&domain.code, 1) < mean_dist(&range.code, 1));
}

#[test]
fn half_signed_coordinates_stay_in_range_and_round_trip() {
    // A 300-texel-wide R: the half coordinate's limits −125 and 126 are reachable.
    let (w, h) = (300usize, 4usize);
    let r = Texture::from_fn(w, h, 1, |x, y, _| ((x * 3 + y) % 256) as f32).unwrap();
    let base = |c: usize| 2 * (c / 2);
    let mut coords = Vec::new();
    for y in 0..h {
        for x in 0..w {
            // The extreme half coordinates where they fit R, else the texel's own base.
            let kx = match x % 3 {
                0 if base(x) >= 250 => base(x) - 250,
                1 if base(x) + 252 <= w - 2 => base(x) + 252,
                _ => base(x),
            };
            let ky = base(y).min(h - 2);
            coords.push((ky * w + kx) as u32);
        }
    }
    let code = FractalCode::new(r, coords, vec![0.25; w * h]).unwrap();
    let (p, _) = pack(&code, CoordStorage::HalfSigned).unwrap();
    let mut seen = [false; 2];
    for b in p.coords.chunks_exact(3) {
        let (sx, sy) = (b[0] as i8 as i32, b[1] as i8 as i32);
        assert!((HALF_MIN..=HALF_MAX).contains(&sx) && (HALF_MIN..=HALF_MAX).contains(&sy));
        assert_eq!(b[2], 0);
        seen[0] |= sx == HALF_MIN;
        seen[1] |= sx == HALF_MAX;
    }
    assert_eq!(seen, [true, true], "both limits exercised");
    assert_eq!(unpack(&p).unwrap(), code);
    // Values outside [−125, 126] are refused when unpacking …
    for bad in [127i8, -126] {
        let mut q = p.clone();
        q.coords[0] = bad as u8;
        let e = unpack(&q).unwrap_err().to_string();
        assert!(e.contains("[-125, 126]"), "{e}");
    }
    // … and a block the layout cannot hold is refused when packing: odd, or beyond the range.
    let (r, mut coords, offsets) = code.into_parts();
    coords[0] = 1;
    let odd = FractalCode::new(r.clone(), coords.clone(), offsets.clone()).unwrap();
    assert!(pack(&odd, CoordStorage::HalfSigned).is_err());
    assert!(pack(&odd, CoordStorage::SignMagnitude).is_ok());
    coords[0] = 254; // texel 0: half coordinate 127
    let far = FractalCode::new(r, coords, offsets).unwrap();
    let e = pack(&far, CoordStorage::HalfSigned)
        .unwrap_err()
        .to_string();
    assert!(e.contains("half-signed"), "{e}");
}

#[test]
fn paper_codes_round_trip_through_the_packed_files() {
    let dir = tempfile::tempdir().unwrap();
    for (name, grey) in [("grass.png", false), ("wood.png", false)] {
        let s = Texture::load(&data(name), grey).unwrap();
        let s = s.crop(0, 0, s.width().min(80), s.height().min(64)).unwrap();
        for (grid, storage) in [
            (SearchGrid::Even, CoordStorage::HalfSigned),
            (SearchGrid::EvenOffset, CoordStorage::HalfSignedOffset),
        ] {
            let (enc, _) = encode_refined(
                &s,
                &EncoderConfig {
                    grid,
                    ..Preset::Paper.encoder(true)
                },
                &Preset::Paper.refine(),
            )
            .unwrap();
            let path = dir.path().join(format!("{name}-{storage}"));
            let err = save_dir(&enc.code, &path, storage, serde_json::json!({})).unwrap();
            let (back, manifest) = load_dir(&path).unwrap();
            assert_eq!(manifest.coord_storage, storage);
            assert_eq!(back.coords(), enc.code.coords());
            assert_eq!(back.reduced(), enc.code.reduced());
            for (a, b) in back.offsets().iter().zip(enc.code.offsets()) {
                assert!((a - b).abs() <= err.offset_step / 2.0);
            }
            // The other half layout cannot hold this grid's codes.
            let other = if storage == CoordStorage::HalfSigned {
                CoordStorage::HalfSignedOffset
            } else {
                CoordStorage::HalfSigned
            };
            assert!(pack(&enc.code, other).is_err());
        }
    }
    // A version-1 folder (sign-magnitude, before the layouts were named) still loads.
    let s = noise(16, 16, 1, 3);
    let code = encode(&s, &EncoderConfig::default()).unwrap().code;
    let path = dir.path().join("v1");
    save_dir(
        &code,
        &path,
        CoordStorage::SignMagnitude,
        serde_json::json!({}),
    )
    .unwrap();
    let mpath = path.join("code.json");
    let mut m: serde_json::Value = serde_json::from_slice(&std::fs::read(&mpath).unwrap()).unwrap();
    m["version"] = 1.into();
    m.as_object_mut().unwrap().remove("coord_storage");
    std::fs::write(&mpath, serde_json::to_vec(&m).unwrap()).unwrap();
    assert_eq!(load_dir(&path).unwrap().0.coords(), code.coords());
}
