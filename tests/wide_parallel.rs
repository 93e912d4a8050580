//! Parallel nodes by the count programme (book thresholds): against the
//! product chain on small random cases and against simulation on wide ones.

use btrel::compile::phase::phase_chain;
use btrel::curve::{curve, CurveOptions};
use btrel::sim::{simulate, SimOptions};
use btrel::solve::transient::transient;
use btrel::tree::parse_str;
use proptest::prelude::*;

fn parallel_yaml(m: usize, children: &[(f64, f64, f64)]) -> String {
    let kids: Vec<String> = children
        .iter()
        .map(|(ps, mu, nu)| format!("{{action: {{ps: {ps}, mu: {mu}, nu: {nu}}}}}"))
        .collect();
    format!(
        "tree: {{parallel: {{success_threshold: {m}, children: [{}]}}}}",
        kids.join(", ")
    )
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(48))]

    /// The count programme equals the exact product chain.
    #[test]
    fn counts_match_the_product_chain(
        children in proptest::collection::vec((0.0f64..=1.0, 0.05f64..5.0, 0.05f64..5.0), 1..=4),
        m_seed in 0usize..100,
        times in proptest::collection::vec(0.0f64..20.0, 1..4),
    ) {
        let m = 1 + m_seed % children.len();
        let tree = parse_str(&parallel_yaml(m, &children), "p.yaml").unwrap();
        let by_counts = curve(&tree, 0, &times, &CurveOptions::default()).unwrap();
        let chain = phase_chain(&tree, 0, 1_000_000).unwrap();
        let product = transient(&chain, &times, 1e-14);
        for (a, b) in by_counts.iter().zip(&product) {
            prop_assert!((a.success - b.success).abs() < 1e-11, "{:?} vs {:?}", a, b);
            prop_assert!((a.failure - b.failure).abs() < 1e-11, "{:?} vs {:?}", a, b);
        }
    }
}

/// Simulates the whole tree (root only) with the curve at `times`.
fn simulated(tree: &btrel::Tree, times: &[f64], runs: u64) -> btrel::sim::SimResult {
    simulate(
        tree,
        &SimOptions {
            runs,
            times: times.to_vec(),
            per_node: false,
            ..Default::default()
        },
        None,
    )
    .unwrap()
}

/// Binomial standard error of a proportion, from the exact probability
/// (rare events may have no simulated occurrence at all).
fn binomial_se(p: f64, runs: u64) -> f64 {
    (p * (1.0 - p) / runs as f64).sqrt()
}

/// The exact curve within 5 standard errors of the simulated one.
fn assert_curve_close(
    exact: &[btrel::curve::CurvePoint],
    sim: &btrel::sim::SimResult,
    label: &str,
) {
    for (e, s) in exact.iter().zip(&sim.curve) {
        for (x, m) in [(e.success, s.success.mean), (e.failure, s.failure.mean)] {
            assert!(
                (x - m).abs() <= 5.0 * binomial_se(x, sim.runs) + 1e-12,
                "{label}: {e:?} vs {s:?}"
            );
        }
        assert!((e.success + e.failure + e.running - 1.0).abs() < 1e-12);
    }
}

#[test]
fn wide_parallels_agree_with_simulation() {
    for (n, m) in [(10, 5), (16, 8), (24, 12)] {
        let children: Vec<(f64, f64, f64)> = (0..n)
            .map(|i| {
                let i = i as f64;
                (0.5 + 0.02 * i, 0.5 + 0.1 * i, 1.0 + 0.05 * i)
            })
            .collect();
        let tree = parse_str(&parallel_yaml(m, &children), "wide.yaml").unwrap();
        let times = [0.5, 1.0, 2.0, 5.0];
        let exact = curve(&tree, 0, &times, &CurveOptions::default()).unwrap();
        assert_curve_close(
            &exact,
            &simulated(&tree, &times, 200_000),
            &format!("n={n}"),
        );
    }
}

/// A child of a test Parallel: an action, or a small Sequence/Fallback of
/// two actions (a chain with internal transitions).
fn child_yaml(kind: u8, a: (f64, f64, f64), b: (f64, f64, f64)) -> String {
    let act =
        |(ps, mu, nu): (f64, f64, f64)| format!("{{action: {{ps: {ps}, mu: {mu}, nu: {nu}}}}}");
    match kind % 3 {
        0 => act(a),
        1 => format!("{{sequence: {{children: [{}, {}]}}}}", act(a), act(b)),
        _ => format!("{{fallback: {{children: [{}, {}]}}}}", act(a), act(b)),
    }
}

