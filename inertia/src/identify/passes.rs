//! The readings that feed the pipelines: the gate's (the pooled pipeline finds the free
//! flights, per-throw pipelines run beside it), the re-run of throws whose bias guess was
//! wrong, and the hand-chosen segments'.
//!
//! Per-throw pipelines subtract the gate's bias at the end of the log, known only after the
//! last sample. They start at once with the bias the gate holds when the throw begins: the
//! bias is the mean over the longest still run so far, so it settles early (the same for every
//! throw of the ten thrown-fc logs, and for 202 of the 231 throws of the 10-minute bench
//! log). A throw whose guess differs from the final bias in any bit is fed again, from its
//! sample ranges, in one more reading that stops after the last such throw.

use std::ops::Range;

use identifier_core::{
    FlightPipeline, GateSettings, PipelineSettings, Ratios, TensorEstimate, WindowFit,
};

use super::inputs::{Input, Inputs};
use super::throws::{Fed, Pool};
use super::{EstimateJson, IdentifyError, Progress, Trace};
use crate::source::Flow;

/// Samples of the recent past kept for the per-throw pipelines: the pooled pipeline reports a
/// sample fed at most its delay line (256 estimator samples of up to 16 inputs) after it.
const RECENT: usize = 8192;

/// One free flight (or segment): the samples fed, as index ranges.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct Run {
    /// Rank among the runs.
    pub ordinal: usize,
    /// Sample index ranges, in order.
    pub ranges: Vec<Range<usize>>,
    /// Time of the first and last sample, s.
    pub span: (f64, f64),
    /// The bias its per-throw pipeline subtracted, measured on the bench when `Some`.
    pub bias: Option<[f32; 3]>,
}

impl Run {
    fn new(ordinal: usize, bias: Option<[f32; 3]>) -> Self {
        Run {
            ordinal,
            ranges: Vec::new(),
            span: (0.0, 0.0),
            bias,
        }
    }

    fn add(&mut self, i: usize, t: f64) {
        if self.ranges.is_empty() {
            self.span.0 = t;
        }
        self.span.1 = t;
        match self.ranges.last_mut() {
            Some(r) if r.end == i => r.end += 1,
            _ => self.ranges.push(i..i + 1),
        }
    }
}

/// Per-throw estimates by run ordinal.
pub(crate) type Throws = Vec<(usize, EstimateJson)>;

/// What the pooled pipeline ends with.
pub(crate) struct Pooled {
    pub estimate: TensorEstimate,
    pub ratios: Ratios,
    pub fed_inputs: u32,
    /// The bias removed, measured on the bench when `Some`.
    pub bias: Option<[f32; 3]>,
    /// The gyro bias's walk the tensor's fit found ((F12) of the tensor fit): its step std per
    /// pipeline sample, rad/s; 0 where none was found.
    pub bias_walk: f32,
}

impl Pooled {
    fn of(p: &FlightPipeline, bias: Option<[f32; 3]>) -> Self {
        let (estimate, ratios) = p.estimate_and_ratios();
        Pooled {
            ratios,
            estimate,
            fed_inputs: p.fed_inputs(),
            bias,
            bias_walk: p.tensor_fit().estimate().map_or(0.0, |e| e.bias_walk),
        }
    }
}

/// The last [`RECENT`] inputs by sample index.
struct Recent {
    buf: Vec<Input>,
}

impl Recent {
    fn new() -> Self {
        Recent {
            buf: vec![
                Input {
                    i: usize::MAX,
                    ..Input::default()
                };
                RECENT
            ],
        }
    }

    fn put(&mut self, x: &Input) {
        if let Some(slot) = self.buf.get_mut(x.i % RECENT) {
            *slot = *x;
        }
    }

    fn get(&self, i: usize) -> Result<&Input, IdentifyError> {
        self.buf
            .get(i % RECENT)
            .filter(|x| x.i == i)
            .ok_or_else(|| IdentifyError::Internal(format!("sample {i} is no longer held")))
    }
}

fn fed(x: &Input) -> Fed {
    Fed {
        i: x.i,
        w: x.gyro,
        h: x.h,
        dt: x.dt,
    }
}

