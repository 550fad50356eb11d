//! Compressed bakes: the PEM paper's scheme (§4, §6) as a pass over a complete bake
//! ([`compress`]), and the reader that decodes it transparently ([`MapReader`]).
//!
//! **What is coded.** Each cube map becomes integers ([`codec::Planes`]): every f32 is mapped
//! to an integer that orders like it ([`codec::ordered`]); level 0 is stored as those
//! integers, and each coarser level as its difference from level 0 decimated to it (2×2 box
//! means, [`codec::decimate`]), the paper's "residuals from corresponding decimated versions of
//! the finest level". Across viewpoint samples, in the manifest's sample order (increasing
//! view-space index), a layer's maps form chains: a **keyframe** stores its own integers, the
//! maps after it their difference from the map before them, as long as that difference codes
//! smaller than the map alone and the chain is shorter than `keyframe_interval`; otherwise the
//! map starts a new chain as a keyframe. Any map decodes from its keyframe and at most `keyframe_interval − 1` differences,
//! never from the whole sequence. The integers are zigzag-coded, split into four byte planes
//! and compressed with zstd. All arithmetic is exact, so decoding returns the very bits coded.
//!
//! **Lossy option.** `dropped_mantissa_bits` = d > 0 rounds every value to the nearest f32
//! with its d low mantissa bits zero (to nearest in the ordered integers) before coding, a
//! relative error of at most 2^(d−24). 0 (the default) is lossless.
//!
//! **Files.** A compressed bake is a bake directory whose manifest has a `compression` section
//! ([`Compression`]) and lists `.lmz` files instead of `.exr` ones, one per map as before:
//!
//! ```text
//! offset  size  field
//!      0     4  magic "LMZC"
//!      4     4  container version, u32 little-endian (1)
//!      8     4  cube-map edge length, u32
//!     12     1  dropped mantissa bits
//!     13     1  kind: 0 keyframe, 1 difference from the reference
//!     14     2  zero
//!     16    32  scene identity: SHA-256 of "lensmap-scene\0" + scene name + "\0" + scene hash
//!     48    32  SHA-256 of the reference file (zeros for a keyframe)
//!     80     8  payload length, u64
//!     88     …  payload: one zstd frame (with its checksum) of the packed integers
//! ```
//!
//! The manifest's `compression.files` names every file's SHA-256 and its reference. A file is
//! refused, with one line naming it, when it is truncated, when its header names another scene
//! than the bake's, when its checksum differs from the manifest's (changed or damaged), or
//! when what it decodes to is not a valid cube map. Writing is atomic like every bake write, and
//! every file is decoded again and compared with its source before the bake is swapped in.

pub mod codec;
mod write;

use std::collections::{BTreeMap, HashMap};
use std::fs;
use std::path::Path;

use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};

use super::error::{BakeError, io_error};
use super::exr::{check_cube_map, read_cube_map_exr};
use super::manifest::Manifest;
use crate::cubemap::CubeMap;
use codec::{MAX_DROPPED_MANTISSA_BITS, Planes, plane_len};
pub use write::compress;

/// The extension of compressed cube-map files.
pub const COMPRESSED_EXTENSION: &str = "lmz";

/// The keyframe interval [`CompressOptions::default`] uses.
pub const DEFAULT_KEYFRAME_INTERVAL: u32 = 8;

/// The longest keyframe interval a manifest may name (it bounds one map's decoding work).
pub const MAX_KEYFRAME_INTERVAL: u32 = 1024;

/// The first bytes of a compressed cube-map file.
const MAGIC: &[u8; 4] = b"LMZC";

/// The container version this code writes and reads.
const CONTAINER_VERSION: u32 = 1;

/// The length of a file's header, bytes.
const HEADER_LEN: usize = 88;

/// The zstd level: measured on real bakes, higher levels gain little and encode slower.
const ZSTD_LEVEL: i32 = 12;

/// The manifest's `compression` section: present exactly when the bake is compressed.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Compression {
    /// Maps per chain between keyframes, 1..=[`MAX_KEYFRAME_INTERVAL`] (1: every map is a
    /// keyframe, only the MIP residuals are used).
    pub keyframe_interval: u32,
    /// Low mantissa bits dropped before coding, 0..=[`MAX_DROPPED_MANTISSA_BITS`] (0: lossless).
    pub dropped_mantissa_bits: u32,
    /// Every compressed file of the bake, by its name in the layers' `maps`.
    pub files: BTreeMap<String, CompressedFile>,
}

