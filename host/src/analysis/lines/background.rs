//! The smooth background PSD under the lines: running medians of block medians, in ln-ln
//! (module documentation of [`super`], step 2).

use super::scan::DOF_GRID;
use super::{BLOCKS_PER_DECADE, MEDIAN_HALF_WIDTH, MIN_BLOCK, SHAPE_ERROR};

/// Rounds of halving the blocks on a null's fall (each at most doubles a block's count;
/// eight take a 2048-bin block to the least).
const MAX_SPLIT_ROUNDS: usize = 8;

/// A block's bins `[start, end)` and its (ln centre bin, ln level, bins used).
type Block = ((usize, usize), (f64, f64, usize));
use std::f64::consts::LN_2;
use std::sync::atomic::{AtomicUsize, Ordering};

/// A smooth background PSD per bin, the relative variance of its estimate, and the degrees of
/// freedom `nu = 2 / rel_var` of the scaled chi-square that stands for it, rounded down to
/// the grid `2 DOF_GRID^bucket`. Held as the smoothed blocks and interpolated where it is
/// read (a value per bin would be as large as the record).
pub(super) struct Background {
    /// (ln centre bin, ln level, relative variance) per block, in increasing frequency.
    blocks: Vec<(f64, f64, f64)>,
    /// The block found last by [`Background::level`]: bins are mostly read in order, so
    /// the next one is usually found there without a search. A thread reading many bins
    /// beside others takes a [`Cursor`] with a hint of its own.
    hint: AtomicUsize,
}

impl Background {
    /// The level at bin k (one-sided PSD), interpolated linearly in ln-ln between block
    /// centres; constant beyond the first and last.
    pub(super) fn level(&self, k: usize) -> f64 {
        level_of(self.at(k))
    }

    /// The lowest [`Background::level`] over bins `lo..=hi` (`1 <= lo <= hi`): the level is
    /// monotone between block centres and constant beyond the ends, so it is the least of
    /// the levels at the ends and at the centres between them.
    pub(super) fn lowest(&self, lo: usize, hi: usize) -> f64 {
        let (x_lo, x_hi) = ((lo.max(1) as f64).ln(), (hi.max(1) as f64).ln());
        let first = self.blocks.partition_point(|b| b.0 <= x_lo);
        let inside = self.blocks[first..]
            .iter()
            .take_while(|b| b.0 < x_hi)
            .map(|b| b.1.exp().max(f64::MIN_POSITIVE));
        inside.fold(self.level(lo).min(self.level(hi)), f64::min)
    }

    /// The least relative variance at any bin (interpolation stays between blocks' values).
    pub(super) fn least_rel_var(&self) -> f64 {
        self.blocks.iter().map(|b| b.2).fold(1.0, f64::min)
    }

    /// A reader of this background with its own hint, for one thread reading bins mostly in
    /// order: the shared hint of [`Background::level`], written by every read, would travel
    /// between the cores of threads reading different ranges at every bin.
    pub(super) fn cursor(&self) -> Cursor<'_> {
        Cursor {
            background: self,
            hint: 0,
        }
    }

    /// (ln level, relative variance) at bin k >= 1; None at bin 0 or without blocks.
    fn at(&self, k: usize) -> Option<(f64, f64)> {
        let mut hint = self.hint.load(Ordering::Relaxed);
        let found = self.at_from(k, &mut hint);
        self.hint.store(hint, Ordering::Relaxed);
        found
    }

    /// [`Background::at`], looking first at the block `hint` (and leaving there the block
    /// found).
    fn at_from(&self, k: usize, hint: &mut usize) -> Option<(f64, f64)> {
        let smoothed = &self.blocks;
        if k == 0 || smoothed.is_empty() {
            return None;
        }
        let x = (k as f64).ln();
        // The last block whose centre is at or below x (the first when none is).
        let h = *hint;
        let i = if h + 1 < smoothed.len() && smoothed[h].0 <= x && x < smoothed[h + 1].0 {
            h
        } else {
            smoothed.partition_point(|b| b.0 <= x).saturating_sub(1)
        };
        *hint = i;
        Some(if x <= smoothed[0].0 {
            (smoothed[0].1, smoothed[0].2)
        } else if i + 1 >= smoothed.len() {
            (smoothed[i].1, smoothed[i].2)
        } else {
            let (a, b) = (smoothed[i], smoothed[i + 1]);
            let w = (x - a.0) / (b.0 - a.0);
            (a.1 + w * (b.1 - a.1), a.2 + w * (b.2 - a.2))
        })
    }
}

