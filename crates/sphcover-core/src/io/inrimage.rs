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
//!   is checked before anything large is allocated (the steps in [`super::volume_file`]):
//!   against the file size when uncompressed, against what DEFLATE can expand the file to
//!   when compressed, and against the memory limit; a gzip stream that goes on past the
//!   declared data is refused one byte later. Byte offsets in errors count from the start of
//!   the decompressed stream.

use std::path::Path;

use glam::DVec3;

use super::ReadOptions;
use super::error::{Failure, IoError, Location, Problem};
use super::volume_file::{DecodeError, SampleDecoder, SampleType, VolumeStream, VoxelData};
use crate::volume::Volume;

/// The first bytes of every INRIMAGE-4 file.
const MAGIC: &[u8] = b"#INRIMAGE-4#{";
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
    /// Voxels found holding NaN or an infinity, handled as [`ReadOptions::non_finite`] says
    /// (0 when only the header was read).
    pub non_finite_voxels: u64,
}

/// Reads an INRIMAGE-4 file (`.inr` or `.inr.gz`) as a [`Volume`] with axis-aligned voxels.
/// A volume whose values would take more than `options.max_bytes` is refused from the header
/// with [`IoError::OverMemoryLimit`].
pub fn read_inrimage(
    path: &Path,
    options: &ReadOptions,
) -> Result<(Volume, InrimageInfo), IoError> {
    let mut stream = VolumeStream::open(path)?;
    decode(&mut stream, options).map_err(|e| e.into_io(path))
}

/// Reads only the header of an INRIMAGE-4 file, with every check [`read_inrimage`] makes
/// before it reads the voxels.
pub fn read_inrimage_info(path: &Path) -> Result<InrimageInfo, IoError> {
    let mut stream = VolumeStream::open(path)?;
    read_header(&mut stream)
        .map(|(info, _)| info)
        .map_err(|e| e.into_io(path))
}

/// Parses an INRIMAGE-4 file held in memory (plain or gzip); `path` only names it in errors.
pub fn parse_inrimage(
    bytes: &[u8],
    path: &Path,
    options: &ReadOptions,
) -> Result<(Volume, InrimageInfo), IoError> {
    decode(&mut VolumeStream::from_bytes(bytes), options).map_err(|e| e.into_io(path))
}

fn header_error(at: usize, message: impl Into<String>) -> DecodeError {
    DecodeError::Content(Failure::header(Location::Byte(at as u64), message))
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

/// Reads and checks the header, and checks the declared data against what the stream can
/// hold; reads nothing past the header.
fn read_header(stream: &mut VolumeStream<'_>) -> Result<(InrimageInfo, VoxelData), DecodeError> {
    let gzip = stream.gzip();
    let mut header = vec![0u8; BLOCK];
    let got = stream.fill(&mut header)?;
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
        let more = stream.fill(&mut header[block_start + BLOCK..])?;
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
    let data = VoxelData {
        dims: [dims[0], dims[1], dims[2]],
        frames: 1,
        decoder: SampleDecoder::new(sample_type, big_endian, None, true),
        start: header_size as u64,
    };
    let file_size = stream.file_size();
    if declared_end > stream.capacity() {
        if !gzip {
            return Err(data.truncated(file_size));
        }
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
    let [Ok(nx), Ok(ny), Ok(nz)] = [dims[0], dims[1], dims[2]].map(usize::try_from) else {
        return Err(header_error(
            MAGIC.len(),
            format!("dims {:?}: too large for this machine", &dims[..3]),
        ));
    };
    let info = InrimageInfo {
        gzip,
        big_endian,
        sample_type,
        dims: [nx, ny, nz],
        voxel_size: DVec3::from_array(keys.voxel.map(|v| v.unwrap_or(1.0))),
        origin: DVec3::from_array(keys.origin.map(|v| v.unwrap_or(0.0))),
        header_size: header_size as u64,
        comments: keys.comments,
        non_finite_voxels: 0,
    };
    Ok((info, data))
}

fn decode(
    stream: &mut VolumeStream<'_>,
    options: &ReadOptions,
) -> Result<(Volume, InrimageInfo), DecodeError> {
    let (info, data) = read_header(stream)?;
    data.check_memory(options.max_bytes)?;
    let mut values = data.read_values(stream)?;
    stream.expect_end()?;
    let mut info = info;
    info.non_finite_voxels = data.apply_non_finite(&mut values, options.non_finite)?;
    let volume = Volume::axis_aligned(info.dims, values, info.voxel_size, info.origin)
        .map_err(|e| header_error(MAGIC.len(), format!("invalid volume: {e}")))?;
    Ok((volume, info))
}
