//! One cube of the grid on its own: the tables of its corners, edges and faces, and the
//! grouping of its crossing edges into sheets (the closed polygons marching cubes would
//! build, with the asymptotic decider on faces of four crossings).
//!
//! All of it depends on a cell's eight corner values only, never on the grid or the search,
//! so the search, the extraction and the tube faces read the same tables, and the two cells
//! sharing a face decide it alike.

use super::grid::Index3;

/// Corner `c` of a cube (bit 0: +x, bit 1: +y, bit 2: +z).
pub(super) fn corner_offset(c: usize) -> Index3 {
    [(c & 1) as i64, ((c >> 1) & 1) as i64, ((c >> 2) & 1) as i64]
}

/// Cube edge `4d + bu + 2bw` runs along axis `d` from the corner with bit `bu` on axis
/// `(d + 1) % 3` and bit `bw` on axis `(d + 2) % 3` (zero on `d`).
pub(super) const fn edge_ends(e: usize) -> (usize, usize) {
    let d = e / 4;
    let (u, w) = ((d + 1) % 3, (d + 2) % 3);
    let a = ((e & 1) << u) | (((e >> 1) & 1) << w);
    (a, a | (1 << d))
}

const fn edge_between(a: usize, b: usize) -> usize {
    let d = (a ^ b).trailing_zeros() as usize;
    let lo = if a < b { a } else { b };
    let (u, w) = ((d + 1) % 3, (d + 2) % 3);
    4 * d + ((lo >> u) & 1) + 2 * ((lo >> w) & 1)
}

/// The corners of face `2a + s` (normal axis `a`, side `s`) in cyclic order, with the bits of
/// axes `(a + 1) % 3`, `(a + 2) % 3` going (0,0), (1,0), (1,1), (0,1). Both cells sharing a
/// face list its grid vertices in the same order.
pub(super) const FACE_CORNERS: [[usize; 4]; 6] = {
    let mut t = [[0; 4]; 6];
    let mut f = 0;
    while f < 6 {
        let (a, s) = (f / 2, f % 2);
        let (u, w) = ((a + 1) % 3, (a + 2) % 3);
        let base = s << a;
        t[f] = [
            base,
            base | (1 << u),
            base | (1 << u) | (1 << w),
            base | (1 << w),
        ];
        f += 1;
    }
    t
};

/// Edge `k` of face `f` joins its corners `k` and `k + 1`.
pub(super) const FACE_EDGES: [[usize; 4]; 6] = {
    let mut t = [[0; 4]; 6];
    let mut f = 0;
    while f < 6 {
        let mut k = 0;
        while k < 4 {
            t[f][k] = edge_between(FACE_CORNERS[f][k], FACE_CORNERS[f][(k + 1) % 4]);
            k += 1;
        }
        f += 1;
    }
    t
};

/// No sheet crosses this cube edge.
pub(super) const NO_SHEET: u8 = u8::MAX;

pub(super) fn inside(v: f64) -> bool {
    v > 0.0
}

/// Asymptotic decider on a face with four crossings and corner values `q` (in the order of
/// [`FACE_CORNERS`]): whether corners 0 and 2 are joined through the face, i.e. the sign of
/// the bilinear interpolant at its saddle is theirs. Its segments then cut off corners 1 and
/// 3. The denominator cannot vanish: the corner pairs lie strictly on opposite sides of 0.
pub(super) fn joins_corners_0_and_2(q: [f64; 4]) -> bool {
    let saddle = (q[0] * q[2] - q[1] * q[3]) / (q[0] + q[2] - q[1] - q[3]);
    inside(saddle) == inside(q[0])
}

/// The segment (0 or 1) of face edge `k` on a face with four crossings: segments join face
/// edges 0–1 and 2–3 when corners 0 and 2 are joined, 3–0 and 1–2 otherwise.
pub(super) fn face_segment(joins_0_and_2: bool, k: usize) -> usize {
    if joins_0_and_2 {
        k / 2
    } else {
        ((k + 1) % 4) / 2
    }
}

