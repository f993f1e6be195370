//! Camera paths for videos, and cameras named by a dataset split and index.
//!
//! What it is: the geometry of a video's cameras (DESIGN §9.2).
//! - [`SceneFit`]: the scene's up vector and look-at point fitted to a set of cameras: up is the
//!   normalised mean of the cameras' up vectors (image −y in world, the convention of nerfstudio's
//!   and LLFF's pose averaging); the look-at point is the point nearest to every optical axis in
//!   least squares (minimises `Σ |(I − d dᵀ)(p − c)|²` over the centres `c` and view directions
//!   `d`). Around the axis through that point along up, each camera has a radius (distance from
//!   the axis) and a height (along up).
//! - [`orbit`]: `n` cameras on the circle of the mean radius at the mean height, angles
//!   `φ0 + 2π k / n` counter-clockwise about up, starting at the first camera's angle `φ0`, each
//!   looking at the look-at point with no roll (its x axis perpendicular to up).
//! - [`spiral`]: a helix of [`SPIRAL_TURNS`] turns at the mean radius, from the lowest camera's
//!   height to the highest: at `s = k / (n − 1)` the angle is `φ0 + 2π · turns · s` and the height
//!   `h_min + (h_max − h_min) s`; looking and roll as the orbit.
//! - [`Keyframes`]: cameras with times (a dataset split, or a JSON list) in time order, and the
//!   path through them: at a parameter `u ∈ [0, m − 1]` between keyframes `k = ⌊u⌋` and `k + 1`,
//!   the centre, intrinsics and time are interpolated linearly and the rotation by slerp; at a
//!   whole `u = k` it is keyframe `k` exactly, with its time.
//! - [`CameraSpec`]: a camera file or `dataset:SPLIT:INDEX`, and [`split_cameras`]: a run's dataset
//!   cameras at the run's resolution (the cameras evaluation renders from).
//!
//! What it is not: a renderer or an encoder (`evogs_eval::render`, `evogs_io::VideoWriter`).

use std::fmt;
use std::path::{Path, PathBuf};
use std::str::FromStr;

use evogs_eval::LoadedRun;
use evogs_io::{Format, Split};
use evogs_train::TrainError;
use evogs_train::data::open_dataset;
use glam::{DMat3, DVec3, Mat3, Quat, Vec3};
use splat_raster::Camera;

/// Turns of the [`spiral`] path.
pub const SPIRAL_TURNS: f32 = 2.0;

/// A camera's up vector in world coordinates: image −y (OpenCV axes, DESIGN §1.2).
pub fn camera_up(camera: &Camera) -> Vec3 {
    -camera.rotation.row(1)
}

/// A camera's view direction in world coordinates: camera +z.
pub fn camera_forward(camera: &Camera) -> Vec3 {
    camera.rotation.row(2)
}

/// A camera with `template`'s size and intrinsics at `eye`, looking at `target`, with its x axis
/// perpendicular to `up` and image up towards `up`.
pub fn looking_at(template: &Camera, eye: Vec3, target: Vec3, up: Vec3) -> Camera {
    let posed = Camera::look_at(template.width, template.height, 1.0, eye, target, up);
    Camera {
        rotation: posed.rotation,
        translation: posed.translation,
        ..*template
    }
}

/// The scene's up vector and look-at point fitted to a set of cameras, and the cameras' radii and
/// heights about the axis through the look-at point along up (see the module docs).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SceneFit {
    /// Unit up vector.
    pub up: Vec3,
    /// The look-at point.
    pub target: Vec3,
    /// Unit vector perpendicular to up, towards the first camera (angle 0).
    pub e1: Vec3,
    /// `up × e1`: angle π/2.
    pub e2: Vec3,
    /// Mean distance of the cameras from the axis.
    pub radius: f32,
    /// Mean, lowest and highest camera height above the look-at point along up.
    pub height_mean: f32,
    /// Lowest camera height.
    pub height_min: f32,
    /// Highest camera height.
    pub height_max: f32,
}

