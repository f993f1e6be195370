//! The routes of the viewer and [`start`].
//!
//! | route | answer |
//! | --- | --- |
//! | `GET /` | the page (`page/index.html`); `/viewer.js`, `/viewer.css` its script and style |
//! | `GET /api/info` | JSON: each run's [`RunInfo`] (Gaussians, method, backend, PSNR from its eval files, dataset cameras) |
//! | `GET /api/render?...` | a view ([`crate::params::render_params`]): JPEG, or PNG with `fmt=png`; headers `X-Render-Ms` (of which `X-Deform-Ms` and `X-Raster-Ms`), `X-Encode-Ms`, `X-Time`, `X-Version` |
//! | `GET /api/gt?split=&index=` | a ground-truth image of run 0's dataset at the run's resolution |
//! | `GET /api/camera?...` | the camera as a nerfies camera JSON that `evogs render --camera` reads |
//!
//! Anything else is 404; methods other than GET and HEAD 405; a bad parameter 400 with the
//! reason; a camera or image the dataset does not have 404; a render superseded by a newer
//! request for the same run 409. While the viewer listens on a loopback address, requests whose
//! `Host` is not a loopback name are refused (403), so that a web page elsewhere cannot reach it
//! through a rebound DNS name.

use std::net::{IpAddr, TcpListener};
use std::path::PathBuf;
use std::sync::Arc;

use evogs_io::image_io::to_u8;
use evogs_io::{CameraInfo, ImageRgb};
use splat_raster::BackendChoice;

use crate::ViewError;
use crate::http::{Handler, Limits, Listener, Request, Response};
use crate::params::{self, BadRequest, CameraParam, Format};
use crate::worker::{GtError, NO_CONTROLS, RenderFailure, RenderJob, RunHandle, RunInfo};

/// JPEG quality of the page's views.
pub const JPEG_QUALITY: u8 = 90;

const INDEX_HTML: &str = include_str!("../page/index.html");
const VIEWER_JS: &str = include_str!("../page/viewer.js");
const VIEWER_CSS: &str = include_str!("../page/viewer.css");

/// The page's Content-Security-Policy: everything from this server only (no external fetch can
/// happen even by mistake); images also from `blob:` (the rendered views).
const CSP: &str = "default-src 'self'; img-src 'self' blob: data:; style-src 'self'; \
                   script-src 'self'; connect-src 'self'; frame-ancestors 'none'";

/// What `evogs view` asks for.
#[derive(Clone, Debug)]
pub struct ViewOptions {
    /// One run, or two shown side by side.
    pub runs: Vec<PathBuf>,
    /// The address to listen on.
    pub host: IpAddr,
    /// The port (0: any free one).
    pub port: u16,
    /// The rasterizer backend.
    pub backend: BackendChoice,
    /// Reload a run when its files change.
    pub watch: bool,
    /// Connection limits.
    pub limits: Limits,
}

/// A started viewer.
pub struct RunningViewer {
    listener: Listener,
    runs: Vec<Arc<RunHandle>>,
}

impl RunningViewer {
    /// The page's address, `http://HOST:PORT/`.
    pub fn url(&self) -> String {
        let addr = self.listener.addr();
        match addr.ip() {
            IpAddr::V6(ip) => format!("http://[{ip}]:{}/", addr.port()),
            IpAddr::V4(ip) => format!("http://{ip}:{}/", addr.port()),
        }
    }

    /// The address it listens on.
    pub fn addr(&self) -> std::net::SocketAddr {
        self.listener.addr()
    }

    /// Each run's current description.
    pub fn infos(&self) -> Vec<Arc<RunInfo>> {
        self.runs.iter().map(|r| r.info()).collect()
    }

    /// Serves until the process ends.
    pub fn wait(self) {
        self.listener.join();
    }

    /// Stops listening and the render threads.
    pub fn stop(self) {
        self.listener.stop();
        for r in &self.runs {
            r.stop();
        }
    }
}

