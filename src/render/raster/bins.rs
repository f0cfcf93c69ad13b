//! Tile binning: makes the renderer's writes cache-local.
//!
//! A point lands on a random cell of a buffer far larger than the caches (16384² bits at
//! 1024² × 16 is 32 MiB); writing it there directly costs a cache and TLB miss per point.
//! Instead the buffer is cut into tiles of contiguous cells, each small enough to sit in L2
//! beside the bins, and a point only appends its cell to its tile's bin (a sequential
//! store). A full bin is written into its tile in one go: a tight loop of independent
//! read–modify–writes within one tile, whose misses overlap and whose pages stay in the
//! TLB. Setting bits and adding counts do not depend on order, so the image is the same as
//! writing every point directly.
//!
//! Every worker thread has its own bins, and all of them write into one buffer ([`Tiles`]):
//! a tile is locked while a bin is written into it, and two threads seldom flush the same
//! tile at once. One buffer rather than one per thread leaves no buffers to merge, and a
//! third less memory to clear (the kernel's page clearing was a tenth of the render).
//! Before a bin is written, its tile is read in order, one word per cache line ([`warm`]):
//! the hardware prefetcher then streams the tile in at full bandwidth, where the random
//! read–modify–writes would each wait for their line.
//!
//! Sizes, for the development machines' 48 KiB L1d and 1–2 MiB L2 per core (BENCHMARKS.md
//! has the measurements): a tile is 512 KiB, so the tile being written, the bin being read
//! and the chaos game's state fit in L2 together, and its 128 pages in the TLB. A bin holds
//! one point per 8 bytes of its tile (65 536 points, 256 KiB), so a flush writes 8 points
//! per cache line of the tile on average, and each thread's bins take half the memory of
//! the buffer (16 MiB beside 32 MiB at 1024² × 16). While points are binned only each
//! bin's write head, one cache line, needs to stay in L1 (4 KiB for 64 bins); bins are
//! written and read sequentially, so their size costs bandwidth, not misses. Measured on
//! the AMD EPYC VM (issue 37), with the tile read first: bins of 4 to 16 bytes of tile per
//! point within noise of one another (without it, twice the points per flush paid ~1.3×
//! less in tile writes); staging each bin's head in an L1 line copied out with
//! non-temporal stores was slower (the flush then reads its bin back from memory), and
//! handing the sink four points at once to compute their cells together slower still. On
//! the Intel VM earlier (issue 2): 128 KiB tiles (256 write heads) twice as slow, 256 KiB–2
//! MiB tiles the same within noise.

use std::ops::BitOr;
use std::sync::{Mutex, MutexGuard};

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

/// Bytes of one thread's bins beside a buffer of `buffer_bytes` cut into tiles of
/// `tile_bytes` (both powers of two, as the accumulators make them).
pub(crate) fn bin_bytes(buffer_bytes: u64, tile_bytes: u64) -> u64 {
    let tiles = buffer_bytes.div_ceil(tile_bytes.max(1));
    let cap = bin_cap(tile_bytes as usize) as u64;
    tiles * (cap + BIN_PAD as u64) * 4
}

/// Entries of one bin: a power of two.
fn bin_cap(tile_bytes: usize) -> usize {
    (tile_bytes / TILE_BYTES_PER_POINT)
        .max(MIN_BIN)
        .next_power_of_two()
}

/// An accumulator's buffer as tiles that any thread may write, one at a time.
pub(crate) struct Tiles<'a, A: Accumulator> {
    tiles: Vec<Mutex<&'a mut [A::Word]>>,
    shift: u32,
}

impl<'a, A: Accumulator> Tiles<'a, A> {
    /// The tiles of `acc`'s buffer.
    pub(crate) fn new(acc: &'a mut A) -> Self {
        let shift = acc.tile_shift();
        let words = acc.tile_words();
        Tiles {
            tiles: acc.words_mut().chunks_mut(words).map(Mutex::new).collect(),
            shift,
        }
    }

    /// Records one point on each cell `tile · 2^shift + (offset mod 2^shift)`.
    fn write(&self, tile: usize, offsets: &[u32]) {
        let mut words = lock(&self.tiles[tile]);
        warm(&words);
        A::write_tile(&mut words, offsets);
    }
}

