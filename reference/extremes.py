#!/usr/bin/env python3
"""Reference numbers for trees/extremes.yaml (numerical extremes), independent
of the Rust crate. Writes extremes.json next to this file.

The tree (rates 1e-4..1e5, probabilities 1e-12, 0 and 1, mu = nu, a
condition-only subtree, Parallel nodes) is written out again below with every
parameter an exact Fraction of its decimal literal (1e-4 is exactly 1/10000).

Two independent methods, asserted to agree:

  A  outcome paths + exact hypoexponential CDFs. Every node is expanded into
     its outcome paths (probability, list of exponential rates, outcome):
     actions and conditions directly, Sequence/Fallback by concatenation, a
     Parallel by enumerating the race of its running children (each step: the
     running children's current phases compete; the holding time is Exp(sum of
     their rates), the winner is chosen with probability rate/sum). ps, MTTS,
     MTTF are exact rationals (sums over paths of p * sum(1/r)); a path's time
     CDF comes from its exact partial-fraction expansion (repeated rates
     allowed), evaluated with mpmath at 250 digits (the rational coefficients
     cancel heavily when rates span 9 orders of magnitude).
  B  phase-type CTMC, built recursively as matrices (Sequence/Fallback redirect
     exits into the next child's initial vector, Parallel is the product chain
     over the children's local states). ps and E[T;S] by exact rational solves
     (ps = aS + alpha (-T)^-1 s, E[T;S] = alpha (-T)^-2 s); pi(t) by
     pi_S(t) = ps - alpha e^{Tt} h_S with h_S = (-T)^-1 s exact and e^{Tt} from
     mpmath.expm at 60 digits (mpmath raises its working precision for the
     scaling and squaring; ||Tt|| reaches 1e12 here).

Run:  pip install mpmath && python3 reference/extremes.py   (about a minute)
"""

import json
import math
import os
import sys
from fractions import Fraction as Fr
from functools import lru_cache

import mpmath as mp

HERE = os.path.dirname(os.path.abspath(__file__))
TIMES = ["0", "1e-6", "1e-5", "1e-3", "0.1", "1", "10", "100", "1e3", "1e4", "1e5", "1e6", "1e7"]
DPS_A = 250
DPS_B = 60


def F(x):
    return Fr(str(x))


def action(name, ps, mu=None, nu=None, pf=None):
    ps = F(ps)
    pf = F(pf) if pf is not None else 1 - ps
    return {"kind": "action", "name": name, "ps": ps, "pf": pf,
            "mu": F(mu) if mu is not None else None, "nu": F(nu) if nu is not None else None}


def condition(name, ps):
    return {"kind": "condition", "name": name, "ps": F(ps), "pf": 1 - F(ps)}


def seq(name, *ch):
    return {"kind": "sequence", "name": name, "children": list(ch)}


def fb(name, *ch):
    return {"kind": "fallback", "name": name, "children": list(ch)}


def par(name, m, *ch):
    # the book's Parallel: Success at >= M successes, Failure at > N - M failures
    return {"kind": "parallel", "name": name, "M": m, "children": list(ch)}


TREE = seq(
    "extremes",
    fb("instant checks", condition("never", 0), condition("tiny", "1e-12"), condition("always", 1)),
    action("fast", "0.9", mu="1e5", nu="1e4"),
    action("reliable", "0.999999999999", pf="1e-12", mu="2", nu="3"),
    fb("slow search",
       action("long shot", "1e-12", mu="1e-4", nu="1e-4"),
       action("slow", "0.99", mu="1e-4", nu="2e-4")),
    par("pair", 2,
        action("sure", 1, mu="10"),
        action("doomed", 0, nu="1e-3"),
        action("balanced", "0.5", mu="0.1", nu="0.1")),
    fb("last resort",
       par("deadlock", 2, action("dead end", 0, nu="5"), action("coin", "0.3", mu="1", nu="1")),
       action("fallback plan", "0.7", mu="1e-3", nu="1e5")),
)


