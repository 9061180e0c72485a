//! `inertia close-loop` with the tensor as the base model, on simulated board throws with a
//! flywheel spin-up: a delay put into the logged rotor speed must be found (the effect traced),
//! the tensor with it must match the one without it, and no torque, damping, bias, axis or
//! scale effect may be chosen where the simulation has none; air drag on the rotor put into the
//! simulation must be traced to `rotor_drag`.
//!
//! `cargo test --release -p host-tests --test close_loop_tensor -- --nocapture`

use host_tests::throw_sim::{board_throw, simulate, SimThrow, ThrowConfig};
use inertia::close_loop::tensor::{
    analyse_tensor, EffectParams, TensorAnalysis, TensorEffect, TensorOptions,
};
use inertia::identify::Rotor;
use inertia::{Recording, RotorSpeed};

/// The simulated log with its rotor speed read `lag` samples late (the log shows the speed of
/// `lag` samples before).
fn recording(sim: &SimThrow, lag: usize) -> Recording {
    let n = sim.t.len();
    let rotor: Vec<f32> = (0..n)
        .map(|i| sim.rotor_rad_s[i.saturating_sub(lag)])
        .collect();
    Recording {
        source: format!("board_throw, rotor {lag} samples late"),
        t: sim.t.clone(),
        gyro: sim.gyro.clone(),
        accel: Some(sim.accel.clone()),
        rotor: Some(RotorSpeed::RadPerSec(rotor)),
        gyro_full_scale: f32::INFINITY,
        gyro_averaging: 0.0,
        gyro_unit_stated: true,
        gyro_filters: None,
        warnings: Vec::new(),
        ..Recording::default()
    }
}

fn options(sim: &SimThrow) -> TensorOptions {
    let r = &sim.config.rotor;
    TensorOptions {
        rotor: Rotor {
            inertia: r.inertia as f32,
            axis: r.unit_axis().map(|x| x as f32),
            poles: None,
        },
        alpha: 1e-3,
        block_s: 0.01,
        segments: None,
        rotor_hold: inertia::identify::RotorHold::Unhold,
    }
}

#[test]
fn a_late_rotor_speed_is_traced_and_undone() {
    let sim = board_throw(3);
    let dt = sim.dt();
    let opts = options(&sim);
    let clean = analyse_tensor(&recording(&sim, 0), &opts).expect("clean log");
    let lag_of = |an: &inertia::close_loop::tensor::TensorAnalysis| {
        an.after
            .effect_params
            .iter()
            .find(|e| e.effect == TensorEffect::RotorLag)
            .map_or(0.0, |e| e.values[0])
    };
    let base_lag = lag_of(&clean);
    println!(
        "clean: residual {:.2}x the noise's share -> {:.2}x, effects {:?}, lag {:.3} ms",
        clean.before.residual_over_noise,
        clean.after.residual_over_noise,
        clean.after.effects,
        base_lag * 1e3
    );
    // The simulated telemetry itself is read a fraction of a millisecond off (its hold
    // points); nothing else may be taken for an effect.
    assert!(base_lag.abs() < 5e-4, "clean lag {base_lag}");
    for e in &clean.after.effects {
        assert_eq!(
            *e,
            TensorEffect::RotorLag,
            "false effect on a clean log: {e:?}"
        );
    }
    for lag in [4usize, 8, 20] {
        let an = analyse_tensor(&recording(&sim, lag), &opts).expect("lagged log");
        let found = lag_of(&an);
        let put = lag as f64 * dt;
        println!(
            "rotor {:.1} ms late: residual {:.2}x -> {:.2}x the noise's share, effects {:?}, lag found {:.3} ms (minus the clean log's: {:.3}), tensor moved {:.2} %",
            put * 1e3,
            an.before.residual_over_noise,
            an.after.residual_over_noise,
            an.after.effects,
            found * 1e3,
            (found - base_lag) * 1e3,
            100.0 * an.tensor_change
        );
        assert_eq!(an.after.effects.first(), Some(&TensorEffect::RotorLag));
        assert!(
            ((found - base_lag) - put).abs() < 1e-4,
            "lag {found} for {put}"
        );
        // The residual falls back to the clean log's.
        assert!(an.before.residual_rms > 1.5 * clean.after.residual_rms);
        assert!((an.after.residual_rms / clean.after.residual_rms - 1.0).abs() < 0.01);
        // With the lag found, the tensor is the clean log's.
        for (a, b) in an
            .after
            .tensor_kg_m2
            .iter()
            .flatten()
            .zip(clean.after.tensor_kg_m2.iter().flatten())
        {
            assert!(
                (a - b).abs() < 2e-8,
                "{a} vs {b}: {:?} vs {:?}",
                an.after.tensor_kg_m2,
                clean.after.tensor_kg_m2
            );
        }
    }
}

