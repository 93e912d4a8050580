//! The parsed format ([`super::defs`]) to a validated [`Tree`]: kinds,
//! thresholds, counts and names checked, each error at its key.

use super::super::action::{sloc, validate_action, ActionParams, At};
use super::super::error::{TreeError, TreeErrorKind as Kind};
use super::super::{Action, Decorator, Flow, FlowNext, FlowState, Node, NodeKind, Tree};
use super::defs::*;
use super::ParseLimits;

/// The validated tree of a parsed file.
pub(super) fn build(
    def: FileDef,
    source: &str,
    file: &str,
    limits: &ParseLimits,
) -> Result<Tree, TreeError> {
    // one allocation for a million-node tree instead of repeated doubling
    let count = def.tree.value.count();
    let mut b = Builder {
        source,
        file,
        nodes: Vec::with_capacity(count),
        max_depth: limits.max_depth,
        locations: Vec::with_capacity(count),
    };
    b.node(&def.tree, None, 0, "0".into())?;
    b.check_names()?;
    Ok(Tree {
        title: def.name,
        nodes: b.nodes,
    })
}

struct Builder<'a> {
    source: &'a str,
    file: &'a str,
    nodes: Vec<Node>,
    locations: Vec<(usize, usize)>,
    max_depth: usize,
}

fn loc<T>(s: &At<T>) -> (usize, usize) {
    sloc(s)
}

