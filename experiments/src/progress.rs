//! Progress bars for long work (hidden when stderr is not a terminal).

use indicatif::{ProgressBar, ProgressStyle};

/// A bar counting `len` items of `what`.
pub fn bar(len: u64, what: &str) -> ProgressBar {
    let pb = ProgressBar::new(len);
    pb.set_style(
        ProgressStyle::with_template(&format!(
            "{{spinner}} {what} [{{elapsed_precise}}] {{bar:40}} {{human_pos}}/{{human_len}} ({{per_sec}}, eta {{eta}})"
        ))
        .expect("valid template"),
    );
    pb
}

/// An argmin observer that advances a progress bar and shows the current loss.
pub struct ProgressObserver {
    bar: ProgressBar,
}

impl ProgressObserver {
    /// Observes into `bar` (its length is the run's iteration count).
    pub fn new(bar: ProgressBar) -> Self {
        ProgressObserver { bar }
    }
}

impl argmin::core::observers::Observe<ifslab_strategies::driver::GradState> for ProgressObserver {
    fn observe_iter(
        &mut self,
        state: &ifslab_strategies::driver::GradState,
        _kv: &argmin::core::KV,
    ) -> Result<(), argmin::core::Error> {
        use argmin::core::State;
        self.bar.set_position(state.get_iter() + 1);
        self.bar
            .set_message(format!("loss {:.5}", state.get_cost()));
        Ok(())
    }

    fn observe_final(
        &mut self,
        _state: &ifslab_strategies::driver::GradState,
    ) -> Result<(), argmin::core::Error> {
        self.bar.finish_and_clear();
        Ok(())
    }
}