/// Threads for per-throw pipelines beside a reader that also runs the pooled pipeline.
pub(crate) fn workers_beside_pooled() -> usize {
    std::thread::available_parallelism().map_or(1, |n| n.get().saturating_sub(1).max(1))
}

/// The longest stretch whose gate windows fitted pure rotation (F1) within the gate's residual
/// but about a point farther from the accelerometer than [`GateSettings::far_offset`]: what
/// the gate refused for the offset alone. A large object with the flight controller far from
/// its centre of mass gives it, and so does a gyro read too low (a unit mistake: the fit's
/// offset grows with the square of the missing factor). Said when no free flight is found.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct FarRotation {
    /// The stretch in progress: first and last time, sum of the offsets' lengths, samples.
    open: Option<(f64, f64, f64, u32)>,
    /// The longest closed or open stretch: first time, span, mean offset (m).
    best: Option<(f64, f64, f64)>,
}

impl FarRotation {
    /// Shortest stretch worth saying, s: a hand's swing may fit for a window or two.
    const LEAST_S: f64 = 0.1;

    fn push(&mut self, t: f64, fit: Option<WindowFit>, gate: &GateSettings) {
        let far = fit.and_then(|f| {
            let r = f.offset;
            let rn = f64::from((r[0] * r[0] + r[1] * r[1] + r[2] * r[2]).sqrt());
            (!f.free
                && !f.still
                && f.residual < gate.max_residual
                && rn.is_finite()
                && rn > f64::from(gate.far_offset))
            .then_some(rn)
        });
        match far {
            Some(rn) => {
                let (t0, _, sum, n) = self.open.unwrap_or((t, t, 0.0, 0));
                let open = (t0, t, sum + rn, n.saturating_add(1));
                self.open = Some(open);
                let span = t - t0;
                if self.best.is_none_or(|(_, b, _)| span > b) {
                    self.best = Some((t0, span, open.2 / f64::from(open.3)));
                }
            }
            None => self.open = None,
        }
    }

    /// The sentence for the error, when the stretch lasted [`FarRotation::LEAST_S`] or more.
    pub(crate) fn describe(&self, gate: &GateSettings) -> Option<String> {
        let (t0, span, r) = self.best.filter(|(_, span, _)| *span >= Self::LEAST_S)?;
        Some(format!(
            "for {span:.2} s from t = {t0:.2} s the accelerometer read pure rotation, but about \
             a point {r:.2} m from it, beyond the {:.2} m the gate allows: if the flight \
             controller sits that far from the centre of mass of what was thrown, give \
             --segments; if not, the gyro reads too low (check its unit)",
            gate.far_offset
        ))
    }
}

/// The gate's reading: the pooled pipeline over every sample (free flights from the
/// accelerometer, or every sample without one), the runs it fed, the per-throw estimates
/// with the guessed bias (see the module documentation), and what the gate refused for the
/// offset alone.
pub(crate) fn gate(
    inputs: &Inputs<'_>,
    settings: PipelineSettings,
    with_accel: bool,
    rate: f32,
    trace: &mut Option<Trace>,
    progress: &mut dyn Progress,
) -> Result<(Pooled, Vec<Run>, Throws, FarRotation), IdentifyError> {
    let n = inputs.samples;
    let mut p = FlightPipeline::new(settings, with_accel)
        .ok_or_else(|| IdentifyError::Settings("invalid pipeline settings".into()))?;
    let max_gap = (0.1 * rate as f64).max(2.0) as usize;
    std::thread::scope(|scope| {
        let mut pool = Pool::new(scope, settings, workers_beside_pooled())?;
        let mut recent = Recent::new();
        let mut runs: Vec<Run> = Vec::new();
        let mut last_fed: Option<usize> = None;
        let mut far = FarRotation::default();
        let mut step = |x: &Input| -> Result<(), IdentifyError> {
            recent.put(x);
            if let Some(t) = trace.as_mut() {
                t.push(x);
            }
            let exit = p.step(x.gyro, x.accel, x.h, x.dt);
            if with_accel {
                far.push(x.t, p.gate_fit(), &settings.gate);
            }
            let Some(exit) = exit else {
                return Ok(());
            };
            if exit.fed.is_none() {
                return Ok(());
            }
            // The estimator sample averages `inputs` log samples from `first_input`.
            let k = exit.sample.first_input as usize;
            let new_run = last_fed.is_none_or(|l| k > l + max_gap);
            if new_run {
                if let Some(r) = runs.last() {
                    pool.finish(r.ordinal, r.span)?;
                }
                let r = Run::new(runs.len(), p.measured_bias());
                pool.start(r.ordinal, r.bias)?;
                runs.push(r);
            }
            let end = (k + exit.sample.inputs as usize).min(n);
            if let Some(run) = runs.last_mut() {
                for i in k..end {
                    let y = recent.get(i)?;
                    run.add(i, y.t);
                    pool.feed(run.ordinal, fed(y))?;
                }
            }
            last_fed = Some(end.saturating_sub(1));
            Ok(())
        };
        inputs.read_ahead_with(&mut |x| step(x).map(|()| Flow::Continue), &mut |f| {
            progress.update(f)
        })?;
        // The log ends: a free flight still open is fitted now (the trajectory fit runs at
        // each stretch's end, as the firmware's does at the catch).
        p.end_stretch();
        if let Some(r) = runs.last() {
            pool.finish(r.ordinal, r.span)?;
        }
        let pooled = Pooled::of(&p, p.measured_bias());
        Ok((pooled, runs, pool.join()?, far))
    })
}

