//! Colour maps for tiles: a pixel value in (0, 1] to a colour (0 stays transparent).

/// A colour map by name.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Colormap {
    /// matplotlib's inferno (perceptually uniform, dark to pale yellow).
    #[default]
    Inferno,
    /// matplotlib's viridis.
    Viridis,
    /// Grey levels.
    Grey,
    /// White ink whatever the value (a binary view of the attractor).
    White,
}

/// Stops of inferno and viridis, evenly spaced (sampled from matplotlib's tables).
const INFERNO: [[u8; 3]; 9] = [
    [0, 0, 4],
    [31, 12, 72],
    [85, 15, 109],
    [136, 34, 106],
    [186, 54, 85],
    [227, 89, 51],
    [249, 140, 10],
    [249, 201, 50],
    [252, 255, 164],
];
const VIRIDIS: [[u8; 3]; 9] = [
    [68, 1, 84],
    [71, 45, 123],
    [59, 82, 139],
    [44, 114, 142],
    [33, 145, 140],
    [40, 174, 128],
    [94, 201, 98],
    [173, 220, 48],
    [253, 231, 37],
];

/// Where the lowest inked value starts on a map: the maps' dark ends would vanish against
/// the page's black background.
const FLOOR: f32 = 0.25;

impl Colormap {
    /// The names a request may use.
    pub const NAMES: [&'static str; 4] = ["inferno", "viridis", "grey", "white"];

    /// The map called `name`.
    pub fn from_name(name: &str) -> Option<Self> {
        match name {
            "inferno" => Some(Colormap::Inferno),
            "viridis" => Some(Colormap::Viridis),
            "grey" | "gray" => Some(Colormap::Grey),
            "white" => Some(Colormap::White),
            _ => None,
        }
    }

    /// The map's name.
    pub fn name(self) -> &'static str {
        match self {
            Colormap::Inferno => "inferno",
            Colormap::Viridis => "viridis",
            Colormap::Grey => "grey",
            Colormap::White => "white",
        }
    }

    /// The colour of an inked pixel of value `v` (clamped to (0, 1]).
    pub fn colour(self, v: f32) -> [u8; 3] {
        let t = FLOOR + (1.0 - FLOOR) * v.clamp(0.0, 1.0);
        match self {
            Colormap::Inferno => lerp(&INFERNO, t),
            Colormap::Viridis => lerp(&VIRIDIS, t),
            Colormap::Grey => {
                let g = (255.0 * t).round() as u8;
                [g, g, g]
            }
            Colormap::White => [255, 255, 255],
        }
    }
}

/// Linear interpolation between evenly spaced stops, `t` in [0, 1].
fn lerp(stops: &[[u8; 3]], t: f32) -> [u8; 3] {
    let f = t * (stops.len() - 1) as f32;
    let i = (f.floor() as usize).min(stops.len() - 2);
    let u = f - i as f32;
    let (a, b) = (stops[i], stops[i + 1]);
    std::array::from_fn(|k| (a[k] as f32 + u * (b[k] as f32 - a[k] as f32)).round() as u8)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_round_trip_and_ends_are_the_tables() {
        for n in Colormap::NAMES {
            assert_eq!(Colormap::from_name(n).unwrap().name(), n);
        }
        assert_eq!(Colormap::Inferno.colour(1.0), INFERNO[8]);
        assert_eq!(Colormap::Viridis.colour(1.0), VIRIDIS[8]);
        assert_eq!(lerp(&INFERNO, 0.0), INFERNO[0]);
        // The faintest ink is not the background's black.
        assert!(Colormap::Inferno.colour(0.0).iter().any(|&c| c > 40));
    }
}
