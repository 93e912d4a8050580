#!/usr/bin/env python3
"""Exact exponential-polynomial reference for Stochastic BTs with mixed timing.

Independent of the Rust crate: it shares no code and no algorithm with
btrel's engine (no phase chains, no uniformization, no quadrature, no
interpolation). Every outcome law is kept in closed form:

* atoms: weights at exact rational instants (deterministic times, zero-time
  conditions);
* densities: finite sums of terms c * (t - tau)^k * exp(-lam (t - tau)) * H(t - tau)
  with exact rational k, lam, tau (Fractions) and coefficients c in mpmath
  at 60 significant digits.

This class is closed under every operation the tick semantics needs:
convolution (Sequence, Fallback, Retry, Repeat: partial fractions with exact
rational pole gaps), sums, products of CDFs (Parallel: a term shifted to the
later of two shifts by the binomial theorem), and integration (CDFs and mean
times in closed form, via k! / lam^(k+1)).

Parallel(M, F) with the effective failure threshold F' = min(F, N - M + 1)
(Failure once M successes are impossible): until it returns, its children run
independently, so at a time t where no child has an atom the node succeeds
with density sum_h s_h(t) * P(of the others exactly M-1 succeeded and fewer
than F' failed by t), and fails likewise. At an instant where children have
atoms, every child's state (succeeded before, failed before, succeeds now,
fails now, still running) is enumerated and the children returning now are
taken in child order, the node returning at the first threshold met
(BehaviorTree.CPP's rule).

Input (stdin, JSON): {"times": ["0.5", ...], "trees": [node, ...]} where a
node is one of
  {"action": {"ps": "0.3", "success": DUR|null, "failure": DUR|null}}
     DUR = {"exp": rate} | {"fixed": time} | {"trunc": [rate, cap]}
         | {"phases": {"shift": time, "stages": [[rate, count], ...]}}
           (a deterministic shift, then `count` exponential stages of each
           rate in series: Erlang, hypoexponential and their shifted forms;
           an Erlang-k stage block is the term t^(k-1) e^(-rate t) rate^k/(k-1)!)
  {"condition": "0.4"}
  {"sequence": [node...]} | {"fallback": [node...]}
  {"parallel": {"m": 2, "f": 1, "children": [node...]}}
  {"inverter": node} | {"force_success": node} | {"force_failure": node}
  {"retry": [n, node]} | {"repeat": [n, node]}
  {"flow": {"children": [node...], "states": [[child, next_s, next_f], ...]}}
     next = a later state's index | "S" | "F"
Numbers are decimal strings, read exactly. Output (stdout, JSON): per tree,
the nodes in pre-order, each {"ps", "pf", "mtts", "mttf", "success":
[S(t)...], "failure": [F(t)...]} as decimal strings (null where undefined).
With an optional "horizon": "H" (at least every time) in the input, only
what starts by H is kept (below) and each node has "success" and "failure"
only: exact at every t <= H, and much faster on large trees.
"""

import json
import sys
from fractions import Fraction
from math import comb, factorial

import mpmath
from mpmath import mp, mpf

mp.dps = 60

ZERO = Fraction(0)

# With a horizon H (the job's "horizon"), atoms and terms that start after H
# are dropped as they are made: they are zero on [0, H], and every operation
# (convolution, sums, products, integrals) only moves a start later, so every
# value at t <= H is unchanged. Masses and moments then cover [0, H] only and
# are not reported.
HORIZON = None


def beyond(tau):
    return HORIZON is not None and tau > HORIZON


def exp_neg(lam, x):
    """exp(-lam * x) for exact rationals."""
    return mpmath.exp(-mpf(lam.numerator) / lam.denominator * (mpf(x.numerator) / x.denominator))


def fr(x):
    return mpf(x.numerator) / x.denominator


