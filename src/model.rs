//! The library's front door: a tree planned once, and the queries every
//! command asks of it.
//!
//! ```
//! use btrel::{Model, Tree};
//!
//! let tree: Tree = btrel::parse_str(
//!     "tree:\n  sequence:\n    children:\n      - action: {ps: 0.9, mu: 1.0, nu: 2.0}\n      - action: {ps: 0.8, tau_s: 3.0, nu: 1.0}\n",
//!     "example.yaml",
//! )?;
//! let model = Model::new(&tree)?;
//! let root = model.figures(Tree::ROOT)?;
//! assert!((root.ps - 0.72).abs() < 1e-12);
//! // MTTS of a Sequence: the sum of its children's (1/mu + tau_s)
//! assert!((root.mtts.unwrap() - 4.0).abs() < 1e-12);
//! let pi = model.curve(Tree::ROOT, &[1.0, 10.0])?;
//! assert_eq!(pi[0].success, 0.0); // the second action needs 3 s at least
//! # Ok::<(), btrel::Error>(())
//! ```

use crate::compile::{self, Analysis, AnalysisError, Figures, Method, Options, Representation};
use crate::curve::{CurveOptions, CurvePoint, Timing};
use crate::sim::SimError;
use crate::tree::{NodeId, Tree, TreeError};

