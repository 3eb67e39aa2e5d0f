//! A tile's input and function as bytes, so that a distributed engine can move them between
//! processes and machines as opaque blobs (and keep them for a retry).
//!
//! Little-endian, fixed layout, behind a magic tag and a version: the same bytes whatever
//! the machine. Decoding checks every length against what is there and fails with
//! [`ReconError::TileRunner`], never panics.

use sphcover_core::{Aabb, Cover, DVec3, Kernel, LocalFunctions, Normalisation};

use super::ReconError;
use super::streamed::{StreamedTile, StreamedTileProduct};
use super::tiled::{TileFunction, TileInput};

const INPUT_TAG: &[u8; 8] = b"SPCTIN02";
const FUNCTION_TAG: &[u8; 8] = b"SPCTFN01";
const STREAMED_TILE_TAG: &[u8; 8] = b"SPCSTT02";
const STREAMED_PRODUCT_TAG: &[u8; 8] = b"SPCSTP01";

impl StreamedTile {
    /// The task as bytes ([`StreamedTile::from_bytes`] reads them back). The directory is
    /// stored as UTF-8 (a path that is not is stored with its invalid parts replaced).
    pub fn to_bytes(&self) -> Vec<u8> {
        let mut w = Writer(Vec::with_capacity(512));
        w.0.extend_from_slice(STREAMED_TILE_TAG);
        w.u64(self.tile as u64);
        for p in self.position {
            w.u64(p as u64);
        }
        let dir = self.directory.to_string_lossy();
        w.u64(dir.len() as u64);
        w.0.extend_from_slice(dir.as_bytes());
        w.0.push(u8::from(self.scanner));
        for splits in &self.input_splits {
            w.u64(splits.len() as u64);
            splits.iter().for_each(|&x| w.f64(x));
        }
        w.vec3(self.frame.centre);
        w.f64(self.frame.scale);
        w.vec3(self.own_box.min);
        w.vec3(self.own_box.max);
        w.f64(self.spacing);
        w.f64(self.noise);
        w.f64(self.eps);
        w.0.push(u8::from(self.drop_isolated));
        w.0.push(u8::from(self.one_view));
        w.u64(u64::from(self.depth));
        w.0
    }

    /// Reads what [`StreamedTile::to_bytes`] wrote.
    pub fn from_bytes(bytes: &[u8]) -> Result<StreamedTile, ReconError> {
        let mut r = Reader::new(bytes, STREAMED_TILE_TAG, "streamed tile")?;
        let tile = r.count()?;
        let position = [r.count()?, r.count()?, r.count()?];
        let dir_len = r.len()?;
        let directory = String::from_utf8(r.take(dir_len)?.to_vec())
            .map_err(|_| r.error("a directory that is not UTF-8"))?
            .into();
        let scanner = r.flag()?;
        let mut input_splits: [Vec<f64>; 3] = Default::default();
        for splits in &mut input_splits {
            let n = r.len()?;
            *splits = r.f64s(n)?;
        }
        let frame = Normalisation {
            centre: r.vec3()?,
            scale: r.f64()?,
        };
        let own_box = Aabb {
            min: r.vec3()?,
            max: r.vec3()?,
        };
        let (spacing, noise, eps) = (r.f64()?, r.f64()?, r.f64()?);
        let drop_isolated = r.flag()?;
        let one_view = r.flag()?;
        let depth = u32::try_from(r.u64()?).map_err(|_| r.error("a depth beyond u32"))?;
        r.end()?;
        Ok(StreamedTile {
            tile,
            position,
            directory,
            scanner,
            input_splits,
            frame,
            own_box,
            spacing,
            noise,
            eps,
            drop_isolated,
            one_view,
            depth,
        })
    }
}

