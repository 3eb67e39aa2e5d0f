//! Pinholes: tunnels through the inside one or two grid vertices wide, filled before
//! extraction.
//!
//! A wall about as thin as a cell is held by a single layer of inside grid vertices. Where
//! the function dips below zero at one vertex of that layer, or at two beside each other (a
//! sample spacing's worth of error, or grid vertices that fall just outside a wall thinner
//! than a cell), the mesh gets a tunnel through the wall: a handle a cell or two wide,
//! finer than anything the grid can show. Such a *hole* (one vertex, or two face
//! neighbours) is set inside when:
//!
//! - the 26 neighbours of its vertices are known and the 8 cells around each are active (so
//!   filling it changes only cells the extraction meshes anyway), and `f` is defined
//!   wherever it was evaluated within two steps (so no boundary of the mesh passes beside
//!   it);
//! - each of its vertices has at least two inside face neighbours outside the hole;
//! - filled, it joins exactly one piece of the inside of its block (its vertices and their
//!   26 neighbours): it closes a ring, and never joins two parts, which would bridge a gap;
//! - without it, the outside of that block falls apart into two or more pieces (the two
//!   ends of the tunnel);
//! - each of those pieces is joined to another through the outside, around the filled
//!   hole, within [`LOOP_STEPS`] grid steps: the fill then removes a small handle, and
//!   never seals off a pocket (a cavity, which would become a shell of its own) nor cuts a
//!   large loop on which trimming may have left a piece of the surface hanging.
//!
//! Holes of one vertex are filled first, then pairs, so a pair never takes a vertex that a
//! pinhole of its own would have filled alone.
//!
//! Connectivity is that of the extraction (see `cell`): vertices of one side are joined
//! along grid edges, and across a face diagonal when the face's asymptotic decider joins
//! them; never across a cube's body diagonal. So a fill closes exactly the tunnel the mesh
//! would have had. Vertices where `f` is not known block every path.
//!
//! Candidates are tested in parallel on the values as searched, then confirmed one by one
//! in ascending grid order on the values as filled so far, so the result does not depend on
//! the thread count. A filled vertex takes half the mean of its inside face neighbours'
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
/// Rounds of filling: a fill can leave a pinhole beside it only along a longer tunnel.
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

/// The values of `f` in the box of the vertices to fill (one, or two neighbours) and their
/// 26 neighbours each, all known.
struct Block {
    lo: Index3,
    dims: [i64; 3],
    values: Vec<f64>,
    /// The vertices to fill.
    holes: Vec<Index3>,
}

impl Block {
    fn around(known: &mut impl FnMut(Index3) -> Option<f64>, holes: &[Index3]) -> Option<Block> {
        let lo: Index3 = std::array::from_fn(|a| holes.iter().map(|h| h[a]).min().unwrap_or(0) - 1);
        let hi: Index3 = std::array::from_fn(|a| holes.iter().map(|h| h[a]).max().unwrap_or(0) + 1);
        let dims: [i64; 3] = std::array::from_fn(|a| hi[a] - lo[a] + 1);
        let mut block = Block {
            lo,
            dims,
            values: Vec::with_capacity((dims[0] * dims[1] * dims[2]) as usize),
            holes: holes.to_vec(),
        };
        for i in 0..dims[0] * dims[1] * dims[2] {
            let p = block.vertex(i as usize);
            block.values.push(known(p)?);
        }
        Some(block)
    }

    fn vertex(&self, i: usize) -> Index3 {
        let i = i as i64;
        let [nx, ny, _] = self.dims;
        [
            self.lo[0] + i % nx,
            self.lo[1] + (i / nx) % ny,
            self.lo[2] + i / (nx * ny),
        ]
    }

    fn index(&self, p: Index3) -> Option<usize> {
        let d: [i64; 3] = std::array::from_fn(|a| p[a] - self.lo[a]);
        (0..3)
            .all(|a| (0..self.dims[a]).contains(&d[a]))
            .then(|| (d[0] + self.dims[0] * (d[1] + self.dims[1] * d[2])) as usize)
    }

    fn value(&self, p: Index3) -> Option<f64> {
        self.index(p).map(|i| self.values[i])
    }

