//! The error type's messages, conversions and chains.

use super::*;

fn assert_send_sync<T: Send + Sync + 'static>() {}

/// What `ifslab` prints for an error (`main` returns it): the message and its causes,
/// without the backtrace `RUST_BACKTRACE` adds.
fn printed(e: anyhow::Error) -> String {
    let text = format!("{e:?}");
    text.split("\n\nStack backtrace:")
        .next()
        .unwrap()
        .to_owned()
}

#[test]
fn the_error_crosses_threads_and_into_anyhow() {
    assert_send_sync::<Error>();
    let e: anyhow::Error = Error::invalid("x").into();
    assert_eq!(e.to_string(), "x");
}

#[test]
fn context_prints_as_anyhow_did() {
    let io = std::io::Error::new(std::io::ErrorKind::NotFound, "gone");
    let ours = Err::<(), _>(io)
        .doing("reading", Path::new("a.json"))
        .context("loading the run")
        .unwrap_err();
    let io = std::io::Error::new(std::io::ErrorKind::NotFound, "gone");
    let theirs = anyhow::Context::context(
        anyhow::Context::context(Err::<(), _>(io), "reading a.json"),
        "loading the run",
    )
    .unwrap_err();
    assert_eq!(format!("{ours}"), format!("{theirs}"));
    assert_eq!(format!("{ours:#}"), format!("{theirs:#}"));
    assert_eq!(printed(anyhow::Error::from(ours)), printed(theirs));
}

#[test]
fn a_wrapped_error_prints_its_causes_once() {
    let io = std::io::Error::new(std::io::ErrorKind::NotFound, "gone");
    let core = ifslab::Error::io("a.json", io);
    let ours = Error::from(core).context("loading");
    let io = std::io::Error::new(std::io::ErrorKind::NotFound, "gone");
    let theirs = anyhow::Error::new(ifslab::Error::io("a.json", io)).context("loading");
    assert_eq!(format!("{ours:#}"), format!("{theirs:#}"));
    assert_eq!(printed(anyhow::Error::from(ours)), printed(theirs));
}

#[test]
fn kinds_are_found_under_context() {
    let io = std::io::Error::new(std::io::ErrorKind::NotFound, "gone");
    let e = Error::from(ifslab::Error::io("a.json", io))
        .context("x")
        .context("y");
    assert!(e.is_not_found());
    assert!(!e.is_interrupted());
    let e = Error::from(ifslab_strategies::Error::Interrupted("stopped".into()))
        .context("continue it with `ifslab invert --resume out`");
    assert!(e.is_interrupted());
    assert!(!e.is_not_found());
    let e = Error::from(ifslab::Error::Cancelled("gone".into())).context("tile");
    assert!(e.is_cancelled());
    assert!(Error::invalid("x").context("y").root().to_string() == "x");
}
