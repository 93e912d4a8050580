"""Writes rosbag2 recordings of a simulated Nav2 `behavior_tree_log` with
known parameters, using the `rosbags` library (tests/python-requirements.txt).

    python make_bags.py OUT_DIR --bags K --goals N --seed S
        [--storage mcap|sqlite3] [--layout uid|nouid] [--no-definition]
        [--cancel P] [--tree nav|twins] [--no-log-topic]

writes OUT_DIR/bag_0 ... bag_{K-1} and prints, as JSON, the parameters
(`truth`) and each bag's true episodes per leaf ID (`bags`: counts, total
success / failure times and total censoring time, from the drawn durations).

Tree `nav` (uids depth-first from 1, as BehaviorTree.CPP numbers them):

    1 Sequence name=Navigate
    2   RecoveryNode name=ComputePathToPose number_of_retries=1
    3     ComputePathToPose                         (action, same name as 2)
    4     ClearEntireCostmap name=ClearGlobalCostmap (action)
    5   FollowPath                                   (action)

Each action ends in SUCCESS with probability ps after an exponential time of
rate mu, else in FAILURE after an exponential time of rate nu (the book's
model). A goal runs the tree once with Nav2's RecoveryNode semantics (one
retry after a successful recovery action); with probability --cancel it is
cancelled at an exponential time (mean CANCEL_MEAN s) after it starts, which
halts the running action (right-censored). Goals are separated by idle gaps.

Layout `uid` emulates Nav2 with BT.CPP 4: every change is logged, transitions
to IDLE included, with the node's uid. Layout `nouid` emulates Humble
(BT.CPP 3): no uid field, and no transition to IDLE is logged but the root's
(BT.CPP 3's resetStatus() notifies no logger).

Tree `twins`: Sequence(Wait name=W, Wait name=W) — two leaves of one name.

Every bag also holds an unrelated topic (/chatter, std_msgs/msg/String).
"""

import argparse
import json
import random
from pathlib import Path

from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.typesys import Stores, get_typestore, get_types_from_msg

LOG_MSG = "builtin_interfaces/Time timestamp\nBehaviorTreeStatusChange[] event_log\n"
CHANGE_UID = (
    "builtin_interfaces/Time timestamp\nstring node_name\nuint16 uid\n"
    "string previous_status\nstring current_status\n"
)
CHANGE_NOUID = (
    "builtin_interfaces/Time timestamp\nstring node_name\n"
    "string previous_status\nstring current_status\n"
)
LOG_TYPE = "nav2_msgs/msg/BehaviorTreeLog"
CHANGE_TYPE = "nav2_msgs/msg/BehaviorTreeStatusChange"

TRUTH = {
    "ComputePathToPose": {"ps": 0.7, "mu": 2.0, "nu": 0.5},
    "ClearEntireCostmap": {"ps": 0.8, "mu": 4.0, "nu": 1.0},
    "FollowPath": {"ps": 0.85, "mu": 0.2, "nu": 0.4},
    "Wait": {"ps": 0.9, "mu": 1.0, "nu": 2.0},
}
CANCEL_MEAN = 6.0
T0 = 1_700_000_000 * 10**9


class Sim:
    """One bag's simulated log: nodes with statuses, changes grouped by tick."""

    def __init__(self, rng, uid_layout, names, parents):
        self.rng = rng
        self.uid_layout = uid_layout
        self.names = names  # uid -> name
        self.parents = parents  # uid -> parent uid (root: None)
        self.status = {u: "IDLE" for u in names}
        self.t = 0.0
        self.messages = []  # (t, [(t, name, uid, prev, cur)])
        self.pending = []
        # the true episodes per leaf ID: counts and total times
        self.counts = {}

    def set(self, uid, cur):
        prev = self.status[uid]
        assert prev != cur
        self.status[uid] = cur
        if cur == "IDLE" and not self.uid_layout and self.parents[uid] is not None:
            return  # BT.CPP 3 logs no reset to IDLE (but the root's)
        self.pending.append((self.t, self.names[uid], uid, prev, cur))

    def flush(self):
        if self.pending:
            self.messages.append((self.t, self.pending))
            self.pending = []

    def reset(self, uids):
        """Children first, as BT.CPP resets them."""
        for u in sorted(uids, reverse=True):
            if self.status[u] != "IDLE":
                self.set(u, "IDLE")

    def action(self, uid, leaf_id, deadline):
        """Runs an action from now: its outcome, or None when the goal is
        cancelled first (the deadline)."""
        p = TRUTH[leaf_id]
        ok = self.rng.random() < p["ps"]
        d = self.rng.expovariate(p["mu"] if ok else p["nu"])
        self.set(uid, "RUNNING")
        self.flush()
        c = self.counts.setdefault(leaf_id, {
            "successes": 0, "failures": 0, "halted": 0,
            "success_time": 0.0, "failure_time": 0.0, "censored_time": 0.0})
        start_ns = round(self.t * 1e9)
        if self.t + d >= deadline:
            self.t = deadline
            c["halted"] += 1
            c["censored_time"] += (round(self.t * 1e9) - start_ns) * 1e-9
            return None
        self.t += d
        key = "success" if ok else "failure"
        c[key + "es" if ok else key + "s"] += 1
        c[key + "_time"] += (round(self.t * 1e9) - start_ns) * 1e-9
        self.set(uid, "SUCCESS" if ok else "FAILURE")
        return ok


