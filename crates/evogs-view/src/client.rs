//! A minimal HTTP/1.1 client of a running viewer, for its tests and the timing example: one
//! request per connection (as the viewer answers: it closes after each reply), the reply read to
//! the end and split into status, headers and body.
//!
//! What it is not: a general HTTP client (no chunked bodies, redirects, keep-alive or TLS).

use std::io::{Read, Write};
use std::net::{SocketAddr, TcpStream};
use std::time::Duration;

/// A parsed HTTP response.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Reply {
    /// The status code (0 when no response head came back).
    pub status: u16,
    /// The headers, names in lower case.
    pub headers: Vec<(String, String)>,
    /// The body (everything when no response head came back).
    pub body: Vec<u8>,
}

impl Reply {
    /// Splits the bytes of a whole response.
    pub fn parse(all: &[u8]) -> Self {
        let Some(end) = all.windows(4).position(|w| w == b"\r\n\r\n") else {
            return Self {
                status: 0,
                headers: Vec::new(),
                body: all.to_vec(),
            };
        };
        let head = String::from_utf8_lossy(&all[..end]);
        let mut lines = head.split("\r\n");
        let status = lines
            .next()
            .and_then(|l| l.split(' ').nth(1))
            .and_then(|c| c.parse().ok())
            .unwrap_or(0);
        let headers = lines
            .filter_map(|l| l.split_once(':'))
            .map(|(k, v)| (k.trim().to_ascii_lowercase(), v.trim().to_string()))
            .collect();
        Self {
            status,
            headers,
            body: all[end + 4..].to_vec(),
        }
    }

    /// A header's value (`name` in lower case).
    pub fn header(&self, name: &str) -> Option<&str> {
        self.headers
            .iter()
            .find(|(k, _)| k == name)
            .map(|(_, v)| v.as_str())
    }

    /// The body as text (invalid UTF-8 replaced).
    pub fn text(&self) -> String {
        String::from_utf8_lossy(&self.body).into_owned()
    }
}

/// Sends `bytes` as they are to `addr` and reads the reply until the server closes (waiting at
/// most `timeout` for each read). Only a failed connection is an error: a server that answers
/// and closes before all of a long request is written, or resets the connection, gives what it
/// sent (status 0 when that was nothing), since hostile requests are expected to end that way.
pub fn send(addr: SocketAddr, bytes: &[u8], timeout: Duration) -> std::io::Result<Reply> {
    let mut stream = TcpStream::connect(addr)?;
    stream.set_read_timeout(Some(timeout))?;
    let _ = stream.write_all(bytes);
    let mut all = Vec::new();
    let _ = stream.read_to_end(&mut all);
    Ok(Reply::parse(&all))
}

/// `GET path` (with its query) from the viewer at `addr`, with a loopback `Host` header.
pub fn get(addr: SocketAddr, path: &str, timeout: Duration) -> std::io::Result<Reply> {
    send(
        addr,
        format!(
            "GET {path} HTTP/1.1\r\nHost: 127.0.0.1:{}\r\n\r\n",
            addr.port()
        )
        .as_bytes(),
        timeout,
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_status_headers_and_body() {
        let r =
            Reply::parse(b"HTTP/1.1 409 Conflict\r\nX-Version: 3\r\nContent-Length: 2\r\n\r\nhi");
        assert_eq!(r.status, 409);
        assert_eq!(r.header("x-version"), Some("3"));
        assert_eq!(r.header("content-length"), Some("2"));
        assert_eq!(r.text(), "hi");
    }

    #[test]
    fn no_head_is_status_zero_with_everything_as_body() {
        let r = Reply::parse(b"garbage");
        assert_eq!(r.status, 0);
        assert!(r.headers.is_empty());
        assert_eq!(r.body, b"garbage");
    }
}