impl SceneFit {
    /// Fits the scene to `cameras` (at least one). When every optical axis is parallel (no
    /// nearest point), the look-at point is the centres' mean moved one mean camera distance
    /// from it along the mean view direction (1 for a single camera).
    pub fn fit(cameras: &[Camera]) -> Result<Self, TrainError> {
        let Some(first) = cameras.first() else {
            return Err(TrainError::config("camera path", "no cameras to fit"));
        };
        let mut up = cameras.iter().map(camera_up).sum::<Vec3>();
        if up.length() < 1e-3 * cameras.len() as f32 {
            up = camera_up(first);
        }
        let up = up.normalize();
        let centres: Vec<DVec3> = cameras.iter().map(|c| c.center().as_dvec3()).collect();
        let dirs: Vec<DVec3> = cameras
            .iter()
            .map(|c| camera_forward(c).as_dvec3().normalize())
            .collect();
        let mut a = DMat3::ZERO;
        let mut b = DVec3::ZERO;
        for (c, d) in centres.iter().zip(&dirs) {
            let m = DMat3::IDENTITY - DMat3::from_cols(*d * d.x, *d * d.y, *d * d.z);
            a += m;
            b += m * *c;
        }
        let mean_centre = centres.iter().sum::<DVec3>() / centres.len() as f64;
        // Parallel axes make A rank 2: its determinant relative to its scale vanishes.
        let scale = cameras.len() as f64;
        let target = if a.determinant().abs() > 1e-6 * scale.powi(3) {
            (a.inverse() * b).as_vec3()
        } else {
            let spread = centres
                .iter()
                .map(|c| (*c - mean_centre).length())
                .sum::<f64>()
                / scale;
            let dir = dirs.iter().sum::<DVec3>().normalize_or(DVec3::Z);
            (mean_centre + dir * if spread > 0.0 { spread } else { 1.0 }).as_vec3()
        };
        let mut radius = 0.0;
        let (mut h_sum, mut h_min, mut h_max) = (0.0, f32::INFINITY, f32::NEG_INFINITY);
        let mut e1 = Vec3::ZERO;
        for c in cameras {
            let v = c.center() - target;
            let h = v.dot(up);
            let w = v - h * up;
            if e1 == Vec3::ZERO && w.length() > 1e-6 {
                e1 = w.normalize();
            }
            radius += w.length();
            h_sum += h;
            h_min = h_min.min(h);
            h_max = h_max.max(h);
        }
        if e1 == Vec3::ZERO {
            e1 = up.any_orthonormal_vector();
        }
        let n = cameras.len() as f32;
        Ok(Self {
            up,
            target,
            e1,
            e2: up.cross(e1),
            radius: radius / n,
            height_mean: h_sum / n,
            height_min: h_min,
            height_max: h_max,
        })
    }

    /// The point at `angle` (radians from `e1`, counter-clockwise about up), `radius` from the
    /// axis and `height` above the look-at point.
    pub fn point(&self, angle: f32, radius: f32, height: f32) -> Vec3 {
        self.target + radius * (angle.cos() * self.e1 + angle.sin() * self.e2) + height * self.up
    }
}

/// `n` cameras on a circle about the fitted axis (see the module docs), with `template`'s size and
/// intrinsics.
pub fn orbit(fit: &SceneFit, template: &Camera, n: usize) -> Vec<Camera> {
    (0..n)
        .map(|k| {
            let angle = std::f32::consts::TAU * k as f32 / n as f32;
            let eye = fit.point(angle, fit.radius, fit.height_mean);
            looking_at(template, eye, fit.target, fit.up)
        })
        .collect()
}

/// `n` cameras on a helix about the fitted axis (see the module docs), with `template`'s size and
/// intrinsics.
pub fn spiral(fit: &SceneFit, template: &Camera, n: usize) -> Vec<Camera> {
    (0..n)
        .map(|k| {
            let s = if n > 1 {
                k as f32 / (n - 1) as f32
            } else {
                0.0
            };
            let angle = std::f32::consts::TAU * SPIRAL_TURNS * s;
            let height = fit.height_min + (fit.height_max - fit.height_min) * s;
            let eye = fit.point(angle, fit.radius, height);
            looking_at(template, eye, fit.target, fit.up)
        })
        .collect()
}

