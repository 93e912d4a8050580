//! DOT and PRISM exporters: structure, escaping, and exact round-trips.

mod common;

use common::tree;

use btrel::compile::phase::phase_chain;
use btrel::compile::{analyze, Options};
use btrel::export::{dot_mrg, dot_tree, prism_ctmc, prism_model, PRISM_PROPERTIES};
use btrel::tree::{parse_file, NodeKind, Tree};
use btrel::Figures;

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
    for id in 0..t.nodes().len() {
        assert!(dot.contains(&format!("  n{id} [")), "node {id} missing");
    }
    assert_eq!(edges(&dot), t.nodes().len() - 1);
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
    assert_eq!(edges(&dot), t.nodes().len() - 1);
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
        .nodes()
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

/// A Parallel's PRISM model: one module per child, whose commands are the
/// child's phase chain, rates bit for bit, guarded by the node running.
fn check_prism_modules(t: &Tree, id: usize) -> String {
    let text = prism_ctmc(t, id, 1_000_000).unwrap();
    assert!(text.contains("module outcome\n  o : [0..2];"), "{text}");
    assert!(
        text.contains("formula p0_run = o=0 & !p0_s & !p0_f;"),
        "{text}"
    );
    for (k, &child) in t.node(id).kind.children().iter().enumerate() {
        let chain = phase_chain(t, child, 1_000_000).unwrap();
        let n = chain.len();
        assert!(text.contains(&format!("module c{k}\n  s{k} : [0..{}];", n + 1)));
        let mut expected = Vec::new();
        for i in 0..n {
            for &(j, r) in &chain.transitions[i] {
                expected.push((i, r, j));
            }
            for (r, to) in [(chain.exit_success[i], n), (chain.exit_failure[i], n + 1)] {
                if r > 0.0 {
                    expected.push((i, r, to));
                }
            }
        }
        let prefix = format!("[] p0_run & s{k}=");
        let var = format!(" : (s{k}'=");
        let found: Vec<(usize, f64, usize)> = text
            .lines()
            .filter_map(|l| {
                let l = l.trim().strip_prefix(prefix.as_str())?;
                let (from, rest) = l.split_once(" -> ")?;
                let (rate, rest) = rest.split_once(var.as_str())?;
                let to = rest.strip_suffix(");")?;
                Some((from.parse().ok()?, rate.parse().ok()?, to.parse().ok()?))
            })
            .collect();
        assert_eq!(found, expected, "child {k}:\n{text}");
    }
    text
}

