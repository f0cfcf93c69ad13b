//! The `[strategy]` section every problem's config shares: which registered strategy runs
//! ([`crate::registry`]) and its hyper-parameters, completed with defaults and validated
//! when read. The image, SDF and flame configs each hold one.

use serde::{Deserialize, Serialize};

use crate::driver::Params;
use crate::error::{Error, Result};
use crate::optim::hybrid::HybridConfig;
use crate::registry;

/// The strategy and its hyper-parameters: any strategy of [`crate::registry`], by its
/// `kind`, with its parameters completed with defaults and validated when read (so a written
/// config shows every value the run used).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(try_from = "RawStrategy", into = "RawStrategy")]
pub struct StrategyConfig {
    kind: String,
    params: toml::Table,
}

/// How `[strategy]` is written: `kind` and the strategy's own keys side by side.
#[derive(Clone, Serialize, Deserialize)]
struct RawStrategy {
    kind: String,
    #[serde(flatten)]
    params: toml::Table,
}

impl TryFrom<RawStrategy> for StrategyConfig {
    type Error = Error;
    fn try_from(r: RawStrategy) -> Result<Self> {
        let params = registry::resolve(&r.kind, &r.params)?;
        Ok(StrategyConfig {
            kind: r.kind,
            params,
        })
    }
}

impl From<StrategyConfig> for RawStrategy {
    fn from(s: StrategyConfig) -> Self {
        RawStrategy {
            kind: s.kind,
            params: s.params,
        }
    }
}

impl<C: Params> From<C> for StrategyConfig {
    fn from(c: C) -> Self {
        StrategyConfig::new(&c)
    }
}

impl Default for StrategyConfig {
    fn default() -> Self {
        StrategyConfig::new(&HybridConfig::default())
    }
}

impl StrategyConfig {
    /// The strategy whose hyper-parameters are `c`.
    pub fn new<C: Params>(c: &C) -> Self {
        let params = match toml::Value::try_from(c) {
            Ok(toml::Value::Table(t)) => t,
            _ => unreachable!("strategy parameters serialise to a TOML table"),
        };
        StrategyConfig {
            kind: C::KIND.to_owned(),
            params,
        }
    }

    /// The strategy's name (`hybrid`, `adam`, … : [`registry::kinds`]).
    pub fn name(&self) -> &str {
        &self.kind
    }

    /// Its hyper-parameters, every field present.
    pub fn params(&self) -> &toml::Table {
        &self.params
    }

    /// Its hyper-parameters as `C`, if it is `C`'s strategy.
    pub fn typed<C: Params>(&self) -> Option<C> {
        if self.kind != C::KIND {
            return None;
        }
        toml::Value::Table(self.params.clone()).try_into().ok()
    }

    /// Changes the hyper-parameters of `C`'s strategy; false (nothing changed) for another.
    pub fn update<C: Params>(&mut self, f: impl FnOnce(&mut C)) -> bool {
        match self.typed::<C>() {
            Some(mut c) => {
                f(&mut c);
                *self = StrategyConfig::new(&c);
                true
            }
            None => false,
        }
    }

    /// The default configuration of the strategy called `name`.
    pub fn by_name(name: &str) -> Result<Self> {
        Ok(StrategyConfig {
            kind: name.to_owned(),
            params: registry::defaults(name)?,
        })
    }

    /// Checks the strategy exists and its values are valid.
    pub fn validate(&self) -> Result<()> {
        registry::resolve(&self.kind, &self.params).map(|_| ())
    }
}