/// Cameras with times in time order (ties keep their given order), and the interpolated path
/// through them (see the module docs).
#[derive(Clone, Debug, PartialEq)]
pub struct Keyframes {
    cameras: Vec<Camera>,
    times: Vec<f32>,
}

impl Keyframes {
    /// Sorts `cameras` (each with its time) by time. Needs at least one camera, finite times, and
    /// one image size for all.
    pub fn new(mut cameras: Vec<(Camera, f32)>) -> Result<Self, TrainError> {
        let Some(&(first, _)) = cameras.first() else {
            return Err(TrainError::config("camera path", "no cameras"));
        };
        if let Some((k, (_, t))) = cameras.iter().enumerate().find(|(_, c)| !c.1.is_finite()) {
            return Err(TrainError::config(
                "camera path",
                format!("camera {k} has time {t}, not a finite number"),
            ));
        }
        if let Some((k, (c, _))) = cameras
            .iter()
            .enumerate()
            .find(|(_, (c, _))| (c.width, c.height) != (first.width, first.height))
        {
            return Err(TrainError::config(
                "camera path",
                format!(
                    "camera {k} is {}x{}, but camera 0 is {}x{}",
                    c.width, c.height, first.width, first.height
                ),
            ));
        }
        cameras.sort_by(|a, b| a.1.total_cmp(&b.1));
        let (cameras, times) = cameras.into_iter().unzip();
        Ok(Self { cameras, times })
    }

    /// The keyframe cameras, in time order.
    pub fn cameras(&self) -> &[Camera] {
        &self.cameras
    }

    /// The keyframe times, ascending.
    pub fn times(&self) -> &[f32] {
        &self.times
    }

    /// The camera and time at `u ∈ [0, m − 1]` (clamped): keyframe `u` exactly at a whole `u`,
    /// interpolated between keyframes `⌊u⌋` and `⌊u⌋ + 1` otherwise.
    pub fn at(&self, u: f32) -> (Camera, f32) {
        let last = self.cameras.len() - 1;
        let u = u.clamp(0.0, last as f32);
        let k = (u.floor() as usize).min(last);
        let f = u - k as f32;
        if f == 0.0 || k == last {
            return (self.cameras[k], self.times[k]);
        }
        let (a, b) = (&self.cameras[k], &self.cameras[k + 1]);
        let lerp = |x: f32, y: f32| x + (y - x) * f;
        let qa = Quat::from_mat3(&a.rotation).normalize();
        let qb = Quat::from_mat3(&b.rotation).normalize();
        let rotation = Mat3::from_quat(qa.slerp(qb, f));
        let centre = a.center().lerp(b.center(), f);
        let camera = Camera::from_center(
            a.width,
            a.height,
            lerp(a.fx, b.fx),
            lerp(a.fy, b.fy),
            lerp(a.cx, b.cx),
            lerp(a.cy, b.cy),
            rotation,
            centre,
        );
        (camera, lerp(self.times[k], self.times[k + 1]))
    }

    /// `n` cameras evenly spaced in `u` from the first keyframe to the last (`n = m` gives every
    /// keyframe exactly; `n = 1` the first).
    pub fn sample(&self, n: usize) -> Vec<(Camera, f32)> {
        let last = (self.cameras.len() - 1) as f32;
        (0..n)
            .map(|k| {
                let u = if n > 1 {
                    last * k as f32 / (n - 1) as f32
                } else {
                    0.0
                };
                self.at(u)
            })
            .collect()
    }
}

/// Where a camera comes from: a nerfies camera JSON file, or `dataset:SPLIT:INDEX`, the
/// INDEX-th camera (file order, from 0) of the run's dataset split.
#[derive(Clone, Debug, PartialEq)]
pub enum CameraSpec {
    /// A nerfies camera JSON file.
    File(PathBuf),
    /// A camera of the run's dataset.
    Dataset {
        /// The split.
        split: Split,
        /// Its index in file order.
        index: usize,
    },
}

