#!/usr/bin/env python3
"""Solve a CTMC exported by `btrel export` with Storm (stormpy) and print the
node's figures, weighted over its initial distribution, as JSON.

    btrel export TREE --to drn -o sg.drn
    python3 scripts/storm_check.py sg.drn --times 10,100

MODEL is one of btrel's exports:
  * FILE.drn      Storm's explicit DRN format (`--to drn`; best for large chains);
  * FILE.sm       a PRISM-language model (`--to prism`), parsed in Storm's
                  PRISM-compatibility mode (Storm otherwise refuses the
                  PRISM-style CTMC commands);
  * BASE.tra      PRISM's explicit files BASE.tra/.lab/.srew (`--to
                  prism-explicit`); Storm reads another explicit dialect, so
                  they are converted into a temporary directory first. The
                  initial weights are then read from the properties file that
                  `--properties` wrote (give it with --prism-properties).

Storm's property language cannot weight a result by a state expression (PRISM's
`filter(+, w_init * P=? [...], "init")`), so this script computes every
property in all states and sums w_init(s) * value(s) over the initial states,
w_init being the model's reward structure of that name (the initial
probability of each state).

Output (JSON): states, transitions, ps, pf, mean_time (E[T] = ps MTTS + pf
MTTF), curve [{t, success, failure}] for --times, max_exit_rate (over all
states) and max_running_exit_rate (over the phases), build_seconds,
check_seconds, storm_version. Numerics: Storm's sound environment with a
native-solver precision of 1e-12 (--precision); transient probabilities by
Storm's uniformisation (Fox-Glynn).
"""

import argparse
import json
import os
import re
import sys
import tempfile
import time


def fail(msg):
    print(f"storm_check: {msg}", file=sys.stderr)
    sys.exit(2)


def prism_explicit_to_storm(base, tmp):
    """Converts PRISM's explicit .tra/.lab/.srew into Storm's explicit dialect."""
    tra, lab, srew = (base + ext for ext in (".tra", ".lab", ".srew"))
    for f in (tra, lab, srew):
        if not os.path.exists(f):
            fail(f"{f} not found (btrel export --to prism-explicit -o {base} writes it)")
    out_tra = os.path.join(tmp, "m.tra")
    with open(tra) as src, open(out_tra, "w") as dst:
        header = src.readline().split()
        if len(header) != 2:
            fail(f"{tra}: line 1 must be 'states transitions'")
        dst.write("ctmc\n")
        count = 0
        for line in src:
            if line.strip():
                dst.write(line)
                count += 1
        if count != int(header[1]):
            fail(f"{tra}: header says {header[1]} transitions, found {count}")
    out_lab = os.path.join(tmp, "m.lab")
    with open(lab) as src, open(out_lab, "w") as dst:
        names = dict(re.findall(r'(\d+)="([^"]+)"', src.readline()))
        dst.write("#DECLARATION\n" + " ".join(names.values()) + "\n#END\n")
        for line in src:
            if not line.strip():
                continue
            state, labels = line.split(":")
            dst.write(state.strip() + " " + " ".join(names[i] for i in labels.split()) + "\n")
    out_rew = os.path.join(tmp, "m.rew")
    with open(srew) as src, open(out_rew, "w") as dst:
        src.readline()  # "states nonzero"
        for line in src:
            if line.strip():
                dst.write(line)
    return out_tra, out_lab, out_rew, int(header[0])