def walk(node, out):
    out.append(node)
    for c in node.get("children", []):
        walk(c, out)
    return out


# ----------------------------------------------------------------------------
# Method A: outcome paths
# ----------------------------------------------------------------------------
def merge(paths):
    acc = {}
    for p, rates, o in paths:
        if p == 0:
            continue
        key = (tuple(sorted(rates)), o)
        acc[key] = acc.get(key, 0) + p
    return [(p, r, o) for (r, o), p in acc.items()]


def paths(node):
    k = node["kind"]
    if k == "action":
        out = []
        if node["ps"] > 0:
            out.append((node["ps"], (node["mu"],), "S"))
        if node["pf"] > 0:
            out.append((node["pf"], (node["nu"],), "F"))
        return out
    if k == "condition":
        return merge([(node["ps"], (), "S"), (node["pf"], (), "F")])
    if k in ("sequence", "fallback"):
        cont = "S" if k == "sequence" else "F"
        partial = [(Fr(1), ())]
        out = []
        chs = node["children"]
        for i, ch in enumerate(chs):
            nxt = []
            for p, r in partial:
                for q, rr, o in paths(ch):
                    if o == cont and i < len(chs) - 1:
                        nxt.append((p * q, r + rr))
                    else:
                        out.append((p * q, r + rr, o))
            partial = nxt
        return merge(out)
    if k == "parallel":
        return merge(race(node))
    raise ValueError(k)


def race(node):
    """Outcome paths of a Parallel whose children are actions: each child is
    'S-phase' (will succeed, rate mu), 'F-phase' (rate nu), or done S/F."""
    chs = node["children"]
    n, m = len(chs), node["M"]
    assert all(c["kind"] == "action" for c in chs)
    out = []

    def step(state, p, rates):
        ns = sum(1 for s in state if s == "S")
        nf = sum(1 for s in state if s == "F")
        if ns >= m:
            out.append((p, rates, "S"))
            return
        if nf > n - m:
            out.append((p, rates, "F"))
            return
        running = [(i, chs[i]["mu"] if s == "s" else chs[i]["nu"]) for i, s in enumerate(state) if s in "sf"]
        total = sum(r for _, r in running)
        for i, r in running:
            st = list(state)
            st[i] = "S" if state[i] == "s" else "F"
            step(tuple(st), p * r / total, rates + (total,))

    def start(i, state, p):
        if i == n:
            step(tuple(state), p, ())
            return
        c = chs[i]
        if c["ps"] > 0:
            start(i + 1, state + ["s"], p * c["ps"])
        if c["pf"] > 0:
            start(i + 1, state + ["f"], p * c["pf"])

    start(0, [], Fr(1))
    return out


def stats_from_paths(P):
    ps = sum(p for p, _, o in P if o == "S")
    pf = sum(p for p, _, o in P if o == "F")
    ets = sum(p * sum(1 / r for r in rr) for p, rr, o in P if o == "S")
    etf = sum(p * sum(1 / r for r in rr) for p, rr, o in P if o == "F")
    return ps, pf, ets, etf


@lru_cache(maxsize=None)
def hypo_coeffs(rates):
    """CDF(t) = 1 + sum c t^(k-1) e^(-r t) / (k-1)! for a sum of independent
    Exp(rates); exact partial fractions of C / (s prod (s + r_j)^m_j)."""
    mult = {}
    for r in rates:
        mult[r] = mult.get(r, 0) + 1
    c0 = Fr(1)
    for r, m in mult.items():
        c0 *= r ** m
    res = []
    for rj, mj in mult.items():
        order = mj

        def ser(d, m):
            return [Fr(math.comb(m + k - 1, k)) * (-1) ** k / d ** (m + k) for k in range(order)]

        def mul(a, b):
            c = [Fr(0)] * order
            for i, x in enumerate(a):
                for j in range(order - i):
                    c[i + j] += x * b[j]
            return c

        g = [c0] + [Fr(0)] * (order - 1)
        g = mul(g, ser(-rj, 1))
        for ri, mi in mult.items():
            if ri != rj:
                g = mul(g, ser(ri - rj, mi))
        for k in range(1, mj + 1):
            res.append((rj, k, g[mj - k]))
    return res


