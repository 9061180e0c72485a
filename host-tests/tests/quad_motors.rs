//! A quadrotor's own motors as the known rotors: a simulated throw with the propellers off,
//! the motors' speeds logged as eRPM columns of a CSV and described by a vehicle file, gives the
//! tensor in kg m^2 without a separate flywheel; the same columns read in the wrong unit say
//! `UnitsLookWrong`, not a tensor 67 times too large.
//!
//! The frame (a 5-inch quad's inertia) is thrown tumbling while two diagonal motors, spinning
//! the same way (axis -z), run up from idle (the other two stopped): the momentum changes
//! along z, which fixes the tensor's scale, as a flywheel's spin-up does.
//!
//! `cargo test --release -p host-tests --test quad_motors -- --nocapture`

use std::io::Write;
use std::path::Path;

use host_tests::throw_sim::{board_throw_config, simulate, RotorProfile};
use inertia::identify::{identify_source, IdentifyOptions, Quiet, Report};
use inertia::source::open;
use inertia::vehicle::Vehicle;
use inertia::ReadOptions;

/// One motor's rotor (bell, magnets, shaft) about its axis, kg m^2.
const MOTOR_INERTIA: f64 = 1.2e-5;
/// Motor poles (a 14-pole outrunner): mechanical rad/s = eRPM / 7 * 2 pi / 60.
const POLES: f64 = 14.0;

/// `inertia identify --input csv --vehicle toml`, through the library.
fn identify_with(csv: &Path, toml: &Path) -> Report {
    let vehicle = Vehicle::load(toml).unwrap();
    let read = ReadOptions {
        rotor_columns: vehicle.columns(),
        ..ReadOptions::default()
    };
    let src = open(csv, &read).unwrap();
    let opts = IdentifyOptions {
        vehicle: Some(vehicle),
        ..IdentifyOptions::default()
    };
    identify_source(&*src, &opts, &mut Quiet).unwrap()
}

#[test]
fn four_motors_without_propellers_give_the_tensor_in_kg_m2() {
    let mut cfg = board_throw_config(3);
    cfg.inertia = [
        [2.6e-3, 4.0e-5, -2.0e-5],
        [4.0e-5, 2.4e-3, 3.0e-5],
        [-2.0e-5, 3.0e-5, 4.6e-3],
    ];
    // Motors 1 and 3 together: one rotor of twice a motor's inertia about -z.
    cfg.rotor.inertia = 2.0 * MOTOR_INERTIA;
    cfg.rotor.axis = [0.0, 0.0, -1.0];
    cfg.rotor.profile = RotorProfile::board_spin_up();
    cfg.quantize_rotor_speed = false;
    let sim = simulate(&cfg);

    let dir = std::env::temp_dir().join(format!("quad_motors_{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let csv = dir.join("quad.csv");
    let mut w = std::io::BufWriter::new(std::fs::File::create(&csv).unwrap());
    writeln!(w, "t,wx,wy,wz,ax,ay,az,m1_erpm,m2_erpm,m3_erpm,m4_erpm").unwrap();
    let erpm = POLES / 2.0 * 60.0 / std::f64::consts::TAU;
    for k in 0..sim.t.len() {
        let (g, a) = (sim.gyro[k], sim.accel[k]);
        let e = f64::from(sim.rotor_rad_s[k]) * erpm;
        writeln!(
            w,
            "{:.7},{},{},{},{},{},{},{e:.3},0,{e:.3},0",
            sim.t[k], g[0], g[1], g[2], a[0], a[1], a[2]
        )
        .unwrap();
    }
    drop(w);
    let toml = dir.join("quad.toml");
    let motor = |i: usize, z: f64, unit: &str| {
        format!(
            "[[rotor]]\nname = \"m{i}\"\ncolumn = \"m{i}_erpm\"\ninertia_kg_m2 = {MOTOR_INERTIA:e}\n\
             axis = [0.0, 0.0, {z:.1}]\npoles = {POLES}\n{unit}\n"
        )
    };
    let file = |unit: &str| {
        let m = [(1, -1.0), (2, 1.0), (3, -1.0), (4, 1.0)];
        m.map(|(i, z)| motor(i, z, unit)).concat()
    };
    // The columns' unit not declared: `m1_erpm` does not start with "erpm", so it is read as
    // rad/s, 67 times too fast: the tensor would be 67 times too large with a perfect fit.
    std::fs::write(&toml, file("")).unwrap();
    let wrong = identify_with(&csv, &toml);
    println!(
        "unit not declared: {} ({:?})",
        wrong.pooled.tensor_status, wrong.warnings
    );
    assert_eq!(wrong.pooled.tensor_status, "UnitsLookWrong");

    std::fs::write(&toml, file("speed_unit = \"erpm\"\n")).unwrap();
    let rep = identify_with(&csv, &toml);
    let j = rep.pooled.tensor_kg_m2.expect("the tensor in kg m^2");
    let s = rep.pooled.tensor_std_kg_m2.unwrap();
    let (mut e2, mut t2, mut zmax) = (0.0, 0.0, 0.0f64);
    for r in 0..3 {
        for c in 0..3 {
            let e = f64::from(j[r][c]) - cfg.inertia[r][c];
            e2 += e * e;
            t2 += cfg.inertia[r][c] * cfg.inertia[r][c];
            zmax = zmax.max(e.abs() / f64::from(s[r][c]));
        }
    }
    let fro = 100.0 * (e2 / t2).sqrt();
    println!(
        "quad frame, 4 motors (2 spinning up): {} throw(s), {}, Frobenius {fro:.3} %, max |error|/std {zmax:.2}",
        rep.throws.len(),
        rep.pooled.tensor_status
    );
    assert!(fro < 3.0, "{fro} %");
    assert!(zmax < 4.0, "{zmax}");
}
