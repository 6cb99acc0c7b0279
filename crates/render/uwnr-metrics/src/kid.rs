//! Kernel Inception Distance (Bińkowski, Sutherland, Arbel, Gretton 2018, "Demystifying MMD
//! GANs"): the unbiased estimate of the squared maximum mean discrepancy with the cubic
//! polynomial kernel `k(x, y) = (x . y / d + 1)^3`,
//! `MMD^2 = sum_{i != j} k(x_i, x_j) / (m (m-1)) + sum_{i != j} k(y_i, y_j) / (m (m-1))
//!        - 2 sum_{i, j} k(x_i, y_j) / m^2`,
//! averaged over random subsets of m samples drawn without replacement from each set, as
//! torch-fidelity (`kid_subsets`, `kid_subset_size`) and clean-fid (`kernel_distance`) do; the
//! reported spread is the population standard deviation over subsets (`np.std`).
//!
//! Like clean-fid, the subset size is `min(subset_size, n1, n2)` (torch-fidelity refuses sets
//! smaller than the subset size instead). Subsets come from a ChaCha8 generator seeded with
//! `seed`, so values are reproducible here but the subsets differ from numpy's; with the subset
//! size equal to both set sizes every subset is the whole set and the result is exact.

use rand::SeedableRng;
use rand::seq::index::sample;
use rand_chacha::ChaCha8Rng;

use crate::error::{MetricsError, Result};
use crate::frechet::check_set;
use crate::linalg::mul_abt;

/// torch-fidelity's and clean-fid's default number of subsets.
pub const KID_SUBSETS: usize = 100;
/// torch-fidelity's and clean-fid's default subset size.
pub const KID_SUBSET_SIZE: usize = 1000;
/// Kernel-matrix entries (all three blocks) up to which the whole kernel is computed once and
/// subsets index into it (256 MiB of f64); larger sets compute each subset's kernels afresh.
const KID_FULL_KERNEL_MAX_ENTRIES: usize = 32 << 20;

/// The cubic polynomial kernel on a Gram entry: `(g / d + 1)^3`.
fn poly3(gram: f64, d: usize) -> f64 {
    (gram / d as f64 + 1.0).powi(3)
}

/// KID `(mean, std)` over `subsets` subsets of `min(subset_size, n1, n2)` samples.
///
/// Both sets need at least 2 vectors of the same dimension; `subsets` and `subset_size` at
/// least 1 and 2.
pub fn kid(
    a: &[Vec<f64>],
    b: &[Vec<f64>],
    subsets: usize,
    subset_size: usize,
    seed: u64,
) -> Result<(f64, f64)> {
    kid_with_budget(
        a,
        b,
        subsets,
        subset_size,
        seed,
        KID_FULL_KERNEL_MAX_ENTRIES,
    )
}

pub(crate) fn kid_with_budget(
    a: &[Vec<f64>],
    b: &[Vec<f64>],
    subsets: usize,
    subset_size: usize,
    seed: u64,
    max_entries: usize,
) -> Result<(f64, f64)> {
    let d = check_set("first feature set", a, None)?;
    check_set("second feature set", b, Some(d))?;
    if subsets == 0 || subset_size < 2 {
        return Err(MetricsError::InvalidArgument(format!(
            "KID needs at least 1 subset of at least 2 samples, got {subsets} of {subset_size}"
        )));
    }
    let (n1, n2) = (a.len(), b.len());
    let m = subset_size.min(n1).min(n2);
    let flat = |s: &[Vec<f64>]| -> Vec<f64> { s.iter().flatten().copied().collect() };
    let (fa, fb) = (flat(a), flat(b));
    let kernel = |g: Vec<f64>| -> Vec<f64> { g.into_iter().map(|v| poly3(v, d)).collect() };
    let full = if n1 * n1 + n2 * n2 + n1 * n2 <= max_entries {
        Some((
            kernel(mul_abt(&fa, n1, &fa, n1, d)),
            kernel(mul_abt(&fb, n2, &fb, n2, d)),
            kernel(mul_abt(&fa, n1, &fb, n2, d)),
        ))
    } else {
        None
    };

    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut values = Vec::with_capacity(subsets);
    for _ in 0..subsets {
        let ia = sample(&mut rng, n1, m).into_vec();
        let ib = sample(&mut rng, n2, m).into_vec();
        let mmd2 = match &full {
            Some((kaa, kbb, kab)) => {
                let within = |k: &[f64], n: usize, idx: &[usize]| -> f64 {
                    let mut s = 0.0;
                    for (p, &i) in idx.iter().enumerate() {
                        for (q, &j) in idx.iter().enumerate() {
                            if p != q {
                                s += k[i * n + j];
                            }
                        }
                    }
                    s
                };
                let mut cross = 0.0;
                for &i in &ia {
                    for &j in &ib {
                        cross += kab[i * n2 + j];
                    }
                }
                unbiased_mmd2(within(kaa, n1, &ia), within(kbb, n2, &ib), cross, m)
            }
            None => {
                let pick = |f: &[f64], idx: &[usize]| -> Vec<f64> {
                    idx.iter()
                        .flat_map(|&i| f[i * d..(i + 1) * d].iter().copied())
                        .collect()
                };
                let (sa, sb) = (pick(&fa, &ia), pick(&fb, &ib));
                let off_diagonal = |g: Vec<f64>| -> f64 {
                    g.iter()
                        .enumerate()
                        .filter(|(k, _)| k / m != k % m)
                        .map(|(_, &v)| poly3(v, d))
                        .sum()
                };
                let cross: f64 = mul_abt(&sa, m, &sb, m, d)
                    .iter()
                    .map(|&v| poly3(v, d))
                    .sum();
                unbiased_mmd2(
                    off_diagonal(mul_abt(&sa, m, &sa, m, d)),
                    off_diagonal(mul_abt(&sb, m, &sb, m, d)),
                    cross,
                    m,
                )
            }
        };
        values.push(mmd2);
    }
    let k = values.len() as f64;
    let mean = values.iter().sum::<f64>() / k;
    let std = (values.iter().map(|v| (v - mean) * (v - mean)).sum::<f64>() / k).sqrt();
    Ok((mean, std))
}