/// Groups the crossing edges of a cell with corner values `f` into the closed polygons of
/// marching cubes (see the notes of the `polygonise` module): the sheet of each cube edge
/// (or [`NO_SHEET`]) and the number of sheets.
pub(super) fn cell_sheets(f: &[f64; 8]) -> ([u8; 12], u8) {
    const NONE: u8 = u8::MAX;
    let mut partners = [[NONE; 2]; 12];
    let mut link = |a: usize, b: usize| {
        for (x, y) in [(a, b), (b, a)] {
            let slot = if partners[x][0] == NONE { 0 } else { 1 };
            partners[x][slot] = y as u8;
        }
    };
    for face in 0..6 {
        let q = FACE_CORNERS[face].map(|c| f[c]);
        let crosses: [bool; 4] = std::array::from_fn(|k| inside(q[k]) != inside(q[(k + 1) % 4]));
        let edges = FACE_EDGES[face];
        match crosses.iter().filter(|&&c| c).count() {
            2 => {
                let mut it = (0..4).filter(|&k| crosses[k]);
                let (a, b) = (it.next().unwrap_or(0), it.next().unwrap_or(0));
                link(edges[a], edges[b]);
            }
            4 => {
                if joins_corners_0_and_2(q) {
                    // Cut off corners 1 and 3.
                    link(edges[0], edges[1]);
                    link(edges[2], edges[3]);
                } else {
                    // Cut off corners 0 and 2.
                    link(edges[3], edges[0]);
                    link(edges[1], edges[2]);
                }
            }
            _ => {}
        }
    }
    let mut sheet = [NO_SHEET; 12];
    let mut sheets = 0u8;
    for e in 0..12 {
        if partners[e][0] == NONE || sheet[e] != NO_SHEET {
            continue;
        }
        let (mut prev, mut cur) = (usize::MAX, e);
        while sheet[cur] == NO_SHEET {
            sheet[cur] = sheets;
            let [p, q] = partners[cur].map(usize::from);
            let next = if p != prev { p } else { q };
            prev = cur;
            cur = next;
            if cur >= 12 {
                break;
            }
        }
        sheets += 1;
    }
    (sheet, sheets)
}

/// An active cell: which corners are inside and the sheet of each crossing cube edge. (The
/// corner values stay in the bricks: a copy here would double the search's memory.)
#[derive(Clone, Copy, Debug)]
pub(super) struct ActiveCell {
    /// Bit `k` is set when corner `k` is inside.
    pub(super) inside: u8,
    pub(super) sheet: [u8; 12],
    pub(super) sheets: u8,
}

/// The four cells around cube edge `e` of cell `c`, counter-clockwise seen from the edge's
/// positive direction, each with the index the edge has in it.
pub(super) fn cells_around_edge(c: Index3, e: usize) -> [Index3; 4] {
    cells_and_edges_around(c, e).map(|(n, _)| n)
}

pub(super) fn cells_and_edges_around(c: Index3, e: usize) -> [(Index3, usize); 4] {
    let d = e / 4;
    let (u, w) = ((d + 1) % 3, (d + 2) % 3);
    // The grid vertex where the edge starts.
    let mut g = c;
    g[u] += (e & 1) as i64;
    g[w] += ((e >> 1) & 1) as i64;
    // Relative to the edge, cell g lies at (+u, +w); going (+,+), (−,+), (−,−), (+,−) is
    // counter-clockwise seen from +d since (u, w, d) is right-handed.
    let shifted = |du: i64, dw: i64| {
        let mut n = g;
        n[u] -= du;
        n[w] -= dw;
        (n, 4 * d + du as usize + 2 * dw as usize)
    };
    [shifted(0, 0), shifted(1, 0), shifted(1, 1), shifted(0, 1)]
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(24))]

        /// The sheets of a cell: every crossing edge on one, the others on none, each sheet a
        /// polygon of at least three edges, and the same sheets for `−f` (the decider treats
        /// both sides alike).
        #[test]
        fn cell_sheets_are_polygons(values in prop::array::uniform8(-1.0f64..1.0)) {
            let values = values.map(|v| if v == 0.0 { 0.5 } else { v });
            let (sheet, count) = cell_sheets(&values);
            let mut sizes = vec![0; usize::from(count)];
            for e in 0..12 {
                let (a, b) = edge_ends(e);
                let crossing = inside(values[a]) != inside(values[b]);
                prop_assert_eq!(crossing, sheet[e] != NO_SHEET);
                if crossing {
                    sizes[usize::from(sheet[e])] += 1;
                }
            }
            prop_assert!(sizes.iter().all(|&s| s >= 3), "{:?}", sizes);
            prop_assert_eq!(cell_sheets(&values.map(|v| -v)), (sheet, count));
        }
    }

    #[test]
    fn edge_tables_are_consistent() {
        for e in 0..12 {
            let (a, b) = edge_ends(e);
            assert_eq!(edge_between(a, b), e);
            assert_eq!(edge_between(b, a), e);
        }
        for f in 0..6 {
            // Each face edge joins consecutive face corners.
            for k in 0..4 {
                let (a, b) = edge_ends(FACE_EDGES[f][k]);
                let ends = [FACE_CORNERS[f][k], FACE_CORNERS[f][(k + 1) % 4]];
                assert!(ends.contains(&a) && ends.contains(&b));
            }
        }
        // Every cube edge lies on exactly two faces.
        for e in 0..12 {
            assert_eq!(FACE_EDGES.iter().filter(|f| f.contains(&e)).count(), 2);
        }
    }
}
