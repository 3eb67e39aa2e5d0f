//! The fit of one support: the search over shells for the largest radius whose
//! least-squares fit stays within ε (step 2 of the algorithm in the notes of the
//! `volume_cover` module).
//!
//! It is a pure function of the centre, which is what lets the covering fit the next
//! candidates ahead of time in parallel; the normal equations it accumulates are those of
//! `fit`.

use super::fit::{self, NormalEquations, QUADRATIC};
use super::grid::Grid;
use super::support::Support;

impl<'a> Grid<'a> {
    /// Fits the support centred at voxel `centre` (a pure function of `centre`).
    pub(super) fn fit<const N: usize>(&self, centre: usize) -> Support {
        let base = self.base(centre);
        let shift = self.sample(centre).unwrap_or(0.0);
        let mut acc = NormalEquations::<N>::new();
        let mut next_offset = 0;
        // Accumulates shells up to `s` into `acc` (which holds shells below `next_offset`).
        let extend = |acc: &mut NormalEquations<N>, next_offset: &mut usize, s: usize| {
            let end = self.shells[s].1;
            for o in &self.offsets[*next_offset..end] {
                if let Some(idx) = self.neighbour(base, o.step)
                    && let Some(v) = self.sample(idx)
                {
                    acc.add(o.p, v - shift);
                }
            }
            *next_offset = end;
        };
        let last = self.shells.len() - 1;
        // The smallest ball with min_samples samples, and the start: r_min or that ball.
        let mut floor = 0;
        extend(&mut acc, &mut next_offset, floor);
        while acc.count() < self.min_samples && floor < last {
            floor += 1;
            extend(&mut acc, &mut next_offset, floor);
        }
        let floor_acc = acc;
        let s = floor.max(self.first_shell);
        extend(&mut acc, &mut next_offset, s);
        let solve = |acc: &NormalEquations<N>, s: usize| {
            let r = self.radius_of_shell(s);
            acc.solve(self.unit / r)
                .map(|(c, e)| (c, e, r))
                .unwrap_or(([0.0; N], 0.0, r))
        };
        // The largest good shell between a good `good.0` and a bad `hi` (E assumed to grow
        // with r).
        let bisect = |mut good: (usize, ([f64; N], f64, f64), NormalEquations<N>),
                      mut hi: usize| {
            while hi - good.0 > 1 {
                let mid = good.0 + (hi - good.0) / 2;
                let mut trial = good.2;
                let mut trial_next = self.shells[good.0].1;
                extend(&mut trial, &mut trial_next, mid);
                let res = solve(&trial, mid);
                if res.1 <= self.tolerance {
                    good = (mid, res, trial);
                } else {
                    hi = mid;
                }
            }
            good
        };
        let mut good = (s, solve(&acc, s), acc);
        if good.1.1 > self.tolerance && s > floor {
            // Even r_min misses ε: bisect below it, down to the smallest ball with
            // min_samples samples (kept, over ε, when that misses too).
            good = (floor, solve(&floor_acc, floor), floor_acc);
            if good.1.1 <= self.tolerance {
                good = bisect(good, s);
            }
        } else if good.1.1 <= self.tolerance {
            // Gallop outward by radius factors of 1.5 until the error exceeds ε.
            let mut bad = None;
            while good.0 < last {
                let target = self.radius_of_shell(good.0) * 1.5 / self.unit;
                let t2 = target * target;
                let mut probe = good.0 + 1;
                while probe < last && self.shells[probe + 1].0 <= t2 {
                    probe += 1;
                }
                extend(&mut acc, &mut next_offset, probe);
                let res = solve(&acc, probe);
                if res.1 <= self.tolerance {
                    good = (probe, res, acc);
                } else {
                    bad = Some(probe);
                    break;
                }
            }
            // Bisect between the last good and the first bad shell.
            if let Some(hi) = bad {
                good = bisect(good, hi);
            }
        }
        let (shell, (c, _, radius), _) = good;
        let mut coef = [0.0; QUADRATIC];
        coef[..N].copy_from_slice(&c);
        let end = self.shells[shell].1;
        let rms = self.direct_rms::<N>(base, end, &c, radius, shift);
        Support {
            centre: centre as u32,
            radius,
            shell_d2: self.shells[shell].0,
            offsets: end,
            coef,
            shift,
            rms,
        }
    }

    /// RMS residual summed sample by sample (what the statistics report).
    fn direct_rms<const N: usize>(
        &self,
        base: [i64; 3],
        end: usize,
        c: &[f64; N],
        radius: f64,
        shift: f64,
    ) -> f64 {
        let scale = self.unit / radius;
        let (mut sum, mut count) = (0.0, 0usize);
        for o in &self.offsets[..end] {
            if let Some(idx) = self.neighbour(base, o.step)
                && let Some(v) = self.sample(idx)
            {
                let u = [o.p[0] * scale, o.p[1] * scale, o.p[2] * scale];
                let r = fit::evaluate(c, u) - (v - shift);
                sum += r * r;
                count += 1;
            }
        }
        (sum / count.max(1) as f64).sqrt()
    }
}
