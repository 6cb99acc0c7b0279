//! Fréchet distance between two feature sets modelled as Gaussians (Dowson and Landau 1982;
//! the FID of Heusel et al. 2017 when the features are InceptionV3 pool3):
//! `d^2 = |mu1 - mu2|^2 + tr(S1) + tr(S2) - 2 tr((S1 S2)^(1/2))`, with `S` the unbiased sample
//! covariance (`numpy.cov`, divisor n - 1), as pytorch-fid's `calculate_frechet_distance`.
//!
//! pytorch-fid takes `scipy.linalg.sqrtm(S1 S2)` of a non-symmetric product and keeps its real
//! part. Here `tr((S1 S2)^(1/2))` is the sum of square roots of the eigenvalues of `S1 S2`, which
//! are those of the symmetric PSD matrix `S1^(1/2) S2 S1^(1/2)`; both routes below only take
//! symmetric eigendecompositions and clamp the tiny negative eigenvalues rounding leaves to 0:
//! - from statistics ([`frechet_distance_from_stats`]): `S1 = V L V^T`, then the eigenvalues of
//!   `L^(1/2) V^T S2 V L^(1/2)` (a d x d problem);
//! - from features ([`frechet_distance`]) with no more samples than dimensions (plus one):
//!   with centred data `X1`, `X2`, `S1 S2 = X1^T (X1 X2^T) X2 / ((n1-1)(n2-1))`, whose non-zero
//!   eigenvalues are those of `K K^T / ((n1-1)(n2-1))`, `K = X1 X2^T`: the trace is the nuclear
//!   norm of K over `sqrt((n1-1)(n2-1))`. Each `Xc` is first reduced to the `(n-1) x d` matrix
//!   `Z` with `Z^T Z = Xc^T Xc` (a Householder reflection taking the all-ones direction, which
//!   centring annihilates, to the last row, which is dropped), so `K K^T` has no structural
//!   zero eigenvalue. This is exact for rank-deficient covariances (n < d, the usual case
//!   with small evaluation sets), where sqrtm of a singular product loses digits.
//!
//! The square root amplifies rounding near zero: an eigenvalue that should be 0 but comes out
//! as `1e-16 lambda_max` adds `1e-8 sqrt(lambda_max)`. Each route is used where its matrix has
//! no structural zero eigenvalue; statistics of rank-deficient sets passed to
//! [`frechet_distance_from_stats`] are accurate to about 1e-8 relative. Rounding can leave a
//! distance of `-1e-12` between identical sets; results are clamped at 0.

use serde::{Deserialize, Serialize};

use crate::error::{MetricsError, Result};
use crate::linalg::{mul_abt, sym_eigen_vectors, sym_eigenvalues};

/// Mean and covariance of a feature set, what FID tools cache (pytorch-fid's `mu`, `sigma`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct FeatureStats {
    /// Number of samples the statistics come from.
    pub n: usize,
    /// Mean feature vector (length d).
    pub mean: Vec<f64>,
    /// Unbiased covariance (divisor n - 1), row-major d x d.
    pub cov: Vec<f64>,
}

impl FeatureStats {
    /// Mean and unbiased covariance of at least two feature vectors of equal length.
    pub fn from_features(set: &[Vec<f64>]) -> Result<Self> {
        let d = check_set("feature set", set, None)?;
        let n = set.len();
        let (mean, centred) = centre(set, d);
        let mut cov = mul_abt_transposed(&centred, n, d);
        let denom = (n - 1) as f64;
        for v in &mut cov {
            *v /= denom;
        }
        Ok(Self { n, mean, cov })
    }

    /// Feature dimension d.
    #[must_use]
    pub fn dim(&self) -> usize {
        self.mean.len()
    }

    fn validate(&self, what: &'static str) -> Result<()> {
        let d = self.mean.len();
        if self.cov.len() != d * d {
            return Err(MetricsError::InvalidArgument(format!(
                "{what}: covariance has {} values for a mean of length {d}",
                self.cov.len()
            )));
        }
        if self.mean.iter().chain(&self.cov).any(|v| !v.is_finite()) {
            return Err(MetricsError::NonFinite { what });
        }
        Ok(())
    }
}

