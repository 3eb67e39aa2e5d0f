//! Large files: the memory-mapped path, and results that do not depend on the thread count.

use sphcover_core::io::{
    NonFinitePolicy, PlyEncoding, Precision, ReadOptions, WriteOptions, read_geometry,
    write_point_cloud,
};
use sphcover_core::{DVec3, PointCloud};

fn cloud(n: usize) -> PointCloud {
    let positions: Vec<DVec3> = (0..n)
        .map(|i| {
            let t = i as f64 * 1e-3;
            DVec3::new(t.sin(), t.cos(), t)
        })
        .collect();
    let normals = positions.iter().map(|p| p.normalize()).collect();
    PointCloud {
        positions,
        normals: Some(normals),
        confidence: None,
        values: None,
        colors: Some((0..n).map(|i| [i as u8, (i >> 8) as u8, 255]).collect()),
    }
}

fn in_pool<T: Send>(threads: usize, f: impl FnOnce() -> T + Send) -> T {
    sphcover_core::on_threads(threads, f)
}

#[test]
fn a_file_above_the_mapping_threshold_reads_back_identically_on_any_thread_count() {
    // 3M points of 27 bytes (f32 position and normal, 8-bit colour): 81 MB, above the
    // 64 MiB mapping threshold.
    let mut pc = cloud(3_000_000);
    pc.positions[2_999_999].y = f64::NAN;
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("big.ply");
    let options = WriteOptions {
        precision: Precision::F32,
        ..WriteOptions::default()
    };
    write_point_cloud(&path, &pc, &options).unwrap();
    assert!(std::fs::metadata(&path).unwrap().len() > 64 << 20);

    let err = read_geometry(&path, &ReadOptions::default()).unwrap_err();
    let head = std::fs::read(&path).unwrap();
    let body = head.windows(11).position(|w| w == b"end_header\n").unwrap() + 11;
    let message = err.to_string();
    let expected = format!(
        "byte {}: vertex 2999999 is not finite",
        body + 2_999_999 * 27
    );
    assert!(message.contains(&expected), "{message}");

    let keep = ReadOptions {
        non_finite: NonFinitePolicy::Keep,
        ..ReadOptions::default()
    };
    let one = in_pool(1, || read_geometry(&path, &keep).unwrap());
    let three = in_pool(3, || read_geometry(&path, &keep).unwrap());
    let bits = |v: &[DVec3]| -> Vec<[u64; 3]> {
        v.iter().map(|p| p.to_array().map(f64::to_bits)).collect()
    };
    assert!(bits(&one.points.positions) == bits(&three.points.positions));
    assert!(
        bits(one.points.normals.as_ref().unwrap()) == bits(three.points.normals.as_ref().unwrap())
    );
    assert_eq!(one.points.colors, three.points.colors);
    assert_eq!(one.points.colors, pc.colors);
    assert_eq!(one.info.non_finite.vertices, 1);
    let rounded = |v: DVec3| DVec3::new(v.x as f32 as f64, v.y as f32 as f64, v.z as f32 as f64);
    for i in [0, 1, 1_234_567, 2_999_998] {
        assert_eq!(one.points.positions[i], rounded(pc.positions[i]));
        assert_eq!(
            one.points.normals.as_ref().unwrap()[i],
            rounded(pc.normals.as_ref().unwrap()[i])
        );
    }
}

#[test]
fn ascii_and_binary_results_match_on_a_parallel_sized_cloud() {
    let pc = cloud(200_000);
    let dir = tempfile::tempdir().unwrap();
    let mut results = Vec::new();
    for (k, encoding) in [
        PlyEncoding::Ascii,
        PlyEncoding::BinaryLittleEndian,
        PlyEncoding::BinaryBigEndian,
    ]
    .into_iter()
    .enumerate()
    {
        let path = dir.path().join(format!("c{k}.ply"));
        write_point_cloud(
            &path,
            &pc,
            &WriteOptions {
                ply_encoding: encoding,
                ..WriteOptions::default()
            },
        )
        .unwrap();
        let written = std::fs::read(&path).unwrap();
        // Writers encode in parallel chunks: the bytes must not depend on the thread count.
        in_pool(1, || {
            write_point_cloud(
                &path,
                &pc,
                &WriteOptions {
                    ply_encoding: encoding,
                    ..WriteOptions::default()
                },
            )
        })
        .unwrap();
        assert_eq!(std::fs::read(&path).unwrap(), written);
        results.push(
            read_geometry(&path, &ReadOptions::default())
                .unwrap()
                .points,
        );
    }
    for r in &results {
        assert_eq!(r, &pc);
    }
}