/// The close-loop analysis of the clean board throw (seed 3) and of the same throw simulated
/// with `change` made to its configuration, with the effect `effect`'s fitted parameters when
/// it was chosen.
fn clean_and_changed(
    change: impl FnOnce(&mut ThrowConfig),
    effect: TensorEffect,
) -> (TensorAnalysis, TensorAnalysis, Option<EffectParams>) {
    let clean_sim = board_throw(3);
    let opts = options(&clean_sim);
    let clean = analyse_tensor(&recording(&clean_sim, 0), &opts).expect("clean log");
    let mut cfg = clean_sim.config;
    change(&mut cfg);
    let sim = simulate(&cfg);
    let an = analyse_tensor(&recording(&sim, 0), &opts).expect("changed log");
    let params = an
        .after
        .effect_params
        .iter()
        .find(|e| e.effect == effect)
        .cloned();
    (clean, an, params)
}

/// Air drag on the flywheel (`tau = -c |h| h`, an external torque the motor's does not cancel)
/// put into the simulation is traced to the `rotor_drag` effect, its coefficient recovered and
/// the tensor moved back to the drag-free log's.
#[test]
fn air_drag_on_the_rotor_is_traced() {
    let c = 100.0;
    let (clean, an, drag) = clean_and_changed(|cfg| cfg.rotor_drag = c, TensorEffect::RotorDrag);
    println!(
        "drag c = {c}: residual {:.2}x -> {:.2}x the noise's share, effects {:?}, c found {:?}, tensor moved {:.2} %",
        an.before.residual_over_noise,
        an.after.residual_over_noise,
        an.after.effects,
        drag.as_ref().map(|d| (d.values[0], d.std[0])),
        100.0 * an.tensor_change
    );
    let d = drag.expect("rotor_drag chosen");
    assert!(
        (d.values[0] - c).abs() < 4.0 * d.std[0] && d.std[0] < 0.1 * c,
        "c {} +- {} for {c}",
        d.values[0],
        d.std[0]
    );
    assert!(an.before.residual_rms > 1.5 * clean.after.residual_rms);
    for (a, b) in an
        .after
        .tensor_kg_m2
        .iter()
        .flatten()
        .zip(clean.after.tensor_kg_m2.iter().flatten())
    {
        assert!((a - b).abs() < 5e-8, "{a} vs {b}");
    }
}

/// Quadratic air drag on the tumbling body (`tau_k = -c_k |w| w_k`) put into the simulation is
/// traced to `aero_drag`, and the tensor returns to the drag-free log's.
#[test]
fn air_drag_on_the_body_is_traced() {
    let c = [2e-6, 2e-6, 2e-6];
    let (clean, an, drag) = clean_and_changed(|cfg| cfg.aero_drag = c, TensorEffect::AeroDrag);
    println!(
        "aero drag c = {c:?}: residual {:.2}x -> {:.2}x the noise's share, effects {:?}, c found {:?}, tensor moved {:.2} %",
        an.before.residual_over_noise,
        an.after.residual_over_noise,
        an.after.effects,
        drag.as_ref().map(|d| (&d.values, &d.std)),
        100.0 * an.tensor_change
    );
    let d = drag.expect("aero_drag chosen");
    for (k, ((v, s), want)) in d.values.iter().zip(&d.std).zip(c).enumerate() {
        assert!(
            (v - want).abs() < 4.0 * s && *s < 0.3 * want,
            "c_{k} {v} +- {s} for {want}"
        );
    }
    // Back to the drag-free log's tensor within its uncertainty (the drag and the tensor share
    // information: the reported std grows).
    let sd = an.after.tensor_std_kg_m2;
    for ((a, b), s) in an
        .after
        .tensor_kg_m2
        .iter()
        .flatten()
        .zip(clean.after.tensor_kg_m2.iter().flatten())
        .zip(sd.iter().flatten())
    {
        assert!((a - b).abs() < 4.0 * s, "{a} vs {b} (std {s})");
    }
}
