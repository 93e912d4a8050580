//! Sums of independent exponential stages: the Erlang, hypoexponential and
//! (with a deterministic shift, see [`super::Duration::PhaseType`]) shifted
//! timing families of an action's outcome.
//!
//! A [`Stages`] is `count_i` stages of rate `rate_i` for each distinct rate,
//! run one after the other: an Erlang-k is one rate with count `k`, a
//! hypoexponential one count per rate of its list (equal rates merged, which
//! does not change the law of a sum). The order of the stages does not
//! change the law either, so the phase chain lists them by decreasing rate.
//! A [`super::Duration`] holds its stages as an interned `&'static Stages`
//! ([`intern`]: one copy per distinct set of stages for the life of the
//! process), so that it stays `Copy` and 24 bytes and a tree's nodes do not
//! grow for the families most trees do not use.
//!
//! Size: one concern, sums of exponential stages and their CDFs, densities
//! and moments (about 120 lines are comments, 60 tests).

use rand::{Rng, RngExt};
use rand_distr::{Distribution, Exp1, Gamma};

/// Most distinct rates a [`Stages`] holds.
pub const MAX_STAGES: usize = 8;

/// Most stages (phases) in all, e.g. the largest Erlang `k`.
pub const MAX_PHASES: u32 = 1000;

/// Most phases of a general phase-type law ([`Stages::general`]).
pub const MAX_GENERAL_PHASES: usize = 64;

/// `counts[i]` exponential stages of rate `rates[i]` for `i < len`, summed;
/// or (when `general` is set, `len` 0) a general phase-type law.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Stages {
    len: u8,
    rates: [f64; MAX_STAGES],
    counts: [u32; MAX_STAGES],
    general: Option<&'static General>,
}

/// A general phase-type law `PH(α, T)`: the time to absorption of a CTMC
/// started in phase `i` with probability `α_i` (`Σ α = 1`: no atom at 0)
/// with sub-generator `T` (exit rates `t = −T·1`). The phases are stored in
/// a topological order of `T`'s transitions (every transition goes to a
/// later phase; `T` upper triangular), which the engine's chains need;
/// absorption is then certain. Built (validated) by [`Stages::general`].
#[derive(Debug, PartialEq)]
pub struct General {
    alpha: Vec<f64>,
    /// `T`, row-major `n × n`, in the stored (topological) order.
    t: Vec<f64>,
    /// Exit rates `−Σ_j T_ij`.
    exit: Vec<f64>,
    /// Total rates `−T_ii`.
    q: Vec<f64>,
}

impl Stages {
    /// The sum of `count` stages of each `(rate, count)`. Fails (with the
    /// reason) on a rate that is not finite and > 0, a count of 0, more than
    /// [`MAX_STAGES`] distinct rates or more than [`MAX_PHASES`] stages.
    pub fn new(list: &[(f64, u32)]) -> Result<Stages, String> {
        let mut s = Stages {
            len: 0,
            rates: [0.0; MAX_STAGES],
            counts: [0; MAX_STAGES],
            general: None,
        };
        if list.is_empty() {
            return Err("no stage".into());
        }
        let mut total: u64 = 0;
        for &(rate, count) in list {
            if !(rate.is_finite() && rate > 0.0) {
                return Err(format!("rate {rate} is not a finite number > 0"));
            }
            if count == 0 {
                return Err("a stage count is 0".into());
            }
            total += u64::from(count);
            if total > u64::from(MAX_PHASES) {
                return Err(format!("more than {MAX_PHASES} stages"));
            }
            let n = usize::from(s.len);
            match s.rates[..n].iter().position(|&r| r == rate) {
                Some(i) => s.counts[i] += count,
                None if n == MAX_STAGES => {
                    return Err(format!("more than {MAX_STAGES} distinct rates"))
                }
                None => {
                    s.rates[n] = rate;
                    s.counts[n] = count;
                    s.len += 1;
                }
            }
        }
        // a canonical order (by decreasing rate): equal laws compare equal
        let n = usize::from(s.len);
        let mut pairs: Vec<(f64, u32)> = s.iter().collect();
        pairs.sort_by(|a, b| b.0.total_cmp(&a.0));
        for (i, (r, c)) in pairs.into_iter().enumerate().take(n) {
            s.rates[i] = r;
            s.counts[i] = c;
        }
        Ok(s)
    }

    /// Erlang-`k` of `rate`: `k` stages of the same rate.
    pub fn erlang(k: u32, rate: f64) -> Result<Stages, String> {
        Stages::new(&[(rate, k)])
    }

