//! Union–find over `0..n`, with the smallest element of each set as its root.
//!
//! The method is described on [`DisjointSets`].

/// Disjoint sets of `0..n`: path halving, smallest element as root.
///
/// Keeping the smallest element as the root (rather than union by rank or size) makes the
/// root of a set a property of the set alone, not of the order of the unions: code that
/// labels pieces by their root, or walks them root by root, gives the same result however
/// the unions were found, which parallel and sequential builds both rely on.
///
/// ```
/// use sphcover_core::DisjointSets;
///
/// let mut sets = DisjointSets::new(5);
/// sets.union(3, 1);
/// sets.union(4, 3);
/// assert_eq!(sets.find(4), 1);
/// assert!(!sets.same_set(0, 4));
/// assert_eq!(sets.count(), 3); // {0}, {1, 3, 4}, {2}
/// ```
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct DisjointSets {
    parent: Vec<u32>,
}

impl DisjointSets {
    /// `n` singletons.
    pub fn new(n: usize) -> DisjointSets {
        DisjointSets {
            parent: (0..n as u32).collect(),
        }
    }

    /// `n` singletons again, keeping the allocation.
    pub fn reset(&mut self, n: usize) {
        self.parent.clear();
        self.parent.extend(0..n as u32);
    }

    /// Number of elements.
    pub fn len(&self) -> usize {
        self.parent.len()
    }

    /// True when there is no element.
    pub fn is_empty(&self) -> bool {
        self.parent.is_empty()
    }

    /// The root of `x`'s set: its smallest element.
    ///
    /// # Panics
    ///
    /// When `x` is not below [`DisjointSets::len`].
    pub fn find(&mut self, mut x: u32) -> u32 {
        while self.parent[x as usize] != x {
            let grand = self.parent[self.parent[x as usize] as usize];
            self.parent[x as usize] = grand;
            x = grand;
        }
        x
    }

    /// Joins the sets of `a` and `b`; true when they were apart.
    pub fn union(&mut self, a: u32, b: u32) -> bool {
        let (ra, rb) = (self.find(a), self.find(b));
        if ra == rb {
            return false;
        }
        self.parent[ra.max(rb) as usize] = ra.min(rb);
        true
    }

    /// Whether `a` and `b` are in one set.
    pub fn same_set(&mut self, a: u32, b: u32) -> bool {
        self.find(a) == self.find(b)
    }

    /// Number of sets.
    pub fn count(&mut self) -> usize {
        (0..self.parent.len() as u32)
            .filter(|&x| self.find(x) == x)
            .count()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        /// Against a brute-force labelling (repeated relabelling of pairs): the same
        /// partition, each set rooted at its smallest element, whatever the union order.
        #[test]
        fn partition_matches_brute_force(
            n in 1usize..40,
            pairs in prop::collection::vec((0u32..40, 0u32..40), 0..60),
        ) {
            let pairs: Vec<(u32, u32)> =
                pairs.into_iter().map(|(a, b)| (a % n as u32, b % n as u32)).collect();
            let mut label: Vec<u32> = (0..n as u32).collect();
            loop {
                let mut changed = false;
                for &(a, b) in &pairs {
                    let m = label[a as usize].min(label[b as usize]);
                    for x in [a, b] {
                        if label[x as usize] != m {
                            label[x as usize] = m;
                            changed = true;
                        }
                    }
                }
                if !changed {
                    break;
                }
            }
            let mut forward = DisjointSets::new(n);
            let mut backward = DisjointSets::new(n);
            for &(a, b) in &pairs {
                forward.union(a, b);
            }
            for &(a, b) in pairs.iter().rev() {
                backward.union(b, a);
            }
            for x in 0..n as u32 {
                prop_assert_eq!(forward.find(x), label[x as usize]);
                prop_assert_eq!(backward.find(x), label[x as usize]);
            }
            let sets = label.iter().enumerate().filter(|&(i, &l)| i as u32 == l).count();
            prop_assert_eq!(forward.count(), sets);
        }
    }

    #[test]
    fn reset_makes_singletons() {
        let mut sets = DisjointSets::new(3);
        assert!(sets.union(0, 2));
        assert!(!sets.union(2, 0));
        sets.reset(4);
        assert_eq!((sets.len(), sets.count()), (4, 4));
        assert!(DisjointSets::default().is_empty());
    }
}
