//! The simulated throws (`host_tests::throw_sim`) and the tensor Cramer-Rao bound
//! (`host_tests::crb_tensor`).

// Index loops read closest to the equations they check.
#![allow(clippy::needless_range_loop)]

use host_tests::crb_tensor::{
    absolute_bound, ratio_bound, ratio_bound_constrained_from_crb, scale_free_bound, FreeFlight,
    ENTRY_NAMES,
};
use host_tests::throw_sim::{
    self, board_throw, clipped_toss, cross, matvec, no_rotor_toss, norm, quat_to_mat, still,
    tumbling_with_spinup, CsvOptions, SimThrow, ThrowConfig,
};

fn noise_free(mut cfg: ThrowConfig) -> SimThrow {
    cfg.gyro.noise_std = 0.0;
    cfg.gyro.quantize = false;
    cfg.accel.noise_std = 0.0;
    cfg.accel.quantize = false;
    cfg.quantize_rotor_speed = false;
    throw_sim::simulate(&cfg)
}

fn fmt3(v: [f64; 3], p: usize) -> String {
    format!("[{:.p$e}, {:.p$e}, {:.p$e}]", v[0], v[1], v[2])
}

fn energy(j: &[[f64; 3]; 3], w: [f64; 3]) -> f64 {
    let jw = matvec(j, w);
    0.5 * (jw[0] * w[0] + jw[1] * w[1] + jw[2] * w[2])
}

#[test]
fn free_flight_without_rotor_conserves_energy_and_momentum() {
    let sim = noise_free(throw_sim::no_rotor_toss_config(3));
    let r = sim.free_flight().unwrap();
    let j = sim.config.inertia;
    let e0 = energy(&j, sim.omega_true[r.start]);
    let l0 = norm(sim.momentum_body(r.start));
    let lw0 = matvec(&quat_to_mat(sim.quat[r.start]), sim.momentum_body(r.start));
    let (mut de, mut dl, mut dlw) = (0.0f64, 0.0f64, 0.0f64);
    for k in r.clone() {
        de = de.max((energy(&j, sim.omega_true[k]) - e0).abs() / e0);
        dl = dl.max((norm(sim.momentum_body(k)) - l0).abs() / l0);
        let lw = matvec(&quat_to_mat(sim.quat[k]), sim.momentum_body(k));
        dlw = dlw.max(norm([lw[0] - lw0[0], lw[1] - lw0[1], lw[2] - lw0[2]]) / l0);
    }
    println!("no rotor: relative drift energy {de:.2e}, |L| {dl:.2e}, world L {dlw:.2e}");
    assert!(de < 1e-9, "energy drift {de}");
    assert!(dl < 1e-9, "momentum drift {dl}");
    assert!(dlw < 1e-9, "world-frame momentum drift {dlw}");
    // The body really tumbles.
    assert!(norm(sim.omega_true[r.start]) > 14.0);
}

#[test]
fn momentum_is_conserved_through_the_flywheel_spin_up() {
    for sim in [
        noise_free(throw_sim::board_throw_config(1)),
        noise_free(throw_sim::tumbling_with_spinup_config(2)),
    ] {
        let r = sim.free_flight().unwrap();
        let l0 = norm(sim.momentum_body(r.start));
        let lw0 = matvec(&quat_to_mat(sim.quat[r.start]), sim.momentum_body(r.start));
        let (mut dl, mut dlw) = (0.0f64, 0.0f64);
        let j = sim.config.inertia;
        let (mut emin, mut emax) = (f64::MAX, 0.0f64);
        for k in r.clone() {
            dl = dl.max((norm(sim.momentum_body(k)) - l0).abs() / l0);
            let lw = matvec(&quat_to_mat(sim.quat[k]), sim.momentum_body(k));
            dlw = dlw.max(norm([lw[0] - lw0[0], lw[1] - lw0[1], lw[2] - lw0[2]]) / l0);
            let e = energy(&j, sim.omega_true[k]);
            emin = emin.min(e);
            emax = emax.max(e);
        }
        let hmax = r.clone().map(|k| norm(sim.h_true[k])).fold(0.0, f64::max);
        let peak = r.clone().map(|k| sim.rotor_true[k]).fold(0.0, f64::max);
        println!(
            "spin-up: rotor peak {peak:.0} rad/s, |h| max {hmax:.2e} vs |L| {l0:.2e}; drift |L| {dl:.2e}, world L {dlw:.2e}; body energy {emin:.3e}..{emax:.3e} J"
        );
        assert!(peak > 1200.0);
        assert!(dl < 1e-9, "momentum drift {dl}");
        assert!(dlw < 1e-9, "world-frame momentum drift {dlw}");
        // The motor does work: the body's energy is not conserved, so the rotor matters.
        assert!(emax - emin > 0.05 * emax);
    }
}

