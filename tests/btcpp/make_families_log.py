#!/usr/bin/env python3
"""Runs a BehaviorTree.CPP v4 tree whose actions take durations of known
families with behaviortreepy and writes a real FileLogger2 `.btlog`, for
tests/fit_families.rs (`btrel fit --timing auto`).

A Sequence of three actions, run RUNS times:
  Expo   Success with probability 0.7 after Exp(mean 20 ms), else Failure
         after Exp(mean 10 ms)
  Erl    Success after Erlang-3 of rate 200/s (mean 15 ms)
  Shift  Success after 10 ms + Exp(mean 5 ms)
  Hyper  Success after Exp(mean 5 ms) with probability 0.4, else after
         Exp(mean 50 ms): a hyperexponential (its own random stream, so
         the other actions draw what they drew before it was added)
The truth is printed as JSON, with the mean and largest delay between a
drawn end and the tick that returned it (tick quantisation).

usage: make_families_log.py OUT.btlog RUNS SEED
"""
import json
import random
import sys

import behaviortreepy as bt
from btlog_common import TimedActions, run_logged

TREE = """
<root BTCPP_format="4" main_tree_to_execute="Main">
  <BehaviorTree ID="Main">
    <Sequence name="all">
      <ForceSuccess><Expo name="expo"/></ForceSuccess>
      <Erl name="erl"/>
      <Shift name="shift"/>
      <Hyper name="hyper"/>
    </Sequence>
  </BehaviorTree>
</root>
"""


def main():
    out, runs, seed = sys.argv[1], int(sys.argv[2]), int(sys.argv[3])
    rng = random.Random(seed)
    rng_hyper = random.Random(seed + 1_000_003)
    draws = {
        "Expo": lambda: (True, rng.expovariate(50.0))
        if rng.random() < 0.7
        else (False, rng.expovariate(100.0)),
        "Erl": lambda: (True, sum(rng.expovariate(200.0) for _ in range(3))),
        "Shift": lambda: (True, 0.010 + rng.expovariate(200.0)),
        "Hyper": lambda: (
            True,
            rng_hyper.expovariate(1.0 / 0.005)
            if rng_hyper.random() < 0.4
            else rng_hyper.expovariate(1.0 / 0.050),
        ),
    }
    factory = bt.BehaviorTreeFactory()
    actions = TimedActions()
    for name, draw in draws.items():
        factory.register_simple_stateful_action(name, *actions.callbacks(draw))
    run_logged(factory, TREE, out, runs)
    truth = {
        "Expo": {"family": "exponential", "ps": 0.7, "mu": 50.0, "nu": 100.0},
        "Erl": {"family": "Erlang-3", "rate": 200.0},
        "Shift": {"family": "shifted exponential", "shift": 0.010, "rate": 200.0},
        "Hyper": {"family": "hyperexponential-2", "p": 0.4, "rate1": 1 / 0.005, "rate2": 1 / 0.050},
        **actions.late_stats(),
    }
    json.dump(truth, sys.stdout)


if __name__ == "__main__":
    main()
