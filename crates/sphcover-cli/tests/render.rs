//! End-to-end tests of `sphcover render`: silhouettes, determinism, colour by a property,
//! point splats and refused inputs.

mod support;

use std::fmt::Write as _;
use std::path::Path;

use support::{fixture, run as sphcover, text};

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// A decoded PNG as RGBA rows.
struct Png {
    width: usize,
    height: usize,
    rgba: Vec<u8>,
}

impl Png {
    fn read(path: &Path) -> Png {
        let file = std::io::BufReader::new(std::fs::File::open(path).unwrap());
        let mut reader = png::Decoder::new(file).read_info().unwrap();
        let mut buf = vec![0; reader.output_buffer_size().unwrap()];
        let info = reader.next_frame(&mut buf).unwrap();
        buf.truncate(info.buffer_size());
        let rgba = match info.color_type {
            png::ColorType::Rgba => buf,
            png::ColorType::Rgb => buf
                .chunks_exact(3)
                .flat_map(|p| [p[0], p[1], p[2], 255])
                .collect(),
            other => panic!("unexpected colour type {other:?}"),
        };
        Png {
            width: info.width as usize,
            height: info.height as usize,
            rgba,
        }
    }

    fn pixel(&self, x: usize, y: usize) -> [u8; 4] {
        let i = 4 * (y * self.width + x);
        [
            self.rgba[i],
            self.rgba[i + 1],
            self.rgba[i + 2],
            self.rgba[i + 3],
        ]
    }

    /// Covered area in pixels: the sum of the alpha channel.
    fn coverage(&self) -> f64 {
        self.rgba
            .chunks_exact(4)
            .map(|p| f64::from(p[3]) / 255.0)
            .sum()
    }
}

/// A UV sphere of radius 1 as OFF text, poles on ±y and equator vertices on ±x and ±z, so
/// that its front-view extent is exactly the diameter.
fn sphere_off(stacks: usize, slices: usize) -> String {
    let mesh = sphcover_core::synthetic::uv_sphere(1.0, stacks, slices);
    let mut out = format!("OFF\n{} {} 0\n", mesh.vertices.len(), mesh.triangles.len());
    for v in &mesh.vertices {
        writeln!(out, "{} {} {}", v.x, v.y, v.z).unwrap();
    }
    for f in &mesh.triangles {
        writeln!(out, "3 {} {} {}", f[0], f[1], f[2]).unwrap();
    }
    out
}

/// A flat square in the z = 0 plane, two triangles, with a `quality` property equal to x
/// and a `label` property.
fn square_ply() -> String {
    "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\n\
     property float z\nproperty float quality\nproperty uchar label\nelement face 2\n\
     property list uchar int vertex_indices\nend_header\n\
     0 0 0 0 1\n1 0 0 1 1\n1 1 0 1 0\n0 1 0 0 0\n3 0 1 2\n3 0 2 3\n"
        .to_string()
}

#[test]
fn a_sphere_mesh_covers_a_disc_of_its_radius() {
    let dir = tempfile::tempdir().unwrap();
    let mesh = dir.path().join("sphere.off");
    std::fs::write(&mesh, sphere_off(64, 128)).unwrap();
    let out_path = dir.path().join("sphere.png");
    let out = sphcover(&[
        "render",
        s(&mesh),
        "-o",
        s(&out_path),
        "--view",
        "front",
        "--size",
        "320x240",
        "--background",
        "transparent",
    ]);
    assert_eq!(out.status.code(), Some(0), "{}", text(&out.stderr));
    let png = Png::read(&out_path);
    assert_eq!((png.width, png.height), (320, 240));
    // The fit leaves 5% of the smaller side free above and below the sphere.
    let r = 0.5 * 240.0 * 0.9;
    let disc = std::f64::consts::PI * r * r;
    let covered = png.coverage();
    assert!(
        (covered - disc).abs() < 0.01 * disc,
        "covered {covered} px, disc {disc} px"
    );
    // Centred, and lit: brighter towards the light (upper left) than the lower right.
    assert_eq!(png.pixel(160, 120)[3], 255);
    assert_eq!(png.pixel(5, 5)[3], 0);
    let upper_left = png.pixel(160 - 60, 120 - 60)[0];
    let lower_right = png.pixel(160 + 60, 120 + 60)[0];
    assert!(upper_left > lower_right, "{upper_left} vs {lower_right}");
}

