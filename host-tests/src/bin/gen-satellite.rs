//! Writes a simulated small satellite's gyro and reaction-wheel log as a firmware replay file
//! (`firmware::replay_format`, version 6, no orbit), for the QEMU image's continuous mode
//! (`scripts/firmware-paced.sh`, `scripts/run.sh --replay FILE --refit-every N`).
//!
//! The body: a 3U-class satellite of inertia `J` (kg m^2, with products of inertia) tumbling
//! slowly with four reaction wheels in a pyramid (each 2.4e-5 kg m^2, 35 deg from +z), their
//! speeds relative to the body slow sinusoids around a bias. Between actuations the body is
//! torque-free (`L' = L x w` in the body frame, `L = J w + h`, RK4 with 20 substeps a sample);
//! during an actuation (a magnetorquer's torque of `--torque` N m about a fixed body axis) the
//! board flags every sample, as the firmware's `BoardInputs::actuated` would. The gyro adds
//! white noise of `--noise` rad/s (seeded).
//!
//! ```text
//! gen-satellite --out sat.irpl [--hours 2] [--rate 10] [--noise 2e-4] [--seed 1]
//!               [--actuate-every 1800] [--actuate-for 20] [--torque 2e-5]
//! ```
//! `--actuate-every 0` gives a torque-free log (no flags). The true tensor and the wheel table
//! go to standard output.

use std::io::Write;
use std::path::PathBuf;

use clap::Parser;
use firmware::replay_format::{
    encode_rotor, encode_sample, ReplayHeader, ReplaySample, HEADER_LEN, ROTOR_LEN, SAMPLE_MAX_LEN,
};
use identifier_core::{Rotor, MAX_ROTORS};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

#[derive(Parser)]
struct Args {
    /// The replay file to write.
    #[arg(long)]
    out: PathBuf,
    /// Length of the log, hours.
    #[arg(long, default_value_t = 2.0)]
    hours: f64,
    /// Gyro rate, Hz.
    #[arg(long, default_value_t = 10.0)]
    rate: f64,
    /// Gyro white noise, rad/s per sample.
    #[arg(long, default_value_t = 2e-4)]
    noise: f64,
    /// Noise seed.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Seconds between the starts of two actuations (0: none).
    #[arg(long, default_value_t = 1800.0)]
    actuate_every: f64,
    /// Seconds each actuation lasts.
    #[arg(long, default_value_t = 20.0)]
    actuate_for: f64,
    /// The actuation's torque, N m (about the body axis (0.6, 0, 0.8)).
    #[arg(long, default_value_t = 2e-5)]
    torque: f64,
}

/// The body's inertia, kg m^2.
const J: [[f64; 3]; 3] = [
    [0.0400, 0.0010, -0.0005],
    [0.0010, 0.0450, 0.0008],
    [-0.0005, 0.0008, 0.0120],
];
/// Each wheel's inertia about its axis, kg m^2.
const WHEEL_J: f64 = 2.4e-5;

fn solve(j: &[[f64; 3]; 3], b: [f64; 3]) -> [f64; 3] {
    // Cramer's rule (J is well conditioned).
    let det = |m: &[[f64; 3]; 3]| {
        m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1])
            - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
            + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0])
    };
    let d = det(j);
    std::array::from_fn(|k| {
        let mut m = *j;
        for r in 0..3 {
            m[r][k] = b[r];
        }
        det(&m) / d
    })
}

fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

