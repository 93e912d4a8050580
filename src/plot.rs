//! SVG plots of probabilities over time (the book's Figs. 9.18–9.22).
//!
//! A [`PlotSpec`] is a title, axis labels and a list of [`Series`]; each
//! series has a [`SeriesKind`] that fixes its colour (Success green, Failure
//! red, Running blue, the same in every overlay) and a [`Style`] that tells
//! overlays apart (solid, dashed, dotted, dash-dot lines, or `x` markers for
//! Monte Carlo estimates). [`render_svg`] returns the whole SVG document.
//!
//! The y axis is fixed to `[0, 1]`, the x axis runs from 0 to the largest
//! time. The legend lists every series; it is placed in the corner of the
//! plot where it covers the least data, or to the right of the plot if every
//! corner would hide some.
//!
//! ```
//! use btrel::plot::{render_svg, PlotSpec, Series, SeriesKind, Style};
//! let series = vec![Series {
//!     label: "success".into(),
//!     kind: SeriesKind::Success,
//!     style: Style::Solid,
//!     points: vec![(0.0, 0.0), (1.0, 0.6), (2.0, 0.8)],
//! }];
//! let svg = render_svg(&PlotSpec::new("example", series)).unwrap();
//! assert!(svg.starts_with("<svg") && svg.contains("example"));
//! ```

use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};

/// Which probability a series shows; fixes its colour.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum SeriesKind {
    /// P(returned Success by t): green.
    Success,
    /// P(returned Failure by t): red.
    Failure,
    /// P(still running at t): blue.
    Running,
}

impl SeriesKind {
    /// The three kinds, in legend order.
    pub const ALL: [SeriesKind; 3] = [
        SeriesKind::Success,
        SeriesKind::Failure,
        SeriesKind::Running,
    ];

    /// The colour as `(r, g, b)`.
    pub fn rgb(self) -> (u8, u8, u8) {
        match self {
            SeriesKind::Success => (0x2C, 0xA0, 0x2C),
            SeriesKind::Failure => (0xD6, 0x27, 0x28),
            SeriesKind::Running => (0x1F, 0x77, 0xB4),
        }
    }

    /// The colour as SVG writes it, e.g. `#2CA02C`.
    pub fn hex(self) -> String {
        let (r, g, b) = self.rgb();
        format!("#{r:02X}{g:02X}{b:02X}")
    }

    /// `success`, `failure` or `running`.
    pub fn name(self) -> &'static str {
        match self {
            SeriesKind::Success => "success",
            SeriesKind::Failure => "failure",
            SeriesKind::Running => "running",
        }
    }

    fn color(self) -> RGBColor {
        let (r, g, b) = self.rgb();
        RGBColor(r, g, b)
    }
}

/// How a series is drawn.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Style {
    /// A solid line.
    Solid,
    /// A dashed line.
    Dashed,
    /// A dotted line.
    Dotted,
    /// A dash-dot line.
    DashDot,
    /// An `x` marker at each point, no line (Monte Carlo estimates).
    Markers,
}

impl Style {
    /// Line style of the `i`-th overlay: solid, dashed, dotted, dash-dot,
    /// then again.
    pub fn overlay(i: usize) -> Style {
        [Style::Solid, Style::Dashed, Style::Dotted, Style::DashDot][i % 4]
    }

    /// Dash pattern of a line style in output pixels, as in SVG
    /// `stroke-dasharray` (`None` for solid or markers).
    pub fn dasharray(self) -> Option<&'static str> {
        match self {
            Style::Dashed => Some("10 6"),
            Style::Dotted => Some("2 5"),
            Style::DashDot => Some("12 5 2 5"),
            Style::Solid | Style::Markers => None,
        }
    }

    /// plotters' SVG backend cannot dash a polyline: dashed styles are drawn
    /// with this (otherwise unused) opacity, and the attribute is rewritten to
    /// a `stroke-dasharray` afterwards, so each line stays one `<polyline>`.
    fn opacity_tag(self) -> Option<&'static str> {
        match self {
            Style::Dashed => Some("0.998"),
            Style::Dotted => Some("0.997"),
            Style::DashDot => Some("0.996"),
            Style::Solid | Style::Markers => None,
        }
    }

    fn alpha(self) -> f64 {
        self.opacity_tag()
            .map_or(1.0, |t| t.parse().expect("opacity tag is a number"))
    }
}

