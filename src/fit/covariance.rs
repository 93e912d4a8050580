//! The joint covariance of a leaf's estimates (p̂, μ̂, ν̂) and the 3×3
//! algebra `fit` and `--ci` need for it.
//!
//! `fit` inverts the observed information of the censored likelihood
//! ([`super`] module docs). Its diagonal gives the standard errors
//! (`ps_se`, `mu_se`, `nu_se`); its off-diagonal entries are written as
//! `fit: {cov: {ps_mu, ps_nu, mu_nu}}` for a leaf with halted episodes —
//! without halts the log-likelihood separates into a p, a μ and a ν part,
//! the information is diagonal and these are zero, so they are left out.

/// The covariances of (p̂, μ̂, ν̂) off the diagonal.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Covariance {
    pub ps_mu: f64,
    pub ps_nu: f64,
    pub mu_nu: f64,
}

/// A symmetric 3×3 matrix, rows and columns in the order (ps, mu, nu).
pub(crate) type Matrix = [[f64; 3]; 3];

impl Covariance {
    /// The off-diagonal entries of a symmetric matrix (the mean of the two
    /// triangles, which inversion leaves equal up to rounding).
    pub fn from_matrix(m: &Matrix) -> Covariance {
        Covariance {
            ps_mu: 0.5 * (m[0][1] + m[1][0]),
            ps_nu: 0.5 * (m[0][2] + m[2][0]),
            mu_nu: 0.5 * (m[1][2] + m[2][1]),
        }
    }

    /// The full matrix with standard errors `se` = (ps, mu, nu) on the
    /// diagonal (squared).
    pub fn matrix(&self, se: [f64; 3]) -> Matrix {
        [
            [se[0] * se[0], self.ps_mu, self.ps_nu],
            [self.ps_mu, se[1] * se[1], self.mu_nu],
            [self.ps_nu, self.mu_nu, se[2] * se[2]],
        ]
    }

    /// Whether every covariance is zero (a diagonal information).
    pub fn is_zero(&self) -> bool {
        self.ps_mu == 0.0 && self.ps_nu == 0.0 && self.mu_nu == 0.0
    }
}

/// Relative tolerance of [`cholesky`] for a pivot of zero (rounding in a
/// semidefinite matrix).
pub const PSD_TOLERANCE: f64 = 1e-9;

/// Why a matrix has no Cholesky factor.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum NotPsd {
    /// An entry is not finite.
    NotFinite,
    /// The matrix is not positive semidefinite: its leading `k`×`k` block
    /// (k = 1..=n) has a negative determinant or an inconsistent zero
    /// pivot.
    Block(usize),
}

/// The lower-triangular `L` with `L Lᵀ = m` of a positive semidefinite
/// `m`. A pivot within [`PSD_TOLERANCE`] of zero (relative to its diagonal
/// entry) is a zero column when the rest of its column is zero too, so a
/// singular covariance (a parameter determined by the others) still draws.
pub fn cholesky(m: &Matrix) -> Result<Matrix, NotPsd> {
    let rows: Vec<Vec<f64>> = m.iter().map(|r| r.to_vec()).collect();
    let l = cholesky_n(&rows)?;
    Ok(std::array::from_fn(|i| std::array::from_fn(|j| l[i][j])))
}

/// [`cholesky`] of a square matrix of any size (rows of equal length; a
/// row of another length is [`NotPsd::NotFinite`]).
pub(crate) fn cholesky_n(m: &[Vec<f64>]) -> Result<Vec<Vec<f64>>, NotPsd> {
    let n = m.len();
    if m.iter().any(|r| r.len() != n) || m.iter().flatten().any(|x| !x.is_finite()) {
        return Err(NotPsd::NotFinite);
    }
    let mut l = vec![vec![0.0f64; n]; n];
    for j in 0..n {
        let d = m[j][j] - (0..j).map(|k| l[j][k] * l[j][k]).sum::<f64>();
        let tol = PSD_TOLERANCE * m[j][j].abs();
        if d < -tol {
            return Err(NotPsd::Block(j + 1));
        }
        if d <= tol {
            for i in j + 1..n {
                let r = m[i][j] - (0..j).map(|k| l[i][k] * l[j][k]).sum::<f64>();
                if r.abs() > PSD_TOLERANCE.sqrt() * (m[i][i].abs() * m[j][j].abs()).sqrt() {
                    return Err(NotPsd::Block(j + 1));
                }
            }
            continue;
        }
        l[j][j] = d.sqrt();
        for i in j + 1..n {
            let r = m[i][j] - (0..j).map(|k| l[i][k] * l[j][k]).sum::<f64>();
            l[i][j] = r / l[j][j];
        }
    }
    Ok(l)
}

