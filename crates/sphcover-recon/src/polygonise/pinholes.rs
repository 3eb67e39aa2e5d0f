//! Pinholes: tunnels through the inside one grid vertex wide, filled before extraction.
//!
//! A wall about as thin as a cell is held by a single layer of inside grid vertices. Where
//! the function dips below zero at one vertex of that layer (a sample spacing's worth of
//! error, or a grid vertex that falls just outside a wall thinner than a cell), the mesh
//! gets a tunnel through the wall: a handle one cell wide, finer than anything the grid
//! can show. Such a vertex is set inside when:
//!
//! - its 26 neighbours are known and the 8 cells around it are active (so filling it
//!   changes only cells the extraction meshes anyway);
//! - at least two of its face neighbours are inside;
//! - filled, it joins exactly one piece of the inside of its 3×3×3 block (it closes a ring;
//!   it never joins two parts, which would bridge a gap);
//! - without it, the outside of that block falls apart into two or more pieces (the two
//!   ends of the tunnel);
//! - each of those pieces is joined to another through the outside, around the filled
//!   vertex, within [`LOOP_STEPS`] grid steps: the fill then removes a small handle, and
//!   never seals off a pocket (a cavity, which would become a shell of its own) nor cuts a
//!   large loop on which trimming may have left a piece of the surface hanging.
//!
//! Connectivity is that of the extraction (see `cell`): vertices of one side are joined
//! along grid edges, and across a face diagonal when the face's asymptotic decider joins
//! them; never across a cube's body diagonal. So a fill closes exactly the tunnel the mesh
//! would have had. Vertices where `f` is not known block every path.
//!
//! Candidates are tested in parallel on the values as searched, then confirmed one by one
//! in ascending grid order on the values as filled so far, so the result does not depend on
//! the thread count. The filled vertex takes half the mean of its inside face neighbours'
//! values, so the surface around it stays between it and its outside neighbours.

use std::collections::VecDeque;

use rayon::prelude::*;

use super::bricks::BrickReader;
use super::cell::{ActiveCell, NO_SHEET, corner_offset, inside, joins_corners_0_and_2};
use super::grid::{Grid, Index3, KeyMap, pack, unpack};
use super::search::{Search, classify};

/// Grid steps within which the two ends of a tunnel must be joined around it, through the
/// outside, for it to be filled: its handle is then small (a loop of at most twice this).
/// The pinholes of the 200K-point housing scans (fins 1.3 cells thick) close within 35
/// steps; on CGAL's building scan, 2 of 64 tunnels do not close within 40 steps, and
/// filling those cut off pieces of seen surface that trimming had left hanging on them.
const LOOP_STEPS: usize = 40;
/// Most outside vertices one search visits: a bound on its cost where the outside around a
/// tunnel is a wide open space (a search stopped by it fills nothing).
const LOOP_SEARCH: usize = 1 << 16;
/// Rounds of filling: a fill can leave a neighbour a pinhole only along a longer tunnel.
const MAX_ROUNDS: usize = 4;

/// `u` moved by `by` along `axis`.
fn step(mut u: Index3, axis: usize, by: i64) -> Index3 {
    u[axis] += by;
    u
}

/// The vertices the extraction joins to `u`, of side `side` (`true` inside), into `out`;
/// `value` gives `f` where it is known.
fn joined(
    value: &mut impl FnMut(Index3) -> Option<f64>,
    u: Index3,
    side: bool,
    out: &mut Vec<Index3>,
) {
    out.clear();
    for axis in 0..3 {
        for by in [-1, 1] {
            let w = step(u, axis, by);
            if value(w).map(inside) == Some(side) {
                out.push(w);
            }
        }
    }
    for a in 0..3 {
        for b in a + 1..3 {
            for (da, db) in [(-1, -1), (-1, 1), (1, -1), (1, 1)] {
                let (ua, ub) = (step(u, a, da), step(u, b, db));
                let w = step(ua, b, db);
                // Across the face only when both other corners are known and on the other
                // side (else joined through them, or not known).
                let q = [u, ua, w, ub].map(|p| value(p).unwrap_or(f64::NAN));
                let sides = q.map(|x| (!x.is_nan()).then(|| inside(x)));
                if sides[2] != Some(side) || sides[1] != Some(!side) || sides[3] != Some(!side) {
                    continue;
                }
                if joins_corners_0_and_2(q) {
                    out.push(w);
                }
            }
        }
    }
}

/// The values of `f` in the 3×3×3 block around a grid vertex `v`, all known.
struct Block {
    v: Index3,
    values: [f64; 27],
}

