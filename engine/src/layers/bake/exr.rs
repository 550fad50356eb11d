//! Cube maps as files: the multi-part OpenEXR layout of the module documentation of
//! [`super`] (one part per mip level and face, premultiplied f32 RGBA, lossless ZIP), its writer
//! and its checking reader, and cube-map problems said as bake errors naming the file and part.

use std::fs::File;
use std::io::{BufReader, Cursor};
use std::path::{Path, PathBuf};

use super::error::{BakeError, io_error};
use crate::cubemap::{CubeMap, CubeMapError, TexelProblem, check_face_texels};

/// Face names in Vulkan layer order, as used in EXR part names.
pub const FACE_NAMES: [&str; 6] = ["+X", "-X", "+Y", "-Y", "+Z", "-Z"];

/// The lossless, deterministic encoding of every part.
const ENCODING: exr::prelude::Encoding = exr::prelude::Encoding::SMALL_LOSSLESS;

/// The EXR part name of a face of a mip level: `level{level}/{face}`.
pub fn part_name(level: usize, face: usize) -> String {
    format!("level{level}/{}", FACE_NAMES[face])
}

/// Checks a cube map with the one cube-map validator ([`CubeMap::validate`]: size, full chain,
/// texel counts, finite texels with α in [0, 1] within [`ALPHA_TOLERANCE`](super::ALPHA_TOLERANCE)) and reports a problem
/// as the bake error that names `path` and the EXR part.
pub fn check_cube_map(cube: &CubeMap, size: u32, path: &Path) -> Result<(), BakeError> {
    cube.validate(Some(size))
        .map_err(|error| cube_map_error(error, path))
}

/// A cube-map problem as the bake error naming the file and its EXR part.
fn cube_map_error(error: CubeMapError, path: &Path) -> BakeError {
    let path = path.to_owned();
    match error {
        CubeMapError::NotPowerOfTwo { size } => BakeError::NonPowerOfTwo { path, size },
        CubeMapError::WrongSize { found, expected } => BakeError::WrongSize {
            path,
            part: part_name(0, 0),
            found: format!("{found}×{found}"),
            expected,
            size: expected,
        },
        CubeMapError::ExtraLevel {
            level,
            size,
            levels,
        } => BakeError::BadPart {
            path,
            part: part_name(level, 0),
            problem: format!("is beyond the {levels} levels of a {size}² cube map"),
        },
        CubeMapError::MissingLevel {
            level,
            size,
            levels,
        } => BakeError::MissingLevel {
            path,
            part: part_name(level, 0),
            size,
            levels,
        },
        CubeMapError::TexelCount {
            level,
            face,
            found,
            edge,
        } => BakeError::WrongSize {
            path,
            part: part_name(level, face.index()),
            found: format!("{found} texels"),
            expected: edge,
            size: edge << level,
        },
        CubeMapError::Texel {
            level,
            face,
            x,
            y,
            problem,
        } => texel_error(path, part_name(level, face.index()), x, y, problem),
    }
}

/// A bad texel as the bake error naming the file and part.
fn texel_error(
    path: PathBuf,
    part: String,
    x: usize,
    y: usize,
    problem: TexelProblem,
) -> BakeError {
    match problem {
        TexelProblem::NonFinite { channel, value } => BakeError::NonFinite {
            path,
            part,
            x,
            y,
            channel: ['R', 'G', 'B', 'A'][channel],
            value,
        },
        TexelProblem::AlphaOutOfRange { value } => BakeError::AlphaOutOfRange {
            path,
            part,
            x,
            y,
            value,
        },
    }
}

/// Writes `cube` as a cube-map EXR (the layout in the module docs) to `path` and fsyncs it.
/// Writes whatever levels `cube` has without checking its values (see [`check_cube_map`]); fails
/// only if a face's texel count does not match its level's size, or on I/O errors.
pub fn write_cube_map_exr(cube: &CubeMap, path: &Path) -> Result<(), BakeError> {
    let bytes = encode_cube_map_exr(cube, path)?;
    crate::atomic::write_synced(path, &bytes).map_err(io_error(path, "write"))
}

/// The bytes of the cube-map EXR of `cube` (see [`write_cube_map_exr`]); `path` names the file
/// in errors.
pub fn encode_cube_map_exr(cube: &CubeMap, path: &Path) -> Result<Vec<u8>, BakeError> {
    use exr::prelude::*;
    let mut parts = Vec::with_capacity(cube.levels.len() * 6);
    for (level, faces) in cube.levels.iter().enumerate() {
        let edge = cube.level_size(level) as usize;
        for (face, texels) in faces.iter().enumerate() {
            let name = part_name(level, face);
            if texels.len() != edge * edge {
                return Err(BakeError::WrongSize {
                    path: path.to_owned(),
                    part: name,
                    found: format!("{} texels", texels.len()),
                    expected: edge as u32,
                    size: cube.size,
                });
            }
            let channel = |index: usize, channel_name: &str| {
                AnyChannel::new(
                    channel_name,
                    FlatSamples::F32(texels.iter().map(|texel| texel[index]).collect()),
                )
            };
            let channels = AnyChannels::sort(SmallVec::from_vec(vec![
                channel(0, "R"),
                channel(1, "G"),
                channel(2, "B"),
                channel(3, "A"),
            ]));
            parts.push(Layer::new(
                (edge, edge),
                LayerAttributes::named(name.as_str()),
                ENCODING,
                channels,
            ));
        }
    }
    let size = cube.size.max(1) as usize;
    let image = Image::from_layers(
        ImageAttributes::new(IntegerBounds::from_dimensions((size, size))),
        parts,
    );
    let mut bytes = Cursor::new(Vec::new());
    image
        .write()
        .to_buffered(&mut bytes)
        .map_err(|error| BakeError::Exr {
            path: path.to_owned(),
            message: error.to_string(),
        })?;
    Ok(bytes.into_inner())
}

