//! One [`Recording`] comes out of every reader: time, gyro, and the optional accelerometer and
//! rotor-speed channels, in SI units and in the log's own sensor axes (as logged, never
//! re-oriented: the tensor is reported in that frame). The type is the readers' own
//! ([`crate::readers`] make it), re-exported here with the statistics the layers
//! above take from a recording: its median time step ([`median_dt`]) and its gyro noise
//! ([`estimate_noise`], [`white_noise`]).

use crate::readers::gyro_filters::GyroFilters;
pub use crate::readers::{Recording, RotorSpeed};

impl Recording {
    /// The time variance of the gyro's filters and of the reader's interpolation, s^2 (0
    /// without filters), as the fits take it
    /// (`identifier_core::PipelineSettings::with_filtered_gyro`; [`GyroFilters::smoothing`]
    /// at the median time step).
    pub fn gyro_smoothing(&self) -> f32 {
        self.gyro_filters
            .as_ref()
            .map_or(0.0, |f| f.smoothing(median_dt(&self.t)) as f32)
    }

    /// The accelerometer at rest: its median magnitude over the longest run of samples whose
    /// every rate is below the gate's
    /// [`STILL_RATE`](identifier_core::free_flight::STILL_RATE) (the bench, as for the gyro's
    /// bias), over standard gravity. The median, because such a run ends where a hand lifts
    /// the body before it turns it: tens of milliseconds at well over 1 g. At rest `|f|` is one `g` in any orientation, so this is 1
    /// for an accelerometer true in m/s^2; one orientation cannot tell a scale error from a
    /// bias along gravity. `None` without an accelerometer or a still sample.
    pub fn accel_at_rest_g(&self) -> Option<f64> {
        let acc = self.accel.as_ref()?;
        let still = identifier_core::free_flight::STILL_RATE;
        let is_still = |i: usize| self.gyro[i].iter().all(|x| x.abs() < still);
        let n = self.gyro.len().min(acc.len());
        let (mut best, mut start) = (0..0, None);
        for i in 0..=n {
            match (i < n && is_still(i), start) {
                (true, None) => start = Some(i),
                (false, Some(s)) => {
                    if i - s > best.len() {
                        best = s..i;
                    }
                    start = None;
                }
                _ => {}
            }
        }
        let mut m: Vec<f64> = acc[best]
            .iter()
            .map(|f| f.iter().map(|&x| f64::from(x).powi(2)).sum::<f64>().sqrt())
            .filter(|m| m.is_finite())
            .collect();
        if m.is_empty() {
            return None;
        }
        let mid = m.len() / 2;
        let median = *m.select_nth_unstable_by(mid, f64::total_cmp).1;
        Some(median / f64::from(identifier_core::free_flight::G))
    }
}

/// Median time step of the recording, s.
pub fn median_dt(t: &[f64]) -> f64 {
    let mut d: Vec<f64> = t.windows(2).map(|w| w[1] - w[0]).collect();
    if d.is_empty() {
        return f64::NAN;
    }
    d.sort_by(|a, b| a.total_cmp(b));
    d[d.len() / 2]
}

/// Gyro white noise estimated from the data: the median absolute third difference per axis
/// (third differences cancel any quadratic motion; for white noise their variance is
/// `20 sigma^2`), read within its level when the gyro's counts put the differences on a grid
/// ([`level_median`], (N1)), turned into a standard deviation, smallest over the axes. Floored
/// at `1e-4 rad/s`.
pub fn estimate_noise(gyro: &[[f32; 3]]) -> f32 {
    noise_from_medians((0..3).map(|ax| {
        let mut d: Vec<f32> = gyro
            .windows(4)
            .map(|w| (w[3][ax] - 3.0 * w[2][ax] + 3.0 * w[1][ax] - w[0][ax]).abs())
            .filter(|x| x.is_finite())
            .collect();
        d.sort_by(|a, b| a.total_cmp(b));
        let largest = gyro
            .iter()
            .map(|w| w[ax].abs())
            .filter(|x| x.is_finite())
            .fold(0.0f32, f32::max);
        match crate::select::runs_of_sorted(&d) {
            Some(runs) => level_median(&runs, largest),
            None => d.get(d.len() / 2).copied(),
        }
    }))
}

/// Smallest share of all the differences on the median's level for the level to be read as a
/// level of the gyro's grid (a continuous reading has one or two per value).
pub const GRID_SHARE: f64 = 0.01;

/// Largest spread within one level of the grid, relative to the plain median: a log's decimal
/// printing or a scale applied to the counts moves them by less.
pub const LEVEL_SHARE: f64 = 0.01;