/// One curve (or set of markers) of a plot.
#[derive(Debug, Clone, PartialEq)]
pub struct Series {
    /// Legend text.
    pub label: String,
    /// Which probability: fixes the colour.
    pub kind: SeriesKind,
    /// Line style or markers.
    pub style: Style,
    /// `(t, probability)`, in the order to draw them (increasing t for a
    /// line). Points with a NaN or infinite coordinate are skipped.
    pub points: Vec<(f64, f64)>,
}

/// What to plot.
#[derive(Debug, Clone, PartialEq)]
pub struct PlotSpec {
    /// Title above the plot.
    pub title: String,
    /// x axis label, e.g. `time t (s)`.
    pub x_label: String,
    /// y axis label, e.g. `probability`.
    pub y_label: String,
    /// The series, drawn in this order and listed in this order in the legend.
    pub series: Vec<Series>,
    /// Width of the image in pixels (at least [`MIN_WIDTH`]).
    pub width: u32,
    /// Height of the image in pixels (at least [`MIN_HEIGHT`]).
    pub height: u32,
}

/// Default image width in pixels.
pub const DEFAULT_WIDTH: u32 = 960;
/// Default image height in pixels.
pub const DEFAULT_HEIGHT: u32 = 600;
/// Smallest accepted width.
pub const MIN_WIDTH: u32 = 400;
/// Smallest accepted height.
pub const MIN_HEIGHT: u32 = 300;

impl PlotSpec {
    /// A plot with axis labels `time t (s)` and `probability`, 960 × 600.
    pub fn new(title: impl Into<String>, series: Vec<Series>) -> PlotSpec {
        PlotSpec {
            title: title.into(),
            x_label: "time t (s)".into(),
            y_label: "probability".into(),
            series,
            width: DEFAULT_WIDTH,
            height: DEFAULT_HEIGHT,
        }
    }
}

/// Why a plot cannot be drawn.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum PlotError {
    /// The spec has no series.
    #[error("nothing to plot: no series given")]
    NoSeries,
    /// The image is too small to hold the axes and labels.
    #[error("a plot of {width}x{height} pixels is too small: at least {MIN_WIDTH}x{MIN_HEIGHT}")]
    TooSmall {
        /// Width asked.
        width: u32,
        /// Height asked.
        height: u32,
    },
    /// plotters failed.
    #[error("cannot draw the plot: {0}")]
    Draw(String),
}

/// The three series (success, failure, running) of an exact curve, labelled
/// `"{label_prefix}: success"` etc. (just `success` with an empty prefix).
pub fn curve_series(
    label_prefix: &str,
    points: &[crate::curve::CurvePoint],
    style: Style,
) -> Vec<Series> {
    SeriesKind::ALL
        .iter()
        .map(|&kind| Series {
            label: label(label_prefix, kind),
            kind,
            style,
            points: points
                .iter()
                .map(|p| {
                    let y = match kind {
                        SeriesKind::Success => p.success,
                        SeriesKind::Failure => p.failure,
                        SeriesKind::Running => p.running,
                    };
                    (p.t, y)
                })
                .collect(),
        })
        .collect()
}

/// The three series of a Monte Carlo curve (the estimates' means), drawn as
/// `x` markers like the book's figures.
pub fn mc_series(label_prefix: &str, points: &[crate::sim::CurvePoint]) -> Vec<Series> {
    SeriesKind::ALL
        .iter()
        .map(|&kind| Series {
            label: label(label_prefix, kind),
            kind,
            style: Style::Markers,
            points: points
                .iter()
                .map(|p| {
                    let e = match kind {
                        SeriesKind::Success => p.success,
                        SeriesKind::Failure => p.failure,
                        SeriesKind::Running => p.running,
                    };
                    (p.t, e.mean)
                })
                .collect(),
        })
        .collect()
}

fn label(prefix: &str, kind: SeriesKind) -> String {
    if prefix.is_empty() {
        kind.name().to_string()
    } else {
        format!("{prefix}: {}", kind.name())
    }
}

