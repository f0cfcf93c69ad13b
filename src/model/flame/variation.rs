//! The 99 variations of flam3 3.1.1: their names, parameters with flam3's defaults, and
//! which of them draw random numbers.
//!
//! A [`Variation`] is one weighted term of a transform: its [`VariationKind`], its weight,
//! and its parameters (at most [`MAX_PARAMS`]). Parameters are set through
//! [`Variation::set_param`], which refreshes the values flam3 precomputes from them
//! (perspective's sine, julian's exponent, …) so the render loop reads them ready-made.

use crate::error::{Error, Result};
use crate::model::flame::scalar::FlameScalar;

/// The most parameters a variation has (mobius: four complex numbers).
pub const MAX_PARAMS: usize = 8;
/// The most values precomputed from a variation's parameters.
pub const MAX_DERIVED: usize = 4;

macro_rules! variations {
    ($( $idx:literal $variant:ident $name:literal $random:literal [ $( $pname:literal = $pdef:expr ),* ] ; )*) => {
        /// A flam3 variation, numbered as in flam3 (`VAR_LINEAR` = 0 … `VAR_MOBIUS` = 98).
        #[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
        #[repr(u8)]
        pub enum VariationKind {
            $(
                #[doc = concat!("`", $name, "`")]
                $variant = $idx,
            )*
        }

        impl VariationKind {
            /// Every variation, in flam3's order.
            pub const ALL: [VariationKind; 99] = [$(VariationKind::$variant),*];

            /// The name flam3 writes in `.flame` files.
            pub const fn name(self) -> &'static str {
                match self { $(VariationKind::$variant => $name),* }
            }

            /// Whether the variation draws random numbers (forward-only: no Jacobian).
            pub const fn is_random(self) -> bool {
                match self { $(VariationKind::$variant => $random),* }
            }

            /// Parameter names (as written in `.flame` files) and flam3's defaults.
            pub fn params(self) -> &'static [(&'static str, f64)] {
                match self {
                    $(VariationKind::$variant => &[$(($pname, $pdef)),*]),*
                }
            }
        }
    };
}

use std::f64::consts::PI;

