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
    dashed: &[(Series, usize)],
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
        .y_label_area_size(85)
        .build_cartesian_2d(x0..x1, y0..y1)
        .map_err(|e| e.to_string())?;
    c.configure_mesh()
        .x_desc(chart.x_label)
        .y_desc(chart.y_label)
        .x_label_formatter(&axis_number)
        .y_label_formatter(&axis_number)
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
        // Sparse series (a scan's few runs) show where the samples are, not only the line
        // through them (a single sample only as its marker); a two-point series is a
        // reference line.
        if s.points.len() == 1 || (3..=SPARSE_POINTS).contains(&s.points.len()) {
            c.draw_series(
                s.points
                    .iter()
                    .map(|&(x, y)| Circle::new((x, y), 5, color.filled())),
            )
            .map_err(|e| e.to_string())?;
        }
    }
    draw_dashed(&mut c, dashed, |p| {
        p.1 >= y0 && p.1 <= y1 && p.0 >= x0 && p.0 <= x1
    })?;
    c.configure_series_labels()
        .position(legend_corner(&chart.series, (x0, x1), (y0, y1), |v| v))
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .label_font(("sans-serif", 15))
        .draw()
        .map_err(|e| e.to_string())?;
    root.present().map_err(|e| e.to_string())
}

/// A linear axis's tick label as plotters prints it, without the sign of a zero (a tick at
/// -1e-17 read "-0.0").
fn axis_number(v: &f64) -> String {
    use plotters::coord::ranged1d::ValueFormatter;
    use plotters::coord::types::RangedCoordf64;
    let s = RangedCoordf64::format(v);
    match s.strip_prefix('-') {
        Some(rest) if rest.chars().all(|c| c == '0' || c == '.') => rest.to_string(),
        _ => s,
    }
}

/// The corner whose box (45% of the width, 12% of the height per legend entry, at least 20%)
/// holds the fewest points, so the legend covers as little of the curves as it can. `map`
/// takes data to axis coordinates (identity, or log10 on log axes).
fn legend_corner(
    series: &[Series],
    (x0, x1): (f64, f64),
    (y0, y1): (f64, f64),
    map: impl Fn(f64) -> f64,
) -> SeriesLabelPosition {
    let (x0, x1, y0, y1) = (map(x0), map(x1), map(y0), map(y1));
    let h = (0.12 * series.len() as f64).clamp(0.2, 0.6);
    let corners = [
        (SeriesLabelPosition::UpperRight, true, true),
        (SeriesLabelPosition::UpperLeft, false, true),
        (SeriesLabelPosition::LowerRight, true, false),
        (SeriesLabelPosition::LowerLeft, false, false),
    ];
    let count = |right: bool, upper: bool| {
        series
            .iter()
            .flat_map(|s| s.points.iter())
            .filter(|(x, y)| {
                let fx = (map(*x) - x0) / (x1 - x0);
                let fy = (map(*y) - y0) / (y1 - y0);
                let inx = if right { fx >= 0.55 } else { fx <= 0.45 };
                let iny = if upper { fy >= 1.0 - h } else { fy <= h };
                inx && iny
            })
            .count()
    };
    corners
        .into_iter()
        .min_by_key(|(_, right, upper)| count(*right, *upper))
        .map(|c| c.0)
        .unwrap_or(SeriesLabelPosition::UpperRight)
}

/// Series with at most this many points are drawn with a marker at each.
const SPARSE_POINTS: usize = 12;

/// The font of every chart's text, carried by the binary (DejaVu Sans; its licence is
/// `experiments/assets/DejaVuSans-LICENSE.txt`), so drawing needs no system font library.
static FONT: &[u8] = include_bytes!("../../assets/DejaVuSans.ttf");

/// Register [`FONT`] as "sans-serif" once.
fn register_font() {
    static ONCE: std::sync::Once = std::sync::Once::new();
    ONCE.call_once(|| {
        // The font is valid OpenType (a test draws with it); a failure would only leave text
        // out of the PNG charts.
        let _ = plotters::style::register_font("sans-serif", FontStyle::Normal, FONT);
    });
}

