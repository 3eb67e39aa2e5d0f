//! Runs an external command and measures its wall time, CPU time and peak memory.
//!
//! Peak memory is the maximum resident set size the kernel reports when the process is
//! reaped (`wait4`'s `ru_maxrss`). The standard library does not expose it and the workspace
//! denies `unsafe`, so the command runs under GNU `time` (`/usr/bin/time -f`), which prints
//! exactly those fields. Where GNU `time` is missing, wall time is measured here and the
//! memory is reported as unknown rather than guessed.
//!
//! On a virtual machine the hypervisor may run other guests on the cores this one was
//! given; the time it takes is the *steal* column of Linux's `/proc/stat`. Read before and
//! after the run, it tells a slow run on a shared host from a slow program: on the 2-core
//! VM of `docs/benchmarks.md`, a run with more than a few percent stolen measures the host's
//! load, not the tool (*Reading the times* there).

use std::io::Read;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

/// GNU time, which reports `ru_maxrss` of the command it waits for.
const GNU_TIME: &str = "/usr/bin/time";

/// How a measured command ended.
#[derive(Clone, Debug, PartialEq)]
pub enum RunOutcome {
    /// Exit status 0.
    Success,
    /// A non-zero exit status (or death by a signal), with the last line of its stderr.
    Failed {
        /// Exit code, if the process exited normally.
        code: Option<i32>,
        /// The last non-empty line of stderr.
        message: String,
    },
    /// Killed after the time limit.
    TimedOut,
    /// The command could not be started.
    NotStarted(String),
}

impl RunOutcome {
    /// Why the run left nothing to score, as a table's status says it (`timeout` is the
    /// limit it ran under); `None` when it exited with status 0.
    pub fn failure(&self, timeout: Duration) -> Option<String> {
        match self {
            RunOutcome::Success => None,
            RunOutcome::Failed { code, message } => Some(format!(
                "failed ({}): {message}",
                code.map_or_else(|| "signal".to_string(), |c| format!("exit {c}"))
            )),
            RunOutcome::TimedOut => Some(format!("timed out after {} s", timeout.as_secs())),
            RunOutcome::NotStarted(m) => Some(format!("not started: {m}")),
        }
    }
}

/// What one run cost.
#[derive(Clone, Debug, PartialEq)]
pub struct RunMeasurement {
    /// How it ended.
    pub outcome: RunOutcome,
    /// Wall-clock seconds.
    pub wall_seconds: f64,
    /// User plus system CPU seconds, when known.
    pub cpu_seconds: Option<f64>,
    /// Peak resident memory in MiB, when known.
    pub peak_mib: Option<f64>,
    /// The share of the machine's CPU time (all cores, over the run) that the hypervisor
    /// gave to other guests, in percent; `None` where `/proc/stat` is unavailable.
    pub steal_percent: Option<f64>,
    /// The full stderr of the command (without GNU time's own line).
    pub stderr: String,
}

impl RunMeasurement {
    /// True when the command exited with status 0.
    pub fn succeeded(&self) -> bool {
        self.outcome == RunOutcome::Success
    }
}

