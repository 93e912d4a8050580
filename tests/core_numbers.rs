//! Numbers from independent derivations: the book's Table 9.1, closed forms
//! (eqs. 9.74–9.75), hand calculations, and `reference/refs.json` (computed
//! offline with exact rationals / mpmath, see `reference/README.md`).
//!
//! No expected value in this file was taken from btrel's own output.

use std::path::{Path, PathBuf};

use approx::assert_relative_eq;
use btrel::compile::{analyze, Analysis, AnalysisError, Figures, Method, Options};
use btrel::tree::{parse_file, parse_str, Tree};
use serde_json::Value;

const METHODS: [Method; 2] = [Method::Exact, Method::Book];

fn repo(rel: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(rel)
}

fn load(rel: &str) -> Tree {
    parse_file(&repo(rel)).unwrap_or_else(|e| panic!("{rel} must parse: {e}"))
}

fn run(tree: &Tree, method: Method) -> Analysis {
    let options = Options {
        method,
        ..Options::default()
    };
    analyze(tree, &options).unwrap_or_else(|e| panic!("analysis ({method:?}) failed: {e}"))
}

fn fig(tree: &Tree, a: &Analysis, name: &str) -> Figures {
    let id = tree
        .find(name)
        .unwrap_or_else(|| panic!("node '{name}' not found"));
    a.nodes[id]
}

fn refs() -> Value {
    let text = std::fs::read_to_string(repo("reference/refs.json")).expect("reference/refs.json");
    serde_json::from_str(&text).expect("refs.json is JSON")
}

fn num(v: &Value) -> Option<f64> {
    if v.is_null() {
        None
    } else {
        Some(v.as_f64().unwrap_or_else(|| panic!("not a number: {v}")))
    }
}

/// Parses "a/b" from refs.json's `*_exact_fraction` fields.
fn fraction(v: &Value) -> f64 {
    let s = v.as_str().expect("fraction string");
    let (a, b) = s.split_once('/').unwrap_or((s, "1"));
    a.parse::<f64>().unwrap() / b.parse::<f64>().unwrap()
}

fn close(what: &str, got: f64, want: f64, rel: f64) {
    let ok = if want == 0.0 {
        got.abs() <= rel
    } else {
        ((got - want) / want).abs() <= rel
    };
    assert!(
        ok,
        "{what}: got {got:e}, expected {want:e} (relative tolerance {rel:e})"
    );
}

fn close_opt(what: &str, got: Option<f64>, want: Option<f64>, rel: f64) {
    match (got, want) {
        (Some(g), Some(w)) => close(what, g, w, rel),
        (None, None) => {}
        _ => panic!("{what}: got {got:?}, expected {want:?}"),
    }
}

/// Checks a node against a refs.json node record (ps, pf, MTTS, MTTF, mu, nu).
fn check_record(what: &str, f: &Figures, r: &Value, rel: f64) {
    close(&format!("{what} ps"), f.ps, num(&r["ps"]).unwrap(), rel);
    close(&format!("{what} pf"), f.pf, num(&r["pf"]).unwrap(), rel);
    close_opt(&format!("{what} MTTS"), f.mtts, num(&r["MTTS"]), rel);
    close_opt(&format!("{what} MTTF"), f.mttf, num(&r["MTTF"]), rel);
    close_opt(&format!("{what} mu"), f.mu(), num(&r["mu"]), rel);
    close_opt(&format!("{what} nu"), f.nu(), num(&r["nu"]), rel);
}

// ---------------------------------------------------------------------------
// Table 9.1 (search and grasp, Example 9.9)
// ---------------------------------------------------------------------------

/// The book prints 5 significant digits (x.xxxx e-k). Its values are not
/// consistently rounded (mu0 and mu3 are truncated, nu0 is rounded), so the
/// check is "within one unit of the last printed digit".
fn matches_book(what: &str, got: f64, book: f64) {
    let exponent = book.abs().log10().floor();
    let unit = 1e-4 * 10f64.powf(exponent);
    assert!(
        (got - book).abs() < unit,
        "{what}: got {got:.6e}, book prints {book:.4e} (must agree within {unit:e})"
    );
}

