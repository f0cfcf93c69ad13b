//! Binary coverage buffer, tiled so each output pixel's `s×s` sub-pixels are contiguous bits.

use rayon::prelude::*;

use super::Accumulator;

/// 64-bit words for a `width × height` image at `s×` supersampling.
pub(crate) fn words_for(width: u32, height: u32, s: u32) -> usize {
    let bits = width as u64 * height as u64 * (s as u64).pow(2);
    bits.div_ceil(64) as usize
}

pub(crate) struct Coverage {
    bits: Vec<u64>,
    s: u32,
    ss: u64,
}

impl Coverage {
    pub(crate) fn new(words: usize, s: u32) -> Self {
        Coverage {
            bits: vec![0; words],
            s,
            ss: (s as u64).pow(2),
        }
    }
}

/// Number of set bits in `[start, start + len)`.
fn count_bits(bits: &[u64], start: u64, len: u64) -> u32 {
    let end = start + len;
    let (mut w, last) = ((start >> 6) as usize, ((end - 1) >> 6) as usize);
    let lo_mask = !0u64 << (start & 63);
    let hi_mask = !0u64 >> (63 - ((end - 1) & 63));
    if w == last {
        return (bits[w] & lo_mask & hi_mask).count_ones();
    }
    let mut n = (bits[w] & lo_mask).count_ones();
    w += 1;
    while w < last {
        n += bits[w].count_ones();
        w += 1;
    }
    n + (bits[last] & hi_mask).count_ones()
}

impl Accumulator for Coverage {
    #[inline(always)]
    fn add(&mut self, pixel: u64, sx: u32, sy: u32) {
        let bit = pixel * self.ss + (sy * self.s + sx) as u64;
        // The index is < width·height·s² by construction of `PixelMap::locate`.
        let w = &mut self.bits[(bit >> 6) as usize];
        *w |= 1u64 << (bit & 63);
    }

    fn merge(&mut self, other: Self) {
        self.bits
            .par_chunks_mut(1 << 14)
            .zip(other.bits.par_chunks(1 << 14))
            .for_each(|(a, b)| a.iter_mut().zip(b).for_each(|(x, y)| *x |= y));
    }

    fn finish(self, width: u32, height: u32) -> Vec<f32> {
        let ss = self.ss;
        let inv = 1.0 / ss as f32;
        (0..width as u64 * height as u64)
            .into_par_iter()
            .map(|p| count_bits(&self.bits, p * ss, ss) as f32 * inv)
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn count_bits_matches_naive() {
        let bits = vec![
            0xF0F0_1234_5678_9ABCu64,
            0xFFFF_0000_FFFF_0001,
            0x8000_0000_0000_0001,
        ];
        let naive = |s: u64, l: u64| {
            (s..s + l)
                .filter(|b| bits[(b >> 6) as usize] >> (b & 63) & 1 == 1)
                .count() as u32
        };
        for s in 0..150 {
            for l in 1..(192 - s).min(100) {
                assert_eq!(count_bits(&bits, s, l), naive(s, l), "start {s} len {l}");
            }
        }
    }
}