/// Runs `argv` (program and arguments, no shell) in `cwd` with a time limit, measuring it.
/// Stdout is discarded; stderr is kept.
pub fn run_measured(argv: &[String], cwd: &Path, timeout: Duration) -> RunMeasurement {
    let not_started = |m: String| RunMeasurement {
        outcome: RunOutcome::NotStarted(m),
        wall_seconds: 0.0,
        cpu_seconds: None,
        peak_mib: None,
        steal_percent: None,
        stderr: String::new(),
    };
    let Some((program, args)) = argv.split_first() else {
        return not_started("empty command".into());
    };
    let gnu_time = Path::new(GNU_TIME).is_file();
    let report = std::env::temp_dir().join(format!(
        "sphcover-bench-time-{}-{}",
        std::process::id(),
        unique()
    ));
    let mut cmd = if gnu_time {
        let mut c = Command::new(GNU_TIME);
        c.arg("-f")
            .arg("%e %U %S %M")
            .arg("-o")
            .arg(&report)
            .arg("--")
            .arg(program)
            .args(args);
        c
    } else {
        let mut c = Command::new(program);
        c.args(args);
        c
    };
    cmd.current_dir(cwd)
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(Stdio::piped());
    let ticks_before = machine_ticks();
    let start = Instant::now();
    let mut child = match cmd.spawn() {
        Ok(c) => c,
        Err(e) => return not_started(format!("{program}: {e}")),
    };
    // Drain stderr on a thread so a chatty command cannot block on a full pipe.
    let mut pipe = child.stderr.take();
    let reader = std::thread::spawn(move || {
        let mut s = String::new();
        if let Some(p) = pipe.as_mut() {
            let _ = p.read_to_string(&mut s);
        }
        s
    });
    let mut timed_out = false;
    let status = loop {
        match child.try_wait() {
            Ok(Some(status)) => break Some(status),
            Ok(None) => {}
            Err(_) => break None,
        }
        if start.elapsed() > timeout {
            timed_out = true;
            // Under GNU time the measured process is a grandchild: end it first, so time
            // reports and exits, then make sure time itself is gone.
            for pid in children_of(child.id()) {
                let _ = Command::new("kill")
                    .arg("-KILL")
                    .arg(pid.to_string())
                    .status();
            }
            let _ = child.kill();
            break child.wait().ok();
        }
        std::thread::sleep(Duration::from_millis(20));
    };
    let wall = start.elapsed().as_secs_f64();
    let steal_percent = ticks_before
        .zip(machine_ticks())
        .and_then(|(before, after)| after.steal_percent_since(&before));
    let stderr = reader.join().unwrap_or_default();
    let times = std::fs::read_to_string(&report).ok();
    let _ = std::fs::remove_file(&report);
    let parsed = times.as_deref().and_then(parse_gnu_time);

    let outcome = if timed_out {
        RunOutcome::TimedOut
    } else {
        match status {
            Some(s) if s.success() => RunOutcome::Success,
            Some(s) => RunOutcome::Failed {
                code: s.code(),
                message: last_line(&stderr),
            },
            None => RunOutcome::Failed {
                code: None,
                message: "could not wait for the process".into(),
            },
        }
    };
    RunMeasurement {
        outcome,
        wall_seconds: parsed.map_or(wall, |p| p.0),
        cpu_seconds: parsed.map(|p| p.1),
        peak_mib: parsed.map(|p| p.2),
        steal_percent,
        stderr,
    }
}

/// The machine's CPU time so far, summed over its cores, in clock ticks.
#[derive(Clone, Copy, Debug, PartialEq)]
struct MachineTicks {
    /// Every state: user, nice, system, idle, iowait, irq, softirq and steal.
    total: u64,
    /// Steal alone.
    steal: u64,
}

impl MachineTicks {
    /// Percent of the ticks since `before` that were stolen; `None` when none passed.
    fn steal_percent_since(&self, before: &MachineTicks) -> Option<f64> {
        let total = self.total.checked_sub(before.total)?;
        let steal = self.steal.checked_sub(before.steal)?;
        (total > 0).then(|| 100.0 * steal as f64 / total as f64)
    }
}

/// The machine's ticks from `/proc/stat`, or `None` where it cannot be read.
fn machine_ticks() -> Option<MachineTicks> {
    parse_proc_stat(&std::fs::read_to_string("/proc/stat").ok()?)
}

/// The aggregate `cpu` line of `/proc/stat`: `cpu user nice system idle iowait irq softirq
/// steal guest guest_nice`. The guest times are already counted in user and nice, so they
/// are left out of the total. Kernels before 2.6.11 have no steal column: `None`.
fn parse_proc_stat(stat: &str) -> Option<MachineTicks> {
    let line = stat
        .lines()
        .find(|l| l.split_whitespace().next() == Some("cpu"))?;
    let fields: Vec<u64> = line
        .split_whitespace()
        .skip(1)
        .take(8)
        .map(str::parse)
        .collect::<Result<_, _>>()
        .ok()?;
    (fields.len() == 8).then(|| MachineTicks {
        total: fields.iter().sum(),
        steal: fields[7],
    })
}

/// `(wall s, cpu s, peak MiB)` from GNU time's `%e %U %S %M` line (its last line; earlier
/// lines hold messages such as "Command exited with non-zero status").
fn parse_gnu_time(report: &str) -> Option<(f64, f64, f64)> {
    let line = report.lines().rev().find(|l| !l.trim().is_empty())?;
    let f: Vec<f64> = line
        .split_whitespace()
        .map(str::parse)
        .collect::<Result<_, _>>()
        .ok()?;
    match f[..] {
        [e, u, s, kib] => Some((e, u + s, kib / 1024.0)),
        _ => None,
    }
}

/// The last non-empty line of `s`, trimmed.
fn last_line(s: &str) -> String {
    s.lines()
        .rev()
        .map(str::trim)
        .find(|l| !l.is_empty())
        .unwrap_or("")
        .to_string()
}