def nav_goal(sim, deadline):
    """Sequence(Recovery(ComputePathToPose, ClearGlobalCostmap), FollowPath)."""
    sim.set(1, "RUNNING")
    sim.set(2, "RUNNING")
    retries = 0
    result = None
    while True:
        ok = sim.action(3, "ComputePathToPose", deadline)
        if ok is None:
            return None
        if ok:
            sim.reset([3, 4])
            sim.set(2, "SUCCESS")
            break
        if retries >= 1:
            sim.reset([3, 4])
            sim.set(2, "FAILURE")
            result = False
            break
        ok = sim.action(4, "ClearEntireCostmap", deadline)
        if ok is None:
            return None
        sim.reset([3, 4])
        if not ok:
            sim.set(2, "FAILURE")
            result = False
            break
        retries += 1
    if result is False:
        sim.reset([2])
        sim.set(1, "FAILURE")
        return False
    ok = sim.action(5, "FollowPath", deadline)
    if ok is None:
        return None
    sim.reset([2, 5])
    sim.set(1, "SUCCESS" if ok else "FAILURE")
    return ok


def twins_goal(sim, deadline):
    """Sequence(W, W)."""
    sim.set(1, "RUNNING")
    for u in (2, 3):
        ok = sim.action(u, "Wait", deadline)
        if ok is None:
            return None
        if not ok:
            sim.reset([2, 3])
            sim.set(1, "FAILURE")
            return False
    sim.reset([2, 3])
    sim.set(1, "SUCCESS")
    return True


def simulate(rng, args):
    if args.tree == "nav":
        names = {1: "Navigate", 2: "ComputePathToPose", 3: "ComputePathToPose",
                 4: "ClearGlobalCostmap", 5: "FollowPath"}
        parents = {1: None, 2: 1, 3: 2, 4: 2, 5: 1}
        goal = nav_goal
    else:
        names = {1: "Sequence", 2: "W", 3: "W"}
        parents = {1: None, 2: 1, 3: 1}
        goal = twins_goal
    sim = Sim(rng, args.layout == "uid", names, parents)
    for _ in range(args.goals):
        sim.t += rng.expovariate(1.0)
        start = sim.t
        cancel = (start + rng.expovariate(1.0 / CANCEL_MEAN)
                  if rng.random() < args.cancel else float("inf"))
        r = goal(sim, cancel)
        if r is None:
            # cancelled: BT.CPP halts the tree, children first
            sim.reset(list(names))
        else:
            sim.set(1, "IDLE")
        sim.flush()
    return sim.messages, sim.counts


def write_bag(path, messages, args, store):
    plugin = StoragePlugin.MCAP if args.storage == "mcap" else StoragePlugin.SQLITE3
    with Writer(path, version=9, storage_plugin=plugin) as w:
        chatter = w.add_connection("/chatter", "std_msgs/msg/String", typestore=store)
        log = None
        if not args.no_log_topic:
            if args.no_definition:
                log = w.add_connection("/behavior_tree_log", LOG_TYPE, msgdef="", rihs01="RIHS01_00")
            else:
                log = w.add_connection("/behavior_tree_log", LOG_TYPE, typestore=store)
        String = store.types["std_msgs/msg/String"]
        Log = store.types[LOG_TYPE]
        Change = store.types[CHANGE_TYPE]
        Time = store.types["builtin_interfaces/msg/Time"]

        def stamp(t):
            ns = T0 + round(t * 1e9)
            return ns, Time(sec=ns // 10**9, nanosec=ns % 10**9)

        for i, (t, changes) in enumerate(messages):
            ns, tm = stamp(t)
            if i % 3 == 0:
                w.write(chatter, ns, store.serialize_cdr(String(data=f"hello {i}"), "std_msgs/msg/String"))
            if log is None:
                continue
            events = []
            for (tc, name, uid, prev, cur) in changes:
                _, tcm = stamp(tc)
                fields = dict(timestamp=tcm, node_name=name, previous_status=prev, current_status=cur)
                if args.layout == "uid":
                    fields["uid"] = uid
                events.append(Change(**fields))
            w.write(log, ns, store.serialize_cdr(Log(timestamp=tm, event_log=events), LOG_TYPE))


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("out")
    ap.add_argument("--bags", type=int, default=1)
    ap.add_argument("--goals", type=int, default=50)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--storage", choices=["mcap", "sqlite3"], default="mcap")
    ap.add_argument("--layout", choices=["uid", "nouid"], default="uid")
    ap.add_argument("--no-definition", action="store_true")
    ap.add_argument("--cancel", type=float, default=0.2)
    ap.add_argument("--tree", choices=["nav", "twins"], default="nav")
    ap.add_argument("--no-log-topic", action="store_true")
    args = ap.parse_args()

    store = get_typestore(Stores.ROS2_HUMBLE)
    types = {}
    types.update(get_types_from_msg(LOG_MSG, LOG_TYPE))
    change = CHANGE_UID if args.layout == "uid" else CHANGE_NOUID
    types.update(get_types_from_msg(change, CHANGE_TYPE))
    store.register(types)

    rng = random.Random(args.seed)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    bags = []
    for b in range(args.bags):
        messages, counts = simulate(rng, args)
        write_bag(out / f"bag_{b}", messages, args, store)
        bags.append(counts)
    print(json.dumps({"truth": TRUTH, "bags": bags}))


if __name__ == "__main__":
    main()