variations! {
    0 Linear "linear" false [];
    1 Sinusoidal "sinusoidal" false [];
    2 Spherical "spherical" false [];
    3 Swirl "swirl" false [];
    4 Horseshoe "horseshoe" false [];
    5 Polar "polar" false [];
    6 Handkerchief "handkerchief" false [];
    7 Heart "heart" false [];
    8 Disc "disc" false [];
    9 Spiral "spiral" false [];
    10 Hyperbolic "hyperbolic" false [];
    11 Diamond "diamond" false [];
    12 Ex "ex" false [];
    13 Julia "julia" true [];
    14 Bent "bent" false [];
    15 Waves "waves" false [];
    16 Fisheye "fisheye" false [];
    17 Popcorn "popcorn" false [];
    18 Exponential "exponential" false [];
    19 Power "power" false [];
    20 Cosine "cosine" false [];
    21 Rings "rings" false [];
    22 Fan "fan" false [];
    23 Blob "blob" false ["blob_low" = 0.0, "blob_high" = 1.0, "blob_waves" = 1.0];
    24 Pdj "pdj" false ["pdj_a" = 0.0, "pdj_b" = 0.0, "pdj_c" = 0.0, "pdj_d" = 0.0];
    25 Fan2 "fan2" false ["fan2_x" = 0.0, "fan2_y" = 0.0];
    26 Rings2 "rings2" false ["rings2_val" = 0.0];
    27 Eyefish "eyefish" false [];
    28 Bubble "bubble" false [];
    29 Cylinder "cylinder" false [];
    30 Perspective "perspective" false ["perspective_angle" = 0.0, "perspective_dist" = 0.0];
    31 Noise "noise" true [];
    32 Julian "julian" true ["julian_power" = 1.0, "julian_dist" = 1.0];
    33 Juliascope "juliascope" true ["juliascope_power" = 1.0, "juliascope_dist" = 1.0];
    34 Blur "blur" true [];
    35 GaussianBlur "gaussian_blur" true [];
    36 RadialBlur "radial_blur" true ["radial_blur_angle" = 0.0];
    37 Pie "pie" true ["pie_slices" = 6.0, "pie_rotation" = 0.0, "pie_thickness" = 0.5];
    38 Ngon "ngon" false ["ngon_sides" = 5.0, "ngon_power" = 3.0, "ngon_circle" = 1.0, "ngon_corners" = 2.0];
    39 Curl "curl" false ["curl_c1" = 1.0, "curl_c2" = 0.0];
    40 Rectangles "rectangles" false ["rectangles_x" = 1.0, "rectangles_y" = 1.0];
    41 Arch "arch" true [];
    42 Tangent "tangent" false [];
    43 Square "square" true [];
    44 Rays "rays" true [];
    45 Blade "blade" true [];
    46 Secant2 "secant2" false [];
    47 Twintrian "twintrian" true [];
    48 Cross "cross" false [];
    49 Disc2 "disc2" false ["disc2_rot" = 0.0, "disc2_twist" = 0.0];
    50 SuperShape "super_shape" true ["super_shape_rnd" = 0.0, "super_shape_m" = 0.0, "super_shape_n1" = 1.0, "super_shape_n2" = 1.0, "super_shape_n3" = 1.0, "super_shape_holes" = 0.0];
    51 Flower "flower" true ["flower_petals" = 0.0, "flower_holes" = 0.0];
    52 Conic "conic" true ["conic_eccentricity" = 1.0, "conic_holes" = 0.0];
    53 Parabola "parabola" true ["parabola_height" = 0.0, "parabola_width" = 0.0];
    54 Bent2 "bent2" false ["bent2_x" = 1.0, "bent2_y" = 1.0];
    55 Bipolar "bipolar" false ["bipolar_shift" = 0.0];
    56 Boarders "boarders" true [];
    57 Butterfly "butterfly" false [];
    58 Cell "cell" false ["cell_size" = 1.0];
    59 Cpow "cpow" true ["cpow_r" = 1.0, "cpow_i" = 0.0, "cpow_power" = 1.0];
    60 Curve "curve" false ["curve_xamp" = 0.0, "curve_yamp" = 0.0, "curve_xlength" = 1.0, "curve_ylength" = 1.0];
    61 Edisc "edisc" false [];
    62 Elliptic "elliptic" false [];
    63 Escher "escher" false ["escher_beta" = 0.0];
    64 Foci "foci" false [];
    65 Lazysusan "lazysusan" false ["lazysusan_spin" = 0.0, "lazysusan_space" = 0.0, "lazysusan_twist" = 0.0, "lazysusan_x" = 0.0, "lazysusan_y" = 0.0];
    66 Loonie "loonie" false [];
    67 PreBlur "pre_blur" true [];
    68 Modulus "modulus" false ["modulus_x" = 0.0, "modulus_y" = 0.0];
    69 Oscilloscope "oscilloscope" false ["oscilloscope_separation" = 1.0, "oscilloscope_frequency" = PI, "oscilloscope_amplitude" = 1.0, "oscilloscope_damping" = 0.0];
    70 Polar2 "polar2" false [];
    71 Popcorn2 "popcorn2" false ["popcorn2_x" = 0.0, "popcorn2_y" = 0.0, "popcorn2_c" = 0.0];
    72 Scry "scry" false [];
    73 Separation "separation" false ["separation_x" = 0.0, "separation_xinside" = 0.0, "separation_y" = 0.0, "separation_yinside" = 0.0];
    74 Split "split" false ["split_xsize" = 0.0, "split_ysize" = 0.0];
    75 Splits "splits" false ["splits_x" = 0.0, "splits_y" = 0.0];
    76 Stripes "stripes" false ["stripes_space" = 0.0, "stripes_warp" = 0.0];
    77 Wedge "wedge" false ["wedge_angle" = 0.0, "wedge_hole" = 0.0, "wedge_count" = 1.0, "wedge_swirl" = 0.0];
    78 WedgeJulia "wedge_julia" true ["wedge_julia_angle" = 0.0, "wedge_julia_count" = 1.0, "wedge_julia_power" = 1.0, "wedge_julia_dist" = 0.0];
    79 WedgeSph "wedge_sph" false ["wedge_sph_angle" = 0.0, "wedge_sph_count" = 1.0, "wedge_sph_hole" = 0.0, "wedge_sph_swirl" = 0.0];
    80 Whorl "whorl" false ["whorl_inside" = 0.0, "whorl_outside" = 0.0];
    81 Waves2 "waves2" false ["waves2_freqx" = 0.0, "waves2_scalex" = 0.0, "waves2_freqy" = 0.0, "waves2_scaley" = 0.0];
    82 Exp "exp" false [];
    83 Log "log" false [];
    84 Sin "sin" false [];
    85 Cos "cos" false [];
    86 Tan "tan" false [];
    87 Sec "sec" false [];
    88 Csc "csc" false [];
    89 Cot "cot" false [];
    90 Sinh "sinh" false [];
    91 Cosh "cosh" false [];
    92 Tanh "tanh" false [];
    93 Sech "sech" false [];
    94 Csch "csch" false [];
    95 Coth "coth" false [];
    96 Auger "auger" false ["auger_sym" = 0.0, "auger_weight" = 0.5, "auger_freq" = 1.0, "auger_scale" = 1.0];
    97 Flux "flux" false ["flux_spread" = 0.0];
    98 Mobius "mobius" false ["mobius_re_a" = 0.0, "mobius_im_a" = 0.0, "mobius_re_b" = 0.0, "mobius_im_b" = 0.0, "mobius_re_c" = 0.0, "mobius_im_c" = 0.0, "mobius_re_d" = 0.0, "mobius_im_d" = 0.0];
}

