//! A hand throw of a rigid body with a full inertia tensor and an internal flywheel, in `f64`,
//! with the gyro, accelerometer and rotor-speed readings a flight controller would log.
//!
//! The body is described in the sensor (IMU) frame: inertia tensor `J` about the centre of
//! mass (kg m^2, symmetric, not diagonal in general), a rotor of inertia `j_r` about a unit
//! axis `e`, spinning at `omega_r(t)`, so its momentum is `h = j_r omega_r(t) e` and
//! `h' = j_r omega_r'(t) e`. In free flight the angular velocity `w` (body frame) obeys Euler's
//! equation with rotor momentum,
//!
//! ```text
//! J w' = (J w + h) x w - h'          (torque-free: J w' + w x (J w + h) + h' = 0)
//! ```
//!
//! and the centre of mass falls freely, so the accelerometer, at `r` from the centre of mass,
//! reads only `f = w x (w x r) + w' x r`. Everywhere else the motion is prescribed:
//!
//! | phase | angular velocity | centre-of-mass acceleration (world) |
//! |---|---|---|
//! | still on the bench | 0 | 0 (the accelerometer reads gravity) |
//! | picked up and swung by hand | smooth wobble ramping to `omega_release` | lift, swing, throw push |
//! | free flight, `[release_s, catch_s)` | Euler's equation above | `g` (free fall) |
//! | catch | `w(catch) exp(-(t - catch)/tau)` | a short impact pulse (clips at 16 g) |
//! | held | the tail of that decay | 0 |
//!
//! The specific force at the IMU is `f = R^T (a_com - g) + w' x r + w x (w x r)` in every
//! phase, with `R` the body-to-world rotation integrated as a unit quaternion
//! (`q' = q (0, w) / 2`, RK4 together with `w` in free flight), so gravity in the body frame is
//! right after the tumble. Phase boundaries lie on the internal RK4 grid, so `release_s` and
//! `catch_s` are exact.
//!
//! Sensors: gyro `Q(clip(w + b + n))`, accelerometer `Q(clip(f + n))`, with white Gaussian `n`
//! from a seeded ChaCha8 stream, optional quantisation to the logged resolution (16.384 LSB per
//! deg/s; 2048 LSB per g; the rotor speed in steps of the `erpm[0]` field, 100 eRPM with 12
//! poles) and clipping at the full scale (2000 deg/s = 34.9 rad/s; 16 g). Readings are `f32`.

// Index loops read closest to the equations they implement.
#![allow(clippy::needless_range_loop)]

use anyhow::{Context, Result};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use std::f64::consts::TAU;
use std::io::{BufWriter, Write};
use std::ops::Range;
use std::path::Path;

/// Standard gravity, m/s^2.
pub const G: f64 = 9.80665;
/// 2000 deg/s in rad/s: the gyro full scale of the logged boards.
pub const GYRO_FULL_SCALE_RAD_S: f64 = 2000.0 * std::f64::consts::PI / 180.0;
/// Logged gyro resolution, LSB per deg/s.
pub const GYRO_LSB_PER_DEG_S: f64 = 16.384;
/// Logged accelerometer resolution, LSB per g.
pub const ACCEL_LSB_PER_G: f64 = 2048.0;
/// Flywheel speed resolution of the `erpm[0]` field (100 eRPM, 12 poles), rad/s.
pub const ROTOR_SPEED_QUANTUM_RAD_S: f64 = 100.0 / 6.0 * 2.0 * std::f64::consts::PI / 60.0;
/// The anchor board's inertia about its centre of mass, IMU frame, kg m^2 (rounded).
pub const BOARD_INERTIA: [[f64; 3]; 3] = [
    [7.5e-5, -1.7e-6, 1.1e-6],
    [-1.7e-6, 2.2e-5, 6.8e-6],
    [1.1e-6, 6.8e-6, 8.8e-5],
];
/// The anchor board's flywheel inertia, kg m^2.
pub const BOARD_ROTOR_INERTIA: f64 = 1.69e-6;
/// Position of the board's centre of mass seen from the IMU, m.
pub const BOARD_COM_FROM_IMU: [f64; 3] = [10.9e-3, 1.6e-3, 9.0e-3];

/// How the flywheel speed varies. Times are relative to the release.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum RotorProfile {
    /// No rotor momentum at all.
    None,
    /// Constant speed, rad/s.
    Constant(f64),
    /// Idle, then a raised-cosine ramp up to `peak`, a hold, and a raised-cosine ramp back to
    /// idle (speed and acceleration continuous).
    SpinUp {
        /// Idle speed, rad/s.
        idle: f64,
        /// Peak speed, rad/s.
        peak: f64,
        /// Start of the ramp up after the release, s.
        start_after_release: f64,
        /// Duration of the ramp up, s.
        ramp_up: f64,
        /// Time at the peak, s.
        hold: f64,
        /// Duration of the ramp down, s.
        ramp_down: f64,
    },
}

impl RotorProfile {
    /// The data's profile: idle at 175 rad/s, up to 1250 rad/s and back inside the free flight
    /// (from 0.08 s to 0.48 s after the release).
    pub fn board_spin_up() -> Self {
        RotorProfile::SpinUp {
            idle: 175.0,
            peak: 1250.0,
            start_after_release: 0.08,
            ramp_up: 0.15,
            hold: 0.05,
            ramp_down: 0.20,
        }
    }

