//! A tile request, checked before any work: whole numbers only, the level, position and size
//! in range, a known mode and colour map, no unknown or repeated parameter; a refusal is a
//! [`TileError`] naming the parameter.

use super::*;

/// How a tile is drawn.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TileMode {
    /// Binary coverage of a code's attractor (a colour map's brightest colour).
    Coverage,
    /// A code's log density through a colour map.
    Density,
    /// A flame's own colours and tone map.
    Colour,
}

impl TileMode {
    /// The mode's name in a request.
    pub fn name(self) -> &'static str {
        match self {
            TileMode::Coverage => "coverage",
            TileMode::Density => "density",
            TileMode::Colour => "colour",
        }
    }

    fn from_name(name: &str) -> Option<Self> {
        [TileMode::Coverage, TileMode::Density, TileMode::Colour]
            .into_iter()
            .find(|m| m.name() == name)
    }
}

/// A tile request refused, with the parameter to change.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum TileError {
    /// A parameter the endpoint needs is absent.
    Missing(&'static str),
    /// A parameter the endpoint does not know.
    Unknown(String),
    /// A parameter given twice.
    Repeated(String),
    /// A parameter whose value is out of range or not a number.
    Invalid {
        /// The parameter.
        param: &'static str,
        /// What it must be, and what it was.
        reason: String,
    },
}

impl fmt::Display for TileError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            TileError::Missing(p) => write!(f, "tile parameter `{p}` is missing"),
            TileError::Unknown(p) => write!(
                f,
                "unknown tile parameter `{p}` (known: level, x, y, size, mode, cmap, gen, sid)"
            ),
            TileError::Repeated(p) => write!(f, "tile parameter `{p}` is given twice"),
            TileError::Invalid { param, reason } => {
                write!(f, "bad tile parameter `{param}`: {reason}")
            }
        }
    }
}

impl std::error::Error for TileError {}

/// One tile: where, how big, drawn how, and which view generation asked for it.
#[derive(Clone, Debug, PartialEq)]
pub struct TileRequest {
    /// Level: the base window cut into `2^level` tiles a side.
    pub level: u32,
    /// Column, from the left.
    pub x: u64,
    /// Row, from the top.
    pub y: u64,
    /// Side in pixels.
    pub size: u32,
    /// Density or binary coverage (codes), or colour (flames).
    pub mode: TileMode,
    /// Colour map of the inked pixels.
    pub cmap: Colormap,
    /// The page's view generation and the page's id: a tile of a generation older than the
    /// latest its page asked for is skipped (`None`: never skipped).
    pub generation: Option<(u64, u64)>,
}

impl TileRequest {
    /// Parses and checks a query string (`level=3&x=1&y=5&mode=density…`) against `tiling`
    /// and the view's `modes` (the first one when the request names none).
    pub fn parse(query: &str, tiling: &Tiling, modes: &[TileMode]) -> Result<Self, TileError> {
        let mut seen: Vec<&str> = Vec::new();
        let (mut level, mut x, mut y) = (None, None, None);
        let (mut size, mut mode, mut cmap) = (TILE_SIZE_DEFAULT, modes[0], Colormap::default());
        let (mut gen_, mut sid) = (None, None);
        for pair in query.split('&').filter(|p| !p.is_empty()) {
            let (key, value) = pair.split_once('=').unwrap_or((pair, ""));
            if seen.contains(&key) {
                return Err(TileError::Repeated(shown(key)));
            }
            seen.push(key);
            match key {
                "level" => level = Some(whole("level", value, tiling.max_level as u64)? as u32),
                "x" => x = Some(value),
                "y" => y = Some(value),
                "size" => {
                    size = whole("size", value, TILE_SIZE_MAX as u64)? as u32;
                    if size < TILE_SIZE_MIN {
                        return Err(TileError::Invalid {
                            param: "size",
                            reason: format!(
                                "must lie in {TILE_SIZE_MIN}..={TILE_SIZE_MAX} pixels, got {size}"
                            ),
                        });
                    }
                }
                "mode" => {
                    mode = match TileMode::from_name(value) {
                        Some(m) if modes.contains(&m) => m,
                        _ => {
                            let names: Vec<String> =
                                modes.iter().map(|m| format!("`{}`", m.name())).collect();
                            return Err(TileError::Invalid {
                                param: "mode",
                                reason: format!(
                                    "must be {} for this view, got `{}`",
                                    names.join(" or "),
                                    shown(value)
                                ),
                            });
                        }
                    }
                }
                "cmap" => {
                    cmap = Colormap::from_name(value).ok_or_else(|| TileError::Invalid {
                        param: "cmap",
                        reason: format!(
                            "must be one of {}, got `{}`",
                            Colormap::NAMES.join(", "),
                            shown(value)
                        ),
                    })?
                }
                "gen" => gen_ = Some(whole("gen", value, u64::MAX)?),
                "sid" => sid = Some(whole("sid", value, u64::MAX)?),
                _ => return Err(TileError::Unknown(shown(key))),
            }
        }
        let level = level.ok_or(TileError::Missing("level"))?;
        // Columns and rows are checked against their level's count.
        let last = (1u64 << level) - 1;
        let x = whole("x", x.ok_or(TileError::Missing("x"))?, last)?;
        let y = whole("y", y.ok_or(TileError::Missing("y"))?, last)?;
        let generation = match (gen_, sid) {
            (Some(g), Some(s)) => Some((s, g)),
            (None, None) => None,
            _ => {
                return Err(TileError::Invalid {
                    param: if gen_.is_some() { "sid" } else { "gen" },
                    reason: "`gen` and `sid` come together (a page's view generation and its id)"
                        .into(),
                });
            }
        };
        Ok(TileRequest {
            level,
            x,
            y,
            size,
            mode,
            cmap,
            generation,
        })
    }

    /// The request without its generation: what makes two tiles the same picture.
    pub fn key(&self) -> String {
        format!(
            "{}/{}/{}/{}/{}/{}",
            self.level,
            self.x,
            self.y,
            self.size,
            self.mode.name(),
            self.cmap.name()
        )
    }
}

/// A parameter's value as a whole number in `0..=max`.
pub(super) fn whole(param: &'static str, value: &str, max: u64) -> Result<u64, TileError> {
    let bad = |what: &str| TileError::Invalid {
        param,
        reason: format!(
            "must be a whole number in 0..={max}{what}, got `{}`",
            shown(value)
        ),
    };
    if value.is_empty() || !value.bytes().all(|b| b.is_ascii_digit()) {
        return Err(bad(""));
    }
    match value.parse::<u64>() {
        Ok(v) if v <= max => Ok(v),
        _ if param == "level" => Err(bad(
            " (deeper tiles would be narrower than the renderer's double-precision bound here)",
        )),
        _ => Err(bad("")),
    }
}

/// A request's text as an error message shows it: at most 40 characters, no control
/// characters.
pub(super) fn shown(s: &str) -> String {
    let mut out: String = s
        .chars()
        .take(40)
        .map(|c| if c.is_control() { '?' } else { c })
        .collect();
    if s.chars().count() > 40 {
        out.push('…');
    }
    out
}
