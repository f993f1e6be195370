//! The deformation row: which per-Gaussian components a deformation vector holds (position,
//! rotation, scale, opacity, colour) and where each sits in it ([`Layout`]). The one definition
//! of the row's columns: the backbones write rows in their own layout, the evolution state keeps
//! them, densification reads them, and [`crate::deformed`] adds them to the Gaussians and turns
//! the rasterizer's gradients back into rows, all through a [`Layout`].
//!
//! It is not a deformation model: nothing here computes a deformation.

use std::fmt;
use std::str::FromStr;

/// One deformation component. In the deformation vector the enabled components appear in this
/// order: position, rotation, scale, opacity, colour.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Component {
    /// Offset of the mean (3), in scene units.
    Position,
    /// Offset added to the raw quaternion w, x, y, z (4).
    Rotation,
    /// Offset added to the log-scale (3).
    Scale,
    /// Offset added to the opacity logit (1).
    Opacity,
    /// Offset added to the SH DC colour coefficients (3).
    Colour,
}

impl Component {
    /// Number of values of the component.
    pub const fn width(self) -> usize {
        match self {
            Component::Position | Component::Scale | Component::Colour => 3,
            Component::Rotation => 4,
            Component::Opacity => 1,
        }
    }

    /// Every component, in the order of the deformation vector.
    pub const ALL: [Component; 5] = [
        Component::Position,
        Component::Rotation,
        Component::Scale,
        Component::Opacity,
        Component::Colour,
    ];
}

/// Which components the deformation vector holds. Disabled components cost nothing.
///
/// Its command-line spelling ([`FromStr`], [`fmt::Display`]) is a comma-separated list of
/// `pos`/`position`, `rot`/`rotation`, `scale`, `opacity`, `colour`/`color`; with the `serde`
/// feature it is recorded as an object of five booleans named as its fields.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct Layout {
    /// [`Component::Position`] is held.
    pub position: bool,
    /// [`Component::Rotation`] is held.
    pub rotation: bool,
    /// [`Component::Scale`] is held.
    pub scale: bool,
    /// [`Component::Opacity`] is held.
    pub opacity: bool,
    /// [`Component::Colour`] is held.
    pub colour: bool,
}

impl Default for Layout {
    /// [`Layout::GEOMETRY`]: position, rotation and scale (D = 10), as D-3DGS deforms.
    fn default() -> Self {
        Self::GEOMETRY
    }
}

impl Layout {
    /// Position, rotation and scale (D = 10): the geometry every backbone deforms, and what
    /// D-3DGS's, 4DGaussians' and Grid4D's heads give; [`Layout::default`].
    pub const GEOMETRY: Self = Self {
        position: true,
        rotation: true,
        scale: true,
        opacity: false,
        colour: false,
    };

    /// Every component (D = [`Layout::MAX_DIM`]).
    pub const ALL: Self = Self {
        position: true,
        rotation: true,
        scale: true,
        opacity: true,
        colour: true,
    };

    /// The widest row: every component (position 3, rotation 4, scale 3, opacity 1, colour 3).
    pub const MAX_DIM: usize = 14;

    /// Whether `component` is enabled.
    pub const fn has(&self, component: Component) -> bool {
        match component {
            Component::Position => self.position,
            Component::Rotation => self.rotation,
            Component::Scale => self.scale,
            Component::Opacity => self.opacity,
            Component::Colour => self.colour,
        }
    }

    /// The enabled components with their ranges in the deformation vector, in order.
    pub fn components(&self) -> Vec<(Component, std::ops::Range<usize>)> {
        let mut start = 0;
        let mut out = Vec::new();
        for c in Component::ALL {
            if self.has(c) {
                out.push((c, start..start + c.width()));
                start += c.width();
            }
        }
        out
    }

    /// D: the sum of the enabled components' widths.
    pub fn dim(&self) -> usize {
        Component::ALL
            .iter()
            .filter(|c| self.has(**c))
            .map(|c| c.width())
            .sum()
    }

    /// First column of `component` in the deformation vector, if enabled (no allocation: the
    /// widths of the enabled components before it).
    pub fn offset(&self, component: Component) -> Option<usize> {
        self.has(component).then(|| {
            Component::ALL
                .iter()
                .take_while(|c| **c != component)
                .filter(|c| self.has(**c))
                .map(|c| c.width())
                .sum()
        })
    }