    /// Hypoexponential: one stage of each rate.
    pub fn hypoexponential(rates: &[f64]) -> Result<Stages, String> {
        Stages::new(&rates.iter().map(|&r| (r, 1)).collect::<Vec<_>>())
    }

    /// The general phase-type law `PH(alpha, t)` (`t` the sub-generator,
    /// one row per phase). Fails (with the reason, phases numbered from 1)
    /// unless there are 1 to [`MAX_GENERAL_PHASES`] phases, `t` is square
    /// of that order, the `alpha_i` are finite, ≥ 0 and sum to 1 (within
    /// 1e-9: no atom at 0), `T_ii` < 0 and `T_ij` ≥ 0 are finite, every row
    /// sums to ≤ 0 and absorption is certain (every phase leads to an exit:
    /// `T` nonsingular). The engine's chains are acyclic: a law without
    /// cycles is stored in a topological order of its phases (the same
    /// chain); one with cycles as its canonical acyclic form
    /// (Cumani's CF1: the same law, checked), which fails when `T` has
    /// complex eigenvalues or the form would need a negative probability.
    /// One phase is the exponential.
    pub fn general(alpha: &[f64], t: &[Vec<f64>]) -> Result<Stages, String> {
        let n = alpha.len();
        if n == 0 {
            return Err("alpha is empty".into());
        }
        if n > MAX_GENERAL_PHASES {
            return Err(format!(
                "{n} phases: at most {MAX_GENERAL_PHASES} are allowed"
            ));
        }
        if t.len() != n {
            return Err(format!("alpha has {n} entries but T has {} rows", t.len()));
        }
        if let Some((i, r)) = t.iter().enumerate().find(|(_, r)| r.len() != n) {
            return Err(format!(
                "row {} of T has {} entries: T is {n} × {n}",
                i + 1,
                r.len()
            ));
        }
        if let Some((i, a)) = alpha
            .iter()
            .enumerate()
            .find(|(_, a)| !(a.is_finite() && **a >= 0.0))
        {
            return Err(format!(
                "alpha[{}] = {a} is not a probability (finite, >= 0)",
                i + 1
            ));
        }
        let sum: f64 = alpha.iter().sum();
        if (sum - 1.0).abs() > 1e-9 {
            return Err(format!(
                "alpha sums to {sum}, not 1 (an atom at time 0 is not supported)"
            ));
        }
        let mut exit = vec![0.0; n];
        for (i, row) in t.iter().enumerate() {
            for (j, &x) in row.iter().enumerate() {
                let ok = x.is_finite() && if i == j { x < 0.0 } else { x >= 0.0 };
                if !ok {
                    let want = if i == j {
                        "a diagonal entry is minus a phase's total rate: finite and < 0"
                    } else {
                        "an off-diagonal entry is a transition rate: finite and >= 0"
                    };
                    return Err(format!("T[{}][{}] = {x}: {want}", i + 1, j + 1));
                }
            }
            let row_sum: f64 = row.iter().sum();
            if row_sum > 1e-12 * -row[i] {
                return Err(format!(
                    "row {} of T sums to {row_sum} > 0 (a row's sum is minus the phase's exit rate)",
                    i + 1
                ));
            }
            exit[i] = (-row_sum).max(0.0);
        }
        // absorption is certain iff every phase leads to an exit
        let mut exits = exit.iter().map(|&x| x > 0.0).collect::<Vec<_>>();
        loop {
            let before = exits.iter().filter(|&&x| x).count();
            for i in 0..n {
                if !exits[i] && (0..n).any(|j| j != i && t[i][j] > 0.0 && exits[j]) {
                    exits[i] = true;
                }
            }
            if exits.iter().filter(|&&x| x).count() == before {
                break;
            }
        }
        let trapped: Vec<String> = (0..n)
            .filter(|&i| !exits[i])
            .map(|i| (i + 1).to_string())
            .collect();
        if !trapped.is_empty() {
            return Err(format!(
                "absorption is not certain: no path from phase(s) {} leads to an exit (T is singular)",
                trapped.join(", ")
            ));
        }
        // topological order (Kahn, smallest index first)
        let mut indegree: Vec<usize> = (0..n)
            .map(|j| (0..n).filter(|&i| i != j && t[i][j] > 0.0).count())
            .collect();
        let mut order = Vec::with_capacity(n);
        let mut placed = vec![false; n];
        while let Some(i) = (0..n).find(|&i| !placed[i] && indegree[i] == 0) {
            placed[i] = true;
            order.push(i);
            for j in 0..n {
                if j != i && t[i][j] > 0.0 {
                    indegree[j] -= 1;
                }
            }
        }
        if order.len() < n {
            let cycle: Vec<String> = (0..n)
                .filter(|&i| !placed[i])
                .map(|i| (i + 1).to_string())
                .collect();
            // a cyclic law: its canonical acyclic form, when it has one
            let alpha: Vec<f64> = alpha.iter().map(|a| a / sum).collect();
            let (beta, mu) = canonical_form(&alpha, t, &exit).map_err(|why| {
                format!(
                    "the transitions between phases {} form a cycle, and {why}; btrel's \
                     chains are acyclic, so such a law is not supported",
                    cycle.join(", ")
                )
            })?;
            let m = mu.len();
            if m == 1 {
                return Stages::erlang(1, mu[0]);
            }
            let mut tt = vec![0.0; m * m];
            for (i, &r) in mu.iter().enumerate() {
                tt[i * m + i] = -r;
                if i + 1 < m {
                    tt[i * m + i + 1] = r;
                }
            }
            let mut exit = vec![0.0; m];
            exit[m - 1] = mu[m - 1];
            let g = General {
                alpha: beta,
                t: tt,
                exit,
                q: mu,
            };
            return Ok(Stages {
                len: 0,
                rates: [0.0; MAX_STAGES],
                counts: [0; MAX_STAGES],
                general: Some(intern_general(g)),
            });
        }
        if n == 1 {
            return Stages::erlang(1, -t[0][0]);
        }
        let g = General {
            alpha: order.iter().map(|&i| alpha[i] / sum).collect(),
            t: order
                .iter()
                .flat_map(|&i| order.iter().map(move |&j| t[i][j]))
                .collect(),
            exit: order.iter().map(|&i| exit[i]).collect(),
            q: order.iter().map(|&i| -t[i][i]).collect(),
        };
        Ok(Stages {
            len: 0,
            rates: [0.0; MAX_STAGES],
            counts: [0; MAX_STAGES],
            general: Some(intern_general(g)),
        })
    }

