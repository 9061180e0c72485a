//! Simulated logs shared by the integration tests (`identify`, `export`): each test crate
//! includes this module (`mod common;`) and uses what it needs.
// Each test crate that includes this module uses a subset of it.
#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::process::Command;

use log_writers::blackbox as blackbox_writer;

/// The test crate's own directory `name` under Cargo's temporary directory, made if missing.
pub fn out_dir(name: &str) -> PathBuf {
    let d = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join(name);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// `inertia identify ARGS --json OUT`: the exit code, the JSON (null when none was written:
/// a JSON left by an earlier run is removed first) and stderr.
pub fn identify_cli<S: AsRef<std::ffi::OsStr>>(
    args: &[S],
    json: &Path,
) -> (i32, serde_json::Value, String) {
    let _ = std::fs::remove_file(json);
    let o = Command::new(env!("CARGO_BIN_EXE_inertia"))
        .arg("identify")
        .args(args)
        .arg("--json")
        .arg(json)
        .output()
        .unwrap();
    let v = std::fs::read_to_string(json)
        .ok()
        .and_then(|s| serde_json::from_str(&s).ok())
        .unwrap_or(serde_json::Value::Null);
    let err = String::from_utf8_lossy(&o.stderr).to_string();
    (o.status.code().unwrap_or(-1), v, err)
}

/// Unit normal deviates from `seed`: xorshift64, the sum of twelve uniforms less 6.
pub fn gaussian(seed: u64) -> impl FnMut() -> f64 {
    let mut s = seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1;
    move || {
        let mut acc = 0.0;
        for _ in 0..12 {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            acc += (s >> 11) as f64 / (1u64 << 53) as f64;
        }
        acc - 6.0
    }
}

/// Betaflight's default gyro filters at an 8 kHz loop as its header lists them (first-order
/// stages at 250 and 500 Hz, no notches), the gyro logged in tenths of deg/s when
/// `high_resolution`, else in whole deg/s.
pub fn betaflight_header(high_resolution: bool) -> Vec<(&'static str, String)> {
    [
        (
            "blackbox_high_resolution",
            if high_resolution { "1" } else { "0" },
        ),
        ("looptime", "125"),
        ("gyro_lpf1_type", "0"),
        ("gyro_lpf1_static_hz", "250"),
        ("gyro_lpf1_dyn_hz", "0,0"),
        ("gyro_lpf2_type", "0"),
        ("gyro_lpf2_static_hz", "500"),
        ("dyn_notch_count", "0"),
    ]
    .iter()
    .map(|(k, v)| (*k, v.to_string()))
    .collect()
}

/// `header` without its gyro low-pass lines: a log that names no gyro filter.
pub fn without_gyro_filters(header: &[(&'static str, String)]) -> Vec<(&'static str, String)> {
    header
        .iter()
        .filter(|(k, _)| !k.starts_with("gyro_lpf"))
        .cloned()
        .collect()
}

/// A body with a flywheel spinning up (as the thrown-FC board's, 175 to 1250 rad/s), simulated
/// at an 8 kHz gyro loop, its gyro through Betaflight's default filters (first-order stages
/// at 250 and 500 Hz: 0.95 ms late, 6e-7 s^2 of time spread), logged every fourth loop in
/// tenths of deg/s with the rotor's eRPM: frames of a Betaflight blackbox log. With `still`
/// (s, and `deg`: logged in whole deg/s, Betaflight's default), the log starts with the body
/// at rest on the bench that long.
pub fn betaflight_throw(
    moments: [f64; 3],
    w0: [f64; 3],
    rotor: f64,
    seed: u64,
) -> Vec<blackbox_writer::Frame> {
    betaflight_log_of(moments, w0, rotor, seed, 0.0, false)
}

pub fn betaflight_log_of(
    moments: [f64; 3],
    w0: [f64; 3],
    rotor: f64,
    seed: u64,
    still: f64,
    deg: bool,
) -> Vec<blackbox_writer::Frame> {
    let dt = 125e-6;
    let speed = |s: f64| -> (f64, f64) {
        // Idle, a cosine ramp up, a hold, a cosine ramp down (s after the log's start).
        let (idle, peak, pi) = (175.0, 1250.0, std::f64::consts::PI);
        let d = peak - idle;
        let u = s - 0.08;
        if u <= 0.0 || u >= 0.4 {
            (idle, 0.0)
        } else if u < 0.15 {
            let x = u / 0.15;
            (
                idle + d * 0.5 * (1.0 - (pi * x).cos()),
                d * 0.5 * pi / 0.15 * (pi * x).sin(),
            )
        } else if u < 0.2 {
            (peak, 0.0)
        } else {
            let x = (u - 0.2) / 0.2;
            (
                peak - d * 0.5 * (1.0 - (pi * x).cos()),
                -d * 0.5 * pi / 0.2 * (pi * x).sin(),
            )
        }
    };
    // Euler with a rotor along z: J w' = -w x (J w + h) - h'.
    let f = |s: f64, w: [f64; 3]| -> [f64; 3] {
        let (om, om_d) = speed(s);
        let l = [
            moments[0] * w[0],
            moments[1] * w[1],
            moments[2] * w[2] + rotor * om,
        ];
        let c = [
            w[1] * l[2] - w[2] * l[1],
            w[2] * l[0] - w[0] * l[2],
            w[0] * l[1] - w[1] * l[0],
        ];
        [
            -c[0] / moments[0],
            -c[1] / moments[1],
            (-c[2] - rotor * om_d) / moments[2],
        ]
    };
    let mut gauss = gaussian(seed);
    let gain = |hz: f64| {
        let x = 2.0 * std::f64::consts::PI * hz * dt;
        x / (1.0 + x)
    };
    let (k1, k2) = (gain(250.0), gain(500.0));
    let rest = (still / dt).round() as usize;
    let (mut w, mut p1, mut p2) = if rest > 0 {
        ([0.0; 3], [0.0; 3], [0.0; 3])
    } else {
        (w0, w0, w0)
    };
    let unit = if deg { 1.0 } else { 10.0 };
    let mut frames = Vec::new();
    for i in 0..rest + (0.7 / dt) as usize {
        if i == rest {
            w = w0;
        }
        let time = i as f64 * dt;
        let s = if i < rest {
            0.0
        } else {
            (i - rest) as f64 * dt
        };
        for a in 0..3 {
            let x = w[a] + 2e-3 * gauss();
            p1[a] += k1 * (x - p1[a]);
            p2[a] += k2 * (p1[a] - p2[a]);
        }
        if i % 4 == 0 {
            frames.push(blackbox_writer::Frame {
                time_us: 1_000_000 + (time * 1e6).round() as u64,
                gyro: p2.map(|v| (v.to_degrees() * unit).round() as i64),
                accel: None,
                erpm: (rotor > 0.0).then(|| {
                    (speed(s).0 * 6.0 * 60.0 / (2.0 * std::f64::consts::PI) / 100.0).round() as u64
                }),
            });
        }
        if i < rest {
            continue;
        }
        let k1 = f(s, w);
        let k2 = f(
            s + dt / 2.0,
            std::array::from_fn(|a| w[a] + dt / 2.0 * k1[a]),
        );
        let k3 = f(
            s + dt / 2.0,
            std::array::from_fn(|a| w[a] + dt / 2.0 * k2[a]),
        );
        let k4 = f(s + dt, std::array::from_fn(|a| w[a] + dt * k3[a]));
        for a in 0..3 {
            w[a] += dt / 6.0 * (k1[a] + 2.0 * k2[a] + 2.0 * k3[a] + k4[a]);
        }
    }
    frames
}

/// The simulated body's principal moments, kg m^2 (its axes the gyro's), for the throws of
/// [`betaflight_throw`] the export and pooling tests share.
pub const MOMENTS: [f64; 3] = [2.4e-4, 1.5e-4, 3.1e-4];
/// Its flywheel's inertia about z, kg m^2.
pub const ROTOR_INERTIA: f64 = 1.69e-6;
/// The same flywheel as `inertia identify`'s flags.
pub const ROTOR: [&str; 6] = [
    "--rotor-inertia",
    "1.69e-6",
    "--rotor-axis",
    "z",
    "--rotor-poles",
    "12",
];