/// Vertex `i` of the 3×3×3 block around `v` (`i = dx + 3 dy + 9 dz`, offsets plus one).
fn block_vertex(v: Index3, i: usize) -> Index3 {
    let i = i as i64;
    [v[0] + i % 3 - 1, v[1] + (i / 3) % 3 - 1, v[2] + i / 9 - 1]
}

/// The inverse of [`block_vertex`], for vertices in the block.
fn block_index(v: Index3, p: Index3) -> Option<usize> {
    let d: [i64; 3] = std::array::from_fn(|a| p[a] - v[a] + 1);
    d.iter()
        .all(|c| (0..3).contains(c))
        .then(|| (d[0] + 3 * d[1] + 9 * d[2]) as usize)
}

impl Block {
    fn around(known: &mut impl FnMut(Index3) -> Option<f64>, v: Index3) -> Option<Block> {
        let mut values = [0.0; 27];
        for (i, value) in values.iter_mut().enumerate() {
            *value = known(block_vertex(v, i))?;
        }
        Some(Block { v, values })
    }

    fn value(&self, p: Index3) -> Option<f64> {
        block_index(self.v, p).map(|i| self.values[i])
    }

    /// A label for each vertex of `side` in the block but the centre, one per piece
    /// (`u8::MAX` elsewhere).
    fn pieces(&self, side: bool) -> [u8; 27] {
        let mut label = [u8::MAX; 27];
        let mut next = 0u8;
        let (mut stack, mut around) = (Vec::new(), Vec::new());
        let mut value = |p: Index3| self.value(p);
        for start in 0..27 {
            if start == 13 || label[start] != u8::MAX || inside(self.values[start]) != side {
                continue;
            }
            label[start] = next;
            stack.push(block_vertex(self.v, start));
            while let Some(u) = stack.pop() {
                joined(&mut value, u, side, &mut around);
                for &w in &around {
                    let i = block_index(self.v, w).unwrap_or(13);
                    if i != 13 && label[i] == u8::MAX {
                        label[i] = next;
                        stack.push(w);
                    }
                }
            }
            next += 1;
        }
        label
    }

    /// When the centre is a pinhole by its block (module notes): the value that fills it,
    /// and one outside vertex of each piece the fill leaves apart.
    fn fill(&mut self) -> Option<(f64, Vec<Index3>)> {
        if inside(self.values[13]) {
            return None;
        }
        let (v, mut around) = (self.v, Vec::new());
        joined(&mut |p| self.value(p), v, true, &mut around);
        let faces: Vec<f64> = around
            .iter()
            .filter(|p| (0..3).map(|a| (p[a] - v[a]).abs()).sum::<i64>() == 1)
            .filter_map(|&p| self.value(p))
            .collect();
        if faces.len() < 2 {
            return None;
        }
        joined(&mut |p| self.value(p), v, false, &mut around);
        let outside_ends = around.clone();

        let before = self.values[13];
        let filled = 0.5 * faces.iter().sum::<f64>() / faces.len() as f64;
        self.values[13] = filled;
        // The filled centre joins exactly one piece of the inside...
        joined(&mut |p| self.value(p), v, true, &mut around);
        let inside_pieces = self.pieces(true);
        let mut joined_pieces = around.iter().filter_map(|&p| block_index(v, p));
        let one_ring = joined_pieces
            .next()
            .is_some_and(|first| joined_pieces.all(|i| inside_pieces[i] == inside_pieces[first]));
        // ...and leaves the outside it was joined to in two or more.
        let outside_pieces = self.pieces(false);
        let mut ends: Vec<Index3> = Vec::new();
        let mut seen = Vec::new();
        for p in outside_ends {
            let label = block_index(v, p).map_or(u8::MAX, |i| outside_pieces[i]);
            if !seen.contains(&label) {
                seen.push(label);
                ends.push(p);
            }
        }
        self.values[13] = before;
        (one_ring && ends.len() >= 2).then_some((filled, ends))
    }
}

/// Whether, with `v` filled, every one of `ends` is joined through the outside to another
/// within [`LOOP_STEPS`] steps (module notes): a breadth-first search from each.
fn ends_meet_nearby(
    known: &mut impl FnMut(Index3) -> Option<f64>,
    v: Index3,
    filled: f64,
    ends: &[Index3],
) -> bool {
    let mut value = |p: Index3| if p == v { Some(filled) } else { known(p) };
    let (mut queue, mut around) = (VecDeque::new(), Vec::new());
    ends.iter().enumerate().all(|(e, &start)| {
        let mut reached = KeyMap::<()>::default();
        reached.insert(pack(start), ());
        queue.clear();
        queue.push_back((start, 0));
        while let Some((u, steps)) = queue.pop_front() {
            if steps == LOOP_STEPS || reached.len() > LOOP_SEARCH {
                return false;
            }
            joined(&mut value, u, false, &mut around);
            for &w in &around {
                if reached.insert(pack(w), ()).is_none() {
                    if ends.iter().enumerate().any(|(o, &x)| o != e && x == w) {
                        return true;
                    }
                    queue.push_back((w, steps + 1));
                }
            }
        }
        false
    })
}

