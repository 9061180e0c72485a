//! The human-readable outputs of the loop: a markdown table and SVG plots.
#![allow(clippy::needless_range_loop)]

use super::analysis::Analysis;
use super::plot::{write_svg, Chart, Series};
use anyhow::Result;
use std::fmt::Write as _;
use std::path::Path;

fn v3(a: [f64; 3]) -> String {
    format!("({:+.4}, {:+.4}, {:+.4})", a[0], a[1], a[2])
}

fn opt3(a: Option<[f64; 3]>) -> String {
    a.map_or("-".into(), |a| {
        format!("({:.4}, {:.4}, {:.4})", a[0], a[1], a[2])
    })
}

fn opt(v: Option<f64>) -> String {
    v.map_or("-".into(), |v| format!("{v:.4}"))
}

/// The markdown summary: effects with their test statistics, then before/after.
pub fn markdown(an: &Analysis, title: &str) -> String {
    let mut s = String::new();
    let names: Vec<&str> = an.effects.iter().map(|e| e.name()).collect();
    let _ = writeln!(s, "## {title}\n");
    let _ = writeln!(s, "Input: `{}`; {} blocks of {} samples in {} segments; gyro noise estimated from the final residual: {:.4} rad/s.\n",
        an.input, an.blocks,
        an.samples_per_block, an.segments.len(), an.noise_std_estimate);
    if !an.spikes.is_empty() {
        let list: Vec<String> = an.spikes.iter().map(|k| format!("{:.3} s", k.t)).collect();
        let _ = writeln!(
            s,
            "Isolated spikes replaced by the mean of their neighbours before the fit: {} (at {}).\n",
            an.spikes.len(),
            list.join(", ")
        );
    }
    let _ = writeln!(
        s,
        "Effects found: **{}**\n",
        if names.is_empty() {
            "none".to_string()
        } else {
            names.join(", ")
        }
    );
    let _ = writeln!(
        s,
        "| round | candidate | F | F crit | z | z crit | dBIC | significant |"
    );
    let _ = writeln!(s, "|---|---|---|---|---|---|---|---|");
    for (i, r) in an.rounds.iter().enumerate() {
        for c in &r.candidates {
            let mark = if Some(c.effect) == r.chosen {
                " (chosen)"
            } else {
                ""
            };
            let _ = writeln!(
                s,
                "| {} | {}{} | {:.2} | {:.2} | {:.2} | {:.2} | {:.1} | {} |",
                i + 1,
                c.effect.name(),
                mark,
                c.f,
                c.f_crit,
                c.z,
                c.z_crit,
                c.delta_bic,
                c.significant
            );
        }
    }
    let _ = writeln!(s, "\n| quantity | before | after |");
    let _ = writeln!(s, "|---|---|---|");
    let mut row = |k: &str, b: String, a: String| {
        let _ = writeln!(s, "| {k} | {b} | {a} |");
    };
    row(
        "a (on-board: core identifier / extended identifier)",
        v3(an.a_before),
        v3(an.a_after),
    );
    row(
        "residual RMS, rad/s (on-board estimates)",
        format!("{:.4}", an.residual_rms_before),
        format!("{:.4}", an.residual_rms_after),
    );
    row(
        "systematic part of residual, rad/s",
        format!("{:.4}", an.residual_systematic_before),
        format!("{:.4}", an.residual_systematic_after),
    );
    row(
        "free-run prediction RMS, rad/s (mean over segments)",
        format!("{:.3}", an.free_run_rms_before),
        format!("{:.3}", an.free_run_rms_after),
    );
    row(
        "free-run prediction RMS, rad/s (least squares)",
        format!("{:.3}", an.free_run_ls_before),
        format!("{:.3}", an.free_run_ls_after),
    );
    row(
        "consistency a1+a2+a3+a1a2a3",
        format!("{:+.4}", an.consistency_before),
        format!("{:+.4}", an.consistency_after),
    );
    if let Some(t) = an.truth {
        let d = |a: [f64; 3]| v3(std::array::from_fn(|i| a[i] - t[i]));
        row("a - truth (per component)", d(an.a_before), d(an.a_after));
        row(
            "a - truth (least squares)",
            d(an.ls_before.a),
            d(an.ls_after.a),
        );
    }
    row(
        "parameter error max|a - truth|",
        opt(an.a_error_before),
        opt(an.a_error_after),
    );
    row(
        "a (batch least squares)",
        v3(an.ls_before.a),
        v3(an.ls_after.a),
    );
    row(
        "residual RMS, rad/s (least squares)",
        format!("{:.4}", an.ls_before.residual_rms),
        format!("{:.4}", an.ls_after.residual_rms),
    );
    row(
        "systematic part (least squares)",
        format!("{:.4}", an.ls_before.residual_systematic),
        format!("{:.4}", an.ls_after.residual_systematic),
    );
    row(
        "parameter error (least squares)",
        opt(an.ls_before.a_error),
        opt(an.ls_after.a_error),
    );
    row(
        "spread of per-segment a (std)",
        opt3(an.spread_before),
        opt3(an.spread_after),
    );
    let w = |x: &Option<super::analysis::Whiteness>| {
        x.as_ref().map_or("-".into(), |w| {
            format!("Q={:.1}, df={}, z={:.2}, white={}", w.q, w.df, w.z, w.white)
        })
    };
    row(
        "Ljung-Box on LS residual",
        w(&an.whiteness_before),
        w(&an.whiteness_after),
    );
    if let Some(t) = an.truth {
        let _ = writeln!(s, "\nTruth a = {}.", v3(t));
    }
    let _ = writeln!(
        s,
        "\nOn-board RLS with no effect (estimator alone): a = {}, residual RMS {:.4} rad/s.",
        v3(an.rls_no_effect.a),
        an.rls_no_effect.residual_rms
    );
    if !an.effect_params.is_empty() {
        let _ = writeln!(s, "\nEffect parameters (on-board / least squares):\n");
        for (k, v) in &an.effect_params {
            let ls = an
                .ls_after
                .effect_params
                .get(k)
                .cloned()
                .unwrap_or_default();
            let _ = writeln!(
                s,
                "- {k}: {:?} / {:?}",
                v.iter()
                    .map(|x| (x * 1e5).round() / 1e5)
                    .collect::<Vec<_>>(),
                ls.iter()
                    .map(|x| (x * 1e5).round() / 1e5)
                    .collect::<Vec<_>>()
            );
        }
    }
    let _ = writeln!(s, "\n| segment | samples | blocks | LS a before | LS a after | free-run before (core / LS) | free-run after (extended / LS) |");
    let _ = writeln!(s, "|---|---|---|---|---|---|---|");
    for g in &an.segments {
        let _ = writeln!(
            s,
            "| {} | {} | {} | {} | {} | {:.3} / {:.3} | {:.3} / {:.3} |",
            g.label,
            g.samples,
            g.blocks,
            opt3(g.ls_a_before),
            opt3(g.ls_a_after),
            g.free_run_before,
            g.free_run_ls_before,
            g.free_run_after,
            g.free_run_ls_after
        );
    }
    s
}

