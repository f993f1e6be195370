//! The training plot of `evogs plot RUN`: loss, training PSNR and Gaussian count against the
//! iteration, three panels from `train_log.jsonl` (`evogs_train::train_log`), drawn with `plotters`
//! (bitmap backend). Text uses the system's sans-serif font; where none can be found the panels
//! are drawn again without text (curves and axes only), as the ablation plot does.

use evogs_train::RunPaths;
use evogs_train::train_log::{LogLine, read_log};
use image::RgbImage;
use plotters::prelude::*;

use crate::ExperimentError;
use crate::plotting::{draw_with_fallback, padded_range, tick_label};

const WIDTH: u32 = 900;
const HEIGHT: u32 = 900;

/// The plot as an RGB image; the error is plotters' message.
pub fn plot(lines: &[LogLine]) -> Result<RgbImage, String> {
    draw_with_fallback((WIDTH, HEIGHT), |buf, text| draw(lines, buf, text))
}

/// The axis range of `values`, 5 % margins.
fn range(values: impl Iterator<Item = f64>) -> (f64, f64) {
    padded_range(values, 0.05, 1e-6)
}

/// A panel: its axis name, the value it reads from a line, its colour.
type Series = (&'static str, fn(&LogLine) -> f64, RGBColor);

fn draw(lines: &[LogLine], buf: &mut [u8], text: bool) -> Result<(), String> {
    let err = |e: &dyn std::fmt::Display| e.to_string();
    let root = BitMapBackend::with_buffer(buf, (WIDTH, HEIGHT)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| err(&e))?;
    let panels = root.split_evenly((3, 1));
    let (x0, x1) = range(lines.iter().map(|l| l.iteration as f64));
    let series: [Series; 3] = [
        ("loss", |l| l.loss, RED),
        ("training PSNR (dB)", |l| l.psnr, BLUE),
        ("Gaussians", |l| l.gaussians as f64, BLACK),
    ];
    for (area, (name, value, colour)) in panels.iter().zip(series) {
        let (y0, y1) = range(lines.iter().map(value));
        let mut builder = ChartBuilder::on(area);
        builder.margin(15);
        if text {
            builder.x_label_area_size(35).y_label_area_size(70);
        } else {
            builder.x_label_area_size(5).y_label_area_size(5);
        }
        let mut chart = builder
            .build_cartesian_2d(x0..x1, y0..y1)
            .map_err(|e| err(&e))?;
        let mut mesh = chart.configure_mesh();
        if text {
            mesh.x_desc("iteration")
                .y_desc(name)
                .x_label_formatter(&|v| tick_label(*v))
                .y_label_formatter(&|v| tick_label(*v));
        } else {
            mesh.disable_x_mesh()
                .disable_y_mesh()
                .x_labels(0)
                .y_labels(0);
        }
        mesh.draw().map_err(|e| err(&e))?;
        let points: Vec<(f64, f64)> = lines
            .iter()
            .map(|l| (l.iteration as f64, value(l)))
            .filter(|(_, y)| y.is_finite())
            .collect();
        chart
            .draw_series(LineSeries::new(
                points.iter().copied(),
                colour.stroke_width(2),
            ))
            .map_err(|e| err(&e))?;
        chart
            .draw_series(points.iter().map(|&p| Circle::new(p, 3, colour.filled())))
            .map_err(|e| err(&e))?;
    }
    root.present().map_err(|e| err(&e))?;
    Ok(())
}

/// Draws the run's `train_log.jsonl` into `out` (PNG, written atomically); returns the number
/// of lines plotted. Errors name the file.
pub fn plot_run(run: &std::path::Path, out: &std::path::Path) -> Result<usize, ExperimentError> {
    let log = RunPaths::new(run).train_log();
    let lines = read_log(&log)?;
    if lines.is_empty() {
        return Err(ExperimentError::output(&log, "no lines to plot"));
    }
    let image = plot(&lines)
        .map_err(|problem| ExperimentError::output(out, format!("plotting: {problem}")))?;
    evogs_io::image_io::save_rgb8_png(out, &image)?;
    Ok(lines.len())
}
