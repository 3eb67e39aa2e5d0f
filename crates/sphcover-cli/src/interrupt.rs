//! Interrupts: Ctrl-C (SIGINT), SIGTERM and SIGHUP end the run at once, without leaving a
//! partial output behind.
//!
//! Every output goes through `sphcover_core::io::write_atomic`, which writes a hidden
//! temporary file `.NAME.PID.XXXXXX.tmp` beside the output and renames it over `NAME` only when
//! complete. A process ended by a signal's default action cannot remove that temporary
//! file, so the runner installs a handler: a thread woken by the signal (through
//! `signal-hook`'s self-pipe, so it runs however long the current stage is) removes the
//! temporary files of the run's outputs and exits with status 128 + the signal's number
//! (130 for Ctrl-C, 143 for SIGTERM), as shells report a process a signal ended.
//!
//! A signal ignored when the run started stays ignored (`nohup` ignores SIGHUP; background
//! jobs of a non-interactive shell ignore SIGINT), as the user who ignored it meant.
//!
//! The writer does not say which temporary file it made, so the outputs are registered
//! instead ([`InProgressOutputs`], built from the command line before any work) and the
//! handler removes the temporary files named after them that did not exist when the run
//! started: files another run was writing at that time are left alone. (The one window
//! left is a temporary file created between the handler's removal and the process's exit,
//! a few microseconds.) The output itself is never touched: it is either the previous
//! file or a complete new one.

use std::collections::HashSet;
use std::ffi::{OsStr, OsString};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};

use signal_hook::consts::signal::{SIGHUP, SIGINT, SIGTERM};
use signal_hook::iterator::Signals;

use crate::args::Command;

/// Length of the random part of `write_atomic`'s temporary names (`tempfile`'s default).
const RANDOM_CHARS: usize = 6;

/// The outputs a run may be writing, shared between the command runner and the handler.
#[derive(Clone, Debug, Default)]
pub struct InProgressOutputs {
    outputs: Arc<[PendingOutput]>,
    /// Where this run writes tile files (`recon --stream`), removed with the outputs'
    /// temporary files.
    tile_files: Option<PathBuf>,
}

/// One output and the temporary files beside it that are not this run's.
#[derive(Debug)]
struct PendingOutput {
    directory: PathBuf,
    file_name: OsString,
    /// Temporary files named after the output that existed before the run started.
    foreign: HashSet<OsString>,
}

impl InProgressOutputs {
    /// The outputs of `command` (every output path on its command line), with the temporary
    /// files already beside them noted as not this run's.
    pub fn of(command: &Command) -> InProgressOutputs {
        let mut outputs = InProgressOutputs::for_paths(&output_paths(command));
        if let Command::Recon(a) = command
            && a.stream
        {
            outputs.tile_files = Some(crate::commands::recon::scratch_directory(a));
        }
        outputs
    }

    /// Registers `paths` as the run's outputs.
    pub fn for_paths(paths: &[&Path]) -> InProgressOutputs {
        let outputs: Vec<PendingOutput> = paths
            .iter()
            .filter_map(|path| {
                let directory = directory_of(path)?;
                let file_name = path.file_name()?.to_os_string();
                let foreign = temporaries_of(&directory, &file_name)
                    .into_iter()
                    .map(|(name, _)| name)
                    .collect();
                Some(PendingOutput {
                    directory,
                    file_name,
                    foreign,
                })
            })
            .collect();
        InProgressOutputs {
            outputs: outputs.into(),
            tile_files: None,
        }
    }

    /// Removes this run's temporary files; returns how many were removed.
    pub fn remove_temporaries(&self) -> usize {
        let mut removed = 0;
        for output in self.outputs.iter() {
            for (name, _) in temporaries_of(&output.directory, &output.file_name) {
                if !output.foreign.contains(&name)
                    && std::fs::remove_file(output.directory.join(&name)).is_ok()
                {
                    removed += 1;
                }
            }
        }
        if let Some(scratch) = &self.tile_files {
            let ours = format!(
                "{}{}-",
                sphcover_recon::TILE_DIRECTORY_PREFIX,
                std::process::id()
            );
            for entry in std::fs::read_dir(scratch).into_iter().flatten().flatten() {
                if entry.file_name().to_string_lossy().starts_with(&ours)
                    && std::fs::remove_dir_all(entry.path()).is_ok()
                {
                    removed += 1;
                }
            }
        }
        removed
    }
}

