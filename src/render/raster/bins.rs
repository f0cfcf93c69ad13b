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
//! Points reach the bins in batches of [`BATCH`] cells (the renderer gathers the chaos
//! game's points in an L1-resident buffer and computes their cells in one vectorised
//! loop): before a batch every bin is given room for all of it, so appending is a
//! branch-free loop of a load, two stores and a prefetch per point, with the write head's
//! position held in a small array rather than tested for a full bin each time. Points
//! outside the window go to one more bin that is dropped. The hot loops — cells, appends,
//! tile writes — are compiled per instruction set like the chaos game ([`Isa`]).
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
//! handing the sink four points at once to compute their cells together, in the chaos
//! game's loop, slower still (the batches above compute cells in a loop of their own). On
//! the Intel VM earlier (issue 2): 128 KiB tiles (256 write heads) twice as slow, 256 KiB–2
//! MiB tiles the same within noise.

use std::ops::BitOr;
use std::sync::{Mutex, MutexGuard};

use super::Accumulator;
use crate::isa::Isa;

/// Target bytes of one tile of an accumulator's buffer.
pub(crate) const TILE_BYTES: usize = 512 << 10;

/// Bytes of tile per binned point.
const TILE_BYTES_PER_POINT: usize = 8;

/// Smallest bin (entries), for tiny buffers: a flush stays a loop worth calling.
const MIN_BIN: usize = 1 << 10;

const _: () = assert!(MIN_BIN >= BATCH);

/// Entries (one cache line) between consecutive bins, so bins of capacity 2^k do not all
/// start in the same L1 set.
const BIN_PAD: usize = 16;

/// Bytes of one thread's bins beside a buffer of `buffer_bytes` cut into tiles of
/// `tile_bytes` (both powers of two, as the accumulators make them).
pub(crate) fn bin_bytes(buffer_bytes: u64, tile_bytes: u64) -> u64 {
    let tiles = buffer_bytes.div_ceil(tile_bytes.max(1));
    let cap = bin_cap(tile_bytes as usize) as u64;
    (tiles * (cap + BIN_PAD as u64) + BATCH as u64) * 4
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
    /// What the tile writes are compiled for (checked by the caller).
    isa: Isa,
}

impl<'a, A: Accumulator> Tiles<'a, A> {
    /// The tiles of `acc`'s buffer, written with code for `isa` (which must have passed
    /// [`Isa::checked`]).
    pub(crate) fn new(acc: &'a mut A, isa: Isa) -> Self {
        let shift = acc.tile_shift();
        let words = acc.tile_words();
        Tiles {
            tiles: acc.words_mut().chunks_mut(words).map(Mutex::new).collect(),
            shift,
            isa,
        }
    }

    /// Records one point on each cell `tile · 2^shift + (offset mod 2^shift)`.
    fn write(&self, tile: usize, offsets: &[u32]) {
        let mut words = lock(&self.tiles[tile]);
        match self.isa {
            #[cfg(target_arch = "x86_64")]
            // SAFETY: `isa` passed `Isa::checked` (`Tiles::new`): `Fma` only where the CPU
            // has AVX2, FMA and BMI1/2.
            Isa::Fma => unsafe { write_fma::<A>(&mut words, offsets) },
            _ => write_tile::<A>(&mut words, offsets),
        }
    }
}

/// Reads a tile in order ([`warm`]), then records the points of `offsets` in it.
#[inline(always)]
fn write_tile<A: Accumulator>(words: &mut [A::Word], offsets: &[u32]) {
    warm(words);
    A::write_tile(words, offsets);
}

