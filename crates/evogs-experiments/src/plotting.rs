//! What the plots of evogs share: the training plot ([`crate::train_plot`]) and the ablation and
//! benchmark plots of `evogs-experiments`. Each draws with `plotters` into an RGB buffer; where the
//! system has no sans-serif font the text-less drawing is tried next ([`draw_with_fallback`]).
//! Axis ranges come from the finite values only ([`finite_bounds`], [`padded_range`]); tick labels
//! are written by [`tick_label`] (`1000`, not plotters' `1000.0`).
//!
//! What it is not: a plot. Each plot keeps its own layout, series and margins.

use image::RgbImage;

/// Draws a `width × height` plot with `draw(buffer, text)`: first with text, and when that fails
/// (e.g. no font) again without text on a blank buffer. The error is plotters' message.
pub fn draw_with_fallback(
    (width, height): (u32, u32),
    draw: impl Fn(&mut [u8], bool) -> Result<(), String>,
) -> Result<RgbImage, String> {
    let mut buf = vec![255u8; (width * height * 3) as usize];
    if draw(&mut buf, true).is_err() {
        buf.fill(255);
        draw(&mut buf, false)?;
    }
    RgbImage::from_raw(width, height, buf).ok_or_else(|| "plot buffer of the wrong size".into())
}

/// The smallest and largest finite value, or `None` when there is none.
pub fn finite_bounds(values: impl Iterator<Item = f64>) -> Option<(f64, f64)> {
    let (lo, hi) = values
        .filter(|v| v.is_finite())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
            (lo.min(v), hi.max(v))
        });
    lo.is_finite().then_some((lo, hi))
}

/// A finite range around `values`, widened on each side by `fraction` of its span, and by at least
/// `floor` times the largest magnitude (at least 1), so that a single value still gets a range;
/// `(0, 1)` when there are no finite values.
pub fn padded_range(values: impl Iterator<Item = f64>, fraction: f64, floor: f64) -> (f64, f64) {
    let Some((lo, hi)) = finite_bounds(values) else {
        return (0.0, 1.0);
    };
    let margin = ((hi - lo) * fraction).max(floor * hi.abs().max(1.0));
    (lo - margin, hi + margin)
}

/// An axis tick's label: a whole number without a decimal point (`1000`, `-5`, `0`), anything
/// else with four significant digits and no trailing zeros (`0.025`, `27.5`, `0.0001234`);
/// magnitudes below 10⁻⁴ in scientific notation (`2.5e-6`). Whole is judged with a tolerance
/// relative to the value, so that ticks plotters computes as `999.9999999999` print as `1000`.
pub fn tick_label(value: f64) -> String {
    if !value.is_finite() {
        return value.to_string();
    }
    let rounded = value.round();
    if (value - rounded).abs() <= 1e-9 * value.abs().max(1.0) && rounded.abs() < 1e15 {
        // `as i64` is exact below 2^53 and turns -0.0 into 0.
        return (rounded as i64).to_string();
    }
    let magnitude = value.abs().log10().floor();
    if magnitude < -4.0 {
        let text = format!("{value:.3e}");
        let (mantissa, exponent) = text.split_once('e').unwrap_or((&text, "0"));
        return format!("{}e{exponent}", trim_zeros(mantissa));
    }
    // Four significant digits: 3 − ⌊log10 |v|⌋ decimals (0 from 1000 up).
    let decimals = (3.0 - magnitude).clamp(0.0, 8.0) as usize;
    trim_zeros(&format!("{value:.decimals$}")).to_string()
}

/// `text` without trailing zeros after a decimal point, nor a bare trailing point.
fn trim_zeros(text: &str) -> &str {
    if text.contains('.') {
        text.trim_end_matches('0').trim_end_matches('.')
    } else {
        text
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ranges_have_margins_and_survive_nan_and_single_values() {
        let (lo, hi) = padded_range([1.0, 3.0, f64::NAN].into_iter(), 0.1, 0.05);
        assert!(lo < 1.0 && hi > 3.0);
        let (lo, hi) = padded_range([20.0].into_iter(), 0.05, 1e-6);
        assert!(lo < 20.0 && hi > 20.0);
        assert_eq!(padded_range(std::iter::empty(), 0.1, 0.05), (0.0, 1.0));
        assert_eq!(finite_bounds([f64::NAN, f64::INFINITY].into_iter()), None);
        assert_eq!(finite_bounds([2.0, -1.0].into_iter()), Some((-1.0, 2.0)));
    }

    #[test]
    fn tick_labels_print_whole_numbers_as_integers() {
        for (value, label) in [
            (1000.0, "1000"),
            (0.0, "0"),
            (-0.0, "0"),
            (-5.0, "-5"),
            (45_000.0, "45000"),
            (999.999_999_999_9, "1000"),
            (0.1 + 0.2, "0.3"),
            (0.025, "0.025"),
            (27.5, "27.5"),
            (-12.25, "-12.25"),
            (1234.6, "1235"),
            (0.000_123_4, "0.0001234"),
            (0.000_002_5, "2.5e-6"),
            (f64::NAN, "NaN"),
        ] {
            assert_eq!(tick_label(value), label, "{value}");
        }
    }

    #[test]
    fn the_text_less_drawing_runs_when_the_first_fails() {
        let image = draw_with_fallback((4, 2), |buf, text| {
            if text {
                buf.fill(7);
                return Err("no font".into());
            }
            buf[0] = 1;
            Ok(())
        })
        .unwrap();
        assert_eq!(image.get_pixel(0, 0).0, [1, 255, 255]);
        assert_eq!(image.get_pixel(3, 1).0, [255, 255, 255]);
        let err = draw_with_fallback((4, 2), |_, _| Err("broken".into())).unwrap_err();
        assert_eq!(err, "broken");
    }
}
