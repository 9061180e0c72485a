//! Rotor speed reconstructed from a sample-and-hold telemetry channel ([`unhold`]), and the
//! same reconstruction sample by sample with a bounded lookahead ([`Unhold`]).
//!
//! The value at a sample interpolates between the last knot at or before it and the next one,
//! and the next knot is only known at the next change of the logged value, which can be far
//! ahead (a rotor held at one speed for seconds). The streaming version keeps samples waiting
//! for at most [`LOOKAHEAD`] samples; the knots a sample would wait longer for are noted by
//! a first reading of the log ([`Planner`]): at most two per [`LOOKAHEAD`] samples, and in
//! practice a handful per log (a long hold is a rotor at rest or at a set speed).

use std::collections::VecDeque;

/// Samples a sample may wait for its next knot before the noted knots are used.
pub const LOOKAHEAD: usize = 8192;

/// Rotor speed reconstructed from a sample-and-hold telemetry channel.
///
/// ESC telemetry (eRPM) arrives every one to a few milliseconds and the log holds each value
/// until the next: a staircase that lags the true speed by about half an update interval. On
/// the thrown-FC logs this lag is the largest effect the model lacks (the residual of the
/// rotor axis follows the rotor's speed changes closely). Each new value is taken as the
/// speed at the middle of the interval it replaced and the speed is interpolated linearly
/// between those points; before the first change the log is kept as it is (a rotor at rest).
pub fn unhold(t: &[f64], speed: &[f32]) -> Vec<f32> {
    let n = speed.len().min(t.len());
    let mut knots: Vec<(f64, f32)> = Vec::new();
    let mut prev_change = 0usize;
    for i in 1..n {
        if speed[i] != speed[i - 1] {
            knots.push((0.5 * (t[i] + t[prev_change]), speed[i]));
            prev_change = i;
        }
    }
    if knots.len() < 2 {
        return speed.to_vec();
    }
    let first_change = {
        let mut k = 1;
        while k < n && speed[k] == speed[k - 1] {
            k += 1;
        }
        k
    };
    let mut out = speed[..n].to_vec();
    let mut j = 0usize;
    for (i, o) in out.iter_mut().enumerate().skip(first_change) {
        let ti = t[i];
        while j + 1 < knots.len() && knots[j + 1].0 <= ti {
            j += 1;
        }
        let (t0, v0) = knots[j];
        *o = if j + 1 < knots.len() && ti >= t0 {
            let (t1, v1) = knots[j + 1];
            let f = ((ti - t0) / (t1 - t0)) as f32;
            v0 + (v1 - v0) * f
        } else if ti < t0 {
            // Between the first change and the first knot's time: interpolate from the held
            // value before it.
            let (tp, vp) = (t[first_change - 1], speed[first_change - 1]);
            let f = ((ti - tp) / (t0 - tp)) as f32;
            vp + (v0 - vp) * f
        } else {
            v0
        };
    }
    out
}

/// A knot: the speed `v` taken at time `t`, the `ordinal`-th change of the logged value.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Knot {
    /// Which change (0-based).
    pub ordinal: u64,
    /// Middle of the interval the new value replaced, s.
    pub t: f64,
    /// The new value.
    pub v: f32,
}

/// How the rotor-speed channel's held values become a speed per sample.
///
/// ESC telemetry holds each value until the next. Fast telemetry (bidirectional DShot eRPM,
/// a new value every millisecond or so) is best taken as logged: on the thrown-FC logs the
/// staircase gives the board's throws closer tensors and the proof body a smaller
/// leave-one-out error than the interpolation, and a lag scan of the rotor fit
/// (`inertia close-loop`'s `rotor_lag`) puts the best timing within half a step of the
/// staircase's. Slow telemetry (an ESC
/// status at tens of hertz) is a staircase whose steps are themselves a model error, and is
/// interpolated ([`unhold`]). `Auto` decides from the log: interpolate when most intervals
/// between changes of the logged value are longer than [`SLOW_HOLD_S`].
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum RotorHold {
    /// Decide from the log's own update intervals.
    #[default]
    Auto,
    /// As logged (`--rotor-raw`).
    Raw,
    /// Interpolated between held steps (`--rotor-unhold`).
    Unhold,
}