def mpf(x):
    return mp.mpf(x.numerator) / x.denominator


def hypo_cdf(rates, t):
    if len(rates) == 0:
        return mp.mpf(1)
    if t == 0:
        return mp.mpf(0)
    s = mp.mpf(1)
    for r, k, c in hypo_coeffs(tuple(sorted(rates))):
        s += mpf(c) * t ** (k - 1) * mp.exp(-mpf(r) * t) / mp.factorial(k - 1)
    return s


def curve_from_paths(P, t):
    s = sum((mpf(p) * hypo_cdf(r, t) for p, r, o in P if o == "S"), mp.mpf(0))
    f = sum((mpf(p) * hypo_cdf(r, t) for p, r, o in P if o == "F"), mp.mpf(0))
    return s, f


# ----------------------------------------------------------------------------
# Method B: phase-type CTMC as matrices
# ----------------------------------------------------------------------------
class PH:
    """aS, aF: immediate absorption; alpha: initial vector over n phases;
    T: n x n generator block; s, f: exit rates to Success / Failure."""

    def __init__(self, aS, aF, alpha, T, s, f):
        self.aS, self.aF, self.alpha, self.T, self.s, self.f = aS, aF, alpha, T, s, f

    @property
    def n(self):
        return len(self.alpha)


def zeros(r, c):
    return [[Fr(0)] * c for _ in range(r)]


def ph(node):
    k = node["kind"]
    if k == "condition":
        return PH(node["ps"], node["pf"], [], [], [], [])
    if k == "action":
        alpha, rates, s, f = [], [], [], []
        if node["ps"] > 0:
            alpha.append(node["ps"]); rates.append(node["mu"]); s.append(node["mu"]); f.append(Fr(0))
        if node["pf"] > 0:
            alpha.append(node["pf"]); rates.append(node["nu"]); s.append(Fr(0)); f.append(node["nu"])
        T = zeros(len(rates), len(rates))
        for i, r in enumerate(rates):
            T[i][i] = -r
        return PH(Fr(0), Fr(0), alpha, T, s, f)
    if k in ("sequence", "fallback"):
        acc = ph(node["children"][0])
        for ch in node["children"][1:]:
            acc = chain(acc, ph(ch), k)
        return acc
    if k == "parallel":
        return product(node)
    raise ValueError(k)


def chain(A, B, kind):
    """A then B: in a Sequence A's Success exits continue into B (Fallback:
    its Failure exits)."""
    n, m = A.n, B.n
    T = zeros(n + m, n + m)
    for i in range(n):
        for j in range(n):
            T[i][j] = A.T[i][j]
    for i in range(m):
        for j in range(m):
            T[n + i][n + j] = B.T[i][j]
    if kind == "sequence":
        go, stop_s, stop_f = A.s, [Fr(0)] * n, A.f
        aS, aF = A.aS * B.aS, A.aF + A.aS * B.aF
        alpha = A.alpha + [A.aS * x for x in B.alpha]
    else:
        go, stop_s, stop_f = A.f, A.s, [Fr(0)] * n
        aS, aF = A.aS + A.aF * B.aS, A.aF * B.aF
        alpha = A.alpha + [A.aF * x for x in B.alpha]
    for i in range(n):
        for j in range(m):
            T[i][n + j] += go[i] * B.alpha[j]
    s = [stop_s[i] + go[i] * B.aS for i in range(n)] + list(B.s)
    f = [stop_f[i] + go[i] * B.aF for i in range(n)] + list(B.f)
    return PH(aS, aF, alpha, T, s, f)


