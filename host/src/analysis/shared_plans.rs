//! Real FFT plans and Hann windows kept across calls.
//!
//! The model workflow transforms hundreds of series of one length (a record and its
//! simulated realisations), each in a fresh call. A realfft plan for a million points
//! computes about as many twiddle factors (a sine and a cosine each) as the transform
//! itself does butterflies, and a Hann window a cosine per sample; made once per length
//! and shared, they cost nothing after the first call. The plans are the ones a fresh
//! planner would make (the planner's choice depends only on the length and the processor),
//! so results are the same bit for bit.
//!
//! The cache holds the [`KEPT`] most recently used entries of each kind, so a long-lived
//! process (the Python module, `bench`) that meets many lengths stays bounded in memory.

use crate::analysis::psd::Window;
use realfft::{ComplexToReal, RealFftPlanner, RealToComplex};
use std::sync::{Arc, Mutex, MutexGuard};

/// Entries kept per kind: a round of the model workflow uses one or two lengths.
pub const KEPT: usize = 6;

/// The most recently used values by length, newest first.
struct Recent<T: ?Sized>(Mutex<Vec<(usize, Arc<T>)>>);

impl<T: ?Sized> Recent<T> {
    const fn new() -> Self {
        Recent(Mutex::new(Vec::new()))
    }

    /// The value for `len`, made by `make` (with the cache locked, so two threads asking
    /// for the same length make it once) when not held.
    fn get(&self, len: usize, make: impl FnOnce() -> Arc<T>) -> Arc<T> {
        let mut held = self.held();
        let value = match held.iter().position(|(l, _)| *l == len) {
            Some(i) => held.remove(i).1,
            None => make(),
        };
        held.insert(0, (len, Arc::clone(&value)));
        held.truncate(KEPT);
        value
    }

    fn held(&self) -> MutexGuard<'_, Vec<(usize, Arc<T>)>> {
        // Entries are inserted whole, so a thread that panicked while holding the lock
        // left a usable list.
        self.0
            .lock()
            .unwrap_or_else(|poisoned| poisoned.into_inner())
    }
}

static FORWARD: Recent<dyn RealToComplex<f64>> = Recent::new();
static INVERSE: Recent<dyn ComplexToReal<f64>> = Recent::new();
static HANN: Recent<[f64]> = Recent::new();

/// The forward real FFT of `len` points.
pub fn forward(len: usize) -> Arc<dyn RealToComplex<f64>> {
    FORWARD.get(len, || RealFftPlanner::<f64>::new().plan_fft_forward(len))
}

/// The inverse real FFT of `len` points (unnormalised, as realfft's).
pub fn inverse(len: usize) -> Arc<dyn ComplexToReal<f64>> {
    INVERSE.get(len, || RealFftPlanner::<f64>::new().plan_fft_inverse(len))
}

/// The periodic Hann window of `len` points ([`Window::Hann`]'s coefficients).
pub fn hann(len: usize) -> Arc<[f64]> {
    HANN.get(len, || Window::Hann.coefficients(len).into())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A shared plan transforms as a fresh one does, bit for bit, and is reused.
    #[test]
    fn shared_plans_match_fresh_ones_and_stay_bounded() {
        let n = 1000;
        let x: Vec<f64> = (0..n).map(|i| ((i * 7919) % 101) as f64 - 50.0).collect();
        let fresh = RealFftPlanner::<f64>::new().plan_fft_forward(n);
        let mut want = fresh.make_output_vec();
        fresh.process(&mut x.clone(), &mut want).unwrap();
        let shared = forward(n);
        let mut got = shared.make_output_vec();
        shared.process(&mut x.clone(), &mut got).unwrap();
        assert_eq!(got, want);
        assert!(
            Arc::ptr_eq(&shared, &forward(n)),
            "the second call reuses the plan"
        );
        let mut back = inverse(n).make_output_vec();
        inverse(n).process(&mut got, &mut back).unwrap();
        for (a, b) in back.iter().zip(&x) {
            assert!((a / n as f64 - b).abs() < 1e-9);
        }
    }

    /// The cache keeps the newest lengths only, and a length used again becomes newest.
    #[test]
    fn the_cache_keeps_the_most_recently_used() {
        let recent: Recent<[f64]> = Recent::new();
        let made = |len: usize| move || Arc::from(vec![len as f64; 1]);
        recent.get(1, made(1));
        for len in 2..=KEPT {
            recent.get(len, made(len));
        }
        recent.get(1, || unreachable!("length 1 is held"));
        recent.get(KEPT + 1, made(KEPT + 1));
        let held: Vec<usize> = recent.held().iter().map(|(l, _)| *l).collect();
        assert_eq!(held.len(), KEPT);
        assert_eq!(held[..2], [KEPT + 1, 1]);
        assert!(!held.contains(&2), "the least recently used went first");
    }

    /// The window is the periodic Hann window: 0 at the start, 1 at the middle, symmetric.
    #[test]
    fn hann_is_the_periodic_window() {
        let w = hann(8);
        assert_eq!(w[0], 0.0);
        assert!((w[4] - 1.0).abs() < 1e-15);
        for t in 1..8 {
            assert!((w[t] - w[8 - t]).abs() < 1e-15);
        }
    }
}
