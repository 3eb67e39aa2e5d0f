//! End-to-end benchmark harness for `sphcover`, with peers side by side.
//!
//! Five binaries live here:
//!
//! * `recon-bench` generates the standard synthetic scans of ground-truth meshes
//!   (`sphcover_evaluation::scan_simulation`), runs `sphcover recon` and any peer given as a command
//!   template on each, measures wall time, CPU time and peak memory, scores every output
//!   against the ground truth (`sphcover_evaluation::recon_metrics`) and prints one markdown
//!   table;
//! * `skeleton-bench` runs `sphcover skeleton` with `--method ridge` and `--method nms` on the
//!   CT phantoms and tabulates cost and topology;
//! * `head-ct-bench` does the same on the generated clinical head CT
//!   (`sphcover_evaluation::head_ct_phantom`) with the clinical scores of
//!   `sphcover_evaluation::head_sheet_metrics`;
//! * `recon-score` scores one reconstruction against its ground truth as JSON;
//! * `tetra-bench` times `sphcover_tetra::RegularTriangulation` against CGAL's
//!   `Regular_triangulation_3` (`peers/cgal_regular.cpp`) on generated weighted point sets
//!   ([`sphere_sets`]) and checks that both give the same tetrahedra ([`tet_lists`],
//!   [`cgal_peer`]).
//!
//! A tool that fails or is missing gets a row that says so; the run goes on. The
//! per-function criterion benchmarks live next to each crate (`cargo bench -p
//! sphcover-core`). This library holds what the binaries share: peer command templates,
//! measured runs, markdown tables, and the sphere sets and tetrahedron lists of `tetra-bench`.
//!
//! ```
//! use std::path::Path;
//! use std::time::Duration;
//! use sphcover_benches::command_template::CommandTemplate;
//! use sphcover_benches::markdown_table::{MarkdownTable, fixed};
//! use sphcover_benches::measured_run::{RunOutcome, run_measured};
//!
//! // A peer as `--peer` takes it: {in} and {out} become the scan and the output mesh.
//! let peer = CommandTemplate::parse("poisson=PoissonRecon --in {in} --out {out} --depth 10")?;
//! let argv = peer.expand(Path::new("scan.ply"), Path::new("mesh.ply"));
//! assert_eq!(argv[..5], ["PoissonRecon", "--in", "scan.ply", "--out", "mesh.ply"]);
//!
//! // A tool that is not installed gives a row that says so, and the run goes on (under GNU
//! // time, when present, it is time's "command not found").
//! let argv = ["no-such-peer-binary".to_string()];
//! let run = run_measured(&argv, Path::new("."), Duration::from_secs(5));
//! assert!(!run.succeeded());
//! assert!(matches!(run.outcome, RunOutcome::NotStarted(_) | RunOutcome::Failed { .. }));
//!
//! let mut table = MarkdownTable::new(["tool", "wall s"]);
//! table.push(vec![peer.name.clone(), fixed(None, 2)]);
//! assert_eq!(table.render().lines().nth(2), Some("| poisson | –      |"));
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
#![deny(missing_docs)]

pub mod cgal_peer;
pub mod command_template;
pub mod markdown_table;
pub mod measured_run;
pub mod sphere_sets;
pub mod tet_lists;

use std::path::{Path, PathBuf};

/// Opens a file of fixed-size records of `record_bytes` each (the binary files exchanged
/// with the CGAL peer) and returns a buffered reader and the record count; an error naming
/// the file when its size is not a whole number of `what`.
pub(crate) fn open_records(
    path: &Path,
    record_bytes: u64,
    what: &str,
) -> std::io::Result<(std::io::BufReader<std::fs::File>, usize)> {
    let file = std::fs::File::open(path)?;
    let bytes = file.metadata()?.len();
    if bytes % record_bytes != 0 {
        return Err(std::io::Error::new(
            std::io::ErrorKind::InvalidData,
            format!(
                "{}: {bytes} bytes is not a whole number of {what}",
                path.display()
            ),
        ));
    }
    Ok((
        std::io::BufReader::new(file),
        (bytes / record_bytes) as usize,
    ))
}

/// The workspace root (the parent of this crate's directory).
pub fn workspace_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .map_or_else(|| PathBuf::from("."), Path::to_path_buf)
}

/// Where cargo puts release binaries: `$CARGO_TARGET_DIR/release` when that is set, else
/// `target/release` under the workspace root.
pub fn release_dir() -> PathBuf {
    match std::env::var_os("CARGO_TARGET_DIR") {
        Some(dir) if !dir.is_empty() => {
            let dir = PathBuf::from(dir);
            if dir.is_absolute() {
                dir.join("release")
            } else {
                workspace_root().join(dir).join("release")
            }
        }
        _ => workspace_root().join("target").join("release"),
    }
}

/// This process's command line, each argument quoted for a POSIX shell where needed, so a
/// table's header can be pasted back into a terminal.
pub fn command_line() -> String {
    std::env::args()
        .map(|a| shell_quote(&a))
        .collect::<Vec<_>>()
        .join(" ")
}

/// `word` as a POSIX shell would need it: unchanged when it holds only safe characters,
/// otherwise in single quotes (a single quote inside becomes `'\''`).
pub fn shell_quote(word: &str) -> String {
    let safe = |c: char| c.is_ascii_alphanumeric() || "-_./=:,+@%".contains(c);
    if !word.is_empty() && word.chars().all(safe) {
        word.to_string()
    } else {
        format!("'{}'", word.replace('\'', "'\\''"))
    }
}

/// The last line of a tool's stderr, shortened for a table cell.
pub fn short_message(message: &str, max_chars: usize) -> String {
    let m = message.trim();
    if m.chars().count() <= max_chars {
        m.to_string()
    } else {
        let cut: String = m.chars().take(max_chars.saturating_sub(1)).collect();
        format!("{cut}…")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn words_are_quoted_only_when_needed() {
        assert_eq!(shell_quote("--sizes"), "--sizes");
        assert_eq!(shell_quote("a=b/c.ply"), "a=b/c.ply");
        assert_eq!(shell_quote("p=x {in} {out}"), "'p=x {in} {out}'");
        assert_eq!(shell_quote("it's"), "'it'\\''s'");
        assert_eq!(shell_quote(""), "''");
        // Splitting the quoted form gives the word back.
        for w in ["p=x {in} {out}", "it's", "a\"b", ""] {
            assert_eq!(
                command_template::split_words(&shell_quote(w)).unwrap(),
                vec![w.to_string()]
            );
        }
    }

    #[test]
    fn messages_are_shortened_on_char_boundaries() {
        assert_eq!(short_message("  short ", 10), "short");
        assert_eq!(short_message("ééééé", 3), "éé…");
    }

    #[test]
    fn the_workspace_root_holds_the_workspace_manifest() {
        assert!(workspace_root().join("Cargo.toml").is_file());
        assert!(workspace_root().join("benches").is_dir());
    }
}
