//! The `close-loop` command end to end: a simulated CSV log in, JSON, markdown and SVG out;
//! malformed input refused with the file and line.

use host_tests::gyro::GyroModel;
use host_tests::rigid_body::Body;
use std::path::PathBuf;
use std::process::Command;

fn tmpdir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("close_loop_cli_{}_{name}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d
}

#[test]
fn command_writes_json_table_and_plots() {
    let dir = tmpdir("ok");
    let mut body = Body::free([19.5, 1.39, 20.7]);
    body.damping = [0.15 * 19.5, 0.15 * 1.39, 0.15 * 20.7];
    // One plain CSV, no segments file: the whole log is one free flight of 3 s.
    let traj = body.simulate([20.0, 1.0, 1.5], 3.0, 100.0, 8);
    let meas = GyroModel::noisy(0.015, 5).measure(&traj);
    let mut csv = String::from("t,wx,wy,wz\n");
    for (t, w) in traj.t.iter().zip(&meas) {
        csv.push_str(&format!("{t},{},{},{}\n", w[0], w[1], w[2]));
    }
    let input = dir.join("log.csv");
    std::fs::write(&input, csv).unwrap();
    let json = dir.join("out.json");
    let plots = dir.join("plots");
    let out = Command::new(env!("CARGO_BIN_EXE_close-loop"))
        .args(["--input", input.to_str().unwrap()])
        .args(["--json", json.to_str().unwrap()])
        .args(["--plots", plots.to_str().unwrap()])
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: serde_json::Value = serde_json::from_slice(&std::fs::read(&json).unwrap()).unwrap();
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
}

#[test]
fn command_names_file_and_line_of_bad_input() {
    let dir = tmpdir("bad");
    let input = dir.join("bad.csv");
    std::fs::write(&input, "t,wx,wy,wz\n0,1,2,3\n0.01,1,nan,3\n").unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_close-loop"))
        .args(["--input", input.to_str().unwrap(), "--json"])
        .arg(dir.join("o.json"))
        .output()
        .unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("bad.csv:3"), "{err}");
}