/// The value that fills `v` when it is a pinhole (module notes); `known` gives `f` at grid
/// vertices where it is known (evaluated and defined).
fn pinhole_fill(known: &mut impl FnMut(Index3) -> Option<f64>, v: Index3) -> Option<f64> {
    let (filled, ends) = Block::around(known, v)?.fill()?;
    ends_meet_nearby(known, v, filled, &ends).then_some(filled)
}

/// `f` where the search evaluated it and it is defined.
fn known_values<'r>(
    reader: &'r mut BrickReader<'_>,
    grid: &'r Grid,
) -> impl FnMut(Index3) -> Option<f64> + 'r {
    |p| {
        grid.in_range(p)
            .then(|| reader.value(p))
            .flatten()
            .filter(|x| !x.is_nan())
    }
}

/// How many of the six face neighbours of `v`, the lowest corner of `cell`, are inside: the
/// three on the positive sides are corners of the cell.
fn inside_face_neighbours(reader: &mut BrickReader<'_>, v: Index3, cell: &ActiveCell) -> u32 {
    let positive = (cell.inside & 0b1_0110).count_ones();
    let negative = (0..3)
        .filter(|&axis| reader.value(step(v, axis, -1)).is_some_and(inside))
        .count() as u32;
    positive + negative
}

/// Whether the 8 cells around grid vertex `v` are active.
fn cells_around_active(reader: &mut BrickReader<'_>, v: Index3) -> bool {
    (0..8).all(|k| {
        let o = corner_offset(k);
        reader
            .active_slot([v[0] - o[0], v[1] - o[1], v[2] - o[2]])
            .is_some()
    })
}

