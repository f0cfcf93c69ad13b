//! A flame ("genome" in flam3): transforms, optional final transform, palette, camera and
//! the rendering settings a `.flame` file carries, with flam3-render's defaults.

use crate::error::{Error, Result};
use crate::model::flame::palette::Palette;
use crate::model::flame::xform::Xform;

/// Spatial filter kernels by the names `.flame` files use.
///
/// flam3 3.1.1 numbers the names in one order (`flam3.h`) and evaluates kernels by number
/// in another (`flam3_spatial_filter`), so several names render with a different kernel
/// than they say (e.g. `lanczos3` draws with Mitchell's). [`FilterShape::kernel`] returns
/// the kernel flam3 actually uses, so images match flam3's.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum FilterShape {
    /// `gaussian` (the default).
    #[default]
    Gaussian,
    /// `hermite`
    Hermite,
    /// `box`
    Box,
    /// `triangle`
    Triangle,
    /// `bell`
    Bell,
    /// `bspline`
    BSpline,
    /// `lanczos3`
    Lanczos3,
    /// `lanczos2`
    Lanczos2,
    /// `mitchell`
    Mitchell,
    /// `blackman`
    Blackman,
    /// `catrom`
    Catrom,
    /// `hamming`
    Hamming,
    /// `hanning`
    Hanning,
    /// `quadratic`
    Quadratic,
}

/// The filter functions flam3 evaluates (indexed as `flam3_spatial_filter` does).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Kernel {
    /// exp(−2x²)·√(2/π), support 1.5
    Gaussian,
    /// 2|t|³ − 3|t|² + 1, support 1
    Hermite,
    /// support 0.5
    Box,
    /// support 1
    Triangle,
    /// support 1.5
    Bell,
    /// support 2
    BSpline,
    /// Mitchell–Netravali (B = C = 1/3), support 2
    Mitchell,
    /// sinc · Blackman, support 1
    Blackman,
    /// Catmull–Rom, support 2
    Catrom,
    /// sinc · Hanning, support 1
    Hanning,
    /// sinc · Hamming, support 1
    Hamming,
    /// Lanczos-3 · sinc(x/3), support 3
    Lanczos3,
    /// Lanczos-2 · sinc(x/2), support 2
    Lanczos2,
    /// support 1.5
    Quadratic,
}

impl FilterShape {
    /// Every shape, in flam3's numbering.
    pub const ALL: [FilterShape; 14] = [
        FilterShape::Gaussian,
        FilterShape::Hermite,
        FilterShape::Box,
        FilterShape::Triangle,
        FilterShape::Bell,
        FilterShape::BSpline,
        FilterShape::Lanczos3,
        FilterShape::Lanczos2,
        FilterShape::Mitchell,
        FilterShape::Blackman,
        FilterShape::Catrom,
        FilterShape::Hamming,
        FilterShape::Hanning,
        FilterShape::Quadratic,
    ];

    /// The name in `.flame` files.
    pub fn name(self) -> &'static str {
        match self {
            FilterShape::Gaussian => "gaussian",
            FilterShape::Hermite => "hermite",
            FilterShape::Box => "box",
            FilterShape::Triangle => "triangle",
            FilterShape::Bell => "bell",
            FilterShape::BSpline => "bspline",
            FilterShape::Lanczos3 => "lanczos3",
            FilterShape::Lanczos2 => "lanczos2",
            FilterShape::Mitchell => "mitchell",
            FilterShape::Blackman => "blackman",
            FilterShape::Catrom => "catrom",
            FilterShape::Hamming => "hamming",
            FilterShape::Hanning => "hanning",
            FilterShape::Quadratic => "quadratic",
        }
    }

    /// The shape a file names.
    pub fn from_name(s: &str) -> Option<Self> {
        Self::ALL.iter().copied().find(|f| f.name() == s)
    }

    /// The kernel flam3 evaluates for this name (its number looked up in the kernel table).
    pub fn kernel(self) -> Kernel {
        const BY_NUMBER: [Kernel; 14] = [
            Kernel::Gaussian,
            Kernel::Hermite,
            Kernel::Box,
            Kernel::Triangle,
            Kernel::Bell,
            Kernel::BSpline,
            Kernel::Mitchell,
            Kernel::Blackman,
            Kernel::Catrom,
            Kernel::Hanning,
            Kernel::Hamming,
            Kernel::Lanczos3,
            Kernel::Lanczos2,
            Kernel::Quadratic,
        ];
        BY_NUMBER[Self::ALL.iter().position(|&f| f == self).expect("listed")]
    }
}

