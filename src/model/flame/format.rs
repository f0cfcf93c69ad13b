//! `.flame` files: flam3's XML genome format, read and written.
//!
//! Reading follows flam3 3.1.1's parser: every `<flame>` element anywhere in the document
//! (`<flames>`, flam3-genome's `<pick>`, a bare `<flame>`), flame attributes with
//! flam3-render's defaults, palettes as `<color index rgb|rgba>` entries, `<colors>` or
//! `<palette count format>` hex data or a `palette="N"` library number (with `hue`),
//! missing entries interpolated; `<xform>`/`<finalxform>` with `weight`, `color`,
//! `color_speed` (or the older `symmetry`), `opacity` (or `plotmode="off"`), `coefs`,
//! `post`, `chaos`, variation weights by name (or the old `var`/`var1`) and variation
//! parameters; a `<symmetry kind>` element adds flam3's symmetry transforms.
//!
//! Where flam3 warns and carries on, this reader is stricter: malformed numbers, NaN or ∞,
//! an unknown variation, a palette index out of range, a missing `coefs`, or an empty
//! flame are errors naming the file, line, flame and transform. Attributes and child
//! elements it does not interpret (`version`, `time`, interpolation settings, `<edit>`,
//! other programs' extras) are kept and written back unchanged.
//!
//! An xform attribute that is not flam3's is taken for a variation (and refused as unknown)
//! when its value is a number and it is neither a known editor attribute (Apophysis'
//! `var_color`, `name`, JWildfire's `mod_*`, `material*`, …) nor a parameter of another
//! attribute of the same xform (`julia3D_power` beside `julia3D`).
//!
//! Writing produces a `<flames>` document flam3-render reads: the flame attributes flam3
//! writes, 256 `<color>` entries, variations and their parameters by name. Numbers are
//! written in the shortest form that reads back to the same `f64`, so read → write → read
//! gives an identical [`Flame`].

use std::path::Path;

use quick_xml::events::{BytesEnd, BytesStart, Event};

use crate::error::{Error, Result};
use crate::io::write_atomic;
use crate::model::flame::genome::{FilterShape, Flame, PaletteMode};
use crate::model::flame::palette::{Palette, fill_missing};
use crate::model::flame::variation::{Variation, VariationKind};
use crate::model::flame::xform::{IDENTITY, Xform};

/// Reads every flame of a `.flame` file.
pub fn read_flames(path: &Path) -> Result<Vec<Flame>> {
    let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
    parse_flames(&text, path)
}

/// Parses the text of a `.flame` file; `path` names it in errors.
pub fn parse_flames(text: &str, path: &Path) -> Result<Vec<Flame>> {
    let doc = roxmltree::Document::parse(text).map_err(|e| Error::FlameFile {
        path: path.to_owned(),
        location: format!("line {}, column {}", e.pos().row, e.pos().col),
        message: format!("not well-formed XML: {e}"),
    })?;
    let mut flames = Vec::new();
    collect_flames(doc.root(), &doc, text, path, &mut flames)?;
    if flames.is_empty() {
        return Err(Error::FlameFile {
            path: path.to_owned(),
            location: "document".into(),
            message: "no <flame> element".into(),
        });
    }
    Ok(flames)
}

fn collect_flames(
    node: roxmltree::Node,
    doc: &roxmltree::Document,
    text: &str,
    path: &Path,
    out: &mut Vec<Flame>,
) -> Result<()> {
    for child in node.children().filter(|n| n.is_element()) {
        if child.has_tag_name("flame") {
            let mut r = Reader {
                doc,
                text,
                path,
                index: out.len(),
                name: None,
            };
            out.push(r.flame(child)?);
        } else {
            collect_flames(child, doc, text, path, out)?;
        }
    }
    Ok(())
}

struct Reader<'a, 'input> {
    doc: &'a roxmltree::Document<'input>,
    text: &'a str,
    path: &'a Path,
    index: usize,
    name: Option<String>,
}

/// Attributes of `<xform>` that flam3 reads (besides variations and their parameters).
const XFORM_ATTRS: &[&str] = &[
    "weight",
    "symmetry",
    "color_speed",
    "animate",
    "color",
    "var1",
    "var",
    "chaos",
    "plotmode",
    "opacity",
    "coefs",
    "post",
];

