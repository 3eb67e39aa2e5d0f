//! Tile files: the samples of each tile's box and halo, written while the scan streams past
//! and read back one tile at a time, so that no process holds the whole scan.
//!
//! A tile file is a sequence of little-endian records in the scan's order: the position's
//! three `f64`, the normal's three `f64`, and the scanner's confidence as one more `f64`
//! when the scan has one. The files live in a directory of their own that is removed,
//! with everything in it, when the [`TileFiles`] is dropped.

use std::fs::File;
use std::io::{BufReader, Read, Write};
use std::path::{Path, PathBuf};

use sphcover_core::DVec3;

use super::ReconError;

/// The tile files of a run go into a directory named this, the process id, `-` and a
/// number, inside the scratch directory; a handler of signals that end the process can
/// remove `{prefix}{pid}-*` there.
pub const TILE_DIRECTORY_PREFIX: &str = ".sphcover-tiles-";

/// Buffered bytes of all tiles together before they are written (each tile gets its share,
/// between 16 KiB and 1 MiB).
const BUFFERED: usize = 64 << 20;

/// The samples of one tile as read back.
#[derive(Clone, Debug, Default, PartialEq)]
pub(super) struct TileSamples {
    pub points: Vec<DVec3>,
    pub normals: Vec<DVec3>,
    pub scanner: Option<Vec<f64>>,
}

/// Where a run's tile files are and how their records are laid out: all a process needs
/// to read a tile's samples and to store and read their labels.
#[derive(Clone, Debug, PartialEq)]
pub(super) struct TileDirectory {
    pub dir: PathBuf,
    /// Whether each record carries the scanner's confidence.
    pub scanner: bool,
}

/// The tile files of one run, in a directory removed with them.
pub(super) struct TileFiles {
    directory: TileDirectory,
    buffers: Vec<Vec<u8>>,
    flush_at: usize,
}

impl TileFiles {
    /// A new, empty directory for `tiles` tile files inside `scratch` (created if needed).
    pub fn create(scratch: &Path, tiles: usize, scanner: bool) -> Result<TileFiles, ReconError> {
        std::fs::create_dir_all(scratch).map_err(|e| scratch_error(scratch, &e))?;
        let dir = (0u32..)
            .map(|k| scratch.join(format!("{TILE_DIRECTORY_PREFIX}{}-{k}", std::process::id())))
            .find(|d| !d.exists())
            .unwrap_or_else(|| scratch.join(TILE_DIRECTORY_PREFIX));
        std::fs::create_dir(&dir).map_err(|e| scratch_error(&dir, &e))?;
        let flush_at = (BUFFERED / tiles.max(1)).clamp(16 << 10, 1 << 20);
        Ok(TileFiles {
            directory: TileDirectory { dir, scanner },
            buffers: vec![Vec::new(); tiles],
            flush_at,
        })
    }

    /// Where the files are.
    pub fn directory(&self) -> &TileDirectory {
        &self.directory
    }

    /// Appends a sample to tile `tile`.
    pub fn push(
        &mut self,
        tile: usize,
        point: DVec3,
        normal: DVec3,
        scanner: Option<f64>,
    ) -> Result<(), ReconError> {
        let buffer = &mut self.buffers[tile];
        for v in point.to_array().into_iter().chain(normal.to_array()) {
            buffer.extend_from_slice(&v.to_le_bytes());
        }
        if self.directory.scanner {
            buffer.extend_from_slice(&scanner.unwrap_or(1.0).to_le_bytes());
        }
        if buffer.len() >= self.flush_at {
            self.flush(tile)?;
        }
        Ok(())
    }

    fn flush(&mut self, tile: usize) -> Result<(), ReconError> {
        let path = self.directory.path(tile);
        let buffer = std::mem::take(&mut self.buffers[tile]);
        if buffer.is_empty() {
            return Ok(());
        }
        let mut file = std::fs::OpenOptions::new()
            .create(true)
            .append(true)
            .open(&path)
            .map_err(|e| scratch_error(&path, &e))?;
        file.write_all(&buffer)
            .map_err(|e| scratch_error(&path, &e))?;
        // The buffer's allocation is kept for the tile's next records.
        self.buffers[tile] = buffer;
        self.buffers[tile].clear();
        Ok(())
    }

    /// Writes out what is still buffered and frees the buffers.
    pub fn finish(&mut self) -> Result<(), ReconError> {
        for tile in 0..self.buffers.len() {
            self.flush(tile)?;
        }
        self.buffers = vec![Vec::new(); self.buffers.len()];
        Ok(())
    }
}

impl TileDirectory {
    fn record_bytes(&self) -> usize {
        if self.scanner { 56 } else { 48 }
    }

    fn path(&self, tile: usize) -> PathBuf {
        self.dir.join(format!("tile-{tile}.bin"))
    }

    /// Samples written to tile `tile` (none when it has no file).
    pub fn samples(&self, tile: usize) -> Result<usize, ReconError> {
        let path = self.path(tile);
        match std::fs::metadata(&path) {
            Ok(m) => Ok((m.len() / self.record_bytes() as u64) as usize),
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(0),
            Err(e) => Err(scratch_error(&path, &e)),
        }
    }