class Fn:
    """sum of c (t-tau)^k e^{-lam (t-tau)} H(t-tau), keyed by (k, lam, tau)."""

    __slots__ = ("terms",)

    def __init__(self, terms=None):
        self.terms = dict(terms or {})

    def add_term(self, k, lam, tau, c):
        if c == 0 or beyond(tau):
            return
        key = (k, lam, tau)
        self.terms[key] = self.terms.get(key, mpf(0)) + c

    def __add__(self, other):
        out = Fn(self.terms)
        for (k, lam, tau), c in other.terms.items():
            out.add_term(k, lam, tau, c)
        return out

    def scale(self, a):
        return Fn({key: c * a for key, c in self.terms.items()})

    def shift(self, d):
        return Fn({(k, lam, tau + d): c for (k, lam, tau), c in self.terms.items() if not beyond(tau + d)})

    def __mul__(self, other):
        out = Fn()
        for (k1, l1, t1), c1 in self.terms.items():
            for (k2, l2, t2), c2 in other.terms.items():
                tau = max(t1, t2)
                # (t - ti)^ki = sum_r C(ki, r) (t - tau)^r (tau - ti)^(ki - r)
                a1 = c1 * exp_neg(l1, tau - t1)
                a2 = c2 * exp_neg(l2, tau - t2)
                for r1 in range(k1 + 1):
                    b1 = a1 * a2 * comb(k1, r1) * fr(tau - t1) ** (k1 - r1)
                    if b1 == 0:
                        continue
                    for r2 in range(k2 + 1):
                        b2 = b1 * comb(k2, r2) * fr(tau - t2) ** (k2 - r2)
                        out.add_term(r1 + r2, l1 + l2, tau, b2)
        return out

    def value(self, t):
        s = mpf(0)
        for (k, lam, tau), c in self.terms.items():
            if t >= tau:
                x = t - tau
                s += c * fr(x) ** k * exp_neg(lam, x)
        return s

    def integral_to(self, t):
        """int_0^t of the function (every term has lam > 0 or is integrated as a polynomial)."""
        s = mpf(0)
        for (k, lam, tau), c in self.terms.items():
            if t <= tau:
                continue
            x = t - tau
            if lam == 0:
                s += c * fr(x) ** (k + 1) / (k + 1)
            else:
                lx = fr(lam) * fr(x)
                part = sum(lx**i / factorial(i) for i in range(k + 1))
                s += c * factorial(k) / fr(lam) ** (k + 1) * (1 - mpmath.exp(-lx) * part)
        return s

    def integral_fn(self):
        """t -> int_0^t of the function, as a Fn (every lam > 0)."""
        out = Fn()
        for (k, lam, tau), c in self.terms.items():
            assert lam > 0, "a density term without decay"
            base = c * factorial(k) / fr(lam) ** (k + 1)
            out.add_term(0, ZERO, tau, base)
            for i in range(k + 1):
                out.add_term(i, lam, tau, -base * fr(lam) ** i / factorial(i))
        return out

    def total(self):
        """int_0^inf."""
        s = mpf(0)
        for (k, lam, tau), c in self.terms.items():
            assert lam > 0
            s += c * factorial(k) / fr(lam) ** (k + 1)
        return s

    def first_moment(self):
        """int_0^inf t f(t) dt."""
        s = mpf(0)
        for (k, lam, tau), c in self.terms.items():
            assert lam > 0
            s += c * (factorial(k + 1) / fr(lam) ** (k + 2) + fr(tau) * factorial(k) / fr(lam) ** (k + 1))
        return s


def conv_terms(k1, l1, k2, l2):
    """int_0^t s^k1 e^{-l1 s} (t-s)^k2 e^{-l2 (t-s)} ds as {(k, lam): coef}."""
    if l1 == l2:
        return {(k1 + k2 + 1, l1): mpf(factorial(k1) * factorial(k2)) / factorial(k1 + k2 + 1)}
    m, n = k1 + 1, k2 + 1
    out = {}
    scale = factorial(k1) * factorial(k2)
    d = l2 - l1  # exact rational, nonzero
    for i in range(1, m + 1):
        r = m - i
        a = Fraction((-1) ** r * comb(n + r - 1, r)) / d ** (n + r)
        out[(i - 1, l1)] = out.get((i - 1, l1), mpf(0)) + fr(a * scale) / factorial(i - 1)
    for j in range(1, n + 1):
        r = n - j
        b = Fraction((-1) ** r * comb(m + r - 1, r)) / (-d) ** (m + r)
        out[(j - 1, l2)] = out.get((j - 1, l2), mpf(0)) + fr(b * scale) / factorial(j - 1)
    return out