type Spec = (u8, (f64, f64, f64), (f64, f64, f64));

/// Sequence(action, Parallel(5 of 8 two-action subtrees), action): the
/// issue's nested example, with a product bound of 1.7e7 states.
fn nested_yaml() -> String {
    let subtrees: Vec<String> = (0..8)
        .map(|i| {
            let i = i as f64;
            child_yaml(
                1 + (i as u8 % 2),
                (0.6 + 0.04 * i, 0.4 + 0.2 * i, 1.5 - 0.1 * i),
                (0.7, 1.0 + 0.1 * i, 2.0),
            )
        })
        .collect();
    format!(
        "tree: {{sequence: {{children: [{{action: {{ps: 0.9, mu: 1.0, nu: 2.0}}}}, \
         {{parallel: {{success_threshold: 5, children: [{}]}}}}, \
         {{action: {{ps: 0.8, mu: 0.5, nu: 1.0}}}}]}}}}",
        subtrees.join(", ")
    )
}

fn mixed_parallel(m: usize, specs: &[Spec]) -> btrel::Tree {
    let kids: Vec<String> = specs.iter().map(|&(k, a, b)| child_yaml(k, a, b)).collect();
    let yaml = format!(
        "tree: {{parallel: {{success_threshold: {m}, children: [{}]}}}}",
        kids.join(", ")
    );
    parse_str(&yaml, "p.yaml").unwrap()
}

fn action_params() -> impl Strategy<Value = (f64, f64, f64)> {
    (0.0f64..=1.0, 0.05f64..5.0, 0.05f64..5.0)
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(40))]

    /// Mean times by counting (quadrature with a rigorous bound) equal the
    /// product chain's (exact linear solves), within the stated bound.
    #[test]
    fn counted_means_match_the_product_chain(
        specs in proptest::collection::vec((0u8..3, action_params(), action_params()), 1..=5),
        m_seed in 0usize..100,
    ) {
        use btrel::compile::counts::{parallel_means, ChildLaw, ACCEPTED};
        let m = 1 + m_seed % specs.len();
        let tree = mixed_parallel(m, &specs);
        let children = tree.node(0).kind.children().to_vec();
        let laws: Vec<ChildLaw> = children
            .iter()
            .map(|&c| ChildLaw::new(phase_chain(&tree, c, 1_000_000).unwrap()))
            .collect();
        let (s, f) = parallel_means(&laws, m).unwrap();
        let product = btrel::solve::solve_absorbing(
            &phase_chain(&tree, 0, 1_000_000).unwrap().jump_chain(),
        )
        .unwrap();
        prop_assert!((s.probability - product.success).abs() < 1e-13);
        prop_assert!((f.probability - product.failure).abs() < 1e-13);
        for (c, exact) in [(s, product.time_success), (f, product.time_failure)] {
            prop_assert!(c.bound <= ACCEPTED * c.time + 1e-300, "{c:?}");
            // the product's own rounding: a few ulps of the sum
            prop_assert!(
                (c.time - exact).abs() <= c.bound + 1e-12 * exact,
                "{c:?} vs {exact}"
            );
        }
    }
}