#[test]
fn table_9_1_search_and_grasp_both_methods() {
    let tree = load("trees/search-and-grasp.yaml");
    for method in METHODS {
        let a = run(&tree, method);
        let root = fig(&tree, &a, "search and grasp");
        let search = fig(&tree, &a, "search");
        let grasp = fig(&tree, &a, "grasp");
        let m = method.name();
        // node 0 is the root
        assert_eq!(tree.find("search and grasp"), Some(0));
        matches_book(&format!("{m} mu0"), root.mu().unwrap(), 5.9039e-3);
        matches_book(&format!("{m} nu0"), root.nu().unwrap(), 4.4832e-3);
        matches_book(&format!("{m} mu3"), search.mu().unwrap(), 6.2905e-3);
        matches_book(&format!("{m} nu3"), search.nu().unwrap(), 2.6415e-3);
        matches_book(&format!("{m} nu5"), grasp.nu().unwrap(), 4.8780e-2);
        // mu5: the book prints 9.6060e-2, which is 1e-4 (relative) off the
        // exact value 0.55 / 5.725 = 9.60699e-2 (a typo for 9.6070e-2), so it
        // is checked against the exact rational. grasp = Fallback[one hand
        // (.1, mu .1, nu 2), two hands (.5, .1, .05)]: ps5 = .1 + .9 * .5 = .55
        // and E[T; S] = .1 * 10 + .9 * .5 * (.5 + 10) = 1 + 4.725 = 5.725.
        close(
            &format!("{m} mu5"),
            grasp.mu().unwrap(),
            0.55 / 5.725,
            1e-12,
        );
        // and the hand-derived nu5 = 1 / (0.5 + 20)
        close(
            &format!("{m} nu5 exact"),
            grasp.nu().unwrap(),
            1.0 / 20.5,
            1e-12,
        );
        // nu3 = 1 / (1/0.01 + 1/0.01 + 1/0.0056)
        close(
            &format!("{m} nu3 exact"),
            search.nu().unwrap(),
            1.0 / (100.0 + 100.0 + 1.0 / 0.0056),
            1e-12,
        );
    }
}

/// refs.json node name -> name in trees/search-and-grasp.yaml
const SEARCH_AND_GRASP_NAMES: [(&str, &str); 12] = [
    ("root", "search and grasp"),
    ("find object", "find object"),
    ("object position retrieved", "object position retrieved"),
    ("search", "search"),
    ("search on the floor", "search floor"),
    ("search in the drawer", "search drawer"),
    ("search in the closet", "search closet"),
    ("grasp object", "grasp object"),
    ("object grasped", "object grasped"),
    ("grasp", "grasp"),
    ("one hand grasp", "one hand grasp"),
    ("two hands grasp", "two hands grasp"),
];

#[test]
fn search_and_grasp_every_node_matches_refs() {
    let refs = refs();
    let nodes = &refs["search_and_grasp"]["nodes"];
    let tree = load("trees/search-and-grasp.yaml");
    assert_eq!(tree.nodes().len(), SEARCH_AND_GRASP_NAMES.len());
    for method in METHODS {
        let a = run(&tree, method);
        for (rname, yname) in SEARCH_AND_GRASP_NAMES {
            let r = &nodes[rname];
            assert!(r.is_object(), "refs.json has no node '{rname}'");
            check_record(
                &format!("{} {yname}", method.name()),
                &fig(&tree, &a, yname),
                r,
                1e-12,
            );
        }
    }
}

#[test]
fn search_and_grasp_drawer_first_matches_refs() {
    let refs = refs();
    let nodes = &refs["search_and_grasp"]["drawer_first"]["nodes"];
    let tree = load("trees/search-and-grasp-drawer-first.yaml");
    for method in METHODS {
        let a = run(&tree, method);
        for (rname, yname) in [
            ("root", "search and grasp"),
            ("find object", "find object"),
            ("search", "search"),
        ] {
            check_record(
                &format!("{} drawer-first {yname}", method.name()),
                &fig(&tree, &a, yname),
                &nodes[rname],
                1e-12,
            );
        }
    }
}

