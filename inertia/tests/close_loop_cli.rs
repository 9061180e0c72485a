//! `inertia close-loop` end to end: a simulated CSV log in, JSON, markdown and SVG out; and
//! the honesty list (issue 12): malformed input refused with the file and line, units that
//! look wrong, motion that cannot identify, single bad samples, segments that do not fit the
//! log, a summary that compares like with like, negative numbers as arguments. Nothing may
//! panic. Exit codes: 0 done, 3 unusable input, 4 the data cannot identify `a`.
//!
//! The logs come from a small torque-free (optionally damped) rigid-body integrator here, so
//! this crate needs nothing from `host-tests` (which depends on it).

use std::path::{Path, PathBuf};
use std::process::Command;

/// Racquet-like principal moments (x intermediate, y along the handle, z primary).
const INERTIA: [f64; 3] = [19.5, 1.39, 20.7];

fn tmpdir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("inertia_close_loop_{}_{name}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// Deterministic standard normal samples (xorshift and Box-Muller).
struct Noise(u64);

impl Noise {
    fn uniform(&mut self) -> f64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        ((self.0 >> 11) as f64 + 0.5) / (1u64 << 53) as f64
    }
    fn normal(&mut self) -> f64 {
        let (u, v) = (self.uniform(), self.uniform());
        (-2.0 * u.ln()).sqrt() * (2.0 * std::f64::consts::PI * v).cos()
    }
}

/// `I w' = (I w) x w - d I w`, sampled at `rate` for `secs` from `w0`, plus white noise.
fn simulate(
    w0: [f64; 3],
    damping: f64,
    secs: f64,
    rate: f64,
    noise: f64,
) -> (Vec<f64>, Vec<[f64; 3]>) {
    let i = INERTIA;
    let f = |w: [f64; 3]| -> [f64; 3] {
        [
            (i[1] - i[2]) / i[0] * w[1] * w[2] - damping * w[0],
            (i[2] - i[0]) / i[1] * w[2] * w[0] - damping * w[1],
            (i[0] - i[1]) / i[2] * w[0] * w[1] - damping * w[2],
        ]
    };
    let add =
        |a: [f64; 3], b: [f64; 3], s: f64| -> [f64; 3] { std::array::from_fn(|k| a[k] + s * b[k]) };
    let n = (secs * rate).round() as usize;
    let (sub, h) = (8, 1.0 / rate / 8.0);
    let mut w = w0;
    let mut rng = Noise(0x2545_f491_4f6c_dd1d);
    let (mut t, mut out) = (Vec::new(), Vec::new());
    for k in 0..n {
        t.push(k as f64 / rate);
        out.push(std::array::from_fn(|a| w[a] + noise * rng.normal()));
        for _ in 0..sub {
            let k1 = f(w);
            let k2 = f(add(w, k1, h / 2.0));
            let k3 = f(add(w, k2, h / 2.0));
            let k4 = f(add(w, k3, h));
            w = std::array::from_fn(|a| {
                w[a] + h / 6.0 * (k1[a] + 2.0 * k2[a] + 2.0 * k3[a] + k4[a])
            });
        }
    }
    (t, out)
}

fn write_csv(path: &Path, t: &[f64], w: &[[f64; 3]], t_scale: f64, w_scale: f64) {
    let mut csv = String::from("t,wx,wy,wz\n");
    for (tk, v) in t.iter().zip(w) {
        csv.push_str(&format!(
            "{},{},{},{}\n",
            tk * t_scale,
            v[0] * w_scale,
            v[1] * w_scale,
            v[2] * w_scale
        ));
    }
    std::fs::write(path, csv).unwrap();
}

/// A clean tumble about the intermediate axis: 3 s at 100 Hz, noise 0.015 rad/s.
fn clean() -> (Vec<f64>, Vec<[f64; 3]>) {
    simulate([20.0, 1.0, 1.5], 0.0, 3.0, 100.0, 0.015)
}

struct Run {
    code: i32,
    stdout: String,
    stderr: String,
    json: Option<serde_json::Value>,
}

