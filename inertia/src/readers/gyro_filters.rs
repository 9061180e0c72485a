//! The low-pass filters a Betaflight flight controller runs on the gyro it logs, read from the
//! blackbox header, as the two numbers the fits need: their delay and their time variance.
//!
//! Betaflight logs `gyroADC` as `gyro.gyroADCf`, the gyro after its filters (two low-pass
//! stages, static notches, dynamic notches), not the rate at the sample's time. A linear filter
//! with impulse response `g` (unit gain at 0 Hz) gives, for a smooth rate `w`,
//!
//! ```text
//! (g * w)(t) = w(t - k1) + k2/2 w''(t - k1) + O(k3 w''')                         (G1)
//! ```
//!
//! with `k1` and `k2` the first two cumulants of `g` (its mean delay and time variance; both
//! add over filters in series). The blackbox reader reads each frame's rate `k1` after the
//! frame, interpolated between the two logged readings around that time (the rotor's speed
//! stays with its frame, so a rotor's momentum is aligned with the rate and keeps its
//! telemetry steps), and the fits count `k2` and the interpolation's spread ((G3),
//! [`GyroFilters::smoothing`]) in their block means, as they count an averaging window ((B0')
//! of `identifier_core`'s output-error fits). The noise they assume is the filtered noise's
//! white equivalent, the log's rounding included ((G2), [`GyroFilters::white_noise`]). Taken
//! for instants, the filtered rate is a window nobody counted: simulated tosses through
//! Betaflight's default filters come out `Converged` several standard deviations off, and the
//! filter's delay (about 1 ms) between the rate and a logged rotor's speed leaves a model error the
//! fit calls `ModelMismatch` (see the tests of `inertia identify`). The accelerometer's low-pass is
//! read the same way for the free-flight gate ([`betaflight_accel_delay`]).
//!
//! The cumulants are those of the firmware's discrete filters at its gyro loop rate (the
//! header's `looptime`), computed from their impulse responses. What is read:
//!
//! | header | filter |
//! |---|---|
//! | `gyro_lpf1_type`, `gyro_lpf1_static_hz`, `gyro_lpf1_dyn_hz` (`gyro_lowpass_type`, `gyro_lowpass_hz`, `dyn_lpf_gyro_min_hz` before 4.3) | first low-pass: PT1, biquad, PT2 or PT3; when dynamic, its lowest cutoff (the throttle is at zero in a throw) |
//! | `gyro_lpf2_type`, `gyro_lpf2_static_hz` (`gyro_lowpass2_*`) | second low-pass |
//! | `gyro_notch_hz`, `gyro_notch_cutoff` | two static notches |
//! | `dyn_notch_count`, `dyn_notch_q`, `dyn_notch_min_hz`, `dyn_notch_max_hz` | dynamic notches, taken at `sqrt(min max)` (where they sit is not logged: see [`GyroFilters::uncertain`]) |
//!
//! Not modelled: the RPM filter (its notches follow the motors and are faded out below
//! `rpm_filter_min_hz`: off when the motors are, as in a throw) and the gyro chip's own
//! anti-aliasing filter.

use std::f64::consts::PI;

/// The logged gyro's filters, as (G1) needs them.
#[derive(Clone, Debug, PartialEq)]
pub struct GyroFilters {
    /// `k1`, s: how late the logged rate is.
    pub delay_s: f64,
    /// `k2`, s^2: the filters' time variance (at least 0).
    pub variance_s2: f64,
    /// The part of `k2` that depends on where the dynamic notches sat (not logged), s^2: from
    /// all at `dyn_notch_max_hz` to all at `dyn_notch_min_hz`, the total moves by about this
    /// much either way.
    pub uncertain: f64,
    /// The filters read, for the warning (`"PT1 250 Hz, PT1 500 Hz"`).
    pub described: String,
    /// The filters, in series.
    kinds: Vec<Kind>,
    /// The gyro loop's step, s (`looptime`).
    loop_dt: f64,
    /// The log's resolution, rad/s (its unit: 1 or 0.1 deg/s).
    quantum: f64,
    /// The header named the filters (false: [`GyroFilters::none`]).
    known: bool,
}