#[test]
fn output_is_byte_identical_whatever_the_thread_count() {
    let dir = tempfile::tempdir().unwrap();
    for input in ["real/bunny_npm.off", "real/kitten.ply"] {
        let mut images = Vec::new();
        for threads in ["1", "2", "3"] {
            let path = dir.path().join(format!("out{threads}.png"));
            let out = sphcover(&[
                "--threads",
                threads,
                "render",
                s(&fixture(input)),
                "-o",
                s(&path),
                "--size",
                "300x200",
                "--view",
                "30,20",
                "--colour-by",
                "y",
            ]);
            assert_eq!(out.status.code(), Some(0), "{}", text(&out.stderr));
            images.push(std::fs::read(&path).unwrap());
        }
        assert!(images.windows(2).all(|w| w[0] == w[1]), "{input}");
    }
}

#[test]
fn colour_by_a_ply_property_follows_its_values() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("square.ply");
    std::fs::write(&input, square_ply()).unwrap();
    let out_path = dir.path().join("square.png");
    let out = sphcover(&[
        "render",
        s(&input),
        "-o",
        s(&out_path),
        "--view",
        "front",
        "--size",
        "400x300",
        "--color-by", // the American spelling is an alias
        "quality",
        "--no-color-bar",
    ]);
    assert_eq!(out.status.code(), Some(0), "{}", text(&out.stderr));
    let stderr = text(&out.stderr);
    assert!(
        stderr.contains("colour by quality: 0 (dark purple) to 1 (yellow)"),
        "{stderr}"
    );
    let png = Png::read(&out_path);
    // quality = x: the left edge is viridis' purple (blue above green), the right edge its
    // yellow (red and green above blue).
    let left = png.pixel(70, 150);
    let right = png.pixel(330, 150);
    assert!(left[2] > left[1] && left[2] > 40, "{left:?}");
    assert!(
        right[0] > right[2] + 60 && right[1] > right[2] + 60,
        "{right:?}"
    );

    // A colour bar takes a strip on the right; the square moves left to make room.
    let with_bar = dir.path().join("bar.png");
    let out = sphcover(&[
        "render",
        s(&input),
        "-o",
        s(&with_bar),
        "--view",
        "front",
        "--size",
        "400x300",
        "--colour-by",
        "label",
        "--range",
        "0,2",
    ]);
    assert_eq!(out.status.code(), Some(0), "{}", text(&out.stderr));
    assert!(text(&out.stderr).contains("colour by label: 0 (dark purple) to 2 (yellow)"));
    let png = Png::read(&with_bar);
    let yellow_rows = (0..300)
        .filter(|&y| {
            (300..400).any(|x| {
                let p = png.pixel(x, y);
                p[0] > 200 && p[1] > 200 && p[2] < 100
            })
        })
        .count();
    assert!(yellow_rows > 0, "no colour bar top in the right strip");
}

