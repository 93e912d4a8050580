//! The YAML params file: leaf entries by name or ID, and blackboard or port
//! values (`"{name}": {value: N}`, `"<node>/<port>": {value: x}`).

use super::*;

/// A params file entry: an action's keys, plus an optional `fit:` mapping
/// (written by `btrel fit`: counts, standard errors, intervals) that the
/// analysis ignores.
#[derive(serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct ParamsEntry {
    #[serde(default)]
    pub(super) ps: Option<At<f64>>,
    #[serde(default)]
    pub(super) pf: Option<At<f64>>,
    #[serde(default)]
    pub(super) mu: Option<At<f64>>,
    #[serde(default)]
    pub(super) nu: Option<At<f64>>,
    #[serde(default)]
    pub(super) tau_s: Option<At<f64>>,
    #[serde(default)]
    pub(super) tau_f: Option<At<f64>>,
    #[serde(default)]
    pub(super) success_time: Option<At<TimeDef>>,
    #[serde(default)]
    pub(super) failure_time: Option<At<TimeDef>>,
    #[serde(default)]
    #[allow(dead_code)]
    pub(super) fit: Option<serde::de::IgnoredAny>,
    /// The value of a blackboard entry (keys written `"{name}"`).
    #[serde(default)]
    pub(super) value: Option<At<f64>>,
}

/// The params file: leaf entries by name or ID, and blackboard values by
/// their reference as written in the XML (`{num_samples}`).
pub(super) struct ParamsTable {
    pub(super) leaves: BTreeMap<String, At<ActionParams>>,
    pub(super) blackboard: BTreeMap<String, At<f64>>,
}

/// Whether a params key names a blackboard entry (`{name}`).
pub(super) fn is_blackboard_key(key: &str) -> bool {
    key.len() > 2 && key.starts_with('{') && key.ends_with('}')
}

pub(super) fn parse_params(src: &str, file: &str) -> Result<ParamsTable, TreeError> {
    let entries: BTreeMap<String, At<ParamsEntry>> = parse_params_entries(src, file)?;
    let mut table = ParamsTable {
        leaves: BTreeMap::new(),
        blackboard: BTreeMap::new(),
    };
    for (k, e) in entries {
        let p = e.value;
        let at = |line: u32, column: u32| (line as usize, column as usize);
        // `"<node>/<port>": {value: x}`: a number a node reads for a port
        // whose value comes from the robot (a DistanceController's speed)
        let port_value = k.contains('/') && p.value.is_some();
        if is_blackboard_key(&k) || port_value {
            let leaf_key = [&p.ps, &p.pf, &p.mu, &p.nu, &p.tau_s, &p.tau_f]
                .into_iter()
                .flatten()
                .map(|x| (x.line, x.column))
                .chain(
                    [&p.success_time, &p.failure_time]
                        .into_iter()
                        .flatten()
                        .map(|x| (x.line, x.column)),
                )
                .next();
            let Some(v) = p.value else {
                return Err(TreeError::at(
                    Kind::Structure,
                    file,
                    src,
                    at(e.line, e.column),
                    format!("blackboard entry `{k}` needs a `value`"),
                )
                .with_help(format!(
                    "a key written `{{name}}` gives the value a port `{{name}}` reads, e.g. \
                     `\"{k}\": {{value: 3}}`"
                )));
            };
            if leaf_key.is_some() || p.fit.is_some() {
                let (line, column) = leaf_key.unwrap_or((e.line, e.column));
                let what = if port_value {
                    "port value"
                } else {
                    "blackboard entry"
                };
                return Err(TreeError::at(
                    Kind::Structure,
                    file,
                    src,
                    at(line, column),
                    format!("{what} `{k}` takes only `value`"),
                )
                .with_help("leaf parameters (ps, mu, ...) belong under the leaf's name or ID"));
            }
            // errors about the entry point at its key
            let v = At {
                value: v.value,
                line: e.line,
                column: e.column,
            };
            table.blackboard.insert(k, v);
            continue;
        }
        if let Some(v) = p.value {
            return Err(TreeError::at(
                Kind::Structure,
                file,
                src,
                at(v.line, v.column),
                format!(
                    "`value` in the entry of `{k}`, which is not a blackboard reference or a \
                     node's port"
                ),
            )
            .with_help(format!(
                "`value` gives a blackboard entry, keyed as the XML writes it: `\"{{{k}}}\": \
                 {{value: ...}}`, or a node's port, keyed `\"<node>/<port>\"` (e.g. \
                 `\"DistanceController/speed\": {{value: 0.3}}`); a leaf takes ps, pf, mu, nu, \
                 tau_s, tau_f"
            )));
        }
        let params = ActionParams {
            ps: p.ps,
            pf: p.pf,
            mu: p.mu,
            nu: p.nu,
            tau_s: p.tau_s,
            tau_f: p.tau_f,
            success_time: p.success_time,
            failure_time: p.failure_time,
        };
        table.leaves.insert(
            k,
            At {
                value: params,
                line: e.line,
                column: e.column,
            },
        );
    }
    Ok(table)
}