/// The report's figures of wide Parallels (10, 16, 24 children; counted)
/// and of a Parallel of 8 subtrees nested in a Sequence agree with
/// simulation: probabilities within 5 binomial standard errors, mean times
/// within 5 standard errors of the simulated means.
#[test]
fn counted_reports_agree_with_simulation() {
    let mut trees = Vec::new();
    for (n, m) in [(10usize, 5usize), (16, 4), (24, 20)] {
        let specs: Vec<Spec> = (0..n)
            .map(|i| {
                let i = i as f64;
                (
                    0,
                    (0.55 + 0.015 * i, 0.5 + 0.1 * i, 1.0 + 0.05 * i),
                    (0.0, 1.0, 1.0),
                )
            })
            .collect();
        trees.push(mixed_parallel(m, &specs));
    }
    trees.push(parse_str(&nested_yaml(), "nested.yaml").unwrap());
    for tree in &trees {
        let analysis = btrel::analyze(tree, &Default::default()).unwrap();
        let sim = simulate(
            tree,
            &SimOptions {
                runs: 400_000,
                per_node: false,
                ..Default::default()
            },
            None,
        )
        .unwrap();
        let (a, s) = (analysis.nodes[0], &sim.nodes[0]);
        assert!(
            (a.ps - s.ps.mean).abs() <= 5.0 * s.ps.se + 1e-12,
            "{a:?} vs {s:?}"
        );
        for (exact, est) in [(a.mtts, s.mtts), (a.mttf, s.mttf)] {
            if let (Some(x), Some(e)) = (exact, est) {
                if e.count > 100 {
                    assert!((x - e.mean).abs() <= 5.0 * e.se, "{a:?} vs {s:?}");
                }
            }
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(32))]

    /// A Parallel nested in a Sequence/Fallback (optionally under an
    /// inverter): π(t) by composing the counted Parallel with the rest
    /// equals the product chain's. A small budget forces the composition.
    #[test]
    fn composed_curves_match_the_product_chain(
        specs in proptest::collection::vec((0u8..3, action_params(), action_params()), 2..=3),
        m_seed in 0usize..100,
        outer in 0u8..3,
        before in action_params(),
        after in action_params(),
    ) {
        let m = 1 + m_seed % specs.len();
        let kids: Vec<String> = specs.iter().map(|&(k, a, b)| child_yaml(k, a, b)).collect();
        let parallel = format!(
            "{{parallel: {{success_threshold: {m}, children: [{}]}}}}",
            kids.join(", ")
        );
        let body = format!("[{}, {parallel}, {}]", child_yaml(0, before, before), child_yaml(0, after, after));
        let yaml = match outer {
            0 => format!("tree: {{sequence: {{children: {body}}}}}"),
            1 => format!("tree: {{fallback: {{children: {body}}}}}"),
            _ => format!("tree: {{inverter: {{child: {{sequence: {{children: {body}}}}}}}}}"),
        };
        let tree = parse_str(&yaml, "n.yaml").unwrap();
        let times = [0.0, 0.3, 1.0, 3.0, 10.0];
        // a budget whose Parallel share (1/16) is below any product of two
        // or more children: composition (the other chains are ≤ 32 phases)
        let small = CurveOptions {
            max_states: 32,
            ..CurveOptions::default()
        };
        let composed = curve(&tree, 0, &times, &small).unwrap();
        let chain = phase_chain(&tree, 0, 10_000_000).unwrap();
        let product = transient(&chain, &times, 1e-14);
        for (a, b) in composed.iter().zip(&product) {
            prop_assert!((a.success - b.success).abs() < 1e-9, "{a:?} vs {b:?}");
            prop_assert!((a.failure - b.failure).abs() < 1e-9, "{a:?} vs {b:?}");
        }
    }
}