/// One compressed cube-map file, as the manifest records it.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CompressedFile {
    /// SHA-256 of the whole file, 64 lowercase hex digits.
    pub sha256: String,
    /// The file this one is a difference from (the previous sample's map of its layer); absent
    /// for a keyframe.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub reference: Option<String>,
}

/// How [`compress`] codes a bake.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct CompressOptions {
    /// Maps per chain between keyframes, 1..=[`MAX_KEYFRAME_INTERVAL`].
    pub keyframe_interval: u32,
    /// Low mantissa bits dropped (lossy), 0..=[`MAX_DROPPED_MANTISSA_BITS`]; 0 is lossless.
    pub dropped_mantissa_bits: u32,
}

impl Default for CompressOptions {
    fn default() -> Self {
        CompressOptions {
            keyframe_interval: DEFAULT_KEYFRAME_INTERVAL,
            dropped_mantissa_bits: 0,
        }
    }
}

/// What [`compress`] did.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct CompressSummary {
    /// Cube-map files coded.
    pub files: usize,
    /// Of which keyframes.
    pub keyframes: usize,
    /// Bytes of the source's map files.
    pub bytes_before: u64,
    /// Bytes of the compressed map files.
    pub bytes_after: u64,
    /// The largest absolute difference of a decoded value from its source value (0 when
    /// lossless).
    pub max_abs_error: f64,
    /// PSNR of the decoded maps against the source maps over every value of every level,
    /// peak 1, dB; `None` when they are identical.
    pub map_psnr_db: Option<f64>,
    /// Seconds spent decoding the compressed files again to check them, one entry per file in
    /// chain order (each from its decoded reference).
    pub decode_seconds: Vec<f64>,
}

/// The name a map file gets in a compressed bake: its `.exr` extension replaced by `.lmz`.
pub fn compressed_name(file: &str) -> String {
    let stem = file.strip_suffix(".exr").unwrap_or(file);
    if stem.ends_with(".lmz") {
        stem.to_owned()
    } else {
        format!("{stem}.{COMPRESSED_EXTENSION}")
    }
}

/// The name a compressed map file gets when written uncompressed again: `.lmz` → `.exr`.
pub fn uncompressed_name(file: &str) -> String {
    let stem = file.strip_suffix(".lmz").unwrap_or(file);
    if stem.ends_with(".exr") {
        stem.to_owned()
    } else {
        format!("{stem}.exr")
    }
}

/// SHA-256 as 64 lowercase hex digits.
fn hex(digest: &[u8]) -> String {
    digest.iter().map(|byte| format!("{byte:02x}")).collect()
}

/// The scene identity a bake's compressed files carry: what tells a file of another scene.
fn scene_identity(manifest: &Manifest) -> [u8; 32] {
    let scene_hash = manifest
        .provenance
        .as_ref()
        .map_or("", |p| p.scene_hash.as_str());
    let mut sha = Sha256::new();
    sha.update(b"lensmap-scene\0");
    sha.update(manifest.scene.as_bytes());
    sha.update(b"\0");
    sha.update(scene_hash.as_bytes());
    sha.finalize().into()
}

/// A compressed file's header.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Header {
    size: u32,
    dropped: u32,
    keyframe: bool,
    scene: [u8; 32],
    reference: [u8; 32],
    payload_len: u64,
}

impl Header {
    fn to_bytes(self) -> Vec<u8> {
        let mut bytes = Vec::with_capacity(HEADER_LEN);
        bytes.extend_from_slice(MAGIC);
        bytes.extend_from_slice(&CONTAINER_VERSION.to_le_bytes());
        bytes.extend_from_slice(&self.size.to_le_bytes());
        bytes.push(self.dropped as u8);
        bytes.push(u8::from(!self.keyframe));
        bytes.extend_from_slice(&[0, 0]);
        bytes.extend_from_slice(&self.scene);
        bytes.extend_from_slice(&self.reference);
        bytes.extend_from_slice(&self.payload_len.to_le_bytes());
        bytes
    }