/// The inverse of a symmetric positive definite matrix (by its Cholesky
/// factor); None when it is not positive definite.
pub(crate) fn inverse_pd(m: &[Vec<f64>]) -> Option<Vec<Vec<f64>>> {
    let n = m.len();
    let l = cholesky_n(m).ok()?;
    if (0..n).any(|j| l[j][j].partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater)) {
        return None;
    }
    // solve L Lᵀ x = e_c column by column
    let mut inv = vec![vec![0.0; n]; n];
    #[allow(clippy::needless_range_loop)] // triangular solves: indices read clearest
    for c in 0..n {
        let mut y = vec![0.0; n];
        for i in 0..n {
            let e = if i == c { 1.0 } else { 0.0 };
            y[i] = (e - (0..i).map(|k| l[i][k] * y[k]).sum::<f64>()) / l[i][i];
        }
        for i in (0..n).rev() {
            y[i] = (y[i] - (i + 1..n).map(|k| l[k][i] * y[k]).sum::<f64>()) / l[i][i];
        }
        for i in 0..n {
            inv[i][c] = y[i];
        }
    }
    inv.iter().flatten().all(|x| x.is_finite()).then_some(inv)
}

/// Whether `m` is positive definite (every pivot of its Cholesky factor
/// positive).
pub(crate) fn positive_definite(m: &Matrix) -> bool {
    cholesky(m).is_ok_and(|l| (0..3).all(|j| l[j][j] > 0.0))
}

/// `J m J` for a diagonal `J = diag(d)`: the covariance of `(f₀(x₀), f₁(x₁),
/// f₂(x₂))` by the delta method, `d` the derivatives `f'(x)`.
pub fn scale(m: &Matrix, d: [f64; 3]) -> Matrix {
    let mut r = *m;
    for (i, row) in r.iter_mut().enumerate() {
        for (j, v) in row.iter_mut().enumerate() {
            *v *= d[i] * d[j];
        }
    }
    r
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cholesky_of_a_known_product() {
        // L = [[2,0,0],[1,3,0],[-1,0.5,1]] by hand; m = L Lᵀ
        let l = [[2.0, 0.0, 0.0], [1.0, 3.0, 0.0], [-1.0, 0.5, 1.0]];
        let mut m = [[0.0; 3]; 3];
        for i in 0..3 {
            for j in 0..3 {
                m[i][j] = (0..3).map(|k| l[i][k] * l[j][k]).sum();
            }
        }
        let got = cholesky(&m).unwrap();
        for i in 0..3 {
            for j in 0..3 {
                assert!((got[i][j] - l[i][j]).abs() < 1e-12, "{got:?}");
            }
        }
        assert!(positive_definite(&m));
    }

    #[test]
    fn inverse_of_a_known_matrix() {
        // [[4, 2], [2, 3]]⁻¹ = [[3, −2], [−2, 4]] / 8 by hand
        let inv = inverse_pd(&[vec![4.0, 2.0], vec![2.0, 3.0]]).unwrap();
        let want = [[0.375, -0.25], [-0.25, 0.5]];
        for i in 0..2 {
            for j in 0..2 {
                assert!((inv[i][j] - want[i][j]).abs() < 1e-15, "{inv:?}");
            }
        }
        assert!(inverse_pd(&[vec![1.0, 1.0], vec![1.0, 1.0]]).is_none());
    }

    #[test]
    fn semidefinite_and_indefinite() {
        // rank 1: v vᵀ with v = (1, 2, 3)
        let m = [[1.0, 2.0, 3.0], [2.0, 4.0, 6.0], [3.0, 6.0, 9.0]];
        let l = cholesky(&m).unwrap();
        assert_eq!(l[1][1], 0.0);
        assert!(!positive_definite(&m));
        // correlation 1.5: no covariance
        let bad = [[1.0, 1.5, 0.0], [1.5, 1.0, 0.0], [0.0, 0.0, 1.0]];
        assert_eq!(cholesky(&bad), Err(NotPsd::Block(2)));
        // zero variance with a non-zero covariance
        let bad = [[0.0, 0.1, 0.0], [0.1, 1.0, 0.0], [0.0, 0.0, 1.0]];
        assert_eq!(cholesky(&bad), Err(NotPsd::Block(1)));
        let nan = [[f64::NAN, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
        assert_eq!(cholesky(&nan), Err(NotPsd::NotFinite));
    }
}