/// One of Betaflight's filter kinds, at its gyro loop step.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Kind {
    /// `order` first-order stages in series, each at `hz` times Betaflight's cutoff correction
    /// for that order (so the series is 3 dB down at `hz`).
    Pt(u8, f64),
    /// Second-order Butterworth low-pass (RBJ biquad, `Q = 1/sqrt 2`).
    Biquad(f64),
    /// Notch at `hz` with quality `q` (RBJ).
    Notch(f64, f64),
}

/// Runs `kind` at loop step `dt` over `x`, in place, from rest.
fn apply(kind: Kind, dt: f64, x: &mut [f64]) {
    match kind {
        Kind::Pt(order, hz) => {
            // Betaflight's pt1/pt2/pt3 gains: k = w dt / (w dt + 1), w = 2 pi hz c with
            // c = 1/sqrt(2^(1/order) - 1) (1 for a single stage).
            let c = 1.0 / (2f64.powf(1.0 / f64::from(order)) - 1.0).sqrt();
            let w = 2.0 * PI * hz * c * dt;
            let k = w / (w + 1.0);
            for _ in 0..order {
                let mut s = 0.0;
                for v in x.iter_mut() {
                    s += k * (*v - s);
                    *v = s;
                }
            }
        }
        Kind::Biquad(hz) | Kind::Notch(hz, _) => {
            let q = match kind {
                Kind::Notch(_, q) => q,
                _ => std::f64::consts::FRAC_1_SQRT_2,
            };
            let om = 2.0 * PI * hz * dt;
            let (sn, cs) = om.sin_cos();
            let alpha = sn / (2.0 * q);
            let a0 = 1.0 + alpha;
            let (b0, b1, b2) = match kind {
                Kind::Notch(..) => (1.0 / a0, -2.0 * cs / a0, 1.0 / a0),
                _ => (
                    (1.0 - cs) / 2.0 / a0,
                    (1.0 - cs) / a0,
                    (1.0 - cs) / 2.0 / a0,
                ),
            };
            let (a1, a2) = (-2.0 * cs / a0, (1.0 - alpha) / a0);
            let (mut x1, mut x2, mut y1, mut y2) = (0.0, 0.0, 0.0, 0.0);
            for v in x.iter_mut() {
                let y = b0 * *v + b1 * x1 + b2 * x2 - a1 * y1 - a2 * y2;
                (x2, x1, y2, y1) = (x1, *v, y1, y);
                *v = y;
            }
        }
    }
}

/// The impulse response of `kinds` in series at loop step `dt`, over 2 s (every filter here
/// has decayed by 1e-12 well before that).
fn response(kinds: &[Kind], dt: f64) -> Vec<f64> {
    let n = (2.0 / dt).ceil().clamp(1000.0, 200_000.0) as usize;
    let mut h = vec![0.0f64; n];
    if let Some(first) = h.first_mut() {
        *first = 1.0;
    }
    for &k in kinds {
        apply(k, dt, &mut h);
    }
    h
}

/// `(k1, k2)` of the filters `kinds` in series at loop step `dt`, in seconds, from their
/// impulse response.
fn cumulants(kinds: &[Kind], dt: f64) -> (f64, f64) {
    let h = response(kinds, dt);
    let (mut m0, mut m1, mut m2) = (0.0, 0.0, 0.0);
    for (i, &v) in h.iter().enumerate() {
        let t = i as f64;
        m0 += v;
        m1 += v * t;
        m2 += v * t * t;
    }
    if !(m0.abs() > 1e-9 && m0.is_finite() && m1.is_finite() && m2.is_finite()) {
        return (0.0, 0.0);
    }
    let mean = m1 / m0;
    (mean * dt, (m2 / m0 - mean * mean) * dt * dt)
}

fn describe(kind: Kind) -> String {
    match kind {
        Kind::Pt(1, hz) => format!("PT1 {hz} Hz"),
        Kind::Pt(o, hz) => format!("PT{o} {hz} Hz"),
        Kind::Biquad(hz) => format!("biquad {hz} Hz"),
        Kind::Notch(hz, q) => format!("notch {hz:.0} Hz Q {q:.2}"),
    }
}

