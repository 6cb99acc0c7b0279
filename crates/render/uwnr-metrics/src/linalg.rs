//! Dense f64 linear algebra the distribution distances need: `A B^T` products and the
//! symmetric eigendecomposition by Householder tridiagonalisation and the implicit QL method
//! (EISPACK `tred2` / `tql2`, in the public-domain form of the JAMA package).
//!
//! Matrices are row-major `Vec<f64>`. Eigenvectors are returned as the rows of a matrix.

use rayon::prelude::*;

use crate::error::{MetricsError, Result};

/// QL sweeps allowed per eigenvalue before giving up (LAPACK allows 30 per eigenvalue).
const MAX_QL_ITERATIONS: usize = 60;
/// Matrices at least this large spread their row updates over rayon.
const PAR_MIN_DIM: usize = 128;
/// Rows of `A` that share one pass over `B` in [`mul_abt`].
const ROW_TILE: usize = 16;

/// `A B^T` for `A` of `ra x k` and `B` of `rb x k` (both row-major): an `ra x rb` matrix.
pub(crate) fn mul_abt(a: &[f64], ra: usize, b: &[f64], rb: usize, k: usize) -> Vec<f64> {
    debug_assert_eq!(a.len(), ra * k);
    debug_assert_eq!(b.len(), rb * k);
    let mut out = vec![0.0; ra * rb];
    if ra == 0 || rb == 0 {
        return out;
    }
    let tile = |(t, dst): (usize, &mut [f64])| {
        let rows = dst.len() / rb;
        for j in 0..rb {
            let bj = &b[j * k..(j + 1) * k];
            for r in 0..rows {
                let i = t * ROW_TILE + r;
                dst[r * rb + j] = dot(&a[i * k..(i + 1) * k], bj);
            }
        }
    };
    if ra * rb * k >= 1 << 20 {
        out.par_chunks_mut(ROW_TILE * rb).enumerate().for_each(tile);
    } else {
        out.chunks_mut(ROW_TILE * rb).enumerate().for_each(tile);
    }
    out
}

/// Dot product with four partial sums (lets the compiler vectorise).
#[inline]
pub(crate) fn dot(a: &[f64], b: &[f64]) -> f64 {
    let mut acc = [0.0; 4];
    let ca = a.chunks_exact(4);
    let cb = b.chunks_exact(4);
    let (ra, rb) = (ca.remainder(), cb.remainder());
    for (x, y) in ca.zip(cb) {
        acc[0] += x[0] * y[0];
        acc[1] += x[1] * y[1];
        acc[2] += x[2] * y[2];
        acc[3] += x[3] * y[3];
    }
    let tail: f64 = ra.iter().zip(rb).map(|(x, y)| x * y).sum();
    (acc[0] + acc[1]) + (acc[2] + acc[3]) + tail
}

/// Eigenvalues (ascending order not guaranteed) of a symmetric `n x n` matrix.
pub(crate) fn sym_eigenvalues(a: &[f64], n: usize) -> Result<Vec<f64>> {
    Ok(sym_eigen(a, n, false)?.0)
}

/// Eigenvalues and eigenvectors of a symmetric `n x n` matrix: `(values, vectors)` where row
/// `i` of `vectors` (row-major `n x n`) is the unit eigenvector of `values[i]`.
pub(crate) fn sym_eigen_vectors(a: &[f64], n: usize) -> Result<(Vec<f64>, Vec<f64>)> {
    sym_eigen(a, n, true)
}

fn sym_eigen(a: &[f64], n: usize, want_vectors: bool) -> Result<(Vec<f64>, Vec<f64>)> {
    debug_assert_eq!(a.len(), n * n);
    if a.iter().any(|v| !v.is_finite()) {
        return Err(MetricsError::NonFinite {
            what: "matrix to decompose",
        });
    }
    if n == 0 {
        return Ok((Vec::new(), Vec::new()));
    }
    // `w` holds V^T: JAMA's V[r][c] lives at w[c * n + r], so JAMA's column loops run along
    // contiguous rows here. A is symmetric, so V = A initially is also w = A.
    let mut w = a.to_vec();
    let mut d = vec![0.0; n];
    let mut e = vec![0.0; n];
    tred2(&mut w, &mut d, &mut e, n, want_vectors);
    tql2(&mut w, &mut d, &mut e, n, want_vectors)?;
    Ok((d, if want_vectors { w } else { Vec::new() }))
}