/// Render one figure twice, to `<stem>.png` and `<stem>.svg`, each written atomically (the PNG
/// through a hidden temporary file, since the bitmap backend writes to a path).
fn render(
    stem: &Path,
    size: (u32, u32),
    png: impl FnOnce(DrawingArea<BitMapBackend<'_>, plotters::coord::Shift>) -> Result<(), String>,
    svg: impl FnOnce(DrawingArea<SVGBackend<'_>, plotters::coord::Shift>) -> Result<(), String>,
) -> Result<(), crate::io::IoError> {
    register_font();
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
    render(
        stem,
        (900, 600),
        |a| draw(a, chart, &[]),
        |a| draw(a, chart, &[]),
    )
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
        .titled(title, ("sans-serif", 18))
        .map_err(|e| e.to_string())?;
    // Panels on the left, the shared colour bar (with its scale and unit) on the right.
    let width = root.dim_in_pixel().0;
    let (main, bar) = root.split_horizontally(width.saturating_sub(150));
    // The scale and its unit on the bar's right, clear of the bar.
    let mut cb = ChartBuilder::on(&bar)
        .margin(10)
        .margin_top(40)
        .margin_bottom(45)
        .right_y_label_area_size(95)
        .build_cartesian_2d(0.0..1.0, lo..(lo + span))
        .map_err(|e| e.to_string())?;
    cb.configure_mesh()
        .disable_mesh()
        .disable_x_axis()
        .y_desc(scale_label)
        .y_labels(6)
        // A space between the tick mark and the number, which would otherwise read as a sign.
        .y_label_formatter(&|v| format!("  {v:.1e}"))
        .label_style(("sans-serif", 12))
        .axis_desc_style(("sans-serif", 14))
        .draw()
        .map_err(|e| e.to_string())?;
    const STEPS: usize = 100;
    cb.draw_series((0..STEPS).map(|i| {
        let (a, b) = (i as f64 / STEPS as f64, (i + 1) as f64 / STEPS as f64);
        Rectangle::new(
            [(0.0, lo + a * span), (1.0, lo + b * span)],
            colormap((a + b) / 2.0).filled(),
        )
    }))
    .map_err(|e| e.to_string())?;
    let areas = main.split_evenly((1, panels.len().max(1)));
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
    let size = (450 * panels.len().max(1) as u32 + 130, 500);
    render(
        stem,
        size,
        |a| draw_panels(a, title, scale_label, panels),
        |a| draw_panels(a, title, scale_label, panels),
    )
}

/// Tick text on a log axis: only 1, 2 and 5 times a power of ten are labelled (others get
/// an empty string, so labels never crowd), in the shortest plain form.
fn log_tick(v: &f64) -> String {
    if v.is_nan() || *v <= 0.0 {
        return String::new();
    }
    let e = v.log10().floor();
    let m = v / 10f64.powf(e);
    if ![1.0, 2.0, 5.0].iter().any(|k| (m - k).abs() < 1e-6 * k) {
        return String::new();
    }
    let r = m.round() * 10f64.powf(e);
    if (1e-3..1e5).contains(&r) {
        format!("{}", (r * 1e6).round() / 1e6)
    } else {
        format!("{r:.0e}")
    }
}

/// The ticks of a log axis over `lo..hi`: every 1-2-5 value (1, 2 or 5 times a power of ten)
/// inside it where it spans at most three decades, else the powers of ten (with the 1-2-5
/// values of the decade around the data where fewer than two powers fall inside).
fn ticks_125(lo: f64, hi: f64) -> Vec<f64> {
    if !(lo > 0.0 && hi > lo && lo.is_finite() && hi.is_finite()) {
        return Vec::new();
    }
    let (e0, e1) = (lo.log10().floor() as i32, hi.log10().ceil() as i32);
    let all = |mults: &[f64]| -> Vec<f64> {
        (e0..=e1)
            .flat_map(|e| mults.iter().map(move |m| m * 10f64.powi(e)))
            .filter(|v| *v >= lo * (1.0 - 1e-12) && *v <= hi * (1.0 + 1e-12))
            .collect()
    };
    let decades = all(&[1.0]);
    if hi / lo > 1e3 && decades.len() >= 2 {
        decades
    } else {
        all(&[1.0, 2.0, 5.0])
    }
}

fn draw_log<DB: DrawingBackend>(
    root: DrawingArea<DB, plotters::coord::Shift>,
    title: &str,
    x_label: &str,
    y_label: &str,
    series: &[Series],
    labels: &[(f64, f64, String)],
) -> Result<(), String>
where
    DB::ErrorType: 'static,
{
    root.fill(&WHITE).map_err(|e| e.to_string())?;
    // Room around the points: half a decade where labels sit right of the points, less
    // without labels (every series then gets markers).
    let room = if labels.is_empty() { 1.3 } else { 3.0 };
    let positive = |pick: fn(&(f64, f64)) -> f64| {
        let vals: Vec<f64> = series
            .iter()
            .flat_map(|s| s.points.iter().map(pick))
            .filter(|v| v.is_finite() && *v > 0.0)
            .collect();
        let lo = vals.iter().copied().fold(f64::INFINITY, f64::min);
        let hi = vals.iter().copied().fold(0.0, f64::max);
        if lo.is_finite() && hi > 0.0 {
            (lo / room, hi * room)
        } else {
            (0.1, 10.0)
        }
    };
    let (x0, x1) = positive(|p| p.0);
    let (y0, y1) = positive(|p| p.1);
    let mut c = ChartBuilder::on(&root)
        .caption(title, ("sans-serif", 22))
        .margin(15)
        .x_label_area_size(45)
        .y_label_area_size(80)
        .build_cartesian_2d(
            (x0..x1).log_scale().with_key_points(ticks_125(x0, x1)),
            (y0..y1).log_scale().with_key_points(ticks_125(y0, y1)),
        )
        .map_err(|e| e.to_string())?;
    c.configure_mesh()
        .x_desc(x_label)
        .y_desc(y_label)
        .label_style(("sans-serif", 15))
        .axis_desc_style(("sans-serif", 17))
        .x_labels(12)
        .y_label_formatter(&|v| format!("{v:.0e}"))
        .x_label_formatter(&log_tick)
        .draw()
        .map_err(|e| e.to_string())?;
    for (i, s) in series.iter().enumerate() {
        let color = COLORS[i % COLORS.len()];
        c.draw_series(LineSeries::new(
            s.points.iter().copied(),
            color.stroke_width(2),
        ))
        .map_err(|e| e.to_string())?
        .label(s.label.clone())
        .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], color.stroke_width(2)));
        // Markers where the points are few enough to tell apart (a measured curve of many
        // samples stays a line).
        if (i == 0 || labels.is_empty()) && s.points.len() <= MAX_MARKED_POINTS {
            let r = if labels.is_empty() { 3 } else { 5 };
            c.draw_series(
                s.points
                    .iter()
                    .map(|&(x, y)| Circle::new((x, y), r, color.filled())),
            )
            .map_err(|e| e.to_string())?;
        }
    }
    c.draw_series(labels.iter().map(|(x, y, t)| {
        Text::new(
            t.clone(),
            (*x * 1.08, *y * 1.1),
            ("sans-serif", 15).into_font(),
        )
    }))
    .map_err(|e| e.to_string())?;
    c.configure_series_labels()
        .position(legend_corner(series, (x0, x1), (y0, y1), |v| {
            v.max(1e-300).log10()
        }))
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .label_font(("sans-serif", 15))
        .draw()
        .map_err(|e| e.to_string())?;
    root.present().map_err(|e| e.to_string())
}

