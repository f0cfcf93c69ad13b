//! Chaos-game point generators.
//!
//! Many independent trajectories run in parallel. Trajectory `i` draws every random number
//! (start point, map sequence) from its own generator seeded by `(seed, i)`, so the points
//! depend on the seed and the trajectory layout only, never on the number of threads.
//! The first `warmup` points of each trajectory are dropped: from a start point in a box
//! they need a few steps to reach the attractor (error shrinks like σmax^k).
//! A trajectory whose point becomes non-finite or leaves [`DIVERGENCE_BOUND`] is reported as
//! [`crate::Error::Divergent`].
//!
//! [`PointStream`] is the form the evaluation renderer runs: trajectories stepped four at a
//! time, each point handed to a sink, the loop compiled once per instruction set ([`Isa`],
//! [`crate::isa`])
//! so affine maps' multiply–adds are single instructions where the CPU has FMA.
//!
//! [`Tape3`] is the 3-D game with its tape (every state and map index kept) and the
//! backward scan through it, for the multi-view splat; [`points3`] its kept points alone.
//!
//! [`WindowWords`] is the deep-zoom sampler: the words of the code whose images of the
//! attractor meet a window, so that the points of a zoomed view come from about as many
//! chaos-game points as the full view's ([`WordSink`] maps a stream's points through them).

mod game;
mod game3;
mod rng;
mod sampler;
mod stream;
mod zoom;

/// The instruction-set policy lives in [`crate::isa`]; re-exported here, where it started.
pub use crate::isa::Isa;
pub use game::{ChaosGame, DIVERGENCE_BOUND, Points, Trajectory, bbox, generate_nd, is_bounded};
pub use game3::{Tape3, points3};
pub use rng::{mix_seed, trajectory_rng};
pub use sampler::MapSampler;
pub use stream::{LANES, PointSink, PointStream};
pub use zoom::{WindowWords, WordSink};
