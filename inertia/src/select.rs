//! The exact k-th smallest of a long stream of numbers in bounded memory.
//!
//! `identify` takes medians over the whole log (the time step, the gyro's third differences);
//! its report must stay bit for bit what sorting every value gives. A median of millions of
//! values cannot be kept exactly in bounded memory in one reading in general, but the log can
//! be read again, so this is a radix selection over the values' ordered bit patterns:
//!
//! * each reading counts the values in 65536 buckets of the next 16 bits (among the values
//!   whose higher bits match the ones already fixed), which fixes 16 more bits of the answer:
//!   an `f32` is exact after two readings, an `f64` after four;
//! * alongside, the distinct values are counted exactly while there are at most
//!   [`DISTINCT_CAP`] of them. Logged gyro rates are quantised (ADC counts) and time steps
//!   take a handful of values, so this usually answers after the first reading (the 10-minute
//!   bench log: 22 distinct time steps, about 3400 distinct third differences per axis).
//!
//! Memory: one 512 KiB histogram and at most [`DISTINCT_CAP`] map entries per selection.
//! Values are ordered as `total_cmp` orders them (the order `sort_by(total_cmp)` gave).

use std::collections::HashMap;
use std::hash::{BuildHasherDefault, Hasher};

/// Distinct values counted exactly before falling back to the buckets.
pub const DISTINCT_CAP: usize = 1 << 16;

const DIGIT: u32 = 16;
const BUCKETS: usize = 1 << DIGIT;

/// A value with a total order, mapped to an unsigned key of the same order.
pub trait Ordered: Copy {
    /// Bits in the key (32 or 64).
    const BITS: u32;
    /// The key: unsigned, ordered as `total_cmp` orders the values.
    fn key(self) -> u64;
    /// The value of a key.
    fn from_key(k: u64) -> Self;
}

impl Ordered for f64 {
    const BITS: u32 = 64;
    fn key(self) -> u64 {
        let b = self.to_bits();
        if b >> 63 == 1 {
            !b
        } else {
            b | 1 << 63
        }
    }
    fn from_key(k: u64) -> Self {
        f64::from_bits(if k >> 63 == 1 { k & !(1 << 63) } else { !k })
    }
}

impl Ordered for f32 {
    const BITS: u32 = 32;
    fn key(self) -> u64 {
        let b = self.to_bits();
        u64::from(if b >> 31 == 1 { !b } else { b | 1 << 31 })
    }
    fn from_key(k: u64) -> Self {
        let k = k as u32;
        f32::from_bits(if k >> 31 == 1 { k & !(1 << 31) } else { !k })
    }
}

/// A cheap hasher for the distinct-value map (keys are bit patterns, not attacker-chosen).
#[derive(Default)]
struct MixHasher(u64);

impl Hasher for MixHasher {
    fn finish(&self) -> u64 {
        self.0
    }
    fn write(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.write_u64(u64::from(b));
        }
    }
    fn write_u64(&mut self, x: u64) {
        self.0 = (self.0.rotate_left(5) ^ x).wrapping_mul(0x9E37_79B9_7F4A_7C15);
    }
}

type Distinct = HashMap<u64, u64, BuildHasherDefault<MixHasher>>;

/// The element of rank `len / 2` (0-based) in `total_cmp` order: the median as
/// `v.sort_by(total_cmp); v[v.len() / 2]` gives it.
#[derive(Clone, Debug)]
pub struct Median<T: Ordered> {
    /// Bits of the answer fixed by the readings so far (from the top).
    fixed: u32,
    /// Those bits.
    prefix: u64,
    /// Rank of the answer among the values that match `prefix` (known after the first reading).
    rank: u64,
    /// Counts of the next 16 bits in this reading.
    hist: Vec<u64>,
    /// Exact counts of the matching values, dropped past [`DISTINCT_CAP`] of them.
    distinct: Option<Distinct>,
    /// Values seen in this reading (all of them in the first).
    seen: u64,
    /// The answer once known; `Some(None)` when there was no value at all.
    result: Option<Option<T>>,
    /// Every distinct value with its count, ascending, when the answer came from the exact
    /// counts (at most [`DISTINCT_CAP`] distinct values).
    runs: Option<Vec<(T, u64)>>,
}

impl<T: Ordered> Default for Median<T> {
    fn default() -> Self {
        Self::new()
    }
}

impl<T: Ordered> Median<T> {
    /// Nothing seen yet.
    pub fn new() -> Self {
        Median {
            fixed: 0,
            prefix: 0,
            rank: 0,
            hist: vec![0; BUCKETS],
            distinct: Some(Distinct::default()),
            seen: 0,
            result: None,
            runs: None,
        }
    }

    /// The answer, once the readings have fixed it: `Some(None)` for an empty stream.
    pub fn result(&self) -> Option<Option<T>> {
        self.result
    }

    /// Every distinct value with its count, ascending, once the answer is known and there were
    /// at most [`DISTINCT_CAP`] distinct values (`None` otherwise): what
    /// [`runs_of_sorted`] gives for the same values.
    pub fn runs(&self) -> Option<&[(T, u64)]> {
        self.runs.as_deref()
    }

    /// True while another reading of the same values is needed.
    pub fn needs_reading(&self) -> bool {
        self.result.is_none()
    }