/// A chart with a linear x axis and a logarithmic y axis: `series` as solid curves, `dashed`
/// as dashed reference lines (a theory's slope, a level), to `<stem>.png` and `<stem>.svg`.
pub fn semilog_chart(
    stem: &Path,
    chart: &Chart,
    dashed: &[(Series, usize)],
) -> Result<(), crate::io::IoError> {
    // Less than a decade and a half of data without reference lines reads better on a linear
    // axis.
    let ys: Vec<f64> = chart
        .series
        .iter()
        .flat_map(|s| s.points.iter().map(|p| p.1))
        .filter(|v| v.is_finite() && *v > 0.0)
        .collect();
    let lo = ys.iter().copied().fold(f64::INFINITY, f64::min);
    let hi = ys.iter().copied().fold(0.0, f64::max);
    // Exponential reference lines (a growth theory) read as lines only on a log axis.
    let wide = hi / lo >= 30.0 || !dashed.is_empty();
    if !wide {
        return render(
            stem,
            (900, 600),
            |a| draw(a, chart, dashed),
            |a| draw(a, chart, dashed),
        );
    }
    render(
        stem,
        (1000, 650),
        |a| draw_semilog(a, chart, dashed),
        |a| draw_semilog(a, chart, dashed),
    )
}

fn draw_semilog<DB: DrawingBackend>(
    root: DrawingArea<DB, plotters::coord::Shift>,
    chart: &Chart,
    dashed: &[(Series, usize)],
) -> Result<(), String>
where
    DB::ErrorType: 'static,
{
    root.fill(&WHITE).map_err(|e| e.to_string())?;
    let (x0, x1) = range(&chart.series, |p| p.0);
    let ys: Vec<f64> = chart
        .series
        .iter()
        .flat_map(|s| s.points.iter().map(|p| p.1))
        .filter(|v| v.is_finite() && *v > 0.0)
        .collect();
    let lo = ys.iter().copied().fold(f64::INFINITY, f64::min);
    let hi = ys.iter().copied().fold(0.0, f64::max);
    let (y0, y1) = if lo.is_finite() && hi > 0.0 {
        (lo / 2.0, hi * 2.0)
    } else {
        (0.1, 10.0)
    };
    let mut c = ChartBuilder::on(&root)
        .caption(chart.title, ("sans-serif", 22))
        .margin(15)
        .x_label_area_size(45)
        .y_label_area_size(85)
        // Ticks at the 1-2-5 values: plotters' own on a log axis crowd near the powers of ten.
        .build_cartesian_2d(
            x0..x1,
            (y0..y1).log_scale().with_key_points(ticks_125(y0, y1)),
        )
        .map_err(|e| e.to_string())?;
    c.configure_mesh()
        .x_desc(chart.x_label)
        .y_desc(chart.y_label)
        .label_style(("sans-serif", 15))
        .axis_desc_style(("sans-serif", 17))
        .x_label_formatter(&axis_number)
        .y_label_formatter(&|v| format!("{v:.0e}"))
        .draw()
        .map_err(|e| e.to_string())?;
    let clip = |p: &(f64, f64)| p.1 > 0.0 && p.1 >= y0 && p.1 <= y1 && p.0 >= x0 && p.0 <= x1;
    for (i, s) in chart.series.iter().enumerate() {
        let color = COLORS[i % COLORS.len()];
        c.draw_series(LineSeries::new(
            s.points.iter().copied().filter(|p| p.1 > 0.0),
            color.stroke_width(2),
        ))
        .map_err(|e| e.to_string())?
        .label(s.label.clone())
        .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], color.stroke_width(2)));
    }
    draw_dashed(&mut c, dashed, clip)?;
    c.configure_series_labels()
        .position(SeriesLabelPosition::LowerRight)
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .label_font(("sans-serif", 14))
        .draw()
        .map_err(|e| e.to_string())?;
    root.present().map_err(|e| e.to_string())
}

