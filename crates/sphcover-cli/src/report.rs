//! What the command tells a person while it runs: progress bars, stage timings, warnings and
//! errors, all on stderr so that stdout carries only results.

use std::io::IsTerminal;
use std::time::{Duration, Instant};

use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use sphcover_core::StageProgress;

/// Where progress, timings and messages go, and how much of them.
#[derive(Debug)]
pub struct Reporter {
    verbose: u8,
    quiet: bool,
    bars: bool,
}

impl Reporter {
    /// A reporter for the given `-v` count and `--quiet`. Progress bars are drawn only when
    /// stderr is a terminal and `--quiet` is off.
    pub fn new(verbose: u8, quiet: bool) -> Reporter {
        Reporter {
            verbose,
            quiet,
            bars: !quiet && std::io::stderr().is_terminal(),
        }
    }

    /// A progress bar over `len` steps, or a spinner when the length is unknown; hidden when
    /// bars are off. The caller finishes it with `finish_and_clear`.
    pub fn progress(&self, len: Option<u64>, message: &str) -> ProgressBar {
        if !self.bars {
            return ProgressBar::hidden();
        }
        let bar = ProgressBar::with_draw_target(len, ProgressDrawTarget::stderr());
        let style = match len {
            Some(_) => {
                ProgressStyle::with_template("{msg:>12} [{bar:40}] {percent:>3}% {elapsed_precise}")
                    .map(|s| s.progress_chars("=> "))
            }
            None => ProgressStyle::with_template("{spinner} {msg} {elapsed_precise}"),
        };
        bar.set_style(style.unwrap_or_else(|_| ProgressStyle::default_bar()));
        bar.set_message(message.to_owned());
        if len.is_none() {
            bar.enable_steady_tick(Duration::from_millis(100));
        }
        bar
    }

    /// Starts timing a stage; its time is printed with `-v` when the guard is finished.
    pub fn stage(&self, name: &str) -> Stage<'_> {
        Stage {
            reporter: self,
            name: name.to_owned(),
            start: Instant::now(),
        }
    }

    /// The closing report of a command, printed unless `--quiet`.
    pub fn summary(&self, message: &str) {
        if !self.quiet {
            eprintln!("{message}");
        }
    }

    /// A note on what the run decided for the user (an automatic setting and its reason),
    /// printed unless `--quiet`.
    pub fn note(&self, message: &str) {
        if !self.quiet {
            eprintln!("note: {message}");
        }
    }

    /// A warning, printed unless `--quiet`.
    pub fn warn(&self, message: &str) {
        if !self.quiet {
            eprintln!("warning: {message}");
        }
    }

    /// A note printed with `-v`.
    pub fn detail(&self, message: &str) {
        if self.verbose > 0 {
            eprintln!("{message}");
        }
    }

    /// The error that ended the run, with its chain of causes; always printed.
    pub fn error(&self, err: &anyhow::Error) {
        eprintln!("error: {err}");
        for cause in err.chain().skip(1) {
            eprintln!("  caused by: {cause}");
        }
    }
}

impl Reporter {
    /// A bar over the stages of a pipeline, with the running stage's name and the elapsed
    /// time ticking during long stages; hidden when bars are off. Each stage is shown with
    /// [`show_stage`] as it starts; the caller finishes the bar with `finish_and_clear`.
    pub fn stage_bar(&self, message: &str) -> ProgressBar {
        if !self.bars {
            return ProgressBar::hidden();
        }
        let bar = ProgressBar::with_draw_target(Some(1), ProgressDrawTarget::stderr());
        let style = ProgressStyle::with_template(
            "{spinner} {msg:<32} [{bar:30}] {pos}/{len} stages {elapsed_precise}",
        )
        .map(|s| s.progress_chars("=> "));
        bar.set_style(style.unwrap_or_else(|_| ProgressStyle::default_bar()));
        bar.set_message(message.to_owned());
        bar.enable_steady_tick(Duration::from_millis(100));
        bar
    }
}

/// Moves a [`Reporter::stage_bar`] to `stage` as it starts: the stages before it are done.
pub fn show_stage(bar: &ProgressBar, stage: StageProgress) {
    bar.set_length(stage.count as u64);
    bar.set_position(stage.index as u64);
    bar.set_message(stage.name);
}

/// A timed stage of a command.
#[derive(Debug)]
pub struct Stage<'a> {
    reporter: &'a Reporter,
    name: String,
    start: Instant,
}

impl Stage<'_> {
    /// Ends the stage, prints its time with `-v`, and returns it.
    pub fn finish(self) -> Duration {
        let elapsed = self.start.elapsed();
        self.reporter.detail(&format!(
            "  {:<24} {:>9.3} s",
            self.name,
            elapsed.as_secs_f64()
        ));
        elapsed
    }
}
