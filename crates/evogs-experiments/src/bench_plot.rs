//! The bench plot: PSNR on each scene's headline split against training time, one panel per
//! scene, one line per method, and the published D-3DGS figure as a dashed horizontal line
//! (`plotters`, bitmap backend). Text is drawn with the system's sans-serif font; where none can
//! be found the plot is drawn again without text.

use crate::plotting::{draw_with_fallback, finite_bounds, tick_label};
use image::RgbImage;
use plotters::prelude::*;

use crate::bench_data::{BenchRun, published_for};

const PANEL_WIDTH: u32 = 480;
const PANEL_HEIGHT: u32 = 360;

/// The plot as an RGB image (panels side by side, two per row); the error is plotters' message.
pub fn plot(runs: &[BenchRun]) -> Result<RgbImage, String> {
    let scenes = scene_order(runs);
    let cols = scenes.len().clamp(1, 2) as u32;
    let rows = scenes.len().div_ceil(2).max(1) as u32;
    let (w, h) = (cols * PANEL_WIDTH, rows * PANEL_HEIGHT);
    draw_with_fallback((w, h), |buf, text| {
        draw(runs, &scenes, (w, h), (rows, cols), buf, text)
    })
}

/// Scene names in the order they first appear.
fn scene_order(runs: &[BenchRun]) -> Vec<&str> {
    let mut out: Vec<&str> = Vec::new();
    for r in runs {
        if !out.contains(&r.scene.as_str()) {
            out.push(&r.scene);
        }
    }
    out
}

/// Axis ranges of a panel: time in minutes from 0, PSNR around every curve point and the
/// published figure.
fn ranges(points: &[(f64, f64)], published: Option<f64>) -> ((f64, f64), (f64, f64)) {
    let finite = |v: &f64| v.is_finite();
    let x1 = points
        .iter()
        .map(|p| p.0)
        .filter(finite)
        .fold(0.0f64, f64::max)
        .max(1e-3);
    let Some((lo, hi)) = finite_bounds(points.iter().map(|p| p.1).chain(published)) else {
        return ((0.0, x1 * 1.05), (0.0, 1.0));
    };
    let margin = ((hi - lo) * 0.08).max(0.5);
    ((0.0, x1 * 1.05), (lo - margin, hi + margin))
}

fn draw(
    runs: &[BenchRun],
    scenes: &[&str],
    size: (u32, u32),
    grid: (u32, u32),
    buf: &mut [u8],
    text: bool,
) -> Result<(), String> {
    let err = |e: &dyn std::fmt::Display| e.to_string();
    let root = BitMapBackend::with_buffer(buf, size).into_drawing_area();
    root.fill(&WHITE).map_err(|e| err(&e))?;
    let panels = root.split_evenly((grid.0 as usize, grid.1 as usize));
    for (panel, scene) in panels.iter().zip(scenes) {
        let mine: Vec<&BenchRun> = runs.iter().filter(|r| r.scene == *scene).collect();
        let resolution = mine.first().map_or(400, |r| r.resolution);
        let published = published_for(scene, resolution);
        let all: Vec<(f64, f64)> = mine
            .iter()
            .flat_map(|r| r.curve.iter().map(|p| (p.seconds / 60.0, p.psnr)))
            .collect();
        let ((x0, x1), (y0, y1)) = ranges(&all, published.map(|p| p.psnr));
        let mut builder = ChartBuilder::on(panel);
        builder.margin(12);
        if text {
            let split = mine.first().map_or("", |r| r.headline.as_str());
            builder
                .caption(format!("{scene} ({split})"), ("sans-serif", 20))
                .x_label_area_size(35)
                .y_label_area_size(50);
        } else {
            builder.x_label_area_size(8).y_label_area_size(8);
        }
        let mut chart = builder
            .build_cartesian_2d(x0..x1, y0..y1)
            .map_err(|e| err(&e))?;
        let mut mesh = chart.configure_mesh();
        if text {
            mesh.x_desc("training time (min)")
                .y_desc("PSNR (dB)")
                .x_label_formatter(&|v| tick_label(*v))
                .y_label_formatter(&|v| tick_label(*v));
        } else {
            mesh.x_labels(0).y_labels(0);
        }
        mesh.draw().map_err(|e| err(&e))?;
        for (i, r) in mine.iter().enumerate() {
            let colour = Palette99::pick(i);
            let line: Vec<(f64, f64)> = r
                .curve
                .iter()
                .filter(|p| p.seconds.is_finite() && p.psnr.is_finite())
                .map(|p| (p.seconds / 60.0, p.psnr))
                .collect();
            let series = chart
                .draw_series(LineSeries::new(line.clone(), colour.stroke_width(2)))
                .map_err(|e| err(&e))?;
            if text {
                let c = colour.to_rgba();
                series
                    .label(r.method.to_string())
                    .legend(move |(x, y)| PathElement::new([(x, y), (x + 16, y)], c));
            }
            chart
                .draw_series(line.iter().map(|&p| Circle::new(p, 3, colour.filled())))
                .map_err(|e| err(&e))?;
        }
        if let Some(p) = published {
            let dashes = (0..40).map(|k| {
                let a = x0 + (x1 - x0) * (2 * k) as f64 / 80.0;
                let b = x0 + (x1 - x0) * (2 * k + 1) as f64 / 80.0;
                PathElement::new([(a, p.psnr), (b, p.psnr)], BLACK)
            });
            let series = chart.draw_series(dashes).map_err(|e| err(&e))?;
            if text {
                series
                    .label(format!(
                        "D-3DGS {}×{} ({})",
                        p.resolution, p.resolution, p.split
                    ))
                    .legend(|(x, y)| PathElement::new([(x, y), (x + 16, y)], BLACK));
            }
        }
        if text {
            chart
                .configure_series_labels()
                .position(SeriesLabelPosition::LowerRight)
                .background_style(WHITE.mix(0.8))
                .border_style(BLACK)
                .draw()
                .map_err(|e| err(&e))?;
        }
    }
    root.present().map_err(|e| err(&e))?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ranges_start_at_zero_and_include_the_published_figure() {
        let ((x0, x1), (y0, y1)) = ranges(&[(1.0, 20.0), (2.0, 25.0)], Some(33.0));
        assert_eq!(x0, 0.0);
        assert!(x1 > 2.0);
        assert!(y0 < 20.0 && y1 > 33.0);
        let (_, (y0, y1)) = ranges(&[], None);
        assert_eq!((y0, y1), (0.0, 1.0));
        let (_, (y0, y1)) = ranges(&[(1.0, f64::NAN)], Some(30.0));
        assert!(y0 < 30.0 && y1 > 30.0);
    }
}
