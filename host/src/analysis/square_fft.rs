//! The DFT of a real record of `n = 2 m^2` samples, computed in the record's own buffer with
//! work space of a few rows: for the full-record periodogram of long records
//! ([`super::lines`]), where a general FFT plan holds tables as large as the record and
//! writes its output beside a copy of it (4.5 times the record's memory for 10^7 samples,
//! and over 20 times for a length with a large prime factor, whose plan falls back to
//! Bluestein's algorithm).
//!
//! # Method
//!
//! 1. **Real as half-length complex.** The samples are packed as `z_j = x_2j + i x_(2j+1)`,
//!    `N = n / 2 = m^2` complex values, and `Z = DFT_N(z)` gives the real record's DFT
//!    `X_k = E_k + W^k O_k` for `k = 0..=N`, with `E_k = (Z_k + conj Z_(N-k)) / 2` and
//!    `O_k = (Z_k - conj Z_(N-k)) / (2 i)` the DFTs of the even and odd samples and
//!    `W = e^(-2 pi i / n)`; `X_(N-k) = conj(E_k - W^k O_k)`, so each pair (k, N - k) is
//!    rewritten in place (Press et al., *Numerical Recipes*, 3rd ed., 2007, sec. 12.3.2).
//! 2. **Four-step DFT of the square.** With `j = j1 + m j2` (z as an m x m row-major matrix,
//!    row j2, column j1) and `k = m k1 + k2`,
//!    `Z_(m k1 + k2) = sum_j1 W_m^(j1 k1) W_N^(j1 k2) sum_j2 z_(j1 + m j2) W_m^(j2 k2)`
//!    (Bailey, "FFTs in external or hierarchical memory", J. Supercomputing 4, 1990): a
//!    length-m DFT down every column, a twiddle `W_N^(j1 k2)` on element (k2, j1), a
//!    length-m DFT along every row, which leaves `Z_(m k1 + k2)` at (k2, k1); one in-place
//!    transpose of the square puts it in natural order. The inverse runs the same steps
//!    backwards with conjugate twiddles.
//! 3. **Twiddles without a table of N.** `W_N^p` for `p = a m + b < N` is
//!    `W_m^a W_N^b`: two tables of m values, each entry from `sin_cos` (no accumulated
//!    rounding).
//!
//! The DFTs of length m are rustfft's; columns are gathered a few at a time into contiguous
//! work space, and rows and column groups are shared among rayon's threads.

use rayon::prelude::*;
use realfft::num_complex::Complex;
use rustfft::{Fft, FftPlanner};
use std::f64::consts::PI;
use std::sync::Arc;

type C = Complex<f64>;

/// Share of a record [`SquareRealFft::fitting`] may leave out, beyond the largest square,
/// to take a side with small prime factors.
const SMOOTH_SIDE_LOSS: f64 = 0.005;

/// The largest prime factor of `m >= 1` (1 for 1).
pub(crate) fn largest_prime_factor(mut m: usize) -> usize {
    let mut largest = 1;
    let mut p = 2;
    while p * p <= m {
        while m.is_multiple_of(p) {
            m /= p;
            largest = p;
        }
        p += 1;
    }
    largest.max(m)
}

/// Columns gathered at once: 8 complex values are two 64-byte cache lines of a row.
pub(crate) const COLUMN_BLOCK: usize = 8;

/// The in-place real DFT of `2 m^2` samples ([module documentation](self)).
pub struct SquareRealFft {
    m: usize,
    forward: Arc<dyn Fft<f64>>,
    inverse: Arc<dyn Fft<f64>>,
    /// `W_N^p`, p < N.
    twiddles: Twiddles,
    /// `W_n^k`, k <= N / 2 (n = 2 N): the real pairing's twiddles.
    real_twiddles: Twiddles,
}

/// `W_q^p = e^(-2 pi i p / q)` for `p = a s + b` (b < s) as `W_q^(a s) W_q^b`: a table of the
/// coarse steps and one of the fine, where a table of every p would be as long as the
/// transform.
pub(crate) struct Twiddles {
    side: usize,
    /// `W_q^(a s)`.
    coarse: Vec<C>,
    /// `W_q^b`, b < s.
    fine: Vec<C>,
}

