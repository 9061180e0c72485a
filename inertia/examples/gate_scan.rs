//! Runs the shared pipeline over a log and prints the gate's windows and the result:
//! `cargo run -p inertia --example gate_scan -- LOG`.
use identifier_core::{FlightPipeline, PipelineSettings};
use inertia::readers::{read, ReadOptions};
fn main() {
    let path = std::env::args().nth(1).expect("LOG");
    let verbose = std::env::args().nth(2).is_some();
    let r = read(std::path::Path::new(&path), &ReadOptions::default()).expect("read");
    let rate = ((r.len() - 1) as f64 / (r.t[r.len() - 1] - r.t[0])) as f32;
    let rot = r
        .rotor
        .as_ref()
        .and_then(|x| x.rad_per_sec(Some(12)))
        .unwrap();
    let acc = r.accel.as_ref().unwrap();
    let mut p = FlightPipeline::new(PipelineSettings::for_rate(rate, 2e-3), true).unwrap();
    let mut fed = Vec::new();
    let mut last_free = false;
    for i in 0..r.len() {
        let dt = if i == 0 {
            1.0 / rate
        } else {
            (r.t[i] - r.t[i - 1]) as f32
        };
        let sgn: f32 = std::env::var("HS")
            .ok()
            .and_then(|s| s.parse().ok())
            .unwrap_or(-1.0);
        let dl: usize = std::env::var("RD")
            .ok()
            .and_then(|s| s.parse().ok())
            .unwrap_or(0);
        let ri = if dl >= 0 {
            (i + dl).min(r.len() - 1)
        } else {
            i
        };
        let h = [0.0, 0.0, sgn * 1.689e-6 * rot[ri]];
        if let Some(e) = p.step(r.gyro[i], acc[i], h, dt) {
            if e.fed.is_some() {
                fed.push(e.sample.index);
            }
        }
        let free = p.in_free_flight();
        if verbose && free != last_free {
            println!("t={:.3} free={free} fit={:?}", r.t[i], p.gate_fit());
        }
        last_free = free;
    }
    let est = p.estimate();
    let (a, b) = (
        fed.first().copied().unwrap_or(0) as usize,
        fed.last().copied().unwrap_or(0) as usize,
    );
    println!(
        "{}: end {:.3}, fed {} samples t {:.3}..{:.3}, throws {}, bias {:?}\n  status {:?} model {:?} resid {:.1} exc {:.0}\n  J {:?}\n  std {:?}",
        path, r.t[r.len() - 1], fed.len(), r.t[a], r.t[b], p.throws(), p.bias(), est.status, est.model, est.residual_ratio, est.excitation, est.tensor, est.tensor_std
    );
}
