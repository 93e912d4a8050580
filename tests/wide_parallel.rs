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
        let r = simulate(
            &tree,
            &SimOptions {
                runs: 200_000,
                times: times.to_vec(),
                per_node: false,
                ..Default::default()
            },
            None,
        )
        .unwrap();
        // binomial standard errors from the exact probabilities (rare events
        // may have no simulated occurrence at all)
        let se = |p: f64| (p * (1.0 - p) / 200_000.0).sqrt();
        for (e, s) in exact.iter().zip(&r.curve) {
            assert!(
                (e.success - s.success.mean).abs() <= 5.0 * se(e.success) + 1e-12,
                "n={n}: {e:?} vs {s:?}"
            );
            assert!(
                (e.failure - s.failure.mean).abs() <= 5.0 * se(e.failure) + 1e-12,
                "n={n}: {e:?} vs {s:?}"
            );
            assert!((e.success + e.failure + e.running - 1.0).abs() < 1e-12);
        }
    }
}