/// Householder reduction to tridiagonal form (diagonal `d`, sub-diagonal `e[1..]`), with the
/// orthogonal transformation accumulated in `w` (as V^T) when `want_vectors`.
fn tred2(w: &mut [f64], d: &mut [f64], e: &mut [f64], n: usize, want_vectors: bool) {
    let ix = |r: usize, c: usize| c * n + r; // JAMA V[r][c]
    for j in 0..n {
        d[j] = w[ix(n - 1, j)];
    }
    for i in (1..n).rev() {
        let scale: f64 = d[..i].iter().map(|v| v.abs()).sum();
        let mut h = 0.0;
        if scale == 0.0 {
            e[i] = d[i - 1];
            for j in 0..i {
                d[j] = w[ix(i - 1, j)];
                w[ix(i, j)] = 0.0;
                w[ix(j, i)] = 0.0;
            }
        } else {
            for v in &mut d[..i] {
                *v /= scale;
                h += *v * *v;
            }
            let mut f = d[i - 1];
            let mut g = h.sqrt();
            if f > 0.0 {
                g = -g;
            }
            e[i] = scale * g;
            h -= f * g;
            d[i - 1] = f - g;
            e[..i].fill(0.0);
            for j in 0..i {
                f = d[j];
                w[ix(j, i)] = f;
                g = e[j] + w[ix(j, j)] * f;
                let col = &w[j * n..j * n + i]; // V[k][j] for k < i
                for k in j + 1..i {
                    g += col[k] * d[k];
                    e[k] += col[k] * f;
                }
                e[j] = g;
            }
            f = 0.0;
            for j in 0..i {
                e[j] /= h;
                f += e[j] * d[j];
            }
            let hh = f / (h + h);
            for j in 0..i {
                e[j] -= hh * d[j];
            }
            // Rank-2 update of the leading i x i block: V[k][j] -= d[j] e[k] + e[j] d[k], k >= j.
            {
                let (dd, ee) = (&d[..i], &e[..i]);
                let update = |(j, col): (usize, &mut [f64])| {
                    let (f, g) = (dd[j], ee[j]);
                    for k in j..i {
                        col[k] -= f * ee[k] + g * dd[k];
                    }
                };
                let cols = &mut w[..i * n];
                if i >= PAR_MIN_DIM {
                    cols.par_chunks_mut(n).enumerate().for_each(update);
                } else {
                    cols.chunks_mut(n).enumerate().for_each(update);
                }
            }
            for j in 0..i {
                d[j] = w[ix(i - 1, j)];
                w[ix(i, j)] = 0.0;
            }
        }
        d[i] = h;
    }

    if !want_vectors {
        // The accumulation below only moves the diagonal into d; without it, read it directly.
        for (j, dj) in d.iter_mut().enumerate() {
            *dj = w[ix(j, j)];
        }
        e[0] = 0.0;
        return;
    }

    for i in 0..n - 1 {
        w[ix(n - 1, i)] = w[ix(i, i)];
        w[ix(i, i)] = 1.0;
        let h = d[i + 1];
        if h != 0.0 {
            let (head, tail) = w.split_at_mut((i + 1) * n);
            let next = &tail[..i + 1]; // V[k][i+1], k <= i
            for k in 0..=i {
                d[k] = next[k] / h;
            }
            let dk = &d[..=i];
            let update = |col: &mut [f64]| {
                let g = dot(&next[..=i], &col[..=i]);
                for k in 0..=i {
                    col[k] -= g * dk[k];
                }
            };
            let cols = &mut head[..(i + 1) * n];
            if i >= PAR_MIN_DIM {
                cols.par_chunks_mut(n).for_each(update);
            } else {
                cols.chunks_mut(n).for_each(update);
            }
        }
        for k in 0..=i {
            w[ix(k, i + 1)] = 0.0;
        }
    }
    for j in 0..n {
        d[j] = w[ix(n - 1, j)];
        w[ix(n - 1, j)] = 0.0;
    }
    w[ix(n - 1, n - 1)] = 1.0;
    e[0] = 0.0;
}