/// Reads one word of each cache line of `tile` in order, so that the hardware prefetcher
/// streams the tile into the cache at full bandwidth before the random read–modify–writes
/// of a flush, which would otherwise each wait for their line (measured: ~8 % of the
/// render's CPU time).
#[inline(always)]
fn warm<W: Copy + Default + BitOr<Output = W>>(tile: &[W]) {
    let step = (64 / std::mem::size_of::<W>()).max(1);
    let seen = tile.iter().step_by(step).fold(W::default(), |a, &w| a | w);
    std::hint::black_box(seen);
}

/// Locks a tile (a panic elsewhere cannot leave it half-written: setting bits or adding
/// counts has no invariant a panic breaks, so a poisoned lock is taken as is).
pub(crate) fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|e| e.into_inner())
}

/// One thread's bins in front of the shared [`Tiles`].
pub(crate) struct Bins<'t, 'a, A: Accumulator> {
    tiles: &'t Tiles<'a, A>,
    /// Entries per bin (a power of two).
    cap: usize,
    /// Where each tile's next entry goes in `entries` (bin `t` starts at `t · stride`).
    pos: Vec<usize>,
    entries: Vec<u32>,
    /// Points written into tiles so far.
    written: u64,
}

impl<'t, 'a, A: Accumulator> Bins<'t, 'a, A> {
    pub(crate) fn new(tiles: &'t Tiles<'a, A>) -> Self {
        let n = tiles.tiles.len();
        let tile_bytes = (1usize << tiles.shift) * A::CELL_BITS as usize / 8;
        let cap = bin_cap(tile_bytes);
        let stride = cap + BIN_PAD;
        Bins {
            tiles,
            cap,
            pos: (0..n).map(|t| t * stride).collect(),
            entries: vec![0; n * stride],
            written: 0,
        }
    }

    /// Bytes of the bins.
    #[cfg(test)]
    pub(crate) fn bytes(&self) -> u64 {
        std::mem::size_of_val(&self.entries[..]) as u64
    }

    /// Points recorded so far (written or binned).
    pub(crate) fn recorded(&self) -> u64 {
        let stride = self.cap + BIN_PAD;
        let binned: u64 = self
            .pos
            .iter()
            .enumerate()
            .map(|(t, &p)| (p - t * stride) as u64)
            .sum();
        self.written + binned
    }

    /// A writer for a batch of points; what it bins stays here.
    pub(crate) fn writer(&mut self) -> BinWriter<'_, 't, 'a, A> {
        BinWriter {
            shift: self.tiles.shift,
            cap_mask: self.cap - 1,
            cap: self.cap,
            pos: &mut self.pos,
            entries: &mut self.entries,
            tiles: self.tiles,
            written: &mut self.written,
        }
    }

    /// Writes what the bins hold into the tiles.
    pub(crate) fn flush(self) {
        let stride = self.cap + BIN_PAD;
        for (t, &p) in self.pos.iter().enumerate() {
            let start = t * stride;
            if p > start {
                self.tiles.write(t, &self.entries[start..p]);
            }
        }
    }
}

/// Appends points to the bins of a [`Bins`]; its fields are copies, so the hot loop keeps
/// them in registers.
pub(crate) struct BinWriter<'b, 't, 'a, A: Accumulator> {
    shift: u32,
    cap_mask: usize,
    cap: usize,
    pos: &'b mut [usize],
    entries: &'b mut [u32],
    tiles: &'t Tiles<'a, A>,
    written: &'b mut u64,
}

impl<A: Accumulator> BinWriter<'_, '_, '_, A> {
    /// Records a point on `cell` (a cell of the accumulator's buffer).
    #[inline(always)]
    pub(crate) fn push(&mut self, cell: u64) {
        let t = (cell >> self.shift) as usize;
        let i = self.pos[t];
        // The tile's bits of the cell are its bin's: the tile write keeps the offset bits.
        self.entries[i] = cell as u32;
        let i = i + 1;
        // Bin `t` spans `t · (cap + BIN_PAD) + [0, cap)`: full when `i − t · BIN_PAD` is a
        // multiple of `cap`.
        if i.wrapping_sub(t * BIN_PAD) & self.cap_mask == 0 {
            self.flush_full(t);
        } else {
            self.pos[t] = i;
        }
    }

    /// Writes the full bin of tile `t` into the tile and empties it.
    #[cold]
    #[inline(never)]
    fn flush_full(&mut self, t: usize) {
        let start = t * (self.cap + BIN_PAD);
        self.tiles.write(t, &self.entries[start..start + self.cap]);
        *self.written += self.cap as u64;
        self.pos[t] = start;
    }
}
