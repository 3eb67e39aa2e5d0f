//! Seeded generators that give the same stream on every platform and need no dependency:
//! the triangulation's insertion order and walk, and synthetic data for tests and examples.
//! Neither is for statistics that need a strong generator.

/// SplitMix64: small and fast; the triangulation's insertion order and walk need only
/// decorrelation, not statistical quality, and must be identical on every platform.
#[derive(Clone, Debug)]
pub struct SplitMix64(u64);

impl SplitMix64 {
    /// A generator started from `seed`.
    pub fn new(seed: u64) -> Self {
        Self(seed)
    }

    /// The next 64 random bits.
    #[inline]
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }

    /// A uniform integer in `0..n` (`n > 0`), by multiply-shift.
    #[inline]
    pub fn below(&mut self, n: u64) -> u64 {
        ((self.next_u64() as u128 * n as u128) >> 64) as u64
    }
}

/// Marsaglia's xorshift generator: a seeded stream of uniform numbers for synthetic data
/// (jittered samples, noisy phantoms) that is the same on every platform and needs no
/// dependency. Not for statistics that need a strong generator.
///
/// ```
/// use sphcover_core::random::XorShift64;
///
/// let mut rng = XorShift64::new(7);
/// let u = rng.uniform();
/// assert!((0.0..1.0).contains(&u));
/// assert_eq!(XorShift64::new(7).uniform(), u);
/// ```
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct XorShift64 {
    state: u64,
}

impl XorShift64 {
    /// A generator started at `state` (0 is replaced by 1: the all-zero state never moves).
    pub fn new(state: u64) -> XorShift64 {
        XorShift64 {
            state: state.max(1),
        }
    }

    /// The next number, uniform in `[0, 1)` with 53 random bits.
    pub fn uniform(&mut self) -> f64 {
        let s = &mut self.state;
        *s ^= *s << 13;
        *s ^= *s >> 7;
        *s ^= *s << 17;
        (*s >> 11) as f64 / (1u64 << 53) as f64
    }
}