/// Fills the pinholes of the searched grid (module notes) and updates the cells around
/// them; the number filled.
pub(super) fn fill_pinholes(search: &mut Search) -> usize {
    let grid = search.grid;
    let mut filled = 0;
    for _ in 0..MAX_ROUNDS {
        // Every cell around a pinhole is active, its own (of which it is the lowest corner)
        // among them: so each candidate is met once, as corner 0 of its cell.
        let mut candidates: Vec<u64> = search
            .cells
            .par_iter()
            .filter(|(_, cell)| cell.inside & 1 == 0)
            .map_init(
                || search.reader(),
                |reader, &(key, cell)| {
                    let v = unpack(key);
                    let candidate = inside_face_neighbours(reader, v, &cell) >= 2
                        && cells_around_active(reader, v)
                        && pinhole_fill(&mut known_values(reader, grid), v).is_some();
                    candidate.then_some(key)
                },
            )
            .flatten()
            .collect();
        candidates.par_sort_unstable();
        let mut round = Vec::new();
        let mut cache = [(u64::MAX, 0); 8];
        for key in candidates {
            let v = unpack(key);
            // An earlier fill of this round may have changed its surroundings.
            let Some(value) = pinhole_fill(&mut known_values(&mut search.reader(), grid), v) else {
                continue;
            };
            let (brick, l) = search.brick_mut(v, &mut cache);
            brick.set_value(l, value);
            round.push(v);
        }
        for &v in &round {
            for k in 0..8 {
                let o = corner_offset(k);
                let c = [v[0] - o[0], v[1] - o[1], v[2] - o[2]];
                let mut reader = search.reader();
                let Some(slot) = reader.active_slot(c) else {
                    continue;
                };
                // A cell left with every corner inside keeps its slot but meshes nothing.
                let cell = classify(&mut reader, c).unwrap_or(ActiveCell {
                    inside: u8::MAX,
                    sheet: [NO_SHEET; 12],
                    sheets: 0,
                });
                search.cells[slot as usize].1 = cell;
            }
        }
        filled += round.len();
        if round.is_empty() {
            break;
        }
    }
    filled
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// Grid coordinates of the tests' worlds are centred here, so keys stay positive.
    const C: i64 = 100;

    /// `f` of a world where `inside(p)` holds (`f = 1`) or not (`f = −1`), known only
    /// within two steps of the inside, as the search evaluates only near the surface.
    fn world(inside_at: impl Fn(Index3) -> bool) -> impl FnMut(Index3) -> Option<f64> {
        move |p| {
            let near = (-2..=2).any(|dz| {
                (-2..=2).any(|dy| (-2..=2).any(|dx| inside_at([p[0] + dx, p[1] + dy, p[2] + dz])))
            });
            near.then(|| if inside_at(p) { 1.0 } else { -1.0 })
        }
    }

    /// `p` with its axes turned so that its axis `normal` becomes axis 2.
    fn turned(p: Index3, normal: usize) -> Index3 {
        std::array::from_fn(|a| p[(a + normal + 1) % 3])
    }

    /// The vertices within `r` of the world's centre that would be filled.
    fn filled(known: &mut impl FnMut(Index3) -> Option<f64>, r: i64) -> Vec<Index3> {
        let mut out = Vec::new();
        for z in -r..=r {
            for y in -r..=r {
                for x in -r..=r {
                    let v = [C + x, C + y, C + z];
                    if pinhole_fill(known, v).is_some() {
                        out.push(v);
                    }
                }
            }
        }
        out
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(12))]

        /// A square plate one or two vertices thick, across any axis, with a tunnel one
        /// vertex wide through it: the tunnel is filled (one of its vertices, set inside),
        /// and nothing else anywhere around the plate.
        #[test]
        fn a_pinhole_through_a_thin_plate_is_filled(
            normal in 0usize..3,
            half in 3i64..9,
            thickness in 1i64..3,
            hx in -1i64..2,
            hy in -1i64..2,
        ) {
            let plate = move |p: Index3| {
                let q = [p[0] - C, p[1] - C, p[2] - C];
                let (x, y, z) = (q[0], q[1], q[2]);
                x.abs() <= half && y.abs() <= half && (0..thickness).contains(&z)
                    && !(x == hx && y == hy)
            };
            let mut known = world(move |p| plate(turned(p, normal)));
            let found = filled(&mut known, half + 2);
            // turned() is a rotation of the axes: three turns make the identity.
            let hole: Vec<Index3> = (0..thickness)
                .map(|z| {
                    let q = turned(turned([hx, hy, z], normal), normal);
                    [C + q[0], C + q[1], C + q[2]]
                })
                .collect();
            prop_assert!(!found.is_empty(), "hole {hole:?} not filled");
            prop_assert!(found.iter().all(|v| hole.contains(v)), "{found:?} outside {hole:?}");
            for &v in &found {
                prop_assert!(pinhole_fill(&mut known, v).is_some_and(inside));
            }
        }

        /// A gap one vertex wide between two plates (joined along one edge, a slot) is
        /// never bridged, nor a pit one vertex wide and up to three deep in a block sealed.
        #[test]
        fn gaps_and_pits_are_not_filled(
            normal in 0usize..3,
            half in 3i64..7,
            depth in 1i64..4,
        ) {
            let slot = move |p: Index3| {
                let q = [p[0] - C, p[1] - C, p[2] - C];
                q[0].abs() <= half && q[1].abs() <= half && q[2].abs() <= 1
                    && (q[2] != 0 || q[0] == -half)
            };
            let mut known = world(move |p| slot(turned(p, normal)));
            prop_assert_eq!(filled(&mut known, half + 1), Vec::<Index3>::new());

            let pit = move |p: Index3| {
                let q = [p[0] - C, p[1] - C, p[2] - C];
                let in_block = q.iter().all(|c| c.abs() <= 4);
                in_block && !(q[0] == 0 && q[1] == 0 && q[2] > 4 - depth)
            };
            let mut known = world(move |p| pit(turned(p, normal)));
            prop_assert_eq!(filled(&mut known, 5), Vec::<Index3>::new());
        }
    }

    /// A tunnel through the middle of a plate too wide for its two ends to meet around it
    /// within the loop bound stays: that is a large handle, not a grid-scale one.
    #[test]
    fn a_tunnel_through_a_wide_plate_is_left() {
        let half = LOOP_STEPS as i64;
        let mut known = world(|p| {
            let q = [p[0] - C, p[1] - C, p[2] - C];
            q[0].abs() <= half && q[1].abs() <= half && q[2] == 0 && q[..2] != [0, 0]
        });
        assert_eq!(pinhole_fill(&mut known, [C, C, C]), None);
        // The same tunnel near the plate's edge is filled.
        let mut known = world(|p| {
            let q = [p[0] - C, p[1] - C, p[2] - C];
            q[0].abs() <= half && q[1].abs() <= half && q[2] == 0 && q[..2] != [half - 3, 0]
        });
        assert!(pinhole_fill(&mut known, [C + half - 3, C, C]).is_some());
    }
}