impl Builder<'_> {
    fn err(&self, kind: Kind, at: (usize, usize), msg: impl Into<String>) -> TreeError {
        TreeError::at(kind, self.file, self.source, at, msg)
    }

    fn node(
        &mut self,
        def: &At<NodeDef>,
        parent: Option<usize>,
        depth: usize,
        path: String,
    ) -> Result<usize, TreeError> {
        let at = loc(def);
        if depth >= self.max_depth {
            return Err(self
                .err(Kind::Budget, at, "the tree is nested too deeply")
                .with_help(format!(
                    "btrel accepts trees up to {} levels deep",
                    self.max_depth
                )));
        }
        let id = self.nodes.len();
        if let Some((name, decorator, child)) = self.decorator(&def.value)? {
            let name = self.node_name(name, decorator.keyword(), &path)?;
            self.nodes.push(Node {
                name,
                path: path.clone(),
                depth,
                parent,
                kind: NodeKind::Decorator {
                    decorator,
                    child: 0,
                },
                location: Some(at),
            });
            self.locations.push(name_location(def).unwrap_or(at));
            let c = self.node(child, Some(id), depth + 1, child_path(&path, 0))?;
            if let NodeKind::Decorator { child, .. } = &mut self.nodes[id].kind {
                *child = c;
            }
            return Ok(id);
        }
        let (name, kind, children) = match &def.value {
            NodeDef::Action(a) => (&a.name, NodeKind::Action(self.action(a)?), None),
            NodeDef::Condition(c) => {
                let ps = self.probability("ps", &c.ps)?;
                (&c.name, NodeKind::Condition { ps }, None)
            }
            NodeDef::Sequence(c) => (
                &c.name,
                NodeKind::Sequence {
                    children: Vec::new(),
                },
                Some(&c.children),
            ),
            NodeDef::Fallback(c) => (
                &c.name,
                NodeKind::Fallback {
                    children: Vec::new(),
                },
                Some(&c.children),
            ),
            NodeDef::Parallel(p) => (
                &p.name,
                NodeKind::Parallel {
                    success_threshold: 0,
                    failure_threshold: 0,
                    children: Vec::new(),
                },
                Some(&p.children),
            ),
            NodeDef::IfThenElse(c) => (
                &c.name,
                NodeKind::Flow(Flow {
                    children: Vec::new(),
                    states: Vec::new(),
                }),
                Some(&c.children),
            ),
            NodeDef::Flow(f) => (
                &f.name,
                NodeKind::Flow(Flow {
                    children: Vec::new(),
                    states: Vec::new(),
                }),
                Some(&f.children),
            ),
            _ => unreachable!("decorators are handled above"),
        };
        let keyword = match &def.value {
            NodeDef::IfThenElse(_) => "if_then_else",
            _ => kind.keyword(),
        };
        let name = self.node_name(name, keyword, &path)?;
        self.nodes.push(Node {
            name,
            path: path.clone(),
            depth,
            parent,
            kind,
            location: Some(at),
        });
        self.locations.push(name_location(def).unwrap_or(at));
        if let Some(list) = children {
            if list.value.is_empty() {
                let keyword = self.nodes[id].kind.keyword();
                return Err(self
                    .err(
                        Kind::Structure,
                        loc(list),
                        format!("{keyword} has no children"),
                    )
                    .with_help("a control node needs at least one child"));
            }
            let mut ids = Vec::with_capacity(list.value.len());
            for (i, child) in list.value.iter().enumerate() {
                ids.push(self.node(child, Some(id), depth + 1, child_path(&path, i))?);
            }
            let thresholds = match &def.value {
                NodeDef::Parallel(p) => Some(self.thresholds(p, ids.len())?),
                _ => None,
            };
            let flow = match &def.value {
                NodeDef::IfThenElse(_) => {
                    if !(2..=3).contains(&ids.len()) {
                        return Err(self
                            .err(
                                Kind::Structure,
                                loc(list),
                                format!("if_then_else has {} children", ids.len()),
                            )
                            .with_help(
                                "if_then_else takes 2 or 3 children: condition, then, else \
                                 (without else it fails when the condition fails)",
                            ));
                    }
                    Some(Flow::if_then_else(ids[0], ids[1], ids.get(2).copied()))
                }
                NodeDef::Flow(f) => Some(self.flow(f, ids.clone())?),
                _ => None,
            };
            match &mut self.nodes[id].kind {
                NodeKind::Sequence { children } | NodeKind::Fallback { children } => {
                    *children = ids
                }
                NodeKind::Parallel {
                    children,
                    success_threshold,
                    failure_threshold,
                } => {
                    *children = ids;
                    (*success_threshold, *failure_threshold) = thresholds.unwrap_or((0, 0));
                }
                NodeKind::Flow(f) => *f = flow.expect("a flow definition"),
                _ => unreachable!("only control nodes have children"),
            }
        }
        Ok(id)
    }

    fn node_name(
        &self,
        name: &Option<At<String>>,
        keyword: &str,
        path: &str,
    ) -> Result<String, TreeError> {
        match name {
            Some(n) if n.value.trim().is_empty() => Err(self
                .err(Kind::InvalidValue, loc(n), "a node name must not be empty")
                .with_help("omit `name` to get a generated one")),
            Some(n) => Ok(n.value.clone()),
            None => Ok(format!("{keyword}@{path}")),
        }
    }

    #[allow(clippy::type_complexity)]
    fn decorator<'d>(
        &self,
        def: &'d NodeDef,
    ) -> Result<Option<(&'d Option<At<String>>, Decorator, &'d At<NodeDef>)>, TreeError> {
        Ok(Some(match def {
            NodeDef::Inverter(d) => (&d.name, Decorator::Inverter, &d.child),
            NodeDef::ForceSuccess(d) => (&d.name, Decorator::ForceSuccess, &d.child),
            NodeDef::ForceFailure(d) => (&d.name, Decorator::ForceFailure, &d.child),
            NodeDef::UntilFailure(d) => (&d.name, Decorator::UntilFailure, &d.child),
            NodeDef::UntilSuccess(d) => (&d.name, Decorator::UntilSuccess, &d.child),
            NodeDef::Retry(d) => (
                &d.name,
                Decorator::Retry {
                    attempts: self.count("attempts", &d.attempts)?,
                },
                &d.child,
            ),
            NodeDef::Repeat(d) => (
                &d.name,
                Decorator::Repeat {
                    times: self.count("times", &d.times)?,
                },
                &d.child,
            ),
            _ => return Ok(None),
        }))
    }

    /// The states of a `flow:` over children `ids`.
    fn flow(&self, def: &FlowDef, ids: Vec<usize>) -> Result<Flow, TreeError> {
        let n_states = def.states.value.len();
        let index = |v: &At<f64>, what: &str, bound: usize| -> Result<usize, TreeError> {
            let x = v.value;
            if !(x.is_finite() && x.fract() == 0.0 && x >= 0.0 && x < bound as f64) {
                return Err(self
                    .err(
                        Kind::InvalidValue,
                        loc(v),
                        format!("{what} {x} does not exist"),
                    )
                    .with_help(format!(
                        "{what}s are numbered from 0 to {} in the order written",
                        bound.saturating_sub(1)
                    )));
            }
            Ok(x as usize)
        };
        let mut states = Vec::with_capacity(n_states);
        for (i, s) in def.states.value.iter().enumerate() {
            let child = index(&s.value.run, "child", ids.len())?;
            let next = |n: &At<NextDef>| -> Result<FlowNext, TreeError> {
                match &n.value {
                    NextDef::Outcome(w) if w == "success" => Ok(FlowNext::Success),
                    NextDef::Outcome(w) if w == "failure" => Ok(FlowNext::Failure),
                    NextDef::Outcome(w) => Err(self
                        .err(Kind::InvalidValue, loc(n), format!("`{w}` is not a state"))
                        .with_help("write a later state's number, `success` or `failure`")),
                    NextDef::State(_) => {
                        let at = At {
                            value: match n.value {
                                NextDef::State(x) => x,
                                _ => unreachable!(),
                            },
                            line: n.line,
                            column: n.column,
                        };
                        let j = index(&at, "state", n_states)?;
                        if j <= i {
                            return Err(self
                                .err(
                                    Kind::Structure,
                                    loc(n),
                                    format!("state {i} goes back to state {j}"),
                                )
                                .with_help(
                                    "a flow is acyclic: a state may only lead to a later state \
                                     (repeat with retry/repeat around the flow instead)",
                                ));
                        }
                        Ok(FlowNext::State(j))
                    }
                }
            };
            states.push(FlowState {
                child,
                on_success: next(&s.value.success)?,
                on_failure: next(&s.value.failure)?,
            });
        }
        Flow::new(ids, states).map_err(|what| {
            self.err(
                Kind::Structure,
                loc(&def.states),
                format!("invalid flow: {what}"),
            )
            .with_help("every child must be run by some state; state 0 runs first")
        })
    }

    /// A repetition count: a whole number from 1 to 1,000,000.
    fn count(&self, key: &str, v: &At<f64>) -> Result<usize, TreeError> {
        let x = v.value;
        if !(x.is_finite() && x.fract() == 0.0 && (1.0..=1e6).contains(&x)) {
            return Err(self
                .err(
                    Kind::InvalidValue,
                    loc(v),
                    format!("{key} = {x} is not a valid count"),
                )
                .with_help(format!("{key} must be a whole number from 1 to 1000000")));
        }
        Ok(x as usize)
    }

    fn thresholds(&self, p: &ParallelDef, n: usize) -> Result<(usize, usize), TreeError> {
        let check = |t: &At<f64>, key: &str, meaning: &str| -> Result<usize, TreeError> {
            let v = t.value;
            if !(v.is_finite() && v.fract() == 0.0 && v >= 1.0 && v <= n as f64) {
                return Err(self
                    .err(
                        Kind::InvalidValue,
                        loc(t),
                        format!(
                            "{key} = {v} is not valid for {n} {}",
                            if n == 1 { "child" } else { "children" }
                        ),
                    )
                    .with_help(format!(
                        "{key} must be a whole number from 1 to {n}: {meaning}"
                    )));
            }
            Ok(v as usize)
        };
        let m = match &p.success_threshold {
            Some(t) => check(t, "success_threshold", "Success at >= M successes")?,
            None => n,
        };
        let f = match &p.failure_threshold {
            Some(t) => check(t, "failure_threshold", "Failure at >= F failures")?,
            None => n - m + 1,
        };
        Ok((m, f))
    }

    fn probability(&self, key: &str, v: &At<f64>) -> Result<f64, TreeError> {
        let x = v.value;
        if !x.is_finite() || !(0.0..=1.0).contains(&x) {
            return Err(self
                .err(
                    Kind::InvalidValue,
                    loc(v),
                    format!("{key} = {x} is not a probability"),
                )
                .with_help(format!("{key} must be a number in [0, 1]")));
        }
        Ok(x)
    }

    fn action(&self, a: &ActionDef) -> Result<Action, TreeError> {
        let params = ActionParams {
            ps: Some(a.ps.clone()),
            pf: a.pf.clone(),
            mu: a.mu.clone(),
            nu: a.nu.clone(),
            tau_s: a.tau_s.clone(),
            tau_f: a.tau_f.clone(),
            success_time: a.success_time.clone(),
            failure_time: a.failure_time.clone(),
        };
        let err = |at: (usize, usize), message: String, help: String| {
            self.err(Kind::InvalidValue, at, message).with_help(help)
        };
        match validate_action(&params, &err)? {
            Ok(action) => Ok(action),
            Err(missing) => {
                let (what, help) = missing.split_once(": ").unwrap_or((&missing, ""));
                Err(self
                    .err(Kind::MissingParameter, loc(&a.ps), format!("action {what}"))
                    .with_help(help.to_string()))
            }
        }
    }

    fn check_names(&self) -> Result<(), TreeError> {
        let mut seen: std::collections::HashMap<&str, usize> =
            std::collections::HashMap::with_capacity(self.nodes.len());
        for (i, n) in self.nodes.iter().enumerate() {
            if let Some(&j) = seen.get(n.name.as_str()) {
                let (l, c) = self.locations[j];
                return Err(self
                    .err(
                        Kind::Structure,
                        self.locations[i],
                        format!("duplicate node name '{}'", n.name),
                    )
                    .with_help(format!(
                        "names must be unique; '{}' is already used at line {l}, column {c}",
                        n.name
                    )));
            }
            seen.insert(&n.name, i);
        }
        Ok(())
    }
}

