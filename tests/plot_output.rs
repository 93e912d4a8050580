//! `plot` output: real PNG files with rendered text, refused extensions,
//! default horizons from the tree's figures, deadline markers, Monte Carlo
//! markers per node, `--timing both` labels, wrapped titles.

use btrel::curve::{curve, CurveOptions, Timing};
use btrel::plot::{default_horizon, render_svg, PlotSpec, Series, SeriesKind, Style};
use btrel::tree::{parse_str, Tree};

mod common;
use common::run_btrel as btrel;

/// Parallel (M = N = 2) of a fixed-time and a random action.
const MIXED: &str = "tree:
  parallel:
    name: both
    children:
      - action: {name: fixed, ps: 0.9, tau_s: 2.0, tau_f: 1.0}
      - action: {name: random, ps: 0.8, mu: 0.5, nu: 1.0}
";

/// Every action with fixed times: instants 1 (a fails), 4.5, 5 and 7.5.
const FIXED: &str = "tree:
  sequence:
    name: root
    children:
      - action: {name: a, ps: 0.9, tau_s: 2.0, tau_f: 1.0}
      - fallback:
          name: f
          children:
            - action: {name: b, ps: 0.5, tau_s: 3.0, tau_f: 1.5}
            - action: {name: c, ps: 0.8, tau_s: 1.0, tau_f: 4.0}
";

/// The text contents of an SVG's `<text>` elements, trimmed.
fn texts(svg: &str) -> Vec<String> {
    svg.split("<text")
        .skip(1)
        .filter_map(|t| {
            t.split_once('>')
                .and_then(|(_, r)| r.split_once('<'))
                .map(|(x, _)| x.trim().to_string())
        })
        .collect()
}

fn decode(bytes: &[u8]) -> (u32, u32, Vec<u8>) {
    let decoder = png::Decoder::new(std::io::Cursor::new(bytes));
    let mut reader = decoder.read_info().unwrap();
    let mut buf = vec![0; reader.output_buffer_size()];
    let info = reader.next_frame(&mut buf).unwrap();
    assert_eq!(info.color_type, png::ColorType::Rgb);
    assert_eq!(info.bit_depth, png::BitDepth::Eight);
    buf.truncate(info.buffer_size());
    (info.width, info.height, buf)
}

#[test]
fn png_is_a_real_png_with_rendered_text() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("sg.png");
    let p = path.to_str().unwrap();
    let (code, _, err) = btrel(&[
        "plot",
        "trees/search-and-grasp.yaml",
        "-o",
        p,
        "--mc",
        "2000",
    ]);
    assert_eq!(code, 0, "{err}");
    let bytes = std::fs::read(&path).unwrap();
    assert_eq!(&bytes[..8], b"\x89PNG\r\n\x1a\n");
    let (w, h, px) = decode(&bytes);
    assert_eq!((w, h), (960, 600));
    let pixel = |x: u32, y: u32| {
        let i = ((y * w + x) * 3) as usize;
        (px[i], px[i + 1], px[i + 2])
    };
    // the background is white; the title band (top 40 rows, centre half)
    // holds dark glyph pixels, and nothing else is drawn there
    assert_eq!(pixel(2, 2), (255, 255, 255));
    let dark = (0..40)
        .flat_map(|y| (w / 4..3 * w / 4).map(move |x| (x, y)))
        .filter(|&(x, y)| {
            let (r, g, b) = pixel(x, y);
            r < 100 && g < 100 && b < 100
        })
        .count();
    assert!(dark > 200, "only {dark} dark pixels in the title band");
    // the curves' colours appear (success green)
    let green = (0..h)
        .flat_map(|y| (0..w).map(move |x| (x, y)))
        .filter(|&(x, y)| pixel(x, y) == (0x2C, 0xA0, 0x2C))
        .count();
    assert!(green > 100, "{green} green pixels");
}

