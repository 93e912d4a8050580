//! SVG plots: well-formed XML, title and legend, one polyline per line series
//! with every point, markers for Monte Carlo series, edge cases.
//!
//! Set `BTREL_PLOT_OUT=/tmp/sg.svg` to keep the search-and-grasp plot.

use std::collections::HashMap;
use std::path::Path;

use btrel::curve::{curve, CurveOptions};
use btrel::plot::{
    curve_series, mc_series, render_svg, Marker, PlotError, PlotSpec, Series, SeriesKind, Style,
};
use btrel::sim::{simulate, SimOptions};
use btrel::tree::parse_file;

/// One element of the document: name and attributes (text is not kept).
#[derive(Debug)]
struct Element {
    name: String,
    attrs: HashMap<String, String>,
}

/// A small XML well-formedness check: tags balanced and properly nested,
/// attributes quoted and unique, `&` only in entities, one root element.
/// Returns the elements in document order and the text contents.
fn parse_xml(doc: &str) -> (Vec<Element>, Vec<String>) {
    fn check_text(t: &str) {
        let mut rest = t;
        while let Some(i) = rest.find('&') {
            let end = rest[i..].find(';').expect("unterminated entity") + i;
            let ent = &rest[i + 1..end];
            assert!(
                ["lt", "gt", "amp", "quot", "apos"].contains(&ent) || ent.starts_with('#'),
                "bad entity &{ent};"
            );
            rest = &rest[end + 1..];
        }
        assert!(!t.contains('>'), "stray '>' in text {t:?}");
    }
    let mut elements = Vec::new();
    let mut texts = Vec::new();
    let mut stack: Vec<String> = Vec::new();
    let mut roots = 0;
    let mut rest = doc;
    loop {
        let Some(lt) = rest.find('<') else {
            assert!(rest.trim().is_empty(), "text after the root: {rest:?}");
            break;
        };
        let text = &rest[..lt];
        check_text(text);
        if stack.is_empty() {
            assert!(text.trim().is_empty(), "text outside the root: {text:?}");
        } else if !text.trim().is_empty() {
            texts.push(text.trim().to_string());
        }
        rest = &rest[lt..];
        if let Some(r) = rest.strip_prefix("<?") {
            let end = r.find("?>").expect("unterminated <?");
            rest = &r[end + 2..];
            continue;
        }
        if let Some(r) = rest.strip_prefix("<!--") {
            let end = r.find("-->").expect("unterminated comment");
            rest = &r[end + 3..];
            continue;
        }
        // a tag: find its end outside quotes
        let mut in_quote = None;
        let mut end = None;
        for (i, c) in rest.char_indices().skip(1) {
            match (in_quote, c) {
                (None, '"' | '\'') => in_quote = Some(c),
                (Some(q), c) if c == q => in_quote = None,
                (None, '<') => panic!("'<' inside a tag: {}", &rest[..i]),
                (None, '>') => {
                    end = Some(i);
                    break;
                }
                _ => {}
            }
        }
        let end = end.expect("unterminated tag");
        let tag = &rest[1..end];
        rest = &rest[end + 1..];
        if let Some(name) = tag.strip_prefix('/') {
            let open = stack.pop().expect("closing tag without an open one");
            assert_eq!(open, name.trim(), "mismatched closing tag");
            continue;
        }
        let (tag, self_closing) = match tag.strip_suffix('/') {
            Some(t) => (t, true),
            None => (tag, false),
        };
        let name_end = tag.find(|c: char| c.is_whitespace()).unwrap_or(tag.len());
        let name = tag[..name_end].to_string();
        assert!(
            !name.is_empty()
                && name
                    .chars()
                    .all(|c| c.is_ascii_alphanumeric() || "-_:".contains(c)),
            "bad tag name {name:?}"
        );
        let mut attrs = HashMap::new();
        let mut a = tag[name_end..].trim_start();
        while !a.is_empty() {
            let eq = a.find('=').expect("attribute without '='");
            let key = a[..eq].trim().to_string();
            assert!(!key.is_empty() && !key.contains(char::is_whitespace));
            let v = a[eq + 1..].trim_start();
            let q = v.chars().next().expect("attribute without value");
            assert!(q == '"' || q == '\'', "unquoted attribute {key}");
            let close = v[1..].find(q).expect("unterminated attribute") + 1;
            let value = &v[1..close];
            check_text(value);
            assert!(!value.contains('<'), "'<' in attribute {key}");
            assert!(
                attrs.insert(key.clone(), value.to_string()).is_none(),
                "duplicate attribute {key}"
            );
            a = v[close + 1..].trim_start();
        }
        if stack.is_empty() {
            roots += 1;
        }
        if !self_closing {
            stack.push(name.clone());
        }
        elements.push(Element { name, attrs });
    }
    assert!(stack.is_empty(), "unclosed tags: {stack:?}");
    assert_eq!(roots, 1, "exactly one root element");
    (elements, texts)
}