/// Series of more points than this are drawn as lines without markers in [`log_chart`].
const MAX_MARKED_POINTS: usize = 20;

/// A log-log chart of `series` (the first drawn with point markers, every one where `labels`
/// is empty; none on a series of more than `MAX_MARKED_POINTS` (20) points), each point of
/// `labels` annotated with its text, to `<stem>.png` and `<stem>.svg`.
pub fn log_chart(
    stem: &Path,
    title: &str,
    x_label: &str,
    y_label: &str,
    series: &[Series],
    labels: &[(f64, f64, String)],
) -> Result<(), crate::io::IoError> {
    render(
        stem,
        (900, 600),
        |a| draw_log(a, title, x_label, y_label, series, labels),
        |a| draw_log(a, title, x_label, y_label, series, labels),
    )
}

/// A map of categorical outcomes: cell `(column, row, category, text)` on a grid whose columns
/// and rows are labelled by `x_ticks` and `y_ticks`; `categories` gives each category's legend
/// name and colour (RGB).
#[derive(Clone, Debug)]
pub struct OutcomeMap<'a> {
    /// Title.
    pub title: &'a str,
    /// x-axis label with unit.
    pub x_label: &'a str,
    /// y-axis label with unit.
    pub y_label: &'a str,
    /// Column labels.
    pub x_ticks: Vec<String>,
    /// Row labels (bottom to top).
    pub y_ticks: Vec<String>,
    /// `(name, (r, g, b))` of each category.
    pub categories: Vec<(String, (u8, u8, u8))>,
    /// `(column, row, category index, text in the cell)`.
    pub cells: Vec<(usize, usize, usize, String)>,
}