/// Attributes other programs write on `<xform>` that are not variations (kept as they are).
const EDITOR_XFORM_ATTRS: &[&str] = &[
    "name",
    "var_color",
    "motion_frequency",
    "motion_function",
    "amw_amp",
    "material",
    "material_speed",
    "draw_mode",
    "color_type",
    "target_color",
];

/// Prefixes of other programs' non-variation `<xform>` attributes.
const EDITOR_XFORM_PREFIXES: &[&str] = &["mod_", "material_", "weighting_field", "wfield_"];

impl Reader<'_, '_> {
    fn flame_label(&self) -> String {
        match &self.name {
            Some(n) => format!("flame {} \"{}\"", self.index, n),
            None => format!("flame {}", self.index),
        }
    }

    fn at(&self, node: roxmltree::Node, what: &str) -> String {
        let pos = self.doc.text_pos_at(node.range().start);
        if what.is_empty() {
            format!("line {}, {}", pos.row, self.flame_label())
        } else {
            format!("line {}, {}, {what}", pos.row, self.flame_label())
        }
    }

    fn err(&self, node: roxmltree::Node, what: &str, message: impl Into<String>) -> Error {
        Error::FlameFile {
            path: self.path.to_owned(),
            location: self.at(node, what),
            message: message.into(),
        }
    }

    fn number(&self, node: roxmltree::Node, what: &str, attr: &str, s: &str) -> Result<f64> {
        let t = s.trim();
        let v: f64 = t.parse().map_err(|_| {
            self.err(
                node,
                what,
                format!("attribute {attr}=\"{s}\" is not a number"),
            )
        })?;
        if !v.is_finite() {
            return Err(self.err(
                node,
                what,
                format!("attribute {attr}=\"{s}\" is not finite; every number must be finite"),
            ));
        }
        Ok(v)
    }

    fn numbers<const N: usize>(
        &self,
        node: roxmltree::Node,
        what: &str,
        attr: &str,
        s: &str,
    ) -> Result<[f64; N]> {
        let parts: Vec<&str> = s.split_whitespace().collect();
        if parts.len() != N {
            return Err(self.err(
                node,
                what,
                format!(
                    "attribute {attr}=\"{s}\" has {} numbers; it needs {N}",
                    parts.len()
                ),
            ));
        }
        let mut out = [0.0; N];
        for (o, p) in out.iter_mut().zip(parts) {
            *o = self.number(node, what, attr, p)?;
        }
        Ok(out)
    }

    fn integer(&self, node: roxmltree::Node, what: &str, attr: &str, s: &str) -> Result<i64> {
        s.trim().parse().map_err(|_| {
            self.err(
                node,
                what,
                format!("attribute {attr}=\"{s}\" is not an integer"),
            )
        })
    }