impl StreamedTileProduct {
    /// The product as bytes ([`StreamedTileProduct::from_bytes`] reads them back).
    pub fn to_bytes(&self) -> Vec<u8> {
        let function = self.function.to_bytes();
        let seeds: usize = self.seeds.iter().map(Vec::len).sum();
        let mut w = Writer(Vec::with_capacity(function.len() + 24 * seeds + 128));
        w.0.extend_from_slice(STREAMED_PRODUCT_TAG);
        w.u64(function.len() as u64);
        w.0.extend_from_slice(&function);
        for seeds in &self.seeds {
            w.u64(seeds.len() as u64);
            seeds.iter().for_each(|&p| w.vec3(p));
        }
        for x in self.qualified {
            w.u64(x as u64);
        }
        for x in [self.own_samples, self.samples, self.isolated, self.outliers] {
            w.u64(x as u64);
        }
        w.0
    }

    /// Reads what [`StreamedTileProduct::to_bytes`] wrote.
    pub fn from_bytes(bytes: &[u8]) -> Result<StreamedTileProduct, ReconError> {
        let mut r = Reader::new(bytes, STREAMED_PRODUCT_TAG, "streamed tile product")?;
        let function_len = r.len()?;
        let function = TileFunction::from_bytes(r.take(function_len)?)?;
        let mut seeds: [Vec<DVec3>; 2] = Default::default();
        for set in &mut seeds {
            let n = r.len()?;
            *set = r.vec3s(n)?;
        }
        let qualified = [r.count()?, r.count()?];
        let [own_samples, samples, isolated, outliers] =
            [r.count()?, r.count()?, r.count()?, r.count()?];
        r.end()?;
        Ok(StreamedTileProduct {
            function,
            seeds,
            qualified,
            own_samples,
            samples,
            isolated,
            outliers,
        })
    }
}

impl TileInput {
    /// The input as bytes ([`TileInput::from_bytes`] reads them back).
    pub fn to_bytes(&self) -> Vec<u8> {
        let n = self.points.len();
        let mut w = Writer(Vec::with_capacity(128 + n * 58));
        w.0.extend_from_slice(INPUT_TAG);
        for p in self.position {
            w.u64(p as u64);
        }
        w.vec3(self.own_box.min);
        w.vec3(self.own_box.max);
        w.u64(n as u64);
        w.f64(self.spacing);
        w.f64(self.noise);
        w.f64(self.eps);
        w.0.push(u8::from(self.drop_isolated));
        w.0.push(u8::from(self.one_view));
        w.u64(u64::from(self.depth));
        w.0.push(u8::from(self.scanner.is_some()));
        self.points.iter().for_each(|&p| w.vec3(p));
        self.normals.iter().for_each(|&p| w.vec3(p));
        if let Some(c) = &self.scanner {
            c.iter().for_each(|&x| w.f64(x));
        }
        w.0.extend(self.isolated.iter().map(|&b| u8::from(b)));
        w.0.extend(self.own.iter().map(|&b| u8::from(b)));
        w.0
    }

    /// Reads what [`TileInput::to_bytes`] wrote.
    pub fn from_bytes(bytes: &[u8]) -> Result<TileInput, ReconError> {
        let mut r = Reader::new(bytes, INPUT_TAG, "tile input")?;
        let position = [r.len()?, r.len()?, r.len()?];
        let own_box = Aabb {
            min: r.vec3()?,
            max: r.vec3()?,
        };
        let n = r.len()?;
        let (spacing, noise, eps) = (r.f64()?, r.f64()?, r.f64()?);
        let drop_isolated = r.flag()?;
        let one_view = r.flag()?;
        let depth = u32::try_from(r.u64()?).map_err(|_| r.error("a depth beyond u32"))?;
        let has_scanner = r.flag()?;
        let points = r.vec3s(n)?;
        let normals = r.vec3s(n)?;
        let scanner = if has_scanner { Some(r.f64s(n)?) } else { None };
        let isolated = r.flags(n)?;
        let own = r.flags(n)?;
        r.end()?;
        let bad = |what: &str| ReconError::TileRunner(format!("tile input: {what}"));
        if !own_box.min.cmple(own_box.max).all() {
            return Err(bad("a box whose lower corner is not below its upper one"));
        }
        if let Some(i) = (0..n).find(|&i| !(points[i].is_finite() && normals[i].is_finite())) {
            return Err(bad(&format!("sample {i} is not finite")));
        }
        if ![spacing, noise, eps]
            .iter()
            .all(|x| x.is_finite() && *x >= 0.0)
        {
            return Err(bad(
                "a spacing, noise or tolerance that is not a finite length",
            ));
        }
        Ok(TileInput {
            position,
            own_box,
            points,
            normals,
            scanner,
            isolated,
            own,
            spacing,
            noise,
            eps,
            drop_isolated,
            one_view,
            depth,
        })
    }
}

