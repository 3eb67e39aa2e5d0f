//! Reading a scan a block at a time gives exactly the points of the whole read, in order,
//! whatever the block size, format and encoding; a damaged file fails as its whole read does.

use std::path::{Path, PathBuf};

use proptest::prelude::*;
use sphcover_core::io::{
    IoError, PlyEncoding, Precision, ReadOptions, WriteOptions, read_point_cloud, stream_points,
    write_point_cloud,
};
use sphcover_core::{DVec3, PointCloud};

fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("sphcover-stream-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir.join(name)
}

/// The blocks of `path`, joined, and how many there were.
fn streamed(path: &Path, block: usize) -> Result<(PointCloud, usize, bool), IoError> {
    let mut joined = PointCloud::default();
    let mut blocks = 0;
    let info = stream_points(path, &ReadOptions::default(), block, |b: PointCloud| {
        assert!(b.len() <= block.max(1) && !b.is_empty());
        blocks += 1;
        joined.positions.extend(&b.positions);
        for (all, part) in [(&mut joined.normals, b.normals)] {
            if let Some(part) = part {
                all.get_or_insert_with(Vec::new).extend(part);
            }
        }
        if let Some(part) = b.confidence {
            joined.confidence.get_or_insert_with(Vec::new).extend(part);
        }
        if let Some(part) = b.values {
            joined.values.get_or_insert_with(Vec::new).extend(part);
        }
        if let Some(part) = b.colors {
            joined.colors.get_or_insert_with(Vec::new).extend(part);
        }
        Ok::<(), IoError>(())
    })?;
    assert_eq!(info.points as usize, joined.len());
    Ok((joined, blocks, info.streamed))
}

fn cloud(n: usize, seed: u64, attributes: bool) -> PointCloud {
    let mut s = seed;
    let mut next = move || {
        s = s
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (s >> 11) as f64 / (1u64 << 53) as f64 - 0.5
    };
    let positions: Vec<DVec3> = (0..n).map(|_| DVec3::new(next(), next(), next())).collect();
    PointCloud {
        normals: attributes.then(|| positions.iter().map(|p| p.normalize_or(DVec3::Z)).collect()),
        confidence: attributes.then(|| (0..n).map(|i| (i % 7) as f64 / 7.0).collect()),
        colors: attributes.then(|| (0..n).map(|i| [i as u8, 3, 200]).collect()),
        positions,
        ..PointCloud::default()
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(24))]
    #[test]
    fn blocks_join_to_the_whole_read(
        n in 1usize..600,
        block in 1usize..200,
        seed in any::<u64>(),
        attributes in any::<bool>(),
        encoding in 0usize..3,
        f32s in any::<bool>(),
    ) {
        let encoding = [PlyEncoding::BinaryLittleEndian, PlyEncoding::BinaryBigEndian, PlyEncoding::Ascii][encoding];
        let path = scratch(&format!("p{seed}-{n}-{block}.ply"));
        let options = WriteOptions {
            ply_encoding: encoding,
            precision: if f32s { Precision::F32 } else { Precision::F64 },
            inputs: Vec::new(),
        };
        write_point_cloud(&path, &cloud(n, seed, attributes), &options).unwrap();
        let whole = read_point_cloud(&path, &ReadOptions::default()).unwrap();
        let (joined, blocks, was_streamed) = streamed(&path, block).unwrap();
        std::fs::remove_file(&path).unwrap();
        prop_assert_eq!(joined, whole);
        prop_assert_eq!(blocks, n.div_ceil(block));
        prop_assert_eq!(was_streamed, encoding != PlyEncoding::Ascii);
    }
}

#[test]
fn text_formats_are_read_whole_and_handed_out_in_blocks() {
    let path = scratch("points.xyz");
    write_point_cloud(&path, &cloud(250, 7, false), &WriteOptions::default()).unwrap();
    let (joined, blocks, was_streamed) = streamed(&path, 100).unwrap();
    assert_eq!(
        joined,
        read_point_cloud(&path, &ReadOptions::default()).unwrap()
    );
    assert_eq!((blocks, was_streamed), (3, false));
}

/// LAS and LAZ (the same 13,511 points of an aerial survey, `fixtures/real`) stream the
/// positions of their whole reads.
#[test]
fn las_and_laz_stream_their_positions() {
    let fixtures = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fixtures/real");
    for name in ["urban.las", "urban.laz"] {
        let path = fixtures.join(name);
        let whole = read_point_cloud(&path, &ReadOptions::default()).unwrap();
        let (joined, blocks, was_streamed) = streamed(&path, 4000).unwrap();
        assert_eq!(joined.positions, whole.positions, "{name}");
        assert_eq!((blocks, was_streamed), (4, true), "{name}");
    }
}

#[test]
fn a_truncated_file_fails_naming_it_and_the_byte() {
    let path = scratch("cut.ply");
    write_point_cloud(&path, &cloud(100, 3, true), &WriteOptions::default()).unwrap();
    let bytes = std::fs::read(&path).unwrap();
    std::fs::write(&path, &bytes[..bytes.len() - 10]).unwrap();
    let whole = read_point_cloud(&path, &ReadOptions::default()).unwrap_err();
    let blockwise = streamed(&path, 16).unwrap_err();
    assert_eq!(blockwise.to_string(), whole.to_string());
    assert!(blockwise.to_string().contains("cut.ply"), "{blockwise}");
}

#[test]
fn the_consumer_can_stop_the_stream() {
    let path = scratch("stop.ply");
    write_point_cloud(&path, &cloud(100, 5, false), &WriteOptions::default()).unwrap();
    let mut seen = 0;
    let stopped = stream_points(&path, &ReadOptions::default(), 10, |_| {
        seen += 1;
        if seen == 3 {
            Err(IoError::Read {
                path: "stop.ply".into(),
                source: std::io::Error::other("enough"),
            })
        } else {
            Ok(())
        }
    });
    assert!(stopped.is_err());
    assert_eq!(seen, 3);
}