    fn flame(&mut self, node: roxmltree::Node) -> Result<Flame> {
        self.name = node.attribute("name").map(str::to_string);
        let mut f = Flame {
            name: self.name.clone(),
            ..Flame::default()
        };
        let mut palette_number: Option<i64> = None;
        let mut hue = 0.0;
        let mut solo: Option<i64> = None;
        for a in node.attributes() {
            let (k, v) = (a.name(), a.value());
            let num = |r: &Self| r.number(node, "", k, v);
            match k {
                "name" => {}
                "size" => {
                    let [w, h] = self.numbers::<2>(node, "", k, v)?;
                    if w < 1.0
                        || h < 1.0
                        || w.fract() != 0.0
                        || h.fract() != 0.0
                        || w > 1e6
                        || h > 1e6
                    {
                        return Err(self.err(
                            node,
                            "",
                            format!("size=\"{v}\" must be two whole numbers ≥ 1"),
                        ));
                    }
                    f.size = [w as u32, h as u32];
                }
                "center" => f.center = self.numbers::<2>(node, "", k, v)?,
                "scale" => f.scale = num(self)?,
                "rotate" => f.rotate = num(self)?,
                "zoom" => f.zoom = num(self)?,
                "supersample" | "oversample" => {
                    let s = self.integer(node, "", k, v)?;
                    if !(1..=16).contains(&s) {
                        return Err(self.err(node, "", format!("{k}=\"{v}\" must lie in 1..=16")));
                    }
                    f.supersample = s as u32;
                }
                "filter" => f.filter = num(self)?,
                "filter_shape" => {
                    f.filter_shape = FilterShape::from_name(v.trim()).ok_or_else(|| {
                        self.err(
                            node,
                            "",
                            format!(
                                "unknown filter_shape \"{v}\"; known: {}",
                                FilterShape::ALL.map(|s| s.name()).join(", ")
                            ),
                        )
                    })?
                }
                "quality" => f.quality = num(self)?,
                "passes" => {
                    let p = self.integer(node, "", k, v)?;
                    if p < 1 {
                        return Err(self.err(node, "", format!("passes=\"{v}\" must be ≥ 1")));
                    }
                    f.passes = p as u32;
                }
                "temporal_samples" => {
                    let t = self.integer(node, "", k, v)?;
                    f.temporal_samples = t.max(1) as u32;
                }
                "background" => f.background = self.numbers::<3>(node, "", k, v)?,
                "brightness" => f.brightness = num(self)?,
                "gamma" => f.gamma = num(self)?,
                "highlight_power" => f.highlight_power = num(self)?,
                "vibrancy" => f.vibrancy = num(self)?,
                "hue" => hue = num(self)? % 1.0,
                "estimator_radius" => f.estimator_radius = num(self)?,
                "estimator_minimum" => f.estimator_minimum = num(self)?,
                "estimator_curve" => f.estimator_curve = num(self)?,
                "gamma_threshold" => f.gamma_threshold = num(self)?,
                "palette" => palette_number = Some(self.integer(node, "", k, v)?),
                "palette_mode" => {
                    f.palette_mode = match v.trim() {
                        "step" => PaletteMode::Step,
                        "linear" => PaletteMode::Linear,
                        _ => {
                            return Err(self.err(
                                node,
                                "",
                                format!("palette_mode=\"{v}\" must be step or linear"),
                            ));
                        }
                    }
                }
                "soloxform" => {
                    solo = Some(self.integer(node, "", k, v)?);
                    f.extra.push((k.to_string(), v.to_string()));
                }
                _ => f.extra.push((k.to_string(), v.to_string())),
            }
        }

        let mut colors: [Option<[f64; 4]>; 256] = [None; 256];
        let mut xforms: Vec<Xform> = Vec::new();
        let mut final_xform: Option<Xform> = None;
        for child in node.children() {
            if !child.is_element() {
                continue;
            }
            match child.tag_name().name() {
                "color" => self.color(child, &mut colors)?,
                "colors" => {
                    let count = child
                        .attribute("count")
                        .map(|c| self.integer(child, "<colors>", "count", c))
                        .transpose()?
                        .unwrap_or(0);
                    let data = child.attribute("data").unwrap_or("");
                    self.hex_colors(child, "<colors>", data, count, HexKind::Padded, &mut colors)?;
                }
                "palette" => {
                    if child.attribute("index0").is_some() || child.attribute("index1").is_some() {
                        return Err(self.err(
                            child,
                            "<palette>",
                            "the old interpolated-palette form (index0/index1/blend) is not \
                             supported; give the colours",
                        ));
                    }
                    let count = child
                        .attribute("count")
                        .map(|c| self.integer(child, "<palette>", "count", c))
                        .transpose()?
                        .unwrap_or(256);
                    let kind = match child.attribute("format").unwrap_or("RGB") {
                        "RGB" => HexKind::Rgb,
                        "RGBA" => HexKind::Rgba,
                        other => {
                            return Err(self.err(
                                child,
                                "<palette>",
                                format!("format=\"{other}\" must be RGB or RGBA"),
                            ));
                        }
                    };
                    let data: String = child
                        .descendants()
                        .filter(|n| n.is_text())
                        .filter_map(|n| n.text())
                        .collect();
                    self.hex_colors(child, "<palette>", &data, count, kind, &mut colors)?;
                }
                "symmetry" => {
                    if f.symmetry.is_some() {
                        return Err(self.err(child, "<symmetry>", "more than one <symmetry>"));
                    }
                    let kind = child
                        .attribute("kind")
                        .ok_or_else(|| self.err(child, "<symmetry>", "missing kind"))?;
                    let kind = self.integer(child, "<symmetry>", "kind", kind)?;
                    if kind == 0 || kind.abs() > 1000 {
                        return Err(self.err(
                            child,
                            "<symmetry>",
                            format!(
                                "kind=\"{kind}\" must be a non-zero symmetry order (|kind| ≤ 1000)"
                            ),
                        ));
                    }
                    f.symmetry = Some(kind as i32);
                    xforms.extend(symmetry_xforms(kind as i32));
                }
                "xform" => {
                    let what = format!("xform {}", xforms.len());
                    xforms.push(self.xform(child, &what, false)?);
                }
                "finalxform" => {
                    if final_xform.is_some() {
                        return Err(self.err(child, "<finalxform>", "more than one <finalxform>"));
                    }
                    final_xform = Some(self.xform(child, "final xform", true)?);
                }
                _ => {
                    let r = child.range();
                    f.extra_children.push(self.text[r].to_string());
                }
            }
        }
        if xforms.is_empty() {
            return Err(self.err(node, "", "the flame has no <xform>"));
        }
        if let Some(s) = solo
            && s >= 0
        {
            for (i, x) in xforms.iter_mut().enumerate() {
                if i as i64 != s {
                    x.opacity = 0.0;
                }
            }
        }
        f.xforms = xforms;
        f.final_xform = final_xform;

        f.palette = if let Some(n) = palette_number.filter(|&n| n != -1) {
            Palette::from_library(n, hue).map_err(|e| self.err(node, "palette", e.to_string()))?
        } else if colors.iter().all(Option::is_none) {
            return Err(self.err(
                node,
                "",
                "the flame has no palette (no <color>, <colors>, <palette> or palette=\"N\")",
            ));
        } else {
            Palette {
                colors: fill_missing(&mut colors)?.to_vec(),
            }
        };
        f.validate().map_err(|e| match e {
            Error::FlameFile { .. } => e,
            other => self.err(node, "", other.to_string()),
        })?;
        Ok(f)
    }