/// Betaflight's low-pass type number (`FILTER_PT1` 0, `FILTER_BIQUAD` 1, `FILTER_PT2` 2,
/// `FILTER_PT3` 3) at `hz`; `None` for a cutoff of 0 (off) or an unknown type.
fn lowpass(kind: u32, hz: f64) -> Option<Kind> {
    if !(hz > 0.0 && hz.is_finite()) {
        return None;
    }
    match kind {
        0 => Some(Kind::Pt(1, hz)),
        1 => Some(Kind::Biquad(hz)),
        2 => Some(Kind::Pt(2, hz)),
        3 => Some(Kind::Pt(3, hz)),
        _ => None,
    }
}

fn numbers(v: Option<&str>) -> Vec<f64> {
    v.map(|s| {
        s.split(',')
            .filter_map(|x| x.trim().parse::<f64>().ok())
            .collect()
    })
    .unwrap_or_default()
}

/// The gyro filters of a Betaflight log's header (`value` looks a header key up), or `None`
/// when the header names none of them (another firmware, or a Betaflight too old to log
/// them). Filters that are off (cutoff 0, count 0) are left out; a header that lists filters,
/// all off, gives zero delay and variance.
pub fn betaflight(value: &dyn Fn(&str) -> Option<String>, quantum: f64) -> Option<GyroFilters> {
    let first = |keys: &[&str]| keys.iter().find_map(|k| value(k));
    let lpf1_type = first(&["gyro_lpf1_type", "gyro_lowpass_type"]);
    let lpf1_hz = first(&["gyro_lpf1_static_hz", "gyro_lowpass_hz"]);
    let lpf2_type = first(&["gyro_lpf2_type", "gyro_lowpass2_type"]);
    let lpf2_hz = first(&["gyro_lpf2_static_hz", "gyro_lowpass2_hz"]);
    if lpf1_hz.is_none() && lpf2_hz.is_none() {
        return None;
    }
    // The gyro loop's step: `looptime` microseconds (8 kHz when absent).
    let dt = numbers(value("looptime").as_deref())
        .first()
        .copied()
        .filter(|&us| us > 10.0 && us < 100_000.0)
        .map_or(125e-6, |us| us * 1e-6);
    let mut kinds: Vec<Kind> = Vec::new();
    let ty = |v: &Option<String>| numbers(v.as_deref()).first().map_or(0, |&t| t as u32);
    // A dynamic first stage (`min,max` with min > 0) runs at its minimum at zero throttle.
    let dyn_min = numbers(
        first(&[
            "gyro_lpf1_dyn_hz",
            "gyro_lpf1_dyn_min_hz",
            "dyn_lpf_gyro_min_hz",
            "gyro_lowpass_dyn_min_hz",
        ])
        .as_deref(),
    )
    .first()
    .copied()
    .filter(|&m| m > 0.0);
    let lpf1 = dyn_min.or_else(|| numbers(lpf1_hz.as_deref()).first().copied());
    kinds.extend(lpf1.and_then(|hz| lowpass(ty(&lpf1_type), hz)));
    kinds.extend(
        numbers(lpf2_hz.as_deref())
            .first()
            .and_then(|&hz| lowpass(ty(&lpf2_type), hz)),
    );
    // Static notches: centre and cutoff, Q = f c / (f^2 - c^2) (Betaflight's filterGetNotchQ).
    let (centres, cutoffs) = (
        numbers(value("gyro_notch_hz").as_deref()),
        numbers(value("gyro_notch_cutoff").as_deref()),
    );
    for (&f, &c) in centres.iter().zip(&cutoffs) {
        if f > 0.0 && c > 0.0 && c < f {
            kinds.push(Kind::Notch(f, f * c / (f * f - c * c)));
        }
    }
    let mut names: Vec<String> = kinds.iter().map(|&k| describe(k)).collect();
    // Dynamic notches: `dyn_notch_q` is Q times 100.
    let count = numbers(value("dyn_notch_count").as_deref())
        .first()
        .copied()
        .unwrap_or(0.0);
    let q = numbers(value("dyn_notch_q").as_deref())
        .first()
        .map_or(0.0, |q| q / 100.0);
    let lo = numbers(value("dyn_notch_min_hz").as_deref())
        .first()
        .copied()
        .unwrap_or(0.0);
    let hi = numbers(value("dyn_notch_max_hz").as_deref())
        .first()
        .copied()
        .unwrap_or(lo);
    let mut uncertain = 0.0;
    if (1.0..=8.0).contains(&count) && q > 0.0 && lo > 0.0 && hi >= lo {
        let at = |hz: f64| cumulants(&[Kind::Notch(hz, q)], dt).1;
        uncertain = count * (at(lo) - at(hi)).abs() / 2.0;
        for _ in 0..count as usize {
            kinds.push(Kind::Notch((lo * hi).sqrt(), q));
        }
        names.push(format!(
            "{count:.0} dynamic notch(es) Q {q:.2} taken at {:.0} Hz ({lo:.0}-{hi:.0} Hz)",
            (lo * hi).sqrt()
        ));
    }
    let (delay_s, variance_s2) = cumulants(&kinds, dt);
    Some(GyroFilters {
        delay_s,
        variance_s2: variance_s2.max(0.0),
        uncertain,
        described: if names.is_empty() {
            "none".to_string()
        } else {
            names.join(", ")
        },
        kinds,
        loop_dt: dt,
        quantum,
        known: true,
    })
}