fn points_of(e: &Element) -> Vec<(f64, f64)> {
    e.attrs["points"]
        .split_whitespace()
        .map(|p| {
            let (x, y) = p.split_once(',').expect("x,y");
            (x.parse().expect("x"), y.parse().expect("y"))
        })
        .collect()
}

/// Polylines of the plot drawn in `kind`'s colour, legend samples (2 points
/// on one horizontal line) excluded.
fn polylines(elements: &[Element], kind: SeriesKind) -> Vec<&Element> {
    elements
        .iter()
        .filter(|e| e.name == "polyline" && e.attrs["stroke"] == kind.hex())
        .filter(|e| {
            let p = points_of(e);
            !(p.len() == 2 && p[0].1 == p[1].1)
        })
        .collect()
}

/// Width and height of the viewBox.
fn view_box(elements: &[Element]) -> (f64, f64) {
    let v: Vec<f64> = elements[0].attrs["viewBox"]
        .split_whitespace()
        .map(|x| x.parse().unwrap())
        .collect();
    assert_eq!(&v[..2], [0.0, 0.0]);
    (v[2], v[3])
}

fn lines_of(elements: &[Element], kind: SeriesKind) -> usize {
    elements
        .iter()
        .filter(|e| e.name == "line" && e.attrs["stroke"] == kind.hex())
        .count()
}

fn line(label: &str, kind: SeriesKind, style: Style, points: Vec<(f64, f64)>) -> Series {
    Series {
        label: label.into(),
        kind,
        style,
        points,
    }
}

fn ramp(n: usize, f: impl Fn(f64) -> f64) -> Vec<(f64, f64)> {
    (0..n)
        .map(|i| {
            let t = 10.0 * i as f64 / (n - 1) as f64;
            (t, f(t))
        })
        .collect()
}

fn three() -> Vec<Series> {
    vec![
        line(
            "P(success)",
            SeriesKind::Success,
            Style::Solid,
            ramp(21, |t| 0.6 * (1.0 - (-t / 3.0).exp())),
        ),
        line(
            "P(failure)",
            SeriesKind::Failure,
            Style::Solid,
            ramp(21, |t| 0.4 * (1.0 - (-t / 3.0).exp())),
        ),
        line(
            "P(running)",
            SeriesKind::Running,
            Style::Solid,
            ramp(21, |t| (-t / 3.0).exp()),
        ),
    ]
}

#[test]
fn no_series_is_an_error() {
    assert_eq!(
        render_svg(&PlotSpec::new("empty", vec![])),
        Err(PlotError::NoSeries)
    );
}

#[test]
fn tiny_image_is_an_error() {
    let mut spec = PlotSpec::new("tiny", three());
    spec.width = 50;
    assert!(matches!(
        render_svg(&spec),
        Err(PlotError::TooSmall { width: 50, .. })
    ));
}

