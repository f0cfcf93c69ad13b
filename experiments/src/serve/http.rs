//! The little HTTP/1.1 `ifslab serve` needs, on the standard library's sockets: `GET`
//! requests without bodies, answers with a known length, kept-alive connections, one thread
//! per connection.
//!
//! **Why not a web crate.** The server first ran on `tiny_http` 0.12, whose pool of
//! connection threads has a race: `TaskPool::spawn` counts a thread woken for one
//! connection as still idle until that thread takes the lock again, so a second connection
//! accepted in between is queued with no thread to take it — and since a pool thread serves
//! one connection for as long as it stays open (a browser keeps its six open for minutes),
//! the queued one waits until some connection closes. Measured with headless Chromium: 3 of
//! 12 page loads left a tile unanswered for more than 120 s (one for 313 s). Here every
//! accepted connection gets its own thread at once (up to [`MAX_CONNECTIONS`]; beyond that
//! a connection is answered `503` and closed), so no request waits behind another
//! connection, and the thread that waits for a tile can see its client leave (see
//! [`client_gone`]).

use std::io::{self, BufRead, BufReader, Write};
use std::net::{Shutdown, TcpStream};
use std::time::{Duration, Instant};

/// Most connections open at once.
pub const MAX_CONNECTIONS: usize = 256;
/// Most bytes of a request's line and headers.
const MAX_HEAD: usize = 16 << 10;
/// A kept-alive connection idle this long is closed.
pub const IDLE: Duration = Duration::from_secs(120);
/// How long a started request may take to arrive whole.
const HEAD_TIME: Duration = Duration::from_secs(20);
/// How often a waiting read looks at the server's stop flag.
pub const POLL: Duration = Duration::from_millis(250);

/// A request's line and the headers the server uses.
#[derive(Debug)]
pub struct Head {
    /// `GET`, `HEAD`…
    pub method: String,
    /// The path and query, as sent.
    pub target: String,
    /// Whether the client keeps the connection for another request.
    pub keep_alive: bool,
}

/// Why no request was read.
#[derive(Debug)]
pub enum ReadError {
    /// The client closed the connection, was idle too long, or the server stops.
    Closed,
    /// Not a request this server takes: answer with this status and reason, then close.
    Bad(u16, &'static str),
}

/// A connection's reading half, buffered.
pub struct Conn {
    reader: BufReader<TcpStream>,
    stream: TcpStream,
}

impl Conn {
    /// A connection of `stream`, reads polling every [`POLL`].
    pub fn new(stream: TcpStream) -> io::Result<Self> {
        stream.set_nodelay(true)?;
        stream.set_read_timeout(Some(POLL))?;
        stream.set_write_timeout(Some(Duration::from_secs(30)))?;
        Ok(Conn {
            reader: BufReader::new(stream.try_clone()?),
            stream,
        })
    }

    /// The socket (to answer on, and to see the client leave).
    pub fn stream(&self) -> &TcpStream {
        &self.stream
    }

    /// Reads the next request's head; `stop` is polled while the connection is idle.
    pub fn read_head(&mut self, stop: &dyn Fn() -> bool) -> Result<Head, ReadError> {
        let mut raw: Vec<u8> = Vec::new();
        let idle_since = Instant::now();
        let mut started: Option<Instant> = None;
        loop {
            let before = raw.len();
            match self.reader.read_until(b'\n', &mut raw) {
                Ok(0) => return Err(ReadError::Closed),
                Ok(_) => {}
                Err(e)
                    if matches!(
                        e.kind(),
                        io::ErrorKind::WouldBlock | io::ErrorKind::TimedOut
                    ) => {}
                Err(e) if e.kind() == io::ErrorKind::Interrupted => continue,
                Err(_) => return Err(ReadError::Closed),
            }
            if raw.len() > before && started.is_none() {
                started = Some(Instant::now());
            }
            if raw.len() > MAX_HEAD {
                return Err(ReadError::Bad(431, "the request's headers are too long"));
            }
            // Blank lines before a request are allowed (RFC 9112 §2.2).
            if raw.first() == Some(&b'\r') && raw.get(1) == Some(&b'\n')
                || raw.first() == Some(&b'\n')
            {
                let skip = if raw[0] == b'\r' { 2 } else { 1 };
                raw.drain(..skip);
                continue;
            }
            if raw.ends_with(b"\r\n\r\n") || raw.ends_with(b"\n\n") {
                return parse_head(&raw);
            }
            match started {
                None if stop() || idle_since.elapsed() > IDLE => return Err(ReadError::Closed),
                Some(t) if t.elapsed() > HEAD_TIME => {
                    return Err(ReadError::Bad(408, "the request did not arrive in time"));
                }
                _ => {}
            }
        }
    }

    /// Writes a whole response; false if the client is gone.
    pub fn respond(&mut self, r: &Response, keep_alive: bool, with_body: bool) -> bool {
        let mut out = format!(
            "HTTP/1.1 {} {}\r\nContent-Type: {}\r\nContent-Length: {}\r\nCache-Control: {}\r\n\
             X-Content-Type-Options: nosniff\r\nConnection: {}\r\n\r\n",
            r.status,
            reason(r.status),
            r.content_type,
            r.body.len(),
            r.cache,
            if keep_alive { "keep-alive" } else { "close" },
        )
        .into_bytes();
        if with_body {
            out.extend_from_slice(&r.body);
        }
        let ok = (&self.stream)
            .write_all(&out)
            .and_then(|_| (&self.stream).flush());
        if !keep_alive {
            let _ = self.stream.shutdown(Shutdown::Write);
        }
        ok.is_ok()
    }
}

/// An answer.
#[derive(Clone, Debug)]
pub struct Response {
    /// The status code.
    pub status: u16,
    /// The body's type.
    pub content_type: &'static str,
    /// `Cache-Control`.
    pub cache: &'static str,
    /// The body.
    pub body: Vec<u8>,
}

impl Response {
    /// A body of `content_type`; PNG answers of 200 may be cached, nothing else is.
    pub fn new(status: u16, content_type: &'static str, body: Vec<u8>) -> Self {
        let cache = match (status, content_type) {
            (200, "image/png") => "max-age=3600",
            _ => "no-store",
        };
        Response {
            status,
            content_type,
            cache,
            body,
        }
    }

