//! COLMAP's binary model files (little-endian), as written by `colmap model_converter` and read
//! by D-3DGS `read_intrinsics_binary` / `read_extrinsics_binary` / `read_points3D_binary`.
//! Encoders for the same layout are here too (for tests and tools).

use std::path::Path;

use super::model::{CameraModel, ColmapCamera, ColmapImage, ColmapPoint};
use crate::IoError;

/// A reader over the bytes of one file that names the file, the record and the field when the
/// data runs out.
struct Cursor<'a> {
    path: &'a Path,
    bytes: &'a [u8],
    at: usize,
}

impl<'a> Cursor<'a> {
    fn take(&mut self, n: usize, field: &dyn Fn() -> String) -> Result<&'a [u8], IoError> {
        let end = self.at.checked_add(n).filter(|&e| e <= self.bytes.len());
        match end {
            Some(end) => {
                let out = &self.bytes[self.at..end];
                self.at = end;
                Ok(out)
            }
            None => Err(IoError::field(
                self.path,
                field(),
                format!(
                    "truncated: needs {n} bytes at offset {}, the file has {}",
                    self.at,
                    self.bytes.len()
                ),
            )),
        }
    }

    fn u64(&mut self, field: &dyn Fn() -> String) -> Result<u64, IoError> {
        let b = self.take(8, field)?;
        Ok(u64::from_le_bytes(b.try_into().unwrap_or([0; 8])))
    }

    fn i32(&mut self, field: &dyn Fn() -> String) -> Result<i32, IoError> {
        let b = self.take(4, field)?;
        Ok(i32::from_le_bytes(b.try_into().unwrap_or([0; 4])))
    }

    fn f64s<const N: usize>(&mut self, field: &dyn Fn() -> String) -> Result<[f64; N], IoError> {
        let b = self.take(8 * N, field)?;
        let mut out = [0.0; N];
        for (v, chunk) in out.iter_mut().zip(b.chunks_exact(8)) {
            *v = f64::from_le_bytes(chunk.try_into().unwrap_or([0; 8]));
        }
        Ok(out)
    }

    /// A count of records of at least `min_size` bytes each, checked against the bytes left.
    fn count(&mut self, min_size: usize, field: &dyn Fn() -> String) -> Result<usize, IoError> {
        let n = self.u64(field)?;
        let left = (self.bytes.len() - self.at) as u64;
        if n.checked_mul(min_size as u64)
            .is_none_or(|need| need > left)
        {
            return Err(IoError::field(
                self.path,
                field(),
                format!(
                    "truncated: count {n} needs at least {min_size} bytes each, only {left} bytes are left"
                ),
            ));
        }
        Ok(n as usize)
    }

    fn error(&self, field: String, problem: impl Into<String>) -> IoError {
        IoError::field(self.path, field, problem)
    }

    fn finish(&self) -> Result<(), IoError> {
        if self.at != self.bytes.len() {
            return Err(IoError::field(
                self.path,
                "(end)",
                format!(
                    "{} unexpected bytes after the last record",
                    self.bytes.len() - self.at
                ),
            ));
        }
        Ok(())
    }
}

fn read(path: &Path) -> Result<Vec<u8>, IoError> {
    std::fs::read(path).map_err(|e| IoError::io(path, e))
}

fn id_u32(cursor: &Cursor<'_>, value: i64, field: String) -> Result<u32, IoError> {
    u32::try_from(value).map_err(|_| cursor.error(field, format!("{value} is not a valid id")))
}

/// Reads `cameras.bin`.
pub fn read_cameras_bin(path: &Path) -> Result<Vec<ColmapCamera>, IoError> {
    parse_cameras_bin(path, &read(path)?)
}

/// Parses the bytes of `cameras.bin`; `path` names it in errors.
pub fn parse_cameras_bin(path: &Path, bytes: &[u8]) -> Result<Vec<ColmapCamera>, IoError> {
    let mut c = Cursor { path, bytes, at: 0 };
    let n = c.count(24, &|| "num_cameras".into())?;
    let mut out = Vec::with_capacity(n);
    for i in 0..n {
        let f = |what: &'static str| move || format!("cameras[{i}].{what}");
        let id = c.i32(&f("camera_id"))?;
        let id = id_u32(&c, id.into(), f("camera_id")())?;
        let model_id = c.i32(&f("model_id"))?;
        let model = CameraModel::from_id(model_id).map_err(|p| c.error(f("model_id")(), p))?;
        let width = c.u64(&f("width"))?;
        let height = c.u64(&f("height"))?;
        let mut params = Vec::with_capacity(model.param_count());
        for _ in 0..model.param_count() {
            params.push(c.f64s::<1>(&f("params"))?[0]);
        }
        let camera = ColmapCamera {
            id,
            model,
            width: u32::try_from(width).unwrap_or(u32::MAX),
            height: u32::try_from(height).unwrap_or(u32::MAX),
            params,
        };
        camera
            .validate()
            .map_err(|p| c.error(format!("cameras[{i}]"), p))?;
        out.push(camera);
    }
    c.finish()?;
    Ok(out)
}

/// Reads `images.bin` (the 2D point lists are skipped).
pub fn read_images_bin(path: &Path) -> Result<Vec<ColmapImage>, IoError> {
    parse_images_bin(path, &read(path)?)
}

