//! `inertia identify --export` end to end: a simulated Betaflight log of a body with a flywheel
//! spinning up (the tensor in kg m^2), exported as URDF (parsed back with `urdf-rs`), SDF
//! (parsed back with `roxmltree`), PX4 parameters and JSON; and the refusals: no mass, no
//! rotor, an untrusted status without `--force`, a tensor that is no rigid body's.
use std::path::{Path, PathBuf};
use std::process::Command;

use inertia::export::{export, ExportError, ExportFormat, ExportOptions, InvalidTensor};
use inertia::identify::{identify, IdentifyOptions, Rotor};
use log_writers::blackbox as blackbox_writer;

mod common;
use common::{
    betaflight_header, betaflight_throw, without_gyro_filters, MOMENTS, ROTOR, ROTOR_INERTIA,
};

const MASS: &str = "0.032";

fn out_dir() -> PathBuf {
    common::out_dir("export")
}

/// Writes the throw as a Betaflight blackbox log `NAME.bbl`: its gyro filters declared in the
/// header (`declared`, identified `Converged`) or not (read for instants: not trusted).
fn throw_log(name: &str, declared: bool) -> PathBuf {
    let header = betaflight_header(true);
    let header = if declared {
        header
    } else {
        without_gyro_filters(&header)
    };
    let frames = betaflight_throw(MOMENTS, [12.0, -9.0, 14.0], ROTOR_INERTIA, 0);
    let bytes = blackbox_writer::blackbox("Betaflight 4.4.2 (abc) STM32F405", &header, &frames);
    let path = out_dir().join(format!("{name}.bbl"));
    std::fs::write(&path, bytes).unwrap();
    path
}

/// Runs `inertia identify --input LOG ARGS`: exit code and stderr.
fn identify_cli(log: &Path, args: &[&str]) -> (i32, String) {
    let o = Command::new(env!("CARGO_BIN_EXE_inertia"))
        .arg("identify")
        .arg("--input")
        .arg(log)
        .args(args)
        .output()
        .unwrap();
    (
        o.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&o.stderr).to_string(),
    )
}

fn path_str(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// The pooled tensor and its status from a JSON report.
fn pooled_tensor(json: &Path) -> ([[f32; 3]; 3], String) {
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(json).unwrap()).unwrap();
    let t = &v["pooled"]["tensor_kg_m2"];
    let j = std::array::from_fn(|r| {
        std::array::from_fn(|c| t[r][c].as_f64().expect("tensor in kg m^2") as f32)
    });
    (
        j,
        v["pooled"]["tensor_status"].as_str().unwrap().to_string(),
    )
}

/// `ixx ixy ixz iyy iyz izz` of `j`.
fn six(j: &[[f32; 3]; 3]) -> [f32; 6] {
    [j[0][0], j[0][1], j[0][2], j[1][1], j[1][2], j[2][2]]
}

/// Identifies the `declared` throw with `--export FORMAT` and the extra `args`: the JSON
/// report's pooled tensor (`Converged`, near the simulated body) and the exported text.
fn export_converged(name: &str, format: &str, args: &[&str]) -> ([[f32; 3]; 3], String) {
    let d = out_dir();
    let log = throw_log(name, true);
    let (json, out) = (
        d.join(format!("{name}.json")),
        d.join(format!("{name}.{format}")),
    );
    let _ = std::fs::remove_file(&out);
    let mut all = ROTOR.to_vec();
    all.extend([
        "--json",
        path_str(&json),
        "--export",
        format,
        "--export-out",
        path_str(&out),
    ]);
    all.extend_from_slice(args);
    let (code, err) = identify_cli(&log, &all);
    assert_eq!(code, 0, "{err}");
    assert!(err.contains("export written to"), "{err}");
    let (j, status) = pooled_tensor(&json);
    assert_eq!(status, "Converged", "{err}");
    for i in 0..3 {
        let rel = (f64::from(j[i][i]) - MOMENTS[i]).abs() / MOMENTS[i];
        assert!(rel < 0.05, "J[{i}][{i}] = {} vs {}", j[i][i], MOMENTS[i]);
    }
    (j, std::fs::read_to_string(&out).unwrap())
}

#[test]
fn urdf_export_round_trips_through_urdf_rs() {
    let (j, text) = export_converged("urdf", "urdf", &["--mass", MASS]);
    let robot = urdf_rs::read_from_string(&text).unwrap();
    assert_eq!(robot.links.len(), 1, "{text}");
    let inertial = &robot.links[0].inertial;
    assert_eq!(inertial.mass.value, 0.032);
    // No centre of mass given: at the IMU, and the file says so.
    assert_eq!(*inertial.origin.xyz, [0.0; 3]);
    assert_eq!(*inertial.origin.rpy, [0.0; 3]);
    assert!(text.contains("Centre of mass not known"), "{text}");
    let i = &inertial.inertia;
    let parsed = [i.ixx, i.ixy, i.ixz, i.iyy, i.iyz, i.izz];
    // The report's f32 entries exactly, off-diagonal signs as in the matrix.
    assert_eq!(parsed.map(|x| x as f32), six(&j), "{text}");
}