impl Twiddles {
    /// `W_q^p` for `p < steps * side`, in steps of `side`.
    pub(crate) fn new(q: usize, side: usize, steps: usize) -> Twiddles {
        Twiddles {
            side,
            coarse: (0..steps).map(|a| unit(a * side, q)).collect(),
            fine: (0..side).map(|b| unit(b, q)).collect(),
        }
    }

    /// `W_q^p`.
    pub(crate) fn at(&self, p: usize) -> C {
        self.split(p / self.side, p % self.side)
    }

    /// `W_q^(a s + b)`, b < s.
    pub(crate) fn split(&self, a: usize, b: usize) -> C {
        self.coarse[a] * self.fine[b]
    }

    /// `out[i]` times `W_q^(i step)` (conjugated when `conjugate`), `step < side`, without a
    /// division per element.
    pub(crate) fn scale_run(&self, step: usize, conjugate: bool, out: &mut [C]) {
        let (mut a, mut b) = (0usize, 0usize);
        for v in out.iter_mut() {
            let w = self.split(a, b);
            *v *= if conjugate { w.conj() } else { w };
            b += step;
            if b >= self.side {
                b -= self.side;
                a += 1;
            }
        }
    }
}

/// `e^(-2 pi i p / q)`.
pub(crate) fn unit(p: usize, q: usize) -> C {
    let (s, c) = (-2.0 * PI * p as f64 / q as f64).sin_cos();
    C::new(c, s)
}

impl SquareRealFft {
    /// The transform of `2 m^2` real samples; `m >= 1`.
    pub fn new(m: usize) -> SquareRealFft {
        let m = m.max(1);
        let big = m * m;
        let mut planner = FftPlanner::<f64>::new();
        SquareRealFft {
            m,
            forward: planner.plan_fft_forward(m),
            inverse: planner.plan_fft_inverse(m),
            twiddles: Twiddles::new(big, m, m),
            real_twiddles: Twiddles::new(2 * big, m, m / 2 + 1),
        }
    }

    /// The square transform for a record of `n >= 2` samples: the largest side `m` with
    /// `2 m^2 <= n` whose prime factors are all at most 31 (rustfft's own butterflies; a
    /// larger prime factor takes Rader's or Bluestein's algorithm, about twice as slow) if one
    /// leaves out at most 0.5 % more of the record, else the largest side.
    pub fn fitting(n: usize) -> SquareRealFft {
        let mut largest = ((n / 2) as f64).sqrt() as usize;
        while largest * largest * 2 > n {
            largest -= 1;
        }
        while (largest + 1) * (largest + 1) * 2 <= n {
            largest += 1;
        }
        let lowest = (largest as f64 * (1.0 - SMOOTH_SIDE_LOSS / 2.0)).ceil() as usize;
        let m = (lowest.max(1)..=largest)
            .rev()
            .find(|&m| largest_prime_factor(m) <= 31)
            .unwrap_or(largest);
        SquareRealFft::new(m)
    }

    /// Real samples transformed: `2 m^2`.
    pub fn len(&self) -> usize {
        2 * self.m * self.m
    }

    /// Whether it transforms no samples (never: `m >= 1`).
    pub fn is_empty(&self) -> bool {
        false
    }

    /// Complex values of the buffer [`SquareRealFft::forward`] works in: the packed samples,
    /// then one slot for the Nyquist bin (`m^2 + 1`).
    pub fn buffer_len(&self) -> usize {
        self.m * self.m + 1
    }

    /// The DFT `X_k = sum_t x_t e^(-2 pi i k t / n)`, k = 0..=n/2, of the real samples packed
    /// in `data` as `x_2j + i x_(2j+1)`, j < m^2, written over them. `data` holds
    /// [`SquareRealFft::buffer_len`] values; the last is overwritten.
    pub fn forward(&self, data: &mut [C]) {
        let big = self.m * self.m;
        assert_eq!(
            data.len(),
            self.buffer_len(),
            "buffer of the transform's length"
        );
        let square = &mut data[..big];
        self.columns(square, &*self.forward, false);
        self.rows(square, &*self.forward, None);
        transpose(square, self.m);
        self.unpack(data);
    }