/// Parses the bytes of `images.bin`; `path` names it in errors.
pub fn parse_images_bin(path: &Path, bytes: &[u8]) -> Result<Vec<ColmapImage>, IoError> {
    let mut c = Cursor { path, bytes, at: 0 };
    let n = c.count(73, &|| "num_reg_images".into())?;
    let mut out = Vec::with_capacity(n);
    for i in 0..n {
        let f = |what: &'static str| move || format!("images[{i}].{what}");
        let id = c.i32(&f("image_id"))?;
        let id = id_u32(&c, id.into(), f("image_id")())?;
        let qvec = c.f64s::<4>(&f("qvec"))?;
        let tvec = c.f64s::<3>(&f("tvec"))?;
        let camera_id = c.i32(&f("camera_id"))?;
        let camera_id = id_u32(&c, camera_id.into(), f("camera_id")())?;
        let rest = &bytes[c.at..];
        let len = rest
            .iter()
            .position(|&b| b == 0)
            .ok_or_else(|| c.error(f("name")(), "truncated: no terminating NUL"))?;
        let name = std::str::from_utf8(&rest[..len])
            .map_err(|_| c.error(f("name")(), "not UTF-8"))?
            .to_owned();
        if name.is_empty() {
            return Err(c.error(f("name")(), "empty"));
        }
        c.at += len + 1;
        let points = c.count(24, &f("num_points2D"))?;
        c.take(points * 24, &f("points2D"))?;
        out.push(ColmapImage {
            id,
            qvec,
            tvec,
            camera_id,
            name,
        });
    }
    c.finish()?;
    Ok(out)
}

/// Reads `points3D.bin` (tracks and errors are skipped).
pub fn read_points3d_bin(path: &Path) -> Result<Vec<ColmapPoint>, IoError> {
    parse_points3d_bin(path, &read(path)?)
}

/// Parses the bytes of `points3D.bin`; `path` names it in errors.
pub fn parse_points3d_bin(path: &Path, bytes: &[u8]) -> Result<Vec<ColmapPoint>, IoError> {
    let mut c = Cursor { path, bytes, at: 0 };
    let n = c.count(51, &|| "num_points".into())?;
    let mut out = Vec::with_capacity(n);
    for i in 0..n {
        let f = |what: &'static str| move || format!("points[{i}].{what}");
        c.u64(&f("point3D_id"))?;
        let xyz = c.f64s::<3>(&f("xyz"))?;
        if xyz.iter().any(|v| !v.is_finite()) {
            return Err(c.error(f("xyz")(), "a coordinate is not finite"));
        }
        let rgb = c.take(3, &f("rgb"))?;
        let rgb = [rgb[0], rgb[1], rgb[2]];
        c.f64s::<1>(&f("error"))?;
        let track = c.count(8, &f("track_length"))?;
        c.take(track * 8, &f("track"))?;
        out.push(ColmapPoint { xyz, rgb });
    }
    c.finish()?;
    Ok(out)
}

/// Encodes `cameras.bin`.
pub fn encode_cameras_bin(cameras: &[ColmapCamera]) -> Vec<u8> {
    let mut out = (cameras.len() as u64).to_le_bytes().to_vec();
    for cam in cameras {
        out.extend_from_slice(&(cam.id as i32).to_le_bytes());
        out.extend_from_slice(&cam.model.id().to_le_bytes());
        out.extend_from_slice(&u64::from(cam.width).to_le_bytes());
        out.extend_from_slice(&u64::from(cam.height).to_le_bytes());
        for p in &cam.params {
            out.extend_from_slice(&p.to_le_bytes());
        }
    }
    out
}

/// Encodes `images.bin`, each image with `points2d` dummy 2D points (x, y, id −1).
pub fn encode_images_bin(images: &[ColmapImage], points2d: usize) -> Vec<u8> {
    let mut out = (images.len() as u64).to_le_bytes().to_vec();
    for im in images {
        out.extend_from_slice(&(im.id as i32).to_le_bytes());
        for v in im.qvec.iter().chain(&im.tvec) {
            out.extend_from_slice(&v.to_le_bytes());
        }
        out.extend_from_slice(&(im.camera_id as i32).to_le_bytes());
        out.extend_from_slice(im.name.as_bytes());
        out.push(0);
        out.extend_from_slice(&(points2d as u64).to_le_bytes());
        for k in 0..points2d {
            out.extend_from_slice(&(k as f64).to_le_bytes());
            out.extend_from_slice(&0.5f64.to_le_bytes());
            out.extend_from_slice(&(-1i64).to_le_bytes());
        }
    }
    out
}

/// Encodes `points3D.bin`, each point with a one-entry track.
pub fn encode_points3d_bin(points: &[ColmapPoint]) -> Vec<u8> {
    let mut out = (points.len() as u64).to_le_bytes().to_vec();
    for (i, p) in points.iter().enumerate() {
        out.extend_from_slice(&(i as u64 + 1).to_le_bytes());
        for v in &p.xyz {
            out.extend_from_slice(&v.to_le_bytes());
        }
        out.extend_from_slice(&p.rgb);
        out.extend_from_slice(&0.25f64.to_le_bytes());
        out.extend_from_slice(&1u64.to_le_bytes());
        out.extend_from_slice(&1i32.to_le_bytes());
        out.extend_from_slice(&0i32.to_le_bytes());
    }
    out
}
