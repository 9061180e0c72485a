//! A vehicle file's rotor fields in a PX4 ULog (`topic.field`, `topic:N.field`).
//!
//! The Basilisk 6U tumble with four reaction wheels (`tests/data/spacecraft/sat6u-pyramid-10hz`)
//! written as a ULog, its wheels in two instances of `esc_status` (integer rpm) and in
//! `actuator_outputs` (float rad/s), through `inertia identify --vehicle`: the tensor of the
//! same samples written as a CSV, within its standard deviation of the truth. A small log
//! checks the hold (the last value at or before each gyro sample, the samples before a field's
//! first message left out) and the refusals (a field, topic or instance the log lacks, an
//! array's bare name, a bool, a non-finite value).
//!
//! `cargo test --release -p inertia --test ulog_rotors -- --nocapture`

use std::path::{Path, PathBuf};
use std::process::Command;

use inertia::{read, ReadOptions};

mod common;
use log_writers::ulog::{add_logged, add_logged_instance, header, msg};

fn out_dir() -> PathBuf {
    common::out_dir("ulog_rotors")
}

fn spacecraft(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data/spacecraft")
        .join(name)
}

fn identify(args: &[&str], json: &Path) -> (i32, serde_json::Value, String) {
    common::identify_cli(args, json)
}

/// One data message of `msg_id`: its timestamp (us) then `rest`.
fn data(f: &mut Vec<u8>, msg_id: u16, t_us: u64, rest: &[u8]) {
    let mut d = msg_id.to_le_bytes().to_vec();
    d.extend_from_slice(&t_us.to_le_bytes());
    d.extend_from_slice(rest);
    msg(f, b'D', &d);
}

/// Little-endian bytes of `f32`s.
fn floats(v: &[f32]) -> Vec<u8> {
    v.iter().flat_map(|x| x.to_le_bytes()).collect()
}

/// `esc_status`'s payload after its timestamp: two ESCs at `rpm`.
fn escs(t_us: u64, rpm: [i32; 2]) -> Vec<u8> {
    let mut d = vec![2u8];
    for r in rpm {
        d.extend_from_slice(&t_us.to_le_bytes());
        d.extend_from_slice(&r.to_le_bytes());
        d.extend_from_slice(&16.0f32.to_le_bytes());
    }
    d
}

/// The header and formats every log here has; message ids: 0 `sensor_combined` (gyro only),
/// 1 and 2 `esc_status` instances 0 and 1, 3 `actuator_outputs`, 4 `actuator_armed`.
fn start() -> Vec<u8> {
    let mut f = header(0);
    for format in [
        "sensor_combined:uint64_t timestamp;float[3] gyro_rad;",
        "esc_report:uint64_t timestamp;int32_t esc_rpm;float esc_voltage;",
        "esc_status:uint64_t timestamp;uint8_t esc_count;esc_report[2] esc;",
        "actuator_outputs:uint64_t timestamp;float[4] output;",
        "actuator_armed:uint64_t timestamp;bool armed;",
    ] {
        msg(&mut f, b'F', format.as_bytes());
    }
    add_logged(&mut f, 0, "sensor_combined");
    add_logged_instance(&mut f, 0, 1, "esc_status");
    add_logged_instance(&mut f, 1, 2, "esc_status");
    add_logged(&mut f, 3, "actuator_outputs");
    add_logged(&mut f, 4, "actuator_armed");
    f
}

// ---- the Basilisk tumble as a ULog ----

/// The 6U's CSV rows: `t` (s), gyro (rad/s), four wheel speeds (rad/s).
fn basilisk_rows() -> Vec<(f64, [f32; 3], [f32; 4])> {
    let text = std::fs::read_to_string(spacecraft("sat6u-pyramid-10hz.csv")).unwrap();
    text.lines()
        .skip(1)
        .map(|l| {
            let v: Vec<f64> = l.split(',').map(|x| x.parse().unwrap()).collect();
            (
                v[0],
                [1, 2, 3].map(|i| v[i] as f32),
                [4, 5, 6, 7].map(|i| v[i] as f32),
            )
        })
        .collect()
}

/// The wheels' `(name, column in the ULog, column in the CSV twin, unit)`.
const WHEELS: [(&str, &str, &str, &str); 4] = [
    ("rw1", "esc_status.esc[0].esc_rpm", "rw1_rpm", "rpm"),
    ("rw2", "esc_status.esc[1].esc_rpm", "rw2_rpm", "rpm"),
    ("rw3", "esc_status:1.esc[0].esc_rpm", "rw3_rpm", "rpm"),
    ("rw4", "actuator_outputs.output[3]", "rw4_rad_s", "rad/s"),
];

