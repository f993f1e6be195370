//! What the viewer's tests share: a tiny trained run, and a running `evogs view` asked through
//! the viewer's own minimal HTTP client (`evogs_view::client`).

use std::io::{BufRead, BufReader, Read};
use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::process::{Child, Stdio};
use std::time::Duration;

use evogs_view::client;
pub use evogs_view::client::Reply;

use super::{command, evogs_ok, ok, rigid_scene, s, train_tiny};

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

/// Trains a run of `iterations` on the 32×32 rigid scene of 16 frames in `dir/scene` (written
/// first if missing) into `dir/name`.
pub fn train_run(dir: &Path, name: &str, iterations: u32) -> PathBuf {
    train_run_with(dir, name, iterations, &[])
}

/// [`train_run`] with more `evogs train` arguments.
pub fn train_run_with(dir: &Path, name: &str, iterations: u32, extra: &[&str]) -> PathBuf {
    let data = dir.join("scene");
    if !data.exists() {
        rigid_scene(dir, 32, 16);
    }
    let run = dir.join(name);
    let iterations = iterations.to_string();
    ok(&train_tiny(
        &data,
        &run,
        &[&["--iterations", &iterations][..], extra].concat(),
    ));
    run
}

/// The shared fixture: the trained run, evaluated on its test split.
pub fn fixture() -> RunFixture {
    let dir = tempfile::tempdir().unwrap();
    let run = train_run(dir.path(), "trained", 100);
    evogs_ok(&["eval", "--run", s(&run), "--split", "test"]);
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
        let child = command()
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
        client::get(self.addr, path, Duration::from_secs(120)).unwrap()
    }

    /// Sends `bytes` as they are and reads the reply.
    pub fn raw(&self, bytes: &[u8]) -> Reply {
        client::send(self.addr, bytes, Duration::from_secs(120)).unwrap()
    }
}

impl Drop for Viewer {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// A reply's body as an image.
pub trait ReplyImage {
    /// The body decoded as an image (the status must be 200).
    fn image(&self) -> image::RgbImage;
}

impl ReplyImage for Reply {
    fn image(&self) -> image::RgbImage {
        assert_eq!(self.status, 200, "{}", self.text());
        image::load_from_memory(&self.body).unwrap().to_rgb8()
    }
}
