//! Per-entry work over an adjacency in compressed sparse rows (row `v` is entries
//! `offsets[v]..offsets[v + 1]`), in parallel over fixed blocks of entries.
//!
//! Collecting per-row results into one array (a `flat_map_iter` into a `Vec`) goes through a
//! list of per-task vectors that are then copied into place. Filling a preallocated array
//! block by block writes each entry once and saves that copy, which shows in the graph cut
//! stage over the millions of entries of a scan's sphere intersection graph.

use rayon::prelude::*;

/// Entries per parallel block.
const BLOCK: usize = 4096;

/// Sets `out[k] = value(row, k)` for every entry `k`, where `row` is the row holding `k`.
/// `out` has one element per entry (`offsets` ends with its length).
pub(crate) fn fill_entries<T: Send>(
    offsets: &[u32],
    out: &mut [T],
    value: impl Fn(usize, usize) -> T + Sync,
) {
    debug_assert_eq!(offsets.last().map_or(0, |&o| o as usize), out.len());
    out.par_chunks_mut(BLOCK)
        .enumerate()
        .for_each(|(block, chunk)| {
            let first = block * BLOCK;
            // The row of entry `first` (the last row starting at or before it: empty rows
            // start there too), then advanced entry by entry.
            let mut row = offsets.partition_point(|&o| o as usize <= first) - 1;
            for (local, slot) in chunk.iter_mut().enumerate() {
                let k = first + local;
                while offsets[row + 1] as usize <= k {
                    row += 1;
                }
                *slot = value(row, k);
            }
        });
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        /// Every entry gets its own row, empty rows included, across block boundaries.
        #[test]
        fn each_entry_gets_its_row(lengths in prop::collection::vec(
            prop_oneof![Just(0usize), 0usize..5, 0usize..3 * BLOCK], 1..40)
        ) {
            let mut offsets = vec![0u32];
            for l in &lengths {
                offsets.push(offsets.last().unwrap() + *l as u32);
            }
            let total = *offsets.last().unwrap() as usize;
            let mut rows = vec![usize::MAX; total];
            fill_entries(&offsets, &mut rows, |row, _| row);
            let expected: Vec<usize> = lengths
                .iter()
                .enumerate()
                .flat_map(|(row, &l)| std::iter::repeat_n(row, l))
                .collect();
            prop_assert_eq!(rows, expected);
        }
    }
}
