//! Node types whose control flow depends on the robot or on a person, read
//! under the SBT assumptions with the numbers the params file gives:
//!
//! * Nav2's `DistanceController` and `SpeedController` (they tick their
//!   child the first time, then again once the robot has travelled
//!   `distance` since the child's last Success, or once a period set by the
//!   robot's speed has passed): RateControllers whose period comes from the
//!   robot's speed, a port value `"<node>/speed": {value: v}` in m/s.
//! * Nav2's `GoalUpdatedController` (ticks its child the first time and
//!   again when the goal changes) and `PathLongerOnApproach` (ticks its
//!   child only when a re-planned path near the goal is much longer).
//! * BT.CPP v3's `ManualSelector` (the user picks the child to run): a
//!   branch chosen with the probabilities of the params file.

use super::{
    Builder, Decorator, Elem, Flow, FlowNext, FlowState, Kind, LeafKind, NodeKind, TreeError,
};

impl<'a> Builder<'a> {
    /// A number the params file gives port `port` of `e` (a port whose
    /// value comes from the robot, not from the XML): the entry
    /// `"<node>/<port>": {value: x}`, keyed by the full name, then the
    /// `name` attribute, then the type. `None` (and the keys tried) if
    /// absent.
    pub(super) fn port_value(
        &self,
        e: &Elem,
        ty: &str,
        base: &str,
        prefix: &str,
        port: &str,
    ) -> Result<Result<f64, Vec<String>>, TreeError> {
        let mut keys = vec![format!("{prefix}{base}/{port}")];
        if let Some(n) = self.name_attr(e)? {
            keys.push(format!("{n}/{port}"));
        }
        keys.push(format!("{ty}/{port}"));
        keys.dedup();
        for k in &keys {
            if let Some(v) = self.table.blackboard.get(k) {
                self.blackboard_used.borrow_mut().insert(k.clone());
                return Ok(Ok(v.value));
            }
        }
        Ok(Err(keys))
    }

    /// A number attribute of `e` with BT.CPP's default; `None` (a problem
    /// recorded) for a blackboard reference.
    fn number_attr(
        &mut self,
        e: &Elem,
        ty: &str,
        key: &str,
        default: f64,
    ) -> Result<Option<f64>, TreeError> {
        let Some(a) = e.attr(key) else {
            return Ok(Some(default));
        };
        let v = a.value.trim();
        if let Some(given) = self.table.blackboard.get(v) {
            self.blackboard_used.borrow_mut().insert(v.to_string());
            return Ok(Some(given.value));
        }
        if v.starts_with('{') {
            self.missing_value(e, a.loc, ty, key, "give it", "x");
            return Ok(None);
        }
        match v.parse::<f64>() {
            Ok(x) if x.is_finite() => Ok(Some(x)),
            _ => Err(self
                .err(
                    Kind::InvalidValue,
                    a.loc,
                    format!("{key} = \"{v}\" is not a number"),
                )
                .with_help(format!("write {key} as a number such as 1.0"))),
        }
    }

