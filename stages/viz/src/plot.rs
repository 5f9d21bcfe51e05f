//! PNG plots for people: the match-value response (like the paper's figures
//! 3 and 6), reliability diagrams and latency curves, drawn with plotters
//! into a buffer and saved with `image`.

use plotters::prelude::*;
use std::path::{Path, PathBuf};
use std::sync::Once;

/// A plot could not be drawn or written.
#[derive(Debug, thiserror::Error)]
pub enum PlotError {
    /// Plotters failed to draw.
    #[error("drawing {}: {reason}", path.display())]
    Draw {
        /// The plot's file.
        path: PathBuf,
        /// What plotters said.
        reason: String,
    },
    /// The PNG could not be written.
    #[error("writing {}", path.display())]
    Write {
        /// The plot's file.
        path: PathBuf,
        /// What the encoder said.
        #[source]
        source: image::ImageError,
    },
}

/// What a drawing closure returns: plotters' errors as text.
pub type DrawResult = Result<(), String>;

/// Turns a plotters error into a [`DrawResult`] error.
pub fn draw_err<E: std::fmt::Display>(e: E) -> String {
    e.to_string()
}

/// Plotters needs a font; the embedded one makes plots work on machines
/// without any installed.
fn register_font() {
    static ONCE: Once = Once::new();
    ONCE.call_once(|| {
        // Registration only fails on unparsable font bytes, which are fixed here.
        let _ = plotters::style::register_font(
            "sans-serif",
            FontStyle::Normal,
            epaint_default_fonts::UBUNTU_LIGHT,
        );
    });
}

/// Draws into a white RGB canvas and writes it as PNG.
pub fn draw_png(
    path: &Path,
    (w, h): (u32, u32),
    draw: impl FnOnce(&DrawingArea<BitMapBackend, plotters::coord::Shift>) -> DrawResult,
) -> Result<(), PlotError> {
    register_font();
    let failed = |reason: String| PlotError::Draw {
        path: path.to_owned(),
        reason,
    };
    let mut buf = vec![255u8; (w * h * 3) as usize];
    {
        let root = BitMapBackend::with_buffer(&mut buf, (w, h)).into_drawing_area();
        root.fill(&WHITE).map_err(draw_err).map_err(failed)?;
        draw(&root).map_err(failed)?;
        root.present().map_err(draw_err).map_err(failed)?;
    }
    image::RgbImage::from_raw(w, h, buf)
        .expect("buffer matches its size")
        .save(path)
        .map_err(|source| PlotError::Write {
            path: path.to_owned(),
            source,
        })
}

/// One θ slice of a response plot: its first view index, length and θ.
pub struct SliceMark {
    /// First view index.
    pub start: usize,
    /// Number of views.
    pub len: usize,
    /// Elevation, degrees.
    pub theta_deg: f32,
}

/// Plots the response over the view index with the θ slices shaded and
/// labelled, the best view marked, and the true view when known.
pub fn response_plot(
    path: &Path,
    title: &str,
    response: &[f32],
    slices: &[SliceMark],
    best: usize,
    truth: Option<usize>,
) -> Result<(), PlotError> {
    let e = draw_err;
    draw_png(path, (1000, 420), |root| {
        let lo = response
            .iter()
            .copied()
            .fold(f32::INFINITY, f32::min)
            .min(1.0);
        let y0 = (lo - 0.05).max(0.0);
        let mut chart = ChartBuilder::on(root)
            .caption(title, ("sans-serif", 20))
            .margin(12)
            .x_label_area_size(36)
            .y_label_area_size(50)
            .build_cartesian_2d(0f32..response.len() as f32, y0..1.0f32)
            .map_err(e)?;
        chart
            .configure_mesh()
            .disable_x_mesh()
            .x_desc("training view (θ slice by θ slice, φ ascending)")
            .y_desc("match value")
            .draw()
            .map_err(e)?;
        for (k, s) in slices.iter().enumerate() {
            let shade = if k % 2 == 0 {
                RGBColor(236, 240, 248)
            } else {
                WHITE
            };
            let (a, b) = (s.start as f32 - 0.5, (s.start + s.len) as f32 - 0.5);
            chart
                .draw_series(std::iter::once(Rectangle::new(
                    [(a, y0), (b, 1.0)],
                    shade.filled(),
                )))
                .map_err(e)?;
            chart
                .draw_series(std::iter::once(Text::new(
                    format!("θ={}", s.theta_deg),
                    (a + 1.0, 0.985),
                    ("sans-serif", 14),
                )))
                .map_err(e)?;
        }
        chart
            .draw_series(LineSeries::new(
                response.iter().enumerate().map(|(i, &v)| (i as f32, v)),
                BLUE.stroke_width(2),
            ))
            .map_err(e)?;
        if let Some(t) = truth {
            chart
                .draw_series(std::iter::once(PathElement::new(
                    vec![(t as f32, y0), (t as f32, 1.0)],
                    GREEN.stroke_width(2),
                )))
                .map_err(e)?
                .label("nearest view to the truth")
                .legend(|(x, y)| {
                    PathElement::new(vec![(x, y), (x + 18, y)], GREEN.stroke_width(2))
                });
        }
        chart
            .draw_series(std::iter::once(Circle::new(
                (best as f32, response[best]),
                6,
                RED.filled(),
            )))
            .map_err(e)?
            .label("best view")
            .legend(|(x, y)| Circle::new((x + 9, y), 5, RED.filled()));
        chart
            .configure_series_labels()
            .position(SeriesLabelPosition::LowerRight)
            .background_style(WHITE.mix(0.8))
            .border_style(BLACK)
            .draw()
            .map_err(e)?;
        Ok(())
    })
}

