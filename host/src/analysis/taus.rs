//! Grids of averaging factors m (tau = m tau0) at which deviations are computed.

use std::fmt;
use std::str::FromStr;

/// A grid of averaging factors.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum TauGrid {
    /// 1, 2, 4, 8, ... (Stable32 "octave").
    Octave,
    /// 1, 2, 4, 10, 20, 40, 100, ... (Stable32 "decade").
    Decade,
    /// Every factor 1, 2, 3, ..., max.
    All,
    /// K log-spaced factors per decade: round(10^(i/K)), i = 0, 1, ..., de-duplicated.
    PerDecade(u32),
}

const CHOICES: &str = "octave, decade, all, per-decade:K (K = 1..=1000 factors per decade)";

/// Why a text is not a [`TauGrid`]; each holds the text.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum TauGridError {
    #[error("unknown tau grid '{0}': one of {CHOICES}")]
    Unknown(String),
    #[error(
        "bad tau grid '{0}': K in per-decade:K must be an integer 1..=1000; choices: {CHOICES}"
    )]
    BadK(String),
}

impl FromStr for TauGrid {
    type Err = TauGridError;
    fn from_str(s: &str) -> Result<Self, TauGridError> {
        match s.to_ascii_lowercase().as_str() {
            "octave" => Ok(TauGrid::Octave),
            "decade" => Ok(TauGrid::Decade),
            "all" => Ok(TauGrid::All),
            other => {
                let k = other
                    .strip_prefix("per-decade:")
                    .ok_or_else(|| TauGridError::Unknown(s.to_string()))?;
                match k.trim().parse::<u32>() {
                    Ok(k) if (1..=1000).contains(&k) => Ok(TauGrid::PerDecade(k)),
                    _ => Err(TauGridError::BadK(s.to_string())),
                }
            }
        }
    }
}

impl fmt::Display for TauGrid {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            TauGrid::Octave => f.write_str("octave"),
            TauGrid::Decade => f.write_str("decade"),
            TauGrid::All => f.write_str("all"),
            TauGrid::PerDecade(k) => write!(f, "per-decade:{k}"),
        }
    }
}

/// The averaging factors of `grid` up to and including `max_m`, ascending, without
/// duplicates. Empty when `max_m` is 0.
pub fn factors(grid: TauGrid, max_m: usize) -> Vec<usize> {
    match grid {
        TauGrid::All => (1..=max_m).collect(),
        TauGrid::Octave => geometric(max_m, &[1]).collect(),
        TauGrid::Decade => geometric(max_m, &[1, 2, 4]).collect(),
        TauGrid::PerDecade(k) => per_decade(k.max(1), max_m),
    }
}

/// `mantissas` × 1, 10, 100, ... for decades, or × 1, 2, 4, ... for octaves (a single
/// mantissa 1 means powers of two), up to `max_m`.
fn geometric(max_m: usize, mantissas: &'static [usize]) -> impl Iterator<Item = usize> {
    let base: usize = if mantissas.len() == 1 { 2 } else { 10 };
    (0u32..)
        .map_while(move |p| base.checked_pow(p))
        .take_while(move |&scale| scale <= max_m)
        .flat_map(move |scale| mantissas.iter().filter_map(move |&a| a.checked_mul(scale)))
        .take_while(move |&m| m <= max_m)
}

fn per_decade(k: u32, max_m: usize) -> Vec<usize> {
    let mut out: Vec<usize> = Vec::new();
    for i in 0u32.. {
        let m = 10f64.powf(f64::from(i) / f64::from(k)).round();
        if m > max_m as f64 {
            break;
        }
        let m = m as usize;
        if out.last() != Some(&m) {
            out.push(m);
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn octave_and_decade_grids() {
        assert_eq!(factors(TauGrid::Octave, 100), vec![1, 2, 4, 8, 16, 32, 64]);
        assert_eq!(factors(TauGrid::Octave, 64), vec![1, 2, 4, 8, 16, 32, 64]);
        assert_eq!(
            factors(TauGrid::Decade, 500),
            vec![1, 2, 4, 10, 20, 40, 100, 200, 400]
        );
        assert_eq!(factors(TauGrid::Decade, 3), vec![1, 2]);
        assert_eq!(factors(TauGrid::All, 4), vec![1, 2, 3, 4]);
        for g in [
            TauGrid::Octave,
            TauGrid::Decade,
            TauGrid::All,
            TauGrid::PerDecade(5),
        ] {
            assert!(factors(g, 0).is_empty(), "{g}");
            assert_eq!(factors(g, 1), vec![1], "{g}");
        }
        // No overflow near the top of usize.
        assert_eq!(
            factors(TauGrid::Octave, usize::MAX).len(),
            usize::BITS as usize
        );
    }

    #[test]
    fn per_decade_is_rounded_log_spacing_without_duplicates() {
        assert_eq!(
            factors(TauGrid::PerDecade(5), 100),
            vec![1, 2, 3, 4, 6, 10, 16, 25, 40, 63, 100]
        );
        let f = factors(TauGrid::PerDecade(20), 1000);
        assert!(f.windows(2).all(|w| w[0] < w[1]));
        assert_eq!((f[0], *f.last().unwrap()), (1, 1000));
        assert_eq!(factors(TauGrid::PerDecade(1), 999), vec![1, 10, 100]);
    }

    #[test]
    fn parse_and_display_round_trip() {
        for g in [
            TauGrid::Octave,
            TauGrid::Decade,
            TauGrid::All,
            TauGrid::PerDecade(7),
        ] {
            assert_eq!(g.to_string().parse::<TauGrid>(), Ok(g));
        }
        assert_eq!("OCTAVE".parse::<TauGrid>(), Ok(TauGrid::Octave));
        let e = "log".parse::<TauGrid>().unwrap_err();
        assert_eq!(e, TauGridError::Unknown("log".into()));
        assert_eq!(
            e.to_string(),
            "unknown tau grid 'log': one of octave, decade, all, per-decade:K (K = 1..=1000 factors per decade)"
        );
        let e = "per-decade:0".parse::<TauGrid>().unwrap_err();
        assert!(e.to_string().contains("1..=1000"), "{e}");
        assert!("per-decade:x".parse::<TauGrid>().is_err());
    }
}
