//! The power spectrum `|X_k|^2`, `k = 0..=L/2`, of real segments of `L` samples, summed over
//! segments, computed in a buffer of the segment's own length: for Welch estimates with long
//! segments ([`super::psd`]), where a real-FFT plan holds tables about as long as the segment
//! and writes its output beside its input (two buffers and a table, where this holds one
//! buffer and tables of a few thousand values).
//!
//! # Method
//!
//! As [`super::square_fft`]'s, on a rectangle and without its transpose:
//!
//! 1. **Real as half-length complex.** The segment is packed as `z_j = x_2j + i x_(2j+1)`,
//!    `N = L / 2` values, and with `Z = DFT_N(z)` the real segment's DFT is
//!    `X_k = E_k + W_L^k O_k`, `E_k = (Z_k + conj Z_(N-k)) / 2`,
//!    `O_k = (Z_k - conj Z_(N-k)) / (2 i)`, for `k = 0..N`, and `X_N = Re Z_0 - Im Z_0`
//!    (Press et al., *Numerical Recipes*, 3rd ed., 2007, sec. 12.3.2).
//! 2. **Four-step DFT of an R x C rectangle**, `R C = N`, `R <= C`: with `j = j1 + C j2`
//!    (row j2, column j1) and `k = R k1 + k2`,
//!    `Z_(R k1 + k2) = sum_j1 W_C^(j1 k1) W_N^(j1 k2) sum_j2 z_(j1 + C j2) W_R^(j2 k2)`
//!    (Bailey, "FFTs in external or hierarchical memory", J. Supercomputing 4, 1990): a
//!    length-R DFT down every column, the twiddle `W_N^(j1 k2)` on element (k2, j1), a
//!    length-C DFT along every row. `Z_(R k1 + k2)` is then at row k2, column k1.
//! 3. **No transpose.** Only powers are wanted, so they are summed where the rectangle leaves
//!    them: `Z_k`'s partner `Z_(N-k)` is in row `(R - k2) mod R`, read backwards, so both
//!    reads run along rows. The sums are put in natural order once, after the last segment
//!    ([`PowerFft::natural`]).
//! 4. **Twiddles from short tables.** `W_N^p = W_R^(p div C) W_N^(p mod C)` and
//!    `W_L^(R k1 + k2) = W_L^(R k1) W_L^k2`: tables of R and C values, each entry from
//!    `sin_cos`.

use super::square_fft::{COLUMN_BLOCK, Twiddles};
use bytemuck::cast_slice_mut;
use realfft::num_complex::Complex;
use rustfft::{Fft, FftPlanner};
use std::sync::Arc;

type C = Complex<f64>;

/// A side shorter than this is not worth the four steps (the rectangle would be a few long
/// rows, each needing the long DFT's own work space).
const MIN_SIDE: usize = 16;

/// Summed power spectra of real segments of one length ([module documentation](self)).
pub struct PowerFft {
    /// Rows R and columns C of the rectangle, `R C = N = L / 2`.
    rows: usize,
    cols: usize,
    column_fft: Arc<dyn Fft<f64>>,
    row_fft: Arc<dyn Fft<f64>>,
    /// `W_N^p`, p < N, in steps of C.
    twiddles: Twiddles,
    /// `W_L^k`, k < N, in steps of R.
    real_twiddles: Twiddles,
}

impl PowerFft {
    /// The transform of segments of `len` samples, when `len` is even and `len / 2` has a
    /// divisor R with `MIN_SIDE <= R <= sqrt(len / 2)` (the largest is taken); `None` otherwise.
    pub fn new(len: usize) -> Option<PowerFft> {
        if !len.is_multiple_of(2) {
            return None;
        }
        let n = len / 2;
        let root = (n as f64).sqrt() as usize;
        let rows = (MIN_SIDE..=root).rev().find(|r| n.is_multiple_of(*r))?;
        let cols = n / rows;
        let mut planner = FftPlanner::<f64>::new();
        Some(PowerFft {
            rows,
            cols,
            column_fft: planner.plan_fft_forward(rows),
            row_fft: planner.plan_fft_forward(cols),
            twiddles: Twiddles::new(n, cols, rows),
            real_twiddles: Twiddles::new(len, rows, cols),
        })
    }

    /// Real samples per segment, L.
    pub fn len(&self) -> usize {
        2 * self.rows * self.cols
    }

    /// Whether segments are empty (never: `new` needs a side of at least 16).
    pub fn is_empty(&self) -> bool {
        false
    }

    /// Room for the sums: `N + 1` values, in the transform's order.
    pub fn sums(&self) -> Vec<f64> {
        vec![0.0; self.rows * self.cols + 1]
    }

    /// Adds `|X_k|^2`, k = 0..=L/2, of the real segment in `segment` (L samples; overwritten)
    /// to `sums` (from [`PowerFft::sums`]: `X_k` for `k = R k1 + k2 < N` at `k2 C + k1`, and
    /// `X_N` last).
    pub fn add(&self, segment: &mut [f64], sums: &mut [f64]) {
        assert_eq!(
            segment.len(),
            self.len(),
            "a segment of the transform's length"
        );
        assert_eq!(
            sums.len(),
            self.rows * self.cols + 1,
            "sums from PowerFft::sums"
        );
        let z: &mut [C] = cast_slice_mut(segment);
        self.columns(z);
        let mut scratch = vec![C::new(0.0, 0.0); self.row_fft.get_inplace_scratch_len()];
        self.row_fft.process_with_scratch(z, &mut scratch);
        self.add_powers(z, sums);
    }