/// One thread's reader of a [`Background`] ([`Background::cursor`]): the same values as the
/// background's own methods.
pub(super) struct Cursor<'a> {
    background: &'a Background,
    hint: usize,
}

impl Cursor<'_> {
    /// [`Background::level`].
    pub(super) fn level(&mut self, k: usize) -> f64 {
        level_of(self.background.at_from(k, &mut self.hint))
    }

    /// The relative variance of [`Background::level`] at bin k.
    pub(super) fn rel_var(&mut self, k: usize) -> f64 {
        self.background
            .at_from(k, &mut self.hint)
            .map_or(1.0, |(_, var)| var)
    }

    /// The degrees of freedom at bin k on the grid `2 DOF_GRID^bucket`.
    pub(super) fn bucket(&mut self, k: usize) -> i32 {
        bucket_of(self.rel_var(k))
    }
}

/// The level (one-sided PSD) of what [`Background::at`] found.
fn level_of(at: Option<(f64, f64)>) -> f64 {
    at.map_or(f64::MIN_POSITIVE, |(ln_level, _)| {
        ln_level.exp().max(f64::MIN_POSITIVE)
    })
}

/// The bucket of degrees of freedom `2 / rel_var` on the grid `2 DOF_GRID^bucket`.
fn bucket_of(rel_var: f64) -> i32 {
    ((1.0 / rel_var).max(1.0).ln() / DOF_GRID.ln()).floor() as i32
}

/// The running-median background of `power` over bins 3..=k_hi, leaving out masked bins
/// (module documentation, step 2); `median_variance` is the constant c of its relative
/// variance `c / n_w`.
pub(super) fn background(
    power: impl Fn(usize) -> f64,
    mask: &[bool],
    k_hi: usize,
    widest: usize,
    median_variance: f64,
) -> Background {
    // Blocks 1/40 decade wide, at least MIN_BLOCK bins and at most half the widest line.
    let growth = 10f64.powf(1.0 / BLOCKS_PER_DECADE) - 1.0;
    let most = (widest / 2).max(MIN_BLOCK);
    let mut spans: Vec<(usize, usize)> = Vec::new();
    // Bins 1 and 2 share power with the mean and slope the search removes first.
    let mut start = 3;
    while start <= k_hi {
        let width = ((start as f64 * growth) as usize).clamp(MIN_BLOCK, most);
        let end = (start + width).min(k_hi + 1);
        spans.push((start, end));
        start = end;
    }
    let mut values = Vec::new();
    let mut level_of_span = |(start, end): (usize, usize)| -> Option<(f64, f64, usize)> {
        values.clear();
        values.extend((start..end).filter(|&k| !mask[k]).map(&power));
        if values.len() * 2 < end - start || values.len() < 3 {
            return None;
        }
        // An odd count, so that the median is one order statistic.
        let m = values.len() - (1 - values.len() % 2);
        let (_, median, _) = values[..m].select_nth_unstable_by(m / 2, f64::total_cmp);
        let level = *median / LN_2;
        let centre = 0.5 * (start + end - 1) as f64;
        (level > 0.0).then(|| (centre.ln(), level.ln(), m))
    };
    let mut measured: Vec<Block> = spans
        .iter()
        .filter_map(|&span| level_of_span(span).map(|b| (span, b)))
        .collect();
    let mut smoothed = smooth(&measured, median_variance);
    // A digital filter run at the output rate has a zero at Nyquist (a bilinear filter's PSD
    // falls as cos^4 there), and its ln PSD bends down so fast that the chord between block
    // centres lies up to a factor 4 below it, which the bins would stand out against. Blocks
    // on such a fall are halved, while they have the bins, until the chord (an eighth of the
    // levels' second difference) stays within SHAPE_ERROR or within the levels' own noise.
    // Only a fall that steepens all the way to the last block is taken for a null: a line's
    // flank levels out again beyond it, and splitting there would let the line into the
    // running median.
    for _ in 0..MAX_SPLIT_ROUNDS {
        let last = smoothed.len().saturating_sub(1);
        let falls_to_end = |i: usize| (i..last).all(|j| smoothed[j + 1].1 < smoothed[j].1);
        let bent: Vec<bool> = (0..smoothed.len())
            .map(|i| {
                if i == 0 || i >= last || !falls_to_end(i - 1) {
                    return false;
                }
                let (a, b, c) = (smoothed[i - 1], smoothed[i], smoothed[i + 1]);
                // The levels' second derivative in ln frequency (spacings unequal), the
                // chord's largest departure from the curve over the wider spacing, and that
                // departure's own noise (a second difference of the smoothed levels).
                let (h0, h1) = (b.0 - a.0, c.0 - b.0);
                let bend = 2.0 * ((c.1 - b.1) / h1 - (b.1 - a.1) / h0) / (h0 + h1);
                let chord = -bend * h0.max(h1).powi(2) / 8.0;
                let noise = (a.2 + 4.0 * b.2 + c.2).sqrt() / 8.0;
                chord > SHAPE_ERROR && chord > 4.0 * noise
            })
            .collect();
        let mut next = Vec::with_capacity(measured.len() + 8);
        for (i, &(span, block)) in measured.iter().enumerate() {
            let (lo, hi) = span;
            if bent[i] && hi - lo >= 2 * MIN_BLOCK {
                let mid = lo + (hi - lo) / 2;
                for half in [(lo, mid), (mid, hi)] {
                    if let Some(b) = level_of_span(half) {
                        next.push((half, b));
                    }
                }
            } else {
                next.push((span, block));
            }
        }
        if next.len() == measured.len() {
            break;
        }
        measured = next;
        smoothed = smooth(&measured, median_variance);
    }
    let smoothed: Vec<(f64, f64, f64)> = smoothed
        .into_iter()
        .map(|(centre, level, rel_var)| (centre, level, rel_var + SHAPE_ERROR * SHAPE_ERROR))
        .collect();
    Background {
        blocks: smoothed,
        hint: AtomicUsize::new(0),
    }
}

