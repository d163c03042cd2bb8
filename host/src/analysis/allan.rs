//! The Allan family of deviations on phase data, after NIST SP 1065 (W. J. Riley, *Handbook of
//! Frequency Stability Analysis*, 2008), section 5.2.
//!
//! Notation: phase samples x\[0..N) every tau0 seconds (0-based here; SP 1065 counts from 1),
//! averaging factor m, tau = m tau0. Two finite-difference operators do all the work:
//!
//! - second difference `D2(i) = x[i+2m] - 2 x[i+m] + x[i]` (Allan family),
//! - third difference `D3(i) = x[i+3m] - 3 x[i+2m] + 3 x[i+m] - x[i]` (Hadamard family).
//!
//! Every estimator is a sum of squares of one of them (taken at stride m, at stride 1, as a
//! moving sum, or on a reflected extension of x), scaled. The `n` reported per tau is the
//! number of squared terms, which is Stable32's `#` column (for totdev Stable32 prints N - 2,
//! and so do we).
//!
//! Speed: the sums run over whole slices with eight independent accumulators so that they
//! auto-vectorise; long sums are split into blocks that rayon spreads over the cores together
//! with the taus. No estimator copies the input.

use super::{Deviation, Estimator};
use rayon::prelude::*;

/// Terms per parallel work item. Big enough to amortise scheduling, small enough to balance.
const BLOCK: usize = 1 << 16;

/// Order of the finite difference an estimator squares.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Order {
    /// `x[i+2m] - 2 x[i+m] + x[i]`
    Second,
    /// `x[i+3m] - 3 x[i+2m] + 3 x[i+m] - x[i]`
    Third,
}

impl Order {
    /// Span of one difference in samples, in units of m.
    fn span(self) -> usize {
        match self {
            Order::Second => 2,
            Order::Third => 3,
        }
    }

    /// The starts of the overlapping differences at factor m on `n` phase points.
    fn starts(self, n: usize, m: usize) -> usize {
        n - self.span() * m
    }
}

/// Largest averaging factor m for which `est` has at least one term on `n_phase` points
/// (0 when there is none).
///
/// - adev, oadev: `n = floor((N-1)/m) - 1`, `N - 2m` → m ≤ (N-1)/2
/// - hdev, ohdev: `n = floor((N-1)/m) - 2`, `N - 3m` → m ≤ (N-1)/3
/// - mdev, tdev: `n = N - 3m + 1` → m ≤ N/3
/// - totdev: the reflected extension allows m ≤ N-1, but like Stable32 we stop at half the
///   record, m ≤ (N-1)/2; it needs N ≥ 3 (N - 2 terms).
pub fn max_factor(est: Estimator, n_phase: usize) -> usize {
    let n1 = n_phase.saturating_sub(1);
    match est {
        Estimator::Adev | Estimator::Oadev => n1 / 2,
        Estimator::Hdev | Estimator::Ohdev => n1 / 3,
        Estimator::Mdev | Estimator::Tdev => n_phase / 3,
        Estimator::Totdev if n_phase >= 3 => n1 / 2,
        Estimator::Totdev => 0,
    }
}

/// Number of terms `est` sums at factor m on `n_phase` points (Stable32's `#`); 0 if none.
pub fn term_count(est: Estimator, n_phase: usize, m: usize) -> usize {
    terms_up_to(est, n_phase, m, max_factor(est, n_phase))
}

/// Largest averaging factor of totdev on the whole reflected extension of `n_phase` points:
/// the extension reaches N - 2 points past either end, so a centre's neighbours at ±m stay on
/// it for m ≤ N - 1 (0 when N < 3). allantools computes totdev this far; [`max_factor`] stops
/// at half the record as Stable32 does.
pub fn totdev_extension_max_factor(n_phase: usize) -> usize {
    if n_phase >= 3 { n_phase - 1 } else { 0 }
}

/// [`term_count`] with the largest factor given.
fn terms_up_to(est: Estimator, n_phase: usize, m: usize, limit: usize) -> usize {
    if m == 0 || m > limit {
        return 0;
    }
    let n1 = n_phase - 1;
    match est {
        Estimator::Adev => n1 / m - 1,
        Estimator::Oadev => n_phase - 2 * m,
        Estimator::Hdev => n1 / m - 2,
        Estimator::Ohdev => n_phase - 3 * m,
        Estimator::Mdev | Estimator::Tdev => n_phase + 1 - 3 * m,
        Estimator::Totdev => n_phase - 2,
    }
}

