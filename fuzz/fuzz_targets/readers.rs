//! Fuzz target for the host tool's text readers (`inertia::readers`: phyphox and CSV, format
//! detection), the close-loop segments reader and the close-the-loop analysis on whatever they
//! accept. The input bytes are written to a file (the readers take paths) and read by every
//! reader. Invariants: no panic; an accepted log has at least two samples, finite values and
//! strictly increasing time; a refusal names the file and, when it names a line, a line that
//! exists.
#![no_main]

use std::path::PathBuf;
use std::sync::OnceLock;

use inertia::close_loop::analysis::{analyse, Options};
use inertia::close_loop::load;
use inertia::readers::phyphox::read_segments;
use inertia::readers::{csv::read_csv, detect, phyphox::read_phyphox};
use inertia::{ReadError, ReadOptions, Recording};
use libfuzzer_sys::fuzz_target;

fn path() -> &'static PathBuf {
    static P: OnceLock<PathBuf> = OnceLock::new();
    P.get_or_init(|| {
        let d = std::env::temp_dir().join(format!("fuzz_readers_{}", std::process::id()));
        std::fs::create_dir_all(&d).expect("temp dir");
        d.join("Raw Data.csv")
    })
}

fn check_err(e: &ReadError, lines: usize) {
    let msg = e.to_string();
    assert!(
        msg.contains("Raw Data.csv"),
        "error does not name the file: {msg}"
    );
    if let Some(l) = e.line() {
        assert!(l >= 1 && l <= lines, "line {l} of {lines}: {msg}");
    }
}

fn check_samples(t: &[f64], w: &[[f64; 3]]) {
    assert!(t.len() >= 2 && t.len() == w.len());
    assert!(t.windows(2).all(|x| x[1] > x[0]), "time not increasing");
    assert!(t.iter().all(|x| x.is_finite()));
    assert!(w.iter().flatten().all(|x| x.is_finite()));
}

fn check_recording(r: &Recording) {
    let w: Vec<[f64; 3]> = r.gyro.iter().map(|v| v.map(f64::from)).collect();
    check_samples(&r.t, &w);
}

fuzz_target!(|data: &[u8]| {
    let p = path();
    if std::fs::write(p, data).is_err() {
        return;
    }
    let lines = data.split(|&b| b == b'\n').count();
    for r in [read_csv(p, &ReadOptions::default()), read_phyphox(p)] {
        match r {
            Ok(rec) => check_recording(&rec),
            Err(e) => check_err(&e, lines),
        }
    }
    match read_segments(p) {
        Ok(s) => assert!(s.iter().all(|s| s.start.is_finite() && s.end > s.start)),
        Err(e) => check_err(&e, lines),
    }
    if let Err(e) = detect(p) {
        check_err(&e, lines);
    }
    // The close-loop's loader checks units and segments on top of the readers: its errors are
    // messages (no line to check), but it must not panic.
    if let Ok((log, _)) = load(p, None, None, &ReadOptions::default()) {
        check_samples(&log.t, &log.omega);
        // The analysis must not panic on anything the loader accepts (errors are fine).
        if log.t.len() <= 4096 {
            let _ = analyse(&log, &Options::default());
        }
    }
});