/// The gyro samples before `esc_status` instance 1's first message (left out by the reader).
const LATE: usize = 5;

/// The 6U as a ULog, and the CSV of the samples the reader should give: gyro and time as
/// logged, rw1-rw3 in whole rpm in `esc_status` (instance 0 from the fourth gyro sample on,
/// instance 1 from the sixth), rw4 in rad/s in `actuator_outputs`, stamped 40 ms before the
/// gyro sample whose speed it is.
fn sat6u_logs() -> (Vec<u8>, String) {
    let rows = basilisk_rows();
    let mut f = start();
    let mut csv = String::from("t,wx,wy,wz,rw1_rpm,rw2_rpm,rw3_rpm,rw4_rad_s\n");
    let to_rpm = 60.0 / std::f64::consts::TAU;
    for (k, (t, w, wheels)) in rows.iter().enumerate() {
        let ts = 1_000_000 + (t * 1e6).round() as u64;
        let rpm = wheels.map(|x| (f64::from(x) * to_rpm).round() as i32);
        data(&mut f, 3, ts - 40_000, &floats(&[0.0, 0.0, 0.0, wheels[3]]));
        if k >= 3 {
            data(&mut f, 1, ts, &escs(ts, [rpm[0], rpm[1]]));
        }
        if k >= LATE {
            data(&mut f, 2, ts, &escs(ts, [rpm[2], 0]));
        }
        data(&mut f, 0, ts, &floats(w));
        if k >= LATE {
            csv += &format!(
                "{},{},{},{},{},{},{},{}\n",
                ts as f64 * 1e-6,
                w[0],
                w[1],
                w[2],
                rpm[0],
                rpm[1],
                rpm[2],
                wheels[3]
            );
        }
    }
    (f, csv)
}

/// The 6U's vehicle file with each wheel's column `column(i)` in `unit(i)`.
fn vehicle(column: impl Fn(usize) -> String, unit: impl Fn(usize) -> String) -> String {
    let text = std::fs::read_to_string(spacecraft("sat6u-pyramid-10hz.toml")).unwrap();
    let v: toml::Value = toml::from_str(&text).unwrap();
    let mut out = String::new();
    for (i, r) in v["rotor"].as_array().unwrap().iter().enumerate() {
        assert_eq!(r["name"].as_str(), Some(WHEELS[i].0));
        out += &format!(
            "[[rotor]]\nname = {}\ncolumn = \"{}\"\ninertia_kg_m2 = {}\naxis = {}\n\
             speed_unit = \"{}\"\n\n",
            r["name"],
            column(i),
            r["inertia_kg_m2"],
            r["axis"],
            unit(i)
        );
    }
    out
}

fn truth() -> [[f64; 3]; 3] {
    let text = std::fs::read_to_string(spacecraft("sat6u-pyramid-10hz.truth.toml")).unwrap();
    let v: toml::Value = toml::from_str(&text).unwrap();
    let rows = v["inertia_kg_m2"].as_array().unwrap();
    core::array::from_fn(|r| core::array::from_fn(|c| rows[r][c].as_float().unwrap()))
}

/// The pooled tensor and its standard deviations from a report.
fn tensor(v: &serde_json::Value) -> ([[f64; 3]; 3], [[f64; 3]; 3]) {
    let m = |key: &str| -> [[f64; 3]; 3] {
        core::array::from_fn(|r| {
            core::array::from_fn(|c| {
                v["pooled"][key][r][c]
                    .as_f64()
                    .unwrap_or_else(|| panic!("{key} in {v}"))
            })
        })
    };
    (m("tensor_kg_m2"), m("tensor_std_kg_m2"))
}

/// Frobenius error (%) and the largest |error| / std of `j` (std `s`) against `t`.
fn errors(j: &[[f64; 3]; 3], s: &[[f64; 3]; 3], t: &[[f64; 3]; 3]) -> (f64, f64) {
    let (mut e2, mut t2, mut z) = (0.0, 0.0, 0.0f64);
    for r in 0..3 {
        for c in 0..3 {
            let e = j[r][c] - t[r][c];
            e2 += e * e;
            t2 += t[r][c] * t[r][c];
            z = z.max(e.abs() / s[r][c]);
        }
    }
    (100.0 * (e2 / t2).sqrt(), z)
}