    /// A label for each vertex of `side` in the block but the holes, one per piece
    /// (`u8::MAX` elsewhere).
    fn pieces(&self, side: bool) -> Vec<u8> {
        let mut label = vec![u8::MAX; self.values.len()];
        let mut next = 0u8;
        let (mut stack, mut around) = (Vec::new(), Vec::new());
        let mut value = |p: Index3| self.value(p);
        for start in 0..self.values.len() {
            let u = self.vertex(start);
            if label[start] != u8::MAX
                || self.holes.contains(&u)
                || inside(self.values[start]) != side
            {
                continue;
            }
            label[start] = next;
            stack.push(u);
            while let Some(u) = stack.pop() {
                joined(&mut value, u, side, &mut around);
                for &w in &around {
                    if let Some(i) = self.index(w)
                        && label[i] == u8::MAX
                        && !self.holes.contains(&w)
                    {
                        label[i] = next;
                        stack.push(w);
                    }
                }
            }
            next += 1;
        }
        label
    }

    /// The vertices of `side` the extraction joins to some hole, but the holes.
    fn joined_to_holes(&self, side: bool) -> Vec<Index3> {
        let (mut all, mut around) = (Vec::new(), Vec::new());
        for &h in &self.holes {
            joined(&mut |p| self.value(p), h, side, &mut around);
            all.extend(around.iter().filter(|p| !self.holes.contains(p)));
        }
        all.sort_unstable();
        all.dedup();
        all
    }

    /// When the holes are a pinhole by their block (module notes): the value that fills
    /// each, and one outside vertex of each piece the fill leaves apart.
    fn fill(&mut self) -> Option<(Vec<f64>, Vec<Index3>)> {
        let mut fills = Vec::with_capacity(self.holes.len());
        for &h in &self.holes {
            if self.value(h).is_none_or(inside) {
                return None;
            }
            let faces: Vec<f64> = (0..3)
                .flat_map(|axis| [-1, 1].map(|by| step(h, axis, by)))
                .filter(|p| !self.holes.contains(p))
                .filter_map(|p| self.value(p))
                .filter(|&x| inside(x))
                .collect();
            if faces.len() < 2 {
                return None;
            }
            fills.push(0.5 * faces.iter().sum::<f64>() / faces.len() as f64);
        }
        let outside_ends = self.joined_to_holes(false);

        let before: Vec<f64> = self.holes.iter().filter_map(|&h| self.value(h)).collect();
        self.set_holes(&fills);
        // The filled holes join exactly one piece of the inside...
        let inside_pieces = self.pieces(true);
        let mut joined_pieces = self
            .joined_to_holes(true)
            .into_iter()
            .filter_map(|p| self.index(p).map(|i| inside_pieces[i]));
        let one_ring = joined_pieces
            .next()
            .is_some_and(|first| joined_pieces.all(|label| label == first));
        // ...and leave the outside they were joined to in two or more.
        let outside_pieces = self.pieces(false);
        let mut ends: Vec<Index3> = Vec::new();
        let mut seen = Vec::new();
        for p in outside_ends {
            let label = self.index(p).map_or(u8::MAX, |i| outside_pieces[i]);
            if !seen.contains(&label) {
                seen.push(label);
                ends.push(p);
            }
        }
        self.set_holes(&before);
        (one_ring && ends.len() >= 2).then_some((fills, ends))
    }

    fn set_holes(&mut self, values: &[f64]) {
        for (&h, &value) in self.holes.iter().zip(values) {
            if let Some(i) = self.index(h) {
                self.values[i] = value;
            }
        }
    }
}

/// Whether, with `holes` filled with `fills`, every one of `ends` is joined through the
/// outside to another within [`LOOP_STEPS`] steps (module notes): a breadth-first search
/// from each.
fn ends_meet_nearby(
    known: &mut impl FnMut(Index3) -> Option<f64>,
    holes: &[Index3],
    fills: &[f64],
    ends: &[Index3],
) -> bool {
    let mut value = |p: Index3| match holes.iter().position(|&h| h == p) {
        Some(k) => Some(fills[k]),
        None => known(p),
    };
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

/// The values that fill `holes` (one vertex, or two neighbours) when they are a pinhole
/// (module notes). `searched` gives `f` at the grid vertices the search evaluated: NaN where
/// `f` is not defined, `None` where it was not evaluated.
fn pinhole_fill(
    searched: &mut impl FnMut(Index3) -> Option<f64>,
    holes: &[Index3],
) -> Option<Vec<f64>> {
    let (fills, ends) = Block::around(&mut known(searched), holes)?.fill()?;
    (defined_around(searched, holes)
        && ends_meet_nearby(&mut known(searched), holes, &fills, &ends))
    .then_some(fills)
}

/// `f` where it is known: evaluated and defined.
fn known(
    searched: &mut impl FnMut(Index3) -> Option<f64>,
) -> impl FnMut(Index3) -> Option<f64> + '_ {
    |p| searched(p).filter(|x| !x.is_nan())
}

