//! General dense numerics of the fits: non-negative least squares, least squares by
//! Householder QR, the inverse of a small symmetric positive definite matrix, matrix
//! products and small linear systems. The Allan and PSD noise fits, the calibration fits and
//! the model workflow share them.

/// Dense product of two row-major matrices.
pub fn mat_mul(a: &[Vec<f64>], b: &[Vec<f64>]) -> Vec<Vec<f64>> {
    let cols = b.first().map_or(0, Vec::len);
    a.iter()
        .map(|row| {
            let mut out = vec![0.0; cols];
            for (x, brow) in row.iter().zip(b) {
                for (o, y) in out.iter_mut().zip(brow) {
                    *o += x * y;
                }
            }
            out
        })
        .collect()
}

/// [`nnls`] on `g` with every column scaled to unit norm first (bases that span many decades
/// would otherwise be ill-conditioned), the solution mapped back to the original columns.
pub fn nnls_normalised(mut g: Vec<Vec<f64>>, b: &[f64]) -> Vec<f64> {
    let p = g.first().map_or(0, Vec::len);
    let norms: Vec<f64> = (0..p)
        .map(|j| {
            g.iter()
                .map(|r| r[j] * r[j])
                .sum::<f64>()
                .sqrt()
                .max(f64::MIN_POSITIVE)
        })
        .collect();
    for row in &mut g {
        row.iter_mut().zip(&norms).for_each(|(v, n)| *v /= n);
    }
    nnls(&g, b).iter().zip(&norms).map(|(t, n)| t / n).collect()
}

/// Lawson–Hanson non-negative least squares, min ||G x - b|| subject to x >= 0 (Lawson &
/// Hanson, "Solving Least Squares Problems", 1974, ch. 23). `g` is row-major with p columns.
///
/// A problem with more rows than columns is first reduced to its p x p triangle by
/// Householder QR ([`nnls_by_columns`], on the columns copied out once): the active-set
/// iterations then cost nothing per row.
pub fn nnls(g: &[Vec<f64>], b: &[f64]) -> Vec<f64> {
    let p = g.first().map_or(0, Vec::len);
    if g.len() > p {
        let mut columns: Vec<f64> = (0..p)
            .flat_map(|j| g.iter().map(move |row| row[j]))
            .collect();
        return nnls_by_columns(&mut columns, &mut b.to_vec());
    }
    let bnorm = b.iter().map(|v| v * v).sum::<f64>().sqrt();
    lawson_hanson(g, b, bnorm)
}

/// [`nnls`] of a design held column by column: `a` holds its p columns of `b.len()` rows
/// one after another. Both are overwritten by the Householder reduction to the p x p
/// triangle `R` of `a = Q R` and `c`, the first p entries of `Q^T b`: for every x,
/// `||a x - b||^2 = ||R x - c||^2 + ||(Q^T b)[p..]||^2`, so the constrained problem has the
/// same solution on `R`. On contiguous columns each reflection is a pass over memory.
pub fn nnls_by_columns(a: &mut [f64], b: &mut [f64]) -> Vec<f64> {
    let n = b.len();
    if n == 0 {
        return Vec::new();
    }
    let p = a.len() / n;
    let bnorm = b.iter().map(|v| v * v).sum::<f64>().sqrt();
    if n <= p {
        let g: Vec<Vec<f64>> = (0..n)
            .map(|i| (0..p).map(|j| a[j * n + i]).collect())
            .collect();
        return lawson_hanson(&g, b, bnorm);
    }
    for c in 0..p {
        let (done, rest) = a.split_at_mut((c + 1) * n);
        let v = &mut done[c * n + c..];
        let norm = dot(v, v).sqrt();
        if norm == 0.0 {
            continue;
        }
        let alpha = if v[0] > 0.0 { -norm } else { norm };
        v[0] -= alpha;
        let vnorm2 = dot(v, v);
        if vnorm2 == 0.0 {
            v[0] += alpha;
            continue;
        }
        let reflect = |x: &mut [f64]| {
            let s = 2.0 * dot(v, x) / vnorm2;
            x.iter_mut().zip(v.iter()).for_each(|(x, a)| *x -= s * a);
        };
        for other in rest.chunks_exact_mut(n) {
            reflect(&mut other[c..]);
        }
        reflect(&mut b[c..]);
        // The reflection takes the column to `alpha` on the diagonal and 0 below it.
        v[0] = alpha;
    }
    let r: Vec<Vec<f64>> = (0..p)
        .map(|i| {
            (0..p)
                .map(|j| if j >= i { a[j * n + i] } else { 0.0 })
                .collect()
        })
        .collect();
    lawson_hanson(&r, &b[..p], bnorm)
}

