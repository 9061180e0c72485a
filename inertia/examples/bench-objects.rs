//! Objects of known inertia by difference, throw by throw: the thrown-FC rig's test series
//! (`../shared/data/thrown-fc/objects/`), each throw run through `inertia calibrate` exactly as
//! the command line does (`--board` the five board throws, `--assembly` the five proof-body
//! throws, `--object` one throw), then all of an object's throws pooled (`--object` every
//! throw), and the assembly through `inertia identify` per throw and pooled (`--input` every
//! throw, `inertia::pool`). Prints, per object, the errors against the truth with the anchor's own metric (the
//! principal moments' error `|lambda - lambda_true| / |lambda_true|`, moments in ascending
//! order, and the angle of the rotation between the two sets of principal axes, both as the
//! anchor's `computeError` defines them), the whole tensor's Frobenius error (which also holds
//! the axes' error), the errors over the reported standard deviations, and the anchor's
//! published figures. The calibration's scale is calibrated as a clock's (`--scale auto
//! --scale-of clock`, the default); the baselines, in the same process, are the same objects
//! with the scale calibrated as a gyro's (`--scale-of gyro`), with the log as read
//! (`--scale 1`), and with the accelerometer read through its reading at rest (`--accel-scale`
//! the calibration throws' median `accel_at_rest_g`). Last, the calibration's geometry against
//! the anchor's: the board's and each object's centre of mass from the IMU, the board's tensor
//! diagonal, and what the difference in that diagonal is as a share of each object's (an object
//! by difference takes the board's error whole). Then the turn about z each body's principal
//! axes have against the truth's, from its throws' `xy` entries, and the objects' throws against
//! the truth turned by their common angle: a diagnosis of the truth's alignment.
//!
//! Usage: `cargo run --release -p inertia --example bench-objects [-- --poles 14] [--plot SVG]`
//! (`scripts/bench-objects.sh`). Skips with a message when `../shared` is absent.
use plotters::prelude::*;
use std::path::{Path, PathBuf};

use inertia::calibrate::{
    axis_angle_deg, clock_scaled, eigen, rel_frobenius, run, unit_throw, CalibrateArgs,
    ScaleFactor, ScaleOf,
};
use inertia::identify::{identify, IdentifyOptions, Rotor, RotorHold};

type M3 = [[f64; 3]; 3];

fn data() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../shared/data/thrown-fc")
}

fn logs(sub: &str) -> Vec<PathBuf> {
    let mut v: Vec<PathBuf> = std::fs::read_dir(data().join(sub))
        .map(|d| d.filter_map(|e| e.ok().map(|e| e.path())).collect())
        .unwrap_or_default();
    v.retain(|p| p.extension().is_some_and(|e| e.eq_ignore_ascii_case("bfl")));
    v.sort();
    v
}

/// The proof body about its own centre (the data README's cuboid) in the log's frame: the
/// anchor's frame is the log's turned -90 deg about z, so x and y exchange.
fn proof_log_frame() -> [f64; 3] {
    let m = 0.346;
    let anchor = [
        m / 12.0 * (0.0302f64.powi(2) + 0.0700f64.powi(2)),
        m / 12.0 * (0.0302f64.powi(2) + 0.0600f64.powi(2)),
        m / 12.0 * (0.0600f64.powi(2) + 0.0700f64.powi(2)),
    ];
    [anchor[1], anchor[0], anchor[2]]
}

/// Each entry's error over its reported standard deviation: `(xx, yy, zz, xy, xz, yz)`.
fn z_scores(got: &M3, std: &M3, truth: &M3) -> Vec<f64> {
    [(0, 0), (1, 1), (2, 2), (0, 1), (0, 2), (1, 2)]
        .iter()
        .filter(|&&(r, c)| std[r][c] > 0.0)
        .map(|&(r, c)| (got[r][c] - truth[r][c]) / std[r][c])
        .collect()
}

/// Largest angle between matched principal axes, degrees (axes matched by ascending moment).
fn axis_error(got: &M3, truth: &M3) -> f64 {
    let (_, eg) = eigen(got);
    let (_, et) = eigen(truth);
    (0..3)
        .map(|i| axis_angle_deg(eg[i], et[i]))
        .fold(0.0, f64::max)
}

/// The anchor's inertia error: `|lambda - lambda_true| / |lambda_true|` over the principal
/// moments in ascending order (the axes' error is reported apart, [`rotation_error`]).
fn moment_error(got: &M3, truth: &M3) -> f64 {
    let (lg, _) = eigen(got);
    let (lt, _) = eigen(truth);
    let d: f64 = (0..3).map(|i| (lg[i] - lt[i]).powi(2)).sum();
    let n: f64 = lt.iter().map(|x| x * x).sum();
    (d / n).sqrt()
}

