//! Progress of long work, reported through a callback: the library never draws. The
//! `ifslab` binary shows bars (indicatif), a sweep may log, a notebook may print.
//!
//! Methods take `&self` so that worker threads can report through a shared reference;
//! implementations use interior mutability (an indicatif bar already does).

/// Receives the progress of one piece of long work.
pub trait Progress: Send + Sync {
    /// The work starts: `len` steps of `what`.
    fn start(&self, _what: &str, _len: u64) {}
    /// The number of steps changed (e.g. another round of a render with a hit target).
    fn set_length(&self, _len: u64) {}
    /// `n` more steps are done.
    fn inc(&self, _n: u64) {}
    /// `done` steps are done.
    fn set_position(&self, _done: u64) {}
    /// How it goes (e.g. the current loss).
    fn message(&self, _message: &str) {}
    /// The work is over.
    fn finish(&self) {}
    /// Whether whoever waits for the work no longer wants it (a viewer's tile that left
    /// the screen): the renderers poll it between batches and end with
    /// [`crate::Error::Cancelled`]. Never, unless an implementation says so.
    fn cancelled(&self) -> bool {
        false
    }
}

/// Reports nothing.
#[derive(Clone, Copy, Debug, Default)]
pub struct Silent;

impl Progress for Silent {}