/// One bin of a reliability diagram.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ReliabilityBin {
    /// Mean predicted confidence of the bin's estimates.
    pub mean_confidence: f64,
    /// Share of them that were reliable.
    pub accuracy: f64,
    /// Estimates in the bin.
    pub count: usize,
}

/// A reliability diagram: per confidence bin, the share of reliable
/// estimates against the mean confidence, one series per network; the
/// diagonal is perfect calibration. Bar labels give the bin counts.
pub fn reliability_diagram(
    path: &Path,
    title: &str,
    series: &[(&str, &[ReliabilityBin])],
) -> Result<(), PlotError> {
    let e = draw_err;
    let colours = [BLUE, RED, GREEN, MAGENTA];
    draw_png(path, (640, 560), |root| {
        let mut chart = ChartBuilder::on(root)
            .caption(title, ("sans-serif", 18))
            .margin(14)
            .x_label_area_size(40)
            .y_label_area_size(50)
            .build_cartesian_2d(0f64..1f64, 0f64..1f64)
            .map_err(e)?;
        chart
            .configure_mesh()
            .x_desc("predicted confidence")
            .y_desc("share of reliable estimates")
            .draw()
            .map_err(e)?;
        chart
            .draw_series(std::iter::once(PathElement::new(
                vec![(0.0, 0.0), (1.0, 1.0)],
                BLACK.mix(0.4).stroke_width(1),
            )))
            .map_err(e)?
            .label("perfect calibration")
            .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 18, y)], BLACK.mix(0.4)));
        for (k, (name, bins)) in series.iter().enumerate() {
            let colour = colours[k % colours.len()];
            let points: Vec<(f64, f64)> = bins
                .iter()
                .filter(|b| b.count > 0)
                .map(|b| (b.mean_confidence, b.accuracy))
                .collect();
            chart
                .draw_series(LineSeries::new(points.clone(), colour.stroke_width(2)))
                .map_err(e)?
                .label(format!(
                    "{name} ({} estimates)",
                    bins.iter().map(|b| b.count).sum::<usize>()
                ))
                .legend(move |(x, y)| {
                    PathElement::new(vec![(x, y), (x + 18, y)], colour.stroke_width(2))
                });
            chart
                .draw_series(points.iter().map(|&p| Circle::new(p, 4, colour.filled())))
                .map_err(e)?;
        }
        chart
            .configure_series_labels()
            .position(SeriesLabelPosition::UpperLeft)
            .background_style(WHITE.mix(0.8))
            .border_style(BLACK)
            .draw()
            .map_err(e)?;
        Ok(())
    })
}

/// One line of a [`panels`] plot.
pub struct Series {
    /// Legend name.
    pub name: String,
    /// (x, y) points, drawn in order.
    pub points: Vec<(f64, f64)>,
    /// A y drawn as a dashed line across the panel (the unperturbed value).
    pub reference: Option<f64>,
}

/// One panel of a [`panels`] plot: its own x axis, y in [0, 1].
pub struct Panel {
    /// Panel title (what x is).
    pub title: String,
    /// Its lines.
    pub series: Vec<Series>,
}

/// A grid of small line plots sharing a y axis in [0, 1] (rates), four
/// per row, with markers at the points and each series' reference as a
/// dashed line.
pub fn panels(path: &Path, title: &str, y_desc: &str, panels: &[Panel]) -> Result<(), PlotError> {
    let e = draw_err;
    let colours = [BLUE, RED, GREEN, MAGENTA];
    let cols = 4usize;
    let rows = panels.len().div_ceil(cols).max(1);
    draw_png(path, (1280, 60 + 300 * rows as u32), |root| {
        let root = root.titled(title, ("sans-serif", 20)).map_err(e)?;
        let areas = root.split_evenly((rows, cols));
        for (panel, area) in panels.iter().zip(areas.iter()) {
            let xs = panel
                .series
                .iter()
                .flat_map(|s| s.points.iter().map(|p| p.0));
            let (lo, hi) = xs.fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), x| {
                (lo.min(x), hi.max(x))
            });
            let (lo, hi) = if lo < hi {
                let pad = 0.05 * (hi - lo);
                (lo - pad, hi + pad)
            } else {
                (lo - 1.0, lo + 1.0)
            };
            let mut chart = ChartBuilder::on(area)
                .caption(&panel.title, ("sans-serif", 15))
                .margin(10)
                .x_label_area_size(28)
                .y_label_area_size(40)
                .build_cartesian_2d(lo..hi, 0f64..1f64)
                .map_err(e)?;
            chart
                .configure_mesh()
                .y_desc(y_desc)
                .x_labels(6)
                .y_labels(6)
                .draw()
                .map_err(e)?;
            for (k, s) in panel.series.iter().enumerate() {
                let colour = colours[k % colours.len()];
                if let Some(y) = s.reference {
                    chart
                        .draw_series(DashedLineSeries::new(
                            vec![(lo, y), (hi, y)],
                            6,
                            4,
                            colour.mix(0.5).stroke_width(1),
                        ))
                        .map_err(e)?;
                }
                chart
                    .draw_series(LineSeries::new(s.points.clone(), colour.stroke_width(2)))
                    .map_err(e)?
                    .label(&s.name)
                    .legend(move |(x, y)| {
                        PathElement::new(vec![(x, y), (x + 18, y)], colour.stroke_width(2))
                    });
                chart
                    .draw_series(s.points.iter().map(|&p| Circle::new(p, 3, colour.filled())))
                    .map_err(e)?;
            }
            chart
                .configure_series_labels()
                .position(SeriesLabelPosition::UpperLeft)
                .background_style(WHITE.mix(0.8))
                .border_style(BLACK)
                .label_font(("sans-serif", 12))
                .draw()
                .map_err(e)?;
        }
        Ok(())
    })
}