    /// The hyperexponential law: with probability `p_i` an exponential of
    /// rate `rate_i`, for each `(p_i, rate_i)` (a phase-type law with a
    /// diagonal `T`). Fails as [`Stages::general`] does.
    pub fn hyperexponential(branches: &[(f64, f64)]) -> Result<Stages, String> {
        if let Some((i, r)) = branches
            .iter()
            .map(|b| b.1)
            .enumerate()
            .find(|(_, r)| !(r.is_finite() && *r > 0.0))
        {
            return Err(format!(
                "branch {}: rate {r} is not a finite number > 0",
                i + 1
            ));
        }
        let n = branches.len();
        let t: Vec<Vec<f64>> = (0..n)
            .map(|i| {
                (0..n)
                    .map(|j| if i == j { -branches[i].1 } else { 0.0 })
                    .collect()
            })
            .collect();
        let alpha: Vec<f64> = branches.iter().map(|b| b.0).collect();
        Stages::general(&alpha, &t)
    }

    /// The `(p, rate)` branches of a two-branch hyperexponential law, in
    /// the order they were written; None for any other law.
    pub fn as_two_branches(&self) -> Option<[(f64, f64); 2]> {
        let g = self.as_general().filter(|g| g.is_hyperexponential())?;
        (g.len() == 2).then(|| [(g.alpha()[0], -g.t(0, 0)), (g.alpha()[1], -g.t(1, 1))])
    }

