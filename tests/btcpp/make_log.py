#!/usr/bin/env python3
"""Runs a small BehaviorTree.CPP v4 tree many times with behaviortreepy and
writes a real FileLogger2 `.btlog`, for tests/fit.rs.

Each custom action draws its outcome first (Success with probability ps),
then its duration (Exp(mu) for a success, Exp(nu) for a failure), as in the
SBT model; each condition returns Success with probability ps. The truth is
printed as JSON on stdout so the test compares the fit with it, with the
mean and largest delay between a drawn end and the tick that returned it.

usage: make_log.py OUT.btlog RUNS SEED
"""
import json
import random
import sys

import behaviortreepy as bt
from btlog_common import TimedActions, run_logged

# leaf ID -> (ps, mu, nu) in 1/s; conditions have ps only
ACTIONS = {
    "Move": (0.7, 1 / 0.004, 1 / 0.008),
    "Grasp": (0.6, 1 / 0.003, 1 / 0.002),
    "ArmA": (0.8, 1 / 0.004, 1 / 0.003),
    "ArmB": (0.5, 1 / 0.005, 1 / 0.004),
}
CONDITIONS = {"Ready": 0.75}

# Fallback(Sequence(Ready, Move), Grasp), then a Parallel (success_count 1,
# failure_count 2) whose first success halts the other arm: halted arms are
# right-censored episodes in the log.
TREE = """
<root BTCPP_format="4" main_tree_to_execute="Main">
  <BehaviorTree ID="Main">
    <Sequence name="mission">
      <ForceSuccess>
        <Fallback name="get there">
          <Sequence>
            <Ready name="ready"/>
            <Move name="move"/>
          </Sequence>
          <Grasp name="grasp"/>
        </Fallback>
      </ForceSuccess>
      <Parallel name="arms" success_count="1" failure_count="2">
        <ArmA name="arm a"/>
        <ArmB name="arm b"/>
      </Parallel>
    </Sequence>
  </BehaviorTree>
</root>
"""


def main():
    out, runs, seed = sys.argv[1], int(sys.argv[2]), int(sys.argv[3])
    rng = random.Random(seed)
    factory = bt.BehaviorTreeFactory()
    actions = TimedActions()

    def draw(ps, mu, nu):
        ok = rng.random() < ps
        return ok, rng.expovariate(mu if ok else nu)

    for name, (ps, mu, nu) in ACTIONS.items():
        factory.register_simple_stateful_action(
            name, *actions.callbacks(lambda ps=ps, mu=mu, nu=nu: draw(ps, mu, nu))
        )
    for name, ps in CONDITIONS.items():
        factory.register_simple_condition(
            name,
            lambda node, ps=ps: bt.NodeStatus.SUCCESS
            if rng.random() < ps
            else bt.NodeStatus.FAILURE,
        )

    run_logged(factory, TREE, out, runs)
    truth = {k: {"ps": v[0], "mu": v[1], "nu": v[2]} for k, v in ACTIONS.items()}
    truth.update({k: {"ps": v} for k, v in CONDITIONS.items()})
    truth.update(actions.late_stats())
    json.dump(truth, sys.stdout)


if __name__ == "__main__":
    main()
