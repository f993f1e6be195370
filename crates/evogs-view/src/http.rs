//! The connection layer: a listener, one thread that reads request heads, a fixed number of
//! worker threads, bounded queues.
//!
//! One thread accepts connections and reads their request heads without blocking on any of them
//! (non-blocking sockets polled in turn, at most [`Limits::pending`] at once; more are answered
//! `503` at once and closed). A head must arrive whole (at most [`Limits::max_head`] bytes) within
//! [`Limits::head_timeout`] of the connection, however it is split, or it is answered `400`. A
//! complete head, parsed with `httparse`, goes to [`Limits::workers`] workers through a channel of
//! [`Limits::backlog`] places (full: `503`). So a client trickling its head a byte at a time (a
//! slowloris) holds one entry of the head list, never a worker: the workers only ever serve
//! complete requests, and another client's request is read and answered at once. (`tiny_http`,
//! the usual small synchronous server, starts a thread per connection without a limit, its issue
//! #221; owning the accept loop is what bounds it here.) Bodies are refused; the handler's
//! response is written with `Connection: close` (within [`Limits::timeout`]).
//!
//! The head thread sleeps [`POLL_INTERVAL`] when a pass over its connections made no progress,
//! and blocks in `accept` when it has none (an idle viewer costs nothing). A readiness API
//! (`epoll` through `mio` or `polling`) would wake it exactly when a byte arrives; at a viewer's
//! handful of connections the 2 ms poll is not measurable and needs no further dependency.

use std::io::ErrorKind;
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
    /// Worker threads (requests served at once).
    pub workers: usize,
    /// Complete requests waiting for a worker; more are answered 503.
    pub backlog: usize,
    /// Connections whose request head is still arriving; more are answered 503.
    pub pending: usize,
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
            pending: 256,
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

/// Parses the request head received so far: `None` while it is incomplete (and within
/// [`Limits::max_head`]), else the request or the response to send instead.
fn parse_head(buf: &[u8], limits: &Limits) -> Option<Result<Request, Response>> {
    let mut headers = [httparse::EMPTY_HEADER; 64];
    let mut req = httparse::Request::new(&mut headers);
    Some(match req.parse(buf) {
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
                return Some(Err(Response::text(413, "request bodies are not accepted")));
            }
            let target = req.path.unwrap_or("/");
            let (path, query) = target.split_once('?').unwrap_or((target, ""));
            Ok(Request {
                method: req.method.unwrap_or("GET").to_string(),
                path: path.to_string(),
                query: query.to_string(),
                host: header("host"),
            })
        }
        Ok(httparse::Status::Partial) if buf.len() < limits.max_head => return None,
        Ok(httparse::Status::Partial) => Err(Response::text(
            431,
            format!("the request head exceeds {} bytes", limits.max_head),
        )),
        Err(e) => Err(Response::text(400, format!("malformed request: {e}"))),
    })
}

/// The handler of every request.
pub type Handler = Arc<dyn Fn(&Request) -> Response + Send + Sync>;

/// A running listener; dropping it does not stop it, [`Listener::stop`] does.
pub struct Listener {
    addr: SocketAddr,
    stop: Arc<AtomicBool>,
    threads: Vec<JoinHandle<()>>,
}

/// How long the head thread sleeps after a pass over its connections that read nothing.
pub const POLL_INTERVAL: Duration = Duration::from_millis(2);

/// A complete request head with its connection: what the head thread hands to a worker.
type Job = (TcpStream, Request);

