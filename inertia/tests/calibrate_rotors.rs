//! `inertia calibrate --vehicle` with several rotors, on simulated throws whose truth is known:
//! a board with four motors on three axes (two identical ones on +-z, a smaller one on x, a
//! larger one tilted), each with its own speed column and profile, thrown alone, bolted to a
//! proof body of known inertia and bolted to an unknown object. The vehicle file gives the
//! motors' inertias up to one common scale (1.69 here, as if the file held the datasheet's
//! ratios in microgram square metres): the calibrated scale must come back within its
//! standard deviation of the truth, each motor's inertia with it, and the object by difference
//! within its standard deviation. And the inputs that can go wrong: a log without a rotor
//! column the file names, rotors whose momentum is zero.

// Index loops read closest to the equations they simulate.
#![allow(clippy::needless_range_loop)]

mod common;

use std::f64::consts::PI;
use std::path::{Path, PathBuf};

use inertia::calibrate::{eigen, rel_frobenius, run, CalibrateArgs, CalibrationReport};

type M3 = [[f64; 3]; 3];

const RATE: f64 = 1000.0;
const G: f64 = 9.80665;
const BOARD_MASS: f64 = 0.10067;
const PROOF_MASS: f64 = 0.346;
const OBJECT_MASS: f64 = 0.21;
/// The board's tensor about its centre of mass (the anchor board's, rounded), kg m^2.
const BOARD_INERTIA: M3 = [
    [7.5e-5, -1.7e-6, 1.1e-6],
    [-1.7e-6, 2.2e-5, 6.8e-6],
    [1.1e-6, 6.8e-6, 8.8e-5],
];
/// The board's centre of mass from the IMU, m.
const BOARD_COM: [f64; 3] = [10.9e-3, 1.6e-3, 9.0e-3];
/// Each motor's true inertia over the vehicle file's.
const SCALE: f64 = 1.69;

/// A motor: the vehicle file's inertia, its axis, its column (and the column's unit factor
/// from rad/s), and its speed during the free flight: `from` rad/s until `at` s after the
/// release, a cosine ramp of `ramp` s to `to`, then `to`.
struct Motor {
    name: &'static str,
    column: &'static str,
    file_inertia: f64,
    axis: [f64; 3],
    rpm: bool,
    from: f64,
    to: f64,
    at: f64,
    ramp: f64,
}

const MOTORS: [Motor; 4] = [
    Motor {
        name: "m1",
        column: "m1_rad_s",
        file_inertia: 1.0e-6,
        axis: [0.0, 0.0, -1.0],
        rpm: false,
        from: 175.0,
        to: 1250.0,
        at: 0.08,
        ramp: 0.15,
    },
    Motor {
        name: "m2",
        column: "m2_rad_s",
        file_inertia: 1.0e-6,
        axis: [0.0, 0.0, 1.0],
        rpm: false,
        from: 900.0,
        to: 250.0,
        at: 0.2,
        ramp: 0.2,
    },
    Motor {
        name: "m3",
        column: "m3_rpm",
        file_inertia: 0.5e-6,
        axis: [1.0, 0.0, 0.0],
        rpm: true,
        from: 300.0,
        to: 1400.0,
        at: 0.05,
        ramp: 0.25,
    },
    Motor {
        name: "m4",
        column: "m4_rad_s",
        file_inertia: 1.5e-6,
        axis: [0.0, 0.6, 0.8],
        rpm: false,
        from: 200.0,
        to: 700.0,
        at: 0.3,
        ramp: 0.15,
    },
];

impl Motor {
    /// Speed and its rate, `s` seconds after the release (`speeds`: scaled by it, zero for a
    /// vehicle whose rotors are stopped).
    fn speed(&self, s: f64, speeds: f64) -> (f64, f64) {
        let u = ((s - self.at) / self.ramp).clamp(0.0, 1.0);
        let d = self.to - self.from;
        let w = self.from + d * 0.5 * (1.0 - (PI * u).cos());
        let inside = s > self.at && s < self.at + self.ramp;
        let wd = if inside {
            d * 0.5 * PI / self.ramp * (PI * u).sin()
        } else {
            0.0
        };
        (speeds * w, speeds * wd)
    }

    /// The vehicle file's entry.
    fn toml(&self) -> String {
        format!(
            "[[rotor]]\nname = \"{}\"\ncolumn = \"{}\"\ninertia_kg_m2 = {:e}\naxis = [{:?}, {:?}, {:?}]\n{}\n",
            self.name,
            self.column,
            self.file_inertia,
            self.axis[0],
            self.axis[1],
            self.axis[2],
            if self.rpm { "speed_unit = \"rpm\"\n" } else { "" }
        )
    }
}

fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

fn mat_vec(m: &M3, v: [f64; 3]) -> [f64; 3] {
    std::array::from_fn(|r| (0..3).map(|c| m[r][c] * v[c]).sum())
}

fn inverse(m: &M3) -> M3 {
    let c = |r: usize, k: usize| {
        let (r1, r2, k1, k2) = ((r + 1) % 3, (r + 2) % 3, (k + 1) % 3, (k + 2) % 3);
        m[r1][k1] * m[r2][k2] - m[r1][k2] * m[r2][k1]
    };
    let det: f64 = (0..3).map(|k| m[0][k] * c(0, k)).sum();
    std::array::from_fn(|r| std::array::from_fn(|k| c(k, r) / det))
}

/// A solid cuboid of mass `m` and edges `a, b, c` about its centre, turned by `angle` about
/// the unit `axis` (Rodrigues): `R diag(I) R^T`.
fn cuboid(m: f64, [a, b, c]: [f64; 3], axis: [f64; 3], angle: f64) -> M3 {
    let d = [
        m / 12.0 * (b * b + c * c),
        m / 12.0 * (a * a + c * c),
        m / 12.0 * (a * a + b * b),
    ];
    let n = axis.iter().map(|x| x * x).sum::<f64>().sqrt();
    let u = axis.map(|x| x / n);
    let (s, co) = angle.sin_cos();
    let r: M3 = std::array::from_fn(|i| {
        std::array::from_fn(|k| {
            let kron = if i == k { 1.0 } else { 0.0 };
            let eps = match (i, k) {
                (0, 1) => -u[2],
                (1, 0) => u[2],
                (0, 2) => u[1],
                (2, 0) => -u[1],
                (1, 2) => -u[0],
                (2, 1) => u[0],
                _ => 0.0,
            };
            co * kron + s * eps + (1.0 - co) * u[i] * u[k]
        })
    });
    std::array::from_fn(|i| std::array::from_fn(|k| (0..3).map(|l| r[i][l] * d[l] * r[k][l]).sum()))
}

/// `|d|^2 I - d d^T`.
fn parallel(d: [f64; 3]) -> M3 {
    let n2: f64 = d.iter().map(|x| x * x).sum();
    std::array::from_fn(|r| std::array::from_fn(|c| if r == c { n2 } else { 0.0 } - d[r] * d[c]))
}

/// The board and a part rigidly joined: the whole's tensor about its centre of mass and that
/// centre, from the IMU.
fn joined(part: M3, part_com: [f64; 3], part_mass: f64) -> (M3, [f64; 3]) {
    let total = BOARD_MASS + part_mass;
    let c: [f64; 3] =
        std::array::from_fn(|k| (BOARD_MASS * BOARD_COM[k] + part_mass * part_com[k]) / total);
    let pb = parallel(std::array::from_fn(|k| BOARD_COM[k] - c[k]));
    let pp = parallel(std::array::from_fn(|k| part_com[k] - c[k]));
    let j = std::array::from_fn(|r| {
        std::array::from_fn(|k| {
            BOARD_INERTIA[r][k] + BOARD_MASS * pb[r][k] + part[r][k] + part_mass * pp[r][k]
        })
    });
    (j, c)
}

fn proof_body() -> (M3, [f64; 3]) {
    (
        cuboid(PROOF_MASS, [0.0302, 0.0600, 0.0700], [0.2, 1.0, -0.3], 0.25),
        [1.5e-3, 2.0e-3, -38.0e-3],
    )
}

fn object_body() -> (M3, [f64; 3]) {
    (
        cuboid(OBJECT_MASS, [0.050, 0.080, 0.030], [0.3, -0.5, 0.4], 0.75),
        [12.0e-3, -20.0e-3, -35.0e-3],
    )
}

