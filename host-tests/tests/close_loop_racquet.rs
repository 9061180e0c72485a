//! The close-the-loop analysis (`inertia::close_loop`) on the measured racquet tosses in `../shared/data/racquet/`
//! (beside the repository; CI has it). Skips with a message only if that directory is absent.

use inertia::close_loop::analysis::{analyse, Options};
use inertia::close_loop::model::Effect;
use std::path::PathBuf;

/// `a` implied by the pendulum-measured inertias (the data's README).
const PENDULUM: [f64; 3] = [-1.03, 1.37, 0.84];
/// Pendulum inertias, kg m^2, sensor axes (x intermediate, y handle, z primary).
const INERTIA: [f64; 3] = [18.8e-3, 1.391e-3, 20.7e-3];

fn racquet_dir() -> Option<PathBuf> {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..");
    let d = root.join("..").join("shared").join("data").join("racquet");
    d.is_dir().then_some(d)
}

fn export(round: &str) -> PathBuf {
    let dir = racquet_dir().unwrap().join(round);
    std::fs::read_dir(&dir)
        .unwrap()
        .filter_map(|e| e.ok())
        .map(|e| e.path())
        .find(|p| p.join("Raw Data.csv").is_file())
        .unwrap_or_else(|| panic!("no phyphox export in {}", dir.display()))
}

#[test]
fn racquet_residual_traces_to_damping() {
    let Some(_) = racquet_dir() else {
        eprintln!("SKIPPED: ../shared/data/racquet not found beside the repository");
        return;
    };
    for (round, segments) in [("round1", 6), ("round2", 5), ("round4", 6)] {
        let (log, _) =
            inertia::close_loop::load(&export(round), None, None, &Default::default()).unwrap();
        assert_eq!(log.segments.len(), segments, "{round}: kept segments");
        let an = analyse(
            &log,
            &Options {
                truth: Some(PENDULUM),
                ..Default::default()
            },
        )
        .unwrap();
        let first = &an.rounds[0];
        let damping = first
            .candidates
            .iter()
            .find(|c| c.effect == Effect::Damping)
            .unwrap();
        println!(
            "{round}: effects {:?}; damping z {:.2} vs {:.2}; LS residual {:.4} -> {:.4} (systematic {:.4} -> {:.4}); on-board residual {:.4} -> {:.4}; a {:?} -> {:?}; LS a {:?} -> {:?}; spread {:?} -> {:?}; free-run {:.3} -> {:.3}; error vs pendulum {:?} -> {:?}",
            an.effects, damping.z, damping.z_crit,
            an.ls_before.residual_rms, an.ls_after.residual_rms,
            an.ls_before.residual_systematic, an.ls_after.residual_systematic,
            an.residual_rms_before, an.residual_rms_after,
            an.a_before, an.a_after, an.ls_before.a, an.ls_after.a,
            an.spread_before, an.spread_after,
            an.free_run_rms_before, an.free_run_rms_after,
            an.a_error_before, an.a_error_after,
        );
        // The first effect traced is damping: energy is lost in every toss (air drag).
        assert_eq!(an.effects.first(), Some(&Effect::Damping), "{round}");
        let d = &an.ls_after.effect_params["damping"];
        assert!(
            d.iter().all(|v| *v > 0.0),
            "{round}: damping must drain energy: {d:?}"
        );
        // Drag torque implied by the fitted damping with the pendulum inertias: the rate of
        // change of |L| along the toss, to compare with the report's -0.048 +- 0.026 N m.
        let (mut dl, mut n) = (0.0, 0);
        for (i0, i1) in log.segment_ranges() {
            for w in &log.omega[i0..i1] {
                let l: Vec<f64> = (0..3).map(|i| INERTIA[i] * w[i]).collect();
                let ln = l.iter().map(|v| v * v).sum::<f64>().sqrt();
                let tau: Vec<f64> = (0..3).map(|i| -d[i] * INERTIA[i] * w[i]).collect();
                dl += l.iter().zip(&tau).map(|(a, b)| a * b).sum::<f64>() / ln;
                n += 1;
            }
        }
        println!(
            "{round}: mean d|L|/dt from the fitted damping: {:.4} N m",
            dl / n as f64
        );
        // Adding it shrinks the residual and its systematic part, and the on-board residual.
        assert!(
            an.ls_after.residual_rms < an.ls_before.residual_rms,
            "{round}"
        );
        // Its systematic part does not grow (round 1's is already zero by this measure: its
        // residual is large but not smooth over five blocks).
        assert!(
            an.ls_after.residual_systematic <= an.ls_before.residual_systematic,
            "{round}"
        );
        assert!(an.residual_rms_after < an.residual_rms_before, "{round}");
        // The extended estimate is a rigid body (consistency near zero).
        assert!(
            an.consistency_after.abs() < 0.05,
            "{round}: {}",
            an.consistency_after
        );
    }
}
