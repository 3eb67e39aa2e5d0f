//! Errors of the readers and writers: every one names the file, and every complaint about
//! the content of a file names where in it (a line for text, a byte offset for binary data).

use std::fmt;
use std::path::{Path, PathBuf};

use super::byte_size::format_byte_size;

/// Where in a file a problem was found.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Location {
    /// A 1-based line number (text formats and PLY headers).
    Line(u64),
    /// A 0-based byte offset from the start of the file (binary data).
    Byte(u64),
}

impl fmt::Display for Location {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Location::Line(n) => write!(f, "line {n}"),
            Location::Byte(n) => write!(f, "byte {n}"),
        }
    }
}

/// What is wrong with the content of a file (see [`IoError::Malformed`]).
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum Problem {
    /// The file has no byte at all.
    #[error("empty file")]
    EmptyFile,
    /// The header (PLY, OFF, STL) is not what the format requires.
    #[error("{0}")]
    Header(String),
    /// A record has the wrong number of fields.
    #[error("{element} {index}: expected {expected} numbers, found {found}")]
    WrongFieldCount {
        /// Element name (`vertex`, `face`, …).
        element: String,
        /// 0-based index of the record within its element.
        index: u64,
        /// Number of fields the layout requires.
        expected: usize,
        /// Number of fields on the line.
        found: usize,
    },
    /// A field is not a number of the required kind.
    #[error("{element} {index}: bad number {token:?}{expected}")]
    BadNumber {
        /// Element name.
        element: String,
        /// 0-based index of the record within its element.
        index: u64,
        /// The offending text (cut to 40 characters).
        token: String,
        /// What was expected, with a leading separator (`""` or `" (expected an integer)"`).
        expected: &'static str,
    },
    /// The file ends inside, or before, a record the header declares.
    #[error(
        "{element} {index} truncated (the file declares {declared} {element} record{})",
        plural(.declared)
    )]
    Truncated {
        /// Element name.
        element: String,
        /// 0-based index of the first record that is missing or incomplete.
        index: u64,
        /// Number of records the header declares.
        declared: u64,
    },
    /// A face refers to a vertex that does not exist.
    #[error("face {face}: vertex index {index} out of range (the file has {vertices} vertices)")]
    FaceIndexOutOfRange {
        /// 0-based face index in the file.
        face: u64,
        /// The index as written in the file (1-based for OBJ, relative when negative).
        index: i64,
        /// Number of vertices.
        vertices: u64,
    },
    /// Anything else that breaks the format's grammar.
    #[error("{0}")]
    Syntax(String),
}

