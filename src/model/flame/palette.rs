//! Flame palettes: 256 RGBA entries, from a `.flame` file's colours or from flam3's palette
//! library (`flam3-palettes.xml`, Debian package `flam3-palette`) by number.
//!
//! Entries are stored in file units — red, green, blue and alpha in 0–255, as a `<color
//! rgb=…>` element writes them — so a file read and written back keeps its numbers exactly.
//! [`Palette::flam3_colors`] gives what flam3 renders with: components in [0, 1], colour
//! premultiplied by alpha.

use std::path::{Path, PathBuf};

use crate::error::{Error, Result};

/// 256 colours, RGBA in 0–255.
#[derive(Clone, Debug, PartialEq)]
pub struct Palette {
    /// The entries, index 0 to 255.
    pub colors: Vec<[f64; 4]>,
}

impl Default for Palette {
    /// A grey ramp from black to white.
    fn default() -> Self {
        Palette {
            colors: (0..256)
                .map(|i| {
                    let v = i as f64;
                    [v, v, v, 255.0]
                })
                .collect(),
        }
    }
}

impl Palette {
    /// Number of entries of every flame palette.
    pub const LEN: usize = 256;

    /// flam3's rendering colours: `[r, g, b, a]` in [0, 1], colour premultiplied by alpha.
    pub fn flam3_colors(&self) -> Vec<[f64; 4]> {
        self.colors
            .iter()
            .map(|c| {
                let a = c[3] / 255.0;
                [a * c[0] / 255.0, a * c[1] / 255.0, a * c[2] / 255.0, a]
            })
            .collect()
    }

    /// Checks there are 256 finite entries within 0–255.
    pub fn validate(&self, what: &str) -> Result<()> {
        if self.colors.len() != Self::LEN {
            return Err(Error::Shape(format!(
                "{what}: palette has {} entries; flame palettes have 256",
                self.colors.len()
            )));
        }
        for (i, c) in self.colors.iter().enumerate() {
            for (k, &v) in c.iter().enumerate() {
                if !v.is_finite() {
                    return Err(Error::NonFinite {
                        what: format!("{what}: palette"),
                        location: format!("colour {i}, channel {k}"),
                        value: v,
                    });
                }
                if !(0.0..=255.0).contains(&v) {
                    return Err(Error::param(
                        "palette",
                        format!("{what}: colour {i} channel {k} is {v}; channels lie in 0–255"),
                    ));
                }
            }
        }
        Ok(())
    }

    /// Palette `number` of flam3's library, hue rotated by `hue` turns (as flam3's
    /// `hue` attribute). The library file is looked up by [`palette_library_path`].
    pub fn from_library(number: i64, hue: f64) -> Result<Palette> {
        let path = palette_library_path()?;
        let lib = PaletteLibrary::load(&path)?;
        lib.get(number, hue).ok_or_else(|| {
            Error::param(
                "palette",
                format!(
                    "palette number {number} is not in {} (it has {} palettes, numbered {}–{})",
                    path.display(),
                    lib.palettes.len(),
                    lib.palettes.first().map_or(0, |p| p.0),
                    lib.palettes.last().map_or(0, |p| p.0)
                ),
            )
        })
    }
}

/// Where flam3's palette library is: `$flam3_palettes` (flam3's own variable), else the
/// Debian/Ubuntu and /usr/local install locations.
pub fn palette_library_path() -> Result<PathBuf> {
    let mut tried = Vec::new();
    if let Some(p) = std::env::var_os("flam3_palettes") {
        let p = PathBuf::from(p);
        if p.is_file() {
            return Ok(p);
        }
        tried.push(p);
    }
    for p in [
        "/usr/share/flam3/flam3-palettes.xml",
        "/usr/local/share/flam3/flam3-palettes.xml",
    ] {
        let p = PathBuf::from(p);
        if p.is_file() {
            return Ok(p);
        }
        tried.push(p);
    }
    Err(Error::param(
        "palette",
        format!(
            "the flame names a flam3 palette by number, but flam3's palette library was not \
             found (looked at {}); install it (Debian: apt-get install flam3-palette) or set \
             flam3_palettes to the file",
            tried
                .iter()
                .map(|p| p.display().to_string())
                .collect::<Vec<_>>()
                .join(", ")
        ),
    ))
}

/// flam3's palette library: numbered palettes of 256 colours.
#[derive(Clone, Debug)]
pub struct PaletteLibrary {
    /// `(number, colours 0–255)`.
    pub palettes: Vec<(i64, Vec<[u8; 3]>)>,
}

impl PaletteLibrary {
    /// Reads a `flam3-palettes.xml` file.
    pub fn load(path: &Path) -> Result<Self> {
        let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
        let doc = roxmltree::Document::parse(&text).map_err(|e| Error::FlameFile {
            path: path.to_owned(),
            location: "document".into(),
            message: e.to_string(),
        })?;
        let mut palettes = Vec::new();
        for node in doc.descendants().filter(|n| n.has_tag_name("palette")) {
            let (Some(num), Some(data)) = (node.attribute("number"), node.attribute("data")) else {
                continue;
            };
            let Ok(num) = num.trim().parse::<i64>() else {
                continue;
            };
            let hex: Vec<u8> = data.bytes().filter(|b| !b.is_ascii_whitespace()).collect();
            if hex.len() < 256 * 8 {
                continue;
            }
            let mut colors = Vec::with_capacity(256);
            let mut ok = true;
            for i in 0..256 {
                // "00RRGGBB"
                let chunk = &hex[i * 8..i * 8 + 8];
                let byte = |k: usize| {
                    std::str::from_utf8(&chunk[k..k + 2])
                        .ok()
                        .and_then(|s| u8::from_str_radix(s, 16).ok())
                };
                match (byte(2), byte(4), byte(6)) {
                    (Some(r), Some(g), Some(b)) => colors.push([r, g, b]),
                    _ => {
                        ok = false;
                        break;
                    }
                }
            }
            if ok {
                palettes.push((num, colors));
            }
        }
        if palettes.is_empty() {
            return Err(Error::FlameFile {
                path: path.to_owned(),
                location: "document".into(),
                message: "no <palette number=… data=…> entries".into(),
            });
        }
        Ok(PaletteLibrary { palettes })
    }

