//! A gyro whose readings sit on a grid of whole counts, and readings moved to their cells'
//! centres.
//!
//! A digital gyro reports whole counts of its least significant bit `q`. How a rate becomes a
//! count differs: rounding to the nearest count leaves an error within `+-q/2`, zero on
//! average; truncation toward zero (Basilisk's `imuSensor` by default, and some ADCs) leaves
//! `-q/2 sign(w)` on average, an error that flips with the rate's sign. Away from zero it is a
//! constant offset a bias absorbs; on an axis whose rate crosses zero it is not, and it weighs
//! on the tensor when `q` is not small against the noise. Under truncation toward zero, count
//! `k` holds the rates `[k q, (k + 1) q)` for `k > 0`, `(k - 1) q, k q]` for `k < 0` and
//! `(-q, q)` for `k = 0`, whose centres are
//!
//! ```text
//! c(k q) = k q + sign(k) q / 2   (k != 0),   c(0) = 0                              (Q1)
//! ```
//!
//! The readings alone do not tell the two roundings apart (only the crossings of zero do, a
//! few samples each). `inertia identify` fits the log as read and, where the residual is
//! within a few counts, once more with (Q1) applied ([`centred`]), and keeps the one
//! whose residual is smaller: the two have the same parameters, so that is the likelier.
//!
//! [`detect`] finds `q` per axis from the distinct readings: with at most [`MAX_LEVELS`] of
//! them, the smallest gap between distinct readings (readings within a `1e-5` share of each
//! other being one: a scale in `f32` or a log's decimal printing moves them by less) gives a
//! first `q0`, refined by least squares through zero over the counts `k = round(v / q0)`,
//! `q = sum c_v |v| |k| / sum c_v k^2` (`c_v` the reading's count); the grid holds when every
//! reading is within [`GRID_SLACK`] of a count of `q` and the axis has at least [`MIN_LEVELS`]
//! counts.

use std::collections::HashMap;

use crate::readers::ReadError;
use crate::source::{Flow, MappedSource, Sample, Source};

/// Most distinct readings per axis looked at (a 16-bit gyro has 65536 counts).
pub const MAX_LEVELS: usize = 1 << 16;

/// Fewest distinct counts on an axis for a grid to be read from it.
pub const MIN_LEVELS: usize = 8;

/// Largest distance of a reading from its count, in counts, on a grid.
pub const GRID_SLACK: f64 = 0.02;

/// Distinct readings of an axis at which [`GridStats`] checks once that they sit on a grid,
/// letting the axis go if not (a continuous reading need not fill [`MAX_LEVELS`] first).
pub const EARLY_CHECK: usize = 4096;

/// Whether the distinct readings counted in `map` sit on a grid ([`grid_of`]).
fn on_grid(map: &HashMap<u32, u64>) -> bool {
    let values: Vec<(f32, u64)> = map.iter().map(|(&b, &c)| (f32::from_bits(b), c)).collect();
    grid_of(&values).is_some()
}

/// Readings closer than this share of their size are one count.
const SAME_COUNT: f64 = 1e-5;

/// The distinct readings of each gyro axis, counted while there are at most [`MAX_LEVELS`] of
/// them (an axis past that is dropped: its readings are not whole counts of a 16-bit gyro).
#[derive(Clone, Debug)]
pub struct GridStats {
    seen: [Option<HashMap<u32, u64>>; 3],
}

impl Default for GridStats {
    fn default() -> Self {
        GridStats {
            seen: [
                Some(HashMap::new()),
                Some(HashMap::new()),
                Some(HashMap::new()),
            ],
        }
    }
}

impl GridStats {
    /// The next sample's rates.
    #[inline]
    pub fn push(&mut self, w: [f32; 3]) {
        for (m, v) in self.seen.iter_mut().zip(w) {
            if let Some(map) = m {
                let before = map.len();
                *map.entry(v.to_bits()).or_insert(0) += 1;
                let n = map.len();
                // Continuous readings are let go once they have shown it, not at the cap.
                let off_grid = n > before && n == EARLY_CHECK && !on_grid(map);
                if n > MAX_LEVELS || off_grid {
                    *m = None;
                }
            }
        }
    }

    /// True when no axis can be on a grid any more.
    pub fn exhausted(&self) -> bool {
        self.seen.iter().all(Option::is_none)
    }

    /// The LSB of each axis, rad/s, when every axis's readings sit on a grid through zero
    /// ([`grid_of`]).
    pub fn lsb(&self) -> Option<[f32; 3]> {
        let mut lsb = [0.0f32; 3];
        for (q, m) in lsb.iter_mut().zip(&self.seen) {
            let values: Vec<(f32, u64)> = m
                .as_ref()?
                .iter()
                .map(|(&b, &c)| (f32::from_bits(b), c))
                .collect();
            *q = grid_of(&values)?;
        }
        Some(lsb)
    }
}