/// Feeds `runs` again (in order) with `bias`, to as many threads as there are cores; the
/// reading stops after the last run.
pub(crate) fn rerun(
    inputs: &Inputs<'_>,
    settings: PipelineSettings,
    runs: &[&Run],
    bias: Option<[f32; 3]>,
    progress: &mut dyn Progress,
) -> Result<Throws, IdentifyError> {
    let Some(end) = runs.last().and_then(|r| r.ranges.last()).map(|r| r.end) else {
        return Ok(Vec::new());
    };
    let workers = std::thread::available_parallelism().map_or(1, |n| n.get());
    std::thread::scope(|scope| {
        let mut pool = Pool::new(scope, settings, workers)?;
        let (mut ri, mut qi) = (0usize, 0usize);
        let mut step = |x: &Input| -> Result<Flow, IdentifyError> {
            let Some(run) = runs.get(ri) else {
                return Ok(Flow::Stop);
            };
            let Some(range) = run.ranges.get(qi) else {
                return Err(IdentifyError::Internal("a run without samples".into()));
            };
            if x.i < range.start {
                return Ok(Flow::Continue);
            }
            if qi == 0 && x.i == range.start {
                pool.start(run.ordinal, bias)?;
            }
            pool.feed(run.ordinal, fed(x))?;
            if x.i + 1 >= range.end {
                qi += 1;
                if qi == run.ranges.len() {
                    pool.finish(run.ordinal, run.span)?;
                    ri += 1;
                    qi = 0;
                    if ri == runs.len() {
                        return Ok(Flow::Stop);
                    }
                }
            }
            Ok(Flow::Continue)
        };
        inputs.read_ahead_with(&mut step, &mut |f| {
            progress.update(f * inputs.samples as f32 / end as f32)
        })?;
        if ri != runs.len() {
            return Err(IdentifyError::Internal(
                "the log ended inside a throw".into(),
            ));
        }
        pool.join()
    })
}

/// Ends a segment: one that `held` samples ends its stretch and its throw (the last run).
fn close(
    held: bool,
    runs: &[Run],
    pool: &mut Pool<'_>,
    pooled: &mut FlightPipeline,
) -> Result<(), IdentifyError> {
    if held {
        pooled.end_stretch();
        if let Some(r) = runs.last() {
            pool.finish(r.ordinal, r.span)?;
        }
    }
    Ok(())
}