/// The deviation `est` of phase data `x` (interval `tau0`) at each averaging factor in
/// `factors` that the data support (at least one term); factors are sorted ascending and
/// de-duplicated, unsupported ones (0, or above [`max_factor`]) are skipped. Empty or
/// too-short input gives an empty [`Deviation`]. Taus are computed in parallel.
pub fn deviation(est: Estimator, x: &[f64], tau0: f64, factors: &[usize]) -> Deviation {
    curve(est, x, tau0, factors, max_factor(est, x.len()))
}

/// Totdev (SP 1065 eq. 25) at each factor in `factors` up to
/// [`totdev_extension_max_factor`]: past half the record, where [`deviation`] stops, the
/// centres' neighbours lie on the reflected extension on both sides. Otherwise as
/// [`deviation`]. This is the range allantools' `totdev` reports.
pub fn totdev_whole_extension(x: &[f64], tau0: f64, factors: &[usize]) -> Deviation {
    let limit = totdev_extension_max_factor(x.len());
    curve(Estimator::Totdev, x, tau0, factors, limit)
}

/// [`deviation`] with factors up to `limit` kept.
fn curve(est: Estimator, x: &[f64], tau0: f64, factors: &[usize], limit: usize) -> Deviation {
    let terms = |m: usize| terms_up_to(est, x.len(), m, limit);
    let mut ms: Vec<usize> = factors.iter().copied().filter(|&m| terms(m) > 0).collect();
    ms.sort_unstable();
    ms.dedup();
    let sums = match est {
        Estimator::Oadev => overlapping_sums(x, &ms, Order::Second),
        Estimator::Ohdev => overlapping_sums(x, &ms, Order::Third),
        _ => ms.par_iter().map(|&m| sum_of_squares(est, x, m)).collect(),
    };
    let n: Vec<usize> = ms.iter().map(|&m| terms(m)).collect();
    let dev = ms
        .iter()
        .zip(&sums)
        .zip(&n)
        .map(|((&m, &sum), &n)| scale(est, sum, n, m, tau0))
        .collect();
    Deviation {
        estimator: est,
        tau: ms.iter().map(|&m| m as f64 * tau0).collect(),
        n,
        m: ms,
        dev,
    }
}

/// The sum of squared differences behind `est` at factor m (which must have terms):
///
/// - adev: Σ_{i=0,m,2m..} D2(i)² (SP 1065 eq. 7 in phase form)
/// - oadev: Σ_{i=0}^{N-2m-1} D2(i)² (eq. 11)
/// - hdev: Σ_{i=0,m,2m..} D3(i)² (eq. 17 in phase form)
/// - ohdev: Σ_{i=0}^{N-3m-1} D3(i)² (eq. 18)
/// - mdev, tdev: Σ_{j=0}^{N-3m} (Σ_{i=j}^{j+m-1} D2(i))² (eq. 14)
/// - totdev: Σ_{i=1}^{N-2} (x*(i-m) - 2 x(i) + x*(i+m))² on the reflected extension x*
///   (eq. 25, §5.2.11)
fn sum_of_squares(est: Estimator, x: &[f64], m: usize) -> f64 {
    match est {
        Estimator::Adev => sum_sq(x, m, Order::Second, m),
        Estimator::Oadev => sum_sq(x, m, Order::Second, 1),
        Estimator::Hdev => sum_sq(x, m, Order::Third, m),
        Estimator::Ohdev => sum_sq(x, m, Order::Third, 1),
        Estimator::Mdev | Estimator::Tdev => sum_sq_moving(x, m),
        Estimator::Totdev => sum_sq_reflected(x, m),
    }
}

/// Deviation from the sum of n squared differences at tau = m tau0:
///
/// - AVAR = sum / (2 n tau²) (adev, oadev, totdev; SP 1065 eqs. 7, 11, 25)
/// - HVAR = sum / (6 n tau²) (hdev, ohdev; eqs. 17, 18)
/// - MVAR = sum / (2 m² n tau²) (mdev; eq. 14); TDEV = tau / sqrt(3) MDEV (eq. 15)
fn scale(est: Estimator, sum: f64, n: usize, m: usize, tau0: f64) -> f64 {
    let tau = m as f64 * tau0;
    let denom = 2.0 * n as f64 * tau * tau;
    let var = match est {
        Estimator::Adev | Estimator::Oadev | Estimator::Totdev => sum / denom,
        Estimator::Hdev | Estimator::Ohdev => sum / (3.0 * denom),
        Estimator::Mdev | Estimator::Tdev => sum / (denom * (m * m) as f64),
    };
    match est {
        Estimator::Tdev => tau / 3f64.sqrt() * var.sqrt(),
        _ => var.sqrt(),
    }
}