// ---------------------------------------------------------------------------
// Example 9.7: closed forms (9.74)–(9.75)
// ---------------------------------------------------------------------------

#[test]
fn example_9_7_closed_forms() {
    let tree = load("trees/three-action-fallback.yaml");
    // (ps, mu, nu) of the three actions, from the YAML file's comments / refs
    let p = [(0.3, 0.5, 1.0), (0.6, 0.2, 0.4), (0.5, 0.1, 0.25)];
    let (ps1, ps2, ps3) = (p[0].0, p[1].0, p[2].0);
    let (pf1, pf2, pf3) = (1.0 - ps1, 1.0 - ps2, 1.0 - ps3);
    let ts = |i: usize| 1.0 / p[i].1;
    let tf = |i: usize| 1.0 / p[i].2;
    let ps = ps1 + pf1 * ps2 + pf1 * pf2 * ps3;
    // eq. (9.74)
    let mu = ps
        / (ps1 * ts(0) + pf1 * ps2 * (tf(0) + ts(1)) + pf1 * pf2 * ps3 * (tf(0) + tf(1) + ts(2)));
    // eq. (9.75)
    let nu = 1.0 / (tf(0) + tf(1) + tf(2));
    // sanity of the hand derivation against the numbers in the YAML comment
    assert_relative_eq!(ps, 0.86, max_relative = 1e-14);
    assert_relative_eq!(1.0 / mu, 501.0 / 86.0, max_relative = 1e-14);
    assert_relative_eq!(1.0 / nu, 7.5, max_relative = 1e-14);
    let refs = refs();
    let r = &refs["example_9_7"];
    for method in METHODS {
        let a = run(&tree, method);
        let f = a.nodes[0];
        let m = method.name();
        close(
            &format!("{m} ps"),
            f.ps,
            fraction(&r["ps_exact_fraction"]),
            1e-13,
        );
        close(&format!("{m} pf"), f.pf, pf1 * pf2 * pf3, 1e-13);
        close(
            &format!("{m} MTTS"),
            f.mtts.unwrap(),
            fraction(&r["MTTS_exact_fraction"]),
            1e-13,
        );
        close(
            &format!("{m} MTTF"),
            f.mttf.unwrap(),
            fraction(&r["MTTF_exact_fraction"]),
            1e-13,
        );
        close(&format!("{m} mu (9.74)"), f.mu().unwrap(), mu, 1e-13);
        close(&format!("{m} nu (9.75)"), f.nu().unwrap(), nu, 1e-13);
        check_record(&format!("{m} example 9.7"), &f, &r["node"], 1e-12);
    }
}

// ---------------------------------------------------------------------------
// Parallel nodes: refs.json hand cases (a), (b), (c)
// ---------------------------------------------------------------------------

fn parallel_yaml(case: &Value) -> String {
    let m = case["M"].as_u64().unwrap();
    let mut s = format!("tree:\n  parallel:\n    success_threshold: {m}\n    children:\n");
    for c in case["children"].as_array().unwrap() {
        let c: Vec<f64> = c
            .as_array()
            .unwrap()
            .iter()
            .map(|x| x.as_f64().unwrap())
            .collect();
        s.push_str(&format!(
            "      - action: {{ps: {}, mu: {}, nu: {}}}\n",
            c[0], c[1], c[2]
        ));
    }
    s
}

#[test]
fn parallel_hand_cases_exact() {
    let refs = refs();
    for case in ["a_M1_of_2", "b_M2_of_2", "c_M2_of_3"] {
        let r = &refs["parallel"][case];
        let tree = parse_str(&parallel_yaml(r), case).unwrap();
        let f = run(&tree, Method::Exact).nodes[0];
        close(
            &format!("{case} ps"),
            f.ps,
            fraction(&r["ps_exact_fraction"]),
            1e-12,
        );
        close(
            &format!("{case} pf"),
            f.pf,
            fraction(&r["pf_exact_fraction"]),
            1e-12,
        );
        close(
            &format!("{case} MTTS"),
            f.mtts.unwrap(),
            fraction(&r["MTTS_exact_fraction"]),
            1e-12,
        );
        close(
            &format!("{case} MTTF"),
            f.mttf.unwrap(),
            fraction(&r["MTTF_exact_fraction"]),
            1e-12,
        );
        check_record(case, &f, r, 1e-12);
    }
}