    /// Speed (rad/s) and its time derivative (rad/s^2) at `s` seconds after the release.
    pub fn speed_and_accel(&self, s: f64) -> (f64, f64) {
        match *self {
            RotorProfile::None => (0.0, 0.0),
            RotorProfile::Constant(v) => (v, 0.0),
            RotorProfile::SpinUp {
                idle,
                peak,
                start_after_release,
                ramp_up,
                hold,
                ramp_down,
            } => {
                let pi = std::f64::consts::PI;
                let d = peak - idle;
                let u = s - start_after_release;
                if u <= 0.0 {
                    (idle, 0.0)
                } else if u < ramp_up {
                    let x = u / ramp_up;
                    (
                        idle + d * 0.5 * (1.0 - (pi * x).cos()),
                        d * 0.5 * pi / ramp_up * (pi * x).sin(),
                    )
                } else if u < ramp_up + hold {
                    (peak, 0.0)
                } else if u < ramp_up + hold + ramp_down {
                    let x = (u - ramp_up - hold) / ramp_down;
                    (
                        peak - d * 0.5 * (1.0 - (pi * x).cos()),
                        -d * 0.5 * pi / ramp_down * (pi * x).sin(),
                    )
                } else {
                    (idle, 0.0)
                }
            }
        }
    }
}

/// A rotor (flywheel) inside the body.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Rotor {
    /// Rotor inertia about its axis, kg m^2.
    pub inertia: f64,
    /// Unit axis in the IMU frame (normalised on use).
    pub axis: [f64; 3],
    /// Speed profile.
    pub profile: RotorProfile,
}

impl Rotor {
    /// No rotor.
    pub fn none() -> Self {
        Rotor {
            inertia: 0.0,
            axis: [0.0, 0.0, -1.0],
            profile: RotorProfile::None,
        }
    }

    /// The anchor board's flywheel (about -z) with the data's spin-up profile.
    pub fn board() -> Self {
        Rotor {
            inertia: BOARD_ROTOR_INERTIA,
            axis: [0.0, 0.0, -1.0],
            profile: RotorProfile::board_spin_up(),
        }
    }

    pub fn unit_axis(&self) -> [f64; 3] {
        let n = norm(self.axis);
        if n > 0.0 {
            self.axis.map(|v| v / n)
        } else {
            [0.0; 3]
        }
    }

    /// `(h, h')` at `s` seconds after the release (body frame, N m s and N m).
    pub fn momentum(&self, s: f64) -> ([f64; 3], [f64; 3]) {
        let (v, dv) = self.profile.speed_and_accel(s);
        let e = self.unit_axis();
        (
            e.map(|x| self.inertia * v * x),
            e.map(|x| self.inertia * dv * x),
        )
    }
}

/// Gyro error model.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GyroSensor {
    /// White noise standard deviation per sample, rad/s.
    pub noise_std: f64,
    /// Constant bias, rad/s.
    pub bias: [f64; 3],
    /// Full scale, rad/s: readings are clipped to +-full_scale.
    pub full_scale: f64,
    /// Quantise to the logged resolution (16.384 LSB per deg/s).
    pub quantize: bool,
}

/// Accelerometer error model.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AccelSensor {
    /// White noise standard deviation per sample, m/s^2.
    pub noise_std: f64,
    /// Full scale, m/s^2.
    pub full_scale: f64,
    /// Quantise to the logged resolution (2048 LSB per g).
    pub quantize: bool,
}

/// Everything that defines one simulated throw. [`ThrowConfig::default`] is the anchor board
/// thrown like in the shared logs.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ThrowConfig {
    /// Inertia tensor about the centre of mass, IMU frame, kg m^2 (symmetric).
    pub inertia: [[f64; 3]; 3],
    /// Position of the centre of mass seen from the IMU, m. The accelerometer's lever arm in
    /// `f = w x (w x r) + w' x r` is `r = -com_from_imu` (the IMU seen from the centre of mass).
    pub com_from_imu: [f64; 3],
    /// The flywheel.
    pub rotor: Rotor,
    /// Sample rate, Hz.
    pub rate_hz: f64,
    /// RK4 steps per sample.
    pub substeps: usize,
    /// Seconds still on the bench.
    pub still_s: f64,
    /// Seconds in the hand (picked up, swung, thrown); 0 with `throw = false`.
    pub hand_s: f64,
    /// Seconds of free flight.
    pub free_s: f64,
    /// Time constant of the decay of `w` at the catch, s (~50 ms to a few percent).
    pub catch_tau_s: f64,
    /// Peak centre-of-mass acceleration of the catch impact, in g.
    pub catch_peak_g: f64,
    /// Duration of the impact pulse, s.
    pub catch_pulse_s: f64,
    /// Seconds held after the catch.
    pub held_s: f64,
    /// Angular velocity at the release (body frame), rad/s.
    pub omega_release: [f64; 3],
    /// Amplitude of the hand's angular wobble, rad/s.
    pub hand_wobble_rad_s: f64,
    /// `false`: the body stays on the bench for the whole recording (`still_s`).
    pub throw: bool,
    /// Initial attitude on the bench, rotation vector (rad), body to world.
    pub initial_tilt: [f64; 3],
    /// Gyro model.
    pub gyro: GyroSensor,
    /// Accelerometer model.
    pub accel: AccelSensor,
    /// Quantise the reported rotor speed to the `erpm[0]` resolution.
    pub quantize_rotor_speed: bool,
    /// Air drag on the spinning rotor in free flight, `tau = -c |h| h` (1/(kg m^2); 0: none):
    /// an external torque, unlike the motor's.
    pub rotor_drag: f64,
    /// Air drag on the tumbling body in free flight, `tau_k = -c_k |w| w_k` (kg m^2; 0: none).
    pub aero_drag: [f64; 3],
    /// Seed of the noise and of the hand's motion.
    pub seed: u64,
}