/// Overlapping sums Σ D(i)² for every factor in `ms` (ascending, all supported) in one sweep:
/// the start indices are cut into tiles and each tile is summed for every m before moving
/// on, so a tile and its neighbourhood come from memory once for all taus instead of once
/// per tau (one tau at a time, these loops are memory-bound). Tiles run on all cores.
fn overlapping_sums(x: &[f64], ms: &[usize], order: Order) -> Vec<f64> {
    const TILE: usize = 1 << 13;
    let Some(&m_min) = ms.first() else {
        return Vec::new();
    };
    let arch = pulp::Arch::new();
    let tiles: Vec<Vec<f64>> = blocks(order.starts(x.len(), m_min), TILE)
        .map(|(start, len)| {
            arch.dispatch(TileSums {
                x,
                ms,
                order,
                start,
                len,
            })
        })
        .collect();
    // Added in tile order, so the result does not depend on how the tiles were scheduled.
    let mut sums = vec![0.0; ms.len()];
    for tile in tiles {
        sums.iter_mut().zip(tile).for_each(|(a, b)| *a += b);
    }
    sums
}

/// One tile of [`overlapping_sums`]: Σ D(i)² over the starts `start..start + len` (those
/// that fit in x) for every factor in `ms`. As a [`pulp::WithSimd`] operation its loops are
/// compiled once per vector width and run at the widest the CPU has (AVX2 or AVX-512 instead
/// of the baseline SSE2 on x86-64); the arithmetic and its order are the same, so the sums
/// are bit for bit the same on every CPU.
struct TileSums<'a> {
    x: &'a [f64],
    ms: &'a [usize],
    order: Order,
    start: usize,
    len: usize,
}

impl pulp::WithSimd for TileSums<'_> {
    type Output = Vec<f64>;

    #[inline(always)]
    fn with_simd<S: pulp::Simd>(self, _simd: S) -> Vec<f64> {
        let mut sums = Vec::with_capacity(self.ms.len());
        for &m in self.ms {
            let end = (self.start + self.len).min(self.order.starts(self.x.len(), m));
            sums.push(if end > self.start {
                sum_sq_run(self.x, m, self.order, self.start, end - self.start)
            } else {
                0.0
            });
        }
        sums
    }
}

/// Sum of `term(i)²` for i in 0..count, with eight independent accumulators so the loop
/// vectorises and the rounding error stays small.
#[inline(always)]
fn sum_squares(count: usize, term: impl Fn(usize) -> f64) -> f64 {
    let mut acc = [0.0f64; 8];
    let full = count / 8 * 8;
    let mut i = 0;
    while i < full {
        for (k, a) in acc.iter_mut().enumerate() {
            let t = term(i + k);
            *a += t * t;
        }
        i += 8;
    }
    for j in full..count {
        let t = term(j);
        acc[j % 8] += t * t;
    }
    acc.iter().sum()
}

/// Σ D(i)² for `count` consecutive starts i = start, start+1, ... (stride 1).
#[inline(always)]
fn sum_sq_run(x: &[f64], m: usize, order: Order, start: usize, count: usize) -> f64 {
    let tap = |k: usize| &x[start + k * m..start + k * m + count];
    match order {
        Order::Second => sum_sq_taps([tap(0), tap(1), tap(2)], [1.0, -2.0, 1.0]),
        Order::Third => sum_sq_taps([tap(0), tap(1), tap(2), tap(3)], [-1.0, 3.0, -3.0, 1.0]),
    }
}

/// Σ_i (Σ_j coef\[j\] taps\[j\]\[i\])² over taps of equal length, eight lanes at a time so
/// that the loop compiles to packed arithmetic (one bounds check per tap and 8 terms).
#[inline(always)]
fn sum_sq_taps<const T: usize>(taps: [&[f64]; T], coef: [f64; T]) -> f64 {
    let len = taps[0].len();
    let full = len / 8 * 8;
    let mut acc = [0.0f64; 8];
    let mut i = 0;
    while i < full {
        let mut t = [0.0f64; 8];
        for (tap, c) in taps.iter().zip(coef) {
            let s: &[f64; 8] = tap[i..i + 8].try_into().expect("8 lanes");
            for (t, s) in t.iter_mut().zip(s) {
                *t += c * s;
            }
        }
        for (a, t) in acc.iter_mut().zip(t) {
            *a += t * t;
        }
        i += 8;
    }
    let tail = sum_squares(len - full, |k| {
        taps.iter()
            .zip(coef)
            .map(|(tap, c)| c * tap[full + k])
            .sum::<f64>()
    });
    acc.iter().sum::<f64>() + tail
}