/// The median of the absolute third differences of one gyro axis, given as distinct values
/// with their counts (ascending), read within its level when the readings sit on a grid.
///
/// A quantised gyro's third differences are whole counts, so their plain median is a whole
/// count too, whatever the noise between levels. The differences of readings up to `largest`
/// in magnitude, taken in `f32`, scatter about their count by at most `16 largest eps_f32`
/// (eight readings' worth of rounding, twice), and a log's decimal printing or a scale on the
/// counts by a small share of a count, so values closer than `tol`, the larger of that bound
/// and [`LEVEL_SHARE`] of the plain median, are gathered into one level. With level `k` holding the median (`F_k <= N/2 < F_k +
/// c_k`, `F_k` the count below it, `c_k` its count, `m_k` its mean value), holding at least
/// [`GRID_SHARE`] of the `N` values, spanning at most `2 tol` and at least `8 tol` from its
/// nearest neighbour, the median is interpolated across the level's cell, as for grouped
/// data:
///
/// ```text
/// w = min(m_k - m_(k-1), m_(k+1) - m_k),   lo = max(m_k - w/2, 0),   hi = m_k + w/2
/// median = lo + (N/2 - F_k) / c_k (hi - lo)                                         (N1)
/// ```
///
/// On a moving body the rounding is then measured with the noise (`sigma^2 + LSB^2/12` when
/// the noise spans half a count or more), which is what a fit sees in each reading. Otherwise
/// it is the plain median, the element of rank `N/2`. `None` for no value.
pub fn level_median(runs: &[(f32, u64)], largest: f32) -> Option<f32> {
    let n: u64 = runs.iter().map(|&(_, c)| c).sum();
    if n == 0 {
        return None;
    }
    // Plain median: the element of rank n / 2.
    let rank = n / 2;
    let mut below = 0u64;
    let mut plain = None;
    for &(v, c) in runs {
        if rank < below + c {
            plain = Some(v);
            break;
        }
        below += c;
    }
    let tol = (16.0 * f64::from(largest) * f64::from(f32::EPSILON))
        .max(LEVEL_SHARE * f64::from(plain.unwrap_or(0.0)));
    // Levels: (mean value, count, count below, lowest value, highest value).
    let mut levels: Vec<(f64, u64, u64, f64, f64)> = Vec::new();
    let mut sum = 0.0f64;
    let mut seen = 0u64;
    for &(v, c) in runs {
        let v = f64::from(v);
        match levels.last_mut() {
            Some((m, lc, _, _, hi)) if v - *hi <= tol => {
                sum += v * c as f64;
                *lc += c;
                *m = sum / *lc as f64;
                *hi = v;
            }
            _ => {
                sum = v * c as f64;
                levels.push((v, c, seen, v, v));
            }
        }
        seen += c;
    }
    let k = levels.iter().position(|l| rank < l.2 + l.1)?;
    let (m, c, f, lo_v, hi_v) = levels[k];
    let gap_below = k.checked_sub(1).map(|i| m - levels[i].0);
    let gap_above = levels.get(k + 1).map(|l| l.0 - m);
    let w = match (gap_below, gap_above) {
        (Some(a), Some(b)) => a.min(b),
        (Some(a), None) => a,
        (None, Some(b)) => b,
        (None, None) => return plain,
    };
    let grid = (c as f64) >= GRID_SHARE * n as f64 && hi_v - lo_v <= 2.0 * tol && w >= 8.0 * tol;
    if !grid {
        return plain;
    }
    let lo = (m - 0.5 * w).max(0.0);
    let hi = m + 0.5 * w;
    let frac = ((n as f64 / 2.0 - f as f64) / c as f64).clamp(0.0, 1.0);
    Some((lo + frac * (hi - lo)) as f32)
}

/// The white noise the fits assume, from the noise `measured` by [`estimate_noise`] on a log
/// of step `log_dt` whose gyro has passed through `filters` ((G2) of
/// [`GyroFilters::white_noise`]); `measured` itself without filters.
pub fn white_noise(measured: f32, filters: Option<&GyroFilters>, log_dt: f64) -> f32 {
    match filters {
        Some(f) => f.white_noise(f64::from(measured), log_dt) as f32,
        None => measured,
    }
}

/// The noise from each axis's median absolute third difference (`None` for an axis without
/// one): the median turned into a standard deviation (third differences of white noise have
/// variance `20 sigma^2`), smallest over the axes, floored at `1e-4 rad/s`; `2e-3` when no axis
/// has a difference. Shared by [`estimate_noise`] and the streaming survey, so both give the
/// same bits.
pub(crate) fn noise_from_medians(medians: impl IntoIterator<Item = Option<f32>>) -> f32 {
    let mut best = f32::INFINITY;
    for mad in medians.into_iter().flatten() {
        let s = mad / 0.6745 / 20f32.sqrt();
        if s < best {
            best = s;
        }
    }
    if best.is_finite() {
        best.max(1e-4)
    } else {
        2e-3
    }
}
