//! Parallel encoding of records for the writers.
//!
//! Records are encoded into per-chunk buffers on all threads and written in record order,
//! a bounded batch at a time, so output bytes never depend on the thread count and memory
//! stays at one batch however large the file.

use std::io::Write;

use rayon::prelude::*;

/// Records per parallel task.
const CHUNK: usize = 1 << 14;
/// Tasks per batch written at once.
const CHUNKS_PER_BATCH: usize = 64;

/// Writes records `0..count`, each encoded by `encode(index, buffer)` appending its bytes.
pub(crate) fn write_records<F>(w: &mut dyn Write, count: usize, encode: F) -> std::io::Result<()>
where
    F: Fn(usize, &mut Vec<u8>) + Sync,
{
    let chunks = count.div_ceil(CHUNK);
    for batch_start in (0..chunks).step_by(CHUNKS_PER_BATCH) {
        let batch_end = (batch_start + CHUNKS_PER_BATCH).min(chunks);
        let buffers: Vec<Vec<u8>> = (batch_start..batch_end)
            .into_par_iter()
            .map(|c| {
                let mut buffer = Vec::new();
                for i in c * CHUNK..((c + 1) * CHUNK).min(count) {
                    encode(i, &mut buffer);
                }
                buffer
            })
            .collect();
        for buffer in &buffers {
            w.write_all(buffer)?;
        }
    }
    Ok(())
}