class Measure:
    """Sub-distribution: atoms {tau: w} plus a density Fn."""

    __slots__ = ("atoms", "dens")

    def __init__(self, atoms=None, dens=None):
        self.atoms = {tau: w for tau, w in (atoms or {}).items() if not beyond(tau)}
        self.dens = dens if dens is not None else Fn()

    def __add__(self, other):
        atoms = dict(self.atoms)
        for tau, w in other.atoms.items():
            atoms[tau] = atoms.get(tau, mpf(0)) + w
        return Measure(atoms, self.dens + other.dens)

    def conv(self, other):
        atoms = {}
        for t1, w1 in self.atoms.items():
            for t2, w2 in other.atoms.items():
                if not beyond(t1 + t2):
                    atoms[t1 + t2] = atoms.get(t1 + t2, mpf(0)) + w1 * w2
        dens = Fn()
        for t1, w1 in self.atoms.items():
            dens = dens + other.dens.shift(t1).scale(w1)
        for t2, w2 in other.atoms.items():
            dens = dens + self.dens.shift(t2).scale(w2)
        for (k1, l1, s1), c1 in self.dens.terms.items():
            for (k2, l2, s2), c2 in other.dens.terms.items():
                for (k, lam), c in conv_terms(k1, l1, k2, l2).items():
                    dens.add_term(k, lam, s1 + s2, c1 * c2 * c)
        return Measure(atoms, dens)

    def mass(self):
        return sum(self.atoms.values(), mpf(0)) + self.dens.total()

    def moment(self):
        return sum((fr(t) * w for t, w in self.atoms.items()), mpf(0)) + self.dens.first_moment()

    def cdf(self, t):
        return sum((w for tau, w in self.atoms.items() if tau <= t), mpf(0)) + self.dens.integral_to(t)

    def cdf_fn(self):
        """Right-continuous CDF as a Fn (atoms as steps)."""
        out = self.dens.integral_fn()
        for tau, w in self.atoms.items():
            out.add_term(0, ZERO, tau, w)
        return out

    def cdf_before(self, t):
        """P(returned strictly before t) (the density part is continuous)."""
        return sum((w for tau, w in self.atoms.items() if tau < t), mpf(0)) + self.dens.integral_to(t)


def delta(tau, w=1):
    return Measure() if beyond(tau) else Measure({tau: mpf(w)})


def side(w, dur):
    """The law of one outcome of an action: weight w, its duration."""
    if dur is None:
        return Measure()
    if "exp" in dur:
        lam = Fraction(dur["exp"])
        return Measure(dens=Fn({(0, lam, ZERO): w * fr(lam)}))
    if "fixed" in dur:
        return delta(Fraction(dur["fixed"]), w)
    if "phases" in dur:
        law = delta(Fraction(dur["phases"]["shift"]), w)
        for rate, count in dur["phases"]["stages"]:
            lam, k = Fraction(rate), int(count)
            erlang = Fn({(k - 1, lam, ZERO): fr(lam) ** k / factorial(k - 1)})
            law = law.conv(Measure(dens=erlang))
        return law
    lam, cap = Fraction(dur["trunc"][0]), Fraction(dur["trunc"][1])
    tail = exp_neg(lam, cap)
    dens = Fn({(0, lam, ZERO): w * fr(lam)})
    dens.add_term(0, lam, cap, -w * fr(lam) * tail)
    return Measure({cap: w * tail}, dens)


def in_turn(laws, keep_going):
    """Sequence (keep_going = 'S') or Fallback ('F'): (S, F) measures."""
    done = delta(ZERO)
    ends = Measure()
    for s, f in laws:
        go, stop = (s, f) if keep_going == "S" else (f, s)
        ends = ends + done.conv(stop)
        done = done.conv(go)
    return (done, ends) if keep_going == "S" else (ends, done)


def parallel(laws, m, f):
    n = len(laws)
    fp = min(f, n - m + 1)
    cs = [s.cdf_fn() for s, _ in laws]
    cf = [fl.cdf_fn() for _, fl in laws]
    one = Fn({(0, ZERO, ZERO): mpf(1)})
    running = [one + cs[h].scale(-1) + cf[h].scale(-1) for h in range(n)]

    def others(h):
        # generating polynomial over the others: {(successes, failures): Fn}, capped
        poly = {(0, 0): one}
        for g in range(n):
            if g == h:
                continue
            nxt = {}
            for (k, j), fn in poly.items():
                for dk, dj, part in ((0, 0, running[g]), (1, 0, cs[g]), (0, 1, cf[g])):
                    kk, jj = k + dk, j + dj
                    if kk > m or jj > fp:
                        continue
                    prod = fn * part
                    nxt[(kk, jj)] = nxt[(kk, jj)] + prod if (kk, jj) in nxt else prod
            poly = nxt
        return poly

    dens_s, dens_f = Fn(), Fn()
    for h, (s, fl) in enumerate(laws):
        poly = others(h)
        qs = Fn()
        qf = Fn()
        for (k, j), fn in poly.items():
            if k == m - 1 and j < fp:
                qs = qs + fn
            if k < m and j == fp - 1:
                qf = qf + fn
        dens_s = dens_s + s.dens * qs
        dens_f = dens_f + fl.dens * qf
    # atoms: every instant where some child has an atom
    instants = sorted({t for s, fl in laws for t in list(s.atoms) + list(fl.atoms)})
    atoms_s, atoms_f = {}, {}
    for tau in instants:
        states = []
        for s, fl in laws:
            bs, bf = s.cdf_before(tau), fl.cdf_before(tau)
            js, jf = s.atoms.get(tau, mpf(0)), fl.atoms.get(tau, mpf(0))
            states.append((bs, bf, js, jf, 1 - bs - bf - js - jf))
        ps_now, pf_now = mpf(0), mpf(0)

        def walk(h, prob, k0, j0, seq):
            nonlocal ps_now, pf_now
            if prob == 0:
                return
            if h == n:
                if k0 >= m or j0 >= fp:
                    return  # returned before tau
                k, j = k0, j0
                for o in seq:
                    if o == "S":
                        k += 1
                    else:
                        j += 1
                    if k >= m:
                        ps_now += prob
                        return
                    if j >= fp:
                        pf_now += prob
                        return
                return
            bs, bf, js, jf, rest = states[h]
            walk(h + 1, prob * bs, k0 + 1, j0, seq)
            walk(h + 1, prob * bf, k0, j0 + 1, seq)
            walk(h + 1, prob * js, k0, j0, seq + "S")
            walk(h + 1, prob * jf, k0, j0, seq + "F")
            walk(h + 1, prob * rest, k0, j0, seq)

        walk(0, mpf(1), 0, 0, "")
        if ps_now != 0:
            atoms_s[tau] = ps_now
        if pf_now != 0:
            atoms_f[tau] = pf_now
    return Measure(atoms_s, dens_s), Measure(atoms_f, dens_f)