    /// The general phase-type law, when this is one (not a sum of stages).
    pub fn as_general(&self) -> Option<&'static General> {
        self.general
    }

    /// The distinct rates with their counts.
    pub fn iter(&self) -> impl Iterator<Item = (f64, u32)> + '_ {
        (0..usize::from(self.len)).map(|i| (self.rates[i], self.counts[i]))
    }

    /// The largest total rate of a phase (1/s): how fast the law's density
    /// can change.
    pub fn fastest(&self) -> f64 {
        match self.general {
            Some(g) => g.q.iter().copied().fold(0.0, f64::max),
            None => self.iter().map(|(r, _)| r).fold(0.0, f64::max),
        }
    }

    /// Total number of stages (of phases, for a general law).
    pub fn phases(&self) -> u32 {
        match self.general {
            Some(g) => g.len() as u32,
            None => self.iter().map(|(_, c)| c).sum(),
        }
    }

    /// `Some((k, rate))` when every stage has the same rate (an Erlang-k).
    pub fn as_erlang(&self) -> Option<(u32, f64)> {
        (self.len == 1).then(|| (self.counts[0], self.rates[0]))
    }

    /// The rate of every stage, stage by stage (decreasing); empty for a
    /// general law (see [`Stages::as_general`]).
    pub fn series(&self) -> Vec<f64> {
        self.iter()
            .flat_map(|(r, c)| std::iter::repeat_n(r, c as usize))
            .collect()
    }

    /// Mean `Σ count/rate`; `α (−T)⁻¹ 1` for a general law.
    pub fn mean(&self) -> f64 {
        match self.general {
            Some(g) => g.moments().0,
            None => self.iter().map(|(r, c)| f64::from(c) / r).sum(),
        }
    }

    /// `E[e^{θX}]`: `Π (rate/(rate − θ))^count`; `α (−T − θI)⁻¹ t` for a
    /// general law (back substitution: `T` is upper triangular). `∞` where
    /// it diverges (`θ` at or past a rate).
    pub fn mgf(&self, theta: f64) -> f64 {
        match self.general {
            Some(g) => g.mgf(theta),
            None => self
                .iter()
                .map(|(r, c)| {
                    if theta < r {
                        (r / (r - theta)).powi(c as i32)
                    } else {
                        f64::INFINITY
                    }
                })
                .product(),
        }
    }

    /// Variance `Σ count/rate²`; `2 α (−T)⁻² 1 − mean²` for a general law.
    pub fn variance(&self) -> f64 {
        match self.general {
            Some(g) => {
                let (m1, m2) = g.moments();
                (m2 - m1 * m1).max(0.0)
            }
            None => self.iter().map(|(r, c)| f64::from(c) / (r * r)).sum(),
        }
    }

    /// `P(sum ≤ t)`: the regularized lower incomplete gamma function for an
    /// Erlang; the transient solution of the stage chain otherwise.
    pub fn cdf(&self, t: f64) -> f64 {
        if t.is_nan() || t <= 0.0 {
            return 0.0;
        }
        if t.is_infinite() {
            return 1.0;
        }
        if let Some((k, rate)) = self.as_erlang() {
            return erlang_cdf(k, rate, t);
        }
        let chain = self.chain();
        crate::solve::transient::transient(&chain, &[t], 1e-14)
            .first()
            .map_or(0.0, |p| p.success)
            .clamp(0.0, 1.0)
    }

    /// The stages as a phase chain: stage `i` enters `i + 1`, the last
    /// exits to Success (a general law: its phases, exits to Success).
    pub fn chain(&self) -> crate::solve::chain::PhaseChain {
        if let Some(g) = self.general {
            return g.chain();
        }
        let mut c = crate::solve::chain::PhaseChain::default();
        let series = self.series();
        for (i, &r) in series.iter().enumerate() {
            let p = c.push_phase();
            debug_assert_eq!(p, i);
            if i + 1 < series.len() {
                c.transitions[i].push((i + 1, r));
            } else {
                c.exit_success[i] = r;
            }
        }
        c.initial.push((0, 1.0));
        c
    }

    /// One draw of the sum.
    pub fn sample<R: Rng + ?Sized>(&self, rng: &mut R) -> f64 {
        if let Some(g) = self.general {
            return g.sample(rng);
        }
        self.iter()
            .map(|(r, c)| {
                if c <= 16 {
                    (0..c).map(|_| -> f64 { Exp1.sample(rng) }).sum::<f64>() / r
                } else {
                    // shape c ≥ 17 and scale 1/r > 0 are valid parameters
                    Gamma::new(f64::from(c), 1.0 / r).map_or(f64::from(c) / r, |g| g.sample(rng))
                }
            })
            .sum()
    }
}

/// `ln Γ(n + 1) = ln n!` by summation (exact enough for n ≤ MAX_PHASES).
fn ln_factorial(n: u32) -> f64 {
    (2..=n).map(|i| f64::from(i).ln()).sum()
}

