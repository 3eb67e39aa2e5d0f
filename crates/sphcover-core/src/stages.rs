//! Pipelines as explicit lists of stages over a shared context, and the one runner that
//! times them and reports their progress.
//!
//! The method is described on [`run_stages()`].

use std::fmt;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

/// One named step of a pipeline over the context `C`, failing with `E`.
pub struct Stage<C, E> {
    /// The name shown in progress displays and stage timings.
    pub name: &'static str,
    /// The work: reads what earlier stages left in the context and leaves its product there.
    pub run: fn(&mut C) -> Result<(), E>,
}

impl<C, E> Stage<C, E> {
    /// A stage named `name` that runs `run`.
    pub const fn new(name: &'static str, run: fn(&mut C) -> Result<(), E>) -> Stage<C, E> {
        Stage { name, run }
    }
}

// Manual impls: the derives would demand `C: Clone` and `E: Clone`, which a function
// pointer does not need.
impl<C, E> Clone for Stage<C, E> {
    fn clone(&self) -> Self {
        *self
    }
}

impl<C, E> Copy for Stage<C, E> {}

impl<C, E> fmt::Debug for Stage<C, E> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_tuple("Stage").field(&self.name).finish()
    }
}

/// The start of a stage, as a progress display is told of it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct StageProgress {
    /// The stage's name.
    pub name: &'static str,
    /// Its position in the list, from 0.
    pub index: usize,
    /// How many stages the list holds.
    pub count: usize,
}