impl RotorHold {
    /// True when the speed is to be interpolated, given whether the telemetry is slow.
    pub fn interpolates(self, slow: bool) -> bool {
        match self {
            RotorHold::Auto => slow,
            RotorHold::Raw => false,
            RotorHold::Unhold => true,
        }
    }
}

/// An interval between changes of the logged rotor speed longer than this is a slow update,
/// s (fast ESC telemetry updates every 0.5-2 ms; an ESC status topic at 10-100 Hz every
/// 10-100 ms).
pub const SLOW_HOLD_S: f64 = 0.005;

/// Counts the intervals between changes of a held value, shorter and longer than
/// [`SLOW_HOLD_S`]: the same verdict for the streaming and the whole-log paths.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct HoldCounter {
    last_change_t: Option<f64>,
    prev: Option<f32>,
    /// Intervals at most [`SLOW_HOLD_S`].
    pub fast: u64,
    /// Intervals longer.
    pub slow: u64,
}

impl HoldCounter {
    /// The next sample: time and logged value.
    pub fn push(&mut self, t: f64, v: f32) {
        if self.prev.is_some_and(|p| p != v) {
            if let Some(t0) = self.last_change_t {
                if t - t0 > SLOW_HOLD_S {
                    self.slow += 1;
                } else {
                    self.fast += 1;
                }
            }
            self.last_change_t = Some(t);
        }
        self.prev = Some(v);
    }

    /// True when most intervals between changes are slow updates.
    pub fn is_slow(&self) -> bool {
        self.slow > self.fast
    }
}

/// [`HoldCounter::is_slow`] of a whole channel.
pub fn slow_telemetry(t: &[f64], speed: &[f32]) -> bool {
    let mut c = HoldCounter::default();
    for (&ti, &v) in t.iter().zip(speed) {
        c.push(ti, v);
    }
    c.is_slow()
}

/// What a first reading tells the streaming reconstruction.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Plan {
    /// Knots in the whole log (with fewer than two the log is kept as it is).
    pub knots: u64,
    /// The knots that samples would wait for longer than the lookahead, in order.
    pub noted: Vec<Knot>,
    /// The channel's update intervals ([`RotorHold::Auto`]).
    pub holds: HoldCounter,
}

/// Follows the knots `unhold` would make from a first reading and notes the ones that
/// samples would wait for beyond `lookahead`.
///
/// The samples waiting for knot `k` (the first knot after them) come after change `k - 2`
/// (knot `k - 1`, at the middle of changes `k - 2` and `k - 1`, is at or before them) and
/// after the first change; so knot `k` is noted when change `k` is more than `lookahead`
/// samples after change `max(k - 2, 0)`.
#[derive(Clone, Debug)]
pub struct Planner {
    lookahead: usize,
    i: usize,
    prev: f32,
    prev_change_t: f64,
    /// Sample indices of the first change and of the last two.
    changes: [usize; 3],
    plan: Plan,
}

impl Planner {
    /// A planner for a lookahead of `lookahead` samples.
    pub fn new(lookahead: usize) -> Self {
        Planner {
            lookahead,
            i: 0,
            prev: 0.0,
            prev_change_t: 0.0,
            changes: [0; 3],
            plan: Plan::default(),
        }
    }

    /// The next sample: time and speed.
    #[inline]
    pub fn push(&mut self, t: f64, v: f32) {
        self.plan.holds.push(t, v);
        let i = self.i;
        self.i += 1;
        if i == 0 {
            self.prev_change_t = t;
        } else if v != self.prev {
            let k = self.plan.knots;
            let knot = Knot {
                ordinal: k,
                t: 0.5 * (t + self.prev_change_t),
                v,
            };
            let [first, before_last, last] = &mut self.changes;
            let since = match k {
                0 => {
                    *first = i;
                    i
                }
                1 => *first,
                _ => *before_last,
            };
            if i - since > self.lookahead {
                self.plan.noted.push(knot);
            }
            *before_last = *last;
            *last = i;
            self.prev_change_t = t;
            self.plan.knots += 1;
        }
        self.prev = v;
    }

    /// The plan.
    pub fn finish(self) -> Plan {
        self.plan
    }
}

