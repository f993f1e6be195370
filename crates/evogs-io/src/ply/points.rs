//! Point clouds in PLY files (`x y z` and optional `red green blue`), as nerfstudio's
//! `sparse_pc.ply` and other SfM tools write them; the initial points of a dataset.

use std::fs::File;
use std::io::BufReader;
use std::path::Path;

use glam::Vec3;

use super::header::ScalarType;
use super::read::{Prelude, Rows, plan_columns};
use crate::IoError;
use crate::dataset_types::PointCloud;

/// Record slots: position, then colour.
const NAMES: [&str; 6] = ["x", "y", "z", "red", "green", "blue"];

struct Points {
    cloud: PointCloud,
    /// Divides a stored colour value into [0, 1]: 255 for `uchar`, 65535 for `ushort`, 1 for
    /// floating point.
    colour_scale: f32,
    has_colour: bool,
}

impl Rows for Points {
    fn reserve(&mut self, count: usize) {
        self.cloud.positions.reserve_exact(count);
        self.cloud.colours.reserve_exact(count);
    }

    fn push(&mut self, record: &[f32]) {
        self.cloud
            .positions
            .push(Vec3::new(record[0], record[1], record[2]));
        let colour = if self.has_colour {
            Vec3::new(record[3], record[4], record[5]) / self.colour_scale
        } else {
            Vec3::splat(0.5)
        };
        self.cloud.colours.push(colour);
    }
}

/// Reads a PLY point cloud: the `vertex` element's `x y z` (required) and `red green blue`
/// (optional, all three or none; integers are divided by their type's maximum, floats kept;
/// grey 0.5 when absent). Other properties are ignored. ASCII or binary of either endianness.
pub fn read_point_cloud(path: &Path) -> Result<PointCloud, IoError> {
    let file = File::open(path).map_err(|e| IoError::io(path, e))?;
    let len = file.metadata().map_err(|e| IoError::io(path, e))?.len();
    let mut reader = BufReader::with_capacity(1 << 20, file);
    let prelude = Prelude::read(&mut reader, len).map_err(|f| f.at(path))?;
    let slot_of = |name: &str| NAMES.iter().position(|&n| n == name);
    let present = |name: &str| prelude.vertex().properties.iter().any(|p| p.name == name);
    let colours = NAMES[3..].iter().filter(|n| present(n)).count();
    let required: Vec<String> = if colours > 0 {
        // Some colour channels but not all: name the first missing one.
        NAMES.iter().map(|n| n.to_string()).collect()
    } else {
        NAMES[..3].iter().map(|n| n.to_string()).collect()
    };
    let plan = plan_columns(
        prelude.vertex(),
        prelude.encoding(),
        NAMES.len(),
        slot_of,
        |_| false,
        &required,
    )
    .map_err(|problem| IoError::Ply {
        path: path.to_path_buf(),
        problem,
    })?;
    let colour_scale = match plan.type_of_slot(3) {
        Some(ScalarType::U8) => 255.0,
        Some(ScalarType::U16) => 65535.0,
        _ => 1.0,
    };
    let mut points = Points {
        cloud: PointCloud::default(),
        colour_scale,
        has_colour: colours > 0,
    };
    prelude
        .read_rows(&mut reader, &plan, &mut points)
        .map_err(|f| f.at(path))?;
    Ok(points.cloud)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn read_text(text: &str) -> Result<PointCloud, IoError> {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("points.ply");
        std::fs::write(&path, text).unwrap();
        read_point_cloud(&path)
    }

    #[test]
    fn ascii_and_binary_with_and_without_colour() {
        let cloud = read_text(
            "ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\n\
             property float z\nproperty uchar red\nproperty uchar green\nproperty uchar blue\n\
             end_header\n1 2 3 255 0 51\n-1 0.5 0 0 255 0\n",
        )
        .unwrap();
        assert_eq!(
            cloud.positions,
            vec![Vec3::new(1.0, 2.0, 3.0), Vec3::new(-1.0, 0.5, 0.0)]
        );
        assert_eq!(cloud.colours[0], Vec3::new(1.0, 0.0, 0.2));
        let cloud = read_text(
            "ply\nformat ascii 1.0\nelement vertex 1\nproperty double x\nproperty double y\n\
             property double z\nproperty float nx\nend_header\n1 2 3 0\n",
        )
        .unwrap();
        assert_eq!(cloud.colours, vec![Vec3::splat(0.5)]);
        // Binary little endian, float colours kept as they are.
        let mut bytes = b"ply\nformat binary_little_endian 1.0\nelement vertex 1\n\
            property float x\nproperty float y\nproperty float z\nproperty float red\n\
            property float green\nproperty float blue\nend_header\n"
            .to_vec();
        for v in [0.5f32, 1.5, 2.5, 0.25, 0.5, 0.75] {
            bytes.extend(v.to_le_bytes());
        }
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("b.ply");
        std::fs::write(&path, bytes).unwrap();
        let cloud = read_point_cloud(&path).unwrap();
        assert_eq!(cloud.positions, vec![Vec3::new(0.5, 1.5, 2.5)]);
        assert_eq!(cloud.colours, vec![Vec3::new(0.25, 0.5, 0.75)]);
    }

    #[test]
    fn missing_coordinates_or_channels_are_named() {
        let m = read_text(
            "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\n\
             end_header\n1 2\n",
        )
        .unwrap_err()
        .to_string();
        assert!(
            m.contains("points.ply") && m.contains("`z` is missing"),
            "{m}"
        );
        let m = read_text(
            "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\n\
             property float z\nproperty uchar red\nend_header\n1 2 3 4\n",
        )
        .unwrap_err()
        .to_string();
        assert!(m.contains("`green` is missing"), "{m}");
        let m = read_text("ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nend_header\n1 2 3\n")
            .unwrap_err()
            .to_string();
        assert!(m.contains("points.ply"), "{m}");
    }
}