#[test]
fn parallel_hand_cases_book_probabilities() {
    // The book's recursion replaces children by exponential actions with the
    // same outcome probabilities; the outcome vector alone decides a Parallel
    // node's outcome, so ps and pf are the exact ones.
    let refs = refs();
    for case in ["a_M1_of_2", "b_M2_of_2", "c_M2_of_3"] {
        let r = &refs["parallel"][case];
        let tree = parse_str(&parallel_yaml(r), case).unwrap();
        let f = run(&tree, Method::Book).nodes[0];
        close(
            &format!("book {case} ps"),
            f.ps,
            fraction(&r["ps_exact_fraction"]),
            1e-12,
        );
        close(
            &format!("book {case} pf"),
            f.pf,
            fraction(&r["pf_exact_fraction"]),
            1e-12,
        );
        for t in [f.mtts, f.mttf] {
            let t = t.expect("both outcomes are possible");
            assert!(t.is_finite() && t > 0.0);
        }
    }
}

#[test]
fn parallel_case_a_by_hand() {
    // M = 1 of A1 (.6, 1, 2), A2 (.3, .5, .25), derived independently here:
    // ps = 1 - .4 * .7; failure needs both to fail: max(Exp 2, Exp .25).
    let yaml = "tree:\n  parallel:\n    success_threshold: 1\n    children:\n      \
                - action: {ps: 0.6, mu: 1, nu: 2}\n      \
                - action: {ps: 0.3, mu: 0.5, nu: 0.25}\n";
    let tree = parse_str(yaml, "a.yaml").unwrap();
    let f = run(&tree, Method::Exact).nodes[0];
    assert_relative_eq!(f.ps, 1.0 - 0.4 * 0.7, max_relative = 1e-12);
    // E[max(X, Y)] = 1/a + 1/b - 1/(a + b)
    assert_relative_eq!(
        f.mttf.unwrap(),
        1.0 / 2.0 + 1.0 / 0.25 - 1.0 / 2.25,
        max_relative = 1e-12
    );
    // SS: min(Exp 1, Exp .5); SF: the success Exp(1) (the failure of the
    // other may come first or not, the node waits for the success);
    // FS: Exp(.5)
    let mtts = (0.6 * 0.3 / 1.5 + 0.6 * 0.7 / 1.0 + 0.4 * 0.3 / 0.5) / 0.72;
    assert_relative_eq!(f.mtts.unwrap(), mtts, max_relative = 1e-12);
}

#[test]
fn two_arm_parallel_tree_by_composition() {
    let refs = refs();
    let c = &refs["parallel"]["c_M2_of_3"];
    let b = &refs["parallel"]["b_M2_of_2"];
    // the file's two Parallel nodes are refs cases (c) and (b)
    let tree = load("trees/two-arm-parallel.yaml");
    let a = run(&tree, Method::Exact);
    check_record("localise", &fig(&tree, &a, "localise"), c, 1e-12);
    check_record("both arms", &fig(&tree, &a, "both arms"), b, 1e-12);

    // root = Sequence[condition .95, localise, both arms]:
    let (ps_c, mtts_c, mttf_c) = (
        fraction(&c["ps_exact_fraction"]),
        fraction(&c["MTTS_exact_fraction"]),
        fraction(&c["MTTF_exact_fraction"]),
    );
    let (ps_b, mtts_b, mttf_b) = (
        fraction(&b["ps_exact_fraction"]),
        fraction(&b["MTTS_exact_fraction"]),
        fraction(&b["MTTF_exact_fraction"]),
    );
    let q = 0.95;
    let ps = q * ps_c * ps_b;
    // success: 0 + MTTS_c + MTTS_b
    let mtts = mtts_c + mtts_b;
    // failure paths: condition fails (time 0); localise fails (MTTF_c);
    // localise succeeds and the arms fail (MTTS_c + MTTF_b)
    let w_cond = 1.0 - q;
    let w_loc = q * (1.0 - ps_c);
    let w_arms = q * ps_c * (1.0 - ps_b);
    let pf = w_cond + w_loc + w_arms;
    let mttf = (w_cond * 0.0 + w_loc * mttf_c + w_arms * (mtts_c + mttf_b)) / pf;
    assert_relative_eq!(ps, 0.1368, max_relative = 1e-14);

    let root = a.nodes[0];
    close("root ps", root.ps, ps, 1e-12);
    close("root pf", root.pf, pf, 1e-12);
    close("root MTTS", root.mtts.unwrap(), mtts, 1e-12);
    close("root MTTF", root.mttf.unwrap(), mttf, 1e-12);

    // the book method agrees on probabilities
    let book = run(&tree, Method::Book).nodes[0];
    close("book root ps", book.ps, ps, 1e-12);
    close("book root pf", book.pf, pf, 1e-12);
}

