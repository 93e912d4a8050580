//! DOT and PRISM exporters: structure, escaping, and exact round-trips.

use btrel::compile::phase::phase_chain;
use btrel::compile::{analyze, Options};
use btrel::export::{dot_mrg, dot_tree, prism_ctmc, prism_model, PRISM_PROPERTIES};
use btrel::tree::{parse_file, parse_str, Tree};
use btrel::Figures;

fn tree(yaml: &str) -> Tree {
    parse_str(yaml, "test.yaml").unwrap_or_else(|e| panic!("{e}"))
}

fn search_and_grasp() -> Tree {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/trees/search-and-grasp.yaml");
    parse_file(std::path::Path::new(path)).unwrap_or_else(|e| panic!("{e}"))
}

const MIXED: &str = r#"
name: "a \"quoted\" \\ title"
tree:
  sequence:
    name: root
    children:
      - condition: {name: 'say "hi" \ there', ps: 0.9}
      - parallel:
          name: par
          success_threshold: 1
          failure_threshold: 1
          children:
            - action: {name: a, ps: 0.3, mu: 1.0, nu: 2.0}
            - action: {name: b, ps: 0.6, mu: 0.5, nu: 0.25}
      - retry:
          attempts: 3
          child: {action: {name: c, ps: 0.5, mu: 1.0, nu: 2.0}}
      - fallback:
          children:
            - action: {name: d, ps: 1.0, tau_s: 2.0}
            - inverter: {child: {condition: {ps: 0.2}}}
"#;

fn edges(dot: &str) -> usize {
    dot.lines().filter(|l| l.contains(" -> ")).count()
}

fn balanced(dot: &str) -> bool {
    // braces outside double-quoted strings
    let (mut depth, mut in_str, mut esc) = (0i64, false, false);
    for c in dot.chars() {
        if in_str {
            match (esc, c) {
                (true, _) => esc = false,
                (false, '\\') => esc = true,
                (false, '"') => in_str = false,
                _ => {}
            }
            continue;
        }
        match c {
            '"' => in_str = true,
            '{' => depth += 1,
            '}' => {
                depth -= 1;
                if depth < 0 {
                    return false;
                }
            }
            _ => {}
        }
    }
    depth == 0 && !in_str
}

/// Runs `dot -Tsvg` on `text` when Graphviz is installed.
fn graphviz_accepts(text: &str) {
    use std::io::Write;
    use std::process::{Command, Stdio};
    let Ok(mut child) = Command::new("dot")
        .arg("-Tsvg")
        .stdin(Stdio::piped())
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
    else {
        eprintln!("graphviz `dot` not installed: skipping the rendering check");
        return;
    };
    child
        .stdin
        .take()
        .unwrap()
        .write_all(text.as_bytes())
        .unwrap();
    let out = child.wait_with_output().unwrap();
    assert!(
        out.status.success(),
        "dot failed: {}\n{text}",
        String::from_utf8_lossy(&out.stderr)
    );
}

