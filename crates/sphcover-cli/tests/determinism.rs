//! Every subcommand gives byte-identical output whatever `--threads`: the same file (and,
//! for `info`, the same standard output) with 1, 2 and 8 worker threads on the bundled
//! fixtures. Runs are separate processes, so each gets a fresh thread pool.

mod support;

use std::time::Duration;

use support::{fixture, sphcover_in, text};

const THREAD_COUNTS: [&str; 3] = ["1", "2", "8"];
/// Generous against a loaded machine; each run takes about a second at most.
const LIMIT: Duration = Duration::from_secs(120);

/// What one run produced: its standard output and the bytes of each named output file.
#[derive(PartialEq)]
struct Outputs {
    stdout: Vec<u8>,
    files: Vec<(String, Vec<u8>)>,
}

/// Runs `args` (the input paths absolute, output names relative to a fresh directory) with
/// each thread count and asserts that the standard output (when `compare_stdout`) and every
/// file in `outputs` are identical byte for byte.
fn assert_thread_independent(args: &[&str], outputs: &[&str], compare_stdout: bool) {
    let mut first: Option<(String, Outputs)> = None;
    for threads in THREAD_COUNTS {
        let dir = tempfile::tempdir().unwrap();
        let mut full = vec!["--threads", threads, "--quiet"];
        full.extend_from_slice(args);
        let run = sphcover_in(Some(dir.path()), &full, LIMIT);
        assert_eq!(
            run.status.code(),
            Some(0),
            "sphcover {}: {}",
            full.join(" "),
            text(&run.stderr)
        );
        let files = outputs
            .iter()
            .map(|name| {
                let bytes = std::fs::read(dir.path().join(name))
                    .unwrap_or_else(|e| panic!("{name} was written: {e}"));
                assert!(!bytes.is_empty(), "{name} is empty");
                (name.to_string(), bytes)
            })
            .collect();
        let this = Outputs {
            stdout: if compare_stdout {
                run.stdout
            } else {
                Vec::new()
            },
            files,
        };
        match &first {
            None => first = Some((threads.to_string(), this)),
            Some((reference_threads, reference)) => {
                assert!(
                    this.stdout == reference.stdout,
                    "{}: stdout differs between --threads {reference_threads} and {threads}",
                    args.join(" ")
                );
                for ((name, a), (_, b)) in reference.files.iter().zip(&this.files) {
                    assert!(
                        a == b,
                        "{}: {name} differs between --threads {reference_threads} and {threads}",
                        args.join(" ")
                    );
                }
            }
        }
    }
}

fn path(rel: &str) -> String {
    fixture(rel).to_str().unwrap().to_string()
}

#[test]
fn info_json_is_thread_independent() {
    let files = [
        path("real/kitten.ply"),
        path("real/bunny_npm.off"),
        path("torus_3k.xyz"),
        path("grid_spheres.sph"),
        path("phantoms/t_junction_ct_n000.nii.gz"),
    ];
    let mut args = vec!["info", "--json"];
    args.extend(files.iter().map(String::as_str));
    assert_thread_independent(&args, &[], true);
}

#[test]
fn surface_cover_is_thread_independent() {
    let input = path("real/kitten.ply");
    assert_thread_independent(&["cover", &input, "-o", "cover.ply"], &["cover.ply"], false);
}

#[test]
fn volume_cover_is_thread_independent() {
    let input = path("phantoms/t_junction_ct_n000.nii.gz");
    assert_thread_independent(
        &["cover", &input, "--threshold", "500", "-o", "cover.ply"],
        &["cover.ply"],
        false,
    );
}

#[test]
fn tetra_is_thread_independent() {
    let random = path("tetra/random_3k.spheres.txt");
    assert_thread_independent(
        &["tetra", &random, "-o", "mesh.tets"],
        &["mesh.tets"],
        false,
    );
    let grid = path("grid_spheres.sph");
    assert_thread_independent(&["tetra", &grid, "-o", "mesh.vtk"], &["mesh.vtk"], false);
}

#[test]
fn recon_with_every_output_is_thread_independent() {
    let input = path("real/kitten.ply");
    assert_thread_independent(
        &[
            "recon",
            &input,
            "-o",
            "mesh.ply",
            "--depth",
            "6",
            "--points-out",
            "points.ply",
            "--cover-out",
            "cover.ply",
        ],
        &["mesh.ply", "points.ply", "cover.ply"],
        false,
    );
}

#[test]
fn recon_with_estimated_normals_and_graph_cut_is_thread_independent() {
    // The noisy sphere without its normals: normal estimation and orientation, then the
    // graph-cut-only pipeline (dual complex, max-flow, marching tetrahedra, smoothing).
    let input = path("sphere_noisy_2k.ply");
    assert_thread_independent(
        &[
            "recon",
            &input,
            "-o",
            "mesh.obj",
            "--depth",
            "6",
            "--estimate-normals",
            "--method",
            "graphcut",
        ],
        &["mesh.obj"],
        false,
    );
}

#[test]
fn recon_of_an_open_scan_with_trimming_is_thread_independent() {
    let input = path("real/hippo2.ply");
    assert_thread_independent(
        &["recon", &input, "-o", "mesh.ply", "--depth", "6", "--trim"],
        &["mesh.ply"],
        false,
    );
}

#[test]
fn skeleton_is_thread_independent() {
    let input = path("phantoms/t_junction_ct_n000.nii.gz");
    assert_thread_independent(
        &["skeleton", &input, "-o", "sheet.ply"],
        &["sheet.ply"],
        false,
    );
    assert_thread_independent(
        &["skeleton", &input, "--method", "nms", "-o", "sheet.ply"],
        &["sheet.ply"],
        false,
    );
}

#[test]
fn render_is_thread_independent() {
    let points = path("real/kitten.ply");
    assert_thread_independent(
        &[
            "render",
            &points,
            "-o",
            "view.png",
            "--size",
            "160x120",
            "--colour-by",
            "y",
        ],
        &["view.png"],
        false,
    );
    let mesh = path("real/bunny_npm.off");
    assert_thread_independent(
        &[
            "render",
            &mesh,
            "-o",
            "view.png",
            "--size",
            "160x120",
            "--perspective",
        ],
        &["view.png"],
        false,
    );
}
