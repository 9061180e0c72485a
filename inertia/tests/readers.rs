//! The log readers on the measured data in `../shared/data` (skipped with a note when it is
//! absent), on synthetic files of every format, and on truncated and garbage input (an error
//! or a shorter recording, never a panic).

use std::path::{Path, PathBuf};

use inertia::readers::phyphox::{read_segments, segments_file};
use inertia::readers::{detect, read, Format, GyroUnit, ReadOptions, TimeUnit};
use inertia::{Recording, RotorSpeed};

use log_writers::ulog::{add_logged, header, msg};

fn shared(sub: &str) -> Option<PathBuf> {
    let p = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../shared/data")
        .join(sub);
    if p.is_dir() {
        Some(p)
    } else {
        eprintln!("note: {} absent, test skipped", p.display());
        None
    }
}

fn tmp_dir() -> PathBuf {
    let d = std::env::temp_dir().join(format!("inertia_readers_{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn tmp(name: &str, bytes: &[u8]) -> PathBuf {
    let p = tmp_dir().join(name);
    std::fs::write(&p, bytes).unwrap();
    p
}

fn thrown_logs() -> Vec<PathBuf> {
    let Some(root) = shared("thrown-fc") else {
        return Vec::new();
    };
    let mut out = Vec::new();
    for sub in ["device_only", "proof_body"] {
        let mut v: Vec<PathBuf> = std::fs::read_dir(root.join(sub))
            .unwrap()
            .map(|e| e.unwrap().path())
            .filter(|p| p.extension().is_some_and(|e| e == "BFL"))
            .collect();
        v.sort();
        out.extend(v);
    }
    assert_eq!(out.len(), 10, "{out:?}");
    out
}

fn median_dt(r: &Recording) -> f64 {
    let mut dt: Vec<f64> = r.t.windows(2).map(|w| w[1] - w[0]).collect();
    dt.sort_by(f64::total_cmp);
    dt[dt.len() / 2]
}

#[test]
fn thrown_fc_blackbox_logs() {
    for p in thrown_logs() {
        assert_eq!(detect(&p).unwrap(), Format::Blackbox);
        let r = read(&p, &ReadOptions::default()).unwrap_or_else(|e| panic!("{e}"));
        let n = r.len();
        let rate = 1.0 / median_dt(&r);
        let dur = r.t[n - 1] - r.t[0];
        let peak = r
            .gyro
            .iter()
            .flat_map(|w| w.iter())
            .fold(0.0f32, |m, v| m.max(v.abs()));
        // Accelerometer at rest: the first 0.2 s, on the bench.
        let acc = r.accel.as_ref().expect("accSmooth");
        let rest: Vec<f32> =
            r.t.iter()
                .zip(acc)
                .take_while(|(t, _)| **t - r.t[0] < 0.2)
                .map(|(_, a)| (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]).sqrt())
                .collect();
        let g_rest = rest.iter().sum::<f32>() / rest.len() as f32;
        let Some(RotorSpeed::Erpm(erpm)) = &r.rotor else {
            panic!("{}: no eRPM", p.display());
        };
        let erpm_max = erpm.iter().fold(0.0f32, |m, v| m.max(*v));
        println!(
            "{}: {n} samples, {dur:.2} s, {rate:.0} Hz, gyro peak {peak:.2} rad/s, \
             |a| at rest {g_rest:.3} m/s^2, eRPM max {erpm_max:.0}, warnings {:?}",
            p.file_name().unwrap().to_string_lossy(),
            r.warnings
        );
        assert!(n > 5_000, "{n}");
        assert_eq!(erpm.len(), n);
        assert_eq!(acc.len(), n);
        assert!((3_500.0..4_500.0).contains(&rate), "{rate}");
        assert!(peak < 35.0 && peak > 5.0, "{peak}");
        assert!((g_rest - 9.81).abs() < 0.4, "{g_rest}");
        assert!(erpm_max > 10_000.0, "{erpm_max}");
        assert!(r.t.windows(2).all(|w| w[1] > w[0]));
        assert!((r.gyro_full_scale - 34.9066).abs() < 1e-3);
        assert!(r.warnings.iter().any(|w| w.contains("Indiflight")));
        assert!(!r.warnings.iter().any(|w| w.contains("deg/s read as rad/s")));
        if p.ends_with("LOG00119.BFL") {
            // The first P-frame after the I-frame at iteration 128, which blackbox-log 0.4.3
            // alone decodes as (0, 0, 14) counts; orangebox and the corrected reader say
            // (-1, 0, 16).
            let counts = r.gyro[129].map(|v| (f64::from(v).to_degrees() * 16.384).round());
            assert_eq!(counts, [-1.0, 0.0, 16.0]);
        }
    }
}

/// `data` with the value of its first `H key:` header line replaced by `value`.
fn set_header(data: &[u8], key: &str, value: &str) -> Vec<u8> {
    let key = format!("H {key}:");
    let at = data
        .windows(key.len())
        .position(|w| w == key.as_bytes())
        .unwrap();
    let end = at + data[at..].iter().position(|&b| b == b'\n').unwrap();
    let mut out = data[..at].to_vec();
    out.extend_from_slice(format!("{key}{value}\n").as_bytes());
    out.extend_from_slice(&data[end + 1..]);
    out
}

/// Betaflight logs `gyroADC` in deg/s (tenths with `blackbox_high_resolution`), INDIflight in
/// raw counts (16.384 per deg/s), both under `gyro_scale` 1.0: the reader goes by the
/// firmware's name. The same frames under Betaflight's names read as 16.384 (1.6384) times the
/// INDIflight rates; versions `blackbox-log` refuses (4.1, 2025.12) are read too.
#[test]
fn blackbox_gyro_unit_follows_the_firmware() {
    let Some(p) = thrown_logs().into_iter().next() else {
        return;
    };
    let data = std::fs::read(&p).unwrap();
    let indi = read(&p, &ReadOptions::default()).unwrap();
    // These logs say `blackbox_high_resolution:1` (INDIflight writes it, and still logs counts).
    for (revision, high_resolution, factor) in [
        ("Betaflight 4.4.2 (abc) STM32F405", "0", 16.384),
        ("Betaflight 2025.12.1 (abc) STM32H743", "0", 16.384),
        ("Betaflight 4.1.0 (abc) STM32F405", "0", 16.384),
        ("INAV 7.1.0 (abc) MATEKF405", "0", 16.384),
        ("Betaflight 4.5.1 (abc) STM32F7X2", "1", 1.6384),
        ("Rotorflight 2.1.0 (abc) STM32F7X2", "0", 16.384),
    ] {
        let edited = set_header(&data, "Firmware revision", revision);
        let edited = set_header(&edited, "blackbox_high_resolution", high_resolution);
        // Under Betaflight's name the header's 100 Hz low-pass would be read as the logged
        // gyro's filter and its `acc_lpf_hz` as the accelerometer's (below); switched off
        // here, the rates must differ by the unit alone.
        let edited = set_header(&edited, "gyro_lpf1_static_hz", "0");
        let edited = set_header(&edited, "acc_lpf_hz", "0");
        let file = tmp("revision.BFL", &edited);
        let r = read(&file, &ReadOptions::default()).unwrap_or_else(|e| panic!("{revision}: {e}"));
        assert_eq!(r.len(), indi.len(), "{revision}");
        for (a, b) in r.gyro.iter().zip(&indi.gyro).step_by(97) {
            for k in 0..3 {
                let want = b[k] * factor;
                assert!(
                    (a[k] - want).abs() <= 1e-5 * want.abs().max(1.0),
                    "{revision}: {a:?} {b:?}"
                );
            }
        }
        assert!(
            r.warnings
                .iter()
                .any(|w| w.contains("deg/s (") || w.contains("tenths of deg/s")),
            "{revision}: {:?}",
            r.warnings
        );
        assert!(
            r.warnings.iter().all(|w| !w.contains("raw counts")),
            "{:?}",
            r.warnings
        );
    }
    // With the header's 100 Hz first-order low-pass read as Betaflight's gyro filter and its
    // `acc_lpf_hz` (5000: 50 Hz) as Betaflight 4.4's accelerometer PT2: each frame's rate is
    // the rate read the gyro filter's delay later (its time constant: Betaflight's discrete
    // stage, gain `x / (1 + x)` with `x = 2 pi fc dt`, has a mean delay of `1/x` loops), its
    // specific force the PT2's delay later (two stages at 50 Hz times 1.5538), both
    // interpolated between the frames around them; the last frames, with nothing that late,
    // are dropped; the times and the rotor stay.
    let edited = set_header(
        &data,
        "Firmware revision",
        "Betaflight 4.4.2 (abc) STM32F405",
    );
    let edited = set_header(&edited, "blackbox_high_resolution", "0");
    let file = tmp("filtered.BFL", &edited);
    let r = read(&file, &ReadOptions::default()).unwrap();
    let note = r
        .warnings
        .iter()
        .find(|w| w.contains("filtered gyro"))
        .expect("filter note");
    assert!(note.contains("PT1 100 Hz"), "{note}");
    assert!(
        r.warnings
            .iter()
            .any(|w| w.contains("low-passed accelerometer")),
        "{:?}",
        r.warnings
    );
    let tau = 1.0 / (2.0 * std::f64::consts::PI * 100.0);
    let tau_acc = 1.0 / (2.0 * std::f64::consts::PI * 50.0 / (2f64.sqrt() - 1.0).sqrt());
    let (dg, da) = (tau, 2.0 * tau_acc);
    let last = indi.t[indi.len() - 1];
    let dropped = indi.t.iter().filter(|&&t| t + dg.max(da) > last).count();
    assert_eq!(r.len(), indi.len() - dropped, "{note}");
    assert_eq!(r.t[..], indi.t[..r.len()]);
    let interp = |x: &[[f32; 3]], when: f64| -> [f32; 3] {
        let j = indi.t.partition_point(|&t| t <= when) - 1;
        let f = ((when - indi.t[j]) / (indi.t[j + 1] - indi.t[j])) as f32;
        [0, 1, 2].map(|k| x[j][k] + f * (x[j + 1][k] - x[j][k]))
    };
    let (acc, acc_indi) = (r.accel.as_ref().unwrap(), indi.accel.as_ref().unwrap());
    for i in (0..r.len()).step_by(101) {
        let g = interp(&indi.gyro, indi.t[i] + dg).map(|v| 16.384 * v);
        let a = interp(acc_indi, indi.t[i] + da);
        for k in 0..3 {
            assert!(
                (r.gyro[i][k] - g[k]).abs() <= 2e-3 * g[k].abs().max(1.0),
                "{i}: {:?} {g:?}",
                r.gyro[i]
            );
            assert!(
                (acc[i][k] - a[k]).abs() <= 2e-3 * a[k].abs().max(1.0),
                "{i}: {:?} {a:?}",
                acc[i]
            );
        }
    }
    // An unknown fork: raw counts, as INDIflight, with a warning that says what if not.
    let edited = set_header(&data, "Firmware revision", "Someflight 1.0.0 (x) F4");
    let file = tmp("revision.BFL", &edited);
    let r = read(&file, &ReadOptions::default()).unwrap();
    assert_eq!(r.gyro, indi.gyro);
    assert!(
        r.warnings.iter().any(|w| w.contains("16.4x too small")),
        "{:?}",
        r.warnings
    );
}

#[test]
fn thrown_fc_truncated_and_damaged_never_panic() {
    let Some(p) = thrown_logs().into_iter().next() else {
        return;
    };
    let bytes = std::fs::read(&p).unwrap();
    let full = read(&p, &ReadOptions::default()).unwrap().len();
    // Cut inside the header: an error naming the file.
    for cut in [10, 200, 2_000] {
        let q = tmp("cut_header.BFL", &bytes[..cut]);
        match read(&q, &ReadOptions::default()) {
            Err(e) => assert!(e.to_string().contains("cut_header.BFL"), "{e}"),
            Ok(r) => panic!("cut at {cut}: read {} samples", r.len()),
        }
    }
    // Cut inside the data: the frames before the cut.
    let q = tmp("cut_data.BFL", &bytes[..bytes.len() / 2]);
    let r = read(&q, &ReadOptions::default()).unwrap();
    assert!(
        r.len() > full / 3 && r.len() < full,
        "{} of {full}",
        r.len()
    );
    // Garbage in the data section: whatever comes out, no panic, and time still increases.
    let mut damaged = bytes.clone();
    let mut x = 12345u32;
    for b in damaged[bytes.len() / 3..].iter_mut().step_by(97) {
        x = x.wrapping_mul(1_103_515_245).wrapping_add(12_345);
        *b = (x >> 16) as u8;
    }
    let q = tmp("damaged.BFL", &damaged);
    match read(&q, &ReadOptions::default()) {
        Ok(r) => assert!(r.t.windows(2).all(|w| w[1] > w[0])),
        Err(e) => println!("damaged log: {e}"),
    }
}

#[test]
fn blackbox_garbage_is_an_error() {
    let mut g = b"H Product:Blackbox flight data recorder by Nicholas Sherlock\n".to_vec();
    g.extend((0..5000u32).map(|i| (i.wrapping_mul(2_654_435_761) >> 13) as u8));
    let p = tmp("garbage.bbl", &g);
    assert_eq!(detect(&p).unwrap(), Format::Blackbox);
    let e = read(&p, &ReadOptions::default()).unwrap_err();
    assert!(e.to_string().contains("garbage.bbl"), "{e}");
    let p = tmp(
        "just_marker.bbl",
        b"H Product:Blackbox flight data recorder",
    );
    assert!(read(&p, &ReadOptions::default()).is_err());
}

#[test]
fn racquet_phyphox_exports() {
    let Some(root) = shared("racquet") else {
        return;
    };
    let mut dirs = Vec::new();
    for round in std::fs::read_dir(&root).unwrap() {
        let round = round.unwrap().path();
        if round.is_dir() {
            for d in std::fs::read_dir(&round).unwrap() {
                dirs.push(d.unwrap().path());
            }
        }
    }
    dirs.sort();
    assert_eq!(dirs.len(), 3, "{dirs:?}");
    for d in dirs {
        assert_eq!(detect(&d).unwrap(), Format::Phyphox);
        let r = read(&d, &ReadOptions::default()).unwrap_or_else(|e| panic!("{e}"));
        // The csv file itself reads the same.
        let f = read(&d.join("Raw Data.csv"), &ReadOptions::default()).unwrap();
        assert_eq!(f.t, r.t);
        let dt = median_dt(&r);
        let peak = r
            .gyro
            .iter()
            .map(|w| (w[0] * w[0] + w[1] * w[1] + w[2] * w[2]).sqrt())
            .fold(0.0f32, f32::max);
        let segs = read_segments(&segments_file(&d).unwrap()).unwrap();
        println!(
            "{}: {} samples, dt {dt:.4} s, |w| peak {peak:.1} rad/s, {} kept segments, warnings {:?}",
            d.display(),
            r.len(),
            segs.len(),
            r.warnings
        );
        assert!(r.len() > 1_000);
        assert!((dt - 0.01002).abs() < 0.0005, "{dt}");
        assert!(peak > 10.0 && peak < 50.0, "{peak}");
        assert!(r.accel.is_none() && r.rotor.is_none());
        assert!(!segs.is_empty());
        for s in &segs {
            assert!(s.start >= r.t[0] && s.end <= r.t[r.len() - 1], "{s:?}");
        }
    }
}

#[test]
fn phyphox_truncated_and_garbage() {
    let head = "\"Time (s)\",\"Gyroscope x (rad/s)\",\"Gyroscope y (rad/s)\",\"Gyroscope z (rad/s)\",\"Absolute (rad/s)\"\n";
    let ok = format!("{head}0.0,1,2,3,4\n0.01,1,2,3,4\n0.02,1,2,3,4\n");
    let dir = tmp_dir().join("phyphox_export");
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(dir.join("Raw Data.csv"), &ok).unwrap();
    assert_eq!(read(&dir, &ReadOptions::default()).unwrap().len(), 3);
    // Truncated in the middle of the last row, at every byte.
    for cut in head.len()..ok.len() - 1 {
        let p = tmp("phy_cut.csv", &ok.as_bytes()[..cut]);
        if let Err(e) = read(&p, &ReadOptions::default()) {
            assert!(e.to_string().contains("phy_cut.csv"), "{e}");
        }
    }
    let cases: [(&str, String, Option<usize>); 4] = [
        (
            "phy_short.csv",
            format!("{head}0.0,1,2,3\n0.01,1,2\n"),
            Some(3),
        ),
        (
            "phy_nan.csv",
            format!("{head}0.0,1,2,3\n0.01,1,inf,3\n"),
            Some(3),
        ),
        (
            "phy_back.csv",
            format!("{head}0.0,1,2,3\n0.02,1,2,3\n0.01,1,2,3\n"),
            Some(4),
        ),
        ("phy_one.csv", format!("{head}0.0,1,2,3\n"), None),
    ];
    for (name, text, line) in cases {
        let p = tmp(name, text.as_bytes());
        let e = read(&p, &ReadOptions::default()).unwrap_err();
        assert_eq!(e.line(), line, "{e}");
        assert!(e.to_string().contains(name), "{e}");
    }
    let p = tmp("phy_bin.csv", b"\"Time (s)\",\xff\xfe\x00\x01\n");
    assert!(read(&p, &ReadOptions::default()).is_err());
    let empty = tmp_dir().join("empty_dir");
    std::fs::create_dir_all(&empty).unwrap();
    assert!(read(&empty, &ReadOptions::default()).is_err());
}

#[test]
fn csv_units_converted() {
    // 10 ms steps, 180 deg/s about z, accel and eRPM.
    let mut s = String::from("time,gx,gy,gz,ax,ay,az,erpm\n");
    for i in 0..50 {
        s += &format!("{},0,90,180,0,0,9.81,{}\n", i * 10, 1000 * i);
    }
    let p = tmp("units.csv", s.as_bytes());
    assert_eq!(detect(&p).unwrap(), Format::Csv);
    let o = ReadOptions {
        gyro_unit: Some(GyroUnit::DegPerSec),
        time_unit: Some(TimeUnit::Ms),
        ..ReadOptions::default()
    };
    let r = read(&p, &o).unwrap();
    assert_eq!(r.len(), 50);
    assert!((r.t[1] - 0.01).abs() < 1e-12 && (r.t[49] - 0.49).abs() < 1e-12);
    assert!((r.gyro[3][2] - std::f32::consts::PI).abs() < 1e-6);
    assert!((r.gyro[3][1] - std::f32::consts::FRAC_PI_2).abs() < 1e-6);
    assert_eq!(r.accel.as_ref().unwrap()[7], [0.0, 0.0, 9.81]);
    assert_eq!(r.rotor.as_ref().unwrap().len(), 50);
    assert!(r.warnings.is_empty(), "{:?}", r.warnings);

    // Read with the defaults, the same file warns about both units.
    let r = read(&p, &ReadOptions::default()).unwrap();
    assert!(
        r.warnings.iter().any(|w| w.contains("deg/s")),
        "{:?}",
        r.warnings
    );
    assert!(
        r.warnings.iter().any(|w| w.contains("time unit")),
        "{:?}",
        r.warnings
    );

    // microseconds, rad/s, rotor in rad/s.
    let p = tmp(
        "us.csv",
        b"t,wx,wy,wz,rotor_rad_s\n0,0.1,0.2,0.3,100\n2500,0.1,0.2,0.3,101\n5000,0.1,0.2,0.3,102\n",
    );
    let o = ReadOptions {
        time_unit: Some(TimeUnit::Us),
        ..ReadOptions::default()
    };
    let r = read(&p, &o).unwrap();
    assert_eq!(r.t, vec![0.0, 0.0025, 0.005]);
    assert_eq!(
        r.rotor,
        Some(RotorSpeed::RadPerSec(vec![100.0, 101.0, 102.0]))
    );

    // Other common names of the same columns.
    let p = tmp(
        "aliases.csv",
        b"time_s,gyro_x,gyro_y,gyro_z,acc_x,acc_y,acc_z\n0,0.1,0.2,0.3,0,0,9.8\n0.01,0.1,0.2,0.3,0,0,9.8\n",
    );
    let r = read(&p, &ReadOptions::default()).unwrap();
    assert_eq!(r.t, vec![0.0, 0.01]);
    assert_eq!(r.gyro[1], [0.1, 0.2, 0.3]);
    assert_eq!(r.accel.as_ref().unwrap()[0], [0.0, 0.0, 9.8]);

    // The rotor in mechanical rpm (both row paths: plain and with a `;` separator).
    for (name, text) in [
        (
            "rpm.csv",
            "t,wx,wy,wz,rotor_rpm\n0,0.1,0.2,0.3,600\n0.01,0.1,0.2,0.3,-1200\n",
        ),
        (
            "rpm-semi.csv",
            "t;wx;wy;wz;rotor_rpm\n0;0,1;0,2;0,3;600\n0,01;0,1;0,2;0,3;-1200\n",
        ),
    ] {
        let r = read(&tmp(name, text.as_bytes()), &ReadOptions::default()).unwrap();
        let Some(RotorSpeed::RadPerSec(v)) = &r.rotor else {
            panic!("{name}: {:?}", r.rotor);
        };
        let want = [20.0 * std::f32::consts::PI, -40.0 * std::f32::consts::PI];
        for (a, b) in v.iter().zip(want) {
            assert!((a - b).abs() < 1e-4, "{name}: {v:?}");
        }
    }
}

#[test]
fn csv_truncated_and_garbage() {
    let ok = "t,wx,wy,wz\n0,1,2,3\n0.01,1,2,3\n0.02,1,2,3\n";
    for cut in 0..ok.len() {
        let p = tmp("csv_cut.csv", &ok.as_bytes()[..cut]);
        if let Err(e) = read(&p, &ReadOptions::default()) {
            assert!(e.to_string().contains("csv_cut.csv"), "{e}");
        }
    }
    let cases: [(&str, &[u8], Option<usize>); 6] = [
        ("c_nan.csv", b"t,wx,wy,wz\n0,1,2,3\n0.01,NaN,2,3\n", Some(3)),
        (
            "c_big.csv",
            b"t,wx,wy,wz\n0,1,2,3\n0.01,1e300,2,3\n",
            Some(3),
        ),
        (
            "c_text.csv",
            b"t,wx,wy,wz\n0,1,2,3\n0.01,abc,2,3\n",
            Some(3),
        ),
        ("c_head.csv", b"time,a,b,c\n0,1,2,3\n", Some(1)),
        (
            "c_utf.csv",
            b"t,wx,wy,wz\n0,1,2,3\n0.01,\xff,2,3\n",
            Some(3),
        ),
        ("c_bin.csv", b"\x00\x01\x02\x03garbage", Some(1)),
    ];
    for (name, bytes, line) in cases {
        let p = tmp(name, bytes);
        let e = read(&p, &ReadOptions::default()).unwrap_err();
        assert_eq!(e.line(), line, "{name}: {e}");
        assert!(e.to_string().contains(name), "{e}");
    }
    let e = read(Path::new("/nonexistent/x.csv"), &ReadOptions::default()).unwrap_err();
    assert!(e.to_string().contains("x.csv"), "{e}");
}

// ---- ULog: a tiny file written by hand in the ULog binary format ----

/// A ULog with `n` sensor_combined samples at 1 kHz (gyro `(0.1 i, -0.2, 3)`, accel
/// `(0, 0, -9.8)`) and esc_status at 100 Hz (rpm `1000 + 10 j`), starting 2 ms after the
/// gyro.
fn ulog(n: usize, nan_at: Option<usize>) -> Vec<u8> {
    ulog_clipped(n, nan_at, None)
}

/// [`ulog`] with `gyro_clipping` logged: bit 2 (z) set at sample `clip_at`.
fn ulog_clipped(n: usize, nan_at: Option<usize>, clip_at: Option<usize>) -> Vec<u8> {
    let mut f = header(1_000);
    msg(
        &mut f,
        b'F',
        b"sensor_combined:uint64_t timestamp;float[3] gyro_rad;uint32_t gyro_integral_dt;float[3] accelerometer_m_s2;uint8_t gyro_clipping;",
    );
    msg(
        &mut f,
        b'F',
        b"esc_report:uint64_t timestamp;int32_t esc_rpm;float esc_voltage;",
    );
    msg(
        &mut f,
        b'F',
        b"esc_status:uint64_t timestamp;uint8_t esc_count;esc_report[2] esc;",
    );
    add_logged(&mut f, 0, "sensor_combined");
    add_logged(&mut f, 1, "esc_status");
    for i in 0..n {
        let t = 10_000u64 + 1_000 * i as u64;
        if i % 10 == 2 {
            let j = (i / 10) as i32;
            let mut d = 1u16.to_le_bytes().to_vec();
            d.extend_from_slice(&t.to_le_bytes());
            d.push(2);
            for e in 0..2 {
                d.extend_from_slice(&t.to_le_bytes());
                d.extend_from_slice(&(1000 + 10 * j + e).to_le_bytes());
                d.extend_from_slice(&12.0f32.to_le_bytes());
            }
            msg(&mut f, b'D', &d);
        }
        let mut d = 0u16.to_le_bytes().to_vec();
        d.extend_from_slice(&t.to_le_bytes());
        let gx = if nan_at == Some(i) {
            f32::NAN
        } else {
            0.1 * i as f32
        };
        for v in [gx, -0.2, 3.0] {
            d.extend_from_slice(&v.to_le_bytes());
        }
        d.extend_from_slice(&1000u32.to_le_bytes());
        for v in [0.0f32, 0.0, -9.8] {
            d.extend_from_slice(&v.to_le_bytes());
        }
        d.push(if clip_at == Some(i) { 0b100 } else { 0 });
        msg(&mut f, b'D', &d);
    }
    f
}

#[test]
fn ulog_synthetic() {
    let p = tmp("synthetic.ulg.bin", &ulog(100, None));
    assert_eq!(detect(&p).unwrap(), Format::Ulog);
    let r = read(&p, &ReadOptions::default()).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(r.len(), 100);
    // Each reading is the mean over its 1 ms `gyro_integral_dt`, stamped at its end: the
    // time is the interval's middle, and the whole step is averaged.
    assert!((r.t[0] - 0.0095).abs() < 1e-12 && (r.t[99] - 0.1085).abs() < 1e-12);
    assert_eq!(r.gyro_averaging, 1.0);
    assert!((r.gyro[5][0] - 0.5).abs() < 1e-6);
    assert_eq!(r.gyro[5][1..], [-0.2, 3.0]);
    assert_eq!(r.accel.as_ref().unwrap()[50], [0.0, 0.0, -9.8]);
    let Some(RotorSpeed::RadPerSec(w)) = &r.rotor else {
        panic!("{:?}", r.rotor);
    };
    let k = 2.0 * std::f32::consts::PI / 60.0;
    // Held at the intervals' middles: samples 0 to 2 precede the first esc_status (value held
    // backwards), 3..12 see j = 0, 13..22 see j = 1, ...
    assert!((w[0] - 1000.0 * k).abs() < 1e-3);
    assert!((w[12] - 1000.0 * k).abs() < 1e-3);
    assert!((w[13] - 1010.0 * k).abs() < 1e-3);
    assert!((w[99] - 1090.0 * k).abs() < 1e-3);
    assert!(
        r.warnings.iter().any(|w| w.contains("esc_status starts")),
        "{:?}",
        r.warnings
    );
    // gyro_clipping logged: the full scale is PX4's 2000 deg/s, and the clipped axis of the
    // marked sample reads at it (saturated); the other axes and samples as logged.
    assert!(
        (r.gyro_full_scale - 34.906_586).abs() < 1e-4,
        "{}",
        r.gyro_full_scale
    );
    let p = tmp("clipped.ulg.bin", &ulog_clipped(100, None, Some(40)));
    let c = read(&p, &ReadOptions::default()).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(c.gyro[40][..2], r.gyro[40][..2]);
    assert_eq!(c.gyro[40][2], c.gyro_full_scale);
    assert_eq!(c.gyro[41], r.gyro[41]);
    assert!(
        c.warnings.iter().any(|w| w.contains("1 sample(s) clipped")),
        "{:?}",
        c.warnings
    );
}

#[test]
fn ulog_non_finite_truncated_and_garbage() {
    let p = tmp("nan.ulg", &ulog(30, Some(17)));
    let e = read(&p, &ReadOptions::default()).unwrap_err();
    assert_eq!(e.frame(), Some(17), "{e}");
    assert!(e.to_string().contains("frame 17"), "{e}");

    let full = ulog(40, None);
    for cut in 0..full.len() {
        let p = tmp("cut.ulg", &full[..cut]);
        match read(&p, &ReadOptions::default()) {
            Ok(r) => assert!(r.len() <= 40 && r.len() >= 2),
            Err(e) => assert!(e.to_string().contains("cut.ulg"), "{e}"),
        }
    }
    let mut g = b"ULog\x01\x12\x35\x01".to_vec();
    g.extend((0..3000u32).map(|i| (i.wrapping_mul(2_654_435_761) >> 11) as u8));
    let p = tmp("garbage.ulg", &g);
    assert_eq!(detect(&p).unwrap(), Format::Ulog);
    assert!(read(&p, &ReadOptions::default()).is_err());
    // Damaged bytes inside a valid file: an error or a recording, never a panic.
    for k in (16..full.len()).step_by(7) {
        let mut d = full.clone();
        d[k] ^= 0xA5;
        let p = tmp("flip.ulg", &d);
        let _ = read(&p, &ReadOptions::default());
    }
}

/// A 203-byte ULog found by `scripts/fuzz.sh 90` on which the `px4-ulog` crate panics (an index
/// out of bounds in its message parser): the reader returns an error naming the file, and no
/// panic message reaches the user.
#[test]
fn a_ulog_the_parser_panics_on_is_an_error() {
    let bytes = include_bytes!("data/ulog_parser_panics.bin");
    let p = tmp("ulog_parser_panics.ulg", bytes);
    assert_eq!(detect(&p).unwrap(), Format::Ulog);
    let e = read(&p, &ReadOptions::default()).expect_err("a malformed ULog");
    let msg = e.to_string();
    assert!(
        msg.contains("ulog_parser_panics.ulg") && msg.contains("malformed"),
        "{msg}"
    );
}

/// `read` (the whole-log reading of `close-loop`, `calibrate` and `export-replay`) takes a
/// blackbox log's rotor fields as `source::open` does (`identify`'s reading), and refuses a
/// field the log lacks.
#[test]
fn read_takes_a_blackbox_logs_rotor_fields_as_the_source_does() {
    use log_writers::blackbox::{blackbox, Frame};
    let frames: Vec<Frame> = (0..200u64)
        .map(|i| Frame {
            time_us: 1_000_000 + 125 * i,
            gyro: [100, -50, 30 + i as i64],
            accel: None,
            erpm: Some(20 + i),
        })
        .collect();
    let bytes = blackbox("Betaflight 4.4.2 (abc) STM32F405", &[], &frames);
    let p = tmp("rotor_fields.bbl", &bytes);
    let opts = ReadOptions {
        rotor_columns: vec!["eRPM[0]".into()],
        ..ReadOptions::default()
    };
    let rec = read(&p, &opts).unwrap();
    let src = inertia::source::open(&p, &opts).unwrap();
    let mut streamed = Vec::new();
    src.read_all(
        &mut |s| {
            streamed.push(s.extra.wheels[0]);
            Ok(inertia::source::Flow::Continue)
        },
        &mut |_| {},
    )
    .unwrap();
    assert_eq!(rec.wheels.len(), 1);
    assert_eq!(rec.wheels[0], streamed);
    // True eRPM: the logged eRPM / 100 times 100.
    assert_eq!(rec.wheels[0].first(), Some(&2000.0));
    let opts = ReadOptions {
        rotor_columns: vec!["eRPM[3]".into()],
        ..ReadOptions::default()
    };
    let e = read(&p, &opts).err().unwrap().to_string();
    assert!(e.contains("eRPM[3]"), "{e}");
}
