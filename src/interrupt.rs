//! Interruptions a long run survives: a signal (Ctrl-C, SIGTERM) asks the run in progress to
//! stop at its next consistent point — the end of an iteration, after a checkpoint of it —
//! instead of dying mid-write.
//!
//! The binary installs the signal handler ([`on_signal`] is what it calls); the library
//! only keeps the flag. A computation that honours it holds a [`Watch`] while it runs and
//! polls [`requested`]; when none is held, a signal ends the process at once (exit 130), as
//! it would without a handler, and a second signal always does.

use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};

static REQUESTED: AtomicBool = AtomicBool::new(false);
static WATCHERS: AtomicUsize = AtomicUsize::new(0);

/// The exit status of a process ended by an interruption (128 + SIGINT).
pub const EXIT_INTERRUPTED: i32 = 130;

/// What a signal handler calls: the first signal during a watched computation asks it to
/// stop (true returned); otherwise the process exits with [`EXIT_INTERRUPTED`].
pub fn on_signal() -> bool {
    if WATCHERS.load(Ordering::SeqCst) > 0 && !REQUESTED.swap(true, Ordering::SeqCst) {
        eprintln!(
            "\ninterrupted: stopping at the next checkpoint (interrupt again to quit at once)"
        );
        return true;
    }
    std::process::exit(EXIT_INTERRUPTED);
}

/// Asks the watched computations to stop (as a signal does).
pub fn request() {
    REQUESTED.store(true, Ordering::SeqCst);
}

/// Withdraws a stop request once nothing that polls it runs any more, so that a process
/// outliving one interrupted computation (a Python session after Ctrl-C) can start the
/// next; the command line, whose process ends with the computation, never needs it.
/// Returns false, leaving the request in place, while a [`Watch`] is held: a computation
/// still on its way to a checkpoint must see it.
pub fn clear() -> bool {
    if WATCHERS.load(Ordering::SeqCst) > 0 {
        return !REQUESTED.load(Ordering::SeqCst);
    }
    REQUESTED.store(false, Ordering::SeqCst);
    true
}

/// Whether a stop was asked for.
pub fn requested() -> bool {
    REQUESTED.load(Ordering::SeqCst)
}

/// Held while a computation that polls [`requested`] runs.
#[must_use = "the watch ends when dropped"]
pub struct Watch(());

impl Watch {
    /// Marks a polling computation as running.
    pub fn start() -> Self {
        WATCHERS.fetch_add(1, Ordering::SeqCst);
        Watch(())
    }
}

impl Drop for Watch {
    fn drop(&mut self) {
        WATCHERS.fetch_sub(1, Ordering::SeqCst);
    }
}