    /// One value of the current reading (every reading must present the same values).
    #[inline]
    pub fn push(&mut self, v: T) {
        if self.result.is_some() {
            return;
        }
        let k = v.key();
        if self.fixed > 0 && k >> (T::BITS - self.fixed) != self.prefix {
            return;
        }
        self.seen += 1;
        let shift = T::BITS - self.fixed - DIGIT;
        let digit = ((k >> shift) as usize) & (BUCKETS - 1);
        if let Some(h) = self.hist.get_mut(digit) {
            *h += 1;
        }
        if let Some(d) = &mut self.distinct {
            *d.entry(k).or_insert(0) += 1;
            if d.len() > DISTINCT_CAP {
                self.distinct = None;
            }
        }
    }

    /// Ends a reading: fixes 16 more bits, or the answer. Call [`Self::needs_reading`] next.
    pub fn end_reading(&mut self) {
        if self.result.is_some() {
            return;
        }
        if self.fixed == 0 {
            if self.seen == 0 {
                self.result = Some(None);
                return;
            }
            self.rank = self.seen / 2;
        }
        if let Some(d) = self.distinct.take() {
            let mut keys: Vec<(u64, u64)> = d.into_iter().collect();
            keys.sort_unstable_by_key(|&(k, _)| k);
            let mut below = 0u64;
            for &(k, c) in &keys {
                if self.rank < below + c {
                    self.result = Some(Some(T::from_key(k)));
                    self.runs = Some(keys.iter().map(|&(k, c)| (T::from_key(k), c)).collect());
                    return;
                }
                below += c;
            }
        }
        let mut below = 0u64;
        let mut digit = 0u64;
        for (d, &c) in self.hist.iter().enumerate() {
            if self.rank < below + c {
                digit = d as u64;
                break;
            }
            below += c;
        }
        self.rank -= below;
        self.prefix = (self.prefix << DIGIT) | digit;
        self.fixed += DIGIT;
        if self.fixed >= T::BITS {
            self.result = Some(Some(T::from_key(self.prefix)));
            return;
        }
        self.hist.iter_mut().for_each(|h| *h = 0);
        self.distinct = Some(Distinct::default());
        self.seen = 0;
    }
}

/// Every distinct value of `sorted` (ascending in `total_cmp` order) with its count, when there
/// are at most [`DISTINCT_CAP`] of them (`None` otherwise): what [`Median::runs`] gives for the
/// same values read as a stream.
pub fn runs_of_sorted<T: Ordered>(sorted: &[T]) -> Option<Vec<(T, u64)>> {
    let mut runs: Vec<(T, u64)> = Vec::new();
    for &v in sorted {
        match runs.last_mut() {
            Some((last, c)) if last.key() == v.key() => *c += 1,
            _ => {
                if runs.len() == DISTINCT_CAP {
                    return None;
                }
                runs.push((v, 1));
            }
        }
    }
    Some(runs)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn reference<T: Ordered>(v: &[T], cmp: impl Fn(&T, &T) -> std::cmp::Ordering) -> Option<T> {
        let mut s = v.to_vec();
        s.sort_by(cmp);
        s.get(s.len() / 2).copied()
    }

    fn select<T: Ordered>(v: &[T]) -> (Option<T>, usize) {
        let mut m = Median::<T>::new();
        let mut readings = 0;
        while m.needs_reading() {
            readings += 1;
            for &x in v {
                m.push(x);
            }
            m.end_reading();
        }
        (m.result().flatten(), readings)
    }

    /// xorshift, reproducible.
    fn rng(seed: u64) -> impl FnMut() -> u64 {
        let mut s = seed | 1;
        move || {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            s
        }
    }

    #[test]
    fn keys_keep_total_order() {
        let v = [
            f64::NEG_INFINITY,
            -1.0,
            -0.0,
            0.0,
            1e-300,
            1.0,
            f64::INFINITY,
            f64::NAN,
        ];
        for w in v.windows(2) {
            assert!(w[0].key() < w[1].key(), "{w:?}");
            assert_eq!(f64::from_key(w[0].key()).to_bits(), w[0].to_bits());
        }
        let v = [f32::NEG_INFINITY, -2.5, -0.0, 0.0, 3.0, f32::NAN];
        for w in v.windows(2) {
            assert!(w[0].key() < w[1].key(), "{w:?}");
            assert_eq!(f32::from_key(w[0].key()).to_bits(), w[0].to_bits());
        }
    }

    #[test]
    fn exact_on_few_and_many_distinct_values() {
        let mut r = rng(7);
        // Few distinct values: one reading.
        let v: Vec<f32> = (0..100_001).map(|_| (r() % 50) as f32 * 0.125).collect();
        assert_eq!(select(&v), (reference(&v, f32::total_cmp), 1));
        // Many distinct f32 (uniform bits, any sign, NaN included): two readings.
        let v: Vec<f32> = (0..200_000).map(|_| f32::from_bits(r() as u32)).collect();
        let (got, n) = select(&v);
        assert_eq!(
            got.map(f32::to_bits),
            reference(&v, f32::total_cmp).map(f32::to_bits)
        );
        assert_eq!(n, 2);
        // Many distinct f64 close together (time steps with rounding noise): up to four.
        let v: Vec<f64> = (0..150_000)
            .map(|_| 1.25e-4 + (r() % 1_000_000) as f64 * 1e-19)
            .collect();
        let (got, n) = select(&v);
        assert_eq!(got, reference(&v, f64::total_cmp));
        assert!(n <= 4);
        // Even and odd counts, one value, none.
        for len in [1usize, 2, 3, 4, 65_537, 65_538] {
            let v: Vec<f64> = (0..len).map(|_| f64::from_bits(r() >> 2)).collect();
            assert_eq!(select(&v).0, reference(&v, f64::total_cmp), "{len}");
        }
        assert_eq!(select::<f64>(&[]).0, None);
    }
}