/// Loads the runs and starts serving; returns once the server listens.
pub fn start(options: &ViewOptions) -> Result<RunningViewer, ViewError> {
    if options.runs.is_empty() || options.runs.len() > 2 {
        return Err(ViewError::Option {
            option: "RUN",
            problem: format!(
                "{} runs given; the viewer shows one or two",
                options.runs.len()
            ),
        });
    }
    let runs = options
        .runs
        .iter()
        .map(|r| RunHandle::start(r, options.backend, options.watch))
        .collect::<Result<Vec<_>, _>>()?;
    let listener =
        TcpListener::bind((options.host, options.port)).map_err(|cause| ViewError::Bind {
            addr: format!("{}:{}", options.host, options.port),
            cause,
        })?;
    let routes = Arc::new(Routes {
        runs: runs.clone(),
        loopback_only: options.host.is_loopback(),
    });
    let handler: Handler = Arc::new(move |req: &Request| routes.handle(req));
    let listener =
        Listener::spawn(listener, handler, options.limits).map_err(|cause| ViewError::Bind {
            addr: format!("{}:{}", options.host, options.port),
            cause,
        })?;
    Ok(RunningViewer { listener, runs })
}

/// The request handler: the runs and the host policy.
pub struct Routes {
    runs: Vec<Arc<RunHandle>>,
    loopback_only: bool,
}

/// Whether a `Host` header names this machine's loopback interface, with no port or a port in
/// 1..=65535 written in digits (`127.0.0.1:80@evil.com` and `127.0.0.1:99999999` are not).
fn loopback_host(host: &str) -> bool {
    let (name, port) = if let Some(rest) = host.strip_prefix('[') {
        let Some((name, tail)) = rest.split_once(']') else {
            return false;
        };
        match tail.strip_prefix(':') {
            Some(port) => (name, Some(port)),
            None if tail.is_empty() => (name, None),
            None => return false,
        }
    } else {
        match host.rsplit_once(':') {
            Some((name, port)) => (name, Some(port)),
            None => (host, None),
        }
    };
    let port_ok = port.is_none_or(|p| {
        !p.is_empty()
            && p.bytes().all(|b| b.is_ascii_digit())
            && p.parse::<u16>().is_ok_and(|p| p > 0)
    });
    port_ok
        && (name.eq_ignore_ascii_case("localhost")
            || name.parse::<IpAddr>().is_ok_and(|ip| ip.is_loopback()))
}

fn bad(e: BadRequest) -> Response {
    Response::text(400, e.0)
}

/// Encodes 8-bit RGB in `format`.
pub fn encode(image: &ImageRgb, format: Format) -> Result<Vec<u8>, String> {
    use image::ImageEncoder;
    let bytes: Vec<u8> = image.pixels.iter().flatten().map(|&v| to_u8(v)).collect();
    let mut out = Vec::new();
    let (w, h) = (image.width, image.height);
    let result = match format {
        Format::Jpeg => image::codecs::jpeg::JpegEncoder::new_with_quality(&mut out, JPEG_QUALITY)
            .write_image(&bytes, w, h, image::ExtendedColorType::Rgb8),
        Format::Png => image::codecs::png::PngEncoder::new(&mut out).write_image(
            &bytes,
            w,
            h,
            image::ExtendedColorType::Rgb8,
        ),
    };
    result.map(|()| out).map_err(|e| e.to_string())
}

/// [`encode`] and the milliseconds it took.
fn timed_encode(image: &ImageRgb, format: Format) -> Result<(Vec<u8>, f64), String> {
    let start = std::time::Instant::now();
    let body = encode(image, format)?;
    Ok((body, start.elapsed().as_secs_f64() * 1e3))
}

fn content_type(format: Format) -> &'static str {
    match format {
        Format::Jpeg => "image/jpeg",
        Format::Png => "image/png",
    }
}