impl Default for ThrowConfig {
    fn default() -> Self {
        ThrowConfig {
            inertia: BOARD_INERTIA,
            com_from_imu: BOARD_COM_FROM_IMU,
            rotor: Rotor::board(),
            rate_hz: 4000.0,
            substeps: 4,
            still_s: 0.5,
            hand_s: 1.2,
            free_s: 0.6,
            catch_tau_s: 0.012,
            catch_peak_g: 30.0,
            catch_pulse_s: 0.02,
            held_s: 0.3,
            omega_release: [9.0, -8.0, -13.0],
            hand_wobble_rad_s: 3.0,
            throw: true,
            initial_tilt: [0.02, -0.03, 0.4],
            gyro: GyroSensor {
                noise_std: 2e-3,
                bias: [0.0; 3],
                full_scale: GYRO_FULL_SCALE_RAD_S,
                quantize: false,
            },
            accel: AccelSensor {
                noise_std: 0.05,
                full_scale: 16.0 * G,
                quantize: false,
            },
            quantize_rotor_speed: false,
            rotor_drag: 0.0,
            aero_drag: [0.0; 3],
            seed: 1,
        }
    }
}

impl ThrowConfig {
    /// Lever arm of the accelerometer from the centre of mass, `r = -com_from_imu`, m.
    pub fn imu_from_com(&self) -> [f64; 3] {
        self.com_from_imu.map(|v| -v)
    }

    /// `w'` of the free flight at `s` seconds after the release.
    pub fn free_rhs(&self, w: [f64; 3], s: f64, jinv: &[[f64; 3]; 3]) -> [f64; 3] {
        let (h, dh) = self.rotor.momentum(s);
        let jw = matvec(&self.inertia, w);
        let l = [jw[0] + h[0], jw[1] + h[1], jw[2] + h[2]];
        let lxw = cross(l, w);
        let n = (h[0] * h[0] + h[1] * h[1] + h[2] * h[2]).sqrt();
        let wn = (w[0] * w[0] + w[1] * w[1] + w[2] * w[2]).sqrt();
        let tau: [f64; 3] =
            core::array::from_fn(|k| -self.rotor_drag * n * h[k] - self.aero_drag[k] * wn * w[k]);
        matvec(
            jinv,
            [
                lxw[0] - dh[0] + tau[0],
                lxw[1] - dh[1] + tau[1],
                lxw[2] - dh[2] + tau[2],
            ],
        )
    }
}

/// One simulated recording: readings as logged, and the truth behind them.
#[derive(Clone, Debug)]
pub struct SimThrow {
    /// Sample times, s (first at 0).
    pub t: Vec<f64>,
    /// Gyro readings, rad/s.
    pub gyro: Vec<[f32; 3]>,
    /// Whether any axis of the gyro reading is at full scale.
    pub gyro_clipped: Vec<bool>,
    /// Accelerometer readings (specific force), m/s^2.
    pub accel: Vec<[f32; 3]>,
    /// Reported flywheel speed, rad/s.
    pub rotor_rad_s: Vec<f32>,
    /// True release time, s (`None` when the body never leaves the bench).
    pub release_s: Option<f64>,
    /// True catch time, s.
    pub catch_s: Option<f64>,
    /// True angular velocity, rad/s.
    pub omega_true: Vec<[f64; 3]>,
    /// True angular acceleration, rad/s^2.
    pub omega_dot_true: Vec<[f64; 3]>,
    /// True specific force at the IMU, m/s^2.
    pub accel_true: Vec<[f64; 3]>,
    /// True flywheel speed, rad/s.
    pub rotor_true: Vec<f64>,
    /// True rotor momentum `h`, body frame, N m s.
    pub h_true: Vec<[f64; 3]>,
    /// True attitude, unit quaternion `(w, x, y, z)`, body to world.
    pub quat: Vec<[f64; 4]>,
    /// The configuration that produced it.
    pub config: ThrowConfig,
}

impl SimThrow {
    /// Indices of the samples inside the true free flight, `release_s <= t < catch_s`.
    pub fn free_flight(&self) -> Option<Range<usize>> {
        let (r, c) = (self.release_s?, self.catch_s?);
        let a = self.t.partition_point(|&t| t < r);
        let b = self.t.partition_point(|&t| t < c);
        Some(a..b)
    }

    /// Sample interval, s.
    pub fn dt(&self) -> f64 {
        1.0 / self.config.rate_hz
    }