    fn color(&self, node: roxmltree::Node, colors: &mut [Option<[f64; 4]>; 256]) -> Result<()> {
        let what = "<color>";
        let mut index: Option<i64> = None;
        let (mut rgb, mut a) = ([0.0; 3], 255.0);
        for at in node.attributes() {
            let (k, v) = (at.name(), at.value());
            match k {
                "index" => index = Some(self.integer(node, what, k, v)?),
                "rgb" => rgb = self.numbers::<3>(node, what, k, v)?,
                "rgba" => {
                    let c = self.numbers::<4>(node, what, k, v)?;
                    rgb = [c[0], c[1], c[2]];
                    a = c[3];
                }
                "a" => a = self.number(node, what, k, v)?,
                _ => {
                    return Err(self.err(node, what, format!("unknown attribute `{k}`")));
                }
            }
        }
        let index = index.ok_or_else(|| self.err(node, what, "missing index"))?;
        if !(0..=255).contains(&index) {
            return Err(self.err(
                node,
                what,
                format!("palette index {index} is out of range; indices run 0–255"),
            ));
        }
        for (k, &c) in rgb.iter().chain([&a]).enumerate() {
            if !(0.0..=255.0).contains(&c) {
                return Err(self.err(
                    node,
                    what,
                    format!("colour {index} channel {k} is {c}; channels lie in 0–255"),
                ));
            }
        }
        colors[index as usize] = Some([rgb[0], rgb[1], rgb[2], a]);
        Ok(())
    }