/// Checks that `set` has at least two vectors, all of length `expected` (or of the first's).
/// Returns the dimension.
pub(crate) fn check_set(
    what: &'static str,
    set: &[Vec<f64>],
    expected: Option<usize>,
) -> Result<usize> {
    if set.len() < 2 {
        return Err(MetricsError::TooFewSamples {
            what,
            min: 2,
            got: set.len(),
        });
    }
    let d = expected.unwrap_or(set[0].len());
    for (index, v) in set.iter().enumerate() {
        if v.len() != d {
            return Err(MetricsError::FeatureDimMismatch {
                set: what,
                index,
                expected: d,
                got: v.len(),
            });
        }
        if v.iter().any(|x| !x.is_finite()) {
            return Err(MetricsError::NonFinite { what });
        }
    }
    if d == 0 {
        return Err(MetricsError::InvalidArgument(format!(
            "{what}: empty feature vectors"
        )));
    }
    Ok(d)
}

/// Column means and the centred data (row-major n x d).
fn centre(set: &[Vec<f64>], d: usize) -> (Vec<f64>, Vec<f64>) {
    let n = set.len() as f64;
    let mut mean = vec![0.0; d];
    for v in set {
        for (m, x) in mean.iter_mut().zip(v) {
            *m += x;
        }
    }
    for m in &mut mean {
        *m /= n;
    }
    let centred = set
        .iter()
        .flat_map(|v| v.iter().zip(&mean).map(|(x, m)| x - m))
        .collect();
    (mean, centred)
}

/// For centred `xc` (n x d, n >= 2, columns summing to 0): the first n - 1 rows of `H xc`, with
/// `H` the Householder reflection swapping `1 / sqrt(n)` (all ones) and the last unit vector.
/// The dropped last row is `1^T xc / sqrt(n) = 0`, so the result `Z` has `Z^T Z = xc^T xc`.
fn drop_centring_direction(xc: &[f64], n: usize, d: usize) -> Vec<f64> {
    let u = 1.0 / (n as f64).sqrt();
    let v = |i: usize| if i == n - 1 { u - 1.0 } else { u };
    let vtv = 2.0 - 2.0 * u;
    let mut vtx = vec![0.0; d];
    for i in 0..n {
        let vi = v(i);
        for (acc, x) in vtx.iter_mut().zip(&xc[i * d..(i + 1) * d]) {
            *acc += vi * x;
        }
    }
    let coef = 2.0 * u / vtv;
    let mut z = Vec::with_capacity((n - 1) * d);
    for i in 0..n - 1 {
        z.extend(
            xc[i * d..(i + 1) * d]
                .iter()
                .zip(&vtx)
                .map(|(x, w)| x - coef * w),
        );
    }
    z
}

/// `X^T X` for row-major `X` of n x d.
fn mul_abt_transposed(x: &[f64], n: usize, d: usize) -> Vec<f64> {
    let xt = transpose(x, n, d);
    mul_abt(&xt, d, &xt, d, n)
}

fn transpose(x: &[f64], rows: usize, cols: usize) -> Vec<f64> {
    let mut t = vec![0.0; rows * cols];
    for r in 0..rows {
        for c in 0..cols {
            t[c * rows + r] = x[r * cols + c];
        }
    }
    t
}

fn sum_sqrt_clamped(eigenvalues: &[f64]) -> f64 {
    eigenvalues.iter().map(|&v| v.max(0.0).sqrt()).sum()
}

fn squared_distance(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| (x - y) * (x - y)).sum()
}

/// Fréchet distance between two feature sets (rows are samples), each of at least 2 vectors of
/// the same dimension. Picks the cheaper exact route: the sample-space one when either set has
/// no more samples than dimensions, the statistics one otherwise.
pub fn frechet_distance(a: &[Vec<f64>], b: &[Vec<f64>]) -> Result<f64> {
    let d = check_set("first feature set", a, None)?;
    check_set("second feature set", b, Some(d))?;
    if a.len().min(b.len()) <= d + 1 {
        Ok(frechet_distance_sample_space(a, b, d)?.max(0.0))
    } else {
        frechet_distance_from_stats(
            &FeatureStats::from_features(a)?,
            &FeatureStats::from_features(b)?,
        )
    }
}