/// The canonical acyclic form (Cumani's CF1) of a cyclic `PH(α, T)`, exit
/// rates `exit`: `(β, μ)`, the law of entering a series of phases of rates
/// `μ₁ ≤ μ₂ ≤ … ≤ μₘ` (exit from the last) at phase `j` with probability
/// `β_j`. The phases that `α` never leads to are dropped first; the `μ` are
/// minus the eigenvalues of (the rest of) `T`, and `β = α P` for the `P`
/// with `T P = P S` (`S` the series' sub-generator), built column by column
/// from the last one, `P_{·m} = exit/μₘ`, `P_{·j−1} = (T + μ_j I) P_{·j} /
/// μ_{j−1}` (no solve: Cayley–Hamilton closes the recursion). Then `α e^{Tt}
/// 1 = β e^{St} 1`: the same law. Fails (saying why) when an eigenvalue is
/// not real, a `β_j` is negative (no such form of this order) or the
/// moments `k! α(−T)^{−k}1` of the two forms, `k ≤ 2m − 1` (which determine
/// a law of order m; compared scaled by powers of the mean, up to the first
/// one that overflows or underflows, at least 3 of them), differ by more
/// than 1e-8 relative (rounding).
fn canonical_form(
    alpha: &[f64],
    t: &[Vec<f64>],
    exit: &[f64],
) -> Result<(Vec<f64>, Vec<f64>), String> {
    let n = alpha.len();
    // the phases α leads to
    let mut seen: Vec<bool> = alpha.iter().map(|&a| a > 0.0).collect();
    let mut stack: Vec<usize> = (0..n).filter(|&i| seen[i]).collect();
    while let Some(i) = stack.pop() {
        for j in 0..n {
            if j != i && t[i][j] > 0.0 && !seen[j] {
                seen[j] = true;
                stack.push(j);
            }
        }
    }
    let keep: Vec<usize> = (0..n).filter(|&i| seen[i]).collect();
    let m = keep.len();
    let a: Vec<f64> = keep.iter().map(|&i| alpha[i]).collect();
    let tm: Vec<Vec<f64>> = keep
        .iter()
        .map(|&i| keep.iter().map(|&j| t[i][j]).collect())
        .collect();
    let ex: Vec<f64> = keep.iter().map(|&i| exit[i]).collect();
    let eig = faer::Mat::<f64>::from_fn(m, m, |i, j| tm[i][j])
        .eigenvalues()
        .map_err(|e| format!("its eigenvalues could not be computed ({e:?})"))?;
    let mut mu = Vec::with_capacity(m);
    for z in &eig {
        if z.im.abs() > 1e-9 * z.re.abs().max(f64::MIN_POSITIVE) {
            return Err(format!(
                "T has the complex eigenvalue {} ± {}i (such a law has no acyclic form of \
                 the same order)",
                z.re,
                z.im.abs()
            ));
        }
        if z.re >= 0.0 || z.re.is_nan() {
            return Err(format!("T has the eigenvalue {} (not < 0)", z.re));
        }
        mu.push(-z.re);
    }
    mu.sort_by(f64::total_cmp);
    // P column by column from the last
    let mut cols: Vec<Vec<f64>> = vec![Vec::new(); m];
    cols[m - 1] = ex.iter().map(|e| e / mu[m - 1]).collect();
    for j in (1..m).rev() {
        let c = &cols[j];
        let next: Vec<f64> = (0..m)
            .map(|i| {
                let tc: f64 = (0..m).map(|k| tm[i][k] * c[k]).sum();
                (tc + mu[j] * c[i]) / mu[j - 1]
            })
            .collect();
        cols[j - 1] = next;
    }
    let mut beta: Vec<f64> = cols
        .iter()
        .map(|c| a.iter().zip(c).map(|(x, y)| x * y).sum())
        .collect();
    if let Some((j, b)) = beta.iter().enumerate().find(|(_, b)| **b < -1e-9) {
        return Err(format!(
            "its canonical acyclic form of order {m} would start in phase {} with \
             probability {b} < 0 (no acyclic form of that order)",
            j + 1
        ));
    }
    for b in &mut beta {
        *b = b.max(0.0);
    }
    let total: f64 = beta.iter().sum();
    if (total - 1.0).abs() >= 1e-8 || total.is_nan() {
        return Err(format!(
            "its canonical acyclic form's probabilities sum to {total}, not 1 (rounding)"
        ));
    }
    for b in &mut beta {
        *b /= total;
    }
    // check: the moments of both forms, as `α(−T)^{−k}1 / mean^{k−1}` (the
    // k! is common to both; the scaling keeps them finite far longer)
    let ph = moments_dense(&a, &tm, 2 * m - 1)
        .ok_or_else(|| "T is singular (absorption is not certain)".to_string())?;
    let cf: Vec<f64> = {
        // S upper bidiagonal: (−S)⁻¹ v by back substitution
        let mut v = vec![1.0; m];
        let mut out = Vec::with_capacity(2 * m - 1);
        let mut scale = 1.0;
        for _ in 1..2 * m {
            let mut w = vec![0.0; m];
            for i in (0..m).rev() {
                let later = if i + 1 < m { mu[i] * w[i + 1] } else { 0.0 };
                w[i] = (v[i] + later) / mu[i];
            }
            v = w.iter().map(|x| x / scale).collect();
            out.push(beta.iter().zip(&v).map(|(x, y)| x * y).sum::<f64>());
            scale = ph[0];
        }
        out
    };
    let mut checked = 0;
    for (k, (x, y)) in ph.iter().zip(&cf).enumerate() {
        // beyond a moment that overflows or underflows there is nothing to compare
        if !(x.is_normal() && y.is_normal()) {
            break;
        }
        if (x - y).abs() > 1e-8 * x.abs().max(y.abs()) {
            return Err(format!(
                "its canonical acyclic form's moment {} differs by {:.1e} relative (rounding)",
                k + 1,
                (x - y).abs() / x.abs().max(y.abs())
            ));
        }
        checked += 1;
    }
    if checked < (2 * m - 1).min(3) {
        return Err("its canonical acyclic form's moments could not be checked".into());
    }
    Ok((beta, mu))
}

