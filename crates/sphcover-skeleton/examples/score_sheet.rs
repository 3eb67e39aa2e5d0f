//! Scores a sheet (mesh or point set, world units) against a phantom directory in the layout
//! of the reference phantoms (`meta.json`, `gt_sheet.ply`, `gt_boundary.ply`):
//!
//! `cargo run --release -p sphcover-skeleton --example score_sheet -- PHANTOM_DIR SHEET.ply`
use std::path::Path;
use std::process::ExitCode;

use sphcover_core::io::{self, ReadOptions};
use sphcover_evaluation::sheet_metrics::{read_ground_truth, score_mesh, score_points};

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().collect();
    if args.len() != 3 {
        eprintln!("usage: score_sheet PHANTOM_DIR SHEET");
        return ExitCode::from(2);
    }
    let truth = match read_ground_truth(Path::new(&args[1])) {
        Ok(t) => t,
        Err(e) => {
            eprintln!("error: {}: {e}", args[1]);
            return ExitCode::FAILURE;
        }
    };
    let metrics = match io::read_mesh(Path::new(&args[2]), &ReadOptions::default()) {
        Ok(mesh) if !mesh.triangles.is_empty() => score_mesh(&mesh, &truth, 1.0),
        _ => match io::read_point_cloud(Path::new(&args[2]), &ReadOptions::default()) {
            Ok(cloud) => score_points(&cloud.positions, &truth, 1.0),
            Err(e) => {
                eprintln!("error: {}: {e}", args[2]);
                return ExitCode::FAILURE;
            }
        },
    };
    println!("{metrics:#?}");
    ExitCode::SUCCESS
}
