//! BehaviorTree.CPP XML front end (formats 3 and 4), for trees as published.
//!
//! A tree is read from the BT.CPP XML (structure), optionally more XML files
//! (SubTrees defined elsewhere, node models), and a small YAML params file
//! (the stochastic parameters of each action and condition):
//!
//! ```yaml
//! # keyed by the node's name attribute first, then its ID
//! search floor: {ps: 0.3, mu: 0.0167, nu: 0.01}
//! OneHandGrasp: {ps: 0.1, mu: 0.1, nu: 2}
//! ObjectGrasped: {ps: 0.0}          # conditions: ps only
//! ```
//!
//! A leaf's parameters are looked up by its final (unique, prefixed) name,
//! then its `name` attribute, then its `ID`; the first key present wins.
//! Action parameters follow the YAML format's rules exactly. Every params
//! key must be used by some node. All leaves whose parameters are missing are
//! listed in one error, one line each with the node's file, line and column.
//!
//! # Leaves
//!
//! An element without children that is not a known node type is a leaf. It
//! is an action or a condition by, in this order: its explicit form
//! (`<Action ID>` / `<Condition ID>`), a `<TreeNodesModel>` entry (in any file
//! read), or its params entry: an entry with `ps` only is a condition (an
//! action with `ps` alone would lack its outcome times), an entry with any
//! of `pf`, `mu`, `nu`, `tau_s`, `tau_f` is an action. A `<SubTree ID>` that
//! no file defines but that has a params entry is one such leaf (a black
//! box).
//!
//! # Files
//!
//! The main file's trees come first: a BehaviorTree ID defined there shadows
//! included definitions; an ID defined by two included files is an error
//! when used. `<include path="..."/>` is followed relative to the including
//! file (`ros_pkg` is refused); each file is read once. Without
//! `main_tree_to_execute` the first tree of the main file is analysed; a
//! file's only `<BehaviorTree>` may have no ID (not in an included file).
//!
//! # Node types
//!
//! * `Sequence`, `SequenceWithMemory` (v3: `SequenceStar`),
//!   `ReactiveSequence` become a Sequence; `Fallback`, `ReactiveFallback` a
//!   Fallback. Under the SBT assumptions (a condition is evaluated once per
//!   execution of its parent and keeps its outcome; a running action is never
//!   interrupted by a re-evaluated sibling) a reactive node runs exactly like
//!   its non-reactive counterpart — when at most one child holds actions. BT.CPP
//!   halts the other children when one returns RUNNING and re-ticks them from
//!   IDLE, so with actions in two children an earlier action is restarted
//!   while a later one runs (found by `tests/btcpp_referee.rs`): read as that
//!   restart loop (`reactive.rs`), which may never return; refused when a
//!   child may return within its first tick.
//!   `SequenceWithMemory` resumes at the failed
//!   child when ticked again after a failure, so below a node that ticks a
//!   failed child again (`RetryUntilSuccessful` with more than one attempt,
//!   the main branch of a `RecoveryNode`) it differs from a fresh Sequence:
//!   there it is a `NodeKind::SequenceWithMemory` whose copies share one
//!   index slot, followed as a flow by `tree::nav2` — except as the direct
//!   child of a `RetryUntilSuccessful` without a retrying ancestor, which
//!   becomes one flow over (failures so far, child index)
//!   (`Builder::retry_with_memory`).
//! * `IfThenElse` (2 or 3 children) is the flow C → (Success: T, Failure: E
//!   or Failure); `WhileDoElse` likewise when its condition child holds
//!   conditions only (BT.CPP re-ticks it while a branch runs, which changes
//!   nothing while conditions keep their value); with an action there it is
//!   refused.
//! * `Parallel`: v4 `success_count` (default −1), `failure_count` (default
//!   1); v3 `success_threshold` (required), `failure_threshold` (default 1);
//!   a negative count k means N + k + 1. A file without `BTCPP_format` uses
//!   the v3 names if the node does, else the v4 rules.
//! * `Inverter`, `ForceSuccess`, `ForceFailure`, `RetryUntilSuccessful` (v3:
//!   `RetryUntilSuccesful`) `num_attempts`, `Repeat num_cycles` (1 to
//!   1 000 000).
//! * Nav2's `RecoveryNode(main, recovery) number_of_retries=n` (default 1,
//!   0 to 1000): Fallback(main, Sequence(recovery, RecoveryNode(n − 1))) with
//!   RecoveryNode(0) = main, built from fresh copies (named `R/recovery k/..`
//!   and `R/attempt k/..`): Nav2's loop exactly; the index of a RoundRobin
//!   or SequenceWithMemory in the main branch, which carries over the
//!   retries, is followed as a flow (`tree::nav2`).
//! * `AlwaysSuccess` / `AlwaysFailure`: conditions with ps 1 / 0.
//! * `Script`, `SetBlackboard`, `UnsetBlackboard`: BT.CPP runs them at once
//!   and they return Success: a condition with ps 1, unless the params file
//!   has an entry for them (then that entry models them, e.g. a run time).
//! * The explicit forms `<Control ID="X">`, `<Decorator ID="X">`,
//!   `<Action ID="X">`, `<Condition ID="X">` are the node type X;
//!   `SubTreePlus` (v3) is `SubTree`.
//!
//! * ManualSelector, ConsumeQueue, MoveIt Pro's ForEach and
//!   RepeatUnlessFailureEachTick, Nav2's GoalUpdatedController,
//!   PathLongerOnApproach, DistanceController and SpeedController: see
//!   `controllers.rs` and `predicates.rs` (branch probabilities, queue
//!   lengths and the robot's speed from the params file).
//!
//! Known node types without a stochastic meaning yet (RunOnce, ParallelAll,
//! Nav2's PersistentSequence, ...), custom control nodes
//! and decorators, counts of −1 (forever), and
//! pre-conditions (`_skipIf`, `_failureIf`, `_successIf`, `_while`, unless
//! constant no-ops such as `_skipIf="false"`) are all listed in one error
//! of kind `NoMeaning` (see [`is_unsupported`]); unknown nodes with children
//! and SubTrees defined nowhere are listed in one error too (`UnknownNode`),
//! each with its file, line and column. A count, duration, rate or queue
//! read from the blackboard (`"{name}"`) takes its value from the params
//! file (`"{name}": {value: N}`); without it, it is a missing parameter
//! (`MissingParameter`), listed with the leaves' missing parameters, and
//! nodes without a stochastic meaning follow that list.
//!
//! # Accepted as BT.CPP's parser does
//!
//! Other attributes starting with `_` (Groot and MoveIt Pro metadata such as
//! `_description`, `_collapsed`; `_autoremap`; the post-conditions
//! `_onSuccess`, `_onFailure`, `_onHalted`, `_post`, which only write the
//! blackboard after the node has returned) are ignored; data ports of leaves,
//! SubTrees and BehaviorTrees are ignored (the params file gives the outcome
//! distribution). Like tinyxml2, a `&` that does not start a known reference
//! is kept as it is (`a && b`), text anywhere (also around the root element)
//! is ignored, and a comment ends at the first `-->`. CDATA, DOCTYPE and
//! processing instructions are refused.
//!
//! # Names
//!
//! A node's name is its `name` attribute, else its ID (the tag for control
//! nodes and decorators, e.g. `Sequence`). Nodes expanded from a SubTree are
//! prefixed with the SubTree instance's name (its `name`, else its ID) and
//! `/`, nested instances with each instance in turn (`Outer/Inner/grasp`).
//! Names must be unique, so a later node whose name is taken gets `#2`, `#3`,
//! ... (the first free one) appended, in pre-order.
//!
//! # Limits
//!
//! Input up to 256 MiB (all XML files together), at most 10 000 files, XML
//! elements nested at most 202 deep (`root`, `BehaviorTree` and 200 tree
//! levels), expanded trees at most 200 levels deep, at most 5 million nodes
//! after SubTree and RecoveryNode expansion (checked before building) and
//! 256 MiB of node names. The XML reader is iterative and the tree builder's
//! recursion is bounded by those depths.

