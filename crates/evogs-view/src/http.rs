//! The connection layer: a listener, a fixed number of worker threads, a bounded backlog.
//!
//! One thread accepts connections and hands them to [`Limits::workers`] workers through a
//! channel of [`Limits::backlog`] places; when every place is taken the connection is answered
//! `503` at once and closed, so the number of open connections and threads stays bounded
//! whatever arrives. (`tiny_http`, the usual small synchronous server, starts a thread per
//! connection without a limit, its issue #221; owning the accept loop is what bounds it here.)
//! A worker reads one request head (at most [`Limits::max_head`] bytes, all of it within
//! [`Limits::head_timeout`]: one deadline for the whole head, so a client trickling a byte at a
//! time cannot hold a worker longer), parses it with `httparse`, refuses bodies, calls the
//! handler and writes the response with `Connection: close` (within [`Limits::timeout`]).

use std::io::{Read, Write};
use std::net::{SocketAddr, TcpListener, TcpStream};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{Receiver, SyncSender, TrySendError, sync_channel};
use std::sync::{Arc, Mutex, PoisonError};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

/// Bounds of the connection layer.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Limits {
    /// Worker threads (connections served at once).
    pub workers: usize,
    /// Connections waiting for a worker; more are answered 503.
    pub backlog: usize,
    /// Writing a response times out after this.
    pub timeout: Duration,
    /// The whole request head must arrive within this, however it is split (a browser sends it
    /// at once; on loopback it takes well under a millisecond).
    pub head_timeout: Duration,
    /// Longest accepted request head in bytes (request line and headers).
    pub max_head: usize,
}

impl Default for Limits {
    fn default() -> Self {
        Self {
            workers: 6,
            backlog: 16,
            timeout: Duration::from_secs(10),
            head_timeout: Duration::from_secs(3),
            max_head: 16 * 1024,
        }
    }
}

/// A parsed request head.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Request {
    /// `GET`, `HEAD`, ...
    pub method: String,
    /// The path, before `?`, as sent (not decoded).
    pub path: String,
    /// After `?` (empty without one), not decoded.
    pub query: String,
    /// The `Host` header.
    pub host: Option<String>,
}

/// A response.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Response {
    /// The status code.
    pub status: u16,
    /// `Content-Type`.
    pub content_type: &'static str,
    /// Further headers.
    pub headers: Vec<(&'static str, String)>,
    /// The body.
    pub body: Vec<u8>,
}

impl Response {
    /// A plain-text response (a reason for an error status).
    pub fn text(status: u16, text: impl Into<String>) -> Self {
        let mut body = text.into().into_bytes();
        body.push(b'\n');
        Self {
            status,
            content_type: "text/plain; charset=utf-8",
            headers: Vec::new(),
            body,
        }
    }

    /// A response with `body` of type `content_type`, status 200.
    pub fn ok(content_type: &'static str, body: Vec<u8>) -> Self {
        Self {
            status: 200,
            content_type,
            headers: Vec::new(),
            body,
        }
    }

    /// Adds a header.
    #[must_use]
    pub fn with(mut self, name: &'static str, value: impl Into<String>) -> Self {
        self.headers.push((name, value.into()));
        self
    }

    /// The body as text (for tests and messages).
    pub fn body_text(&self) -> String {
        String::from_utf8_lossy(&self.body).into_owned()
    }
}

fn reason(status: u16) -> &'static str {
    match status {
        200 => "OK",
        400 => "Bad Request",
        403 => "Forbidden",
        404 => "Not Found",
        405 => "Method Not Allowed",
        409 => "Conflict",
        413 => "Content Too Large",
        431 => "Request Header Fields Too Large",
        500 => "Internal Server Error",
        503 => "Service Unavailable",
        _ => "Status",
    }
}