/// [`write_tile`] compiled for AVX2 and BMI2 ([`crate::isa`]).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma,bmi1,bmi2")]
fn write_fma<A: Accumulator>(words: &mut [A::Word], offsets: &[u32]) {
    write_tile::<A>(words, offsets)
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

/// Points a [`BinWriter`] takes at once ([`BinWriter::push`]): before a batch every bin
/// is given room for all of them, so the batch is appended with no test per point.
pub(crate) const BATCH: usize = 512;

/// One thread's bins in front of the shared [`Tiles`].
///
/// Bin `t` spans `entries[t · stride ..][.. cap]`; after the last bin, `BATCH` more entries
/// take the points of a batch that landed outside the buffer (cell `u64::MAX`), dropped
/// before each batch.
pub(crate) struct Bins<'t, 'a, A: Accumulator> {
    tiles: &'t Tiles<'a, A>,
    /// Entries per bin (a power of two, at least `BATCH`).
    cap: usize,
    /// Where each bin's next entry goes in `entries` (bin `t` starts at `t · stride`), and
    /// last where the outside points' next one goes.
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
            pos: (0..=n).map(|t| t * stride).collect(),
            entries: vec![0; n * stride + BATCH],
            written: 0,
        }
    }

    fn stride(&self) -> usize {
        self.cap + BIN_PAD
    }

    /// Bytes of the bins.
    #[cfg(test)]
    pub(crate) fn bytes(&self) -> u64 {
        std::mem::size_of_val(&self.entries[..]) as u64
    }

    /// Points recorded so far (written or binned).
    pub(crate) fn recorded(&self) -> u64 {
        let stride = self.stride();
        let binned: u64 = self.pos[..self.tiles.tiles.len()]
            .iter()
            .enumerate()
            .map(|(t, &p)| (p - t * stride) as u64)
            .sum();
        self.written + binned
    }

    /// A writer for a batch of points; what it bins stays here.
    pub(crate) fn writer(&mut self) -> BinWriter<'_, 't, 'a, A> {
        BinWriter { bins: self }
    }

    /// Writes the points of bin `t` into its tile and empties the bin.
    #[cold]
    #[inline(never)]
    fn write_bin(&mut self, t: usize) {
        let start = t * self.stride();
        let end = self.pos[t];
        if end > start {
            self.tiles.write(t, &self.entries[start..end]);
            self.written += (end - start) as u64;
            self.pos[t] = start;
        }
    }

    /// Writes what the bins hold into the tiles.
    pub(crate) fn flush(mut self) {
        for t in 0..self.tiles.tiles.len() {
            self.write_bin(t);
        }
    }
}

/// Appends points to the bins of a [`Bins`].
pub(crate) struct BinWriter<'b, 't, 'a, A: Accumulator> {
    bins: &'b mut Bins<'t, 'a, A>,
}

impl<A: Accumulator> BinWriter<'_, '_, '_, A> {
    /// Records a point on each cell of `cells` (cells of the accumulator's buffer, at most
    /// [`BATCH`] of them); a cell of `u64::MAX` is no point.
    #[inline(always)]
    pub(crate) fn push(&mut self, cells: &[u64]) {
        let b = &mut *self.bins;
        assert!(cells.len() <= BATCH);
        let n = b.tiles.tiles.len();
        // Room for the whole batch in every bin: a bin with more than `cap − BATCH` points
        // is written into its tile first.
        let (stride, room) = (b.stride(), b.cap - BATCH);
        for t in 0..n {
            if b.pos[t] - t * stride > room {
                b.write_bin(t);
            }
        }
        b.pos[n] = n * stride;
        let shift = b.tiles.shift;
        let pos = &mut b.pos[..=n];
        let entries = &mut b.entries[..];
        for &cell in cells {
            // Cells beyond the buffer (the outside points' `u64::MAX`) go to bin `n`.
            let t = ((cell >> shift) as usize).min(n);
            // SAFETY: `t ≤ n < pos.len()`. Bin `t < n` holds at most `cap − BATCH` points
            // after the loop above and bin `n` none after the line above it, and this loop
            // adds at most `BATCH` to any of them, so `i < t · stride + cap ≤
            // entries.len()` for `t < n`, and `i < n · stride + BATCH = entries.len()` for
            // `t = n`.
            unsafe {
                let i = *pos.get_unchecked(t);
                // The tile's bits of the cell are its bin's: the tile write keeps the
                // offset bits.
                *entries.get_unchecked_mut(i) = cell as u32;
                *pos.get_unchecked_mut(t) = i + 1;
                prefetch_write(entries.as_ptr().wrapping_add(i + AHEAD));
            }
        }
    }
}

/// Entries ahead of a bin's write head that [`BinWriter::push`] asks the cache for: three
/// cache lines, so the line a bin writes next was fetched batches earlier (the bins are
/// written in more streams than the hardware prefetcher follows).
const AHEAD: usize = 48;

/// Asks for the cache line at `p` in a state to be written (a hint: any address will do).
#[inline(always)]
fn prefetch_write(p: *const u32) {
    #[cfg(target_arch = "x86_64")]
    // SAFETY: a prefetch reads nothing and faults on no address.
    unsafe {
        use std::arch::x86_64::{_MM_HINT_ET0, _mm_prefetch};
        _mm_prefetch::<_MM_HINT_ET0>(p as *const i8);
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = p;
}
