//! The ablation plot: test PSNR against training time, one labelled point per row with a
//! vertical error bar of ± one sample standard deviation over seeds where there are several
//! (`plotters`, bitmap backend). Text is drawn with the system's sans-serif font; where none can be found the
//! plot is drawn again without text (points and axes only).

use crate::plotting::{draw_with_fallback, padded_range, tick_label};
use image::RgbImage;
use plotters::prelude::*;

use crate::ablate_data::AblationResult;

const WIDTH: u32 = 800;
const HEIGHT: u32 = 600;

/// The plot as an RGB image; the error is plotters' message.
pub fn plot(results: &[AblationResult]) -> Result<RgbImage, String> {
    draw_with_fallback((WIDTH, HEIGHT), |buf, text| draw(results, buf, text))
}

/// The axis range of `values`, 10 % margins (at least 5 % of the largest value).
fn range(values: impl Iterator<Item = f64>) -> (f64, f64) {
    padded_range(values, 0.1, 0.05)
}

fn draw(results: &[AblationResult], buf: &mut [u8], text: bool) -> Result<(), String> {
    let err = |e: &dyn std::fmt::Display| e.to_string();
    let root = BitMapBackend::with_buffer(buf, (WIDTH, HEIGHT)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| err(&e))?;
    let (x0, x1) = range(results.iter().map(|r| r.scores.seconds));
    let spread = |r: &AblationResult| r.std.as_ref().map_or(0.0, |d| d.psnr);
    let (y0, y1) = range(
        results
            .iter()
            .flat_map(|r| [r.scores.psnr - spread(r), r.scores.psnr + spread(r)]),
    );
    let mut builder = ChartBuilder::on(&root);
    builder.margin(20);
    if text {
        builder
            .caption("PSNR against training time", ("sans-serif", 24))
            .x_label_area_size(40)
            .y_label_area_size(60);
    } else {
        builder.x_label_area_size(10).y_label_area_size(10);
    }
    let mut chart = builder
        .build_cartesian_2d(x0..x1, y0..y1)
        .map_err(|e| err(&e))?;
    let mut mesh = chart.configure_mesh();
    if text {
        mesh.x_desc("training time (s)")
            .y_desc("test PSNR (dB)")
            .x_label_formatter(&|v| tick_label(*v))
            .y_label_formatter(&|v| tick_label(*v));
    } else {
        mesh.disable_x_mesh()
            .disable_y_mesh()
            .x_labels(0)
            .y_labels(0);
    }
    mesh.draw().map_err(|e| err(&e))?;
    let points: Vec<(f64, f64, &str)> = results
        .iter()
        .filter(|r| r.scores.seconds.is_finite() && r.scores.psnr.is_finite())
        .map(|r| (r.scores.seconds, r.scores.psnr, r.name.as_str()))
        .collect();
    let bars: Vec<(f64, f64, f64)> = results
        .iter()
        .filter(|r| r.scores.seconds.is_finite() && r.scores.psnr.is_finite())
        .map(|r| (r.scores.seconds, r.scores.psnr, spread(r)))
        .collect();
    chart
        .draw_series(
            bars.iter()
                .enumerate()
                .filter(|(_, b)| b.2 > 0.0 && b.2.is_finite())
                .map(|(i, &(x, y, d))| {
                    ErrorBar::new_vertical(
                        x,
                        y - d,
                        y,
                        y + d,
                        Palette99::pick(i).stroke_width(2),
                        10,
                    )
                }),
        )
        .map_err(|e| err(&e))?;
    chart
        .draw_series(
            points
                .iter()
                .enumerate()
                .map(|(i, &(x, y, _))| Circle::new((x, y), 5, Palette99::pick(i).filled())),
        )
        .map_err(|e| err(&e))?;
    if text {
        // Labels to the right of their point, staggered downwards so that rows with nearly equal
        // time and PSNR stay readable.
        chart
            .draw_series(points.iter().enumerate().map(|(i, &(x, y, name))| {
                EmptyElement::at((x, y))
                    + Text::new(
                        name.to_string(),
                        (8, -8 + 15 * (i % 4) as i32),
                        ("sans-serif", 15).into_font(),
                    )
            }))
            .map_err(|e| err(&e))?;
    }
    root.present().map_err(|e| err(&e))?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn range_has_ten_percent_margins_and_a_floor_for_single_values() {
        assert_eq!(range([0.0, 10.0, f64::NAN].into_iter()), (-1.0, 11.0));
        assert_eq!(range([20.0].into_iter()), (19.0, 21.0));
    }
}