/// [`unhold`] sample by sample: [`Unhold::push`] each sample with a payload, take the ones
/// whose speed is known with [`Unhold::pop`] (in order), and [`Unhold::finish`] at the end.
/// The speeds are bit for bit `unhold`'s.
#[derive(Debug)]
pub struct Unhold<'a, P> {
    plan: &'a Plan,
    lookahead: usize,
    i: usize,
    prev: (f64, f32),
    prev_change_t: f64,
    /// Knots made so far from the samples.
    made: u64,
    /// The time and value of the sample before the first change, once there was one.
    before_first: Option<(f64, f32)>,
    /// The knot in use and those after it that are known (consecutive ordinals).
    known: VecDeque<Knot>,
    /// Ordinal after the last known knot.
    known_end: u64,
    /// Next noted knot to look at.
    next_noted: usize,
    waiting: VecDeque<(f64, f32, P)>,
    ready: VecDeque<(P, f32)>,
}

impl<'a, P> Unhold<'a, P> {
    /// A reconstruction following `plan` (made with the same `lookahead`).
    pub fn new(plan: &'a Plan, lookahead: usize) -> Self {
        Unhold {
            plan,
            lookahead,
            i: 0,
            prev: (0.0, 0.0),
            prev_change_t: 0.0,
            made: 0,
            before_first: None,
            known: VecDeque::new(),
            known_end: 0,
            next_noted: 0,
            waiting: VecDeque::new(),
            ready: VecDeque::new(),
        }
    }

    /// The next sample: time, logged speed, payload.
    pub fn push(&mut self, t: f64, v: f32, payload: P) -> Result<(), String> {
        let i = self.i;
        self.i += 1;
        if i == 0 {
            self.prev_change_t = t;
        } else if v != self.prev.1 {
            let knot = Knot {
                ordinal: self.made,
                t: 0.5 * (t + self.prev_change_t),
                v,
            };
            self.made += 1;
            self.prev_change_t = t;
            if self.before_first.is_none() {
                self.before_first = Some(self.prev);
            }
            if knot.ordinal == self.known_end {
                self.known.push_back(knot);
                self.known_end += 1;
            } else if knot.ordinal > self.known_end {
                return Err("rotor knots out of order".into());
            }
        }
        self.prev = (t, v);
        if self.plan.knots < 2 || self.before_first.is_none() {
            // As logged: no reconstruction, or before the first change.
            self.ready.push_back((payload, v));
            return Ok(());
        }
        self.waiting.push_back((t, v, payload));
        self.settle();
        while self.waiting.len() > self.lookahead {
            // The first waiting sample's next knot is beyond the lookahead: it was noted.
            while self
                .plan
                .noted
                .get(self.next_noted)
                .is_some_and(|k| k.ordinal < self.known_end)
            {
                self.next_noted += 1;
            }
            match self.plan.noted.get(self.next_noted) {
                Some(k) if k.ordinal == self.known_end => {
                    self.known.push_back(*k);
                    self.known_end += 1;
                    self.next_noted += 1;
                }
                _ => return Err("a rotor knot beyond the lookahead was not noted".into()),
            }
            self.settle();
        }
        Ok(())
    }

    /// Moves the waiting samples whose speed is known to the ready ones.
    fn settle(&mut self) {
        while let Some(&(t, _, _)) = self.waiting.front() {
            let Some(v) = self.speed_at(t) else {
                return;
            };
            if let Some((_, _, p)) = self.waiting.pop_front() {
                self.ready.push_back((p, v));
            }
        }
    }

    /// The speed at `ti` (the first waiting sample's time), if the knots around it are known.
    fn speed_at(&mut self, ti: f64) -> Option<f32> {
        while self.known.len() >= 2 && self.known.get(1).is_some_and(|k| k.t <= ti) {
            self.known.pop_front();
        }
        let &Knot { t: t0, v: v0, .. } = self.known.front()?;
        let next = self.known.get(1).copied();
        let last = self.known.front()?.ordinal + 1 == self.plan.knots;
        if next.is_none() && !last {
            return None;
        }
        Some(match next {
            Some(Knot { t: t1, v: v1, .. }) if ti >= t0 => {
                let f = ((ti - t0) / (t1 - t0)) as f32;
                v0 + (v1 - v0) * f
            }
            _ if ti < t0 => {
                // Between the first change and the first knot's time: interpolate from the
                // held value before it.
                let (tp, vp) = self.before_first?;
                let f = ((ti - tp) / (t0 - tp)) as f32;
                vp + (v0 - vp) * f
            }
            _ => v0,
        })
    }

    /// The next sample whose speed is known, in order: payload and speed.
    pub fn pop(&mut self) -> Option<(P, f32)> {
        self.ready.pop_front()
    }