impl Listener {
    /// Serves `listener` with `handler` on background threads.
    pub fn spawn(listener: TcpListener, handler: Handler, limits: Limits) -> std::io::Result<Self> {
        let addr = listener.local_addr()?;
        let stop = Arc::new(AtomicBool::new(false));
        let (tx, rx) = sync_channel::<Job>(limits.backlog.max(1));
        let rx = Arc::new(Mutex::new(rx));
        let mut threads = Vec::new();
        for k in 0..limits.workers.max(1) {
            let rx = Arc::clone(&rx);
            let handler = Arc::clone(&handler);
            threads.push(
                std::thread::Builder::new()
                    .name(format!("evogs-view-http-{k}"))
                    .spawn(move || worker(&rx, &handler))?,
            );
        }
        let stop_flag = Arc::clone(&stop);
        threads.push(
            std::thread::Builder::new()
                .name("evogs-view-heads".into())
                .spawn(move || read_heads(&listener, &tx, &stop_flag, &limits))?,
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
        // Wake the accept loop up (it blocks in `accept` when no head is arriving).
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

/// A connection whose request head is still arriving.
struct Arriving {
    stream: TcpStream,
    head: Vec<u8>,
    deadline: Instant,
}

/// Answers `response` on a connection that no worker will serve (busy, late or malformed) and
/// closes it. The socket is non-blocking: a short answer fits the kernel's send buffer, and a
/// client that does not read cannot stall the head thread.
fn refuse(mut stream: TcpStream, response: &Response) {
    let _ = stream.set_nonblocking(true);
    write_response(&mut stream, response, false);
}

/// The head thread: accepts connections, reads their heads without blocking on any, and hands
/// each complete head to the workers (see the module's documentation).
fn read_heads(listener: &TcpListener, tx: &SyncSender<Job>, stop: &AtomicBool, limits: &Limits) {
    let mut arriving: Vec<Arriving> = Vec::new();
    let mut chunk = [0u8; 4096];
    loop {
        // Block in `accept` when nothing is arriving; otherwise take what is queued and go on.
        let idle = arriving.is_empty();
        if listener.set_nonblocking(!idle).is_err() {
            return;
        }
        loop {
            match listener.accept() {
                Ok((stream, _)) => {
                    if stop.load(Ordering::SeqCst) {
                        return;
                    }
                    if arriving.len() >= limits.pending.max(1) {
                        refuse(
                            stream,
                            &Response::text(503, "the viewer is busy: too many connections"),
                        );
                    } else if stream.set_nonblocking(true).is_ok() {
                        arriving.push(Arriving {
                            stream,
                            head: Vec::new(),
                            deadline: Instant::now() + limits.head_timeout,
                        });
                    }
                    if idle {
                        break;
                    }
                }
                Err(e) if e.kind() == ErrorKind::WouldBlock => break,
                // A failed accept (e.g. out of file descriptors) is the client's loss; the next
                // pass tries again.
                Err(_) => {
                    std::thread::sleep(POLL_INTERVAL);
                    break;
                }
            }
        }
        if stop.load(Ordering::SeqCst) {
            return;
        }
        let now = Instant::now();
        let mut progress = false;
        let mut k = 0;
        while k < arriving.len() {
            let a = &mut arriving[k];
            let outcome = loop {
                match a.stream.read(&mut chunk) {
                    Ok(0) => {
                        break Some(Err(Response::text(
                            400,
                            "the connection closed mid-request",
                        )));
                    }
                    Ok(n) => {
                        progress = true;
                        a.head.extend_from_slice(&chunk[..n]);
                        if let Some(parsed) = parse_head(&a.head, limits) {
                            break Some(parsed);
                        }
                    }
                    Err(e) if e.kind() == ErrorKind::WouldBlock => {
                        break (now >= a.deadline).then(|| {
                            Err(Response::text(
                                400,
                                "the request head did not arrive in time",
                            ))
                        });
                    }
                    Err(e) if e.kind() == ErrorKind::Interrupted => {}
                    Err(_) => break Some(Err(Response::text(400, "the connection failed"))),
                }
            };
            let Some(outcome) = outcome else {
                k += 1;
                continue;
            };
            let Arriving { stream, .. } = arriving.swap_remove(k);
            match outcome {
                Err(response) => refuse(stream, &response),
                Ok(request) => {
                    if stream.set_nonblocking(false).is_err()
                        || stream.set_write_timeout(Some(limits.timeout)).is_err()
                    {
                        continue;
                    }
                    match tx.try_send((stream, request)) {
                        Ok(()) => {}
                        Err(TrySendError::Full((stream, _))) => refuse(
                            stream,
                            &Response::text(503, "the viewer is busy: too many requests"),
                        ),
                        Err(TrySendError::Disconnected(_)) => return,
                    }
                }
            }
        }
        if !progress && !arriving.is_empty() {
            std::thread::sleep(POLL_INTERVAL);
        }
    }
    // Dropping the sender ends the workers once the backlog is served.
}

fn worker(rx: &Mutex<Receiver<Job>>, handler: &Handler) {
    loop {
        let next = rx.lock().unwrap_or_else(PoisonError::into_inner).recv();
        let Ok((mut stream, request)) = next else {
            return;
        };
        let response = match request.method.as_str() {
            "GET" | "HEAD" => {
                // A panic in a handler is a bug; it must not take the worker down.
                std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| handler(&request)))
                    .unwrap_or_else(|_| Response::text(500, "internal error"))
            }
            _ => Response::text(405, "only GET and HEAD are served").with("Allow", "GET, HEAD"),
        };
        write_response(&mut stream, &response, request.method == "HEAD");
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

    /// Sends a complete GET and returns the answer's status line and how long it took.
    fn get(addr: SocketAddr) -> (String, Duration) {
        let start = Instant::now();
        let mut client = TcpStream::connect(addr).unwrap();
        client
            .set_read_timeout(Some(Duration::from_secs(10)))
            .unwrap();
        client
            .write_all(b"GET / HTTP/1.1\r\nHost: localhost\r\n\r\n")
            .unwrap();
        let mut answer = Vec::new();
        let _ = client.read_to_end(&mut answer);
        let answer = String::from_utf8_lossy(&answer).into_owned();
        let status = answer.lines().next().unwrap_or("").to_string();
        (status, start.elapsed())
    }

    /// The slowloris case, bounded: 50 clients trickling their heads a byte every 100 ms
    /// (more than eight times the workers) do not delay another client, whose request is
    /// answered within a second every time while they are connected.
    #[test]
    fn fifty_trickling_clients_do_not_delay_a_normal_request() {
        let listener = TcpListener::bind("127.0.0.1:0").unwrap();
        let limits = Limits::default();
        let handler: Handler = Arc::new(|_| Response::text(200, "ok"));
        let server = Listener::spawn(listener, handler, limits).unwrap();
        let addr = server.addr();
        let mut slow: Vec<TcpStream> = (0..50).map(|_| TcpStream::connect(addr).unwrap()).collect();
        let head = b"GET / HTTP/1.1\r\nHost: localhost\r\nX-Slow: ";
        let start = Instant::now();
        let mut answered = 0;
        // 2 s of trickling: within the 3 s head deadline, so every slow client stays pending.
        for tick in 0..20 {
            for client in &mut slow {
                client
                    .write_all(&[head.get(tick).copied().unwrap_or(b'a')])
                    .unwrap();
            }
            if tick % 4 == 3 {
                let (status, took) = get(addr);
                assert_eq!(status, "HTTP/1.1 200 OK", "tick {tick}");
                assert!(
                    took < Duration::from_secs(1),
                    "answered after {took:?} at tick {tick}"
                );
                answered += 1;
            }
            std::thread::sleep(Duration::from_millis(100));
        }
        assert!(
            start.elapsed() < limits.head_timeout,
            "the test outlived the slow clients' deadline"
        );
        assert_eq!(answered, 5);
        drop(slow);
        server.stop();
    }

    /// More connections with their heads still arriving than [`Limits::pending`] are answered
    /// 503 at once, and the server answers normally again once they are gone.
    #[test]
    fn connections_beyond_the_pending_limit_are_refused_at_once() {
        let listener = TcpListener::bind("127.0.0.1:0").unwrap();
        let limits = Limits {
            pending: 4,
            ..Limits::default()
        };
        let handler: Handler = Arc::new(|_| Response::text(200, "ok"));
        let server = Listener::spawn(listener, handler, limits).unwrap();
        let addr = server.addr();
        let idle: Vec<TcpStream> = (0..4).map(|_| TcpStream::connect(addr).unwrap()).collect();
        // Let the head thread take the four before the fifth arrives.
        std::thread::sleep(Duration::from_millis(100));
        let (status, took) = get(addr);
        assert_eq!(status, "HTTP/1.1 503 Service Unavailable");
        assert!(took < Duration::from_secs(1), "{took:?}");
        drop(idle);
        std::thread::sleep(Duration::from_millis(100));
        assert_eq!(get(addr).0, "HTTP/1.1 200 OK");
        server.stop();
    }
}