/// Where part `name` of a cube map of `size` belongs, `(level, face, edge)`, and that its
/// `(width, height)` is that level's: the rule the headers and the pixels are both checked by.
fn part_place(
    path: &Path,
    name: &str,
    size: u32,
    width: usize,
    height: usize,
) -> Result<(usize, usize, usize), BakeError> {
    let levels = CubeMap::full_chain_levels(size) as usize;
    let Some((level, face)) = parse_part_name(name).filter(|(level, _)| *level < levels) else {
        return Err(BakeError::BadPart {
            path: path.to_owned(),
            part: name.to_owned(),
            problem: format!("is not one of level0/+X … level{}/-Z", levels - 1),
        });
    };
    let edge = (size >> level).max(1) as usize;
    if width != edge || height != edge {
        return Err(BakeError::WrongSize {
            path: path.to_owned(),
            part: name.to_owned(),
            found: format!("{width}×{height}"),
            expected: edge as u32,
            size,
        });
    }
    Ok((level, face, edge))
}

/// Checks the parts' names, sizes and channel counts from the file's headers alone, before
/// any pixel is read: the EXR reader allocates whatever a header claims, so a damaged header
/// could ask for gigabytes (found by fuzzing). The same rules as [`read_cube_map_exr`] applies
/// to the pixels, so the messages are the same.
fn check_headers(path: &Path, size: u32) -> Result<(), BakeError> {
    let file = File::open(path).map_err(io_error(path, "open"))?;
    let meta =
        exr::meta::MetaData::read_from_buffered(BufReader::new(file), false).map_err(|error| {
            BakeError::Exr {
                path: path.to_owned(),
                message: error.to_string(),
            }
        })?;
    for header in &meta.headers {
        let name = header
            .own_attributes
            .layer_name
            .as_ref()
            .map_or_else(String::new, |name| name.to_string());
        part_place(path, &name, size, header.layer_size.0, header.layer_size.1)?;
        if header.channels.list.len() != 4 {
            return Err(BakeError::BadPart {
                path: path.to_owned(),
                part: name,
                problem: format!(
                    "has {} channels, not R, G, B and A",
                    header.channels.list.len()
                ),
            });
        }
    }
    Ok(())
}

/// Reads a cube-map EXR written by [`write_cube_map_exr`] and checks it against `size`: every
/// part of the full chain present once with f32 `R G B A` channels of the right size, and every
/// texel finite with α in [0, 1] (tolerance [`ALPHA_TOLERANCE`](super::ALPHA_TOLERANCE)).
pub fn read_cube_map_exr(path: &Path, size: u32) -> Result<CubeMap, BakeError> {
    use exr::prelude::*;
    check_headers(path, size)?;
    let file = File::open(path).map_err(io_error(path, "open"))?;
    let image = read()
        .no_deep_data()
        .largest_resolution_level()
        .all_channels()
        .all_layers()
        .all_attributes()
        .from_buffered(BufReader::new(file))
        .map_err(|error| BakeError::Exr {
            path: path.to_owned(),
            message: error.to_string(),
        })?;
    let levels = CubeMap::full_chain_levels(size) as usize;
    let mut found: Vec<[Option<Vec<[f32; 4]>>; 6]> =
        (0..levels).map(|_| Default::default()).collect();
    for part in &image.layer_data {
        let name = part
            .attributes
            .layer_name
            .as_ref()
            .map_or_else(String::new, |name| name.to_string());
        let bad = |problem: String| BakeError::BadPart {
            path: path.to_owned(),
            part: name.clone(),
            problem,
        };
        let (level, face, edge) = part_place(path, &name, size, part.size.0, part.size.1)?;
        if found[level][face].is_some() {
            return Err(bad("appears twice".to_owned()));
        }
        let mut texels = vec![[0.0f32; 4]; edge * edge];
        for (index, channel_name) in ["R", "G", "B", "A"].into_iter().enumerate() {
            let channel = part
                .channel_data
                .list
                .iter()
                .find(|channel| channel.name.eq(channel_name))
                .ok_or_else(|| bad(format!("has no channel {channel_name}")))?;
            let FlatSamples::F32(samples) = &channel.sample_data else {
                return Err(bad(format!("channel {channel_name} is not 32-bit float")));
            };
            for (texel, value) in texels.iter_mut().zip(samples) {
                texel[index] = *value;
            }
        }
        check_face_texels(&texels, edge)
            .map_err(|(x, y, problem)| texel_error(path.to_owned(), name.clone(), x, y, problem))?;
        found[level][face] = Some(texels);
    }
    let mut chain = Vec::with_capacity(levels);
    for (level, faces) in found.into_iter().enumerate() {
        let mut complete = Vec::with_capacity(6);
        for (face, texels) in faces.into_iter().enumerate() {
            complete.push(texels.ok_or_else(|| BakeError::MissingLevel {
                path: path.to_owned(),
                part: part_name(level, face),
                size,
                levels: levels as u32,
            })?);
        }
        let faces: [Vec<[f32; 4]>; 6] = complete
            .try_into()
            .unwrap_or_else(|_| unreachable!("six faces were pushed"));
        chain.push(faces);
    }
    Ok(CubeMap {
        size,
        levels: chain,
    })
}

/// `level{l}/{face}` → `(l, face index)`.
fn parse_part_name(name: &str) -> Option<(usize, usize)> {
    let (level, face) = name.strip_prefix("level")?.split_once('/')?;
    let level = level.parse().ok()?;
    let face = FACE_NAMES.iter().position(|f| *f == face)?;
    Some((level, face))
}
