//! Small perforations through a thin plate: the sheet of `ThinShape::SmallPerforations`
//! (a plate 3 voxels thick with eight holes of radius 1.0–1.7 voxels through the solid, true
//! χ = −7), on isotropic voxels and with every second slice (z spacing 2×), at 10 % and 30 %
//! noise: how many holes the sheet leaves open, its Euler characteristic, coverage and
//! spurious area, and what the repairs did.
//!
//! `cargo run --release -p sphcover-skeleton --example small_perforations [-- --no-perforations] [--seeds A-B] [--write DIR]`
//!
//! `--no-perforations` switches the perforation repair off, to show the sheet without it;
//! `--seeds A-B` runs noise seeds A to B (default 1-3, the seeds the parameters were chosen
//! on; others are held out); `--write DIR` writes each sheet to
//! `DIR/perforations_<noise>_z<step>_seed<seed>.ply`, for `sphcover render`.
use sphcover_core::io::{WriteOptions, write_mesh};
use sphcover_evaluation::sheet_metrics::{line_meets_mesh, score_mesh};
use sphcover_evaluation::thin_phantoms::{
    PhantomParams, ThinShape, every_slice, perforations, thin_phantom,
};
use sphcover_skeleton::{SkeletonParams, extract_skeleton};
use std::path::PathBuf;

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let mut params = SkeletonParams::default();
    if args.iter().any(|a| a == "--no-perforations") {
        params.repairs.perforations = None;
    }
    let seeds = args.iter().position(|a| a == "--seeds").map_or(1..=3, |i| {
        let range = args.get(i + 1).expect("--seeds takes A-B");
        let (a, b) = range.split_once('-').expect("--seeds takes A-B");
        a.parse().expect("a seed")..=b.parse().expect("a seed")
    });
    let write_dir = args
        .iter()
        .position(|a| a == "--write")
        .map(|i| PathBuf::from(args.get(i + 1).expect("--write takes a directory")));
    println!(
        "| noise | z spacing | seed | holes open | χ (truth) | coverage | spurious | fans filled | perforations cut |"
    );
    println!("|---|---|---|---|---|---|---|---|---|");
    for noise in [0.1, 0.3] {
        for step in [1, 2] {
            for seed in seeds.clone() {
                let phantom_params = PhantomParams {
                    noise,
                    seed,
                    ..PhantomParams::default()
                };
                let phantom = thin_phantom(ThinShape::SmallPerforations, &phantom_params);
                let volume = every_slice(&phantom.volume, step);
                let (mesh, stats) = extract_skeleton(&volume, &params, &|_| {}).expect("a sheet");
                if let Some(dir) = &write_dir {
                    let name = format!("perforations_{:.0}_z{step}_seed{seed}.ply", 100.0 * noise);
                    write_mesh(&dir.join(name), &mesh, &WriteOptions::default())
                        .expect("the sheet written");
                }
                let m = score_mesh(&mesh, &phantom.truth, 1.0);
                let holes = perforations(ThinShape::SmallPerforations, &phantom_params);
                let open = holes
                    .iter()
                    .filter(|h| {
                        !line_meets_mesh(&mesh, h.centre, h.axis, 3.0 * phantom_params.voxel)
                    })
                    .count();
                println!(
                    "| {:.0} % | {step}× | {seed} | {open} of {} | {} ({}) | {:.3} | {:.3} | {} | {} |",
                    100.0 * noise,
                    holes.len(),
                    m.euler_characteristic
                        .map_or_else(|| "–".to_owned(), |c| c.to_string()),
                    phantom.truth.euler_characteristic,
                    m.coverage,
                    m.spurious,
                    stats.cleaning.holes_filled,
                    stats.perforations,
                );
            }
        }
    }
}
