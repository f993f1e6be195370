//! Request parameters, parsed strictly: every problem is a [`BadRequest`] with a one-line reason
//! that the server answers as HTTP 400.
//!
//! - A query is `key=value` pairs (percent-decoded); an unknown key, a repeated key or a query
//!   longer than [`MAX_QUERY`] bytes is refused.
//! - Numbers must be finite; sizes whole numbers in `1..=`[`MAX_SIDE`].
//! - A camera is either `cam=dataset:SPLIT:INDEX` (a camera of the run's dataset; a camera file
//!   is never read from a request) or a pose: `R` (the world-to-camera rotation, 9 numbers, row
//!   by row: the camera's x, y, z axes in world, OpenCV axes), `C` (the centre, 3 numbers) and
//!   `K` (`fx,fy,cx,cy` in pixels of the requested `w × h`), with `w` and `h`. `R` must be a
//!   proper rotation within evogs-io's [`evogs_io::ROTATION_TOLERANCE`] (the tolerance camera
//!   files are read with).

use std::collections::HashMap;

use evogs_io::Split;
use evogs_video::camera_path::CameraSpec;
use glam::{Mat3, Vec3};
use splat_raster::Camera;

/// Renders and images wider or taller than this are refused.
pub const MAX_SIDE: u32 = 2048;

/// Queries longer than this many bytes are refused.
pub const MAX_QUERY: usize = 2048;

/// A request that cannot be served, and why (one line).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct BadRequest(pub String);

impl BadRequest {
    fn new(text: impl Into<String>) -> Self {
        Self(text.into())
    }
}

impl std::fmt::Display for BadRequest {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

/// The image encoding of a response.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Format {
    /// JPEG (quality [`crate::server::JPEG_QUALITY`]): the page's views.
    Jpeg,
    /// PNG, lossless: saving a view, and tests.
    Png,
}

/// Where a view is seen from.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum CameraParam {
    /// A camera of run 0's dataset, at the run's resolution unless `w`/`h` resize it.
    Dataset {
        /// The split.
        split: Split,
        /// Its index in file order.
        index: usize,
    },
    /// An explicit camera.
    Pose(Camera),
}

/// `GET /api/render`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RenderParams {
    /// Which run (0, or 1 for the second of two).
    pub run: usize,
    /// The camera.
    pub camera: CameraParam,
    /// The scene time; absent: the dataset camera's time, or 0.
    pub time: Option<f32>,
    /// Output size (a dataset camera is resized to it, fx/cx by the width ratio and fy/cy by
    /// the height ratio, as `evogs render --width --height` does).
    pub width: Option<u32>,
    /// Output size.
    pub height: Option<u32>,
    /// The encoding.
    pub format: Format,
    /// `controls=1`: draw the run's control points over the view (`0` or absent: not).
    pub controls: bool,
}

/// `GET /api/gt`: a ground-truth image of run 0's dataset.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct GtParams {
    /// The split.
    pub split: Split,
    /// Its index in file order.
    pub index: usize,
    /// The encoding.
    pub format: Format,
}

/// The parsed query: each allowed key at most once.
pub struct Query(HashMap<String, String>);

impl Query {
    /// Parses `raw` (the part after `?`, possibly empty), allowing only the keys in `allowed`.
    pub fn parse(raw: &str, allowed: &[&str]) -> Result<Self, BadRequest> {
        if raw.len() > MAX_QUERY {
            return Err(BadRequest::new(format!(
                "the query is {} bytes long; at most {MAX_QUERY} are accepted",
                raw.len()
            )));
        }
        let mut map = HashMap::new();
        for (key, value) in form_urlencoded::parse(raw.as_bytes()) {
            if !allowed.contains(&key.as_ref()) {
                return Err(BadRequest::new(format!(
                    "unknown parameter `{}`; expected one of {}",
                    printable(&key),
                    allowed.join(", ")
                )));
            }
            if map.insert(key.to_string(), value.into_owned()).is_some() {
                return Err(BadRequest::new(format!("parameter `{key}` is given twice")));
            }
        }
        Ok(Self(map))
    }

    fn get(&self, key: &str) -> Option<&str> {
        self.0.get(key).map(String::as_str)
    }

