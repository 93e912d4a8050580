#!/usr/bin/env python3
"""A BehaviorTree.CPP referee for btrel: runs a BT.CPP XML tree in real
BehaviorTree.CPP v4 (the `behaviortreepy` wheel) with leaves that draw their
outcome and duration from a btrel params file, and prints the observed
figures as JSON.

    referee.py TREE.xml PARAMS [--runs N] [--seed S] [--scale SECONDS] [--sleep-ms MS]
    referee.py --jobs JOBS.json          # several trees in one process

PARAMS is btrel's params file: per leaf (its `name` attribute, else its ID)
`ps` alone for a condition, or `ps` with `mu`/`nu` (rates) or `tau_s`/`tau_f`
(times), as btrel reads them. It is read as JSON (a JSON object is valid YAML,
so the same file is btrel's params file); YAML proper needs PyYAML.

Time scale: one unit of the params' time is `--scale` seconds of wall clock
(default 0.01: a rate mu = 1 means a mean of 10 ms), so that a run takes tens
of milliseconds. Reported times are in the params' units (wall time / scale).

Leaves (registered under every leaf ID of the tree):
* an action draws its outcome (Success with probability ps) and its duration
  at onStart (Def. 9.7-9.9: Exp(mu) / Exp(nu), tau_s / tau_f, the hybrids
  truncated at the deterministic time), returns RUNNING until that much wall
  clock time has passed since onStart, then the outcome; a zero duration
  returns the outcome from onStart.
* a condition returns Success with probability ps. The SBT assumption is that
  a condition keeps its value during an execution of its parent; BT.CPP's
  ReactiveSequence/ReactiveFallback re-tick their conditions on every tick.
  A condition therefore draws a fresh value on every tick, except when it is
  re-ticked by its nearest Reactive ancestor while an action below that
  ancestor is still running (counted by the actions' onStart/return/halt) and
  nothing below that ancestor has been idle since the draw: then it keeps the
  value it drew. Retry/Repeat re-executions draw fresh values.

With "fresh_tree" (--jobs) the tree is created afresh for every run (btrel
models one execution of a fresh tree; SequenceWithMemory keeps its index
after a failure, also into the next execution of the same tree instance).

The tree is ticked by Tree.tick_while_running(sleep_ms): BT.CPP ticks,
sleeps sleep_ms, ticks again. An action that finishes between two ticks is
noticed at the next tick, so each sequential action step is observed late by
up to one tick period. The referee measures that period (the gaps between
successive onRunning calls of one action) and reports its mean and maximum.

Output (one JSON object per tree; a list with --jobs): runs, successes,
failures, ps with its binomial standard error, mtts/mttf (means of the
Success/Failure runs' wall times, in params units) with standard errors,
tick_ms_mean/tick_ms_max, scale, wall_s.
"""

import argparse
import json
import math
import random
import sys
import time
import xml.etree.ElementTree as ET

import behaviortreepy as bt

S = bt.NodeStatus

# BT.CPP's built-in node types (v4 names and the v3 ones btrel reads): not leaves
# to register.
BUILTIN = {
    "root", "BehaviorTree", "TreeNodesModel", "include", "SubTree", "SubTreePlus",
    "Sequence", "Fallback", "ReactiveSequence", "ReactiveFallback",
    "SequenceWithMemory", "SequenceStar", "Parallel", "ParallelAll",
    "Inverter", "ForceSuccess", "ForceFailure", "RetryUntilSuccessful",
    "RetryUntilSuccesful", "Repeat", "AlwaysSuccess", "AlwaysFailure",
    "Script", "SetBlackboard", "UnsetBlackboard", "Control", "Decorator",
    "IfThenElse", "WhileDoElse",
}
# nodes that tick their (condition) children again while a later child runs
REACTIVE = {"ReactiveSequence", "ReactiveFallback", "WhileDoElse"}


def fail(msg):
    print(f"referee: {msg}", file=sys.stderr)
    sys.exit(2)


def read_params(path):
    with open(path, encoding="utf-8") as f:
        text = f.read()
    try:
        return json.loads(text)
    except json.JSONDecodeError:
        pass
    try:
        import yaml  # noqa: PLC0415
    except ImportError:
        fail(f"{path}: not JSON, and PyYAML is not installed to read it as YAML")
    return yaml.safe_load(text)


