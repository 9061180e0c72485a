//! The first reading of a log, before the pipeline can start: everything `identify` needs
//! from the whole recording (sample count, median time step, gyro noise, unit warnings, the
//! rotor channel's changes, the plot's extent), in bounded memory and bit for bit.
//!
//! The medians are exact ([`crate::select`]); when the first reading leaves one open (many
//! distinct values), the log is read again for it, the time step and the gyro only.

use crate::readers::{time_warning, AccelCheck, ReadError, UnitCheck};
use crate::select::Median;
use crate::source::{Flow, Source};
use crate::unhold::{Plan, Planner, LOOKAHEAD};

/// What to find besides the sample count, time step and unit warnings.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Wanted {
    /// The gyro noise estimate.
    pub noise: bool,
    /// The rotor channel's changes for the streaming `unhold`, the logged value turned to rad/s
    /// by this factor (`Some(None)`: as logged).
    pub unhold: Option<Option<f32>>,
    /// The rotor channel's resolution ([`RotorStep`]), the logged value turned to rad/s by
    /// this factor (`Some(None)`: as logged).
    pub rotor_step: Option<Option<f32>>,
}

/// The findings.
#[derive(Clone, Debug, Default)]
pub struct Survey {
    /// Samples in the log.
    pub samples: usize,
    /// Median time step, s (`None` with fewer than two samples).
    pub median_dt: Option<f64>,
    /// The gyro noise `estimate_noise` gives, when wanted.
    pub noise: Option<f32>,
    /// The duplicates warning of the reading (if any) and the unit warnings.
    pub warnings: Vec<String>,
    /// The rotor's knots, when wanted.
    pub unhold: Option<Plan>,
    /// First and last time, s.
    pub span: (f64, f64),
    /// Largest absolute rate over the log, at least 1 rad/s (the plot's scale).
    pub rate_max: f32,
    /// The rotor speed's resolution, rad/s, when wanted and the speed ever changed.
    pub rotor_step: Option<f32>,
    /// The accelerometer's unit warning ([`AccelCheck`]), also in `warnings`.
    pub accel_units: Option<String>,
    /// The gyro's unit warning ([`UnitCheck::rate_warning`]: rates sustained above 50 rad/s),
    /// also in `warnings`.
    pub gyro_units: Option<String>,
    /// Each gyro axis's LSB, rad/s, when its readings are whole counts
    /// ([`crate::grid::GridStats`]).
    pub gyro_lsb: Option<[f32; 3]>,
}

/// The resolution of a rotor-speed channel: the smallest change between consecutive logged
/// values, rad/s. A telemetry channel is quantised (DShot eRPM in steps of 100 eRPM, an ESC's
/// rpm in whole rpm), and its value dithers between neighbouring steps wherever the speed is
/// steady, so the smallest change is one step; a channel that only ever moves by several steps
/// gives a multiple of it (a larger, safe figure). Changes below `1e-6` of the value are the
/// unit conversion's rounding, not steps.
#[derive(Clone, Copy, Debug, Default)]
pub struct RotorStep {
    prev: Option<f32>,
    step: Option<f32>,
}

impl RotorStep {
    /// The next logged speed, rad/s.
    #[inline]
    pub fn push(&mut self, v: f32) {
        if !v.is_finite() {
            return;
        }
        if let Some(p) = self.prev {
            let d = (v - p).abs();
            if d > 1e-6 * v.abs().max(p.abs()) && self.step.is_none_or(|s| d < s) {
                self.step = Some(d);
            }
        }
        self.prev = Some(v);
    }

    /// The smallest change seen (`None`: the speed never changed).
    pub fn step(&self) -> Option<f32> {
        self.step
    }

    /// The smallest change of a whole channel held in memory (the readings pushed in order).
    pub fn of(speed: &[f32]) -> Option<f32> {
        let mut s = RotorStep::default();
        for &v in speed {
            s.push(v);
        }
        s.step()
    }
}

/// Median absolute third difference of each gyro axis (see
/// [`crate::recording::estimate_noise`]).
#[derive(Clone, Debug, Default)]
pub struct NoiseStats {
    last: [[f32; 3]; 3],
    seen: usize,
    medians: [Median<f32>; 3],
    /// Largest finite reading per axis.
    largest: [f32; 3],
}

impl NoiseStats {
    /// The next sample's rate.
    #[inline]
    pub fn push(&mut self, w: [f32; 3]) {
        for (l, x) in self.largest.iter_mut().zip(w) {
            if x.is_finite() {
                *l = l.max(x.abs());
            }
        }
        if self.seen >= 3 {
            let [w0, w1, w2] = self.last;
            for ax in 0..3 {
                let d = (w[ax] - 3.0 * w2[ax] + 3.0 * w1[ax] - w0[ax]).abs();
                if d.is_finite() {
                    self.medians[ax].push(d);
                }
            }
        }
        self.last = [self.last[1], self.last[2], w];
        self.seen += 1;
    }