    /// The inverse of [`SquareRealFft::forward`]: from the DFT bins k = 0..=n/2 in `data` (the
    /// imaginary parts of bins 0 and n/2 are ignored), the real samples `x_t`, packed as
    /// `x_2j + i x_(2j+1)` in `data[..m^2]` (normalised: forward then inverse returns the
    /// samples). The last value is left as zero.
    pub fn inverse(&self, data: &mut [C]) {
        let big = self.m * self.m;
        assert_eq!(
            data.len(),
            self.buffer_len(),
            "buffer of the transform's length"
        );
        self.pack(data);
        let square = &mut data[..big];
        transpose(square, self.m);
        self.rows(square, &*self.inverse, Some(true));
        self.columns(square, &*self.inverse, true);
        let scale = 1.0 / big as f64;
        square.par_iter_mut().for_each(|v| *v *= scale);
        data[big] = C::new(0.0, 0.0);
    }

    /// `W_N^(r c)` (conjugated for the inverse) for r, c < m.
    fn twiddle_row(&self, r: usize, conjugate: bool, out: &mut [C]) {
        self.twiddles.scale_run(r, conjugate, out);
    }

    /// Length-m DFTs along every row; with `twiddle`, row r then times `W_N^(r c)` at column c
    /// (conjugated when `Some(true)`).
    fn rows(&self, square: &mut [C], fft: &dyn Fft<f64>, twiddle: Option<bool>) {
        let m = self.m;
        let rows_per_task = (16384 / m).max(1);
        square
            .par_chunks_mut(m * rows_per_task)
            .enumerate()
            .for_each(|(task, chunk)| {
                let mut scratch = vec![C::new(0.0, 0.0); fft.get_inplace_scratch_len()];
                fft.process_with_scratch(chunk, &mut scratch);
                if let Some(conjugate) = twiddle {
                    for (i, row) in chunk.chunks_mut(m).enumerate() {
                        self.twiddle_row(task * rows_per_task + i, conjugate, row);
                    }
                }
            });
    }

    /// Length-m DFTs down every column; the forward transform then multiplies element (r, c)
    /// by `W_N^(r c)`. Columns are split into one group per thread, each given its slice of
    /// every row.
    fn columns(&self, square: &mut [C], fft: &dyn Fft<f64>, inverse: bool) {
        let m = self.m;
        let threads = rayon::current_num_threads().max(1);
        let width = m.div_ceil(threads).div_ceil(COLUMN_BLOCK) * COLUMN_BLOCK;
        let groups = m.div_ceil(width);
        let mut parts: Vec<Vec<&mut [C]>> = (0..groups).map(|_| Vec::with_capacity(m)).collect();
        for row in square.chunks_mut(m) {
            let mut rest = row;
            for part in parts.iter_mut() {
                let (mine, others) = rest.split_at_mut(width.min(rest.len()));
                part.push(mine);
                rest = others;
            }
        }
        parts
            .into_par_iter()
            .enumerate()
            .for_each(|(group, mut rows)| {
                let first = group * width;
                let columns = rows.first().map_or(0, |r| r.len());
                let mut block = vec![C::new(0.0, 0.0); COLUMN_BLOCK * m];
                let mut scratch = vec![C::new(0.0, 0.0); fft.get_inplace_scratch_len()];
                let mut twiddles = vec![C::new(0.0, 0.0); m];
                for c0 in (0..columns).step_by(COLUMN_BLOCK) {
                    let b = COLUMN_BLOCK.min(columns - c0);
                    for (r, row) in rows.iter().enumerate() {
                        for i in 0..b {
                            block[i * m + r] = row[c0 + i];
                        }
                    }
                    fft.process_with_scratch(&mut block[..b * m], &mut scratch);
                    if !inverse {
                        for i in 0..b {
                            twiddles.iter_mut().for_each(|t| *t = C::new(1.0, 0.0));
                            self.twiddle_row(first + c0 + i, false, &mut twiddles);
                            block[i * m..(i + 1) * m]
                                .iter_mut()
                                .zip(&twiddles)
                                .for_each(|(v, w)| *v *= w);
                        }
                    }
                    for (r, row) in rows.iter_mut().enumerate() {
                        for i in 0..b {
                            row[c0 + i] = block[i * m + r];
                        }
                    }
                }
            });
    }

    /// `W_n^k`, k <= N / 2.
    fn real_twiddle(&self, k: usize) -> C {
        self.real_twiddles.at(k)
    }