/// The anchor's alignment error: the angle of the rotation `E_true^T E` between the two
/// right-handed sets of principal axes (ascending moments), the smallest over the four sign
/// choices that keep them right-handed, degrees.
fn rotation_error(got: &M3, truth: &M3) -> f64 {
    let basis = |m: &M3| {
        let (_, mut e) = eigen(m);
        let c = cross3(e[0], e[1]);
        if c[0] * e[2][0] + c[1] * e[2][1] + c[2] * e[2][2] < 0.0 {
            e[2] = e[2].map(|x| -x);
        }
        e
    };
    let (eg, et) = (basis(got), basis(truth));
    [
        [1.0, 1.0, 1.0],
        [1.0, -1.0, -1.0],
        [-1.0, 1.0, -1.0],
        [-1.0, -1.0, 1.0],
    ]
    .iter()
    .map(|s: &[f64; 3]| {
        // trace(E_true^T E S) = sum_i s_i (e_true_i . e_i)
        let tr: f64 = (0..3)
            .map(|i| s[i] * (0..3).map(|k| et[i][k] * eg[i][k]).sum::<f64>())
            .sum();
        ((tr - 1.0) / 2.0).clamp(-1.0, 1.0).acos().to_degrees()
    })
    .fold(f64::INFINITY, f64::min)
}

