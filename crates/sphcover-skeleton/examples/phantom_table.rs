//! Runs the skeleton pipeline (default parameters) and the NMS baseline on every generated
//! phantom at the given noise levels and prints the metrics as a Markdown table:
//!
//! `cargo run --release -p sphcover-skeleton --example phantom_table -- 0.1 0.3`
//!
//! `SHAPES=t_junction,wedge_plate` restricts the table to those shapes; `PLY_DIR=dir` also
//! writes each ridge sheet there as `SHAPE_NOISE.ply` (ASCII, with normals), for inspection;
//! `PARAMS=name=value,...` overrides numeric fields of the default parameters (see
//! `overridden`), for measuring alternatives with the same command; `SLICES=k` renders the
//! phantom on slices `k` times thicker along z (each the mean of `k` slices, as a scanner
//! acquires thick slices), which the pipeline resamples beyond 1.75:1; `SEED=n` draws the
//! noise with seed `n` (1 by default, the seed the parameters were chosen on; others are
//! held out).
use sphcover_core::io::{self, PlyEncoding, WriteOptions};
use sphcover_evaluation::sheet_metrics::{SheetMetrics, score_mesh, score_points};
use sphcover_evaluation::thin_phantoms::{PhantomParams, ThinShape, thick_slices, thin_phantom};
use sphcover_skeleton::{NmsParams, SkeletonParams, extract_skeleton, nms_skeleton};

fn row(name: &str, method: &str, noise: f64, m: &SheetMetrics, truth_euler: i64, secs: f64) {
    println!(
        "| {name} | {method} | {:.0}% | {:.3} | {:.3} | {:.3} | {:.2} | {} | {} ({truth_euler}) | {:.2} | {:.2} |",
        100.0 * noise,
        m.coverage,
        m.spurious,
        m.spurious_interior,
        m.distance_interior_p95,
        m.components,
        m.euler_characteristic
            .map_or("-".to_string(), |e| e.to_string()),
        m.boundary_reach_mean,
        secs
    );
}

fn main() {
    let noises: Vec<f64> = std::env::args()
        .skip(1)
        .filter_map(|a| a.parse().ok())
        .collect();
    let noises = if noises.is_empty() { vec![0.1] } else { noises };
    let params = overridden(SkeletonParams::default());
    let seed: u64 = std::env::var("SEED")
        .ok()
        .and_then(|n| n.parse().ok())
        .unwrap_or(1);
    let slices: usize = std::env::var("SLICES")
        .ok()
        .and_then(|k| k.parse().ok())
        .unwrap_or(1)
        .max(1);
    println!(
        "| phantom | method | noise | coverage | spurious | spurious away from rim | p95 away from rim (vox) | components | Euler (true) | boundary reach (vox) | time (s) |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|---|");
    for &noise in &noises {
        for shape in ThinShape::ALL {
            if let Ok(only) = std::env::var("SHAPES")
                && !only.split(',').any(|n| n == shape.name())
            {
                continue;
            }
            let ph = thin_phantom(
                shape,
                &PhantomParams {
                    noise,
                    seed,
                    ..PhantomParams::default()
                },
            );
            let thick;
            let volume = if slices > 1 {
                thick = thick_slices(&ph.volume, slices);
                &thick
            } else {
                &ph.volume
            };
            let start = std::time::Instant::now();
            match extract_skeleton(volume, &params, &|_| {}) {
                Ok((mesh, _)) => {
                    let secs = start.elapsed().as_secs_f64();
                    let m = score_mesh(&mesh, &ph.truth, 1.0);
                    if let Some(dir) = std::env::var_os("PLY_DIR") {
                        let path = std::path::Path::new(&dir).join(format!(
                            "{}_{:.0}.ply",
                            shape.name(),
                            100.0 * noise
                        ));
                        let options = WriteOptions {
                            ply_encoding: PlyEncoding::Ascii,
                            ..WriteOptions::default()
                        };
                        if let Err(e) = io::write_mesh(&path, &mesh, &options) {
                            eprintln!("{}: {e}", path.display());
                        }
                    }
                    row(
                        shape.name(),
                        "ridge",
                        noise,
                        &m,
                        ph.truth.euler_characteristic,
                        secs,
                    );
                }
                Err(e) => println!("| {} | ridge | {noise} | error: {e} |", shape.name()),
            }
            if std::env::var_os("NMS").is_some() {
                let start = std::time::Instant::now();
                match nms_skeleton(volume, &NmsParams::default()) {
                    Ok((points, _)) => {
                        let secs = start.elapsed().as_secs_f64();
                        let m = score_points(&points, &ph.truth, 1.0);
                        row(
                            shape.name(),
                            "nms σ=1",
                            noise,
                            &m,
                            ph.truth.euler_characteristic,
                            secs,
                        );
                    }
                    Err(e) => println!("| {} | nms | {noise} | error: {e} |", shape.name()),
                }
            }
        }
    }
}