// ---------------------------------------------------------------------------
// Stiff tree
// ---------------------------------------------------------------------------

#[test]
fn stiff_tree_matches_refs() {
    // refs.json "stiff": Sequence[S1(.9,1e5,1e4), S2(.99,1e-4,2e-4),
    //                             Fallback[S3(.5,10,1), S4(.5,1e-3,1e-2)]]
    let yaml = "\
tree:
  sequence:
    children:
      - action: {name: S1, ps: 0.9, mu: 1e5, nu: 1e4}
      - action: {name: S2, ps: 0.99, mu: 1e-4, nu: 2e-4}
      - fallback:
          children:
            - action: {name: S3, ps: 0.5, mu: 10, nu: 1}
            - action: {name: S4, ps: 0.5, mu: 1e-3, nu: 1e-2}
";
    let refs = refs();
    let r = &refs["stiff"];
    let tree = parse_str(yaml, "stiff.yaml").unwrap();
    for method in METHODS {
        let f = run(&tree, method).nodes[0];
        let m = method.name();
        close(
            &format!("{m} stiff ps"),
            f.ps,
            fraction(&r["ps_exact_fraction"]),
            1e-9,
        );
        check_record(&format!("{m} stiff"), &f, &r["node"], 1e-9);
    }
}

// ---------------------------------------------------------------------------
// Deterministic and hybrid leaves (Defs. 9.8, 9.9)
// ---------------------------------------------------------------------------

#[test]
fn deterministic_sequence_by_hand() {
    let yaml = "\
tree:
  sequence:
    children:
      - action: {name: A, ps: 0.8, tau_s: 2, tau_f: 3}
      - action: {name: B, ps: 0.5, tau_s: 4, tau_f: 1.5}
";
    let tree = parse_str(yaml, "det.yaml").unwrap();
    for method in METHODS {
        let a = run(&tree, method);
        let f = a.nodes[0];
        assert_relative_eq!(f.ps, 0.4, max_relative = 1e-14);
        assert_relative_eq!(f.pf, 0.6, max_relative = 1e-14);
        assert_relative_eq!(f.mtts.unwrap(), 2.0 + 4.0, max_relative = 1e-14);
        // A fails (.2, 3 s) or A succeeds then B fails (.4, 2 + 1.5 s)
        assert_relative_eq!(
            f.mttf.unwrap(),
            (0.2 * 3.0 + 0.4 * 3.5) / 0.6,
            max_relative = 1e-14
        );
        let leaf = fig(&tree, &a, "A");
        assert_eq!(leaf.mtts, Some(2.0));
        assert_eq!(leaf.mttf, Some(3.0));
    }
}