use std::collections::{BTreeMap, HashMap, HashSet};
use std::path::Path;

use super::action::{sloc, validate_action, ActionParams, At, Loc, TimeDef};
use super::error::{nearest, TreeError, TreeErrorKind as Kind};
use super::{Decorator, Flow, FlowNext, FlowState, Node, NodeKind, Tree};

// The stages, in the order a tree goes through them: lexing, the params
// file, files and includes, the node-type tables, lowering (the builder's
// state and steps, the per-type dispatch, SubTrees and counts, and the
// controllers, predicates and reactive nodes), then the checks.
mod builder;
mod checks;
mod controllers;
mod files;
mod leaves;
mod lex;
mod lower;
mod params;
mod predicates;
mod reactive;
mod steps;
mod subtree;
mod types;

use builder::*;
use checks::*;
use files::*;
use leaves::*;
use lex::*;
use lower::*;
use params::*;
use types::*;

pub use lex::{scan_elements, XmlElement};
pub use types::is_unsupported;
pub(crate) use types::{MAX_FLOW_STATES, MAX_RECOVERY_RETRIES, UNSUPPORTED};

/// Largest XML or params file, in bytes.
pub(crate) const MAX_BYTES: usize = 256 << 20;
/// Deepest tree after SubTree expansion (the root is level 1).
pub(crate) const MAX_DEPTH: usize = 200;
/// Deepest XML element nesting: `root`, `BehaviorTree`, then the tree.
pub(crate) const MAX_XML_DEPTH: usize = MAX_DEPTH + 2;
/// Most nodes after SubTree expansion.
pub(crate) const MAX_NODES: usize = 5_000_000;
/// Most bytes of node names after SubTree expansion.
pub(crate) const MAX_NAME_BYTES: usize = 256 << 20;

