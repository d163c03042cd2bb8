//! A Gauss-Markov term's maximum-likelihood correlation time and standard deviation, with
//! profile-likelihood intervals, in the cosine-transform view ([`super::cosine`]).
//!
//! The view's likelihood is that of the record's cosine coefficients up to 1 Hz, every term
//! of the model diagonal there, with the flicker and random-walk levels free beside the term
//! (they trade power with it) and the named regressors profiled out. Its four free
//! parameters are searched in logs: the grid's likeliest correlation time, refined by a
//! simplex over all four.
//!
//! Each parameter's interval is where `-2 ln L`, minimised over the other three, stays
//! within [`PROFILE_RISE`] of its minimum: by Wilks's theorem the rise is asymptotically
//! chi-square with one degree of freedom, so a rise of 1 bounds a 68.3 % interval (Venzon &
//! Moolgavkar, "A method for computing profile-likelihood-based confidence intervals",
//! Applied Statistics 37, 1988). A profile that stays below the rise up to the search's end
//! (a correlation time from [`SHORTEST_SAMPLES`] samples to the record's length, a variance
//! down to nothing) leaves that side open: the data bound it no further. Unlike an interval
//! from the curvature at the best point, a profile interval follows the likelihood's own
//! shape, which for a correlation time near the record's resolution is far from a parabola.

use super::cosine::CosineLikelihood;
use super::gls::nelder_mead_n;
use rayon::prelude::*;

/// The rise of `-2 ln L` over its minimum that bounds a 68.3 % profile interval.
pub const PROFILE_RISE: f64 = 1.0;
/// The shortest correlation time a profile searches, in samples.
pub const SHORTEST_SAMPLES: f64 = 10.0;
/// Bisection steps that place an interval's end once it is bracketed.
const BISECTIONS: usize = 8;
/// Log-levels searched, relative to the scale of each column at the first coefficient.
const LOG_RANGE: (f64, f64) = (-30.0, 30.0);

/// The term's estimate and its 68.3 % profile intervals (`None`: open on that side).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GaussMarkovFit {
    /// Correlation time, s.
    pub tau_c: f64,
    /// Standard deviation, u.
    pub sigma: f64,
    pub tau_c_interval: (Option<f64>, Option<f64>),
    pub sigma_interval: (Option<f64>, Option<f64>),
}

/// The parameters in logs: flicker level, random-walk level (each relative to its column's
/// scale), ln tau_c, and the term's variance relative to its scale.
struct Space<'a> {
    view: &'a CosineLikelihood,
    scale: [f64; 3],
    tau_range: (f64, f64),
}