fn close_loop(dir: &Path, input: &Path, extra: &[&str]) -> Run {
    let json = dir.join("out.json");
    let _ = std::fs::remove_file(&json);
    let out = Command::new(env!("CARGO_BIN_EXE_inertia"))
        .arg("close-loop")
        .arg("--input")
        .arg(input)
        .arg("--json")
        .arg(&json)
        .args(extra)
        .output()
        .expect("run inertia close-loop");
    let run = Run {
        code: out.status.code().unwrap_or(-1),
        stdout: String::from_utf8_lossy(&out.stdout).into_owned(),
        stderr: String::from_utf8_lossy(&out.stderr).into_owned(),
        json: std::fs::read(&json)
            .ok()
            .and_then(|b| serde_json::from_slice(&b).ok()),
    };
    assert!(!run.stderr.contains("panicked"), "{}", run.stderr);
    run
}

#[test]
fn command_writes_json_table_and_plots() {
    let dir = tmpdir("ok");
    // One plain CSV, no segments file: the whole log is one free flight of 3 s.
    let (t, w) = simulate([20.0, 1.0, 1.5], 0.15, 3.0, 100.0, 0.015);
    let input = dir.join("log.csv");
    write_csv(&input, &t, &w, 1.0, 1.0);
    let plots = dir.join("plots");
    let r = close_loop(&dir, &input, &["--plots", plots.to_str().unwrap()]);
    assert_eq!(r.code, 0, "{}", r.stderr);
    let v = r.json.unwrap();
    assert_eq!(v["effects"], serde_json::json!(["damping"]));
    for k in ["a_before", "a_after"] {
        assert_eq!(v[k].as_array().unwrap().len(), 3, "{k}");
    }
    let d = v["effect_params"]["damping"].as_array().unwrap();
    assert!((d[0].as_f64().unwrap() - 0.15).abs() < 0.02, "{d:?}");
    let (b, a) = (
        v["residual_rms_before"].as_f64().unwrap(),
        v["residual_rms_after"].as_f64().unwrap(),
    );
    assert!(a < b, "{b} -> {a}");
    for f in ["summary.md", "residual.svg", "estimates.svg"] {
        assert!(plots.join(f).is_file(), "{f} missing");
    }
    // The JSON fields of the former `close-loop` binary, all present.
    for k in [
        "input",
        "effects",
        "a_before",
        "a_after",
        "effect_params",
        "residual_rms_before",
        "residual_rms_after",
        "residual_systematic_before",
        "residual_systematic_after",
        "free_run_rms_before",
        "free_run_rms_after",
        "free_run_ls_before",
        "free_run_ls_after",
        "spread_before",
        "spread_after",
        "consistency_before",
        "consistency_after",
        "a_error_before",
        "a_error_after",
        "truth",
        "ls_before",
        "ls_after",
        "rls_no_effect",
        "whiteness_before",
        "whiteness_after",
        "noise_std_estimate",
        "rounds",
        "segments",
        "blocks",
        "samples_per_block",
        "skipped_segments",
    ] {
        assert!(v.get(k).is_some(), "field {k} missing");
    }
    assert_eq!(v.as_object().unwrap().len(), 31, "no field added or lost");
    // The summary compares the same estimator without and with the effect.
    assert!(r.stdout.contains("without -> with"), "{}", r.stdout);
    let rls0 = v["rls_no_effect"]["residual_rms"].as_f64().unwrap();
    assert!(
        r.stdout.contains(&format!("{rls0:.4} -> {a:.4}")),
        "{}",
        r.stdout
    );
}

#[test]
fn command_names_file_and_line_of_bad_input() {
    let dir = tmpdir("bad");
    let cases: [(&str, &str, usize); 4] = [
        ("nan.csv", "t,wx,wy,wz\n0,1,2,3\n0.01,1,nan,3\n", 3),
        ("text.csv", "t,wx,wy,wz\n0,1,2,3\n0.01,abc,2,3\n", 3),
        ("trunc.csv", "t,wx,wy,wz\n0,1,2,3\n0.01,1,2\n", 3),
        (
            "back.csv",
            "t,wx,wy,wz\n0,1,2,3\n0.02,1,2,3\n0.01,1,2,3\n",
            4,
        ),
    ];
    for (name, text, line) in cases {
        let input = dir.join(name);
        std::fs::write(&input, text).unwrap();
        let r = close_loop(&dir, &input, &[]);
        assert_eq!(r.code, 3, "{name}: {}", r.stderr);
        assert!(
            r.stderr.contains(&format!("{name}:{line}")),
            "{name}: {}",
            r.stderr
        );
    }
}

