//! How much the root's figure depends on each leaf parameter
//! (`btrel sensitivity`).
//!
//! For every leaf parameter θ (a condition's `ps`; an action's `ps`, `mu`,
//! `nu`, `tau_s`, `tau_f`, and the stage parameters of an Erlang or
//! two-branch hyperexponential time, [`Param::StageRate`] ...) the derivative ∂O/∂θ of the root's objective O
//! (ps, MTTS, MTTF, mean time E\[T\] = ps·MTTS + pf·MTTF, or P(Success by a
//! deadline)) and its elasticity ∂ln O/∂ln θ = θ/O · ∂O/∂θ (the % change of
//! O per % change of θ). Changing an action's `ps` changes `pf = 1 − ps` with
//! it; changing `tau_s` of a hybrid action (Def. 9.9) moves the cap of its
//! exponential failure time with it (likewise `tau_f`).
//!
//! # Derivatives: exact where the algebra allows (`sensitivity::exact`)
//!
//! Dual numbers carried from the leaf up to the root through the maps of
//! Sequence, Fallback, flows, decorators and loops, and the count
//! programme of a Parallel's P(S)/P(F) (`sensitivity::exact` module docs);
//! through a Parallel's product phase chain and a counted Parallel's
//! quadrature of its mean times by the engine's chains rebuilt in dual
//! numbers, and P(Success by a deadline) of a phase chain by uniformising
//! its doubled chain (`sensitivity::chain` module docs). Every row says
//! which method gave it ([`Scheme`]). The rest (races and counted Parallels
//! over deterministic, hybrid or shifted leaves, strategy `book`'s
//! Parallels, trees with Nav2 nodes, P(Success by a deadline) of a tree
//! that is not one phase chain) is differenced, and so is a stage
//! parameter wherever a node needs its leaf's phase chain (its moments are
//! exact):
//!
//! # Richardson-extrapolated differences through the engine
//!
//! Each such derivative is a central difference D(h) = (O(θ+h) − O(θ−h))/2h of
//! the engine's figures, extrapolated to h → 0 from h and h/2: R = (4D(h/2)
//! − D(h))/3 (error O(h⁴)), with h = 10⁻³·θ (10⁻³ for θ = 0). The error
//! estimate is |R − D(h/2)|, which bounds the error of the less accurate
//! D(h/2). Where θ − h leaves the parameter's domain (ps near 0 or 1, a
//! time near 0) the differences are one-sided, D(h) = (O(θ+h) − O(θ))/h,
//! extrapolated as R = 2D(h/2) − D(h) (error O(h²)), and the row says so.
//! The engine's figures are exact up to rounding (and the truncation
//! tolerance of π(t)), so the error is dominated by the extrapolation.

mod chain;
mod dual;
mod exact;

use crate::compile::{Analysis, AnalysisError, Options, Plan};
use crate::curve::CurveOptions;
use crate::tree::{Duration, NodeId, NodeKind, Tree};
use crate::Model;

/// What the derivatives are of: a figure of the root.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Objective {
    Ps,
    Mtts,
    Mttf,
    /// E\[T\] = ps·MTTS + pf·MTTF.
    MeanTime,
    /// P(root returned Success by the deadline).
    SuccessBy(f64),
}

impl Objective {
    /// The name on the command line.
    pub fn name(&self) -> &'static str {
        match self {
            Objective::Ps => "ps",
            Objective::Mtts => "mtts",
            Objective::Mttf => "mttf",
            Objective::MeanTime => "mean-time",
            Objective::SuccessBy(_) => "success-by",
        }
    }

    /// The objective in words, for sentences.
    pub fn describe(&self) -> String {
        match self {
            Objective::Ps => "the root's P(Success)".into(),
            Objective::Mtts => "the root's MTTS".into(),
            Objective::Mttf => "the root's MTTF".into(),
            Objective::MeanTime => "the root's mean time E[T]".into(),
            Objective::SuccessBy(t) => {
                format!("P(success by {} s)", crate::number::full(*t))
            }
        }
    }
}