/// `α(−T)^{−k} 1 / mean^{k−1}` for `k = 1..=count` (`mean = α(−T)⁻¹1`, the
/// first), by Gaussian elimination with partial
/// pivoting; `None` if `T` is singular.
fn moments_dense(alpha: &[f64], t: &[Vec<f64>], count: usize) -> Option<Vec<f64>> {
    let m = alpha.len();
    // LU of −T
    let mut lu: Vec<Vec<f64>> = t.iter().map(|r| r.iter().map(|x| -x).collect()).collect();
    let mut piv: Vec<usize> = (0..m).collect();
    for c in 0..m {
        let p = (c..m).max_by(|&i, &j| lu[i][c].abs().total_cmp(&lu[j][c].abs()))?;
        if lu[p][c] == 0.0 {
            return None;
        }
        lu.swap(c, p);
        piv.swap(c, p);
        let pivot_row = lu[c].clone();
        for row in lu.iter_mut().skip(c + 1) {
            let f = row[c] / pivot_row[c];
            row[c] = f;
            for (x, p) in row.iter_mut().zip(&pivot_row).skip(c + 1) {
                *x -= f * p;
            }
        }
    }
    let solve = |b: &[f64]| {
        let mut y: Vec<f64> = piv.iter().map(|&i| b[i]).collect();
        for i in 0..m {
            for j in 0..i {
                y[i] -= lu[i][j] * y[j];
            }
        }
        for i in (0..m).rev() {
            for j in i + 1..m {
                y[i] -= lu[i][j] * y[j];
            }
            y[i] /= lu[i][i];
        }
        y
    };
    let mut v = vec![1.0; m];
    let mut out = Vec::with_capacity(count);
    let mut scale = 1.0;
    for _ in 1..=count {
        v = solve(&v).iter().map(|x| x / scale).collect();
        out.push(alpha.iter().zip(&v).map(|(a, x)| a * x).sum::<f64>());
        // the mean scales the later moments
        scale = out[0];
    }
    Some(out)
}

/// The interned copy of `s` (the same reference for equal stages).
pub fn intern(s: Stages) -> &'static Stages {
    use std::collections::HashMap;
    use std::sync::{Mutex, OnceLock};
    type Key = ([u64; MAX_STAGES], [u32; MAX_STAGES], u8, usize);
    static TABLE: OnceLock<Mutex<HashMap<Key, &'static Stages>>> = OnceLock::new();
    // a general law is interned itself: its address identifies it
    let general = s.general.map_or(0, |g| std::ptr::from_ref(g) as usize);
    let key: Key = (s.rates.map(f64::to_bits), s.counts, s.len, general);
    let mut table = TABLE
        .get_or_init(Default::default)
        .lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner);
    table.entry(key).or_insert_with(|| Box::leak(Box::new(s)))
}

/// The interned copy of `g` (the same reference for equal laws).
fn intern_general(g: General) -> &'static General {
    use std::collections::HashMap;
    use std::sync::{Mutex, OnceLock};
    static TABLE: OnceLock<Mutex<HashMap<Vec<u64>, &'static General>>> = OnceLock::new();
    let key: Vec<u64> = std::iter::once(g.alpha.len() as u64)
        .chain(g.alpha.iter().chain(&g.t).map(|x| x.to_bits()))
        .collect();
    let mut table = TABLE
        .get_or_init(Default::default)
        .lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner);
    table.entry(key).or_insert_with(|| Box::leak(Box::new(g)))
}

impl General {
    /// Number of phases.
    pub fn len(&self) -> usize {
        self.alpha.len()
    }

    /// Whether there is no phase (never: a law has at least two).
    pub fn is_empty(&self) -> bool {
        self.alpha.is_empty()
    }

    /// The initial probabilities, in the stored order.
    pub fn alpha(&self) -> &[f64] {
        &self.alpha
    }

    /// `T_ij` in the stored order.
    pub fn t(&self, i: usize, j: usize) -> f64 {
        self.t[i * self.len() + j]
    }

    /// Whether `T` is diagonal: a hyperexponential law (rates `−T_ii`).
    pub fn is_hyperexponential(&self) -> bool {
        let n = self.len();
        (0..n).all(|i| (0..n).all(|j| i == j || self.t(i, j) == 0.0))
    }