#[test]
fn degenerate_and_extreme_logs_fail_cleanly() {
    let dir = tmpdir("degenerate");
    let n = 2000;
    let rows = |f: &dyn Fn(usize) -> String| -> String {
        std::iter::once("t,wx,wy,wz\n".to_string())
            .chain((0..n).map(f))
            .collect()
    };
    let cases: Vec<(&str, String)> = vec![
        (
            "constant",
            rows(&|k| format!("{},1,0,0\n", k as f64 * 0.01)),
        ),
        ("zeros", rows(&|k| format!("{},0,0,0\n", k as f64 * 0.01))),
        ("two_rows", "t,wx,wy,wz\n0,1,2,3\n0.01,1,2,3\n".into()),
        (
            "huge_dt",
            rows(&|k| format!("{:e},1,2,3\n", k as f64 * 1e300)),
        ),
        (
            "tiny_dt",
            rows(&|k| format!("{:e},1,2,3\n", k as f64 * 1e-300)),
        ),
    ];
    for (name, body) in cases {
        let input = dir.join(format!("{name}.csv"));
        std::fs::write(&input, body).unwrap();
        let r = close_loop(&dir, &input, &[]);
        assert!(
            r.code == 3 || r.code == 4,
            "{name}: exit {}: {}",
            r.code,
            r.stderr
        );
        assert!(
            r.stderr.contains(&format!("{name}.csv")),
            "{name}: {}",
            r.stderr
        );
    }
}

#[test]
fn rates_in_deg_per_s_are_refused_unless_declared() {
    let dir = tmpdir("degs");
    let (t, w) = clean();
    let rad = dir.join("rad.csv");
    write_csv(&rad, &t, &w, 1.0, 1.0);
    let deg = dir.join("deg.csv");
    write_csv(&deg, &t, &w, 1.0, 180.0 / std::f64::consts::PI);
    let r = close_loop(&dir, &deg, &[]);
    assert_eq!(r.code, 3, "{}", r.stderr);
    assert!(
        r.stderr.contains("deg/s") && r.stderr.contains("--gyro-unit deg/s"),
        "{}",
        r.stderr
    );
    assert!(r.json.is_none(), "no result written");
    // Declared: converted, and the same answer as the log in rad/s.
    let r = close_loop(&dir, &deg, &["--gyro-unit", "deg/s"]);
    assert_eq!(r.code, 0, "{}", r.stderr);
    let a_deg = r.json.unwrap()["a_after"].clone();
    let r = close_loop(&dir, &rad, &[]);
    assert_eq!(r.code, 0, "{}", r.stderr);
    let a_rad = r.json.unwrap()["a_after"].clone();
    for k in 0..3 {
        let (x, y) = (a_deg[k].as_f64().unwrap(), a_rad[k].as_f64().unwrap());
        assert!((x - y).abs() < 1e-3, "{a_deg} vs {a_rad}");
    }
}

#[test]
fn time_in_ms_or_us_is_refused_unless_declared() {
    let dir = tmpdir("ms");
    let (t, w) = clean();
    for (unit, scale) in [("ms", 1e3), ("us", 1e6)] {
        let p = dir.join(format!("{unit}.csv"));
        write_csv(&p, &t, &w, scale, 1.0);
        let r = close_loop(&dir, &p, &[]);
        assert_eq!(r.code, 3, "{unit}: {}", r.stderr);
        assert!(r.stderr.contains("--time-unit ms"), "{unit}: {}", r.stderr);
        let r = close_loop(&dir, &p, &["--time-unit", unit]);
        assert_eq!(r.code, 0, "{unit}: {}", r.stderr);
    }
}