def product(node):
    chs = [ph(c) for c in node["children"]]
    n_ch, m = len(chs), node["M"]

    def status(st):
        ns = sum(1 for x in st if x == "S")
        nf = sum(1 for x in st if x == "F")
        return "S" if ns >= m else ("F" if nf > n_ch - m else None)

    # initial distribution over local states (phase index, 'S' or 'F')
    init = {(): Fr(1)}
    for c in chs:
        nxt = {}
        for st, p in init.items():
            for loc, q in [(i, a) for i, a in enumerate(c.alpha)] + [("S", c.aS), ("F", c.aF)]:
                if q != 0:
                    nxt[st + (loc,)] = nxt.get(st + (loc,), 0) + p * q
        init = nxt
    index, order, trans = {}, [], {}
    frontier = [st for st in init if status(st) is None]
    for st in frontier:
        index.setdefault(st, len(index))
    order = list(frontier)
    while frontier:
        new = []
        for st in frontier:
            out = []
            for ci, loc in enumerate(st):
                if loc in ("S", "F"):
                    continue
                c = chs[ci]
                for j in range(c.n):
                    if j != loc and c.T[loc][j] != 0:
                        out.append((st[:ci] + (j,) + st[ci + 1:], c.T[loc][j]))
                if c.s[loc] != 0:
                    out.append((st[:ci] + ("S",) + st[ci + 1:], c.s[loc]))
                if c.f[loc] != 0:
                    out.append((st[:ci] + ("F",) + st[ci + 1:], c.f[loc]))
            trans[st] = out
            for nst, _ in out:
                if status(nst) is None and nst not in index:
                    index[nst] = len(index)
                    order.append(nst)
                    new.append(nst)
        frontier = new
    N = len(order)
    T = zeros(N, N)
    s, f = [Fr(0)] * N, [Fr(0)] * N
    alpha = [Fr(0)] * N
    aS = aF = Fr(0)
    for st, p in init.items():
        stt = status(st)
        if stt == "S":
            aS += p
        elif stt == "F":
            aF += p
        else:
            alpha[index[st]] += p
    for st in order:
        i = index[st]
        for nst, r in trans[st]:
            T[i][i] -= r
            stt = status(nst)
            if stt == "S":
                s[i] += r
            elif stt == "F":
                f[i] += r
            else:
                T[i][index[nst]] += r
    return PH(aS, aF, alpha, T, s, f)


def solve(A, b):
    """Exact solution of A x = b (Fractions, Gauss-Jordan with pivoting)."""
    n = len(A)
    M = [list(A[i]) + [b[i]] for i in range(n)]
    for c in range(n):
        p = next(r for r in range(c, n) if M[r][c] != 0)
        M[c], M[p] = M[p], M[c]
        for r in range(n):
            if r != c and M[r][c] != 0:
                fac = M[r][c] / M[c][c]
                M[r] = [x - fac * y for x, y in zip(M[r], M[c])]
    return [M[i][n] / M[i][i] for i in range(n)]


def ph_stats(P):
    if P.n == 0:
        return P.aS, P.aF, Fr(0), Fr(0)
    negT = [[-x for x in row] for row in P.T]
    hS, hF = solve(negT, P.s), solve(negT, P.f)   # absorption probabilities
    gS, gF = solve(negT, hS), solve(negT, hF)     # (-T)^-2 s, (-T)^-2 f
    dot = lambda a, b: sum(x * y for x, y in zip(a, b))
    return P.aS + dot(P.alpha, hS), P.aF + dot(P.alpha, hF), dot(P.alpha, gS), dot(P.alpha, gF)


def ph_curve(P, ts):
    ps, pf, _, _ = ph_stats(P)
    if P.n == 0:
        return [(mpf(P.aS), mpf(P.aF)) for _ in ts]
    negT = [[-x for x in row] for row in P.T]
    hS, hF = solve(negT, P.s), solve(negT, P.f)
    Tm = mp.matrix([[mpf(x) for x in row] for row in P.T])
    a = mp.matrix([[mpf(x) for x in P.alpha]])
    hs = mp.matrix([mpf(x) for x in hS])
    hf = mp.matrix([mpf(x) for x in hF])
    out = []
    for t in ts:
        if t == 0:
            out.append((mpf(P.aS), mpf(P.aF)))
            continue
        E = mp.expm(Tm * t)
        v = a * E
        out.append((mpf(ps) - (v * hs)[0], mpf(pf) - (v * hf)[0]))
    return out


