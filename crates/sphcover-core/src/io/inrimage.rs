//! INRIMAGE-4 volumes (`.inr`, `.inr.gz`), read in-house.
//!
//! * The header is text in blocks of 256 bytes: it starts `#INRIMAGE-4#{`, holds one
//!   `KEY=value` per line (lines starting `#` are comments), and its last block ends with
//!   `##}` and a newline, padded with newlines before them. The voxels follow the header
//!   block, x fastest.
//! * Keys read: `XDIM YDIM` (required), `ZDIM VDIM` (default 1), `TYPE` (`unsigned fixed`,
//!   `signed fixed`, `float`), `PIXSIZE` (`8`, `16`, `32` or `64 bits`; fixed types up to
//!   32), `SCALE` (only `2**0`, which every writer uses for plain integers), `CPU` (`decm`,
//!   `alpha`, `pc`: little-endian; `sun`, `sgi`: big-endian; required for samples of more
//!   than one byte), `VX VY VZ` voxel size (default 1), `TX TY TZ` the position of voxel
//!   `(0, 0, 0)` (default 0). Other keys are ignored.
//! * Vector images (`VDIM > 1`) are refused.
//! * 8- and 16-bit and `float` samples are stored as `f32`, 32-bit integers and `double` as
//!   `f64`, as the NIfTI reader does.
//! * gzip is recognised by its magic bytes, whatever the extension. The declared data size
//!   is checked before anything large is allocated: against the file size when
//!   uncompressed, against what DEFLATE can expand the file to when compressed, and no more
//!   than header and declared data is ever decompressed. Byte offsets in errors count from
//!   the start of the decompressed stream.

use std::fs::File;
use std::io::{BufReader, Read};
use std::path::Path;

use glam::DVec3;

use super::error::{Failure, IoError, Location, Problem};
use super::volume_file::{DecodeError, SampleType, decode_samples};
use crate::volume::Volume;

/// DEFLATE cannot expand data by more than this ratio (see the NIfTI reader).
const MAX_DEFLATE_RATIO: u64 = 1032;
/// Header blocks are this long.
const BLOCK: usize = 256;
/// No writer produces a header longer than this; a file without `##}` before it is not an
/// INRIMAGE file.
const MAX_HEADER: usize = 1 << 20;

/// What an INRIMAGE-4 header declares.
#[derive(Clone, Debug, PartialEq)]
pub struct InrimageInfo {
    /// True when the file is gzip-compressed.
    pub gzip: bool,
    /// True for big-endian samples (`CPU=sun` or `sgi`).
    pub big_endian: bool,
    /// The sample type.
    pub sample_type: SampleType,
    /// `[XDIM, YDIM, ZDIM]`.
    pub dims: [usize; 3],
    /// `VX VY VZ`.
    pub voxel_size: DVec3,
    /// `TX TY TZ`: the centre of voxel `(0, 0, 0)`.
    pub origin: DVec3,
    /// Length of the header in bytes (where the voxels start).
    pub header_size: u64,
    /// Comment lines of the header, without their `#`.
    pub comments: Vec<String>,
}

/// Reads an INRIMAGE-4 file (`.inr` or `.inr.gz`) as a [`Volume`] with axis-aligned voxels.
pub fn read_inrimage(path: &Path) -> Result<(Volume, InrimageInfo), IoError> {
    let read_error = |source| IoError::Read {
        path: path.to_path_buf(),
        source,
    };
    let file = File::open(path).map_err(read_error)?;
    let file_size = file.metadata().map_err(read_error)?.len();
    let mut reader = BufReader::with_capacity(1 << 16, file);
    let gzip = {
        let buf = std::io::BufRead::fill_buf(&mut reader).map_err(read_error)?;
        buf.starts_with(&[0x1f, 0x8b])
    };
    let result = if gzip {
        decode(flate2::read::MultiGzDecoder::new(reader), file_size, true)
    } else {
        decode(reader, file_size, false)
    };
    result.map_err(|e| e.into_io(path))
}