/// One throw as a CSV log `t,wx,wy,wz,ax,ay,az` and the motors' columns at 1 kHz: 0.5 s on
/// the bench (the accelerometer reads gravity), 0.3 s in the hand (the rate ramped up to the
/// release's, pushed about), 0.6 s of free flight (Euler's equation with the four motors'
/// momentum, RK4 in four steps a sample; the accelerometer reads `w x (w x r) + w' x r`,
/// `r` the IMU from the centre of mass), 0.2 s of catch and 0.3 s held. White noise of 2e-3
/// rad/s and 0.05 m/s^2; the speeds are logged exactly. `speeds` scales every motor's speed.
/// `columns` lists the motors whose columns the log has.
fn throw(path: &Path, (inertia, com): (M3, [f64; 3]), seed: u64, speeds: f64, columns: &[usize]) {
    let mut gauss = common::gaussian(seed);
    let r_arm = com.map(|x| -x);
    let jinv = inverse(&inertia);
    // The release rate: 15-20 rad/s in a direction drawn from the seed.
    let w0 = loop {
        let d: [f64; 3] = std::array::from_fn(|_| gauss());
        let n = d.iter().map(|x| x * x).sum::<f64>().sqrt();
        if n > 0.3 {
            let mag = 15.0 + 5.0 * (gauss() / 3.0).clamp(-1.0, 1.0).abs();
            break d.map(|x| x / n * mag);
        }
    };
    let momentum = |s: f64| -> ([f64; 3], [f64; 3]) {
        let (mut h, mut hd) = ([0.0; 3], [0.0; 3]);
        for m in &MOTORS {
            let (w, wd) = m.speed(s, speeds);
            for k in 0..3 {
                h[k] += SCALE * m.file_inertia * w * m.axis[k];
                hd[k] += SCALE * m.file_inertia * wd * m.axis[k];
            }
        }
        (h, hd)
    };
    let rhs = |s: f64, w: [f64; 3]| -> [f64; 3] {
        let (h, hd) = momentum(s);
        let jw = mat_vec(&inertia, w);
        let l = std::array::from_fn(|k| jw[k] + h[k]);
        let c = cross(l, w);
        mat_vec(&jinv, std::array::from_fn(|k| c[k] - hd[k]))
    };
    let dt = 1.0 / RATE;
    let mut out = String::from("t,wx,wy,wz,ax,ay,az");
    for &i in columns {
        out += ",";
        out += MOTORS[i].column;
    }
    out += "\n";
    let mut k = 0usize;
    let mut row = |w: [f64; 3], f: [f64; 3], s: f64, gauss: &mut dyn FnMut() -> f64| {
        out += &format!("{:.4}", k as f64 * dt);
        for a in 0..3 {
            out += &format!(",{:e}", w[a] + 2e-3 * gauss());
        }
        for a in 0..3 {
            out += &format!(",{:e}", f[a] + 0.05 * gauss());
        }
        for &i in columns {
            let m = &MOTORS[i];
            let v = m.speed(s, speeds).0;
            out += &format!(",{:e}", if m.rpm { v * 60.0 / (2.0 * PI) } else { v });
        }
        out += "\n";
        k += 1;
    };
    let n = |seconds: f64| (seconds * RATE).round() as usize;
    for _ in 0..n(0.5) {
        row([0.0; 3], [0.0, 0.0, G], -1.0, &mut gauss);
    }
    for i in 0..n(0.3) {
        let p = i as f64 / n(0.3) as f64;
        row(
            w0.map(|x| x * p),
            [4.0 * p, 2.0, G + 6.0 * p],
            -1.0,
            &mut gauss,
        );
    }
    let mut w = w0;
    let sub = 4;
    let h = dt / sub as f64;
    for i in 0..n(0.6) {
        let s = i as f64 * dt;
        let wd = rhs(s, w);
        let cen = cross(w, cross(w, r_arm));
        let tan = cross(wd, r_arm);
        row(w, std::array::from_fn(|a| cen[a] + tan[a]), s, &mut gauss);
        for j in 0..sub {
            let t = s + j as f64 * h;
            let k1 = rhs(t, w);
            let k2 = rhs(t + h / 2.0, std::array::from_fn(|a| w[a] + h / 2.0 * k1[a]));
            let k3 = rhs(t + h / 2.0, std::array::from_fn(|a| w[a] + h / 2.0 * k2[a]));
            let k4 = rhs(t + h, std::array::from_fn(|a| w[a] + h * k3[a]));
            w = std::array::from_fn(|a| {
                w[a] + h / 6.0 * (k1[a] + 2.0 * k2[a] + 2.0 * k3[a] + k4[a])
            });
        }
    }
    let end = n(0.6) as f64 * dt;
    for i in 0..n(0.2) {
        let p = (-(i as f64) * dt / 0.03).exp();
        row(
            w.map(|x| x * p),
            [20.0 * p, -5.0, G + 15.0 * p],
            end,
            &mut gauss,
        );
    }
    for _ in 0..n(0.3) {
        row([0.0; 3], [0.0, 0.0, G], end, &mut gauss);
    }
    std::fs::write(path, out).unwrap();
}