    fn hex_colors(
        &self,
        node: roxmltree::Node,
        what: &str,
        data: &str,
        count: i64,
        kind: HexKind,
        colors: &mut [Option<[f64; 4]>; 256],
    ) -> Result<()> {
        if !(0..=256).contains(&count) {
            return Err(self.err(node, what, format!("count=\"{count}\" must lie in 0–256")));
        }
        let hex: Vec<u8> = data.bytes().filter(|b| !b.is_ascii_whitespace()).collect();
        let width = match kind {
            HexKind::Rgb => 6,
            HexKind::Rgba | HexKind::Padded => 8,
        };
        if hex.len() != count as usize * width {
            return Err(self.err(
                node,
                what,
                format!(
                    "{} hex digits for {count} colours of {width} digits each",
                    hex.len()
                ),
            ));
        }
        for i in 0..count as usize {
            let chunk = &hex[i * width..(i + 1) * width];
            let byte = |k: usize| -> Result<f64> {
                std::str::from_utf8(&chunk[k..k + 2])
                    .ok()
                    .and_then(|s| u8::from_str_radix(s, 16).ok())
                    .map(f64::from)
                    .ok_or_else(|| {
                        self.err(
                            node,
                            what,
                            format!(
                                "colour {i}: \"{}\" is not hexadecimal",
                                String::from_utf8_lossy(chunk)
                            ),
                        )
                    })
            };
            colors[i] = Some(match kind {
                HexKind::Rgb => [byte(0)?, byte(2)?, byte(4)?, 255.0],
                HexKind::Rgba => [byte(0)?, byte(2)?, byte(4)?, byte(6)?],
                HexKind::Padded => [byte(2)?, byte(4)?, byte(6)?, 255.0],
            });
        }
        Ok(())
    }

    fn xform(&self, node: roxmltree::Node, what: &str, is_final: bool) -> Result<Xform> {
        let mut x = Xform {
            variations: Vec::new(),
            weight: 0.0,
            ..Xform::default()
        };
        let mut weights: Vec<(VariationKind, f64)> = Vec::new();
        let mut params: Vec<(String, f64)> = Vec::new();
        let mut saw_coefs = false;
        let attr_names: Vec<&str> = node.attributes().map(|a| a.name()).collect();
        for at in node.attributes() {
            let (k, v) = (at.name(), at.value());
            match k {
                "weight" => {
                    x.weight = self.number(node, what, k, v)?;
                    if is_final && x.weight != 0.0 {
                        return Err(self.err(node, what, "a final xform has no weight"));
                    }
                }
                "symmetry" => {
                    let s = self.number(node, what, k, v)?;
                    x.color_speed = (1.0 - s) / 2.0;
                    x.animate = if s > 0.0 { 0.0 } else { 1.0 };
                }
                "color_speed" => x.color_speed = self.number(node, what, k, v)?,
                "animate" => x.animate = self.number(node, what, k, v)?,
                "color" => {
                    let first = v.split_whitespace().next().unwrap_or("");
                    if v.split_whitespace().count() > 2 {
                        return Err(self.err(node, what, format!("color=\"{v}\" is malformed")));
                    }
                    x.color = self.number(node, what, k, first)?;
                }
                "var1" => {
                    let i = self.integer(node, what, k, v)?;
                    let kind = usize::try_from(i)
                        .ok()
                        .and_then(VariationKind::from_index)
                        .ok_or_else(|| {
                            self.err(
                                node,
                                what,
                                format!("var1=\"{v}\" is not a variation number (0–98)"),
                            )
                        })?;
                    weights.clear();
                    weights.push((kind, 1.0));
                }
                "var" => {
                    let vals: Vec<&str> = v.split_whitespace().collect();
                    if vals.len() != 99 {
                        return Err(self.err(
                            node,
                            what,
                            format!("var has {} weights; flam3 writes 99", vals.len()),
                        ));
                    }
                    weights.clear();
                    for (i, s) in vals.iter().enumerate() {
                        let w = self.number(node, what, k, s)?;
                        if w != 0.0 {
                            weights.push((VariationKind::ALL[i], w));
                        }
                    }
                }
                "chaos" => {
                    let mut row = Vec::new();
                    for s in v.split_whitespace() {
                        row.push(self.number(node, what, k, s)?);
                    }
                    while row.last() == Some(&1.0) {
                        row.pop();
                    }
                    if row.iter().any(|&c| c < 0.0) {
                        return Err(self.err(node, what, "xaos (chaos) entries must be ≥ 0"));
                    }
                    x.chaos = row;
                }
                "plotmode" => {
                    if v.trim() == "off" {
                        x.opacity = 0.0;
                    }
                    x.extra.push((k.to_string(), v.to_string()));
                }
                "opacity" => x.opacity = self.number(node, what, k, v)?,
                "coefs" => {
                    x.coefs = self.numbers::<6>(node, what, k, v)?;
                    saw_coefs = true;
                }
                "post" => x.post = self.numbers::<6>(node, what, k, v)?,
                _ => {
                    if let Some(kind) = VariationKind::from_name(k) {
                        let w = self.number(node, what, k, v)?;
                        weights.retain(|(kk, _)| *kk != kind);
                        weights.push((kind, w));
                    } else if VariationKind::param_owner(k).is_some() {
                        params.push((k.to_string(), self.number(node, what, k, v)?));
                    } else if is_unknown_variation(k, v, &attr_names) {
                        return Err(Error::UnknownVariation {
                            name: k.to_string(),
                            path: self.path.to_owned(),
                            location: self.at(node, what),
                        });
                    } else {
                        x.extra.push((k.to_string(), v.to_string()));
                    }
                }
            }
        }
        if !saw_coefs {
            return Err(self.err(node, what, "missing coefs (the pre-affine map a b c d e f)"));
        }
        if node.children().any(|c| c.is_element()) {
            return Err(self.err(
                node,
                what,
                "child elements of an xform (flam3 <motion>) are not supported",
            ));
        }
        for (kind, w) in weights {
            if w != 0.0 {
                x.variations.push(Variation::new(kind, w));
            }
        }
        x.sort_variations();
        for (name, value) in params {
            let (owner, _) = VariationKind::param_owner(&name).expect("checked");
            match x.variations.iter_mut().find(|v| v.kind() == owner) {
                Some(var) => var.set_param(&name, value)?,
                // A parameter of a variation this xform does not use: flam3 stores it and
                // ignores it; keep it for the round trip.
                None => x.extra.push((name, fmt_num(value))),
            }
        }
        if is_final {
            x.weight = 0.0;
        }
        Ok(x)
    }
}