/// Installs the handler of SIGINT, SIGTERM and SIGHUP (those not ignored when the run
/// started) for a run writing `outputs`: on the first of them it removes the run's
/// temporary files and exits with 128 + the signal.
pub fn install(outputs: InProgressOutputs) -> std::io::Result<Ending> {
    let ignored = ignored_signals();
    let handled: Vec<i32> = [SIGINT, SIGTERM, SIGHUP]
        .into_iter()
        .filter(|&signal| ignored & (1 << (signal - 1)) == 0)
        .collect();
    let mut signals = Signals::new(handled)?;
    let ending = Ending::default();
    let set = ending.clone();
    std::thread::Builder::new()
        .name("interrupt".to_owned())
        .spawn(move || {
            if let Some(signal) = signals.forever().next() {
                set.0.store(true, Ordering::SeqCst);
                let removed = outputs.remove_temporaries();
                eprintln!(
                    "error: interrupted by {}{}",
                    signal_name(signal),
                    match removed {
                        0 => String::new(),
                        1 => "; removed 1 partial output".to_owned(),
                        n => format!("; removed {n} partial outputs"),
                    }
                );
                std::process::exit(128 + signal);
            }
        })?;
    Ok(ending)
}

/// Set once a signal is being handled: the handler is removing the run's files (tile files
/// a stage may still be reading, among them) and then ends the process with the signal's
/// status, which the run's own result must not pre-empt ([`Ending::wait_if_set`]).
#[derive(Clone, Debug, Default)]
pub struct Ending(Arc<AtomicBool>);

impl Ending {
    /// Blocks for good when a signal is being handled (the handler exits the process);
    /// returns at once otherwise.
    pub fn wait_if_set(&self) {
        while self.0.load(Ordering::SeqCst) {
            std::thread::park();
        }
    }
}

/// The mask of signals this process ignores (bit `n - 1` for signal `n`), from
/// `/proc/self/status` (Linux); 0 (none known to be ignored) where that cannot be read.
fn ignored_signals() -> u64 {
    std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|status| {
            let line = status.lines().find(|l| l.starts_with("SigIgn:"))?;
            u64::from_str_radix(line["SigIgn:".len()..].trim(), 16).ok()
        })
        .unwrap_or(0)
}

fn signal_name(signal: i32) -> &'static str {
    match signal {
        SIGINT => "SIGINT",
        SIGTERM => "SIGTERM",
        SIGHUP => "SIGHUP",
        _ => "a signal",
    }
}

/// Every output path on the command line of `command`.
fn output_paths(command: &Command) -> Vec<&Path> {
    let mut paths: Vec<&Path> = Vec::new();
    match command {
        Command::Info(_) => {}
        Command::Recon(a) => {
            paths.push(&a.output);
            paths.extend(
                [&a.points_out, &a.cover_out, &a.report]
                    .into_iter()
                    .flatten()
                    .map(PathBuf::as_path),
            );
        }
        Command::Skeleton(a) => {
            paths.push(&a.output);
            paths.extend(a.report.as_deref());
        }
        Command::Cover(a) => paths.push(&a.output),
        Command::Tetra(a) => paths.push(&a.output),
        Command::Render(a) => paths.push(&a.output),
    }
    paths
}

/// Names of the files in `directory` that look like `write_atomic`'s temporary files for
/// `file_name`: `.{file_name}.` + the writer's process id and `.` (absent in names written by
/// earlier versions) + six letters or digits + `.tmp`; with the process id when there is one.
fn temporaries_of(directory: &Path, file_name: &OsStr) -> Vec<(OsString, Option<u32>)> {
    let Ok(entries) = std::fs::read_dir(directory) else {
        return Vec::new();
    };
    let mut prefix = OsString::from(".");
    prefix.push(file_name);
    prefix.push(".");
    let prefix = prefix.as_encoded_bytes().to_vec();
    entries
        .filter_map(Result::ok)
        .map(|entry| entry.file_name())
        .filter_map(|name| {
            let rest = name.as_encoded_bytes().strip_prefix(prefix.as_slice())?;
            let rest = rest.strip_suffix(b".tmp")?;
            let (pid, random) = match rest.iter().position(|&b| b == b'.') {
                Some(dot) => {
                    let digits = std::str::from_utf8(&rest[..dot]).ok()?;
                    let pid = digits.parse::<u32>().ok()?;
                    (Some(pid), &rest[dot + 1..])
                }
                None => (None, rest),
            };
            (random.len() == RANDOM_CHARS && random.iter().all(u8::is_ascii_alphanumeric))
                .then_some((name, pid))
        })
        .collect()
}