/// A leaf parameter.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Param {
    Ps,
    Mu,
    Nu,
    TauS,
    TauF,
    /// The stage rate of an Erlang-k (or shifted exponential) time of the
    /// Success (`true`) or Failure outcome: `success_rate`, `failure_rate`.
    StageRate(bool),
    /// A two-branch hyperexponential time's first branch probability
    /// (`success_p`, `failure_p`), and its branches' rates (`success_rate1`,
    /// `success_rate2`, ...), in the order the law was written.
    Branch(bool),
    Rate1(bool),
    Rate2(bool),
}

impl Param {
    pub fn name(&self) -> &'static str {
        match self {
            Param::Ps => "ps",
            Param::Mu => "mu",
            Param::Nu => "nu",
            Param::TauS => "tau_s",
            Param::TauF => "tau_f",
            Param::StageRate(true) => "success_rate",
            Param::StageRate(false) => "failure_rate",
            Param::Branch(true) => "success_p",
            Param::Branch(false) => "failure_p",
            Param::Rate1(true) => "success_rate1",
            Param::Rate1(false) => "failure_rate1",
            Param::Rate2(true) => "success_rate2",
            Param::Rate2(false) => "failure_rate2",
        }
    }

    /// Whether it is a parameter of a phase-type law's stages (Erlang,
    /// hyperexponential).
    pub fn of_stages(&self) -> bool {
        matches!(
            self,
            Param::StageRate(_) | Param::Branch(_) | Param::Rate1(_) | Param::Rate2(_)
        )
    }
}

/// The stage parameters of a phase-type law: `(k, rate)` of an Erlang-k
/// (shifted or not), or the two `(p, rate)` branches of a hyperexponential.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum StageLaw {
    Erlang(u32, f64),
    Hyper([(f64, f64); 2]),
}

impl StageLaw {
    /// The shift and stage law of a duration, when it is one of these.
    pub fn of(d: &Duration) -> Option<(f64, StageLaw)> {
        let Duration::PhaseType { shift, stages } = *d else {
            return None;
        };
        if let Some((k, r)) = stages.as_erlang() {
            return Some((shift, StageLaw::Erlang(k, r)));
        }
        Some((shift, StageLaw::Hyper(stages.as_two_branches()?)))
    }

    /// The law's parameters for one outcome, with their values.
    fn params(&self, success: bool) -> Vec<(Param, f64)> {
        match *self {
            StageLaw::Erlang(_, r) => vec![(Param::StageRate(success), r)],
            StageLaw::Hyper([(p, r1), (_, r2)]) => vec![
                (Param::Branch(success), p),
                (Param::Rate1(success), r1),
                (Param::Rate2(success), r2),
            ],
        }
    }

    /// The law with `param` set to `x`.
    fn with(self, param: Param, x: f64) -> StageLaw {
        match (self, param) {
            (StageLaw::Erlang(k, _), Param::StageRate(_)) => StageLaw::Erlang(k, x),
            (StageLaw::Hyper([a, b]), Param::Branch(_)) => {
                StageLaw::Hyper([(x, a.1), (1.0 - x, b.1)])
            }
            (StageLaw::Hyper([a, b]), Param::Rate1(_)) => StageLaw::Hyper([(a.0, x), b]),
            (StageLaw::Hyper([a, b]), Param::Rate2(_)) => StageLaw::Hyper([a, (b.0, x)]),
            _ => self,
        }
    }

    /// `d mean / d param` (the shift does not move).
    pub(crate) fn mean_derivative(&self, param: Param) -> Option<f64> {
        match (*self, param) {
            (StageLaw::Erlang(k, r), Param::StageRate(_)) => Some(-f64::from(k) / (r * r)),
            (StageLaw::Hyper([(_, r1), (_, r2)]), Param::Branch(_)) => Some(1.0 / r1 - 1.0 / r2),
            (StageLaw::Hyper([(p, r1), _]), Param::Rate1(_)) => Some(-p / (r1 * r1)),
            (StageLaw::Hyper([_, (q, r2)]), Param::Rate2(_)) => Some(-q / (r2 * r2)),
            _ => None,
        }
    }