/// Whether `f` is defined wherever it was evaluated within two steps of the hole: the cells
/// around the hole and their neighbours are then meshed wherever the surface crosses them,
/// so no boundary of the mesh (where `f` is not defined) passes beside the fill, and the
/// fill changes the mesh's topology by exactly the handle it closes.
fn defined_around(searched: &mut impl FnMut(Index3) -> Option<f64>, holes: &[Index3]) -> bool {
    holes.iter().all(|h| {
        (-2..=2).all(|dz| {
            (-2..=2).all(|dy| {
                (-2..=2)
                    .all(|dx| !searched([h[0] + dx, h[1] + dy, h[2] + dz]).is_some_and(f64::is_nan))
            })
        })
    })
}

/// The pinhole one vertex wide at `v` (`width` 1), or two wide at `v` and one of its
/// outside neighbours on the positive side of an axis (`width` 2, so that each pair is
/// tried once): the vertices and their values.
fn pinhole_at(
    searched: &mut impl FnMut(Index3) -> Option<f64>,
    v: Index3,
    width: usize,
) -> Option<(Vec<Index3>, Vec<f64>)> {
    if width == 1 {
        return pinhole_fill(searched, &[v]).map(|fills| (vec![v], fills));
    }
    (0..3).find_map(|axis| {
        let w = step(v, axis, 1);
        if known(searched)(w).is_none_or(inside) {
            return None;
        }
        let holes = vec![v, w];
        pinhole_fill(searched, &holes).map(|fills| (holes, fills))
    })
}

/// `f` at the grid vertices the search evaluated (NaN where it is not defined).
fn searched_values<'r>(
    reader: &'r mut BrickReader<'_>,
    grid: &'r Grid,
) -> impl FnMut(Index3) -> Option<f64> + 'r {
    |p| grid.in_range(p).then(|| reader.value(p)).flatten()
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

/// The pinhole at `v` in the searched grid ([`pinhole_at`]), when the cells around every
/// vertex it fills are active (checked at `v` before the costlier test).
fn searched_pinhole(
    reader: &mut BrickReader<'_>,
    grid: &Grid,
    v: Index3,
    width: usize,
) -> Option<(Vec<Index3>, Vec<f64>)> {
    if !cells_around_active(reader, v) {
        return None;
    }
    let (holes, fills) = pinhole_at(&mut searched_values(reader, grid), v, width)?;
    holes
        .iter()
        .filter(|&&h| h != v)
        .all(|&h| cells_around_active(reader, h))
        .then_some((holes, fills))
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

/// Fills the pinholes of the searched grid (module notes), those one vertex wide first,
/// and updates the cells around them; the number of pinholes filled.
pub(super) fn fill_pinholes(search: &mut Search) -> usize {
    let mut filled = 0;
    for _ in 0..MAX_ROUNDS {
        let before = filled;
        for width in [1, 2] {
            filled += fill_pinholes_of_width(search, width);
        }
        if filled == before {
            break;
        }
    }
    filled
}

/// One pass of [`fill_pinholes`] over the pinholes of `width` (see [`pinhole_at`]).
fn fill_pinholes_of_width(search: &mut Search, width: usize) -> usize {
    let grid = search.grid;
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
                    && searched_pinhole(reader, grid, v, width).is_some();
                candidate.then_some(key)
            },
        )
        .flatten()
        .collect();
    candidates.par_sort_unstable();
    let mut filled = 0;
    let mut cache = [(u64::MAX, 0); 8];
    for key in candidates {
        // An earlier fill may have changed its surroundings.
        let Some((holes, fills)) = searched_pinhole(&mut search.reader(), grid, unpack(key), width)
        else {
            continue;
        };
        for (&h, &value) in holes.iter().zip(&fills) {
            let (brick, l) = search.brick_mut(h, &mut cache);
            brick.set_value(l, value);
        }
        for &h in &holes {
            reclassify_cells_around(search, h);
        }
        filled += 1;
    }
    filled
}