/// The active-set iterations of [`nnls`]; `bnorm` is the norm of the original right-hand
/// side, which sets the tolerance on the gradient.
fn lawson_hanson(g: &[Vec<f64>], b: &[f64], bnorm: f64) -> Vec<f64> {
    let p = g.first().map_or(0, Vec::len);
    let mut x = vec![0.0; p];
    let mut passive = vec![false; p];
    let tol = 1e-12 * bnorm.max(f64::MIN_POSITIVE);
    for _ in 0..(3 * p + 3) {
        let w = gradient(g, b, &x);
        let candidate = (0..p)
            .filter(|&j| !passive[j] && w[j] > tol)
            .max_by(|&i, &j| w[i].total_cmp(&w[j]));
        let Some(t) = candidate else { break };
        passive[t] = true;
        for _ in 0..(3 * p + 3) {
            let cols: Vec<usize> = (0..p).filter(|&j| passive[j]).collect();
            let z = lstsq_columns(g, b, &cols, p);
            if cols.iter().all(|&j| z[j] > 0.0) {
                x = z;
                break;
            }
            // Step from x towards z until the first passive variable hits zero.
            let alpha = cols
                .iter()
                .filter(|&&j| z[j] <= 0.0)
                .map(|&j| x[j] / (x[j] - z[j]))
                .fold(f64::INFINITY, f64::min);
            for j in 0..p {
                x[j] += alpha * (z[j] - x[j]);
                if passive[j] && x[j] <= tol {
                    x[j] = 0.0;
                    passive[j] = false;
                }
            }
        }
    }
    x
}

/// `G^T (b - G x)`, the negative gradient of the half squared residual.
fn gradient(g: &[Vec<f64>], b: &[f64], x: &[f64]) -> Vec<f64> {
    let mut w = vec![0.0; x.len()];
    for (row, bi) in g.iter().zip(b) {
        let r = bi - row.iter().zip(x).map(|(a, v)| a * v).sum::<f64>();
        for (wj, a) in w.iter_mut().zip(row) {
            *wj += a * r;
        }
    }
    w
}

/// Unconstrained least squares on the columns `cols` of `g` (Householder QR); the result has
/// length `p` with zeros outside `cols`.
fn lstsq_columns(g: &[Vec<f64>], b: &[f64], cols: &[usize], p: usize) -> Vec<f64> {
    let mut a: Vec<Vec<f64>> = g
        .iter()
        .map(|r| cols.iter().map(|&j| r[j]).collect())
        .collect();
    let mut rhs = b.to_vec();
    let sol = householder_solve(&mut a, &mut rhs);
    let mut x = vec![0.0; p];
    for (c, &j) in cols.iter().enumerate() {
        x[j] = sol[c];
    }
    x
}

/// The dot product of two equally long slices (the shorter one's length otherwise), in
/// eight interleaved partial sums: the processor keeps them in vector registers, where a
/// single running sum would serialise every addition on its latency. The regressor tests'
/// Cholesky factors are made of such products: a model run on a CI-size record took 17 % less
/// processor time.
pub fn dot(a: &[f64], b: &[f64]) -> f64 {
    let n = a.len().min(b.len());
    let (a8, b8) = (a[..n].chunks_exact(8), b[..n].chunks_exact(8));
    let tail: f64 = a8
        .remainder()
        .iter()
        .zip(b8.remainder())
        .map(|(u, v)| u * v)
        .sum();
    let mut lanes = [0.0; 8];
    for (x, y) in a8.zip(b8) {
        for k in 0..8 {
            lanes[k] += x[k] * y[k];
        }
    }
    ((lanes[0] + lanes[4]) + (lanes[1] + lanes[5]))
        + ((lanes[2] + lanes[6]) + (lanes[3] + lanes[7]))
        + tail
}