    fn duration(&self, shift: f64) -> Option<Duration> {
        let stages = match *self {
            StageLaw::Erlang(k, r) => crate::tree::Stages::erlang(k, r),
            StageLaw::Hyper(b) => crate::tree::Stages::hyperexponential(&b),
        };
        stages.ok().map(|s| Duration::phase_type(shift, s))
    }
}

/// How a derivative was computed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Scheme {
    /// Exact: dual numbers through the node maps (`sensitivity::exact` module docs).
    Exact,
    /// Richardson-extrapolated central differences, error O(h⁴).
    Central,
    /// Richardson-extrapolated one-sided differences (at a domain
    /// boundary), error O(h²).
    Forward,
}

impl Scheme {
    pub fn name(&self) -> &'static str {
        match self {
            Scheme::Exact => "exact",
            Scheme::Central => "richardson-central",
            Scheme::Forward => "richardson-forward",
        }
    }

    /// `exact` or `richardson` (the JSON's `method`).
    pub fn method(&self) -> &'static str {
        match self {
            Scheme::Exact => "exact",
            Scheme::Central | Scheme::Forward => "richardson",
        }
    }
}

/// One parameter's sensitivity.
#[derive(Debug, Clone, PartialEq)]
pub struct Row {
    pub leaf: NodeId,
    pub param: Param,
    pub value: f64,
    pub derivative: f64,
    /// θ/O · ∂O/∂θ; `None` when O = 0 or undefined.
    pub elasticity: Option<f64>,
    pub scheme: Scheme,
    /// Estimated absolute error of the derivative.
    pub error: f64,
}

/// The result: the objective's value and the rows, ranked by |elasticity|
/// (rows without one last, by |derivative|).
#[derive(Debug, Clone, PartialEq)]
pub struct Sensitivity {
    pub objective: Objective,
    pub value: f64,
    pub rows: Vec<Row>,
    /// Parameters without a derivative, and why.
    pub skipped: Vec<String>,
}

/// Errors: the analysis failed, or the objective is undefined at the
/// given parameters.
#[derive(Debug)]
pub enum SensitivityError {
    Analysis(AnalysisError),
    Undefined(String),
}

impl From<AnalysisError> for SensitivityError {
    fn from(e: AnalysisError) -> Self {
        SensitivityError::Analysis(e)
    }
}

impl From<crate::Error> for SensitivityError {
    fn from(e: crate::Error) -> Self {
        match e {
            crate::Error::Analysis(e) => SensitivityError::Analysis(e),
            // a deadline that is not a time: the objective is undefined
            other => SensitivityError::Undefined(other.to_string()),
        }
    }
}

/// The root's objective for a tree.
pub(crate) fn objective_value(
    tree: &Tree,
    objective: Objective,
    options: &Options,
) -> Result<f64, SensitivityError> {
    objective_of(&Model::with_options(tree, *options)?, objective)
}

/// The root's objective from the tree's model.
fn objective_of(model: &Model, objective: Objective) -> Result<f64, SensitivityError> {
    if let Objective::SuccessBy(t) = objective {
        return Ok(model.curve(Tree::ROOT, &[t])?[0].success);
    }
    let f = model.figures(Tree::ROOT)?;
    let undefined =
        |what: &str| SensitivityError::Undefined(format!("the root's {what} is undefined"));
    Ok(match objective {
        Objective::Ps => f.ps,
        Objective::Mtts => f
            .mtts
            .ok_or_else(|| undefined("MTTS (it never succeeds)"))?,
        Objective::Mttf => f.mttf.ok_or_else(|| undefined("MTTF (it never fails)"))?,
        Objective::MeanTime => f.mean_time(),
        Objective::SuccessBy(_) => unreachable!("handled above"),
    })
}