/// `n` throws of a body from seed `seed0` on, into `dir`, with every motor's column.
fn throws(dir: &Path, name: &str, seed0: u64, n: u64, body: (M3, [f64; 3])) -> Vec<PathBuf> {
    (seed0..seed0 + n)
        .map(|seed| {
            let path = dir.join(format!("{name}-{seed}.csv"));
            throw(&path, body, seed, 1.0, &[0, 1, 2, 3]);
            path
        })
        .collect()
}

fn vehicle_file(dir: &Path) -> PathBuf {
    let path = dir.join("quad.toml");
    std::fs::write(&path, MOTORS.iter().map(Motor::toml).collect::<String>()).unwrap();
    path
}

/// The arguments of a calibration of `board`, `assembly` and `object` throws.
fn args(
    dir: &Path,
    board: Vec<PathBuf>,
    assembly: Vec<PathBuf>,
    object: Vec<PathBuf>,
) -> CalibrateArgs {
    let (p, _) = proof_body();
    CalibrateArgs {
        board,
        assembly,
        proof_inertia: vec![p[0][0], p[1][1], p[2][2], p[0][1], p[0][2], p[1][2]],
        board_mass: BOARD_MASS,
        proof_mass: PROOF_MASS,
        object_mass: (!object.is_empty()).then_some(OBJECT_MASS),
        object,
        rotor_axis: None,
        rotor_poles: None,
        vehicle: Some(vehicle_file(dir)),
        scale: inertia::calibrate::ScaleFactor::Auto,
        scale_of: inertia::calibrate::ScaleOf::Clock,
        accel_scale: 1.0,
        json: dir.join("calibration.json"),
        plots: None,
    }
}

fn board_and_assembly(dir: &Path) -> (Vec<PathBuf>, Vec<PathBuf>) {
    let (proof, proof_com) = proof_body();
    (
        throws(dir, "board", 1, 5, (BOARD_INERTIA, BOARD_COM)),
        throws(dir, "assembly", 11, 5, joined(proof, proof_com, PROOF_MASS)),
    )
}