    /// The sums in natural order: index k holds `X_k`'s, k = 0..=N.
    pub fn natural(&self, sums: &[f64]) -> Vec<f64> {
        let (rows, cols) = (self.rows, self.cols);
        let n = rows * cols;
        let mut out = vec![0.0; n + 1];
        for (k2, row) in sums[..n].chunks_exact(cols).enumerate() {
            for (k1, &v) in row.iter().enumerate() {
                out[rows * k1 + k2] = v;
            }
        }
        out[n] = sums[n];
        out
    }

    /// Length-R DFTs down every column, then element (k2, j1) times `W_N^(j1 k2)`.
    fn columns(&self, z: &mut [C]) {
        let (rows, cols) = (self.rows, self.cols);
        let mut block = vec![C::new(0.0, 0.0); COLUMN_BLOCK * rows];
        let mut scratch = vec![C::new(0.0, 0.0); self.column_fft.get_inplace_scratch_len()];
        for c0 in (0..cols).step_by(COLUMN_BLOCK) {
            let b = COLUMN_BLOCK.min(cols - c0);
            for r in 0..rows {
                let row = &z[r * cols + c0..r * cols + c0 + b];
                for (i, v) in row.iter().enumerate() {
                    block[i * rows + r] = *v;
                }
            }
            self.column_fft
                .process_with_scratch(&mut block[..b * rows], &mut scratch);
            for (i, column) in block[..b * rows].chunks_exact_mut(rows).enumerate() {
                // Element k2 times W_N^(j1 k2).
                self.twiddles.scale_run(c0 + i, false, column);
            }
            for r in 0..rows {
                let row = &mut z[r * cols + c0..r * cols + c0 + b];
                for (i, v) in row.iter_mut().enumerate() {
                    *v = block[i * rows + r];
                }
            }
        }
    }

    /// `|X_k|^2` added at `k`'s place in the rectangle, each row read with its partner row
    /// backwards.
    fn add_powers(&self, z: &[C], sums: &mut [f64]) {
        let (rows, cols) = (self.rows, self.cols);
        let n = rows * cols;
        let z0 = z[0];
        let half = C::new(0.5, 0.0);
        let minus_half_i = C::new(0.0, -0.5);
        for k2 in 0..rows {
            let row = &z[k2 * cols..(k2 + 1) * cols];
            let partner_row = (rows - k2) % rows;
            let partner = &z[partner_row * cols..(partner_row + 1) * cols];
            let out = &mut sums[k2 * cols..(k2 + 1) * cols];
            for (k1, (&zk, s)) in row.iter().zip(out.iter_mut()).enumerate() {
                // Z_(N-k): N - k = R (C - 1 - k1) + (R - k2) for k2 > 0, R (C - k1) for
                // k2 = 0 (and Z_N = Z_0).
                let znk = match (k2, k1) {
                    (0, 0) => z0,
                    (0, _) => partner[cols - k1],
                    _ => partner[cols - 1 - k1],
                }
                .conj();
                let even = (zk + znk) * half;
                let odd = (zk - znk) * minus_half_i;
                let x = even + self.real_twiddles.split(k1, k2) * odd;
                *s += x.norm_sqr();
            }
        }
        let nyquist = z0.re - z0.im;
        sums[n] += nyquist * nyquist;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;
    use realfft::RealFftPlanner;

    fn series(len: usize, seed: u64) -> Vec<f64> {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        (0..len).map(|_| rng.random_range(-0.5..0.5)).collect()
    }

    /// realfft's `|X_k|^2`, summed over the segments given.
    fn reference(segments: &[Vec<f64>]) -> Vec<f64> {
        let len = segments[0].len();
        let plan = RealFftPlanner::<f64>::new().plan_fft_forward(len);
        let mut sums = vec![0.0; len / 2 + 1];
        for s in segments {
            let mut input = s.clone();
            let mut out = plan.make_output_vec();
            plan.process(&mut input, &mut out).unwrap();
            for (a, x) in sums.iter_mut().zip(&out) {
                *a += x.norm_sqr();
            }
        }
        sums
    }

    #[test]
    fn summed_powers_match_realfft() {
        // Squares, oblong rectangles, odd and prime sides, and powers of two.
        for &(len, segments) in &[
            (2 * 16 * 16, 1),
            (2 * 16 * 17, 3),
            (2 * 16 * 64, 2),
            (2 * 24 * 30, 2),
            (2 * 19 * 19, 1),
            (1 << 12, 3),
            (1 << 15, 2),
        ] {
            let fft = PowerFft::new(len).expect("a side of at least 16");
            assert_eq!(fft.len(), len);
            let data: Vec<Vec<f64>> = (0..segments).map(|s| series(len, 7 + s as u64)).collect();
            let mut sums = fft.sums();
            for s in &data {
                let mut segment = s.clone();
                fft.add(&mut segment, &mut sums);
            }
            let got = fft.natural(&sums);
            let want = reference(&data);
            let largest = want.iter().cloned().fold(0.0, f64::max);
            for (k, (g, w)) in got.iter().zip(&want).enumerate() {
                assert!(
                    (g - w).abs() <= 1e-12 * largest,
                    "len {len}, bin {k}: {g} against {w}"
                );
            }
        }
    }

    #[test]
    fn lengths_without_a_balanced_rectangle_are_refused() {
        assert!(PowerFft::new(2 * 16 * 16 + 1).is_none(), "odd");
        assert!(PowerFft::new(2 * 8 * 8).is_none(), "side below 16");
        assert!(PowerFft::new(2 * 1009).is_none(), "prime half");
        assert!(PowerFft::new(2 * 16 * 1009).is_some());
    }
}