/// The parameters of a leaf and their values (a parameter that has no
/// meaning for it, e.g. `mu` of an action that never succeeds, is absent).
pub(crate) fn params_of(kind: &NodeKind) -> Vec<(Param, f64)> {
    match kind {
        NodeKind::Condition { ps } => vec![(Param::Ps, *ps)],
        NodeKind::Action(a) => {
            let mut v = vec![(Param::Ps, a.ps)];
            for (d, rate, tau) in [
                (a.success, Param::Mu, Param::TauS),
                (a.failure, Param::Nu, Param::TauF),
            ] {
                match d {
                    Some(Duration::Exponential { rate: r })
                    | Some(Duration::TruncatedExponential { rate: r, .. }) => v.push((rate, r)),
                    Some(Duration::Fixed { time }) => v.push((tau, time)),
                    // a shifted law's shift is its tau; the stages of an
                    // Erlang or two-branch hyperexponential law have their
                    // own parameters (other phase-type laws' are held)
                    Some(d @ Duration::PhaseType { shift, .. }) => {
                        if shift > 0.0 {
                            v.push((tau, shift));
                        }
                        if let Some((_, law)) = StageLaw::of(&d) {
                            v.extend(law.params(tau == Param::TauS));
                        }
                    }
                    None => {}
                }
            }
            v
        }
        _ => Vec::new(),
    }
}

/// `tree` with leaf `id`'s parameter set to `x` (see the module docs for
/// what moves with it).
pub(crate) fn with_param(tree: &Tree, id: NodeId, param: Param, x: f64) -> Tree {
    let mut t = tree.clone();
    match &mut t.nodes[id].kind {
        NodeKind::Condition { ps } => *ps = x,
        NodeKind::Action(a) => match param {
            Param::Ps => {
                a.ps = x;
                a.pf = 1.0 - x;
            }
            Param::Mu | Param::Nu => {
                let d = if param == Param::Mu {
                    &mut a.success
                } else {
                    &mut a.failure
                };
                if let Some(
                    Duration::Exponential { rate } | Duration::TruncatedExponential { rate, .. },
                ) = d
                {
                    *rate = x;
                }
            }
            Param::TauS | Param::TauF => {
                let (own, other) = if param == Param::TauS {
                    (&mut a.success, &mut a.failure)
                } else {
                    (&mut a.failure, &mut a.success)
                };
                if let Some(Duration::Fixed { time } | Duration::PhaseType { shift: time, .. }) =
                    own
                {
                    *time = x;
                }
                if let Some(Duration::TruncatedExponential { cap, .. }) = other {
                    *cap = x;
                }
            }
            Param::StageRate(success)
            | Param::Branch(success)
            | Param::Rate1(success)
            | Param::Rate2(success) => {
                let d = if success {
                    &mut a.success
                } else {
                    &mut a.failure
                };
                if let Some((shift, law)) = d.as_ref().and_then(StageLaw::of) {
                    if let Some(new) = law.with(param, x).duration(shift) {
                        *d = Some(new);
                    }
                }
            }
        },
        _ => {}
    }
    t
}

/// Whether `x` is a valid value of the parameter for this leaf.
fn in_domain(kind: &NodeKind, param: Param, x: f64) -> bool {
    match param {
        Param::Ps => {
            let ok = (0.0..=1.0).contains(&x);
            match kind {
                // an action needs a time for every outcome it can have
                NodeKind::Action(a) => {
                    ok && (x == 0.0 || a.success.is_some()) && (x == 1.0 || a.failure.is_some())
                }
                _ => ok,
            }
        }
        Param::Mu | Param::Nu | Param::StageRate(_) | Param::Rate1(_) | Param::Rate2(_) => {
            x > 0.0 && x.is_finite()
        }
        Param::Branch(_) => x > 0.0 && x < 1.0,
        Param::TauS | Param::TauF => x >= 0.0 && x.is_finite(),
    }
}