/// A small Parallel of 2–3 children, as YAML.
fn small_parallel() -> impl Strategy<Value = String> {
    (
        proptest::collection::vec((0u8..3, action_params(), action_params()), 2..=3),
        0usize..100,
    )
        .prop_map(|(specs, m_seed)| {
            let m = 1 + m_seed % specs.len();
            let kids: Vec<String> = specs.iter().map(|&(k, a, b)| child_yaml(k, a, b)).collect();
            format!(
                "{{parallel: {{success_threshold: {m}, children: [{}]}}}}",
                kids.join(", ")
            )
        })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(40))]

    /// Several Parallels in one Sequence/Fallback, one of them under a
    /// decorator (retry, repeat, inverter, force) and one nested a level
    /// deeper: π(t) from the composed outcome laws equals the product
    /// chain's. A small budget makes every Parallel opaque.
    #[test]
    fn composed_laws_match_the_product_chain(
        first in small_parallel(),
        second in small_parallel(),
        third in small_parallel(),
        between in action_params(),
        outer in 0u8..2,
        decorator in 0u8..6,
        condition in 0.0f64..=1.0,
    ) {
        let act = |(ps, mu, nu): (f64, f64, f64)| format!("{{action: {{ps: {ps}, mu: {mu}, nu: {nu}}}}}");
        let decorated = match decorator {
            0 => format!("{{retry: {{attempts: 3, child: {second}}}}}"),
            1 => format!("{{repeat: {{times: 2, child: {second}}}}}"),
            2 => format!("{{inverter: {{child: {second}}}}}"),
            3 => format!("{{force_success: {{child: {second}}}}}"),
            4 => format!("{{force_failure: {{child: {second}}}}}"),
            _ => second.clone(),
        };
        let inner = if outer == 0 { "fallback" } else { "sequence" };
        let nested = format!(
            "{{{inner}: {{children: [{{condition: {{ps: {condition}}}}}, {third}, {}]}}}}",
            act(between)
        );
        let kind = if outer == 0 { "sequence" } else { "fallback" };
        let yaml = format!(
            "tree: {{{kind}: {{children: [{first}, {}, {decorated}, {nested}]}}}}",
            act(between)
        );
        let tree = parse_str(&yaml, "laws.yaml").unwrap();
        let times = [0.0, 0.2, 1.0, 3.0, 12.0];
        let small = CurveOptions {
            max_states: 32,
            ..CurveOptions::default()
        };
        let composed = curve(&tree, 0, &times, &small).unwrap();
        let chain = phase_chain(&tree, 0, 10_000_000).unwrap();
        let product = transient(&chain, &times, 1e-15);
        for (a, b) in composed.iter().zip(&product) {
            prop_assert!((a.success - b.success).abs() < 1e-11, "{:?} vs {:?}", a, b);
            prop_assert!((a.failure - b.failure).abs() < 1e-11, "{:?} vs {:?}", a, b);
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(32))]

    /// A Parallel one of whose children holds another Parallel (which a
    /// small budget makes opaque): the report's figures — probabilities by
    /// counting, mean times from the composed law on growing horizons —
    /// equal the product chain's (exact linear solves).
    #[test]
    fn means_over_composed_laws_match_the_product_chain(
        inner in small_parallel(),
        before in action_params(),
        others in proptest::collection::vec((0u8..3, action_params(), action_params()), 1..=2),
        m_seed in 0usize..100,
    ) {
        let act = |(ps, mu, nu): (f64, f64, f64)| format!("{{action: {{ps: {ps}, mu: {mu}, nu: {nu}}}}}");
        let mut kids = vec![format!("{{sequence: {{children: [{}, {inner}]}}}}", act(before))];
        kids.extend(others.iter().map(|&(k, a, b)| child_yaml(k, a, b)));
        let m = 1 + m_seed % kids.len();
        let yaml = format!(
            "tree: {{parallel: {{success_threshold: {m}, children: [{}]}}}}",
            kids.join(", ")
        );
        let tree = parse_str(&yaml, "pp.yaml").unwrap();
        let small = btrel::Options { max_states: 32, ..Default::default() };
        let a = btrel::analyze(&tree, &small).unwrap().nodes[0];
        let product = btrel::solve::solve_absorbing(
            &phase_chain(&tree, 0, 10_000_000).unwrap().jump_chain(),
        )
        .unwrap();
        prop_assert!((a.ps - product.success).abs() < 1e-13, "{a:?} vs {product:?}");
        prop_assert!((a.pf - product.failure).abs() < 1e-13, "{a:?} vs {product:?}");
        for (mean, p, time) in [
            (a.mtts, product.success, product.time_success),
            (a.mttf, product.failure, product.time_failure),
        ] {
            if p > 1e-9 {
                let x = mean.unwrap() * p;
                prop_assert!((x - time).abs() <= 1e-9 * (product.time_success + product.time_failure), "{a:?} vs {product:?}");
            }
        }
    }
}

/// The nested example of the issue (a Parallel of 8 subtrees between two
/// actions; product bound 1.7e7 states): composed π(t) against simulation.
#[test]
fn nested_parallel_curve_agrees_with_simulation() {
    let tree = parse_str(&nested_yaml(), "nested.yaml").unwrap();
    let times = [0.5, 1.0, 2.0, 5.0, 10.0];
    let exact = curve(&tree, 0, &times, &CurveOptions::default()).unwrap();
    assert_curve_close(&exact, &simulated(&tree, &times, 400_000), "nested");
}

