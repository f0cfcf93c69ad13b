//! Progress bars for long work (hidden when stderr is not a terminal): the library's
//! [`Progress`] reports drawn with indicatif.

use ifslab_experiments::progress::Progress;
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

/// An indicatif bar behind the library's [`Progress`]: `start` gives it its style, its
/// prefix and its length; counts and messages go straight through.
pub struct Bar(ProgressBar);

impl Default for Bar {
    fn default() -> Self {
        Bar(ProgressBar::hidden())
    }
}

impl Bar {
    /// Reports into an existing bar (its style and length as they are).
    pub fn of(pb: ProgressBar) -> Self {
        Bar(pb)
    }
}

impl Progress for Bar {
    fn start(&self, what: &str, len: u64) {
        self.0
            .set_draw_target(indicatif::ProgressDrawTarget::stderr());
        self.0.set_style(
            ProgressStyle::with_template(
                "{spinner} {prefix} [{elapsed_precise}] {bar:40} {human_pos}/{human_len} ({per_sec}, eta {eta}) {msg}",
            )
            .expect("valid template"),
        );
        self.0.set_prefix(what.to_owned());
        self.0.set_length(len);
        self.0.set_position(0);
    }
    fn set_length(&self, len: u64) {
        self.0.set_length(len);
    }
    fn inc(&self, n: u64) {
        self.0.inc(n);
    }
    fn set_position(&self, done: u64) {
        self.0.set_position(done);
    }
    fn message(&self, message: &str) {
        self.0.set_message(message.to_owned());
    }
    fn finish(&self) {
        self.0.finish_and_clear();
    }
}