#[test]
fn motion_that_cannot_identify_is_an_error() {
    let dir = tmpdir("motion");
    // A phone lying still (noise only), and a steady spin about the major axis.
    let still = simulate([0.0, 0.0, 0.0], 0.0, 3.0, 100.0, 0.015);
    let spin = simulate([0.0, 0.0, 10.0], 0.0, 3.0, 100.0, 0.015);
    for (name, (t, w)) in [("still", still), ("spin", spin)] {
        let p = dir.join(format!("{name}.csv"));
        write_csv(&p, &t, &w, 1.0, 1.0);
        let r = close_loop(&dir, &p, &[]);
        assert_eq!(
            r.code, 4,
            "{name}: exit {}: {}{}",
            r.code, r.stderr, r.stdout
        );
        assert!(
            r.stderr.contains("does not determine"),
            "{name}: {}",
            r.stderr
        );
        assert!(r.json.is_none(), "{name}: no result written");
    }
}

#[test]
fn one_bad_sample_invents_no_effect() {
    let dir = tmpdir("spike");
    let (t, w) = clean();
    let p = dir.join("clean.csv");
    write_csv(&p, &t, &w, 1.0, 1.0);
    let r = close_loop(&dir, &p, &[]);
    assert_eq!(r.code, 0, "{}", r.stderr);
    assert_eq!(r.json.as_ref().unwrap()["effects"], serde_json::json!([]));
    let clean = r.json.unwrap();
    let clean_a = clean["a_after"].clone();
    for (name, value) in [("spike100", 100.0), ("spike1e30", 1e30)] {
        let mut w2 = w.clone();
        w2[150][1] = value;
        let p = dir.join(format!("{name}.csv"));
        write_csv(&p, &t, &w2, 1.0, 1.0);
        let r = close_loop(&dir, &p, &[]);
        assert_eq!(r.code, 0, "{name}: {}", r.stderr);
        let v = r.json.unwrap();
        assert_eq!(v["effects"], serde_json::json!([]), "{name}: {}", r.stdout);
        assert!(
            r.stderr.contains("1 isolated spike"),
            "{name}: {}",
            r.stderr
        );
        // The paper's identifier (a_before) is not thrown either (without the gate the
        // 100 rad/s spike put it at 1.2e9).
        for k in 0..3 {
            let (x, y) = (
                v["a_before"][k].as_f64().unwrap(),
                clean["a_before"][k].as_f64().unwrap(),
            );
            assert!((x - y).abs() < 0.05, "{name}: {}", v["a_before"]);
        }
        for k in 0..3 {
            let (x, y) = (
                v["a_after"][k].as_f64().unwrap(),
                clean_a[k].as_f64().unwrap(),
            );
            assert!(
                (x - y).abs() < 0.01,
                "{name}: {} vs {clean_a}",
                v["a_after"]
            );
        }
    }
}

#[test]
fn clean_log_summary_claims_no_improvement() {
    let dir = tmpdir("summary");
    let (t, w) = clean();
    let p = dir.join("clean.csv");
    write_csv(&p, &t, &w, 1.0, 1.0);
    let r = close_loop(&dir, &p, &[]);
    assert_eq!(r.code, 0, "{}", r.stderr);
    assert!(r.stdout.starts_with("effects: none"), "{}", r.stdout);
    assert!(!r.stdout.contains("->"), "{}", r.stdout);
}

/// A log of 0 to 3 s with segments files in phyphox's layout.
fn segment_run(name: &str, segments: &str) -> Run {
    let dir = tmpdir(name);
    let (t, w) = clean();
    let p = dir.join("log.csv");
    write_csv(&p, &t, &w, 1.0, 1.0);
    let s = dir.join("segments.csv");
    std::fs::write(&s, segments).unwrap();
    close_loop(&dir, &p, &["--segments", s.to_str().unwrap()])
}