    /// A finite number, if present.
    pub fn number(&self, key: &str) -> Result<Option<f32>, BadRequest> {
        self.get(key).map(|v| number(key, v)).transpose()
    }

    /// A comma-separated list of exactly `n` finite numbers, if present.
    pub fn numbers(&self, key: &str, n: usize) -> Result<Option<Vec<f32>>, BadRequest> {
        let Some(text) = self.get(key) else {
            return Ok(None);
        };
        let values: Vec<&str> = text.split(',').collect();
        if values.len() != n {
            return Err(BadRequest::new(format!(
                "`{key}` has {} values; expected {n} separated by commas",
                values.len()
            )));
        }
        values
            .iter()
            .enumerate()
            .map(|(i, v)| number(&format!("{key}[{i}]"), v))
            .collect::<Result<Vec<_>, _>>()
            .map(Some)
    }

    /// An image side in `1..=MAX_SIDE`, if present.
    pub fn side(&self, key: &str) -> Result<Option<u32>, BadRequest> {
        self.get(key)
            .map(|v| match v.parse::<u32>() {
                Ok(s) if (1..=MAX_SIDE).contains(&s) => Ok(s),
                _ => Err(BadRequest::new(format!(
                    "`{key}` is `{}`; expected a whole number of pixels in 1..={MAX_SIDE}",
                    printable(v)
                ))),
            })
            .transpose()
    }

    /// A whole number below `limit` (default 0 when absent); `usize::MAX`: no limit known here
    /// (the caller checks it), and the message says only that a whole number is expected.
    pub fn index(&self, key: &str, limit: usize) -> Result<usize, BadRequest> {
        let Some(v) = self.get(key) else {
            return Ok(0);
        };
        match v.parse::<usize>() {
            Ok(i) if i < limit => Ok(i),
            _ if limit == usize::MAX => Err(BadRequest::new(format!(
                "`{key}` is `{}`; expected a whole number (0, 1, 2, ...)",
                printable(v)
            ))),
            _ => Err(BadRequest::new(format!(
                "`{key}` is `{}`; expected a whole number in 0..{limit}",
                printable(v)
            ))),
        }
    }

    /// A switch: `1` on, `0` or absent off.
    pub fn switch(&self, key: &str) -> Result<bool, BadRequest> {
        match self.get(key) {
            None | Some("0") => Ok(false),
            Some("1") => Ok(true),
            Some(other) => Err(BadRequest::new(format!(
                "`{key}` is `{}`; expected 1 or 0",
                printable(other)
            ))),
        }
    }

    /// `fmt`: `jpeg` (default) or `png`.
    pub fn format(&self) -> Result<Format, BadRequest> {
        match self.get("fmt") {
            None | Some("jpeg" | "jpg") => Ok(Format::Jpeg),
            Some("png") => Ok(Format::Png),
            Some(other) => Err(BadRequest::new(format!(
                "`fmt` is `{}`; expected jpeg or png",
                printable(other)
            ))),
        }
    }

    /// A required value.
    pub fn required<'a>(&'a self, key: &str) -> Result<&'a str, BadRequest> {
        self.get(key)
            .ok_or_else(|| BadRequest::new(format!("parameter `{key}` is missing")))
    }

    /// A split name: train, val or test.
    pub fn split(&self, key: &str) -> Result<Split, BadRequest> {
        let text = self.required(key)?;
        text.parse::<Split>()
            .map_err(|e| BadRequest::new(format!("`{key}`: {}", printable(&e))))
    }
}

/// At most 60 characters of `text`, control characters replaced, so that a reason stays one
/// readable line whatever a request holds.
fn printable(text: &str) -> String {
    let mut out: String = text
        .chars()
        .take(60)
        .map(|c| if c.is_control() { '?' } else { c })
        .collect();
    if text.chars().count() > 60 {
        out.push('…');
    }
    out
}

fn number(key: &str, text: &str) -> Result<f32, BadRequest> {
    match text.trim().parse::<f32>() {
        Ok(v) if v.is_finite() => Ok(v),
        _ => Err(BadRequest::new(format!(
            "`{key}` is `{}`; expected a finite number",
            printable(text)
        ))),
    }
}