    /// Nav2's `DistanceController` / `SpeedController` as a RateController
    /// (`Decorator::Rate`): `(first wait, period)` in seconds, from the
    /// robot's speed `v` (`"<node>/speed": {value: v}`, m/s, assumed
    /// constant while the node runs). DistanceController: `distance / v`
    /// (both waits; `distance` default 1.0 m). SpeedController: Nav2's
    /// `getScaledRate`, rate = clamp(min_rate + (v − min_speed) / (max_speed
    /// − min_speed) · (max_rate − min_rate), min_rate, max_rate), period
    /// 1/rate, the first wait 2/(min_rate + max_rate) (the period it starts
    /// with; `updatePeriod` runs only when that has passed). `None` when a
    /// problem was recorded.
    pub(super) fn motion_period(
        &mut self,
        e: &Elem,
        ty: &str,
        distance: bool,
        base: &str,
        prefix: &str,
    ) -> Result<Option<(f64, f64)>, TreeError> {
        let speed = match self.port_value(e, ty, base, prefix, "speed")? {
            Ok(v) => v,
            Err(keys) => {
                let what = if distance {
                    "the time to travel `distance`"
                } else {
                    "its re-planning period"
                };
                self.missing_values.push((
                    e.doc,
                    e.loc,
                    format!(
                        "{ty} `{prefix}{base}`: no robot speed, which sets {what} (keys tried: \
                         {}); give the mean speed in m/s, e.g. `\"{}\": {{value: 0.3}}`",
                        keys.join(", "),
                        keys.last().map_or("", String::as_str)
                    ),
                ));
                return Ok(Some((1.0, 1.0)));
            }
        };
        let bad_speed = |b: &Self| {
            b.err(
                Kind::InvalidValue,
                e.loc,
                format!("<{ty}>: speed {speed} m/s from the params file is not valid"),
            )
            .with_help("the speed is the robot's mean speed in m/s, a number ≥ 0")
        };
        if !(speed.is_finite() && speed >= 0.0) {
            return Err(bad_speed(self));
        }
        if distance {
            let Some(d) = self.number_attr(e, ty, "distance", 1.0)? else {
                return Ok(None);
            };
            if d < 0.0 {
                return Err(self
                    .err(
                        Kind::InvalidValue,
                        e.loc,
                        format!("<{ty}> with distance = {d}"),
                    )
                    .with_help("distance is in metres, ≥ 0"));
            }
            if speed == 0.0 {
                return Err(bad_speed(self).with_help(
                    "a robot that does not move never travels `distance`: give a speed > 0",
                ));
            }
            let t = d / speed;
            if !t.is_finite() {
                return Err(bad_speed(self));
            }
            return Ok(Some((t, t)));
        }
        let get = |b: &mut Self, key: &str, default: f64| b.number_attr(e, ty, key, default);
        let (Some(min_rate), Some(max_rate), Some(min_speed), Some(max_speed)) = (
            get(self, "min_rate", 0.1)?,
            get(self, "max_rate", 1.0)?,
            get(self, "min_speed", 0.0)?,
            get(self, "max_speed", 0.5)?,
        ) else {
            return Ok(None);
        };
        if !(min_rate > 0.0 && max_rate >= min_rate && max_speed > min_speed) {
            return Err(self
                .err(
                    Kind::InvalidValue,
                    e.loc,
                    format!(
                        "<{ty}> with min_rate {min_rate}, max_rate {max_rate}, min_speed \
                         {min_speed}, max_speed {max_speed}"
                    ),
                )
                .with_help(
                    "Nav2 needs 0 < min_rate ≤ max_rate (Hz) and min_speed < max_speed (m/s)",
                ));
        }
        let scaled =
            (speed - min_speed) / (max_speed - min_speed) * (max_rate - min_rate) + min_rate;
        let rate = scaled.min(max_rate).max(min_rate);
        let (first, period) = (2.0 / (max_rate + min_rate), 1.0 / rate);
        if !(first.is_finite() && period.is_finite()) {
            return Err(self
                .err(
                    Kind::InvalidValue,
                    e.loc,
                    format!("<{ty}>: rates {min_rate}..{max_rate} Hz give no finite period"),
                )
                .with_help("give rates of at least 1e-300 Hz"));
        }
        // equal up to rounding (v at the middle of the speed range): one
        // period
        let first = if (first - period).abs() <= 1e-12 * period {
            period
        } else {
            first
        };
        Ok(Some((first, period)))
    }

    /// Nav2's `PathLongerOnApproach` (`path_longer_on_approach.cpp`): when
    /// ticked it checks whether the path was re-planned near the goal
    /// (`prox_len`) into one more than `length_factor` times longer; if so it
    /// runs its child and returns its status, else it returns Success at
    /// once. The check is a predicate `<node>/longer` (*Predicates*: `ps` =
    /// probability that it holds when the node starts): the flow longer →
    /// (S: child, F: Success). After the child returns the node stores the
    /// new path, so a re-tick finds no new path and returns Success, while
    /// the path keeps its value (the SBT assumption).
    #[allow(clippy::too_many_arguments)]
    pub(super) fn path_longer(
        &mut self,
        e: &'a Elem,
        ty: &str,
        parent: Option<usize>,
        depth: usize,
        path: &str,
        prefix: &str,
        retry: Option<&'static str>,
    ) -> Result<usize, TreeError> {
        self.one_child(e, ty)?;
        let base = self.name_attr(e)?.unwrap_or_else(|| ty.to_string());
        let id = self.guarded_child(
            e, ty, "longer", &base, true, parent, depth, path, prefix, retry,
        )?;
        self.once.push((id, e.doc, e.loc, "PathLongerOnApproach"));
        Ok(id)
    }