/// The derivative of `f` at `x` by Richardson extrapolation (module docs):
/// (derivative, error estimate, scheme).
pub fn richardson(
    f: &mut dyn FnMut(f64) -> Result<f64, SensitivityError>,
    x: f64,
    fx: f64,
    h: f64,
    central: bool,
) -> Result<(f64, f64, Scheme), SensitivityError> {
    if central {
        let d1 = (f(x + h)? - f(x - h)?) / (2.0 * h);
        let d2 = (f(x + h / 2.0)? - f(x - h / 2.0)?) / h;
        let r = (4.0 * d2 - d1) / 3.0;
        Ok((r, (r - d2).abs(), Scheme::Central))
    } else {
        let d1 = (f(x + h)? - fx) / h;
        let d2 = (f(x + h / 2.0)? - fx) / (h / 2.0);
        let r = 2.0 * d2 - d1;
        Ok((r, (r - d2).abs(), Scheme::Forward))
    }
}

/// Sensitivities of the root's `objective` to every leaf parameter: exact
/// where the node maps allow (`sensitivity::exact`), Richardson otherwise (each row
/// says which).
pub fn sensitivity(
    tree: &Tree,
    objective: Objective,
    options: &Options,
) -> Result<Sensitivity, SensitivityError> {
    sensitivity_with(tree, objective, options, true)
}

/// [`sensitivity`] with every derivative by Richardson extrapolation (a
/// cross-check of the exact derivatives).
pub fn sensitivity_by_differences(
    tree: &Tree,
    objective: Objective,
    options: &Options,
) -> Result<Sensitivity, SensitivityError> {
    sensitivity_with(tree, objective, options, false)
}

fn sensitivity_with(
    tree: &Tree,
    objective: Objective,
    options: &Options,
    exact: bool,
) -> Result<Sensitivity, SensitivityError> {
    // one model: the objective, and the plan and analysis the exact
    // derivatives start from (not for a tree with Nav2 nodes: its leaves
    // stand for several)
    let model = Model::with_options(tree, *options)?;
    let value = objective_of(&model, objective)?;
    let plan = if exact { model.own_plan() } else { None };
    let grids = exact::Grids::default();
    let analysis = match plan {
        Some(_) if !matches!(objective, Objective::SuccessBy(_)) => Some(model.analysis()?),
        _ => None,
    };
    let mut rows = Vec::new();
    let mut skipped = Vec::new();
    for (id, node) in tree.nodes.iter().enumerate() {
        if !node.kind.children().is_empty() {
            continue;
        }
        for (param, x) in params_of(&node.kind) {
            if let Some(d) = plan
                .and_then(|p| exact_derivative(p, &grids, analysis, id, param, objective, value))
            {
                if in_domain(&node.kind, param, x + 1e-9) || in_domain(&node.kind, param, x - 1e-9)
                {
                    let elasticity = (value != 0.0 && value.is_finite()).then(|| d * x / value);
                    rows.push(Row {
                        leaf: id,
                        param,
                        value: x,
                        derivative: d,
                        elasticity,
                        scheme: Scheme::Exact,
                        error: 0.0,
                    });
                    continue;
                }
            }
            let h0 = if x == 0.0 { 1e-3 } else { 1e-3 * x.abs() };
            let h = if param == Param::Ps { h0.min(1e-3) } else { h0 };
            let up = in_domain(&node.kind, param, x + h);
            let down = in_domain(&node.kind, param, x - h);
            let mut f =
                |v: f64| objective_value(&with_param(tree, id, param, v), objective, options);
            let (derivative, error, scheme) = match (up, down) {
                (true, true) => richardson(&mut f, x, value, h, true)?,
                (true, false) => richardson(&mut f, x, value, h, false)?,
                (false, true) => richardson(&mut f, x, value, -h, false)?,
                (false, false) => {
                    skipped.push(format!(
                        "{} {}: cannot be changed ({} = {x}, and the action has no time for the other outcome)",
                        node.name,
                        param.name(),
                        param.name()
                    ));
                    continue;
                }
            };
            let elasticity = (value != 0.0 && value.is_finite()).then(|| derivative * x / value);
            rows.push(Row {
                leaf: id,
                param,
                value: x,
                derivative,
                elasticity,
                scheme,
                error,
            });
        }
    }
    rows.sort_by(|a, b| {
        let key = |r: &Row| {
            (
                r.elasticity.is_none(),
                -r.elasticity.map_or(r.derivative.abs(), f64::abs),
            )
        };
        let (ka, kb) = (key(a), key(b));
        ka.0.cmp(&kb.0).then(ka.1.total_cmp(&kb.1))
    });
    Ok(Sensitivity {
        objective,
        value,
        rows,
        skipped,
    })
}