/// The delay of Betaflight's accelerometer low-pass (`acc_lpf_hz`, logged as the cutoff times
/// 100; a PT2 since Betaflight 4.3, a biquad before, `revision` tells), s; 0 when the header
/// has none or it is off. Taken at a 1 kHz accelerometer rate (the delay of a low-pass well
/// below the rate hardly depends on it).
pub fn betaflight_accel_delay(value: &dyn Fn(&str) -> Option<String>, revision: &str) -> f64 {
    let Some(hz) = numbers(value("acc_lpf_hz").as_deref())
        .first()
        .map(|v| v / 100.0)
        .filter(|&hz| hz > 0.0 && hz < 1000.0)
    else {
        return 0.0;
    };
    // "Betaflight 4.2.11 (...)": major.minor; 2025.12 and later are newer than 4.3.
    let version: Vec<u32> = revision
        .split(' ')
        .nth(1)
        .unwrap_or_default()
        .split('.')
        .take(2)
        .filter_map(|x| x.parse().ok())
        .collect();
    let pt2 = match version[..] {
        [major, minor] => major > 4 || (major == 4 && minor >= 3),
        _ => true,
    };
    let kind = if pt2 {
        Kind::Pt(2, hz)
    } else {
        Kind::Biquad(hz)
    };
    cumulants(&[kind], 1e-3).0
}

impl GyroFilters {
    /// No filter known (a header that names none): no delay, no time spread; the log's
    /// resolution `quantum` (rad/s) is still counted in its noise ([`GyroFilters::white_noise`]).
    pub fn none(quantum: f64) -> Self {
        GyroFilters {
            delay_s: 0.0,
            variance_s2: 0.0,
            uncertain: 0.0,
            described: "none known".to_string(),
            kinds: Vec::new(),
            loop_dt: 125e-6,
            quantum,
            known: false,
        }
    }

    /// Whether the header named no filter ([`GyroFilters::none`]).
    pub fn is_none(&self) -> bool {
        !self.known
    }

    /// Where the reader's interpolation falls between two logged samples `log_dt` apart: the
    /// fraction `f` of (G3).
    fn fraction(&self, log_dt: f64) -> f64 {
        if log_dt > 0.0 && self.delay_s.is_finite() {
            (self.delay_s / log_dt).fract()
        } else {
            0.0
        }
    }

    /// The time variance of the gyro as the reader gives it, s^2: the filters' `k2` and the
    /// interpolation's,
    ///
    /// ```text
    /// k2 + f (1 - f) log_dt^2                                                      (G3)
    /// ```
    ///
    /// (the reader takes each rate `k1` later than its frame, between the two logged samples
    /// around that time, weights `1 - f` and `f`).
    pub fn smoothing(&self, log_dt: f64) -> f64 {
        let f = self.fraction(log_dt);
        self.variance_s2 + f * (1.0 - f) * log_dt * log_dt
    }