/// `inertia identify --vehicle` on the 6U as a ULog gives the tensor the CSV of the same
/// samples gives, `Converged` and within its standard deviation of the truth.
#[test]
fn a_ulog_with_wheels_in_esc_and_actuator_topics_gives_the_csv_tensor() {
    let dir = out_dir();
    let (ulog, csv) = sat6u_logs();
    let (ulg, csv_path) = (dir.join("sat6u.ulg"), dir.join("sat6u.csv"));
    std::fs::write(&ulg, ulog).unwrap();
    std::fs::write(&csv_path, csv).unwrap();
    let (v_ulog, v_csv) = (dir.join("sat6u-ulog.toml"), dir.join("sat6u-csv.toml"));
    let unit = |i: usize| WHEELS[i].3.to_string();
    std::fs::write(&v_ulog, vehicle(|i| WHEELS[i].1.into(), unit)).unwrap();
    std::fs::write(&v_csv, vehicle(|i| WHEELS[i].2.into(), unit)).unwrap();

    let (code, from_ulog, err) = identify(
        &[
            "--vehicle",
            v_ulog.to_str().unwrap(),
            "--input",
            ulg.to_str().unwrap(),
        ],
        &dir.join("ulog.json"),
    );
    assert_eq!(code, 0, "{err}");
    // The first LATE gyro samples have no rw3 speed: left out, with a warning naming rw3.
    assert!(
        err.contains("rotor \"rw3\"") && err.contains(&format!("the {LATE} gyro sample(s)")),
        "{err}"
    );
    // esc_status is not also read as the `--rotor-*` flags' rotor.
    assert!(!err.contains("esc_status starts"), "{err}");
    let (code, from_csv, err) = identify(
        &[
            "--vehicle",
            v_csv.to_str().unwrap(),
            "--input",
            csv_path.to_str().unwrap(),
            "--gyro-unit",
            "rad/s",
        ],
        &dir.join("csv.json"),
    );
    assert_eq!(code, 0, "{err}");
    assert_eq!(
        from_ulog["pooled"]["samples"], from_csv["pooled"]["samples"],
        "the same samples"
    );

    let (ju, su) = tensor(&from_ulog);
    let (jc, sc) = tensor(&from_csv);
    let apart = (0..9)
        .map(|i| (ju[i / 3][i % 3] - jc[i / 3][i % 3]).abs() / sc[i / 3][i % 3])
        .fold(0.0, f64::max);
    let t = truth();
    let (fro_u, z_u) = errors(&ju, &su, &t);
    let (fro_c, z_c) = errors(&jc, &sc, &t);
    println!(
        "6U as ULog: {} Frobenius {fro_u:.4} %, max |error|/std {z_u:.2}; as CSV: {} Frobenius \
         {fro_c:.4} %, max |error|/std {z_c:.2}; ULog - CSV at most {apart:.2e} std",
        from_ulog["pooled"]["tensor_status"], from_csv["pooled"]["tensor_status"]
    );
    assert!(apart < 1e-3, "ULog and CSV apart by {apart} std");
    assert_eq!(from_ulog["pooled"]["tensor_status"], "Converged");
    assert!(fro_u < 0.05 && z_u < 4.0, "{fro_u} % {z_u}");

    // The whole-log reading (`close-loop`, `calibrate`, `export-replay`) takes the fields too:
    // the replay of both logs is one file.
    let replay = |vehicle: &Path, input: &Path, out: &Path, extra: &[&str]| {
        let o = Command::new(env!("CARGO_BIN_EXE_inertia"))
            .arg("export-replay")
            .arg("--vehicle")
            .arg(vehicle)
            .arg("--input")
            .arg(input)
            .arg("--out")
            .arg(out)
            .args(extra)
            .output()
            .unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        std::fs::read(out).unwrap()
    };
    let from_ulog = replay(&v_ulog, &ulg, &dir.join("ulog.replay"), &[]);
    let from_csv = replay(
        &v_csv,
        &csv_path,
        &dir.join("csv.replay"),
        &["--gyro-unit", "rad/s"],
    );
    assert!(from_ulog == from_csv, "the replays differ");
}

// ---- a small log: the hold, the refusals ----

