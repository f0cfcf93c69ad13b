//! Runs made of several whole runs ("legs"), each in a folder of the run with its own
//! checkpoint, start and log, of which one is kept: `sdf fit` at several widths σ
//! (`sigma-0`, `sigma-1`, …) and `invert` as the best of several seeds (`run-0`, `run-1`,
//! …). What they share: the progress of the legs shown as one bar, the refusal of a folder
//! that already holds legs, and where each leg resumes.

use std::path::Path;
use std::sync::Arc;

use ifslab_strategies::driver::plan::CHECKPOINT_FILE;

use crate::progress::Progress;

/// Reports a leg's iterations as part of the whole run's: positions offset by the legs
/// before it, finished with the last leg only.
pub struct LegProgress {
    inner: Arc<dyn Progress>,
    offset: u64,
    last: bool,
}

impl LegProgress {
    /// The `index`-th of `count` legs of `iterations` each, reported to `inner`.
    pub fn new(inner: Arc<dyn Progress>, index: usize, count: usize, iterations: u64) -> Self {
        LegProgress {
            inner,
            offset: index as u64 * iterations,
            last: index + 1 == count,
        }
    }
}

impl Progress for LegProgress {
    fn set_position(&self, done: u64) {
        self.inner.set_position(self.offset + done);
    }
    fn message(&self, message: &str) {
        self.inner.message(message);
    }
    fn finish(&self) {
        if self.last {
            self.inner.finish();
        }
    }
    fn cancelled(&self) -> bool {
        self.inner.cancelled()
    }
}

/// Refuses to start a run in `dir` when its first leg (`first_leg`, a folder inside it)
/// already holds a checkpoint: the same words as a single run's refusal, naming the run's
/// folder (not the leg's) in the command that continues it.
pub fn refuse_existing_legs(dir: &Path, first_leg: &str) -> crate::Result<()> {
    if dir.join(first_leg).join(CHECKPOINT_FILE).exists() {
        crate::error::bail!(
            "{} already holds a run ({first_leg}/{CHECKPOINT_FILE}); continue it with --resume {} \
             or choose another output folder",
            dir.display(),
            dir.display()
        );
    }
    Ok(())
}

/// Whether a leg in `leg_dir` resumes: when the run does and the leg had checkpointed (a
/// leg the interrupted run had not reached, or had not checkpointed yet, starts afresh).
pub fn leg_resumes(leg_dir: &Path, resume: bool) -> bool {
    resume && leg_dir.join(CHECKPOINT_FILE).is_file()
}