/// The error of every reader and writer in [`crate::io`].
#[derive(Debug, thiserror::Error)]
pub enum IoError {
    /// The file could not be opened or read.
    #[error("{}: cannot read: {source}", path.display())]
    Read {
        /// The file.
        path: PathBuf,
        /// What the operating system said.
        #[source]
        source: std::io::Error,
    },
    /// The extension names no supported format.
    #[error(
        "{}: unknown file format (extension must be one of .ply .obj .off .stl .xyz .pwn .txt .sph .spheres .las .laz, .vtp .vtu (written only), or a volume: .nii .nii.gz .inr .inr.gz)",
        path.display()
    )]
    UnknownFormat {
        /// The file.
        path: PathBuf,
    },
    /// The content breaks the format.
    #[error("{}: {at}: {problem}", path.display())]
    Malformed {
        /// The file.
        path: PathBuf,
        /// Where the problem was found.
        at: Location,
        /// What the problem is.
        problem: Problem,
    },
    /// Vertices with NaN or infinite coordinates were found and the policy refuses them.
    #[error(
        "{}: {at}: vertex {index} is not finite ({vertices} vert{} with {coordinates} NaN or infinite value{}; the non-finite policy can drop or keep them)",
        path.display(),
        if *.vertices == 1 { "ex" } else { "ices" },
        plural(.coordinates)
    )]
    NonFinite {
        /// The file.
        path: PathBuf,
        /// Where the first offending vertex is.
        at: Location,
        /// 0-based index of the first offending vertex.
        index: u64,
        /// Number of offending vertices.
        vertices: u64,
        /// Number of non-finite values among their positions, normals and radii.
        coordinates: u64,
    },
    /// Voxels holding NaN or an infinity were found and the policy refuses them (or none is
    /// finite).
    #[error(
        "{}: voxel ({}, {}, {}) is not finite ({count} voxel{} hold{} NaN or an infinity{})",
        path.display(),
        voxel[0],
        voxel[1],
        voxel[2],
        plural(.count),
        if *.count == 1 { "s" } else { "" },
        if *.all { ": every voxel" } else { "" }
    )]
    NonFiniteVoxels {
        /// The file.
        path: PathBuf,
        /// Grid coordinates `(i, j, k)` of the first offending voxel.
        voxel: [usize; 3],
        /// Number of offending voxels.
        count: u64,
        /// True when no voxel is finite (no policy can help).
        all: bool,
    },
    /// A sphere set was asked for but the file has no radius per vertex.
    #[error(
        "{}: the file holds no sphere radii (a PLY `radius` vertex property or 4 columns x y z r)",
        path.display()
    )]
    NoRadius {
        /// The file.
        path: PathBuf,
    },
    /// The output format cannot hold the data it was given.
    #[error("{}: {format} cannot hold {what}", path.display())]
    Unsupported {
        /// The output file.
        path: PathBuf,
        /// The format's name.
        format: &'static str,
        /// What it cannot hold, with a hint of what to do.
        what: String,
    },
    /// The output path is one of the inputs.
    #[error("{}: refusing to overwrite an input file", path.display())]
    OutputIsInput {
        /// The output file.
        path: PathBuf,
    },
    /// Creating, writing or renaming the output failed (unwritable directory, full disk…).
    #[error("{}: cannot write: {source}", path.display())]
    Write {
        /// The output file.
        path: PathBuf,
        /// What the operating system said.
        #[source]
        source: std::io::Error,
    },
    /// The data handed to a writer is inconsistent (attribute arrays of the wrong length,
    /// triangle indices out of range, more vertices than `u32` indices reach).
    #[error("{}: {message}", path.display())]
    InvalidData {
        /// The output file.
        path: PathBuf,
        /// What is inconsistent.
        message: String,
    },
    /// The file is well formed, but holding what its header declares would take more memory
    /// than [`ReadOptions::max_bytes`](super::ReadOptions::max_bytes) allows. Refused from
    /// the header, before the data is read or allocated.
    #[error(
        "{}: declares {declared}: {} in memory, above the memory limit {}",
        path.display(),
        format_byte_size(*bytes),
        format_byte_size(*limit)
    )]
    OverMemoryLimit {
        /// The file.
        path: PathBuf,
        /// What the header declares, e.g. `512 x 512 x 300 voxels of int16 (150.0 MiB
        /// decoded, held as float32)`.
        declared: String,
        /// Bytes the reader would allocate for it.
        bytes: u64,
        /// The limit.
        limit: u64,
    },
    /// The memory for what the file declares was within the limit but could not be
    /// allocated (an address-space or cgroup limit, or an exhausted machine).
    #[error(
        "{}: cannot allocate {} for {what}",
        path.display(),
        format_byte_size(*bytes)
    )]
    OutOfMemory {
        /// The file.
        path: PathBuf,
        /// What the memory was for.
        what: String,
        /// Bytes asked for.
        bytes: u64,
    },
}

/// The plural ending of a count.
fn plural(n: &u64) -> &'static str {
    if *n == 1 { "" } else { "s" }
}

impl IoError {
    /// True when the error lies with what the caller asked for (a missing, unreadable or
    /// malformed input, an input larger than the memory limit, an unknown format, an output
    /// the format cannot hold, an output that would overwrite an input) rather than with the
    /// machine (a failed write or allocation) or with the caller's data structures.
    /// Command-line tools map it to their "bad input" exit code.
    pub fn is_bad_input(&self) -> bool {
        match self {
            IoError::Read { .. }
            | IoError::UnknownFormat { .. }
            | IoError::Malformed { .. }
            | IoError::NonFinite { .. }
            | IoError::NonFiniteVoxels { .. }
            | IoError::NoRadius { .. }
            | IoError::Unsupported { .. }
            | IoError::OutputIsInput { .. }
            | IoError::OverMemoryLimit { .. } => true,
            IoError::Write { .. } | IoError::InvalidData { .. } | IoError::OutOfMemory { .. } => {
                false
            }
        }
    }
}

/// Why a reader stopped, before its caller attaches the file name: a problem in the content
/// and its place, or a size the read must not allocate.
#[derive(Clone, Debug, PartialEq)]
pub(crate) enum Failure {
    /// The content breaks the format ([`IoError::Malformed`]).
    Content { at: Location, problem: Problem },
    /// The declared data is above the memory limit ([`IoError::OverMemoryLimit`]).
    OverLimit {
        declared: String,
        bytes: u64,
        limit: u64,
    },
    /// The allocator refused memory within the limit ([`IoError::OutOfMemory`]).
    OutOfMemory { what: String, bytes: u64 },
    /// Voxels are not finite ([`IoError::NonFiniteVoxels`]).
    NonFiniteVoxels {
        voxel: [usize; 3],
        count: u64,
        all: bool,
    },
}