fn main() -> anyhow::Result<()> {
    let a = Args::parse();
    let (s, c) = (35f64.to_radians().sin(), 35f64.to_radians().cos());
    let axes = [[s, 0.0, c], [0.0, s, c], [-s, 0.0, c], [0.0, -s, c]];
    // Speeds: bias + amplitude * sin(2 pi t / period + phase), rad/s.
    let wheels = [
        (300.0, 120.0, 900.0, 0.0),
        (-200.0, 150.0, 1300.0, 1.0),
        (250.0, 90.0, 700.0, 2.0),
        (-350.0, 110.0, 1100.0, 3.0),
    ];
    let speed = |i: usize, t: f64| {
        let (b, amp, p, ph) = wheels[i];
        b + amp * (2.0 * std::f64::consts::PI * t / p + ph).sin()
    };
    let h_of = |t: f64| -> [f64; 3] {
        let mut h = [0.0; 3];
        for (i, g) in axes.iter().enumerate() {
            let w = speed(i, t);
            for k in 0..3 {
                h[k] += WHEEL_J * w * g[k];
            }
        }
        h
    };
    let torque_axis = [0.6, 0.0, 0.8];
    let actuated = |t: f64| {
        a.actuate_every > 0.0 && t >= a.actuate_every && (t % a.actuate_every) < a.actuate_for
    };
    let n = (a.hours * 3600.0 * a.rate).round() as usize;
    let dt = 1.0 / a.rate;
    let sub = 20;
    let h_step = dt / sub as f64;
    // Initial body rate 0.06 rad/s about a tilted axis.
    let w0 = [0.04, -0.03, 0.035];
    let jw0: [f64; 3] = std::array::from_fn(|k| (0..3).map(|m| J[k][m] * w0[m]).sum());
    let h0 = h_of(0.0);
    let mut l: [f64; 3] = std::array::from_fn(|k| jw0[k] + h0[k]);
    let deriv = |l: [f64; 3], t: f64| -> [f64; 3] {
        let h = h_of(t);
        let w = solve(&J, [l[0] - h[0], l[1] - h[1], l[2] - h[2]]);
        let mut d = cross(l, w);
        if actuated(t) {
            for k in 0..3 {
                d[k] += a.torque * torque_axis[k];
            }
        }
        d
    };
    let mut rng = ChaCha8Rng::seed_from_u64(a.seed);
    let noise = Normal::new(0.0, a.noise)?;
    let rotors: Vec<Rotor> = axes
        .iter()
        .map(|g| Rotor::new(WHEEL_J as f32, g.map(|x| x as f32)))
        .collect();
    let header = ReplayHeader {
        rate_hz: a.rate as f32,
        noise_std: a.noise as f32,
        full_scale: 2000f32.to_radians(),
        with_accel: false,
        orbit: false,
        centred: false,
        momentum_quantum: 0.0,
        gyro_averaging: 0.0,
        gyro_smoothing: 0.0,
        rotors: rotors.len() as u32,
        samples: n as u32,
    };
    let mut out = Vec::with_capacity(HEADER_LEN + 16 * rotors.len() + n * (32 + 16));
    let mut hb = [0u8; HEADER_LEN];
    header.encode(&mut hb);
    out.extend_from_slice(&hb);
    let mut table = vec![0u8; ROTOR_LEN * rotors.len()];
    for (i, r) in rotors.iter().enumerate() {
        encode_rotor(r, i, &mut table);
    }
    out.extend_from_slice(&table);
    let mut t = 0.0f64;
    let mut flagged = 0usize;
    let mut buf = [0u8; SAMPLE_MAX_LEN];
    for _ in 0..n {
        let h = h_of(t);
        let w = solve(&J, [l[0] - h[0], l[1] - h[1], l[2] - h[2]]);
        let mut speeds = [0.0f32; MAX_ROTORS];
        for (i, s) in speeds.iter_mut().take(4).enumerate() {
            *s = speed(i, t) as f32;
        }
        let act = actuated(t);
        flagged += usize::from(act);
        let sample = ReplaySample {
            omega: std::array::from_fn(|k| (w[k] + noise.sample(&mut rng)) as f32),
            accel: [0.0; 3],
            dt: dt as f32,
            actuated: act,
            speeds,
        };
        let len = encode_sample(&sample, rotors.len(), &mut buf);
        out.extend_from_slice(&buf[..len]);
        for _ in 0..sub {
            let k1 = deriv(l, t);
            let y2: [f64; 3] = std::array::from_fn(|k| l[k] + 0.5 * h_step * k1[k]);
            let k2 = deriv(y2, t + 0.5 * h_step);
            let y3: [f64; 3] = std::array::from_fn(|k| l[k] + 0.5 * h_step * k2[k]);
            let k3 = deriv(y3, t + 0.5 * h_step);
            let y4: [f64; 3] = std::array::from_fn(|k| l[k] + h_step * k3[k]);
            let k4 = deriv(y4, t + h_step);
            for k in 0..3 {
                l[k] += h_step / 6.0 * (k1[k] + 2.0 * k2[k] + 2.0 * k3[k] + k4[k]);
            }
            t += h_step;
        }
    }
    std::fs::File::create(&a.out)?.write_all(&out)?;
    println!(
        "wrote {} ({} samples at {} Hz, {:.2} h, {} flagged as actuated, 4 wheels of {WHEEL_J:e} kg m^2)",
        a.out.display(),
        n,
        a.rate,
        n as f64 / a.rate / 3600.0,
        flagged
    );
    println!(
        "true J = [[{:e}, {:e}, {:e}], [{:e}, {:e}, {:e}], [{:e}, {:e}, {:e}]] kg m^2",
        J[0][0], J[0][1], J[0][2], J[1][0], J[1][1], J[1][2], J[2][0], J[2][1], J[2][2]
    );
    Ok(())
}