#[test]
fn segments_are_checked_against_the_log() {
    // Outside the log: which segment and why.
    let r = segment_run(
        "outside",
        "segment,start,end,keep,comment\n1,0.1,1.4,,\n2,5.0,6.0,,late\n",
    );
    assert_eq!(r.code, 3, "{}", r.stderr);
    assert!(
        r.stderr
            .contains("segment 2 [5 s, 6 s] lies outside the log")
            && r.stderr.contains("2.99"),
        "{}",
        r.stderr
    );
    // Overlapping: both named.
    let r = segment_run(
        "overlap",
        "segment,start,end,keep,comment\n1,0.1,1.5,,\n2,1.2,2.9,,\n",
    );
    assert_eq!(r.code, 3, "{}", r.stderr);
    assert!(
        r.stderr.contains("segments 1") && r.stderr.contains("overlap"),
        "{}",
        r.stderr
    );
    // A rejected phyphox row with empty start and end is skipped.
    let r = segment_run(
        "rejected",
        "segment,start,end,keep,comment\n1,0.1,1.4,,\n28,,,false,random noise\n2,1.5,2.9,true,\n",
    );
    assert_eq!(r.code, 0, "{}", r.stderr);
    let segs = r.json.unwrap()["segments"].as_array().unwrap().len();
    assert_eq!(segs, 2);
    // A kept row with an empty time is still an error with its line.
    let r = segment_run("empty_kept", "segment,start,end,keep,comment\n1,,1.4,,\n");
    assert_eq!(r.code, 3, "{}", r.stderr);
    assert!(r.stderr.contains("segments.csv:2"), "{}", r.stderr);
}

#[test]
fn number_arguments_take_a_leading_minus() {
    let dir = tmpdir("minus");
    let (t, w) = clean();
    let p = dir.join("clean.csv");
    write_csv(&p, &t, &w, 1.0, 1.0);
    let r = close_loop(&dir, &p, &["--truth", "-0.78,0.5,-0.2"]);
    assert_eq!(r.code, 0, "{}", r.stderr);
    assert_eq!(
        r.json.unwrap()["truth"],
        serde_json::json!([-0.78, 0.5, -0.2])
    );
    let r = close_loop(&dir, &p, &["--truth=-0.78,0.5,-0.2"]);
    assert_eq!(r.code, 0, "{}", r.stderr);
    // A negative alpha parses and is then refused for its value, not as an unknown flag.
    let r = close_loop(&dir, &p, &["--alpha", "-0.1"]);
    assert_eq!(r.code, 3, "{}", r.stderr);
    assert!(
        r.stderr.contains("--alpha -0.1 must be in (0, 1)"),
        "{}",
        r.stderr
    );
}

#[test]
fn the_tensor_base_model_refuses_wrong_units_too() {
    // `--rotor-inertia` switches to the tensor base model (`close_loop::tensor`); its input
    // gets the same unit checks before anything is fitted.
    let dir = tmpdir("tensor-units");
    let (t, w) = clean();
    let write = |name: &str, t_scale: f64, w_scale: f64| {
        let mut csv = String::from("t,wx,wy,wz,rotor_rad_s\n");
        for (tk, v) in t.iter().zip(&w) {
            csv.push_str(&format!(
                "{},{},{},{},300\n",
                tk * t_scale,
                v[0] * w_scale,
                v[1] * w_scale,
                v[2] * w_scale
            ));
        }
        let p = dir.join(name);
        std::fs::write(&p, csv).unwrap();
        p
    };
    let rotor = ["--rotor-inertia", "1.7e-6", "--rotor-axis", "-z"];
    let deg = write("deg.csv", 1.0, 180.0 / std::f64::consts::PI);
    let r = close_loop(&dir, &deg, &rotor);
    assert_eq!(r.code, 3, "{}", r.stderr);
    assert!(r.stderr.contains("--gyro-unit deg/s"), "{}", r.stderr);
    assert!(r.json.is_none());
    let ms = write("ms.csv", 1e3, 1.0);
    let r = close_loop(&dir, &ms, &rotor);
    assert_eq!(r.code, 3, "{}", r.stderr);
    assert!(r.stderr.contains("--time-unit ms"), "{}", r.stderr);
    // Declared, both are converted and analysed.
    let r = close_loop(
        &dir,
        &deg,
        &[&rotor[..], &["--gyro-unit", "deg/s"]].concat(),
    );
    assert_eq!(r.code, 0, "{}", r.stderr);
    assert_eq!(r.json.unwrap()["base_model"], "tensor");
    let r = close_loop(&dir, &ms, &[&rotor[..], &["--time-unit", "ms"]].concat());
    assert_eq!(r.code, 0, "{}", r.stderr);
}