/// The camera of a query: `cam=dataset:SPLIT:INDEX`, or `R`, `C`, `K`, `w`, `h` (module docs).
pub fn camera(query: &Query) -> Result<CameraParam, BadRequest> {
    if let Some(spec) = query.get("cam") {
        if ["R", "C", "K"].iter().any(|k| query.get(k).is_some()) {
            return Err(BadRequest::new(
                "give either `cam` or `R`, `C`, `K`, not both",
            ));
        }
        return match spec.parse::<CameraSpec>() {
            Ok(CameraSpec::Dataset { split, index }) => Ok(CameraParam::Dataset { split, index }),
            Ok(CameraSpec::File(_)) => Err(BadRequest::new(format!(
                "`cam` is `{}`; expected dataset:SPLIT:INDEX (camera files are not read from \
                 requests)",
                printable(spec)
            ))),
            Err(e) => Err(BadRequest::new(format!("`cam`: {}", printable(&e)))),
        };
    }
    let missing = || BadRequest::new("a camera needs `cam=dataset:SPLIT:INDEX` or `R`, `C`, `K`");
    let r = query.numbers("R", 9)?.ok_or_else(missing)?;
    let c = query.numbers("C", 3)?.ok_or_else(missing)?;
    let k = query.numbers("K", 4)?.ok_or_else(missing)?;
    let width = query
        .side("w")?
        .ok_or_else(|| BadRequest::new("a pose camera needs `w` and `h`"))?;
    let height = query
        .side("h")?
        .ok_or_else(|| BadRequest::new("a pose camera needs `w` and `h`"))?;
    let rows = [0, 1, 2].map(|i| [0, 1, 2].map(|j| f64::from(r[3 * i + j])));
    let err = evogs_io::rotation_error(&rows);
    if err > evogs_io::ROTATION_TOLERANCE {
        return Err(BadRequest::new(format!(
            "`R` is not a rotation matrix (R·Rᵀ − I reaches {err:.3e}, or det(R) <= 0)"
        )));
    }
    if k[0] <= 0.0 || k[1] <= 0.0 {
        return Err(BadRequest::new("`K`: the focal lengths must be positive"));
    }
    let rotation =
        Mat3::from_cols_array(&[r[0], r[1], r[2], r[3], r[4], r[5], r[6], r[7], r[8]]).transpose();
    Ok(CameraParam::Pose(Camera::from_center(
        width,
        height,
        k[0],
        k[1],
        k[2],
        k[3],
        rotation,
        Vec3::new(c[0], c[1], c[2]),
    )))
}

/// Parses `GET /api/render`'s query; `runs` is how many runs the viewer shows.
pub fn render_params(raw: &str, runs: usize) -> Result<RenderParams, BadRequest> {
    let query = Query::parse(
        raw,
        &[
            "run", "cam", "R", "C", "K", "t", "w", "h", "fmt", "seq", "controls",
        ],
    )?;
    let camera = camera(&query)?;
    Ok(RenderParams {
        run: query.index("run", runs)?,
        camera,
        time: query.number("t")?,
        width: query.side("w")?,
        height: query.side("h")?,
        format: query.format()?,
        controls: query.switch("controls")?,
    })
}

/// Parses `GET /api/gt`'s query (the index is checked against the split by the caller).
pub fn gt_params(raw: &str) -> Result<GtParams, BadRequest> {
    let query = Query::parse(raw, &["split", "index", "fmt"])?;
    let split = query.split("split")?;
    query.required("index")?;
    Ok(GtParams {
        split,
        index: query.index("index", usize::MAX)?,
        format: query.format()?,
    })
}

/// Parses `GET /api/camera`'s query: a pose camera (`R`, `C`, `K`, `w`, `h`) or a dataset one.
pub fn camera_params(raw: &str) -> Result<CameraParam, BadRequest> {
    let query = Query::parse(raw, &["cam", "R", "C", "K", "w", "h"])?;
    camera(&query)
}

#[cfg(test)]
mod tests {
    use super::*;

    const POSE: &str = "R=1,0,0,0,1,0,0,0,1&C=0,0,-4&K=100,100,50,40&w=100&h=80";

