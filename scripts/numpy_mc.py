#!/usr/bin/env python3
"""A vectorised numpy Monte Carlo of a Stochastic Behavior Tree: the anchor
against which btrel's simulator is timed (docs/BENCHMARKS.md).

This is the simulation a researcher would write with numpy: every leaf is
sampled for a whole batch of episodes at once (`Generator.random` for the
outcome, `Generator.standard_exponential` scaled by the outcome's mean for the
time), and a Sequence / Fallback combines its children's arrays (a child
counts for the episodes still running when it is reached). It shares nothing
with btrel but the tree file's meaning.

Two models:

* `numpy_mc.py TREE.yaml`: a btrel YAML tree made of `sequence`, `fallback`,
  `action` (ps / pf, mu / nu or tau_s / tau_f) and `condition` (ps) nodes;
  anything else is refused.
* `numpy_mc.py --nav2 PARAMS.yaml`: Nav2's default tree
  (`navigate_to_pose_w_replanning_and_recovery.xml`) with the semantics
  btrel gives it (README, *Nav2's default tree*), written out by hand: a
  RecoveryNode with 6 retries around the PipelineSequence (five selectors,
  the 1 Hz RateController re-planning with one costmap-clearing retry while
  FollowPath runs with its own, a failed re-plan failing the attempt), the
  recovery branch (two "would a recovery help" checks, GoalUpdated, and the
  RoundRobin of four recoveries without wrap_around whose index survives the
  retries). Re-plans are run for the episodes still re-planning, a vector
  step at a time.

Prints the root's P(Success), P(Failure), MTTS and MTTF (estimate ± standard
error), the curve at --times, and the throughput; `--json` prints the same as
one JSON object. Needs numpy and PyYAML (tests/python-requirements.txt).
"""

import argparse
import json
import math
import sys
import time

import numpy as np
import yaml


class TreeError(Exception):
    pass


# ---------------------------------------------------------------- YAML trees


def _leaf(kind, body, where):
    if not isinstance(body, dict):
        raise TreeError(f"{where}: a {kind} needs a mapping of parameters")
    ps = body.get("ps")
    pf = body.get("pf")
    if ps is None and pf is None:
        raise TreeError(f"{where}: a {kind} needs ps or pf")
    ps = float(ps) if ps is not None else 1.0 - float(pf)
    if kind == "condition":
        return ("leaf", ps, (0.0, 0.0), (0.0, 0.0))

    def law(rate_key, fixed_key, possible):
        if not possible:
            return (0.0, 0.0)
        if rate_key in body:
            return (1.0 / float(body[rate_key]), 0.0)  # (mean of Exp, fixed)
        if fixed_key in body:
            return (0.0, float(body[fixed_key]))
        raise TreeError(f"{where}: an action needs {rate_key} or {fixed_key}")

    for key in body:
        if key not in ("name", "ps", "pf", "mu", "nu", "tau_s", "tau_f"):
            raise TreeError(f"{where}: '{key}' is not supported by this baseline")
    return ("leaf", ps, law("mu", "tau_s", ps > 0), law("nu", "tau_f", ps < 1))


def parse_node(node, where="tree"):
    if not isinstance(node, dict) or len(node) != 1:
        raise TreeError(f"{where}: a node is a mapping with one key")
    (kind, body), = node.items()
    if kind in ("action", "condition"):
        return _leaf(kind, body, where)
    if kind in ("sequence", "fallback"):
        kids = body.get("children") if isinstance(body, dict) else None
        if not kids:
            raise TreeError(f"{where}: a {kind} needs children")
        return (kind, [parse_node(k, f"{where}/{kind}[{i}]") for i, k in enumerate(kids)])
    raise TreeError(f"{where}: node kind '{kind}' is not supported by this baseline")