    /// Total angular momentum in the body frame, `J w + h`, at sample `k` (true values).
    pub fn momentum_body(&self, k: usize) -> [f64; 3] {
        let jw = matvec(&self.config.inertia, self.omega_true[k]);
        let h = self.h_true[k];
        [jw[0] + h[0], jw[1] + h[1], jw[2] + h[2]]
    }

    /// A one-line-per-phase text summary (phases, rates, accelerometer levels).
    pub fn summary(&self) -> String {
        let mut s = String::new();
        let n = self.t.len();
        let seg = |a: usize, b: usize, name: &str| -> String {
            if b <= a {
                return format!("{name:>8}: (empty)\n");
            }
            let max_w = (a..b)
                .map(|k| norm(self.gyro[k].map(f64::from)))
                .fold(0.0, f64::max);
            let mean_f = (a..b)
                .map(|k| norm(self.accel[k].map(f64::from)))
                .sum::<f64>()
                / (b - a) as f64;
            let max_f = (a..b)
                .map(|k| norm(self.accel[k].map(f64::from)))
                .fold(0.0, f64::max);
            let max_r = (a..b)
                .map(|k| f64::from(self.rotor_rad_s[k]))
                .fold(0.0, f64::max);
            let clipped = (a..b).filter(|&k| self.gyro_clipped[k]).count();
            format!(
                "{name:>8}: t {:.4}..{:.4} s, {} samples, max |w| {:.1} rad/s, |f| mean {:.1} max {:.1} m/s^2, rotor max {:.0} rad/s, clipped {}\n",
                self.t[a],
                self.t[b - 1],
                b - a,
                max_w,
                mean_f,
                max_f,
                max_r,
                clipped
            )
        };
        match self.free_flight() {
            Some(r) => {
                s += &format!(
                    "release {:.6} s, catch {:.6} s\n",
                    self.release_s.unwrap_or(f64::NAN),
                    self.catch_s.unwrap_or(f64::NAN)
                );
                s += &seg(0, r.start, "before");
                s += &seg(r.start, r.end, "free");
                s += &seg(r.end, n, "after");
            }
            None => s += &seg(0, n, "still"),
        }
        s
    }

    /// Writes the CSV `t,wx,wy,wz,ax,ay,az,rotor_rad_s` (s, rad/s, m/s^2, rad/s), or with the
    /// unit mistakes of `opts` (header unchanged).
    pub fn write_csv(&self, path: &Path, opts: CsvOptions) -> Result<()> {
        if let Some(dir) = path.parent() {
            if !dir.as_os_str().is_empty() {
                std::fs::create_dir_all(dir)
                    .with_context(|| format!("creating {}", dir.display()))?;
            }
        }
        let f =
            std::fs::File::create(path).with_context(|| format!("creating {}", path.display()))?;
        let mut w = BufWriter::new(f);
        self.write_csv_to(&mut w, opts)?;
        w.flush()
            .with_context(|| format!("writing {}", path.display()))?;
        Ok(())
    }

    /// As [`SimThrow::write_csv`], to any writer.
    pub fn write_csv_to<W: Write>(&self, w: &mut W, opts: CsvOptions) -> Result<()> {
        writeln!(w, "t,wx,wy,wz,ax,ay,az,rotor_rad_s")?;
        let ws = if opts.deg_per_s {
            (180.0 / std::f64::consts::PI) as f32
        } else {
            1.0
        };
        let ts = if opts.time_ms { 1e3 } else { 1.0 };
        for k in 0..self.t.len() {
            let g = self.gyro[k];
            let a = self.accel[k];
            writeln!(
                w,
                "{:.7},{},{},{},{},{},{},{}",
                self.t[k] * ts,
                g[0] * ws,
                g[1] * ws,
                g[2] * ws,
                a[0],
                a[1],
                a[2],
                self.rotor_rad_s[k]
            )?;
        }
        Ok(())
    }
}

/// Unit choices of the CSV output: the defaults are the declared units; the others reproduce
/// common user mistakes.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct CsvOptions {
    /// Gyro columns in deg/s instead of rad/s.
    pub deg_per_s: bool,
    /// Time column in milliseconds instead of seconds.
    pub time_ms: bool,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Phase {
    Still,
    Hand,
    Free,
    Catch,
}

/// Smooth hand motion drawn from the seed.
struct Hand {
    t0: f64,
    dur: f64,
    w_rel: [f64; 3],
    amp: f64,
    freq: [[f64; 2]; 3],
    phase: [[f64; 2]; 3],
    swing_phase: [f64; 2],
}

impl Hand {
    fn omega(&self, t: f64) -> [f64; 3] {
        let pi = std::f64::consts::PI;
        let u = ((t - self.t0) / self.dur).clamp(0.0, 1.0);
        let window = (pi * u).sin().powi(2);
        let x = ((u - 0.7) / 0.3).clamp(0.0, 1.0);
        let ramp = x * x * (3.0 - 2.0 * x);
        std::array::from_fn(|i| {
            let wob: f64 = (0..2)
                .map(|m| (2.0 * pi * self.freq[i][m] * (t - self.t0) + self.phase[i][m]).sin())
                .sum::<f64>()
                * 0.5
                * self.amp;
            window * wob + ramp * self.w_rel[i]
        })
    }

    fn omega_dot(&self, t: f64) -> [f64; 3] {
        let e = 1e-6;
        let a = self.omega(t + e);
        let b = self.omega(t - e);
        std::array::from_fn(|i| (a[i] - b[i]) / (2.0 * e))
    }

