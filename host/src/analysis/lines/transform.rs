//! The full-record DFT the search reads its periodograms from, and its inverse for the
//! removal of lines' excess power (module documentation of [`super`], steps 1 and 5).
//!
//! Below [`SQUARE_MIN_SAMPLES`] the whole record is transformed by realfft's plan. From there
//! on, the record's first `2 m^2` samples are transformed in place by
//! [`SquareRealFft::fitting`]: its plan holds a few rows where a general plan of the whole
//! record holds tables as large as the record (and, for a length with a large prime factor,
//! Bluestein's work space of several times it), and its output takes the place of the
//! detrended copy instead of lying beside it. The samples after the square, under 0.8 % of
//! the record at 2^20 samples and under 0.6 % from 10^7 on, are searched no further;
//! [`super::clean`] removes the lines' excess from them through a second square ending at the
//! record's end.

use super::{Trend, detrend};
use crate::analysis::shared_plans;
use crate::analysis::square_fft::SquareRealFft;
use realfft::RealToComplex;
use realfft::num_complex::Complex;
use std::sync::Arc;

/// Records from this length on are transformed by the square in-place DFT. Below it the
/// whole-record plan holds at most about 190 MB (measured for the prime length 1048573, 22
/// times its 8 MB; a length with small prime factors needs about 3.5 times), and the records
/// the module's families were calibrated on keep their whole-record periodogram.
pub const SQUARE_MIN_SAMPLES: usize = 1 << 20;

/// A record's DFT held in the record's own buffer ([`Transform::dft_in_place`]).
pub(super) struct InPlace {
    /// The least-squares line of the samples transformed.
    pub(super) trend: Trend,
    /// Their DFT less the line, bins 0..=len/2 (and one slot more).
    pub(super) dft: Vec<Complex<f64>>,
    /// The record's samples after those transformed.
    pub(super) tail: Vec<f64>,
}

/// A DFT of the samples the search transforms.
pub(super) enum Transform {
    /// The whole record, by realfft's plan.
    Plan(Arc<dyn RealToComplex<f64>>),
    /// The first `2 m^2` samples, in place.
    Square(SquareRealFft),
}

impl Transform {
    /// The transform for a record of `n` samples.
    pub(super) fn for_record(n: usize) -> Transform {
        if n < SQUARE_MIN_SAMPLES {
            Transform::Plan(shared_plans::forward(n))
        } else {
            Transform::Square(SquareRealFft::fitting(n))
        }
    }

    /// Samples transformed.
    pub(super) fn len(&self) -> usize {
        match self {
            Transform::Plan(plan) => plan.len(),
            Transform::Square(square) => square.len(),
        }
    }

    /// The least-squares line of `y`'s first [`Transform::len`] samples, and the DFT (bins
    /// 0..=len/2) of those samples less it. Room is kept for `capacity` real samples and two
    /// more, so that [`Transform::samples`]'s result can be extended to that length, and then
    /// become phase ([`crate::analysis::into_phase`]), in place.
    pub(super) fn dft_detrended(&self, y: &[f64], capacity: usize) -> (Trend, Vec<Complex<f64>>) {
        let n = self.len();
        let window = &y[..n];
        match self {
            Transform::Plan(plan) => {
                let (trend, mut x) = detrend(window);
                let mut dft = plan.make_output_vec();
                plan.process(&mut x, &mut dft)
                    .expect("buffer lengths match the FFT plan");
                (trend, dft)
            }
            Transform::Square(square) => {
                let trend = super::line_of(window);
                let mut data =
                    Vec::with_capacity(square.buffer_len().max(capacity.div_ceil(2) + 1));
                data.extend(window.chunks_exact(2).enumerate().map(|(j, pair)| {
                    Complex::new(
                        pair[0] - trend.at(2 * j, n),
                        pair[1] - trend.at(2 * j + 1, n),
                    )
                }));
                data.push(Complex::new(0.0, 0.0));
                square.forward(&mut data);
                (trend, data)
            }
        }
    }

    /// [`Transform::dft_detrended`] of a record given up by its caller, in its own buffer; the
    /// samples after the square are handed back apart (the DFT's Nyquist slot takes the place
    /// of the first two), for [`Transform::restore`]. `None` (and the record untouched) for
    /// the whole-record plan, which transforms out of place.
    pub(super) fn dft_in_place(&self, y: &mut Vec<f64>) -> Option<InPlace> {
        let Transform::Square(square) = self else {
            return None;
        };
        let n = square.len();
        let total = y.len();
        let tail = y[n..].to_vec();
        let trend = super::line_of(&y[..n]);
        y.truncate(n);
        // Room for the record again, even for the cast to complex values.
        let room = (2 * square.buffer_len()).max(total).next_multiple_of(2);
        if y.capacity() < room {
            y.reserve_exact(room - n);
        } else {
            y.shrink_to(room);
        }
        for (t, v) in y.iter_mut().enumerate() {
            *v -= trend.at(t, n);
        }
        y.resize(2 * square.buffer_len(), 0.0);
        let mut dft = match bytemuck::allocation::try_cast_vec(std::mem::take(y)) {
            Ok(dft) => dft,
            // A capacity the allocator left odd: the samples are copied once.
            Err((_, samples)) => samples
                .chunks_exact(2)
                .map(|pair| Complex::new(pair[0], pair[1]))
                .collect(),
        };
        square.forward(&mut dft);
        Some(InPlace { trend, dft, tail })
    }

    /// The record [`Transform::dft_in_place`] transformed, from its (possibly changed) DFT:
    /// the inverse, the line added back and the samples after the square appended.
    pub(super) fn restore(&self, in_place: InPlace) -> Vec<f64> {
        let InPlace { trend, dft, tail } = in_place;
        let mut y = self.samples(dft, trend);
        y.extend_from_slice(&tail);
        y
    }

    /// The [`Transform::len`] samples whose DFT is `dft` (bins 0..=len/2), plus `trend`: the
    /// inverse of [`Transform::dft_detrended`]. Consumes `dft`; the square's result is
    /// written in its buffer.
    pub(super) fn samples(&self, mut dft: Vec<Complex<f64>>, trend: Trend) -> Vec<f64> {
        let n = self.len();
        let mut y = match self {
            Transform::Plan(_) => {
                let inverse = shared_plans::inverse(n);
                let mut y = inverse.make_output_vec();
                inverse
                    .process(&mut dft, &mut y)
                    .expect("buffer lengths match the FFT plan");
                y.iter_mut().for_each(|v| *v /= n as f64);
                y
            }
            Transform::Square(square) => {
                square.inverse(&mut dft);
                let mut y: Vec<f64> = bytemuck::allocation::cast_vec(dft);
                y.truncate(n);
                y
            }
        };
        for (t, v) in y.iter_mut().enumerate() {
            *v += trend.at(t, n);
        }
        y
    }
}