def run_node(node, rng, n):
    """(success, duration) arrays of n independent episodes of `node`."""
    if node[0] == "leaf":
        _, ps, (ms, fs), (mf, ff) = node
        ok = rng.random(n) < ps
        if ms == 0.0 and mf == 0.0:
            # fixed times (or a condition): no draw
            return ok, np.where(ok, fs, ff)
        if fs == 0.0 and ff == 0.0:
            return ok, rng.standard_exponential(n) * np.where(ok, ms, mf)
        e = rng.standard_exponential(n)
        return ok, np.where(ok, e * ms + fs, e * mf + ff)
    kind, kids = node
    want = kind == "fallback"  # the outcome that ends the loop
    t = np.zeros(n)
    going = np.ones(n, dtype=bool)  # episodes that reach the next child
    for child in kids:
        ok, d = run_node(child, rng, n)
        t += np.where(going, d, 0.0)
        going &= ok != want
    return ~going if want else going, t


# ------------------------------------------------------------ Nav2's default


def nav2_params(path):
    with open(path) as f:
        p = yaml.safe_load(f)

    def leaf(name):
        e = p[name]
        ps = float(e["ps"])
        if not any(k in e for k in ("mu", "nu", "tau_s", "tau_f")):
            return (ps, 0.0, 0.0, 0.0, 0.0)  # a condition
        ms = 1.0 / float(e["mu"]) if "mu" in e else 0.0
        mf = 1.0 / float(e["nu"]) if "nu" in e else 0.0
        return (ps, ms, mf, float(e.get("tau_s", 0.0)), float(e.get("tau_f", 0.0)))

    names = [
        "ProgressCheckerSelector", "GoalCheckerSelector", "PathHandlerSelector",
        "ControllerSelector", "PlannerSelector", "GlobalUpdatedGoal", "IsGoalNearby",
        "TruncatePathLocal", "ValidatePath", "ComputePathToPose",
        "WouldAPlannerRecoveryHelp", "ClearEntireCostmap", "FollowPath",
        "WouldAControllerRecoveryHelp", "GoalUpdated", "Spin", "Wait", "BackUp",
    ]
    return {n: leaf(n) for n in names}


def sample(leaf, rng, n):
    ps, ms, mf, ts, tf = leaf
    ok = rng.random(n) < ps
    if ms == 0.0 and mf == 0.0:
        return ok, np.where(ok, ts, tf)
    e = rng.standard_exponential(n)
    return ok, np.where(ok, e * ms + ts, e * mf + tf)


def seq(*parts):
    """A Sequence of already sampled children (each (ok, t) of length n)."""
    ok, t = parts[0]
    ok, t = ok.copy(), t.copy()
    for k_ok, k_t in parts[1:]:
        t += np.where(ok, k_t, 0.0)
        ok &= k_ok
    return ok, t


def fb(*parts):
    ok, t = parts[0]
    ok, t = ok.copy(), t.copy()
    for k_ok, k_t in parts[1:]:
        t += np.where(ok, 0.0, k_t)
        ok |= k_ok
    return ok, t


def nav2_plan(P, rng, n):
    """The RateController's child: RecoveryNode(1)(FallbackComputePathToPose,
    Sequence(WouldAPlannerRecoveryHelp, ClearGlobalCostmap)) = Fallback(main,
    Sequence(recovery, main))."""

    def main():
        # ReactiveSequence of zero-time leaves, then ComputePathToPose
        check = seq(
            (~sample(P["GlobalUpdatedGoal"], rng, n)[0], np.zeros(n)),
            sample(P["IsGoalNearby"], rng, n),
            sample(P["TruncatePathLocal"], rng, n),
            sample(P["ValidatePath"], rng, n),
        )
        return fb(check, sample(P["ComputePathToPose"], rng, n))

    first = main()
    retry = seq(sample(P["WouldAPlannerRecoveryHelp"], rng, n),
                sample(P["ClearEntireCostmap"], rng, n), main())
    return fb(first, retry)


