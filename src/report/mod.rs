//! Per-node reports and their exporters.
//!
//! A [`Report`] pairs each node of a tree with its analysed [`Figures`].
//! Each output format is one [`Exporter`]: [`table::TableExporter`] for the
//! terminal, [`json::JsonExporter`] and [`csv::CsvExporter`] for programs.

pub mod csv;
pub mod intervals;
pub mod json;
pub use crate::number;
pub mod ranking;
pub mod sensitivity;
pub mod sequential;
pub mod simulation;
pub mod table;

use std::io::{self, Write};

use crate::compile::{Analysis, Figures, Method};
use crate::tree::Tree;

/// One node's line of a report.
#[derive(Debug, Clone, PartialEq)]
pub struct NodeReport {
    /// The node's unique name.
    pub name: String,
    /// Dotted path (root `0`).
    pub path: String,
    /// Node kind keyword (`sequence`, `action`, ...).
    pub kind: &'static str,
    /// Depth (root 0).
    pub depth: usize,
    /// The analysed figures.
    pub figures: Figures,
}

/// The name reports give a tree: its title, or the root's name.
pub fn title(tree: &Tree) -> String {
    tree.title
        .clone()
        .unwrap_or_else(|| tree.nodes[0].name.clone())
}

/// Figures of every node of a tree, in tree order.
#[derive(Debug, Clone, PartialEq)]
pub struct Report {
    /// The tree's title, or the root's name.
    pub tree: String,
    /// The method that produced the figures.
    pub method: Method,
    /// One entry per node, in tree order (pre-order).
    pub nodes: Vec<NodeReport>,
}

impl Report {
    /// Pairs a tree with its analysis.
    pub fn new(tree: &Tree, analysis: &Analysis) -> Report {
        Report {
            tree: title(tree),
            method: analysis.method,
            nodes: tree
                .nodes
                .iter()
                .zip(&analysis.nodes)
                .map(|(n, f)| NodeReport {
                    name: n.name.clone(),
                    path: n.path.clone(),
                    kind: n.kind.keyword(),
                    depth: n.depth,
                    figures: *f,
                })
                .collect(),
        }
    }
}

/// Writes a [`Report`] in one output format.
pub trait Exporter {
    /// Writes the whole report to `out`.
    fn write(&self, report: &Report, out: &mut dyn Write) -> io::Result<()>;

    /// The report as a string.
    fn to_string(&self, report: &Report) -> String {
        let mut buf = Vec::new();
        self.write(report, &mut buf)
            .expect("writing to a Vec cannot fail");
        String::from_utf8(buf).expect("exporters write UTF-8")
    }
}

/// The output formats of `btrel report`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Format {
    /// Aligned text table.
    #[default]
    Table,
    /// JSON document.
    Json,
    /// CSV, one row per node.
    Csv,
}

impl Format {
    /// The exporter for this format.
    pub fn exporter(self) -> Box<dyn Exporter> {
        match self {
            Format::Table => Box::new(table::TableExporter),
            Format::Json => Box::new(json::JsonExporter),
            Format::Csv => Box::new(csv::CsvExporter),
        }
    }
}