fn check_prism(t: &Tree, id: usize) -> String {
    if matches!(t.node(id).kind, NodeKind::Parallel { .. }) {
        return check_prism_modules(t, id);
    }
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
    for id in 0..t.nodes().len() {
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
    for id in 0..pair.nodes().len() {
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

/// The largest exit rate of a phase: its rates grouped by target and summed
/// in target order (the order a checker reading the files sums them in).
fn fastest(chain: &btrel::solve::chain::PhaseChain) -> f64 {
    grouped(chain)
        .iter()
        .take(chain.len())
        .map(|row| row.values().sum::<f64>())
        .fold(0.0, f64::max)
}

/// Outgoing rates of every state, grouped by target (`BTreeMap` sums).
fn grouped(chain: &btrel::solve::chain::PhaseChain) -> Vec<std::collections::BTreeMap<usize, f64>> {
    let n = chain.len();
    let mut rows = vec![std::collections::BTreeMap::new(); n + 2];
    for (i, row) in rows.iter_mut().enumerate().take(n) {
        for &(j, r) in chain.transitions[i]
            .iter()
            .chain(&[(n, chain.exit_success[i]), (n + 1, chain.exit_failure[i])])
        {
            if r > 0.0 {
                *row.entry(j).or_insert(0.0) += r;
            }
        }
    }
    rows
}

#[test]
fn prism_absorbing_loop_keeps_the_uniformisation_rate() {
    let t = search_and_grasp();
    let chain = phase_chain(&t, 0, 1_000_000).unwrap();
    let text = prism_ctmc(&t, 0, 1_000_000).unwrap();
    // the grasp phase of rate 1 + 1 (two hands: Success 0.05·…) is the
    // fastest; the loop on Success/Failure has exactly that rate
    let q = fastest(&chain);
    assert!(q > 0.0 && q < 1e3);
    let n = chain.len();
    assert!(
        text.contains(&format!(
            "  [] s>={n} -> {} : true;",
            btrel::export::prism::prism_number(q)
        )),
        "{text}"
    );
    assert!(!text.contains("-> 1.0 : true;") || q == 1.0);
    // the initial weights as a reward structure, for Storm
    assert!(text.contains("rewards \"w_init\"\n"));
    for &(i, w) in &chain.initial {
        assert!(text.contains(&format!(
            "  s={i} : {};",
            btrel::export::prism::prism_number(w)
        )));
    }
}

fn explicit_files(chain: &btrel::solve::chain::PhaseChain) -> Vec<String> {
    btrel::export::PRISM_EXPLICIT_EXTENSIONS
        .iter()
        .map(|ext| {
            let mut v = Vec::new();
            btrel::export::write_prism_explicit(chain, ext, &mut v).unwrap();
            String::from_utf8(v).unwrap()
        })
        .collect()
}

#[test]
fn prism_explicit_files_are_the_chain() {
    let t = search_and_grasp();
    let pair = tree(MIXED.replace("tau_s: 2.0", "mu: 0.5").as_str());
    for (t, id) in (0..t.nodes().len())
        .map(|i| (&t, i))
        .chain((0..pair.nodes().len()).map(|i| (&pair, i)))
    {
        let chain = phase_chain(t, id, 1_000_000).unwrap();
        let n = chain.len();
        let files = explicit_files(&chain);
        let (tra, sta, lab, srew) = (&files[0], &files[1], &files[2], &files[3]);
        // .tra: header, then rows in order, rates bit for bit
        let mut lines = tra.lines();
        let header: Vec<usize> = lines
            .next()
            .unwrap()
            .split(' ')
            .map(|x| x.parse().unwrap())
            .collect();
        let rows = grouped(&chain);
        let mut expected: Vec<(usize, usize, f64)> = rows
            .iter()
            .enumerate()
            .flat_map(|(i, r)| r.iter().map(move |(&j, &x)| (i, j, x)))
            .collect();
        let q = if n == 0 { 1.0 } else { fastest(&chain) };
        expected.push((n, n, q));
        expected.push((n + 1, n + 1, q));
        let got: Vec<(usize, usize, f64)> = lines
            .map(|l| {
                let f: Vec<&str> = l.split(' ').collect();
                assert_eq!(f.len(), 3, "{l}");
                (
                    f[0].parse().unwrap(),
                    f[1].parse().unwrap(),
                    f[2].parse().unwrap(),
                )
            })
            .collect();
        assert_eq!(header, vec![n + 2, expected.len()]);
        assert_eq!(got, expected);
        // .sta: the variable s is the state index
        assert!(sta.starts_with("(s)\n0:(0)\n"));
        assert_eq!(sta.lines().count(), n + 3);
        assert!(sta.ends_with(&format!("{}:({})\n", n + 1, n + 1)));
        // .lab: init on the states of positive initial probability
        let mut init: Vec<usize> = chain.initial.iter().map(|&(i, _)| i).collect();
        if chain.initial_success > 0.0 {
            init.push(n);
        }
        if chain.initial_failure > 0.0 {
            init.push(n + 1);
        }
        init.sort();
        init.dedup();
        let mut lab_lines = lab.lines();
        assert_eq!(
            lab_lines.next(),
            Some("0=\"init\" 1=\"success\" 2=\"failure\" 3=\"done\" 4=\"running\"")
        );
        let labelled: Vec<(usize, Vec<&str>)> = lab_lines
            .map(|l| {
                let (s, ls) = l.split_once(": ").unwrap();
                (s.parse().unwrap(), ls.split(' ').collect())
            })
            .collect();
        assert_eq!(labelled.len(), n + 2);
        for (s, ls) in &labelled {
            assert_eq!(ls.contains(&"0"), init.contains(s), "state {s}");
            let rest: Vec<&str> = ls.iter().copied().filter(|&l| l != "0").collect();
            let want: &[&str] = if *s < n {
                &["4"]
            } else if *s == n {
                &["1", "3"]
            } else {
                &["2", "3"]
            };
            assert_eq!(rest, want);
        }
        // .srew: 1 per unit time in every phase
        let mut want = format!("{} {n}\n", n + 2);
        for i in 0..n {
            want.push_str(&format!("{i} 1.0\n"));
        }
        assert_eq!(srew, &want);
        // the properties weight by the same initial distribution
        let props = btrel::export::prism_explicit_properties(&chain, &[]);
        assert_eq!(props.matches("filter(+, (").count(), 5);
        assert!(props.contains("R=? [ F \"done\" ]"));
    }
}

#[test]
fn drn_is_the_chain_with_weights() {
    let t = search_and_grasp();
    let chain = phase_chain(&t, 0, 1_000_000).unwrap();
    let n = chain.len();
    let mut v = Vec::new();
    btrel::export::write_drn(&chain, "root", &mut v).unwrap();
    let text = String::from_utf8(v).unwrap();
    assert!(text.contains("@type: CTMC\n") && text.contains("@reward_models\ntime w_init\n"));
    assert!(text.contains(&format!("@nr_states\n{}\n@nr_choices\n{}\n", n + 2, n + 2)));
    let rows = grouped(&chain);
    let q = fastest(&chain);
    let body = text.split("@model\n").nth(1).unwrap();
    let mut states = body.split("state ").skip(1);
    for (i, row) in rows.iter().enumerate() {
        let block = states.next().unwrap();
        let mut lines = block.lines();
        let head: Vec<&str> = lines.next().unwrap().split(' ').collect();
        assert_eq!(head[0].parse::<usize>().unwrap(), i);
        let exit: f64 = head[1].strip_prefix('!').unwrap().parse().unwrap();
        assert_eq!(lines.next(), Some("\taction 0"));
        let out: Vec<(usize, f64)> = lines
            .map(|l| {
                let (j, r) = l.trim().split_once(" : ").unwrap();
                (j.parse().unwrap(), r.parse().unwrap())
            })
            .collect();
        let want: Vec<(usize, f64)> = if i < n {
            row.iter().map(|(&j, &r)| (j, r)).collect()
        } else {
            vec![(i, q)]
        };
        assert_eq!(out, want, "state {i}");
        assert_eq!(exit, want.iter().map(|&(_, r)| r).sum::<f64>());
        let w = chain
            .initial
            .iter()
            .find(|&&(s, _)| s == i)
            .map_or(0.0, |&(_, w)| w);
        let rewards = format!(
            "[{}, {}]",
            if i < n { "1.0" } else { "0.0" },
            btrel::export::prism::prism_number(w)
        );
        assert!(block.contains(&rewards), "{block}");
        assert_eq!(block.contains(" init"), w > 0.0, "{block}");
        assert_eq!(block.contains(" done"), i >= n, "{block}");
    }
}

#[test]
fn cli_explicit_and_drn_exports() {
    use assert_cmd::Command;
    let tree = concat!(env!("CARGO_MANIFEST_DIR"), "/trees/search-and-grasp.yaml");
    let dir = tempfile::tempdir().unwrap();
    // four files from -o BASE (a .tra or .all extension names the same set)
    for base in ["sg", "sg2.tra", "sg3.all"] {
        let out = dir.path().join(base);
        Command::cargo_bin("btrel")
            .unwrap()
            .args(["export", tree, "--to", "prism-explicit", "-o"])
            .arg(&out)
            .arg("--properties")
            .arg(dir.path().join("p.csl"))
            .assert()
            .success();
        let stem = out.with_extension("");
        for ext in ["tra", "sta", "lab", "srew"] {
            assert!(stem.with_extension(ext).is_file(), "{base}: .{ext}");
        }
    }
    let csl = std::fs::read_to_string(dir.path().join("p.csl")).unwrap();
    assert!(
        csl.contains("(s=0 ? 0.3 : 0.0) + (s=1 ? 0.7 : 0.0)"),
        "{csl}"
    );
    let mut names: Vec<String> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    assert_eq!(names.len(), 13, "{names:?}");
    // no -o: refused, nothing written
    let fail = Command::cargo_bin("btrel")
        .unwrap()
        .current_dir(dir.path())
        .args(["export", tree, "--to", "prism-explicit"])
        .assert()
        .code(2);
    let err = String::from_utf8_lossy(&fail.get_output().stderr).into_owned();
    assert!(err.contains("-o BASE"), "{err}");
    // DRN to standard output; --properties refused with the reason
    let drn = Command::cargo_bin("btrel")
        .unwrap()
        .args(["export", tree, "--to", "drn"])
        .assert()
        .success();
    assert!(String::from_utf8_lossy(&drn.get_output().stdout).contains("@type: CTMC"));
    let fail = Command::cargo_bin("btrel")
        .unwrap()
        .args(["export", tree, "--to", "drn", "--properties", "x.csl"])
        .assert()
        .code(2);
    let err = String::from_utf8_lossy(&fail.get_output().stderr).into_owned();
    assert!(err.contains("w_init"), "{err}");
    Command::cargo_bin("btrel")
        .unwrap()
        .args(["export", tree, "--to", "drn", "--mrg", "search"])
        .assert()
        .code(2);
    // a failed set leaves none of its files: a directory named like one file
    let blocked = dir.path().join("blocked");
    std::fs::create_dir(dir.path().join("blocked.lab")).unwrap();
    Command::cargo_bin("btrel")
        .unwrap()
        .args(["export", tree, "--to", "prism-explicit", "-o"])
        .arg(&blocked)
        .assert()
        .code(2);
    for ext in ["tra", "sta", "srew"] {
        assert!(!blocked.with_extension(ext).exists(), ".{ext} written");
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
