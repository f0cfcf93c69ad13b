//! Tile binning: makes the renderer's writes cache-local.
//!
//! A point lands on a random cell of a buffer far larger than the caches (16384² bits at
//! 1024² × 16 is 32 MiB per thread); writing it there directly costs a cache and TLB miss
//! per point. Instead the buffer is cut into tiles of contiguous cells, each small enough
//! to sit in L2 beside the bins, and a point only appends its cell offset to its tile's bin
//! (a sequential store). A full bin is written into its tile in one go: a tight loop of
//! independent read–modify–writes within one tile, whose misses overlap and whose pages
//! stay in the TLB. Setting bits and adding counts do not depend on order, so the image is
//! the same as writing every point directly.
//!
//! Sizes, for the development machine's 48 KiB L1d and 2 MiB L2 per core (BENCHMARKS.md has
//! the measurements): a tile is 512 KiB, a quarter of L2, so the tile being written, the
//! bin being read and the chaos game's state fit in L2 together, and its 128 pages in the
//! TLB. A bin holds one point per 8 bytes of its tile (65 536 points, 256 KiB), so a flush
//! writes 8 points per cache line of the tile on average, and the bins of an accumulator
//! take half the memory of its buffer (16 MiB beside 32 MiB at 1024² × 16). While points
//! are binned only each bin's write head, one cache line, needs to stay in L1 (4 KiB for
//! 64 bins); bins are written and read sequentially, so their size costs bandwidth, not
//! misses. Shorter bins measured slower (a quarter: ~10 %, a sixteenth: ~15 %), longer
//! ones no faster; 128 KiB tiles (256 write heads) twice as slow, 256 KiB–2 MiB tiles the
//! same within noise.

use super::Accumulator;

/// Target bytes of one tile of an accumulator's buffer.
pub(crate) const TILE_BYTES: usize = 512 << 10;

/// Bytes of tile per binned point.
const TILE_BYTES_PER_POINT: usize = 8;

/// Smallest bin (entries), for tiny buffers: a flush stays a loop worth calling.
const MIN_BIN: usize = 1 << 10;

/// Entries (one cache line) between consecutive bins, so bins of capacity 2^k do not all
/// start in the same L1 set.
const BIN_PAD: usize = 16;

/// An accumulator behind per-tile bins.
pub(crate) struct Binned<A> {
    acc: A,
    shift: u32,
    cap: usize,
    stride: usize,
    lens: Vec<u32>,
    entries: Vec<u32>,
    /// Points written into tiles so far.
    written: u64,
}

impl<A: Accumulator> Binned<A> {
    pub(crate) fn new(acc: A) -> Self {
        let shift = acc.tile_shift();
        let tiles = acc.tiles();
        let tile_bytes = (1usize << shift) * A::CELL_BITS as usize / 8;
        let cap = (tile_bytes / TILE_BYTES_PER_POINT).max(MIN_BIN);
        let stride = cap + BIN_PAD;
        Binned {
            acc,
            shift,
            cap,
            stride,
            lens: vec![0; tiles],
            entries: vec![0; tiles * stride],
            written: 0,
        }
    }

    /// The accumulator (its bins not yet written).
    pub(crate) fn acc(&self) -> &A {
        &self.acc
    }

    /// Points recorded so far (written or binned).
    pub(crate) fn recorded(&self) -> u64 {
        self.written + self.lens.iter().map(|&n| n as u64).sum::<u64>()
    }

    /// A writer for a batch of points; what it bins stays here.
    pub(crate) fn writer(&mut self) -> BinWriter<'_, A> {
        BinWriter {
            shift: self.shift,
            mask: (1u64 << self.shift) - 1,
            cap: self.cap,
            stride: self.stride,
            lens: &mut self.lens,
            entries: &mut self.entries,
            acc: &mut self.acc,
            written: &mut self.written,
        }
    }

    /// Writes what the bins hold and returns the accumulator.
    pub(crate) fn into_inner(mut self) -> A {
        for (t, &n) in self.lens.iter().enumerate() {
            if n > 0 {
                let start = t * self.stride;
                self.acc
                    .write_tile(t, &self.entries[start..start + n as usize]);
            }
        }
        self.acc
    }
}

/// Appends points to the bins of a [`Binned`]; its fields are copies, so the hot loop keeps
/// them in registers.
pub(crate) struct BinWriter<'a, A> {
    shift: u32,
    mask: u64,
    cap: usize,
    stride: usize,
    lens: &'a mut [u32],
    entries: &'a mut [u32],
    acc: &'a mut A,
    written: &'a mut u64,
}

impl<A: Accumulator> BinWriter<'_, A> {
    /// Records a point on `cell` (a cell of the accumulator's buffer).
    #[inline(always)]
    pub(crate) fn push(&mut self, cell: u64) {
        let t = (cell >> self.shift) as usize;
        let n = self.lens[t] as usize;
        self.entries[t * self.stride + n] = (cell & self.mask) as u32;
        if n + 1 == self.cap {
            self.flush_full(t);
        } else {
            self.lens[t] = n as u32 + 1;
        }
    }

    /// Writes the full bin of tile `t` into the tile and empties it.
    #[cold]
    #[inline(never)]
    fn flush_full(&mut self, t: usize) {
        let start = t * self.stride;
        self.acc
            .write_tile(t, &self.entries[start..start + self.cap]);
        *self.written += self.cap as u64;
        self.lens[t] = 0;
    }
}
