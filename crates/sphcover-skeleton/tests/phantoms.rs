//! The skeleton's goals on generated CT phantoms, with ONE parameter set
//! (`SkeletonParams::default()`) for every shape and noise level. Each assertion is a goal
//! the pipeline meets as measured; where it falls short of the goal, the bound
//! asserted is the measured one and the comment says so.

use sphcover_core::MeshTopology;
use sphcover_evaluation::sheet_metrics::{SheetMetrics, score_mesh};
use sphcover_evaluation::thin_phantoms::{Phantom, PhantomParams, ThinShape, thin_phantom};
use sphcover_skeleton::{SkeletonParams, extract_skeleton};

fn run(shape: ThinShape, noise: f64) -> (Phantom, SheetMetrics) {
    let phantom = thin_phantom(
        shape,
        &PhantomParams {
            noise,
            seed: 1,
            ..PhantomParams::default()
        },
    );
    let (mesh, stats) = extract_skeleton(&phantom.volume, &SkeletonParams::default(), &|_| {})
        .unwrap_or_else(|e| panic!("{}: {e}", shape.name()));
    let m = score_mesh(&mesh, &phantom.truth, 1.0);
    // The stats describe the mesh returned.
    let topology = MeshTopology::of(&mesh);
    assert_eq!(stats.triangles, mesh.triangles.len());
    assert_eq!(stats.components, topology.components);
    assert_eq!(stats.euler_characteristic, topology.euler_characteristic());
    (phantom, m)
}

#[test]
fn noise_10_percent_meets_the_goals() {
    for shape in ThinShape::ALL {
        let (phantom, m) = run(shape, 0.1);
        let name = shape.name();
        // Goal ≥ 0.99, met on every shape (T-junction 0.994 since rim trimming keeps the
        // pieces it would cut off, 0.980 before).
        assert!(m.coverage >= 0.99, "{name}: {m:?}");
        assert!(m.spurious <= 0.03, "{name}: {m:?}");
        assert!(m.spurious_interior <= 0.01, "{name}: {m:?}");
        // Goal ≤ 0.3 voxel, met on every shape (0.10–0.14; T-junction 0.29 since the junction
        // band is snapped onto the sheets' planes, 0.46 before).
        assert!(m.distance_interior_p95 <= 0.3, "{name}: {m:?}");
        assert!(m.boundary_reach_mean <= 0.5, "{name}: {m:?}");
        assert_eq!(m.components, 1, "{name}: {m:?}");
        // The Euler characteristic of the true sheet on every shape, the T-junction included
        // (measured: closing the tunnels through material up to 24 voxels takes it from −7
        // to 1; with 16 voxels one generator was left, χ 0).
        assert_eq!(
            m.euler_characteristic,
            Some(phantom.truth.euler_characteristic),
            "{name}: {m:?}"
        );
    }
}

#[test]
fn noise_30_percent_meets_the_goals() {
    for shape in ThinShape::ALL {
        let (phantom, m) = run(shape, 0.3);
        let name = shape.name();
        assert!(m.coverage >= 0.97, "{name}: {m:?}");
        assert!(m.spurious <= 0.05, "{name}: {m:?}");
        assert_eq!(m.components, 1, "{name}: {m:?}");
        // Measured: the true χ on every shape, the T-junction included (tunnels closed).
        assert_eq!(
            m.euler_characteristic,
            Some(phantom.truth.euler_characteristic),
            "{name}: {m:?}"
        );
    }
}

#[test]
fn noise_free_sheets_are_accurate() {
    for shape in [
        ThinShape::PlateWithHole,
        ThinShape::Wedge,
        ThinShape::SphericalCap,
    ] {
        let (phantom, m) = run(shape, 0.0);
        let name = shape.name();
        assert!(m.coverage >= 0.99 && m.spurious <= 0.01, "{name}: {m:?}");
        assert!(m.distance_interior_p95 <= 0.15, "{name}: {m:?}");
        assert_eq!(
            m.euler_characteristic,
            Some(phantom.truth.euler_characteristic),
            "{name}"
        );
    }
}

#[test]
fn output_does_not_depend_on_the_thread_count() {
    let phantom = thin_phantom(
        ThinShape::CurvedPlate,
        &PhantomParams {
            noise: 0.1,
            scale: 0.7,
            ..PhantomParams::default()
        },
    );
    let run = |threads| {
        sphcover_core::on_threads(threads, || {
            extract_skeleton(&phantom.volume, &SkeletonParams::default(), &|_| {})
                .unwrap()
                .0
        })
    };
    let (a, b) = (run(1), run(2));
    assert_eq!(a, b);
}

#[test]
fn small_perforations_stay_open() {
    // Holes of radius 1.0–1.7 voxels through a plate 3 voxels thick: the cover's function
    // passes over the smaller ones, and at 10% noise the sheet spanned 3–5 of the 8
    // (isotropic) and 1–3 (every second slice) before the perforation repair read the voxels.
    use sphcover_evaluation::sheet_metrics::line_meets_mesh;
    use sphcover_evaluation::thin_phantoms::{every_slice, perforations};
    for (noise, seed) in [0.1, 0.3]
        .into_iter()
        .flat_map(|n| (1..=3).map(move |s| (n, s)))
    {
        let params = PhantomParams {
            noise,
            seed,
            ..PhantomParams::default()
        };
        let phantom = thin_phantom(ThinShape::SmallPerforations, &params);
        let holes = perforations(ThinShape::SmallPerforations, &params);
        assert_eq!(holes.len(), 8);
        for (grid, volume) in [
            ("isotropic", phantom.volume.clone()),
            ("2× slices", every_slice(&phantom.volume, 2)),
        ] {
            let (mesh, _) =
                extract_skeleton(&volume, &SkeletonParams::default(), &|_| {}).expect("a sheet");
            let open = holes
                .iter()
                .filter(|h| !line_meets_mesh(&mesh, h.centre, h.axis, 3.0 * params.voxel))
                .count();
            let m = score_mesh(&mesh, &phantom.truth, 1.0);
            // Measured at 10% noise: all 8 open, spurious 0.003–0.005 on both grids (2×
            // slices processed without resampling: 6–8 open, 0.020–0.050). At 30%: 5–7 open,
            // spurious 0.015–0.039 (0.042–0.057 with the column's noise taken as 3 voxels').
            let (least, spurious) = if noise < 0.2 { (8, 0.01) } else { (5, 0.05) };
            let case = format!("noise {noise}, seed {seed}, {grid}");
            assert!(open >= least, "{case}: {open} of 8 open");
            assert!(m.spurious <= spurious, "{case}: {m:?}");
            assert!(m.coverage >= 0.97, "{case}: {m:?}");
        }
    }
}