    /// After the last sample: every sample's speed is known (the log must have given the
    /// knots the plan counted).
    pub fn finish(&mut self) -> Result<(), String> {
        if self.made != self.plan.knots {
            return Err(format!(
                "the rotor speed changed {} times in this reading, {} in the first",
                self.made, self.plan.knots
            ));
        }
        self.settle();
        if self.waiting.is_empty() {
            Ok(())
        } else {
            Err("rotor samples left without a speed".into())
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn stream(t: &[f64], v: &[f32], lookahead: usize) -> Vec<f32> {
        let mut planner = Planner::new(lookahead);
        for (&ti, &vi) in t.iter().zip(v) {
            planner.push(ti, vi);
        }
        let plan = planner.finish();
        let mut u = Unhold::new(&plan, lookahead);
        let mut out = Vec::new();
        for (i, (&ti, &vi)) in t.iter().zip(v).enumerate() {
            u.push(ti, vi, i).unwrap();
            while let Some((j, s)) = u.pop() {
                assert_eq!(j, out.len());
                out.push(s);
            }
            assert!(u.waiting.len() <= lookahead);
        }
        u.finish().unwrap();
        while let Some((_, s)) = u.pop() {
            out.push(s);
        }
        out
    }

    #[test]
    fn same_bits_as_unhold_with_any_lookahead() {
        let mut s = 0x2545_F491_4F6C_DD1Du64;
        let mut rnd = move || {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            s
        };
        for case in 0..200 {
            let n = 1 + (rnd() % 3000) as usize;
            let mut t = Vec::with_capacity(n);
            let mut v = Vec::with_capacity(n);
            let mut ti = (rnd() % 100) as f64 * 1e-3;
            let mut vi = 0.0f32;
            for _ in 0..n {
                t.push(ti);
                v.push(vi);
                ti += 1.25e-4 * (1.0 + (rnd() % 3) as f64);
                // Runs of holds of every length, changes now and then, long holds too.
                let r = rnd() % 1000;
                if r < 40 || (case % 3 == 0 && r < 400) {
                    vi = (rnd() % 50) as f32 * 3.7;
                }
            }
            let want = unhold(&t, &v);
            for lookahead in [1usize, 2, 3, 7, 64, LOOKAHEAD] {
                let got = stream(&t, &v, lookahead);
                assert_eq!(
                    got.iter().map(|x| x.to_bits()).collect::<Vec<_>>(),
                    want.iter().map(|x| x.to_bits()).collect::<Vec<_>>(),
                    "case {case}, n {n}, lookahead {lookahead}"
                );
            }
        }
        // No change, one change, two changes.
        for v in [
            vec![1.0f32; 5],
            vec![1.0, 1.0, 2.0, 2.0],
            vec![1.0, 2.0, 2.0, 3.0, 3.0],
        ] {
            let t: Vec<f64> = (0..v.len()).map(|i| i as f64).collect();
            assert_eq!(stream(&t, &v, 1), unhold(&t, &v));
        }
    }

    /// A channel updated every `every` samples at 4 kHz, ramping, with a rest at the start.
    fn channel(every: usize) -> (Vec<f64>, Vec<f32>) {
        let n = 8000;
        let t: Vec<f64> = (0..n).map(|i| i as f64 / 4000.0).collect();
        let v: Vec<f32> = (0..n)
            .map(|i| {
                if i < 2000 {
                    0.0
                } else {
                    (i / every * every) as f32 * 0.1
                }
            })
            .collect();
        (t, v)
    }

    #[test]
    fn fast_telemetry_is_taken_as_logged_and_slow_interpolated() {
        for (every, slow) in [(4, false), (8, false), (40, true), (400, true)] {
            let (t, v) = channel(every);
            assert_eq!(slow_telemetry(&t, &v), slow, "every {every}");
            // The streaming plan's verdict is the whole-channel one.
            let mut planner = Planner::new(LOOKAHEAD);
            for (&ti, &vi) in t.iter().zip(&v) {
                planner.push(ti, vi);
            }
            assert_eq!(planner.finish().holds.is_slow(), slow, "every {every}");
            assert_eq!(RotorHold::Auto.interpolates(slow), slow);
            assert!(!RotorHold::Raw.interpolates(slow));
            assert!(RotorHold::Unhold.interpolates(slow));
        }
    }
}
