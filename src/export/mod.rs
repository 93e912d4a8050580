//! Exporters: Graphviz DOT drawings of a tree and of a control node's
//! marking reachability graph, and PRISM models of a node's exact phase chain.
//!
//! * [`dot_tree`]: the tree in the book's notation (Sequence `→`, Fallback
//!   `?`, Parallel `⇒`, decorators `◇`), optionally annotated with analysed
//!   figures;
//! * [`dot_mrg`]: a Sequence/Fallback/Parallel node's MRG with the DTMC
//!   probability of every event (the book's Figs. 9.8–9.10);
//! * [`prism_ctmc`]: a node's exact phase chain as a PRISM `ctmc` model, to
//!   be checked with the properties in [`PRISM_PROPERTIES`].

pub mod dot;
pub mod prism;

pub use dot::{dot_mrg, dot_tree};
pub use prism::{prism_ctmc, prism_model, PRISM_PROPERTIES};

/// Escapes text for a double-quoted DOT string: backslashes and quotes are
/// escaped, line breaks become DOT's `\n`.
pub fn dot_escape(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    for c in text.chars() {
        match c {
            '\\' => out.push_str("\\\\"),
            '"' => out.push_str("\\\""),
            '\n' => out.push_str("\\n"),
            '\r' => {}
            c => out.push(c),
        }
    }
    out
}