fn draw_outcomes<DB: DrawingBackend>(
    root: DrawingArea<DB, plotters::coord::Shift>,
    map: &OutcomeMap,
) -> Result<(), String>
where
    DB::ErrorType: 'static,
{
    root.fill(&WHITE).map_err(|e| e.to_string())?;
    let (nx, ny) = (map.x_ticks.len().max(1), map.y_ticks.len().max(1));
    let (main, legend) = root.split_horizontally(root.dim_in_pixel().0 as i32 - 220);
    let xt = map.x_ticks.clone();
    let yt = map.y_ticks.clone();
    let mut c = ChartBuilder::on(&main)
        .caption(map.title, ("sans-serif", 20))
        .margin(15)
        .x_label_area_size(50)
        .y_label_area_size(85)
        .build_cartesian_2d(0.0..nx as f64, 0.0..ny as f64)
        .map_err(|e| e.to_string())?;
    c.configure_mesh()
        .disable_mesh()
        .x_labels(2 * nx + 1)
        .y_labels(2 * ny + 1)
        .x_label_formatter(&move |v| {
            let k = v - 0.5;
            if (k - k.round()).abs() < 1e-6 && k >= -1e-6 {
                xt.get(k.round() as usize).cloned().unwrap_or_default()
            } else {
                String::new()
            }
        })
        .y_label_formatter(&move |v| {
            let k = v - 0.5;
            if (k - k.round()).abs() < 1e-6 && k >= -1e-6 {
                yt.get(k.round() as usize).cloned().unwrap_or_default()
            } else {
                String::new()
            }
        })
        .x_desc(map.x_label)
        .y_desc(map.y_label)
        .label_style(("sans-serif", 15))
        .axis_desc_style(("sans-serif", 17))
        .draw()
        .map_err(|e| e.to_string())?;
    for (x, y, k, text) in &map.cells {
        let (r, g, b) = map
            .categories
            .get(*k)
            .map(|c| c.1)
            .unwrap_or((128, 128, 128));
        let (x, y) = (*x as f64, *y as f64);
        c.draw_series(std::iter::once(Rectangle::new(
            [(x + 0.03, y + 0.03), (x + 0.97, y + 0.97)],
            RGBColor(r, g, b).filled(),
        )))
        .map_err(|e| e.to_string())?;
        for (i, line) in text.lines().enumerate() {
            c.draw_series(std::iter::once(Text::new(
                line.to_string(),
                (x + 0.08, y + 0.85 - 0.16 * i as f64),
                ("sans-serif", 13).into_font(),
            )))
            .map_err(|e| e.to_string())?;
        }
    }
    for (i, (name, (r, g, b))) in map.categories.iter().enumerate() {
        let y = 80 + 30 * i as i32;
        legend
            .draw(&Rectangle::new(
                [(5, y), (25, y + 20)],
                RGBColor(*r, *g, *b).filled(),
            ))
            .map_err(|e| e.to_string())?;
        legend
            .draw(&Text::new(
                name.clone(),
                (32, y + 3),
                ("sans-serif", 15).into_font(),
            ))
            .map_err(|e| e.to_string())?;
    }
    root.present().map_err(|e| e.to_string())
}