/// Least-squares solution of `a x = rhs` by Householder QR (a is m x k, m >= k, row-major;
/// both are overwritten). Columns that are numerically dependent get 0.
// Dense small-matrix algebra reads best with explicit indices.
#[allow(clippy::needless_range_loop)]
pub fn householder_solve(a: &mut [Vec<f64>], rhs: &mut [f64]) -> Vec<f64> {
    let m = a.len();
    let k = a.first().map_or(0, Vec::len);
    householder_triangularise(a, rhs);
    let mut x = vec![0.0; k];
    for c in (0..k.min(m)).rev() {
        let s: f64 = ((c + 1)..k).map(|j| a[c][j] * x[j]).sum();
        x[c] = if a[c][c].abs() > 1e-13 {
            (rhs[c] - s) / a[c][c]
        } else {
            0.0
        };
    }
    x
}

/// Householder reflections applied to `a` (m x k, row-major) and `rhs` alike, column by
/// column, until `a`'s first k rows hold the triangle R of `a = Q R` (below its diagonal, what
/// the reflections leave is not zeroed) and `rhs` holds `Q^T rhs`. A column with nothing left
/// to reflect is skipped.
// Dense small-matrix algebra reads best with explicit indices.
#[allow(clippy::needless_range_loop)]
fn householder_triangularise(a: &mut [Vec<f64>], rhs: &mut [f64]) {
    let m = a.len();
    let k = a.first().map_or(0, Vec::len);
    let mut v = vec![0.0; m];
    for c in 0..k.min(m) {
        let norm = (c..m).map(|i| a[i][c] * a[i][c]).sum::<f64>().sqrt();
        if norm == 0.0 {
            continue;
        }
        let alpha = if a[c][c] > 0.0 { -norm } else { norm };
        for i in c..m {
            v[i] = a[i][c];
        }
        v[c] -= alpha;
        let vnorm2: f64 = v[c..].iter().map(|x| x * x).sum();
        if vnorm2 == 0.0 {
            continue;
        }
        for col in c..k {
            let s: f64 = (c..m).map(|i| v[i] * a[i][col]).sum::<f64>() * 2.0 / vnorm2;
            (c..m).for_each(|i| a[i][col] -= s * v[i]);
        }
        let s: f64 = (c..m).map(|i| v[i] * rhs[i]).sum::<f64>() * 2.0 / vnorm2;
        (c..m).for_each(|i| rhs[i] -= s * v[i]);
    }
}

/// Inverse of a small symmetric positive definite matrix by Cholesky; None when singular.
// Dense small-matrix algebra reads best with explicit indices.
#[allow(clippy::needless_range_loop)]
pub fn invert_spd(h: &[Vec<f64>]) -> Option<Vec<Vec<f64>>> {
    let k = h.len();
    let mut l = vec![vec![0.0; k]; k];
    for i in 0..k {
        for j in 0..=i {
            let s: f64 = h[i][j] - (0..j).map(|p| l[i][p] * l[j][p]).sum::<f64>();
            if i == j {
                if s <= 1e-12 * h[i][i].max(f64::MIN_POSITIVE) {
                    return None;
                }
                l[i][i] = s.sqrt();
            } else {
                l[i][j] = s / l[j][j];
            }
        }
    }
    // Solve L L^T X = I column by column.
    let mut inv = vec![vec![0.0; k]; k];
    for col in 0..k {
        let mut y = vec![0.0; k];
        for i in 0..k {
            let e = if i == col { 1.0 } else { 0.0 };
            y[i] = (e - (0..i).map(|p| l[i][p] * y[p]).sum::<f64>()) / l[i][i];
        }
        for i in (0..k).rev() {
            let s: f64 = ((i + 1)..k).map(|p| l[p][i] * inv[p][col]).sum();
            inv[i][col] = (y[i] - s) / l[i][i];
        }
    }
    Some(inv)
}

