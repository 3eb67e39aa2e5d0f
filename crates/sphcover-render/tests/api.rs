//! The public API as another crate sees it: scenes and options built from outside, what a
//! picture reports about itself, the messages of refusals (the CLI prints them as they are)
//! and the PNG bytes.

use sphcover_render::{
    Background, DVec3, Projection, RenderError, RenderOptions, Scene, Shading, UpAxis, ViewAngles,
    colour_bar_label, render,
};

/// A regular tetrahedron around the origin, wound outwards.
fn tetrahedron() -> ([DVec3; 4], [[u32; 3]; 4]) {
    (
        [
            DVec3::new(1.0, 1.0, 1.0),
            DVec3::new(1.0, -1.0, -1.0),
            DVec3::new(-1.0, 1.0, -1.0),
            DVec3::new(-1.0, -1.0, 1.0),
        ],
        [[0, 1, 2], [0, 3, 1], [0, 2, 3], [1, 3, 2]],
    )
}

fn options(width: usize, height: usize) -> RenderOptions {
    RenderOptions {
        width,
        height,
        background: Background::Transparent,
        ..RenderOptions::default()
    }
}

#[test]
fn the_camera_of_a_picture_places_points_in_it() {
    let (positions, triangles) = tetrahedron();
    let scene = Scene {
        positions: &positions,
        triangles: &triangles,
        normals: None,
        radii: None,
        scalars: None,
        colors: None,
    };
    let opts = RenderOptions {
        view: ViewAngles::parse("30,20").unwrap(),
        projection: Projection::Perspective { fov_deg: 40.0 },
        shading: Shading::Flat,
        ..options(160, 120)
    };
    let out = render(&scene, &opts).unwrap();
    assert_eq!(out.triangles, 4);
    assert_eq!(
        (out.splats, out.point_diameter, out.colour_range),
        (0, None, None)
    );
    // Every vertex lands inside the picture, and the middle of every face, front or back,
    // lands on the solid.
    for p in positions {
        let q = out.camera.project(p);
        assert!(out.camera.in_front(q.distance));
        assert!(
            (0.0..160.0).contains(&q.x) && (0.0..120.0).contains(&q.y),
            "{q:?}"
        );
    }
    for t in triangles {
        let centre = t.iter().map(|&v| positions[v as usize]).sum::<DVec3>() / 3.0;
        let q = out.camera.project(centre);
        let pixel = out.image.get(q.x as usize, q.y as usize);
        assert_eq!(pixel[3], 255, "face {t:?} at {q:?}");
    }
    assert_eq!(out.image.get(0, 0)[3], 0);
}

#[test]
fn colouring_by_a_value_reports_its_range_and_draws_a_bar() {
    let (positions, triangles) = tetrahedron();
    let values = [0.0, 1.0, 2.0, 4.0];
    let scene = Scene {
        positions: &positions,
        triangles: &triangles,
        normals: None,
        radii: None,
        scalars: Some(&values),
        colors: None,
    };
    let out = render(&scene, &options(600, 450)).unwrap();
    assert_eq!(out.colour_range, Some((0.0, 4.0)));
    assert!(out.colour_bar);
    let small = render(&scene, &options(60, 45)).unwrap();
    assert!(!small.colour_bar, "a bar would not fit");
    let opts = RenderOptions {
        colour_range: Some((-1.0, 1.0)),
        colour_bar: false,
        ..options(600, 450)
    };
    let out = render(&scene, &opts).unwrap();
    assert_eq!(
        (out.colour_range, out.colour_bar),
        (Some((-1.0, 1.0)), false)
    );
    assert_eq!(colour_bar_label(-1.0), "-1");
    assert_eq!(colour_bar_label(2.5e7), "2.50e7");
}

#[test]
fn sphere_sets_are_balls_and_points_are_splats() {
    let positions = [
        DVec3::ZERO,
        DVec3::new(3.0, 0.0, 0.0),
        DVec3::new(0.0, 0.0, 3.0),
    ];
    let radii = [1.0, 0.5, 0.25];
    let balls = Scene {
        positions: &positions,
        triangles: &[],
        normals: None,
        radii: Some(&radii),
        scalars: None,
        colors: None,
    };
    let opts = RenderOptions {
        up: UpAxis::Z,
        ..options(200, 150)
    };
    let out = render(&balls, &opts).unwrap();
    assert_eq!(
        (out.triangles, out.splats, out.point_diameter),
        (0, 3, None)
    );
    let q = out.camera.project(positions[0]);
    assert_eq!(out.image.get(q.x as usize, q.y as usize)[3], 255);

    let points = Scene {
        radii: None,
        ..balls
    };
    let out = render(&points, &opts).unwrap();
    assert_eq!(out.splats, 3);
    let d = out.point_diameter.unwrap();
    assert!((1.0..=24.0).contains(&d), "{d}");
    let fixed = RenderOptions {
        point_diameter: Some(5.0),
        ..opts
    };
    assert_eq!(render(&points, &fixed).unwrap().point_diameter, Some(5.0));
}

#[test]
fn refusals_say_what_is_wrong() {
    let (positions, triangles) = tetrahedron();
    let scene = Scene {
        positions: &positions,
        triangles: &triangles,
        normals: None,
        radii: None,
        scalars: None,
        colors: None,
    };
    let message = |opts: RenderOptions| render(&scene, &opts).unwrap_err().to_string();
    assert_eq!(
        message(options(0, 10)),
        "image size 0x10: each side must be between 1 and 16384 pixels"
    );
    assert_eq!(
        message(RenderOptions {
            supersample: 9,
            ..options(10, 10)
        }),
        "supersampling 9: must be between 1 and 4"
    );
    assert_eq!(
        message(RenderOptions {
            point_diameter: Some(-2.0),
            ..options(10, 10)
        }),
        "point size -2: must be a positive number of pixels"
    );
    let short = [1.0, 2.0];
    let bad = Scene {
        scalars: Some(&short),
        ..scene
    };
    let err = render(&bad, &options(10, 10)).unwrap_err();
    assert!(matches!(err, RenderError::Inconsistent(_)), "{err:?}");
    assert_eq!(
        err.to_string(),
        "inconsistent scene: 2 values for 4 vertices"
    );
}

#[test]
fn png_bytes_are_the_same_every_time() {
    let (positions, triangles) = tetrahedron();
    let scene = Scene {
        positions: &positions,
        triangles: &triangles,
        normals: None,
        radii: None,
        scalars: None,
        colors: None,
    };
    let encode = |background| {
        let opts = RenderOptions {
            background,
            ..options(90, 70)
        };
        let mut bytes = Vec::new();
        let image = render(&scene, &opts).unwrap().image;
        image.write_png(&mut bytes).unwrap();
        (image, bytes)
    };
    let (image, bytes) = encode(Background::Transparent);
    assert!(!image.is_opaque());
    assert_eq!(encode(Background::Transparent).1, bytes);

    let decoder = png::Decoder::new(std::io::Cursor::new(&bytes));
    let info = decoder.read_info().unwrap().info().clone();
    assert_eq!((info.width, info.height), (90, 70));
    assert_eq!(info.color_type, png::ColorType::Rgba);

    let (opaque, bytes) = encode(Background::Colour([10, 20, 30]));
    assert!(opaque.is_opaque());
    assert_eq!(opaque.get(0, 0), [10, 20, 30, 255]);
    let decoder = png::Decoder::new(std::io::Cursor::new(&bytes));
    assert_eq!(
        decoder.read_info().unwrap().info().color_type,
        png::ColorType::Rgb
    );
}