impl TileFunction {
    /// The function as bytes ([`TileFunction::from_bytes`] reads them back).
    pub fn to_bytes(&self) -> Vec<u8> {
        let m = self.cover.len();
        let own = self.confidence.len();
        let mut w = Writer(Vec::with_capacity(64 + m * 128 + own * 9));
        w.0.extend_from_slice(FUNCTION_TAG);
        let kernel = Kernel::ALL
            .iter()
            .position(|&k| k == self.cover.kernel())
            .unwrap_or(0);
        w.0.push(kernel as u8);
        let linear = matches!(self.cover.funcs(), LocalFunctions::Linear { .. });
        w.0.push(u8::from(!linear));
        w.u64(m as u64);
        w.u64(own as u64);
        w.u64(self.inconsistent_supports as u64);
        w.u64(self.confirmed_supports as u64);
        self.cover.centres().iter().for_each(|&c| w.vec3(c));
        self.cover.radii().iter().for_each(|&r| w.f64(r));
        match self.cover.funcs() {
            LocalFunctions::Linear { alpha, beta } => {
                alpha.iter().for_each(|&a| w.vec3(a));
                beta.iter().for_each(|&b| w.f64(b));
            }
            LocalFunctions::Quadratic { a, b, k } => {
                a.iter()
                    .for_each(|m| m.to_cols_array().iter().for_each(|&x| w.f64(x)));
                b.iter().for_each(|&v| w.vec3(v));
                k.iter().for_each(|&x| w.f64(x));
            }
        }
        self.support_confidence.iter().for_each(|&x| w.f64(x));
        self.confidence.iter().for_each(|&x| w.f64(x));
        w.0.extend(self.outliers.iter().map(|&b| u8::from(b)));
        w.0
    }

    /// Reads what [`TileFunction::to_bytes`] wrote; the cover passes [`Cover::new`]'s checks.
    pub fn from_bytes(bytes: &[u8]) -> Result<TileFunction, ReconError> {
        let mut r = Reader::new(bytes, FUNCTION_TAG, "tile function")?;
        let kernel = *Kernel::ALL
            .get(usize::from(r.byte()?))
            .ok_or_else(|| r.error("an unknown kernel"))?;
        let quadratic = r.flag()?;
        let m = r.len()?;
        let own = r.len()?;
        let inconsistent_supports = r.len()?;
        let confirmed_supports = r.len()?;
        let centres = r.vec3s(m)?;
        let radii = r.f64s(m)?;
        let funcs = if quadratic {
            let cols = r.f64s(
                m.checked_mul(9)
                    .ok_or_else(|| r.error("too many supports"))?,
            )?;
            LocalFunctions::Quadratic {
                a: cols
                    .chunks_exact(9)
                    .map(|c| glam::DMat3::from_cols_array(&std::array::from_fn(|i| c[i])))
                    .collect(),
                b: r.vec3s(m)?,
                k: r.f64s(m)?,
            }
        } else {
            LocalFunctions::Linear {
                alpha: r.vec3s(m)?,
                beta: r.f64s(m)?,
            }
        };
        let support_confidence = r.f64s(m)?;
        let confidence = r.f64s(own)?;
        let outliers = r.flags(own)?;
        r.end()?;
        let cover = Cover::new(centres, radii, funcs, kernel)
            .map_err(|e| ReconError::TileRunner(format!("tile function: {e}")))?;
        Ok(TileFunction {
            cover,
            support_confidence,
            confidence,
            outliers,
            inconsistent_supports,
            confirmed_supports,
        })
    }
}