    /// Ends a reading; true when another is needed.
    pub fn end_reading(&mut self) -> bool {
        self.last = [[0.0; 3]; 3];
        self.seen = 0;
        let mut again = false;
        for m in &mut self.medians {
            m.end_reading();
            again |= m.needs_reading();
        }
        again
    }

    /// The noise, once no reading is needed: the median (read within its level on a grid,
    /// [`crate::recording::level_median`]) turned into a standard deviation
    /// (third differences of white noise have variance `20 sigma^2`), smallest over the axes,
    /// floored at `1e-4 rad/s`; `2e-3` when no axis has a difference.
    pub fn noise(&self) -> f32 {
        crate::recording::noise_from_medians(self.medians.iter().zip(self.largest).map(
            |(m, largest)| match m.runs() {
                Some(runs) => crate::recording::level_median(runs, largest),
                None => m.result().flatten(),
            },
        ))
    }
}

/// Median of the time steps.
#[derive(Clone, Debug, Default)]
pub struct DtStats {
    prev: Option<f64>,
    median: Median<f64>,
}

impl DtStats {
    /// The next sample's time.
    #[inline]
    pub fn push(&mut self, t: f64) {
        if let Some(p) = self.prev {
            self.median.push(t - p);
        }
        self.prev = Some(t);
    }

    /// Ends a reading; true when another is needed.
    pub fn end_reading(&mut self) -> bool {
        self.prev = None;
        self.median.end_reading();
        self.median.needs_reading()
    }

    /// The median, once no reading is needed (`None` without a step).
    pub fn median(&self) -> Option<f64> {
        self.median.result().flatten()
    }
}

/// Reads `src` once (and again while a median is open). `progress` gets the fraction of the
/// first reading done.
pub fn survey(
    src: &dyn Source,
    wanted: Wanted,
    progress: &mut dyn FnMut(f32),
) -> Result<Survey, ReadError> {
    let mut dt = DtStats::default();
    let mut noise = NoiseStats::default();
    let mut units = UnitCheck::default();
    let mut accel = src.channels().accel.then(AccelCheck::default);
    let mut planner = wanted.unhold.map(|_| Planner::new(LOOKAHEAD));
    let factor = wanted.unhold.flatten();
    let mut rotor_step = RotorStep::default();
    let mut span: Option<(f64, f64)> = None;
    let mut rate_max = 1.0f32;
    let mut grid = crate::grid::GridStats::default();
    let reading = src.read_all(
        &mut |s| {
            dt.push(s.t);
            if !grid.exhausted() {
                grid.push(s.gyro);
            }
            if wanted.noise {
                noise.push(s.gyro);
            }
            units.push(s.t, s.gyro);
            if let Some(c) = &mut accel {
                c.push(s.gyro, s.accel);
            }
            if let Some(p) = &mut planner {
                p.push(s.t, factor.map_or(s.rotor, |k| s.rotor * k));
            }
            if let Some(k) = wanted.rotor_step {
                rotor_step.push(k.map_or(s.rotor, |k| s.rotor * k));
            }
            span = Some(span.map_or((s.t, s.t), |(a, _)| (a, s.t)));
            for x in s.gyro {
                if x.abs() > rate_max {
                    rate_max = x.abs();
                }
            }
            Ok(Flow::Continue)
        },
        progress,
    )?;
    let mut again = dt.end_reading();
    if wanted.noise {
        again |= noise.end_reading();
    }
    while again {
        src.read_all(
            &mut |s| {
                dt.push(s.t);
                if wanted.noise {
                    noise.push(s.gyro);
                }
                Ok(Flow::Continue)
            },
            &mut |_| {},
        )?;
        again = dt.end_reading();
        if wanted.noise {
            again |= noise.end_reading();
        }
    }
    let median_dt = dt.median();
    let mut warnings: Vec<String> = reading.duplicates.into_iter().collect();
    let gyro_units = units.rate_warning(src.full_scale());
    warnings.extend(gyro_units.clone());
    warnings.extend(time_warning(median_dt));
    let accel_units = accel.and_then(|c| c.warning());
    warnings.extend(accel_units.clone());
    Ok(Survey {
        samples: reading.samples,
        median_dt,
        noise: wanted.noise.then(|| noise.noise()),
        warnings,
        unhold: planner.map(Planner::finish),
        span: span.unwrap_or((0.0, 0.0)),
        rate_max,
        rotor_step: wanted.rotor_step.and(rotor_step.step()),
        accel_units,
        gyro_units,
        gyro_lsb: grid.lsb(),
    })
}

#[cfg(test)]
mod tests {
    use super::RotorStep;

