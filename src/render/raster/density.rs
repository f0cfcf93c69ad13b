//! Hit counts per output pixel, log tone-mapped at the end.

use rayon::prelude::*;

use super::Accumulator;

pub(crate) struct Density {
    counts: Vec<u32>,
}

impl Density {
    pub(crate) fn new(width: u32, height: u32) -> Self {
        Density {
            counts: vec![0; width as usize * height as usize],
        }
    }
}

impl Accumulator for Density {
    #[inline(always)]
    fn add(&mut self, pixel: u64, _sx: u32, _sy: u32) {
        let c = &mut self.counts[pixel as usize];
        *c = c.saturating_add(1);
    }

    fn merge(&mut self, other: Self) {
        self.counts
            .par_iter_mut()
            .zip(other.counts.par_iter())
            .for_each(|(a, b)| *a = a.saturating_add(*b));
    }

    fn finish(self, _width: u32, _height: u32) -> Vec<f32> {
        let max = self.counts.iter().copied().max().unwrap_or(0);
        if max == 0 {
            return vec![0.0; self.counts.len()];
        }
        let norm = 1.0 / (1.0 + max as f64).ln();
        self.counts
            .par_iter()
            .map(|&c| ((1.0 + c as f64).ln() * norm) as f32)
            .collect()
    }
}