/// Writes `response` (its body left out for `HEAD`) and closes the connection.
fn write_response(stream: &mut TcpStream, response: &Response, head_only: bool) {
    let mut head = format!(
        "HTTP/1.1 {} {}\r\nContent-Type: {}\r\nContent-Length: {}\r\nConnection: close\r\n\
         Cache-Control: no-store\r\nX-Content-Type-Options: nosniff\r\n",
        response.status,
        reason(response.status),
        response.content_type,
        response.body.len()
    );
    for (name, value) in &response.headers {
        // Header values are made by the server; line breaks would split the head.
        let value: String = value.chars().filter(|c| !c.is_control()).collect();
        head.push_str(&format!("{name}: {value}\r\n"));
    }
    head.push_str("\r\n");
    let _ = stream.write_all(head.as_bytes());
    if !head_only {
        let _ = stream.write_all(&response.body);
    }
    let _ = stream.flush();
    let _ = stream.shutdown(std::net::Shutdown::Both);
}

/// Reads and parses one request head; an `Err` is the response to send instead.
fn read_request(stream: &mut TcpStream, limits: &Limits) -> Result<Request, Response> {
    let mut buf = vec![0u8; 0];
    let mut chunk = [0u8; 4096];
    let late = || Response::text(400, "the request head did not arrive in time");
    let deadline = Instant::now() + limits.head_timeout;
    loop {
        let left = deadline.saturating_duration_since(Instant::now());
        if left.is_zero() || stream.set_read_timeout(Some(left)).is_err() {
            return Err(late());
        }
        let n = match stream.read(&mut chunk) {
            Ok(0) => return Err(Response::text(400, "the connection closed mid-request")),
            Ok(n) => n,
            Err(_) => return Err(late()),
        };
        buf.extend_from_slice(&chunk[..n]);
        let mut headers = [httparse::EMPTY_HEADER; 64];
        let mut req = httparse::Request::new(&mut headers);
        match req.parse(&buf) {
            Ok(httparse::Status::Complete(_)) => {
                let header = |name: &str| {
                    req.headers
                        .iter()
                        .find(|h| h.name.eq_ignore_ascii_case(name))
                        .map(|h| String::from_utf8_lossy(h.value).into_owned())
                };
                let has_body = header("content-length").is_some_and(|v| v.trim() != "0")
                    || header("transfer-encoding").is_some();
                if has_body {
                    return Err(Response::text(413, "request bodies are not accepted"));
                }
                let target = req.path.unwrap_or("/");
                let (path, query) = target.split_once('?').unwrap_or((target, ""));
                return Ok(Request {
                    method: req.method.unwrap_or("GET").to_string(),
                    path: path.to_string(),
                    query: query.to_string(),
                    host: header("host"),
                });
            }
            Ok(httparse::Status::Partial) if buf.len() < limits.max_head => continue,
            Ok(httparse::Status::Partial) => {
                return Err(Response::text(
                    431,
                    format!("the request head exceeds {} bytes", limits.max_head),
                ));
            }
            Err(e) => return Err(Response::text(400, format!("malformed request: {e}"))),
        }
    }
}

/// The handler of every request.
pub type Handler = Arc<dyn Fn(&Request) -> Response + Send + Sync>;

/// A running listener; dropping it does not stop it, [`Listener::stop`] does.
pub struct Listener {
    addr: SocketAddr,
    stop: Arc<AtomicBool>,
    threads: Vec<JoinHandle<()>>,
}

impl Listener {
    /// Serves `listener` with `handler` on background threads.
    pub fn spawn(listener: TcpListener, handler: Handler, limits: Limits) -> std::io::Result<Self> {
        let addr = listener.local_addr()?;
        let stop = Arc::new(AtomicBool::new(false));
        let (tx, rx) = sync_channel::<TcpStream>(limits.backlog.max(1));
        let rx = Arc::new(Mutex::new(rx));
        let mut threads = Vec::new();
        for k in 0..limits.workers.max(1) {
            let rx = Arc::clone(&rx);
            let handler = Arc::clone(&handler);
            threads.push(
                std::thread::Builder::new()
                    .name(format!("evogs-view-http-{k}"))
                    .spawn(move || worker(&rx, &handler, &limits))?,
            );
        }
        let stop_flag = Arc::clone(&stop);
        threads.push(
            std::thread::Builder::new()
                .name("evogs-view-accept".into())
                .spawn(move || accept(&listener, &tx, &stop_flag, &limits))?,
        );
        Ok(Self {
            addr,
            stop,
            threads,
        })
    }