/// The names of `n`'s child elements.
fn elements(n: roxmltree::Node<'_, '_>) -> Vec<String> {
    n.children()
        .filter(|c| c.is_element())
        .map(|c| c.tag_name().name().to_string())
        .collect()
}

/// `n`'s child element `name`.
fn child<'a, 'i>(n: roxmltree::Node<'a, 'i>, name: &str) -> roxmltree::Node<'a, 'i> {
    n.children()
        .find(|c| c.has_tag_name(name))
        .unwrap_or_else(|| panic!("no <{name}> in <{}>", n.tag_name().name()))
}

/// The number an element holds.
fn number(n: roxmltree::Node<'_, '_>) -> f64 {
    n.text().unwrap().trim().parse().unwrap()
}

#[test]
fn sdf_export_parses_with_its_structure_and_values() {
    let (j, text) = export_converged(
        "sdf",
        "sdf",
        &["--mass", MASS, "--com", "0.004,-0.0025,0.01"],
    );
    let doc = roxmltree::Document::parse(&text).unwrap();
    let root = doc.root_element();
    assert_eq!(root.tag_name().name(), "sdf");
    assert_eq!(root.attribute("version"), Some("1.9"));
    assert_eq!(elements(root), ["model"]);
    let model = child(root, "model");
    assert_eq!(elements(model), ["link"]);
    let link = child(model, "link");
    assert_eq!(elements(link), ["inertial"]);
    let inertial = child(link, "inertial");
    assert_eq!(elements(inertial), ["mass", "pose", "inertia"]);
    assert_eq!(number(child(inertial, "mass")), 0.032);
    let pose: Vec<f64> = child(inertial, "pose")
        .text()
        .unwrap()
        .split_whitespace()
        .map(|x| x.parse().unwrap())
        .collect();
    assert_eq!(pose, [0.004, -0.0025, 0.01, 0.0, 0.0, 0.0]);
    assert!(!text.contains("Centre of mass not known"), "{text}");
    let inertia = child(inertial, "inertia");
    let names = ["ixx", "ixy", "ixz", "iyy", "iyz", "izz"];
    assert_eq!(elements(inertia), names);
    let parsed = names.map(|k| number(child(inertia, k)) as f32);
    assert_eq!(parsed, six(&j), "{text}");
}

#[test]
fn px4_export_sets_the_vehicle_model_and_sih_parameters() {
    let (j, text) = export_converged("px4", "px4", &["--mass", MASS]);
    let params: Vec<(&str, f64)> = text
        .lines()
        .filter(|l| !l.starts_with('#'))
        .map(|l| {
            let w: Vec<&str> = l.split_whitespace().collect();
            assert_eq!(w.len(), 4, "{l}");
            assert_eq!(&w[..2], ["param", "set"], "{l}");
            (w[2], w[3].parse().unwrap())
        })
        .collect();
    let names: Vec<&str> = params.iter().map(|p| p.0).collect();
    assert_eq!(
        names,
        [
            "VM_MASS",
            "VM_INERTIA_XX",
            "VM_INERTIA_XY",
            "VM_INERTIA_XZ",
            "VM_INERTIA_YY",
            "VM_INERTIA_YZ",
            "VM_INERTIA_ZZ",
            "SIH_MASS",
            "SIH_IXX",
            "SIH_IXY",
            "SIH_IXZ",
            "SIH_IYY",
            "SIH_IYZ",
            "SIH_IZZ"
        ]
    );
    for block in params.chunks(7) {
        assert_eq!(block[0].1, 0.032);
        let values: Vec<f32> = block[1..].iter().map(|p| p.1 as f32).collect();
        assert_eq!(values, six(&j));
    }
    assert!(text.contains("# <inertial>"), "{text}");
}

/// `--export json` writes what `--json` writes, and `--json` is the same bytes with or without
/// an export.
#[test]
fn json_export_is_the_json_report_byte_for_byte() {
    let (_, exported) = export_converged("json", "json", &[]);
    let d = out_dir();
    let with = std::fs::read_to_string(d.join("json.json")).unwrap();
    assert_eq!(exported, with);
    let plain = d.join("json_plain.json");
    let mut args = ROTOR.to_vec();
    args.extend(["--json", path_str(&plain)]);
    let (code, err) = identify_cli(&throw_log("json_plain", true), &args);
    assert_eq!(code, 0, "{err}");
    let without = std::fs::read_to_string(&plain).unwrap();
    // The reports differ only in the input's name.
    assert_eq!(without.replace("json_plain.bbl", "json.bbl"), with);
}

