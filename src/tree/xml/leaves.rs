//! Step 4 of the pipeline: each leaf's parameters from the params file (by
//! its unique name, `name` attribute, then ID), every missing one listed
//! at once with the blackboard values the params file lacks, then params
//! keys that nothing reads.

use super::*;

/// Gives every leaf its kind and parameters; returns the params key of each
/// leaf node. `no_meaning_after` (nodes without a stochastic meaning) is
/// appended to the missing-parameters error.
pub(super) fn resolve_leaves(
    b: &mut Builder,
    table: &ParamsTable,
    params: &str,
    params_file: &str,
    no_meaning_after: Option<String>,
) -> Result<Vec<(usize, String)>, TreeError> {
    let sources = b.sources;
    // parameters
    let perr_as = |kind: Kind, at: Loc, msg: String, help: String| {
        TreeError::at(kind, params_file, params, at, msg).with_help(help)
    };
    let perr = |at: Loc, msg: String, help: String| perr_as(Kind::InvalidValue, at, msg, help);
    let mut used_keys: HashSet<&str> = HashSet::new();
    let mut param_keys: Vec<(usize, String)> = Vec::new();
    // (document, location, line, what copies of one element share: its keys)
    let mut missing: Vec<(usize, Loc, String, Option<String>)> = Vec::new();
    let leaves = std::mem::take(&mut b.leaves);
    for leaf in &leaves {
        let shared = Some(format!(
            "{}\0{}",
            leaf.id,
            leaf.name_attr.as_deref().unwrap_or("")
        ));
        let node = &b.nodes[leaf.node];
        let at = node.location.unwrap_or((0, 0));
        let mut keys = vec![node.name.as_str()];
        for k in leaf.name_attr.iter().chain(std::iter::once(&leaf.id)) {
            if !keys.contains(&k.as_str()) {
                keys.push(k);
            }
        }
        let found = keys.iter().find_map(|k| table.leaves.get_key_value(*k));
        let is_action = match (leaf.kind, found) {
            (LeafKind::Action, _) => true,
            (LeafKind::Condition, _) => false,
            (LeafKind::ZeroTime, None) => {
                b.nodes[leaf.node].kind = NodeKind::Condition { ps: 1.0 };
                continue;
            }
            (LeafKind::Inferred | LeafKind::ZeroTime, Some((_, def))) => has_timing(&def.value),
            (LeafKind::Inferred, None) => {
                let typo = match nearest(&leaf.id, BUILTINS) {
                    Some(k) if k != leaf.id => format!(" (or did you mean <{k}>?)"),
                    _ => String::new(),
                };
                missing.push((
                    leaf.doc,
                    at,
                    format!(
                        "leaf `{}` (ID `{}`): no entry (keys tried: {}); give `{{ps: ...}}` for a \
                         condition or `{{ps: ..., mu: ..., nu: ...}}` for an action{typo}",
                        node.name,
                        leaf.id,
                        keys.join(", ")
                    ),
                    shared,
                ));
                continue;
            }
        };
        let kind = if is_action { "action" } else { "condition" };
        let who = format!("{kind} `{}` (ID `{}`)", node.name, leaf.id);
        let Some((key, def)) = found else {
            missing.push((
                leaf.doc,
                at,
                format!("{who}: no entry (keys tried: {})", keys.join(", ")),
                shared,
            ));
            continue;
        };
        used_keys.insert(key.as_str());
        param_keys.push((leaf.node, key.clone()));
        let p = &def.value;
        let new_kind = if is_action {
            match validate_action(p, &perr)? {
                Ok(a) => NodeKind::Action(a),
                Err(m) => {
                    missing.push((leaf.doc, at, format!("{who} (key `{key}`): {m}"), shared));
                    continue;
                }
            }
        } else {
            if let Some(extra) = [&p.pf, &p.mu, &p.nu, &p.tau_s, &p.tau_f]
                .into_iter()
                .flatten()
                .map(sloc)
                .chain(p.time_law_at())
                .next()
            {
                return Err(perr_as(
                    Kind::Structure,
                    extra,
                    format!("`{key}` is used by {who}, and a condition takes only `ps`"),
                    "a condition returns in zero time; give only its probability of success `ps`"
                        .into(),
                ));
            }
            let Some(ps) = &p.ps else {
                missing.push((
                    leaf.doc,
                    at,
                    format!("{who} (key `{key}`): missing `ps` (probability of success in [0, 1])"),
                    shared,
                ));
                continue;
            };
            if !ps.value.is_finite() || !(0.0..=1.0).contains(&ps.value) {
                return Err(perr_as(
                    Kind::InvalidValue,
                    sloc(ps),
                    format!("ps = {} is not a probability", ps.value),
                    "ps must be a number in [0, 1]".into(),
                ));
            }
            NodeKind::Condition { ps: ps.value }
        };
        b.nodes[leaf.node].kind = new_kind;
    }
    let values_missing = !b.missing_values.is_empty();
    missing.extend(
        b.missing_values
            .drain(..)
            .map(|(d, at, m)| (d, at, m, None)),
    );
    if let Some(&(doc, first, ..)) = missing.first() {
        // copies of one element (a RecoveryNode's retries, a SubTree used
        // twice) share its keys: one line each, with the number of copies
        let mut lines: Vec<String> = Vec::new();
        let mut seen: HashMap<(usize, Loc, &str), (usize, usize)> = HashMap::new();
        for (d, at, m, shared) in &missing {
            let (l, c) = at;
            let line = format!("  {}:{l}:{c}: {m}", sources[*d].name);
            let Some(shared) = shared else {
                lines.push(line);
                continue;
            };
            match seen.get_mut(&(*d, *at, shared.as_str())) {
                Some((_, copies)) => *copies += 1,
                None => {
                    seen.insert((*d, *at, shared), (lines.len(), 1));
                    lines.push(line);
                }
            }
        }
        for &(line, copies) in seen.values() {
            if copies > 1 {
                lines[line].push_str(&format!(
                    " [{copies} copies of this element (retries, SubTrees): one entry keyed by \
                     its name or ID covers them all]"
                ));
            }
        }
        let n = lines.len();
        return Err(b
            .err_in(
                Kind::MissingParameter,
                doc,
                first,
                format!(
                    "missing parameters for {n} node{} in {params_file}:\n{}{}",
                    if n == 1 { "" } else { "s" },
                    lines.join("\n"),
                    no_meaning_after.unwrap_or_default()
                ),
            )
            .with_help(format!(
                "add an entry per node to {params_file}, keyed by name or ID, e.g. \
                 `grasp: {{ps: 0.5, mu: 0.1, nu: 0.2}}` (actions) or `ready: {{ps: 0.9}}` \
                 (conditions){}",
                if values_missing {
                    ", and one per blackboard value, keyed by the reference as written, e.g. \
                     `\"{waypoints}\": {value: 5}`"
                } else {
                    ""
                }
            )));
    }
    let blackboard_used = b.blackboard_used.take();
    if let Some((key, def)) = table
        .blackboard
        .iter()
        .filter(|(k, _)| !blackboard_used.contains(k.as_str()))
        .min_by_key(|(_, d)| sloc(d))
    {
        return Err(perr_as(
            Kind::InvalidValue,
            sloc(def),
            format!(
                "params key `{key}` matches no blackboard reference or port value that btrel reads"
            ),
            "blackboard values (keys written `{name}`) are read where a count, a duration or a \
             queue (num_cycles, num_attempts, number_of_retries, msec, delay_msec, queue, \
             vector_in, ...) is written as that reference; port values (keys written \
             `<node>/<port>`) are read by DistanceController and SpeedController (`speed`); \
             remove the entry or check its spelling"
                .into(),
        ));
    }
    if let Some((key, def)) = table
        .leaves
        .iter()
        .filter(|(k, _)| !used_keys.contains(k.as_str()))
        .min_by_key(|(_, d)| sloc(d))
    {
        let names: Vec<&str> = leaves
            .iter()
            .flat_map(|l| {
                [b.nodes[l.node].name.as_str(), l.id.as_str()]
                    .into_iter()
                    .chain(l.name_attr.as_deref())
            })
            .collect();
        let hint = match nearest(key, &names) {
            Some(k) => format!("did you mean `{k}`? keys are leaf names or IDs"),
            None => "keys are the names or IDs of the tree's actions and conditions; remove unused entries".into(),
        };
        return Err(perr_as(
            Kind::InvalidValue,
            sloc(def),
            format!("params key `{key}` matches no action or condition"),
            hint,
        ));
    }
    Ok(param_keys)
}
