//! The tensor fit with and without multiple shooting ((F11) of `identifier_core::tensor_fit`)
//! on simulated thrown boards with what the torque-free model lacks: air drag on a plate, a
//! flywheel's bearing (air) drag, and vibration lines at the flywheel's speed and at 13 times
//! it folded by the logging rate, as the real thrown-FC logs show. Each seed's whole gated log
//! (bench, hand, free flight, catch) goes through `FlightPipeline` twice, multiple shooting on
//! and off; prints per scenario the RMS relative Frobenius error, the RMS of the diagonal and
//! off-diagonal entries' errors over their reported standard deviations, and the statuses.
//!
//! Usage: `cargo run --release -p host-tests --bin shooting-bench [-- SEEDS]` (16 by default).
//! A benchmark: it asserts nothing.
use host_tests::throw_sim::{board_throw_config, simulate, SimThrow, ThrowConfig};
use identifier_core::{FlightPipeline, PipelineSettings, Status, TensorEstimate};

/// One scenario: its name and what it changes in the simulated throw.
struct Scenario {
    name: &'static str,
    about: &'static str,
    change: fn(&mut ThrowConfig),
    /// Gyro vibration amplitude, rad/s, at the flywheel's speed and its 13th harmonic.
    vibration: f64,
}

const SCENARIOS: [Scenario; 4] = [
    Scenario {
        name: "clean",
        about: "the model's own: white noise, logged resolution",
        change: |_| {},
        vibration: 0.0,
    },
    Scenario {
        name: "plate-drag",
        about: "air drag on the tumbling body, tau_k = -c |w| w_k, c = 2e-6 kg m^2",
        change: |c| c.aero_drag = [2e-6; 3],
        vibration: 0.0,
    },
    Scenario {
        name: "bearing-drag",
        about: "air drag on the spinning flywheel, tau = -c |h| h, c = 100 /(kg m^2)",
        change: |c| c.rotor_drag = 100.0,
        vibration: 0.0,
    },
    Scenario {
        name: "vibration",
        about: "gyro lines at the flywheel's speed and 13x it (folded), 0.05 rad/s each",
        change: |_| {},
        vibration: 0.05,
    },
];

/// Adds the flywheel's vibration lines to the logged gyro: a line at the flywheel's angle
/// and one at 13 times it (sampled at the log's rate, so folded), each axis its own phase.
fn vibrate(sim: &mut SimThrow, amplitude: f64) {
    if amplitude == 0.0 {
        return;
    }
    let mut angle = 0.0f64;
    for k in 0..sim.gyro.len() {
        if k > 0 {
            angle += f64::from(sim.rotor_rad_s[k]) * (sim.t[k] - sim.t[k - 1]);
        }
        for (i, w) in sim.gyro[k].iter_mut().enumerate() {
            let p = 2.1 * i as f64;
            let v = amplitude * ((angle + p).sin() + (13.0 * angle + 2.0 * p).sin());
            *w += v as f32;
        }
    }
}

/// The gated log through the pipeline, multiple shooting on or off.
fn run(cfg: &ThrowConfig, sim: &SimThrow, shooting: bool) -> TensorEstimate {
    let settings = PipelineSettings::for_rate(cfg.rate_hz as f32, cfg.gyro.noise_std as f32)
        .with_full_scale(34.9);
    let mut p = FlightPipeline::new(settings, true)
        .expect("valid settings")
        .with_multiple_shooting(shooting);
    let j_r = cfg.rotor.inertia as f32;
    let axis = cfg.rotor.unit_axis().map(|x| x as f32);
    for ((&w, &f), &speed) in sim.gyro.iter().zip(&sim.accel).zip(&sim.rotor_rad_s) {
        p.step(w, f, axis.map(|a| a * j_r * speed), sim.dt() as f32);
    }
    p.end_stretch();
    p.estimate()
}

/// Accumulated figures of one fit over the seeds.
#[derive(Default)]
struct Tally {
    frob2: f64,
    diag_z2: f64,
    off_z2: f64,
    n: usize,
    converged: usize,
    mismatch: usize,
}

impl Tally {
    fn add(&mut self, e: &TensorEstimate, truth: &[[f64; 3]; 3]) {
        let (Some(t), Some(s)) = (e.tensor, e.tensor_std) else {
            return;
        };
        let (mut d, mut n) = (0.0, 0.0);
        for r in 0..3 {
            for c in 0..3 {
                let err = f64::from(t[r][c]) - truth[r][c];
                d += err * err;
                n += truth[r][c] * truth[r][c];
                if c >= r {
                    let z2 = (err / f64::from(s[r][c])).powi(2);
                    if r == c {
                        self.diag_z2 += z2;
                    } else {
                        self.off_z2 += z2;
                    }
                }
            }
        }
        self.frob2 += d / n;
        self.n += 1;
        self.converged += usize::from(e.status == Status::Converged);
        self.mismatch += usize::from(e.status == Status::ModelMismatch);
    }

    fn row(&self) -> String {
        let n = self.n.max(1) as f64;
        format!(
            "{:.2} % | {:.2} | {:.2} | {}/{} Converged, {} ModelMismatch",
            100.0 * (self.frob2 / n).sqrt(),
            (self.diag_z2 / (3.0 * n)).sqrt(),
            (self.off_z2 / (3.0 * n)).sqrt(),
            self.converged,
            self.n,
            self.mismatch
        )
    }
}

fn main() {
    let seeds: u64 = std::env::args()
        .nth(1)
        .and_then(|s| s.parse().ok())
        .unwrap_or(16);
    println!("simulated board throws (board_throw_config), {seeds} seeds per scenario");
    println!(
        "| scenario | fit | RMS Frobenius error | RMS(error/std) diagonal | RMS(error/std) products | statuses |"
    );
    println!("|---|---|---|---|---|---|");
    for sc in &SCENARIOS {
        let (mut on, mut off) = (Tally::default(), Tally::default());
        for seed in 1..=seeds {
            let mut cfg = board_throw_config(seed);
            (sc.change)(&mut cfg);
            let mut sim = simulate(&cfg);
            vibrate(&mut sim, sc.vibration);
            on.add(&run(&cfg, &sim, true), &cfg.inertia);
            off.add(&run(&cfg, &sim, false), &cfg.inertia);
        }
        println!(
            "| {} ({}) | single trajectory | {} |",
            sc.name,
            sc.about,
            off.row()
        );
        println!("| {} | multiple shooting | {} |", sc.name, on.row());
    }
}