def nav2_attempt(P, rng, n):
    """One run of the PipelineSequence NavigateWithReplanning."""
    sel = seq(*[sample(P[k], rng, n) for k in (
        "ProgressCheckerSelector", "GoalCheckerSelector", "PathHandlerSelector",
        "ControllerSelector", "PlannerSelector")])
    plan_ok, plan_t = nav2_plan(P, rng, n)
    follow = fb(sample(P["FollowPath"], rng, n),
                seq(sample(P["WouldAControllerRecoveryHelp"], rng, n),
                    sample(P["ClearEntireCostmap"], rng, n),
                    sample(P["FollowPath"], rng, n)))
    t0 = sel[1] + plan_t  # the follower starts after the first plan
    stop = t0 + follow[1]  # and returns then
    # re-plans: one second after the first plan's Success, then one second
    # after each re-plan's Success, until one fails or the follower returns
    fail_at = np.full(n, np.inf)
    nxt = t0 + 1.0
    live = np.flatnonzero(sel[0] & plan_ok & (nxt <= stop))
    while live.size:
        ok, d = nav2_plan(P, rng, live.size)
        end = nxt[live] + d
        fail_at[live[~ok]] = end[~ok]
        nxt[live] = end + 1.0
        live = live[ok & (nxt[live] <= stop[live])]
    # a re-plan failing at or before the follower's return fails the attempt
    replan_fails = fail_at <= stop
    ok = sel[0] & plan_ok & follow[0] & ~replan_fails
    t = np.where(
        ~sel[0], sel[1],
        np.where(~plan_ok, t0, np.where(replan_fails, fail_at, stop)))
    return ok, t


def nav2_episodes(P, rng, n, retries=6):
    """RecoveryNode(6)(pipeline, Sequence(Fallback(WouldAController..,
    WouldAPlanner..), ReactiveFallback(GoalUpdated, RoundRobin(...))))."""
    ok = np.zeros(n, dtype=bool)
    t = np.zeros(n)
    rr = np.zeros(n, dtype=np.int64)  # the RoundRobin's index, per episode
    live = np.arange(n)  # episodes still in the RecoveryNode
    for attempt in range(retries + 1):
        a_ok, a_t = nav2_attempt(P, rng, live.size)
        t[live] += a_t
        ok[live[a_ok]] = True
        live = live[~a_ok]
        if attempt == retries or live.size == 0:
            break
        m = live.size
        helps = fb(sample(P["WouldAControllerRecoveryHelp"], rng, m),
                   sample(P["WouldAPlannerRecoveryHelp"], rng, m))[0]
        updated = sample(P["GoalUpdated"], rng, m)[0]
        # the RoundRobin runs (and moves its index) only where it is reached
        reach = helps & ~updated
        r_ok, r_t = nav2_round_robin(P, rng, rr, live[reach])
        ok_rec = helps & updated
        ok_rec[reach] = r_ok
        t[live[reach]] += r_t  # the checks take no time
        live = live[ok_rec]  # a failed recovery fails the tree
    return ok, t


def nav2_round_robin(P, rng, rr, live):
    """RoundRobin(ClearingActions, Spin, Wait, BackUp) without wrap_around,
    for the episodes `live`; updates their indices in `rr`. Returns (ok, t) of
    length live.size."""
    m = live.size
    clearing = seq(sample(P["ClearEntireCostmap"], rng, m), sample(P["ClearEntireCostmap"], rng, m))
    kids = [clearing, sample(P["Spin"], rng, m), sample(P["Wait"], rng, m),
            sample(P["BackUp"], rng, m)]
    k_ok = np.stack([k[0] for k in kids])
    k_t = np.stack([k[1] for k in kids])
    idx = rr[live].copy()
    ok = np.zeros(m, dtype=bool)
    t = np.zeros(m)
    going = np.ones(m, dtype=bool)
    cols = np.arange(m)
    for _ in range(len(kids)):
        c_ok = k_ok[idx, cols]
        t += np.where(going, k_t[idx, cols], 0.0)
        nxt = idx + 1
        last = nxt == len(kids)
        # passing the last child leaves the loop with Failure, index 0;
        # a Success returns Success with the index at the next child
        done = going & (last | c_ok)
        ok |= done & c_ok & ~last
        idx = np.where(going, np.where(last, 0, nxt), idx)
        going &= ~done
    rr[live] = idx
    return ok, t


# ------------------------------------------------------------------ driver