#[test]
fn well_formed_with_title_axis_labels_and_legend() {
    let svg = render_svg(&PlotSpec::new("A & B <test>", three())).unwrap();
    assert!(svg.starts_with("<svg"));
    let (elements, texts) = parse_xml(&svg);
    assert_eq!(elements[0].name, "svg");
    assert_eq!(elements[0].attrs["width"], "960");
    assert_eq!(elements[0].attrs["height"], "600");
    let (vw, vh) = view_box(&elements);
    let scale = vw / 960.0;
    assert_eq!(vh / 600.0, scale);
    for want in [
        "A &amp; B &lt;test&gt;",
        "time t (s)",
        "probability",
        "P(success)",
        "P(failure)",
        "P(running)",
    ] {
        assert!(texts.iter().any(|t| t == want), "no text {want:?}");
    }
    // y ticks 0.0 .. 1.0, x ticks up to the last time
    for want in ["0.0", "0.5", "1.0", "0", "10"] {
        assert!(texts.iter().any(|t| t == want), "no tick {want:?}");
    }
    // readable fonts (in output pixels)
    for e in elements.iter().filter(|e| e.name == "text") {
        let size: f64 = e.attrs["font-size"].parse().unwrap();
        assert!(size / scale >= 14.0, "font-size {size}");
    }
    // no text anchored outside the image
    for e in elements.iter().filter(|e| e.name == "text") {
        let x: f64 = e.attrs["x"].parse().unwrap();
        let y: f64 = e.attrs["y"].parse().unwrap();
        assert!((0.0..=vw).contains(&x) && (0.0..=vh).contains(&y));
    }
}

#[test]
fn one_polyline_per_line_series_with_every_point_in_x_order() {
    let svg = render_svg(&PlotSpec::new("lines", three())).unwrap();
    let (elements, _) = parse_xml(&svg);
    for kind in SeriesKind::ALL {
        let lines = polylines(&elements, kind);
        assert_eq!(lines.len(), 1, "{kind:?}");
        let p = points_of(lines[0]);
        assert_eq!(p.len(), 21);
        assert!(p.windows(2).all(|w| w[0].0 < w[1].0), "x increasing");
        let (vw, _) = view_box(&elements);
        let width: f64 = lines[0].attrs["stroke-width"].parse().unwrap();
        assert_eq!(width * 960.0 / vw, 2.0, "2 px lines");
        assert!(!lines[0].attrs.contains_key("stroke-dasharray"));
    }
    // running falls: its pixel y grows (SVG y points down)
    let run = points_of(polylines(&elements, SeriesKind::Running)[0]);
    assert!(run.first().unwrap().1 < run.last().unwrap().1);
}

#[test]
fn overlays_keep_colours_and_differ_by_dashes() {
    let mut series = three();
    for (i, style) in [Style::Dashed, Style::Dotted, Style::DashDot]
        .into_iter()
        .enumerate()
    {
        series.push(line(
            &format!("overlay {i}"),
            SeriesKind::Success,
            style,
            ramp(11, |t| 0.05 * t),
        ));
    }
    let svg = render_svg(&PlotSpec::new("overlay", series)).unwrap();
    let (elements, texts) = parse_xml(&svg);
    let green = polylines(&elements, SeriesKind::Success);
    assert_eq!(green.len(), 4);
    // dash lengths in output pixels (the viewBox is larger than the image)
    let scale = view_box(&elements).0 / 960.0;
    let dashes: Vec<Option<String>> = green
        .iter()
        .map(|e| {
            e.attrs.get("stroke-dasharray").map(|d| {
                d.split_whitespace()
                    .map(|x| (x.parse::<f64>().unwrap() / scale).to_string())
                    .collect::<Vec<_>>()
                    .join(" ")
            })
        })
        .collect();
    let want: Vec<Option<String>> = [Style::Solid, Style::Dashed, Style::Dotted, Style::DashDot]
        .iter()
        .map(|s| s.dasharray().map(str::to_string))
        .collect();
    assert_eq!(dashes, want);
    assert!(green.iter().all(|e| e.attrs["opacity"] == "1"));
    assert_eq!(points_of(green[1]).len(), 11);
    for i in 0..3 {
        assert!(texts.contains(&format!("overlay {i}")));
    }
    assert_eq!(Style::overlay(0), Style::Solid);
    assert_eq!(Style::overlay(7), Style::Dashed);
}

