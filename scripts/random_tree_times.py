#!/usr/bin/env python3
"""Times `btrel report` + `btrel curve` on the engine specification's random
trees (tests/engine_spec.rs: at most 10 leaves, every node kind and timing
family), one process each, as a user would run them. The figures in
docs/BENCHMARKS.md ("random ≤ 10-leaf mixed trees") come from this script.

    cargo build --release
    python3 scripts/random_tree_times.py --trees 300 [--from 0] [--binary target/release/btrel]

The trees are the survey's (`BTREL_SPEC_SURVEY`, which prints each tree's
YAML; the survey also runs its own Monte Carlo check, not timed here). The
curve asks the times the specification asks: 0.5, 2, 8 and 10,000 s.
Prints the median, 90th percentile and slowest time, the trees over 1 s and
any that failed.
"""

import argparse
import os
import re
import statistics
import subprocess
import sys
import tempfile
import time


def survey_trees(n, start):
    env = dict(os.environ, BTREL_SPEC_SURVEY=str(n), BTREL_SPEC_FROM=str(start))
    out = subprocess.run(
        ["cargo", "test", "--release", "--test", "engine_spec", "--", "random_trees",
         "--nocapture"],
        env=env, capture_output=True, text=True, check=False,
    )
    trees = {}
    for line in out.stderr.splitlines():
        m = re.match(r"survey: seed (\d+) starts: (.*)", line)
        if m:
            trees[int(m.group(1))] = m.group(2)
    if not trees:
        sys.exit("no trees printed by the survey:\n" + out.stderr[-2000:])
    return trees


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--trees", type=int, default=300)
    ap.add_argument("--from", dest="start", type=int, default=0)
    ap.add_argument("--binary", default="target/release/btrel")
    args = ap.parse_args()
    trees = survey_trees(args.trees, args.start)
    times, slow, failed = [], [], []
    with tempfile.TemporaryDirectory() as d:
        for seed, yaml in sorted(trees.items()):
            path = os.path.join(d, f"{seed}.yaml")
            with open(path, "w") as f:
                f.write(yaml + "\n")
            t0 = time.perf_counter()
            codes = [
                subprocess.run([args.binary, "report", path], capture_output=True).returncode,
                subprocess.run([args.binary, "curve", path, "--times", "0.5,2,8,10000"],
                               capture_output=True).returncode,
            ]
            took = time.perf_counter() - t0
            times.append(took)
            if took > 1.0:
                slow.append((seed, round(took, 2)))
            if any(codes):
                failed.append((seed, codes))
    times.sort()
    print(f"{len(times)} trees: median {statistics.median(times):.3f} s, "
          f"90th percentile {times[int(0.9 * len(times))]:.3f} s, slowest {times[-1]:.2f} s, "
          f"total {sum(times):.1f} s")
    print(f"over 1 s ({len(slow)}): {slow}")
    print(f"failed (report, curve exit codes): {failed}")


if __name__ == "__main__":
    main()
