//! `inertia identify --input A --input B ...`: throws of one body in several logs, each
//! identified on its own and pooled by their covariances ((P1)-(P3) of `inertia::pool`).
//! Simulated Betaflight logs of a body with a flywheel spinning up, three seeds.
use std::path::PathBuf;

use log_writers::blackbox as blackbox_writer;

mod common;
use common::{betaflight_header, betaflight_throw, MOMENTS, ROTOR, ROTOR_INERTIA};

fn out_dir() -> PathBuf {
    common::out_dir("pool")
}

fn log(seed: u64, w0: [f64; 3]) -> PathBuf {
    let frames = betaflight_throw(MOMENTS, w0, ROTOR_INERTIA, seed);
    let bytes = blackbox_writer::blackbox(
        "Betaflight 4.4.2 (abc) STM32F405",
        &betaflight_header(true),
        &frames,
    );
    let path = out_dir().join(format!("throw-{seed}.bbl"));
    std::fs::write(&path, bytes).unwrap();
    path
}

fn identify(inputs: &[PathBuf], rotor: bool, json: &str) -> (i32, serde_json::Value, String) {
    let mut args: Vec<std::ffi::OsString> = Vec::new();
    for i in inputs {
        args.push("--input".into());
        args.push(i.into());
    }
    if rotor {
        args.extend(ROTOR.iter().map(Into::into));
    }
    common::identify_cli(&args, &out_dir().join(json))
}

fn diag(v: &serde_json::Value, key: &str) -> [f64; 3] {
    [0, 1, 2].map(|i| v["pooled"][key][i][i].as_f64().unwrap())
}

#[test]
fn throws_in_several_logs_are_pooled_by_their_covariances() {
    let logs = [
        log(1, [12.0, -9.0, 14.0]),
        log(2, [-10.0, 11.0, 13.0]),
        log(3, [9.0, 12.0, -15.0]),
    ];
    let (code, v, err) = identify(&logs, true, "pooled.json");
    assert_eq!(code, 0, "{err}");
    assert_eq!(v["inputs"].as_array().unwrap().len(), 3);
    assert_eq!(v["logs"].as_array().unwrap().len(), 3);
    assert_eq!(v["throws_per_input"], serde_json::json!([1, 1, 1]));
    let spread = &v["spread"];
    println!("spread {spread}");
    assert_eq!(spread["dof"], 12);
    // Three logs of the same body agree to their standard deviations.
    assert_eq!(spread["consistent"], true, "{spread}");
    let (t, s) = (diag(&v, "tensor_kg_m2"), diag(&v, "tensor_std_kg_m2"));
    for i in 0..3 {
        let z = (t[i] - MOMENTS[i]) / s[i];
        // Smaller than any one log's.
        for l in v["logs"].as_array().unwrap() {
            let one = l["pooled"]["tensor_std_kg_m2"][i][i].as_f64().unwrap();
            assert!(
                s[i] < one,
                "moment {i}: pooled std {} vs one log's {one}",
                s[i]
            );
        }
        println!("moment {i}: {:.4e} +- {:.1e} (z {z:+.2})", t[i], s[i]);
        assert!(z.abs() < 4.0, "moment {i}: z {z}");
    }
    // One log's report is the single-input report (byte for byte the same JSON).
    let (_, single, _) = identify(&logs[..1], true, "single.json");
    assert_eq!(single, v["logs"][0]);
}

#[test]
fn several_logs_without_a_rotor_are_refused_with_the_reason() {
    let logs = [log(4, [12.0, -9.0, 14.0]), log(5, [-10.0, 11.0, 13.0])];
    let (code, _, err) = identify(&logs, false, "norotor.json");
    assert_eq!(code, 3, "{err}");
    assert!(err.contains("no tensor in kg m^2"), "{err}");
}
