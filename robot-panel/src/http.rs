//! HTTP/1.1 as the panel speaks it, every part bounded: a request's head is at most
//! [`MAX_HEAD`] bytes and [`MAX_HEADERS`] headers (parsed by `httparse`), its body at
//! most [`MAX_BODY`] bytes (no chunked bodies: a button's POST has none), the whole
//! request in [`READ_WITHIN`], each write of the answer in [`WRITE_WITHIN`]; one request
//! a connection, answered with `Connection: close` (no pipelining to run ahead of the
//! answers).

use std::io::{self, Read, Write};
use std::net::TcpStream;
use std::time::{Duration, Instant};

/// The most bytes of a request's line and headers.
pub const MAX_HEAD: usize = 8 * 1024;
/// The most headers of a request.
pub const MAX_HEADERS: usize = 32;
/// The most bytes of a request's body.
pub const MAX_BODY: usize = 1024;
/// How long a client may take to send its whole request.
pub const READ_WITHIN: Duration = Duration::from_secs(5);
/// How long a client may take to take each write of the answer.
pub const WRITE_WITHIN: Duration = Duration::from_secs(10);

/// A request read.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Request {
    pub method: String,
    /// The path and the query, as sent.
    pub target: String,
    /// The headers, names in lower case.
    headers: Vec<(String, String)>,
}

impl Request {
    /// The value of header `name` (lower case), the first if it came twice.
    pub fn header(&self, name: &str) -> Option<&str> {
        self.headers
            .iter()
            .find(|(n, _)| n == name)
            .map(|(_, v)| v.as_str())
    }
}

/// Why no request was read.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Refused {
    /// Answer with this status and reason, then close.
    Status(u16, &'static str),
    /// The client went away or took too long: close without a word.
    Gone,
}

/// Reads one request from `stream` (whose read timeout this sets).
pub fn read(stream: &mut TcpStream) -> Result<Request, Refused> {
    let deadline = Instant::now() + READ_WITHIN;
    let mut buf = vec![0u8; MAX_HEAD];
    let mut len = 0;
    let (request, head) = loop {
        if len == buf.len() {
            return Err(Refused::Status(431, "request header fields too large"));
        }
        let n = read_before(stream, &mut buf[len..], deadline)?;
        len += n;
        let mut headers = [httparse::EMPTY_HEADER; MAX_HEADERS];
        let mut parsed = httparse::Request::new(&mut headers);
        match parsed.parse(&buf[..len]) {
            Ok(httparse::Status::Complete(head)) => break (request_of(&parsed), head),
            Ok(httparse::Status::Partial) => {}
            Err(httparse::Error::TooManyHeaders) => {
                return Err(Refused::Status(431, "too many header fields"))
            }
            Err(_) => return Err(Refused::Status(400, "malformed request")),
        }
    };
    let request = request?;
    if request.header("transfer-encoding").is_some() {
        return Err(Refused::Status(501, "no chunked bodies"));
    }
    let mut lengths = request
        .headers
        .iter()
        .filter(|(n, _)| n == "content-length")
        .map(|(_, v)| v.trim().parse::<usize>());
    let length = match (lengths.next(), lengths.next()) {
        (None, _) => 0,
        (Some(Ok(n)), None) => n,
        _ => return Err(Refused::Status(400, "one Content-Length, a number")),
    };
    if length > MAX_BODY {
        return Err(Refused::Status(413, "content too large"));
    }
    // The body (unused: read so that closing does not reset the answer).
    let mut have = len - head;
    let mut body = [0u8; MAX_BODY];
    while have < length {
        have += read_before(stream, &mut body[..length - have], deadline)?;
    }
    Ok(request)
}

/// The request `httparse` read, or why it is refused.
fn request_of(parsed: &httparse::Request<'_, '_>) -> Result<Request, Refused> {
    let (Some(method), Some(target)) = (parsed.method, parsed.path) else {
        return Err(Refused::Status(400, "malformed request"));
    };
    let mut headers = Vec::with_capacity(parsed.headers.len());
    for h in parsed.headers.iter() {
        let Ok(value) = std::str::from_utf8(h.value) else {
            return Err(Refused::Status(400, "a header value that is not UTF-8"));
        };
        headers.push((h.name.to_ascii_lowercase(), value.to_string()));
    }
    Ok(Request {
        method: method.to_string(),
        target: target.to_string(),
        headers,
    })
}

/// Reads into `buf` before `deadline`: the bytes read (at least one), or [`Refused::Gone`].
fn read_before(
    stream: &mut TcpStream,
    buf: &mut [u8],
    deadline: Instant,
) -> Result<usize, Refused> {
    let left = deadline.saturating_duration_since(Instant::now());
    if left.is_zero() {
        return Err(Refused::Gone);
    }
    stream
        .set_read_timeout(Some(left))
        .map_err(|_| Refused::Gone)?;
    match stream.read(buf) {
        Ok(0) | Err(_) => Err(Refused::Gone),
        Ok(n) => Ok(n),
    }
}

/// The reason phrase of a status the panel answers with.
fn reason(code: u16) -> &'static str {
    match code {
        200 => "OK",
        303 => "See Other",
        400 => "Bad Request",
        403 => "Forbidden",
        404 => "Not Found",
        405 => "Method Not Allowed",
        409 => "Conflict",
        413 => "Content Too Large",
        431 => "Request Header Fields Too Large",
        501 => "Not Implemented",
        503 => "Service Unavailable",
        504 => "Gateway Timeout",
        _ => "",
    }
}

