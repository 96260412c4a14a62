//! Line charts as PNG and SVG (plotters), with labelled axes and a legend.

use plotters::prelude::*;
use std::path::Path;

/// One curve: legend label and points.
#[derive(Clone, Debug)]
pub struct Series {
    /// Legend label.
    pub label: String,
    /// `(x, y)` points.
    pub points: Vec<(f64, f64)>,
}

/// A chart description.
#[derive(Clone, Debug)]
pub struct Chart<'a> {
    /// Title.
    pub title: &'a str,
    /// x-axis label with unit.
    pub x_label: &'a str,
    /// y-axis label with unit.
    pub y_label: &'a str,
    /// Curves.
    pub series: Vec<Series>,
}

const COLORS: [RGBColor; 6] = [
    RGBColor(31, 119, 180),
    RGBColor(255, 127, 14),
    RGBColor(44, 160, 44),
    RGBColor(214, 39, 40),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
];

fn range(series: &[Series], pick: impl Fn(&(f64, f64)) -> f64) -> (f64, f64) {
    let vals: Vec<f64> = series
        .iter()
        .flat_map(|s| s.points.iter().map(&pick))
        .filter(|v| v.is_finite())
        .collect();
    let lo = vals.iter().copied().fold(f64::INFINITY, f64::min);
    let hi = vals.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    if !lo.is_finite() {
        return (0.0, 1.0);
    }
    let pad = if hi > lo {
        0.05 * (hi - lo)
    } else {
        0.5 * lo.abs().max(1.0)
    };
    (lo - pad, hi + pad)
}

fn draw<DB: DrawingBackend>(
    root: DrawingArea<DB, plotters::coord::Shift>,
    chart: &Chart,
) -> Result<(), String>
where
    DB::ErrorType: 'static,
{
    root.fill(&WHITE).map_err(|e| e.to_string())?;
    let (x0, x1) = range(&chart.series, |p| p.0);
    let (y0, y1) = range(&chart.series, |p| p.1);
    let mut c = ChartBuilder::on(&root)
        .caption(chart.title, ("sans-serif", 22))
        .margin(15)
        .x_label_area_size(45)
        .y_label_area_size(70)
        .build_cartesian_2d(x0..x1, y0..y1)
        .map_err(|e| e.to_string())?;
    c.configure_mesh()
        .x_desc(chart.x_label)
        .y_desc(chart.y_label)
        .label_style(("sans-serif", 15))
        .axis_desc_style(("sans-serif", 17))
        .draw()
        .map_err(|e| e.to_string())?;
    for (i, s) in chart.series.iter().enumerate() {
        let color = COLORS[i % COLORS.len()];
        c.draw_series(LineSeries::new(
            s.points.iter().copied(),
            color.stroke_width(2),
        ))
        .map_err(|e| e.to_string())?
        .label(s.label.clone())
        .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], color.stroke_width(2)));
    }
    c.configure_series_labels()
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .label_font(("sans-serif", 15))
        .draw()
        .map_err(|e| e.to_string())?;
    root.present().map_err(|e| e.to_string())
}