#[test]
fn accelerometer_reads_only_rotation_about_the_centre_of_mass_in_free_flight() {
    let cfg = throw_sim::board_throw_config(4);
    let r_arm = cfg.imu_from_com();
    let jinv = throw_sim::inverse3(&cfg.inertia);
    for sim in [noise_free(cfg), throw_sim::simulate(&cfg)] {
        let r = sim.free_flight().unwrap();
        let release = sim.release_s.unwrap();
        let mut worst = 0.0f64;
        let mut sq = 0.0;
        for k in r.clone() {
            let w = sim.omega_true[k];
            // w' from Euler's equation with the rotor, independently of the simulator's record.
            let (h, dh) = cfg.rotor.momentum(sim.t[k] - release);
            let jw = matvec(&cfg.inertia, w);
            let lxw = cross([jw[0] + h[0], jw[1] + h[1], jw[2] + h[2]], w);
            let wd = matvec(&jinv, [lxw[0] - dh[0], lxw[1] - dh[1], lxw[2] - dh[2]]);
            let c = cross(w, cross(w, r_arm));
            let t = cross(wd, r_arm);
            for i in 0..3 {
                let f = c[i] + t[i];
                let d = f64::from(sim.accel[k][i]) - f;
                worst = worst.max(d.abs());
                sq += d * d;
            }
        }
        let rms = (sq / (3 * r.len()) as f64).sqrt();
        println!(
            "accelerometer against w x (w x r) + w' x r: worst {worst:.2e}, rms {rms:.2e} m/s^2"
        );
        if sim.config.accel.noise_std == 0.0 {
            assert!(worst < 1e-5, "{worst}");
        } else {
            // noise 0.05 m/s^2 and the 2048 LSB/g resolution
            assert!((rms - 0.05).abs() < 0.01, "{rms}");
        }
    }
}

#[test]
fn phases_are_visible_and_true_times_are_returned() {
    for (name, sim) in [
        ("board_throw", board_throw(1)),
        ("tumbling_with_spinup", tumbling_with_spinup(1)),
        ("no_rotor_toss", no_rotor_toss(1)),
        ("clipped_toss", clipped_toss(1)),
        ("still", still(1)),
    ] {
        println!("{name}:\n{}", sim.summary());
        let Some(r) = sim.free_flight() else {
            assert_eq!(name, "still");
            assert!(sim.release_s.is_none() && sim.catch_s.is_none());
            // The bench: 1 g, no rotation.
            for k in 0..sim.t.len() {
                assert!((norm(sim.accel_true[k]) - throw_sim::G).abs() < 1e-9);
                assert!(norm(sim.gyro[k].map(f64::from)) < 0.05);
            }
            continue;
        };
        let (rel, cat) = (sim.release_s.unwrap(), sim.catch_s.unwrap());
        assert!((cat - rel - sim.config.free_s).abs() < 1e-9);
        assert!(sim.t[r.start] >= rel && sim.t[r.start] - rel < sim.dt());
        // On the bench: 1 g.
        assert!((norm(sim.accel_true[10]) - throw_sim::G).abs() < 1e-9);
        // Free flight: no gravity, only the rotation about the centre of mass (< 2 g here).
        let fmax = r
            .clone()
            .map(|k| norm(sim.accel_true[k]))
            .fold(0.0, f64::max);
        let lim = norm(sim.config.com_from_imu) * 60f64.powi(2);
        assert!(fmax < lim, "{fmax}");
        // Just before the release the hand pushes: not free fall.
        let before = norm(sim.accel_true[r.start - 40]);
        assert!(before > 5.0, "{before}");
        // The catch: an impact at full scale of the accelerometer, and w decays in ~50 ms.
        let after = r.end..(r.end + (0.05 * sim.config.rate_hz) as usize);
        let fpeak = after
            .clone()
            .map(|k| sim.accel[k].iter().map(|v| v.abs()).fold(0.0f32, f32::max))
            .fold(0.0f32, f32::max);
        assert!(f64::from(fpeak) >= 0.99 * sim.config.accel.full_scale);
        let w_end = norm(sim.omega_true[after.end]);
        assert!(w_end < 0.05 * norm(sim.omega_true[r.end - 1]));
        let clipped = r.clone().filter(|&k| sim.gyro_clipped[k]).count();
        if name == "clipped_toss" {
            assert!(clipped > 100, "{clipped}");
        } else {
            assert_eq!(clipped, 0, "{name}");
        }
    }
}