/// Other spellings flam3 accepts for parameter names (Apophysis' oscilloscope and mobius
/// names), mapped to the canonical one.
pub(crate) const PARAM_ALIASES: &[(&str, &str)] = &[
    ("oscope_separation", "oscilloscope_separation"),
    ("oscope_frequency", "oscilloscope_frequency"),
    ("oscope_amplitude", "oscilloscope_amplitude"),
    ("oscope_damping", "oscilloscope_damping"),
    ("Re_A", "mobius_re_a"),
    ("Im_A", "mobius_im_a"),
    ("Re_B", "mobius_re_b"),
    ("Im_B", "mobius_im_b"),
    ("Re_C", "mobius_re_c"),
    ("Im_C", "mobius_im_c"),
    ("Re_D", "mobius_re_d"),
    ("Im_D", "mobius_im_d"),
];

impl VariationKind {
    /// The variation with flam3 number `index`.
    pub fn from_index(index: usize) -> Option<Self> {
        Self::ALL.get(index).copied()
    }

    /// flam3's number of the variation.
    pub fn index(self) -> usize {
        self as usize
    }

    /// The variation a `.flame` file calls `name`.
    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL.iter().copied().find(|k| k.name() == name)
    }

    /// The variation and parameter slot a (possibly aliased) parameter name belongs to.
    pub fn param_owner(name: &str) -> Option<(Self, usize)> {
        let canonical = PARAM_ALIASES
            .iter()
            .find(|(alias, _)| *alias == name)
            .map_or(name, |(_, c)| c);
        Self::ALL.iter().copied().find_map(|k| {
            k.params()
                .iter()
                .position(|(p, _)| *p == canonical)
                .map(|i| (k, i))
        })
    }

    /// Whether the formula reads the radius √(x² + y²) or its square (so the render loop
    /// can skip the square root when no variation of a transform needs it).
    pub fn uses_radius(self) -> bool {
        use VariationKind as V;
        !matches!(
            self,
            V::Arch
                | V::Auger
                | V::Bent
                | V::Bent2
                | V::Blur
                | V::Boarders
                | V::Butterfly
                | V::Cell
                | V::Cos
                | V::Cosh
                | V::Cosine
                | V::Cot
                | V::Coth
                | V::Cross
                | V::Csc
                | V::Csch
                | V::Curl
                | V::Curve
                | V::Cylinder
                | V::Disc2
                | V::Exp
                | V::Exponential
                | V::Flux
                | V::Foci
                | V::GaussianBlur
                | V::Lazysusan
                | V::Linear
                | V::Mobius
                | V::Modulus
                | V::Noise
                | V::Oscilloscope
                | V::Perspective
                | V::Pie
                | V::Popcorn
                | V::Popcorn2
                | V::PreBlur
                | V::Rectangles
                | V::Sec
                | V::Sech
                | V::Separation
                | V::Sin
                | V::Sinh
                | V::Sinusoidal
                | V::Split
                | V::Splits
                | V::Square
                | V::Stripes
                | V::Tan
                | V::Tangent
                | V::Tanh
                | V::Waves
                | V::Waves2
        )
    }

    /// Whether the variation reads the transform's pre-affine coefficients (flam3's
    /// "dependent" variations: waves, popcorn, rings, fan).
    pub fn reads_coefs(self) -> bool {
        matches!(
            self,
            VariationKind::Waves
                | VariationKind::Popcorn
                | VariationKind::Rings
                | VariationKind::Fan
        )
    }
}