/// Parses a BehaviorTree.CPP XML tree (format 3 or 4) with its params file.
/// `file` and `params_file` name the sources in error messages. The text
/// was not read from a file, so `<include>` is refused.
pub fn parse_xml_str(
    xml: &str,
    file: &str,
    params: &str,
    params_file: &str,
) -> Result<Tree, TreeError> {
    parse_xml_str_with(xml, file, &[], params, params_file)
}

/// Like [`parse_xml_str`], with more XML texts (`(name, text)`) whose
/// BehaviorTrees and node models the tree may use, as `--include` files.
pub fn parse_xml_str_with(
    xml: &str,
    file: &str,
    includes: &[(&str, &str)],
    params: &str,
    params_file: &str,
) -> Result<Tree, TreeError> {
    parse_xml_str_with_keyed(xml, file, includes, params, params_file).map(|k| k.tree)
}

/// [`parse_xml_str_with`], also giving each node's params-file key.
fn parse_xml_str_with_keyed(
    xml: &str,
    file: &str,
    includes: &[(&str, &str)],
    params: &str,
    params_file: &str,
) -> Result<Keyed, TreeError> {
    for (src, name) in [(xml, file), (params, params_file)]
        .into_iter()
        .chain(includes.iter().map(|&(n, t)| (t, n)))
    {
        if src.len() > MAX_BYTES {
            return Err(too_large(name, src.len()));
        }
    }
    on_parser_thread(file, || {
        let mut files = Files::new();
        files.add(file.to_string(), xml.to_string(), None)?;
        for &(name, text) in includes {
            files.add(name.to_string(), text.to_string(), None)?;
        }
        build_keyed(files, params, params_file)
    })
}

/// Reads a BehaviorTree.CPP XML file and its params file.
pub fn parse_xml_file(xml: &Path, params: &Path) -> Result<Tree, TreeError> {
    parse_xml_files(xml, params, &[])
}

/// Reads a BehaviorTree.CPP XML file, its params file, and the files (or
/// folders of `.xml` files) in `includes`, whose BehaviorTrees and node
/// models the tree may use. `<include path>` elements are followed
/// (relative to the including file); every file is read once.
pub fn parse_xml_files(
    xml: &Path,
    params: &Path,
    includes: &[std::path::PathBuf],
) -> Result<Tree, TreeError> {
    parse_xml_files_keyed(xml, params, includes).map(|k| k.tree)
}

/// Like [`parse_xml_str`], also giving each node's params-file key.
pub fn parse_xml_str_keyed(
    xml: &str,
    file: &str,
    params: &str,
    params_file: &str,
) -> Result<Keyed, TreeError> {
    parse_xml_str_with_keyed(xml, file, &[], params, params_file)
}

/// Like [`parse_xml_files`], also giving each node's params-file key.
pub fn parse_xml_files_keyed(
    xml: &Path,
    params: &Path,
    includes: &[std::path::PathBuf],
) -> Result<Keyed, TreeError> {
    let xml_name = xml.display().to_string();
    let params_name = params.display().to_string();
    let params_src = read_text(params, &params_name)?;
    on_parser_thread(&xml_name, || {
        let mut files = Files::new();
        files.add_file(xml)?;
        for inc in includes {
            files.add_include(inc)?;
        }
        build_keyed(files, &params_src, &params_name)
    })
}

/// Runs `f` on a thread with a dedicated stack: the builder recurses once
/// per tree level and SubTree (both bounded).
fn on_parser_thread<T: Send, F>(file: &str, f: F) -> Result<T, TreeError>
where
    F: FnOnce() -> Result<T, TreeError> + Send,
{
    std::thread::scope(|s| {
        std::thread::Builder::new()
            .name("btrel-xml".into())
            .stack_size(64 << 20)
            .spawn_scoped(s, f)
            .map_err(|e| {
                TreeError::file(
                    Kind::Internal,
                    file,
                    format!("cannot start the parser thread: {e}"),
                )
            })?
            .join()
            .unwrap_or_else(|_| {
                Err(TreeError::file(
                    Kind::Internal,
                    file,
                    "internal error: the XML parser panicked",
                )
                .with_help("please report this file as a bug"))
            })
    })
}

/// A tree read from XML with, for every node, the params-file key its
/// parameters came from (`None` for control nodes and leaves without an
/// entry, e.g. a Script).
#[derive(Debug, Clone)]
pub struct Keyed {
    pub tree: Tree,
    /// Indexed like `tree.nodes`.
    pub keys: Vec<Option<String>>,
}
