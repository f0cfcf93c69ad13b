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
/// prefix and its length; counts go straight through; messages are the bar's status line,
/// or with [`Bar::logging`] lines of their own on stderr (what scripts read).
pub struct Bar {
    bar: ProgressBar,
    log_messages: bool,
}

impl Default for Bar {
    fn default() -> Self {
        Bar {
            bar: ProgressBar::hidden(),
            log_messages: false,
        }
    }
}

impl Bar {
    /// Reports into an existing bar (its style and length as they are).
    pub fn of(pb: ProgressBar) -> Self {
        Bar {
            bar: pb,
            log_messages: false,
        }
    }

    /// A bar that prints every message as a line on stderr (above the bar while one is
    /// drawn, also when stderr is not a terminal).
    pub fn logging() -> Self {
        Bar {
            log_messages: true,
            ..Bar::default()
        }
    }

    /// The bar for a run of `problem`: image inversions (2-D and 3-D) and sdf fits report
    /// their loss as the status line; the other problems report results worth keeping, as
    /// lines.
    pub fn for_problem(problem: &str) -> Self {
        if matches!(problem, "image" | "sdf" | "image3d") {
            Bar::default()
        } else {
            Bar::logging()
        }
    }
}

impl Progress for Bar {
    fn start(&self, what: &str, len: u64) {
        self.bar
            .set_draw_target(indicatif::ProgressDrawTarget::stderr());
        self.bar.set_style(
            ProgressStyle::with_template(
                "{spinner} {prefix} [{elapsed_precise}] {bar:40} {human_pos}/{human_len} ({per_sec}, eta {eta}) {msg}",
            )
            .expect("valid template"),
        );
        self.bar.set_prefix(what.to_owned());
        self.bar.set_length(len);
        self.bar.set_position(0);
    }
    fn set_length(&self, len: u64) {
        self.bar.set_length(len);
    }
    fn inc(&self, n: u64) {
        self.bar.inc(n);
    }
    fn set_position(&self, done: u64) {
        self.bar.set_position(done);
    }
    fn message(&self, message: &str) {
        if self.log_messages {
            self.bar.suspend(|| eprintln!("{message}"));
        } else {
            self.bar.set_message(message.to_owned());
        }
    }
    fn finish(&self) {
        self.bar.finish_and_clear();
    }
}
