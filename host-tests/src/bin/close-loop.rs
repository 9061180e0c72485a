//! `close-loop`: identify, trace the residual to a missing effect, add it, report before and
//! after, on any gyro log.
//!
//! ```text
//! cargo run --release --bin close-loop -- --input FILE [--segments FILE] --json OUT.json \
//!     [--plots DIR] [--format phyphox|csv] [--truth a1,a2,a3] [--title TEXT]
//! ```

use anyhow::{Context, Result};
use clap::Parser;
use host_tests::close_loop::{analysis, report};
use host_tests::log_input::{read_log, Format};
use std::path::PathBuf;

#[derive(Parser, Debug)]
#[command(
    about = "Close the loop on a gyro log: residual, effect, extended model, error before and after"
)]
struct Args {
    /// The log: a phyphox export (`Raw Data.csv` or its folder) or a CSV `t,wx,wy,wz`.
    #[arg(long)]
    input: PathBuf,
    /// Free-flight windows (`segment,start,end,keep,comment`); default: a phyphox export's
    /// `meta/segments.csv`, else the whole log.
    #[arg(long)]
    segments: Option<PathBuf>,
    /// Input format; detected from the header when absent.
    #[arg(long)]
    format: Option<Format>,
    /// Where to write the JSON result.
    #[arg(long)]
    json: PathBuf,
    /// Directory for the markdown table and SVG plots.
    #[arg(long)]
    plots: Option<PathBuf>,
    /// Reference `a` (comma separated) for the parameter error.
    #[arg(long, value_delimiter = ',', allow_negative_numbers = true)]
    truth: Option<Vec<f64>>,
    /// Title of the markdown table.
    #[arg(long)]
    title: Option<String>,
    /// Family-wise significance level of each selection round.
    #[arg(long, default_value_t = 1e-3)]
    alpha: f64,
}

fn main() -> Result<()> {
    let args = Args::parse();
    if args.truth.as_ref().is_some_and(|t| t.len() != 3) {
        anyhow::bail!("--truth needs three numbers a1,a2,a3");
    }
    let log = read_log(&args.input, args.format, args.segments.as_deref())?;
    let opts = analysis::Options {
        alpha: args.alpha,
        truth: args.truth.as_ref().map(|t| [t[0], t[1], t[2]]),
        ..Default::default()
    };
    let an = analysis::analyse(&log, &opts)
        .map_err(|e| anyhow::anyhow!("{}: {e}", args.input.display()))?;
    if !an.skipped_segments.is_empty() {
        eprintln!(
            "warning: segments with too few samples skipped: {}",
            an.skipped_segments.join(", ")
        );
    }
    let json = serde_json::to_string_pretty(&an)?;
    std::fs::write(&args.json, json).with_context(|| format!("writing {}", args.json.display()))?;
    let title = args
        .title
        .clone()
        .unwrap_or_else(|| args.input.display().to_string());
    let md = report::markdown(&an, &title);
    if let Some(dir) = &args.plots {
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
        std::fs::write(dir.join("summary.md"), &md)?;
        report::plots(&an, dir, &title)?;
    }
    let names: Vec<&str> = an.effects.iter().map(|e| e.name()).collect();
    println!(
        "effects: {}; residual RMS {:.4} -> {:.4} rad/s; a {:?} -> {:?}",
        if names.is_empty() {
            "none".into()
        } else {
            names.join(", ")
        },
        an.residual_rms_before,
        an.residual_rms_after,
        an.a_before,
        an.a_after
    );
    Ok(())
}