/// The sample-space route (see the module docs); exact for any n, accurate when n <= d + 1.
pub(crate) fn frechet_distance_sample_space(
    a: &[Vec<f64>],
    b: &[Vec<f64>],
    d: usize,
) -> Result<f64> {
    let (n1, n2) = (a.len(), b.len());
    let (mu1, x1) = centre(a, d);
    let (mu2, x2) = centre(b, d);
    let tr1 = x1.iter().map(|v| v * v).sum::<f64>() / (n1 - 1) as f64;
    let tr2 = x2.iter().map(|v| v * v).sum::<f64>() / (n2 - 1) as f64;
    let (r1, r2) = (n1 - 1, n2 - 1);
    let z1 = drop_centring_direction(&x1, n1, d); // r1 x d
    let z2 = drop_centring_direction(&x2, n2, d); // r2 x d
    let k = mul_abt(&z1, r1, &z2, r2, d); // r1 x r2
    let gram = if r1 <= r2 {
        mul_abt(&k, r1, &k, r1, r2) // K K^T, r1 x r1
    } else {
        let kt = transpose(&k, r1, r2);
        mul_abt(&kt, r2, &kt, r2, r1) // K^T K, r2 x r2
    };
    let m = r1.min(r2);
    let tr_sqrt = sum_sqrt_clamped(&sym_eigenvalues(&symmetrised(gram, m), m)?)
        / (((n1 - 1) * (n2 - 1)) as f64).sqrt();
    Ok(squared_distance(&mu1, &mu2) + tr1 + tr2 - 2.0 * tr_sqrt)
}

/// Fréchet distance between two cached statistics of the same dimension.
pub fn frechet_distance_from_stats(a: &FeatureStats, b: &FeatureStats) -> Result<f64> {
    a.validate("first statistics")?;
    b.validate("second statistics")?;
    let d = a.dim();
    if b.dim() != d {
        return Err(MetricsError::FeatureDimMismatch {
            set: "second statistics",
            index: 0,
            expected: d,
            got: b.dim(),
        });
    }
    let s1 = symmetrised(a.cov.clone(), d);
    let s2 = symmetrised(b.cov.clone(), d);
    // S1 = V L V^T; rows of `vecs` are the eigenvectors (V^T).
    let (vals, vecs) = sym_eigen_vectors(&s1, d)?;
    let t = mul_abt(&vecs, d, &s2, d, d); // V^T S2 (S2 symmetric)
    let mut m = mul_abt(&t, d, &vecs, d, d); // V^T S2 V
    let root: Vec<f64> = vals.iter().map(|v| v.max(0.0).sqrt()).collect();
    for i in 0..d {
        for j in 0..d {
            m[i * d + j] *= root[i] * root[j];
        }
    }
    let tr_sqrt = sum_sqrt_clamped(&sym_eigenvalues(&symmetrised(m, d), d)?);
    let tr1: f64 = (0..d).map(|i| s1[i * d + i]).sum();
    let tr2: f64 = (0..d).map(|i| s2[i * d + i]).sum();
    Ok((squared_distance(&a.mean, &b.mean) + tr1 + tr2 - 2.0 * tr_sqrt).max(0.0))
}

/// `(M + M^T) / 2`, removing the asymmetry rounding leaves in products.
fn symmetrised(mut m: Vec<f64>, n: usize) -> Vec<f64> {
    for i in 0..n {
        for j in i + 1..n {
            let v = 0.5 * (m[i * n + j] + m[j * n + i]);
            m[i * n + j] = v;
            m[j * n + i] = v;
        }
    }
    m
}

#[cfg(test)]
mod tests {
    use super::*;

    fn set(rows: &[&[f64]]) -> Vec<Vec<f64>> {
        rows.iter().map(|r| r.to_vec()).collect()
    }

