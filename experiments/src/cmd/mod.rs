//! One module per subcommand: its clap `Args` and a `run` function.

pub mod codes;
pub mod collect;
pub mod demo;
pub mod fit_points;
pub mod flame;
pub mod invert;
pub mod invert3d;
pub mod landscape;
pub mod pack;
pub mod redraw;
pub mod render;
pub mod run;
pub mod sample;
pub mod sdf;
pub mod serve;
pub mod suite;
pub mod sweep;
pub mod texture;
pub mod unpack;
pub mod weights;

pub use ifslab_experiments::codes::resolve_code;

/// A config table from command-line flags: a flag left out sets nothing, so the config's
/// recipe fills it in (`RunConfig::from_table`).
#[derive(Debug, Default)]
pub struct Flags(pub toml::Table);

impl Flags {
    /// Sets the dotted `key` when the flag was given.
    pub fn set(&mut self, key: &str, v: Option<toml::Value>) {
        if let Some(v) = v {
            ifslab_experiments::sweep::expand::set_dotted(&mut self.0, key, v)
                .expect("flag keys are distinct config keys");
        }
    }
}

/// A count flag as a TOML integer.
pub fn count<T: TryInto<i64>>(v: Option<T>) -> Option<toml::Value> {
    v.map(|v| toml::Value::Integer(v.try_into().unwrap_or(i64::MAX)))
}

/// A number flag as a TOML float.
pub fn float(v: Option<f64>) -> Option<toml::Value> {
    v.map(toml::Value::Float)
}