fn unbiased_mmd2(kxx_off: f64, kyy_off: f64, kxy: f64, m: usize) -> f64 {
    let mf = m as f64;
    (kxx_off + kyy_off) / (mf * (mf - 1.0)) - 2.0 * kxy / (mf * mf)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sets() -> (Vec<Vec<f64>>, Vec<Vec<f64>>) {
        let a = (0..12)
            .map(|i| (0..4).map(|j| ((i * 3 + j * 5) % 7) as f64 / 7.0).collect())
            .collect();
        let b = (0..15)
            .map(|i| {
                (0..4)
                    .map(|j| ((i * 2 + j * 3) % 5) as f64 / 4.0 - 0.2)
                    .collect()
            })
            .collect();
        (a, b)
    }

    #[test]
    fn both_kernel_paths_agree_and_are_seeded() {
        let (a, b) = sets();
        let full = kid_with_budget(&a, &b, 20, 6, 7, usize::MAX).unwrap();
        let per_subset = kid_with_budget(&a, &b, 20, 6, 7, 0).unwrap();
        assert!((full.0 - per_subset.0).abs() < 1e-12 && (full.1 - per_subset.1).abs() < 1e-12);
        assert_eq!(
            kid(&a, &b, 20, 6, 7).unwrap(),
            kid(&a, &b, 20, 6, 7).unwrap()
        );
        assert_ne!(
            kid(&a, &b, 20, 6, 7).unwrap(),
            kid(&a, &b, 20, 6, 8).unwrap()
        );
        assert!(full.1 > 0.0);
    }

    #[test]
    fn whole_set_subsets_have_no_spread_and_identical_sets_have_zero_mean_cross_term() {
        let (a, _) = sets();
        // Same set on both sides, each subset the whole set: within and cross sums share all
        // off-diagonal terms, leaving -2 / m^2 sum_i k(x_i, x_i) + ... exactly computable.
        let (mean, std) = kid(&a, &a, 3, 100, 1).unwrap();
        // Subsets are permutations of the whole set: equal up to summation order.
        assert!(std < 1e-12, "{std}");
        let m = a.len() as f64;
        let diag: f64 = a
            .iter()
            .map(|x| poly3(x.iter().map(|v| v * v).sum(), 4))
            .sum();
        let all: f64 = a
            .iter()
            .flat_map(|x| {
                a.iter()
                    .map(move |y| poly3(x.iter().zip(y).map(|(p, q)| p * q).sum(), 4))
            })
            .sum();
        let want = 2.0 * (all - diag) / (m * (m - 1.0)) - 2.0 * all / (m * m);
        assert!((mean - want).abs() < 1e-12, "{mean} vs {want}");
    }

    #[test]
    fn rejects_bad_arguments() {
        let (a, b) = sets();
        assert!(kid(&a, &b, 0, 10, 1).is_err());
        assert!(kid(&a, &b, 10, 1, 1).is_err());
        assert!(kid(&a[..1], &b, 10, 10, 1).is_err());
    }
}