#[test]
fn scenarios_are_reproducible_and_csv_has_the_declared_units() {
    let a = board_throw(7);
    let b = board_throw(7);
    assert_eq!(a.gyro, b.gyro);
    assert_eq!(a.accel, b.accel);
    assert_ne!(a.gyro, board_throw(8).gyro);
    let mut buf = Vec::new();
    a.write_csv_to(&mut buf, CsvOptions::default()).unwrap();
    let text = String::from_utf8(buf).unwrap();
    let mut lines = text.lines();
    assert_eq!(lines.next().unwrap(), "t,wx,wy,wz,ax,ay,az,rotor_rad_s");
    let k = a.free_flight().unwrap().start + 100;
    let row: Vec<f64> = lines
        .nth(k)
        .unwrap()
        .split(',')
        .map(|v| v.parse().unwrap())
        .collect();
    assert!((row[0] - a.t[k]).abs() < 1e-6);
    assert_eq!(row[1] as f32, a.gyro[k][0]);
    assert_eq!(row[7] as f32, a.rotor_rad_s[k]);
    let mut buf = Vec::new();
    a.write_csv_to(
        &mut buf,
        CsvOptions {
            deg_per_s: true,
            time_ms: true,
        },
    )
    .unwrap();
    let text = String::from_utf8(buf).unwrap();
    let row: Vec<f64> = text
        .lines()
        .nth(k + 1)
        .unwrap()
        .split(',')
        .map(|v| v.parse().unwrap())
        .collect();
    assert!((row[0] - 1e3 * a.t[k]).abs() < 1e-3);
    assert!((row[1] - f64::from(a.gyro[k][0]).to_degrees()).abs() < 1e-3);
}