    /// Range of `component` in the deformation vector, if enabled.
    pub fn range(&self, component: Component) -> Option<std::ops::Range<usize>> {
        self.components()
            .into_iter()
            .find(|(c, _)| *c == component)
            .map(|(_, r)| r)
    }

    /// Compact code (bit per component, in [`Component`] order) used when saving.
    pub fn bits(&self) -> u8 {
        Component::ALL
            .iter()
            .enumerate()
            .filter(|(_, c)| self.has(**c))
            .map(|(i, _)| 1u8 << i)
            .sum()
    }

    /// The layout of a [`Layout::bits`] code; `None` for a code with bits past [`Component`]'s.
    pub fn from_bits(bits: u8) -> Option<Self> {
        if bits >= 1 << 5 {
            return None;
        }
        let on = |i: u8| bits & (1 << i) != 0;
        Some(Self {
            position: on(0),
            rotation: on(1),
            scale: on(2),
            opacity: on(3),
            colour: on(4),
        })
    }
}

/// A [`Layout`] spelling that names an unknown component or one component twice.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum LayoutParseError {
    /// A name that is no component.
    #[error("unknown component `{0}`; expected a list of pos, rot, scale, opacity, colour")]
    Unknown(String),
    /// A component named twice.
    #[error("`{0}` is listed twice")]
    Twice(String),
}

impl FromStr for Layout {
    type Err = LayoutParseError;

    /// A comma-separated list of `pos`/`position`, `rot`/`rotation`, `scale`, `opacity`,
    /// `colour`/`color`, none twice. An empty list is accepted here (it enables nothing;
    /// users of a layout refuse D = 0).
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let mut layout = Self::from_bits(0).expect("0 is a layout code");
        for part in s.split(',').map(str::trim) {
            let slot = match part {
                "pos" | "position" => &mut layout.position,
                "rot" | "rotation" => &mut layout.rotation,
                "scale" => &mut layout.scale,
                "opacity" => &mut layout.opacity,
                "colour" | "color" => &mut layout.colour,
                other => return Err(LayoutParseError::Unknown(other.to_string())),
            };
            if *slot {
                return Err(LayoutParseError::Twice(part.to_string()));
            }
            *slot = true;
        }
        Ok(layout)
    }
}

impl fmt::Display for Layout {
    /// The enabled components' short names, comma-separated (`pos,rot,scale`).
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let names = [
            (self.position, "pos"),
            (self.rotation, "rot"),
            (self.scale, "scale"),
            (self.opacity, "opacity"),
            (self.colour, "colour"),
        ];
        let on: Vec<&str> = names.iter().filter(|(b, _)| *b).map(|(_, n)| *n).collect();
        f.write_str(&on.join(","))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn layout_spellings_parse_and_print() {
        let all: Layout = "pos, rotation,scale,opacity,color".parse().unwrap();
        assert_eq!(all.bits(), 31);
        assert_eq!(all.to_string(), "pos,rot,scale,opacity,colour");
        assert_eq!(
            "pos,rot,scale".parse::<Layout>().unwrap(),
            Layout::default()
        );
        assert_eq!(Layout::default().to_string(), "pos,rot,scale");
        for bits in 1..32u8 {
            let l = Layout::from_bits(bits).unwrap();
            assert_eq!(l.to_string().parse::<Layout>().unwrap(), l);
        }
        assert_eq!(
            "pos,pos".parse::<Layout>().unwrap_err(),
            LayoutParseError::Twice("pos".into())
        );
        let e = "pos,velocity".parse::<Layout>().unwrap_err().to_string();
        assert!(
            e.contains("`velocity`") && e.contains("opacity, colour"),
            "{e}"
        );
        assert!("".parse::<Layout>().is_err());
    }

    #[test]
    fn offsets_and_ranges_agree_for_every_layout() {
        assert_eq!(Layout::ALL.dim(), Layout::MAX_DIM);
        assert_eq!(Layout::GEOMETRY.dim(), 10);
        for bits in 0..32u8 {
            let l = Layout::from_bits(bits).unwrap();
            for c in Component::ALL {
                assert_eq!(l.offset(c), l.range(c).map(|r| r.start), "{l} {c:?}");
            }
            let widths: usize = l.components().iter().map(|(_, r)| r.len()).sum();
            assert_eq!(widths, l.dim());
        }
        let all = Layout::ALL;
        let offsets = Component::ALL.map(|c| all.offset(c).unwrap());
        assert_eq!(offsets, [0, 3, 7, 10, 11]);
    }
}
