//! Writes any log the tool reads as CSV `t,wx,wy,wz,ax,ay,az,rotor_rad_s` (SI units; rotor
//! speed for a 12-pole motor) to stdout: `cargo run -p inertia --example dump_csv -- LOG`.
use inertia::readers::{read, ReadOptions};
fn main() {
    let Some(path) = std::env::args().nth(1) else {
        eprintln!("usage: dump_csv LOG");
        std::process::exit(2)
    };
    let r = read(std::path::Path::new(&path), &ReadOptions::default()).unwrap_or_else(|e| {
        eprintln!("{e}");
        std::process::exit(1)
    });
    let rot = r.rotor.as_ref().and_then(|x| x.rad_per_sec(Some(12)));
    println!("t,wx,wy,wz,ax,ay,az,rotor_rad_s");
    for i in 0..r.len() {
        let a = r.accel.as_ref().map(|a| a[i]).unwrap_or([f32::NAN; 3]);
        let ro = rot.as_ref().map(|v| v[i]).unwrap_or(f32::NAN);
        let w = r.gyro[i];
        println!(
            "{},{},{},{},{},{},{},{}",
            r.t[i], w[0], w[1], w[2], a[0], a[1], a[2], ro
        );
    }
}
