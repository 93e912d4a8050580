#!/usr/bin/env python3
"""A drone-fleet tree with K drones and a Parallel M of K (trees/drone-fleet.yaml
with fewer drones), whose product chain is large: K = 5, 6, 7 give chains of
28,782, 218,454 and 1.6 million states, for timing btrel's exports and
checkers on large chains.

    python3 scripts/fleet_tree.py 6 5 > fleet6.yaml
"""
import sys
k=int(sys.argv[1]); m=int(sys.argv[2])
print("name: fleet %d"%k)
print("tree:\n  sequence:\n    name: mission\n    children:\n      - condition: {name: weather ok, ps: 0.97}\n      - action: {name: pre-flight check, ps: 0.99, mu: 0.2, nu: 0.5}")
print("      - parallel:\n          name: survey\n          success_threshold: %d\n          children:"%m)
for i in range(1,k+1):
    print(f"""            - sequence:
                name: drone {i}
                children:
                  - action: {{name: fly {i}, ps: 0.97, mu: {0.05+0.01*i}, nu: 0.02}}
                  - fallback:
                      name: survey sector {i}
                      children:
                        - action: {{name: scan {i}, ps: 0.85, mu: 0.01, nu: 0.05}}
                        - action: {{name: rescan {i}, ps: 0.7, mu: 0.02, nu: 0.05}}""")
print("      - action: {name: upload, ps: 0.95, mu: 0.1, nu: 0.3}")