    /// BT.CPP v3's `ManualSelector` (`manual_node.cpp`): at each execution
    /// the user picks the child to run (its status is the node's); without
    /// children the user picks the status. Under the SBT assumptions the
    /// pick is a random choice made when the node starts and kept while the
    /// child runs: predicates `<node>/select_k` for k = 1 … N − 1, `ps` = the
    /// probability that the user picks child k given that no earlier child
    /// was picked (the last child gets the rest, as a Switch's default),
    /// one flow select_k → (S: child k, F: select_{k+1}); without children a
    /// condition keyed like a leaf (`ps` = probability that the user answers
    /// SUCCESS). `repeat_last_selection` true (the first pick is kept for all
    /// later executions) is refused; the user's S/F/R "skip" keys are not
    /// modelled (the user picks a child).
    #[allow(clippy::too_many_arguments)]
    pub(super) fn manual_selector(
        &mut self,
        e: &'a Elem,
        ty: &str,
        parent: Option<usize>,
        depth: usize,
        path: &str,
        prefix: &str,
        retry: Option<&'static str>,
    ) -> Result<usize, TreeError> {
        let base = self.name_attr(e)?.unwrap_or_else(|| ty.to_string());
        if let Some(a) = e.attr("repeat_last_selection") {
            match a.value.trim() {
                "0" | "false" | "False" | "FALSE" => {}
                v @ ("1" | "true" | "True" | "TRUE") => {
                    self.problem(
                        e.doc,
                        a.loc,
                        format!(
                            "<{ty}> with repeat_last_selection = \"{v}\": the first pick is kept \
                             for every later execution, one choice shared by all of them, which \
                             independent executions do not model"
                        ),
                        true,
                    );
                    return self.placeholder(e, &base, parent, depth, path, prefix, retry);
                }
                v if v.starts_with('{') => {
                    self.problem(
                        e.doc,
                        a.loc,
                        format!(
                            "<{ty}> with repeat_last_selection = \"{v}\", a blackboard \
                             reference: known only at run time"
                        ),
                        true,
                    );
                    return self.placeholder(e, &base, parent, depth, path, prefix, retry);
                }
                v => {
                    return Err(self
                        .err(
                            Kind::InvalidValue,
                            a.loc,
                            format!("repeat_last_selection = \"{v}\" is not a boolean"),
                        )
                        .with_help("write repeat_last_selection=\"false\" or \"true\""));
                }
            }
        }
        let n = e.children.len();
        if n == 0 {
            return self.leaf(e, ty, LeafKind::Condition, parent, depth, path, prefix);
        }
        let kind = NodeKind::Flow(Flow {
            children: Vec::new(),
            states: Vec::new(),
        });
        let id = self.push(e, &base, prefix, parent, depth, path, kind)?;
        let picks = n - 1;
        let mut ids = Vec::with_capacity(picks + n);
        for k in 1..=picks {
            let at = format!("{path}.{}", k - 1);
            let port = format!("select_{k}");
            ids.push(self.predicate_leaf(e, ty, &port, id, depth + 1, &at, prefix, false)?);
        }
        for (i, &c) in e.children.iter().enumerate() {
            let at = format!("{path}.{}", picks + i);
            ids.push(self.node(c, Some(id), depth + 1, at, prefix, retry)?);
        }
        let mut states = Vec::with_capacity(picks + n);
        for k in 0..picks {
            states.push(FlowState {
                child: k,
                on_success: FlowNext::State(picks + k),
                on_failure: FlowNext::State(if k + 1 < picks { k + 1 } else { 2 * picks }),
            });
        }
        for k in 0..n {
            states.push(FlowState {
                child: picks + k,
                on_success: FlowNext::Success,
                on_failure: FlowNext::Failure,
            });
        }
        self.nodes[id].kind =
            NodeKind::Flow(Flow::new(ids, states).expect("a ManualSelector's flow is valid"));
        Ok(id)
    }

    /// Nav2's `DistanceController` / `SpeedController` element `e`: a
    /// RateController ([`Builder::motion_period`]).
    #[allow(clippy::too_many_arguments)]
    pub(super) fn motion_controller(
        &mut self,
        e: &'a Elem,
        ty: &str,
        distance: bool,
        parent: Option<usize>,
        depth: usize,
        path: &str,
        prefix: &str,
        retry: Option<&'static str>,
    ) -> Result<usize, TreeError> {
        self.one_child(e, ty)?;
        let base = self.name_attr(e)?.unwrap_or_else(|| ty.to_string());
        let Some((first, period)) = self.motion_period(e, ty, distance, &base, prefix)? else {
            return self.placeholder(e, &base, parent, depth, path, prefix, retry);
        };
        let kind = NodeKind::Decorator {
            decorator: Decorator::Rate { period, first },
            child: 0,
        };
        let id = self.push(e, &base, prefix, parent, depth, path, kind)?;
        let ids = self.children(e, id, depth, path, prefix, retry)?;
        self.set_children(id, ids);
        Ok(id)
    }
}
