//! Tube faces: the rare saddle where the polygons of both cells sharing a face use both of
//! its crossing segments, so the surface runs through the face as a tube.
//!
//! One vertex per cell sheet would pinch such a tube into an edge of four quads; here each
//! segment gets a vertex of its own on the face. It is kept apart from the plain extraction,
//! which only takes this path when a tube face exists (no real scan measured has one).

use glam::DVec3;
use rayon::prelude::*;

use super::cell::{
    ActiveCell, FACE_CORNERS, FACE_EDGES, NO_SHEET, corner_offset, edge_ends, face_segment,
    joins_corners_0_and_2,
};
use super::extract::{edge_crossing, split_quad};
use super::grid::{Grid, Index3, KeyMap, pack, unpack};
use super::search::Search;

/// A face where the polygons of both cells sharing it use both of its crossing segments: a
/// tube of surface through the face, which one vertex per cell sheet would pinch into an
/// edge of four quads. Each segment gets a vertex of its own on the face.
#[derive(Clone, Copy, Debug)]
pub(super) struct TubeFace {
    /// The vertex of segment 0; segment 1's follows it.
    first_vertex: u32,
    /// The decider's pairing on the face, as the lower cell sees it (its face `2a + 1`).
    joins_0_and_2: bool,
    /// Mean of each segment's two edge crossings, in cell units from the lower cell's origin.
    pub(super) positions: [DVec3; 2],
}

/// The tube faces among the active cells (sorted by `keys`): the key of the lower cell, the
/// face's normal axis, and the face, numbered in that order from vertex `first`.
pub(super) fn tube_faces(
    search: &Search,
    grid: &Grid,
    keys: &[u64],
    cells: &[&ActiveCell],
    first: u32,
) -> Vec<(u64, usize, TubeFace)> {
    // One sheet through all four edges of a face (a four-crossing face pairs them into two
    // segments, so the sheet uses both).
    let one_sheet = |cell: &ActiveCell, face: usize| {
        let s = FACE_EDGES[face].map(|e| cell.sheet[e]);
        s[0] != NO_SHEET && s.iter().all(|&x| x == s[0])
    };
    let found: Vec<(u64, usize, TubeFace)> = keys
        .par_iter()
        .zip(cells)
        .map_init(
            || search.reader(),
            |reader, (&key, cell)| {
                let c = unpack(key);
                let mut out = Vec::new();
                for axis in 0..3 {
                    let face = 2 * axis + 1;
                    if !one_sheet(cell, face) {
                        continue;
                    }
                    let mut n = c;
                    n[axis] += 1;
                    let neighbour_one_sheet = grid.in_range(n)
                        && reader.active_slot(n).is_some_and(|slot| {
                            one_sheet(&search.cells[slot as usize].1, 2 * axis)
                        });
                    if !neighbour_one_sheet {
                        continue;
                    }
                    let mut q = [0.0; 4];
                    for (v, &k) in q.iter_mut().zip(&FACE_CORNERS[face]) {
                        let o = corner_offset(k);
                        *v = reader
                            .value([c[0] + o[0], c[1] + o[1], c[2] + o[2]])
                            .unwrap_or(f64::NAN);
                    }
                    let joins_0_and_2 = joins_corners_0_and_2(q);
                    let mut sums = [DVec3::ZERO; 2];
                    for (k, &e) in FACE_EDGES[face].iter().enumerate() {
                        let (a, b) = edge_ends(e);
                        let (fa, fb) = (q[corner_slot(face, a)], q[corner_slot(face, b)]);
                        sums[face_segment(joins_0_and_2, k)] += 0.5 * edge_crossing(a, b, fa, fb);
                    }
                    out.push((
                        key,
                        axis,
                        TubeFace {
                            first_vertex: 0,
                            joins_0_and_2,
                            positions: sums,
                        },
                    ));
                }
                out
            },
        )
        .flatten_iter()
        .collect();
    found
        .into_iter()
        .enumerate()
        .map(|(i, (key, axis, t))| {
            let first_vertex = first + 2 * i as u32;
            (key, axis, TubeFace { first_vertex, ..t })
        })
        .collect()
}

