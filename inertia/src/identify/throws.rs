//! Per-throw estimates on worker threads: each throw gets a fresh `FlightPipeline` fed
//! exactly the samples the pooled pipeline fed during that throw, the gyro bias subtracted
//! (`identify`'s per-throw results). The throws are independent of each other and of the
//! pooled pipeline, so they run beside it; a throw goes to worker `ordinal % workers` and the
//! results are the same bits whatever thread computed them.
//!
//! Memory: the samples travel in batches through bounded channels (the reader waits when a
//! worker falls behind); a worker holds one pipeline at a time.

use std::sync::mpsc::{sync_channel, Receiver, SyncSender};
use std::thread::{Scope, ScopedJoinHandle};

use identifier_core::{FlightPipeline, PipelineSettings};

use super::{EstimateJson, IdentifyError};

/// Samples per batch sent to a worker.
const BATCH: usize = 1024;
/// Batches a worker's channel holds (2.6 MB at most): enough that the pooled pipeline and the
/// workers, each busy in bursts (a flight's fit at its end), rarely wait for each other.
const QUEUE: usize = 64;
/// Stack of a worker: a pipeline is a large value.
const STACK: usize = 16 << 20;

/// One fed sample: its index in the log, rate (bias not yet removed), rotor momentum, time
/// step.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Fed {
    pub i: usize,
    pub w: [f32; 3],
    pub h: [f32; 3],
    pub dt: f32,
}

enum Msg {
    /// A throw starts; its rates have `bias` removed, measured on the bench when `Some`.
    Start {
        ordinal: usize,
        bias: Option<[f32; 3]>,
    },
    Fed(Vec<Fed>),
    Finish {
        span: (f64, f64),
    },
}

type Results = Vec<(usize, EstimateJson)>;

struct Worker<'s> {
    tx: SyncSender<Msg>,
    batch: Vec<Fed>,
    handle: ScopedJoinHandle<'s, Result<Results, String>>,
}

/// The workers.
pub(crate) struct Pool<'s> {
    workers: Vec<Worker<'s>>,
}

/// A worker's loop: one throw after the other, as `identify` always computed them.
fn work(settings: PipelineSettings, rx: Receiver<Msg>) -> Result<Results, String> {
    let mut out = Vec::new();
    let mut cur: Option<(usize, FlightPipeline, [f32; 3], Option<usize>)> = None;
    for msg in rx {
        match msg {
            Msg::Start { ordinal, bias } => {
                let mut e = FlightPipeline::new(settings, false)
                    .ok_or("invalid estimator settings for a throw")?;
                e.set_bias_removed(bias.is_some());
                cur = Some((ordinal, e, bias.unwrap_or([0.0; 3]), None));
            }
            Msg::Fed(batch) => {
                let (_, e, b, prev) = cur.as_mut().ok_or("samples before a throw started")?;
                for f in batch {
                    // Stretches of a throw separated by held-back samples: no integral across.
                    if prev.is_some_and(|p| f.i != p + 1) {
                        e.end_stretch();
                    }
                    *prev = Some(f.i);
                    let w = [f.w[0] - b[0], f.w[1] - b[1], f.w[2] - b[2]];
                    e.step(w, [0.0; 3], f.h, f.dt);
                }
            }
            Msg::Finish { span } => {
                let (ordinal, mut e, _, _) = cur.take().ok_or("a throw ended before it started")?;
                e.end_stretch();
                let (est, ratios) = e.estimate_and_ratios();
                let mut j = EstimateJson::from(&est, &ratios, span.0, span.1);
                j.samples = e.fed_inputs();
                out.push((ordinal, j));
            }
        }
    }
    Ok(out)
}

impl<'s> Pool<'s> {
    /// `workers` threads (at least one) in `scope`.
    pub(crate) fn new<'e>(
        scope: &'s Scope<'s, 'e>,
        settings: PipelineSettings,
        workers: usize,
    ) -> Result<Self, IdentifyError> {
        let mut out = Vec::new();
        for _ in 0..workers.max(1) {
            let (tx, rx) = sync_channel(QUEUE);
            let handle = std::thread::Builder::new()
                .name("throws".into())
                .stack_size(STACK)
                .spawn_scoped(scope, move || work(settings, rx))
                .map_err(|e| IdentifyError::Internal(format!("cannot start a thread: {e}")))?;
            out.push(Worker {
                tx,
                batch: Vec::with_capacity(BATCH),
                handle,
            });
        }
        Ok(Pool { workers: out })
    }

    fn worker(&mut self, ordinal: usize) -> &mut Worker<'s> {
        let n = self.workers.len();
        &mut self.workers[ordinal % n]
    }

    fn send(w: &mut Worker<'s>, msg: Msg) -> Result<(), IdentifyError> {
        // A worker that stopped has an error to tell; `join` tells it.
        w.tx.send(msg)
            .map_err(|_| IdentifyError::Internal("a throw worker stopped".into()))
    }

    fn flush(w: &mut Worker<'s>) -> Result<(), IdentifyError> {
        if w.batch.is_empty() {
            return Ok(());
        }
        let batch = std::mem::replace(&mut w.batch, Vec::with_capacity(BATCH));
        Self::send(w, Msg::Fed(batch))
    }

    /// Throw `ordinal` starts; its rates will have `bias` removed (measured on the bench when
    /// `Some`, none otherwise).
    pub(crate) fn start(
        &mut self,
        ordinal: usize,
        bias: Option<[f32; 3]>,
    ) -> Result<(), IdentifyError> {
        let w = self.worker(ordinal);
        Self::flush(w)?;
        Self::send(w, Msg::Start { ordinal, bias })
    }

    /// The next sample of throw `ordinal`.
    #[inline]
    pub(crate) fn feed(&mut self, ordinal: usize, f: Fed) -> Result<(), IdentifyError> {
        let w = self.worker(ordinal);
        w.batch.push(f);
        if w.batch.len() >= BATCH {
            Self::flush(w)?;
        }
        Ok(())
    }

    /// Throw `ordinal` ends; `span` is the time of its first and last samples.
    pub(crate) fn finish(&mut self, ordinal: usize, span: (f64, f64)) -> Result<(), IdentifyError> {
        let w = self.worker(ordinal);
        Self::flush(w)?;
        Self::send(w, Msg::Finish { span })
    }

    /// Waits for the workers: every finished throw's estimate, by ordinal.
    pub(crate) fn join(self) -> Result<Results, IdentifyError> {
        let mut all = Vec::new();
        let mut handles = Vec::new();
        for mut w in self.workers {
            Self::flush(&mut w)?;
            drop(w.tx);
            handles.push(w.handle);
        }
        for h in handles {
            let r = h
                .join()
                .map_err(|_| IdentifyError::Internal("a throw worker panicked".into()))?;
            all.extend(r.map_err(IdentifyError::Internal)?);
        }
        all.sort_by_key(|(k, _)| *k);
        Ok(all)
    }
}