    /// The header at the start of `bytes`, or what is wrong with it.
    fn parse(bytes: &[u8]) -> Result<Header, String> {
        if bytes.len() < HEADER_LEN {
            if !MAGIC.starts_with(&bytes[..bytes.len().min(4)]) {
                return Err("is not a compressed cube map (no LMZC header)".into());
            }
            return Err(format!(
                "is truncated: {} bytes, shorter than the {HEADER_LEN}-byte header",
                bytes.len()
            ));
        }
        let u32_at = |at: usize| {
            u32::from_le_bytes([bytes[at], bytes[at + 1], bytes[at + 2], bytes[at + 3]])
        };
        if &bytes[..4] != MAGIC {
            return Err("is not a compressed cube map (no LMZC header)".into());
        }
        if u32_at(4) != CONTAINER_VERSION {
            return Err(format!(
                "is container version {}, but this lensmap reads version {CONTAINER_VERSION}",
                u32_at(4)
            ));
        }
        let kind = bytes[13];
        if kind > 1 {
            return Err(format!(
                "has kind {kind}, neither keyframe (0) nor difference (1)"
            ));
        }
        let array = |at: usize| -> [u8; 32] { std::array::from_fn(|i| bytes[at + i]) };
        let mut payload_len = [0u8; 8];
        payload_len.copy_from_slice(&bytes[80..88]);
        Ok(Header {
            size: u32_at(8),
            dropped: u32::from(bytes[12]),
            keyframe: kind == 0,
            scene: array(16),
            reference: array(48),
            payload_len: u64::from_le_bytes(payload_len),
        })
    }
}

/// A compressed-file error naming `path`.
fn damaged(path: &Path, problem: String) -> BakeError {
    BakeError::Compressed {
        path: path.to_owned(),
        problem,
        fix: "restore the file, or compress the bake again from its uncompressed copy",
    }
}

/// The bytes of a compressed file holding `values` (packed and zstd-compressed) under `header`
/// (whose payload length is filled in).
fn encode_file(mut header: Header, values: &[i32], path: &Path) -> Result<Vec<u8>, BakeError> {
    let mut compressor =
        zstd::bulk::Compressor::new(ZSTD_LEVEL).map_err(io_error(path, "compress"))?;
    compressor
        .include_checksum(true)
        .map_err(io_error(path, "compress"))?;
    let payload = compressor
        .compress(&codec::pack(values))
        .map_err(io_error(path, "compress"))?;
    header.payload_len = payload.len() as u64;
    let mut bytes = header.to_bytes();
    bytes.extend_from_slice(&payload);
    Ok(bytes)
}

/// Reads the maps of one bake, compressed or not, in any order; decodes each compressed
/// map from its chain, keeping the integers of the last map of each chain so that reading a
/// layer's maps in sample order decodes each file once.
pub struct MapReader<'a> {
    dir: &'a Path,
    manifest: &'a Manifest,
    scene: [u8; 32],
    /// The intra integers of decoded files no later file has used as its reference yet.
    decoded: HashMap<String, Planes>,
}