#[test]
fn an_untrusted_tensor_is_refused_without_force() {
    let d = out_dir();
    // The filters left out of the header: the rate read 0.95 ms behind the rotor's speed.
    let log = throw_log("untrusted", false);
    let (json, out) = (d.join("untrusted.json"), d.join("untrusted.urdf"));
    let _ = std::fs::remove_file(&out);
    let mut args = ROTOR.to_vec();
    args.extend([
        "--json",
        path_str(&json),
        "--export",
        "urdf",
        "--export-out",
        path_str(&out),
        "--mass",
        MASS,
    ]);
    let (code, err) = identify_cli(&log, &args);
    let (j, status) = pooled_tensor(&json);
    assert_ne!(status, "Converged");
    assert_eq!(code, 3, "{err}");
    assert!(
        err.contains(&format!("error: the pooled tensor's status is {status}"))
            && err.contains("--force"),
        "{err}"
    );
    assert!(!out.exists());
    args.push("--force");
    let (code, err) = identify_cli(&log, &args);
    assert_eq!(code, 0, "{err}");
    assert!(err.contains("warning: --force: exporting"), "{err}");
    let robot = urdf_rs::read_from_string(&std::fs::read_to_string(&out).unwrap()).unwrap();
    let i = &robot.links[0].inertial.inertia;
    assert_eq!(
        [i.ixx, i.ixy, i.ixz, i.iyy, i.iyz, i.izz].map(|x| x as f32),
        six(&j)
    );
}

/// The identification's own report with its tensor changed so that the largest principal
/// moment exceeds the sum of the other two: refused with and without `--force`.
#[test]
fn a_tensor_violating_the_triangle_inequality_is_refused() {
    let log = throw_log("triangle", true);
    let rec = inertia::read(&log, &Default::default()).unwrap();
    let opts = IdentifyOptions {
        rotor: Some(Rotor {
            inertia: ROTOR_INERTIA as f32,
            axis: [0.0, 0.0, 1.0],
            poles: Some(12),
        }),
        ..Default::default()
    };
    let mut report = identify(&rec, &opts).unwrap();
    // Status `Converged` (as the CLI's run of the same log), so only the tensor is judged.
    report.pooled.tensor_status = "Converged".into();
    let mut bad = report.clone();
    let mut j = report.pooled.tensor_kg_m2.unwrap();
    j[2][2] = 1.2 * (j[0][0] + j[1][1]);
    bad.pooled.tensor_kg_m2 = Some(j);
    for format in [ExportFormat::Urdf, ExportFormat::Sdf, ExportFormat::Px4] {
        for force in [false, true] {
            let o = ExportOptions {
                format,
                mass_kg: Some(0.032),
                com_m: None,
                force,
            };
            assert!(export(&report, &o).is_ok());
            let e = export(&bad, &o).unwrap_err();
            assert!(
                matches!(
                    e,
                    ExportError::Invalid(InvalidTensor::TriangleInequality(_))
                ),
                "{e:?}"
            );
            assert!(e.to_string().contains("triangle inequality"), "{e}");
        }
    }
}

/// Refusals that need no identification: said before the log is read.
#[test]
fn a_missing_mass_or_rotor_is_refused_at_once() {
    let d = out_dir();
    let log = d.join("no_such_log.bbl");
    let out = d.join("never.urdf");
    let json = d.join("never.json");
    let base = [
        "--json",
        path_str(&json),
        "--export",
        "urdf",
        "--export-out",
        path_str(&out),
    ];
    let mut args = ROTOR.to_vec();
    args.extend(base);
    let (code, err) = identify_cli(&log, &args);
    assert_eq!(code, 3, "{err}");
    assert!(
        err.contains("error: --export urdf needs the body's mass: give --mass"),
        "{err}"
    );
    let mut args = base.to_vec();
    args.extend(["--mass", MASS]);
    let (code, err) = identify_cli(&log, &args);
    assert_eq!(code, 3, "{err}");
    assert!(err.contains("only up to scale"), "{err}");
    let mut args = ROTOR.to_vec();
    args.extend(base);
    args.extend(["--mass", MASS, "--com", "1,2"]);
    let (code, err) = identify_cli(&log, &args);
    assert_eq!(code, 3, "{err}");
    assert!(err.contains("--com"), "{err}");
    assert!(!out.exists() && !json.exists());
}
