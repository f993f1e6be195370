//! The original 3DGS vertex layout (DESIGN §2) and how its properties map to [`Gaussians`] fields.
//!
//! [`Gaussians`]: splat_core::Gaussians

use splat_core::sh_coeff_count;

/// Number of `f_rest_*` properties at an SH degree: `3 · ((deg + 1)² − 1)`.
pub(crate) fn rest_count(degree: u32) -> usize {
    3 * (sh_coeff_count(degree) - 1)
}

/// The SH degree whose `f_rest_*` count is `count`, if any.
pub(crate) fn degree_from_rest_count(count: usize) -> Option<u32> {
    (0..=3).find(|&d| rest_count(d) == count)
}

/// The vertex property names in the order 3DGS writes them, for an SH degree:
/// `x y z nx ny nz f_dc_0..2 f_rest_* opacity scale_0..2 rot_0..3`.
pub fn property_names(degree: u32) -> Vec<String> {
    let mut names: Vec<String> = ["x", "y", "z", "nx", "ny", "nz"]
        .iter()
        .map(|s| s.to_string())
        .collect();
    names.extend((0..3).map(|i| format!("f_dc_{i}")));
    names.extend((0..rest_count(degree)).map(|i| format!("f_rest_{i}")));
    names.push("opacity".into());
    names.extend((0..3).map(|i| format!("scale_{i}")));
    names.extend((0..4).map(|i| format!("rot_{i}")));
    names
}

/// Where a decoded vertex value goes, as an index into a per-row record laid out as
/// `[x y z | opacity | scale_0..2 | rot_0..3 | sh coefficient-major ...]`.
pub(crate) struct RecordLayout {
    pub degree: u32,
}

impl RecordLayout {
    pub const MEAN: usize = 0;
    pub const OPACITY: usize = 3;
    pub const SCALE: usize = 4;
    pub const ROT: usize = 7;
    pub const SH: usize = 11;

    /// Values per record.
    pub fn len(&self) -> usize {
        Self::SH + 3 * sh_coeff_count(self.degree)
    }

    /// Record slot of a required property name, `None` for names the reader ignores.
    pub fn slot_of(&self, name: &str) -> Option<usize> {
        let coeffs = sh_coeff_count(self.degree);
        let indexed = |prefix: &str| -> Option<usize> {
            let digits = name.strip_prefix(prefix)?;
            if digits.is_empty() || (digits.len() > 1 && digits.starts_with('0')) {
                return None;
            }
            digits.parse().ok()
        };
        match name {
            "x" => return Some(Self::MEAN),
            "y" => return Some(Self::MEAN + 1),
            "z" => return Some(Self::MEAN + 2),
            "opacity" => return Some(Self::OPACITY),
            _ => {}
        }
        if let Some(i) = indexed("scale_").filter(|&i| i < 3) {
            return Some(Self::SCALE + i);
        }
        if let Some(i) = indexed("rot_").filter(|&i| i < 4) {
            return Some(Self::ROT + i);
        }
        if let Some(c) = indexed("f_dc_").filter(|&i| i < 3) {
            return Some(Self::SH + c);
        }
        if let Some(i) = indexed("f_rest_").filter(|&i| i < rest_count(self.degree)) {
            // Channel-major in the file: all R coefficients 1.., then G, then B.
            let per_channel = coeffs - 1;
            let (channel, coeff) = (i / per_channel, 1 + i % per_channel);
            return Some(Self::SH + coeff * 3 + channel);
        }
        None
    }

    /// Names of every required property, for reporting the first missing one.
    pub fn required_names(&self) -> Vec<String> {
        property_names(self.degree)
            .into_iter()
            .filter(|n| !matches!(n.as_str(), "nx" | "ny" | "nz"))
            .collect()
    }
}

/// True for names of the form `f_rest_<k>`.
pub(crate) fn is_rest_name(name: &str) -> bool {
    name.strip_prefix("f_rest_")
        .is_some_and(|d| !d.is_empty() && d.bytes().all(|b| b.is_ascii_digit()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn slots_cover_record_exactly_once_per_degree() {
        for degree in 0..=3 {
            let layout = RecordLayout { degree };
            let mut seen = vec![0; layout.len()];
            for name in layout.required_names() {
                let slot = layout.slot_of(&name).expect(&name);
                seen[slot] += 1;
            }
            assert!(seen.iter().all(|&n| n == 1), "degree {degree}: {seen:?}");
            assert_eq!(property_names(degree).len(), 17 + rest_count(degree));
        }
    }

    #[test]
    fn rest_is_channel_major() {
        let layout = RecordLayout { degree: 1 };
        // degree 1: 3 rest coefficients per channel; f_rest_3 is G of coefficient 1.
        assert_eq!(layout.slot_of("f_rest_3"), Some(RecordLayout::SH + 3 + 1));
        assert_eq!(layout.slot_of("f_rest_8"), Some(RecordLayout::SH + 9 + 2));
        assert_eq!(layout.slot_of("f_rest_9"), None);
        assert_eq!(layout.slot_of("scale_3"), None);
        assert_eq!(layout.slot_of("rot_01"), None);
    }
}