#[test]
fn dot_tree_structure_symbols_and_escaping() {
    let t = tree(MIXED);
    let dot = dot_tree(&t, None);
    assert!(dot.starts_with("digraph"));
    assert!(balanced(&dot), "{dot}");
    assert!(dot.contains("ordering=out"));
    for id in 0..t.nodes.len() {
        assert!(dot.contains(&format!("  n{id} [")), "node {id} missing");
    }
    assert_eq!(edges(&dot), t.nodes.len() - 1);
    for symbol in ["→", "?", "⇒ M/N = 1/2, F = 1", "◇ retry 3", "◇ inverter"] {
        assert!(dot.contains(symbol), "{symbol} missing:\n{dot}");
    }
    // quotes and backslashes escaped, in names and the title
    assert!(dot.contains(r#"say \"hi\" \\ there"#), "{dot}");
    assert!(dot.contains(r#"a \"quoted\" \\ title"#), "{dot}");
    // actions are boxes with ps and mean times; conditions ellipses
    assert!(
        dot.contains("shape=box, label=\"a\\nps = 0.3\\nMTTS = 1 (μ = 1)\\nMTTF = 0.5 (ν = 2)\"")
    );
    assert!(dot.contains("shape=box, label=\"d\\nps = 1\\nMTTS = 2 (τs = 2)\""));
    assert!(dot.contains("shape=ellipse"));
    graphviz_accepts(&dot);
}

#[test]
fn dot_tree_book_parallel_has_no_f_and_analysis_annotates_control_nodes() {
    let t = search_and_grasp();
    let a = analyze(&t, &Options::default()).unwrap();
    let dot = dot_tree(&t, Some(&a));
    assert!(balanced(&dot));
    assert_eq!(edges(&dot), t.nodes.len() - 1);
    // root: ps = 0.48840
    assert!(dot.contains("ps = 0.4884, MTTS = 169.38"), "{dot}");
    // conditions with ps = 0 have no MTTS; they are leaves, not annotated
    assert_eq!(dot.matches("MTTS = ").count(), 5 + 5);
    let p = dot_tree(
        &tree("tree: {parallel: {success_threshold: 2, children: [{action: {ps: 0.5, mu: 1, nu: 1}}, {action: {ps: 0.5, mu: 1, nu: 1}}]}}"),
        None,
    );
    assert!(p.contains("⇒ M/N = 2/2\\n") && !p.contains(", F = "), "{p}");
    graphviz_accepts(&dot);
}

fn figs(t: &Tree, id: usize) -> Vec<Figures> {
    let a = analyze(t, &Options::default()).unwrap();
    t.node(id)
        .kind
        .children()
        .iter()
        .map(|&c| a.nodes[c])
        .collect()
}

#[test]
fn mrg_of_sequence_of_three() {
    let t = tree(
        "tree: {sequence: {children: [{action: {ps: 0.3, mu: 1, nu: 2}}, {condition: {ps: 0.5}}, {action: {ps: 0.9, mu: 1, nu: 2}}]}}",
    );
    let dot = dot_mrg(&t, 0, &figs(&t, 0)).unwrap();
    assert!(balanced(&dot));
    assert_eq!(dot.matches("[label=\"[").count(), 7, "{dot}");
    assert_eq!(edges(&dot), 6);
    assert!(dot.contains("m0 [label=\"[0,0,0]\", penwidth=2]"));
    assert!(dot.contains("m3 [label=\"[1,1,1]\", style=\"rounded,filled\", fillcolor=palegreen"));
    assert!(dot.contains("[label=\"[1,-1,0]\", style=\"rounded,filled\", fillcolor=lightpink"));
    assert!(dot.contains("m0 -> m1 [label=\"h1 S\\np = 0.3\"]"), "{dot}");
    assert!(dot.contains("m0 -> m4 [label=\"h1 F\\np = 0.7\"]"), "{dot}");
    graphviz_accepts(&dot);
}

#[test]
fn mrg_of_parallel_two_of_two_uses_rate_shares() {
    // SJ = 0.5·1 + 0.5·0.5 = 0.75 and 0.5·2 + 0.5·1 = 1.5: shares 2/3, 1/3
    let t = tree(
        "tree: {parallel: {success_threshold: 2, children: [{action: {ps: 0.5, mu: 1, nu: 2}}, {action: {ps: 0.5, mu: 0.5, nu: 1}}]}}",
    );
    let dot = dot_mrg(&t, 0, &figs(&t, 0)).unwrap();
    assert!(balanced(&dot));
    assert_eq!(dot.matches("[label=\"[").count(), 8, "{dot}");
    // from [0,0]: 4 events; from [1,0] and [0,1]: 2 each
    assert_eq!(edges(&dot), 8);
    let p = |x: f64| format!("{}", format!("{x:.4e}").parse::<f64>().unwrap());
    assert!(
        dot.contains(&format!("h1 S\\np = {}", p(0.5 * 2.0 / 3.0))),
        "{dot}"
    );
    assert!(
        dot.contains(&format!("h2 F\\np = {}", p(0.5 / 3.0))),
        "{dot}"
    );
    graphviz_accepts(&dot);
}

#[test]
fn mrg_of_leaf_or_decorator_is_an_error() {
    let t = tree(MIXED);
    let retry = t
        .nodes
        .iter()
        .position(|n| n.kind.keyword() == "retry")
        .unwrap();
    let e = dot_mrg(&t, retry, &figs(&t, retry)).unwrap_err();
    assert!(
        e.contains("retry") && e.contains("marking reachability graph"),
        "{e}"
    );
    assert!(dot_mrg(&t, 1, &[]).is_err());
    // wrong number of children's figures
    assert!(dot_mrg(&t, 0, &[]).is_err());
}

/// `(from, rate, to)` of every `[] s=i -> r : (s'=j);` command.
fn commands(text: &str) -> Vec<(usize, f64, usize)> {
    text.lines()
        .filter_map(|l| {
            let l = l.trim().strip_prefix("[] s=")?;
            let (from, rest) = l.split_once(" -> ")?;
            let (rate, rest) = rest.split_once(" : (s'=")?;
            let to = rest.strip_suffix(");")?;
            Some((from.parse().ok()?, rate.parse().ok()?, to.parse().ok()?))
        })
        .collect()
}

fn check_prism(t: &Tree, id: usize) -> String {
    let chain = phase_chain(t, id, 1_000_000).unwrap();
    let text = prism_ctmc(t, id, 1_000_000).unwrap();
    let n = chain.len();
    for needle in [
        "ctmc\n",
        "module btrel\n",
        "endmodule\n",
        &format!("label \"success\" = s={n};"),
        &format!("label \"failure\" = s={};", n + 1),
        &format!("s : [0..{}]", n + 1),
        "formula w_init = ",
        "rewards \"time\"",
    ] {
        assert!(text.contains(needle), "{needle} missing:\n{text}");
    }
    let mut expected: Vec<(usize, f64, usize)> = Vec::new();
    for i in 0..n {
        expected.extend(
            chain.transitions[i]
                .iter()
                .filter(|&&(_, r)| r > 0.0)
                .map(|&(j, r)| (i, r, j)),
        );
        for (r, to) in [(chain.exit_success[i], n), (chain.exit_failure[i], n + 1)] {
            if r > 0.0 {
                expected.push((i, r, to));
            }
        }
    }
    // rates parse back bit for bit, one command per transition or exit
    assert_eq!(commands(&text), expected);
    // plus the single absorbing self-loop
    assert_eq!(text.matches("] s").count(), expected.len() + 1);
    text
}

#[test]
fn prism_matches_phase_chains_exactly() {
    let t = search_and_grasp();
    for id in 0..t.nodes.len() {
        check_prism(&t, id);
    }
    let text = check_prism(&t, 0);
    // the root starts in a mixture: several initial states, weighted
    let chain = phase_chain(&t, 0, 1_000_000).unwrap();
    assert!(chain.initial.len() > 1);
    assert!(text.contains("\ninit\n") && text.contains("endinit"));
    for &(i, w) in &chain.initial {
        assert!(text.contains(&format!(
            "(s={i} ? {} : 0.0)",
            btrel::export::prism::prism_number(w)
        )));
    }
    let pair = tree(MIXED.replace("tau_s: 2.0", "mu: 0.5").as_str());
    for id in 0..pair.nodes.len() {
        check_prism(&pair, id);
    }
}

#[test]
fn prism_instantaneous_outcomes_are_initial_states() {
    // a condition: no phases, Success/Failure mass at s=0 / s=1
    let t = tree("tree: {condition: {ps: 0.25}}");
    let text = check_prism(&t, 0);
    assert!(text.contains("s : [0..1];"));
    assert!(text.contains("init\n  s=0 | s=1\nendinit"), "{text}");
    assert!(text.contains("formula w_init = (s=0 ? 0.25 : 0.0) + (s=1 ? 0.75 : 0.0);"));
    // sequence(condition, action): instantaneous failure plus the action's phases
    let t = tree(
        "tree: {sequence: {children: [{condition: {ps: 0.5}}, {action: {ps: 0.5, mu: 3, nu: 1e-7}}]}}",
    );
    let text = check_prism(&t, 0);
    assert!(text.contains("s=3 ? 0.5"), "{text}");
    assert!(text.contains("1e-7 : (s'=3)"), "{text}");
    // a single initial state uses the variable's init
    let t = tree("tree: {action: {ps: 1.0, mu: 2}}");
    let text = check_prism(&t, 0);
    assert!(
        text.contains("s : [0..2] init 0;") && !text.contains("endinit"),
        "{text}"
    );
}

#[test]
fn prism_numbers_round_trip_in_prism_syntax() {
    use btrel::export::prism::prism_number;
    for x in [
        1.0,
        0.0167,
        0.1 + 0.2,
        1e-5,
        1.5e-300,
        1e15,
        1e20,
        123456.789,
        2.0 / 3.0,
    ] {
        let s = prism_number(x);
        assert_eq!(s.parse::<f64>().unwrap(), x, "{s}");
        // PRISM's REG_DOUBLE: digits* '.'? digits+ ([eE][+-]?digits+)?, not an integer
        let (mantissa, exp) = s.split_once('e').unwrap_or((&s, "0"));
        assert!(s.contains('.') || s.contains('e'), "{s}");
        assert!(
            !mantissa.ends_with('.') && mantissa.chars().all(|c| c.is_ascii_digit() || c == '.')
        );
        assert!(exp
            .trim_start_matches('-')
            .chars()
            .all(|c| c.is_ascii_digit()));
    }
    let m = prism_model(&Default::default(), "empty");
    assert!(m.contains("ctmc") && m.contains("init\n  false\nendinit"));
    for p in [
        "const double T;",
        "filter(+, w_init * P=? [ F<=T \"success\" ], \"init\")",
    ] {
        assert!(PRISM_PROPERTIES.contains(p));
    }
}

#[test]
fn dot_control_nodes_are_compact_boxes_not_squares() {
    // a `square` grows to its label's width in both directions
    let tree =
        btrel::tree::parse_file(std::path::Path::new("trees/search-and-grasp.yaml")).unwrap();
    let dot = btrel::export::dot_tree(&tree, None);
    assert!(
        !dot.contains("shape=square") && !dot.contains("shape=diamond"),
        "{dot}"
    );
    let control = dot
        .lines()
        .filter(|l| l.contains("label=\"?\\n") || l.contains("label=\"→\\n"))
        .count();
    assert_eq!(control, 5, "{dot}");
    assert!(dot
        .lines()
        .filter(|l| l.contains("label=\"?\\n") || l.contains("label=\"→\\n"))
        .all(|l| l.contains("shape=box, style=\"rounded,filled\"")));
}