struct Writer(Vec<u8>);

impl Writer {
    fn u64(&mut self, x: u64) {
        self.0.extend_from_slice(&x.to_le_bytes());
    }
    fn f64(&mut self, x: f64) {
        self.0.extend_from_slice(&x.to_le_bytes());
    }
    fn vec3(&mut self, v: DVec3) {
        self.f64(v.x);
        self.f64(v.y);
        self.f64(v.z);
    }
}

struct Reader<'b> {
    bytes: &'b [u8],
    at: usize,
    what: &'static str,
}

impl<'b> Reader<'b> {
    fn new(bytes: &'b [u8], tag: &[u8; 8], what: &'static str) -> Result<Reader<'b>, ReconError> {
        let r = Reader {
            bytes,
            at: tag.len(),
            what,
        };
        if bytes.get(..tag.len()) != Some(&tag[..]) {
            return Err(ReconError::TileRunner(format!(
                "{what}: not sphcover tile data of this version (tag {:?})",
                String::from_utf8_lossy(tag)
            )));
        }
        Ok(r)
    }

    fn error(&self, problem: &str) -> ReconError {
        ReconError::TileRunner(format!(
            "{}: {problem} at byte {} of {}",
            self.what,
            self.at,
            self.bytes.len()
        ))
    }

    fn take(&mut self, n: usize) -> Result<&'b [u8], ReconError> {
        let end = self
            .at
            .checked_add(n)
            .filter(|&e| e <= self.bytes.len())
            .ok_or_else(|| self.error("the data ends"))?;
        let slice = &self.bytes[self.at..end];
        self.at = end;
        Ok(slice)
    }

    fn byte(&mut self) -> Result<u8, ReconError> {
        Ok(self.take(1)?[0])
    }

    fn flag(&mut self) -> Result<bool, ReconError> {
        match self.byte()? {
            0 => Ok(false),
            1 => Ok(true),
            _ => Err(self.error("a flag other than 0 or 1")),
        }
    }

    fn u64(&mut self) -> Result<u64, ReconError> {
        let b = self.take(8)?;
        Ok(u64::from_le_bytes(std::array::from_fn(|i| b[i])))
    }

    /// A count, checked against what is left so that no allocation follows a corrupt one.
    fn len(&mut self) -> Result<usize, ReconError> {
        let n = self.u64()?;
        usize::try_from(n)
            .ok()
            .filter(|&n| n <= self.bytes.len())
            .ok_or_else(|| self.error("a count larger than the data"))
    }

    /// A number of things that are not in the data (samples of a tile, its position).
    fn count(&mut self) -> Result<usize, ReconError> {
        let n = self.u64()?;
        usize::try_from(n).map_err(|_| self.error("a count beyond usize"))
    }

    fn f64(&mut self) -> Result<f64, ReconError> {
        Ok(f64::from_bits(self.u64()?))
    }

    fn vec3(&mut self) -> Result<DVec3, ReconError> {
        Ok(DVec3::new(self.f64()?, self.f64()?, self.f64()?))
    }

    fn f64s(&mut self, n: usize) -> Result<Vec<f64>, ReconError> {
        let bytes = self.take(
            n.checked_mul(8)
                .ok_or_else(|| self.error("the data ends"))?,
        )?;
        Ok(bytes
            .chunks_exact(8)
            .map(|b| f64::from_le_bytes(std::array::from_fn(|i| b[i])))
            .collect())
    }

    fn vec3s(&mut self, n: usize) -> Result<Vec<DVec3>, ReconError> {
        let flat = self.f64s(
            n.checked_mul(3)
                .ok_or_else(|| self.error("the data ends"))?,
        )?;
        Ok(flat
            .chunks_exact(3)
            .map(|c| DVec3::new(c[0], c[1], c[2]))
            .collect())
    }

    fn flags(&mut self, n: usize) -> Result<Vec<bool>, ReconError> {
        let bytes = self.take(n)?;
        if bytes.iter().any(|&b| b > 1) {
            return Err(self.error("a flag other than 0 or 1"));
        }
        Ok(bytes.iter().map(|&b| b == 1).collect())
    }

    fn end(&self) -> Result<(), ReconError> {
        if self.at == self.bytes.len() {
            Ok(())
        } else {
            Err(self.error("bytes left over"))
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::pipeline::{ReconParams, tile_function};
    use proptest::prelude::*;

    fn input(n: usize, seed: u64) -> TileInput {
        let cloud = sphcover_evaluation::sphere(DVec3::ZERO, 0.3, n.max(1));
        let points: Vec<DVec3> = cloud
            .positions
            .iter()
            .map(|&p| p + 1e-3 * seed as f64)
            .collect();
        let n = points.len();
        TileInput {
            position: [1, 0, 2],
            own_box: Aabb {
                min: DVec3::new(f64::NEG_INFINITY, -0.1, 0.0),
                max: DVec3::new(0.2, f64::INFINITY, 0.4),
            },
            normals: cloud.normals.unwrap(),
            scanner: seed.is_multiple_of(2).then(|| vec![0.5; n]),
            isolated: (0..n).map(|i| i % 7 == 3).collect(),
            own: (0..n).map(|i| i % 3 != 0).collect(),
            points,
            spacing: 0.01,
            noise: 1e-4,
            eps: 2.5e-3,
            drop_isolated: seed.is_multiple_of(3),
            one_view: seed.is_multiple_of(2),
            depth: 6,
        }
    }

    proptest! {
        /// Bytes read back give exactly what was written, for inputs and functions.
        #[test]
        fn inputs_round_trip(n in 0usize..200, seed in 0u64..10) {
            let input = input(n, seed);
            prop_assert_eq!(TileInput::from_bytes(&input.to_bytes()).unwrap(), input);
        }

        /// Cut or altered bytes are refused with an error, never a panic.
        #[test]
        fn damaged_bytes_are_refused(cut in 0usize..4000, flip in 0usize..4000) {
            let bytes = input(50, 1).to_bytes();
            let cut = cut % bytes.len();
            prop_assert!(TileInput::from_bytes(&bytes[..cut]).is_err());
            let mut altered = bytes.clone();
            altered[flip % bytes.len()] ^= 0xA5;
            // Some alterations leave valid data (a coordinate changes); none may panic.
            let _ = TileInput::from_bytes(&altered);
        }
    }

    fn streamed_tile(seed: u64) -> StreamedTile {
        let x = seed as f64;
        StreamedTile {
            tile: seed as usize % 8,
            position: [1, 0, seed as usize % 3],
            directory: format!("/scratch/.sphcover-tiles-{seed}-0").into(),
            scanner: seed.is_multiple_of(2),
            input_splits: [vec![0.5 * x], vec![], vec![-1.0, 2.0 + x]],
            frame: Normalisation {
                centre: DVec3::new(x, -x, 3.0),
                scale: 7.5,
            },
            own_box: Aabb {
                min: DVec3::new(f64::NEG_INFINITY, 0.1, -0.2),
                max: DVec3::new(0.3, f64::INFINITY, 0.4),
            },
            spacing: 1e-3 * x,
            noise: 2e-5,
            eps: 2.5e-3,
            drop_isolated: seed.is_multiple_of(3),
            one_view: seed.is_multiple_of(2),
            depth: 9,
        }
    }

    proptest! {
        /// Streamed tasks and products read back as written; damaged ones are refused,
        /// never a panic.
        #[test]
        fn streamed_tasks_and_products_round_trip(seed in 0u64..50, cut in 0usize..2000, flip in 0usize..2000) {
            let task = streamed_tile(seed);
            let bytes = task.to_bytes();
            prop_assert_eq!(StreamedTile::from_bytes(&bytes).unwrap(), task);
            prop_assert!(StreamedTile::from_bytes(&bytes[..cut % bytes.len()]).is_err());
            let mut altered = bytes.clone();
            altered[flip % bytes.len()] ^= 0x5A;
            let _ = StreamedTile::from_bytes(&altered);

            let product = StreamedTileProduct {
                function: TileFunction {
                    cover: Cover::new(
                        vec![DVec3::splat(0.1 * seed as f64)],
                        vec![0.05],
                        LocalFunctions::from_linear([sphcover_core::LinearFunction::default()]),
                        Kernel::default(),
                    )
                    .unwrap(),
                    support_confidence: vec![0.5],
                    confidence: Vec::new(),
                    outliers: Vec::new(),
                    inconsistent_supports: seed as usize,
                    confirmed_supports: 1,
                },
                seeds: [vec![DVec3::X; seed as usize % 5], vec![DVec3::Y; 3]],
                qualified: [123_456_789, seed as usize],
                own_samples: 40_000_000,
                samples: 90_000_000,
                isolated: 7,
                outliers: 11,
            };
            let bytes = product.to_bytes();
            prop_assert_eq!(StreamedTileProduct::from_bytes(&bytes).unwrap(), product);
            prop_assert!(StreamedTileProduct::from_bytes(&bytes[..cut % bytes.len()]).is_err());
            let mut altered = bytes.clone();
            altered[flip % bytes.len()] ^= 0x5A;
            let _ = StreamedTileProduct::from_bytes(&altered);
        }
    }

    #[test]
    fn inputs_that_decode_but_make_no_sense_are_refused() {
        let good = input(20, 1);
        let mut flipped = good.clone();
        flipped.own_box = Aabb {
            min: good.own_box.max,
            max: good.own_box.min,
        };
        let mut nan = good.clone();
        nan.points[3].y = f64::NAN;
        let mut negative = good.clone();
        negative.eps = -1.0;
        for bad in [flipped, nan, negative] {
            assert!(matches!(
                TileInput::from_bytes(&bad.to_bytes()),
                Err(ReconError::TileRunner(_))
            ));
        }
    }

    #[test]
    fn a_tile_function_round_trips_and_damage_is_refused() {
        let cloud = sphcover_evaluation::sphere(DVec3::ZERO, 0.4, 3000);
        let n = cloud.len();
        let input = TileInput {
            position: [0, 0, 0],
            own_box: Aabb {
                min: DVec3::splat(f64::NEG_INFINITY),
                max: DVec3::new(0.0, f64::INFINITY, f64::INFINITY),
            },
            points: cloud.positions.clone(),
            normals: cloud.normals.clone().unwrap(),
            scanner: None,
            isolated: vec![false; n],
            own: cloud.positions.iter().map(|p| p.x < 0.0).collect(),
            spacing: 0.02,
            noise: 0.0,
            eps: 2.5e-3,
            drop_isolated: false,
            one_view: false,
            depth: 6,
        };
        let function = tile_function(&input, &ReconParams::default())
            .unwrap()
            .unwrap();
        assert!(function.cover.centres().iter().all(|c| c.x < 0.2));
        let bytes = function.to_bytes();
        assert_eq!(TileFunction::from_bytes(&bytes).unwrap(), function);
        for cut in [0, 7, 8, 100, bytes.len() - 1] {
            assert!(matches!(
                TileFunction::from_bytes(&bytes[..cut]),
                Err(ReconError::TileRunner(_))
            ));
        }
        assert!(TileFunction::from_bytes(&input.to_bytes()).is_err());
        let mut longer = bytes.clone();
        longer.push(0);
        assert!(TileFunction::from_bytes(&longer).is_err());
    }
}
