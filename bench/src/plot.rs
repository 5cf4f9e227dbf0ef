//! Pictures of the benchmarks with `plotters`: curves over time, and latency
//! distributions as percentile plots on a log scale. The font is bundled
//! (DejaVu Sans Mono, `bench/assets/`), so a machine without fonts draws
//! the same PNG.

use std::path::Path;
use std::sync::Once;

use anyhow::Context;
use plotters::prelude::*;
use plotters::style::FontStyle;

use crate::stats::Latencies;

/// The bundled font, registered once under this family name.
const FAMILY: &str = "simbus-mono";

fn register_font() {
    static ONCE: Once = Once::new();
    ONCE.call_once(|| {
        // The bytes are a valid TrueType font shipped with the source.
        let _ = plotters::style::register_font(
            FAMILY,
            FontStyle::Normal,
            include_bytes!("../assets/DejaVuSansMono.ttf"),
        );
    });
}

/// One named curve.
pub(crate) struct Series {
    pub(crate) name: String,
    pub(crate) points: Vec<(f64, f64)>,
}

/// A palette that stays apart when printed in grey too.
const COLOURS: [RGBColor; 8] = [
    RGBColor(31, 119, 180),
    RGBColor(255, 127, 14),
    RGBColor(44, 160, 44),
    RGBColor(214, 39, 40),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
    RGBColor(227, 119, 194),
    RGBColor(23, 190, 207),
];

/// The smallest and largest of `values`, a little apart when equal.
fn extent(values: impl Iterator<Item = f64>) -> (f64, f64) {
    let (low, high) = values
        .filter(|v| v.is_finite())
        .fold((f64::MAX, f64::MIN), |(l, h), v| (l.min(v), h.max(v)));
    if low > high {
        (0.0, 1.0)
    } else if high - low < 1e-9 {
        (low - 0.5, high + 0.5)
    } else {
        let pad = (high - low) * 0.05;
        (low - pad, high + pad)
    }
}

type Chart<'a, X, Y> = ChartContext<'a, BitMapBackend<'a>, Cartesian2d<X, Y>>;

/// Draws curve number `i` with its legend entry.
fn curve<X, Y>(
    chart: &mut Chart<'_, X, Y>,
    i: usize,
    name: &str,
    points: &[(f64, f64)],
) -> anyhow::Result<()>
where
    X: Ranged<ValueType = f64>,
    Y: Ranged<ValueType = f64>,
{
    let colour = COLOURS[i % COLOURS.len()];
    chart
        .draw_series(LineSeries::new(
            points.iter().copied(),
            colour.stroke_width(2),
        ))?
        .label(name)
        .legend(move |(x, y)| PathElement::new([(x, y), (x + 18, y)], colour.stroke_width(2)));
    Ok(())
}

type Canvas<'a> = DrawingArea<BitMapBackend<'a>, plotters::coord::Shift>;

/// A white 960x600 PNG canvas at `path`.
fn canvas(path: &Path) -> anyhow::Result<Canvas<'_>> {
    let root = BitMapBackend::new(path, (960, 600)).into_drawing_area();
    root.fill(&WHITE)?;
    Ok(root)
}

/// A chart on `root` with `title` and room for the axes' labels.
fn titled<'a, 'b>(root: &'a Canvas<'b>, title: &str) -> ChartBuilder<'a, 'b, BitMapBackend<'b>> {
    let mut builder = ChartBuilder::on(root);
    builder
        .caption(title, (FAMILY, 20))
        .margin(12)
        .x_label_area_size(44)
        .y_label_area_size(64);
    builder
}

/// Draws the legend and writes the PNG.
fn finish<X, Y>(chart: &mut Chart<'_, X, Y>, root: &Canvas<'_>, path: &Path) -> anyhow::Result<()>
where
    X: Ranged<ValueType = f64>,
    Y: Ranged<ValueType = f64>,
{
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::LowerRight)
        .label_font((FAMILY, 14))
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .draw()?;
    root.present()
        .with_context(|| format!("writing {}", path.display()))?;
    Ok(())
}

/// Draws `series` as lines over a linear x and y into a PNG at `path`.
pub(crate) fn lines(
    path: &Path,
    title: &str,
    (x_label, y_label): (&str, &str),
    series: &[Series],
) -> anyhow::Result<()> {
    register_font();
    let (x0, x1) = extent(series.iter().flat_map(|s| s.points.iter().map(|p| p.0)));
    let (y0, y1) = extent(series.iter().flat_map(|s| s.points.iter().map(|p| p.1)));
    let root = canvas(path)?;
    let mut chart = titled(&root, title).build_cartesian_2d(x0..x1, y0..y1)?;
    chart
        .configure_mesh()
        .x_desc(x_label)
        .y_desc(y_label)
        .label_style((FAMILY, 14))
        .draw()?;
    for (i, s) in series.iter().enumerate() {
        curve(&mut chart, i, &s.name, &s.points)?;
    }
    finish(&mut chart, &root, path)
}

/// Draws latency distributions side by side as percentile plots: latency
/// (µs, log scale) against the fraction of samples at or below it.
pub(crate) fn percentiles(
    path: &Path,
    title: &str,
    rows: &[(&str, &Latencies)],
) -> anyhow::Result<()> {
    register_font();
    let curves: Vec<(&str, Vec<(f64, f64)>)> = rows
        .iter()
        .map(|(name, latencies)| (*name, latencies.cdf_us()))
        .collect();
    let (low, high) = curves
        .iter()
        .flat_map(|(_, c)| c.iter().map(|p| p.0))
        .filter(|v| *v > 0.0)
        .fold((f64::MAX, f64::MIN), |(l, h), v| (l.min(v), h.max(v)));
    let (low, high) = if low > high {
        (0.1, 10.0)
    } else {
        (low / 1.5, high * 1.5)
    };
    let root = canvas(path)?;
    let mut chart = titled(&root, title).build_cartesian_2d((low..high).log_scale(), 0.0..1.0)?;
    chart
        .configure_mesh()
        .x_desc("latency, µs (log scale)")
        .y_desc("fraction of samples at or below")
        .label_style((FAMILY, 14))
        .draw()?;
    for (i, (name, points)) in curves.iter().enumerate() {
        curve(&mut chart, i, name, points)?;
    }
    finish(&mut chart, &root, path)
}

/// Writes `series` as CSV: one column of x per series' own times would be
/// unwieldy, so one row per point: `series,x,y`.
pub(crate) fn csv(
    path: &Path,
    (x_name, y_name): (&str, &str),
    series: &[Series],
) -> anyhow::Result<()> {
    use std::fmt::Write;
    let mut text = format!("series,{x_name},{y_name}\n");
    for s in series {
        for (x, y) in &s.points {
            let _ = writeln!(text, "{},{x},{y}", s.name);
        }
    }
    std::fs::write(path, text).with_context(|| format!("writing {}", path.display()))
}