/// One weighted variation of a transform, with its parameters.
#[derive(Clone, Debug, PartialEq)]
pub struct Variation {
    kind: VariationKind,
    /// The weight (flam3 multiplies most variations by it; some use it non-linearly).
    pub weight: f64,
    params: [f64; MAX_PARAMS],
    derived: [f64; MAX_DERIVED],
}

impl Variation {
    /// A variation with flam3's default parameters.
    pub fn new(kind: VariationKind, weight: f64) -> Self {
        let mut params = [0.0; MAX_PARAMS];
        for (p, (_, d)) in params.iter_mut().zip(kind.params()) {
            *p = *d;
        }
        let mut v = Variation {
            kind,
            weight,
            params,
            derived: [0.0; MAX_DERIVED],
        };
        v.refresh();
        v
    }

    /// Which variation this is.
    pub fn kind(&self) -> VariationKind {
        self.kind
    }

    /// The parameter values, in the order of [`VariationKind::params`].
    pub fn params(&self) -> &[f64] {
        &self.params[..self.kind.params().len()]
    }

    /// The values precomputed from the parameters.
    pub(crate) fn derived(&self) -> &[f64; MAX_DERIVED] {
        &self.derived
    }

    /// The raw parameter array (unused slots are zero).
    pub(crate) fn param_array(&self) -> &[f64; MAX_PARAMS] {
        &self.params
    }

    /// Sets parameter `name` (canonical or alias); an error names the variation's parameters
    /// when `name` is not one of them.
    pub fn set_param(&mut self, name: &str, value: f64) -> Result<()> {
        match VariationKind::param_owner(name) {
            Some((k, i)) if k == self.kind => {
                self.params[i] = value;
                self.refresh();
                Ok(())
            }
            _ => Err(Error::param(
                "variation parameter",
                format!(
                    "`{name}` is not a parameter of `{}` (its parameters: {})",
                    self.kind.name(),
                    self.kind
                        .params()
                        .iter()
                        .map(|(n, _)| *n)
                        .collect::<Vec<_>>()
                        .join(", ")
                ),
            )),
        }
    }

    /// Sets parameter slot `i` (in the order of [`VariationKind::params`]).
    pub fn set_param_index(&mut self, i: usize, value: f64) {
        assert!(i < self.kind.params().len(), "parameter slot out of range");
        self.params[i] = value;
        self.refresh();
    }