// Layout. plotters' coordinates are whole pixels, so the image is drawn at
// `S` times its size (smooth curves, half-pixel strokes) and the `<svg>`
// element is given the requested size with the larger viewBox. Constants are
// in output pixels; `S *` converts.
const S: i32 = 2;
// plotters' SVG backend writes `font-size` = size / 1.24.
const FONT_SCALE: f64 = 1.24;
const TITLE_PX: f64 = 22.0;
const AXIS_LABEL_PX: f64 = 17.0;
const TICK_PX: f64 = 15.0;
const LEGEND_PX: f64 = 15.0;
const LEGEND_ROW: i32 = 23;
const LEGEND_PAD: i32 = 10;
const LEGEND_SAMPLE: i32 = 40;
const LEGEND_GAP: i32 = 8;
const LEGEND_COL_GAP: i32 = 24;
const LEGEND_INSET: i32 = 12;
const MARGIN: i32 = 14;
const MARGIN_RIGHT: i32 = 34;
const X_LABEL_AREA: i32 = 62;
const Y_LABEL_AREA: i32 = 78;
const MARKER_HALF: i32 = 4;
/// Upper bound on the width of one character, as a fraction of the font size
/// (DejaVu Sans / Arial average under this).
const CHAR_EM: f64 = 0.58;

fn font(px: f64) -> FontDesc<'static> {
    ("sans-serif", px * S as f64 * FONT_SCALE).into_font()
}

fn text_width(text: &str, px: f64) -> i32 {
    (text.chars().count() as f64 * CHAR_EM * px).ceil() as i32
}

fn err(e: impl std::fmt::Display) -> PlotError {
    PlotError::Draw(e.to_string())
}

/// The whole SVG document of the plot.
///
/// The legend goes in the corner of the plot where it hides no data; if every
/// corner would hide some, to the right of the plot; if it is too wide for
/// that, in the least crowded corner; and if it does not fit in the plot at
/// all (many or very long labels), in columns below the plot, the image
/// growing taller to hold it.
///
/// Errors: no series, an image smaller than [`MIN_WIDTH`] × [`MIN_HEIGHT`].
/// Empty series, single points and NaN values are fine (NaN points are
/// skipped; a line of one point is drawn as a dot).
pub fn render_svg(spec: &PlotSpec) -> Result<String, PlotError> {
    if spec.series.is_empty() {
        return Err(PlotError::NoSeries);
    }
    if spec.width < MIN_WIDTH || spec.height < MIN_HEIGHT {
        return Err(PlotError::TooSmall {
            width: spec.width,
            height: spec.height,
        });
    }
    let series: Vec<Vec<(f64, f64)>> = spec
        .series
        .iter()
        .map(|s| {
            s.points
                .iter()
                .filter(|(x, y)| x.is_finite() && y.is_finite())
                .map(|&(x, y)| (x, y.clamp(0.0, 1.0)))
                .collect()
        })
        .collect();
    let column = Legend::columns(spec, 1);
    let first = draw(spec, &series, Placement::Inside)?;
    let (plot_w, plot_h) = first.plot;
    let fits_inside =
        column.w + 2 * S * LEGEND_INSET <= plot_w && column.h + 2 * S * LEGEND_INSET <= plot_h;
    let svg = if fits_inside && first.hits == 0 {
        first.svg
    } else if column.w + 2 * S * LEGEND_INSET <= S * spec.width as i32 * 2 / 5 && column.h <= plot_h
    {
        draw(spec, &series, Placement::Right)?.svg
    } else if fits_inside {
        first.svg
    } else {
        draw(spec, &series, Placement::Below)?.svg
    };
    Ok(finish(svg))
}