    /// Palette `number`, hue rotated by `hue` turns as flam3 does (through HSV).
    pub fn get(&self, number: i64, hue: f64) -> Option<Palette> {
        let (_, colors) = self.palettes.iter().find(|(n, _)| *n == number)?;
        Some(Palette {
            colors: colors
                .iter()
                .map(|c| {
                    let rgb = [
                        c[0] as f64 / 255.0,
                        c[1] as f64 / 255.0,
                        c[2] as f64 / 255.0,
                    ];
                    let mut hsv = rgb_to_hsv(rgb);
                    hsv[0] += hue * 6.0;
                    let rgb = hsv_to_rgb(hsv);
                    [rgb[0] * 255.0, rgb[1] * 255.0, rgb[2] * 255.0, 255.0]
                })
                .collect(),
        })
    }
}

/// RGB in [0, 1] to HSV with hue in [0, 6) (flam3's convention).
pub fn rgb_to_hsv(rgb: [f64; 3]) -> [f64; 3] {
    let [r, g, b] = rgb;
    let max = if r >= g { r.max(b) } else { g.max(b) };
    let min = if r <= g { r.min(b) } else { g.min(b) };
    let del = max - min;
    let v = max;
    let s = if max != 0.0 { del / max } else { 0.0 };
    let mut h = 0.0;
    if s != 0.0 {
        let rc = (max - r) / del;
        let gc = (max - g) / del;
        let bc = (max - b) / del;
        if r == max {
            h = bc - gc;
        } else if g == max {
            h = 2.0 + rc - bc;
        } else if b == max {
            h = 4.0 + gc - rc;
        }
        if h < 0.0 {
            h += 6.0;
        }
    }
    [h, s, v]
}

/// HSV (hue in [0, 6), wrapped) to RGB in [0, 1] (flam3's convention).
pub fn hsv_to_rgb(hsv: [f64; 3]) -> [f64; 3] {
    let [mut h, s, v] = hsv;
    if h.is_finite() {
        h = h.rem_euclid(6.0);
    } else {
        h = 0.0;
    }
    let j = h.floor();
    let f = h - j;
    let p = v * (1.0 - s);
    let q = v * (1.0 - s * f);
    let t = v * (1.0 - s * (1.0 - f));
    match j as i32 {
        0 => [v, t, p],
        1 => [q, v, p],
        2 => [p, v, t],
        3 => [p, q, v],
        4 => [t, p, v],
        5 => [v, p, q],
        _ => [v, t, p],
    }
}

/// Fills palette entries a file left out by linear interpolation between the nearest
/// given ones, wrapping around the ends (flam3's `flam3_interp_missing_colors`).
pub fn fill_missing(colors: &mut [Option<[f64; 4]>; 256]) -> Result<[[f64; 4]; 256]> {
    let known: Vec<usize> = (0..256).filter(|&i| colors[i].is_some()).collect();
    if known.is_empty() {
        return Err(Error::Empty("the palette has no colours".into()));
    }
    let mut out = [[0.0; 4]; 256];
    for i in 0..256 {
        if let Some(c) = colors[i] {
            out[i] = c;
            continue;
        }
        // Nearest known entries left and right, wrapping.
        let left = known.iter().rev().find(|&&k| k < i).copied();
        let right = known.iter().find(|&&k| k > i).copied();
        let (li, lpos) = match left {
            Some(k) => (k, k as f64),
            None => {
                let k = *known.last().expect("non-empty");
                (k, k as f64 - 256.0)
            }
        };
        let (ri, rpos) = match right {
            Some(k) => (k, k as f64),
            None => {
                let k = known[0];
                (k, k as f64 + 256.0)
            }
        };
        let t = (i as f64 - lpos) / (rpos - lpos);
        let (a, b) = (colors[li].expect("known"), colors[ri].expect("known"));
        for k in 0..4 {
            out[i][k] = (a[k] * (1.0 - t) + b[k] * t).clamp(0.0, 255.0);
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hsv_round_trip_keeps_colours() {
        for rgb in [
            [0.2, 0.4, 0.6],
            [1.0, 0.0, 0.5],
            [0.3, 0.3, 0.3],
            [0.0, 0.0, 0.0],
        ] {
            let back = hsv_to_rgb(rgb_to_hsv(rgb));
            for k in 0..3 {
                assert!((back[k] - rgb[k]).abs() < 1e-12, "{rgb:?} → {back:?}");
            }
        }
        // A half turn of hue takes red to cyan.
        let mut h = rgb_to_hsv([1.0, 0.0, 0.0]);
        h[0] += 3.0;
        assert_eq!(hsv_to_rgb(h), [0.0, 1.0, 1.0]);
    }

    #[test]
    fn missing_entries_are_interpolated_with_wraparound() {
        let mut c = [None; 256];
        c[0] = Some([0.0, 0.0, 0.0, 255.0]);
        c[100] = Some([100.0, 0.0, 0.0, 255.0]);
        let out = fill_missing(&mut c).unwrap();
        assert_eq!(out[50][0], 50.0);
        // 200 lies between 100 and 256 (= entry 0 wrapped).
        assert!((out[200][0] - 100.0 * (56.0 / 156.0)).abs() < 1e-12);
    }
}