    /// Centre-of-mass acceleration, world frame (z up): lift, swing, forward-up throw push.
    fn accel_com(&self, t: f64) -> [f64; 3] {
        let pi = std::f64::consts::PI;
        let s = t - self.t0;
        let mut a = [0.0; 3];
        let lift = 0.3;
        if s < lift {
            a[2] += 6.0 * (2.0 * pi * s / lift).sin();
        }
        let push = 0.2;
        let swing_end = self.dur - push;
        if s >= lift && s < swing_end {
            let u = (s - lift) / (swing_end - lift);
            let win = (pi * u).sin().powi(2);
            a[0] += 8.0 * win * (2.0 * pi * 1.6 * s + self.swing_phase[0]).sin();
            a[1] += 4.0 * win * (2.0 * pi * 2.3 * s + self.swing_phase[1]).sin();
            a[2] += 3.0 * win * (2.0 * pi * 1.1 * s).sin();
        }
        if s >= swing_end {
            let v = ((s - swing_end) / push).clamp(0.0, 1.0);
            let b = (pi * v).sin();
            a[0] += 20.0 * b;
            a[2] += 12.0 * b;
        }
        a
    }
}

/// Simulates the throw described by `cfg`.
pub fn simulate(cfg: &ThrowConfig) -> SimThrow {
    let mut rng = ChaCha8Rng::seed_from_u64(cfg.seed);
    let m = cfg.substeps.max(1);
    let dt = 1.0 / cfg.rate_hz;
    let h = dt / m as f64;
    // Phase boundaries on the internal grid (step indices).
    let steps = |s: f64| (s / h).round().max(0.0) as usize;
    let n_pick = steps(cfg.still_s);
    let (n_rel, n_catch, n_end) = if cfg.throw {
        let n_rel = n_pick + steps(cfg.hand_s).max(1);
        let n_catch = n_rel + steps(cfg.free_s).max(1);
        (n_rel, n_catch, n_catch + steps(cfg.held_s))
    } else {
        (usize::MAX, usize::MAX, n_pick)
    };
    let n_samples = n_end / m + 1;
    let t_rel = n_rel as f64 * h;
    let t_catch = n_catch as f64 * h;

    let mut u = || rng.gen::<f64>();
    let hand = Hand {
        t0: n_pick as f64 * h,
        dur: (n_rel.min(n_end) - n_pick.min(n_end)) as f64 * h,
        w_rel: cfg.omega_release,
        amp: cfg.hand_wobble_rad_s,
        freq: std::array::from_fn(|_| [0.8 + 1.5 * u(), 2.0 + 2.0 * u()]),
        phase: std::array::from_fn(|_| [TAU * u(), TAU * u()]),
        swing_phase: [TAU * u(), TAU * u()],
    };
    let catch_dir = {
        let d = [-0.5, 0.3 * (u() - 0.5), 1.0];
        let n = norm(d);
        d.map(|v| v / n)
    };

    let jinv = inverse3(&cfg.inertia);
    let r_arm = cfg.imu_from_com();
    let phase_of = |i: usize| -> Phase {
        if !cfg.throw || i < n_pick {
            Phase::Still
        } else if i < n_rel {
            Phase::Hand
        } else if i < n_catch {
            Phase::Free
        } else {
            Phase::Catch
        }
    };

    let mut q = quat_from_rotvec(cfg.initial_tilt);
    let mut w = [0.0; 3];
    let mut w_catch = [0.0; 3];
    let mut out = SimThrow {
        t: Vec::with_capacity(n_samples),
        gyro: Vec::with_capacity(n_samples),
        gyro_clipped: Vec::with_capacity(n_samples),
        accel: Vec::with_capacity(n_samples),
        rotor_rad_s: Vec::with_capacity(n_samples),
        release_s: cfg.throw.then_some(t_rel),
        catch_s: cfg.throw.then_some(t_catch),
        omega_true: Vec::with_capacity(n_samples),
        omega_dot_true: Vec::with_capacity(n_samples),
        accel_true: Vec::with_capacity(n_samples),
        rotor_true: Vec::with_capacity(n_samples),
        h_true: Vec::with_capacity(n_samples),
        quat: Vec::with_capacity(n_samples),
        config: *cfg,
    };
    // Prescribed angular velocity and acceleration (not used in free flight).
    let presc = |ph: Phase, t: f64, w_catch: [f64; 3]| -> ([f64; 3], [f64; 3]) {
        match ph {
            Phase::Still | Phase::Free => ([0.0; 3], [0.0; 3]),
            Phase::Hand => (hand.omega(t), hand.omega_dot(t)),
            Phase::Catch => {
                let e = (-(t - t_catch) / cfg.catch_tau_s).exp();
                (
                    w_catch.map(|v| v * e),
                    w_catch.map(|v| -v * e / cfg.catch_tau_s),
                )
            }
        }
    };
    let com_accel = |ph: Phase, t: f64| -> [f64; 3] {
        match ph {
            Phase::Still => [0.0; 3],
            Phase::Hand => hand.accel_com(t),
            Phase::Free => [0.0, 0.0, -G],
            Phase::Catch => {
                let s = t - t_catch;
                if s < cfg.catch_pulse_s {
                    let b =
                        cfg.catch_peak_g * G * (std::f64::consts::PI * s / cfg.catch_pulse_s).sin();
                    catch_dir.map(|v| v * b)
                } else {
                    [0.0; 3]
                }
            }
        }
    };

    let gyro_noise = Normal::new(0.0, cfg.gyro.noise_std.max(0.0)).ok();
    let accel_noise = Normal::new(0.0, cfg.accel.noise_std.max(0.0)).ok();
    let gyro_q = std::f64::consts::PI / 180.0 / GYRO_LSB_PER_DEG_S;
    let accel_q = G / ACCEL_LSB_PER_G;

    for i in 0..=n_end {
        let t = i as f64 * h;
        let ph = phase_of(i);
        if ph == Phase::Catch && i == n_catch {
            w_catch = w;
        }
        if ph != Phase::Free {
            w = presc(ph, t, w_catch).0;
        }
        if i % m == 0 {
            // Record a sample.
            let s_rel = t - t_rel;
            let rotor_phase_s = if cfg.throw { s_rel } else { -1.0 };
            let (hv, _) = cfg.rotor.momentum(rotor_phase_s);
            let (speed, _) = cfg.rotor.profile.speed_and_accel(rotor_phase_s);
            let wd = if ph == Phase::Free {
                cfg.free_rhs(w, s_rel, &jinv)
            } else {
                presc(ph, t, w_catch).1
            };
            let rot = quat_to_mat(q);
            let ac = com_accel(ph, t);
            let d = [ac[0], ac[1], ac[2] + G];
            let f_lin = mat_t_vec(&rot, d);
            let cen = cross(w, cross(w, r_arm));
            let tan = cross(wd, r_arm);
            let f: [f64; 3] = std::array::from_fn(|k| f_lin[k] + cen[k] + tan[k]);
            let mut clipped = false;
            let gyro: [f32; 3] = std::array::from_fn(|k| {
                let n = match gyro_noise {
                    Some(dist) if cfg.gyro.noise_std > 0.0 => dist.sample(&mut rng),
                    _ => 0.0,
                };
                let mut x = w[k] + cfg.gyro.bias[k] + n;
                if x.abs() >= cfg.gyro.full_scale {
                    clipped = true;
                }
                x = x.clamp(-cfg.gyro.full_scale, cfg.gyro.full_scale);
                if cfg.gyro.quantize {
                    x = (x / gyro_q).round() * gyro_q;
                }
                x as f32
            });
            let accel: [f32; 3] = std::array::from_fn(|k| {
                let n = match accel_noise {
                    Some(dist) if cfg.accel.noise_std > 0.0 => dist.sample(&mut rng),
                    _ => 0.0,
                };
                let mut x = (f[k] + n).clamp(-cfg.accel.full_scale, cfg.accel.full_scale);
                if cfg.accel.quantize {
                    x = (x / accel_q).round() * accel_q;
                }
                x as f32
            });
            let reported = if cfg.quantize_rotor_speed {
                (speed / ROTOR_SPEED_QUANTUM_RAD_S).round() * ROTOR_SPEED_QUANTUM_RAD_S
            } else {
                speed
            };
            out.t.push(i as f64 * h);
            out.gyro.push(gyro);
            out.gyro_clipped.push(clipped);
            out.accel.push(accel);
            out.rotor_rad_s.push(reported as f32);
            out.omega_true.push(w);
            out.omega_dot_true.push(wd);
            out.accel_true.push(f);
            out.rotor_true.push(speed);
            out.h_true.push(hv);
            out.quat.push(q);
        }
        if i == n_end {
            break;
        }
        // One RK4 step of (w, q) over [t, t + h].
        let deriv = |tt: f64, x: &[f64; 7]| -> [f64; 7] {
            let (ww, dw) = if ph == Phase::Free {
                let ww = [x[0], x[1], x[2]];
                (ww, cfg.free_rhs(ww, tt - t_rel, &jinv))
            } else {
                (presc(ph, tt, w_catch).0, [0.0; 3])
            };
            let dq = quat_rate([x[3], x[4], x[5], x[6]], ww);
            [dw[0], dw[1], dw[2], dq[0], dq[1], dq[2], dq[3]]
        };
        let x0 = [w[0], w[1], w[2], q[0], q[1], q[2], q[3]];
        let x1 = rk4_7(deriv, t, &x0, h);
        w = [x1[0], x1[1], x1[2]];
        let qn = (x1[3] * x1[3] + x1[4] * x1[4] + x1[5] * x1[5] + x1[6] * x1[6]).sqrt();
        q = [x1[3] / qn, x1[4] / qn, x1[5] / qn, x1[6] / qn];
    }
    out
}