    /// DShot eRPM in rad/s for 12 poles: multiples of 1.745 rad/s, a steady idle dithering
    /// between two of them and a spin-up moving by several at a time: the step is one.
    #[test]
    fn a_quantised_channel_gives_its_step() {
        let q = 100.0f32 / 6.0 * 2.0 * core::f32::consts::PI / 60.0;
        let idle = [100.0f32, 101.0, 100.0, 100.0, 101.0];
        let ramp = [104.0f32, 109.0, 117.0, 130.0];
        let v: Vec<f32> = idle.iter().chain(&ramp).map(|k| k * q).collect();
        let s = RotorStep::of(&v).unwrap();
        assert!((s / q - 1.0).abs() < 1e-5, "{s} against {q}");
        // Only moves of several steps: a multiple of it (a larger, safe figure).
        let s = RotorStep::of(&ramp.map(|k| k * q)).unwrap();
        assert!((s / q - 5.0).abs() < 1e-5, "{s}");
    }

    /// A speed that never changes has no step to tell; non-finite readings are skipped;
    /// changes at the unit conversion's rounding are not steps.
    #[test]
    fn constant_nan_and_rounding_give_no_step() {
        assert_eq!(RotorStep::of(&[175.0; 8]), None);
        assert_eq!(
            RotorStep::of(&[175.0, f32::NAN, 175.0, f32::INFINITY, 175.0]),
            None
        );
        let x = 1234.5678f32;
        assert_eq!(
            RotorStep::of(&[x, f32::from_bits(x.to_bits() + 1), x]),
            None
        );
        assert_eq!(RotorStep::of(&[1.0, f32::NAN, 3.0]), Some(2.0));
    }
}

#[cfg(test)]
mod noise_tests {
    use super::NoiseStats;
    use crate::recording::estimate_noise;

    /// Gaussian white noise by Box-Muller from a small linear congruential generator.
    fn white(n: usize, sigma: f64, seed: u64) -> Vec<f64> {
        let mut s = seed;
        let mut u = move || {
            s = s
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((s >> 11) as f64 + 0.5) / (1u64 << 53) as f64
        };
        (0..n)
            .map(|_| sigma * (-2.0 * u().ln()).sqrt() * (2.0 * std::f64::consts::PI * u()).cos())
            .collect()
    }

    fn streamed(gyro: &[[f32; 3]]) -> f32 {
        let mut s = NoiseStats::default();
        loop {
            for &w in gyro {
                s.push(w);
            }
            if !s.end_reading() {
                return s.noise();
            }
        }
    }

    /// A moving body's gyro reading whole counts of `lsb` (scaled in `f32`, as readers do, up to
    /// about 10^4 counts), with white noise from half a count to two counts: the noise found is
    /// that of the noise and the rounding together, `sqrt(sigma^2 + lsb^2 / 12)`, within 5 %,
    /// where the plain median sticks to a whole count; the streamed survey gives the same bits.
    #[test]
    fn a_quantised_gyro_gives_its_noise_and_rounding_not_a_whole_count() {
        let lsb = 1.065e-3f32;
        for (i, sigma_counts) in [0.5, 0.75, 1.0, 2.0].into_iter().enumerate() {
            let n = 20_000;
            let axes: Vec<Vec<f64>> = (0..3)
                .map(|a| white(n, sigma_counts, 7 + 3 * i as u64 + a))
                .collect();
            let gyro: Vec<[f32; 3]> = (0..n)
                .map(|k| {
                    [0, 1, 2].map(|a| {
                        (axes[a][k] + (0.37 + 0.11 * a as f64) * k as f64).round() as f32 * lsb
                    })
                })
                .collect();
            let found = estimate_noise(&gyro);
            let expect = (sigma_counts * sigma_counts + 1.0 / 12.0).sqrt() as f32 * lsb;
            assert!(
                (found / expect - 1.0).abs() < 0.05,
                "sigma {sigma_counts} counts: {found} against {expect}"
            );
            assert_eq!(found.to_bits(), streamed(&gyro).to_bits());
        }
    }

    /// Unquantised readings: the plain median, as sorting gives it, in memory and streamed.
    #[test]
    fn continuous_readings_give_the_plain_median() {
        let n = 5_000;
        let x = white(n, 1e-3, 99);
        let gyro: Vec<[f32; 3]> = (0..n).map(|k| [x[k] as f32; 3]).collect();
        let mut d: Vec<f32> = gyro
            .windows(4)
            .map(|w| (w[3][0] - 3.0 * w[2][0] + 3.0 * w[1][0] - w[0][0]).abs())
            .collect();
        d.sort_by(|a, b| a.total_cmp(b));
        let plain = (d[d.len() / 2] / 0.6745 / 20f32.sqrt()).max(1e-4);
        assert_eq!(estimate_noise(&gyro).to_bits(), plain.to_bits());
        assert_eq!(streamed(&gyro).to_bits(), plain.to_bits());
    }
}