/// Parses an INRIMAGE-4 file held in memory (plain or gzip); `path` only names it in errors.
pub fn parse_inrimage(bytes: &[u8], path: &Path) -> Result<(Volume, InrimageInfo), IoError> {
    let size = bytes.len() as u64;
    if bytes.starts_with(&[0x1f, 0x8b]) {
        decode(flate2::read::MultiGzDecoder::new(bytes), size, true)
    } else {
        decode(bytes, size, false)
    }
    .map_err(|e| e.into_io(path))
}

fn header_error(at: usize, message: impl Into<String>) -> DecodeError {
    DecodeError::Content(Failure::header(Location::Byte(at as u64), message))
}

/// Reads up to `buf.len()` bytes, stopping early only at the end of the stream; `offset` is
/// the stream offset of `buf[0]` (for messages about corrupt gzip data).
fn fill<R: Read>(r: &mut R, buf: &mut [u8], offset: u64, gzip: bool) -> Result<usize, DecodeError> {
    let mut done = 0;
    while done < buf.len() {
        match r.read(&mut buf[done..]) {
            Ok(0) => break,
            Ok(n) => done += n,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
            Err(e)
                if gzip
                    && matches!(
                        e.kind(),
                        std::io::ErrorKind::InvalidData
                            | std::io::ErrorKind::InvalidInput
                            | std::io::ErrorKind::UnexpectedEof
                    ) =>
            {
                return Err(DecodeError::Content(Failure::syntax(
                    Location::Byte(offset + done as u64),
                    format!("corrupt gzip stream: {e}"),
                )));
            }
            Err(e) => return Err(DecodeError::Os(e)),
        }
    }
    Ok(done)
}

/// The header keys the reader uses, each with the byte offset of its line.
#[derive(Default)]
struct Keys {
    dims: [Option<(u64, usize)>; 4],
    type_name: Option<(String, usize)>,
    pixsize: Option<(u32, usize)>,
    cpu: Option<(bool, usize)>,
    voxel: [Option<f64>; 3],
    origin: [Option<f64>; 3],
    comments: Vec<String>,
}

fn parse_keys(header: &[u8]) -> Result<Keys, DecodeError> {
    let text = String::from_utf8_lossy(header);
    let mut keys = Keys::default();
    let mut at = 0usize;
    for (n, line) in text.split('\n').enumerate() {
        let line_at = at;
        at += line.len() + 1;
        if n == 0 {
            continue;
        }
        let line = line.trim();
        if line.starts_with("##}") {
            break;
        }
        if line.is_empty() {
            continue;
        }
        if let Some(comment) = line.strip_prefix('#') {
            keys.comments.push(comment.trim().to_string());
            continue;
        }
        let Some((key, value)) = line.split_once('=') else {
            return Err(header_error(
                line_at,
                format!(
                    "header line {:?} is not KEY=value",
                    super::error::token_for_message(line.as_bytes())
                ),
            ));
        };
        let (key, value) = (key.trim(), value.trim());
        let bad = |what: &str| {
            header_error(
                line_at,
                format!(
                    "{key}={} is not {what}",
                    super::error::token_for_message(value.as_bytes())
                ),
            )
        };
        let real = |what: &str| {
            value
                .parse::<f64>()
                .ok()
                .filter(|v| v.is_finite())
                .ok_or_else(|| bad(what))
        };
        match key {
            "XDIM" | "YDIM" | "ZDIM" | "VDIM" => {
                let axis = ["XDIM", "YDIM", "ZDIM", "VDIM"]
                    .iter()
                    .position(|k| *k == key)
                    .unwrap_or(0);
                let v = value
                    .parse::<u64>()
                    .ok()
                    .filter(|&v| v > 0)
                    .ok_or_else(|| bad("a positive integer"))?;
                keys.dims[axis] = Some((v, line_at));
            }
            "TYPE" => keys.type_name = Some((value.to_string(), line_at)),
            "PIXSIZE" => {
                let bits = value
                    .strip_suffix("bits")
                    .and_then(|b| b.trim().parse::<u32>().ok())
                    .ok_or_else(|| bad("a size \"N bits\""))?;
                keys.pixsize = Some((bits, line_at));
            }
            "SCALE" if value != "2**0" => {
                return Err(header_error(
                    line_at,
                    format!(
                        "SCALE={} (fixed-point scaling) is not supported; only 2**0",
                        super::error::token_for_message(value.as_bytes())
                    ),
                ));
            }
            "CPU" => {
                let big = match value {
                    "decm" | "alpha" | "pc" => false,
                    "sun" | "sgi" => true,
                    _ => return Err(bad("one of decm, alpha, pc, sun, sgi")),
                };
                keys.cpu = Some((big, line_at));
            }
            "VX" | "VY" | "VZ" => {
                let v = real("a finite voxel size")?;
                if v <= 0.0 {
                    return Err(bad("a positive voxel size"));
                }
                keys.voxel[usize::from(key.as_bytes()[1] - b'X')] = Some(v);
            }
            "TX" | "TY" | "TZ" => {
                keys.origin[usize::from(key.as_bytes()[1] - b'X')] = Some(real("a finite number")?);
            }
            _ => {}
        }
    }
    Ok(keys)
}