/// A three-phase mission of 8 robots (each a Sequence of a move and a
/// Fallback of two tries): Sequence(all 8 go, 6 of 8 work, Retry 2 × (7 of 8
/// return)). Three wide Parallels in one Sequence, one under a Retry: π(t)
/// from composed laws, and the report, against simulation.
fn mission_yaml() -> String {
    let act = |ps: f64, mu: f64, nu: f64| format!("{{action: {{ps: {ps}, mu: {mu}, nu: {nu}}}}}");
    let robot = |i: usize, phase: usize| {
        let i = i as f64;
        format!(
            "{{sequence: {{children: [{}, {{fallback: {{children: [{}, {}]}}}}]}}}}",
            act(0.95 - 0.01 * i, 0.5 + 0.05 * i + 0.1 * phase as f64, 1.0),
            act(0.7, 1.0 + 0.1 * i, 2.0),
            act(0.6, 0.8, 1.5)
        )
    };
    let parallel = |m: usize, phase: usize| {
        let kids: Vec<String> = (0..8).map(|i| robot(i, phase)).collect();
        format!(
            "{{parallel: {{success_threshold: {m}, children: [{}]}}}}",
            kids.join(", ")
        )
    };
    format!(
        "tree: {{sequence: {{children: [{}, {}, {{retry: {{attempts: 2, child: {}}}}}]}}}}\n",
        parallel(8, 0),
        parallel(6, 1),
        parallel(7, 2)
    )
}

/// The root's π(t) at `times` and its report (ps within 5 binomial standard
/// errors, MTTS and MTTF within 5 standard errors) against 400,000 runs.
fn assert_root_agrees_with_simulation(tree: &btrel::Tree, times: &[f64], label: &str) {
    let exact = curve(tree, 0, times, &CurveOptions::default()).unwrap();
    let runs = 400_000;
    let sim = simulated(tree, times, runs);
    assert_curve_close(&exact, &sim, label);
    let a = btrel::analyze(tree, &Default::default()).unwrap().nodes[0];
    let s = &sim.nodes[0];
    assert!(
        (a.ps - s.ps.mean).abs() <= 5.0 * binomial_se(a.ps, runs),
        "{label}: {a:?} vs {s:?}"
    );
    for (x, e) in [(a.mtts, s.mtts), (a.mttf, s.mttf)] {
        let (x, e) = (x.unwrap(), e.unwrap());
        assert!((x - e.mean).abs() <= 5.0 * e.se, "{label}: {a:?} vs {s:?}");
    }
}

#[test]
fn three_phase_mission_agrees_with_simulation() {
    let tree = parse_str(&mission_yaml(), "mission.yaml").unwrap();
    let times = [2.0, 5.0, 10.0, 20.0];
    assert_root_agrees_with_simulation(&tree, &times, "mission");
}

/// Stiff children (a slow and a fast phase in turn, rates 0.01 and 500):
/// eight identical Sequences that always succeed, so the node's success
/// time is the minimum (M = 1) or maximum (M = 8) of eight hypoexponential
/// times with survival `S(t) = (b e^{−at} − a e^{−bt})/(b − a)`. Expanding
/// `S^j` binomially gives `∫ S^j = Σ_k C(j,k) (b/(b−a))^{j−k} (−a/(b−a))^k
/// / ((j−k)a + kb)`, hence `E[min] = ∫ S^8` and `E[max] = Σ_j C(8,j)
/// (−1)^{j+1} ∫ S^j`. These children are stiff
/// (largest rate × 32 × mean > 1e5): their mean times come from quadrature
/// of the counted curve, the children's curves by dense exponentials.
#[test]
fn stiff_children_match_order_statistics() {
    // rates 0.01 and 500; and 1e-3 and 1e6 (the 16-child stiff case of the
    // engine issue took 11 s and 2.75 GB before being refused)
    for (a, b) in [(0.01f64, 500.0f64), (1e-3, 1e6)] {
        stiff_case(a, b);
    }
}