/// Σ D(i)² over i = 0, stride, 2 stride, ... while the difference fits in x. Stride 1 is the
/// overlapping estimator, stride m the non-overlapping one. Long runs are split in blocks
/// summed in parallel.
fn sum_sq(x: &[f64], m: usize, order: Order, stride: usize) -> f64 {
    let span = order.span() * m;
    let count = (x.len() - 1 - span) / stride + 1;
    if stride == 1 {
        return sum_blocks(count, BLOCK, |(s, c)| sum_sq_run(x, m, order, s, c));
    }
    // Non-overlapping: few terms (N/m); a strided gather is as good as it gets.
    let d = |i: usize| match order {
        Order::Second => x[i + 2 * m] - 2.0 * x[i + m] + x[i],
        Order::Third => x[i + 3 * m] - 3.0 * (x[i + 2 * m] - x[i + m]) - x[i],
    };
    sum_squares(count, |k| d(k * stride))
}

/// `f` summed over (start, len) blocks covering 0..count, the blocks computed in parallel
/// and added in order (the same result however they were scheduled).
fn sum_blocks(count: usize, block: usize, f: impl Fn((usize, usize)) -> f64 + Sync + Send) -> f64 {
    let parts: Vec<f64> = blocks(count, block).map(f).collect();
    parts.iter().sum()
}

/// Parallel iterator over (start, len) blocks covering 0..count.
fn blocks(count: usize, block: usize) -> impl ParallelIterator<Item = (usize, usize)> {
    let block = block.max(1);
    (0..count.div_ceil(block))
        .into_par_iter()
        .map(move |b| (b * block, block.min(count - b * block)))
}

/// Modified Allan sum Σ_j W(j)², W(j) = Σ_{i=j}^{j+m-1} D2(i), j = 0..=N-3m, in O(N) for any
/// m: the window sum is updated as W(j+1) = W(j) + D2(j+m) - D2(j). Each block restarts the
/// window from a direct sum (bounding rounding-error growth) and runs eight interleaved
/// lanes so that the eight dependency chains overlap. Blocks are at least 8m long so that the
/// restarts cost at most a few per cent.
fn sum_sq_moving(x: &[f64], m: usize) -> f64 {
    let count = x.len() + 1 - 3 * m;
    let d2 = |i: usize| x[i + 2 * m] - 2.0 * x[i + m] + x[i];
    let window = |j: usize| (j..j + m).map(d2).sum::<f64>();
    sum_blocks(count, BLOCK.max(64 * m), |(start, len)| {
        let lanes = 8usize.min(len);
        let per = len / lanes;
        let mut w: Vec<f64> = (0..lanes).map(|l| window(start + l * per)).collect();
        let mut acc = vec![0.0f64; lanes];
        for k in 0..per {
            let step = k + 1 < per;
            for l in 0..lanes {
                acc[l] += w[l] * w[l];
                if step {
                    let j = start + l * per + k;
                    w[l] += d2(j + m) - d2(j);
                }
            }
        }
        // The remainder (len not a multiple of lanes) gets a window of its own.
        let rest = start + lanes * per..start + len;
        let mut tail = 0.0;
        if !rest.is_empty() {
            let mut wr = window(rest.start);
            for j in rest.clone() {
                tail += wr * wr;
                if j + 1 < rest.end {
                    wr += d2(j + m) - d2(j);
                }
            }
        }
        acc.iter().sum::<f64>() + tail
    })
}