impl Failure {
    pub(crate) fn new(at: Location, problem: Problem) -> Failure {
        Failure::Content { at, problem }
    }

    pub(crate) fn syntax(at: Location, message: impl Into<String>) -> Failure {
        Failure::new(at, Problem::Syntax(message.into()))
    }

    pub(crate) fn header(at: Location, message: impl Into<String>) -> Failure {
        Failure::new(at, Problem::Header(message.into()))
    }

    pub(crate) fn into_io(self, path: &Path) -> IoError {
        let path = path.to_path_buf();
        match self {
            Failure::Content { at, problem } => IoError::Malformed { path, at, problem },
            Failure::OverLimit {
                declared,
                bytes,
                limit,
            } => IoError::OverMemoryLimit {
                path,
                declared,
                bytes,
                limit,
            },
            Failure::OutOfMemory { what, bytes } => IoError::OutOfMemory { path, what, bytes },
            Failure::NonFiniteVoxels { voxel, count, all } => IoError::NonFiniteVoxels {
                path,
                voxel,
                count,
                all,
            },
        }
    }
}

/// The memory a reader sets aside for what a file declares, checked against the read's limit
/// ([`ReadOptions::max_bytes`](super::ReadOptions::max_bytes)) before each allocation.
#[derive(Debug)]
pub(crate) struct MemoryBudget {
    limit: Option<u64>,
    bytes: u64,
    declared: Vec<String>,
}

impl MemoryBudget {
    pub(crate) fn new(limit: Option<u64>) -> MemoryBudget {
        MemoryBudget {
            limit,
            bytes: 0,
            declared: Vec::new(),
        }
    }

    /// Counts `bytes` more, for what `declared` describes (`"1000 vertices"`); refuses when
    /// the total passes the limit, naming everything counted so far.
    pub(crate) fn reserve(
        &mut self,
        bytes: u64,
        declared: impl FnOnce() -> String,
    ) -> Result<(), Failure> {
        self.bytes = self.bytes.saturating_add(bytes);
        let Some(limit) = self.limit else {
            return Ok(());
        };
        self.declared.push(declared());
        if self.bytes > limit {
            return Err(Failure::OverLimit {
                declared: self.declared.join(" and "),
                bytes: self.bytes,
                limit,
            });
        }
        Ok(())
    }
}

/// The memory of the records a text file holds, counted as they are read: a text file
/// declares no count to check first. The arrays holding the records grow by doubling, so a
/// read may hold up to twice what its records take: twice their bytes is what is checked
/// against the limit ([`ReadOptions::max_bytes`](super::ReadOptions::max_bytes)), before each
/// record is stored.
#[derive(Debug)]
pub(crate) struct GrowingBudget {
    limit: Option<u64>,
    bytes: u64,
}

impl GrowingBudget {
    pub(crate) fn new(limit: Option<u64>) -> GrowingBudget {
        GrowingBudget { limit, bytes: 0 }
    }

    /// How many records of `bytes` each to reserve room for when about `estimate` are
    /// expected: the estimate, capped where the reservation alone would pass the limit.
    pub(crate) fn capped(&self, estimate: usize, bytes: u64) -> usize {
        match self.limit {
            Some(limit) => {
                estimate.min(usize::try_from(limit / 2 / bytes.max(1)).unwrap_or(usize::MAX))
            }
            None => estimate,
        }
    }

    /// Counts `bytes` more for the next record; refuses once twice the total passes the
    /// limit, with what `declared` says was read so far (`"1000 points by line 1001"`).
    #[inline]
    pub(crate) fn add(
        &mut self,
        bytes: u64,
        declared: impl FnOnce() -> String,
    ) -> Result<(), Failure> {
        self.bytes = self.bytes.saturating_add(bytes);
        match self.limit {
            Some(limit) if self.bytes.saturating_mul(2) > limit => Err(Failure::OverLimit {
                declared: format!("{} (text, with room for its arrays to grow)", declared()),
                bytes: self.bytes.saturating_mul(2),
                limit,
            }),
            _ => Ok(()),
        }
    }
}

/// Cuts a token for an error message so a megabyte of garbage does not end up in it.
pub(crate) fn token_for_message(token: &[u8]) -> String {
    const MAX: usize = 40;
    let text = String::from_utf8_lossy(&token[..token.len().min(MAX)]).into_owned();
    if token.len() > MAX {
        format!("{text}…")
    } else {
        text
    }
}