/// Headers every answer carries: nothing cached, no `Referer` sent on from the page (its
/// address may hold the token), and no page of another site may frame it (a frame under a
/// decoy button would have the operator press START: clickjacking).
pub const COMMON: &str = "Cache-Control: no-store\r\nReferrer-Policy: no-referrer\r\n\
    X-Frame-Options: DENY\r\nContent-Security-Policy: frame-ancestors 'none'\r\n";

/// Writes a whole answer (`Connection: close`) to `out`.
pub fn respond(out: &mut impl Write, code: u16, kind: &str, body: &str) -> io::Result<()> {
    respond_with(out, code, kind, body, "")
}

/// [`respond`] with more header lines (`extra`, each ending in CRLF).
pub fn respond_with(
    out: &mut impl Write,
    code: u16,
    kind: &str,
    body: &str,
    extra: &str,
) -> io::Result<()> {
    let head = format!(
        "HTTP/1.1 {code} {}\r\nContent-Type: {kind}\r\n{COMMON}{extra}\
         Content-Length: {}\r\nConnection: close\r\n\r\n",
        reason(code),
        body.len()
    );
    out.write_all(head.as_bytes())?;
    out.write_all(body.as_bytes())?;
    out.flush()
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::net::TcpListener;

    /// What `read` makes of `bytes`, all a client sends.
    fn read_sent(bytes: &[u8]) -> Result<Request, Refused> {
        let listener = TcpListener::bind("127.0.0.1:0").expect("binds");
        let mut client =
            TcpStream::connect(listener.local_addr().expect("addr")).expect("connects");
        client.write_all(bytes).expect("sends");
        // Nothing more comes: a request cut short is found at once, not at the deadline.
        client.shutdown(std::net::Shutdown::Write).expect("shuts");
        let (mut server, _) = listener.accept().expect("accepts");
        read(&mut server)
    }

    #[test]
    fn a_request_is_read_with_its_headers() {
        let r = read_sent(b"POST /command/HOME?token=1 HTTP/1.1\r\nHost: a:1\r\nX-Panel: button\r\nContent-Length: 2\r\n\r\n{}")
            .expect("reads");
        assert_eq!(
            (r.method.as_str(), r.target.as_str()),
            ("POST", "/command/HOME?token=1")
        );
        assert_eq!(
            (r.header("host"), r.header("x-panel")),
            (Some("a:1"), Some("button"))
        );
    }

    #[test]
    fn what_passes_a_bound_is_refused_with_its_status() {
        let big = format!("GET / HTTP/1.1\r\nX: {}\r\n\r\n", "a".repeat(MAX_HEAD));
        assert_eq!(
            read_sent(big.as_bytes()),
            Err(Refused::Status(431, "request header fields too large"))
        );
        let many: String = (0..=MAX_HEADERS).map(|i| format!("X{i}: 1\r\n")).collect();
        let many = format!("GET / HTTP/1.1\r\n{many}\r\n");
        assert_eq!(
            read_sent(many.as_bytes()),
            Err(Refused::Status(431, "too many header fields"))
        );
        let huge = b"POST /command/STOP HTTP/1.1\r\nContent-Length: 1000000000000\r\n\r\nx";
        assert_eq!(
            read_sent(huge),
            Err(Refused::Status(413, "content too large"))
        );
        let overflow = b"POST / HTTP/1.1\r\nContent-Length: 18446744073709551616\r\n\r\n";
        assert_eq!(
            read_sent(overflow),
            Err(Refused::Status(400, "one Content-Length, a number"))
        );
        let two = b"POST / HTTP/1.1\r\nContent-Length: 0\r\nContent-Length: 40\r\n\r\n";
        assert_eq!(
            read_sent(two),
            Err(Refused::Status(400, "one Content-Length, a number"))
        );
        let chunked = b"POST / HTTP/1.1\r\nTransfer-Encoding: xchunked\r\n\r\n";
        assert_eq!(
            read_sent(chunked),
            Err(Refused::Status(501, "no chunked bodies"))
        );
        assert_eq!(
            read_sent(b"\xff\xfe / HTTP/1.1\r\n\r\n"),
            Err(Refused::Status(400, "malformed request"))
        );
    }

    #[test]
    fn a_client_that_stops_sending_is_gone() {
        assert_eq!(read_sent(b"GET / HTTP/1.1\r\nHost: a"), Err(Refused::Gone));
        assert_eq!(
            read_sent(b"POST / HTTP/1.1\r\nContent-Length: 10\r\n\r\nabc"),
            Err(Refused::Gone)
        );
    }

    #[test]
    fn an_answer_says_its_length_and_closes() {
        let mut out = Vec::new();
        respond(&mut out, 409, "text/plain", "refused\n").expect("writes");
        assert_eq!(
            String::from_utf8(out).expect("utf-8"),
            "HTTP/1.1 409 Conflict\r\nContent-Type: text/plain\r\nCache-Control: no-store\r\n\
             Referrer-Policy: no-referrer\r\nX-Frame-Options: DENY\r\n\
             Content-Security-Policy: frame-ancestors 'none'\r\nContent-Length: 8\r\nConnection: close\r\n\r\n\
             refused\n"
        );
        let mut out = Vec::new();
        respond_with(&mut out, 303, "text/plain", "", "Location: /\r\n").expect("writes");
        assert_eq!(
            String::from_utf8(out).expect("utf-8"),
            "HTTP/1.1 303 See Other\r\nContent-Type: text/plain\r\nCache-Control: no-store\r\n\
             Referrer-Policy: no-referrer\r\nX-Frame-Options: DENY\r\n\
             Content-Security-Policy: frame-ancestors 'none'\r\nLocation: /\r\nContent-Length: 0\r\n\
             Connection: close\r\n\r\n"
        );
    }
}