    /// Step 1 forward: `Z` (k < N) to `X` (k <= N) in place.
    fn unpack(&self, data: &mut [C]) {
        let big = self.m * self.m;
        let z0 = data[0];
        data[0] = C::new(z0.re + z0.im, 0.0);
        data[big] = C::new(z0.re - z0.im, 0.0);
        for k in 1..=big / 2 {
            let (zk, zn) = (data[k], data[big - k].conj());
            let e = (zk + zn) * 0.5;
            let o = (zk - zn) * C::new(0.0, -0.5);
            let wo = self.real_twiddle(k) * o;
            data[k] = e + wo;
            data[big - k] = (e - wo).conj();
        }
    }

    /// Step 1 backwards: `X` (k <= N) to `Z` (k < N) in place.
    fn pack(&self, data: &mut [C]) {
        let big = self.m * self.m;
        let (a, b) = (data[0].re, data[big].re);
        data[0] = C::new((a + b) * 0.5, (a - b) * 0.5);
        for k in 1..=big / 2 {
            let (xk, xn) = (data[k], data[big - k].conj());
            let e = (xk + xn) * 0.5;
            let o = (xk - xn) * 0.5 * self.real_twiddle(k).conj();
            let i = C::new(0.0, 1.0);
            data[k] = e + i * o;
            data[big - k] = e.conj() + i * o.conj();
        }
    }
}

/// Transposes the row-major m x m `square` in place, a tile at a time.
fn transpose(square: &mut [C], m: usize) {
    const TILE: usize = 32;
    for r0 in (0..m).step_by(TILE) {
        for c0 in (r0..m).step_by(TILE) {
            for r in r0..(r0 + TILE).min(m) {
                let from = if c0 == r0 { r + 1 } else { c0 };
                for c in from..(c0 + TILE).min(m) {
                    square.swap(r * m + c, c * m + r);
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;
    use realfft::RealFftPlanner;

    fn packed(x: &[f64]) -> Vec<C> {
        let mut data: Vec<C> = x.chunks(2).map(|p| C::new(p[0], p[1])).collect();
        data.push(C::new(0.0, 0.0));
        data
    }

    /// Every m from 1 to 40 (odd, even, prime, the rustfft planner's many algorithms) on
    /// random samples: the bins agree with realfft's to 1e-13 of the largest, and the
    /// inverse returns the samples to 1e-13.
    #[test]
    fn the_square_transform_is_the_dft_and_inverts() {
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        for m in 1..=40 {
            let fft = SquareRealFft::new(m);
            let n = fft.len();
            let x: Vec<f64> = (0..n).map(|_| rng.random::<f64>() - 0.3).collect();
            let mut data = packed(&x);
            fft.forward(&mut data);
            let plan = RealFftPlanner::<f64>::new().plan_fft_forward(n);
            let mut expected = plan.make_output_vec();
            plan.process(&mut x.clone(), &mut expected).unwrap();
            let largest = expected.iter().map(|v| v.norm()).fold(0.0, f64::max);
            for (k, (got, want)) in data.iter().zip(&expected).enumerate() {
                assert!(
                    (got - want).norm() <= 1e-13 * largest,
                    "m = {m}, bin {k}: {got} against {want}"
                );
            }
            fft.inverse(&mut data);
            for (j, pair) in x.chunks(2).enumerate() {
                let got = data[j];
                assert!(
                    (got.re - pair[0]).abs() < 1e-13 && (got.im - pair[1]).abs() < 1e-13,
                    "m = {m}, sample pair {j}: {got} against {pair:?}"
                );
            }
        }
    }

    /// The square fits the record, leaves out at most 0.5 % more than the largest square
    /// would, and has a side free of prime factors above 31 where one is that close.
    #[test]
    fn the_fitting_square_fits_with_a_smooth_side() {
        assert_eq!(largest_prime_factor(2233), 29);
        assert_eq!(largest_prime_factor(2236), 43);
        assert_eq!(largest_prime_factor(1), 1);
        for (n, side) in [
            (2, 1),
            (9, 2),
            (1_000_000, 707),
            (10_000_000, 2233),
            (10_000_019, 2233),
        ] {
            let fft = SquareRealFft::fitting(n);
            let largest = ((n / 2) as f64).sqrt().floor();
            assert_eq!(fft.len(), 2 * side * side, "n = {n}");
            assert!(fft.len() <= n, "n = {n}");
            assert!(
                side as f64 >= largest * (1.0 - SMOOTH_SIDE_LOSS / 2.0),
                "n = {n}"
            );
        }
    }
}
