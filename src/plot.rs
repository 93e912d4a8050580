//! Plots of probabilities over time (the book's Figs. 9.18–9.22), as SVG or
//! PNG.
//!
//! A [`PlotSpec`] is a title, axis labels, a list of [`Series`] and optional
//! vertical markers (e.g. a deadline); each series has a [`SeriesKind`] that
//! fixes its colour (Success green, Failure red, Running blue, the same in
//! every overlay) and a [`Style`] that tells overlays apart (solid, dashed,
//! dotted, dash-dot lines, or markers — `x`, `+`, `o`, triangles, squares,
//! diamonds — for Monte Carlo estimates). [`render_svg`] returns the whole
//! SVG document, [`render_png`] the bytes of a PNG image.
//!
//! Text is laid out with the bundled DejaVu Sans font
//! (`assets/fonts/DejaVuSans.ttf`, licence next to it), so nothing depends
//! on the fonts installed: a PNG draws its glyphs from that font, and an
//! SVG names `DejaVu Sans` first in its font list (a viewer without it uses
//! a similar sans-serif; the layout leaves room for that).
//!
//! The y axis is fixed to `[0, 1]`, the x axis runs from 0 to the largest
//! time. The title is wrapped (and shrunk if need be) to the image width.
//! When the series form several overlays (line styles or marker shapes)
//! with the three probabilities each, the legend is compact: one entry per
//! colour and one per overlay; otherwise one entry per series. It is placed
//! in a corner of the plot where it covers no data, else to the right of the
//! plot, else below it.
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
//!
//! Size: one concern, plotting: the public spec and series builders, then the
//! plotters rendering with its legend layout (about 180 lines are comments,
//! 40 tests).

use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};

use crate::curve::Timing;
use crate::tree::{Decorator, Duration, NodeId, NodeKind, Tree};
use crate::Model;

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

/// The shape of a Monte Carlo marker.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Marker {
    /// `x`
    Cross,
    /// `+`
    Plus,
    /// An open circle.
    Circle,
    /// An open triangle.
    Triangle,
    /// An open square.
    Square,
    /// An open diamond.
    Diamond,
}

impl Marker {
    /// Marker of the `i`-th overlay: `x`, `o`, triangle, `+`, square,
    /// diamond, then again.
    pub fn overlay(i: usize) -> Marker {
        [
            Marker::Cross,
            Marker::Circle,
            Marker::Triangle,
            Marker::Plus,
            Marker::Square,
            Marker::Diamond,
        ][i % 6]
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
    /// A long-dashed line.
    LongDash,
    /// A dash-dot-dot line.
    DashDotDot,
    /// A marker at each point, no line (Monte Carlo estimates).
    Markers(Marker),
}

impl Style {
    /// Line style of the `i`-th overlay: solid, dashed, dotted, dash-dot,
    /// long-dashed, dash-dot-dot, then again.
    pub fn overlay(i: usize) -> Style {
        [
            Style::Solid,
            Style::Dashed,
            Style::Dotted,
            Style::DashDot,
            Style::LongDash,
            Style::DashDotDot,
        ][i % 6]
    }

    /// Dash pattern of a line style in output pixels, as in SVG
    /// `stroke-dasharray` (`None` for solid or markers).
    pub fn dasharray(self) -> Option<&'static str> {
        match self {
            Style::Dashed => Some("10 6"),
            Style::Dotted => Some("2 5"),
            Style::DashDot => Some("12 5 2 5"),
            Style::LongDash => Some("20 6"),
            Style::DashDotDot => Some("12 4 2 4 2 4"),
            Style::Solid | Style::Markers(_) => None,
        }
    }

    fn dashes(self) -> Option<Vec<i32>> {
        self.dasharray().map(|d| {
            d.split(' ')
                .map(|x| x.parse::<i32>().expect("dash length") * S)
                .collect()
        })
    }