    /// A line of text.
    pub fn text(status: u16, message: &str) -> Self {
        Response::new(
            status,
            "text/plain; charset=utf-8",
            format!("{message}\n").into_bytes(),
        )
    }
}

fn parse_head(raw: &[u8]) -> Result<Head, ReadError> {
    let text = std::str::from_utf8(raw).map_err(|_| ReadError::Bad(400, "a request is ASCII"))?;
    let mut lines = text.lines();
    let line = lines.next().unwrap_or("");
    let mut parts = line.split(' ');
    let (Some(method), Some(target), Some(version), None) =
        (parts.next(), parts.next(), parts.next(), parts.next())
    else {
        return Err(ReadError::Bad(
            400,
            "a request line is METHOD TARGET HTTP/1.1",
        ));
    };
    let mut keep_alive = match version {
        "HTTP/1.1" => true,
        "HTTP/1.0" => false,
        _ => return Err(ReadError::Bad(505, "only HTTP/1.0 and HTTP/1.1 are served")),
    };
    if !target.starts_with('/') {
        return Err(ReadError::Bad(400, "the target must be a path (/…)"));
    }
    let mut body = 0usize;
    for h in lines.filter(|l| !l.is_empty()) {
        let Some((name, value)) = h.split_once(':') else {
            return Err(ReadError::Bad(400, "a header line is NAME: VALUE"));
        };
        let value = value.trim().to_ascii_lowercase();
        match name.trim().to_ascii_lowercase().as_str() {
            "connection" if value.split(',').any(|v| v.trim() == "close") => keep_alive = false,
            "connection" if value.split(',').any(|v| v.trim() == "keep-alive") => keep_alive = true,
            "content-length" => {
                body = value
                    .parse()
                    .map_err(|_| ReadError::Bad(400, "Content-Length must be a whole number"))?
            }
            "transfer-encoding" => {
                return Err(ReadError::Bad(501, "request bodies are not taken"));
            }
            _ => {}
        }
    }
    if body > 0 {
        // Only GET is served; a body is refused (and the connection closed after).
        return Err(ReadError::Bad(413, "request bodies are not taken"));
    }
    Ok(Head {
        method: method.to_string(),
        target: target.to_string(),
        keep_alive,
    })
}

/// Whether the client closed its end (or the connection broke) — what a browser does when
/// the page aborts a request it no longer needs. A client that sent more (the next request,
/// pipelined) is still there.
pub fn client_gone(stream: &TcpStream) -> bool {
    if stream.set_nonblocking(true).is_err() {
        return true;
    }
    let mut byte = [0u8; 1];
    let gone = match stream.peek(&mut byte) {
        Ok(0) => true,
        Ok(_) => false,
        Err(e) => e.kind() != io::ErrorKind::WouldBlock,
    };
    let _ = stream.set_nonblocking(false);
    gone
}

fn reason(status: u16) -> &'static str {
    match status {
        200 => "OK",
        400 => "Bad Request",
        404 => "Not Found",
        405 => "Method Not Allowed",
        408 => "Request Timeout",
        409 => "Conflict",
        413 => "Content Too Large",
        431 => "Request Header Fields Too Large",
        500 => "Internal Server Error",
        501 => "Not Implemented",
        503 => "Service Unavailable",
        505 => "HTTP Version Not Supported",
        _ => "",
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn heads_are_parsed_and_refused_with_reasons() {
        let h = parse_head(b"GET /tile/a?level=1 HTTP/1.1\r\nHost: x\r\n\r\n").unwrap();
        assert_eq!(
            (h.method.as_str(), h.target.as_str(), h.keep_alive),
            ("GET", "/tile/a?level=1", true)
        );
        let h = parse_head(b"GET / HTTP/1.1\r\nConnection: close\r\n\r\n").unwrap();
        assert!(!h.keep_alive);
        let h = parse_head(b"GET / HTTP/1.0\r\n\r\n").unwrap();
        assert!(!h.keep_alive);
        for (raw, status) in [
            (&b"GET /\r\n\r\n"[..], 400),
            (b"GET / HTTP/2\r\n\r\n", 505),
            (b"GET http://x/ HTTP/1.1\r\n\r\n", 400),
            (b"POST / HTTP/1.1\r\nContent-Length: 5\r\n\r\n", 413),
            (
                b"POST / HTTP/1.1\r\nTransfer-Encoding: chunked\r\n\r\n",
                501,
            ),
            (b"GET / HTTP/1.1\r\nno colon\r\n\r\n", 400),
        ] {
            match parse_head(raw) {
                Err(ReadError::Bad(s, _)) => {
                    assert_eq!(s, status, "{}", String::from_utf8_lossy(raw))
                }
                other => panic!("{}: {other:?}", String::from_utf8_lossy(raw)),
            }
        }
    }
}