impl<'a> MapReader<'a> {
    /// A reader of the maps `manifest` (read from `dir`) lists.
    pub fn new(dir: &'a Path, manifest: &'a Manifest) -> MapReader<'a> {
        MapReader {
            dir,
            manifest,
            scene: scene_identity(manifest),
            decoded: HashMap::new(),
        }
    }

    /// The bake directory.
    pub fn dir(&self) -> &Path {
        self.dir
    }

    /// Whether the bake's maps are compressed.
    pub fn is_compressed(&self) -> bool {
        self.manifest.compression.is_some()
    }

    /// Reads and checks map `file` (a name the manifest lists): an EXR as
    /// [`read_cube_map_exr`] does, a compressed file decoded from its keyframe.
    pub fn read(&mut self, file: &str) -> Result<CubeMap, BakeError> {
        let path = self.dir.join(file);
        let size = self.manifest.cube_map_size;
        let Some(compression) = &self.manifest.compression else {
            return read_cube_map_exr(&path, size);
        };
        let planes = self.planes(file)?;
        let cube = planes
            .to_cube_map(compression.dropped_mantissa_bits)
            .ok_or_else(|| damaged(&path, "decodes to the wrong number of values".into()))?;
        check_cube_map(&cube, size, &path)?;
        self.decoded.insert(file.to_owned(), planes);
        Ok(cube)
    }

    /// The intra integers of compressed file `file`: decoded from the nearest file up its
    /// chain whose integers are kept (or its keyframe), then forward.
    fn planes(&mut self, file: &str) -> Result<Planes, BakeError> {
        let files = self
            .manifest
            .compression
            .as_ref()
            .map(|c| &c.files)
            .ok_or_else(|| damaged(&self.dir.join(file), "is not compressed".into()))?;
        // Validation bounds every chain by the keyframe interval, so this walk ends.
        let mut chain = vec![file.to_owned()];
        let mut base = None;
        while let Some(reference) = chain
            .last()
            .and_then(|last| files.get(last))
            .and_then(|entry| entry.reference.clone())
        {
            if let Some(planes) = self.decoded.remove(&reference) {
                base = Some(planes);
                break;
            }
            chain.push(reference);
        }
        for name in chain.iter().rev() {
            base = Some(self.decode_file(name, base.as_ref())?);
        }
        base.ok_or_else(|| damaged(&self.dir.join(file), "has no chain".into()))
    }

    /// The intra integers of one compressed file, given its reference's (`None` for a keyframe).
    fn decode_file(&self, name: &str, reference: Option<&Planes>) -> Result<Planes, BakeError> {
        let path = self.dir.join(name);
        let compression = self
            .manifest
            .compression
            .as_ref()
            .ok_or_else(|| damaged(&path, "is not compressed".into()))?;
        let entry = compression
            .files
            .get(name)
            .ok_or_else(|| damaged(&path, "is not in manifest.json's compression.files".into()))?;
        let expected = Expected {
            scene: self.scene,
            scene_name: &self.manifest.scene,
            size: self.manifest.cube_map_size,
            dropped: compression.dropped_mantissa_bits,
            sha256: &entry.sha256,
            reference_sha256: match &entry.reference {
                Some(reference) => compression.files.get(reference).map(|r| r.sha256.as_str()),
                None => None,
            },
            keyframe: entry.reference.is_none(),
        };
        // A listed file that is gone is a bad bake (exit 2), as a layered bake's missing map is;
        // one that cannot be read for another reason stays an I/O error.
        let bytes = match fs::read(&path) {
            Err(error) if error.kind() == std::io::ErrorKind::NotFound => {
                return Err(BakeError::MissingMap {
                    path,
                    manifest: super::MANIFEST_FILE_NAME,
                    field: format!("compression.files[\"{name}\"]"),
                });
            }
            read => read.map_err(io_error(&path, "read"))?,
        };
        decode_bytes(&bytes, &path, &expected, reference)
    }
}

/// What a compressed file must say, from its bake's manifest.
struct Expected<'a> {
    /// The bake's scene identity.
    scene: [u8; 32],
    /// The bake's scene name (for messages).
    scene_name: &'a str,
    /// The bake's cube-map size.
    size: u32,
    /// The bake's lossy setting.
    dropped: u32,
    /// The file's SHA-256 (hex).
    sha256: &'a str,
    /// The reference's SHA-256 (hex), `None` for a keyframe (or a reference not listed).
    reference_sha256: Option<&'a str>,
    /// Whether the file is a keyframe.
    keyframe: bool,
}