/// Position of cube corner `corner` in the corner list of `face`.
fn corner_slot(face: usize, corner: usize) -> usize {
    FACE_CORNERS[face]
        .iter()
        .position(|&k| k == corner)
        .expect("an edge of the face joins two of its corners")
}

/// Emits the triangles of the quad `quad` around a crossing edge (cells and their edge
/// indices `around`, counter-clockwise), with the segment vertex of every tube face between
/// two consecutive cells inserted between their vertices; wound outward when `outward`,
/// else reversed.
pub(super) fn push_polygon_through_tubes(
    tris: &mut Vec<[u32; 3]>,
    quad: [u32; 4],
    around: [(Index3, usize); 4],
    outward: bool,
    tubes: &KeyMap<[Option<TubeFace>; 3]>,
    vertices: &[DVec3],
) {
    // Four cell vertices and at most one segment vertex between each consecutive two.
    let mut polygon = [0u32; 8];
    let mut len = 0;
    let mut apex = None;
    for k in 0..4 {
        polygon[len] = quad[k];
        len += 1;
        let (c0, e0) = around[k];
        let (c1, e1) = around[(k + 1) % 4];
        let axis = (0..3)
            .find(|&d| c0[d] != c1[d])
            .expect("neighbouring cells");
        let (lower, lower_edge) = if c0[axis] < c1[axis] {
            (c0, e0)
        } else {
            (c1, e1)
        };
        if let Some(t) = tubes.get(&pack(lower)).and_then(|faces| faces[axis]) {
            let k_face = FACE_EDGES[2 * axis + 1]
                .iter()
                .position(|&e| e == lower_edge)
                .expect("the crossing edge lies on the face");
            let v = t.first_vertex + face_segment(t.joins_0_and_2, k_face) as u32;
            apex.get_or_insert(v);
            polygon[len] = v;
            len += 1;
        }
    }
    let polygon = &mut polygon[..len];
    if !outward {
        polygon.reverse();
    }
    let Some(apex) = apex else {
        split_quad(
            tris,
            [polygon[0], polygon[1], polygon[2], polygon[3]],
            vertices,
        );
        return;
    };
    // A fan from a segment vertex: it belongs to this polygon and one other only, so its
    // diagonals are edges of no other triangle.
    let at = polygon.iter().position(|&v| v == apex).unwrap_or(0);
    polygon.rotate_left(at);
    for i in 1..len - 1 {
        tris.push([polygon[0], polygon[i], polygon[i + 1]]);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::polygonise::{
        GridStep, PolygoniseError, PolygoniseParams, PolygoniseStats, polygonise,
    };
    use proptest::prelude::*;
    use sphcover_core::MeshTopology;
    use sphcover_core::{Cover, Kernel, LinearFunction, LocalFunctions, PuEvaluator};

    /// A cover of `[-1, 1]³` by a 5×5×5 lattice of supports carrying the given linear
    /// functions: its zero set is an arbitrary smooth surface, with sheets close together.
    fn random_cover(funcs: &[(DVec3, f64)]) -> Cover {
        let centres: Vec<DVec3> = (0..125)
            .map(|i| DVec3::new((i % 5) as f64, ((i / 5) % 5) as f64, (i / 25) as f64) * 0.5 - 1.0)
            .collect();
        let lin = centres
            .iter()
            .zip(funcs)
            .map(|(&c, &(a, b))| LinearFunction::from_global(a, b, c))
            .collect::<Vec<_>>();
        Cover::new(
            centres,
            vec![0.8; 125],
            LocalFunctions::from_linear(lin),
            Kernel::QuadraticBSpline,
        )
        .unwrap()
    }

    /// The tangled zero set of [`one_sheet_cells_sharing_an_ambiguous_face`]: per lattice
    /// support of [`random_cover`], the gradient and value of its linear function.
    #[rustfmt::skip]
    const TANGLE: [[f64; 4]; 125] = [
        [0.0, 0.0, 0.0, 0.0],
        [0.0, 0.0, 0.0, 0.0],
        [0.0, 0.0, 0.0, 0.0],
        [0.0, 0.0, 0.0, 0.0],
        [0.0, 0.0, 0.0, 0.0],
        [0.0, 0.0, 0.0, 0.0],
        [0.0, 0.0, 0.0, 0.0],
        [0.0, 0.0, 0.0, 0.0],
        [0.0, 0.0, 0.0, 0.0],
        [0.0, 0.0, 0.0, 0.0],
        [0.0, 0.0, 0.0, 0.0],
        [0.0, 0.0, 0.0, 0.0],
        [0.0, 0.0, 0.0, 0.0],
        [0.0, 0.0, 0.0, 0.0],
        [0.0, 0.0, 0.0, 0.0],
        [0.0, 0.0, 0.0, 0.0],
        [0.0, 0.0, 0.0, 0.0],
        [0.0, 0.0, 0.0, 0.0],
        [0.0, 0.0, 0.0, 0.0],
        [0.0, 0.0, 0.0, 0.0],
        [0.0, 0.0, 0.0, 0.0],
        [0.0, 0.0, 0.0, 0.0],
        [0.0, 0.0, 0.0, 0.0],
        [0.0, 0.0, 0.0, 0.0],
        [-0.41982259876301475, -0.41930644080097335, -0.12415545344774259, 0.29713409985764305],
        [0.08672647693349031, -0.8670027665545098, 0.8751838256226313, 0.08364593779986189],
        [0.43300329406906496, 0.7924972436759223, -0.4798176873774507, -0.2639194332354065],
        [0.39945199747239, 0.4347175205448123, 0.6586574548697688, -0.26401297045661376],
        [0.6664013987953484, -0.35882170440308025, -0.6416378965353599, -0.21939095160254207],
        [0.062328806725064904, -0.11184064455765566, -0.3619181881131223, -0.06101172802245994],
        [-0.6525869338740323, 0.1730135124928657, 0.4261129906158749, -0.26205094587674577],
        [-0.7617830311534295, -0.928267963669217, 0.12629733494910178, -0.07355376030244591],
        [-0.6524946623500568, 0.5579786751253042, 0.4740149136562575, 0.06836385424322902],
        [0.266473394104045, 0.32476766784145794, 0.9150136267816606, -0.09735563772512229],
        [0.21463240613344858, 0.40483598828470924, 0.5843198102664908, -0.06464103266589753],
        [0.29468962556762696, -0.7007997046674711, 0.09368426330334721, -0.03675018436508287],
        [-0.24020509959378142, 0.400138552812982, -0.16884229209484855, 0.1510076160821013],
        [0.04121824614019798, -0.755470232016485, -0.5187436759994221, 0.18870819880179773],
        [-0.4781174300541111, 0.3026877244701685, 0.68030839425557, -0.10911544525706732],
        [-0.4613295157974558, -0.7565052518251741, -0.14667323126634488, -0.07825022978114363],
        [-0.6054715189010496, 0.518893729379657, -0.6694651308138115, 0.2651691461754521],
        [-0.30826568090044854, -0.10692141142123283, 0.10509224826711527, 0.06103253505382191],
        [-0.5234764818527851, -0.9809567805830021, -0.6863386111043457, 0.08939396924321172],
        [0.024371586534484273, 0.6099698479900579, -0.6649759112595608, -0.039688159241344986],
        [-0.1382244583681864, 0.5164151971197252, -0.8818105904591502, -0.007646610497832949],
        [0.18122552247167298, 0.3950296555851851, -0.41772932314843697, -0.1033256331916075],
        [0.06254282210968924, -0.36212280548560993, 0.40421609876276027, -0.12382828075226991],
        [0.7734306406254547, 0.8868361784362352, 0.6990722272689701, 0.17844364749138136],
        [-0.09349927146496591, 0.3471414998544411, -0.29614532312769754, -0.22038475631601545],
        [0.9671708231936642, -0.5177632051864702, -0.18201910290387002, -0.05049255443389762],
        [-0.5882510727061399, 0.8996747544219706, 0.5892776630083811, -0.14347523921630678],
        [0.6387423630484272, -0.15495882743414263, 0.3486214943801931, 0.058609812967869365],
        [-0.09758382150187245, -0.7248149265543182, 0.8149307841657802, -0.26933760079387015],
        [-0.18520936846641053, -0.1204003104636337, 0.28992589693349735, 0.09628867821966247],
        [-0.7196921577329464, -0.9103868700536737, -0.6059552807879097, -0.14945882042239275],
        [0.028818379707087272, 0.7717199693831751, -0.5092216455440868, 0.010206547224891015],
        [0.20215458057005742, -0.6488671343158515, -0.36734201882480755, 0.17507115117324445],
        [0.5164852216947137, 0.34935428105229466, 0.520311669138156, 0.2802580512049048],
        [-0.1825102265449309, 0.08911359101977943, -0.9918760557454027, -0.23132320545757043],
        [-0.5425855249202213, 0.13933026566155388, -0.32000532428692763, 0.07454987128239816],
        [-0.086100776287785, 0.6425751054120065, 0.7346174020756451, -0.04012343677339384],
        [0.4161431967015538, 0.6067284283596202, 0.6863203362807264, 0.0943971576540243],
        [0.27996521668048924, 0.32298120837076594, 0.11892531715405161, 0.17096099795550498],
        [-0.20938033289267308, -0.5284594293992516, 0.655249156786148, 0.15121699000214636],
        [0.4088984877342852, -0.6870236144701543, 0.9614230050178888, 0.2038909042559704],
        [0.6896316067075737, 0.7897722802182432, 0.5253055715349618, 0.21722719664807785],
        [0.7294593557131853, 0.8271205945366071, -0.43274914652535973, -0.03934545267200615],
        [-0.5989384630904628, 0.1275471633003839, 0.8156017179593809, 0.2646612125811976],
        [0.724244373933628, -0.7891732872760474, -0.7361018721246491, 0.26833652843038697],
        [0.06749059442053379, -0.5287190802101289, 0.6389715194169482, 0.18311942469765122],
        [0.037288371157633005, 0.83357501427039, -0.7878143374278831, -0.020359472128635727],
        [0.7880137306785694, -0.6703074583582223, 0.3741301622541844, 0.07328169231404806],
        [0.4784264816921216, 0.11923380677012191, -0.8117769267348336, -0.26342624970827166],
        [-0.6779659417268847, -0.5528618173206579, -0.7344437939503923, 0.2945450596151548],
        [-0.5586089055407927, -0.15800250117024697, -0.039025729745865045, -0.10621307099549572],
        [-0.8581629375468501, -0.4344416105495339, -0.05749993898482427, -0.20641718386701904],
        [-0.9781691683809882, 0.6954812523190261, 0.5531343530804052, -0.07836607252483017],
        [0.32868670702073294, 0.43242127321929735, 0.054000918625460664, 0.05033686945503222],
        [0.1039124737703395, -0.047833734448616855, -0.1244210009935379, 0.21204957476061992],
        [0.5693481378774364, -0.3144114999548221, -0.3580947029650622, 0.2510480627300423],
        [0.7100030501415147, 0.6111591813117493, -0.500560868611132, 0.2130862408027498],
        [0.12812476361167596, -0.6906204838330546, -0.6472173101214785, 0.15432506167482365],
        [0.9487196867503896, 0.9004570024641225, 0.07183036251735159, -0.28379482569800324],
        [0.8793078319440006, 0.770835496084664, 0.014769574931220504, 0.08681469054554587],
        [0.6583694484599676, -0.5412540297960784, 0.34950393696646387, 0.18224866930129538],
        [0.9423804638302165, 0.4616347934368144, -0.13547472485721782, 0.09248853552551946],
        [-0.3687109078131071, -0.631784740957235, -0.9640574490883863, -0.020318825044062506],
        [0.039609092301912306, -0.5356177759543922, -0.8910346407663657, 0.2141700255287884],
        [-0.517077988823126, -0.3701136950255429, -0.08050165142533235, 0.24496161558425875],
        [0.5545141281583904, -0.8571595492736278, 0.8068047475416293, 0.04044631090917908],
        [0.11408714880587839, 0.8234740717822208, -0.179922822157974, 0.22445538105224214],
        [0.2516976789810286, -0.10404619058876897, 0.8003244211276999, 0.22815988058555683],
        [0.7371225618740209, -0.8315189675793447, -0.45181551688112936, 0.2597418193616428],
        [0.6174959286437384, -0.7612282731733558, 0.03677261403701954, 0.007143666501242768],
        [-0.003312360779225404, 0.6999662493499381, 0.5231424780098065, 0.1833432873772398],
        [0.7547478550748599, -0.12341124889781659, -0.33691482517118765, 0.22401387599966205],
        [0.804866681948485, -0.5670777587155295, -0.6779365015676904, 0.27497555783540617],
        [0.5116330569311823, -0.7824427328138326, -0.29124791999650285, 0.039969459864516985],
        [-0.6234864898272009, 0.23215764572125344, -0.8170336671486699, -0.2771481326693482],
        [0.9378608881943311, 0.7937761984679808, -0.8633665619428565, -0.08973805302417012],
        [-0.5364337970065567, 0.30578518877085875, -0.40648907579143906, -0.157476092904447],
        [0.6729776990193369, -0.723252390264528, 0.1713061499976043, 0.27266814045908333],
        [-0.9390378828151718, 0.1089349794390745, -0.8676095229736036, 0.10905615568145242],
        [0.8717144833494774, -0.18930679408304962, -0.05425815056870974, 0.12908557816626096],
        [0.6302587971619559, 0.3873720205655489, 0.5756877496804972, -0.2152563382343802],
        [0.35454203441820525, 0.6947837682626457, 0.004263724853661036, -0.07140624431739317],
        [-0.46773440370690555, 0.297541316180282, -0.1951261013286621, 0.026996164988130105],
        [-0.8620234426227993, 0.966195294455819, 0.1294487580870281, -0.14651012920634757],
        [0.5050072933752143, 0.15155836208249257, 0.7993783441862594, -0.14435656392934293],
        [0.17663417746393492, -0.9408492234876646, 0.5504353167286666, 0.2146880471339888],
        [0.1583407215638676, 0.4827367614389574, 0.06664154884577264, -0.08805774425094004],
        [-0.42022141315313405, -0.6308003463263521, -0.5520184204960841, 0.1310331966841414],
        [-0.48250573548792386, -0.10147437167315407, 0.15872695004972023, -0.19101281902246606],
        [-0.11389250037687422, -0.4811238732174069, -0.42367924512738087, 0.06760380858424822],
        [-0.6262634304550695, 0.029992130892995718, 0.5459545183646529, -0.193823951145756],
        [-0.10613884972502036, 0.2583887111152424, 0.5130868269253231, 0.034266560467362414],
        [0.6786211386874593, 0.46540624039795464, 0.9056125651016096, 0.19654042276417114],
        [-0.7061431935623701, -0.27978799872510435, -0.39484720017733327, -0.2549295705711641],
        [0.5104033236825612, -0.6114132153528034, 0.35125869678110794, 0.14008731722836537],
        [0.9086673932388186, -0.33552134258581645, -0.9006893289973608, -0.25100737479375423],
        [0.38950065660247823, 0.23379032149716425, -0.17777348981970012, -0.23604094923213997],
        [0.9872980959039045, 0.7286064550298299, 0.9192457002824033, 0.1470104175775096],
        [0.9936295655353043, 0.3022375255560035, 0.882603868646094, 0.2594531327103684],
        [0.7380060206756249, -0.6610934316861969, 0.4026677108115341, 0.2933751587386393],
        [0.7790935438731792, 0.2053563396325006, 0.263605619836894, -0.13087787705149384],
    ];

    /// Polygonises the zero set of [`random_cover`] with `funcs` from every support centre;
    /// `None` when no surface is near them.
    fn zero_set_topology(
        funcs: &[(DVec3, f64)],
        step: f64,
        project: bool,
        fill_pinholes: bool,
    ) -> Option<(MeshTopology, PolygoniseStats)> {
        let cover = random_cover(funcs);
        let eval = PuEvaluator::new(&cover, 1.0).unwrap();
        let p = PolygoniseParams {
            step: GridStep::Absolute(step),
            project,
            seed_reach: 100.0,
            fill_pinholes,
            ..PolygoniseParams::default()
        };
        match polygonise(&eval, cover.centres(), &p) {
            Ok((mesh, stats)) => Some((MeshTopology::of(&mesh), stats)),
            Err(PolygoniseError::NoSurfaceNearSeeds { .. }) => None,
            Err(e) => panic!("{e}"),
        }
    }

    /// A case `arbitrary_zero_sets_give_oriented_manifolds` found: two
    /// neighbouring cells ([17, 12, 9] and [18, 12, 9]) each hold a single sheet through all
    /// four crossings of their shared, ambiguous face, a tube through it. With one vertex
    /// per cell sheet the dual edge between them carried four quads and one edge ended up
    /// traversed twice in the same direction; each segment of the face now has a vertex.
    /// (Filling pinholes closes this tube, so it is left off here.)
    #[test]
    fn one_sheet_cells_sharing_an_ambiguous_face() {
        let funcs: Vec<(DVec3, f64)> = TANGLE
            .iter()
            .map(|&[x, y, z, b]| (DVec3::new(x, y, z), b))
            .collect();
        let (topo, stats) =
            zero_set_topology(&funcs, 0.1972754302209973, false, false).expect("a surface");
        assert!(stats.tube_faces > 0);
        assert!(topo.is_manifold(), "{topo:?}");
        assert_eq!(topo.inconsistent_edges, 0);
        assert_eq!(topo.invalid_triangles, 0);
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(24))]

        /// Any zero set, however tangled, is meshed as an oriented 2-manifold, with its
        /// pinholes filled or not: multi-sheet cells get one vertex per sheet, and fans are
        /// split where the mesh stops.
        #[test]
        fn arbitrary_zero_sets_give_oriented_manifolds(
            funcs in prop::collection::vec(
                (prop::array::uniform3(-1.0f64..1.0), -0.3f64..0.3), 125),
            step in 0.07f64..0.2,
            project in any::<bool>(),
            fill_pinholes in any::<bool>(),
        ) {
            let funcs: Vec<(DVec3, f64)> =
                funcs.into_iter().map(|(a, b)| (DVec3::from_array(a), b)).collect();
            if let Some((topo, _)) = zero_set_topology(&funcs, step, project, fill_pinholes) {
                prop_assert!(topo.is_manifold(), "{:?}", topo);
                prop_assert_eq!(topo.inconsistent_edges, 0);
                prop_assert_eq!(topo.invalid_triangles, 0);
            }
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(96))]

        /// A brute-force check of the pinhole fill on arbitrary zero sets: the meshes with
        /// and without it differ by exactly one handle per pinhole filled (Euler
        /// characteristic up by two each), with the same boundary. Where the surface is open
        /// the closed tunnel may have been all that joined two pieces (about 1 in 120 cases
        /// with fills), so the components may grow, never shrink.
        #[test]
        fn each_pinhole_filled_closes_one_handle(
            funcs in prop::collection::vec(
                (prop::array::uniform3(-1.0f64..1.0), -0.3f64..0.3), 125),
            step in 0.07f64..0.2,
        ) {
            let funcs: Vec<(DVec3, f64)> =
                funcs.into_iter().map(|(a, b)| (DVec3::from_array(a), b)).collect();
            let open = zero_set_topology(&funcs, step, false, false);
            let filled = zero_set_topology(&funcs, step, false, true);
            if let (Some((open, _)), Some((filled, stats))) = (open, filled) {
                let handles = 2 * stats.pinholes_filled as i64;
                prop_assert_eq!(filled.euler_characteristic() - open.euler_characteristic(), handles);
                prop_assert_eq!(filled.boundary_edges, open.boundary_edges);
                prop_assert!(filled.components >= open.components);
            }
        }
    }
}