/// The running median over blocks (`(span, (ln centre, ln level, bins))`): per block its ln
/// centre, smoothed ln level, and that level's relative variance from the medians alone
/// (`median_variance / bins` times the window's leverage).
fn smooth(blocks: &[Block], median_variance: f64) -> Vec<(f64, f64, f64)> {
    let blocks: Vec<(f64, f64, usize)> = blocks.iter().map(|b| b.1).collect();
    (0..blocks.len())
        .map(|i| {
            // Near the lowest frequencies the window is pushed up (few bins there; see
            // window_level); near Nyquist it shrinks, staying centred (many bins there, and
            // a low-pass filter can bend the spectrum sharply).
            let last = blocks.len() - 1;
            let h = MEDIAN_HALF_WIDTH.min(last - i);
            let span = (2 * h + 1).min(blocks.len());
            let first = i.saturating_sub(h).min(blocks.len() - span);
            let window = &blocks[first..first + span];
            let bins: usize = window.iter().map(|b| b.2).sum();
            let (level, leverage) = window_level(window, i - first);
            (blocks[i].0, level, median_variance / bins as f64 * leverage)
        })
        .collect()
}

/// The background's ln level at block `at` of a window of blocks (ln centre, ln level), and
/// the factor by which its variance exceeds that at the window's centre. A window centred on
/// `at` gives its median (exact for any monotone trend). A window that the ends of the
/// spectrum push off-centre gives the median of the levels moved along the window's
/// Theil-Sen line in ln-ln (the median of pairwise slopes; Sen, "Estimates of the regression
/// coefficient based on Kendall's tau", JASA 63, 1968), so that a power law is not read
/// off-centre; its variance grows as for a line fitted by least squares, `1 + 3 x^2`, x the
/// offset from the window's centre in half-widths.
fn window_level(window: &[(f64, f64, usize)], at: usize) -> (f64, f64) {
    let mid = window.len() / 2;
    let mut levels: Vec<f64> = window.iter().map(|b| b.1).collect();
    if at == mid || window.len() < 3 {
        let half = levels.len() / 2;
        let (_, median, _) = levels.select_nth_unstable_by(half, f64::total_cmp);
        return (*median, 1.0);
    }
    let mut slopes = Vec::with_capacity(window.len() * (window.len() - 1) / 2);
    for i in 0..window.len() {
        for j in i + 1..window.len() {
            slopes.push((window[j].1 - window[i].1) / (window[j].0 - window[i].0));
        }
    }
    let half = slopes.len() / 2;
    let (_, slope, _) = slopes.select_nth_unstable_by(half, f64::total_cmp);
    let slope = *slope;
    let x0 = window[at].0;
    for (l, b) in levels.iter_mut().zip(window) {
        *l -= slope * (b.0 - x0);
    }
    let half = levels.len() / 2;
    let (_, median, _) = levels.select_nth_unstable_by(half, f64::total_cmp);
    let offset = (at as f64 - mid as f64) / mid.max(1) as f64;
    (*median, 1.0 + 3.0 * offset * offset)
}