    /// The address it listens on.
    pub fn addr(&self) -> SocketAddr {
        self.addr
    }

    /// Stops accepting, lets the workers finish their requests, and joins every thread.
    pub fn stop(self) {
        self.stop.store(true, Ordering::SeqCst);
        // Wake the accept loop up.
        let _ = TcpStream::connect_timeout(&self.addr, Duration::from_secs(1));
        for t in self.threads {
            let _ = t.join();
        }
    }

    /// Blocks until the listener stops (never, unless a thread fails).
    pub fn join(self) {
        for t in self.threads {
            let _ = t.join();
        }
    }
}

fn accept(listener: &TcpListener, tx: &SyncSender<TcpStream>, stop: &AtomicBool, limits: &Limits) {
    for stream in listener.incoming() {
        if stop.load(Ordering::SeqCst) {
            break;
        }
        let Ok(stream) = stream else { continue };
        let _ = stream.set_write_timeout(Some(limits.timeout));
        match tx.try_send(stream) {
            Ok(()) => {}
            Err(TrySendError::Full(mut stream)) => {
                let _ = stream.set_write_timeout(Some(Duration::from_secs(1)));
                write_response(
                    &mut stream,
                    &Response::text(503, "the viewer is busy: too many connections"),
                    false,
                );
            }
            Err(TrySendError::Disconnected(_)) => break,
        }
    }
    // Dropping the sender ends the workers once the backlog is served.
}

fn worker(rx: &Mutex<Receiver<TcpStream>>, handler: &Handler, limits: &Limits) {
    loop {
        let next = rx.lock().unwrap_or_else(PoisonError::into_inner).recv();
        let Ok(mut stream) = next else { return };
        let (response, head_only) = match read_request(&mut stream, limits) {
            Ok(request) => {
                let head_only = request.method == "HEAD";
                let response = match request.method.as_str() {
                    "GET" | "HEAD" => {
                        // A panic in a handler is a bug; it must not take the worker down.
                        std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| handler(&request)))
                            .unwrap_or_else(|_| Response::text(500, "internal error"))
                    }
                    _ => Response::text(405, "only GET and HEAD are served")
                        .with("Allow", "GET, HEAD"),
                };
                (response, head_only)
            }
            Err(response) => (response, false),
        };
        write_response(&mut stream, &response, head_only);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A client that trickles its head a byte at a time (each byte well within any per-read
    /// timeout) gets its answer at the head deadline, while it is still sending: it cannot hold
    /// the worker for longer.
    #[test]
    fn a_trickled_head_is_answered_at_the_deadline() {
        let listener = TcpListener::bind("127.0.0.1:0").unwrap();
        let limits = Limits {
            workers: 1,
            head_timeout: Duration::from_millis(300),
            ..Limits::default()
        };
        let handler: Handler = Arc::new(|_| Response::text(200, "ok"));
        let server = Listener::spawn(listener, handler, limits).unwrap();
        let mut client = TcpStream::connect(server.addr()).unwrap();
        client
            .set_read_timeout(Some(Duration::from_millis(50)))
            .unwrap();
        let head = b"GET / HTTP/1.1\r\nHost: localhost\r\nX-Slow: ";
        let mut answer = Vec::new();
        // 200 bytes at one per 50 ms is 10 s: far past the 0.3 s deadline.
        for k in 0..200 {
            let byte = head.get(k).copied().unwrap_or(b'a');
            if client.write_all(&[byte]).is_err() {
                break;
            }
            let mut got = [0u8; 256];
            match client.read(&mut got) {
                Ok(0) => break,
                Ok(n) => {
                    answer.extend_from_slice(&got[..n]);
                    break;
                }
                Err(_) => {}
            }
        }
        let answer = String::from_utf8_lossy(&answer);
        assert!(answer.starts_with("HTTP/1.1 400"), "{answer:?}");
        server.stop();
    }
}