/// Implicit QL iterations on the tridiagonal `(d, e)`; eigenvalues end in `d`, and the plane
/// rotations are applied to the rows of `w` when `want_vectors`.
fn tql2(w: &mut [f64], d: &mut [f64], e: &mut [f64], n: usize, want_vectors: bool) -> Result<()> {
    for i in 1..n {
        e[i - 1] = e[i];
    }
    e[n - 1] = 0.0;
    let mut f = 0.0;
    let mut tst1: f64 = 0.0;
    let eps = f64::EPSILON;
    for l in 0..n {
        tst1 = tst1.max(d[l].abs() + e[l].abs());
        let mut m = l;
        while m < n - 1 && e[m].abs() > eps * tst1 {
            m += 1;
        }
        if m > l {
            let mut iter = 0;
            loop {
                iter += 1;
                if iter > MAX_QL_ITERATIONS {
                    return Err(MetricsError::NoConvergence { size: n });
                }
                let mut g = d[l];
                let mut p = (d[l + 1] - g) / (2.0 * e[l]);
                let mut r = p.hypot(1.0);
                if p < 0.0 {
                    r = -r;
                }
                d[l] = e[l] / (p + r);
                d[l + 1] = e[l] * (p + r);
                let dl1 = d[l + 1];
                let mut h = g - d[l];
                for v in &mut d[l + 2..n] {
                    *v -= h;
                }
                f += h;

                p = d[m];
                let mut c = 1.0;
                let mut c2 = c;
                let mut c3 = c;
                let el1 = e[l + 1];
                let mut s = 0.0;
                let mut s2 = 0.0;
                for i in (l..m).rev() {
                    c3 = c2;
                    c2 = c;
                    s2 = s;
                    g = c * e[i];
                    h = c * p;
                    r = p.hypot(e[i]);
                    e[i + 1] = s * r;
                    s = e[i] / r;
                    c = p / r;
                    p = c * d[i] - s * g;
                    d[i + 1] = h + s * (c * g + s * d[i]);
                    if want_vectors {
                        let (lo, hi) = w.split_at_mut((i + 1) * n);
                        let vi = &mut lo[i * n..];
                        let vi1 = &mut hi[..n];
                        for (a, b) in vi.iter_mut().zip(vi1.iter_mut()) {
                            let hb = *b;
                            *b = s * *a + c * hb;
                            *a = c * *a - s * hb;
                        }
                    }
                }
                p = -s * s2 * c3 * el1 * e[l] / dl1;
                e[l] = s * p;
                d[l] = c * p;
                if e[l].abs() <= eps * tst1 {
                    break;
                }
            }
        }
        d[l] += f;
        e[l] = 0.0;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    fn random_sym(n: usize, rank: usize, seed: u64) -> Vec<f64> {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let x: Vec<f64> = (0..n * rank).map(|_| rng.random::<f64>() - 0.5).collect();
        // X X^T with X of n x rank: symmetric PSD of the given rank.
        mul_abt(&x, n, &x, n, rank)
    }

    fn check_decomposition(a: &[f64], n: usize) {
        let (vals, vecs) = sym_eigen_vectors(a, n).unwrap();
        let scale = a.iter().fold(0.0f64, |m, v| m.max(v.abs())).max(1.0);
        for i in 0..n {
            let v = &vecs[i * n..(i + 1) * n];
            // A v = lambda v
            for r in 0..n {
                let av = dot(&a[r * n..(r + 1) * n], v);
                assert!(
                    (av - vals[i] * v[r]).abs() < 1e-10 * scale,
                    "residual at {i},{r}"
                );
            }
            for j in 0..n {
                let vj = &vecs[j * n..(j + 1) * n];
                let want = if i == j { 1.0 } else { 0.0 };
                assert!((dot(v, vj) - want).abs() < 1e-10, "orthogonality {i},{j}");
            }
        }
        let mut only = sym_eigenvalues(a, n).unwrap();
        let mut with = vals.clone();
        only.sort_by(f64::total_cmp);
        with.sort_by(f64::total_cmp);
        for (x, y) in only.iter().zip(&with) {
            assert!((x - y).abs() < 1e-10 * scale, "{x} vs {y}");
        }
    }

    #[test]
    fn eigen_decomposes_full_and_rank_deficient_matrices() {
        check_decomposition(&random_sym(7, 7, 1), 7);
        check_decomposition(&random_sym(12, 3, 2), 12);
        check_decomposition(&random_sym(200, 150, 3), 200);
        check_decomposition(&[2.0], 1);
        check_decomposition(&[0.0; 16], 4);
        // Repeated eigenvalues.
        let mut eye = vec![0.0; 25];
        for i in 0..5 {
            eye[i * 5 + i] = 3.0;
        }
        check_decomposition(&eye, 5);
    }

    #[test]
    fn eigenvalues_of_a_known_matrix() {
        // [[2, 1], [1, 2]] has eigenvalues 1 and 3.
        let mut v = sym_eigenvalues(&[2.0, 1.0, 1.0, 2.0], 2).unwrap();
        v.sort_by(f64::total_cmp);
        assert!(
            (v[0] - 1.0).abs() < 1e-14 && (v[1] - 3.0).abs() < 1e-14,
            "{v:?}"
        );
    }

    #[test]
    fn rejects_nan() {
        assert!(sym_eigenvalues(&[1.0, f64::NAN, f64::NAN, 1.0], 2).is_err());
    }

    #[test]
    fn mul_abt_matches_the_definition() {
        let a: Vec<f64> = (0..2 * 35).map(|v| v as f64 * 0.5).collect(); // 35 x 2
        let b: Vec<f64> = (0..3 * 2).map(|v| 1.0 - v as f64).collect(); // 3 x 2
        let c = mul_abt(&a, 35, &b, 3, 2);
        for i in 0..35 {
            for j in 0..3 {
                let want = a[2 * i] * b[2 * j] + a[2 * i + 1] * b[2 * j + 1];
                assert_eq!(c[i * 3 + j], want);
            }
        }
    }
}
