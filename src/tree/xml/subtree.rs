//! Lowering, continued: Parallel versions and thresholds, Nav2's
//! RecoveryNode, SubTree expansion and sizes, leaves and loop counts.

use super::*;

impl<'a> Builder<'a> {
    /// The format that decides a Parallel's attributes: the file's, or for
    /// a file without `BTCPP_format`, v3 if the node uses v3 names.
    pub(super) fn parallel_version(&self, e: &Elem) -> Format {
        match self.sources[e.doc].format {
            Format::Unspecified
                if e.attr("success_threshold").is_some()
                    || e.attr("failure_threshold").is_some() =>
            {
                Format::V3
            }
            Format::Unspecified => Format::V4,
            f => f,
        }
    }

    /// Nav2's RecoveryNode(main, recovery, n): tick main; Success is
    /// Success; on Failure, if fewer than n retries were used, tick
    /// recovery: Failure is Failure, Success ticks main again. Built as
    /// Fallback(main, Sequence(recovery, RecoveryNode(main, recovery,
    /// n − 1))) with RecoveryNode(main, recovery, 0) = main, each copy
    /// fresh.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn recovery(
        &mut self,
        e: &'a Elem,
        ty: &str,
        parent: Option<usize>,
        depth: usize,
        path: String,
        prefix: &str,
        retry: Option<&'static str>,
    ) -> Result<usize, TreeError> {
        if e.children.len() != 2 {
            return Err(self
                .err(
                    Kind::Structure,
                    e.loc,
                    format!(
                        "<{ty}> needs exactly two children (the main branch and the recovery), found {}",
                        e.children.len()
                    ),
                )
                .with_help("Nav2's RecoveryNode throws at run time for any other number of children"));
        }
        if let Some(a) = e
            .attr("number_of_retries")
            .filter(|a| self.unresolved(&a.value))
        {
            let at = a.loc;
            self.missing_value(e, at, ty, "number_of_retries", "give the count", "N");
            let base = self.name_attr(e)?.unwrap_or_else(|| ty.to_string());
            return self.placeholder(e, &base, parent, depth, &path, prefix, retry);
        }
        let n = match self.int_attr(e, "number_of_retries")? {
            None => 1,
            Some((n, at)) => {
                if !(0..=MAX_RECOVERY_RETRIES as i64).contains(&n) {
                    return Err(self
                        .err(Kind::InvalidValue, at, format!("number_of_retries = {n} is not a valid count"))
                        .with_help(format!(
                            "number_of_retries must be a whole number from 0 to {MAX_RECOVERY_RETRIES}"
                        )));
                }
                n as usize
            }
        };
        let base = self.name_attr(e)?.unwrap_or_else(|| ty.to_string());
        let (main, rec) = (e.children[0], e.children[1]);
        // the main branch is ticked again after its failure
        let main_retry = if n > 0 { Some("RecoveryNode") } else { retry };
        // (fallback, main copy, sequence, recovery copy) per retry
        let mut levels: Vec<(usize, usize, usize, usize)> = Vec::with_capacity(n);
        let (mut up, mut d, mut p) = (parent, depth, path);
        for k in 1..=n {
            let fb_name = if k == 1 {
                base.clone()
            } else {
                format!("{base}/attempt {k}")
            };
            let main_prefix = if k == 1 {
                prefix.to_string()
            } else {
                format!("{prefix}{base}/attempt {k}/")
            };
            let fb = self.push(
                e,
                &fb_name,
                prefix,
                up,
                d,
                &p,
                NodeKind::Fallback {
                    children: Vec::new(),
                },
            )?;
            let m = self.node(
                main,
                Some(fb),
                d + 1,
                format!("{p}.0"),
                &main_prefix,
                main_retry,
            )?;
            let sq = self.push(
                e,
                &format!("{base}/recovery {k}"),
                prefix,
                Some(fb),
                d + 1,
                &format!("{p}.1"),
                NodeKind::Sequence {
                    children: Vec::new(),
                },
            )?;
            let r = self.node(
                rec,
                Some(sq),
                d + 2,
                format!("{p}.1.0"),
                &format!("{prefix}{base}/recovery {k}/"),
                retry,
            )?;
            levels.push((fb, m, sq, r));
            (up, d, p) = (Some(sq), d + 2, format!("{p}.1.1"));
        }
        let last_prefix = if n == 0 {
            prefix.to_string()
        } else {
            format!("{prefix}{base}/attempt {}/", n + 1)
        };
        let mut next = self.node(main, up, d, p, &last_prefix, main_retry)?;
        for (fb, m, sq, r) in levels.into_iter().rev() {
            self.set_children(sq, vec![r, next]);
            self.set_children(fb, vec![m, sq]);
            next = fb;
        }
        Ok(next)
    }

    /// Number of nodes of tree `id` after SubTree expansion (saturating),
    /// computed without expanding. Cycles and over-deep SubTree chains
    /// count as 0 here: the builder reports them.
    pub(super) fn tree_size(&mut self, id: &'a str, guard: usize) -> u64 {
        if let Some(&s) = self.sizes.get(id) {
            return s;
        }
        let Some(&tree) = self.trees.get(id).and_then(|v| v.first()) else {
            return 1;
        };
        if guard > MAX_DEPTH || !self.sizing.insert(id) {
            return 0;
        }
        let total = match self.elems[tree].children.first() {
            Some(&root) => self.elem_size(root, guard),
            None => 0,
        };
        self.sizing.remove(id);
        self.sizes.insert(id, total);
        total
    }

    pub(super) fn elem_size(&mut self, ei: usize, guard: usize) -> u64 {
        let e = self.elem(ei);
        if matches!(e.name.as_str(), "SubTree" | "SubTreePlus") {
            return match e.attr("ID") {
                Some(a) => self.tree_size(&a.value, guard + 1),
                None => 1,
            };
        }
        let recovery = e.name == "RecoveryNode"
            || (e.name == "Control" && e.attr("ID").is_some_and(|a| a.value == "RecoveryNode"));
        if recovery && e.children.len() == 2 {
            let n = e
                .attr("number_of_retries")
                .and_then(|a| a.value.trim().parse::<u64>().ok())
                .unwrap_or(1)
                .min(MAX_RECOVERY_RETRIES);
            let m = self.elem_size(e.children[0], guard);
            let r = self.elem_size(e.children[1], guard);
            return (2 * n)
                .saturating_add((n + 1).saturating_mul(m))
                .saturating_add(n.saturating_mul(r));
        }
        let mut total = 1u64;
        for &c in &e.children {
            total = total.saturating_add(self.elem_size(c, guard));
        }
        total
    }

    /// A decorator's child count must be one.
    pub(super) fn one_child(&self, e: &Elem, ty: &str) -> Result<(), TreeError> {
        if e.children.len() != 1 {
            return Err(self
                .err(
                    Kind::Structure,
                    e.loc,
                    format!("<{ty}> needs exactly one child, found {}", e.children.len()),
                )
                .with_help("a decorator wraps exactly one node; wrap several in a <Sequence>"));
        }
        Ok(())
    }

    pub(super) fn no_children(&self, e: &Elem) -> Result<(), TreeError> {
        if let Some(&c) = e.children.first() {
            return Err(self
                .err(
                    Kind::Structure,
                    self.elem(c).loc,
                    format!("<{}> is a leaf and takes no children", e.name),
                )
                .with_help("remove the child elements"));
        }
        Ok(())
    }

    #[allow(clippy::too_many_arguments)]
    pub(super) fn leaf(
        &mut self,
        e: &Elem,
        id: &str,
        kind: LeafKind,
        parent: Option<usize>,
        depth: usize,
        path: &str,
        prefix: &str,
    ) -> Result<usize, TreeError> {
        self.no_children(e)?;
        let name_attr = self.name_attr(e)?;
        let base = name_attr.clone().unwrap_or_else(|| id.to_string());
        // placeholder parameters, filled in from the params file
        let node = self.push(
            e,
            &base,
            prefix,
            parent,
            depth,
            path,
            NodeKind::Condition { ps: 0.0 },
        )?;
        self.leaves.push(Leaf {
            node,
            kind,
            id: id.to_string(),
            name_attr,
            doc: e.doc,
        });
        Ok(node)
    }

    /// The BehaviorTree with this ID: the main file's definition, else the
    /// only included one.
    pub(super) fn lookup_tree(&self, id: &str, at: Loc) -> Result<Option<usize>, TreeError> {
        let Some(defs) = self.trees.get(id) else {
            return Ok(None);
        };
        if defs.len() > 1 && self.elem(defs[0]).doc != 0 {
            let places: Vec<String> = defs
                .iter()
                .map(|&d| {
                    let el = self.elem(d);
                    format!("{}:{}:{}", self.sources[el.doc].name, el.loc.0, el.loc.1)
                })
                .collect();
            return Err(self
                .err(
                    Kind::Structure,
                    at,
                    format!("BehaviorTree `{id}` is defined in several included files"),
                )
                .with_help(format!(
                    "defined at {}; include only one of them",
                    places.join(", ")
                )));
        }
        Ok(defs.first().copied())
    }

    pub(super) fn subtree(
        &mut self,
        e: &'a Elem,
        parent: Option<usize>,
        depth: usize,
        path: String,
        prefix: &str,
        retry: Option<&'static str>,
    ) -> Result<usize, TreeError> {
        self.check_attrs(e, &["name", "ID"], true)?;
        self.no_children(e)?;
        let id = self.id_attr(e)?;
        let name_attr = self.name_attr(e)?;
        let instance = name_attr.clone().unwrap_or_else(|| id.to_string());
        let Some(tree) = self.lookup_tree(id, e.loc)? else {
            // a SubTree defined nowhere but given a params entry is one leaf
            let full = format!("{prefix}{instance}");
            let has_entry = [Some(full.as_str()), name_attr.as_deref(), Some(id)]
                .into_iter()
                .flatten()
                .any(|k| self.table.leaves.contains_key(k));
            if has_entry {
                return self.leaf(e, id, LeafKind::Inferred, parent, depth, &path, prefix);
            }
            let ids: Vec<&str> = self.trees.keys().copied().collect();
            let mut sorted = ids.clone();
            sorted.sort_unstable();
            let hint = match nearest(id, &ids) {
                Some(k) => format!("did you mean `{k}`? "),
                None => String::new(),
            };
            let trees = if sorted.is_empty() {
                "none".to_string()
            } else {
                sorted.join(", ")
            };
            self.problem(
                e.doc,
                e.loc,
                format!(
                    "no <BehaviorTree ID=\"{id}\"> for this SubTree ({hint}trees read: {trees}); \
                     include the file that defines it, or give `{id}` a params entry to treat \
                     the SubTree as one leaf"
                ),
                false,
            );
            return self.push(
                e,
                &instance,
                prefix,
                parent,
                depth,
                &path,
                NodeKind::Condition { ps: 1.0 },
            );
        };
        if let Some(pos) = self.expanding.iter().position(|(t, _)| *t == id) {
            let cycle: Vec<&str> = self.expanding[pos..]
                .iter()
                .map(|(t, _)| *t)
                .chain(std::iter::once(id))
                .collect();
            return Err(self
                .err(
                    Kind::Structure,
                    e.loc,
                    format!("recursive SubTree: {}", cycle.join(" -> ")),
                )
                .with_help("a tree cannot contain itself; break the cycle"));
        }
        if self.expanding.len() > MAX_DEPTH {
            return Err(self
                .err(Kind::Budget, e.loc, "SubTrees are nested too deeply")
                .with_help(format!("btrel expands at most {MAX_DEPTH} nested SubTrees")));
        }
        let inner = format!("{prefix}{instance}/");
        self.expanding.push((id, e.loc));
        let root = self.elem(tree).children[0];
        let r = self.node(root, parent, depth, path, &inner, retry);
        self.expanding.pop();
        r
    }

    /// `num_attempts` / `num_cycles`: required, 1..=1e6. A count from the
    /// blackboard or −1 (forever) is recorded as a problem (`None`).
    /// Whether the count attribute `key` is -1 (BT.CPP: repeat without a
    /// bound, read as `until_success` / `until_failure`).
    pub(super) fn forever(&self, e: &Elem, key: &str) -> bool {
        e.attr(key).is_some_and(|a| a.value.trim() == "-1")
    }

    pub(super) fn count(&mut self, e: &Elem, key: &str) -> Result<Option<usize>, TreeError> {
        if let Some(a) = e.attr(key).filter(|a| self.unresolved(&a.value)) {
            let (at, ty) = (a.loc, e.name.clone());
            self.missing_value(e, at, &ty, key, "give the count", "N");
            return Ok(None);
        }
        if let Some((-1, at)) = self.int_attr(e, key)? {
            self.problem(
                e.doc,
                at,
                format!(
                    "<{}> with {key} = -1 (forever): an endless loop has no finite MTTS/MTTF",
                    e.name
                ),
                true,
            );
            return Ok(None);
        }
        let Some((n, at)) = self.int_attr(e, key)? else {
            return Err(self
                .err(
                    Kind::Structure,
                    e.loc,
                    format!("<{}> needs `{key}`", e.name),
                )
                .with_help(format!(
                    "write {key}=\"N\" with N a whole number from 1 to 1000000"
                )));
        };
        if !(1..=1_000_000).contains(&n) {
            return Err(self
                .err(
                    Kind::InvalidValue,
                    at,
                    format!("{key} = {n} is not a valid count"),
                )
                .with_help(format!("{key} must be a whole number from 1 to 1000000")));
        }
        Ok(Some(n as usize))
    }

    /// Parallel thresholds. v4: `success_count` (default −1),
    /// `failure_count` (default 1); v3: `success_threshold` (required),
    /// `failure_threshold` (default 1). A negative count k means N + k + 1.
    pub(super) fn thresholds(
        &self,
        e: &Elem,
        n: usize,
        version: Format,
    ) -> Result<(usize, usize), TreeError> {
        let resolve = |key: &str,
                       default: Option<i64>,
                       meaning: &str|
         -> Result<usize, TreeError> {
            let (k, at) = match (self.int_attr(e, key)?, default) {
                (Some(v), _) => v,
                (None, Some(d)) => (d, e.loc),
                (None, None) => {
                    return Err(self
                        .err(Kind::Structure, e.loc, format!("<{}> needs `{key}` (BT.CPP v3)", e.name))
                        .with_help(format!(
                            "BT.CPP v3 has no default for {key}; write {key}=\"M\" (M from 1 to {n}, or -1 for all children)"
                        )))
                }
            };
            let v = if k < 0 { n as i64 + k + 1 } else { k };
            if v < 1 || v > n as i64 {
                return Err(self
                    .err(Kind::InvalidValue, at, format!("{key} = {k} is not valid for {n} children"))
                    .with_help(format!(
                        "{key} must be from 1 to {n}, or negative (-1 = all children, -2 = all but one, ...): {meaning}"
                    )));
            }
            Ok(v as usize)
        };
        if version == Format::V3 {
            let m = resolve("success_threshold", None, "Success at >= M successes")?;
            let f = resolve("failure_threshold", Some(1), "Failure at >= F failures")?;
            return Ok((m, f));
        }
        let m = resolve("success_count", Some(-1), "Success at >= M successes")?;
        let f = resolve("failure_count", Some(1), "Failure at >= F failures")?;
        Ok((m, f))
    }
}