#[derive(Clone, Copy)]
enum HexKind {
    /// `<palette format="RGB">`: RRGGBB.
    Rgb,
    /// `<palette format="RGBA">`: RRGGBBAA.
    Rgba,
    /// `<colors data>`: 00RRGGBB.
    Padded,
}

/// Whether an xform attribute flam3 does not know must be an unknown variation.
fn is_unknown_variation(name: &str, value: &str, all: &[&str]) -> bool {
    if XFORM_ATTRS.contains(&name)
        || EDITOR_XFORM_ATTRS.contains(&name)
        || EDITOR_XFORM_PREFIXES.iter().any(|p| name.starts_with(p))
    {
        return false;
    }
    if value.trim().parse::<f64>().is_err() {
        return false;
    }
    // `julia3D_power` beside `julia3D`: a parameter of another attribute.
    !all.iter().any(|other| {
        *other != name
            && name.len() > other.len() + 1
            && name.starts_with(other)
            && name.as_bytes()[other.len()] == b'_'
    })
}

/// The transforms flam3 adds for a `<symmetry kind>` element (`flam3_add_symmetry`):
/// a reflection x ↦ −x when `kind < 0`, and rotations by multiples of 2π/|kind|, all
/// linear with weight 1 and colour speed 0, ordered by determinant as flam3 sorts them.
pub fn symmetry_xforms(kind: i32) -> Vec<Xform> {
    let base = Xform {
        weight: 1.0,
        color_speed: 0.0,
        animate: 0.0,
        color: 1.0,
        from_symmetry: true,
        ..Xform::default()
    };
    let mut out = Vec::new();
    if kind == 1 || kind == 0 {
        return out;
    }
    let mut sym = kind;
    if sym < 0 {
        out.push(Xform {
            coefs: [-1.0, 0.0, 0.0, 1.0, 0.0, 0.0],
            ..base.clone()
        });
        sym = -sym;
    }
    let a = 2.0 * std::f64::consts::PI / sym as f64;
    for k in 1..sym {
        let c = round6((k as f64 * a).cos());
        let s = round6((k as f64 * a).sin());
        out.push(Xform {
            coefs: [c, s, round6(-s), c, 0.0, 0.0],
            color: if sym < 3 {
                0.0
            } else {
                (k as f64 - 1.0) / (sym as f64 - 2.0)
            },
            ..base.clone()
        });
    }
    // flam3 sorts the added transforms by determinant (colour speeds are all 0).
    out.sort_by(|a, b| {
        let da = a.coefs[0] * a.coefs[3] - a.coefs[1] * a.coefs[2];
        let db = b.coefs[0] * b.coefs[3] - b.coefs[1] * b.coefs[2];
        da.total_cmp(&db)
    });
    out
}