    #[test]
    fn parses_a_pose_camera() {
        let p = render_params(&format!("{POSE}&t=0.25&fmt=png"), 1).unwrap();
        let CameraParam::Pose(c) = p.camera else {
            panic!("{p:?}")
        };
        assert_eq!((c.width, c.height, c.fx, c.cy), (100, 80, 100.0, 40.0));
        assert_eq!(c.center(), Vec3::new(0.0, 0.0, -4.0));
        assert_eq!(p.time, Some(0.25));
        assert_eq!(p.format, Format::Png);
        assert_eq!(p.run, 0);
    }

    #[test]
    fn parses_a_dataset_camera() {
        let p = render_params("cam=dataset%3Atest%3A3&w=64", 2).unwrap();
        assert_eq!(
            p.camera,
            CameraParam::Dataset {
                split: Split::Test,
                index: 3
            }
        );
        assert_eq!((p.width, p.height, p.time), (Some(64), None, None));
    }

    fn reason(raw: &str) -> String {
        render_params(raw, 2).unwrap_err().0
    }

    #[test]
    fn refuses_bad_numbers_sizes_and_cameras() {
        for (query, expect) in [
            (
                format!("{POSE}&t=NaN"),
                "`t` is `NaN`; expected a finite number",
            ),
            (format!("{POSE}&t=inf"), "`t` is `inf`"),
            (format!("{POSE}&t=1e39"), "`t` is `1e39`"),
            (POSE.replace("w=100", "w=100000"), "`w` is `100000`"),
            (POSE.replace("w=100", "w=0"), "`w` is `0`"),
            (POSE.replace("w=100", "w=-5"), "`w` is `-5`"),
            (POSE.replace("C=0,0,-4", "C=0,0"), "`C` has 2 values"),
            (POSE.replace("C=0,0,-4", "C=0,x,1"), "`C[1]` is `x`"),
            (POSE.replace("R=1,0,0", "R=2,0,0"), "not a rotation matrix"),
            (
                POSE.replace("R=1,0,0,0,1,0", "R=-1,0,0,0,1,0"),
                "not a rotation matrix",
            ),
            (
                POSE.replace("K=100", "K=-100"),
                "focal lengths must be positive",
            ),
            (
                format!("{POSE}&run=2"),
                "`run` is `2`; expected a whole number in 0..2",
            ),
            (format!("{POSE}&fmt=gif"), "`fmt` is `gif`"),
            (format!("{POSE}&t=1&t=2"), "`t` is given twice"),
            (
                format!("{POSE}&path=/etc/passwd"),
                "unknown parameter `path`",
            ),
            ("t=0.5".to_string(), "a camera needs"),
            (
                "cam=../../etc/passwd".to_string(),
                "camera files are not read",
            ),
            (
                "cam=%2Fetc%2Fpasswd".to_string(),
                "camera files are not read",
            ),
            ("cam=dataset:dev:1".to_string(), "unknown split `dev`"),
            ("cam=dataset:test:-1".to_string(), "not a whole number"),
            (format!("cam=dataset:test:1&{POSE}"), "either `cam` or"),
            ("x".repeat(MAX_QUERY + 1), "at most 2048"),
        ] {
            let got = reason(&query);
            assert!(got.contains(expect), "{query}: {got}");
            assert!(!got.contains('\n'), "{got}");
        }
    }

    #[test]
    fn reasons_stay_short_and_printable() {
        let got = reason(&format!("{POSE}&t=%0A{}", "9".repeat(500)));
        assert!(got.len() < 200 && !got.contains('\n'), "{got}");
    }

    #[test]
    fn gt_and_camera_queries() {
        assert_eq!(
            gt_params("split=val&index=2").unwrap(),
            GtParams {
                split: Split::Val,
                index: 2,
                format: Format::Jpeg
            }
        );
        assert!(
            gt_params("split=val")
                .unwrap_err()
                .0
                .contains("`index` is missing")
        );
        assert!(gt_params("split=../x&index=0").is_err());
        // A negative index names what is expected, not a range up to usize::MAX.
        let e = gt_params("split=val&index=-1").unwrap_err().0;
        assert_eq!(e, "`index` is `-1`; expected a whole number (0, 1, 2, ...)");
        assert!(matches!(camera_params(POSE), Ok(CameraParam::Pose(_))));
        assert!(camera_params("R=1").is_err());
    }
}