fn stiff_case(a: f64, b: f64) {
    fn binom(n: usize, k: usize) -> f64 {
        (0..k).fold(1.0, |acc, j| acc * (n - j) as f64 / (j + 1) as f64)
    }
    let power = |j: usize| -> f64 {
        (0..=j)
            .map(|k| {
                binom(j, k) * (b / (b - a)).powi((j - k) as i32) * (-a / (b - a)).powi(k as i32)
                    / ((j - k) as f64 * a + k as f64 * b)
            })
            .sum()
    };
    let child = format!("{{sequence: {{children: [{{action: {{ps: 1, mu: {a}}}}}, {{action: {{ps: 1, mu: {b}}}}}]}}}}");
    let kids = vec![child; 8].join(", ");
    for (m, expected) in [
        (1, power(8)),
        (
            8,
            (1..=8)
                .map(|j| binom(8, j) * if j % 2 == 1 { 1.0 } else { -1.0 } * power(j))
                .sum::<f64>(),
        ),
    ] {
        let yaml = format!("tree: {{parallel: {{success_threshold: {m}, children: [{kids}]}}}}");
        let tree = parse_str(&yaml, "stiff.yaml").unwrap();
        let a = btrel::analyze(&tree, &Default::default()).unwrap().nodes[0];
        assert!((a.ps - 1.0).abs() < 1e-14, "{a:?}");
        let mtts = a.mtts.unwrap();
        assert!(
            (mtts - expected).abs() <= 1e-9 * expected,
            "M = {m}: {mtts} vs {expected}"
        );
    }
}

/// Identical children: given that k of N succeed, the node's success time
/// is the M-th order statistic of k exponentials of rate mu, with mean
/// `(1/mu) Σ_{j<M} 1/(k − j)`; so `E[T·1{S}] = Σ_{k≥M} C(N,k) ps^k pf^(N−k)
/// (1/mu) Σ_{j<M} 1/(k−j)`, and likewise for Failure with F = N − M + 1 and
/// nu. The counted report must match this closed form to 1e-9.
#[test]
fn identical_children_match_order_statistics() {
    fn binom(n: usize, k: usize) -> f64 {
        (0..k).fold(1.0, |acc, j| acc * (n - j) as f64 / (j + 1) as f64)
    }
    fn side(n: usize, need: usize, p: f64, rate: f64) -> (f64, f64) {
        let (mut prob, mut time) = (0.0, 0.0);
        for k in need..=n {
            let w = binom(n, k) * p.powi(k as i32) * (1.0 - p).powi((n - k) as i32);
            prob += w;
            time += w * (0..need).map(|j| 1.0 / (k - j) as f64).sum::<f64>() / rate;
        }
        (prob, time / prob)
    }
    for (n, m, ps, mu, nu) in [
        (10, 5, 0.6, 2.0, 0.5),
        (16, 12, 0.85, 1.0, 3.0),
        (24, 12, 0.5, 0.25, 4.0),
    ] {
        let tree = mixed_parallel(m, &vec![(0, (ps, mu, nu), (0.0, 1.0, 1.0)); n]);
        let a = btrel::analyze(&tree, &Default::default()).unwrap().nodes[0];
        let (p_s, mtts) = side(n, m, ps, mu);
        let (p_f, mttf) = side(n, n - m + 1, 1.0 - ps, nu);
        assert!(
            (a.ps - p_s).abs() < 1e-12 && (a.pf - p_f).abs() < 1e-12,
            "{a:?}"
        );
        assert!(
            (a.mtts.unwrap() - mtts).abs() < 1e-9 * mtts,
            "{a:?} vs {mtts}"
        );
        assert!(
            (a.mttf.unwrap() - mttf).abs() < 1e-9 * mttf,
            "{a:?} vs {mttf}"
        );
    }
}