#[test]
fn unknown_extensions_are_refused_and_svg_is_svg() {
    let dir = tempfile::tempdir().unwrap();
    for name in ["x.pdf", "x", "x.svg.txt"] {
        let path = dir.path().join(name);
        let (code, _, err) = btrel(&[
            "plot",
            "trees/search-and-grasp.yaml",
            "-o",
            path.to_str().unwrap(),
        ]);
        assert_eq!(code, 2, "{name}: {err}");
        assert!(err.contains(".svg") && err.contains(".png"), "{err}");
        assert!(!path.exists());
    }
    let path = dir.path().join("noext");
    let (code, _, err) = btrel(&[
        "plot",
        "trees/search-and-grasp.yaml",
        "-o",
        path.to_str().unwrap(),
        "--format",
        "png",
    ]);
    assert_eq!(code, 0, "{err}");
    assert_eq!(&std::fs::read(&path).unwrap()[..8], b"\x89PNG\r\n\x1a\n");
    let path = dir.path().join("X.SVG");
    let (code, _, err) = btrel(&[
        "plot",
        "trees/search-and-grasp.yaml",
        "-o",
        path.to_str().unwrap(),
    ]);
    assert_eq!(code, 0, "{err}");
    let text = std::fs::read_to_string(&path).unwrap();
    assert!(text.starts_with("<svg"));
    assert!(
        text.contains("DejaVu Sans"),
        "the bundled font is named first"
    );
}

#[test]
fn default_horizon_of_a_fixed_and_random_parallel() {
    // For t >= 2 the node runs iff the fixed action succeeded (0.9) and the
    // random one has not returned: 0.9 (0.8 e^{-t/2} + 0.2 e^{-t}), which
    // is 1e-3 at t ≈ 2 ln(720) = 13.16.
    let tree = parse_str(MIXED, "mixed.yaml").unwrap();
    let running = |t: f64| 0.9 * (0.8 * (-t / 2.0).exp() + 0.2 * (-t).exp());
    let settled = 13.16;
    assert!(running(settled) < 1.001e-3 && running(settled - 0.05) > 1e-3);
    let h = default_horizon(&[(
        Ok(&btrel::Model::new(&tree).unwrap()),
        Tree::ROOT,
        Timing::AsGiven,
    )]);
    assert!(h >= settled && h <= 2.0 * settled, "horizon {h}");
    // the curve agrees with the closed form there
    let p = curve(&tree, Tree::ROOT, &[h], &CurveOptions::default()).unwrap();
    assert!((p[0].running - running(h)).abs() < 1e-9);
    // and the CLI uses it: no 1e-9 axis
    let dir = tempfile::tempdir().unwrap();
    let tree_path = dir.path().join("mixed.yaml");
    std::fs::write(&tree_path, MIXED).unwrap();
    let out = dir.path().join("m.svg");
    let (code, _, err) = btrel(&[
        "plot",
        tree_path.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
    ]);
    assert_eq!(code, 0, "{err}");
    let svg = std::fs::read_to_string(&out).unwrap();
    // x ticks follow the y ticks (0.0 … 1.0); the last is near the horizon
    let t = texts(&svg);
    let after_y = t.iter().position(|x| x == "1.0").unwrap() + 1;
    let ticks: Vec<f64> = t[after_y..].iter().map_while(|x| x.parse().ok()).collect();
    let last = ticks.iter().copied().fold(0.0, f64::max);
    assert!(
        ticks.len() >= 3 && last <= h && last >= 0.75 * h,
        "{ticks:?} for {h}"
    );
}