/// `{path}.{i}` without the formatting machinery (a million-node tree
/// builds a million of these).
fn child_path(path: &str, i: usize) -> String {
    let mut digits = [0u8; 20];
    let mut k = digits.len();
    let mut n = i;
    loop {
        k -= 1;
        digits[k] = b'0' + (n % 10) as u8;
        n /= 10;
        if n == 0 {
            break;
        }
    }
    let mut p = String::with_capacity(path.len() + 1 + digits.len() - k);
    p.push_str(path);
    p.push('.');
    p.extend(digits[k..].iter().map(|&d| d as char));
    p
}

fn name_location(def: &At<NodeDef>) -> Option<(usize, usize)> {
    let name = match &def.value {
        NodeDef::Action(a) => &a.name,
        NodeDef::Condition(c) => &c.name,
        NodeDef::Sequence(c) | NodeDef::Fallback(c) | NodeDef::IfThenElse(c) => &c.name,
        NodeDef::Parallel(p) => &p.name,
        NodeDef::Flow(f) => &f.name,
        NodeDef::Inverter(d)
        | NodeDef::ForceSuccess(d)
        | NodeDef::ForceFailure(d)
        | NodeDef::UntilFailure(d)
        | NodeDef::UntilSuccess(d) => &d.name,
        NodeDef::Retry(d) => &d.name,
        NodeDef::Repeat(d) => &d.name,
    };
    name.as_ref().map(loc)
}
