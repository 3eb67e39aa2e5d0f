//! Checks of the command line's output paths before any work: a run that would fail at its
//! last step (a wrong extension, a missing or unwritable directory, an output that is also an
//! input) must fail in milliseconds, not after the reconstruction.

use std::ffi::OsStr;
use std::path::{Path, PathBuf};

use crate::args::{Command, SkeletonMethod};
use crate::exit::BadInput;

/// One output of a command: where it goes, what it is and the extensions its writer takes.
struct Output<'a> {
    path: &'a Path,
    what: &'static str,
    extensions: &'static [&'static str],
}

const MESH: &[&str] = &["ply", "obj", "off", "stl", "vtp", "vtu"];
const PLY: &[&str] = &["ply"];
const POINTS: &[&str] = &["ply", "xyz", "vtp"];
const JSON: &[&str] = &["json"];
const TET_MESH: &[&str] = &["vtk", "vtu", "txt", "tets"];
const PNG: &[&str] = &["png"];

/// Every output of `command`, with the inputs it must not overwrite.
fn outputs(command: &Command) -> (Vec<Output<'_>>, Vec<&Path>) {
    let out = |path: &'static str, p, e| Output {
        path: p,
        what: path,
        extensions: e,
    };
    match command {
        Command::Info(_) => (Vec::new(), Vec::new()),
        Command::Recon(a) => {
            let mut outputs = vec![out("the mesh output (-o)", &a.output, MESH)];
            if let Some(p) = &a.points_out {
                outputs.push(out("--points-out", p, PLY));
            }
            if let Some(p) = &a.cover_out {
                outputs.push(out("--cover-out", p, PLY));
            }
            if let Some(p) = &a.report {
                outputs.push(out("--report", p, JSON));
            }
            (outputs, vec![&a.input])
        }
        Command::Skeleton(a) => {
            let sheet = match a.method {
                SkeletonMethod::Ridge => out("the sheet output (-o)", &a.output, MESH),
                SkeletonMethod::Nms => {
                    out("the point output of --method nms (-o)", &a.output, POINTS)
                }
            };
            let mut outputs = vec![sheet];
            if let Some(p) = &a.report {
                outputs.push(out("--report", p, JSON));
            }
            (outputs, vec![&a.input])
        }
        Command::Cover(a) => (
            vec![out("the cover output (-o)", &a.output, PLY)],
            vec![&a.input],
        ),
        Command::Tetra(a) => (
            vec![out("the tetrahedral mesh output (-o)", &a.output, TET_MESH)],
            vec![&a.spheres],
        ),
        Command::Render(a) => (
            vec![out("the image output (-o)", &a.output, PNG)],
            vec![&a.input],
        ),
    }
}

/// Refuses an output with an extension its writer does not take, that is a directory, one of
/// the inputs or named twice (bad usage, exit 2), or in a directory that does not exist or
/// cannot be written (a runtime failure, exit 1, as a failed write would be).
pub fn check_outputs(command: &Command) -> anyhow::Result<()> {
    let (outputs, inputs) = outputs(command);
    let bad = |path: &Path, why: String| -> anyhow::Error {
        BadInput(format!("{}: {why}", path.display())).into()
    };
    let inputs: Vec<PathBuf> = inputs.iter().map(|p| identity(p)).collect();
    let mut seen: Vec<PathBuf> = Vec::new();
    for output in &outputs {
        let path = output.path;
        if !has_extension(path, output.extensions) {
            let list: Vec<String> = output.extensions.iter().map(|e| format!(".{e}")).collect();
            return Err(bad(
                path,
                format!("{} must end in {}", output.what, list.join(", ")),
            ));
        }
        let directory = match path.parent() {
            Some(p) if !p.as_os_str().is_empty() => p,
            _ => Path::new("."),
        };
        // A missing or unwritable directory is the machine's state, not a wrong command line:
        // a runtime failure (exit 1), as when a write fails later; only found sooner.
        if !directory.is_dir() {
            anyhow::bail!(
                "{}: cannot write: {} {}",
                path.display(),
                directory.display(),
                if directory.exists() {
                    "is not a directory"
                } else {
                    "does not exist"
                }
            );
        }
        if path.is_dir() {
            return Err(bad(path, "is a directory".to_owned()));
        }
        let id = identity(path);
        if inputs.contains(&id) {
            return Err(bad(
                path,
                "an output must not overwrite an input".to_owned(),
            ));
        }
        if seen.contains(&id) {
            return Err(bad(path, "named as two outputs".to_owned()));
        }
        seen.push(id);
        if let Err(e) = probe_writable(directory) {
            anyhow::bail!(
                "{}: cannot write in {}: {e}",
                path.display(),
                directory.display()
            );
        }
    }
    Ok(())
}

/// True when the file name of `path` ends in `.` and one of `extensions` (any case).
fn has_extension(path: &Path, extensions: &[&str]) -> bool {
    path.extension()
        .and_then(OsStr::to_str)
        .is_some_and(|e| extensions.iter().any(|x| e.eq_ignore_ascii_case(x)))
}

/// The path as the file system resolves it (its directory canonicalised, so `./a.ply`,
/// `a.ply` and a link to the directory name one file); the path as given where the directory
/// cannot be resolved.
fn identity(path: &Path) -> PathBuf {
    if let Ok(p) = path.canonicalize() {
        return p;
    }
    let directory = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    };
    match (directory.canonicalize(), path.file_name()) {
        (Ok(d), Some(name)) => d.join(name),
        _ => path.to_path_buf(),
    }
}

/// Creates and removes an empty file in `directory`: the one test of permission that also
/// holds for read-only mounts, ACLs and full quota tables.
fn probe_writable(directory: &Path) -> std::io::Result<()> {
    let probe = directory.join(format!(".sphcover-probe.{}.tmp", std::process::id()));
    std::fs::OpenOptions::new()
        .write(true)
        .create_new(true)
        .open(&probe)?;
    std::fs::remove_file(&probe)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn extensions_match_in_any_case() {
        assert!(has_extension(Path::new("a/b.PLY"), MESH));
        assert!(has_extension(Path::new("b.stl"), MESH));
        assert!(!has_extension(Path::new("b.nii"), MESH));
        assert!(!has_extension(Path::new("ply"), MESH));
    }

    #[test]
    fn a_relative_and_an_absolute_name_of_one_file_are_one_identity() {
        let dir = tempfile::tempdir().unwrap();
        let absolute = dir.path().join("x.ply");
        let dotted = dir.path().join(".").join("x.ply");
        assert_eq!(identity(&absolute), identity(&dotted));
        std::fs::write(&absolute, b"").unwrap();
        assert_eq!(identity(&absolute), identity(&dotted));
    }

    #[test]
    fn a_writable_directory_keeps_no_probe() {
        let dir = tempfile::tempdir().unwrap();
        probe_writable(dir.path()).unwrap();
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0);
        assert!(probe_writable(&dir.path().join("missing")).is_err());
    }
}