    /// plotters' SVG backend cannot dash a polyline: dashed styles are drawn
    /// with this (otherwise unused) opacity, and the attribute is rewritten to
    /// a `stroke-dasharray` afterwards, so each line stays one `<polyline>`.
    fn opacity_tag(self) -> Option<&'static str> {
        match self {
            Style::Dashed => Some("0.998"),
            Style::Dotted => Some("0.997"),
            Style::DashDot => Some("0.996"),
            Style::LongDash => Some("0.995"),
            Style::DashDotDot => Some("0.994"),
            Style::Solid | Style::Markers(_) => None,
        }
    }

    fn alpha(self) -> f64 {
        self.opacity_tag()
            .map_or(1.0, |t| t.parse().expect("opacity tag is a number"))
    }

    fn is_markers(self) -> bool {
        matches!(self, Style::Markers(_))
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

/// A vertical line across the plot at time `t`, labelled (e.g. a deadline).
#[derive(Debug, Clone, PartialEq)]
pub struct VerticalMarker {
    /// Time (s).
    pub t: f64,
    /// Text next to the line's top.
    pub label: String,
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
    /// Vertical markers (dashed grey lines), e.g. a deadline.
    pub markers: Vec<VerticalMarker>,
    /// Width of the image in pixels (at least [`MIN_WIDTH`]).
    pub width: u32,
    /// Height of the image in pixels (at least [`MIN_HEIGHT`]).
    pub height: u32,
}

/// Default image width in pixels.
pub(crate) const DEFAULT_WIDTH: u32 = 960;
/// Default image height in pixels.
pub(crate) const DEFAULT_HEIGHT: u32 = 600;
/// Smallest accepted width.
pub const MIN_WIDTH: u32 = 400;
/// Smallest accepted height.
pub const MIN_HEIGHT: u32 = 300;
/// Largest accepted width or height.
pub const MAX_SIDE: u32 = 8000;

impl PlotSpec {
    /// A plot with axis labels `time t (s)` and `probability`, 960 × 600.
    pub fn new(title: impl Into<String>, series: Vec<Series>) -> PlotSpec {
        PlotSpec {
            title: title.into(),
            x_label: "time t (s)".into(),
            y_label: "probability".into(),
            series,
            markers: Vec::new(),
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
    /// The image is too large.
    #[error("a plot of {width}x{height} pixels is too large: at most {MAX_SIDE} on each side")]
    TooLarge {
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
/// markers of the given shape like the book's figures.
pub fn mc_series(
    label_prefix: &str,
    points: &[crate::sim::CurvePoint],
    marker: Marker,
) -> Vec<Series> {
    SeriesKind::ALL
        .iter()
        .map(|&kind| Series {
            label: label(label_prefix, kind),
            kind,
            style: Style::Markers(marker),
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

/// Running probability below which a curve counts as settled for the
/// default horizon.
pub const SETTLED: f64 = 1e-3;

/// A time scale of a node from its actions alone (no analysis needed): the
/// longest mean or fixed duration of each action, summed along Sequences
/// and Fallbacks (the children may all run), the largest over a Parallel's
/// children, times the count of a Retry/Repeat (at most 1000).
pub fn time_scale(tree: &Tree, node: NodeId) -> f64 {
    let n = tree.node(node);
    match &n.kind {
        NodeKind::Action(a) => {
            let mean = |d: Option<Duration>, p: f64| {
                d.filter(|_| p > 0.0).map_or(0.0, |d: Duration| d.mean())
            };
            mean(a.success, a.ps).max(mean(a.failure, a.pf))
        }
        NodeKind::Condition { .. } => 0.0,
        NodeKind::Sequence { children }
        | NodeKind::Fallback { children }
        | NodeKind::Pipeline { children }
        | NodeKind::RoundRobin { children, .. }
        | NodeKind::SequenceWithMemory { children, .. } => {
            children.iter().map(|&c| time_scale(tree, c)).sum()
        }
        NodeKind::Parallel { children, .. } => children
            .iter()
            .map(|&c| time_scale(tree, c))
            .fold(0.0, f64::max),
        // a run visits each state at most once
        NodeKind::Flow(flow) => flow
            .states
            .iter()
            .map(|s| time_scale(tree, flow.children[s.child]))
            .sum(),
        NodeKind::Decorator { decorator, child } => {
            let k = match decorator {
                Decorator::Retry { attempts } => *attempts as f64,
                Decorator::Repeat { times } => *times as f64,
                _ => 1.0,
            };
            k.min(1000.0) * time_scale(tree, *child)
        }
    }
}

/// `x` rounded up to 1, 1.2, 1.5, 2, 2.5, 3, 4, 5, 6 or 8 times a power of 10.
pub fn nice_ceil(x: f64) -> f64 {
    if !(x.is_finite() && x > 0.0) {
        return 1.0;
    }
    let p = 10f64.powf(x.log10().floor());
    for m in [1.0, 1.2, 1.5, 2.0, 2.5, 3.0, 4.0, 5.0, 6.0, 8.0, 10.0] {
        if m * p >= x * (1.0 - 1e-12) {
            return m * p;
        }
    }
    10.0 * p
}

/// The default horizon of a plot of `node` of each tree (with its timing):
/// the first time at which every curve's running probability is at most
/// [`SETTLED`] — searched on a geometric grid from the node's time scale
/// (its MTTS and MTTF from the tree's [`Model`], else [`time_scale`]) —
/// plus 5%, rounded up with [`nice_ceil`]. Each item is the tree's model
/// (whose plan the plot's own curves then reuse), or the tree where it has
/// none. A curve that cannot be computed contributes three times its time
/// scale; a node that takes no time gives 1 s.
pub fn default_horizon(items: &[(Result<&Model, &Tree>, NodeId, Timing)]) -> f64 {
    let mut end: f64 = 0.0;
    for &(model, node, timing) in items {
        let figures = model.ok().and_then(|m| m.figures(node).ok());
        let scale = match (figures, model) {
            (Some(f), _) => f.mtts.unwrap_or(0.0).max(f.mttf.unwrap_or(0.0)),
            (None, Ok(m)) => time_scale(m.tree(), node),
            (None, Err(tree)) => time_scale(tree, node),
        };
        if !(scale.is_finite() && scale > 0.0) {
            continue;
        }
        // scale · 1.1^k, k = -24..=160 (1.1^160 ≈ 4e6)
        let times: Vec<f64> = (-24..=160).map(|k| scale * 1.1f64.powi(k)).collect();
        let settled = match model.map(|m| m.curve_with(node, &times, timing)) {
            Ok(Ok(points)) => points
                .iter()
                .find(|p| p.running <= SETTLED)
                .map_or(times[times.len() - 1], |p| p.t),
            _ => 3.0 * scale,
        };
        end = end.max(settled);
    }
    if end > 0.0 {
        nice_ceil(end * 1.05)
    } else {
        1.0
    }
}

// Layout. plotters' coordinates are whole pixels, so the image is drawn at
// `S` times its size (smooth curves, half-pixel strokes): the `<svg>`
// element is given the requested size with the larger viewBox, and a PNG is
// averaged down 2×2 (anti-aliasing). Constants are in output pixels; `S *`
// converts.
const S: i32 = 2;
// plotters writes `font-size` = size / 1.24 (and lays text out at `size`).
const FONT_SCALE: f64 = 1.24;
const TITLE_PX: f64 = 20.0;
const TITLE_MIN_PX: f64 = 14.0;
const AXIS_LABEL_PX: f64 = 16.0;
const TICK_PX: f64 = 14.0;
const LEGEND_PX: f64 = 14.0;
const LEGEND_ROW: i32 = 22;
const LEGEND_PAD: i32 = 10;
const LEGEND_SAMPLE: i32 = 40;
const LEGEND_GAP: i32 = 8;
const LEGEND_COL_GAP: i32 = 24;
const LEGEND_INSET: i32 = 12;
const MARGIN: i32 = 14;
const MARGIN_RIGHT: i32 = 34;
const X_LABEL_AREA: i32 = 58;
const Y_LABEL_AREA: i32 = 74;
const MARKER_HALF: i32 = 4;

/// The family registered with plotters (and written into SVG as a font
/// list: the bundled face first).
const FAMILY: &str = "DejaVu Sans, Verdana, Arial, sans-serif";
static FONT: &[u8] = include_bytes!("../assets/fonts/DejaVuSans.ttf");

fn register_fonts() -> Result<(), PlotError> {
    static DONE: std::sync::OnceLock<bool> = std::sync::OnceLock::new();
    let ok = *DONE.get_or_init(|| {
        [FontStyle::Normal, FontStyle::Bold]
            .iter()
            .all(|&style| plotters::style::register_font(FAMILY, style, FONT).is_ok())
    });
    if ok {
        Ok(())
    } else {
        Err(PlotError::Draw("the bundled font cannot be read".into()))
    }
}

fn font(px: f64) -> FontDesc<'static> {
    (FAMILY, px * S as f64 * FONT_SCALE).into_font()
}

/// Width of `text` in backend pixels at `px` output pixels, measured with the
/// bundled font, plus 8% for a viewer's substitute font.
fn text_width(text: &str, px: f64) -> i32 {
    let w = font(px)
        .box_size(text)
        .map(|(w, _)| w as f64)
        .unwrap_or(text.chars().count() as f64 * 0.6 * px * S as f64);
    (w * 1.08).ceil() as i32
}

fn err(e: impl std::fmt::Display) -> PlotError {
    PlotError::Draw(e.to_string())
}

fn check(spec: &PlotSpec) -> Result<(), PlotError> {
    if spec.series.is_empty() {
        return Err(PlotError::NoSeries);
    }
    if spec.width < MIN_WIDTH || spec.height < MIN_HEIGHT {
        return Err(PlotError::TooSmall {
            width: spec.width,
            height: spec.height,
        });
    }
    if spec.width > MAX_SIDE || spec.height > MAX_SIDE {
        return Err(PlotError::TooLarge {
            width: spec.width,
            height: spec.height,
        });
    }
    register_fonts()
}

fn clean(spec: &PlotSpec) -> Vec<Vec<(f64, f64)>> {
    spec.series
        .iter()
        .map(|s| {
            s.points
                .iter()
                .filter(|(x, y)| x.is_finite() && y.is_finite())
                .map(|&(x, y)| (x, y.clamp(0.0, 1.0)))
                .collect()
        })
        .collect()
}

/// Where the legend goes, decided by trial drawings (SVG, in memory).
fn layout(spec: &PlotSpec, series: &[Vec<(f64, f64)>]) -> Result<Placement, PlotError> {
    let legend = Legend::new(spec, 1);
    let mut buf = String::new();
    let first = {
        let root =
            SVGBackend::with_string(&mut buf, backend_size(spec, &legend, Placement::Inside))
                .into_drawing_area();
        draw(&root, spec, series, Placement::Inside, Dashing::SvgTag)?
    };
    let (plot_w, plot_h) = first.plot;
    let fits_inside =
        legend.w + 2 * S * LEGEND_INSET <= plot_w && legend.h + 2 * S * LEGEND_INSET <= plot_h;
    Ok(if fits_inside && first.hits == 0 {
        Placement::Inside
    } else if legend.w + 2 * S * LEGEND_INSET <= S * spec.width as i32 * 2 / 5 && legend.h <= plot_h
    {
        Placement::Right
    } else {
        // a legend that would hide data goes below the plot
        Placement::Below
    })
}

fn backend_size(spec: &PlotSpec, legend: &Legend, placement: Placement) -> (u32, u32) {
    let (w, h) = (S * spec.width as i32, S * spec.height as i32);
    let total_h = match placement {
        Placement::Below => {
            let below = Legend::fitting(spec, w - 2 * S * MARGIN);
            h + below.h + S * MARGIN
        }
        _ => h,
    };
    let _ = legend;
    (w as u32, total_h as u32)
}

/// The whole SVG document of the plot.
///
/// The legend goes in the corner of the plot where it hides no data; if every
/// corner would hide some, to the right of the plot; if it is too wide for
/// that (many or very long labels), in columns below the plot, the image
/// growing taller to hold it.
///
/// Errors: no series, an image smaller than [`MIN_WIDTH`] × [`MIN_HEIGHT`]
/// or larger than [`MAX_SIDE`]. Empty series, single points and NaN values
/// are fine (NaN points are skipped; a line of one point is drawn as a dot).
pub fn render_svg(spec: &PlotSpec) -> Result<String, PlotError> {
    check(spec)?;
    let series = clean(spec);
    let placement = layout(spec, &series)?;
    let legend = Legend::new(spec, 1);
    let mut buf = String::new();
    {
        let root = SVGBackend::with_string(&mut buf, backend_size(spec, &legend, placement))
            .into_drawing_area();
        draw(&root, spec, &series, placement, Dashing::SvgTag)?;
    }
    Ok(finish(buf))
}

/// The plot as a PNG image (8-bit RGB), text drawn with the bundled font.
/// Same layout and errors as [`render_svg`].
pub fn render_png(spec: &PlotSpec) -> Result<Vec<u8>, PlotError> {
    check(spec)?;
    let series = clean(spec);
    let placement = layout(spec, &series)?;
    let legend = Legend::new(spec, 1);
    let (w, h) = backend_size(spec, &legend, placement);
    let mut big = vec![255u8; w as usize * h as usize * 3];
    {
        let root = BitMapBackend::with_buffer(&mut big, (w, h)).into_drawing_area();
        draw(&root, spec, &series, placement, Dashing::Segments)?;
    }
    // 2×2 average
    let (ow, oh) = (w as usize / S as usize, h as usize / S as usize);
    let mut small = vec![0u8; ow * oh * 3];
    for y in 0..oh {
        for x in 0..ow {
            for c in 0..3 {
                let mut sum = 0u32;
                for dy in 0..S as usize {
                    for dx in 0..S as usize {
                        let i = ((y * S as usize + dy) * w as usize + x * S as usize + dx) * 3 + c;
                        sum += big[i] as u32;
                    }
                }
                small[(y * ow + x) * 3 + c] = ((sum + 2) / (S * S) as u32) as u8;
            }
        }
    }
    let mut out = Vec::new();
    {
        let mut enc = png::Encoder::new(&mut out, ow as u32, oh as u32);
        enc.set_color(png::ColorType::Rgb);
        enc.set_depth(png::BitDepth::Eight);
        let mut writer = enc.write_header().map_err(err)?;
        writer.write_image_data(&small).map_err(err)?;
        writer.finish().map_err(err)?;
    }
    Ok(out)
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
    for style in [
        Style::Dashed,
        Style::Dotted,
        Style::DashDot,
        Style::LongDash,
        Style::DashDotDot,
    ] {
        let tag = format!("opacity=\"{}\"", style.opacity_tag().expect("dashed"));
        let dashes: Vec<String> = style
            .dashes()
            .expect("dashed")
            .iter()
            .map(|d| d.to_string())
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

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Dashing {
    /// SVG: opacity tags rewritten to `stroke-dasharray` afterwards.
    SvgTag,
    /// Bitmaps: the dashes drawn as separate segments.
    Segments,
}

/// What a legend entry shows.
#[derive(Debug, Clone, PartialEq)]
enum Sample {
    Line(RGBColor, Style),
    Markers(RGBColor, Marker),
}

#[derive(Debug, Clone, PartialEq)]
struct Entry {
    sample: Sample,
    label: String,
}

const OVERLAY_GREY: RGBColor = RGBColor(0x44, 0x44, 0x44);

/// The legend entries: compact (one per colour, one per overlay) when the
/// series are overlays of the three probabilities each, else one per
/// series.
fn entries(spec: &PlotSpec) -> Vec<Entry> {
    let full = || {
        spec.series
            .iter()
            .map(|s| Entry {
                sample: match s.style {
                    Style::Markers(m) => Sample::Markers(s.kind.color(), m),
                    st => Sample::Line(s.kind.color(), st),
                },
                label: s.label.clone(),
            })
            .collect::<Vec<_>>()
    };
    // overlays in order of first appearance
    let mut styles: Vec<Style> = Vec::new();
    for s in &spec.series {
        if !styles.contains(&s.style) {
            styles.push(s.style);
        }
    }
    if styles.len() < 2 {
        return full();
    }
    let mut overlays = Vec::new();
    for &st in &styles {
        let group: Vec<&Series> = spec.series.iter().filter(|s| s.style == st).collect();
        let kinds: Vec<SeriesKind> = group.iter().map(|s| s.kind).collect();
        if kinds != SeriesKind::ALL {
            return full();
        }
        let prefix = |s: &Series| -> Option<String> {
            if s.label == s.kind.name() {
                Some(String::new())
            } else {
                s.label
                    .strip_suffix(s.kind.name())
                    .and_then(|p| p.strip_suffix(": "))
                    .map(str::to_string)
            }
        };
        let p = prefix(group[0]);
        if p.is_none() || group.iter().any(|s| prefix(s) != p) {
            return full();
        }
        let mut name = p.unwrap_or_default();
        if name.is_empty() {
            name = if st.is_markers() {
                "Monte Carlo"
            } else {
                "exact"
            }
            .to_string();
        }
        overlays.push(Entry {
            sample: match st {
                Style::Markers(m) => Sample::Markers(OVERLAY_GREY, m),
                st => Sample::Line(OVERLAY_GREY, st),
            },
            label: name,
        });
    }
    let mut out: Vec<Entry> = SeriesKind::ALL
        .iter()
        .map(|&k| Entry {
            sample: Sample::Line(k.color(), Style::Solid),
            label: k.name().to_string(),
        })
        .collect();
    out.extend(overlays);
    out
}

/// Legend box geometry, in backend (×`S`) pixels.
struct Legend {
    entries: Vec<Entry>,
    cols: usize,
    /// Width of one column (sample, gap, text, column gap).
    col_w: i32,
    w: i32,
    h: i32,
}

impl Legend {
    fn new(spec: &PlotSpec, cols: usize) -> Legend {
        let entries = entries(spec);
        let text_w = entries
            .iter()
            .map(|e| text_width(&e.label, LEGEND_PX))
            .max()
            .unwrap_or(0);
        let n = entries.len().max(1);
        let cols = cols.clamp(1, n);
        let rows = n.div_ceil(cols);
        let col_w = S * (LEGEND_SAMPLE + LEGEND_GAP + LEGEND_COL_GAP) + text_w;
        Legend {
            entries,
            cols,
            col_w,
            w: S * 2 * LEGEND_PAD + col_w * cols as i32 - S * LEGEND_COL_GAP,
            h: S * (2 * LEGEND_PAD + LEGEND_ROW * rows as i32 - (LEGEND_ROW - 16)),
        }
    }

    /// As many columns as fit in `width` backend pixels.
    fn fitting(spec: &PlotSpec, width: i32) -> Legend {
        let one = Legend::new(spec, 1);
        let cols = ((width - one.w) / one.col_w).max(0) as usize + 1;
        Legend::new(spec, cols)
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

/// Tick label with as many decimals as ticks `span / 10` apart need;
/// powers of ten notation for very small or large spans.
fn tick_label(v: f64, span: f64) -> String {
    if span >= 1e7 || (span < 1e-3 && span > 0.0) {
        if v == 0.0 {
            return "0".into();
        }
        let s = format!("{v:.2e}");
        // 1.50e3 -> 1.5e3
        return match s.split_once('e') {
            Some((m, e)) => {
                let m = if m.contains('.') {
                    m.trim_end_matches('0').trim_end_matches('.')
                } else {
                    m
                };
                format!("{m}e{e}")
            }
            None => s,
        };
    }
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

fn line_style(color: RGBColor, style: Style) -> ShapeStyle {
    ShapeStyle {
        color: color.mix(style.alpha()),
        filled: false,
        // 1.5 px markers, 2 px lines
        stroke_width: if style.is_markers() { 3 } else { 4 },
    }
}

fn style_of(s: &Series) -> ShapeStyle {
    line_style(s.kind.color(), s.style)
}

/// Wraps the title into lines no wider than `width` backend pixels at the
/// largest size from [`TITLE_PX`] down to [`TITLE_MIN_PX`] that needs at
/// most two lines.
fn title_lines(title: &str, width: i32) -> (f64, Vec<String>) {
    let wrap = |px: f64| -> Vec<String> {
        let mut lines: Vec<String> = Vec::new();
        for word in title.split_whitespace() {
            match lines.last_mut() {
                Some(l) if text_width(&format!("{l} {word}"), px) <= width => {
                    l.push(' ');
                    l.push_str(word);
                }
                _ => lines.push(word.to_string()),
            }
        }
        lines
    };
    let mut px = TITLE_PX;
    loop {
        let lines = wrap(px);
        if lines.len() <= 2 || px <= TITLE_MIN_PX {
            return (px, lines);
        }
        px -= 1.0;
    }
}

struct Drawn {
    /// Data samples hidden by the legend (0 unless `Inside`).
    hits: usize,
    /// Plot area size, backend pixels.
    plot: (i32, i32),
}

/// Splits a pixel polyline into the "on" pieces of a dash pattern.
fn dash_segments(points: &[(i32, i32)], pattern: &[i32]) -> Vec<Vec<(i32, i32)>> {
    let mut out: Vec<Vec<(i32, i32)>> = Vec::new();
    let total: i32 = pattern.iter().sum();
    if total <= 0 || points.len() < 2 {
        return vec![points.to_vec()];
    }
    let (mut k, mut left) = (0usize, pattern[0] as f64);
    let mut current: Vec<(i32, i32)> = vec![points[0]];
    for w in points.windows(2) {
        let (a, b) = (
            (w[0].0 as f64, w[0].1 as f64),
            (w[1].0 as f64, w[1].1 as f64),
        );
        let len = (b.0 - a.0).hypot(b.1 - a.1);
        let mut pos = 0.0;
        while len - pos > left {
            pos += left;
            let f = pos / len;
            let p = (
                (a.0 + (b.0 - a.0) * f).round() as i32,
                (a.1 + (b.1 - a.1) * f).round() as i32,
            );
            if k % 2 == 0 {
                current.push(p);
                out.push(std::mem::take(&mut current));
            } else {
                current = vec![p];
            }
            k = (k + 1) % pattern.len();
            left = pattern[k] as f64;
        }
        left -= len - pos;
        if k % 2 == 0 {
            current.push(w[1]);
        }
    }
    if k % 2 == 0 && current.len() > 1 {
        out.push(current);
    }
    out
}

fn draw_marker<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    marker: Marker,
    (x, y): (i32, i32),
    style: ShapeStyle,
) -> Result<(), PlotError> {
    let r = S * MARKER_HALF;
    match marker {
        Marker::Cross => root.draw(&Cross::new((x, y), r, style)).map_err(err),
        Marker::Plus => {
            root.draw(&PathElement::new(vec![(x - r, y), (x + r, y)], style))
                .map_err(err)?;
            root.draw(&PathElement::new(vec![(x, y - r), (x, y + r)], style))
                .map_err(err)
        }
        Marker::Circle => root.draw(&Circle::new((x, y), r, style)).map_err(err),
        Marker::Triangle => {
            let h = r + S;
            root.draw(&PathElement::new(
                vec![(x, y - h), (x + h, y + r), (x - h, y + r), (x, y - h)],
                style,
            ))
            .map_err(err)
        }
        Marker::Square => root
            .draw(&Rectangle::new([(x - r, y - r), (x + r, y + r)], style))
            .map_err(err),
        Marker::Diamond => {
            let d = r + S;
            root.draw(&PathElement::new(
                vec![(x, y - d), (x + d, y), (x, y + d), (x - d, y), (x, y - d)],
                style,
            ))
            .map_err(err)
        }
    }
}

fn draw_line<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    pixels: &[(i32, i32)],
    style: Style,
    shape: ShapeStyle,
    dashing: Dashing,
) -> Result<(), PlotError> {
    match (dashing, style.dashes()) {
        (Dashing::Segments, Some(pattern)) => {
            let shape = ShapeStyle {
                color: shape.color.to_rgba().mix(1.0),
                ..shape
            };
            for seg in dash_segments(pixels, &pattern) {
                root.draw(&PathElement::new(seg, shape)).map_err(err)?;
            }
            Ok(())
        }
        _ => root
            .draw(&PathElement::new(pixels.to_vec(), shape))
            .map_err(err),
    }
}

fn draw<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    spec: &PlotSpec,
    series: &[Vec<(f64, f64)>],
    placement: Placement,
    dashing: Dashing,
) -> Result<Drawn, PlotError> {
    let (x0, x1) = x_range(series);
    let span = x1 - x0;
    let (w, h) = (S * spec.width as i32, S * spec.height as i32);
    let legend = match placement {
        Placement::Below => Legend::fitting(spec, w - 2 * S * MARGIN),
        _ => Legend::new(spec, 1),
    };
    root.fill(&WHITE).map_err(err)?;
    let (area, _) = root.split_vertically(h);
    // title, wrapped
    let (title_px, lines) = title_lines(&spec.title, w - 2 * S * MARGIN);
    let line_h = (title_px * 1.3 * S as f64).round() as i32;
    let title_h = S * MARGIN + line_h * lines.len() as i32;
    let title_style = font(title_px)
        .style(FontStyle::Bold)
        .color(&BLACK)
        .pos(Pos::new(HPos::Center, VPos::Top));
    for (i, l) in lines.iter().enumerate() {
        area.draw(&Text::new(
            l.clone(),
            (w / 2, S * MARGIN + line_h * i as i32),
            title_style.clone(),
        ))
        .map_err(err)?;
    }
    let (_, area) = area.split_vertically(title_h);
    let right = match placement {
        Placement::Right => S * MARGIN_RIGHT + legend.w,
        _ => S * MARGIN_RIGHT,
    };
    let mut chart = ChartBuilder::on(&area)
        .margin(S * MARGIN)
        .margin_right(right)
        .x_label_area_size(S * X_LABEL_AREA)
        .y_label_area_size(S * Y_LABEL_AREA)
        .build_cartesian_2d(x0..x1, 0.0..1.0)
        .map_err(err)?;
    let (plot_w, plot_h) = chart.plotting_area().dim_in_pixel();
    let (plot_w, plot_h) = (plot_w as i32, plot_h as i32);
    // as many ticks as fit without crowding
    let widest = [x0, x1, (x0 + x1) / 2.0, x0 + span * 0.15]
        .iter()
        .map(|&v| text_width(&tick_label(v, span), TICK_PX))
        .max()
        .unwrap_or(0);
    let x_ticks = (plot_w / (widest + S * 30)).clamp(2, 11) as usize;
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

    let (px, py) = chart.plotting_area().get_pixel_range();
    // vertical markers (deadline) under the curves
    let grey = RGBColor(0x55, 0x55, 0x55);
    for m in &spec.markers {
        if !(m.t.is_finite() && m.t >= x0 && m.t <= x1) {
            continue;
        }
        let (mx, _) = chart.backend_coord(&(m.t, 0.0));
        let pts = [(mx, py.start), (mx, py.end)];
        let shape = ShapeStyle {
            color: grey.mix(Style::Dashed.alpha()),
            filled: false,
            stroke_width: 3,
        };
        draw_line(root, &pts, Style::Dashed, shape, dashing)?;
        let right_side = mx + S * 6 + text_width(&m.label, TICK_PX) < px.end;
        let pos = if right_side {
            Pos::new(HPos::Left, VPos::Top)
        } else {
            Pos::new(HPos::Right, VPos::Top)
        };
        let tx = if right_side { mx + S * 5 } else { mx - S * 5 };
        root.draw(&Text::new(
            m.label.clone(),
            (tx, py.start + S * 4),
            font(TICK_PX).color(&grey).pos(pos),
        ))
        .map_err(err)?;
    }

    let pixels: Vec<Vec<(i32, i32)>> = series
        .iter()
        .map(|pts| pts.iter().map(|p| chart.backend_coord(p)).collect())
        .collect();
    for (s, pix) in spec.series.iter().zip(&pixels) {
        let style = style_of(s);
        match s.style {
            Style::Markers(m) => {
                for &p in pix {
                    draw_marker(root, m, p, style)?;
                }
            }
            _ if pix.len() == 1 => {
                root.draw(&Circle::new(pix[0], S * 3, style.filled()))
                    .map_err(err)?;
            }
            _ if pix.len() > 1 => draw_line(root, pix, s.style, style, dashing)?,
            _ => {}
        }
    }

    let mut hits = 0;
    let (lx, ly) = match placement {
        Placement::Right => (px.end + S * LEGEND_INSET, py.start),
        Placement::Below => ((w - legend.w) / 2, h),
        Placement::Inside => {
            let (pos, n) = place_legend(spec, &pixels, (&px, &py), &legend);
            hits = n;
            pos
        }
    };
    draw_legend(root, (lx, ly), &legend, dashing)?;
    root.present().map_err(err)?;
    Ok(Drawn {
        hits,
        plot: (plot_w, plot_h),
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
        if !s.style.is_markers() {
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
    // the markers' labels and lines count as data too
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

fn draw_legend<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    (x, y): (i32, i32),
    legend: &Legend,
    dashing: Dashing,
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
    for (i, e) in legend.entries.iter().enumerate() {
        let (row, col) = (i / legend.cols, i % legend.cols);
        let cy = y + S * (LEGEND_PAD + 8 + LEGEND_ROW * row as i32);
        let sx = x + S * LEGEND_PAD + legend.col_w * col as i32;
        match e.sample {
            Sample::Markers(color, m) => {
                let style = line_style(color, Style::Markers(m));
                for k in [1, 3] {
                    draw_marker(root, m, (sx + S * LEGEND_SAMPLE * k / 4, cy), style)?;
                }
            }
            Sample::Line(color, st) => {
                draw_line(
                    root,
                    &[(sx, cy), (sx + S * LEGEND_SAMPLE, cy)],
                    st,
                    line_style(color, st),
                    dashing,
                )?;
            }
        }
        root.draw(&Text::new(
            e.label.clone(),
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
    fn nice_numbers_and_dashes() {
        assert_eq!(nice_ceil(1.0), 1.0);
        assert_eq!(nice_ceil(1260.0), 1500.0);
        assert_eq!(nice_ceil(2.1), 2.5);
        assert_eq!(nice_ceil(0.0), 1.0);
        assert_eq!(nice_ceil(9.0e-3), 0.01);
        // a 40 px line with 10 on / 6 off: on at 0-10, 16-26, 32-40
        let segs = dash_segments(&[(0, 0), (40, 0)], &[10, 6]);
        assert_eq!(
            segs,
            vec![
                vec![(0, 0), (10, 0)],
                vec![(16, 0), (26, 0)],
                vec![(32, 0), (40, 0)]
            ]
        );
    }

    #[test]
    fn x_range_edge_cases() {
        assert_eq!(x_range(&[]), (0.0, 1.0));
        assert_eq!(x_range(&[vec![(0.0, 0.5)]]), (0.0, 1.0));
        assert_eq!(x_range(&[vec![(0.0, 0.5), (5.0, 1.0)]]), (0.0, 5.0));
    }
}
