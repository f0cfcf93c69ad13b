//! The library's [`Progress`] reported to an optional Python callback, and Ctrl-C turned
//! into the library's interrupt flag.
//!
//! Long work runs with the GIL released ([`Python::detach`]). Each report re-attaches,
//! calls `callback(event, value)` at most every [`EVERY`] (start, length changes and the
//! end always) and checks Python's signals: a `KeyboardInterrupt` — or an exception raised
//! by the callback — is kept and, for a run, [`ifslab::interrupt::request`] asks it to stop,
//! which a checkpointed run does at the end of its iteration, with its checkpoint (other
//! work goes on to its end; the exception is raised then). The events:
//! `("start", (what, length))`, `("length", n)`, `("position", done)`, `("message", text)`
//! and `("finish", None)`.

use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use ifslab::progress::Progress;
use pyo3::prelude::*;

/// How often the callback is called and signals are checked, at most.
const EVERY: Duration = Duration::from_millis(100);

#[derive(Default)]
struct State {
    done: u64,
    last: Option<Instant>,
    error: Option<PyErr>,
}

/// What the Python side of a run shares with the [`Progress`] handed to the library.
#[derive(Clone)]
pub struct PyProgress {
    callback: Option<Arc<Py<PyAny>>>,
    /// Whether an exception asks the library to stop (a run that polls the flag): the flag
    /// stays set for the rest of the process, so work that does not poll it never sets it.
    stops: bool,
    state: Arc<Mutex<State>>,
}

enum Event<'a> {
    Start(&'a str, u64),
    Length(u64),
    Position,
    /// The last position, reported whatever the time since the previous one.
    Last,
    Message(&'a str),
    Finish,
}

impl PyProgress {
    /// Reports to `callback` (if any) and watches for Ctrl-C; with `stops`, an exception
    /// asks the run to stop at its next checkpoint ([`ifslab::interrupt::request`]), else
    /// the work goes on to its end and the exception is raised then.
    pub fn new(callback: Option<Py<PyAny>>, stops: bool) -> Self {
        PyProgress {
            callback: callback.map(Arc::new),
            stops,
            state: Arc::default(),
        }
    }

    /// A boxed copy to hand to the library.
    pub fn boxed(&self) -> Box<dyn Progress> {
        Box::new(self.clone())
    }

    /// The exception raised while the work ran (Ctrl-C, or the callback's own), if any.
    pub fn take_error(&self) -> Option<PyErr> {
        self.state.lock().ok()?.error.take()
    }

    /// `result` of the work, unless an exception was raised while it ran: then that
    /// exception — a `KeyboardInterrupt` carrying the library's words when the run stopped
    /// with its checkpoint.
    pub fn finish<T>(&self, result: PyResult<T>) -> PyResult<T> {
        if result.is_ok() {
            self.report(Event::Last);
        }
        match (self.take_error(), result) {
            (None, r) => r,
            // The run's own `KeyboardInterrupt` says where its checkpoint is.
            (Some(_), Err(e))
                if Python::attach(|py| {
                    e.is_instance_of::<pyo3::exceptions::PyKeyboardInterrupt>(py)
                }) =>
            {
                Err(e)
            }
            (Some(mine), _) => Err(mine),
        }
    }

    fn report(&self, event: Event<'_>) {
        // Decide under the lock, call Python without it.
        let (done, failed) = {
            let Ok(mut state) = self.state.lock() else {
                return;
            };
            let now = Instant::now();
            let forced = matches!(
                event,
                Event::Start(..) | Event::Length(_) | Event::Last | Event::Finish
            );
            if !forced && state.last.is_some_and(|t| now.duration_since(t) < EVERY) {
                return;
            }
            state.last = Some(now);
            (state.done, state.error.is_some())
        };
        let error = Python::attach(|py| -> Option<PyErr> {
            // Only the main thread sees signals; elsewhere this is a no-op.
            if let Err(e) = py.check_signals() {
                return Some(e);
            }
            let cb = self.callback.as_ref().filter(|_| !failed)?;
            let value = match event {
                Event::Start(what, len) => (what, len).into_pyobject(py).ok()?.into_any(),
                Event::Length(n) => n.into_pyobject(py).ok()?.into_any(),
                Event::Position | Event::Last => done.into_pyobject(py).ok()?.into_any(),
                Event::Message(m) => m.into_pyobject(py).ok()?.into_any(),
                Event::Finish => py.None().into_bound(py),
            };
            let name = match event {
                Event::Start(..) => "start",
                Event::Length(_) => "length",
                Event::Position | Event::Last => "position",
                Event::Message(_) => "message",
                Event::Finish => "finish",
            };
            cb.bind(py).call1((name, value)).err()
        });
        if let Some(e) = error {
            if let Ok(mut state) = self.state.lock()
                && state.error.is_none()
            {
                state.error = Some(e);
            }
            if self.stops {
                ifslab::interrupt::request();
            }
        }
    }
}

impl Progress for PyProgress {
    fn start(&self, what: &str, len: u64) {
        if let Ok(mut s) = self.state.lock() {
            s.done = 0;
        }
        self.report(Event::Start(what, len));
    }
    fn set_length(&self, len: u64) {
        self.report(Event::Length(len));
    }
    fn inc(&self, n: u64) {
        if let Ok(mut s) = self.state.lock() {
            s.done += n;
        }
        self.report(Event::Position);
    }
    fn set_position(&self, done: u64) {
        if let Ok(mut s) = self.state.lock() {
            s.done = done;
        }
        self.report(Event::Position);
    }
    fn message(&self, message: &str) {
        self.report(Event::Message(message));
    }
    fn finish(&self) {
        self.report(Event::Finish);
    }
}