/// The one-line summary the command prints. It compares like with like: the on-board
/// extended identifier without the effects (before) and with them (after); for a log where no
/// effect is found it reports the fit and no "improvement".
pub fn summary_line(an: &Analysis) -> String {
    let f3 = |a: [f64; 3]| format!("({:+.4}, {:+.4}, {:+.4})", a[0], a[1], a[2]);
    let b = &an.rls_no_effect;
    if an.effects.is_empty() {
        let mut s = format!(
            "effects: none (the torque-free model explains the log); residual RMS {:.4} rad/s; \
             a {}",
            an.residual_rms_after,
            f3(an.a_after)
        );
        if let Some(e) = an.a_error_after {
            let _ = write!(s, "; max|a - truth| {e:.4}");
        }
        return s;
    }
    let names: Vec<&str> = an.effects.iter().map(|e| e.name()).collect();
    let mut s = format!(
        "effects: {}; extended identifier without -> with them: residual RMS {:.4} -> {:.4} \
         rad/s, a {} -> {}",
        names.join(", "),
        b.residual_rms,
        an.residual_rms_after,
        f3(b.a),
        f3(an.a_after)
    );
    if let (Some(x), Some(y)) = (b.a_error, an.a_error_after) {
        let _ = write!(s, ", max|a - truth| {x:.4} -> {y:.4}");
    }
    s
}