#[test]
fn markers_for_monte_carlo_series() {
    let mut series = three();
    series.push(line(
        "MC success",
        SeriesKind::Success,
        Style::Markers(Marker::Cross),
        ramp(7, |t| 0.06 * t),
    ));
    let svg = render_svg(&PlotSpec::new("mc", series)).unwrap();
    let (elements, texts) = parse_xml(&svg);
    // an 'x' is two lines: 7 points + 2 in the legend sample
    assert_eq!(lines_of(&elements, SeriesKind::Success), 2 * (7 + 2));
    assert_eq!(lines_of(&elements, SeriesKind::Failure), 0);
    // markers are not a polyline
    assert_eq!(polylines(&elements, SeriesKind::Success).len(), 1);
    assert!(texts.iter().any(|t| t == "MC success"));
}

#[test]
fn nan_points_are_skipped() {
    let mut series = three();
    series[0].points[3].1 = f64::NAN;
    series[0].points[5].0 = f64::NAN;
    series[1].points[0].1 = f64::INFINITY;
    let svg = render_svg(&PlotSpec::new("nan", series)).unwrap();
    assert!(!svg.contains("NaN") && !svg.contains("inf"));
    let (elements, _) = parse_xml(&svg);
    assert_eq!(
        points_of(polylines(&elements, SeriesKind::Success)[0]).len(),
        19
    );
    assert_eq!(
        points_of(polylines(&elements, SeriesKind::Failure)[0]).len(),
        20
    );
}

#[test]
fn edge_cases_do_not_panic() {
    let cases: Vec<Vec<Series>> = vec![
        // a single point
        vec![line(
            "one",
            SeriesKind::Success,
            Style::Solid,
            vec![(3.0, 0.5)],
        )],
        // all times zero
        vec![line(
            "zero",
            SeriesKind::Failure,
            Style::Dashed,
            vec![(0.0, 0.0), (0.0, 1.0)],
        )],
        // empty and all-NaN series
        vec![
            line("empty", SeriesKind::Running, Style::Solid, vec![]),
            line(
                "nan",
                SeriesKind::Running,
                Style::Markers(Marker::Cross),
                vec![(f64::NAN, 0.5)],
            ),
        ],
        // out-of-range probabilities and a very long label
        vec![line(
            &"a very long legend label ".repeat(6),
            SeriesKind::Success,
            Style::Solid,
            vec![(0.0, -0.5), (1e-9, 1.5)],
        )],
        // many series
        (0..24)
            .map(|i| {
                line(
                    &format!("series {i}"),
                    SeriesKind::ALL[i % 3],
                    Style::overlay(i),
                    ramp(5, |t| t / 10.0),
                )
            })
            .collect(),
    ];
    for series in cases {
        let svg = render_svg(&PlotSpec::new("edge", series)).unwrap();
        let (_, texts) = parse_xml(&svg);
        assert!(texts.iter().any(|t| t == "edge"));
    }
    // all-zero times: x axis [0, 1]
    let svg = render_svg(&PlotSpec::new(
        "zero",
        vec![line(
            "z",
            SeriesKind::Success,
            Style::Solid,
            vec![(0.0, 0.2), (0.0, 0.3)],
        )],
    ))
    .unwrap();
    let (_, texts) = parse_xml(&svg);
    assert!(texts.iter().any(|t| t == "1"));
    assert!(texts.iter().any(|t| t == "0.5"));
}