class Sums:
    def __init__(self, times):
        self.n = 0
        self.times = np.asarray(times, dtype=float)
        self.ks = 0
        self.kf = 0
        self.st = self.st2 = self.ft = self.ft2 = 0.0
        self.cs = np.zeros(len(times), dtype=np.int64)
        self.cf = np.zeros(len(times), dtype=np.int64)

    def add(self, ok, t):
        self.n += ok.size
        ts, tf = t[ok], t[~ok]
        self.ks += ts.size
        self.kf += tf.size
        self.st += ts.sum()
        self.st2 += (ts * ts).sum()
        self.ft += tf.sum()
        self.ft2 += (tf * tf).sum()
        if self.times.size:
            self.cs += np.searchsorted(np.sort(ts), self.times, side="right")
            self.cf += np.searchsorted(np.sort(tf), self.times, side="right")

    def result(self, elapsed):
        n = self.n

        def prop(k):
            p = k / n
            return {"mean": p, "se": math.sqrt(p * (1 - p) / n)}

        def mean(k, s1, s2):
            if k < 2:
                return None
            m = s1 / k
            var = max(s2 / k - m * m, 0.0) * k / (k - 1)
            return {"mean": m, "se": math.sqrt(var / k)}

        return {
            "runs": n,
            "ps": prop(self.ks),
            "pf": prop(self.kf),
            "mtts": mean(self.ks, self.st, self.st2),
            "mttf": mean(self.kf, self.ft, self.ft2),
            "curve": [
                {"t": float(t), "success": prop(int(s)), "failure": prop(int(f))}
                for t, s, f in zip(self.times, self.cs, self.cf)
            ],
            "seconds": elapsed,
            "episodes_per_second": n / elapsed,
        }


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("tree", nargs="?", help="a btrel YAML tree (Sequence/Fallback/leaves)")
    ap.add_argument("--nav2", metavar="PARAMS", help="simulate Nav2's default tree with these leaf params")
    ap.add_argument("--runs", type=float, default=1e6)
    ap.add_argument("--times", default="", help="comma-separated curve time points")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--batch", type=int, default=1 << 16, help="episodes per vector step")
    ap.add_argument("--json", action="store_true")
    a = ap.parse_args(argv)
    if (a.tree is None) == (a.nav2 is None):
        ap.error("give a TREE or --nav2 PARAMS")
    runs = int(a.runs)
    if runs < 1:
        ap.error("--runs must be at least 1")
    times = [float(x) for x in a.times.split(",") if x.strip()]
    try:
        if a.nav2:
            P = nav2_params(a.nav2)
            step = lambda rng, n: nav2_episodes(P, rng, n)
            name = "Nav2 default tree"
        else:
            with open(a.tree) as f:
                doc = yaml.safe_load(f)
            root = parse_node(doc.get("tree") if isinstance(doc, dict) else None)
            step = lambda rng, n: run_node(root, rng, n)
            name = doc.get("name", a.tree)
    except (OSError, TreeError, KeyError, ValueError, yaml.YAMLError) as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    rng = np.random.default_rng(a.seed)
    sums = Sums(times)
    start = time.perf_counter()
    done = 0
    while done < runs:
        n = min(a.batch, runs - done)
        ok, t = step(rng, n)
        sums.add(ok, t)
        done += n
    r = sums.result(time.perf_counter() - start)
    if a.json:
        print(json.dumps(r))
        return 0

    def fmt(e):
        return "-" if e is None else f"{e['mean']:.6g} ± {e['se']:.2g}"

    print(f"{name} — numpy Monte Carlo: {runs} runs, seed {a.seed}")
    print(f"ps {fmt(r['ps'])}  pf {fmt(r['pf'])}  MTTS {fmt(r['mtts'])}  MTTF {fmt(r['mttf'])}")
    for p in r["curve"]:
        print(f"t = {p['t']:g}: P(S) {fmt(p['success'])}  P(F) {fmt(p['failure'])}")
    print(f"{r['seconds']:.3f} s, {r['episodes_per_second'] / 1e6:.2f} M episodes/s (one core)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
