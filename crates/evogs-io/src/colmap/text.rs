//! COLMAP's text model files (`cameras.txt`, `images.txt`, `points3D.txt`), as read by D-3DGS
//! `read_intrinsics_text` / `read_extrinsics_text` / `read_points3D_text`. `#` lines are
//! comments; in `images.txt` each image takes two lines, the second (its 2D points, possibly
//! empty) is skipped. Encoders for the same layout are here too (for tests and tools).

use std::fmt::Write as _;
use std::path::Path;
use std::str::FromStr;

use super::model::{CameraModel, ColmapCamera, ColmapImage, ColmapPoint};
use crate::IoError;

fn read(path: &Path) -> Result<String, IoError> {
    let bytes = std::fs::read(path).map_err(|e| IoError::io(path, e))?;
    String::from_utf8(bytes).map_err(|_| IoError::field(path, "(text)", "not UTF-8 text"))
}

/// The whitespace-separated fields of one line, with its line number for errors.
struct Line<'a> {
    path: &'a Path,
    number: usize,
    fields: Vec<&'a str>,
}

impl Line<'_> {
    fn error(&self, field: &str, problem: impl Into<String>) -> IoError {
        IoError::field(self.path, format!("line {}: {field}", self.number), problem)
    }

    fn get<T: FromStr>(&self, index: usize, field: &str) -> Result<T, IoError> {
        let text = self
            .fields
            .get(index)
            .ok_or_else(|| self.error(field, "missing"))?;
        text.parse()
            .map_err(|_| self.error(field, format!("`{text}` is not a valid value")))
    }

    fn finite(&self, index: usize, field: &str) -> Result<f64, IoError> {
        let v: f64 = self.get(index, field)?;
        if !v.is_finite() {
            return Err(self.error(field, format!("{v} is not finite")));
        }
        Ok(v)
    }
}

/// Numbered lines of the text.
fn lines<'a>(path: &'a Path, text: &'a str) -> impl Iterator<Item = Line<'a>> + 'a {
    text.lines().enumerate().map(move |(i, l)| Line {
        path,
        number: i + 1,
        fields: l.split_whitespace().collect(),
    })
}

fn is_blank_or_comment(line: &Line<'_>) -> bool {
    line.fields.first().is_none_or(|f| f.starts_with('#'))
}

/// Reads `cameras.txt`: `CAMERA_ID MODEL WIDTH HEIGHT PARAMS[]`.
pub fn read_cameras_txt(path: &Path) -> Result<Vec<ColmapCamera>, IoError> {
    parse_cameras_txt(path, &read(path)?)
}

/// Parses the text of `cameras.txt`; `path` names it in errors.
pub fn parse_cameras_txt(path: &Path, text: &str) -> Result<Vec<ColmapCamera>, IoError> {
    let mut out = Vec::new();
    for line in lines(path, text).filter(|l| !is_blank_or_comment(l)) {
        let model_name: String = line.get(1, "MODEL")?;
        let model = CameraModel::from_name(&model_name).map_err(|p| line.error("MODEL", p))?;
        let params = (4..line.fields.len())
            .map(|i| line.finite(i, "PARAMS"))
            .collect::<Result<Vec<f64>, _>>()?;
        let camera = ColmapCamera {
            id: line.get(0, "CAMERA_ID")?,
            model,
            width: line.get(2, "WIDTH")?,
            height: line.get(3, "HEIGHT")?,
            params,
        };
        camera.validate().map_err(|p| line.error("camera", p))?;
        out.push(camera);
    }
    Ok(out)
}

/// Reads `images.txt`: `IMAGE_ID QW QX QY QZ TX TY TZ CAMERA_ID NAME`, then a points line.
pub fn read_images_txt(path: &Path) -> Result<Vec<ColmapImage>, IoError> {
    parse_images_txt(path, &read(path)?)
}