/// How a colour coordinate picks its palette colour.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum PaletteMode {
    /// The entry the coordinate falls in (flam3's default).
    #[default]
    Step,
    /// Linear interpolation between neighbouring entries.
    Linear,
}

/// A flame: what a `<flame>` element of a `.flame` file holds.
#[derive(Clone, Debug, PartialEq)]
pub struct Flame {
    /// `name`
    pub name: Option<String>,
    /// Output size in pixels (`size`).
    pub size: [u32; 2],
    /// Camera centre in flame coordinates (`center`).
    pub center: [f64; 2],
    /// Pixels per unit at zoom 0 (`scale`).
    pub scale: f64,
    /// Zoom: scale and sample density grow by 2^zoom (`zoom`).
    pub zoom: f64,
    /// Camera rotation in degrees about the centre (`rotate`).
    pub rotate: f64,
    /// Histogram supersampling per side (`supersample`, alias `oversample`).
    pub supersample: u32,
    /// Spatial filter radius in output pixels (`filter`).
    pub filter: f64,
    /// Spatial filter kernel (`filter_shape`).
    pub filter_shape: FilterShape,
    /// Samples per output pixel (`quality`).
    pub quality: f64,
    /// Rendering passes averaged (`passes`).
    pub passes: u32,
    /// Motion-blur time samples (`temporal_samples`; flam3-render forces 1 for stills, and
    /// so does this renderer).
    pub temporal_samples: u32,
    /// `gamma`
    pub gamma: f64,
    /// Density below which gamma is linearised (`gamma_threshold`).
    pub gamma_threshold: f64,
    /// `brightness`
    pub brightness: f64,
    /// Blend of per-channel gamma (0) and alpha-scaled colour (1) (`vibrancy`).
    pub vibrancy: f64,
    /// Desaturation of over-bright pixels; negative keeps flam3's old clipping
    /// (`highlight_power`).
    pub highlight_power: f64,
    /// Background colour, components in [0, 1] (`background`).
    pub background: [f64; 3],
    /// Density-estimation kernel radius for a single hit, 0 to disable (`estimator_radius`).
    pub estimator_radius: f64,
    /// Smallest density-estimation radius (`estimator_minimum`).
    pub estimator_minimum: f64,
    /// How fast the radius shrinks with density (`estimator_curve`).
    pub estimator_curve: f64,
    /// `palette_mode`
    pub palette_mode: PaletteMode,
    /// The colours.
    pub palette: Palette,
    /// The transforms the chaos game picks from.
    pub xforms: Vec<Xform>,
    /// Applied to every point before it is plotted; the orbit goes on from the point
    /// before it (`<finalxform>`).
    pub final_xform: Option<Xform>,
    /// The `kind` of a `<symmetry>` element, whose transforms are in [`Flame::xforms`]
    /// marked [`Xform::from_symmetry`].
    pub symmetry: Option<i32>,
    /// Attributes of `<flame>` this crate does not interpret, kept in order.
    pub extra: Vec<(String, String)>,
    /// Child elements of `<flame>` this crate does not interpret (e.g. `<edit>`), kept as
    /// XML text.
    pub extra_children: Vec<String>,
}

impl Default for Flame {
    /// flam3-render's defaults, no transforms, a grey palette.
    fn default() -> Self {
        Flame {
            name: None,
            size: [100, 100],
            center: [0.0, 0.0],
            scale: 50.0,
            zoom: 0.0,
            rotate: 0.0,
            supersample: 1,
            filter: 0.5,
            filter_shape: FilterShape::Gaussian,
            quality: 1.0,
            passes: 1,
            temporal_samples: 1000,
            gamma: 4.0,
            gamma_threshold: 0.01,
            brightness: 4.0,
            vibrancy: 1.0,
            highlight_power: -1.0,
            background: [0.0; 3],
            estimator_radius: 9.0,
            estimator_minimum: 0.0,
            estimator_curve: 0.4,
            palette_mode: PaletteMode::Step,
            palette: Palette::default(),
            xforms: Vec::new(),
            final_xform: None,
            symmetry: None,
            extra: Vec::new(),
            extra_children: Vec::new(),
        }
    }
}

impl Flame {
    /// A label for messages: the name, or `flame #index`.
    pub fn label(&self) -> String {
        match &self.name {
            Some(n) => format!("flame \"{n}\""),
            None => "flame (unnamed)".into(),
        }
    }