/// Inverse of a small matrix by Gauss-Jordan elimination with partial pivoting; `None` when
/// it is (numerically) singular.
pub fn inverse(m: &[Vec<f64>]) -> Option<Vec<Vec<f64>>> {
    let k = m.len();
    let mut a: Vec<Vec<f64>> = m
        .iter()
        .enumerate()
        .map(|(i, row)| {
            let mut r = row.clone();
            r.extend((0..k).map(|j| if i == j { 1.0 } else { 0.0 }));
            r
        })
        .collect();
    for c in 0..k {
        let p = (c..k).max_by(|&i, &j| a[i][c].abs().total_cmp(&a[j][c].abs()))?;
        if a[p][c].abs() < 1e-12 {
            return None;
        }
        a.swap(c, p);
        let pivot = a[c][c];
        a[c].iter_mut().for_each(|v| *v /= pivot);
        let pivot_row = a[c].clone();
        for (i, row) in a.iter_mut().enumerate() {
            if i != c {
                let f = row[c];
                row.iter_mut()
                    .zip(&pivot_row)
                    .for_each(|(v, p)| *v -= f * p);
            }
        }
    }
    Some(a.into_iter().map(|r| r[k..].to_vec()).collect())
}

/// Solve a 3×3 system by Gaussian elimination with partial pivoting; None if singular.
pub fn solve3(mut a: [[f64; 3]; 3], mut b: [f64; 3]) -> Option<[f64; 3]> {
    for col in 0..3 {
        let piv = (col..3).max_by(|&i, &j| a[i][col].abs().total_cmp(&a[j][col].abs()))?;
        if a[piv][col].abs() < 1e-300 {
            return None;
        }
        a.swap(col, piv);
        b.swap(col, piv);
        for r in col + 1..3 {
            let f = a[r][col] / a[col][col];
            let pivot_row = a[col];
            for (v, p) in a[r].iter_mut().zip(pivot_row).skip(col) {
                *v -= f * p;
            }
            b[r] -= f * b[col];
        }
    }
    let mut x = [0.0; 3];
    for r in (0..3).rev() {
        let s: f64 = (r + 1..3).map(|c| a[r][c] * x[c]).sum();
        x[r] = (b[r] - s) / a[r][r];
    }
    Some(x)
}

/// Gaussian elimination with partial pivoting; `None` if singular.
pub fn solve4(mut g: [[f64; 4]; 4], mut h: [f64; 4]) -> Option<[f64; 4]> {
    let scale = g.iter().flatten().fold(0.0f64, |m, v| m.max(v.abs()));
    for col in 0..4 {
        let pivot = (col..4).max_by(|&a, &b| g[a][col].abs().total_cmp(&g[b][col].abs()))?;
        if g[pivot][col].abs() <= 1e-12 * scale {
            return None;
        }
        g.swap(col, pivot);
        h.swap(col, pivot);
        let (done, rest) = g.split_at_mut(col + 1);
        let pivot_row = &done[col];
        for (offset, row) in rest.iter_mut().enumerate() {
            let f = row[col] / pivot_row[col];
            for (r, p) in row.iter_mut().zip(pivot_row).skip(col) {
                *r -= f * p;
            }
            h[col + 1 + offset] -= f * h[col];
        }
    }
    let mut x = [0.0; 4];
    for row in (0..4).rev() {
        let tail: f64 = (row + 1..4).map(|j| g[row][j] * x[j]).sum();
        x[row] = (h[row] - tail) / g[row][row];
    }
    Some(x)
}

