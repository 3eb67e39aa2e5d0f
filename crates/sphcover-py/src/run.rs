//! Long calls: the work runs on a thread of its own with the interpreter released, while the
//! calling thread waits in short slices, hands progress to the Python callback and lets
//! Python look at its signals.
//!
//! Ctrl-C (or any signal handler that raises) therefore ends the call within one slice, about
//! 50 ms: the exception propagates at once and the work is asked to stop through a
//! [`StopRequest`]. The pipelines honour the request at their next stage boundary, so the
//! abandoned thread may go on computing for the rest of the current stage (seconds on a large
//! scan) before it exits and frees its memory; its result is dropped.

use std::sync::Arc;
use std::sync::mpsc::{self, RecvTimeoutError};
use std::thread;
use std::time::Duration;

use pyo3::exceptions::PyRuntimeError;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};
use sphcover_core::{StageProgress, StopRequest, on_threads};

/// How long the calling thread waits for news before it looks at Python's signals.
const SLICE: Duration = Duration::from_millis(50);

/// What the work receives: where to report stages, and the request to stop.
pub struct Context {
    stages: mpsc::Sender<StageProgress>,
    stop: Arc<StopRequest>,
}

impl Context {
    /// Reports the start of a stage to the caller's progress callback.
    pub fn stage(&self, stage: StageProgress) {
        // The caller may be gone (interrupted): then nobody listens, which is fine.
        let _ = self.stages.send(stage);
    }

    /// The request the caller makes when it is interrupted.
    pub fn stop(&self) -> &StopRequest {
        &self.stop
    }
}

/// Runs `work` on its own thread (on a pool of `threads` workers when given) with the
/// interpreter released, calling `progress(name, index, count)` as stages start, and returns
/// its result; raises at once what a Python signal handler (or the callback) raises
/// meanwhile, after asking the work to stop.
pub fn run<T, F>(
    py: Python<'_>,
    progress: Option<&Bound<'_, PyAny>>,
    threads: Option<usize>,
    work: F,
) -> PyResult<T>
where
    T: Send + 'static,
    F: FnOnce(&Context) -> PyResult<T> + Send + 'static,
{
    let (stage_tx, stage_rx) = mpsc::channel::<StageProgress>();
    let (done_tx, mut done_rx) = mpsc::channel::<PyResult<T>>();
    let stop = Arc::new(StopRequest::new());
    let context = Context {
        stages: stage_tx,
        stop: Arc::clone(&stop),
    };
    let worker = move || {
        let result = match threads {
            Some(n) => on_threads(n, || work(&context)),
            None => work(&context),
        };
        let _ = done_tx.send(result);
    };
    thread::Builder::new()
        .name("sphcover-work".to_owned())
        .spawn(worker)
        .map_err(|e| PyRuntimeError::new_err(format!("cannot start a work thread: {e}")))?;

    // Hands the stages reported so far to the callback, in order.
    let deliver = || -> PyResult<()> {
        while let Ok(s) = stage_rx.try_recv() {
            if let Some(callback) = progress {
                callback.call1((s.name, s.index, s.count))?;
            }
        }
        Ok(())
    };
    loop {
        if let Err(e) = deliver() {
            stop.request();
            return Err(e);
        }
        // The receiver is not `Sync`: it moves into the detached closure and back.
        let (received, rx) = py.detach(move || (done_rx.recv_timeout(SLICE), done_rx));
        done_rx = rx;
        match received {
            Ok(result) => {
                deliver()?;
                return result;
            }
            Err(RecvTimeoutError::Timeout) => {
                if let Err(e) = py.check_signals() {
                    stop.request();
                    return Err(e);
                }
            }
            Err(RecvTimeoutError::Disconnected) => {
                return Err(PyRuntimeError::new_err(
                    "internal error: the work thread ended without a result (a panic; please report it)",
                ));
            }
        }
    }
}

/// A pipeline's stage timings as the stats dicts hold them: `[{"stage", "seconds"}, …]`.
pub fn stage_times<'py>(
    py: Python<'py>,
    stages: &[(&'static str, Duration)],
) -> PyResult<Bound<'py, PyList>> {
    let list = PyList::empty(py);
    for (name, time) in stages {
        let stage = PyDict::new(py);
        stage.set_item("stage", *name)?;
        stage.set_item("seconds", time.as_secs_f64())?;
        list.append(stage)?;
    }
    Ok(list)
}
