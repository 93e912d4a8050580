//! Graphviz DOT drawings of a tree and of a control node's MRG.

use std::fmt::Write as _;

use super::dot_escape;
use crate::compile::mrg::{parallel_marking_count, Mrg, Outcome, Policy, Status};
use crate::compile::{weighted_events, Analysis, Figures};
use crate::tree::{Decorator, Duration, NodeId, NodeKind, Tree};

/// Most markings [`dot_mrg`] draws (a Parallel MRG can grow like 3^N).
pub const MAX_MRG_MARKINGS: usize = 10_000;

/// A number for a label: 5 significant digits, no exponent for ordinary
/// magnitudes.
fn short(x: f64) -> String {
    if x == 0.0 || !x.is_finite() {
        return format!("{x}");
    }
    let a = x.abs();
    if (1e-4..1e7).contains(&a) {
        let rounded: f64 = format!("{x:.4e}").parse().unwrap_or(x);
        format!("{rounded}")
    } else {
        format!("{x:.4e}")
    }
}

fn opt(x: Option<f64>) -> String {
    x.map_or_else(|| "—".to_string(), short)
}

fn duration_text(d: &Duration, rate_symbol: &str, tau_symbol: &str) -> String {
    match *d {
        Duration::Exponential { rate } => format!("{rate_symbol} = {}", short(rate)),
        Duration::Fixed { time } => format!("{tau_symbol} = {}", short(time)),
        Duration::TruncatedExponential { rate, cap } => {
            format!("{rate_symbol} = {}, cut at {}", short(rate), short(cap))
        }
        Duration::PhaseType { shift, stages } => {
            let body = match stages.as_erlang() {
                _ if stages.as_general().is_some() => d.family().to_string(),
                Some((1, rate)) => format!("exponential, rate {}", short(rate)),
                Some((k, rate)) => format!("Erlang-{k}, rate {}", short(rate)),
                None => format!(
                    "hypoexponential, rates {}",
                    stages
                        .series()
                        .iter()
                        .map(|&r| short(r))
                        .collect::<Vec<_>>()
                        .join(", ")
                ),
            };
            if shift > 0.0 {
                format!("{} + {body}", short(shift))
            } else {
                body
            }
        }
    }
}

/// Attributes of control nodes: a compact grey box whose size follows its
/// label (a `square` would grow to the label's width in both directions).
const CONTROL: &str = "box, style=\"rounded,filled\", fillcolor=\"#E6E6E6\", margin=\"0.08,0.03\"";
/// Attributes of decorators: as control nodes, dashed.
const DECORATOR: &str =
    "box, style=\"rounded,filled,dashed\", fillcolor=\"#F2F2F2\", margin=\"0.08,0.03\"";

/// The label lines of a node (unescaped) and its shape attributes.
fn node_lines(tree: &Tree, id: NodeId) -> (Vec<String>, &'static str) {
    let node = tree.node(id);
    let name = node.name.clone();
    match &node.kind {
        NodeKind::Action(a) => {
            let mut lines = vec![name, format!("ps = {}", short(a.ps))];
            if let Some(d) = a.success.filter(|_| a.ps > 0.0) {
                lines.push(format!(
                    "MTTS = {} ({})",
                    short(d.mean()),
                    duration_text(&d, "μ", "τs")
                ));
            }
            if let Some(d) = a.failure.filter(|_| a.pf > 0.0) {
                lines.push(format!(
                    "MTTF = {} ({})",
                    short(d.mean()),
                    duration_text(&d, "ν", "τf")
                ));
            }
            (lines, "box")
        }
        NodeKind::Condition { ps } => (vec![name, format!("ps = {}", short(*ps))], "ellipse"),
        NodeKind::Sequence { .. } => (vec!["→".to_string(), name], CONTROL),
        NodeKind::Fallback { .. } => (vec!["?".to_string(), name], CONTROL),
        NodeKind::Pipeline { .. } => (vec!["→ (pipeline)".to_string(), name], CONTROL),
        NodeKind::RoundRobin { .. } => (vec!["? (round robin)".to_string(), name], CONTROL),
        NodeKind::SequenceWithMemory { .. } => (vec!["→* (memory)".to_string(), name], CONTROL),
        NodeKind::Parallel {
            success_threshold: m,
            failure_threshold: f,
            children,
        } => {
            let n = children.len();
            let mut head = format!("⇒ M/N = {m}/{n}");
            if *f != n - m + 1 {
                let _ = write!(head, ", F = {f}");
            }
            (vec![head, name], CONTROL)
        }
        NodeKind::Flow(flow) => (
            vec![format!("⑂ flow, {} states", flow.states.len()), name],
            CONTROL,
        ),
        NodeKind::Decorator { decorator, .. } => {
            let kind = match decorator {
                Decorator::Retry { attempts } => format!("retry {attempts}"),
                Decorator::Repeat { times } => format!("repeat {times}"),
                d => d.keyword().to_string(),
            };
            (vec![format!("◇ {kind}"), name], DECORATOR)
        }
    }
}

