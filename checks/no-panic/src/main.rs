//! No-panic proof for identifier-core on the flight target.
//!
//! This program calls every public entry of `identifier-core` on inputs the optimiser cannot
//! see (`black_box`), so no call is folded away, and links for thumbv7em-none-eabihf with the
//! firmware's release options (fat LTO, one codegen unit, `panic = "abort"`).
//!
//! Its panic handler calls a function that exists nowhere. If any panic path (an index out of
//! bounds, an overflow check, an `unwrap`, a division by an integer zero, `unreachable!`...) is
//! still reachable from these entries after optimisation, the handler is kept and the link fails
//! with an undefined reference to `identifier_core_has_a_panic_path`. scripts/check-no-panic.sh
//! also lists the linked symbols and fails on any `panic` among them.
#![no_std]
#![no_main]

use core::fmt::Write;
use core::hint::black_box;

use identifier_core::extended::{columns, consistency_scale, inverse_ratios};
use identifier_core::invariant::{control, phi, phi_of_squares, sign, squares, triple_product};
use identifier_core::{
    consistency, ConvergenceMonitor, ExtendedIdentifier, ExtendedSettings, ExtendedStatus,
    ExtraEffect, GainMatrix, Identifier, InertiaRatios, Refined, RefinedSettings, Settings,
    SignChangeCorrection,
};
use identifier_core::{
    FlightPipeline, FreeFlightGate, GateSettings, PipelineSettings, RatioFit, TensorEstimator,
    TensorFit, TensorSettings,
};

extern "C" {
    /// Deliberately undefined: referencing it makes the link fail.
    fn identifier_core_has_a_panic_path() -> !;
}

#[panic_handler]
fn panic(_: &core::panic::PanicInfo) -> ! {
    // SAFETY: never executed; its only purpose is to make a reachable panic unlinkable.
    unsafe { identifier_core_has_a_panic_path() }
}

/// A `fmt::Write` sink that keeps only a byte count.
struct Sink(usize);

impl Write for Sink {
    fn write_str(&mut self, s: &str) -> core::fmt::Result {
        self.0 = self.0.wrapping_add(s.len());
        Ok(())
    }
}

fn opaque_settings() -> Settings {
    let mut s = black_box(Settings::with_lambda(black_box(3.0)));
    s.gain = black_box(GainMatrix(black_box([
        [-1.0, 0.5, 0.0],
        [0.0, -2.0, 0.1],
        [0.0, 0.0, -3.0],
    ])));
    s.w_min = black_box(1e-3);
    s.full_scale = black_box(34.9);
    s.max_dt = black_box(0.1);
    s.sign_change = if black_box(true) {
        SignChangeCorrection::Enabled
    } else {
        SignChangeCorrection::Disabled
    };
    s.eps = black_box(1e-3);
    s.h = black_box(1.0);
    s.initial_estimate = black_box([0.0; 3]);
    s
}

fn exercise() {
    let s = opaque_settings();
    let _ = black_box(Settings::default());
    let _ = black_box(s.validate());
    let _ = black_box(s.gain.is_hurwitz());
    let _ = black_box(GainMatrix::scalar(black_box(2.0)).rows());

    match Identifier::new(s) {
        Ok(mut id) => {
            for _ in 0..black_box(1000usize) {
                let e = id.step(black_box([1.0, -0.5, 0.25]), black_box(1e-3));
                black_box(e);
                black_box(e.status.integrated());
                black_box(e.status.rejected());
                black_box(e.ratios());
                black_box(e.consistency());
            }
            black_box(id.estimate());
            black_box(id.alpha());
            black_box(id.convergence());
            black_box(id.monitor().span());
            black_box(id.counters());
            black_box(id.settings());
            if black_box(false) {
                id.restart();
            }
            if black_box(false) {
                id.reset();
            }
            black_box(&id);
        }
        Err(e) => {
            // Display of the refusal, as a firmware would log it.
            let mut sink = Sink(0);
            let _ = write!(sink, "{e}");
            black_box(sink.0);
        }
    }

    let w = black_box([0.3, 1.2, -0.7]);
    let a = black_box([0.9, 0.26, -0.94]);
    black_box(triple_product(w));
    black_box(sign(black_box(-0.5)));
    black_box(squares(w));
    black_box(phi(&s.gain, black_box(1.0), w));
    black_box(phi_of_squares(s.gain.rows(), black_box(-1.0), w));
    black_box(control(&s.gain, a, w));
    black_box(consistency(a));
    if let Some(r) = InertiaRatios::from_a(a) {
        black_box(r.to_a());
    }
    let mut m = black_box(ConvergenceMonitor::new());
    black_box(m.observe(a, black_box(1e-3), black_box(1e-3), black_box(1.0)));
    black_box(m.verdict(black_box(1.0)));
    black_box(m.span());
    black_box(ConvergenceMonitor::default());
}