/// Total-variance sum on the reflected extension of x (SP 1065 §5.2.11): with 0-based
/// indices, x*(-k) = 2 x\[0\] - x\[k\] and x*(N-1+k) = 2 x\[N-1\] - x\[N-1-k\] for k = 1..N-2;
/// the sum runs over centres i = 1..=N-2 of `x*(i-m) - 2 x(i) + x*(i+m)`, for any m ≤ N - 1.
/// Centres whose differences stay inside x (i in m..=N-1-m, empty past half the record)
/// reuse the plain second-difference loop; only the others touch the reflection.
fn sum_sq_reflected(x: &[f64], m: usize) -> f64 {
    let n = x.len();
    let last = n - 1;
    let ext = |k: isize| -> f64 {
        if k < 0 {
            2.0 * x[0] - x[(-k) as usize]
        } else if k as usize > last {
            2.0 * x[last] - x[2 * last - k as usize]
        } else {
            x[k as usize]
        }
    };
    let edge = |i: usize| {
        let (i, mi) = (i as isize, m as isize);
        ext(i + mi) - 2.0 * x[i as usize] + ext(i - mi)
    };
    // Centres 1..left reach below x[0]; right..=N-2 reach past x[N-1]; between them, the
    // interior (its first centre m is the second difference starting at x[0]).
    let left = m.min(last);
    let right = (n - m).max(left);
    let interior = sum_blocks(right - left, BLOCK, |(s, c)| {
        sum_sq_run(x, m, Order::Second, s, c)
    });
    let low = sum_squares(left - 1, |k| edge(k + 1));
    let high = sum_squares(last - right, |k| edge(right + k));
    interior + low + high
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Straightforward O(N m) reference implementations, straight from the SP 1065 formulas.
    fn naive(est: Estimator, x: &[f64], tau0: f64, m: usize) -> f64 {
        let n = x.len();
        let tau = m as f64 * tau0;
        let d2 = |i: usize| x[i + 2 * m] - 2.0 * x[i + m] + x[i];
        let d3 = |i: usize| x[i + 3 * m] - 3.0 * x[i + 2 * m] + 3.0 * x[i + m] - x[i];
        let mean = |v: Vec<f64>| v.iter().sum::<f64>() / v.len() as f64;
        match est {
            Estimator::Adev => {
                let v: Vec<f64> = (0..n - 2 * m).step_by(m).map(|i| d2(i).powi(2)).collect();
                (mean(v) / (2.0 * tau * tau)).sqrt()
            }
            Estimator::Oadev => {
                let v: Vec<f64> = (0..n - 2 * m).map(|i| d2(i).powi(2)).collect();
                (mean(v) / (2.0 * tau * tau)).sqrt()
            }
            Estimator::Hdev => {
                let v: Vec<f64> = (0..n - 3 * m).step_by(m).map(|i| d3(i).powi(2)).collect();
                (mean(v) / (6.0 * tau * tau)).sqrt()
            }
            Estimator::Ohdev => {
                let v: Vec<f64> = (0..n - 3 * m).map(|i| d3(i).powi(2)).collect();
                (mean(v) / (6.0 * tau * tau)).sqrt()
            }
            Estimator::Mdev | Estimator::Tdev => {
                let v: Vec<f64> = (0..=n - 3 * m)
                    .map(|j| (j..j + m).map(d2).sum::<f64>().powi(2))
                    .collect();
                let mdev = (mean(v) / (2.0 * (m * m) as f64 * tau * tau)).sqrt();
                if est == Estimator::Tdev {
                    tau * mdev / 3f64.sqrt()
                } else {
                    mdev
                }
            }
            Estimator::Totdev => {
                let mut ext: Vec<f64> = (1..=n - 2).rev().map(|j| 2.0 * x[0] - x[j]).collect();
                let off = ext.len();
                ext.extend_from_slice(x);
                ext.extend((1..=n - 2).map(|j| 2.0 * x[n - 1] - x[n - 1 - j]));
                let v: Vec<f64> = (1..=n - 2)
                    .map(|i| {
                        let c = i + off;
                        (ext[c - m] - 2.0 * ext[c] + ext[c + m]).powi(2)
                    })
                    .collect();
                (mean(v) / (2.0 * tau * tau)).sqrt()
            }
        }
    }

    fn walk(n: usize) -> Vec<f64> {
        let mut s = 12345u64;
        let mut acc = 0.0;
        (0..n)
            .map(|_| {
                s = s
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                acc += (s >> 11) as f64 / (1u64 << 53) as f64 - 0.5;
                acc
            })
            .collect()
    }

    #[test]
    fn fast_sums_equal_the_textbook_formulas() {
        // Long enough for several parallel blocks and mdev lanes with remainders.
        let x = walk(3 * BLOCK + 37);
        for est in Estimator::ALL {
            let mmax = max_factor(est, x.len());
            let ms = [1, 2, 3, 7, 100, 1001, mmax];
            let d = deviation(est, &x, 0.5, &ms);
            assert_eq!(d.m, ms.to_vec(), "{est}");
            for (k, &m) in d.m.iter().enumerate() {
                let want = naive(est, &x, 0.5, m);
                let rel = (d.dev[k] - want).abs() / want;
                assert!(rel < 1e-9, "{est} m={m}: {} vs {want}", d.dev[k]);
                assert_eq!(d.tau[k], m as f64 * 0.5);
            }
        }
    }

    /// The widest vector code the CPU runs (AVX-512 or AVX2 on x86-64) gives the baseline
    /// code's sums bit for bit: the same operations in the same order, only more lanes at once.
    #[test]
    fn tile_sums_are_the_same_at_every_vector_width() {
        use pulp::WithSimd;
        let x = walk(5003);
        let ms = [1, 2, 3, 7, 100, 1001];
        for order in [Order::Second, Order::Third] {
            let tile = || TileSums {
                x: &x,
                ms: &ms,
                order,
                start: 3,
                len: 2000,
            };
            let widest = pulp::Arch::new().dispatch(tile());
            let baseline = tile().with_simd(pulp::Scalar::new());
            assert_eq!(widest, baseline, "{order:?}");
            assert!(widest.iter().all(|s| *s > 0.0), "{widest:?}");
        }
    }

    #[test]
    fn totdev_on_the_whole_extension_equals_the_textbook_formula() {
        // Odd and even lengths, so that m = N/2 and the factors either side of it occur.
        for n in [3, 4, 9, 10, 2 * BLOCK + 5] {
            let x = walk(n);
            let ms: Vec<usize> = [1, 2, n / 2 - 1, n / 2, n / 2 + 1, n - 2, n - 1, n]
                .into_iter()
                .filter(|&m| m >= 1)
                .collect();
            let d = totdev_whole_extension(&x, 0.25, &ms);
            let mut want_ms: Vec<usize> = ms.iter().copied().filter(|&m| m < n).collect();
            want_ms.sort_unstable();
            want_ms.dedup();
            assert_eq!(d.m, want_ms, "n={n}");
            for (k, &m) in d.m.iter().enumerate() {
                let want = naive(Estimator::Totdev, &x, 0.25, m);
                let rel = (d.dev[k] - want).abs() / want;
                assert!(rel < 1e-9, "n={n} m={m}: {} vs {want}", d.dev[k]);
                assert_eq!(d.n[k], n - 2);
            }
            // Up to half the record, the same curve as the Stable32 range.
            let half = deviation(Estimator::Totdev, &x, 0.25, &ms);
            assert_eq!(half.dev[..], d.dev[..half.dev.len()], "n={n}");
        }
        assert!(totdev_whole_extension(&[1.0, 2.0], 1.0, &[1]).m.is_empty());
    }

    #[test]
    fn max_factor_is_the_last_factor_with_a_term() {
        for n in 0..40 {
            for est in Estimator::ALL {
                let mmax = max_factor(est, n);
                if mmax > 0 {
                    assert!(term_count(est, n, mmax) >= 1, "{est} n={n}");
                }
                assert_eq!(term_count(est, n, mmax + 1), 0, "{est} n={n}");
            }
        }
        assert_eq!(max_factor(Estimator::Oadev, 1001), 500);
        assert_eq!(max_factor(Estimator::Hdev, 1001), 333);
        assert_eq!(max_factor(Estimator::Mdev, 1001), 333);
        assert_eq!(max_factor(Estimator::Totdev, 1001), 500);
    }

    #[test]
    fn short_or_empty_input_gives_an_empty_curve() {
        for est in Estimator::ALL {
            for n in 0..3 {
                let d = deviation(est, &vec![1.0; n], 1.0, &[1, 2, 4]);
                assert!(
                    d.m.is_empty() && d.dev.is_empty() && d.n.is_empty(),
                    "{est} {n}"
                );
            }
        }
        let d = deviation(Estimator::Oadev, &[0.0, 1.0, 0.0], 1.0, &[0, 4, 1, 1]);
        assert_eq!((d.m, d.n), (vec![1], vec![1]));
    }

    #[test]
    fn linear_phase_has_zero_deviation() {
        let x: Vec<f64> = (0..200).map(|i| 3.0 + 0.25 * i as f64).collect();
        for est in Estimator::ALL {
            let d = deviation(est, &x, 1.0, &[1, 5, 20]);
            assert!(d.dev.iter().all(|&v| v.abs() < 1e-12), "{est}: {:?}", d.dev);
        }
    }
}