impl Routes {
    /// Answers one request (never panics on any input).
    pub fn handle(&self, req: &Request) -> Response {
        if self.loopback_only && !req.host.as_deref().is_some_and(loopback_host) {
            return Response::text(
                403,
                "the viewer listens on loopback only; the Host header must be localhost or a \
                 loopback address",
            );
        }
        let page = |ct: &'static str, body: &str| {
            Response::ok(ct, body.as_bytes().to_vec()).with("Content-Security-Policy", CSP)
        };
        match req.path.as_str() {
            "/" | "/index.html" => page("text/html; charset=utf-8", INDEX_HTML),
            "/viewer.js" => page("text/javascript; charset=utf-8", VIEWER_JS),
            "/viewer.css" => page("text/css; charset=utf-8", VIEWER_CSS),
            "/api/info" => self.info(),
            "/api/render" => self.render(&req.query),
            "/api/gt" => self.gt(&req.query),
            "/api/camera" => self.camera(&req.query),
            _ => Response::text(404, "not found: the viewer serves only its page and /api/"),
        }
    }

    fn info(&self) -> Response {
        let infos: Vec<Arc<RunInfo>> = self.runs.iter().map(|r| r.info()).collect();
        let runs: Vec<&RunInfo> = infos.iter().map(|i| i.as_ref()).collect();
        match serde_json::to_vec(&serde_json::json!({ "runs": runs })) {
            Ok(body) => Response::ok("application/json", body),
            Err(e) => Response::text(500, format!("cannot encode the run info: {e}")),
        }
    }

    fn render(&self, query: &str) -> Response {
        let p = match params::render_params(query, self.runs.len()) {
            Ok(p) => p,
            Err(e) => return bad(e),
        };
        if p.controls && self.runs[p.run].info().control_points.is_none() {
            return bad(BadRequest(NO_CONTROLS.to_string()));
        }
        let job = RenderJob {
            camera: p.camera,
            time: p.time,
            width: p.width,
            height: p.height,
            controls: p.controls,
        };
        match self.runs[p.run].render(job) {
            Ok(r) => match timed_encode(&r.image, p.format) {
                Ok((body, encode_ms)) => Response::ok(content_type(p.format), body)
                    .with("X-Render-Ms", format!("{:.2}", r.millis))
                    .with("X-Deform-Ms", format!("{:.2}", r.deform_millis))
                    .with("X-Raster-Ms", format!("{:.2}", r.raster_millis))
                    .with("X-Encode-Ms", format!("{encode_ms:.2}"))
                    .with("X-Time", r.time.to_string())
                    .with("X-Version", r.version.to_string()),
                Err(e) => Response::text(500, format!("cannot encode the image: {e}")),
            },
            Err(RenderFailure::Superseded) => {
                Response::text(409, "superseded by a newer request for the same run")
            }
            Err(RenderFailure::Bad(e)) => Response::text(404, e.0),
            Err(RenderFailure::Failed(e)) => Response::text(500, format!("render failed: {e}")),
        }
    }

    fn gt(&self, query: &str) -> Response {
        let p = match params::gt_params(query) {
            Ok(p) => p,
            Err(e) => return bad(e),
        };
        match self.runs[0].info().ground_truth(p.split, p.index) {
            Ok(image) => match encode(&image, p.format) {
                Ok(body) => Response::ok(content_type(p.format), body),
                Err(e) => Response::text(500, format!("cannot encode the image: {e}")),
            },
            Err(GtError::Bad(e)) => Response::text(404, e.0),
            Err(GtError::Failed(e)) => Response::text(500, e),
        }
    }

    fn camera(&self, query: &str) -> Response {
        let camera = match params::camera_params(query) {
            Ok(CameraParam::Pose(c)) => c,
            Ok(CameraParam::Dataset { split, index }) => {
                match self.runs[0].info().dataset_camera(split, index) {
                    Ok((c, _)) => c,
                    Err(e) => return Response::text(404, e.0),
                }
            }
            Err(e) => return bad(e),
        };
        let text = evogs_io::camera_json::nerfies_camera_json(&CameraInfo::pinhole(camera));
        Response::ok("application/json", text.into_bytes()).with(
            "Content-Disposition",
            "attachment; filename=\"camera.json\"",
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn loopback_hosts() {
        for ok in [
            "localhost",
            "localhost:8080",
            "127.0.0.1:1",
            "[::1]:80",
            "127.1.2.3",
        ] {
            assert!(loopback_host(ok), "{ok}");
        }
        for no in [
            "example.com",
            "evil.localhost.example:80",
            "10.0.0.1:80",
            "",
            "[::2]:1",
            "127.0.0.1:80@evil.com",
            "127.0.0.1:99999999",
            "127.0.0.1:0",
            "127.0.0.1:",
            "localhost:+80",
            "[::1]x",
            "[::1]:80@evil.com",
            "[::1",
        ] {
            assert!(!loopback_host(no), "{no}");
        }
    }
}
