//! `evogs view`: a local web viewer of trained runs.
//!
//! What it is: an HTTP server (loopback by default) that serves one embedded page
//! (`page/`, HTML/JS/CSS compiled into the binary, no external fetches, no build step) and the
//! images that page asks for: views of a run rendered by the run's own model through
//! `evogs_eval::render::render_at`'s two halves (the function `evogs render --run` uses; the
//! deformed Gaussians are kept while the time stays the same, so a view equals
//! `evogs render`'s output at the same camera and time), ground-truth dataset images, and the
//! current camera as a nerfies camera JSON that `evogs render --camera` reads.
//! - [`params`]: the strict parsing of request parameters (every problem is an HTTP 4xx with a
//!   reason);
//! - [`latest`]: the render slot where the latest request wins (a newer request supersedes one
//!   that has not started; nothing queues without bound);
//! - [`worker`]: the thread that owns a loaded run, renders, and reloads it (`--watch`);
//! - [`http`]: the connection layer: a fixed number of worker threads, a bounded backlog,
//!   request heads parsed by `httparse`, size and time limits;
//! - [`server`]: the routes and [`start`];
//! - [`client`]: a minimal HTTP client of a running viewer (its tests and timing example).
//!
//! What it is not: a renderer (that is `splat-raster`), a trainer, or a file server: no path
//! from a request ever reaches the file system.

pub mod client;
pub mod error;
pub mod http;
pub mod latest;
pub mod params;
pub mod server;
pub mod worker;

pub use error::ViewError;
pub use server::{RunningViewer, ViewOptions, start};
