//! Halts in the simulator: a Parallel or PipelineSequence that returns
//! halts its children still running, and a node that keeps an index
//! (BT.CPP v4's SequenceWithMemory, v3's SequenceStar, Nav2's RoundRobin)
//! leaves the index its halt leaves — the one it had at that instant, then
//! its own `halt()`: v4 keeps the running child's index
//! (`SequenceWithMemory::halt`), v3 resets it (`SequenceStarNode::halt`),
//! Nav2 resets it (`RoundRobinNode::halt`). A retry above then resumes
//! there. Expected values: hand calculations (closed forms below), against
//! Monte Carlo within 5 standard errors; the v4 case also against real
//! BehaviorTree.CPP runs in `tests/btcpp_referee.rs`.

mod common;

use btrel::tree::xml::parse_xml_files;
use common::{assert_within_z, simulate_root};

fn read(xml: &str, params: &str) -> btrel::Tree {
    let dir = tempfile::tempdir().unwrap();
    let x = dir.path().join("t.xml");
    let p = dir.path().join("t.params.yaml");
    std::fs::write(&x, xml).unwrap();
    std::fs::write(&p, params).unwrap();
    parse_xml_files(&x, &p, &[]).expect("the tree reads")
}

/// `RetryUntilSuccessful(2)(Parallel{1,1}(SWM(A1, A2), A3))` in format
/// `v` (3: SequenceStar and v3's Parallel attributes).
fn retried_race(v: u32) -> String {
    let (seq, m, f) = if v == 3 {
        ("SequenceStar", "success_threshold", "failure_threshold")
    } else {
        ("SequenceWithMemory", "success_count", "failure_count")
    };
    format!(
        r#"<root BTCPP_format="{v}"><BehaviorTree ID="Main">
             <RetryUntilSuccessful num_attempts="2">
               <Parallel {m}="1" {f}="1">
                 <{seq}><A1/><A2/></{seq}>
                 <A3/>
               </Parallel>
             </RetryUntilSuccessful>
           </BehaviorTree></root>"#
    )
}

/// A1 ~ Exp(2) and A2 ~ Exp(1) always succeed; A3 fails at 1 s. The first
/// attempt succeeds iff A1 + A2 < 1; otherwise the Parallel fails at 1 s
/// and halts the SequenceWithMemory, running A2 if A1 < 1 (index 1) or A1
/// (index 0). The second attempt starts at that index in v4, at 0 in v3.
const EXPONENTIAL: &str = r#"{"A1": {"ps": 1.0, "mu": 2.0}, "A2": {"ps": 1.0, "mu": 1.0},
                              "A3": {"ps": 0.0, "tau_f": 1.0}}"#;

/// `(P(S), E[T·1{S}])` of the retried race by hand, for v4 (`keep`) or v3.
fn by_hand(keep: bool) -> (f64, f64) {
    let e1 = (-1.0f64).exp();
    let e2 = (-2.0f64).exp();
    // A1 + A2 (rates 2, 1): density 2(e^{-t} − e^{-2t}); within 1 s
    let p_both = 1.0 - 2.0 * e1 + e2;
    // ∫₀¹ t·2e^{-t} dt = 2(1 − 2/e), ∫₀¹ t·2e^{-2t} dt = (1 − 3e^{-2})/2
    let t_both = 2.0 * (1.0 - 2.0 * e1) - (1.0 - 3.0 * e2) / 2.0;
    // A2 alone within 1 s: 1 − 1/e, ∫₀¹ t e^{-t} dt = 1 − 2/e
    let (p_one, t_one) = (1.0 - e1, 1.0 - 2.0 * e1);
    // halted running A2 (A1 < 1 < A1 + A2) or A1 (A1 > 1)
    let (at_a2, at_a1) = (1.0 - e2 - p_both, e2);
    // the second attempt starts 1 s in
    let again = |p: f64, t: f64| (p, p + t);
    let (p2, t2) = if keep {
        let (pa, ta) = again(p_one, t_one);
        let (pb, tb) = again(p_both, t_both);
        (at_a2 * pa + at_a1 * pb, at_a2 * ta + at_a1 * tb)
    } else {
        let (pb, tb) = again(p_both, t_both);
        ((at_a2 + at_a1) * pb, (at_a2 + at_a1) * tb)
    };
    (p_both + p2, t_both + t2)
}

#[test]
fn a_halted_sequence_with_memory_keeps_the_running_childs_index_in_v4() {
    let tree = read(&retried_race(4), EXPONENTIAL);
    let (ps, ts) = by_hand(true);
    // 0.747645 (v3's reset gives 0.639492: ~80 standard errors apart)
    assert!((ps - 0.747645).abs() < 1e-6, "{ps}");
    let sim = simulate_root(&tree, 200_000, &[]);
    let root = &sim.nodes[0];
    assert_within_z("v4 ps", &root.ps, ps);
    assert_within_z("v4 MTTS", root.mtts.as_ref().unwrap(), ts / ps);
    // both attempts fail at their 1 s deadline
    assert_within_z("v4 MTTF", root.mttf.as_ref().unwrap(), 2.0);
}

