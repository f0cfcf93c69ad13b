//! Streaming trajectories: the 2-D chaos game as the evaluation renderer runs it, every
//! kept point handed to a sink, nothing stored.

use crate::chaos::game::{Trajectory, is_bounded};
use crate::chaos::sampler::MapSampler;
use crate::error::{Error, Result};
use crate::isa::Isa;
use crate::model::Map2;

/// Trajectories stepped together: their chains are independent, so interleaving them hides
/// the latency of each chain's multiply–adds.
pub const LANES: usize = 4;

/// Where a [`PointStream`] puts its points.
///
/// Any `FnMut([f64; 2])` is one. A struct that keeps its state in its own fields (rather
/// than behind references it captured) lets the compiler hold that state in registers
/// through the hot loop.
pub trait PointSink {
    /// Takes one point.
    fn put(&mut self, p: [f64; 2]);

    /// Takes the points of one step of [`LANES`] trajectories stepped together, in lane
    /// order; by default one by one through [`put`](PointSink::put).
    #[inline(always)]
    fn put_lanes(&mut self, ps: [[f64; 2]; LANES]) {
        for p in ps {
            self.put(p);
        }
    }
}

impl<F: FnMut([f64; 2])> PointSink for F {
    #[inline(always)]
    fn put(&mut self, p: [f64; 2]) {
        self(p)
    }
}

/// The trajectories of one seeded run, streamed point by point.
///
/// Trajectory `i` is exactly [`Trajectory::new`]`(maps, sampler, seed, i, half_width)` with
/// its first `warmup` points dropped, whichever [`Isa`] runs it.
#[derive(Clone, Copy)]
pub struct PointStream<'a, M> {
    maps: &'a [M],
    sampler: &'a MapSampler,
    seed: u64,
    half_width: f64,
    warmup: usize,
    isa: Isa,
}

impl<'a, M: Map2> PointStream<'a, M> {
    /// The run seeded `seed`: maps drawn by `sampler`, start points uniform in
    /// `[−half_width, half_width]²`, `warmup` steps dropped; runs on [`Isa::detect`].
    pub fn new(
        maps: &'a [M],
        sampler: &'a MapSampler,
        seed: u64,
        half_width: f64,
        warmup: usize,
    ) -> Result<Self> {
        if maps.is_empty() {
            return Err(Error::Empty("the code has no maps".into()));
        }
        if sampler.len() != maps.len() {
            return Err(Error::Shape(format!(
                "{} probabilities for {} maps",
                sampler.len(),
                maps.len()
            )));
        }
        if !(half_width.is_finite() && half_width >= 0.0) {
            return Err(Error::param(
                "start_half_width",
                format!("must be finite and ≥ 0, got {half_width}"),
            ));
        }
        Ok(PointStream {
            maps,
            sampler,
            seed,
            half_width,
            warmup,
            isa: Isa::detect(),
        })
    }

    /// The same stream on another instruction set (an error if this CPU lacks it).
    pub fn with_isa(self, isa: Isa) -> Result<Self> {
        Ok(PointStream {
            isa: isa.checked()?,
            ..self
        })
    }

    /// The instruction set the stream runs on.
    pub fn isa(&self) -> Isa {
        self.isa
    }

    /// Runs trajectories `first, first + 1, …`, `kept[l]` points of trajectory `first + l`,
    /// and hands every point to `sink`. Points of up to [`LANES`] trajectories interleave;
    /// each trajectory's own points come in order.
    ///
    /// A trajectory that left [`DIVERGENCE_BOUND`](crate::chaos::DIVERGENCE_BOUND) is
    /// reported as [`Error::Divergent`] (its points were handed to the sink).
    pub fn run<S: PointSink>(&self, first: u64, kept: &[u64], sink: &mut S) -> Result<()> {
        match self.isa {
            #[cfg(target_arch = "x86_64")]
            // SAFETY: `isa` is `Fma` only when `Isa::checked` or `Isa::detect` found AVX2 and
            // FMA on this CPU.
            Isa::Fma => unsafe { run_fma(self, first, kept, sink) },
            _ => run_lanes(self, first, kept, sink),
        }
    }
}

/// [`run_lanes`] compiled with FMA: `mul_add` becomes one instruction.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma,bmi1,bmi2")]
fn run_fma<M: Map2, S: PointSink>(
    s: &PointStream<'_, M>,
    first: u64,
    kept: &[u64],
    sink: &mut S,
) -> Result<()> {
    run_lanes(s, first, kept, sink)
}

/// The hot loop; inlined into each instruction-set copy so the maps' arithmetic is compiled
/// with that copy's features.
#[inline(always)]
fn run_lanes<M: Map2, S: PointSink>(
    s: &PointStream<'_, M>,
    first: u64,
    kept: &[u64],
    sink: &mut S,
) -> Result<()> {
    for (c, ns) in kept.chunks(LANES).enumerate() {
        let first = first + (c * LANES) as u64;
        let mut trs: Vec<Trajectory<'_, M>> = (0..ns.len() as u64)
            .map(|l| Trajectory::new(s.maps, s.sampler, s.seed, first + l, s.half_width))
            .collect();
        for tr in trs.iter_mut() {
            for _ in 0..s.warmup {
                tr.step();
            }
        }
        let common = ns.iter().copied().min().unwrap_or(0);
        if let [t0, t1, t2, t3] = trs.as_mut_slice() {
            for _ in 0..common {
                sink.put_lanes([t0.step(), t1.step(), t2.step(), t3.step()]);
            }
        }
        let done = if trs.len() == LANES { common } else { 0 };
        for (tr, &n) in trs.iter_mut().zip(ns) {
            for _ in done..n {
                sink.put(tr.step());
            }
        }
        for (l, tr) in trs.iter().enumerate() {
            if !is_bounded(&tr.point()) {
                return Err(divergence(s, first + l as u64));
            }
        }
    }
    Ok(())
}

/// Escaping is absorbing for diverging codes: replay trajectory `index` to find its first
/// unbounded step.
#[cold]
fn divergence<M: Map2>(s: &PointStream<'_, M>, index: u64) -> Error {
    let mut replay = Trajectory::new(s.maps, s.sampler, s.seed, index, s.half_width);
    let mut step = 0usize;
    while is_bounded(&replay.step()) {
        step += 1;
    }
    Error::Divergent {
        trajectory: index as usize,
        step,
    }
}