fn rk4_7<F: Fn(f64, &[f64; 7]) -> [f64; 7]>(f: F, t: f64, x: &[f64; 7], h: f64) -> [f64; 7] {
    let add = |a: &[f64; 7], b: &[f64; 7], s: f64| -> [f64; 7] {
        std::array::from_fn(|k| a[k] + s * b[k])
    };
    let k1 = f(t, x);
    let k2 = f(t + h / 2.0, &add(x, &k1, h / 2.0));
    let k3 = f(t + h / 2.0, &add(x, &k2, h / 2.0));
    let k4 = f(t + h, &add(x, &k3, h));
    std::array::from_fn(|k| x[k] + h / 6.0 * (k1[k] + 2.0 * k2[k] + 2.0 * k3[k] + k4[k]))
}

/// Draws a release rate of magnitude in `[lo, hi]` rad/s in a random direction, keeping the
/// first candidate whose free flight (simulated without noise) stays below `max_axis` rad/s on
/// every axis; after 64 candidates, the last one.
fn draw_release(
    cfg: &ThrowConfig,
    rng: &mut ChaCha8Rng,
    lo: f64,
    hi: f64,
    max_axis: f64,
) -> [f64; 3] {
    let jinv = inverse3(&cfg.inertia);
    let mut w_rel = cfg.omega_release;
    for _ in 0..64 {
        let dir = loop {
            let d: [f64; 3] = std::array::from_fn(|_| rng.gen::<f64>() * 2.0 - 1.0);
            let n = norm(d);
            if n > 0.2 && n <= 1.0 {
                break d.map(|v| v / n);
            }
        };
        let mag = lo + (hi - lo) * rng.gen::<f64>();
        w_rel = dir.map(|v| v * mag);
        let h = 1.0 / (cfg.rate_hz * cfg.substeps.max(1) as f64);
        let n = (cfg.free_s / h).round() as usize;
        let mut w = w_rel;
        let mut peak: f64 = 0.0;
        for i in 0..n {
            let s = i as f64 * h;
            w = crate::rigid_body::rk4(|x| cfg.free_rhs(x, s, &jinv), w, h);
            peak = peak.max(w[0].abs()).max(w[1].abs()).max(w[2].abs());
        }
        if peak < max_axis {
            return w_rel;
        }
    }
    w_rel
}