    /// `(E[X], E[X²])`: `m = (−T)⁻¹ 1` and `s = (−T)⁻¹ m` by back
    /// substitution (`T` is upper triangular), `E[X] = α m`, `E[X²] = 2 α s`.
    fn moments(&self) -> (f64, f64) {
        let n = self.len();
        let (mut m, mut s) = (vec![0.0; n], vec![0.0; n]);
        for i in (0..n).rev() {
            let later = |v: &[f64]| (i + 1..n).map(|j| self.t(i, j) * v[j]).sum::<f64>();
            m[i] = (1.0 + later(&m)) / self.q[i];
            s[i] = (m[i] + later(&s)) / self.q[i];
        }
        let m1 = self.alpha.iter().zip(&m).map(|(a, x)| a * x).sum();
        let m2 = 2.0 * self.alpha.iter().zip(&s).map(|(a, x)| a * x).sum::<f64>();
        (m1, m2)
    }

    /// `E[e^{θX}] = α x` with `(−T − θI) x = t` (`t` the exit rates), by
    /// back substitution; `∞` when `θ` reaches a phase's total rate.
    fn mgf(&self, theta: f64) -> f64 {
        let n = self.len();
        if self.q.iter().any(|&q| theta >= q) {
            return f64::INFINITY;
        }
        let mut x = vec![0.0; n];
        for i in (0..n).rev() {
            let later: f64 = (i + 1..n).map(|j| self.t(i, j) * x[j]).sum();
            x[i] = (self.exit[i] + later) / (self.q[i] - theta);
        }
        self.alpha.iter().zip(&x).map(|(a, v)| a * v).sum()
    }

    /// The law's phase chain (exits to Success).
    fn chain(&self) -> crate::solve::chain::PhaseChain {
        let n = self.len();
        let mut c = crate::solve::chain::PhaseChain::default();
        for i in 0..n {
            c.push_phase();
            c.exit_success[i] = self.exit[i];
            for j in i + 1..n {
                let r = self.t(i, j);
                if r > 0.0 {
                    c.transitions[i].push((j, r));
                }
            }
        }
        c.initial = (0..n)
            .filter(|&i| self.alpha[i] > 0.0)
            .map(|i| (i, self.alpha[i]))
            .collect();
        c
    }

    /// One draw: the phases walked from one drawn by `α`, an exponential
    /// sojourn of rate `−T_ii` in each, the next phase (or the exit) drawn
    /// in proportion to its rate.
    fn sample<R: Rng + ?Sized>(&self, rng: &mut R) -> f64 {
        let n = self.len();
        let last = (0..n).rev().find(|&i| self.alpha[i] > 0.0).unwrap_or(0);
        let u: f64 = rng.random();
        let mut acc = 0.0;
        let mut i = last;
        for (j, &a) in self.alpha.iter().enumerate() {
            acc += a;
            if a > 0.0 && u < acc {
                i = j;
                break;
            }
        }
        let mut time = 0.0;
        loop {
            let e: f64 = Exp1.sample(rng);
            time += e / self.q[i];
            let u = rng.random::<f64>() * self.q[i];
            let mut acc = 0.0;
            let next = (i + 1..n).find(|&j| {
                acc += self.t(i, j);
                self.t(i, j) > 0.0 && u < acc
            });
            match next {
                Some(j) => i = j,
                None => return time,
            }
        }
    }
}