#[test]
fn hybrid_fallback_by_hand() {
    // D: deterministic; HS: tau_s + nu (deterministic success time);
    // HF: mu + tau_f (deterministic failure time).
    let yaml = "\
tree:
  fallback:
    children:
      - action: {name: D, ps: 0.3, tau_s: 1, tau_f: 2}
      - action: {name: HS, ps: 0.6, tau_s: 5, nu: 0.5}
      - action: {name: HF, ps: 0.5, mu: 2, tau_f: 3}
";
    let tree = parse_str(yaml, "hybrid.yaml").unwrap();
    // hybrid with deterministic success time tau_s: the failure time is
    // min(Exp(nu), tau_s), mean (1 - e^{-nu tau_s}) / nu (eq. 9.21)
    let hs_fail = (1.0 - (-0.5f64 * 5.0).exp()) / 0.5;
    // hybrid with deterministic failure time tau_f: the success time is
    // min(Exp(mu), tau_f), mean (1 - e^{-mu tau_f}) / mu (eq. 9.25)
    let hf_succ = (1.0 - (-2.0f64 * 3.0).exp()) / 2.0;
    let ps = 0.3 + 0.7 * 0.6 + 0.7 * 0.4 * 0.5;
    let mtts =
        (0.3 * 1.0 + 0.7 * 0.6 * (2.0 + 5.0) + 0.7 * 0.4 * 0.5 * (2.0 + hs_fail + hf_succ)) / ps;
    let mttf = 2.0 + hs_fail + 3.0;
    for method in METHODS {
        let a = run(&tree, method);
        let m = method.name();
        let hs = fig(&tree, &a, "HS");
        close(&format!("{m} HS MTTS"), hs.mtts.unwrap(), 5.0, 1e-14);
        close(&format!("{m} HS MTTF"), hs.mttf.unwrap(), hs_fail, 1e-12);
        let hf = fig(&tree, &a, "HF");
        close(&format!("{m} HF MTTS"), hf.mtts.unwrap(), hf_succ, 1e-12);
        close(&format!("{m} HF MTTF"), hf.mttf.unwrap(), 3.0, 1e-14);
        let f = a.nodes[0];
        close(&format!("{m} ps"), f.ps, ps, 1e-13);
        close(&format!("{m} pf"), f.pf, 0.7 * 0.4 * 0.5, 1e-13);
        close(&format!("{m} MTTS"), f.mtts.unwrap(), mtts, 1e-12);
        close(&format!("{m} MTTF"), f.mttf.unwrap(), mttf, 1e-12);
    }
}

#[test]
fn deterministic_leaf_with_certain_outcome() {
    // ps = 1 with only tau_s: MTTS = tau_s, MTTF undefined
    let yaml = "tree:\n  sequence:\n    children:\n      \
                - action: {ps: 1, tau_s: 2.5}\n      \
                - action: {ps: 0, tau_f: 4}\n";
    let tree = parse_str(yaml, "certain.yaml").unwrap();
    for method in METHODS {
        let a = run(&tree, method);
        assert_eq!(a.nodes[1].mtts, Some(2.5));
        assert_eq!(a.nodes[1].mttf, None);
        assert_eq!(a.nodes[2].mtts, None);
        assert_eq!(a.nodes[2].mttf, Some(4.0));
        let root = a.nodes[0];
        assert_eq!(root.ps, 0.0);
        assert_eq!(root.mtts, None);
        assert_relative_eq!(root.mttf.unwrap(), 6.5, max_relative = 1e-14);
    }
}

// ---------------------------------------------------------------------------
// Undefined figures
// ---------------------------------------------------------------------------

fn assert_undefined_mtts(yaml: &str, name: &str) {
    let tree = parse_str(yaml, "undefined.yaml").unwrap();
    for method in METHODS {
        let a = run(&tree, method);
        let f = fig(&tree, &a, name);
        assert_eq!(f.ps, 0.0, "{name}: ps");
        assert_eq!(f.pf, 1.0, "{name}: pf");
        assert_eq!(
            f.mtts, None,
            "{name}: MTTS must be undefined, not {:?}",
            f.mtts
        );
        assert_eq!(f.mu(), None, "{name}: mu");
        let mttf = f.mttf.expect("MTTF is defined when pf = 1");
        assert!(mttf.is_finite() && mttf >= 0.0);
    }
}

