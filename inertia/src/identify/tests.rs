//! The streaming `identify` against the one that held the whole log ([`super::reference`]):
//! same report, bit for bit, on logs made to reach every path (throws whose bias guess is
//! wrong and are fed again, rotor holds longer than the lookahead, a noise median that needs
//! a second reading, hand-chosen segments in any order), and on the thrown-fc logs when
//! `../shared` is there.

use std::path::{Path, PathBuf};

use super::{identify, identify_source, reference, IdentifyOptions, Quiet, Report, Rotor};
use crate::readers::ReadOptions;

fn tmp(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("inertia_identify_{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d.join(name)
}

/// A log of `throws` board throws at `rate` Hz: still (the k-th lasting `still[k]` s, gyro
/// bias plus noise, gravity), hand (pushed about), free flight (torque-free spin with the
/// flywheel spinning up, the accelerometer reading only noise), catch, held. The rotor
/// channel is a sample-and-hold staircase (a new value every third sample while it changes,
/// constant for seconds otherwise). Gyro noise is not quantised.
fn board_log(path: &Path, rate: f64, still: &[f64], seed: u64) {
    let mut s = seed | 1;
    let mut gauss = move || {
        let mut acc = 0.0;
        for _ in 0..4 {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            acc += (s >> 11) as f64 / (1u64 << 53) as f64;
        }
        (acc - 2.0) * 1.7
    };
    let j = [2.0e-5, 3.0e-5, 4.0e-5];
    let bias = [0.004, -0.002, 0.003];
    let dt = 1.0 / rate;
    let mut out = String::from("t,wx,wy,wz,ax,ay,az,rotor_rad_s\n");
    let mut k = 0u64;
    let mut rotor = 100.0f64;
    let mut held = rotor;
    let mut row = |w: [f64; 3], f: [f64; 3], rotor: f64, gauss: &mut dyn FnMut() -> f64| {
        let t = k as f64 * dt;
        k += 1;
        out.push_str(&format!(
            "{t:.7},{},{},{},{},{},{},{rotor}\n",
            w[0] + bias[0] + 2e-3 * gauss(),
            w[1] + bias[1] + 2e-3 * gauss(),
            w[2] + bias[2] + 2e-3 * gauss(),
            f[0] + 0.05 * gauss(),
            f[1] + 0.05 * gauss(),
            f[2] + 0.05 * gauss()
        ));
    };
    for (n, &still_s) in still.iter().enumerate() {
        for _ in 0..(still_s * rate) as usize {
            row([0.0; 3], [0.0, 0.0, 9.81], held, &mut gauss);
        }
        for i in 0..(0.3 * rate) as usize {
            let p = i as f64 / (0.3 * rate);
            let w = [3.0 * p, -2.0 * p, 5.0 * p];
            row(w, [4.0 * p, 2.0, 9.81 + 6.0 * p], held, &mut gauss);
        }
        // Free flight: Euler's equations with the rotor momentum along -z.
        let mut w = [3.0, -2.0 + 0.1 * n as f64, 5.0];
        let hz = -1.69e-6;
        for i in 0..(0.6 * rate) as usize {
            let r_dot = 400.0;
            rotor += r_dot * dt;
            if i % 3 == 0 {
                held = (rotor * 100.0).round() / 100.0;
            }
            let h = [0.0, 0.0, hz * rotor];
            let l = [j[0] * w[0] + h[0], j[1] * w[1] + h[1], j[2] * w[2] + h[2]];
            let c = [
                w[1] * l[2] - w[2] * l[1],
                w[2] * l[0] - w[0] * l[2],
                w[0] * l[1] - w[1] * l[0],
            ];
            let dh = [0.0, 0.0, hz * r_dot];
            let wd = [0, 1, 2].map(|a| (-c[a] - dh[a]) / j[a]);
            row(w, [0.0; 3], held, &mut gauss);
            w = [0, 1, 2].map(|a| w[a] + wd[a] * dt);
        }
        for i in 0..(0.2 * rate) as usize {
            let p = 1.0 - i as f64 / (0.2 * rate);
            let w2 = w.map(|x| x * p);
            row(w2, [20.0 * p, -5.0, 9.81 + 15.0 * p], held, &mut gauss);
        }
    }
    std::fs::write(path, out).unwrap();
}

fn json(r: &Result<Report, super::IdentifyError>) -> String {
    match r {
        Ok(r) => format!(
            "{}\n{:?}",
            serde_json::to_string_pretty(r).unwrap(),
            r.fed_runs
        ),
        Err(e) => format!("error: {e}"),
    }
}

/// Streaming from the file, streaming from the recording, and the reference agree.
fn same(path: &Path, opts: &IdentifyOptions) -> Report {
    let rec = crate::read(path, &ReadOptions::default()).unwrap();
    let want = reference::identify(&rec, opts);
    let src = crate::source::open(path, &ReadOptions::default()).unwrap();
    let got = identify_source(&*src, opts, &mut Quiet);
    assert_eq!(json(&got), json(&want), "{}", path.display());
    assert_eq!(json(&identify(&rec, opts)), json(&want));
    got.unwrap()
}

fn rotor() -> Option<Rotor> {
    Some(Rotor {
        inertia: 1.69e-6,
        axis: [0.0, 0.0, -1.0],
        poles: None,
    })
}

#[test]
fn streaming_is_the_whole_log_bit_for_bit() {
    // Still phases of growing length: the bias changes at each throw, so the throws begun
    // before the last change are fed again. The last still phase is the longest (3 s at
    // 4 kHz: the rotor holds 12000+ samples, beyond the lookahead).
    let p = tmp("board.csv");
    board_log(&p, 4000.0, &[0.3, 0.5, 0.4, 0.7, 3.0, 0.5], 3);
    let with_rotor = IdentifyOptions {
        rotor: rotor(),
        trace: true,
        ..Default::default()
    };
    let r = same(&p, &with_rotor);
    assert!(r.throws.len() >= 4, "{} throws", r.throws.len());
    let trace = r.trace.unwrap();
    assert_eq!(trace.points.len(), r.log_samples.div_ceil(trace.step));
    same(&p, &IdentifyOptions::default());
    same(
        &p,
        &IdentifyOptions {
            rotor: rotor(),
            rotor_hold: crate::identify::RotorHold::Raw,
            ..Default::default()
        },
    );
    same(
        &p,
        &IdentifyOptions {
            rotor: rotor(),
            noise_std: Some(3e-3),
            ..Default::default()
        },
    );
    // Segments: out of order, touching (the boundary sample in both), one empty, one past
    // the end.
    let t_end = r.log_samples as f64 / 4000.0;
    let segs = vec![
        (1.0, 1.5),
        (0.2, 0.6),
        (0.6, 0.9),
        (0.95, 0.96),
        (2.0, 2.0001),
        (t_end + 1.0, t_end + 2.0),
    ];
    let r = same(
        &p,
        &IdentifyOptions {
            rotor: rotor(),
            segments: Some(segs),
            trace: true,
            ..Default::default()
        },
    );
    assert!(r.warnings.iter().any(|w| w.contains("holds no sample")));
    // 8 kHz (decimation 4), long enough (75000 samples of unquantised noise) that the noise
    // median needs a second reading.
    let p8 = tmp("board8k.csv");
    board_log(&p8, 8000.0, &[0.5, 0.3, 4.0, 0.25], 5);
    same(&p8, &with_rotor);
}

#[test]
fn errors_are_the_same() {
    let p = tmp("short.csv");
    std::fs::write(&p, "t,wx,wy,wz\n0,1,2,3\n0.01,1,2,3\n0.02,1,2,3\n").unwrap();
    same_err(&p, &IdentifyOptions::default());
    let p = tmp("still.csv");
    let mut s = String::from("t,wx,wy,wz,ax,ay,az\n");
    for i in 0..5000 {
        s.push_str(&format!("{},0.001,0,0,0,0,9.81\n", i as f64 * 1e-3));
    }
    std::fs::write(&p, s).unwrap();
    same_err(&p, &IdentifyOptions::default());
    same_err(
        &p,
        &IdentifyOptions {
            rotor: rotor(),
            ..Default::default()
        },
    );
}

fn same_err(path: &Path, opts: &IdentifyOptions) {
    let rec = crate::read(path, &ReadOptions::default()).unwrap();
    let want = reference::identify(&rec, opts);
    assert!(want.is_err());
    let src = crate::source::open(path, &ReadOptions::default()).unwrap();
    assert_eq!(json(&identify_source(&*src, opts, &mut Quiet)), json(&want));
}

#[test]
fn thrown_fc_logs_bit_for_bit() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../shared/data/thrown-fc");
    let Ok(dirs) = std::fs::read_dir(&root) else {
        eprintln!("note: {} absent, test skipped", root.display());
        return;
    };
    let mut logs: Vec<PathBuf> = dirs
        .filter_map(|d| std::fs::read_dir(d.ok()?.path()).ok())
        .flatten()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "BFL"))
        .collect();
    logs.sort();
    let with_rotor = IdentifyOptions {
        rotor: Some(Rotor {
            inertia: 1.689e-6,
            axis: [0.0, 0.0, -1.0],
            poles: Some(14),
        }),
        ..Default::default()
    };
    for p in logs.iter().take(3) {
        same(p, &with_rotor);
        same(p, &IdentifyOptions::default());
    }
}