/// Wall time of each stage that ran, in order.
pub type StageTimes = Vec<(&'static str, Duration)>;

/// Runs `stages` in order over `ctx`, telling `progress` as each starts, and returns the wall
/// time of each. The first failing stage ends the run with its error.
///
/// A pipeline (reconstruction, skeletal sheet) keeps what its stages share (point index,
/// sphere intersection graph, cover, samples of each support, …) in a context struct of its
/// own; each stage is a plain function over that context. The list of stages is data, so a
/// caller can print it, a progress display knows how many stages remain, and a new stage is
/// one more entry rather than another branch in a long function.
///
/// ```
/// use sphcover_core::{Stage, StageProgress, run_stages};
///
/// #[derive(Default)]
/// struct Sum {
///     values: Vec<f64>,
///     total: f64,
/// }
/// fn fill(ctx: &mut Sum) -> Result<(), String> {
///     ctx.values = (1..=4).map(f64::from).collect();
///     Ok(())
/// }
/// fn add(ctx: &mut Sum) -> Result<(), String> {
///     ctx.total = ctx.values.iter().sum();
///     Ok(())
/// }
///
/// let stages = [Stage::new("fill", fill), Stage::new("add", add)];
/// let mut ctx = Sum::default();
/// let started = std::sync::Mutex::new(Vec::new());
/// let progress = |p: StageProgress| started.lock().unwrap().push((p.name, p.index, p.count));
/// let times = run_stages(&mut ctx, &stages, &progress)?;
/// assert_eq!(ctx.total, 10.0);
/// assert_eq!(times.iter().map(|t| t.0).collect::<Vec<_>>(), ["fill", "add"]);
/// assert_eq!(*started.lock().unwrap(), [("fill", 0, 2), ("add", 1, 2)]);
/// # Ok::<(), String>(())
/// ```
pub fn run_stages<C, E>(
    ctx: &mut C,
    stages: &[Stage<C, E>],
    progress: &(dyn Fn(StageProgress) + Sync),
) -> Result<StageTimes, E> {
    run_checked(ctx, stages, progress, |_| Ok(()))
}

/// A request to stop a pipeline early, shared between the caller (another thread, a signal
/// handler's flag watcher) and the pipeline. [`run_stages_until`] looks at it before every
/// stage, so a pipeline stops at the next stage boundary: the stages themselves are not
/// interrupted, which keeps every stage free of checks and its product whole.
#[derive(Debug, Default)]
pub struct StopRequest(AtomicBool);

impl StopRequest {
    /// A request not yet made.
    pub const fn new() -> StopRequest {
        StopRequest(AtomicBool::new(false))
    }

    /// Asks the pipeline to stop before its next stage.
    pub fn request(&self) {
        self.0.store(true, Ordering::Relaxed);
    }

    /// Whether a stop was asked for.
    pub fn is_requested(&self) -> bool {
        self.0.load(Ordering::Relaxed)
    }
}

/// A pipeline ended early at a stage boundary because a [`StopRequest`] was made.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
#[error("stopped on request before the stage `{before}`")]
pub struct Stopped {
    /// The first stage that did not run.
    pub before: &'static str,
}

/// [`run_stages`], stopping before the first stage that starts after `stop` was requested
/// with [`Stopped`] (converted into the pipeline's error).
pub fn run_stages_until<C, E: From<Stopped>>(
    ctx: &mut C,
    stages: &[Stage<C, E>],
    progress: &(dyn Fn(StageProgress) + Sync),
    stop: &StopRequest,
) -> Result<StageTimes, E> {
    run_checked(ctx, stages, progress, |before| {
        if stop.is_requested() {
            Err(Stopped { before }.into())
        } else {
            Ok(())
        }
    })
}

/// The loop of both runners: `check` may end the run before each stage.
fn run_checked<C, E>(
    ctx: &mut C,
    stages: &[Stage<C, E>],
    progress: &(dyn Fn(StageProgress) + Sync),
    check: impl Fn(&'static str) -> Result<(), E>,
) -> Result<StageTimes, E> {
    let mut times = Vec::with_capacity(stages.len());
    for (index, stage) in stages.iter().enumerate() {
        check(stage.name)?;
        progress(StageProgress {
            name: stage.name,
            index,
            count: stages.len(),
        });
        let start = Instant::now();
        (stage.run)(ctx)?;
        times.push((stage.name, start.elapsed()));
    }
    Ok(times)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn push_one(ctx: &mut Vec<u32>) -> Result<(), &'static str> {
        ctx.push(1);
        Ok(())
    }

    fn fail(_: &mut Vec<u32>) -> Result<(), &'static str> {
        Err("failed")
    }

    #[test]
    fn a_failing_stage_stops_the_run() {
        let stages = [
            Stage::new("one", push_one),
            Stage::new("fail", fail),
            Stage::new("never", push_one),
        ];
        let mut ctx = Vec::new();
        let seen = std::sync::Mutex::new(Vec::new());
        let result = run_stages(&mut ctx, &stages, &|p| seen.lock().unwrap().push(p.name));
        assert_eq!(result, Err("failed"));
        assert_eq!(ctx, [1]);
        assert_eq!(*seen.lock().unwrap(), ["one", "fail"]);
    }

    #[test]
    fn every_stage_is_timed_in_order() {
        let stages = [Stage::new("a", push_one), Stage::new("b", push_one)];
        let mut ctx = Vec::new();
        let times = run_stages(&mut ctx, &stages, &|_| {}).unwrap();
        assert_eq!(ctx, [1, 1]);
        assert_eq!(times.iter().map(|t| t.0).collect::<Vec<_>>(), ["a", "b"]);
        assert_eq!(format!("{:?}", stages[0]), "Stage(\"a\")");
    }

    #[derive(Debug, PartialEq)]
    enum StopOrFail {
        Stopped(Stopped),
    }

    impl From<Stopped> for StopOrFail {
        fn from(s: Stopped) -> Self {
            StopOrFail::Stopped(s)
        }
    }

    fn push_one_stoppable(ctx: &mut Vec<u32>) -> Result<(), StopOrFail> {
        ctx.push(1);
        Ok(())
    }

    #[test]
    fn a_stop_request_ends_the_run_before_the_next_stage() {
        let stop = StopRequest::new();
        let stages = [
            Stage::new("a", push_one_stoppable),
            Stage::new("b", push_one_stoppable),
        ];
        let mut ctx = Vec::new();
        // The request is made while stage "a" reports its start: "a" still runs, "b" not.
        let result = run_stages_until(&mut ctx, &stages, &|_| stop.request(), &stop);
        assert_eq!(result, Err(StopOrFail::Stopped(Stopped { before: "b" })));
        assert_eq!(ctx, [1]);
        let fresh = StopRequest::new();
        let times = run_stages_until(&mut ctx, &stages, &|_| {}, &fresh).unwrap();
        assert_eq!(times.len(), 2);
    }
}