#[test]
fn default_horizon_ends_after_the_last_instant_and_where_curves_settle() {
    let tree = parse_str(FIXED, "fixed.yaml").unwrap();
    let h = default_horizon(&[(
        Ok(&btrel::Model::new(&tree).unwrap()),
        Tree::ROOT,
        Timing::AsGiven,
    )]);
    assert!((7.5..=7.5 * 1.6).contains(&h), "horizon {h}");
    // search and grasp: settled (running ≤ 1e-3) by the horizon, not at half of it
    let sg = btrel::tree::parse_file(std::path::Path::new("trees/search-and-grasp.yaml")).unwrap();
    let h = default_horizon(&[(
        Ok(&btrel::Model::new(&sg).unwrap()),
        Tree::ROOT,
        Timing::AsGiven,
    )]);
    let p = curve(&sg, Tree::ROOT, &[h / 2.0, h], &CurveOptions::default()).unwrap();
    assert!(
        p[1].running <= 1e-3 && p[0].running > 1e-3,
        "horizon {h}: {p:?}"
    );
    // a tree that takes no time
    let zero = parse_str("tree: {condition: {name: c, ps: 0.5}}", "c.yaml").unwrap();
    assert_eq!(
        default_horizon(&[(
            Ok(&btrel::Model::new(&zero).unwrap()),
            Tree::ROOT,
            Timing::AsGiven
        )]),
        1.0
    );
}

#[test]
fn deadline_marker_mc_markers_per_node_and_timing_labels() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("o.svg");
    let o = out.to_str().unwrap();
    let (code, _, err) = btrel(&[
        "plot",
        "trees/search-and-grasp.yaml",
        "-o",
        o,
        "--compare",
        "search",
        "--deadline",
        "100",
        "--top",
        "1",
    ]);
    assert_eq!(code, 0, "{err}");
    let svg = std::fs::read_to_string(&out).unwrap();
    assert!(
        texts(&svg).iter().any(|t| t == "deadline 100 s"),
        "deadline label"
    );
    assert!(svg.contains("#555555"), "the deadline line");

    let (code, _, err) = btrel(&[
        "plot",
        "trees/search-and-grasp.yaml",
        "-o",
        o,
        "--node",
        "search",
        "--node",
        "grasp",
        "--mc",
        "1000",
    ]);
    assert_eq!(code, 0, "{err}");
    let svg = std::fs::read_to_string(&out).unwrap();
    // first node: crosses (lines), second: circles; legend names both
    assert!(
        svg.matches("<circle").count() >= 3 * 41,
        "circles for the second node"
    );
    let t = texts(&svg);
    assert!(
        t.iter().any(|x| x == "search, Monte Carlo") && t.iter().any(|x| x == "grasp, Monte Carlo")
    );

    let dir2 = tempfile::tempdir().unwrap();
    let fixed = dir2.path().join("fixed.yaml");
    std::fs::write(&fixed, FIXED).unwrap();
    let (code, _, err) = btrel(&["plot", fixed.to_str().unwrap(), "-o", o, "--timing", "both"]);
    assert_eq!(code, 0, "{err}");
    assert!(err.contains("fixed times already"), "{err}");
    let svg = std::fs::read_to_string(&out).unwrap();
    assert!(!svg.contains("stochastic"));
    let (code, _, err) = btrel(&[
        "plot",
        "trees/search-and-grasp.yaml",
        "-o",
        o,
        "--timing",
        "both",
    ]);
    assert_eq!(code, 0, "{err}");
    let svg = std::fs::read_to_string(&out).unwrap();
    let t = texts(&svg);
    assert!(
        t.iter().any(|x| x == "stochastic") && t.iter().any(|x| x == "deterministic (τ = 1/rate)")
    );
}

#[test]
fn long_titles_wrap_within_the_image() {
    let series = vec![Series {
        label: "success".into(),
        kind: SeriesKind::Success,
        style: Style::Solid,
        points: vec![(0.0, 0.0), (1.0, 1.0)],
    }];
    let title = "a rather long title about the orderings of a Fallback with many children, \
                 best by the probability of success by the deadline first";
    let svg = render_svg(&PlotSpec::new(title, series)).unwrap();
    let texts = texts(&svg);
    let parts: Vec<&String> = texts
        .iter()
        .filter(|t| title.contains(t.as_str()) && t.len() > 20)
        .collect();
    assert_eq!(parts.len(), 2, "{texts:?}");
    assert_eq!(format!("{} {}", parts[0], parts[1]), title);
}