/// The parameters with the `PARAMS` environment variable's `name=value` pairs applied.
fn overridden(mut p: SkeletonParams) -> SkeletonParams {
    let Ok(spec) = std::env::var("PARAMS") else {
        return p;
    };
    for pair in spec.split(',').filter(|s| !s.is_empty()) {
        let Some((name, value)) = pair.split_once('=') else {
            panic!("PARAMS: expected name=value, got {pair:?}");
        };
        let v: f64 = value
            .parse()
            .unwrap_or_else(|_| panic!("PARAMS: {name}: not a number: {value:?}"));
        let r = &mut p.repairs;
        match name {
            "sigma" => p.sigma = v,
            "threshold" => p.threshold = Some(v),
            "slice_blur_pixels" => p.slice_blur_pixels = (v > 0.0).then_some(v),
            "smooth_mask_noise" => p.smooth_mask_noise = v,
            "derivative_smoothing_voxels" => p.derivative_smoothing_voxels = (v > 0.0).then_some(v),
            "rim_trim_factor" => set(&mut r.rim_trimming, |t| t.factor = v),
            "rim_slice_exponent" => set(&mut r.rim_trimming, |t| t.slice_exponent = v),
            "rim_keep_pieces_voxels" => set(&mut r.rim_trimming, |t| {
                t.keep_pieces_voxels = v.is_finite().then_some(v);
            }),
            "centring_max_shift_voxels" => set(&mut r.centring, |c| c.max_shift_voxels = v),
            "smoothing_rounds" => set(&mut r.smoothing, |s| s.rounds = v as usize),
            "junction_holes_angle_degrees" => {
                set(&mut r.junction_holes, |h| h.min_angle_degrees = v);
            }
            "junction_fold_reach_voxels" => set(&mut r.junction_fold, |f| f.reach_voxels = v),
            "junction_planes_reach_voxels" => {
                set(&mut r.junction_planes, |j| j.reach_voxels = v);
            }
            "junction_planes_max_shift_voxels" => {
                set(&mut r.junction_planes, |j| j.max_shift_voxels = v);
            }
            "tunnels_max_perimeter_voxels" => {
                set(&mut r.tunnels, |t| t.max_perimeter_voxels = v);
            }
            "flaps_min_alignment" => set(&mut r.flaps, |f| f.min_alignment = v),
            "slice_centroids_min_axis_cosine" => {
                set(&mut r.slice_centroids, |s| s.min_axis_cosine = v);
            }
            "slice_centroids_max_run_slices" => {
                set(&mut r.slice_centroids, |s| s.max_run_slices = v as usize);
            }
            "slice_centroids_max_shift_slices" => {
                set(&mut r.slice_centroids, |s| s.max_shift_slices = v);
            }
            "slice_centroids_max_off_plate_pixels" => {
                set(&mut r.slice_centroids, |s| s.max_off_plate_pixels = v);
            }
            "min_component_fraction" => r.cleaning.min_component_fraction = v,
            "max_hole_perimeter_voxels" => r.cleaning.max_hole_perimeter_voxels = v,
            "min_relative_strength" => p.ridge.min_relative_strength = v,
            "dual_complex" if v != 0.0 => p.tet_complex = sphcover_skeleton::TetComplex::Dual,
            "overlap_complex" if v != 0.0 => {
                p.tet_complex = sphcover_skeleton::TetComplex::Overlap;
            }
            "dual_complex" | "overlap_complex" => {
                p.tet_complex = sphcover_skeleton::TetComplex::Auto;
            }
            "max_eigen_ratio" => p.ridge.max_eigen_ratio = v,
            "off" => {
                // `off=N` switches off the N-th optional repair, in the order of the table
                // in the `repair` module's docs.
                match v as usize {
                    1 => r.rim_trimming = None,
                    2 => r.junction_holes = None,
                    3 => r.tunnels = None,
                    4 => r.flaps = None,
                    5 => (r.centring, r.junction_fold) = (None, None),
                    6 => r.junction_fold = None,
                    7 => r.junction_planes = None,
                    8 => r.slice_centroids = None,
                    _ => panic!("PARAMS: off takes 1..=8"),
                }
            }
            _ => panic!("PARAMS: unknown parameter {name:?}"),
        }
    }
    p
}

/// Applies `change` to a repair's parameters, switching the repair on with its defaults
/// first when it was off.
fn set<T: Default>(repair: &mut Option<T>, change: impl FnOnce(&mut T)) {
    change(repair.get_or_insert_with(T::default));
}
