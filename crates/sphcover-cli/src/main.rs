//! The `sphcover` command: processing of scanned geometry with spherically supported functions.

mod args;
mod commands;
mod exit;
mod interrupt;
mod memory_limit;
mod preflight;
mod report;
mod skeleton_memory;
mod value_samples;
mod volume_input;

use std::process::ExitCode;

use clap::Parser;

use crate::args::{Cli, Command};
use crate::report::Reporter;

fn main() -> ExitCode {
    let cli = match Cli::try_parse() {
        Ok(cli) => cli,
        Err(e) => {
            // clap prints help/version to stdout with success, usage errors to stderr.
            let code = if e.use_stderr() {
                exit::USAGE
            } else {
                exit::SUCCESS
            };
            let _ = e.print();
            return ExitCode::from(code);
        }
    };
    if matches!(cli.command, Command::Recon(_)) {
        sphcover_recon::keep_freed_memory();
    }
    let reporter = Reporter::new(cli.global.verbose, cli.global.quiet);
    if let Err(e) = configure_threads(cli.global.threads, &reporter) {
        reporter.error(&e);
        return ExitCode::from(exit::USAGE);
    }
    if let Err(e) = preflight::check_outputs(&cli.command) {
        reporter.error(&e);
        return ExitCode::from(exit::code_for(&e));
    }
    let stale = interrupt::remove_stale_temporaries(&cli.command);
    for path in &stale.removed {
        reporter.warn(&format!(
            "removed {}, the temporary file of a run that ended while writing",
            path.display()
        ));
    }
    for path in &stale.unknown {
        reporter.warn(&format!(
            "{} looks like the temporary file of an earlier run; remove it unless another run is writing this output",
            path.display()
        ));
    }
    // Before any work: from here on an interrupt removes the run's partial outputs.
    let ending = match interrupt::install(interrupt::InProgressOutputs::of(&cli.command)) {
        Ok(ending) => ending,
        Err(e) => {
            reporter.error(&anyhow::anyhow!(
                "cannot install the interrupt handler: {e}"
            ));
            return ExitCode::from(exit::FAILURE);
        }
    };
    let result = match &cli.command {
        Command::Info(a) => commands::info::run(a, &reporter),
        Command::Recon(a) => commands::recon::run(a, &reporter),
        Command::Skeleton(a) => commands::skeleton::run(a, &reporter),
        Command::Cover(a) => commands::cover::run(a, &reporter),
        Command::Tetra(a) => commands::tetra::run(a, &reporter),
        Command::Render(a) => commands::render::run(a, &reporter),
    };
    // A run that failed because the handler removed its files mid-stage ends as interrupted.
    ending.wait_if_set();
    match result {
        Ok(()) => ExitCode::from(exit::SUCCESS),
        Err(e) => {
            reporter.error(&e);
            ExitCode::from(exit::code_for(&e))
        }
    }
}

/// The most worker threads `--threads` starts per logical core.
const MAX_THREADS_PER_CORE: usize = 4;

/// Sizes rayon's global pool. Results never depend on the thread count (every parallel loop
/// in the libraries is deterministic), so this only trades speed for CPU share.
fn configure_threads(threads: Option<usize>, reporter: &Reporter) -> anyhow::Result<()> {
    if let Some(mut n) = threads {
        if n == 0 {
            anyhow::bail!("--threads must be at least 1");
        }
        // More threads than this only cost start-up time and memory (each has its own stack
        // and scratch), and the output does not depend on the count.
        let cores = std::thread::available_parallelism().map_or(1, |c| c.get());
        if n > MAX_THREADS_PER_CORE * cores {
            reporter.warn(&format!(
                "--threads {n} is more than {MAX_THREADS_PER_CORE} per logical core; using {}",
                MAX_THREADS_PER_CORE * cores
            ));
            n = MAX_THREADS_PER_CORE * cores;
        }
        rayon::ThreadPoolBuilder::new()
            .num_threads(n)
            .build_global()
            .map_err(|e| anyhow::anyhow!("cannot start {n} threads: {e}"))?;
    }
    Ok(())
}