/// flam3's `round6`: rounding to 6 decimals (towards −∞ for negatives, as flam3 does).
fn round6(x: f64) -> f64 {
    let mut x = x * 1e6;
    if x < 0.0 {
        x -= 1.0;
    }
    1e-6 * ((x + 0.5) as i64) as f64
}

/// `v` in the shortest form that reads back to the same `f64` (plain notation unless the
/// exponent is extreme).
pub fn fmt_num(v: f64) -> String {
    if v == 0.0 {
        return "0".into();
    }
    let a = v.abs();
    if (1e-5..1e16).contains(&a) {
        format!("{v}")
    } else {
        format!("{v:e}")
    }
}

fn join(vals: &[f64]) -> String {
    vals.iter()
        .map(|&v| fmt_num(v))
        .collect::<Vec<_>>()
        .join(" ")
}

/// Writes flames as a `.flame` document.
pub fn write_flames(path: &Path, flames: &[Flame]) -> Result<()> {
    let bytes = flames_to_string(flames)?;
    write_atomic(path, bytes.as_bytes())
}

/// The `.flame` document for `flames`.
pub fn flames_to_string(flames: &[Flame]) -> Result<String> {
    let mut w = quick_xml::Writer::new_with_indent(Vec::new(), b' ', 3);
    let xml_err = |e: std::io::Error| Error::io("<memory>", e);
    w.write_event(Event::Start(BytesStart::new("flames")))
        .map_err(xml_err)?;
    for f in flames {
        write_flame(&mut w, f).map_err(xml_err)?;
    }
    w.write_event(Event::End(BytesEnd::new("flames")))
        .map_err(xml_err)?;
    let mut s = String::from_utf8(w.into_inner()).expect("UTF-8 in, UTF-8 out");
    s.push('\n');
    Ok(s)
}

fn write_flame(w: &mut quick_xml::Writer<Vec<u8>>, f: &Flame) -> std::io::Result<()> {
    let mut e = BytesStart::new("flame");
    if let Some(n) = &f.name {
        e.push_attribute(("name", n.as_str()));
    }
    let attrs: Vec<(&str, String)> = vec![
        ("size", format!("{} {}", f.size[0], f.size[1])),
        ("center", join(&f.center)),
        ("scale", fmt_num(f.scale)),
        ("zoom", fmt_num(f.zoom)),
        ("rotate", fmt_num(f.rotate)),
        ("supersample", f.supersample.to_string()),
        ("filter", fmt_num(f.filter)),
        ("filter_shape", f.filter_shape.name().to_string()),
        ("quality", fmt_num(f.quality)),
        ("passes", f.passes.to_string()),
        ("temporal_samples", f.temporal_samples.to_string()),
        ("background", join(&f.background)),
        ("brightness", fmt_num(f.brightness)),
        ("gamma", fmt_num(f.gamma)),
        ("highlight_power", fmt_num(f.highlight_power)),
        ("vibrancy", fmt_num(f.vibrancy)),
        ("estimator_radius", fmt_num(f.estimator_radius)),
        ("estimator_minimum", fmt_num(f.estimator_minimum)),
        ("estimator_curve", fmt_num(f.estimator_curve)),
        ("gamma_threshold", fmt_num(f.gamma_threshold)),
        (
            "palette_mode",
            match f.palette_mode {
                PaletteMode::Step => "step",
                PaletteMode::Linear => "linear",
            }
            .to_string(),
        ),
    ];
    for (k, v) in &attrs {
        e.push_attribute((*k, v.as_str()));
    }
    for (k, v) in &f.extra {
        e.push_attribute((k.as_str(), v.as_str()));
    }
    w.write_event(Event::Start(e))?;
    if let Some(k) = f.symmetry {
        let mut s = BytesStart::new("symmetry");
        s.push_attribute(("kind", k.to_string().as_str()));
        w.write_event(Event::Empty(s))?;
    }
    for x in f.xforms.iter().filter(|x| !x.from_symmetry) {
        write_xform(w, x, false)?;
    }
    if let Some(x) = &f.final_xform {
        write_xform(w, x, true)?;
    }
    for (i, c) in f.palette.colors.iter().enumerate() {
        let mut e = BytesStart::new("color");
        e.push_attribute(("index", i.to_string().as_str()));
        if c[3] == 255.0 {
            e.push_attribute(("rgb", join(&c[..3]).as_str()));
        } else {
            e.push_attribute(("rgba", join(c).as_str()));
        }
        w.write_event(Event::Empty(e))?;
    }
    for raw in &f.extra_children {
        w.get_mut().extend_from_slice(b"\n   ");
        w.get_mut().extend_from_slice(raw.as_bytes());
    }
    w.write_event(Event::End(BytesEnd::new("flame")))?;
    Ok(())
}