fn scenario_rng(seed: u64, salt: u64) -> ChaCha8Rng {
    ChaCha8Rng::seed_from_u64(seed ^ salt.wrapping_mul(0x9E37_79B9_7F4A_7C15))
}

/// The anchor board thrown like in the shared logs: flywheel spin-up inside a 0.6 s free
/// flight, tumble of 15-25 rad/s in a seeded direction that stays below 0.9 of the gyro full
/// scale, white noise 2e-3 rad/s, logged resolution.
pub fn board_throw_config(seed: u64) -> ThrowConfig {
    let mut cfg = ThrowConfig {
        seed,
        ..ThrowConfig::default()
    };
    cfg.gyro.quantize = true;
    cfg.accel.quantize = true;
    cfg.quantize_rotor_speed = true;
    let mut rng = scenario_rng(seed, 1);
    cfg.omega_release = draw_release(&cfg, &mut rng, 15.0, 25.0, 0.9 * cfg.gyro.full_scale);
    cfg
}

/// [`board_throw_config`] simulated.
pub fn board_throw(seed: u64) -> SimThrow {
    simulate(&board_throw_config(seed))
}

/// A heavier, more asymmetric body (the board on a proof body) tumbling at 20-25 rad/s for
/// 0.7 s with the flywheel spin-up.
pub fn tumbling_with_spinup_config(seed: u64) -> ThrowConfig {
    let mut cfg = board_throw_config(seed);
    cfg.inertia = [
        [2.4e-4, -4.0e-6, 6.0e-6],
        [-4.0e-6, 1.5e-4, 1.2e-5],
        [6.0e-6, 1.2e-5, 3.1e-4],
    ];
    cfg.com_from_imu = [5.0e-3, -12.0e-3, 20.0e-3];
    cfg.free_s = 0.7;
    let mut rng = scenario_rng(seed, 2);
    cfg.omega_release = draw_release(&cfg, &mut rng, 20.0, 25.0, 0.9 * cfg.gyro.full_scale);
    cfg
}

/// [`tumbling_with_spinup_config`] simulated.
pub fn tumbling_with_spinup(seed: u64) -> SimThrow {
    simulate(&tumbling_with_spinup_config(seed))
}

/// The board bolted to something else: a body of inertia `inertia` about its centre of mass,
/// which lies at `com_from_imu`, thrown like [`tumbling_with_spinup_config`] (20-25 rad/s for
/// 0.7 s, the board's flywheel spin-up). What `inertia calibrate` is fed for an assembly.
pub fn assembly_throw_config(
    seed: u64,
    inertia: [[f64; 3]; 3],
    com_from_imu: [f64; 3],
) -> ThrowConfig {
    let mut cfg = board_throw_config(seed);
    cfg.inertia = inertia;
    cfg.com_from_imu = com_from_imu;
    cfg.free_s = 0.7;
    let mut rng = scenario_rng(seed, 5);
    cfg.omega_release = draw_release(&cfg, &mut rng, 20.0, 25.0, 0.9 * cfg.gyro.full_scale);
    cfg
}

/// The board without a flywheel (no rotor momentum at all): the tensor is determined up to
/// scale only.
pub fn no_rotor_toss_config(seed: u64) -> ThrowConfig {
    let mut cfg = board_throw_config(seed);
    cfg.rotor = Rotor::none();
    let mut rng = scenario_rng(seed, 3);
    cfg.omega_release = draw_release(&cfg, &mut rng, 15.0, 25.0, 0.9 * cfg.gyro.full_scale);
    cfg
}