pub(super) fn parse_params_entries(
    src: &str,
    file: &str,
) -> Result<BTreeMap<String, At<ParamsEntry>>, TreeError> {
    let only_comments = src
        .lines()
        .all(|l| l.trim().is_empty() || l.trim_start().starts_with('#'));
    if only_comments {
        return Ok(BTreeMap::new());
    }
    let options = serde_saphyr::options! {
        budget: serde_saphyr::budget! {
            max_depth: 16,
            max_nodes: 50_000_000,
            max_events: 200_000_000,
            max_total_scalar_bytes: MAX_BYTES,
            flow_nesting_limit: 16,
        },
        alias_limits: serde_saphyr::alias_limits! {
            max_total_replayed_events: 200_000_000,
        },
        with_snippet: false,
    };
    serde_saphyr::from_str_with_options(src, options).map_err(|e| {
        let at = e
            .location()
            .map_or((0, 0), |l| (l.line() as usize, l.column() as usize));
        let text = e.without_snippet().to_string();
        let text = match text.rfind(" at line ") {
            Some(i) => text[..i].to_string(),
            None => text,
        };
        TreeError::at(Kind::Syntax, file, src, at, format!("invalid params file: {text}")).with_help(
            "the params file maps a node's name or ID to its parameters, e.g. \
             `grasp: {ps: 0.5, mu: 0.1, nu: 0.2}`; accepted keys: ps, pf, mu, nu, tau_s, tau_f, \
             success_time, failure_time (and `fit`, the statistics `btrel fit` writes, which the analysis ignores)",
        )
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn refused(src: &str) -> TreeError {
        match parse_params(src, "p.yaml") {
            Ok(_) => panic!("{src}: accepted"),
            Err(e) => e,
        }
    }

    #[test]
    fn leaves_and_blackboard_values() {
        let t = parse_params(
            "grasp: {ps: 0.5, mu: 0.1, nu: 0.2}\n\"{n}\": {value: 3}\n\"Dist/speed\": {value: 0.3}\n",
            "p.yaml",
        )
        .unwrap();
        assert_eq!(t.leaves.keys().collect::<Vec<_>>(), ["grasp"]);
        let g = &t.leaves["grasp"];
        // a leaf entry is located at its value: `grasp: ` is 7 characters
        assert_eq!((g.line, g.column), (1, 8));
        assert_eq!(g.value.ps.as_ref().map(|p| p.value), Some(0.5));
        assert_eq!(g.value.nu.as_ref().map(|p| p.value), Some(0.2));
        assert!(g.value.pf.is_none());
        // a value is located at its entry too (`"{n}": ` is 7 characters),
        // not at the number
        let n = &t.blackboard["{n}"];
        assert_eq!((n.value, n.line, n.column), (3.0, 2, 8));
        assert_eq!(t.blackboard["Dist/speed"].value, 0.3);
    }

    #[test]
    fn empty_and_comment_only_files() {
        for src in ["", "\n", "# nothing yet\n  # indented\n"] {
            let t = parse_params(src, "p.yaml").unwrap();
            assert!(t.leaves.is_empty() && t.blackboard.is_empty(), "{src:?}");
        }
    }

    #[test]
    fn misplaced_keys() {
        let e = refused("\"{n}\": {ps: 1, value: 2}\n");
        assert_eq!((e.kind, e.line), (Kind::Structure, 1));
        assert_eq!(e.message, "blackboard entry `{n}` takes only `value`");
        let e = refused("\"{n}\": {ps: 1}\n");
        assert_eq!(e.message, "blackboard entry `{n}` needs a `value`");
        let e = refused("grasp: {value: 2}\n");
        assert_eq!(e.kind, Kind::Structure);
        assert!(
            e.message.starts_with("`value` in the entry of `grasp`"),
            "{e}"
        );
        let e = refused("grasp: {ps: 0.5, bogus: 1}\n");
        assert_eq!((e.kind, e.line), (Kind::Syntax, 1));
        assert!(e.message.starts_with("invalid params file: "), "{e}");
    }

    #[test]
    fn blackboard_keys() {
        assert!(is_blackboard_key("{a}"));
        assert!(!is_blackboard_key("{}"));
        assert!(!is_blackboard_key("a"));
        assert!(!is_blackboard_key("{a"));
    }
}