/// Random trees with Parallels of up to 12 leaves anywhere (children may be
/// subtrees and conditions): the analysis answers every one — counted,
/// composed or multiplied out — and the root's figures and π(t) agree with
/// simulation within 5 standard errors.
#[test]
fn random_trees_with_wide_parallels_agree_with_simulation() {
    use btrel::generate::{random_tree_yaml, Shape};
    let shape = Shape {
        leaves: 36,
        max_children: 4,
        condition_fraction: 0.15,
        parallel_fraction: 0.6,
        max_parallel_children: 12,
        ..Shape::sequence_fallback(36)
    };
    let times = [0.5, 2.0, 8.0];
    let runs = 200_000u64;
    for seed in 0..12 {
        let tree = parse_str(&random_tree_yaml(&shape, seed), "r.yaml").unwrap();
        // every such tree is answered: counted, composed or multiplied out
        let analysis = btrel::analyze(&tree, &Default::default()).unwrap();
        let exact = curve(&tree, 0, &times, &CurveOptions::default()).unwrap();
        let sim = simulated(&tree, &times, runs);
        let (a, s) = (analysis.nodes[0], &sim.nodes[0]);
        assert!(
            (a.ps - s.ps.mean).abs() <= 5.0 * binomial_se(a.ps, runs) + 1e-12,
            "seed {seed}: {a:?} vs {s:?}"
        );
        for (x, e) in [(a.mtts, s.mtts), (a.mttf, s.mttf)] {
            if let (Some(x), Some(e)) = (x, e) {
                if e.count > 100 {
                    assert!(
                        (x - e.mean).abs() <= 5.0 * e.se,
                        "seed {seed}: {a:?} vs {s:?}"
                    );
                }
            }
        }
        assert_curve_close(&exact, &sim, &format!("seed {seed}"));
    }
}

/// The bundled fleet example (a 12-of-16 Parallel of two-level subtrees
/// between other steps): `report` and `curve` answer from the command line,
/// and the root's figures agree with simulation.
#[test]
fn drone_fleet_example_is_answered_and_agrees_with_simulation() {
    for args in [
        vec!["report", "trees/drone-fleet.yaml"],
        vec!["curve", "trees/drone-fleet.yaml", "--times", "60,300,600"],
    ] {
        assert_cmd::Command::cargo_bin("btrel")
            .unwrap()
            .args(&args)
            .assert()
            .success()
            .stdout(predicates::str::contains("mission"));
    }
    let tree = btrel::tree::parse_file(std::path::Path::new("trees/drone-fleet.yaml")).unwrap();
    let a = btrel::analyze(&tree, &Default::default()).unwrap().nodes[0];
    let runs = 200_000;
    let sim = simulated(&tree, &[60.0, 300.0, 600.0], runs);
    let s = &sim.nodes[0];
    assert!(
        (a.ps - s.ps.mean).abs() <= 5.0 * binomial_se(a.ps, runs),
        "{a:?} vs {s:?}"
    );
    let (mtts, mttf) = (s.mtts.unwrap(), s.mttf.unwrap());
    assert!(
        (a.mtts.unwrap() - mtts.mean).abs() <= 5.0 * mtts.se,
        "{a:?} vs {s:?}"
    );
    assert!(
        (a.mttf.unwrap() - mttf.mean).abs() <= 5.0 * mttf.se,
        "{a:?} vs {s:?}"
    );
    let exact = curve(&tree, 0, &[60.0, 300.0, 600.0], &CurveOptions::default()).unwrap();
    assert_curve_close(&exact, &sim, "fleet");
}

/// A wide Parallel below a child of a counted Parallel: π(t) (counts of a
/// composed law) and the report (mean times from the law on growing
/// horizons) agree with simulation, and the command line answers.
#[test]
fn parallel_of_nested_wide_parallels() {
    let inner: Vec<String> = (0..12)
        .map(|i| {
            format!(
                "{{action: {{ps: 0.8, mu: {}, nu: 2}}}}",
                1.0 + 0.1 * i as f64
            )
        })
        .collect();
    let wide = format!(
        "{{parallel: {{name: inner, success_threshold: 6, children: [{}]}}}}",
        inner.join(", ")
    );
    let yaml = format!(
        "tree: {{parallel: {{success_threshold: 2, children: [{{action: {{ps: 0.9, mu: 1, nu: 1}}}}, \
         {{sequence: {{children: [{{action: {{ps: 0.9, mu: 1, nu: 1}}}}, {wide}]}}}}, \
         {{action: {{ps: 0.5, mu: 0.5, nu: 0.5}}}}]}}}}\n"
    );
    let tree = parse_str(&yaml, "pp.yaml").unwrap();
    let times = [1.0, 2.0, 5.0];
    assert_root_agrees_with_simulation(&tree, &times, "parallel of nested");
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("pp.yaml");
    std::fs::write(&path, &yaml).unwrap();
    assert_cmd::Command::cargo_bin("btrel")
        .unwrap()
        .args(["report", path.to_str().unwrap()])
        .assert()
        .success()
        .stdout(predicates::str::contains("inner"));
}