/// [`no_rotor_toss_config`] simulated.
pub fn no_rotor_toss(seed: u64) -> SimThrow {
    simulate(&no_rotor_toss_config(seed))
}

/// The board thrown hard (40-50 rad/s): the gyro clips at +-2000 deg/s for part of the free
/// flight. Flywheel at a constant idle.
pub fn clipped_toss_config(seed: u64) -> ThrowConfig {
    let mut cfg = board_throw_config(seed);
    cfg.rotor.profile = RotorProfile::Constant(175.0);
    let mut rng = scenario_rng(seed, 4);
    cfg.omega_release = draw_release(&cfg, &mut rng, 40.0, 50.0, f64::INFINITY);
    cfg
}

/// [`clipped_toss_config`] simulated.
pub fn clipped_toss(seed: u64) -> SimThrow {
    simulate(&clipped_toss_config(seed))
}

/// Three seconds on the bench, never picked up (no free flight; the flywheel idles).
pub fn still_config(seed: u64) -> ThrowConfig {
    let mut cfg = board_throw_config(seed);
    cfg.throw = false;
    cfg.still_s = 3.0;
    cfg
}

/// [`still_config`] simulated.
pub fn still(seed: u64) -> SimThrow {
    simulate(&still_config(seed))
}

/// The scenario names [`scenario`] knows.
pub const SCENARIOS: [&str; 5] = [
    "board_throw",
    "tumbling_with_spinup",
    "no_rotor_toss",
    "clipped_toss",
    "still",
];

/// The configuration of a named scenario (see [`SCENARIOS`]).
pub fn scenario_config(name: &str, seed: u64) -> Option<ThrowConfig> {
    Some(match name {
        "board_throw" => board_throw_config(seed),
        "tumbling_with_spinup" => tumbling_with_spinup_config(seed),
        "no_rotor_toss" => no_rotor_toss_config(seed),
        "clipped_toss" => clipped_toss_config(seed),
        "still" => still_config(seed),
        _ => return None,
    })
}

/// A named scenario simulated (see [`SCENARIOS`]).
pub fn scenario(name: &str, seed: u64) -> Option<SimThrow> {
    scenario_config(name, seed).map(|c| simulate(&c))
}

// --- small linear algebra on arrays ---

/// `a x b`.
pub fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    crate::rigid_body::cross(a, b)
}

/// Euclidean norm.
pub fn norm(a: [f64; 3]) -> f64 {
    (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]).sqrt()
}

/// `M v`.
pub fn matvec(m: &[[f64; 3]; 3], v: [f64; 3]) -> [f64; 3] {
    std::array::from_fn(|i| m[i][0] * v[0] + m[i][1] * v[1] + m[i][2] * v[2])
}

fn mat_t_vec(m: &[[f64; 3]; 3], v: [f64; 3]) -> [f64; 3] {
    std::array::from_fn(|i| m[0][i] * v[0] + m[1][i] * v[1] + m[2][i] * v[2])
}

/// Inverse of a 3x3 matrix by the adjugate (no singularity check: inertia tensors are
/// positive definite).
pub fn inverse3(m: &[[f64; 3]; 3]) -> [[f64; 3]; 3] {
    let c = |i: usize, j: usize| {
        let (i1, i2) = ((i + 1) % 3, (i + 2) % 3);
        let (j1, j2) = ((j + 1) % 3, (j + 2) % 3);
        m[i1][j1] * m[i2][j2] - m[i1][j2] * m[i2][j1]
    };
    let det = m[0][0] * c(0, 0) + m[0][1] * c(0, 1) + m[0][2] * c(0, 2);
    std::array::from_fn(|i| std::array::from_fn(|j| c(j, i) / det))
}

/// Unit quaternion `(w, x, y, z)` of a rotation vector.
pub fn quat_from_rotvec(v: [f64; 3]) -> [f64; 4] {
    let a = norm(v);
    if a < 1e-300 {
        return [1.0, 0.0, 0.0, 0.0];
    }
    let (s, c) = (0.5 * a).sin_cos();
    [c, s * v[0] / a, s * v[1] / a, s * v[2] / a]
}

/// `q' = q (0, w) / 2` for a body-frame angular velocity `w`.
pub fn quat_rate(q: [f64; 4], w: [f64; 3]) -> [f64; 4] {
    let [a, b, c, d] = q;
    [
        0.5 * (-b * w[0] - c * w[1] - d * w[2]),
        0.5 * (a * w[0] + c * w[2] - d * w[1]),
        0.5 * (a * w[1] + d * w[0] - b * w[2]),
        0.5 * (a * w[2] + b * w[1] - c * w[0]),
    ]
}

/// Body-to-world rotation matrix of a unit quaternion.
pub fn quat_to_mat(q: [f64; 4]) -> [[f64; 3]; 3] {
    let [w, x, y, z] = q;
    [
        [
            1.0 - 2.0 * (y * y + z * z),
            2.0 * (x * y - w * z),
            2.0 * (x * z + w * y),
        ],
        [
            2.0 * (x * y + w * z),
            1.0 - 2.0 * (x * x + z * z),
            2.0 * (y * z - w * x),
        ],
        [
            2.0 * (x * z - w * y),
            2.0 * (y * z + w * x),
            1.0 - 2.0 * (x * x + y * y),
        ],
    ]
}
