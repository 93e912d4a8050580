"""Writes search-and-grasp-episodes.csv: 80 simulated runs of every leaf of
trees/search-and-grasp.xml (the book's Table 9.2 parameters; the two
conditions at ps 0.1 and 0.05 instead of 0 so that they have something to
estimate), in btrel fit's CSV episode format. Run from the crate root:
python3 docs/fit/make_episodes.py"""
import random

random.seed(9)
truth = {  # key: (ps, mu, nu); no rates: a condition (an instant)
    "ObjectPositionRetrieved": (0.1, None, None),
    "object grasped": (0.05, None, None),
    "SearchFloor": (0.3, 0.0167, 0.01),
    "search drawer": (0.8, 0.01, 0.01),
    "search closet": (0.2, 0.005, 0.0056),
    "OneHandGrasp": (0.1, 0.1, 2.0),
    "two hands grasp": (0.5, 0.1, 0.05),
}
rows = ["run,node,start,end,status"]
for run in range(1, 81):
    for k, (p, mu, nu) in truth.items():
        ok = random.random() < p
        t0 = round(random.uniform(0, 5), 3)
        d = 0.0 if mu is None else random.expovariate(mu if ok else nu)
        rows.append(f"{run},{k},{t0},{round(t0 + d, 3)},{'success' if ok else 'failure'}")
with open("docs/fit/search-and-grasp-episodes.csv", "w") as f:
    f.write("\n".join(rows) + "\n")
