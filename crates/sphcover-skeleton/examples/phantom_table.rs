//! Runs the skeleton pipeline (default parameters) and the NMS baseline on every generated
//! phantom at the given noise levels and prints the metrics as a Markdown table:
//!
//! `cargo run --release -p sphcover-skeleton --example phantom_table -- 0.1 0.3`
use sphcover_fixtures::sheet_metrics::{SheetMetrics, score_mesh, score_points};
use sphcover_fixtures::thin_phantoms::{PhantomParams, ThinShape, thin_phantom};
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
    let params = SkeletonParams::default();
    println!(
        "| phantom | method | noise | coverage | spurious | spurious away from rim | p95 away from rim (vox) | components | Euler (true) | boundary reach (vox) | time (s) |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|---|");
    for &noise in &noises {
        for shape in ThinShape::ALL {
            let ph = thin_phantom(
                shape,
                &PhantomParams {
                    noise,
                    seed: 1,
                    ..PhantomParams::default()
                },
            );
            let start = std::time::Instant::now();
            match extract_skeleton(&ph.volume, &params) {
                Ok((mesh, _)) => {
                    let secs = start.elapsed().as_secs_f64();
                    let m = score_mesh(&mesh, &ph.truth, 1.0);
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
                match nms_skeleton(&ph.volume, &NmsParams::default()) {
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