#[test]
fn mtts_undefined_when_ps_is_zero() {
    assert_undefined_mtts("tree:\n  condition: {name: c, ps: 0}\n", "c");
    assert_undefined_mtts("tree:\n  action: {name: a, ps: 0, nu: 2}\n", "a");
    assert_undefined_mtts(
        "tree:\n  sequence:\n    name: s\n    children:\n      \
         - action: {ps: 0.5, mu: 1, nu: 1}\n      \
         - condition: {ps: 0.0}\n",
        "s",
    );
    assert_undefined_mtts(
        "tree:\n  fallback:\n    name: f\n    children:\n      \
         - condition: {ps: 0.0}\n      \
         - action: {ps: 0, mu: 1, nu: 4}\n",
        "f",
    );
}

#[test]
fn mttf_undefined_when_pf_is_zero() {
    let yaml = "tree:\n  fallback:\n    name: f\n    children:\n      \
                - action: {ps: 0.5, mu: 1, nu: 1}\n      \
                - condition: {ps: 1.0}\n";
    let tree = parse_str(yaml, "u.yaml").unwrap();
    for method in METHODS {
        let f = run(&tree, method).nodes[0];
        assert_eq!(f.ps, 1.0);
        assert_eq!(f.mttf, None);
        assert_eq!(f.nu(), None);
        // success: first action succeeds (1 s) or fails (1 s) then the
        // condition succeeds instantly: MTTS = 1
        assert_relative_eq!(f.mtts.unwrap(), 1.0, max_relative = 1e-14);
    }
}

#[test]
fn zero_duration_condition_figures() {
    // refs.json: a condition has MTTF = 0 and nu undefined (infinite rate)
    let tree = parse_str("tree:\n  condition: {ps: 0.25}\n", "c.yaml").unwrap();
    let f = run(&tree, Method::Exact).nodes[0];
    assert_eq!((f.ps, f.pf), (0.25, 0.75));
    assert_eq!((f.mtts, f.mttf), (Some(0.0), Some(0.0)));
    assert_eq!((f.mu(), f.nu()), (None, None));
}

// ---------------------------------------------------------------------------
// Parallel with deterministic leaves
// ---------------------------------------------------------------------------

const PARALLEL_DET: &str = "\
tree:
  sequence:
    children:
      - condition: {ps: 0.9}
      - parallel:
          name: par
          success_threshold: 1
          children:
            - action: {name: det, ps: 0.5, tau_s: 1, tau_f: 2}
            - action: {name: sto, ps: 0.5, mu: 1, nu: 1}
";

#[test]
fn parallel_exact_with_deterministic_leaf_matches_hand_calculation() {
    // par: M = 1 of [det: ps 0.5 at 1 s, else Failure at 2 s; sto: ps 0.5,
    // Exp(1) either way]. Success (0.75): det S & sto S at min(1, X), mean
    // 1 − e^{-1}; det S & sto F at 1; det F & sto S at X, mean 1 →
    // MTTS = (0.75 − 0.25/e)/0.75 = 1 − 1/(3e). Failure (0.25): both fail,
    // at max(2, X), mean 2 + e^{-2}. The root Sequence(cond 0.9, par) fails
    // at 0 w.p. 0.1 and with par w.p. 0.225.
    let tree = parse_str(PARALLEL_DET, "p.yaml").unwrap();
    let a = analyze(&tree, &Options::default()).unwrap();
    let e = std::f64::consts::E;
    let par = a.nodes[tree.find("par").unwrap()];
    assert!((par.ps - 0.75).abs() < 1e-12);
    assert!((par.mtts.unwrap() - (1.0 - 1.0 / (3.0 * e))).abs() < 1e-10);
    assert!((par.mttf.unwrap() - (2.0 + (-2.0f64).exp())).abs() < 1e-10);
    let root = a.nodes[0];
    assert!((root.ps - 0.675).abs() < 1e-12);
    let mttf = 0.225 * (2.0 + (-2.0f64).exp()) / 0.325;
    assert!((root.mttf.unwrap() - mttf).abs() < 1e-10);
}

