//! Not a test: the dump `scripts/check-blackbox-reader.sh` compares with a second, independent
//! blackbox decoder. Run as
//! `INERTIA_DUMP_LOG=file INERTIA_DUMP_FRAMES=50 cargo test -p inertia --test readers_dump -- --ignored --nocapture`;
//! prints one line per sample, `DUMP time_us gx gy gz ax ay az erpm_field`, in the log's own
//! units (the reader's SI values turned back into counts), for the first frames.

use std::path::Path;

use inertia::readers::blackbox::{DEFAULT_ACC_1G, ERPM_LOG_FACTOR, G, GYRO_LSB_PER_DEG_S};
use inertia::readers::{read, ReadOptions};
use inertia::RotorSpeed;

#[test]
#[ignore = "a dump for scripts/check-blackbox-reader.sh"]
fn dump_blackbox() {
    let Ok(path) = std::env::var("INERTIA_DUMP_LOG") else {
        eprintln!("INERTIA_DUMP_LOG not set");
        return;
    };
    let frames: usize = std::env::var("INERTIA_DUMP_FRAMES")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(50);
    let r = read(Path::new(&path), &ReadOptions::default()).unwrap_or_else(|e| panic!("{e}"));
    let kw = (1.0 / GYRO_LSB_PER_DEG_S).to_radians();
    let ka = G / DEFAULT_ACC_1G;
    let acc = r.accel.as_ref().expect("accel");
    let Some(RotorSpeed::Erpm(erpm)) = &r.rotor else {
        panic!("no eRPM");
    };
    for i in 0..frames.min(r.len()) {
        let g = r.gyro[i].map(|v| (f64::from(v) / kw).round() as i64);
        let a = acc[i].map(|v| (f64::from(v) / ka).round() as i64);
        println!(
            "DUMP {} {} {} {} {} {} {} {}",
            (r.t[i] * 1e6).round() as i64,
            g[0],
            g[1],
            g[2],
            a[0],
            a[1],
            a[2],
            (erpm[i] / ERPM_LOG_FACTOR).round() as i64
        );
    }
}