/// Parses the text of `images.txt`; `path` names it in errors.
pub fn parse_images_txt(path: &Path, text: &str) -> Result<Vec<ColmapImage>, IoError> {
    let mut out = Vec::new();
    let mut all = lines(path, text);
    while let Some(line) = all.next() {
        if is_blank_or_comment(&line) {
            continue;
        }
        if line.fields.len() < 10 {
            return Err(line.error(
                "image",
                format!(
                    "expected IMAGE_ID QW QX QY QZ TX TY TZ CAMERA_ID NAME, found {} fields",
                    line.fields.len()
                ),
            ));
        }
        let mut qvec = [0.0; 4];
        for (k, v) in qvec.iter_mut().enumerate() {
            *v = line.finite(1 + k, "QVEC")?;
        }
        let mut tvec = [0.0; 3];
        for (k, v) in tvec.iter_mut().enumerate() {
            *v = line.finite(5 + k, "TVEC")?;
        }
        let image = ColmapImage {
            id: line.get(0, "IMAGE_ID")?,
            qvec,
            tvec,
            camera_id: line.get(8, "CAMERA_ID")?,
            name: line.fields[9..].join(" "),
        };
        out.push(image);
        // The 2D points line (possibly empty) belongs to this image.
        all.next();
    }
    Ok(out)
}

/// Reads `points3D.txt`: `POINT3D_ID X Y Z R G B ERROR TRACK[]`.
pub fn read_points3d_txt(path: &Path) -> Result<Vec<ColmapPoint>, IoError> {
    parse_points3d_txt(path, &read(path)?)
}

/// Parses the text of `points3D.txt`; `path` names it in errors.
pub fn parse_points3d_txt(path: &Path, text: &str) -> Result<Vec<ColmapPoint>, IoError> {
    let mut out = Vec::new();
    for line in lines(path, text).filter(|l| !is_blank_or_comment(l)) {
        let xyz = [
            line.finite(1, "X")?,
            line.finite(2, "Y")?,
            line.finite(3, "Z")?,
        ];
        let rgb = [line.get(4, "R")?, line.get(5, "G")?, line.get(6, "B")?];
        out.push(ColmapPoint { xyz, rgb });
    }
    Ok(out)
}

/// Encodes `cameras.txt` (with COLMAP's comment header). Parameters print in Rust's shortest
/// round-trip form, so they read back exactly.
pub fn encode_cameras_txt(cameras: &[ColmapCamera]) -> String {
    let mut out = String::from(
        "# Camera list with one line of data per camera:\n\
         #   CAMERA_ID, MODEL, WIDTH, HEIGHT, PARAMS[]\n",
    );
    let _ = writeln!(out, "# Number of cameras: {}", cameras.len());
    for c in cameras {
        let params: Vec<String> = c.params.iter().map(|p| format!("{p:?}")).collect();
        let _ = writeln!(
            out,
            "{} {} {} {} {}",
            c.id,
            c.model.name(),
            c.width,
            c.height,
            params.join(" ")
        );
    }
    out
}

/// Encodes `images.txt`; each image's 2D points line is empty.
pub fn encode_images_txt(images: &[ColmapImage]) -> String {
    let mut out = String::from(
        "# Image list with two lines of data per image:\n\
         #   IMAGE_ID, QW, QX, QY, QZ, TX, TY, TZ, CAMERA_ID, NAME\n\
         #   POINTS2D[] as (X, Y, POINT3D_ID)\n",
    );
    for im in images {
        let q = im.qvec;
        let t = im.tvec;
        let _ = writeln!(
            out,
            "{} {:?} {:?} {:?} {:?} {:?} {:?} {:?} {} {}\n",
            im.id, q[0], q[1], q[2], q[3], t[0], t[1], t[2], im.camera_id, im.name
        );
    }
    out
}

/// Encodes `points3D.txt`, each point with a one-entry track.
pub fn encode_points3d_txt(points: &[ColmapPoint]) -> String {
    let mut out = String::from(
        "# 3D point list with one line of data per point:\n\
         #   POINT3D_ID, X, Y, Z, R, G, B, ERROR, TRACK[] as (IMAGE_ID, POINT2D_IDX)\n",
    );
    for (i, p) in points.iter().enumerate() {
        let _ = writeln!(
            out,
            "{} {:?} {:?} {:?} {} {} {} 0.25 1 0",
            i + 1,
            p.xyz[0],
            p.xyz[1],
            p.xyz[2],
            p.rgb[0],
            p.rgb[1],
            p.rgb[2]
        );
    }
    out
}
