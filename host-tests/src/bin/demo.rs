//! Host-only demonstration: the identifier on a simulated spinning body with a noisy gyro,
//! printing the estimate converging at 2 Hz. The firmware under QEMU runs the same core.
//!
//! Usage: `cargo run --release -p host-tests --bin demo`.

use host_tests::gyro::GyroModel;
use host_tests::{paper, replay};
use identifier_core::Settings;

fn main() {
    let body = paper::body();
    let a = body.a();
    let tr = body.simulate(paper::OMEGA0, 20.0, 1000.0, 4);
    let meas = GyroModel::noisy(2e-3, 1).measure(&tr);
    let run = replay::run(Settings::with_lambda(3.0), &tr.t, &meas);
    println!("true a = ({:.4}, {:.4}, {:.4})", a[0], a[1], a[2]);
    for (t, e) in run.t.iter().zip(&run.estimates).step_by(500) {
        let r = e.ratios();
        println!(
            "t={t:5.1} s a=({:+.4}, {:+.4}, {:+.4}) A2/A1={:.4} A3/A1={:.4} consistency={:+.1e} {:?} {:?}",
            e.a[0],
            e.a[1],
            e.a[2],
            r.map_or(f32::NAN, |r| r.a2_over_a1),
            r.map_or(f32::NAN, |r| r.a3_over_a1),
            e.consistency(),
            e.status,
            e.convergence,
        );
    }
    println!("{:?}", run.identifier.counters());
}
