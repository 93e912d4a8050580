//! Exporters: Graphviz DOT drawings of a tree and of a control node's
//! marking reachability graph, and PRISM models of a node's exact phase chain.
//!
//! * [`dot_tree`]: the tree in the book's notation (Sequence `→`, Fallback
//!   `?`, Parallel `⇒`, decorators `◇`), optionally annotated with analysed
//!   figures;
//! * [`dot_mrg`]: a Sequence/Fallback/Parallel node's MRG with the DTMC
//!   probability of every event (the book's Figs. 9.8–9.10);
//! * [`prism_ctmc`]: a node's exact phase chain as a PRISM `ctmc` model, to
//!   be checked with the properties in [`PRISM_PROPERTIES`] (a Parallel as
//!   one module per child, `prism_parallel.rs`);
//! * [`write_prism_explicit`]: the same chain as PRISM's explicit model
//!   files (`.tra`, `.sta`, `.lab`, `.srew`), for large chains;
//! * [`write_drn`]: the same chain in Storm's explicit DRN format.

pub(crate) mod dot;
pub(crate) mod drn;
pub(crate) mod explicit;
pub mod prism;
mod prism_parallel;
mod prism_text;

pub use dot::{dot_mrg, dot_tree};
pub use drn::write_drn;
pub use prism::{
    prism_ctmc, prism_explicit_properties, prism_model, prism_properties, write_prism_explicit,
    PRISM_EXPLICIT_EXTENSIONS, PRISM_PROPERTIES,
};

/// Escapes text for a double-quoted DOT string: backslashes and quotes are
/// escaped, line breaks become DOT's `\n`.
pub(crate) fn dot_escape(text: &str) -> String {
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