impl Space<'_> {
    fn nll(&self, u: &[f64]) -> f64 {
        if !self.within(u) {
            return f64::INFINITY;
        }
        self.nll_with(u, &self.view.gauss_markov_column(u[2].exp()))
    }

    /// Whether `u` lies in the searched box.
    fn within(&self, u: &[f64]) -> bool {
        [0, 1, 3]
            .iter()
            .all(|&i| (LOG_RANGE.0..=LOG_RANGE.1).contains(&u[i]))
            && (self.tau_range.0..=self.tau_range.1).contains(&u[2])
    }

    /// [`Space::nll`] with the term's unit column of correlation time `exp(u[2])` given.
    fn nll_with(&self, u: &[f64], column: &[f64]) -> f64 {
        let v = self.view;
        v.nll(
            &[&v.flicker, &v.walk, column],
            &[
                self.scale[0] * u[0].exp(),
                self.scale[1] * u[1].exp(),
                self.scale[2] * u[3].exp(),
            ],
        )
    }

    /// The least nll with parameter `i` held at `x`, the others searched from `warm` (which
    /// is moved to where they end).
    fn profile(&self, i: usize, x: f64, warm: &mut [f64; 4]) -> f64 {
        let put = |w: &[f64]| -> Vec<f64> {
            let mut u = w.to_vec();
            u.insert(i, x);
            u
        };
        let others: Vec<f64> = (0..4).filter(|&j| j != i).map(|j| warm[j]).collect();
        // With the correlation time held, its column is the same at every evaluation: the
        // column (a sum over every coefficient up to 1 Hz) costs far more than the rest.
        let held = (i == 2).then(|| self.view.gauss_markov_column(x.exp()));
        let f = |w: &[f64]| {
            let u = put(w);
            match &held {
                Some(column) if self.within(&u) => self.nll_with(&u, column),
                Some(_) => f64::INFINITY,
                None => self.nll(&u),
            }
        };
        let coarse = nelder_mead_n(&f, &others, 0.3);
        let fine = nelder_mead_n(&f, &coarse, 0.05);
        let u = put(&fine);
        warm.copy_from_slice(&u);
        f(&fine)
    }

    /// Where parameter `i`'s profile rises [`PROFILE_RISE`] above `least` on the side of
    /// `direction`, stepping `step` from the best point `best` then bisecting; `None` when it
    /// does not before `limit`.
    fn crossing(
        &self,
        i: usize,
        best: &[f64; 4],
        least: f64,
        step: f64,
        limit: f64,
    ) -> Option<f64> {
        let target = least + PROFILE_RISE;
        let direction = (limit - best[i]).signum();
        let mut warm = *best;
        let mut inside = best[i];
        let outside = loop {
            let x = inside + direction * step;
            if (x - limit) * direction >= 0.0 {
                let mut at_limit = warm;
                return (self.profile(i, limit, &mut at_limit) > target)
                    .then(|| self.bisect(i, (inside, limit), target, &warm));
            }
            if self.profile(i, x, &mut warm) > target {
                break x;
            }
            inside = x;
        };
        Some(self.bisect(i, (inside, outside), target, &warm))
    }

    fn bisect(
        &self,
        i: usize,
        (mut inside, mut outside): (f64, f64),
        target: f64,
        warm: &[f64; 4],
    ) -> f64 {
        let mut warm = *warm;
        for _ in 0..BISECTIONS {
            let mid = 0.5 * (inside + outside);
            if self.profile(i, mid, &mut warm) > target {
                outside = mid;
            } else {
                inside = mid;
            }
        }
        0.5 * (inside + outside)
    }
}

