//! Deterministic subsets of a sweep, so that n machines split it with no coordinator.

use std::fmt;
use std::str::FromStr;

use crate::error::{Context, bail};

/// Shard `index` of `count` (0-based, `--shard 2/8`): the runs whose position in the sweep
/// is `index` modulo `count`. Round robin spreads the runs of each axis value over the
/// shards, so shards of a sweep whose axes differ in cost take about as long as each other.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Shard {
    /// This shard, `0..count`.
    pub index: usize,
    /// How many shards the sweep is split into.
    pub count: usize,
}

impl Shard {
    /// The whole sweep.
    pub const ALL: Shard = Shard { index: 0, count: 1 };

    /// Shard `index` of `count`, checked.
    pub fn new(index: usize, count: usize) -> crate::Result<Self> {
        if count == 0 {
            bail!("a sweep splits into at least 1 shard, got 0");
        }
        if index >= count {
            bail!(
                "shard {index}/{count} does not exist: shards are numbered 0 to {}",
                count - 1
            );
        }
        Ok(Shard { index, count })
    }

    /// Whether the run at `position` in the sweep belongs to this shard.
    pub fn contains(&self, position: usize) -> bool {
        position % self.count == self.index
    }
}

impl FromStr for Shard {
    type Err = crate::Error;
    fn from_str(s: &str) -> crate::Result<Self> {
        let (i, n) = s
            .split_once('/')
            .with_context(|| format!("`{s}` is not a shard: write INDEX/COUNT, e.g. 0/4"))?;
        let parse = |x: &str| {
            x.trim()
                .parse::<usize>()
                .map_err(|e| crate::Error::invalid(e.to_string()))
                .with_context(|| format!("`{s}` is not a shard: `{x}` is not a whole number"))
        };
        Shard::new(parse(i)?, parse(n)?)
    }
}

impl fmt::Display for Shard {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}/{}", self.index, self.count)
    }
}
