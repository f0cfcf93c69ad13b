//! Random flames that are worth looking at: flam3-genome's draft test (a quick render whose
//! brightness and contrast must pass), retried with fresh seeds.

use crate::error::Result;
use crate::model::flame::{Flame, RandomFlameConfig, random_flame};
use crate::render::flame::{FlameRenderConfig, render_flame};

/// flam3-genome's test of a draft: a quick 100² render of the framed genome at quality 1,
/// whose mean grey must reach 20/255 with ≥ 1 % black and ≤ 5 % white pixels.
pub fn looks_usable(flame: &Flame) -> Result<bool> {
    let mut t = flame.clone();
    t.scale *= 100.0 / t.size[0] as f64;
    t.size = [100, 100];
    t.quality = 1.0;
    t.supersample = 1;
    t.estimator_radius = 0.0;
    let img = render_flame(&t, &FlameRenderConfig::default(), None)?;
    let n = img.pixels.len() as f64;
    let rgb: Vec<[u8; 3]> = img
        .pixels
        .iter()
        .map(|p| [p[0] as u8, p[1] as u8, p[2] as u8])
        .collect();
    let avg = rgb
        .iter()
        .map(|c| c.iter().map(|&v| v as f64).sum::<f64>())
        .sum::<f64>()
        / (3.0 * n);
    let black = rgb.iter().filter(|c| **c == [0, 0, 0]).count() as f64 / n;
    let white = rgb.iter().filter(|c| **c == [255, 255, 255]).count() as f64 / n;
    Ok(avg >= 20.0 && black >= 0.01 && white <= 0.05)
}

/// A random flame for `seed` that passes [`looks_usable`] within `tries` drafts (draft `t`
/// drawn with the seed `mix_seed(seed, t)`), else the last draft; the flag says whether it
/// passed. `tries` must be at least 1.
pub fn usable_random_flame(
    seed: u64,
    cfg: &RandomFlameConfig,
    tries: u64,
) -> Result<(Flame, bool)> {
    if tries == 0 {
        return Err(crate::Error::InvalidParameter {
            name: "tries",
            message: "must be at least 1".into(),
        });
    }
    let mut last = None;
    for t in 0..tries {
        let f = random_flame(crate::chaos::mix_seed(seed, t), cfg)?;
        if looks_usable(&f)? {
            return Ok((f, true));
        }
        last = Some(f);
    }
    Ok((last.expect("tries ≥ 1"), false))
}