/// The exact derivative of the root's `objective` along leaf `id`'s
/// `param` (`sensitivity::exact`, `sensitivity::chain`), or `None` where it
/// is not available. `value` is the engine's objective: a dual value that
/// disagrees with it beyond rounding falls back to differences.
fn exact_derivative(
    plan: &Plan,
    grids: &exact::Grids,
    analysis: Option<&Analysis>,
    id: NodeId,
    param: Param,
    objective: Objective,
    value: f64,
) -> Option<f64> {
    if let Objective::SuccessBy(t) = objective {
        let max_work = CurveOptions::default().max_work;
        let p = exact::success_by_tangent(plan, grids, id, param, t, max_work)?;
        return ((p.v - value).abs() <= 1e-9 && p.d.is_finite()).then_some(p.d);
    }
    let [ps, pf, ts, tf] = exact::root_tangent(plan, grids, analysis?, id, param)?;
    let d = match objective {
        Objective::Ps => ps.d,
        Objective::Mtts => (ts.d * ps.v - ts.v * ps.d) / (ps.v * ps.v),
        Objective::Mttf => (tf.d * pf.v - tf.v * pf.d) / (pf.v * pf.v),
        Objective::MeanTime => ts.d + tf.d,
        Objective::SuccessBy(_) => unreachable!("handled above"),
    };
    d.is_finite().then_some(d)
}

/// The change a sentence describes for a row: ps by ±0.1 (within [0, 1]),
/// a hyperexponential's branch probability by ±0.1 (within (0, 1)), other
/// parameters by +10%.
pub(crate) fn step_for(row: &Row) -> f64 {
    match row.param {
        Param::Ps if row.value <= 0.9 => (row.value + 0.1).min(1.0),
        Param::Ps => row.value - 0.1,
        Param::Branch(_) if row.value < 0.9 => row.value + 0.1,
        Param::Branch(_) if row.value > 0.1 => row.value - 0.1,
        Param::Branch(_) => row.value / 2.0,
        _ if row.value == 0.0 => 0.1,
        _ => row.value * 1.1,
    }
}

/// "raising X's ps from 0.5 to 0.6 raises P(success by 100 s) from 0.198 to
/// 0.243": the new value by running the engine again.
pub fn sentence(
    tree: &Tree,
    s: &Sensitivity,
    row: &Row,
    options: &Options,
) -> Result<String, SensitivityError> {
    use crate::number::significant;
    let to = step_for(row);
    let mut changed = with_param(tree, row.leaf, row.param, to);
    if !in_domain(&tree.nodes[row.leaf].kind, row.param, to) {
        changed = tree.clone();
    }
    let new = objective_value(&changed, s.objective, options)?;
    let verb = |up: bool| if up { "raises" } else { "lowers" };
    let effect = if new == s.value {
        format!(
            "leaves {} at {}",
            s.objective.describe(),
            significant(new, 3)
        )
    } else {
        format!(
            "{} {} from {} to {}",
            verb(new > s.value),
            s.objective.describe(),
            significant(s.value, 3),
            significant(new, 3)
        )
    };
    Ok(format!(
        "{} {}'s {} from {} to {} {effect}",
        if to > row.value {
            "raising"
        } else {
            "lowering"
        },
        tree.nodes[row.leaf].name,
        row.param.name(),
        significant(row.value, 3),
        significant(to, 3),
    ))
}