/// Temporary files of `command`'s outputs that earlier runs left behind.
#[derive(Debug, Default)]
pub struct StaleTemporaries {
    /// Removed: their writer no longer runs (it was killed while writing).
    pub removed: Vec<PathBuf>,
    /// Left alone: written by a version that did not record its process id, or on a
    /// system where a process cannot be looked up; another run may be writing them.
    pub unknown: Vec<PathBuf>,
}

/// Removes the temporary files of `command`'s outputs whose writing process has ended (a run
/// killed by SIGKILL, an out-of-memory kill or a file-size limit cannot remove its own), and
/// lists those whose writer cannot be told. A file another running process is writing is
/// left alone.
pub fn remove_stale_temporaries(command: &Command) -> StaleTemporaries {
    let mut stale = StaleTemporaries::default();
    let processes_visible = Path::new("/proc/self").exists();
    for path in output_paths(command) {
        let (Some(directory), Some(file_name)) = (directory_of(path), path.file_name()) else {
            continue;
        };
        for (name, pid) in temporaries_of(&directory, file_name) {
            let temporary = directory.join(&name);
            match pid {
                Some(pid) if processes_visible => {
                    let running = Path::new("/proc").join(pid.to_string()).exists();
                    if !running && std::fs::remove_file(&temporary).is_ok() {
                        stale.removed.push(temporary);
                    }
                }
                _ => stale.unknown.push(temporary),
            }
        }
    }
    stale
}

/// The directory an output goes to (`.` for a bare file name).
fn directory_of(path: &Path) -> Option<PathBuf> {
    path.file_name()?;
    Some(match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_the_runs_own_temporaries_are_removed() {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("mesh.ply");
        // Another run's temporary file, there before this run started.
        std::fs::write(dir.path().join(".mesh.ply.AAAAAA.tmp"), b"").unwrap();
        let outputs = InProgressOutputs::for_paths(&[&out]);
        for name in [
            ".mesh.ply.b3xY9z.tmp", // this run's
            ".mesh.ply.b3xY9.tmp",  // too short to be a temporary file
            ".mesh.plyX.b3xY9z.tmp",
            ".other.ply.b3xY9z.tmp",
            "mesh.ply",
        ] {
            std::fs::write(dir.path().join(name), b"").unwrap();
        }
        assert_eq!(outputs.remove_temporaries(), 1);
        let mut left: Vec<String> = std::fs::read_dir(dir.path())
            .unwrap()
            .map(|e| e.unwrap().file_name().into_string().unwrap())
            .collect();
        left.sort();
        assert_eq!(
            left,
            [
                ".mesh.ply.AAAAAA.tmp",
                ".mesh.ply.b3xY9.tmp",
                ".mesh.plyX.b3xY9z.tmp",
                ".other.ply.b3xY9z.tmp",
                "mesh.ply"
            ]
        );
    }

    #[test]
    fn temporary_names_carry_the_writers_process_id() {
        let dir = tempfile::tempdir().unwrap();
        for name in [
            ".mesh.ply.1234.b3xY9z.tmp",
            ".mesh.ply.b3xY9z.tmp",
            ".mesh.ply.12a4.b3xY9z.tmp",
            ".mesh.ply.1234.b3xY9.tmp",
        ] {
            std::fs::write(dir.path().join(name), b"").unwrap();
        }
        let mut found = temporaries_of(dir.path(), OsStr::new("mesh.ply"));
        found.sort();
        assert_eq!(
            found,
            [
                (OsString::from(".mesh.ply.1234.b3xY9z.tmp"), Some(1234)),
                (OsString::from(".mesh.ply.b3xY9z.tmp"), None),
            ]
        );
    }

    #[test]
    fn an_output_in_the_working_directory_has_a_directory() {
        let outputs = InProgressOutputs::for_paths(&[Path::new("mesh.ply")]);
        assert_eq!(outputs.outputs[0].directory, Path::new("."));
    }
}