/// Checks the bytes of the compressed file at `path` against `expected` and returns its intra
/// integers, given its reference's (`None` for a keyframe).
fn decode_bytes(
    bytes: &[u8],
    path: &Path,
    expected: &Expected<'_>,
    reference: Option<&Planes>,
) -> Result<Planes, BakeError> {
    let header = Header::parse(bytes).map_err(|problem| damaged(path, problem))?;
    let held = (bytes.len() - HEADER_LEN) as u64;
    if held < header.payload_len {
        return Err(damaged(
            path,
            format!(
                "is truncated: {} bytes, its header says {}",
                bytes.len(),
                (HEADER_LEN as u64).saturating_add(header.payload_len)
            ),
        ));
    }
    if header.scene != expected.scene {
        return Err(BakeError::Compressed {
            path: path.to_owned(),
            problem: format!(
                "is a map of another scene (scene identity {}…, this bake's \"{}\" is {}…)",
                &hex(&header.scene)[..12],
                expected.scene_name,
                &hex(&expected.scene)[..12]
            ),
            fix: "it belongs to another bake; restore this bake's own file",
        });
    }
    let sha = hex(&Sha256::digest(bytes));
    if sha != expected.sha256 || held != header.payload_len {
        return Err(damaged(
            path,
            format!(
                "has SHA-256 {}…, but manifest.json's compression.files says {}… (changed or damaged)",
                &sha[..12],
                &expected.sha256[..expected.sha256.len().min(12)]
            ),
        ));
    }
    let reference_sha = if expected.keyframe {
        Some(hex(&[0; 32]))
    } else {
        expected.reference_sha256.map(str::to_owned)
    };
    if header.size != expected.size
        || header.dropped != expected.dropped
        || header.keyframe != expected.keyframe
        || Some(hex(&header.reference)) != reference_sha
    {
        return Err(damaged(
            path,
            "has a header that disagrees with manifest.json (size, lossy setting or reference)"
                .into(),
        ));
    }
    let length = plane_len(header.size)
        .and_then(|n| n.checked_mul(4))
        .ok_or_else(|| damaged(path, format!("names a size {} past memory", header.size)))?;
    // The frame states its decoded length: anything but the size's is refused before any
    // memory is set aside for it.
    match zstd::zstd_safe::get_frame_content_size(&bytes[HEADER_LEN..]) {
        Ok(Some(stated)) if stated == length as u64 => {}
        _ => {
            return Err(damaged(
                path,
                format!(
                    "holds a compressed frame that is not of a {}² cube map",
                    header.size
                ),
            ));
        }
    }
    let packed = zstd::bulk::decompress(&bytes[HEADER_LEN..], length)
        .map_err(|error| damaged(path, format!("holds damaged compressed data ({error})")))?;
    let values = codec::unpack(&packed)
        .filter(|values| values.len() * 4 == length)
        .ok_or_else(|| damaged(path, "decodes to the wrong number of values".into()))?;
    let planes = Planes {
        size: header.size,
        values,
    };
    match reference {
        None if header.keyframe => Ok(planes),
        Some(reference) if !header.keyframe => planes
            .add_reference(reference)
            .ok_or_else(|| damaged(path, "differs in size from its reference".into())),
        _ => Err(damaged(path, "lacks its reference".into())),
    }
}