#[test]
fn helpers_build_three_series_with_the_right_values() {
    let tree = parse_file(Path::new("trees/search-and-grasp.yaml")).unwrap();
    let times = [0.0, 100.0, 1000.0];
    let exact = curve(&tree, 0, &times, &CurveOptions::default()).unwrap();
    let s = curve_series("exact", &exact, Style::Dashed);
    assert_eq!(
        s.iter().map(|s| s.label.as_str()).collect::<Vec<_>>(),
        ["exact: success", "exact: failure", "exact: running"]
    );
    assert_eq!(
        s.iter().map(|s| s.kind).collect::<Vec<_>>(),
        SeriesKind::ALL
    );
    assert!(s.iter().all(|s| s.style == Style::Dashed));
    assert_eq!(s[0].points[1], (100.0, exact[1].success));
    assert_eq!(s[1].points[2], (1000.0, exact[2].failure));
    assert_eq!(s[2].points[0], (0.0, 1.0));
    assert_eq!(curve_series("", &exact, Style::Solid)[0].label, "success");

    let opts = SimOptions {
        runs: 1000,
        times: times.to_vec(),
        per_node: false,
        ..Default::default()
    };
    let mc = simulate(&tree, &opts, None).unwrap();
    let m = mc_series("Monte Carlo", &mc.curve, Marker::Circle);
    assert_eq!(m[1].label, "Monte Carlo: failure");
    assert!(m.iter().all(|s| s.style == Style::Markers(Marker::Circle)));
    assert_eq!(m[0].points[2], (1000.0, mc.curve[2].success.mean));
    assert_eq!(m[2].points[1], (100.0, mc.curve[1].running.mean));
}

#[test]
fn search_and_grasp_with_monte_carlo_overlay() {
    let tree = parse_file(Path::new("trees/search-and-grasp.yaml")).unwrap();
    let times: Vec<f64> = (0..=200).map(|i| 5.0 * i as f64).collect();
    let exact = curve(&tree, 0, &times, &CurveOptions::default()).unwrap();
    let mc_times: Vec<f64> = (0..=40).map(|i| 25.0 * i as f64).collect();
    let opts = SimOptions {
        runs: 100_000,
        times: mc_times.clone(),
        per_node: false,
        ..Default::default()
    };
    let mc = simulate(&tree, &opts, None).unwrap();
    let mut series = curve_series("exact", &exact, Style::Solid);
    series.extend(mc_series(
        "Monte Carlo (10^5 runs)",
        &mc.curve,
        Marker::Cross,
    ));
    let spec = PlotSpec::new("search and grasp: π(t) of the root", series);
    let svg = render_svg(&spec).unwrap();
    if let Ok(out) = std::env::var("BTREL_PLOT_OUT") {
        std::fs::write(out, &svg).unwrap();
    }

    let (elements, texts) = parse_xml(&svg);
    // compact legend: the three colours, then one entry per overlay
    for want in [
        "success",
        "failure",
        "running",
        "exact",
        "Monte Carlo (10^5 runs)",
    ] {
        assert!(texts.iter().any(|t| t == want), "legend lacks {want}");
    }
    assert!(texts.iter().any(|t| t == "1000"));
    let (w, h) = view_box(&elements);
    let mut finals = Vec::new();
    for kind in SeriesKind::ALL {
        let lines = polylines(&elements, kind);
        assert_eq!(lines.len(), 1);
        let p = points_of(lines[0]);
        assert_eq!(p.len(), times.len());
        assert!(p.windows(2).all(|w| w[0].0 <= w[1].0), "x monotone");
        assert!(p.first().unwrap().0 < p.last().unwrap().0);
        assert!(p.iter().all(|&(x, y)| x > 0.0 && x < w && y > 0.0 && y < h));
        finals.push(p.last().unwrap().1);
        // an 'x' is two lines; the legend's marker sample is grey
        assert_eq!(lines_of(&elements, kind), 2 * mc_times.len());
    }
    // at t = 1000: failure (0.509) above success (0.488) above running (0.003)
    // (higher means a smaller SVG y)
    assert!(finals[1] < finals[0] && finals[0] < finals[2]);
}