/// `P(Erlang(k, rate) ≤ t) = 1 − Σ_{j<k} e^{−x} x^j / j!`, `x = rate·t`;
/// for `x` small the complementary sum `Σ_{j≥k}` (no cancellation).
pub fn erlang_cdf(k: u32, rate: f64, t: f64) -> f64 {
    if t <= 0.0 {
        return 0.0;
    }
    let x = rate * t;
    if !x.is_finite() {
        return 1.0;
    }
    let ln_x = x.ln();
    let term = |j: u32| (-x + f64::from(j) * ln_x - ln_factorial(j)).exp();
    if x < f64::from(k) {
        // Σ_{j≥k}: terms decrease once j > x
        let mut sum = 0.0;
        let mut tj = term(k);
        let mut j = k;
        while tj > sum * 1e-17 && j < k + 100_000 {
            sum += tj;
            j += 1;
            tj *= x / f64::from(j);
        }
        sum.clamp(0.0, 1.0)
    } else {
        let mut q = 0.0;
        let mut tj = (-x).exp();
        if tj == 0.0 {
            // underflow of e^{−x}: terms from their logarithms
            q = (0..k).map(term).sum();
        } else {
            for j in 0..k {
                q += tj;
                tj *= x / f64::from(j + 1);
            }
        }
        (1.0 - q).clamp(0.0, 1.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// MGFs against closed forms: a series multiplies its stages'
    /// `r/(r − θ)`; a hyperexponential mixes them.
    #[test]
    fn mgfs_are_their_closed_forms() {
        let theta = 0.4;
        let h = Stages::hypoexponential(&[1.0, 2.0, 0.5]).unwrap();
        let expect = (1.0 / 0.6) * (2.0 / 1.6) * (0.5 / 0.1);
        assert!((h.mgf(theta) - expect).abs() < 1e-12 * expect);
        assert_eq!(h.mgf(0.5), f64::INFINITY);
        let x = Stages::hyperexponential(&[(0.3, 1.0), (0.7, 3.0)]).unwrap();
        let expect = 0.3 * 1.0 / 0.6 + 0.7 * 3.0 / 2.6;
        assert!((x.mgf(theta) - expect).abs() < 1e-12, "{}", x.mgf(theta));
        assert_eq!(x.mgf(1.0), f64::INFINITY);
        assert!((x.mgf(0.0) - 1.0).abs() < 1e-15);
    }

    #[test]
    fn erlang_cdf_closed_forms() {
        // Erlang-2 of rate 1: 1 − e^{−t}(1 + t)
        for t in [0.01f64, 0.5, 1.0, 3.0, 40.0] {
            let want: f64 = 1.0 - (-t).exp() * (1.0 + t);
            assert!((erlang_cdf(2, 1.0, t) - want).abs() < 1e-15, "{t}");
        }
        // Erlang-1 is the exponential
        assert!((erlang_cdf(1, 2.0, 0.3) - (1.0 - (-0.6f64).exp())).abs() < 1e-15);
        // far tail: 1 − e^{−800}·… rounds to 1, deep head to ~0
        assert_eq!(erlang_cdf(3, 1.0, 800.0), 1.0);
        assert!(erlang_cdf(50, 1.0, 1.0) < 1e-60);
    }

    #[test]
    fn hypoexponential_cdf_matches_the_two_rate_closed_form() {
        // Hypo(a, b): 1 − (b e^{−at} − a e^{−bt}) / (b − a)
        let (a, b) = (1.0f64, 3.0f64);
        let s = Stages::hypoexponential(&[a, b]).expect("valid");
        for t in [0.1, 0.7, 2.0, 6.0] {
            let want = 1.0 - (b * (-a * t).exp() - a * (-b * t).exp()) / (b - a);
            assert!(
                (s.cdf(t) - want).abs() < 1e-11,
                "{t}: {} vs {want}",
                s.cdf(t)
            );
        }
        assert!((s.mean() - (1.0 / a + 1.0 / b)).abs() < 1e-15);
    }

    #[test]
    fn equal_rates_merge_and_limits_hold() {
        let s = Stages::hypoexponential(&[2.0, 2.0, 2.0]).expect("valid");
        assert_eq!(s.as_erlang(), Some((3, 2.0)));
        assert_eq!(s, Stages::erlang(3, 2.0).expect("valid"));
        assert!(Stages::erlang(MAX_PHASES + 1, 1.0).is_err());
        assert!(Stages::hypoexponential(&[1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0, 9.0]).is_err());
        assert!(Stages::hypoexponential(&[1.0, -2.0]).is_err());
        assert!(Stages::erlang(0, 1.0).is_err());
    }

    #[test]
    fn a_two_phase_cycle_becomes_a_series_of_its_eigen_rates() {
        // T = [[−2, 1], [1, −3]]: characteristic polynomial λ² + 5λ + 5,
        // rates (5 ∓ √5)/2; mean α(−T)⁻¹1 with (−T)⁻¹ = [[3, 1], [1, 2]]/5
        let s = Stages::general(&[0.3, 0.7], &[vec![-2.0, 1.0], vec![1.0, -3.0]]).expect("valid");
        let g = s.as_general().expect("general");
        let (lo, hi) = ((5.0 - 5f64.sqrt()) / 2.0, (5.0 + 5f64.sqrt()) / 2.0);
        assert!((-g.t(0, 0) - lo).abs() < 1e-12 && (-g.t(1, 1) - hi).abs() < 1e-12);
        assert!((g.t(0, 1) - lo).abs() < 1e-12 && g.t(1, 0) == 0.0);
        let mean = (0.3 * 4.0 + 0.7 * 3.0) / 5.0;
        assert!((s.mean() - mean).abs() < 1e-12, "{}", s.mean());
        // the Duration stays small: the law is interned
        assert_eq!(std::mem::size_of::<crate::tree::Duration>(), 24);
    }
}