/// Direct children of process `pid`, from `/proc` (empty where that is unavailable).
fn children_of(pid: u32) -> Vec<u32> {
    let path = PathBuf::from(format!("/proc/{pid}/task/{pid}/children"));
    std::fs::read_to_string(path)
        .unwrap_or_default()
        .split_whitespace()
        .filter_map(|s| s.parse().ok())
        .collect()
}

/// A number unique within this process, for temporary file names.
fn unique() -> u64 {
    use std::sync::atomic::{AtomicU64, Ordering};
    static NEXT: AtomicU64 = AtomicU64::new(0);
    NEXT.fetch_add(1, Ordering::Relaxed)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn argv(s: &[&str]) -> Vec<String> {
        s.iter().map(|x| x.to_string()).collect()
    }

    #[test]
    fn failures_say_why_and_success_says_nothing() {
        let limit = Duration::from_secs(30);
        assert_eq!(RunOutcome::Success.failure(limit), None);
        let failed = RunOutcome::Failed {
            code: Some(2),
            message: "bad input".into(),
        };
        assert_eq!(failed.failure(limit).unwrap(), "failed (exit 2): bad input");
        let killed = RunOutcome::Failed {
            code: None,
            message: String::new(),
        };
        assert_eq!(killed.failure(limit).unwrap(), "failed (signal): ");
        assert_eq!(
            RunOutcome::TimedOut.failure(limit).unwrap(),
            "timed out after 30 s"
        );
        assert_eq!(
            RunOutcome::NotStarted("no such file".into())
                .failure(limit)
                .unwrap(),
            "not started: no such file"
        );
    }

    #[test]
    fn gnu_time_lines_parse() {
        assert_eq!(
            parse_gnu_time("Command exited with non-zero status 1\n1.50 2.00 0.25 20480\n"),
            Some((1.5, 2.25, 20.0))
        );
        assert_eq!(parse_gnu_time("garbage"), None);
        assert_eq!(parse_gnu_time(""), None);
    }

    #[test]
    fn proc_stat_gives_the_steal_share() {
        let before = parse_proc_stat(
            "cpu  100 5 50 800 10 0 5 30 7 0\ncpu0 50 2 25 400 5 0 2 15 3 0\nintr 1 2\n",
        )
        .unwrap();
        assert_eq!(
            before,
            MachineTicks {
                total: 1000,
                steal: 30
            }
        );
        let after = parse_proc_stat("cpu  300 5 70 900 10 0 5 130 9 0\n").unwrap();
        // 420 ticks passed, 100 of them stolen.
        let share = after.steal_percent_since(&before).unwrap();
        assert!((share - 100.0 * 100.0 / 420.0).abs() < 1e-9, "{share}");
        assert_eq!(before.steal_percent_since(&before), None);
        assert_eq!(before.steal_percent_since(&after), None);
        assert_eq!(parse_proc_stat("cpu  1 2 3 4\n"), None);
        assert_eq!(parse_proc_stat("cpu0 1 2 3 4 5 6 7 8\n"), None);
        assert_eq!(parse_proc_stat("cpu  1 2 x 4 5 6 7 8\n"), None);
    }

    #[test]
    fn a_successful_command_is_measured() {
        let m = run_measured(&argv(&["true"]), Path::new("."), Duration::from_secs(10));
        assert!(m.succeeded(), "{m:?}");
        if Path::new(GNU_TIME).is_file() {
            assert!(m.peak_mib.unwrap() > 0.0);
        }
    }

    #[test]
    fn failures_carry_the_last_line_of_stderr() {
        let m = run_measured(
            &argv(&["sh", "-c", "echo first >&2; echo 'the reason' >&2; exit 3"]),
            Path::new("."),
            Duration::from_secs(10),
        );
        assert_eq!(
            m.outcome,
            RunOutcome::Failed {
                code: Some(3),
                message: "the reason".into()
            }
        );
        let m = run_measured(
            &argv(&["/nonexistent/tool"]),
            Path::new("."),
            Duration::from_secs(10),
        );
        assert!(!m.succeeded());
    }

    #[test]
    fn slow_commands_time_out() {
        let start = Instant::now();
        let m = run_measured(
            &argv(&["sleep", "30"]),
            Path::new("."),
            Duration::from_millis(300),
        );
        assert_eq!(m.outcome, RunOutcome::TimedOut);
        assert!(start.elapsed() < Duration::from_secs(10));
    }
}