impl FromStr for CameraSpec {
    type Err = String;

    fn from_str(text: &str) -> Result<Self, Self::Err> {
        let Some(rest) = text.strip_prefix("dataset:") else {
            return Ok(Self::File(PathBuf::from(text)));
        };
        let (split, index) = rest
            .split_once(':')
            .ok_or_else(|| format!("`{text}`: expected dataset:SPLIT:INDEX"))?;
        let split: Split = split.parse().map_err(|e| format!("`{text}`: {e}"))?;
        let index = index
            .parse()
            .map_err(|_| format!("`{text}`: index `{index}` is not a whole number"))?;
        Ok(Self::Dataset { split, index })
    }
}

impl fmt::Display for CameraSpec {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::File(path) => write!(f, "{}", path.display()),
            Self::Dataset { split, index } => write!(f, "dataset:{split}:{index}"),
        }
    }
}

/// Resizes a camera to `width × height` (either may be absent), scaling fx, cx by the width
/// ratio and fy, cy by the height ratio.
pub fn resize_camera(camera: Camera, width: Option<u32>, height: Option<u32>) -> Camera {
    let w = width.unwrap_or(camera.width);
    let h = height.unwrap_or(camera.height);
    let sx = w as f32 / camera.width as f32;
    let sy = h as f32 / camera.height as f32;
    Camera {
        width: w,
        height: h,
        fx: camera.fx * sx,
        cx: camera.cx * sx,
        fy: camera.fy * sy,
        cy: camera.cy * sy,
        ..camera
    }
}

/// The cameras and times of a split of `run`'s dataset, in file order, at the run's resolution
/// (the dataset's cameras scaled by its downscale factor, as training and evaluation load them).
/// Errors name the dataset file when the split is empty.
pub fn split_cameras(run: &LoadedRun, split: Split) -> Result<Vec<(Camera, f32)>, TrainError> {
    let root = run.data()?;
    let dataset = open_dataset(root, run.run.train.time_from)?;
    let frames = dataset.split(split);
    if frames.is_empty() {
        return Err(split_error(
            root,
            dataset.format,
            split,
            "the split is empty",
        ));
    }
    let factor = run.run.train.downscale;
    Ok(frames
        .iter()
        .map(|f| (f.camera.camera.scaled(factor), f.time))
        .collect())
}

/// Camera `index` of `split` of `run`'s dataset with its time (see [`split_cameras`]); an index out
/// of range names the file and the split's size.
pub fn dataset_camera(
    run: &LoadedRun,
    split: Split,
    index: usize,
) -> Result<(Camera, f32), TrainError> {
    let cameras = split_cameras(run, split)?;
    cameras.get(index).copied().ok_or_else(|| {
        let format = evogs_io::detect_format(&run.run.data).unwrap_or(Format::Dnerf);
        split_error(
            &run.run.data,
            format,
            split,
            format!(
                "camera index {index} is out of range: the split has {} cameras (0..={})",
                cameras.len(),
                cameras.len() - 1
            ),
        )
    })
}