def weights_from_properties(path, states):
    """The initial weights written out in btrel's explicit properties file."""
    with open(path) as f:
        text = f.read()
    m = re.search(r'"ps": filter\(\+, \((.*)\) \* P=\?', text)
    if not m:
        fail(f"{path}: no btrel 'ps' property (write it with --properties)")
    w = [0.0] * states
    for s, x in re.findall(r"\(s=(\d+) \? ([^ ]+) : 0\.0\)", m.group(1)):
        w[int(s)] += float(x)
    return w


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("model", help="FILE.drn, FILE.sm or BASE.tra exported by btrel")
    ap.add_argument("--times", default="", help="comma-separated times for the curve")
    ap.add_argument("--prism-properties",
                    help="the --properties file of the export (required for prism-explicit: "
                         "its initial weights); each of its properties without the constant T "
                         "is checked too and reported under \"properties\"")
    ap.add_argument("--precision", type=float, default=1e-12, help="Storm solver precision")
    args = ap.parse_args()
    # Storm logs (warnings, Fox-Glynn notes) to standard output: send them to
    # standard error and keep standard output for the JSON
    sys.stdout.flush()
    result_fd = os.dup(1)
    os.dup2(2, 1)
    try:
        import stormpy
        import stormpy.environments
        import stormpy.info
    except ImportError:
        fail("stormpy is not installed (pip install stormpy)")
    times = [float(t) for t in args.times.split(",") if t.strip()]

    t0 = time.perf_counter()
    path = args.model
    weights = None
    program = None
    if path.endswith(".drn"):
        model = stormpy.build_model_from_drn(path)
    elif path.endswith(".tra") or path.endswith(".all"):
        base = path[: -len(".tra")]
        if not args.prism_properties:
            fail("a prism-explicit export needs --prism-properties FILE for its initial weights")
        with tempfile.TemporaryDirectory() as tmp:
            tra, lab, rew, states = prism_explicit_to_storm(base, tmp)
            model = stormpy.build_model_from_explicit(tra, lab, state_rewards=rew)
        weights = weights_from_properties(args.prism_properties, states)
    else:
        program = stormpy.parse_prism_program(path, prism_compatibility=True)
        options = stormpy.BuilderOptions()
        options.set_build_all_reward_models()
        options.set_build_all_labels()
        model = stormpy.build_model(program, options=options)
    build = time.perf_counter() - t0
    if str(model.model_type) != "ModelType.CTMC":
        fail(f"{path} is a {model.model_type}, not a CTMC")
    if weights is None:
        if "w_init" not in model.reward_models:
            fail(f"{path} has no w_init reward (export it with btrel)")
        weights = list(model.reward_models["w_init"].state_rewards)
    init = list(model.initial_states)
    total = sum(weights[s] for s in init)
    if abs(total - 1.0) > 1e-12 or abs(sum(weights) - total) > 0:
        fail(f"{path}: the initial weights sum to {total!r} (outside the init states: "
             f"{sum(weights) - total!r})")

    env = stormpy.environments.sound()
    env.solver().native().precision = stormpy.Rational(repr(args.precision))
    reward = '{"time"}' if "time" in model.reward_models else ""

    def weighted(formula):
        prop = stormpy.parse_properties(formula, program)[0] if program else \
            stormpy.parse_properties(formula)[0]
        result = stormpy.model_checking(model, prop, only_initial_states=False, environment=env)
        values = result.get_value_vector()
        return sum(weights[s] * values[s] for s in init)

    t1 = time.perf_counter()
    out = {
        "model": path,
        "states": model.nr_states,
        "transitions": model.nr_transitions,
        "initial_states": len(init),
        "ps": weighted('P=? [ F "success" ]'),
        "pf": weighted('P=? [ F "failure" ]'),
        "mean_time": weighted(f'R{reward}=? [ F "done" ]'),
        "curve": [
            {
                "t": t,
                "success": weighted(f'P=? [ F<={t!r} "success" ]'),
                "failure": weighted(f'P=? [ F<={t!r} "failure" ]'),
            }
            for t in times
        ],
    }
    # the uniformisation rate Storm sees: the largest exit rate, which
    # btrel's absorbing self-loops must not raise above the phases' largest
    done = model.labeling.get_states("done")
    exits = list(model.exit_rates)
    out["max_exit_rate"] = max(exits)
    out["max_running_exit_rate"] = max(
        (e for s, e in enumerate(exits) if not done.get(s)), default=None)
    if args.prism_properties:
        # every property as written (filter(+, W * PHI, "init")): PHI by Storm,
        # weighted by the initial distribution (W is that distribution)
        props = {}
        pattern = re.compile(r'^"([^"]+)": filter\(\+, (?:\(.*\)|w_init) \* (.*), "init"\);$')
        with open(args.prism_properties) as f:
            for line in f:
                m = pattern.match(line.strip())
                if m and not re.search(r"<=T\b", m.group(2)):
                    props[m.group(1)] = weighted(m.group(2))
        out["properties"] = props
    out["build_seconds"] = build
    out["check_seconds"] = time.perf_counter() - t1
    out["storm_version"] = stormpy.info.storm_version()
    out["precision"] = args.precision
    sys.stdout.flush()
    with os.fdopen(result_fd, "w") as result:
        json.dump(out, result, indent=1)
        result.write("\n")


if __name__ == "__main__":
    main()
