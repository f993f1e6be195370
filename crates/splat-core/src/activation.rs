//! The activations that turn raw Gaussian parameters into the values a renderer uses: opacity is
//! `sigmoid(logit)` and the logit of an opacity is its inverse. Every crate uses these, so that a
//! parameter means the same everywhere.

/// The logistic function `1 / (1 + e^-x)`: opacity from its logit.
pub fn sigmoid(x: f32) -> f32 {
    1.0 / (1.0 + (-x).exp())
}

/// Inverse of [`sigmoid`], `ln(p / (1 - p))`: the logit of an opacity in (0, 1).
pub fn logit(p: f32) -> f32 {
    (p / (1.0 - p)).ln()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn logit_inverts_sigmoid() {
        for p in [0.005f32, 0.1, 0.5, 0.9, 0.99] {
            assert!((sigmoid(logit(p)) - p).abs() < 1e-6, "p = {p}");
        }
        assert_eq!(sigmoid(0.0), 0.5);
        assert_eq!(logit(0.5), 0.0);
    }
}
