//! Linear algebra on compiled chains.
//!
//! [`solve_absorbing`] gives the absorption probabilities and the mean time
//! spent before each absorption of an [`AbsorbingChain`]. With `P` the
//! transient-to-transient jump probabilities (strictly upper triangular,
//! since states are topologically ordered), `α` the initial distribution, and
//! `b_S`, `b_F` the one-step absorption probabilities:
//!
//! * visits `v = (I − Pᵀ)⁻¹ α`, the expected number of visits to each state
//!   (the fundamental matrix `U = Σ_k Pᵏ` of (9.49) applied to `α`);
//! * absorption `h_S = (I − P)⁻¹ b_S`, `h_F = (I − P)⁻¹ b_F`, the probability of
//!   ending in Success (Failure) from each state;
//! * `P(S) = α_S + vᵀ b_S`, and the mean time accumulated on runs that end in
//!   Success, `E[T·1{S}] = Σ_{edges e: i→j} v_i p_e d_e h_S(j)` with
//!   `h_S(Success) = 1`, `h_S(Failure) = 0`: each edge's mean duration `d_e`
//!   counts for the runs that take it and then succeed. MTTS is
//!   `E[T·1{S}] / P(S)`, MTTF likewise.
//!
//! Both systems are triangular and solved by faer's sparse triangular
//! solvers in O(number of edges). faer does not report singular systems, so
//! every result is checked to be finite.

pub mod chain;
pub(crate) mod dd;
pub(crate) mod expm;
pub(crate) mod exponential;
pub(crate) mod interpolant;
pub(crate) mod quadrature;
pub mod transient;

use chain::{AbsorbingChain, Target};
use faer::sparse::linalg::triangular_solve::{
    solve_unit_lower_triangular_in_place, solve_unit_upper_triangular_in_place,
};
use faer::sparse::{SparseColMat, Triplet};
use faer::{Conj, Mat, MatMut, Par};

/// Absorption probabilities and time integrals of an absorbing chain.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Absorption {
    /// Probability of ending in Success.
    pub success: f64,
    /// Probability of ending in Failure.
    pub failure: f64,
    /// E[T · 1{Success}].
    pub time_success: f64,
    /// E[T · 1{Failure}].
    pub time_failure: f64,
}

/// Solves an acyclic absorbing chain (see the module documentation).
///
/// Returns an error message if the chain is malformed (an edge that does not
/// go forward) or the result is not finite.
pub fn solve_absorbing(chain: &AbsorbingChain) -> Result<Absorption, String> {
    let n = chain.n;
    let mut result = Absorption {
        success: chain.initial_success,
        failure: chain.initial_failure,
        time_success: 0.0,
        time_failure: 0.0,
    };
    if n == 0 {
        return Ok(result);
    }
    // I - Pᵀ (lower) and I - P (upper), unit diagonals stored explicitly
    let mut lower = Vec::with_capacity(n + chain.edges.len());
    let mut upper = Vec::with_capacity(n + chain.edges.len());
    let mut b = Mat::<f64>::zeros(n, 2);
    for i in 0..n {
        lower.push(Triplet::new(i, i, 1.0));
        upper.push(Triplet::new(i, i, 1.0));
    }
    for e in &chain.edges {
        match e.to {
            Target::State(j) => {
                if j <= e.from || j >= n {
                    return Err(format!("edge {} -> {} does not go forward", e.from, j));
                }
                lower.push(Triplet::new(j, e.from, -e.prob));
                upper.push(Triplet::new(e.from, j, -e.prob));
            }
            Target::Success => b[(e.from, 0)] += e.prob,
            Target::Failure => b[(e.from, 1)] += e.prob,
        }
    }
    let to_err = |e: faer::sparse::CreationError| format!("cannot build sparse matrix: {e:?}");
    let lower = SparseColMat::<usize, f64>::try_new_from_triplets(n, n, &lower).map_err(to_err)?;
    let upper = SparseColMat::<usize, f64>::try_new_from_triplets(n, n, &upper).map_err(to_err)?;

    let mut visits = vec![0.0; n];
    for &(i, p) in &chain.initial {
        visits[i] += p;
    }
    solve_unit_lower_triangular_in_place(
        lower.as_ref(),
        Conj::No,
        MatMut::from_column_major_slice_mut(&mut visits, n, 1),
        Par::Seq,
    );
    let direct = b.clone();
    solve_unit_upper_triangular_in_place(upper.as_ref(), Conj::No, b.as_mut(), Par::Seq);
    let (h_s, h_f) = (b.col_as_slice(0), b.col_as_slice(1));

    for i in 0..n {
        result.success += visits[i] * direct[(i, 0)];
        result.failure += visits[i] * direct[(i, 1)];
    }
    for e in &chain.edges {
        let w = visits[e.from] * e.prob * e.duration;
        let (s, f) = match e.to {
            Target::State(j) => (h_s[j], h_f[j]),
            Target::Success => (1.0, 0.0),
            Target::Failure => (0.0, 1.0),
        };
        result.time_success += w * s;
        result.time_failure += w * f;
    }
    let all = [
        result.success,
        result.failure,
        result.time_success,
        result.time_failure,
    ];
    if all.iter().any(|x| !x.is_finite()) {
        return Err(format!("non-finite result {all:?}"));
    }
    Ok(result)
}

#[cfg(test)]
mod tests {
    use super::chain::{Edge, PhaseChain};
    use super::*;

    #[test]
    fn single_exponential_phase() {
        // one phase of rate 2 splitting 0.25 / 0.75: time is Exp(2) either way
        let c = PhaseChain {
            initial: vec![(0, 1.0)],
            transitions: vec![vec![]],
            exit_success: vec![0.5],
            exit_failure: vec![1.5],
            ..Default::default()
        };
        let a = solve_absorbing(&c.jump_chain()).unwrap();
        assert!((a.success - 0.25).abs() < 1e-15);
        assert!((a.time_success / a.success - 0.5).abs() < 1e-15);
        assert!((a.time_failure / a.failure - 0.5).abs() < 1e-15);
    }

    #[test]
    fn two_paths_to_success() {
        // 0 -> 1 (p .5, d 1) -> S (d 2); 0 -> S (p .5, d 4): E[T|S] = (.5*3 + .5*4)
        let chain = AbsorbingChain {
            n: 2,
            initial: vec![(0, 1.0)],
            edges: vec![
                Edge {
                    from: 0,
                    to: Target::State(1),
                    prob: 0.5,
                    duration: 1.0,
                },
                Edge {
                    from: 0,
                    to: Target::Success,
                    prob: 0.5,
                    duration: 4.0,
                },
                Edge {
                    from: 1,
                    to: Target::Success,
                    prob: 1.0,
                    duration: 2.0,
                },
            ],
            ..Default::default()
        };
        let a = solve_absorbing(&chain).unwrap();
        assert!((a.success - 1.0).abs() < 1e-15);
        assert!((a.time_success - 3.5).abs() < 1e-14);
        assert_eq!(a.failure, 0.0);
    }

    #[test]
    fn backward_edge_is_rejected() {
        let chain = AbsorbingChain {
            n: 2,
            initial: vec![(0, 1.0)],
            edges: vec![Edge {
                from: 1,
                to: Target::State(0),
                prob: 1.0,
                duration: 1.0,
            }],
            ..Default::default()
        };
        assert!(solve_absorbing(&chain).is_err());
    }
}