def law(node, out):
    """(S, F) measures of node; appends every node's law to out in pre-order."""
    slot = len(out)
    out.append(None)
    (kind, arg), = node.items()
    if kind == "action":
        ps = Fraction(arg["ps"])
        res = (side(fr(ps), arg["success"]), side(fr(1 - ps), arg["failure"]))
    elif kind == "condition":
        ps = Fraction(arg)
        res = (delta(ZERO, fr(ps)), delta(ZERO, fr(1 - ps)))
    elif kind in ("sequence", "fallback"):
        laws = [law(c, out) for c in arg]
        res = in_turn(laws, "S" if kind == "sequence" else "F")
    elif kind == "parallel":
        laws = [law(c, out) for c in arg["children"]]
        res = parallel(laws, arg["m"], arg["f"])
    elif kind == "flow":
        # an acyclic graph of states, each running one child afresh: the law of
        # the rest of the run from state i, computed from the last state back
        laws = [law(c, out) for c in arg["children"]]
        rest = [None] * len(arg["states"])
        for i in reversed(range(len(arg["states"]))):
            child, on_s, on_f = arg["states"][i]
            succ, fail = Measure(), Measure()
            for part, nxt in zip(laws[child], (on_s, on_f)):
                if nxt == "S":
                    succ = succ + part
                elif nxt == "F":
                    fail = fail + part
                else:
                    succ = succ + part.conv(rest[nxt][0])
                    fail = fail + part.conv(rest[nxt][1])
            rest[i] = (succ, fail)
        res = rest[0]
    elif kind == "inverter":
        s, f = law(arg, out)
        res = (f, s)
    elif kind == "force_success":
        s, f = law(arg, out)
        res = (s + f, Measure())
    elif kind == "force_failure":
        s, f = law(arg, out)
        res = (Measure(), s + f)
    elif kind in ("retry", "repeat"):
        times, child = arg
        one = law(child, out)
        res = in_turn([one] * times, "F" if kind == "retry" else "S")
    else:
        raise ValueError(f"unknown node kind {kind}")
    out[slot] = res
    return res


def num(x):
    return None if x is None else mpmath.nstr(x, 30, strip_zeros=False)


def main():
    global HORIZON
    job = json.load(sys.stdin)
    times = [Fraction(t) for t in job["times"]]
    if job.get("horizon") is not None:
        HORIZON = Fraction(job["horizon"])
        assert all(t <= HORIZON for t in times), "every time within the horizon"
    result = []
    for tree in job["trees"]:
        laws = []
        law(tree, laws)
        nodes = []
        for s, f in laws:
            node = {
                "success": [num(s.cdf(t)) for t in times],
                "failure": [num(f.cdf(t)) for t in times],
            }
            if HORIZON is None:
                # masses and moments over all time (not known within a horizon)
                ps, pf = s.mass(), f.mass()
                node["ps"], node["pf"] = num(ps), num(pf)
                node["mtts"] = num(s.moment() / ps) if ps > mpf(10) ** -40 else None
                node["mttf"] = num(f.moment() / pf) if pf > mpf(10) ** -40 else None
            nodes.append(node)
        result.append(nodes)
    json.dump(result, sys.stdout)


if __name__ == "__main__":
    main()
