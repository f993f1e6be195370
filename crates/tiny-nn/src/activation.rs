//! Element-wise activations, applied in place on f32 rows, with derivatives taken from outputs.

/// An element-wise activation function.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Activation {
    /// `y = x`.
    Identity,
    /// `y = max(x, 0)`; derivative 1 where y > 0, else 0 (0 at the kink).
    Relu,
    /// `y = 1 / (1 + exp(-x))`.
    Sigmoid,
}

impl Activation {
    /// Applies the activation in place.
    pub fn apply(self, xs: &mut [f32]) {
        match self {
            Activation::Identity => {}
            Activation::Relu => xs.iter_mut().for_each(|x| *x = x.max(0.0)),
            Activation::Sigmoid => xs.iter_mut().for_each(|x| *x = 1.0 / (1.0 + (-*x).exp())),
        }
    }

    /// Adds `bias` to every row of `xs` (rows of `bias.len()` values) and applies the
    /// activation, in one pass; the same values as adding the bias and then [`Activation::apply`].
    pub fn apply_with_bias(self, xs: &mut [f32], bias: &[f32]) {
        let rows = xs.chunks_exact_mut(bias.len().max(1));
        match self {
            Activation::Identity => rows.for_each(|row| {
                row.iter_mut().zip(bias).for_each(|(x, b)| *x += b);
            }),
            Activation::Relu => rows.for_each(|row| {
                row.iter_mut()
                    .zip(bias)
                    .for_each(|(x, b)| *x = (*x + b).max(0.0));
            }),
            Activation::Sigmoid => rows.for_each(|row| {
                row.iter_mut()
                    .zip(bias)
                    .for_each(|(x, b)| *x = 1.0 / (1.0 + (-(*x + b)).exp()));
            }),
        }
    }

    /// Multiplies `grad` in place by the derivative, given the activation's outputs `ys`.
    pub fn backward_from_output(self, ys: &[f32], grad: &mut [f32]) {
        match self {
            Activation::Identity => {}
            // A select rather than a conditional store, so the loop vectorises (the signs of
            // `ys` are random: a branch here mispredicts about every other element).
            Activation::Relu => grad
                .iter_mut()
                .zip(ys)
                .for_each(|(g, &y)| *g = if y <= 0.0 { 0.0 } else { *g }),
            Activation::Sigmoid => grad
                .iter_mut()
                .zip(ys)
                .for_each(|(g, &y)| *g *= y * (1.0 - y)),
        }
    }
}