#[test]
fn four_motors_calibrate_their_common_scale_and_an_object_by_difference() {
    let dir = common::out_dir("calibrate_rotors");
    let (board, assembly) = board_and_assembly(&dir);
    let (object, object_com) = object_body();
    let objects = throws(
        &dir,
        "object",
        21,
        1,
        joined(object, object_com, OBJECT_MASS),
    );
    let started = std::time::Instant::now();
    let rep: CalibrationReport = run(&args(&dir, board, assembly, objects)).unwrap();
    println!("calibration: {:.1} s", started.elapsed().as_secs_f64());
    assert_eq!(
        rep.throws_per_group,
        [5, 5, 1],
        "skipped: {:?}",
        rep.skipped
    );
    for t in &rep.throws {
        println!(
            "{}: {} / {}, {} samples",
            t.source.rsplit('/').next().unwrap_or(""),
            t.status,
            t.tensor_status,
            t.samples
        );
    }

    // The scale, and each motor's inertia with it.
    let v = rep.vehicle.as_ref().expect("the rotors' calibration");
    let scale_std = v.scale_std.unwrap();
    let z = (v.scale - SCALE) / scale_std;
    println!(
        "scale {:.5} +- {:.5} (truth {SCALE}): {:+.3} %, z {z:+.2}",
        v.scale,
        scale_std,
        100.0 * (v.scale / SCALE - 1.0)
    );
    assert_eq!(v.rotors.len(), MOTORS.len());
    assert_eq!(
        rep.rotor_inertia_kg_m2.to_bits(),
        v.rotors[0].inertia_kg_m2.to_bits()
    );
    for (r, m) in v.rotors.iter().zip(&MOTORS) {
        let truth = SCALE * m.file_inertia;
        let s = r.inertia_std_kg_m2.unwrap();
        let zr = (r.inertia_kg_m2 - truth) / s;
        println!(
            "rotor {}: {:.4e} +- {:.1e} kg m^2 (truth {truth:.4e}), z {zr:+.2}",
            r.name, r.inertia_kg_m2, s
        );
        assert_eq!(r.name, m.name);
        assert_eq!(r.file_inertia_kg_m2, m.file_inertia as f32);
        assert!(zr.abs() < 3.0, "rotor {}: z {zr:+.2}", r.name);
        assert!(
            (r.inertia_kg_m2 / truth - 1.0).abs() < 0.01,
            "rotor {}",
            r.name
        );
    }
    // Within its standard deviation (3 of them: one comparison, seeds fixed), and a standard
    // deviation small enough for that to mean something.
    assert!(
        scale_std > 0.0 && scale_std < 0.01 * SCALE,
        "std {scale_std}"
    );
    assert!(z.abs() < 3.0, "scale z {z:+.2}");

    // The board.
    let board_err = rel_frobenius(&rep.board_tensor_kg_m2, &BOARD_INERTIA);
    println!("board tensor {:.3} % off (Frobenius)", 100.0 * board_err);
    assert!(board_err < 0.01, "board {board_err}");

    // The object by difference, from one throw: its principal moments within their reported
    // standard deviations, every entry too.
    let got = rep.object_tensor_kg_m2.unwrap();
    let std = rep.object_tensor_std_kg_m2.unwrap();
    let l = rep.object_principal_moments_kg_m2.unwrap();
    let ls = rep.object_principal_moments_std_kg_m2.unwrap();
    let (truth, _) = eigen(&object);
    let zm: [f64; 3] = std::array::from_fn(|k| (l[k] - truth[k]) / ls[k]);
    println!(
        "object: {:.3} % off (Frobenius), moments {:+.3?} % (std {:.3?} %), z {:+.2?}",
        100.0 * rel_frobenius(&got, &object),
        std::array::from_fn::<f64, 3, _>(|k| 100.0 * (l[k] / truth[k] - 1.0)),
        std::array::from_fn::<f64, 3, _>(|k| 100.0 * ls[k] / truth[k]),
        zm
    );
    let mut worst: f64 = 0.0;
    for r in 0..3 {
        for c in 0..3 {
            worst = worst.max((got[r][c] - object[r][c]).abs() / std[r][c]);
        }
    }
    println!("object entries: worst |error| / std {worst:.2}");
    for k in 0..3 {
        assert!(zm[k].abs() < 3.0, "object moment {k}: z {:+.2}", zm[k]);
        assert!((l[k] / truth[k] - 1.0).abs() < 0.02, "object moment {k}");
    }
    assert!(worst < 3.5, "an object entry {worst:.2} std off");

    // The JSON keeps its fields and adds the rotors'.
    let json = serde_json::to_value(&rep).unwrap();
    assert!(json["rotor_inertia_kg_m2"].is_number());
    assert_eq!(json["vehicle"]["rotors"][3]["name"], "m4");
}

/// A log without a column the vehicle file names is left out with the column named; when no
/// throw of a group has it, the calibration stops and says so. Rotors whose momentum is zero
/// throughout (stopped motors) cannot fix the scale, which is named too.
#[test]
fn a_missing_rotor_column_or_no_rotor_momentum_is_named() {
    let dir = common::out_dir("calibrate_rotors_bad");
    let (board, assembly) = board_and_assembly(&dir);
    let short = dir.join("board-no-m3.csv");
    throw(&short, (BOARD_INERTIA, BOARD_COM), 7, 1.0, &[0, 1, 3]);

    let mut with_short = board.clone();
    with_short.push(short.clone());
    let rep = run(&args(&dir, with_short, assembly.clone(), vec![])).unwrap();
    for s in &rep.skipped {
        println!("left out: {} ({}): {}", s.source, s.group, s.reason);
    }
    assert_eq!(rep.throws_per_group, [5, 5, 0]);
    assert_eq!(rep.skipped.len(), 1);
    assert!(
        rep.skipped[0].reason.contains("m3_rpm"),
        "{:?}",
        rep.skipped
    );

    let e = run(&args(&dir, vec![short], assembly.clone(), vec![])).unwrap_err();
    println!("no board throw has the column: {e}");
    assert!(
        e.contains("no usable board throw") && e.contains("m3_rpm"),
        "{e}"
    );

    let stopped = dir.join("board-stopped.csv");
    throw(&stopped, (BOARD_INERTIA, BOARD_COM), 8, 0.0, &[0, 1, 2, 3]);
    let e = run(&args(&dir, vec![stopped], assembly, vec![])).unwrap_err();
    println!("motors stopped: {e}");
    assert!(e.contains("did not fix the scale"), "{e}");
}