impl Compression {
    /// Checks the section against the manifest's layers (`listed`: every map file they list):
    /// the interval and lossy setting in range, one entry per listed file and none other, each
    /// SHA-256 64 hex digits, each reference a listed file, and every chain reaching its
    /// keyframe within `keyframe_interval − 1` references (so no chain loops). `path` names
    /// the manifest in errors.
    pub fn validate(&self, path: &Path, listed: &[&str]) -> Result<(), BakeError> {
        let listed: std::collections::HashSet<&str> = listed.iter().copied().collect();
        let invalid = |field: String, problem: String| BakeError::Invalid {
            path: path.to_owned(),
            field,
            problem,
            fix: "compress the bake again from its uncompressed copy",
        };
        if !(1..=MAX_KEYFRAME_INTERVAL).contains(&self.keyframe_interval) {
            return Err(invalid(
                "compression.keyframe_interval".into(),
                format!(
                    "is {}, not in 1..={MAX_KEYFRAME_INTERVAL}",
                    self.keyframe_interval
                ),
            ));
        }
        if self.dropped_mantissa_bits > MAX_DROPPED_MANTISSA_BITS {
            return Err(invalid(
                "compression.dropped_mantissa_bits".into(),
                format!(
                    "is {}, more than {MAX_DROPPED_MANTISSA_BITS}",
                    self.dropped_mantissa_bits
                ),
            ));
        }
        if let Some(file) = listed.iter().find(|file| !self.files.contains_key(**file)) {
            return Err(invalid(
                "compression.files".into(),
                format!("has no entry for '{file}', which the layers list"),
            ));
        }
        for (name, entry) in &self.files {
            let field = format!("compression.files[\"{name}\"]");
            if !listed.contains(name.as_str()) {
                return Err(invalid(field, "is not a map any layer lists".into()));
            }
            let is_hex = |c: char| c.is_ascii_digit() || ('a'..='f').contains(&c);
            if entry.sha256.len() != 64 || !entry.sha256.chars().all(is_hex) {
                return Err(invalid(
                    format!("{field}.sha256"),
                    "is not 64 lowercase hex digits".into(),
                ));
            }
            let mut at = entry;
            let mut steps = 0;
            while let Some(reference) = &at.reference {
                steps += 1;
                at = match self.files.get(reference) {
                    Some(next) if steps < self.keyframe_interval => next,
                    Some(_) => {
                        return Err(invalid(
                            format!("{field}.reference"),
                            format!(
                                "starts a chain of more than {} references (keyframe_interval {})",
                                self.keyframe_interval - 1,
                                self.keyframe_interval
                            ),
                        ));
                    }
                    None => {
                        return Err(invalid(
                            format!("{field}.reference"),
                            format!("names '{reference}', which is not in compression.files"),
                        ));
                    }
                };
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::codec::tests::{bits, drifting_cube};
    use super::*;
    use crate::layers::bake::{Bake, BakedLens, MANIFEST_FILE_NAME, Provenance};
    use crate::layers::shell::LayerShell;
    use glam::{DVec3, Vec3};
    use rand::SeedableRng;
    use rand_pcg::Pcg64;
    use std::path::PathBuf;
    use std::sync::Arc;

    /// A fresh folder for `test`, removed first.
    fn scratch(test: &str) -> PathBuf {
        let dir =
            std::env::temp_dir().join(format!("lensmap-compress-{}-{test}", std::process::id()));
        let _ = fs::remove_dir_all(&dir);
        fs::create_dir_all(&dir).unwrap();
        dir
    }

    /// A bake of `samples` viewpoints, two layers whose maps drift from sample to sample, of
    /// scene `scene` (provenance hash `scene` too).
    fn sequence_bake(samples: usize, scene: &str, seed: u64) -> Bake {
        let mut rng = Pcg64::seed_from_u64(seed);
        let shell = |radius| LayerShell::Sphere {
            centre: DVec3::ZERO,
            radius,
        };
        Bake {
            scene: scene.into(),
            created_by: "test".into(),
            viewpoints: (0..samples)
                .map(|i| Vec3::new(i as f32, 1.0, 5.0))
                .collect(),
            lenses: vec![BakedLens {
                name: "ball".into(),
                em_origins: vec![DVec3::ZERO; 2],
                shells: vec![shell(2.0), shell(9.0)],
                layering: crate::layers::Layering::Distance,
                maps: (0..samples)
                    .map(|i| {
                        (0..2)
                            .map(|layer| {
                                Arc::new(drifting_cube(&mut rng, 8, i as f32 + 10.0 * layer as f32))
                            })
                            .collect()
                    })
                    .collect(),
            }],
            provenance: Some(Provenance::new(
                format!("{scene}-hash"),
                "options".into(),
                (0..samples).collect(),
            )),
        }
    }

    /// The bits of every map of `bake`, sample by sample, layer by layer.
    fn all_bits(bake: &Bake) -> Vec<Vec<u32>> {
        bake.lenses[0]
            .maps
            .iter()
            .flatten()
            .map(|m| bits(m))
            .collect()
    }

    fn options(keyframe_interval: u32, dropped_mantissa_bits: u32) -> CompressOptions {
        CompressOptions {
            keyframe_interval,
            dropped_mantissa_bits,
        }
    }

    #[test]
    fn a_compressed_bake_reads_back_bit_exactly() {
        let dir = scratch("round-trip");
        let (plain, packed) = (dir.join("plain"), dir.join("packed"));
        let bake = sequence_bake(10, "drift", 1);
        bake.write(&plain).unwrap();
        let summary = compress(&plain, &packed, &options(4, 0)).unwrap();
        assert_eq!((summary.files, summary.keyframes), (20, 6));
        assert_eq!((summary.max_abs_error, summary.map_psnr_db), (0.0, None));
        let read = Bake::read(&packed).unwrap();
        assert_eq!(all_bits(&read), all_bits(&bake));
        assert_eq!(read.provenance, bake.provenance);
        let manifest = Manifest::read(&packed).unwrap();
        assert!(manifest.lenses[0].layers[0].maps[3].ends_with(".lmz"));
        // Compressing it again (in place, from the compressed bake) changes nothing read.
        compress(&packed, &packed, &options(3, 0)).unwrap();
        assert_eq!(all_bits(&Bake::read(&packed).unwrap()), all_bits(&bake));
        let _ = fs::remove_dir_all(&dir);
    }

    #[test]
    fn one_sample_decodes_from_its_keyframe_alone() {
        let dir = scratch("keyframe");
        let (plain, packed) = (dir.join("plain"), dir.join("packed"));
        let bake = sequence_bake(10, "drift", 2);
        bake.write(&plain).unwrap();
        compress(&plain, &packed, &options(4, 0)).unwrap();
        let manifest = Manifest::read(&packed).unwrap();
        // Keyframes at samples 0, 4, 8: sample 6 needs the files of 4, 5 and 6 only.
        for lens in &manifest.lenses {
            for layer in &lens.layers {
                for (sample, file) in layer.maps.iter().enumerate() {
                    if !(4..=6).contains(&sample) {
                        fs::remove_file(packed.join(file)).unwrap();
                    }
                }
            }
        }
        let mut reader = MapReader::new(&packed, &manifest);
        for layer in 0..2 {
            let cube = reader
                .read(&manifest.lenses[0].layers[layer].maps[6])
                .unwrap();
            assert_eq!(bits(&cube), bits(&bake.lenses[0].maps[6][layer]));
        }
        // Sample 3's chain starts at the removed keyframe 0.
        let error = reader
            .read(&manifest.lenses[0].layers[0].maps[3])
            .unwrap_err()
            .to_string();
        assert!(
            error.contains("v000") || error.contains("cannot read"),
            "{error}"
        );
        let _ = fs::remove_dir_all(&dir);
    }

    #[test]
    fn dropped_bits_cost_what_the_summary_says() {
        let dir = scratch("lossy");
        let (plain, packed) = (dir.join("plain"), dir.join("packed"));
        let bake = sequence_bake(4, "drift", 3);
        bake.write(&plain).unwrap();
        let lossless = compress(&plain, &packed, &options(4, 0)).unwrap();
        let summary = compress(&plain, &packed, &options(4, 12)).unwrap();
        assert!(summary.bytes_after < lossless.bytes_after);
        let read = Bake::read(&packed).unwrap();
        // Every value is its source rounded; the PSNR is that of those differences.
        let (mut squared, mut count) = (0.0f64, 0u64);
        for (source, decoded) in all_bits(&bake).iter().zip(&all_bits(&read)) {
            for (&a, &b) in source.iter().zip(decoded) {
                let (a, b) = (f32::from_bits(a), f32::from_bits(b));
                assert_eq!(b.to_bits(), codec::lossy_value(a, 12).to_bits());
                squared += (f64::from(a) - f64::from(b)).powi(2);
                count += 1;
            }
        }
        let psnr = -10.0 * (squared / count as f64).log10();
        let reported = summary.map_psnr_db.unwrap();
        assert!((psnr - reported).abs() < 1e-9, "{psnr} vs {reported}");
        let _ = fs::remove_dir_all(&dir);
    }

    /// The one-line error of reading the bake at `dir`.
    fn read_error(dir: &Path) -> String {
        let error = Bake::read(dir).unwrap_err().to_string();
        assert_eq!(error.lines().count(), 1, "{error}");
        error
    }

    #[test]
    fn truncated_changed_and_foreign_files_are_refused_in_one_line() {
        let dir = scratch("damage");
        let (plain, packed) = (dir.join("plain"), dir.join("packed"));
        sequence_bake(3, "drift", 4).write(&plain).unwrap();
        compress(&plain, &packed, &options(8, 0)).unwrap();
        let other = dir.join("other");
        let other_plain = dir.join("other-plain");
        sequence_bake(3, "elsewhere", 4)
            .write(&other_plain)
            .unwrap();
        compress(&other_plain, &other, &options(8, 0)).unwrap();
        let manifest = Manifest::read(&packed).unwrap();
        let file = manifest.lenses[0].layers[1].maps[1].clone();
        let original = fs::read(packed.join(&file)).unwrap();
        let named = packed.join(&file).display().to_string();
        let cases: Vec<(&str, Vec<u8>, &str)> = vec![
            (
                "truncated",
                original[..original.len() - 9].to_vec(),
                "is truncated",
            ),
            (
                "header only",
                original[..40].to_vec(),
                "shorter than the 88-byte header",
            ),
            ("empty", Vec::new(), "is truncated: 0 bytes"),
            (
                "an EXR file",
                fs::read(plain.join(uncompressed_name(&file))).unwrap(),
                "no LMZC header",
            ),
            (
                "a flipped payload bit",
                {
                    let mut bytes = original.clone();
                    let at = bytes.len() - 20;
                    bytes[at] ^= 4;
                    bytes
                },
                "changed or damaged",
            ),
            (
                "bytes appended",
                [original.as_slice(), b"xx"].concat(),
                "changed or damaged",
            ),
            (
                "another scene's file",
                fs::read(other.join(&file)).unwrap(),
                "another scene",
            ),
        ];
        for (case, bytes, words) in cases {
            fs::write(packed.join(&file), &bytes).unwrap();
            let error = read_error(&packed);
            assert!(
                error.contains(&named) && error.contains(words),
                "{case}: {error}"
            );
        }
        fs::write(packed.join(&file), &original).unwrap();
        Bake::read(&packed).unwrap();
        // A delta whose keyframe is gone: a bad bake naming the keyframe and its entry.
        let compression = manifest.compression.as_ref().unwrap();
        let keyframe = compression.files[&file].reference.clone().expect("a delta");
        let kept = fs::read(packed.join(&keyframe)).unwrap();
        fs::remove_file(packed.join(&keyframe)).unwrap();
        let error = MapReader::new(&packed, &manifest).read(&file).unwrap_err();
        assert!(
            matches!(error, BakeError::MissingMap { .. })
                && error.to_string().contains(&format!(
                    "not found (listed in manifest.json at compression.files[\"{keyframe}\"])"
                )),
            "{error}"
        );
        fs::write(packed.join(&keyframe), kept).unwrap();
        // A manifest whose file checksum was changed, or whose chain is longer than its
        // interval, is refused naming the manifest.
        let manifest_path = packed.join(MANIFEST_FILE_NAME);
        let text = fs::read_to_string(&manifest_path).unwrap();
        fs::write(
            &manifest_path,
            text.replace("\"keyframe_interval\": 8", "\"keyframe_interval\": 2"),
        )
        .unwrap();
        let error = read_error(&packed);
        assert!(
            error.contains("manifest.json") && error.contains("chain of more than 1"),
            "{error}"
        );
        let _ = fs::remove_dir_all(&dir);
    }

    #[test]
    fn a_failed_compression_leaves_the_bake_as_it_was() {
        let dir = scratch("atomic");
        let plain = dir.join("plain");
        let bake = sequence_bake(3, "drift", 5);
        bake.write(&plain).unwrap();
        let manifest = Manifest::read(&plain).unwrap();
        let last = plain.join(&manifest.lenses[0].layers[1].maps[2]);
        let good = fs::read(&last).unwrap();
        fs::write(&last, &good[..good.len() / 2]).unwrap();
        let error = compress(&plain, &plain, &options(8, 0))
            .unwrap_err()
            .to_string();
        assert!(error.contains("v002.layer1.exr"), "{error}");
        fs::write(&last, &good).unwrap();
        // Still the uncompressed bake, every file in place.
        assert_eq!(Manifest::read(&plain).unwrap(), manifest);
        assert_eq!(all_bits(&Bake::read(&plain).unwrap()), all_bits(&bake));
        let names: Vec<_> = fs::read_dir(&dir)
            .unwrap()
            .map(|e| e.unwrap().file_name())
            .collect();
        assert_eq!(names, ["plain"]);
        let error = compress(&plain, &plain, &options(0, 0))
            .unwrap_err()
            .to_string();
        assert!(error.contains("keyframe interval 0"), "{error}");
        let _ = fs::remove_dir_all(&dir);
    }
}