/// Gyro at 1 kHz (100 samples from 10 ms); `esc_status` at 200 Hz from 12.3 ms (rpm
/// `1000 + 7 j` and `-3 j`, integers); `actuator_outputs` at 50 Hz from 11 ms (`output[2]` =
/// `0.5 j`, NaN at message `nan_at`); `actuator_armed` and `esc_status` instance 1 once.
fn small_log(nan_at: Option<usize>) -> Vec<u8> {
    let mut f = start();
    data(&mut f, 4, 10_000, &[1]);
    for i in 0..100u64 {
        let t = 10_000 + 1_000 * i;
        for j in 0..18u64 {
            if 12_300 + 5_000 * j == t + 300 {
                let j = j as i32;
                data(&mut f, 1, t + 300, &escs(t, [1000 + 7 * j, -3 * j]));
            }
        }
        if (t - 10_000) % 20_000 == 0 {
            let j = ((t - 10_000) / 20_000) as usize;
            let x = if nan_at == Some(j) {
                f32::NAN
            } else {
                0.5 * j as f32
            };
            data(&mut f, 3, t + 1_000, &floats(&[0.0, 0.0, x, 0.0]));
        }
        if i == 40 {
            data(&mut f, 2, t, &escs(t, [5, 5]));
        }
        data(&mut f, 0, t, &floats(&[0.1, -0.2, 0.3 + 1e-3 * i as f32]));
    }
    f
}

fn small_file(name: &str, nan_at: Option<usize>) -> PathBuf {
    let p = out_dir().join(name);
    std::fs::write(&p, small_log(nan_at)).unwrap();
    p
}

fn columns(cols: &[&str], names: &[&str]) -> ReadOptions {
    ReadOptions {
        rotor_columns: cols.iter().map(|c| c.to_string()).collect(),
        rotor_names: names.iter().map(|c| c.to_string()).collect(),
        ..ReadOptions::default()
    }
}

/// The value a zero-order hold gives at `t`: the last of `msgs` (time, value) at or before it.
fn held_at(msgs: &[(u64, f64)], t: u64) -> Option<f64> {
    msgs.iter().rev().find(|(m, _)| *m <= t).map(|(_, v)| *v)
}

#[test]
fn rotor_fields_are_held_onto_the_gyro_times_from_their_first_message() {
    let p = small_file("small.ulg", None);
    let opts = columns(
        &[
            "esc_status.esc[0].esc_rpm",
            "ESC_STATUS.esc[1].ESC_RPM",
            "actuator_outputs.output[2]",
            "esc_status:0.esc_count",
        ],
        &["a", "b", "c", "d"],
    );
    let rec = read(&p, &opts).unwrap();
    let esc: Vec<(u64, [f64; 2])> = (0..18)
        .map(|j| {
            (
                12_300 + 5_000 * j,
                [1000.0 + 7.0 * j as f64, -3.0 * j as f64],
            )
        })
        .collect();
    let out: Vec<(u64, f64)> = (0..5)
        .map(|j| (11_000 + 20_000 * j, 0.5 * j as f64))
        .collect();
    // 10, 11 and 12 ms come before esc_status's first message at 12.3 ms.
    let kept: Vec<u64> = (3..100).map(|i| 10_000 + 1_000 * i).collect();
    assert_eq!(rec.t.len(), kept.len());
    assert_eq!(rec.wheels.len(), 4);
    for (k, &t) in kept.iter().enumerate() {
        assert_eq!(rec.t[k], t as f64 * 1e-6);
        let e0: Vec<(u64, f64)> = esc.iter().map(|&(m, v)| (m, v[0])).collect();
        let e1: Vec<(u64, f64)> = esc.iter().map(|&(m, v)| (m, v[1])).collect();
        assert_eq!(f64::from(rec.wheels[0][k]), held_at(&e0, t).unwrap(), "{t}");
        assert_eq!(f64::from(rec.wheels[1][k]), held_at(&e1, t).unwrap(), "{t}");
        assert_eq!(
            f64::from(rec.wheels[2][k]),
            held_at(&out, t).unwrap(),
            "{t}"
        );
        assert_eq!(rec.wheels[3][k], 2.0);
    }
    let w = rec.warnings.join("\n");
    assert!(
        w.contains("rotor \"a\"") && w.contains("the 3 gyro sample(s) before it are left out"),
        "{w}"
    );
    // Without rotor fields the log reads whole, as before.
    assert_eq!(read(&p, &ReadOptions::default()).unwrap().t.len(), 100);
}

