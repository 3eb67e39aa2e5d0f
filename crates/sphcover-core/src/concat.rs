//! Joining lists built in parallel into one list.

use rayon::prelude::*;

/// `parts` concatenated, copied in parallel into a list allocated once at its exact size.
/// Appending them in turn to a list had one thread copy everything (and touch every page of
/// the new list) while the others waited.
pub(crate) fn concat_in_parallel<T: Copy + Default + Send + Sync>(parts: &[&[T]]) -> Vec<T> {
    let mut out = vec![T::default(); parts.iter().map(|p| p.len()).sum()];
    let mut targets = Vec::with_capacity(parts.len());
    let mut rest = &mut out[..];
    for part in parts {
        let (target, tail) = rest.split_at_mut(part.len());
        targets.push(target);
        rest = tail;
    }
    targets
        .into_par_iter()
        .zip(parts)
        .for_each(|(target, part)| target.copy_from_slice(part));
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parts_come_out_in_order() {
        let parts: Vec<Vec<u32>> = (0..50)
            .map(|k| (0..k * 7 % 11).map(|i| 100 * k + i).collect())
            .collect();
        let slices: Vec<&[u32]> = parts.iter().map(Vec::as_slice).collect();
        assert_eq!(concat_in_parallel(&slices), parts.concat());
        assert!(concat_in_parallel::<u32>(&[]).is_empty());
    }
}
