//! Progress of long work, reported through a callback: the library never draws; the
//! binary shows bars (indicatif), a sweep may log, a notebook may print.

use argmin::core::observers::Observe;
use argmin::core::{Error as ArgminError, KV, State};
use ifslab_strategies::driver::GradState;

/// Receives the progress of one piece of long work.
pub trait Progress: Send {
    /// The work starts: `len` steps of `what`.
    fn start(&mut self, _what: &str, _len: u64) {}
    /// `done` steps are finished; `message` says how it goes (e.g. the current loss).
    fn advance(&mut self, _done: u64, _message: &str) {}
    /// The work is over.
    fn finish(&mut self) {}
}

/// Reports nothing.
#[derive(Clone, Copy, Debug, Default)]
pub struct Silent;

impl Progress for Silent {}

/// An argmin observer that reports every iteration (and its loss) to a [`Progress`].
pub struct ProgressObserver {
    progress: Box<dyn Progress>,
}

impl ProgressObserver {
    /// Reports to `progress`, which has been started by the caller.
    pub fn new(progress: Box<dyn Progress>) -> Self {
        ProgressObserver { progress }
    }
}

impl Observe<GradState> for ProgressObserver {
    fn observe_iter(&mut self, state: &GradState, _kv: &KV) -> Result<(), ArgminError> {
        self.progress.advance(
            state.get_iter() + 1,
            &format!("loss {:.5}", state.get_cost()),
        );
        Ok(())
    }

    fn observe_final(&mut self, _state: &GradState) -> Result<(), ArgminError> {
        self.progress.finish();
        Ok(())
    }
}