/// The gyro bias measured on the still bench before `until` (s): the pipeline with its
/// free-flight gate fed every sample before it, as a reading of the whole log feeds it, so
/// hand-chosen segments have the bias removed that the whole log's reading removes (one
/// answer for the same samples). `None` when no still stretch came before.
pub(crate) fn bench_bias(
    inputs: &Inputs<'_>,
    settings: PipelineSettings,
    until: f64,
    progress: &mut dyn Progress,
) -> Result<Option<[f32; 3]>, IdentifyError> {
    let mut p = FlightPipeline::new(settings, true)
        .ok_or_else(|| IdentifyError::Settings("invalid pipeline settings".into()))?;
    let mut step = |x: &Input| -> Result<Flow, IdentifyError> {
        if x.t >= until {
            return Ok(Flow::Stop);
        }
        p.step(x.gyro, x.accel, x.h, x.dt);
        Ok(Flow::Continue)
    };
    inputs.read_ahead_with(&mut step, &mut |f| progress.update(f))?;
    Ok(p.measured_bias())
}

/// The hand-chosen segments' readings: the pooled pipeline fed each segment's samples in the
/// order of the segments (one reading per stretch of segments that follow each other in
/// time), per-segment pipelines beside it, `bias` (measured on the bench, [`bench_bias`])
/// removed from every sample. Returns the runs of the segments that held samples and, per
/// segment, whether it held any.
pub(crate) fn segments(
    inputs: &Inputs<'_>,
    settings: PipelineSettings,
    segs: &[(f64, f64)],
    bias: Option<[f32; 3]>,
    trace: &mut Option<Trace>,
    progress: &mut dyn Progress,
) -> Result<(Pooled, Vec<Run>, Throws, Vec<bool>), IdentifyError> {
    let mut pooled = FlightPipeline::new(settings, false)
        .ok_or_else(|| IdentifyError::Settings("invalid estimator settings".into()))?;
    pooled.set_bias_removed(bias.is_some());
    let b = bias.unwrap_or([0.0; 3]);
    // Segments read in one reading: each starts at or after the previous one's end.
    let mut groups: Vec<Range<usize>> = Vec::new();
    for (k, s) in segs.iter().enumerate() {
        match groups.last_mut() {
            Some(g) if s.0 >= segs[k - 1].1 => g.end = k + 1,
            _ => groups.push(k..k + 1),
        }
    }
    let mut held = vec![false; segs.len()];
    std::thread::scope(|scope| {
        let mut pool = Pool::new(scope, settings, workers_beside_pooled())?;
        let mut runs: Vec<Run> = Vec::new();
        for group in groups {
            let mut cur = group.start;
            let mut step = |x: &Input| -> Result<Flow, IdentifyError> {
                if let Some(t) = trace.as_mut() {
                    t.push(x);
                }
                while cur < group.end {
                    let (s, e) = segs[cur];
                    if x.t > e {
                        close(held[cur], &runs, &mut pool, &mut pooled)?;
                        cur += 1;
                        continue;
                    }
                    if x.t < s {
                        break;
                    }
                    if !held[cur] {
                        held[cur] = true;
                        let r = Run::new(runs.len(), bias);
                        pool.start(r.ordinal, r.bias)?;
                        runs.push(r);
                    }
                    let w = [x.gyro[0] - b[0], x.gyro[1] - b[1], x.gyro[2] - b[2]];
                    pooled.step(w, [0.0; 3], x.h, x.dt);
                    if let Some(r) = runs.last_mut() {
                        r.add(x.i, x.t);
                        pool.feed(r.ordinal, fed(x))?;
                    }
                    if x.t < e {
                        break;
                    }
                    // The segment's last possible sample (times increase): it ends here, and
                    // the next segment may start at the same sample.
                    close(held[cur], &runs, &mut pool, &mut pooled)?;
                    cur += 1;
                }
                let done = cur >= group.end && trace.is_none();
                Ok(if done { Flow::Stop } else { Flow::Continue })
            };
            inputs.read_ahead_with(&mut step, &mut |f| progress.update(f))?;
            for &h in held.get(cur..group.end).unwrap_or_default() {
                close(h, &runs, &mut pool, &mut pooled)?;
            }
            // The plot needs one whole reading.
            if let Some(t) = trace.as_mut() {
                t.done = true;
            }
        }
        let p = Pooled::of(&pooled, bias);
        Ok((p, runs, pool.join()?, held))
    })
}
