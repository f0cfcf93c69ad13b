//! Drawing a map index from the probabilities with one 64-bit random number: Walker's
//! alias method with 32-bit column choice and 32-bit threshold.

use crate::error::Result;
use crate::model::probs::validate_probabilities;

/// An alias table over the maps.
#[derive(Clone, Debug)]
pub struct MapSampler {
    threshold: Vec<u32>,
    alias: Vec<u32>,
    uniform: bool,
}

impl MapSampler {
    /// Builds the table; the probabilities are validated (finite, ≥ 0, sum 1).
    pub fn new(probs: &[f64]) -> Result<Self> {
        validate_probabilities(probs, probs.len())?;
        let n = probs.len();
        let first = probs[0];
        let uniform = probs.iter().all(|&p| p == first);
        // Vose's algorithm on scaled probabilities.
        let mut scaled: Vec<f64> = probs.iter().map(|p| p * n as f64).collect();
        let mut threshold = vec![u32::MAX; n];
        let mut alias: Vec<u32> = (0..n as u32).collect();
        let (mut small, mut large): (Vec<usize>, Vec<usize>) =
            (0..n).partition(|&i| scaled[i] < 1.0);
        while let (Some(s), Some(&l)) = (small.pop(), large.last()) {
            threshold[s] = (scaled[s] * 4_294_967_296.0).min(u32::MAX as f64) as u32;
            alias[s] = l as u32;
            scaled[l] -= 1.0 - scaled[s];
            if scaled[l] < 1.0 {
                large.pop();
                small.push(l);
            }
        }
        Ok(MapSampler {
            threshold,
            alias,
            uniform,
        })
    }

    /// Equal probabilities for `n` maps.
    pub fn uniform(n: usize) -> Self {
        MapSampler {
            threshold: vec![u32::MAX; n],
            alias: (0..n as u32).collect(),
            uniform: true,
        }
    }

    /// Number of maps.
    pub fn len(&self) -> usize {
        self.threshold.len()
    }

    /// Whether the table is empty.
    pub fn is_empty(&self) -> bool {
        self.threshold.is_empty()
    }

    /// The map index for one 64-bit random draw.
    #[inline(always)]
    pub fn pick(&self, r: u64) -> usize {
        let n = self.threshold.len() as u64;
        let col = (((r & 0xFFFF_FFFF) * n) >> 32) as usize;
        if self.uniform {
            return col;
        }
        // Branch-free: the comparison is a coin flip the predictor cannot learn.
        let keep = usize::from(((r >> 32) as u32) < self.threshold[col]);
        let alias = self.alias[col] as usize;
        keep * col + (1 - keep) * alias
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::RngCore;

    #[test]
    fn frequencies_match_probabilities() {
        let p = [0.01, 0.85, 0.07, 0.07];
        let s = MapSampler::new(&p).unwrap();
        let mut rng = crate::chaos::trajectory_rng(1, 0);
        let mut counts = [0usize; 4];
        let n = 2_000_000;
        for _ in 0..n {
            counts[s.pick(rng.next_u64())] += 1;
        }
        for (c, p) in counts.iter().zip(p) {
            let f = *c as f64 / n as f64;
            assert!((f - p).abs() < 0.002, "frequency {f} vs probability {p}");
        }
    }
}