/// The LSB of each gyro axis, rad/s, when every axis's readings sit on a grid through zero
/// (`None` otherwise, or for a log with no reading): [`GridStats`] over one reading of `src`.
pub fn detect(src: &dyn Source) -> Result<Option<[f32; 3]>, ReadError> {
    let mut stats = GridStats::default();
    src.read_all(
        &mut |s: &Sample| {
            stats.push(s.gyro);
            Ok(if stats.exhausted() {
                Flow::Stop
            } else {
                Flow::Continue
            })
        },
        &mut |_| {},
    )?;
    Ok(stats.lsb())
}

/// The LSB of one axis's distinct readings with their counts, when they sit on a grid through
/// zero (module documentation).
pub fn grid_of(values: &[(f32, u64)]) -> Option<f32> {
    let mut v: Vec<(f64, u64)> = values
        .iter()
        .filter(|(x, _)| x.is_finite())
        .map(|&(x, c)| (f64::from(x), c))
        .collect();
    v.sort_by(|a, b| a.0.total_cmp(&b.0));
    // Distinct counts: readings within SAME_COUNT of each other are one.
    let mut levels: Vec<f64> = Vec::new();
    for &(x, _) in &v {
        match levels.last() {
            Some(&l) if x - l <= SAME_COUNT * x.abs().max(l.abs()) => {}
            _ => levels.push(x),
        }
    }
    if levels.len() < MIN_LEVELS {
        return None;
    }
    let q0 = levels
        .windows(2)
        .map(|w| w[1] - w[0])
        .fold(f64::INFINITY, f64::min);
    if !(q0 > 0.0 && q0.is_finite()) {
        return None;
    }
    let (mut num, mut den) = (0.0f64, 0.0f64);
    for &(x, c) in &v {
        let k = (x / q0).round();
        num += c as f64 * x.abs() * k.abs();
        den += c as f64 * k * k;
    }
    if den.is_nan() || den <= 0.0 {
        return None;
    }
    let q = num / den;
    let on_grid = v.iter().all(|&(x, _)| {
        let k = x / q;
        (k - k.round()).abs() <= GRID_SLACK
    });
    (on_grid && q > 0.0 && q.is_finite()).then_some(q as f32)
}

/// (Q1) for one reading on a grid of LSB `q`.
pub fn centre(v: f32, q: f32) -> f32 {
    let k = (v / q).round();
    if k == 0.0 {
        0.0
    } else {
        v + 0.5 * q * k.signum()
    }
}

/// (Q1) for every reading of a recording's gyro, axis by axis (LSB `lsb`).
pub fn centre_readings(gyro: &mut [[f32; 3]], lsb: [f32; 3]) {
    for w in gyro {
        for (x, q) in w.iter_mut().zip(lsb) {
            *x = centre(*x, q);
        }
    }
}

/// `inner` with every gyro reading moved to its count's centre under truncation toward zero
/// ((Q1), per axis LSB `lsb`).
pub fn centred(inner: &dyn Source, lsb: [f32; 3]) -> MappedSource<&dyn Source> {
    MappedSource::new(inner, centre, lsb, true)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Counts of 2.663e-4 rad/s as a CSV prints them (7 digits): the LSB to 1e-6; a reading
    /// off the grid, too few counts or continuous readings: none.
    #[test]
    fn finds_the_lsb_of_whole_counts_and_nothing_else() {
        let q = 2.663161e-4f64;
        let counts: Vec<(f32, u64)> = (-300i32..300)
            .map(|k| {
                let v: f32 = format!("{:.7}", k as f64 * q).parse().unwrap();
                (v, 3)
            })
            .collect();
        let found = grid_of(&counts).unwrap();
        assert!((f64::from(found) / q - 1.0).abs() < 1e-6, "{found}");
        let mut off = counts.clone();
        off.push((0.4 * q as f32, 1));
        assert_eq!(grid_of(&off), None);
        assert_eq!(grid_of(&counts[..5]), None);
        let smooth: Vec<(f32, u64)> = (0..1000).map(|i| ((i as f32).sin() * 0.3, 1)).collect();
        assert_eq!(grid_of(&smooth), None);
    }

    /// (Q1): counts move by half a count away from zero, zero stays.
    #[test]
    fn centres_move_half_a_count_away_from_zero() {
        let q = 0.5f32;
        assert_eq!(centre(0.0, q), 0.0);
        assert_eq!(centre(1.5, q), 1.75);
        assert_eq!(centre(-0.5, q), -0.75);
    }
}