    /// The value of parameter `name`, if the variation has it.
    pub fn param(&self, name: &str) -> Option<f64> {
        match VariationKind::param_owner(name) {
            Some((k, i)) if k == self.kind => Some(self.params[i]),
            _ => None,
        }
    }

    fn refresh(&mut self) {
        self.derived = derive(self.kind, &self.params);
    }
}

/// The values flam3 precomputes from a variation's parameters (`*_precalc` in flam3),
/// written over any [`FlameScalar`] so their derivatives flow into the parameter gradients.
#[inline(always)]
pub(crate) fn derive<T: FlameScalar>(kind: VariationKind, p: &[T; MAX_PARAMS]) -> [T; MAX_DERIVED] {
    use VariationKind as V;
    let z = T::cst(0.0);
    match kind {
        V::Perspective => {
            // angle·π/2; vsin = sin, vfcos = dist·cos
            let ang = p[0] * PI / 2.0;
            let (s, c) = ang.sin_cos();
            [s, p[1] * c, z, z]
        }
        V::Julian | V::Juliascope => {
            // rN = |power|, cn = dist / power / 2
            [p[0].abs(), p[1] / p[0] / 2.0, z, z]
        }
        V::RadialBlur => {
            let (spin, zoom) = (p[0] * PI / 2.0).sin_cos();
            [spin, zoom, z, z]
        }
        V::Disc2 => {
            let timespi = p[0] * PI;
            let add = p[1];
            let (mut sinadd, mut cosadd) = add.sin_cos();
            cosadd = cosadd - 1.0;
            if add.v() > 2.0 * PI {
                let k = (add + 1.0) - 2.0 * PI;
                cosadd = cosadd * k;
                sinadd = sinadd * k;
            }
            if add.v() < -2.0 * PI {
                let k = add + 1.0 + 2.0 * PI;
                cosadd = cosadd * k;
                sinadd = sinadd * k;
            }
            [timespi, sinadd, cosadd, z]
        }
        V::SuperShape => {
            // pm_4 = m/4, pneg1_n1 = −1/n1
            [p[1] / 4.0, T::cst(-1.0) / p[2], z, z]
        }
        V::WedgeJulia => {
            // cf = 1 − angle·count·(1/π)·0.5, rN = |power|, cn = dist / power / 2
            let cf = T::cst(1.0) - p[0] * p[1] * std::f64::consts::FRAC_1_PI * 0.5;
            [cf, p[2].abs(), p[3] / p[2] / 2.0, z]
        }
        _ => [z; MAX_DERIVED],
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn numbering_and_names_follow_flam3() {
        assert_eq!(VariationKind::ALL.len(), 99);
        for (i, k) in VariationKind::ALL.iter().enumerate() {
            assert_eq!(k.index(), i);
            assert_eq!(VariationKind::from_name(k.name()), Some(*k));
        }
        assert_eq!(VariationKind::from_index(98), Some(VariationKind::Mobius));
        assert_eq!(
            VariationKind::from_name("gaussian_blur").unwrap().index(),
            35
        );
        assert_eq!(
            VariationKind::param_owner("oscope_damping"),
            Some((VariationKind::Oscilloscope, 3))
        );
        assert_eq!(
            VariationKind::param_owner("Im_C"),
            Some((VariationKind::Mobius, 5))
        );
    }

    #[test]
    fn setting_a_parameter_refreshes_what_is_derived_from_it() {
        let mut v = Variation::new(VariationKind::Julian, 1.0);
        v.set_param("julian_power", -3.0).unwrap();
        v.set_param("julian_dist", 2.0).unwrap();
        assert_eq!(v.derived()[0], 3.0);
        assert_eq!(v.derived()[1], 2.0 / -3.0 / 2.0);
        assert!(v.set_param("pdj_a", 1.0).is_err());
    }
}