fn cross3(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

#[derive(Clone)]
struct Row {
    name: String,
    frob: f64,
    axes: f64,
    /// The anchor's metric: principal moments' error and the axes' rotation angle (deg).
    moments: f64,
    rotation: f64,
    z: Vec<f64>,
    /// Each principal moment's error over its reported std (object by difference only).
    zm: Vec<f64>,
    /// Each diagonal entry's relative error and relative std.
    rel: [(f64, f64); 3],
    /// The object's centre of mass from the IMU, m, log frame (object by difference only).
    com: Option<[f64; 3]>,
    /// The tensor and its entries' standard deviations.
    got: M3,
    std: M3,
}

impl Row {
    /// A tensor `got` with its entries' standard deviations `std` against `truth` (no
    /// principal moments' standard deviations: those only `calibrate` reports).
    fn of_tensor(name: String, got: &M3, std: &M3, truth: &M3) -> Row {
        Row {
            name,
            frob: rel_frobenius(got, truth),
            axes: axis_error(got, truth),
            moments: moment_error(got, truth),
            rotation: rotation_error(got, truth),
            z: z_scores(got, std, truth),
            zm: Vec::new(),
            rel: relative(got, std, truth),
            com: None,
            got: *got,
            std: *std,
        }
    }

    /// The throw's line: its errors and each entry's error over its std.
    fn line(&self) -> String {
        let f = |v: &[f64]| -> String {
            v.iter()
                .map(|z| format!("{z:+.1}"))
                .collect::<Vec<_>>()
                .join(" ")
        };
        let zm = if self.zm.is_empty() {
            String::new()
        } else {
            format!(", moments' error/std {}", f(&self.zm))
        };
        format!(
            "{}: moments {:.2} %, rotation {:.2} deg, Frobenius {:.2} %, axes {:.2} deg, error/std {}{zm}",
            self.name,
            self.moments * 100.0,
            self.rotation,
            self.frob * 100.0,
            self.axes,
            f(&self.z)
        )
    }
}

/// Each diagonal entry's error and std relative to the truth.
fn relative(got: &M3, std: &M3, truth: &M3) -> [(f64, f64); 3] {
    [0, 1, 2].map(|i| (got[i][i] / truth[i][i] - 1.0, std[i][i] / truth[i][i]))
}

/// How the throws are read: the scale between the rates and the clock (`--scale`,
/// `--scale-of`) and the accelerometer's (`--accel-scale`).
#[derive(Clone, Copy, Debug)]
struct Reading {
    scale: ScaleFactor,
    of: ScaleOf,
    accel: f64,
}

/// The product's default: the scale calibrated as a clock's, the accelerometer as read.
const DEFAULT: Reading = Reading {
    scale: ScaleFactor::Auto,
    of: ScaleOf::Clock,
    accel: 1.0,
};

/// The baselines: the scale calibrated as a gyro's; the log as read; the accelerometer read
/// through its reading at rest `at_rest` (the calibration throws' median, in g), the scale
/// calibrated as a clock's.
fn baselines(at_rest: f64) -> Vec<(String, Reading)> {
    vec![
        (
            "with the scale calibrated as a gyro's (`--scale-of gyro`)".into(),
            Reading {
                of: ScaleOf::Gyro,
                ..DEFAULT
            },
        ),
        (
            "with the log as read (`--scale 1`)".into(),
            Reading {
                scale: ScaleFactor::Given(1.0),
                ..DEFAULT
            },
        ),
        (
            format!(
                "with the accelerometer read through its reading at rest (`--accel-scale \
                 {at_rest:.4}`, the calibration throws' median) and the scale calibrated as a \
                 clock's"
            ),
            Reading {
                accel: at_rest,
                ..DEFAULT
            },
        ),
    ]
}

fn args(object: Vec<PathBuf>, mass: f64, poles: u32) -> CalibrateArgs {
    args_at(object, mass, poles, DEFAULT)
}

/// [`args`] with the throws read as `reading` says.
fn args_at(object: Vec<PathBuf>, mass: f64, poles: u32, reading: Reading) -> CalibrateArgs {
    CalibrateArgs {
        board: logs("device_only"),
        assembly: logs("proof_body"),
        proof_inertia: proof_log_frame().to_vec(),
        board_mass: 0.10067,
        proof_mass: 0.346,
        object,
        object_mass: Some(mass),
        rotor_axis: Some([0.0, 0.0, -1.0]),
        vehicle: None,
        rotor_poles: Some(poles),
        scale: reading.scale,
        scale_of: reading.of,
        accel_scale: reading.accel,
        json: std::env::temp_dir().join("bench-objects-unused.json"),
        plots: None,
    }
}

fn row(name: String, a: &CalibrateArgs, truth: &M3) -> Result<Row, String> {
    let rep = run(a)?;
    let got = rep.object_tensor_kg_m2.ok_or("no object tensor")?;
    let std = rep.object_tensor_std_kg_m2.ok_or("no object std")?;
    let (lt, _) = eigen(truth);
    let zm = match (
        rep.object_principal_moments_kg_m2,
        rep.object_principal_moments_std_kg_m2,
    ) {
        (Some(l), Some(s)) => (0..3).map(|i| (l[i] - lt[i]) / s[i]).collect(),
        _ => Vec::new(),
    };
    Ok(Row {
        name,
        frob: rel_frobenius(&got, truth),
        axes: axis_error(&got, truth),
        moments: moment_error(&got, truth),
        rotation: rotation_error(&got, truth),
        z: z_scores(&got, &std, truth),
        zm,
        rel: relative(&got, &std, truth),
        com: rep.object_com_from_imu_m,
        got,
        std,
    })
}

/// The anchor's calibration of the board (data README): its tensor about its centre of mass
/// and that centre from the IMU, anchor frame, and the flywheel's inertia (14 poles).
const BOARD_ANCHOR: M3 = [
    [7.545e-5, -1.68e-6, 1.10e-6],
    [-1.68e-6, 2.179e-5, 6.75e-6],
    [1.10e-6, 6.75e-6, 8.808e-5],
];
const BOARD_COM_ANCHOR_M: [f64; 3] = [10.9e-3, 1.6e-3, 9.0e-3];
const ROTOR_ANCHOR_KG_M2: f64 = 1.689e-6;
const BOARD_MASS_KG: f64 = 0.10067;

/// A vector or tensor from the anchor's frame to the log's: `x_log = y_anchor`,
/// `y_log = -x_anchor`, `z_log = z_anchor` (data README).
fn to_log(v: [f64; 3]) -> [f64; 3] {
    [v[1], -v[0], v[2]]
}

fn tensor_to_log(a: &M3) -> M3 {
    rotated(&[[0.0, 1.0, 0.0], [-1.0, 0.0, 0.0], [0.0, 0.0, 1.0]], a)
}

/// `R A R^T`.
fn rotated(r: &M3, a: &M3) -> M3 {
    std::array::from_fn(|i| {
        std::array::from_fn(|j| {
            (0..3)
                .map(|k| (0..3).map(|l| r[i][k] * a[k][l] * r[j][l]).sum::<f64>())
                .sum()
        })
    })
}

/// The board with the object bolted on about their common centre of mass, log frame: the
/// anchor's board, the object's truth and the parallel-axis term of the two centres,
/// `m_b m_o / (m_b + m_o) (|d|^2 I - d d^T)`.
fn assembly_truth(object: &M3, m_o: f64, com_o_anchor_mm: [f64; 3]) -> M3 {
    let b = tensor_to_log(&BOARD_ANCHOR);
    let d = to_log(std::array::from_fn(|k| {
        com_o_anchor_mm[k] * 1e-3 - BOARD_COM_ANCHOR_M[k]
    }));
    let mu = BOARD_MASS_KG * m_o / (BOARD_MASS_KG + m_o);
    let d2: f64 = d.iter().map(|x| x * x).sum();
    std::array::from_fn(|i| {
        std::array::from_fn(|j| {
            let delta = if i == j { d2 } else { 0.0 };
            b[i][j] + object[i][j] + mu * (delta - d[i] * d[j])
        })
    })
}

/// The rotor inertia and the clock scale an assembly throw is identified with: the anchor's
/// `j` and the log as read, or the calibration's (`identify --rotor-inertia J --clock-scale K`).
#[derive(Clone, Copy)]
struct Through {
    j: f64,
    clock: f64,
}

/// The anchor's rotor inertia, the log as read.
const ANCHOR: Through = Through {
    j: ROTOR_ANCHOR_KG_M2,
    clock: 1.0,
};

/// One throw of the assembly through `inertia identify` (the rotor inertia and clock scale of
/// `through`) against the assembly's truth.
fn assembly_row(path: &Path, poles: u32, truth: &M3, through: Through) -> Result<Row, String> {
    let rec = inertia::read(path, &Default::default()).map_err(|e| e.to_string())?;
    let rec = clock_scaled(&rec, through.clock);
    let t = unit_throw(&rec, [0.0, 0.0, -1.0], Some(poles))?;
    let j = through.j;
    let got = t.j1.map(|r| r.map(|x| x * j));
    let std = t.j1_std.ok_or("no std")?.map(|r| r.map(|x| x * j));
    let name = path.file_name().unwrap_or_default().to_string_lossy();
    Ok(Row::of_tensor(name.into(), &got, &std, truth))
}

/// Every throw of the assembly through `inertia identify --input A --input B ...` (the anchor's
/// rotor inertia), the logs pooled by `inertia::pool`, against the assembly's truth.
fn assembly_pooled(paths: &[PathBuf], poles: u32, truth: &M3) -> Result<Row, String> {
    let opts = IdentifyOptions {
        rotor: Some(Rotor {
            inertia: ROTOR_ANCHOR_KG_M2 as f32,
            axis: [0.0, 0.0, -1.0],
            poles: Some(poles),
        }),
        vehicle: None,
        segments: None,
        noise_std: None,
        rotor_hold: RotorHold::Auto,
        trace: false,
    };
    let reports = paths
        .iter()
        .map(|p| {
            let rec = inertia::read(p, &Default::default()).map_err(|e| e.to_string())?;
            identify(&rec, &opts).map_err(|e| e.to_string())
        })
        .collect::<Result<Vec<_>, String>>()?;
    let pooled = inertia::pool::pool(reports)?.pooled;
    let f = |m: [[f32; 3]; 3]| m.map(|r| r.map(f64::from));
    let got = f(pooled.tensor_kg_m2.ok_or("no pooled tensor")?);
    let std = f(pooled.tensor_std_kg_m2.ok_or("no pooled std")?);
    Ok(Row::of_tensor("pooled".into(), &got, &std, truth))
}

/// Each throw's object by difference with the throws read as `reading` says, one throw at a
/// time on as many threads as the machine has.
fn object_rows(
    throws: &[PathBuf],
    mass: f64,
    poles: u32,
    reading: Reading,
    truth_m: &M3,
) -> Vec<Result<Row, String>> {
    let threads = std::thread::available_parallelism().map_or(1, |n| n.get());
    let chunks: Vec<Vec<PathBuf>> = throws
        .chunks(throws.len().div_ceil(threads).max(1))
        .map(|c| c.to_vec())
        .collect();
    std::thread::scope(|s| {
        let hs: Vec<_> = chunks
            .iter()
            .map(|chunk| {
                s.spawn(|| {
                    chunk
                        .iter()
                        .map(|p| {
                            let n = p.file_name().unwrap_or_default().to_string_lossy();
                            row(
                                n.into(),
                                &args_at(vec![p.clone()], mass, poles, reading),
                                truth_m,
                            )
                        })
                        .collect::<Vec<_>>()
                })
            })
            .collect();
        hs.into_iter()
            .flat_map(|h| h.join().unwrap_or_default())
            .collect()
    })
}

/// RMS of the first three of every six (the diagonal entries' z).
fn rms_diag(rows: &[&Row]) -> f64 {
    let d: Vec<f64> = rows
        .iter()
        .flat_map(|r| r.z.iter().take(3).copied())
        .collect();
    rms(&d)
}

/// `mean / max` of a figure, with its unit.
fn mean_max(v: impl Iterator<Item = f64>, unit: &str) -> String {
    let v: Vec<f64> = v.collect();
    let mean = v.iter().sum::<f64>() / v.len().max(1) as f64;
    let max = v.iter().fold(0.0f64, |a, &x| a.max(x));
    format!("{mean:.2} / {max:.2} {unit}")
}

/// A table row of a centre of mass from the IMU (m, log frame) against the anchor's, in mm.
fn com_line(what: &str, got: [f64; 3], anchor: [f64; 3]) -> String {
    let mm = |v: [f64; 3]| {
        format!(
            "({:.2}, {:.2}, {:.2}) mm",
            v[0] * 1e3,
            v[1] * 1e3,
            v[2] * 1e3
        )
    };
    let d = (0..3)
        .map(|k| (got[k] - anchor[k]).powi(2))
        .sum::<f64>()
        .sqrt();
    format!(
        "| {what} centre of mass from the IMU | {} | {} | {:.2} mm |",
        mm(got),
        mm(anchor),
        d * 1e3
    )
}

/// The turn about z that a tensor's `xy` entry says its principal axes in the xy plane have
/// against the nearest of the frame's axes, `theta = atan(2 J_xy / (J_xx - J_yy)) / 2` (for
/// `R_z(theta) D R_z(theta)^T` of a diagonal `D`, `J_xy = sin(2 theta) (D_xx - D_yy) / 2`),
/// with its standard deviation from the `xy` entry's, both in degrees.
fn yaw_deg(r: &Row) -> (f64, f64) {
    let (j, s) = (&r.got, &r.std);
    let d = j[0][0] - j[1][1];
    let theta = 0.5 * (2.0 * j[0][1] / d).atan();
    (theta.to_degrees(), (s[0][1] / d.abs()).to_degrees())
}

/// `truth` turned about z by `deg`: `R_z T R_z^T`.
fn turned_about_z(truth: &M3, deg: f64) -> M3 {
    let (s, c) = deg.to_radians().sin_cos();
    rotated(&[[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]], truth)
}

/// Inverse-variance mean of `(value, std)` pairs and its standard deviation.
fn weighted_mean(v: &[(f64, f64)]) -> (f64, f64) {
    let w: f64 = v.iter().map(|(_, s)| 1.0 / (s * s)).sum();
    let m: f64 = v.iter().map(|(x, s)| x / (s * s)).sum::<f64>() / w;
    (m, w.sqrt().recip())
}

fn rms(v: &[f64]) -> f64 {
    (v.iter().map(|x| x * x).sum::<f64>() / v.len().max(1) as f64).sqrt()
}

fn main() {
    let mut poles = 14;
    let argv: Vec<String> = std::env::args().collect();
    if let Some(i) = argv.iter().position(|a| a == "--poles") {
        poles = argv.get(i + 1).and_then(|p| p.parse().ok()).unwrap_or(14);
    }
    let Ok(truth) = std::fs::read_to_string(data().join("objects/truth.json")) else {
        eprintln!("../shared/data/thrown-fc/objects absent: nothing to measure");
        return;
    };
    let truth: serde_json::Value = serde_json::from_str(&truth).expect("truth.json");
    // The centres of mass and the board's diagonal against the anchor's calibration.
    let mut geometry: Vec<String> = Vec::new();
    // The board's diagonal less the anchor's, kg m^2.
    let mut board_less_anchor: Option<[f64; 3]> = None;
    let calibrated = match run(&args(Vec::new(), 1.0, poles)) {
        Ok(c) => {
            println!(
                "calibration: {} scale {:.4} +- {:.1e} ({}), rotor inertia {:.4e} +- {:.1e} kg m^2",
                c.scale_of.name(),
                c.scale,
                c.scale_std.unwrap_or(f64::NAN),
                c.scale_source,
                c.rotor_inertia_kg_m2,
                c.rotor_inertia_std_kg_m2.unwrap_or(f64::NAN)
            );
            let mut at_rest: Vec<f64> = c.throws.iter().filter_map(|t| t.accel_at_rest_g).collect();
            at_rest.sort_by(f64::total_cmp);
            let at_rest = at_rest.get(at_rest.len() / 2).copied().unwrap_or(1.0);
            println!("accelerometer at rest over the calibration throws: median {at_rest:.4} g");
            geometry.push(com_line(
                "board",
                c.board_com_from_imu_m,
                to_log(BOARD_COM_ANCHOR_M),
            ));
            let d: [f64; 3] = std::array::from_fn(|i| c.board_tensor_kg_m2[i][i]);
            let b = tensor_to_log(&BOARD_ANCHOR);
            let b = [b[0][0], b[1][1], b[2][2]];
            let fmt = |v: [f64; 3]| v.map(|x| format!("{x:.4e}")).join(", ");
            let rel = (0..3)
                .map(|i| format!("{:+.2} %", 100.0 * (d[i] / b[i] - 1.0)))
                .collect::<Vec<_>>()
                .join(", ");
            geometry.push(format!(
                "| board tensor diagonal, kg m^2 | {} | {} | {rel} |",
                fmt(d),
                fmt(b)
            ));
            board_less_anchor = Some(std::array::from_fn(|i| d[i] - b[i]));
            (
                (c.scale_of == ScaleOf::Clock).then_some(Through {
                    j: c.rotor_inertia_kg_m2,
                    clock: c.scale,
                }),
                at_rest,
            )
        }
        Err(e) => {
            println!("calibration failed: {e}");
            (None, 1.0)
        }
    };
    let (calibrated, at_rest) = calibrated;
    let baselines = baselines(at_rest);
    println!("objects by difference, {poles}-pole rotor, per throw and pooled");
    println!(
        "| object | throws | per throw, the anchor's metric: moments mean / max | rotation mean / max | Frobenius mean / max | RMS(error/std): entries, diagonal, moments | pooled: moments | rotation | Frobenius | RMS(error/std): entries, moments | anchor per throw |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|---|");
    let plot = argv
        .iter()
        .position(|a| a == "--plot")
        .and_then(|i| argv.get(i + 1))
        .map(PathBuf::from);
    let mut assembly_lines = Vec::new();
    let mut calibrated_lines = Vec::new();
    let mut baseline_lines: Vec<Vec<String>> = vec![Vec::new(); baselines.len()];

    let mut plotted: Vec<(String, Vec<Row>)> = Vec::new();
    // Each object's throws by difference, then its pooled result, for the plot's lower panel.
    let mut plotted_objects: Vec<(String, Vec<Row>)> = Vec::new();
    // Each object's truth and its throws by difference, for the axes' turn about z.
    let mut yawed: Vec<(String, M3, Vec<Row>)> = Vec::new();
    for name in ["config_empty", "config_a"] {
        let o = &truth[name];
        let mass = o["mass_kg"].as_f64().unwrap_or(1.0);
        let t = &o["inertia_log_frame_kg_m2"];
        let truth_m: M3 =
            std::array::from_fn(|r| std::array::from_fn(|c| t[r][c].as_f64().unwrap_or(f64::NAN)));
        let throws = logs(&format!("objects/{name}"));
        let com = &o["anchor_object_com_from_imu_mm_anchor_frame"];
        let com: [f64; 3] = std::array::from_fn(|k| com[k].as_f64().unwrap_or(f64::NAN));
        let asm_truth = assembly_truth(&truth_m, mass, com);
        let asm: Vec<Row> = throws
            .iter()
            .filter_map(|p| assembly_row(p, poles, &asm_truth, ANCHOR).ok())
            .collect();
        // The path a user takes: calibrate once, then identify with its `j` and clock scale.
        if let Some(c) = calibrated {
            let rows: Vec<Row> = throws
                .iter()
                .filter_map(|p| assembly_row(p, poles, &asm_truth, c).ok())
                .collect();
            let refs: Vec<&Row> = rows.iter().collect();
            calibrated_lines.push(format!(
                "| {name} | {}/{} | {} | {} | {:.2} |",
                rows.len(),
                throws.len(),
                mean_max(rows.iter().map(|r| r.moments * 100.0), "%"),
                mean_max(rows.iter().map(|r| r.rotation), "deg"),
                rms_diag(&refs)
            ));
        }
        let z: Vec<f64> = asm.iter().flat_map(|r| r.z.iter().copied()).collect();
        for r in &asm {
            println!("  assembly {name} {}", r.line());
        }
        let asm_refs: Vec<&Row> = asm.iter().collect();
        let asm_len = asm.len();
        let pooled = match assembly_pooled(&throws, poles, &asm_truth) {
            Ok(p) => format!(
                "{:.2} % | {:.2} % | {:.2}, {:.2}",
                p.moments * 100.0,
                p.frob * 100.0,
                rms(&p.z),
                rms_diag(&[&p])
            ),
            Err(e) => format!("failed: {e} | | "),
        };
        assembly_lines.push(format!(
            "| {name} | {}/{} | {} | {} | {} | {:.2}, {:.2} | {pooled} |",
            asm_len,
            throws.len(),
            mean_max(asm.iter().map(|r| r.moments * 100.0), "%"),
            mean_max(asm.iter().map(|r| r.rotation), "deg"),
            mean_max(asm.iter().map(|r| r.frob * 100.0), "%"),
            rms(&z),
            rms_diag(&asm_refs)
        ));
        plotted.push((name.to_string(), asm));
        let rows = object_rows(&throws, mass, poles, DEFAULT, &truth_m);
        let ok: Vec<&Row> = rows.iter().filter_map(|r| r.as_ref().ok()).collect();
        for r in &rows {
            match r {
                Ok(r) => println!("  {name} {}", r.line()),
                Err(e) => println!("  {name}: failed: {e}"),
            }
        }
        let pooled = row(
            "pooled".into(),
            &args(throws.clone(), mass, poles),
            &truth_m,
        );
        plotted_objects.push((
            name.to_string(),
            rows.iter()
                .filter_map(|r| r.as_ref().ok())
                .chain(pooled.as_ref().ok())
                .cloned()
                .collect(),
        ));
        yawed.push((
            name.to_string(),
            truth_m,
            ok.iter().map(|r| (*r).clone()).collect(),
        ));
        if let Some(got) = pooled.as_ref().ok().and_then(|p| p.com) {
            let anchor = to_log(com.map(|x| x * 1e-3));
            geometry.push(com_line(&format!("{name} (pooled)"), got, anchor));
        }
        if let Some(diff) = board_less_anchor {
            let share: Vec<String> = (0..3)
                .map(|i| format!("{:+.2} %", 100.0 * diff[i] / truth_m[i][i]))
                .collect();
            geometry.push(format!(
                "| the board's diagonal less the anchor's, over {name}'s diagonal | | | {} |",
                share.join(", ")
            ));
        }
        let z: Vec<f64> = ok.iter().flat_map(|r| r.z.iter().copied()).collect();
        let zm: Vec<f64> = ok.iter().flat_map(|r| r.zm.iter().copied()).collect();
        let (pm, pr, pf, pz) = match &pooled {
            Ok(p) => (
                format!("{:.2} %", p.moments * 100.0),
                format!("{:.2} deg", p.rotation),
                format!("{:.2} %", p.frob * 100.0),
                format!("{:.2}, {:.2}", rms(&p.z), rms(&p.zm)),
            ),
            Err(e) => (
                format!("failed: {e}"),
                String::new(),
                String::new(),
                String::new(),
            ),
        };
        // The baselines in the same process ([`baselines`]).
        for (lines, (_, reading)) in baseline_lines.iter_mut().zip(&baselines) {
            let reading = *reading;
            let base = object_rows(&throws, mass, poles, reading, &truth_m);
            let base_ok: Vec<&Row> = base.iter().filter_map(|r| r.as_ref().ok()).collect();
            let base_zm: Vec<f64> = base_ok.iter().flat_map(|r| r.zm.iter().copied()).collect();
            let base_pooled = row(
                "pooled".into(),
                &args_at(throws.clone(), mass, poles, reading),
                &truth_m,
            )
            .map_or_else(
                |e| format!("failed: {e}"),
                |p| format!("{:.2} %", p.moments * 100.0),
            );
            lines.push(format!(
                "| {name} | {}/{} | {} | {:.2} | {base_pooled} |",
                base_ok.len(),
                throws.len(),
                mean_max(base_ok.iter().map(|r| r.moments * 100.0), "%"),
                rms(&base_zm),
            ));
        }
        println!(
            "| {name} | {}/{} | {} | {} | {} | {:.2}, {:.2}, {:.2} | {pm} | {pr} | {pf} | {pz} | {} |",
            ok.len(),
            throws.len(),
            mean_max(ok.iter().map(|r| r.moments * 100.0), "%"),
            mean_max(ok.iter().map(|r| r.rotation), "deg"),
            mean_max(ok.iter().map(|r| r.frob * 100.0), "%"),
            rms(&z),
            rms_diag(&ok),
            rms(&zm),
            o["anchor_object_error_per_throw"].as_str().unwrap_or("")
        );
    }
    println!();
    for ((title, _), lines) in baselines.iter().zip(&baseline_lines) {
        println!("baseline: the same objects {title}");
        println!("| object | throws | per throw: moments mean / max | moments RMS(error/std) | pooled: moments |");
        println!("|---|---|---|---|---|");
        for l in lines {
            println!("{l}");
        }
        println!();
    }
    println!(
        "the calibration's geometry against the anchor's (log frame; the objects' centres are \
         the anchor's figures in truth.json)"
    );
    println!("| what | this product | the anchor's | difference |");
    println!("|---|---|---|---|");
    for l in &geometry {
        println!("{l}");
    }
    println!();
    println!("assembly per throw (inertia identify, the anchor's rotor inertia) against the anchor's board plus the object");
    println!("| object | throws | moments mean / max | rotation mean / max | Frobenius mean / max | RMS(error/std): entries, diagonal | pooled (`--input` every throw): moments | Frobenius | RMS(error/std): entries, diagonal |");
    println!("|---|---|---|---|---|---|---|---|---|");
    for l in assembly_lines {
        println!("{l}");
    }
    if let Some(c) = calibrated {
        println!();
        println!(
            "assembly per throw through the calibration (inertia identify --rotor-inertia {:.4e} --clock-scale {:.4})",
            c.j, c.clock
        );
        println!("| object | throws | moments mean / max | rotation mean / max | RMS(error/std): diagonal |");
        println!("|---|---|---|---|---|");
        for l in calibrated_lines {
            println!("{l}");
        }
    }
    yaw_table(&yawed, poles);
    if let Some(path) = plot {
        match draw(&path, &plotted, &plotted_objects) {
            Ok(()) => println!("\nplot: {}", path.display()),
            Err(e) => eprintln!("plot {}: {e}", path.display()),
        }
    }
}

/// The objects' axes about z: the turn each throw's `xy` entry implies ([`yaw_deg`]), its
/// inverse-variance mean per object and over both (the objects share their base plate), the
/// proof body's (its throws by difference, against its cuboid) beside them, and every object
/// throw's RMS(error/std) and rotation with the truth turned by the common angle. A diagnosis
/// of the truth's alignment, not a result: the product is never given the angle.
fn yaw_table(yawed: &[(String, M3, Vec<Row>)], poles: u32) {
    println!();
    println!(
        "the principal axes' turn about z each body's xy entry implies (by difference, \
         inverse-variance mean of its throws)"
    );
    println!("| body | throws | turn about z, deg | spread of the throws' turns, deg |");
    println!("|---|---|---|---|");
    let mut all = Vec::new();
    let line = |name: &str, v: &[(f64, f64)]| {
        let (m, s) = weighted_mean(v);
        let spread = rms(&v.iter().map(|(x, _)| x - m).collect::<Vec<_>>());
        println!("| {name} | {} | {m:+.2} +- {s:.2} | {spread:.2} |", v.len());
    };
    for (name, _, rows) in yawed {
        let v: Vec<(f64, f64)> = rows.iter().map(yaw_deg).collect();
        line(name, &v);
        all.extend(v);
    }
    let proof = proof_log_frame();
    let proof_truth: M3 =
        std::array::from_fn(|r| std::array::from_fn(|c| if r == c { proof[r] } else { 0.0 }));
    let proof_rows = object_rows(&logs("proof_body"), 0.346, poles, DEFAULT, &proof_truth);
    let pv: Vec<(f64, f64)> = proof_rows
        .iter()
        .filter_map(|r| r.as_ref().ok())
        .map(yaw_deg)
        .collect();
    line("proof body (its own throws)", &pv);
    if all.is_empty() {
        return;
    }
    let (common, _) = weighted_mean(&all);
    println!(
        "objects by difference per throw against the truth turned {common:+.2} deg about z (both \
         objects' common turn; every other figure above is against the truth as given)"
    );
    println!("| object | RMS(error/std): entries, as given / turned | rotation mean, as given / turned |");
    println!("|---|---|---|");
    for (name, truth, rows) in yawed {
        let t = turned_about_z(truth, common);
        let z0: Vec<f64> = rows.iter().flat_map(|r| r.z.iter().copied()).collect();
        let z1: Vec<f64> = rows
            .iter()
            .flat_map(|r| z_scores(&r.got, &r.std, &t))
            .collect();
        let n = rows.len().max(1) as f64;
        let r0 = rows.iter().map(|r| r.rotation).sum::<f64>() / n;
        let r1 = rows.iter().map(|r| rotation_error(&r.got, &t)).sum::<f64>() / n;
        println!(
            "| {name} | {:.2} / {:.2} | {r0:.2} / {r1:.2} deg |",
            rms(&z0),
            rms(&z1)
        );
    }
}

/// Two panels, object after object: each assembly throw's diagonal (`inertia identify`) and
/// each object throw's by difference (`inertia calibrate`) with the pooled result last (a
/// square), every entry's error relative to the truth with one reported standard deviation as
/// a bar.
fn draw(
    path: &Path,
    assembly: &[(String, Vec<Row>)],
    objects: &[(String, Vec<Row>)],
) -> Result<(), Box<dyn std::error::Error>> {
    let root = SVGBackend::new(path, (900, 820)).into_drawing_area();
    root.fill(&WHITE)?;
    let (top, bottom) = root.split_vertically(410);
    panel(
        &top,
        "assembly per throw (inertia identify): diagonal error against the truth, +- 1 reported std",
        assembly,
        false,
    )?;
    panel(
        &bottom,
        "object by difference per throw (inertia calibrate), pooled last (square): diagonal error, +- 1 reported std",
        objects,
        true,
    )?;
    root.present()?;
    Ok(())
}

/// One panel of [`draw`]: `groups`' rows in order, each row's three diagonal entries side by
/// side; with `pooled_last`, each group's last row is drawn as a square.
fn panel(
    area: &DrawingArea<SVGBackend, plotters::coord::Shift>,
    caption: &str,
    groups: &[(String, Vec<Row>)],
    pooled_last: bool,
) -> Result<(), Box<dyn std::error::Error>> {
    let n: usize = groups.iter().map(|g| g.1.len()).sum();
    let names: Vec<&str> = groups.iter().map(|g| g.0.as_str()).collect();
    let mut chart = ChartBuilder::on(area)
        .caption(caption, ("sans-serif", 15))
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(60)
        // Four throws' width past the last for the legend.
        .build_cartesian_2d(-0.5f64..n as f64 + 3.5, -10.0f64..10.0)?;
    chart
        .configure_mesh()
        .x_desc(format!("throw ({})", names.join(", then ")))
        .y_desc("error, % of the true moment")
        .draw()?;
    for (k, (colour, label)) in [RED, GREEN, BLUE]
        .into_iter()
        .zip(["Jxx", "Jyy", "Jzz"])
        .enumerate()
    {
        let mut pts = Vec::new();
        let mut x = 0.0;
        for (_, rows) in groups {
            for (i, r) in rows.iter().enumerate() {
                let (e, s) = r.rel[k];
                let last = pooled_last && i + 1 == rows.len();
                pts.push((x + (k as f64 - 1.0) * 0.2, e * 100.0, s * 100.0, last));
                x += 1.0;
            }
        }
        chart
            .draw_series(pts.iter().map(|&(x, e, s, _)| {
                ErrorBar::new_vertical(x, e - s, e, e + s, colour.filled(), 6)
            }))?
            .label(label)
            .legend(move |(x, y)| Circle::new((x, y), 4, colour.filled()));
        chart.draw_series(pts.iter().filter(|p| p.3).map(|&(x, e, _, _)| {
            Rectangle::new(
                [(x - 0.08, e - 0.35), (x + 0.08, e + 0.35)],
                colour.filled(),
            )
        }))?;
    }
    chart.draw_series(std::iter::once(PathElement::new(
        vec![(-0.5, 0.0), (n as f64 - 0.5, 0.0)],
        BLACK,
    )))?;
    // A grey line between one object's throws and the next's.
    let mut edge = 0.0;
    for (_, rows) in groups.iter().take(groups.len().saturating_sub(1)) {
        edge += rows.len() as f64;
        chart.draw_series(std::iter::once(PathElement::new(
            vec![(edge - 0.5, -10.0), (edge - 0.5, 10.0)],
            BLACK.mix(0.4),
        )))?;
    }
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .draw()?;
    Ok(())
}