impl CosineLikelihood {
    /// The Gauss-Markov term's maximum-likelihood fit and profile intervals, the searches
    /// started from flicker and random-walk levels `start` (B^2, K^2). `None` when the
    /// likelihood is nowhere finite.
    pub fn gauss_markov_fit(&self, start: [f64; 2]) -> Option<GaussMarkovFit> {
        let (_, levels) = self.without(start);
        let from = [
            levels.first().copied().unwrap_or(start[0]),
            levels.get(1).copied().unwrap_or(start[1]),
        ];
        // The grid's likeliest correlation time, with its levels.
        let fits: Vec<(f64, f64, Vec<f64>)> = self
            .grid
            .par_iter()
            .map(|(tau_c, column)| {
                let start = [from[0], from[1], self.fixed[0] / column[0]];
                let (nll, levels) =
                    self.likeliest(&[&self.flicker, &self.walk, column], &start, &[]);
                (nll, *tau_c, levels)
            })
            .collect();
        let (least, tau_c, best_levels) = fits.into_iter().min_by(|a, b| a.0.total_cmp(&b.0))?;
        if !least.is_finite() || best_levels.len() < 3 {
            return None;
        }
        let scale = [
            self.fixed[0] / self.flicker[0],
            self.fixed[0] / self.walk[0],
            self.fixed[0],
        ];
        let space = Space {
            view: self,
            scale,
            tau_range: ((SHORTEST_SAMPLES * self.tau0).ln(), self.duration.ln()),
        };
        let log_level = |level: f64, scale: f64| {
            (level.max(f64::MIN_POSITIVE) / scale)
                .ln()
                .clamp(LOG_RANGE.0 + 1.0, LOG_RANGE.1 - 1.0)
        };
        let u0 = [
            log_level(best_levels[0], scale[0]),
            log_level(best_levels[1], scale[1]),
            tau_c.ln(),
            log_level(best_levels[2], scale[2]),
        ];
        let f = |u: &[f64]| space.nll(u);
        let coarse = nelder_mead_n(&f, &u0, 0.3);
        let fine = nelder_mead_n(&f, &coarse, 0.05);
        let refined = f(&fine);
        let (best, least) = if refined < least {
            (fine, refined)
        } else {
            (u0.to_vec(), least)
        };
        let best: [f64; 4] = [best[0], best[1], best[2], best[3]];
        // Steps of 0.15 decades in tau_c and a factor 1.3 in sigma (0.5 in the variance's log).
        // The four ends are searched independently, side by side.
        let ends: Vec<Option<f64>> = [
            (2, 0.35, space.tau_range.0),
            (2, 0.35, space.tau_range.1),
            (3, 0.5, LOG_RANGE.0),
            (3, 0.5, LOG_RANGE.1),
        ]
        .par_iter()
        .map(|&(i, step, limit)| space.crossing(i, &best, least, step, limit))
        .collect();
        let (tau_ends, variance_ends) = ([ends[0], ends[1]], [ends[2], ends[3]]);
        let sigma_of = |u: f64| (scale[2] * u.exp()).sqrt();
        // A variance the profile never bounds from below is one the data cannot tell from none.
        let sigma_low = variance_ends[0].map_or(0.0, sigma_of);
        Some(GaussMarkovFit {
            tau_c: best[2].exp(),
            sigma: sigma_of(best[3]),
            tau_c_interval: (tau_ends[0].map(f64::exp), tau_ends[1].map(f64::exp)),
            sigma_interval: (Some(sigma_low), variance_ends[1].map(sigma_of)),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::families::{self, CI_SHAPE, Kind, Shape};

    /// How often the 68.3 % intervals of `count` family Gauss-Markov records of `shape` hold
    /// the generator's correlation time and standard deviation.
    fn coverage(shape: Shape, count: u64) -> (usize, usize) {
        let (mut tau_in, mut sigma_in) = (0, 0);
        for seed in 0..count {
            let hidden = families::generate(Kind::GaussMarkov, shape, 7000 + seed);
            let truth = hidden.terms.gauss_markov.expect("a Gauss-Markov record");
            let terms = &hidden.terms;
            let view = CosineLikelihood::new(
                &hidden.record.channels[0].values,
                shape.rate_hz,
                terms,
                None,
                &[],
            )
            .expect("an hour has coefficients to spare");
            let fit = view
                .gauss_markov_fit([terms.b * terms.b, terms.k * terms.k])
                .expect("a finite likelihood");
            let holds = |(lo, hi): (Option<f64>, Option<f64>), v: f64| {
                lo.is_none_or(|lo| lo <= v) && hi.is_none_or(|hi| v <= hi)
            };
            tau_in += usize::from(holds(fit.tau_c_interval, truth.tau_c));
            sigma_in += usize::from(holds(fit.sigma_interval, truth.sigma));
            eprintln!(
                "seed {seed}: tau_c {:.1} in {:?} (true {:.1}); sigma {:.3e} in {:?} (true {:.3e})",
                fit.tau_c,
                fit.tau_c_interval,
                truth.tau_c,
                fit.sigma,
                fit.sigma_interval,
                truth.sigma
            );
        }
        (tau_in, sigma_in)
    }

    /// Binomial(40, 0.683) lies within 27 +- 9 (3 standard deviations).
    #[test]
    fn profile_intervals_cover_at_their_level() {
        let (tau_in, sigma_in) = coverage(CI_SHAPE, 40);
        eprintln!("held: tau_c {tau_in}/40, sigma {sigma_in}/40");
        assert!((18..=36).contains(&tau_in), "tau_c: {tau_in}/40");
        assert!((18..=36).contains(&sigma_in), "sigma: {sigma_in}/40");
    }
}
