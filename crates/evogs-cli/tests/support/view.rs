//! What the viewer's tests share: a tiny trained run, a running `evogs view`, and a minimal
//! HTTP/1.1 client (one request per connection, as the viewer answers).

use std::io::{BufRead, BufReader, Read, Write};
use std::net::{SocketAddr, TcpStream};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::Duration;

use super::{evogs, s, stderr};

/// A rigid synthetic scene (16 frames, 32×32) and a run trained on it with the tiny preset,
/// evaluated on the test split (so that the viewer has a PSNR to show).
pub struct RunFixture {
    /// Holds everything.
    pub dir: tempfile::TempDir,
    /// The dataset.
    pub data: PathBuf,
    /// The trained run.
    pub run: PathBuf,
}

fn ok(args: &[&str]) {
    let o = evogs(args);
    assert!(o.status.success(), "evogs {args:?}: {}", stderr(&o));
}

/// Trains a run of `iterations` on a fresh 32×32 rigid scene in `dir/name`.
pub fn train_run(dir: &Path, name: &str, iterations: u32) -> PathBuf {
    let data = dir.join("scene");
    if !data.exists() {
        ok(&[
            "synth",
            "--preset",
            "rigid",
            "--out",
            s(&data),
            "--size",
            "32",
            "--frames",
            "16",
        ]);
    }
    let run = dir.join(name);
    ok(&[
        "train",
        "--data",
        s(&data),
        "--out",
        s(&run),
        "--preset",
        "tiny",
        "--iterations",
        &iterations.to_string(),
    ]);
    run
}

/// The shared fixture: the trained run, evaluated on its test split.
pub fn fixture() -> RunFixture {
    let dir = tempfile::tempdir().unwrap();
    let run = train_run(dir.path(), "trained", 100);
    ok(&["eval", "--run", s(&run), "--split", "test"]);
    RunFixture {
        data: dir.path().join("scene"),
        dir,
        run,
    }
}

/// A running `evogs view`, killed when dropped.
pub struct Viewer {
    child: Child,
    /// Where it listens.
    pub addr: SocketAddr,
    /// What it printed before the URL.
    pub stdout: String,
}

impl Viewer {
    /// Starts `evogs view ARGS --port 0` and waits for its URL.
    pub fn start(args: &[&str]) -> Self {
        let child = Command::new(env!("CARGO_BIN_EXE_evogs"))
            .arg("view")
            .args(args)
            .args(["--port", "0"])
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        // Owned by the viewer from here on, so that it is killed and waited for on every path.
        let mut viewer = Self {
            child,
            addr: SocketAddr::from(([127, 0, 0, 1], 0)),
            stdout: String::new(),
        };
        let mut out = BufReader::new(viewer.child.stdout.take().unwrap());
        loop {
            let mut line = String::new();
            if out.read_line(&mut line).unwrap() == 0 {
                let mut err = String::new();
                if let Some(mut e) = viewer.child.stderr.take() {
                    let _ = e.read_to_string(&mut err);
                }
                panic!("evogs view stopped: {}{err}", viewer.stdout);
            }
            viewer.stdout.push_str(&line);
            if let Some(url) = line.trim().strip_prefix("viewer at http://") {
                viewer.addr = url.split('/').next().unwrap().parse().unwrap();
                // Keep draining stdout so that the viewer never blocks on a full pipe.
                std::thread::spawn(move || std::io::copy(&mut out, &mut std::io::sink()));
                return viewer;
            }
        }
    }

    /// `http://ADDR`.
    pub fn base(&self) -> String {
        format!("http://{}", self.addr)
    }

    /// GET `path` (with the query).
    pub fn get(&self, path: &str) -> Reply {
        self.raw(
            format!(
                "GET {path} HTTP/1.1\r\nHost: 127.0.0.1:{}\r\n\r\n",
                self.addr.port()
            )
            .as_bytes(),
        )
    }

    /// Sends `bytes` as they are and reads the reply.
    pub fn raw(&self, bytes: &[u8]) -> Reply {
        let mut stream = TcpStream::connect(self.addr).unwrap();
        stream
            .set_read_timeout(Some(Duration::from_secs(120)))
            .unwrap();
        // The viewer may answer and close before all of a long request is written.
        let _ = stream.write_all(bytes);
        let mut all = Vec::new();
        let _ = stream.read_to_end(&mut all);
        Reply::parse(&all)
    }
}

impl Drop for Viewer {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// A parsed HTTP response.
#[derive(Debug)]
pub struct Reply {
    /// The status code (0 when nothing came back).
    pub status: u16,
    /// The headers, names in lower case.
    pub headers: Vec<(String, String)>,
    /// The body.
    pub body: Vec<u8>,
}

impl Reply {
    fn parse(all: &[u8]) -> Self {
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

    /// A header's value.
    pub fn header(&self, name: &str) -> Option<&str> {
        self.headers
            .iter()
            .find(|(k, _)| k == name)
            .map(|(_, v)| v.as_str())
    }

    /// The body as text.
    pub fn text(&self) -> String {
        String::from_utf8_lossy(&self.body).into_owned()
    }

    /// The body decoded as an image.
    pub fn image(&self) -> image::RgbImage {
        assert_eq!(self.status, 200, "{}", self.text());
        image::load_from_memory(&self.body).unwrap().to_rgb8()
    }
}

/// Mean and largest absolute channel difference of two images of one size.
pub fn diff(a: &image::RgbImage, b: &image::RgbImage) -> (f64, u8) {
    assert_eq!(a.dimensions(), b.dimensions());
    let mut sum = 0u64;
    let mut max = 0u8;
    for (x, y) in a.as_raw().iter().zip(b.as_raw()) {
        let d = x.abs_diff(*y);
        sum += u64::from(d);
        max = max.max(d);
    }
    (sum as f64 / a.as_raw().len() as f64, max)
}
