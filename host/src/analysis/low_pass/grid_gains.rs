//! The folded gains of the search grid's cascades, kept from one detection to the next.
//!
//! The model workflow runs [`super::detect_outside`] on the measured record and on every
//! simulated realisation of its model: records of the same length and rate, so PSDs of the
//! same bins, searched over the same grid of cutoffs (which depends only on the rate and the
//! lowest cutoff searched). The grid's gains, `sum_j |H(f + j f_s)|^2 / sum_j |H(j f_s)|^2`
//! at every bin for every shape and grid cutoff, are then the same numbers in every
//! detection: computed once, they are looked up, bit for bit what computing them gives. The
//! cutoffs the refinement visits (Brent's method, from the grid's best) differ from one
//! record to the next and are computed each time.

use super::shape::Shape;
use std::collections::HashMap;
use std::hash::{DefaultHasher, Hash, Hasher};
use std::sync::{Arc, LazyLock, Mutex, MutexGuard};

/// Most gains kept (64 MB): the cache is emptied when an insertion would pass it. A model
/// run of 3 h at 100 Hz keeps about 1.3 million (the whole band's 27 cutoffs by 8 shapes
/// over about 500 bins, and the knee's 38 by 8 over up to 4096).
const MAX_VALUES: usize = 1 << 23;

/// Which gains: the shape, the bits of the cutoff and of the rate, and the bins'
/// fingerprint ([`fingerprint`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
struct Key {
    shape: Shape,
    cutoff: u64,
    rate: u64,
    bins: u64,
}

#[derive(Default)]
struct Cache {
    gains: HashMap<Key, Arc<[f64]>>,
    values: usize,
}

static CACHE: LazyLock<Mutex<Cache>> = LazyLock::new(Mutex::default);

/// The cache, whichever thread held it last: a panic elsewhere leaves its entries whole
/// (each is inserted complete), so a poisoned lock is still good.
fn cache() -> MutexGuard<'static, Cache> {
    CACHE
        .lock()
        .unwrap_or_else(|poisoned| poisoned.into_inner())
}

/// A fingerprint of a PSD's bin frequencies (Hz): their count and every bit of each.
pub(super) fn fingerprint(freq_hz: &[f64]) -> u64 {
    let mut h = DefaultHasher::new();
    freq_hz.len().hash(&mut h);
    for f in freq_hz {
        f.to_bits().hash(&mut h);
    }
    h.finish()
}

/// The gains of `shape` at `cutoff_hz` on the bins of fingerprint `bins` at `rate_hz`:
/// from the cache, or from `compute` (then kept).
pub(super) fn gains(
    shape: Shape,
    cutoff_hz: f64,
    rate_hz: f64,
    bins: u64,
    compute: impl FnOnce() -> Vec<f64>,
) -> Arc<[f64]> {
    let key = Key {
        shape,
        cutoff: cutoff_hz.to_bits(),
        rate: rate_hz.to_bits(),
        bins,
    };
    if let Some(g) = cache().gains.get(&key) {
        return Arc::clone(g);
    }
    let g: Arc<[f64]> = compute().into();
    let mut c = cache();
    if c.values + g.len() > MAX_VALUES {
        c.gains.clear();
        c.values = 0;
    }
    if c.gains.insert(key, Arc::clone(&g)).is_none() {
        c.values += g.len();
    }
    g
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A second request with the same key is served from the cache (`compute` not called);
    /// another cutoff, rate or set of bins is computed.
    #[test]
    fn the_same_key_is_computed_once() {
        let bins = fingerprint(&[0.5, 1.0, 1.5]);
        let calls = std::cell::Cell::new(0);
        let compute = || {
            calls.set(calls.get() + 1);
            vec![1.0, 0.5, 0.25]
        };
        // A cutoff no other test asks for: the cache is shared by the whole process.
        let cutoff = 12.345_678_9;
        let first = gains(Shape::Bartlett, cutoff, 97.0, bins, compute);
        let again = gains(Shape::Bartlett, cutoff, 97.0, bins, compute);
        assert_eq!(calls.get(), 1);
        assert_eq!(&first[..], &again[..]);
        gains(Shape::Bartlett, cutoff * 1.01, 97.0, bins, compute);
        gains(Shape::Bartlett, cutoff, 98.0, bins, compute);
        gains(
            Shape::Bartlett,
            cutoff,
            97.0,
            fingerprint(&[0.5, 1.0]),
            compute,
        );
        gains(Shape::MovingAverage, cutoff, 97.0, bins, compute);
        assert_eq!(calls.get(), 5);
    }
}