/// The tree as a DOT digraph in the book's notation.
///
/// Nodes are `n<id>` (ids as in [`Tree::nodes`]); control nodes are grey
/// rounded boxes labelled `→` (Sequence), `?` (Fallback), `⇒ M/N = m/n`
/// (Parallel, with `F = f` when it is not the book's N − M + 1);
/// decorators are dashed grey boxes labelled `◇ kind` (e.g. `◇ retry 3`); actions are boxes with their name,
/// ps and mean times (with the rate or fixed time they come from);
/// conditions are ellipses with their ps. With `analysis`, control nodes and
/// decorators also show their analysed ps, MTTS and MTTF. Children are drawn
/// in order (`ordering=out`).
pub fn dot_tree(tree: &Tree, analysis: Option<&Analysis>) -> String {
    let mut out = String::new();
    out.push_str("digraph btrel {\n");
    out.push_str("  graph [ordering=out, rankdir=TB");
    if let Some(title) = &tree.title {
        let _ = write!(out, ", label=\"{}\", labelloc=t", dot_escape(title));
    }
    out.push_str("];\n");
    out.push_str("  node [fontname=\"Helvetica\"];\n");
    for (id, node) in tree.nodes.iter().enumerate() {
        let (mut lines, shape) = node_lines(tree, id);
        let leaf = matches!(node.kind, NodeKind::Action(_) | NodeKind::Condition { .. });
        if let (Some(a), false) = (analysis, leaf) {
            if let Some(f) = a.nodes.get(id) {
                lines.push(format!(
                    "ps = {}, MTTS = {}, MTTF = {}",
                    short(f.ps),
                    opt(f.mtts),
                    opt(f.mttf)
                ));
            }
        }
        let label = lines
            .iter()
            .map(|l| dot_escape(l))
            .collect::<Vec<_>>()
            .join("\\n");
        let _ = writeln!(out, "  n{id} [shape={shape}, label=\"{label}\"];");
    }
    for (id, node) in tree.nodes.iter().enumerate() {
        for &c in node.kind.children() {
            let _ = writeln!(out, "  n{id} -> n{c};");
        }
    }
    out.push_str("}\n");
    out
}

/// The marking reachability graph of control node `node` as a DOT digraph,
/// with the probability of each event in the DTMC over it (Figs. 9.8–9.10).
///
/// `children` are the figures of the node's children, in order (e.g.
/// `analysis.nodes[c]` for each child `c`). Markings are `m<i>`, boxes
/// labelled with the marking vector (eq. 9.29) such as `[1,-1,0]`; the
/// initial marking is bold, Success markings are green, Failure markings
/// red. An edge `h2 S` is "the child at position 2 (1-based, as the book's
/// h) returns Success", labelled with its probability:
///
/// * Sequence, Fallback: `ps_h` or `pf_h` (one child is feasible);
/// * Parallel: the share (9.38)–(9.39) of the feasible children's rates
///   `1/SJ_h`, `SJ_h = ps_h·MTTS_h + pf_h·MTTF_h` ([`Figures::mean_time`]),
///   times `ps_h` or `pf_h`. A feasible child with `SJ_h = 0` is immediate:
///   the first such child returns before the others, whose events at that
///   marking then have probability 0. This is the DTMC the analysis solves.
///
/// Events of probability 0 are drawn dashed and grey.
///
/// Errors if the node is a leaf or a decorator (they have no MRG), if
/// `children` does not have one entry per child, or if the MRG has more
/// than [`MAX_MRG_MARKINGS`] markings.
pub fn dot_mrg(tree: &Tree, node: NodeId, children: &[Figures]) -> Result<String, String> {
    let n = tree
        .nodes
        .get(node)
        .ok_or_else(|| format!("no node with id {node}"))?;
    // the node's operator in the core IR (a Sequence and a Fallback are chains)
    let policy = Policy::of(&crate::ir::op(&n.kind)).ok_or_else(|| {
        format!(
            "node '{}' is a {}: only Sequence, Fallback and Parallel nodes have a marking \
             reachability graph",
            n.name,
            n.kind.keyword()
        )
    })?;
    let count = n.kind.children().len();
    if children.len() != count {
        return Err(format!(
            "node '{}' has {count} children but {} figures were given",
            n.name,
            children.len()
        ));
    }
    if let Policy::Parallel {
        success_threshold,
        failure_threshold,
    } = policy
    {
        let markings = parallel_marking_count(count, success_threshold, failure_threshold);
        if markings > MAX_MRG_MARKINGS as f64 {
            return Err(format!(
                "node '{}' has about {markings:.3e} markings, more than the {MAX_MRG_MARKINGS} \
                 btrel draws",
                n.name
            ));
        }
    }
    let g = Mrg::build(policy, count);
    let competing = matches!(policy, Policy::Parallel { .. });

    let mut out = String::new();
    out.push_str("digraph mrg {\n");
    let symbol = match policy {
        Policy::Sequence => "→",
        Policy::Fallback => "?",
        Policy::Parallel { .. } => "⇒",
    };
    let _ = writeln!(
        out,
        "  graph [rankdir=LR, label=\"{}\", labelloc=t];",
        dot_escape(&format!("MRG of {symbol} {}", n.name))
    );
    out.push_str("  node [shape=box, style=rounded, fontname=\"Helvetica\"];\n");
    for i in 0..g.len() {
        let vector = g
            .marking(i)
            .iter()
            .map(|x| x.to_string())
            .collect::<Vec<_>>()
            .join(",");
        let style = match g.status[i] {
            Status::Running if i == 0 => ", penwidth=2",
            Status::Running => "",
            Status::Success => ", style=\"rounded,filled\", fillcolor=palegreen, color=darkgreen",
            Status::Failure => ", style=\"rounded,filled\", fillcolor=lightpink, color=red3",
        };
        let _ = writeln!(out, "  m{i} [label=\"[{vector}]\"{style}];");
    }
    for w in weighted_events(&g, children, competing) {
        let e = w.event;
        let letter = match e.outcome {
            Outcome::Success => "S",
            Outcome::Failure => "F",
        };
        let style = if w.prob > 0.0 {
            ""
        } else {
            ", style=dashed, color=gray50, fontcolor=gray50"
        };
        let _ = writeln!(
            out,
            "  m{} -> m{} [label=\"h{} {letter}\\np = {}\"{style}];",
            e.from,
            e.to,
            e.child + 1,
            short(w.prob)
        );
    }
    out.push_str("}\n");
    Ok(out)
}