fn exercise_refined() {
    let mut s = black_box(RefinedSettings::new());
    s.block = black_box(32);
    s.end_correction = black_box(true);
    s.full_scale = black_box(34.9);
    black_box(s.is_valid());
    if let Some(mut r) = Refined::new(s) {
        for _ in 0..black_box(1000usize) {
            let e = r.step(black_box([1.0, -0.5, 0.25]), black_box(1e-3));
            black_box(e);
        }
        black_box(r.estimate());
        black_box(r.block_estimate());
        black_box(r.std_per_sigma());
        black_box(r.counters());
        black_box(r.settings());
        black_box(r.convergence());
        if black_box(false) {
            r.restart();
        }
        if black_box(false) {
            r.reset();
        }
        black_box(&r);
    }
}

fn exercise_extended() {
    let effect = |k: u8| match k {
        0 => None,
        1 => Some(ExtraEffect::GyroBias),
        2 => Some(ExtraEffect::BodyTorque),
        3 => Some(ExtraEffect::Damping),
        4 => Some(ExtraEffect::ProductsOfInertia),
        _ => Some(ExtraEffect::RotorMomentum),
    };
    let mut s = ExtendedSettings::new([effect(black_box(1)), effect(black_box(5))]);
    s.scale_correction = black_box(true);
    s.full_scale = black_box(34.9);
    black_box(s.is_valid());
    if let Some(mut x) = ExtendedIdentifier::new(black_box(s)) {
        for _ in 0..black_box(1000usize) {
            black_box(x.step(black_box([1.0, -0.5, 0.25]), black_box(1e-3)));
        }
        black_box(x.settings());
        black_box(x.updates());
        black_box(x.theta());
        black_box(x.variances());
        black_box(x.estimate(black_box(ExtendedStatus::Buffered)));
        if black_box(false) {
            x.restart();
        }
        black_box(&x);
    }
    let a = black_box([0.9, 0.26, -0.94]);
    black_box(columns(&s.effects, a, black_box([0.3, 1.2, -0.7])));
    black_box(inverse_ratios(a));
    black_box(consistency_scale(a));
}

