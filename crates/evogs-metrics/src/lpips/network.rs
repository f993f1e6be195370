//! The two LPIPS backbones as torchvision defines their `features` (AlexNet: conv1..conv5 with
//! max pools 3/2 after conv1 and conv2; VGG16: thirteen 3×3 convolutions in five blocks with
//! max pools 2/2 between them), ReLU fused into each convolution, cut after the fifth feature
//! layer (AlexNet's `relu1`..`relu5`, VGG16's `relu1_2`, `relu2_2`, `relu3_3`, `relu4_3`,
//! `relu5_3`).
//!
//! Not here: loading the weights ([`super::weights`]) and the distance ([`super::Lpips`]).

use super::Backbone;
use super::layers::{Conv, Maps, MaxPool};

/// Geometry of one convolution: kernel side, output channels, stride, padding.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct ConvShape {
    /// Kernel side.
    pub kernel_side: usize,
    /// Output channels.
    pub channels_out: usize,
    /// Stride.
    pub stride: usize,
    /// Zero padding.
    pub pad: usize,
}

/// One step of a backbone's `features`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Step {
    /// The next convolution (+ ReLU) of the weights file, in order.
    Conv(ConvShape),
    /// Max pooling.
    Pool(MaxPool),
    /// The current maps are an LPIPS feature layer.
    Tap,
}

const fn conv(kernel_side: usize, channels_out: usize, stride: usize, pad: usize) -> Step {
    Step::Conv(ConvShape {
        kernel_side,
        channels_out,
        stride,
        pad,
    })
}

const fn pool(window: usize, stride: usize) -> Step {
    Step::Pool(MaxPool { window, stride })
}

const ALEX: &[Step] = &[
    conv(11, 64, 4, 2),
    Step::Tap,
    pool(3, 2),
    conv(5, 192, 1, 2),
    Step::Tap,
    pool(3, 2),
    conv(3, 384, 1, 1),
    Step::Tap,
    conv(3, 256, 1, 1),
    Step::Tap,
    conv(3, 256, 1, 1),
    Step::Tap,
];

const VGG16: &[Step] = &[
    conv(3, 64, 1, 1),
    conv(3, 64, 1, 1),
    Step::Tap,
    pool(2, 2),
    conv(3, 128, 1, 1),
    conv(3, 128, 1, 1),
    Step::Tap,
    pool(2, 2),
    conv(3, 256, 1, 1),
    conv(3, 256, 1, 1),
    conv(3, 256, 1, 1),
    Step::Tap,
    pool(2, 2),
    conv(3, 512, 1, 1),
    conv(3, 512, 1, 1),
    conv(3, 512, 1, 1),
    Step::Tap,
    pool(2, 2),
    conv(3, 512, 1, 1),
    conv(3, 512, 1, 1),
    conv(3, 512, 1, 1),
    Step::Tap,
];

/// The steps of `backbone`'s features, in order.
pub(crate) fn steps(backbone: Backbone) -> &'static [Step] {
    match backbone {
        Backbone::Alex => ALEX,
        Backbone::Vgg => VGG16,
    }
}

/// The convolutions of `backbone` in order, with their input channel counts.
pub(crate) fn convs(backbone: Backbone) -> Vec<(usize, ConvShape)> {
    let mut channels = 3;
    let mut out = Vec::new();
    for step in steps(backbone) {
        if let Step::Conv(shape) = step {
            out.push((channels, *shape));
            channels = shape.channels_out;
        }
    }
    out
}

/// Channel counts of the five feature layers.
pub(crate) fn tap_channels(backbone: Backbone) -> Vec<usize> {
    let mut channels = 3;
    let mut out = Vec::new();
    for step in steps(backbone) {
        match step {
            Step::Conv(shape) => channels = shape.channels_out,
            Step::Tap => out.push(channels),
            Step::Pool(_) => {}
        }
    }
    out
}

/// Whether an image of `side` pixels (either direction) goes through every step.
pub(crate) fn fits(backbone: Backbone, side: usize) -> bool {
    let mut s = side;
    for step in steps(backbone) {
        let next = match step {
            Step::Conv(c) => super::layers::out_side(s, c.kernel_side, c.stride, c.pad),
            Step::Pool(p) => super::layers::out_side(s, p.window, p.stride, 0),
            Step::Tap => Some(s),
        };
        match next {
            Some(n) if n > 0 => s = n,
            _ => return false,
        }
    }
    true
}

/// Smallest image side `backbone` takes (31 for AlexNet, 16 for VGG16).
pub(crate) fn min_side(backbone: Backbone) -> usize {
    (1..).find(|&s| fits(backbone, s)).expect("some side fits")
}

/// Runs `backbone`'s steps with `convs` (the loaded convolutions, in order) on `x`, handing each
/// of the five feature layers to `tap` (with its index) as soon as it is computed.
pub(crate) fn features(
    backbone: Backbone,
    convs: &[Conv],
    x: Maps,
    tap: &mut dyn FnMut(usize, &Maps),
) {
    let mut next_conv = convs.iter();
    let mut taps = 0;
    let mut current = x;
    for step in steps(backbone) {
        match step {
            Step::Conv(_) => {
                let conv = next_conv.next().expect("one conv a step");
                current = conv.forward_relu(&current);
            }
            Step::Pool(p) => current = p.forward(&current),
            Step::Tap => {
                tap(taps, &current);
                taps += 1;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn geometry_is_torchvision_features() {
        assert_eq!(tap_channels(Backbone::Alex), [64, 192, 384, 256, 256]);
        assert_eq!(tap_channels(Backbone::Vgg), [64, 128, 256, 512, 512]);
        assert_eq!(convs(Backbone::Alex).len(), 5);
        assert_eq!(convs(Backbone::Vgg).len(), 13);
        assert_eq!(convs(Backbone::Vgg)[10].0, 512);
        // AlexNet: conv1 (pad 2, stride 4) must leave 7 px for two 3/2 pools; VGG: four 2/2 pools.
        assert_eq!(min_side(Backbone::Alex), 31);
        assert_eq!(min_side(Backbone::Vgg), 16);
        assert!(fits(Backbone::Alex, 32) && !fits(Backbone::Alex, 30));
    }
}