    /// Writes `normals` over the normals of tile `tile`'s samples, in order.
    pub fn replace_normals(&self, tile: usize, normals: &[DVec3]) -> Result<(), ReconError> {
        let path = self.path(tile);
        let replaced = path.with_extension("bin.new");
        let file = File::open(&path).map_err(|e| scratch_error(&path, &e))?;
        let mut reader = BufReader::with_capacity(1 << 20, file);
        let out = File::create(&replaced).map_err(|e| scratch_error(&replaced, &e))?;
        let mut writer = std::io::BufWriter::with_capacity(1 << 20, out);
        let mut record = vec![0u8; self.record_bytes()];
        for n in normals {
            reader
                .read_exact(&mut record)
                .map_err(|e| scratch_error(&path, &e))?;
            for (k, v) in n.to_array().into_iter().enumerate() {
                record[24 + 8 * k..32 + 8 * k].copy_from_slice(&v.to_le_bytes());
            }
            writer
                .write_all(&record)
                .map_err(|e| scratch_error(&replaced, &e))?;
        }
        writer.flush().map_err(|e| scratch_error(&replaced, &e))?;
        drop(writer);
        std::fs::rename(&replaced, &path).map_err(|e| scratch_error(&path, &e))
    }

    /// Reads tile `tile`'s samples back.
    pub fn read(&self, tile: usize) -> Result<TileSamples, ReconError> {
        let n = self.samples(tile)?;
        let mut samples = TileSamples {
            points: Vec::with_capacity(n),
            normals: Vec::with_capacity(n),
            scanner: self.scanner.then(|| Vec::with_capacity(n)),
        };
        if n == 0 {
            return Ok(samples);
        }
        let path = self.path(tile);
        let file = File::open(&path).map_err(|e| scratch_error(&path, &e))?;
        let mut reader = BufReader::with_capacity(1 << 20, file);
        let mut record = vec![0u8; self.record_bytes()];
        let value = |r: &[u8], k: usize| {
            f64::from_le_bytes(r[8 * k..8 * k + 8].try_into().unwrap_or_default())
        };
        for _ in 0..n {
            reader
                .read_exact(&mut record)
                .map_err(|e| scratch_error(&path, &e))?;
            samples.points.push(DVec3::new(
                value(&record, 0),
                value(&record, 1),
                value(&record, 2),
            ));
            samples.normals.push(DVec3::new(
                value(&record, 3),
                value(&record, 4),
                value(&record, 5),
            ));
            if let Some(s) = samples.scanner.as_mut() {
                s.push(value(&record, 6));
            }
        }
        Ok(samples)
    }
}

impl TileDirectory {
    fn labels_path(&self, tile: usize) -> PathBuf {
        self.dir.join(format!("tile-{tile}.labels"))
    }

    /// Stores what the tile's function said of each of its samples (in the order of its
    /// file): its confidence, whether it is an outlier and whether it is isolated.
    pub fn write_labels(
        &self,
        tile: usize,
        confidence: &[f64],
        outliers: &[bool],
        isolated: &[bool],
    ) -> Result<(), ReconError> {
        let mut bytes = Vec::with_capacity(9 * confidence.len());
        for ((c, &o), &i) in confidence.iter().zip(outliers).zip(isolated) {
            bytes.extend_from_slice(&c.to_le_bytes());
            bytes.push(u8::from(o) | (u8::from(i) << 1));
        }
        let path = self.labels_path(tile);
        std::fs::write(&path, bytes).map_err(|e| scratch_error(&path, &e))
    }

    /// The labels [`TileFiles::write_labels`] stored for tile `tile`: `None` when none were.
    pub fn read_labels(&self, tile: usize) -> Result<Option<TileLabels>, ReconError> {
        let path = self.labels_path(tile);
        if !path.exists() {
            return Ok(None);
        }
        let bytes = std::fs::read(&path).map_err(|e| scratch_error(&path, &e))?;
        let samples = self.samples(tile)?;
        if bytes.len() != 9 * samples {
            return Err(ReconError::Scratch(format!(
                "{}: {} bytes for {samples} samples",
                path.display(),
                bytes.len(),
            )));
        }
        let mut labels = TileLabels::default();
        for record in bytes.chunks_exact(9) {
            labels.confidence.push(f64::from_le_bytes(
                record[..8].try_into().unwrap_or_default(),
            ));
            labels.outliers.push(record[8] & 1 != 0);
            labels.isolated.push(record[8] & 2 != 0);
        }
        Ok(Some(labels))
    }
}

/// What a tile's function said of each of its samples.
#[derive(Clone, Debug, Default, PartialEq)]
pub(super) struct TileLabels {
    pub confidence: Vec<f64>,
    pub outliers: Vec<bool>,
    pub isolated: Vec<bool>,
}

impl Drop for TileFiles {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.directory.dir);
    }
}

fn scratch_error(path: &Path, e: &std::io::Error) -> ReconError {
    ReconError::Scratch(format!("{}: {e}", path.display()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn samples_read_back_as_written_and_the_directory_goes() {
        let scratch = std::env::temp_dir().join(format!("sphcover-spill-{}", std::process::id()));
        let mut files = TileFiles::create(&scratch, 3, true).unwrap();
        let dir = files.directory().dir.clone();
        // Few enough bytes per flush that the records cross several writes.
        files.flush_at = 100;
        for i in 0..50 {
            let p = DVec3::new(i as f64, -(i as f64), 0.5);
            files
                .push(i % 3, p, DVec3::Z, Some(i as f64 / 50.0))
                .unwrap();
        }
        files.finish().unwrap();
        let directory = files.directory().clone();
        let counts: Vec<usize> = (0..3).map(|t| directory.samples(t).unwrap()).collect();
        assert_eq!(counts, [17, 17, 16]);
        let tile = directory.read(1).unwrap();
        let expected: Vec<DVec3> = (0..50)
            .filter(|i| i % 3 == 1)
            .map(|i| DVec3::new(i as f64, -(i as f64), 0.5))
            .collect();
        assert_eq!(tile.points, expected);
        assert_eq!(tile.scanner.unwrap()[0], 1.0 / 50.0);
        assert!(dir.exists());
        drop(files);
        assert!(!dir.exists());
        std::fs::remove_dir_all(&scratch).unwrap();
    }
}
