//! Atomic output: a file appears complete or not at all.
//!
//! The data goes to a temporary file in the target directory (same file system, so the final
//! rename is atomic), which is flushed, synced and renamed over the target only when every
//! byte was written. On any error the temporary file is removed and an existing output is
//! left untouched, so an interrupted or failing run never leaves a truncated file that a
//! later step would read as valid.

use std::fs;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

use super::error::IoError;

/// Buffer between the encoders and the file: large enough that writes are few.
const BUFFER_BYTES: usize = 1 << 20;

/// Writes `path` atomically through `write`, refusing to overwrite any of `inputs`.
///
/// `write` receives a buffered writer; its `io::Error` is reported as
/// [`IoError::Write`] naming `path`. An output equal to one of `inputs` (compared by
/// canonical path, so `./a.ply`, `dir/../a.ply` and symbolic links are caught; the output
/// need not exist yet) is refused with [`IoError::OutputIsInput`] before anything is written.
pub fn write_atomic<F>(path: &Path, inputs: &[PathBuf], write: F) -> Result<(), IoError>
where
    F: FnOnce(&mut dyn Write) -> std::io::Result<()>,
{
    let write_error = |source: std::io::Error| IoError::Write {
        path: path.to_path_buf(),
        source,
    };
    let directory = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    };
    let Some(file_name) = path.file_name() else {
        return Err(write_error(std::io::Error::new(
            std::io::ErrorKind::InvalidInput,
            "the output path names no file",
        )));
    };
    let canonical_output = match fs::canonicalize(path) {
        Ok(p) => Some(p),
        // The output does not exist yet: its directory decides where it will be.
        Err(_) => fs::canonicalize(&directory).ok().map(|d| d.join(file_name)),
    };
    if let Some(output) = &canonical_output
        && inputs
            .iter()
            .filter_map(|input| fs::canonicalize(input).ok())
            .any(|input| &input == output)
    {
        return Err(IoError::OutputIsInput {
            path: path.to_path_buf(),
        });
    }

    let mut builder = tempfile::Builder::new();
    // `.NAME.PID.` + random: the process id tells a later run whether the writer still runs,
    // so that one killed while writing (SIGKILL, a file-size limit) does not leave its
    // temporary file for ever.
    let mut prefix = std::ffi::OsString::from(".");
    prefix.push(file_name);
    prefix.push(format!(".{}.", std::process::id()));
    builder.prefix(&prefix).suffix(".tmp");
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        // Like a plain `File::create`: readable by others unless the umask says otherwise
        // (a temporary file is private by default).
        builder.permissions(fs::Permissions::from_mode(0o666));
    }
    let temp = builder.tempfile_in(&directory).map_err(write_error)?;
    if let Ok(existing) = fs::metadata(path) {
        // Replacing a file keeps its permissions, as an in-place write would.
        temp.as_file()
            .set_permissions(existing.permissions())
            .map_err(write_error)?;
    }

    let mut writer = BufWriter::with_capacity(BUFFER_BYTES, temp);
    write(&mut writer).map_err(write_error)?;
    writer.flush().map_err(write_error)?;
    let temp = writer
        .into_inner()
        .map_err(|e| write_error(e.into_error()))?;
    temp.as_file().sync_all().map_err(write_error)?;
    temp.persist(path).map_err(|e| write_error(e.error))?;
    Ok(())
}
