//! The compression pass ([`compress`]): a complete bake, compressed or not, read map by map
//! and written again as a compressed bake, atomically, every file checked by decoding it again.

use std::collections::{BTreeMap, HashSet};
use std::fs;
use std::path::Path;
use std::time::Instant;

use sha2::{Digest, Sha256};

use super::codec::{self, MAX_DROPPED_MANTISSA_BITS, Planes};
use super::{
    CompressOptions, CompressSummary, CompressedFile, Compression, Expected, Header,
    MAX_KEYFRAME_INTERVAL, MapReader, compressed_name, damaged, decode_bytes, encode_file, hex,
    scene_identity,
};
use crate::atomic;
use crate::cubemap::CubeMap;
use crate::layers::bake::error::{BakeError, io_error};
use crate::layers::bake::manifest::{MANIFEST_FILE_NAME, Manifest};

/// Compresses the bake at `source` (the module docs of [`super`] say how) into `out`, which may
/// be `source` itself: written atomically like [`crate::layers::Bake::write`], so a failure
/// leaves whatever was at `out` as it was. A compressed source is decoded and coded again with
/// `options`. Every file is decoded again and compared with its source (bit for bit, after the
/// lossy rounding when `options` asks for one) before anything is swapped in.
pub fn compress(
    source: &Path,
    out: &Path,
    options: &CompressOptions,
) -> Result<CompressSummary, BakeError> {
    check_options(options, out)?;
    let manifest = Manifest::read(source)?;
    let mut reader = MapReader::new(source, &manifest);
    let mut coder = ChainCoder {
        options: *options,
        scene: scene_identity(&manifest),
        size: manifest.cube_map_size,
        scene_name: &manifest.scene,
        files: BTreeMap::new(),
        summary: CompressSummary::default(),
        squared_error: 0.0,
        values: 0,
    };
    let mut compressed = manifest.clone();
    for lens in &mut compressed.lenses {
        for layer in &mut lens.layers {
            for file in &mut layer.maps {
                *file = compressed_name(file);
            }
        }
    }
    crate::layers::bake::write_directory(out, |staging| {
        for chain in chains(&manifest) {
            let mut previous = None;
            // Files in the current chain, its keyframe included.
            let mut chain_length = 0;
            for file in &chain {
                let cube = reader.read(file)?;
                coder.summary.bytes_before += fs::metadata(source.join(file))
                    .map_err(io_error(&source.join(file), "read"))?
                    .len();
                let name = compressed_name(file);
                let reference = previous
                    .as_ref()
                    .filter(|_| chain_length < options.keyframe_interval);
                let coded = coder.code(&cube, &name, reference, out)?;
                chain_length = if coded.keyframe { 1 } else { chain_length + 1 };
                let path = staging.join(&name);
                atomic::write_synced(&path, &coded.bytes)
                    .map_err(io_error(&out.join(&name), "write"))?;
                previous = Some(coded.chain_link);
            }
        }
        compressed.compression = Some(Compression {
            keyframe_interval: options.keyframe_interval,
            dropped_mantissa_bits: options.dropped_mantissa_bits,
            files: std::mem::take(&mut coder.files),
        });
        let manifest_path = out.join(MANIFEST_FILE_NAME);
        compressed.validate(&manifest_path)?;
        let staged = staging.join(MANIFEST_FILE_NAME);
        atomic::write_synced(&staged, compressed.to_json().as_bytes())
            .map_err(io_error(&manifest_path, "write"))?;
        atomic::sync_directory(staging).map_err(io_error(out, "fsync"))
    })?;
    let mut summary = coder.summary;
    summary.map_psnr_db = (coder.squared_error > 0.0)
        .then(|| -10.0 * (coder.squared_error / coder.values.max(1) as f64).log10());
    Ok(summary)
}

/// Refuses options outside their ranges, naming `out`.
fn check_options(options: &CompressOptions, out: &Path) -> Result<(), BakeError> {
    let invalid = |field: &str, problem: String, fix| BakeError::Invalid {
        path: out.to_owned(),
        field: field.to_owned(),
        problem,
        fix,
    };
    if !(1..=MAX_KEYFRAME_INTERVAL).contains(&options.keyframe_interval) {
        return Err(invalid(
            "keyframe interval",
            format!(
                "{} is outside 1..={MAX_KEYFRAME_INTERVAL}",
                options.keyframe_interval
            ),
            "give an interval such as 8 (1: every map a keyframe)",
        ));
    }
    if options.dropped_mantissa_bits > MAX_DROPPED_MANTISSA_BITS {
        return Err(invalid(
            "dropped mantissa bits",
            format!(
                "{} is more than {MAX_DROPPED_MANTISSA_BITS}",
                options.dropped_mantissa_bits
            ),
            "drop 0 (lossless) to 20 of the 23 mantissa bits",
        ));
    }
    Ok(())
}

/// Each layer's distinct map files in sample order, a file listed by an earlier layer (a shared
/// layer) left to that layer: the chains of cross-sample coding.
fn chains(manifest: &Manifest) -> Vec<Vec<String>> {
    let mut seen = HashSet::new();
    manifest
        .lenses
        .iter()
        .flat_map(|lens| &lens.layers)
        .map(|layer| {
            layer
                .maps
                .iter()
                .filter(|file| seen.insert(file.as_str()))
                .cloned()
                .collect::<Vec<_>>()
        })
        .filter(|chain| !chain.is_empty())
        .collect()
}

