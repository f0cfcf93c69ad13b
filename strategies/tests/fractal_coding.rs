//! Fractal-coding texture upsampling: exactness on self-similar textures, the decoder's
//! definition and order independence, the packed format's round trip, and the refinement's
//! monotone objective.

use std::path::{Path, PathBuf};

use ifslab_strategies::fractal_coding::{
    EncoderConfig, FractalCode, RefineConfig, Texture, decode, decode_into, decode_serial,
    decode_texel, encode, encode_refined, laplacian_variance, levels_for_factor, load_dir, pack,
    psnr, refine, save_dir, unpack,
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
    let cfg = EncoderConfig {
        window: 9,
        beta: 0.5,
        delta_e_max: 300.0,
        max_candidates: 6,
    };
    let many = encode(&s, &cfg).unwrap();
    let one = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap()
        .install(|| encode(&s, &cfg).unwrap());
    assert_eq!(many.code, one.code);
    assert_eq!(many.candidates, one.candidates);
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
        let err = save_dir(&code, &path, serde_json::json!({"test": true})).unwrap();
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
    let (p, err) = pack(&code).unwrap();
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
            max_candidates: 12,
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
        &ifslab_strategies::fractal_coding::upsample(
            code.reduced(),
            2,
            ifslab_strategies::fractal_coding::Filter::Bilinear,
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
        let (p, err) = pack(&code).unwrap();
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