/// Render one figure twice, to `<stem>.png` and `<stem>.svg`, each written atomically (the PNG
/// through a hidden temporary file, since the bitmap backend writes to a path).
fn render(
    stem: &Path,
    size: (u32, u32),
    png: impl FnOnce(DrawingArea<BitMapBackend<'_>, plotters::coord::Shift>) -> Result<(), String>,
    svg: impl FnOnce(DrawingArea<SVGBackend<'_>, plotters::coord::Shift>) -> Result<(), String>,
) -> Result<(), crate::io::IoError> {
    let png_path = stem.with_extension("png");
    let err = |m: String| crate::io::IoError::Content {
        path: png_path.clone(),
        message: format!("drawing figure: {m}"),
    };
    let dir = stem.parent().unwrap_or(Path::new("."));
    let name = stem
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let tmp = dir.join(format!(".{name}.render.png"));
    png(BitMapBackend::new(&tmp, size).into_drawing_area()).map_err(err)?;
    let bytes = std::fs::read(&tmp).map_err(crate::io::fs_err(&tmp))?;
    let _ = std::fs::remove_file(&tmp);
    crate::io::write_atomic(&png_path, &bytes)?;
    let mut text = String::new();
    svg(SVGBackend::with_string(&mut text, size).into_drawing_area()).map_err(err)?;
    crate::io::write_atomic(&stem.with_extension("svg"), text.as_bytes())
}

/// Draw `chart` to `<stem>.png` and `<stem>.svg` (each written atomically).
pub fn line_chart(stem: &Path, chart: &Chart) -> Result<(), crate::io::IoError> {
    render(stem, (900, 600), |a| draw(a, chart), |a| draw(a, chart))
}

/// One panel of a row of heat maps: a square `n x n` field, row `y`, column `x`
/// (`values[y * n + x]`), drawn with `y` upwards.
#[derive(Clone, Debug)]
pub struct Panel {
    /// Panel caption.
    pub label: String,
    /// Points per side.
    pub n: usize,
    /// Values, x fastest.
    pub values: Vec<f64>,
}

/// Blue-to-yellow colour map on `t` in [0, 1] (perceptually ordered, readable in grey).
fn colormap(t: f64) -> RGBColor {
    let t = t.clamp(0.0, 1.0);
    let stops = [
        (68.0, 1.0, 84.0),
        (59.0, 82.0, 139.0),
        (33.0, 145.0, 140.0),
        (94.0, 201.0, 98.0),
        (253.0, 231.0, 37.0),
    ];
    let x = t * (stops.len() - 1) as f64;
    let i = (x as usize).min(stops.len() - 2);
    let f = x - i as f64;
    let (a, b) = (stops[i], stops[i + 1]);
    let mix = |p: f64, q: f64| (p + f * (q - p)).round() as u8;
    RGBColor(mix(a.0, b.0), mix(a.1, b.1), mix(a.2, b.2))
}

fn draw_panels<DB: DrawingBackend>(
    root: DrawingArea<DB, plotters::coord::Shift>,
    title: &str,
    scale_label: &str,
    panels: &[Panel],
) -> Result<(), String>
where
    DB::ErrorType: 'static,
{
    root.fill(&WHITE).map_err(|e| e.to_string())?;
    let (lo, hi) = panels
        .iter()
        .flat_map(|p| p.values.iter().copied())
        .filter(|v| v.is_finite())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
            (a.min(v), b.max(v))
        });
    let span = if hi > lo { hi - lo } else { 1.0 };
    let root = root
        .titled(
            &format!("{title} (colour: {scale_label}, from {lo:.3e} to {hi:.3e})"),
            ("sans-serif", 18),
        )
        .map_err(|e| e.to_string())?;
    let areas = root.split_evenly((1, panels.len().max(1)));
    for (area, p) in areas.iter().zip(panels) {
        let n = p.n as f64;
        let mut c = ChartBuilder::on(area)
            .caption(&p.label, ("sans-serif", 15))
            .margin(10)
            .x_label_area_size(35)
            .y_label_area_size(45)
            .build_cartesian_2d(0.0..1.0, 0.0..1.0)
            .map_err(|e| e.to_string())?;
        c.configure_mesh()
            .disable_mesh()
            .x_desc("x / L")
            .y_desc("y / L")
            .label_style(("sans-serif", 13))
            .draw()
            .map_err(|e| e.to_string())?;
        c.draw_series((0..p.n * p.n).map(|k| {
            let (x, y) = ((k % p.n) as f64, (k / p.n) as f64);
            let color = colormap((p.values[k] - lo) / span);
            Rectangle::new(
                [(x / n, y / n), ((x + 1.0) / n, (y + 1.0) / n)],
                color.filled(),
            )
        }))
        .map_err(|e| e.to_string())?;
    }
    root.present().map_err(|e| e.to_string())
}

/// Draw a row of heat maps with one shared colour scale to `<stem>.png` and `<stem>.svg`.
pub fn heatmaps(
    stem: &Path,
    title: &str,
    scale_label: &str,
    panels: &[Panel],
) -> Result<(), crate::io::IoError> {
    let size = (450 * panels.len().max(1) as u32, 500);
    render(
        stem,
        size,
        |a| draw_panels(a, title, scale_label, panels),
        |a| draw_panels(a, title, scale_label, panels),
    )
}