    #[test]
    fn one_dimensional_gaussians() {
        // 1-D: d^2 = (m1 - m2)^2 + (s1 - s2)^2.
        let a = set(&[&[0.0], &[2.0]]); // mean 1, var 2
        let b = set(&[&[3.0], &[11.0]]); // mean 7, var 32
        let want = 36.0 + (2f64.sqrt() - 32f64.sqrt()).powi(2);
        let got = frechet_distance(&a, &b).unwrap();
        assert!((got - want).abs() < 1e-12, "{got} vs {want}");
        let stats = frechet_distance_from_stats(
            &FeatureStats::from_features(&a).unwrap(),
            &FeatureStats::from_features(&b).unwrap(),
        )
        .unwrap();
        assert!((stats - want).abs() < 1e-12, "{stats} vs {want}");
    }

    #[test]
    fn shifting_a_set_adds_the_squared_shift() {
        let a = set(&[
            &[0.0, 1.0, 2.0],
            &[1.0, 0.5, 0.0],
            &[2.0, 2.0, 1.0],
            &[0.5, 0.0, 3.0],
        ]);
        let shift = [1.0, -2.0, 0.5];
        let b: Vec<Vec<f64>> = a
            .iter()
            .map(|v| v.iter().zip(&shift).map(|(x, s)| x + s).collect())
            .collect();
        let got = frechet_distance(&a, &b).unwrap();
        assert!((got - 5.25).abs() < 1e-10, "{got}");
        assert!(frechet_distance(&a, &a).unwrap().abs() < 1e-10);
    }

    #[test]
    fn both_routes_agree_where_both_are_well_posed() {
        // n1 - 1 = d: S1 has full rank (stats route) and K K^T has no structural zero.
        let a: Vec<Vec<f64>> = (0..4)
            .map(|i| {
                (0..3)
                    .map(|j| ((i * 7 + j * 3) % 5) as f64 + 0.1 * (i * j) as f64)
                    .collect()
            })
            .collect();
        let b: Vec<Vec<f64>> = (0..6)
            .map(|i| {
                (0..3)
                    .map(|j| ((i * 5 + j * 2) % 7) as f64 * 0.5 + 0.05 * (i * i) as f64)
                    .collect()
            })
            .collect();
        let stats = frechet_distance_from_stats(
            &FeatureStats::from_features(&a).unwrap(),
            &FeatureStats::from_features(&b).unwrap(),
        )
        .unwrap();
        let sample = frechet_distance_sample_space(&a, &b, 3).unwrap();
        assert!(
            (stats - sample).abs() < 1e-12 * stats,
            "{stats} vs {sample}"
        );
    }

    #[test]
    fn householder_reduction_keeps_the_scatter_matrix() {
        let set: Vec<Vec<f64>> = (0..5)
            .map(|i| vec![i as f64, (i * i) as f64 * 0.3])
            .collect();
        let (_, xc) = centre(&set, 2);
        let z = drop_centring_direction(&xc, 5, 2);
        let (s_x, s_z) = (mul_abt_transposed(&xc, 5, 2), mul_abt_transposed(&z, 4, 2));
        for (p, q) in s_x.iter().zip(&s_z) {
            assert!((p - q).abs() < 1e-12, "{s_x:?} vs {s_z:?}");
        }
    }

    #[test]
    fn rejects_bad_sets() {
        let one = set(&[&[1.0, 2.0]]);
        let two = set(&[&[1.0, 2.0], &[0.0, 1.0]]);
        let ragged = set(&[&[1.0, 2.0], &[0.0]]);
        let nan = set(&[&[1.0, f64::NAN], &[0.0, 1.0]]);
        assert!(matches!(
            frechet_distance(&one, &two),
            Err(MetricsError::TooFewSamples { .. })
        ));
        assert!(matches!(
            frechet_distance(&two, &ragged),
            Err(MetricsError::FeatureDimMismatch { .. })
        ));
        assert!(matches!(
            frechet_distance(&two, &nan),
            Err(MetricsError::NonFinite { .. })
        ));
    }
}
