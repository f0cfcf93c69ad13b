//! Progress of long work: the core's callback ([`ifslab::progress::Progress`]), and an argmin
//! observer that reports an optimisation's iterations to it.

use argmin::core::observers::Observe;
use argmin::core::{Error as ArgminError, KV, State};
pub use ifslab::progress::{Progress, Silent};
use ifslab_strategies::driver::GradState;

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
        self.progress.set_position(state.get_iter() + 1);
        self.progress
            .message(&format!("loss {:.5}", state.get_cost()));
        Ok(())
    }

    fn observe_final(&mut self, _state: &GradState) -> Result<(), ArgminError> {
        self.progress.finish();
        Ok(())
    }
}