/// Draw an outcome map to `<stem>.png` and `<stem>.svg`.
pub fn outcome_map(stem: &Path, map: &OutcomeMap) -> Result<(), crate::io::IoError> {
    let size = (
        (260 + 150 * map.x_ticks.len().max(1) as u32).max(800),
        (160 + 110 * map.y_ticks.len().max(1) as u32).max(450),
    );
    render(
        stem,
        size,
        |a| draw_outcomes(a, map),
        |a| draw_outcomes(a, map),
    )
}

/// Dashed lines on a chart, each in its data series' colour (`(series, index of the data
/// series)`); a second line of the same series dotted. Points outside `keep` are dropped.
fn draw_dashed<'a, DB, Y>(
    c: &mut ChartContext<'a, DB, Cartesian2d<plotters::coord::types::RangedCoordf64, Y>>,
    dashed: &[(Series, usize)],
    keep: impl Fn(&(f64, f64)) -> bool,
) -> Result<(), String>
where
    DB: DrawingBackend + 'a,
    DB::ErrorType: 'static,
    Y: Ranged<ValueType = f64>,
{
    for (k, (s, i)) in dashed.iter().enumerate() {
        let color = COLORS[i % COLORS.len()].mix(0.9);
        let repeat = dashed[..k].iter().any(|(_, j)| j == i);
        let (dash, gap) = if repeat { (3, 4) } else { (8, 5) };
        let pts: Vec<(f64, f64)> = s.points.iter().copied().filter(&keep).collect();
        c.draw_series(DashedLineSeries::new(pts, dash, gap, color.stroke_width(2)))
            .map_err(|e| e.to_string())?
            .label(s.label.clone())
            .legend(move |(x, y)| {
                // Offsets from the anchor: two dashes, or three dots.
                let seg =
                    |a: i32, b: i32| PathElement::new(vec![(a, 0), (b, 0)], color.stroke_width(2));
                let [s1, s2, s3] = if repeat {
                    [(0, 3), (7, 10), (14, 17)]
                } else {
                    [(0, 8), (13, 20), (20, 20)]
                };
                EmptyElement::at((x, y)) + seg(s1.0, s1.1) + seg(s2.0, s2.1) + seg(s3.0, s3.1)
            });
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::{axis_number, log_tick, ticks_125};

    #[test]
    fn linear_ticks_read_zero_without_a_sign() {
        assert_eq!(axis_number(&-1e-17), "0.0");
        assert_eq!(axis_number(&-0.0), "0.0");
        assert_eq!(axis_number(&-0.25), "-0.25");
        assert_eq!(axis_number(&0.5), "0.5");
    }

    #[test]
    fn log_axes_tick_at_one_two_five_values() {
        assert_eq!(
            ticks_125(14.4, 1110.0),
            [20.0, 50.0, 100.0, 200.0, 500.0, 1000.0]
        );
        assert_eq!(ticks_125(0.8, 8.2), [1.0, 2.0, 5.0]);
        assert_eq!(
            ticks_125(1e-9, 2.0),
            [1e-9, 1e-8, 1e-7, 1e-6, 1e-5, 1e-4, 1e-3, 1e-2, 0.1, 1.0]
        );
        assert!(ticks_125(0.0, 1.0).is_empty());
    }

    #[test]
    fn log_ticks_label_only_one_two_five() {
        let got: Vec<String> = [1.0, 2.0, 3.0, 5.0, 7.0, 10.0, 20.0, 0.05, 0.3, 2e-6, 5e5]
            .iter()
            .map(log_tick)
            .collect();
        assert_eq!(
            got,
            ["1", "2", "", "5", "", "10", "20", "0.05", "", "2e-6", "5e5"],
            "{got:?}"
        );
    }
}