fn exercise_tensor() {
    let mut ps = black_box(PipelineSettings::for_rate(
        black_box(4000.0),
        black_box(2e-3),
    ));
    ps.tensor.full_scale = black_box(34.9);
    black_box(ps.tensor.is_valid());
    black_box(ps.gate.is_valid());
    if let Some(mut p) = FlightPipeline::new(black_box(ps), black_box(true)) {
        for _ in 0..black_box(3000usize) {
            black_box(p.step(
                black_box([1.0, -0.5, 0.25]),
                black_box([0.1, 0.2, 9.8]),
                black_box([0.0, 0.0, -2e-3]),
                black_box(2.5e-4),
            ));
        }
        black_box(p.estimate());
        black_box(p.ratios());
        black_box(p.fed_inputs());
        p.end_stretch();
        black_box(p.gate_fit());
        black_box(p.bias());
        black_box(p.throws());
        black_box(p.in_free_flight());
        black_box(p.estimator().counters());
        black_box(p.trajectory().estimate());
        black_box(&p);
    }
    let mut rf = black_box(RatioFit::<64>::new(
        black_box(34.9),
        black_box(0.1),
        black_box(2e-3),
    ));
    for _ in 0..black_box(1000usize) {
        rf.step(black_box([1.0, -0.5, 0.25]), black_box(1e-3));
    }
    black_box(rf.close());
    black_box(rf.estimate());
    black_box(rf.last_outcome());
    black_box(rf.open_samples());
    if black_box(false) {
        rf.reset();
    }
    black_box(&rf);
    let mut tf = black_box(TensorFit::<32>::new(
        black_box(34.9),
        black_box(0.1),
        black_box(2e-3),
    ));
    for _ in 0..black_box(500usize) {
        tf.step_mean(
            black_box([1.0, -0.5, 0.25]),
            black_box([0.0, 0.0, -2e-3]),
            black_box(5e-4),
            black_box(2),
        );
    }
    black_box(tf.close(black_box(Some([
        [1e-4, 0.0, 0.0],
        [0.0, 2e-4, 0.0],
        [0.0, 0.0, 3e-4],
    ]))));
    black_box(tf.estimate());
    black_box(tf.last_outcome());
    black_box(tf.open_samples());
    if black_box(false) {
        tf.discard();
        tf.reset();
    }
    black_box(&tf);
    if let Some(mut e) = TensorEstimator::new(black_box(TensorSettings::new())) {
        for _ in 0..black_box(1000usize) {
            black_box(e.step(
                black_box([1.0, -0.5, 0.25]),
                black_box([0.0; 3]),
                black_box(1e-3),
            ));
        }
        if black_box(false) {
            e.end_stretch();
        }
        if black_box(false) {
            e.reset();
        }
        black_box(e.estimate());
        black_box(&e);
    }
    if let Some(mut g) = FreeFlightGate::new(black_box(GateSettings::for_rate(black_box(1000.0)))) {
        for _ in 0..black_box(1000usize) {
            black_box(g.step(black_box([1.0; 3]), black_box([0.0; 3]), black_box(1e-3)));
        }
        if black_box(false) {
            g.break_window();
        }
        black_box(g.bias());
    }
    black_box(identifier_core::symmetric::eigen_symmetric3(&black_box([
        [1.0, 0.1, 0.0],
        [0.1, 2.0, 0.0],
        [0.0, 0.0, 3.0],
    ])));
    black_box(identifier_core::symmetric::sqrt(black_box(2.0)));
}

fn exercise_gravity() {
    use identifier_core::gravity::{
        gravity_gradient_torque, keep_folded, mul, mul_t, rotation, settled, sqrt, tensor_moved,
        GravityFold,
    };
    let j = black_box([[0.4f32, 0.01, 0.0], [0.01, 0.3, 0.0], [0.0, 0.0, 0.15]]);
    let mut fold = GravityFold::new(j);
    for k in 0..black_box(100usize) {
        black_box(fold.step(
            black_box(k as f64),
            black_box([0.9, 0.1, -0.2, 0.3]),
            black_box([6.8e6, 1.0e5, -2.0e5]),
        ));
    }
    let q = black_box([0.5f32, 0.5, 0.5, 0.5]);
    if let Some(r) = rotation(q) {
        black_box(mul(&r, black_box([1.0, 2.0, 3.0])));
        black_box(mul_t(&r, black_box([1.0, 2.0, 3.0])));
    }
    let jd = black_box([[0.4f64, 0.01, 0.0], [0.01, 0.3, 0.0], [0.0, 0.0, 0.15]]);
    black_box(gravity_gradient_torque(&jd, q, black_box([6.8e6, 0.0, 1.0])));
    black_box(sqrt(black_box(2.0)));
    let moved = tensor_moved(&j, black_box(Some(j)), black_box(Some(j)));
    black_box(settled(moved));
    black_box(keep_folded(black_box(1.0), black_box(2.0)));
}

/// Entry point of the image (the linker's default entry symbol).
#[no_mangle]
pub extern "C" fn _start() -> ! {
    loop {
        exercise();
        exercise_refined();
        exercise_extended();
        exercise_tensor();
        exercise_gravity();
    }
}
