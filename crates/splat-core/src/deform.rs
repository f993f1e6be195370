//! The deformation layout: which per-Gaussian components a deformation vector holds (position,
//! rotation, scale, opacity, colour) and where each sits in it. Shared by the evolution state,
//! densification and the trainer, so that every one reads a deformation row the same way.
//!
//! It is not a deformation model: nothing here computes a deformation.

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

    const ALL: [Component; 5] = [
        Component::Position,
        Component::Rotation,
        Component::Scale,
        Component::Opacity,
        Component::Colour,
    ];
}

/// Which components the deformation vector holds. Disabled components cost nothing.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
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
    /// Position, rotation and scale (D = 10), as D-3DGS deforms.
    fn default() -> Self {
        Self {
            position: true,
            rotation: true,
            scale: true,
            opacity: false,
            colour: false,
        }
    }
}

impl Layout {
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