#[test]
fn a_rotor_field_the_log_lacks_or_cannot_give_is_refused_with_the_rotor_named() {
    let p = small_file("refusals.ulg", None);
    let refused = |col: &str, name: &str| -> String {
        read(&p, &columns(&[col], &[name]))
            .err()
            .unwrap_or_else(|| panic!("{col} is read"))
            .to_string()
    };
    let e = refused("esc_status.esc[0].rpm", "front");
    assert!(
        e.contains("rotor \"front\"")
            && e.contains("has no field \"esc[0].rpm\"")
            && e.contains("come closest: esc[0].esc_rpm"),
        "{e}"
    );
    let e = refused("esc_stats.esc[0].esc_rpm", "front");
    assert!(
        e.contains("no topic \"esc_stats\"") && e.contains("come closest: esc_status"),
        "{e}"
    );
    let e = refused("esc_status:2.esc[0].esc_rpm", "front");
    assert!(e.contains("no instance 2 (it has 0, 1)"), "{e}");
    let e = refused("esc_status:x.esc[0].esc_rpm", "front");
    assert!(e.contains("instance \"x\" is not a number"), "{e}");
    let e = refused("actuator_outputs.output", "front");
    assert!(
        e.contains("is an array: name one element (output[0] to output[3])"),
        "{e}"
    );
    let e = refused("esc_rpm", "front");
    assert!(e.contains("topic.field"), "{e}");
    let e = refused("actuator_armed.armed", "front");
    assert!(e.contains("bool or char field"), "{e}");
    // Without the rotors' names, the field is named.
    let e = read(&p, &columns(&["esc_status.esc[9].esc_rpm"], &[]))
        .err()
        .unwrap()
        .to_string();
    assert!(
        e.contains("rotor field \"esc_status.esc[9].esc_rpm\""),
        "{e}"
    );

    // A NaN is refused where a gyro sample would take it (message 2, at 51 ms).
    let nan = small_file("nan.ulg", Some(2));
    let e = read(&nan, &columns(&["actuator_outputs.output[2]"], &["c"]))
        .err()
        .unwrap()
        .to_string();
    assert!(
        e.contains("rotor \"c\"") && e.contains("0.051000 s holds NaN"),
        "{e}"
    );
}

/// The command line: a vehicle file naming a field the ULog lacks exits 3 with the rotor
/// named and the fields that come close.
#[test]
fn identify_names_the_rotor_whose_ulog_field_is_missing() {
    let dir = out_dir();
    let p = small_file("cli.ulg", None);
    let v = dir.join("missing.toml");
    std::fs::write(
        &v,
        "[[rotor]]\nname = \"rear_left\"\ncolumn = \"esc_status.esc[0].rpm\"\n\
         inertia_kg_m2 = 1e-5\naxis = [0.0, 0.0, 1.0]\nspeed_unit = \"rpm\"\n",
    )
    .unwrap();
    let (code, json, err) = identify(
        &[
            "--vehicle",
            v.to_str().unwrap(),
            "--input",
            p.to_str().unwrap(),
        ],
        &dir.join("missing.json"),
    );
    assert_eq!(code, 3, "{err}");
    assert!(json.is_null());
    assert!(
        err.contains("rotor \"rear_left\"") && err.contains("esc[0].esc_rpm"),
        "{err}"
    );
}

proptest::proptest! {
    #![proptest_config(proptest::prelude::ProptestConfig::with_cases(64))]

    /// A damaged log read with rotor fields never panics; what it gives has every rotor's speed,
    /// finite, at every sample.
    #[test]
    fn a_damaged_ulog_read_with_rotor_fields_never_panics(
        flips in proptest::collection::vec((0usize..1 << 20, proptest::prelude::any::<u8>()), 1..8),
        cut in 0usize..1 << 20,
    ) {
        let mut bytes = small_log(None);
        let n = bytes.len();
        for (at, b) in flips {
            bytes[at % n] = b;
        }
        bytes.truncate(n - cut % (n / 2));
        let p = out_dir().join(format!("damaged_{}.ulg", std::process::id()));
        std::fs::write(&p, &bytes).unwrap();
        let opts = columns(
            &["esc_status.esc[0].esc_rpm", "actuator_outputs.output[2]", "esc_status:1.esc[1].esc_rpm"],
            &["a", "b", "c"],
        );
        if let Ok(rec) = read(&p, &opts) {
            proptest::prop_assert_eq!(rec.wheels.len(), 3);
            for w in &rec.wheels {
                proptest::prop_assert_eq!(w.len(), rec.t.len());
                proptest::prop_assert!(w.iter().all(|x| x.is_finite()));
            }
        }
    }
}
