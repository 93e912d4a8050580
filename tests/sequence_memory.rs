//! BT.CPP's SequenceWithMemory (v3: SequenceStar) ticked again after a
//! Failure resumes at the failed child (`sequence_with_memory_node.cpp`
//! keeps `current_child_idx_` on Failure and resets it after the last
//! child's Success): below a RecoveryNode's retries and below a
//! RetryUntilSuccessful, btrel follows that index as one flow. Expected
//! values: hand calculations (to 1e-12) and Monte Carlo (|z| < 5).

mod common;

use btrel::tree::xml::parse_xml_files;
use common::{assert_root_matches_simulation, check_figures, root_figures};

fn read(dir: &std::path::Path, xml: &str, params: &str) -> btrel::Tree {
    let x = dir.join("t.xml");
    let p = dir.join("t.params.yaml");
    std::fs::write(&x, xml).unwrap();
    std::fs::write(&p, params).unwrap();
    parse_xml_files(&x, &p, &[]).expect("the tree reads")
}

fn main_tree(body: &str) -> String {
    format!(r#"<root BTCPP_format="4"><BehaviorTree ID="Main">{body}</BehaviorTree></root>"#)
}

const PARAMS: &str = "a: {ps: 0.6, mu: 1.0, nu: 2.0}\n\
                      b: {ps: 0.3, mu: 0.5, nu: 0.25}\n\
                      r: {ps: 0.8, mu: 4.0, nu: 3.0}\n";

/// RecoveryNode(1 retry) over SequenceWithMemory(a, b), recovery r, by
/// hand: after `b` failed and `r` succeeded, the second attempt runs `b`
/// only (resume), not `a, b` (a fresh Sequence).
#[test]
fn recovery_node_resumes_at_the_failed_child_by_hand() {
    let dir = tempfile::tempdir().unwrap();
    let tree = read(
        dir.path(),
        &main_tree(
            r#"<RecoveryNode number_of_retries="1" name="R">
                 <SequenceWithMemory name="S"><A name="a"/><B name="b"/></SequenceWithMemory>
                 <Rec name="r"/>
               </RecoveryNode>"#,
        ),
        PARAMS,
    );
    let (pa, pb, pr) = (0.6, 0.3, 0.8);
    let (qa, qb, qr) = (1.0 - pa, 1.0 - pb, 1.0 - pr);
    // mean times: a 1 / 0.5, b 2 / 4, r 0.25 / (1/3)
    let (as_, af, bs, bf, rs, rf) = (1.0, 0.5, 2.0, 4.0, 0.25, 1.0 / 3.0);
    // Success paths: ab; a✗ r a b; a b✗ r b (resumed at b)
    let s = [
        (pa * pb, as_ + bs),
        (qa * pr * pa * pb, af + rs + as_ + bs),
        (pa * qb * pr * pb, as_ + bf + rs + bs),
    ];
    // Failure paths: a✗ r✗; a b✗ r✗; a✗ r a✗; a✗ r a b✗; a b✗ r b✗
    let f = [
        (qa * qr, af + rf),
        (pa * qb * qr, as_ + bf + rf),
        (qa * pr * qa, af + rs + af),
        (qa * pr * pa * qb, af + rs + as_ + bf),
        (pa * qb * pr * qb, as_ + bf + rs + bf),
    ];
    let ps: f64 = s.iter().map(|x| x.0).sum();
    let pf: f64 = f.iter().map(|x| x.0).sum();
    assert!((ps + pf - 1.0).abs() < 1e-15);
    let mtts = s.iter().map(|x| x.0 * x.1).sum::<f64>() / ps;
    let mttf = f.iter().map(|x| x.0 * x.1).sum::<f64>() / pf;
    let got = root_figures(&tree);
    check_figures(got, ps, Some(mtts), Some(mttf));
    // a fresh Sequence (restart from a) would give a different ps
    let restart = pa * pb + (1.0 - pa * pb) * pr * pa * pb;
    assert!((got.ps - restart).abs() > 0.03, "{} vs {restart}", got.ps);
    assert_root_matches_simulation(&tree, 200_000);
    // v3's SequenceStar: the same rule after a Failure
    let v3 = read(
        dir.path(),
        r#"<root main_tree_to_execute="Main"><BehaviorTree ID="Main">
             <RecoveryNode number_of_retries="1" name="R">
               <SequenceStar name="S"><A name="a"/><B name="b"/></SequenceStar>
               <Rec name="r"/>
             </RecoveryNode></BehaviorTree></root>"#,
        PARAMS,
    );
    check_figures(root_figures(&v3), ps, Some(mtts), Some(mttf));
}

/// More retries, a condition before the SequenceWithMemory and three
/// children: Monte Carlo (whose simulator keeps the index across the
/// retries) against the exact figures and curve.
#[test]
fn recovery_node_with_three_retries_matches_simulation() {
    let dir = tempfile::tempdir().unwrap();
    let tree = read(
        dir.path(),
        &main_tree(
            r#"<RecoveryNode number_of_retries="3" name="R">
                 <Sequence><C name="c"/>
                   <SequenceWithMemory name="S"><A name="a"/><B name="b"/><D name="d"/></SequenceWithMemory>
                 </Sequence>
                 <Rec name="r"/>
               </RecoveryNode>"#,
        ),
        &format!("{PARAMS}c: {{ps: 0.8}}\nd: {{ps: 0.5, tau_s: 1.5, nu: 1.0}}\n"),
    );
    let f = root_figures(&tree);
    let times = [1.0, 4.0, 10.0];
    let pts = btrel::curve::curve(&tree, 0, &times, &Default::default()).expect("curve");
    let sim = common::simulate_root(&tree, 200_000, &times);
    common::assert_root_and_curve_within_z("recovery 3", f, &pts, &sim);
}

/// A SequenceWithMemory deeper below a RetryUntilSuccessful (a condition
/// before it is evaluated afresh at every attempt): the flow starts at the
/// Retry. By hand with `C` (0.7), `A1` (0.5), `A2` (0.4), 3 attempts: the
/// state is (attempt, index); index 1 is kept after `A2` failed.
#[test]
fn retry_over_a_sequence_holding_it_resumes_by_hand() {
    let dir = tempfile::tempdir().unwrap();
    let tree = read(
        dir.path(),
        &main_tree(
            r#"<RetryUntilSuccessful num_attempts="3">
                 <Sequence><C1/><SequenceWithMemory><A1/><A2/></SequenceWithMemory></Sequence>
               </RetryUntilSuccessful>"#,
        ),
        "C1: {ps: 0.7}\nA1: {ps: 0.5, mu: 1.0, nu: 1.0}\nA2: {ps: 0.4, mu: 1.0, nu: 1.0}\n",
    );
    let (c, a1, a2) = (0.7, 0.5, 0.4);
    // p(k, i): success within k attempts left, index i
    fn p(k: u32, i: usize, c: f64, a1: f64, a2: f64) -> f64 {
        if k == 0 {
            return 0.0;
        }
        let from_a2 = a2 + (1.0 - a2) * p(k - 1, 1, c, a1, a2);
        let body = if i == 0 {
            a1 * from_a2 + (1.0 - a1) * p(k - 1, 0, c, a1, a2)
        } else {
            from_a2
        };
        c * body + (1.0 - c) * p(k - 1, i, c, a1, a2)
    }
    let ps = p(3, 0, c, a1, a2);
    let got = root_figures(&tree);
    assert!(common::close(got.ps, ps), "{} vs {ps}", got.ps);
    assert_root_matches_simulation(&tree, 200_000);
}

/// Where the index cannot be other than 0 when it starts (only the first
/// child may fail, and a halt resets it in v3) a SequenceWithMemory is a
/// Sequence; in v4 a halt by a Parallel keeps the running child's index,
/// which the flow cannot follow: refused, naming the node (simulated).
#[test]
fn index_that_does_not_matter_is_a_sequence_and_v4_halts_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let params =
        "a: {ps: 0.6, mu: 1.0, nu: 2.0}\nw: {ps: 1.0, mu: 0.5}\nr: {ps: 0.8, mu: 4.0, nu: 3.0}\n";
    let mem = read(
        dir.path(),
        &main_tree(
            r#"<RecoveryNode number_of_retries="2" name="R">
                 <SequenceWithMemory><A name="a"/><W name="w"/></SequenceWithMemory>
                 <Rec name="r"/></RecoveryNode>"#,
        ),
        params,
    );
    let plain = read(
        dir.path(),
        &main_tree(
            r#"<RecoveryNode number_of_retries="2" name="R">
                 <Sequence><A name="a"/><W name="w"/></Sequence>
                 <Rec name="r"/></RecoveryNode>"#,
        ),
        params,
    );
    let (m, p) = (root_figures(&mem), root_figures(&plain));
    check_figures(m, p.ps, p.mtts, p.mttf);
    // v4, below a Parallel that may halt it while `w` runs
    let halted = read(
        dir.path(),
        &main_tree(
            r#"<RecoveryNode number_of_retries="2" name="R">
                 <Parallel success_count="1" failure_count="1">
                   <SequenceWithMemory name="S"><A name="a"/><W name="w"/></SequenceWithMemory>
                   <X name="x"/>
                 </Parallel>
                 <Rec name="r"/></RecoveryNode>"#,
        ),
        &format!("{params}x: {{ps: 0.5, mu: 1.0, nu: 1.0}}\n"),
    );
    let e = btrel::analyze(&halted, &Default::default())
        .unwrap_err()
        .to_string();
    assert!(e.contains("Parallel holds it"), "{e}");
    // the simulator plays that halt (tests/halts.rs)
    let r = btrel::simulate(&halted, &Default::default(), None).unwrap_or_else(|e| panic!("{e}"));
    // every leaf can succeed and fail: so can the root
    let ps = r.nodes[0].ps.mean;
    assert!(ps > 0.0 && ps < 1.0, "{ps}");
    // below a RetryUntilSuccessful without a bound: refused, located
    let forever = read(
        dir.path(),
        &main_tree(
            "<RetryUntilSuccessful num_attempts=\"-1\">\n\
             <Sequence><A name=\"a\"/><SequenceWithMemory name=\"S\"><A name=\"a2\"/><R name=\"r\"/></SequenceWithMemory></Sequence>\n\
             </RetryUntilSuccessful>",
        ),
        "a: {ps: 0.6, mu: 1.0, nu: 2.0}\na2: {ps: 0.6, mu: 1.0, nu: 2.0}\nr: {ps: 0.8, mu: 4.0, nu: 3.0}\n",
    );
    let e = btrel::analyze(&forever, &Default::default())
        .unwrap_err()
        .to_string();
    assert!(e.contains("'S'") && e.contains("line 2"), "{e}");
    assert!(e.contains("resumes at the"), "{e}");
}