/// Writes `residual.svg` (residual against flight time, before and after, per axis) and
/// `estimates.svg` (a per segment) into `dir`.
pub fn plots(an: &Analysis, dir: &Path, title: &str) -> Result<()> {
    // Flight time: segments laid end to end.
    let mut x = Vec::new();
    let mut offset = 0.0;
    let mut last_seg = usize::MAX;
    let mut seg_start = 0.0;
    let mut prev_t = 0.0;
    for &(s, t, _, _) in &an.residual_series {
        if s != last_seg {
            offset += prev_t - seg_start + if last_seg == usize::MAX { 0.0 } else { 0.05 };
            seg_start = t;
            last_seg = s;
        }
        prev_t = t;
        x.push(offset + t - seg_start);
    }
    let axis = ["x (1)", "y (2)", "z (3)"];
    let charts: Vec<Chart> = (0..3)
        .map(|i| Chart {
            title: axis[i],
            x_label: "flight time, segments end to end (s)",
            y_label: "block residual (rad/s)",
            y_range: None,
            series: vec![
                Series {
                    name: "before (torque-free model, best-fit a)".into(),
                    points: x
                        .iter()
                        .zip(&an.residual_series)
                        .map(|(x, r)| (*x, r.2[i]))
                        .collect(),
                },
                Series {
                    name: "after (extended model, extended identifier)".into(),
                    points: x
                        .iter()
                        .zip(&an.residual_series)
                        .map(|(x, r)| (*x, r.3[i]))
                        .collect(),
                },
            ],
        })
        .collect();
    let _ = title;
    write_svg(&dir.join("residual.svg"), &charts)?;

    let names = ["a1 (x)", "a2 (y)", "a3 (z)"];
    let charts: Vec<Chart> = (0..3)
        .map(|i| {
            let seg =
                |f: &dyn Fn(&super::analysis::SegmentReport) -> Option<f64>| -> Vec<(f64, f64)> {
                    an.segments
                        .iter()
                        .enumerate()
                        .filter_map(|(k, s)| f(s).map(|v| (k as f64 + 1.0, v)))
                        .collect()
                };
            let mut series = vec![
                Series {
                    name: "LS per segment, torque-free".into(),
                    points: seg(&|s| s.ls_a_before.map(|a| a[i])),
                },
                Series {
                    name: "LS per segment, with effects".into(),
                    points: seg(&|s| s.ls_a_after.map(|a| a[i])),
                },
                Series {
                    name: "core identifier at segment end".into(),
                    points: seg(&|s| Some(s.core_a[i])),
                },
                Series {
                    name: "extended identifier at segment end".into(),
                    points: seg(&|s| Some(s.extended_a[i])),
                },
            ];
            if let Some(t) = an.truth {
                series.push(Series {
                    name: "truth / reference".into(),
                    points: vec![(1.0, t[i]), (an.segments.len().max(2) as f64, t[i])],
                });
            }
            // The range follows every series but the core identifier's, which can be far
            // off on short segments (it is clipped at the border).
            let (lo, hi) = series
                .iter()
                .enumerate()
                .filter(|(k, _)| *k != 2)
                .flat_map(|(_, s)| s.points.iter().map(|p| p.1))
                .filter(|v| v.is_finite())
                .fold((f64::MAX, f64::MIN), |(a, b), v| (a.min(v), b.max(v)));
            let pad = (0.15 * (hi - lo)).max(0.02);
            let y_range = (lo <= hi).then_some((lo - pad, hi + pad));
            Chart {
                title: names[i],
                x_label: "segment",
                y_label: "estimate (core identifier clipped to the range)",
                y_range,
                series,
            }
        })
        .collect();
    write_svg(&dir.join("estimates.svg"), &charts)?;
    Ok(())
}