    /// Pixels per flame unit after zoom.
    pub fn pixels_per_unit(&self) -> f64 {
        self.scale * 2f64.powf(self.zoom)
    }

    /// Checks everything a render needs; the error names the field and the flame.
    pub fn validate(&self) -> Result<()> {
        let who = self.label();
        let finite = |name: &str, v: f64| -> Result<()> {
            if v.is_finite() {
                Ok(())
            } else {
                Err(Error::NonFinite {
                    what: who.clone(),
                    location: name.to_string(),
                    value: v,
                })
            }
        };
        for (n, v) in [
            ("center[0]", self.center[0]),
            ("center[1]", self.center[1]),
            ("scale", self.scale),
            ("zoom", self.zoom),
            ("rotate", self.rotate),
            ("filter", self.filter),
            ("quality", self.quality),
            ("gamma", self.gamma),
            ("gamma_threshold", self.gamma_threshold),
            ("brightness", self.brightness),
            ("vibrancy", self.vibrancy),
            ("highlight_power", self.highlight_power),
            ("estimator_radius", self.estimator_radius),
            ("estimator_minimum", self.estimator_minimum),
            ("estimator_curve", self.estimator_curve),
            ("background[0]", self.background[0]),
            ("background[1]", self.background[1]),
            ("background[2]", self.background[2]),
        ] {
            finite(n, v)?;
        }
        let bad =
            |name: &'static str, msg: String| Err(Error::param(name, format!("{who}: {msg}")));
        if self.size[0] == 0 || self.size[1] == 0 {
            return bad(
                "size",
                format!("{}×{} has no pixels", self.size[0], self.size[1]),
            );
        }
        if self.scale <= 0.0 || !self.pixels_per_unit().is_finite() || self.pixels_per_unit() <= 0.0
        {
            return bad(
                "scale",
                format!(
                    "the camera is degenerate: scale {} at zoom {} gives {} pixels per unit; \
                     it must be > 0",
                    self.scale,
                    self.zoom,
                    self.pixels_per_unit()
                ),
            );
        }
        if self.supersample == 0 || self.supersample > 16 {
            return bad(
                "supersample",
                format!("{} must lie in 1..=16", self.supersample),
            );
        }
        if self.quality <= 0.0 {
            return bad("quality", format!("{} must be > 0", self.quality));
        }
        if self.passes == 0 {
            return bad("passes", "must be at least 1".into());
        }
        if self.gamma <= 0.0 {
            return bad("gamma", format!("{} must be > 0", self.gamma));
        }
        if self.filter < 0.0 {
            return bad("filter", format!("{} must be ≥ 0", self.filter));
        }
        if self.estimator_radius < 0.0 || self.estimator_minimum < 0.0 {
            return bad(
                "estimator_radius",
                "density estimator radii must be ≥ 0".into(),
            );
        }
        if self.estimator_radius > 0.0 {
            if self.estimator_curve <= 0.0 {
                return bad(
                    "estimator_curve",
                    format!("{} must be > 0", self.estimator_curve),
                );
            }
            if self.estimator_radius < self.estimator_minimum {
                return bad(
                    "estimator_minimum",
                    format!(
                        "{} exceeds estimator_radius {}",
                        self.estimator_minimum, self.estimator_radius
                    ),
                );
            }
        }
        self.palette.validate(&who)?;
        if self.xforms.is_empty() {
            return Err(Error::Empty(format!("{who} has no transforms")));
        }
        for (i, x) in self.xforms.iter().enumerate() {
            x.validate(&format!("{who}, xform {i}"))?;
        }
        if let Some(f) = &self.final_xform {
            f.validate(&format!("{who}, final xform"))?;
        }
        if self.xforms.iter().all(|x| x.weight == 0.0) {
            return bad(
                "weight",
                "every transform has weight 0, so the chaos game cannot pick one".into(),
            );
        }
        for (i, x) in self.xforms.iter().enumerate() {
            if x.chaos.len() > self.xforms.len() {
                return bad(
                    "chaos",
                    format!(
                        "xform {i} has {} xaos entries for {} transforms",
                        x.chaos.len(),
                        self.xforms.len()
                    ),
                );
            }
            let reachable = self
                .xforms
                .iter()
                .enumerate()
                .any(|(j, y)| y.weight * x.chaos.get(j).copied().unwrap_or(1.0) > 0.0);
            if x.weight > 0.0 && !reachable {
                return bad(
                    "chaos",
                    format!("xform {i}'s xaos row gives every following transform weight 0"),
                );
            }
        }
        Ok(())
    }
}