fn write_xform(
    w: &mut quick_xml::Writer<Vec<u8>>,
    x: &Xform,
    is_final: bool,
) -> std::io::Result<()> {
    let mut e = BytesStart::new(if is_final { "finalxform" } else { "xform" });
    let mut attrs: Vec<(String, String)> = Vec::new();
    if !is_final {
        attrs.push(("weight".into(), fmt_num(x.weight)));
    }
    attrs.push(("color".into(), fmt_num(x.color)));
    attrs.push(("color_speed".into(), fmt_num(x.color_speed)));
    // Written for the final transform too, whose `animate` an older `symmetry` attribute
    // may have cleared, so that a read file writes back to the same flame.
    if !is_final || x.animate != 1.0 {
        attrs.push(("animate".into(), fmt_num(x.animate)));
    }
    for v in &x.variations {
        attrs.push((v.kind().name().into(), fmt_num(v.weight)));
    }
    for v in &x.variations {
        for ((name, _), &p) in v.kind().params().iter().zip(v.params()) {
            attrs.push(((*name).into(), fmt_num(p)));
        }
    }
    attrs.push(("coefs".into(), join(&x.coefs)));
    if x.post != IDENTITY {
        attrs.push(("post".into(), join(&x.post)));
    }
    if !is_final && !x.chaos.is_empty() {
        attrs.push(("chaos".into(), join(&x.chaos)));
    }
    attrs.push(("opacity".into(), fmt_num(x.opacity)));
    for (k, v) in &x.extra {
        attrs.push((k.clone(), v.clone()));
    }
    for (k, v) in &attrs {
        e.push_attribute((k.as_str(), v.as_str()));
    }
    w.write_event(Event::Empty(e))?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn numbers_are_written_to_read_back_exactly() {
        for v in [0.1, -1.0 / 3.0, 1e-20, 6.02e23, 255.0, -0.0, 123456.789] {
            let s = fmt_num(v);
            assert_eq!(s.parse::<f64>().unwrap(), v, "{s}");
        }
    }

    #[test]
    fn symmetry_matches_flam3s_transforms() {
        // kind −2: a reflection and a half turn, sorted by determinant (−1 first).
        let s = symmetry_xforms(-2);
        assert_eq!(s.len(), 2);
        assert_eq!(s[0].coefs, [-1.0, 0.0, 0.0, 1.0, 0.0, 0.0]);
        assert_eq!(s[1].coefs[0], -1.0);
        assert!(s[1].coefs[1].abs() < 1e-6);
        assert!(s.iter().all(|x| x.color_speed == 0.0 && x.weight == 1.0));
        assert_eq!(symmetry_xforms(1).len(), 0);
        assert_eq!(symmetry_xforms(5).len(), 4);
    }

    #[test]
    fn parameter_of_another_attribute_is_not_a_variation() {
        let all = ["julia3D", "julia3D_power", "coefs"];
        assert!(is_unknown_variation("julia3D", "1", &all));
        assert!(!is_unknown_variation("julia3D_power", "2", &all));
        assert!(!is_unknown_variation("mod_gamma", "1", &all));
        assert!(!is_unknown_variation("material", "0", &all));
        assert!(!is_unknown_variation("label", "hello", &all));
    }
}