    /// The white noise a fit should assume per sample, from `measured`: the noise
    /// [`crate::recording::estimate_noise`] finds from third differences of the rates the
    /// reader gives, `log_dt` apart (the log's resolution, its unit, counted as white
    /// quantisation noise).
    ///
    /// The filters take the high frequencies out of the gyro's noise, which third differences
    /// (a high-pass) measure, but leave its low frequencies, which the fits' block means see:
    /// Betaflight's default filters at an 8 kHz loop, logged at 2 kHz, show third differences
    /// as if the noise were several times smaller than what the block means carry, and the
    /// fits took their standard deviations and their tests from that. With white noise of
    /// variance `s^2` per loop step, filtered (impulse response `g`, unit gain) and logged
    /// every `D` steps, quantised (variance `q^2 / 12`, white at the log rate) and
    /// interpolated with weights `(1 - f, f)` by the reader, the logged sequence's
    /// autocovariance and the two noises are
    ///
    /// ```text
    /// R(m)   = s^2 rho(|m| D) + q^2/12 [m = 0]                                     (G2)
    /// R'(m)  = ((1 - f)^2 + f^2) R(m) + f (1 - f) (R(m - 1) + R(m + 1))
    /// measured^2 = sum_ij c_i c_j R'(i - j) / 20,   white^2 = sum_m R'(m) = sum_m R(m)
    /// ```
    ///
    /// with `c = (1, -3, 3, -1)` and `rho` the autocorrelation of `g` in loop steps (`white`:
    /// the spectrum at 0 Hz, aliases included). `s^2` is solved from `measured`; where the
    /// quantisation alone explains it, the white noise is the quantisation's.
    pub fn white_noise(&self, measured: f64, log_dt: f64) -> f64 {
        let d = (log_dt / self.loop_dt).round();
        if !(measured.is_finite() && measured > 0.0 && (1.0..=64.0).contains(&d)) {
            return measured;
        }
        let d = d as usize;
        let f = self.fraction(log_dt);
        let h = response(&self.kinds, self.loop_dt);
        let rho =
            |lag: usize| -> f64 { h.iter().zip(h.iter().skip(lag)).map(|(a, b)| a * b).sum() };
        // The two parts of R (per unit s^2 and per unit q^2/12) at logged lag m.
        let r = |m: i64| -> [f64; 2] {
            let m = m.unsigned_abs() as usize;
            [rho(m * d), if m == 0 { 1.0 } else { 0.0 }]
        };
        let interp = |m: i64| -> [f64; 2] {
            let (a, b, c) = (r(m), r(m - 1), r(m + 1));
            let (w0, w1) = ((1.0 - f) * (1.0 - f) + f * f, f * (1.0 - f));
            [0, 1].map(|k| w0 * a[k] + w1 * (b[k] + c[k]))
        };
        let c = [1.0, -3.0, 3.0, -1.0];
        let mut third = [0.0f64; 2];
        for (i, ci) in c.iter().enumerate() {
            for (j, cj) in c.iter().enumerate() {
                let v = interp(i as i64 - j as i64);
                for k in 0..2 {
                    third[k] += ci * cj * v[k] / 20.0;
                }
            }
        }
        // sum_m rho(|m| D) over every lag is the sum over the residues r mod D of the square
        // of the sum of the h_k with k = r mod D: one pass, not one product per lag.
        let mut residues = vec![0.0f64; d];
        for (k, v) in h.iter().enumerate() {
            residues[k % d] += v;
        }
        let zero: f64 = residues.iter().map(|s| s * s).sum();
        let q2 = if self.quantum > 0.0 {
            self.quantum * self.quantum / 12.0
        } else {
            0.0
        };
        if !(third[0] > 0.0 && third[0].is_finite() && zero.is_finite()) {
            return measured;
        }
        let s2 = (measured * measured - third[1] * q2).max(0.0) / third[0];
        (s2 * zero + q2).sqrt()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn header<'a>(lines: &'a [(&'a str, &'a str)]) -> impl Fn(&str) -> Option<String> + 'a {
        move |k| {
            lines
                .iter()
                .find(|(key, _)| *key == k)
                .map(|(_, v)| v.to_string())
        }
    }

    /// A first-order stage of time constant `tau` delays by `tau` and spreads by `tau^2`
    /// (continuous time); Betaflight's discrete stage at 8 kHz adds `tau dt` to the variance.
    #[test]
    fn a_pt1_is_its_time_constant() {
        let dt = 125e-6;
        let tau = 1.0 / (2.0 * PI * 100.0);
        let (k1, k2) = cumulants(&[Kind::Pt(1, 100.0)], dt);
        // Geometric impulse response k (1-k)^i: mean (1-k)/k, variance (1-k)/k^2 (steps).
        let w = 2.0 * PI * 100.0 * dt;
        let k = w / (w + 1.0);
        assert!((k1 - (1.0 - k) / k * dt).abs() < 1e-9, "{k1}");
        assert!((k2 - (1.0 - k) / (k * k) * dt * dt).abs() < 1e-12, "{k2}");
        assert!((k1 - tau).abs() < 0.01 * tau);
        assert!((k2 - (tau * tau + tau * dt)).abs() < 0.02 * tau * tau);
    }

    /// A Butterworth biquad delays by `sqrt 2 / w0` and, its impulse response having a negative
    /// lobe, has (nearly) no time variance; a notch delays by `1/(Q w0)` and spreads by its
    /// square.
    #[test]
    fn biquads_and_notches_follow_their_transfer_functions() {
        let dt = 125e-6;
        let w0 = 2.0 * PI * 100.0;
        let (k1, k2) = cumulants(&[Kind::Biquad(100.0)], dt);
        assert!((k1 - 2f64.sqrt() / w0).abs() < 0.02 * k1, "{k1}");
        assert!(k2.abs() < 0.05 * k1 * k1, "{k2}");
        let w0 = 2.0 * PI * 300.0;
        let (k1, k2) = cumulants(&[Kind::Notch(300.0, 3.0)], dt);
        assert!((k1 - 1.0 / (3.0 * w0)).abs() < 0.03 * k1, "{k1}");
        assert!((k2 - k1 * k1).abs() < 0.1 * k1 * k1, "{k2}");
    }

    /// Betaflight 4.4's defaults: a dynamic PT1 (250-500 Hz: 250 at zero throttle), a PT1 at
    /// 500 Hz, three dynamic notches (Q 3, 100-600 Hz).
    #[test]
    fn betaflight_defaults() {
        let h = [
            ("looptime", "125"),
            ("gyro_lpf1_type", "0"),
            ("gyro_lpf1_static_hz", "250"),
            ("gyro_lpf1_dyn_hz", "250,500"),
            ("gyro_lpf2_type", "0"),
            ("gyro_lpf2_static_hz", "500"),
            ("gyro_notch_hz", "0,0"),
            ("gyro_notch_cutoff", "0,0"),
            ("dyn_notch_count", "3"),
            ("dyn_notch_q", "300"),
            ("dyn_notch_min_hz", "100"),
            ("dyn_notch_max_hz", "600"),
        ];
        let f = betaflight(&header(&h), 0.1f64.to_radians()).expect("filters");
        let (t1, t2) = (1.0 / (2.0 * PI * 250.0), 1.0 / (2.0 * PI * 500.0));
        let notch = 1.0 / (3.0 * 2.0 * PI * (100.0f64 * 600.0).sqrt());
        let want_k1 = t1 + t2 + 3.0 * notch;
        assert!((f.delay_s - want_k1).abs() < 0.05 * want_k1, "{f:?}");
        let want_k2 = t1 * t1 + t2 * t2 + 3.0 * notch * notch;
        assert!((f.variance_s2 - want_k2).abs() < 0.2 * want_k2, "{f:?}");
        assert!(f.uncertain > 0.0 && f.uncertain < f.variance_s2, "{f:?}");
        assert!(f.described.contains("PT1 250 Hz"), "{}", f.described);
        // Filters off: zero; no filter keys at all: not a Betaflight header.
        let off = [("gyro_lpf1_static_hz", "0"), ("gyro_lpf2_static_hz", "0")];
        let f = betaflight(&header(&off), 0.0).expect("filters");
        assert_eq!((f.delay_s, f.variance_s2), (0.0, 0.0));
        assert!(betaflight(&header(&[("looptime", "125")]), 0.0).is_none());
        // Betaflight 4.2's names: a dynamic first stage (its minimum) and a biquad second.
        let old = [
            ("looptime", "125"),
            ("gyro_lowpass_type", "0"),
            ("gyro_lowpass_hz", "200"),
            ("dyn_lpf_gyro_min_hz", "250"),
            ("gyro_lowpass2_type", "1"),
            ("gyro_lowpass2_hz", "500"),
        ];
        let f = betaflight(&header(&old), 0.0).expect("filters");
        assert_eq!(f.described, "PT1 250 Hz, biquad 500 Hz");
        let want = t1 + 2f64.sqrt() / (2.0 * PI * 500.0);
        assert!((f.delay_s - want).abs() < 0.05 * want, "{f:?}");
    }
}