#[test]
fn points_are_drawn_as_splats() {
    let dir = tempfile::tempdir().unwrap();
    let small = dir.path().join("small.png");
    let large = dir.path().join("large.png");
    for (path, size) in [(&small, "1"), (&large, "12")] {
        let out = sphcover(&[
            "render",
            s(&fixture("sphere_2k.ply")),
            "-o",
            s(path),
            "--view",
            "front",
            "--size",
            "200x200",
            "--background",
            "transparent",
            "--point-size",
            size,
        ]);
        assert_eq!(out.status.code(), Some(0), "{}", text(&out.stderr));
        assert!(text(&out.stderr).contains("2000 points as"));
    }
    let (small, large) = (Png::read(&small), Png::read(&large));
    // The sphere of 2,000 points: large splats close the surface into (about) the disc,
    // 1-pixel splats cover a small part of it; nothing lands outside the disc.
    let r = 0.5 * 200.0 * 0.9;
    let disc = std::f64::consts::PI * r * r;
    // Rim splats reach up to their radius (6 px) beyond the fitted silhouette.
    let rim = std::f64::consts::PI * (r + 6.0) * (r + 6.0);
    assert!(
        large.coverage() > 0.9 * disc && large.coverage() < rim,
        "{}",
        large.coverage()
    );
    assert!(small.coverage() < 0.2 * disc, "{}", small.coverage());
    assert_eq!(large.pixel(2, 2)[3], 0);

    // The automatic size closes a scan too.
    let auto = dir.path().join("auto.png");
    let out = sphcover(&[
        "render",
        s(&fixture("sphere_2k.ply")),
        "-o",
        s(&auto),
        "--view",
        "front",
        "--size",
        "200x200",
        "--background",
        "transparent",
    ]);
    assert_eq!(out.status.code(), Some(0), "{}", text(&out.stderr));
    assert!(Png::read(&auto).coverage() > 0.85 * disc);
}

#[test]
fn sphere_sets_are_drawn_as_balls() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("grid.png");
    let out = sphcover(&["render", s(&fixture("grid_spheres.sph")), "-o", s(&path)]);
    assert_eq!(out.status.code(), Some(0), "{}", text(&out.stderr));
    assert!(
        text(&out.stderr).contains("125 balls"),
        "{}",
        text(&out.stderr)
    );
}

#[test]
fn bad_input_exits_2_with_a_message() {
    let dir = tempfile::tempdir().unwrap();
    let png = dir.path().join("x.png");
    let kitten = fixture("real/kitten.ply");
    let before = std::fs::read(&kitten).unwrap();
    let cases: Vec<(Vec<String>, &str)> = vec![
        (
            vec![s(&dir.path().join("missing.ply")).into()],
            "cannot read",
        ),
        (vec![s(&fixture("malformed/empty.ply")).into()], "empty.ply"),
        (
            vec![s(&kitten).into(), "--view".into(), "sideways".into()],
            "view",
        ),
        (
            vec![s(&kitten).into(), "--size".into(), "0x10".into()],
            "image size",
        ),
        (
            vec![s(&kitten).into(), "--size".into(), "big".into()],
            "--size",
        ),
        (
            vec![s(&kitten).into(), "--background".into(), "#12".into()],
            "--background",
        ),
        (
            vec![s(&kitten).into(), "--supersample".into(), "9".into()],
            "supersampling",
        ),
        (
            vec![s(&kitten).into(), "--point-size".into(), "-2".into()],
            "point size",
        ),
        (
            vec![s(&kitten).into(), "--colour-by".into(), "nope".into()],
            "the file has: x, y, z, nx, ny, nz",
        ),
        (
            vec![s(&kitten).into(), "--range".into(), "0,1".into()],
            "--range needs --colour-by",
        ),
        (
            vec![
                s(&kitten).into(),
                "--colour-by".into(),
                "x".into(),
                "--range".into(),
                "1,0".into(),
            ],
            "--range",
        ),
    ];
    for (args, message) in cases {
        let mut full: Vec<&str> = vec!["render"];
        full.extend(args.iter().map(String::as_str));
        full.extend(["-o", s(&png)]);
        let out = sphcover(&full);
        let stderr = text(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{full:?}: {stderr}");
        assert!(stderr.contains(message), "{full:?}: {stderr}");
        assert!(!png.exists(), "{full:?} wrote an image");
    }
    // Output over the input: refused (not a PNG), input untouched.
    let out = sphcover(&["render", s(&kitten), "-o", s(&kitten)]);
    assert_eq!(out.status.code(), Some(2));
    assert!(
        text(&out.stderr).contains("must end in .png"),
        "{}",
        text(&out.stderr)
    );
    assert_eq!(std::fs::read(&kitten).unwrap(), before);
}