fn decode<R: Read>(
    mut stream: R,
    file_size: u64,
    gzip: bool,
) -> Result<(Volume, InrimageInfo), DecodeError> {
    const MAGIC: &[u8] = b"#INRIMAGE-4#{";
    let mut header = vec![0u8; BLOCK];
    let got = fill(&mut stream, &mut header, 0, gzip)?;
    if got == 0 {
        return Err(Failure::new(Location::Byte(0), Problem::EmptyFile).into());
    }
    if !header[..got].starts_with(MAGIC) {
        return Err(header_error(
            0,
            "the file does not start with \"#INRIMAGE-4#{\": not an INRIMAGE-4 file",
        ));
    }
    if got < BLOCK {
        return Err(header_error(
            got,
            "file ends inside the INRIMAGE header (no \"##}\" line)",
        ));
    }
    // The header ends with the block holding "##}".
    loop {
        let block_start = header.len() - BLOCK;
        if header[block_start..].windows(3).any(|w| w == b"##}") {
            break;
        }
        if header.len() >= MAX_HEADER {
            return Err(header_error(
                header.len(),
                format!("no \"##}}\" ends the header within {MAX_HEADER} bytes"),
            ));
        }
        header.resize(header.len() + BLOCK, 0);
        let more = fill(
            &mut stream,
            &mut header[block_start + BLOCK..],
            (block_start + BLOCK) as u64,
            gzip,
        )?;
        if more < BLOCK {
            return Err(header_error(
                block_start + BLOCK + more,
                "file ends inside the INRIMAGE header (no \"##}\" line)",
            ));
        }
    }
    let header_size = header.len();
    let keys = parse_keys(&header)?;

    let mut dims = [1u64; 4];
    for (axis, key) in ["XDIM", "YDIM", "ZDIM", "VDIM"].iter().enumerate() {
        match keys.dims[axis] {
            Some((v, _)) => dims[axis] = v,
            None if axis < 2 => {
                return Err(header_error(
                    MAGIC.len(),
                    format!("the header has no {key}"),
                ));
            }
            None => {}
        }
    }
    if let Some((v, at)) = keys.dims[3]
        && v > 1
    {
        return Err(header_error(
            at,
            format!("VDIM={v}: vector images are not supported (only VDIM=1 scalar volumes)"),
        ));
    }
    let (type_name, type_at) = keys
        .type_name
        .ok_or_else(|| header_error(MAGIC.len(), "the header has no TYPE"))?;
    let (bits, bits_at) = keys
        .pixsize
        .ok_or_else(|| header_error(MAGIC.len(), "the header has no PIXSIZE"))?;
    let sample_type = match (type_name.as_str(), bits) {
        ("unsigned fixed", 8) => SampleType::U8,
        ("signed fixed", 8) => SampleType::I8,
        ("unsigned fixed", 16) => SampleType::U16,
        ("signed fixed", 16) => SampleType::I16,
        ("unsigned fixed", 32) => SampleType::U32,
        ("signed fixed", 32) => SampleType::I32,
        ("float", 32) => SampleType::F32,
        ("float", 64) => SampleType::F64,
        ("unsigned fixed" | "signed fixed" | "float", _) => {
            return Err(header_error(
                bits_at,
                format!("PIXSIZE={bits} bits is not supported for TYPE={type_name}"),
            ));
        }
        _ => {
            return Err(header_error(
                type_at,
                format!(
                    "TYPE={} is not unsigned fixed, signed fixed or float",
                    super::error::token_for_message(type_name.as_bytes())
                ),
            ));
        }
    };
    let big_endian = match keys.cpu {
        Some((big, _)) => big,
        None if sample_type.size() == 1 => false,
        None => {
            return Err(header_error(
                MAGIC.len(),
                "the header has no CPU, so the byte order of multi-byte samples is unknown",
            ));
        }
    };

    let absurd = || header_error(MAGIC.len(), format!("dims {:?} overflow", &dims[..3]));
    let voxels = dims[..3]
        .iter()
        .try_fold(1u64, |acc, &n| acc.checked_mul(n))
        .ok_or_else(absurd)?;
    let data_bytes = voxels
        .checked_mul(sample_type.size() as u64)
        .ok_or_else(absurd)?;
    let declared_end = (header_size as u64)
        .checked_add(data_bytes)
        .ok_or_else(absurd)?;
    let truncated = |end: u64| {
        DecodeError::Content(Failure::new(
            Location::Byte(end),
            Problem::Truncated {
                element: format!("{} voxel", sample_type.name()),
                index: end.saturating_sub(header_size as u64) / sample_type.size() as u64,
                declared: voxels,
            },
        ))
    };
    if gzip {
        let bound = file_size
            .saturating_mul(MAX_DEFLATE_RATIO)
            .saturating_add(1024);
        if declared_end > bound {
            return Err(header_error(
                MAGIC.len(),
                format!(
                    "the header declares {} × {} × {} {} voxels ({declared_end} bytes with the header), more than a {file_size}-byte gzip file can hold",
                    dims[0],
                    dims[1],
                    dims[2],
                    sample_type.name()
                ),
            ));
        }
    } else if declared_end > file_size {
        return Err(truncated(file_size));
    }
    let usable = usize::try_from(data_bytes).map_err(|_| {
        header_error(
            MAGIC.len(),
            format!("dims {:?}: too large for this machine", &dims[..3]),
        )
    })?;

    // Grow as data arrives, so that a gzip stream that lies about its size stays cheap; no
    // more than the declared size is ever decompressed.
    let mut data: Vec<u8> = Vec::new();
    let chunk = 1usize << 22;
    while data.len() < usable {
        let start = data.len();
        let want = (usable - start).min(chunk);
        data.resize(start + want, 0);
        let got = fill(
            &mut stream,
            &mut data[start..],
            (header_size + start) as u64,
            gzip,
        )?;
        if got < want {
            return Err(truncated((header_size + start + got) as u64));
        }
    }

    let values = decode_samples(&data, sample_type, big_endian, None, true);
    let dims3 = [dims[0] as usize, dims[1] as usize, dims[2] as usize];
    let voxel_size = DVec3::from_array(keys.voxel.map(|v| v.unwrap_or(1.0)));
    let origin = DVec3::from_array(keys.origin.map(|v| v.unwrap_or(0.0)));
    let volume = Volume::axis_aligned(dims3, values, voxel_size, origin)
        .map_err(|e| header_error(MAGIC.len(), format!("invalid volume: {e}")))?;
    let info = InrimageInfo {
        gzip,
        big_endian,
        sample_type,
        dims: dims3,
        voxel_size,
        origin,
        header_size: header_size as u64,
        comments: keys.comments,
    };
    Ok((volume, info))
}