fn split_error(
    root: &Path,
    format: Format,
    split: Split,
    problem: impl Into<String>,
) -> TrainError {
    match format {
        Format::Dnerf => TrainError::field(split.transforms_path(root), "frames", problem),
        _ => TrainError::field(root, split.name(), problem),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const EPS: f32 = 1e-4;

    fn template() -> Camera {
        Camera {
            width: 40,
            height: 30,
            fx: 50.0,
            fy: 52.0,
            cx: 19.0,
            cy: 16.0,
            rotation: Mat3::IDENTITY,
            translation: Vec3::ZERO,
        }
    }

    /// Twelve cameras evenly around a tilted ring about `target` at radius 3, heights 0.5, 1, 1.5
    /// in turn (so their up vectors' tilts cancel), each looking at `target` with no roll.
    fn ring(up: Vec3, target: Vec3) -> Vec<Camera> {
        let e1 = up.any_orthonormal_vector();
        let e2 = up.cross(e1);
        (0..12)
            .map(|k| {
                let a = 0.4 + k as f32 * std::f32::consts::TAU / 12.0;
                let h = 0.5 + (k % 3) as f32 * 0.5;
                let eye = target + 3.0 * (a.cos() * e1 + a.sin() * e2) + h * up;
                looking_at(&template(), eye, target, up)
            })
            .collect()
    }

    fn up_and_target() -> (Vec3, Vec3) {
        (
            Vec3::new(0.2, -0.1, 1.0).normalize(),
            Vec3::new(1.0, 2.0, 0.5),
        )
    }

    #[test]
    fn fit_recovers_up_target_radius_and_heights() {
        let (up, target) = up_and_target();
        let cams = ring(up, target);
        let fit = SceneFit::fit(&cams).unwrap();
        let mean_up = cams.iter().map(camera_up).sum::<Vec3>().normalize();
        assert!((fit.up - mean_up).length() < 1e-6, "{:?}", fit.up);
        assert!((fit.up - up).length() < EPS, "{:?}", fit.up);
        assert!((fit.target - target).length() < 1e-3, "{:?}", fit.target);
        assert!((fit.radius - 3.0).abs() < 1e-3, "{}", fit.radius);
        assert!((fit.height_min - 0.5).abs() < 1e-3);
        assert!((fit.height_max - 1.5).abs() < 1e-3);
        assert!((fit.height_mean - 1.0).abs() < 1e-3);
        assert!(fit.e1.dot(fit.up).abs() < EPS && (fit.e1.length() - 1.0).abs() < EPS);
    }

    fn angle_of(fit: &SceneFit, eye: Vec3) -> f32 {
        let v = eye - fit.target;
        v.dot(fit.e2).atan2(v.dot(fit.e1))
    }

    fn wrap(a: f32) -> f32 {
        let tau = std::f32::consts::TAU;
        (a + 0.5 * tau).rem_euclid(tau) - 0.5 * tau
    }

    /// Looks at the target, no roll, image up towards up, template intrinsics.
    fn check_pose(fit: &SceneFit, cam: &Camera) {
        let forward = (fit.target - cam.center()).normalize();
        assert!((camera_forward(cam) - forward).length() < EPS);
        assert!(cam.rotation.row(0).dot(fit.up).abs() < EPS, "roll");
        assert!(camera_up(cam).dot(fit.up) > 0.0);
        let t = template();
        assert_eq!(
            (cam.width, cam.height, cam.fx, cam.fy, cam.cx, cam.cy),
            (t.width, t.height, t.fx, t.fy, t.cx, t.cy)
        );
    }

    #[test]
    fn orbit_cameras_follow_the_definition() {
        let (up, target) = up_and_target();
        let fit = SceneFit::fit(&ring(up, target)).unwrap();
        let n = 8;
        let cams = orbit(&fit, &template(), n);
        assert_eq!(cams.len(), n);
        for (k, cam) in cams.iter().enumerate() {
            let v = cam.center() - fit.target;
            let h = v.dot(fit.up);
            assert!((h - fit.height_mean).abs() < EPS, "height {h}");
            assert!(((v - h * fit.up).length() - fit.radius).abs() < 1e-3);
            let expected = std::f32::consts::TAU * k as f32 / n as f32;
            assert!(wrap(angle_of(&fit, cam.center()) - expected).abs() < 1e-3);
            check_pose(&fit, cam);
        }
        // Starts at the first dataset camera's angle.
        let first = ring(up, target)[0].center();
        assert!(angle_of(&fit, first).abs() < 1e-3);
    }

    #[test]
    fn spiral_cameras_follow_the_definition() {
        let (up, target) = up_and_target();
        let fit = SceneFit::fit(&ring(up, target)).unwrap();
        let n = 9;
        let cams = spiral(&fit, &template(), n);
        for (k, cam) in cams.iter().enumerate() {
            let s = k as f32 / (n - 1) as f32;
            let v = cam.center() - fit.target;
            let h = v.dot(fit.up);
            let expected_h = fit.height_min + (fit.height_max - fit.height_min) * s;
            assert!((h - expected_h).abs() < EPS, "height {h} vs {expected_h}");
            assert!(((v - h * fit.up).length() - fit.radius).abs() < 1e-3);
            let expected = std::f32::consts::TAU * SPIRAL_TURNS * s;
            assert!(wrap(angle_of(&fit, cam.center()) - expected).abs() < 1e-3);
            check_pose(&fit, cam);
        }
    }

    #[test]
    fn parallel_cameras_fall_back_to_a_point_ahead() {
        let c = looking_at(&template(), Vec3::ZERO, Vec3::X, Vec3::Z);
        let fit = SceneFit::fit(&[c]).unwrap();
        assert!((fit.target - Vec3::X).length() < EPS, "{:?}", fit.target);
        assert!(SceneFit::fit(&[]).is_err());
    }

    #[test]
    fn keyframes_hit_each_camera_at_its_time_and_slerp_between() {
        let (up, target) = up_and_target();
        let ring = ring(up, target);
        // Given out of time order: the path sorts them.
        let times = [0.5, 0.0, 1.0];
        let keys = Keyframes::new(ring[..3].iter().copied().zip(times).collect()).unwrap();
        assert_eq!(keys.times(), &[0.0, 0.5, 1.0]);
        let samples = keys.sample(3);
        assert_eq!(samples[0], (ring[1], 0.0));
        assert_eq!(samples[1], (ring[0], 0.5));
        assert_eq!(samples[2], (ring[2], 1.0));
        // Half way between keyframes 0 and 1: centre midpoint, rotation half way, time midpoint.
        let (mid, t) = keys.at(0.5);
        assert!((t - 0.25).abs() < 1e-6);
        assert!((mid.center() - 0.5 * (ring[1].center() + ring[0].center())).length() < EPS);
        let q = Quat::from_mat3(&mid.rotation);
        let (qa, qb) = (
            Quat::from_mat3(&ring[1].rotation),
            Quat::from_mat3(&ring[0].rotation),
        );
        assert!((q.angle_between(qa) - q.angle_between(qb)).abs() < 1e-3);
        assert!((q.angle_between(qa) - 0.5 * qa.angle_between(qb)).abs() < 1e-3);
        // Five samples over three keyframes hit them at 0, 2 and 4.
        let five = keys.sample(5);
        assert_eq!(five[2], (ring[0], 0.5));
        assert_eq!(five[4], (ring[2], 1.0));
    }

    #[test]
    fn keyframes_refuse_bad_input() {
        let c = template();
        assert!(Keyframes::new(vec![]).is_err());
        let e = Keyframes::new(vec![(c, f32::NAN)]).unwrap_err().to_string();
        assert!(e.contains("not a finite"), "{e}");
        let small = Camera { width: 10, ..c };
        let e = Keyframes::new(vec![(c, 0.0), (small, 1.0)])
            .unwrap_err()
            .to_string();
        assert!(e.contains("camera 1 is 10x30"), "{e}");
    }

    #[test]
    fn camera_spec_parses_files_and_dataset_cameras() {
        assert_eq!(
            "cam.json".parse::<CameraSpec>().unwrap(),
            CameraSpec::File("cam.json".into())
        );
        assert_eq!(
            "dataset:test:3".parse::<CameraSpec>().unwrap(),
            CameraSpec::Dataset {
                split: Split::Test,
                index: 3
            }
        );
        let e = "dataset:dev:1".parse::<CameraSpec>().unwrap_err();
        assert!(e.contains("unknown split `dev`"), "{e}");
        let e = "dataset:test".parse::<CameraSpec>().unwrap_err();
        assert!(e.contains("dataset:SPLIT:INDEX"), "{e}");
        let e = "dataset:test:-1".parse::<CameraSpec>().unwrap_err();
        assert!(e.contains("not a whole number"), "{e}");
    }
}