/// Everything that can go wrong in the library, by stage.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum Error {
    /// The tree file is invalid (located: file, line, column).
    #[error(transparent)]
    Tree(#[from] TreeError),
    /// The tree is valid but the analysis cannot answer (too large, never
    /// returns, no exact meaning, ...).
    #[error(transparent)]
    Analysis(#[from] AnalysisError),
    /// Invalid simulation options.
    #[error(transparent)]
    Simulation(#[from] SimError),
    /// A node id outside the tree.
    #[error("node {node} does not exist: the tree has {len} nodes")]
    NoSuchNode {
        /// The id asked for.
        node: NodeId,
        /// Number of nodes of the tree.
        len: usize,
    },
    /// A reordering that is not a permutation of a Fallback's children.
    #[error("cannot reorder node '{node}': {why}")]
    Reorder {
        /// The node's name.
        node: String,
        /// What is wrong.
        why: String,
    },
    /// A time point that is negative, infinite or NaN.
    #[error("time point #{index} is {value}: time points must be finite and >= 0")]
    BadTime {
        /// Its position.
        index: usize,
        /// The value.
        value: f64,
    },
}

/// A tree planned once: every node's figures and curves on demand.
///
/// The engine plans each node's representation once (`compile::plan`:
/// one table of rules, bottom-up) and answers every query from that plan,
/// which the model owns with what it has built (figures, chains, composed
/// laws): figures and curves of a node come from the same law, and a
/// second query reuses the first one's work. Every node's figures are
/// computed at the first query that needs them (a curve at near times does
/// not), once.
pub struct Model {
    tree: Tree,
    options: Options,
    analysis: std::cell::OnceCell<Result<Analysis, AnalysisError>>,
    /// The plan of the tree's core IR ([`crate::ir`]).
    plan: compile::Plan<'static>,
    /// The node of the IR standing for each node of `tree` (`None`: node
    /// for node).
    image: Option<Vec<NodeId>>,
    /// The plan of the deterministic version (curves with
    /// [`Timing::Deterministic`]), made on first use.
    deterministic: std::cell::OnceCell<compile::Plan<'static>>,
}

impl std::fmt::Debug for Model {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Model")
            .field("tree", &self.tree.title())
            .field("nodes", &self.tree.nodes().len())
            .field("method", &self.options.method)
            .finish_non_exhaustive()
    }
}

impl Model {
    /// Plans `tree` for the exact analysis, with the default budget.
    pub fn new(tree: &Tree) -> Result<Model, Error> {
        Model::with_options(tree, Options::default())
    }

    /// Plans `tree` under `options` (strategy: exact or the book's; the
    /// state budget). Fails where the tree cannot be lowered to the core IR
    /// ([`crate::ir`]: a Nav2 node without an exact meaning); the
    /// figures are computed by the first query that needs them.
    pub fn with_options(tree: &Tree, options: Options) -> Result<Model, Error> {
        let lowered = compile::lower(tree)?;
        let image = lowered.image;
        let plan = compile::Plan::owned(lowered.graph, options.method, options.max_states);
        Ok(Model {
            tree: tree.clone(),
            options,
            analysis: std::cell::OnceCell::new(),
            plan,
            image,
            deterministic: std::cell::OnceCell::new(),
        })
    }

    /// [`Model::with_options`] with the figures `known` of another model
    /// of the same tree and options ([`Model::known_planned_figures`]):
    /// the figures that model had computed are not computed again (a
    /// model stays on its thread; its figures can travel).
    pub(crate) fn with_known(
        tree: &Tree,
        options: Options,
        known: &[Option<Figures>],
    ) -> Result<Model, Error> {
        let model = Model::with_options(tree, options)?;
        if known.len() == model.plan.tree().nodes.len() {
            for (i, f) in known.iter().enumerate() {
                if let Some(f) = f {
                    model.plan.remember_figures(i, *f);
                }
            }
        }
        Ok(model)
    }

    /// The figures computed so far, by node of the core IR.
    pub(crate) fn known_planned_figures(&self) -> Vec<Option<Figures>> {
        (0..self.plan.tree().nodes.len())
            .map(|i| self.plan.known_figures(i))
            .collect()
    }

    /// The tree analysed.
    pub fn tree(&self) -> &Tree {
        &self.tree
    }

    /// The strategy used.
    pub fn method(&self) -> Method {
        self.options.method
    }

    /// Figures of node `id`.
    pub fn figures(&self, id: NodeId) -> Result<Figures, Error> {
        self.check_node(id)?;
        Ok(self.analysis()?.nodes[id])
    }

    /// The analysis: every node's figures (computed at the first call,
    /// bottom-up) and the strategy.
    pub fn analysis(&self) -> Result<&Analysis, Error> {
        self.analysis
            .get_or_init(|| compile::analysis_of(&self.plan, self.image.as_deref()))
            .as_ref()
            .map_err(|e| Error::Analysis(e.clone()))
    }

    /// Figures of every node, indexed by node id.
    pub fn all_figures(&self) -> Result<&[Figures], Error> {
        Ok(&self.analysis()?.nodes)
    }

    /// `π(t)` of node `id` at `times` (finite, ≥ 0, any order), exactly.
    pub fn curve(&self, id: NodeId, times: &[f64]) -> Result<Vec<CurvePoint>, Error> {
        self.curve_with(id, times, Timing::AsGiven)
    }

    /// `π(t)` with actions' times as given or made deterministic (`1/rate`,
    /// the book's Figs. 9.20–9.21 comparison).
    pub fn curve_with(
        &self,
        id: NodeId,
        times: &[f64],
        timing: Timing,
    ) -> Result<Vec<CurvePoint>, Error> {
        self.check_node(id)?;
        if let Some((index, &value)) = times
            .iter()
            .enumerate()
            .find(|(_, t)| !(t.is_finite() && **t >= 0.0))
        {
            return Err(Error::BadTime { index, value });
        }
        let options = CurveOptions {
            method: self.options.method,
            timing: Timing::AsGiven,
            max_states: self.options.max_states,
            ..CurveOptions::default()
        };
        let plan = match timing {
            Timing::AsGiven => &self.plan,
            Timing::Deterministic => self.deterministic.get_or_init(|| {
                compile::Plan::owned(
                    crate::compile::curve::deterministic_graph(self.plan.tree()),
                    self.options.method,
                    self.options.max_states,
                )
            }),
        };
        Ok(crate::compile::curve::with_tail(
            plan,
            self.planned(id),
            times,
            &options,
        )?)
    }

    /// Puts the children of each Fallback `node` of `changes` in its
    /// `order` (a permutation of them): the model of that equivalent tree
    /// (Def. 9.10). Where the tree is its own core IR, only those nodes and
    /// their ancestors are analysed again at the next query (every other
    /// node's figures are kept); a tree with Nav2 nodes is lowered again
    /// (its re-run copies and index flows follow the new order). Nothing
    /// changes where a node is not a Fallback or an order not a permutation
    /// of its children.
    pub fn reorder(&mut self, changes: &[(NodeId, &[NodeId])]) -> Result<(), Error> {
        for &(node, order) in changes {
            self.check_node(node)?;
            let n = &self.tree.nodes[node];
            let refuse = |why: String| Error::Reorder {
                node: n.name.clone(),
                why,
            };
            let crate::tree::NodeKind::Fallback { children } = &n.kind else {
                return Err(refuse(format!(
                    "it is a {}, not a Fallback",
                    n.kind.keyword()
                )));
            };
            let mut given = children.clone();
            let mut asked = order.to_vec();
            given.sort_unstable();
            asked.sort_unstable();
            if given != asked {
                return Err(refuse(format!(
                    "{order:?} is not a permutation of its children {children:?}"
                )));
            }
        }
        for &(node, order) in changes {
            self.tree.set_fallback_order(node, order);
        }
        if self.image.is_some() {
            *self = Model::with_options(&self.tree, self.options)?;
            return Ok(());
        }
        // the IR is the tree node for node
        self.plan.reorder(changes);
        self.analysis = std::cell::OnceCell::new();
        self.deterministic = std::cell::OnceCell::new();
        Ok(())
    }

    /// How the engine represents node `id`'s outcome law (for Nav2 nodes:
    /// the node standing for it in the lowered tree).
    pub fn representation(&self, id: NodeId) -> Result<Representation, Error> {
        self.check_node(id)?;
        Ok(self.plan.representation(self.planned(id))?)
    }

    /// The plan, when its IR is the tree's node for node (no Nav2 node to
    /// lower).
    pub(crate) fn own_plan(&self) -> Option<&compile::Plan<'static>> {
        self.image.is_none().then_some(&self.plan)
    }

    /// The core IR planned.
    pub(crate) fn planned_graph(&self) -> &crate::ir::Graph {
        self.plan.tree()
    }

    /// The node of the core IR standing for node `id` of the tree.
    pub(crate) fn planned_node(&self, id: NodeId) -> NodeId {
        self.planned(id)
    }

    fn planned(&self, id: NodeId) -> NodeId {
        self.image.as_ref().map_or(id, |image| image[id])
    }

    fn check_node(&self, id: NodeId) -> Result<(), Error> {
        if id >= self.tree.nodes.len() {
            return Err(Error::NoSuchNode {
                node: id,
                len: self.tree.nodes.len(),
            });
        }
        Ok(())
    }
}