# ----------------------------------------------------------------------------
def fstr(x, digits=34):
    return mp.nstr(x, digits, min_fixed=-1, max_fixed=-1) if x is not None else None


def main():
    nodes = walk(TREE, [])
    out_nodes = {}
    worst = {"stats": 0, "curve_abs": mp.mpf(0)}
    for node in nodes:
        name = node["name"]
        P = paths(node)
        ps, pf, ets, etf = stats_from_paths(P)
        B = ph(node)
        ps2, pf2, ets2, etf2 = ph_stats(B)
        assert (ps, pf, ets, etf) == (ps2, pf2, ets2, etf2), f"A and B differ on {name}"
        assert ps + pf == 1, name
        mtts = ets / ps if ps > 0 else None
        mttf = etf / pf if pf > 0 else None
        mu = 1 / mtts if mtts else None
        nu = 1 / mttf if mttf else None
        mp.mp.dps = DPS_A
        ts_a = [mp.mpf(t) for t in TIMES]
        ca = [curve_from_paths(P, t) for t in ts_a]
        mp.mp.dps = DPS_B
        cb = ph_curve(B, [mp.mpf(t) for t in TIMES])
        diff = max(max(abs(x[0] - y[0]), abs(x[1] - y[1])) for x, y in zip(ca, cb))
        worst["curve_abs"] = max(worst["curve_abs"], diff)
        print(f"{name:15} ps {float(ps):.6g} paths {len(P):5} phases {B.n:3}  |A-B| curve {mp.nstr(diff, 3)}")
        assert diff < mp.mpf("1e-40"), f"curves of {name} disagree: {diff}"
        mp.mp.dps = DPS_A
        rec = {
            "kind": node["kind"],
            "ps": float(ps), "pf": float(pf),
            "mtts": float(mtts) if mtts is not None else None,
            "mttf": float(mttf) if mttf is not None else None,
            "mu": float(mu) if mu is not None else None,
            "nu": float(nu) if nu is not None else None,
            "success": [float(s) for s, _ in ca],
            "failure": [float(f) for _, f in ca],
            "high_precision": {
                "ps": fstr(mpf(ps)), "pf": fstr(mpf(pf)),
                "mtts": fstr(mpf(mtts)) if mtts is not None else None,
                "mttf": fstr(mpf(mttf)) if mttf is not None else None,
                "success": [fstr(s) for s, _ in ca],
                "failure": [fstr(f) for _, f in ca],
            },
            "exact_fraction": {
                "ps": str(ps), "pf": str(pf),
                "mtts": str(mtts) if mtts is not None else None,
                "mttf": str(mttf) if mttf is not None else None,
            },
        }
        out_nodes[name] = rec
    result = {
        "meta": {
            "tree": "trees/extremes.yaml",
            "generator": "reference/extremes.py",
            "python": sys.version.split()[0],
            "mpmath": mp.__version__,
            "methods": "A: outcome paths + exact partial fractions at 250 digits; "
                       "B: phase CTMC, exact rational solves, mpmath.expm at 60 digits",
            "max_abs_difference_A_B_curves": float(worst["curve_abs"]),
            "stats_A_equals_B_exactly": True,
            "null": "undefined: MTTS/mu of a node that never succeeds, MTTF/nu of one that never "
                    "fails, mu/nu of a zero MTTS/MTTF",
        },
        "times": [float(t) for t in TIMES],
        "nodes": out_nodes,
    }
    with open(os.path.join(HERE, "extremes.json"), "w") as fh:
        json.dump(result, fh, indent=1)
        fh.write("\n")
    print("max |A - B| over all curves:", mp.nstr(worst["curve_abs"], 3))


if __name__ == "__main__":
    main()