/// A coded file's link in its chain: what the next file is coded against.
struct ChainLink {
    /// Its name.
    name: String,
    /// Its SHA-256.
    sha256: [u8; 32],
    /// Its intra integers.
    planes: Planes,
}

/// A coded file: its bytes, whether it is a keyframe, and its link.
struct Coded {
    bytes: Vec<u8>,
    keyframe: bool,
    chain_link: ChainLink,
}

/// Codes maps one by one, recording each file and the summary's figures.
struct ChainCoder<'a> {
    options: CompressOptions,
    scene: [u8; 32],
    size: u32,
    scene_name: &'a str,
    files: BTreeMap<String, CompressedFile>,
    summary: CompressSummary,
    squared_error: f64,
    values: u64,
}

impl ChainCoder<'_> {
    /// Codes `cube` as file `name`: as its difference from `reference` where that is smaller,
    /// else as a keyframe; decodes the bytes again and compares them with `cube` after the
    /// lossy rounding; `out` names the bake in errors.
    fn code(
        &mut self,
        cube: &CubeMap,
        name: &str,
        reference: Option<&ChainLink>,
        out: &Path,
    ) -> Result<Coded, BakeError> {
        let path = out.join(name);
        let dropped = self.options.dropped_mantissa_bits;
        let planes = Planes::intra(cube, dropped);
        let header = |reference: Option<&ChainLink>| Header {
            size: self.size,
            dropped,
            keyframe: reference.is_none(),
            scene: self.scene,
            reference: reference.map_or([0; 32], |link| link.sha256),
            payload_len: 0,
        };
        let keyframe = encode_file(header(None), &planes.values, &path)?;
        // A difference is kept only where it is smaller than the map on its own: a map far
        // from the one before it starts a new chain.
        let (bytes, reference) = match reference {
            Some(link) => {
                let delta = planes.delta_from(&link.planes).ok_or_else(|| {
                    damaged(&path, "differs in size from the map before it".into())
                })?;
                let difference = encode_file(header(Some(link)), &delta.values, &path)?;
                if difference.len() < keyframe.len() {
                    (difference, Some(link))
                } else {
                    (keyframe, None)
                }
            }
            None => (keyframe, None),
        };
        let sha256: [u8; 32] = Sha256::digest(&bytes).into();
        let sha_hex = hex(&sha256);
        let reference_hex = reference.map(|link| hex(&link.sha256));
        let expected = Expected {
            scene: self.scene,
            scene_name: self.scene_name,
            size: self.size,
            dropped,
            sha256: &sha_hex,
            reference_sha256: reference_hex.as_deref(),
            keyframe: reference.is_none(),
        };
        let start = Instant::now();
        let decoded_planes =
            decode_bytes(&bytes, &path, &expected, reference.map(|link| &link.planes))?;
        let decoded = decoded_planes.to_cube_map(dropped);
        self.summary
            .decode_seconds
            .push(start.elapsed().as_secs_f64());
        let decoded = decoded
            .filter(|_| decoded_planes == planes)
            .ok_or_else(|| not_decoded(&path))?;
        self.compare(cube, &decoded, &path)?;
        self.summary.files += 1;
        self.summary.keyframes += usize::from(reference.is_none());
        self.summary.bytes_after += bytes.len() as u64;
        self.files.insert(
            name.to_owned(),
            CompressedFile {
                sha256: sha_hex,
                reference: reference.map(|link| link.name.clone()),
            },
        );
        Ok(Coded {
            bytes,
            keyframe: reference.is_none(),
            chain_link: ChainLink {
                name: name.to_owned(),
                sha256,
                planes,
            },
        })
    }

    /// Checks that `decoded` is `cube` after the lossy rounding, bit for bit, and adds the
    /// rounding's error to the figures.
    fn compare(&mut self, cube: &CubeMap, decoded: &CubeMap, path: &Path) -> Result<(), BakeError> {
        let dropped = self.options.dropped_mantissa_bits;
        let pairs = cube
            .levels
            .iter()
            .flatten()
            .flatten()
            .flatten()
            .zip(decoded.levels.iter().flatten().flatten().flatten());
        let mut count = 0u64;
        for (&source, &value) in pairs {
            if codec::lossy_value(source, dropped).to_bits() != value.to_bits() {
                return Err(not_decoded(path));
            }
            let error = f64::from(value) - f64::from(source);
            self.squared_error += error * error;
            self.summary.max_abs_error = self.summary.max_abs_error.max(error.abs());
            count += 1;
        }
        self.values += count;
        Ok(())
    }
}

/// The error of a file that does not decode to what was coded: a fault of this code, caught
/// before the bake is replaced.
fn not_decoded(path: &Path) -> BakeError {
    BakeError::Compressed {
        path: path.to_owned(),
        problem: "does not decode to the map it was coded from".into(),
        fix: "nothing was replaced; report this as a lensmap bug",
    }
}