/// Classifies again the active cells around grid vertex `v`, whose value changed.
fn reclassify_cells_around(search: &mut Search, v: Index3) {
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

    /// World point `p` relative to the world's centre.
    fn local(p: Index3) -> Index3 {
        p.map(|c| c - C)
    }

    /// `p` with its axes turned so that its axis `normal` becomes axis 2; three turns make
    /// the identity.
    fn turned(p: Index3, normal: usize) -> Index3 {
        std::array::from_fn(|a| p[(a + normal + 1) % 3])
    }

    /// The world point of plate coordinates `q` (axis 2 along the plate's normal).
    fn placed(q: Index3, normal: usize) -> Index3 {
        let p = turned(turned(q, normal), normal);
        [C + p[0], C + p[1], C + p[2]]
    }

    /// The vertices within `r` of the world's centre that [`pinhole_at`] would fill at
    /// `width`.
    fn filled(known: &mut impl FnMut(Index3) -> Option<f64>, r: i64, width: usize) -> Vec<Index3> {
        let mut out = Vec::new();
        for z in -r..=r {
            for y in -r..=r {
                for x in -r..=r {
                    if let Some((holes, fills)) = pinhole_at(known, [C + x, C + y, C + z], width) {
                        assert!(fills.iter().all(|&f| inside(f)));
                        out.extend(holes);
                    }
                }
            }
        }
        out.sort_unstable();
        out
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(12))]

        /// A square plate one or two vertices thick, across any axis, with a tunnel one or
        /// two vertices wide through it: the tunnel is filled at its width (one of its
        /// vertices, or two beside each other, set inside), and nothing else anywhere around
        /// the plate; a tunnel two wide is no pinhole one wide.
        #[test]
        fn a_pinhole_through_a_thin_plate_is_filled(
            normal in 0usize..3,
            half in 3i64..9,
            thickness in 1i64..3,
            width in 1usize..3,
            hx in -1i64..2,
            hy in -1i64..2,
        ) {
            let w = width as i64;
            let in_hole = move |x: i64, y: i64| (hx..hx + w).contains(&x) && y == hy;
            let plate = move |p: Index3| {
                let q = local(p);
                q[0].abs() <= half && q[1].abs() <= half && (0..thickness).contains(&q[2])
                    && !in_hole(q[0], q[1])
            };
            let mut known = world(move |p| plate(turned(p, normal)));
            let found = filled(&mut known, half + 2, width);
            let hole: Vec<Index3> = (0..thickness)
                .flat_map(|z| (hx..hx + w).map(move |x| placed([x, hy, z], normal)))
                .collect();
            prop_assert!(!found.is_empty(), "hole {hole:?} not filled");
            prop_assert!(found.iter().all(|v| hole.contains(v)), "{found:?} outside {hole:?}");
            if width == 2 {
                prop_assert_eq!(filled(&mut known, half + 2, 1), Vec::<Index3>::new());
            }
        }

        /// A gap one vertex wide between two plates (joined along one edge, a slot) is
        /// never bridged, nor a pit one or two vertices wide and up to three deep in a block
        /// sealed.
        #[test]
        fn gaps_and_pits_are_not_filled(
            normal in 0usize..3,
            half in 3i64..7,
            depth in 1i64..4,
            pit_width in 1i64..3,
        ) {
            let slot = move |p: Index3| {
                let q = local(p);
                q[0].abs() <= half && q[1].abs() <= half && q[2].abs() <= 1
                    && (q[2] != 0 || q[0] == -half)
            };
            let mut known = world(move |p| slot(turned(p, normal)));
            for width in [1, 2] {
                prop_assert_eq!(filled(&mut known, half + 1, width), Vec::<Index3>::new());
            }

            let pit = move |p: Index3| {
                let q = local(p);
                let in_block = q.iter().all(|c| c.abs() <= 4);
                in_block && !((0..pit_width).contains(&q[0]) && q[1] == 0 && q[2] > 4 - depth)
            };
            let mut known = world(move |p| pit(turned(p, normal)));
            for width in [1, 2] {
                prop_assert_eq!(filled(&mut known, 5, width), Vec::<Index3>::new());
            }
        }
    }

    /// A tunnel through the middle of a plate too wide for its two ends to meet around it
    /// within the loop bound stays: that is a large handle, not a grid-scale one.
    #[test]
    fn a_tunnel_through_a_wide_plate_is_left() {
        let half = LOOP_STEPS as i64;
        let mut known = world(|p| {
            let q = local(p);
            q[0].abs() <= half && q[1].abs() <= half && q[2] == 0 && q[..2] != [0, 0]
        });
        assert_eq!(pinhole_at(&mut known, [C, C, C], 1), None);
        // The same tunnel near the plate's edge is filled.
        let mut known = world(|p| {
            let q = local(p);
            q[0].abs() <= half && q[1].abs() <= half && q[2] == 0 && q[..2] != [half - 3, 0]
        });
        assert!(pinhole_at(&mut known, [C + half - 3, C, C], 1).is_some());
    }
}