#[test]
fn tensor_bound_of_the_board_throw() {
    let sim = board_throw(1);
    let ff = FreeFlight::from_throw(&sim).unwrap();
    let sigma = 2e-3;
    let a = absolute_bound(&ff, sigma, false).unwrap();
    let ab = absolute_bound(&ff, sigma, true).unwrap();
    let j = sim.config.inertia;
    println!(
        "board_throw(1), sigma {sigma}: {} free-flight samples, w0 {:?}",
        a.samples, ff.omega0
    );
    println!("entry       J (kg m^2)   CRB std       rel    | with bias   | J/tr std   ");
    for (e, &(r, c)) in host_tests::crb_tensor::ENTRIES.iter().enumerate() {
        println!(
            "{:4}  {:+.4e}  {:.3e}  {:.2e} | {:.3e}  | {:.3e}",
            ENTRY_NAMES[e],
            j[r][c],
            a.std_j[r][c],
            a.std_j[r][c] / j[r][r].min(j[c][c]),
            ab.std_j[r][c],
            a.std_j_normalized[r][c]
        );
    }
    println!(
        "std w0 {}, with bias: std bias {}",
        fmt3(a.std_omega0, 2),
        fmt3(ab.std_bias.unwrap(), 2)
    );
    // The flywheel makes the scale observable: diagonal entries to better than 1 %.
    for i in 0..3 {
        assert!(a.std_j[i][i] < 0.01 * j[i][i], "{}", a.std_j[i][i]);
        assert!(ab.std_j[i][i] >= a.std_j[i][i] * (1.0 - 1e-9));
    }
    // Without rotor momentum the scale is free: the absolute bound does not exist, the
    // normalised one does.
    let nr = no_rotor_toss(1);
    let ffn = FreeFlight::from_throw(&nr).unwrap();
    assert!(absolute_bound(&ffn, sigma, false).is_none_or(|b| b.std_j[0][0] > j[0][0]));
    let sf = scale_free_bound(&ffn, sigma, false).unwrap();
    println!(
        "no_rotor_toss(1): J/tr std {}",
        sf.std_j.map(|r| fmt3(r, 2)).join(" ")
    );
    for i in 0..3 {
        assert!(sf.std_j[i][i] < 1e-2);
    }
    // The trace of J / tr(J) is exactly 1: its variance is zero.
    let t: f64 = (0..3)
        .flat_map(|a| (0..3).map(move |b| (a, b)))
        .map(|(a, b)| sf.cov_j[(a, b)])
        .sum();
    assert!(t.abs() < 1e-12 * sf.cov_j[(0, 0)], "{t}");
}

#[test]
fn clipped_samples_are_left_out_of_the_bound() {
    let sim = clipped_toss(1);
    let ff = FreeFlight::from_throw(&sim).unwrap();
    let used = ff.samples_used();
    assert!(used < ff.n);
    let b = absolute_bound(&ff, 2e-3, false).unwrap();
    let mut all = ff.clone();
    all.used.clear();
    let ball = absolute_bound(&all, 2e-3, false).unwrap();
    println!(
        "clipped_toss(1): {used} of {} samples used; std Jxx {:.3e} (all samples {:.3e})",
        ff.n, b.std_j[0][0], ball.std_j[0][0]
    );
    assert!(b.std_j[0][0] > ball.std_j[0][0]);
}

/// (c) On the paper's scenario the ratio bound from the diagonal tensor up to scale equals
/// `crb.rs`'s bound with the rigid-body constraint applied.
#[test]
fn ratio_bound_agrees_with_crb_on_the_paper_scenario() {
    let a = host_tests::paper::body().a();
    let (n, rate, sigma) = (20001, 1000.0, 2e-3);
    let w0 = host_tests::paper::OMEGA0;
    let (unc, con) = ratio_bound_constrained_from_crb(a, w0, n, rate, sigma).unwrap();
    let diag = ratio_bound(host_tests::paper::INERTIA, w0, n, rate, sigma, true).unwrap();
    let full = ratio_bound(host_tests::paper::INERTIA, w0, n, rate, sigma, false).unwrap();
    let bench = host_tests::crb::bound(a, w0, n, rate, sigma);
    println!("paper scenario, std of a:");
    println!("  crb.rs (a free in R^3)         {}", fmt3(unc, 4));
    println!("  crb.rs + rigid-body constraint {}", fmt3(con, 4));
    println!("  crb_tensor, diagonal J / tr    {}", fmt3(diag.std_a, 4));
    println!("  crb_tensor, full J / tr        {}", fmt3(full.std_a, 4));
    for i in 0..3 {
        assert!((unc[i] - bench[i]).abs() < 1e-9 * bench[i]);
        let rel = (diag.std_a[i] - con[i]).abs() / con[i];
        assert!(
            rel < 1e-5,
            "a{}: {} vs {} ({rel:e})",
            i + 1,
            diag.std_a[i],
            con[i]
        );
        assert!(con[i] <= unc[i] * (1.0 + 1e-9));
        assert!(full.std_a[i] >= diag.std_a[i] * (1.0 - 1e-6));
    }
}