class Referee:
    def __init__(self, xml_text, params, scale, rng):
        self.scale = scale
        self.rng = rng
        self.leaves = {}  # tag -> dict(kind, params, reactive (nearest), reactives (all))
        self.reset()
        root = ET.fromstring(xml_text)
        ids = set()
        counter = [0]

        def walk(el, reactives, where):
            tag = el.tag
            if tag in ("Action", "Condition"):
                leaf_id = el.get("ID")
                form = tag
            elif tag in BUILTIN:
                leaf_id, form = None, None
            else:
                leaf_id, form = tag, None
            if leaf_id is not None:
                key = el.get("name") if el.get("name") in params else leaf_id
                if key not in params:
                    fail(f"{where}: leaf {leaf_id!r} has no entry in the params")
                p = params[key]
                is_action = any(k in p for k in ("pf", "mu", "nu", "tau_s", "tau_f"))
                if form == "Condition":
                    is_action = False
                elif form == "Action":
                    is_action = True
                counter[0] += 1
                name = f"L{counter[0]}"
                el.set("name", name)
                self.leaves[name] = {
                    "kind": "action" if is_action else "condition",
                    "p": p,
                    "key": key,
                    "reactive": reactives[-1] if reactives else None,
                    "reactives": list(reactives),
                }
                ids.add((leaf_id, is_action))
                return
            if tag in REACTIVE:
                counter[0] += 1
                reactives = reactives + [f"R{counter[0]}"]
            for child in el:
                walk(child, reactives, where)

        for tree in root.iter("BehaviorTree"):
            walk(tree, [], f"BehaviorTree {tree.get('ID')!r}")
        self.xml = ET.tostring(root, encoding="unicode")
        self.factory = bt.BehaviorTreeFactory()
        seen = {}
        for leaf_id, is_action in ids:
            if seen.setdefault(leaf_id, is_action) != is_action:
                fail(f"leaf ID {leaf_id!r} is used both as an action and a condition")
        for leaf_id, is_action in seen.items():
            if is_action:
                self.factory.register_simple_stateful_action(
                    leaf_id, self.on_start, self.on_running, self.on_halted
                )
            else:
                self.factory.register_simple_condition(leaf_id, self.condition)
        self.tree = self.factory.create_tree_from_text(self.xml)
        self.fresh_tree = False

    def reset(self):
        self.actions = {}  # uid -> (deadline, outcome, last on_running time)
        self.running = {}  # reactive id -> number of running actions below it
        self.epoch = {}  # reactive id -> bumped when a condition below it finds none running
        self.cond = {}  # uid -> (value, epoch)

    # --- actions -------------------------------------------------------
    def draw_action(self, p):
        r = self.rng
        ps = float(p["ps"])
        success = r.random() < ps
        if success:
            t = r.expovariate(p["mu"]) if "mu" in p else float(p.get("tau_s", 0.0))
            if "tau_f" in p and "mu" in p:
                t = min(t, float(p["tau_f"]))
        else:
            t = r.expovariate(p["nu"]) if "nu" in p else float(p.get("tau_f", 0.0))
            if "tau_s" in p and "nu" in p:
                t = min(t, float(p["tau_s"]))
        return success, t * self.scale

    def on_start(self, node):
        leaf = self.leaves[node.name()]
        success, wall = self.draw_action(leaf["p"])
        outcome = S.SUCCESS if success else S.FAILURE
        if wall <= 0.0:
            return outcome
        now = time.monotonic()
        self.actions[node.uid()] = (now + wall, outcome, None)
        for r in leaf["reactives"]:
            self.running[r] = self.running.get(r, 0) + 1
        return S.RUNNING

    def finished(self, node):
        self.actions.pop(node.uid(), None)
        for r in self.leaves[node.name()]["reactives"]:
            self.running[r] -= 1

    def on_running(self, node):
        now = time.monotonic()
        deadline, outcome, last = self.actions[node.uid()]
        if last is not None:
            gap = now - last
            self.gaps_n += 1
            self.gaps_sum += gap
            self.gaps_max = max(self.gaps_max, gap)
        if now >= deadline:
            self.finished(node)
            return outcome
        self.actions[node.uid()] = (deadline, outcome, now)
        return S.RUNNING

    def on_halted(self, node):
        if node.uid() in self.actions:
            self.finished(node)

    # --- conditions ----------------------------------------------------
    def condition(self, node):
        leaf = self.leaves[node.name()]
        r = leaf["reactive"]
        uid = node.uid()
        if r is not None:
            if self.running.get(r, 0) == 0:
                self.epoch[r] = self.epoch.get(r, 0) + 1
            else:
                cached = self.cond.get(uid)
                if cached is not None and cached[1] == self.epoch.get(r, 0):
                    return cached[0]
        value = S.SUCCESS if self.rng.random() < float(leaf["p"]["ps"]) else S.FAILURE
        if r is not None:
            self.cond[uid] = (value, self.epoch.get(r, 0))
        return value

    # --- runs ----------------------------------------------------------
    def run(self, runs, sleep_ms):
        self.gaps_n, self.gaps_sum, self.gaps_max = 0, 0.0, 0.0
        times = {True: [], False: []}
        start_all = time.monotonic()
        for _ in range(runs):
            self.reset()
            if self.fresh_tree:
                self.tree = self.factory.create_tree_from_text(self.xml)
            t0 = time.monotonic()
            status = self.tree.tick_while_running(sleep_ms)
            t1 = time.monotonic()
            if status not in (S.SUCCESS, S.FAILURE):
                fail(f"the tree returned {status}")
            times[status == S.SUCCESS].append((t1 - t0) / self.scale)
        wall = time.monotonic() - start_all

        def mean_se(xs):
            if not xs:
                return None, None
            m = sum(xs) / len(xs)
            if len(xs) < 2:
                return m, None
            var = sum((x - m) ** 2 for x in xs) / (len(xs) - 1)
            return m, math.sqrt(var / len(xs))

        k = len(times[True])
        ps = k / runs
        mtts, mtts_se = mean_se(times[True])
        mttf, mttf_se = mean_se(times[False])
        return {
            "runs": runs,
            "successes": k,
            "failures": runs - k,
            "ps": ps,
            "ps_se": math.sqrt(ps * (1 - ps) / runs),
            "mtts": mtts,
            "mtts_se": mtts_se,
            "mttf": mttf,
            "mttf_se": mttf_se,
            "tick_ms_mean": 1e3 * self.gaps_sum / self.gaps_n if self.gaps_n else None,
            "tick_ms_max": 1e3 * self.gaps_max if self.gaps_n else None,
            "scale": self.scale,
            "wall_s": wall,
        }


