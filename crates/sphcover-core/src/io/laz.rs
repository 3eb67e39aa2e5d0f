//! LAZ: LAS files whose point records LASzip compressed. The records are decompressed (with
//! `laz`, the Rust port of LASzip) into the bytes the uncompressed file would hold, which the
//! LAS reader then reads as it reads any LAS file.
//!
//! * A LAZ file is a LAS file with bit 7 (or, from old writers, bit 6) of the point format
//!   byte set and a variable length record `laszip encoded` / 22204 describing the
//!   compression; the point data starts with the offset of the chunk table.
//! * The declared count times the record length is checked against the memory limit before
//!   anything is decompressed (a few compressed bytes may stand for millions of points).

use std::io::Cursor;

use laz::{LasZipDecompressor, LazVlr};

use super::error::{Failure, Location};

/// Bytes of a variable length record's header.
const VLR_HEADER: usize = 54;
/// Points decompressed per call, the step by which the records grow.
const BLOCK_POINTS: u64 = 1 << 16;

/// The LASzip record among the `vlr_count` variable length records starting at byte `start`.
fn laszip_vlr(bytes: &[u8], start: usize, vlr_count: u32) -> Result<LazVlr, Failure> {
    let mut at = start;
    for _ in 0..vlr_count {
        let Some(head) = bytes.get(at..at + VLR_HEADER) else {
            return Err(Failure::header(
                Location::Byte(at as u64),
                "the file ends inside its variable length records",
            ));
        };
        let user_id = &head[2..18];
        let record_id = u16::from_le_bytes([head[18], head[19]]);
        let length = usize::from(u16::from_le_bytes([head[20], head[21]]));
        let data = bytes
            .get(at + VLR_HEADER..at + VLR_HEADER + length)
            .ok_or_else(|| {
                Failure::header(
                    Location::Byte(at as u64),
                    "the file ends inside a variable length record",
                )
            })?;
        let name = user_id.split(|&b| b == 0).next().unwrap_or_default();
        if name == LazVlr::USER_ID.as_bytes() && record_id == LazVlr::RECORD_ID {
            return LazVlr::from_buffer(data).map_err(|e| {
                Failure::header(
                    Location::Byte((at + VLR_HEADER) as u64),
                    format!("bad LASzip record: {e}"),
                )
            });
        }
        at += VLR_HEADER + length;
    }
    Err(Failure::header(
        Location::Byte(start as u64),
        "the point format is compressed (LAZ) but no `laszip encoded` record describes it",
    ))
}

/// Decompresses the `count` records of `record_length` bytes that start at byte `offset`, as
/// the variable length records (`vlr_count` of them from byte `vlr_start`) describe;
/// `layout` is `(vlr_start, vlr_count, offset, count, record_length)`. The caller has checked `count · record_length` against the memory limit; without one, the
/// records take what the data really decompresses to.
pub(crate) fn decompress_records(
    bytes: &[u8],
    layout: (usize, u32, usize, u64, usize),
) -> Result<Vec<u8>, Failure> {
    let (_, _, _, count, record_length) = layout;
    // The records grow block by block as the data yields them: a count the data does not
    // hold fails at its end, having allocated no more than was really there.
    let mut records: Vec<u8> = Vec::new();
    decompress_blocks(bytes, layout, BLOCK_POINTS, |block| {
        records
            .try_reserve(block.len())
            .map_err(|_| Failure::OutOfMemory {
                what: format!("{count} decompressed point records"),
                bytes: count.saturating_mul(record_length as u64),
            })?;
        records.extend_from_slice(block);
        Ok(())
    })?;
    Ok(records)
}

/// Decompresses the records as [`decompress_records`] does, `block_points` at a time, and
/// hands each block of records to `visit`; `layout` is `(vlr_start, vlr_count, offset,
/// count, record_length)`. Holds one block at a time.
pub(crate) fn decompress_blocks(
    bytes: &[u8],
    (vlr_start, vlr_count, offset, count, record_length): (usize, u32, usize, u64, usize),
    block_points: u64,
    mut visit: impl FnMut(&[u8]) -> Result<(), Failure>,
) -> Result<(), Failure> {
    let vlr = laszip_vlr(bytes, vlr_start, vlr_count)?;
    let item_length = vlr.items_size();
    if item_length != record_length as u64 {
        return Err(Failure::header(
            Location::Byte(105),
            format!(
                "point data record length {record_length} differs from the {item_length} bytes the LASzip record describes"
            ),
        ));
    }
    check_chunk_table(bytes, offset, count)?;
    let mut source = Cursor::new(bytes);
    source.set_position(offset as u64);
    let corrupt = |e: &dyn std::fmt::Display| {
        Failure::syntax(
            Location::Byte(offset as u64),
            format!("compressed point data: {e}"),
        )
    };
    let block_points = block_points.max(1);
    // `laz` is not written against hostile input: a panic inside it is a corrupt file here.
    let decompressed = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
        let mut decompressor = LasZipDecompressor::new(source, vlr).map_err(|e| corrupt(&e))?;
        let mut block = Vec::new();
        let mut remaining = count;
        while remaining > 0 {
            let points = remaining.min(block_points);
            block.resize(points as usize * record_length, 0);
            decompressor
                .decompress_many(&mut block)
                .map_err(|e| corrupt(&e))?;
            visit(&block)?;
            remaining -= points;
        }
        Ok(())
    }));
    match decompressed {
        Ok(result) => result,
        Err(_) => Err(corrupt(&"the decompressor failed")),
    }
}

/// Checks what `laz` would allocate from the chunk table (one entry per declared chunk)
/// before it does: a table must lie inside the file, after the data it indexes, and cannot
/// declare more chunks than there are points or bytes of compressed data (every chunk holds
/// at least one of each). Where to find the table follows LASzip: the 8-byte offset at the
/// start of the point data, or, where a writer could not go back to fill it in, the file's
/// last 8 bytes. Without one (a point-wise compressed file) `laz` reads no table.
fn check_chunk_table(bytes: &[u8], offset: usize, count: u64) -> Result<(), Failure> {
    let i64_at = |at: usize| -> Option<i64> {
        Some(i64::from_le_bytes(bytes.get(at..at + 8)?.try_into().ok()?))
    };
    let data = offset as i64;
    let Some(mut table) = i64_at(offset) else {
        return Err(Failure::syntax(
            Location::Byte(offset as u64),
            "the file ends before the compressed point data",
        ));
    };
    if table <= data {
        table = i64_at(bytes.len().saturating_sub(8)).unwrap_or(0);
        if table <= data {
            return Ok(());
        }
    }
    let table = table as u64;
    let bad = |message: String| Err(Failure::syntax(Location::Byte(offset as u64), message));
    let Some(chunks) = usize::try_from(table)
        .ok()
        .and_then(|t| bytes.get(t + 4..t + 8))
        .map(|b| u64::from(u32::from_le_bytes(b.try_into().unwrap_or_default())))
    else {
        return bad(format!(
            "the chunk table offset {table} lies past the end of the file ({} bytes)",
            bytes.len()
        ));
    };
    let compressed = table - (offset as u64 + 8).min(table);
    if chunks > count.max(1) || chunks > compressed.max(1) {
        return bad(format!(
            "the chunk table declares {chunks} chunks for {count} points in {compressed} bytes of compressed data"
        ));
    }
    Ok(())
}