#[test]
fn parallel_exact_all_deterministic_by_hand() {
    // Parallel over A (ps .5, tau_s 1, tau_f 2) and B (ps .4, tau_s 3, tau_f .5).
    // Outcome vectors (A, B): SS .2, SF .3, FS .2, FF .3.
    // M = 1: Success at the first success, Failure when both failed.
    //   SS: 1; SF: B fails at .5, A succeeds at 1; FS: A fails at 2, B
    //   succeeds at 3; FF: 2.  ps = .7, MTTS = (.2 + .3 + .6)/.7, MTTF = 2.
    // M = 2: Success when both succeeded, Failure at the first failure.
    //   SS: 3; SF: .5; FS: 2; FF: .5.  ps = .2, MTTS = 3,
    //   MTTF = (.3 * .5 + .2 * 2 + .3 * .5) / .8.
    let cases = [
        (1, 0.7, 1.1 / 0.7, 2.0),
        (2, 0.2, 3.0, (0.15 + 0.4 + 0.15) / 0.8),
    ];
    for (m, ps, mtts, mttf) in cases {
        let yaml = format!(
            "tree:\n  parallel:\n    success_threshold: {m}\n    children:\n      \
             - action: {{name: A, ps: 0.5, tau_s: 1, tau_f: 2}}\n      \
             - action: {{name: B, ps: 0.4, tau_s: 3, tau_f: 0.5}}\n"
        );
        let tree = parse_str(&yaml, "det-par.yaml").unwrap();
        // book: the probabilities are exact whatever the times
        let book = run(&tree, Method::Book).nodes[0];
        close(&format!("M={m} book ps"), book.ps, ps, 1e-12);
        match analyze(&tree, &Options::default()) {
            // exact support for deterministic Parallel children may or may
            // not exist; if it answers, the answer must be the exact one
            Ok(a) => {
                let f = a.nodes[0];
                close(&format!("M={m} ps"), f.ps, ps, 1e-12);
                close(&format!("M={m} pf"), f.pf, 1.0 - ps, 1e-12);
                close(&format!("M={m} MTTS"), f.mtts.unwrap(), mtts, 1e-12);
                close(&format!("M={m} MTTF"), f.mttf.unwrap(), mttf, 1e-12);
            }
            Err(AnalysisError::NotMarkovian { leaf }) => assert!(leaf == "A" || leaf == "B"),
            Err(e) => panic!("M={m}: unexpected error {e}"),
        }
    }
}

#[test]
fn parallel_book_with_deterministic_leaf_works() {
    let tree = parse_str(PARALLEL_DET, "p.yaml").unwrap();
    let a = run(&tree, Method::Book);
    let par = fig(&tree, &a, "par");
    // M = 1 of 2: fails only if both fail
    assert_relative_eq!(par.ps, 1.0 - 0.5 * 0.5, max_relative = 1e-12);
    assert_relative_eq!(par.pf, 0.25, max_relative = 1e-12);
    for t in [par.mtts, par.mttf] {
        let t = t.unwrap();
        assert!(t.is_finite() && t > 0.0, "{t}");
    }
    let root = a.nodes[0];
    assert_relative_eq!(root.ps, 0.9 * 0.75, max_relative = 1e-12);
    // root times are the Parallel's (the condition takes no time)
    assert_relative_eq!(root.mtts.unwrap(), par.mtts.unwrap(), max_relative = 1e-12);
}

#[test]
fn sequence_exact_with_deterministic_leaves_is_fine() {
    // only Parallel needs Markovian leaves; the mean-time composition of
    // Sequence/Fallback is exact for any distribution
    let tree = parse_str(
        "tree:\n  sequence:\n    children:\n      - action: {ps: 0.5, tau_s: 1, nu: 3}\n",
        "s.yaml",
    )
    .unwrap();
    // a Sequence of one action: its figures, in closed form (success after
    // exactly 1 s; failure at min(X, 1 s), X ~ Exp(3) (Def. 9.9, eq. 9.24):
    // mean (1 − e^{−3})/3)
    let root = analyze(&tree, &Options::default()).unwrap().nodes[0];
    assert_relative_eq!(root.ps, 0.5, max_relative = 1e-12);
    assert_relative_eq!(root.mtts.unwrap(), 1.0, max_relative = 1e-9);
    assert_relative_eq!(
        root.mttf.unwrap(),
        (1.0 - (-3.0f64).exp()) / 3.0,
        max_relative = 1e-9
    );
}