def job(xml_text, params, runs, seed, scale, sleep_ms, fresh_tree=False):
    ref = Referee(xml_text, params, scale, random.Random(seed))
    ref.fresh_tree = fresh_tree
    return ref.run(runs, sleep_ms)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("tree", nargs="?", help="BehaviorTree.CPP XML file")
    ap.add_argument("params", nargs="?", help="btrel params file (JSON, or YAML with PyYAML)")
    ap.add_argument("--runs", type=int, default=1000)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--scale", type=float, default=0.01,
                    help="wall-clock seconds per unit of the params' time (default 0.01)")
    ap.add_argument("--sleep-ms", type=int, default=1,
                    help="tick_while_running's sleep between ticks (default 1)")
    ap.add_argument("--jobs", help="JSON list of {name, xml, params, runs, seed, scale, sleep_ms}")
    a = ap.parse_args()
    if a.jobs:
        with open(a.jobs, encoding="utf-8") as f:
            jobs = json.load(f)
        out = []
        for j in jobs:
            r = job(j["xml"], j["params"], int(j.get("runs", a.runs)), int(j.get("seed", a.seed)),
                    float(j.get("scale", a.scale)), int(j.get("sleep_ms", a.sleep_ms)),
                    bool(j.get("fresh_tree", False)))
            r["name"] = j.get("name")
            out.append(r)
        json.dump(out, sys.stdout, indent=1)
    else:
        if not (a.tree and a.params):
            ap.error("give TREE and PARAMS, or --jobs")
        with open(a.tree, encoding="utf-8") as f:
            xml_text = f.read()
        r = job(xml_text, read_params(a.params), a.runs, a.seed, a.scale, a.sleep_ms)
        json.dump(r, sys.stdout, indent=1)
    print()


if __name__ == "__main__":
    main()