/// The median of `v` (the upper of the two middle values for an even length), reordering
/// `v`; `None` when it is empty.
pub fn median_in_place(v: &mut [f64]) -> Option<f64> {
    if v.is_empty() {
        return None;
    }
    let mid = v.len() / 2;
    let (_, m, _) = v.select_nth_unstable_by(mid, f64::total_cmp);
    Some(*m)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The Householder reduction changes no solution: a design held column by column gives
    /// what the active-set iterations find on the whole design held row by row, unreduced,
    /// on any subset of columns.
    #[test]
    fn a_design_by_columns_gives_the_nnls_solution() {
        use rand::{Rng, SeedableRng, rngs::StdRng};
        for seed in 0..20u64 {
            let mut rng = StdRng::seed_from_u64(seed);
            let rows: Vec<[f64; 4]> = (0..200)
                .map(|i| {
                    let f = 0.1 * 100f64.powf(i as f64 / 199.0);
                    [1.0, 1.0 / f, 1.0 / (f * f), f * f / 100.0]
                })
                .collect();
            let b: Vec<f64> = rows
                .iter()
                .map(|r| 0.5 * r[0] + 0.02 * r[2] + 0.3 * (rng.random::<f64>() - 0.5))
                .collect();
            for columns in [vec![0, 1, 2, 3], vec![0, 2], vec![1, 3], vec![2]] {
                let g: Vec<Vec<f64>> = rows
                    .iter()
                    .map(|r| columns.iter().map(|&j| r[j]).collect())
                    .collect();
                let bnorm = b.iter().map(|v| v * v).sum::<f64>().sqrt();
                let want = lawson_hanson(&g, &b, bnorm);
                let mut a: Vec<f64> = columns
                    .iter()
                    .flat_map(|&j| rows.iter().map(move |r| r[j]))
                    .collect();
                let got = nnls_by_columns(&mut a, &mut b.clone());
                for (got, want) in got.iter().zip(&want) {
                    assert!(
                        (got - want).abs() <= 1e-9 * want.abs().max(1e-6),
                        "seed {seed}, columns {columns:?}: {got} against {want}"
                    );
                }
            }
        }
    }

    #[test]
    fn nnls_matches_a_hand_solved_case() {
        // min ||x - (1, -1)|| with x >= 0 in an identity design: x = (1, 0).
        let g = vec![vec![1.0, 0.0], vec![0.0, 1.0]];
        assert_eq!(nnls(&g, &[1.0, -1.0]), vec![1.0, 0.0]);
        // Overdetermined, interior solution = ordinary least squares (x = 2, y = 1).
        let g = vec![vec![1.0, 1.0], vec![1.0, -1.0], vec![2.0, 0.0]];
        let x = nnls(&g, &[3.0, 1.0, 4.0]);
        assert!((x[0] - 2.0).abs() < 1e-12 && (x[1] - 1.0).abs() < 1e-12);
    }

    /// On tall problems like the spectral fits' (columns 1, 1/f, 1/f^2, f^2 over two decades,
    /// noisy data with some true coefficients zero), the triangle-reduced [`nnls`] finds the
    /// optimum found by trying every support: the least squares on the support whose
    /// solution is positive with the smallest residual.
    #[test]
    fn nnls_on_a_tall_problem_is_the_best_positive_support() {
        use rand::{Rng, SeedableRng, rngs::StdRng};
        let residual = |g: &[Vec<f64>], b: &[f64], x: &[f64]| -> f64 {
            g.iter()
                .zip(b)
                .map(|(r, bi)| (bi - r.iter().zip(x).map(|(a, v)| a * v).sum::<f64>()).powi(2))
                .sum()
        };
        for seed in 0..40u64 {
            let mut rng = StdRng::seed_from_u64(seed);
            let truth: Vec<f64> = (0..4)
                .map(|_| {
                    if rng.random::<f64>() < 0.4 {
                        0.0
                    } else {
                        rng.random::<f64>()
                    }
                })
                .collect();
            let g: Vec<Vec<f64>> = (0..300)
                .map(|i| {
                    let f = 0.1 * 100f64.powf(i as f64 / 299.0);
                    vec![1.0, 1.0 / f, 1.0 / (f * f), f * f / 100.0]
                })
                .collect();
            let b: Vec<f64> = g
                .iter()
                .map(|r| {
                    let clean: f64 = r.iter().zip(&truth).map(|(a, t)| a * t).sum();
                    clean + 0.3 * (rng.random::<f64>() - 0.5)
                })
                .collect();
            let best = (0..16usize)
                .filter_map(|mask| {
                    let cols: Vec<usize> = (0..4).filter(|j| mask >> j & 1 == 1).collect();
                    let x = lstsq_columns(&g, &b, &cols, 4);
                    cols.iter()
                        .all(|&j| x[j] > 0.0)
                        .then(|| (residual(&g, &b, &x), x))
                })
                .min_by(|a, b| a.0.total_cmp(&b.0))
                .expect("the empty support is always feasible");
            let x = nnls(&g, &b);
            assert!(
                residual(&g, &b, &x) <= best.0 * (1.0 + 1e-12),
                "seed {seed}: {x:?} against {:?}",
                best.1
            );
            for (got, want) in x.iter().zip(&best.1) {
                assert!(
                    (got - want).abs() <= 1e-9 * want.abs().max(1e-6),
                    "seed {seed}"
                );
            }
        }
    }
}