/// Gives the `<svg>` element its output size (plotters wrote the `S` times
/// larger one, which stays as the viewBox) and rewrites the opacity tags of
/// dashed lines into `stroke-dasharray`.
fn finish(mut svg: String) -> String {
    if let Some(rest) = svg.strip_prefix("<svg width=\"") {
        let parse = |s: &str| -> Option<(i32, usize)> {
            let end = s.find('"')?;
            Some((s[..end].parse().ok()?, end))
        };
        if let Some((w, wend)) = parse(rest) {
            let after_w = &rest[wend + 1..];
            if let Some(h_rest) = after_w.strip_prefix(" height=\"") {
                if let Some((h, hend)) = parse(h_rest) {
                    let tail = h_rest[hend + 1..].to_string();
                    svg = format!("<svg width=\"{}\" height=\"{}\"{tail}", w / S, h / S);
                }
            }
        }
    }
    for style in [Style::Dashed, Style::Dotted, Style::DashDot] {
        let tag = format!("opacity=\"{}\"", style.opacity_tag().expect("dashed"));
        let dashes: Vec<String> = style
            .dasharray()
            .expect("dashed")
            .split(' ')
            .map(|d| (d.parse::<i32>().expect("dash length") * S).to_string())
            .collect();
        let with = format!("opacity=\"1\" stroke-dasharray=\"{}\"", dashes.join(" "));
        svg = svg.replace(&tag, &with);
    }
    svg
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Placement {
    /// In the plot, in the corner hiding the least data.
    Inside,
    /// To the right of the plot.
    Right,
    /// Below the plot, in columns; the image grows.
    Below,
}

/// Legend box geometry, in backend (×`S`) pixels.
struct Legend {
    cols: usize,
    /// Width of one column (sample, gap, text, column gap).
    col_w: i32,
    w: i32,
    h: i32,
}

impl Legend {
    fn columns(spec: &PlotSpec, cols: usize) -> Legend {
        let text_w = spec
            .series
            .iter()
            .map(|s| text_width(&s.label, LEGEND_PX))
            .max()
            .unwrap_or(0);
        let n = spec.series.len().max(1);
        let cols = cols.clamp(1, n);
        let rows = n.div_ceil(cols);
        let col_w = S * (LEGEND_SAMPLE + LEGEND_GAP + text_w + LEGEND_COL_GAP);
        Legend {
            cols,
            col_w,
            w: S * 2 * LEGEND_PAD + col_w * cols as i32 - S * LEGEND_COL_GAP,
            h: S * (2 * LEGEND_PAD + LEGEND_ROW * rows as i32 - (LEGEND_ROW - 16)),
        }
    }

    /// As many columns as fit in `width` backend pixels.
    fn fitting(spec: &PlotSpec, width: i32) -> Legend {
        let one = Legend::columns(spec, 1);
        let cols = ((width - one.w) / one.col_w).max(0) as usize + 1;
        Legend::columns(spec, cols)
    }
}

fn x_range(series: &[Vec<(f64, f64)>]) -> (f64, f64) {
    let xs = || series.iter().flatten().map(|p| p.0);
    let lo = xs().fold(0.0_f64, f64::min);
    let hi = xs().fold(lo, f64::max);
    if hi > lo {
        (lo, hi)
    } else {
        (lo, lo + 1.0)
    }
}

/// Tick label with as many decimals as ticks `span / 10` apart need.
fn tick_label(v: f64, span: f64) -> String {
    let step = span / 10.0;
    let decimals = ((-step.log10()).ceil().max(0.0) as usize + 1).min(12);
    let s = format!("{v:.decimals$}");
    let s = if s.contains('.') {
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    } else {
        s
    };
    if s == "-0" {
        "0".into()
    } else {
        s
    }
}

/// Probability tick: one decimal (`0.0`, `0.5`), two when needed (`0.25`).
fn prob_label(v: f64) -> String {
    if ((v * 10.0).round() - v * 10.0).abs() < 1e-9 {
        format!("{v:.1}")
    } else {
        format!("{v:.2}")
    }
}

fn style_of(s: &Series) -> ShapeStyle {
    ShapeStyle {
        color: s.kind.color().mix(s.style.alpha()),
        filled: false,
        // 1.5 px crosses, 2 px lines
        stroke_width: if s.style == Style::Markers { 3 } else { 4 },
    }
}

struct Drawn {
    svg: String,
    /// Data samples hidden by the legend (0 unless `Inside`).
    hits: usize,
    /// Plot area size, backend pixels.
    plot: (i32, i32),
}

fn draw(
    spec: &PlotSpec,
    series: &[Vec<(f64, f64)>],
    placement: Placement,
) -> Result<Drawn, PlotError> {
    let (x0, x1) = x_range(series);
    let span = x1 - x0;
    let (w, h) = (S * spec.width as i32, S * spec.height as i32);
    let legend = match placement {
        Placement::Below => Legend::fitting(spec, w - 2 * S * MARGIN),
        _ => Legend::columns(spec, 1),
    };
    let total_h = match placement {
        Placement::Below => h + legend.h + S * MARGIN,
        _ => h,
    };
    let mut buf = String::new();
    let drawn;
    {
        let root =
            SVGBackend::with_string(&mut buf, (w as u32, total_h as u32)).into_drawing_area();
        root.fill(&WHITE).map_err(err)?;
        let (area, _) = root.split_vertically(h);
        let right = match placement {
            Placement::Right => S * MARGIN_RIGHT + legend.w,
            _ => S * MARGIN_RIGHT,
        };
        let mut chart = ChartBuilder::on(&area)
            .caption(&spec.title, font(TITLE_PX).style(FontStyle::Bold))
            .margin(S * MARGIN)
            .margin_right(right)
            .x_label_area_size(S * X_LABEL_AREA)
            .y_label_area_size(S * Y_LABEL_AREA)
            .build_cartesian_2d(x0..x1, 0.0..1.0)
            .map_err(err)?;
        let (plot_w, plot_h) = chart.plotting_area().dim_in_pixel();
        let (plot_w, plot_h) = (plot_w as i32, plot_h as i32);
        // as many ticks as fit without crowding
        let widest = [x0, x1, (x0 + x1) / 2.0]
            .iter()
            .map(|&v| text_width(&tick_label(v, span), TICK_PX))
            .max()
            .unwrap_or(0);
        let x_ticks = (plot_w / (S * (widest + 30))).clamp(2, 11) as usize;
        let y_ticks = (plot_h / (S * 24)).clamp(2, 11) as usize;
        let x_fmt = |v: &f64| tick_label(*v, span);
        let y_fmt = |v: &f64| prob_label(*v);
        chart
            .configure_mesh()
            .x_desc(&spec.x_label)
            .y_desc(&spec.y_label)
            .x_labels(x_ticks)
            .y_labels(y_ticks)
            .max_light_lines(1)
            .x_label_formatter(&x_fmt)
            .y_label_formatter(&y_fmt)
            .label_style(font(TICK_PX).color(&BLACK))
            .axis_desc_style(font(AXIS_LABEL_PX).color(&BLACK))
            .bold_line_style(RGBColor(0xDD, 0xDD, 0xDD).stroke_width(2))
            .light_line_style(RGBColor(0xF2, 0xF2, 0xF2).stroke_width(2))
            .axis_style(BLACK.stroke_width(2))
            .set_all_tick_mark_size(S * 5)
            .draw()
            .map_err(err)?;

        for (s, pts) in spec.series.iter().zip(series) {
            let style = style_of(s);
            if s.style == Style::Markers {
                chart
                    .draw_series(pts.iter().map(|&p| Cross::new(p, S * MARKER_HALF, style)))
                    .map_err(err)?;
            } else if pts.len() == 1 {
                chart
                    .draw_series(std::iter::once(Circle::new(
                        pts[0],
                        (S * 3) as u32,
                        style.filled(),
                    )))
                    .map_err(err)?;
            } else if pts.len() > 1 {
                chart
                    .draw_series(LineSeries::new(pts.iter().copied(), style))
                    .map_err(err)?;
            }
        }

        let (px, py) = chart.plotting_area().get_pixel_range();
        let mut hits = 0;
        let (lx, ly) = match placement {
            Placement::Right => (px.end + S * LEGEND_INSET, py.start),
            Placement::Below => ((w - legend.w) / 2, h),
            Placement::Inside => {
                let pixels: Vec<Vec<(i32, i32)>> = series
                    .iter()
                    .map(|pts| pts.iter().map(|p| chart.backend_coord(p)).collect())
                    .collect();
                let (pos, n) = place_legend(spec, &pixels, (&px, &py), &legend);
                hits = n;
                pos
            }
        };
        draw_legend(&root, spec, (lx, ly), &legend)?;
        root.present().map_err(err)?;
        drawn = (hits, (plot_w, plot_h));
    }
    Ok(Drawn {
        svg: buf,
        hits: drawn.0,
        plot: drawn.1,
    })
}

/// The candidate legend position covering the fewest data samples, with that
/// count (0 when it hides nothing). Preference on ties: upper right, upper
/// left, lower right, lower left, then the middles of the sides.
fn place_legend(
    spec: &PlotSpec,
    pixels: &[Vec<(i32, i32)>],
    (px, py): (&std::ops::Range<i32>, &std::ops::Range<i32>),
    legend: &Legend,
) -> ((i32, i32), usize) {
    let inset = S * LEGEND_INSET;
    let left = px.start + inset;
    let right = px.end - inset - legend.w;
    let mid_x = (px.start + px.end - legend.w) / 2;
    let top = py.start + inset;
    let bottom = py.end - inset - legend.h;
    let mid_y = (py.start + py.end - legend.h) / 2;
    let candidates = [
        (right, top),
        (left, top),
        (right, bottom),
        (left, bottom),
        (right, mid_y),
        (left, mid_y),
        (mid_x, top),
        (mid_x, bottom),
    ];
    // sample lines every few pixels so a line crossing the box counts
    let mut samples = Vec::new();
    for (s, pts) in spec.series.iter().zip(pixels) {
        samples.extend_from_slice(pts);
        if s.style != Style::Markers {
            for w in pts.windows(2) {
                let (a, b) = (w[0], w[1]);
                let len = ((b.0 - a.0) as f64).hypot((b.1 - a.1) as f64);
                let n = (len / (3 * S) as f64).ceil() as i32;
                for k in 1..n {
                    let f = k as f64 / n as f64;
                    samples.push((
                        a.0 + ((b.0 - a.0) as f64 * f).round() as i32,
                        a.1 + ((b.1 - a.1) as f64 * f).round() as i32,
                    ));
                }
            }
        }
    }
    let pad = S * (MARKER_HALF + 2);
    candidates
        .iter()
        .map(|&(x, y)| {
            let hits = samples
                .iter()
                .filter(|&&(sx, sy)| {
                    sx >= x - pad
                        && sx <= x + legend.w + pad
                        && sy >= y - pad
                        && sy <= y + legend.h + pad
                })
                .count();
            ((x, y), hits)
        })
        .enumerate()
        .min_by_key(|&(i, (_, hits))| (hits, i))
        .map(|(_, c)| c)
        .expect("candidates")
}

fn draw_legend(
    root: &DrawingArea<SVGBackend, Shift>,
    spec: &PlotSpec,
    (x, y): (i32, i32),
    legend: &Legend,
) -> Result<(), PlotError> {
    let corner = (x + legend.w, y + legend.h);
    root.draw(&Rectangle::new([(x, y), corner], WHITE.mix(0.9).filled()))
        .map_err(err)?;
    root.draw(&Rectangle::new(
        [(x, y), corner],
        RGBColor(0x88, 0x88, 0x88).stroke_width(2),
    ))
    .map_err(err)?;
    let text = font(LEGEND_PX)
        .color(&BLACK)
        .pos(Pos::new(HPos::Left, VPos::Center));
    for (i, s) in spec.series.iter().enumerate() {
        let (row, col) = (i / legend.cols, i % legend.cols);
        let cy = y + S * (LEGEND_PAD + 8 + LEGEND_ROW * row as i32);
        let sx = x + S * LEGEND_PAD + legend.col_w * col as i32;
        let style = style_of(s);
        if s.style == Style::Markers {
            for k in [1, 3] {
                root.draw(&Cross::new(
                    (sx + S * LEGEND_SAMPLE * k / 4, cy),
                    S * MARKER_HALF,
                    style,
                ))
                .map_err(err)?;
            }
        } else {
            root.draw(&PathElement::new(
                vec![(sx, cy), (sx + S * LEGEND_SAMPLE, cy)],
                style,
            ))
            .map_err(err)?;
        }
        root.draw(&Text::new(
            s.label.clone(),
            (sx + S * (LEGEND_SAMPLE + LEGEND_GAP), cy),
            text.clone(),
        ))
        .map_err(err)?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tick_labels() {
        assert_eq!(tick_label(200.0, 1000.0), "200");
        assert_eq!(tick_label(0.5, 1.0), "0.5");
        assert_eq!(tick_label(0.0, 1.0), "0");
        assert_eq!(tick_label(2.5, 10.0), "2.5");
        assert_eq!(tick_label(0.002, 0.01), "0.002");
        assert_eq!(prob_label(0.30000000000000004), "0.3");
        assert_eq!(prob_label(1.0), "1.0");
        assert_eq!(prob_label(0.25), "0.25");
    }

    #[test]
    fn x_range_edge_cases() {
        assert_eq!(x_range(&[]), (0.0, 1.0));
        assert_eq!(x_range(&[vec![(0.0, 0.5)]]), (0.0, 1.0));
        assert_eq!(x_range(&[vec![(0.0, 0.5), (5.0, 1.0)]]), (0.0, 5.0));
    }
}