#[test]
fn a_halted_sequence_star_restarts_in_v3() {
    let tree = read(&retried_race(3), EXPONENTIAL);
    let (ps, ts) = by_hand(false);
    assert!((ps - 0.639492).abs() < 1e-6, "{ps}");
    let sim = simulate_root(&tree, 200_000, &[]);
    let root = &sim.nodes[0];
    assert_within_z("v3 ps", &root.ps, ps);
    assert_within_z("v3 MTTS", root.mtts.as_ref().unwrap(), ts / ps);
}

/// Fixed times: the first attempt always halts A2 (at 1.5 s, A2 started
/// at 1 s); v4 resumes at A2, which ends at 1 s < 1.5 s: P(S) = ps(A2) = 0.7,
/// MTTS = MTTF = 1.5 + 1 = 2.5 s. (Had the halted run gone on, the index
/// would be 0 and every attempt would fail.)
#[test]
fn fixed_times_resume_at_the_halted_child() {
    let tree = read(
        &retried_race(4),
        r#"{"A1": {"ps": 1.0, "tau_s": 1.0}, "A2": {"ps": 0.7, "tau_s": 1.0, "tau_f": 1.0},
            "A3": {"ps": 0.0, "tau_f": 1.5}}"#,
    );
    let sim = simulate_root(&tree, 100_000, &[]);
    let root = &sim.nodes[0];
    assert_within_z("ps", &root.ps, 0.7);
    assert_within_z("MTTS", root.mtts.as_ref().unwrap(), 2.5);
    assert_within_z("MTTF", root.mttf.as_ref().unwrap(), 2.5);
}

/// Nav2's RoundRobin halted while its second child runs restarts at its
/// first child: A1 fails at 0.5 s, A2 would succeed at 1.3 s but the
/// deadline D fails the Parallel at 1 s, in both attempts: P(S) = 0, MTTF
/// 2 s. (Keeping index 1 would start the retry at A2, which succeeds at
/// 0.8 s; letting the halted run finish would leave index 2, A3: both ps 1.)
#[test]
fn a_halted_round_robin_restarts_at_its_first_child() {
    let tree = read(
        r#"<root BTCPP_format="4"><BehaviorTree ID="Main">
             <RetryUntilSuccessful num_attempts="2">
               <Parallel success_count="1" failure_count="1">
                 <RoundRobin wrap_around="true"><A1/><A2/><A3/></RoundRobin>
                 <D/>
               </Parallel>
             </RetryUntilSuccessful>
           </BehaviorTree></root>"#,
        r#"{"A1": {"ps": 0.0, "tau_f": 0.5}, "A2": {"ps": 1.0, "tau_s": 0.8},
            "A3": {"ps": 1.0, "tau_s": 0.1}, "D": {"ps": 0.0, "tau_f": 1.0}}"#,
    );
    let sim = simulate_root(&tree, 10_000, &[]);
    let root = &sim.nodes[0];
    assert_eq!(root.ps.mean, 0.0);
    assert_within_z("MTTF", root.mttf.as_ref().unwrap(), 2.0);
}

/// A halter inside a halter: the inner Parallel's halt is undone by the
/// outer one's earlier return. Retry(2)(Parallel{1,1}(Parallel{1,1}(SWM(A1,
/// A2), D2), D1)): D1 fails at 1.5 s, D2 would fail at 2.5 s; A1 1 s, A2
/// 1 s (ps 0.7). The outer halt at 1.5 s finds A2 running: the retry resumes
/// at A2 and ends at 1 s — as in the flat case, P(S) = 0.7, MTTS = MTTF = 2.5.
#[test]
fn nested_halters_keep_the_earliest_halt() {
    let tree = read(
        r#"<root BTCPP_format="4"><BehaviorTree ID="Main">
             <RetryUntilSuccessful num_attempts="2">
               <Parallel success_count="1" failure_count="1">
                 <Parallel success_count="1" failure_count="1">
                   <SequenceWithMemory><A1/><A2/></SequenceWithMemory>
                   <D2/>
                 </Parallel>
                 <D1/>
               </Parallel>
             </RetryUntilSuccessful>
           </BehaviorTree></root>"#,
        r#"{"A1": {"ps": 1.0, "tau_s": 1.0}, "A2": {"ps": 0.7, "tau_s": 1.0, "tau_f": 1.0},
            "D1": {"ps": 0.0, "tau_f": 1.5}, "D2": {"ps": 0.0, "tau_f": 2.5}}"#,
    );
    let sim = simulate_root(&tree, 100_000, &[]);
    let root = &sim.nodes[0];
    assert_within_z("ps", &root.ps, 0.7);
    assert_within_z("MTTS", root.mtts.as_ref().unwrap(), 2.5);
    assert_within_z("MTTF", root.mttf.as_ref().unwrap(), 2.5);
}
