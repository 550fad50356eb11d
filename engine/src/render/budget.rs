//! Whether a frame fits the device, checked before any work: the framebuffer's sides against
//! `maxImageDimension2D`, the targets of every frame in flight (colour, depth, readback, a
//! blending scheme's scratch images) against a share of the largest device-local heap, and the
//! maps a frame draws from (layered EMs with their mip chains, light maps) against another share
//! before they are uploaded. A refusal is a [`FramebufferError`] or a [`MapBudgetError`]
//! carrying the sizes and limits, worded by each front end.

use std::{collections::HashSet, sync::Arc};

use super::{FRAMES_IN_FLIGHT, FrameInput, RenderError, TargetFormat, targets::Scratch};
use crate::{
    cubemap::CubeMap,
    gpu::Gpu,
    options::{LibraryWords, OptionWords, Worded, names},
};

/// The share of the largest device-local heap the framebuffer targets may take (see
/// [`MAP_HEAP_SHARE`] for the maps').
pub const FRAMEBUFFER_HEAP_SHARE: f64 = 0.75;

/// The share of the largest device-local heap the maps one frame draws from may take: its
/// layered EMs (RGBA32F cube-map arrays with full mip chains) and its light maps (RGBA16F).
///
/// The two shares are fixed and sum to less than the heap, rather than the maps taking what
/// the targets leave, because the maps are uploaded before the frame's format and blending
/// scheme (which size the targets) are chosen, and one upload may be rendered in several
/// formats: with fixed shares each check stands alone, and a frame whose maps were accepted is
/// never refused later for its targets, or the other way round. What both leave (5 %) holds the
/// meshes, the lens objects' buffers and the driver's own allocations.
pub const MAP_HEAP_SHARE: f64 = 0.2;

/// Bytes a texel of a layered EM takes on the GPU (RGBA32F).
const EM_TEXEL_BYTES: u64 = 16;

/// Bytes a texel of a light map takes on the GPU (RGBA16F).
const LIGHT_MAP_TEXEL_BYTES: u64 = 8;

/// The device memory of the maps one frame draws from, each distinct map once: a cube-map array
/// that two viewpoints, two lens objects or a recent frame share is uploaded (and counted) once,
/// as is the light map of an environment mesh that appears twice.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct MapBytes {
    /// Cube maps of the layered EMs (one per layer of each distinct cube-map array).
    pub cube_maps: usize,
    /// The largest EM face size among them, texels.
    pub largest_em_size: u32,
    /// Bytes of the layered EMs: every face of every mip level, [`EM_TEXEL_BYTES`] a texel.
    pub layered_em_bytes: u64,
    /// Light maps.
    pub light_maps: usize,
    /// Their texels.
    pub light_map_texels: u64,
    /// Bytes of the light maps: one level, [`LIGHT_MAP_TEXEL_BYTES`] a texel.
    pub light_map_bytes: u64,
}

impl MapBytes {
    /// The maps of `frame`, counted from their sizes (nothing is read but the sizes).
    pub fn of_frame(frame: &FrameInput) -> MapBytes {
        let mut bytes = MapBytes::default();
        let mut arrays = HashSet::new();
        for cubes in frame.lenses.iter().flat_map(|lens| &lens.layers) {
            // The renderer's upload cache keys a cube-map array by its maps' identities.
            let key: Vec<usize> = cubes.iter().map(|c| Arc::as_ptr(c) as usize).collect();
            if arrays.insert(key) {
                bytes.add_layered_em(cubes);
            }
        }
        // The glossy draws' maps, one cube-map array a draw, counted with the layered EMs.
        for glossy in &frame.glossy {
            let cubes = glossy.flat_maps();
            let key: Vec<usize> = cubes.iter().map(|c| Arc::as_ptr(c) as usize).collect();
            if arrays.insert(key) {
                bytes.add_layered_em(&cubes);
            }
        }
        let mut meshes = HashSet::new();
        for mesh in &frame.environment {
            if let Some(light_map) = &mesh.light_map
                && !mesh.triangles.is_empty()
                && meshes.insert(Arc::as_ptr(mesh) as usize)
            {
                bytes.add_light_map(light_map.map.width, light_map.map.height);
            }
        }
        bytes
    }

    /// Adds one cube-map array holding `cubes`.
    pub(super) fn add_layered_em(&mut self, cubes: &[Arc<CubeMap>]) {
        for cube in cubes {
            self.cube_maps += 1;
            self.largest_em_size = self.largest_em_size.max(cube.size);
            self.layered_em_bytes += cube_map_bytes(cube.size, cube.levels.len());
        }
    }

    /// Adds one light map of `width × height` texels.
    pub(super) fn add_light_map(&mut self, width: u32, height: u32) {
        let texels = u64::from(width) * u64::from(height);
        self.light_maps += 1;
        self.light_map_texels += texels;
        self.light_map_bytes += texels * LIGHT_MAP_TEXEL_BYTES;
    }

    /// All of it, bytes.
    pub fn total(&self) -> u64 {
        self.layered_em_bytes + self.light_map_bytes
    }
}

/// Bytes of one cube map of `size²` texels a face with `levels` mip levels on the GPU: six faces
/// of `max(size >> l, 1)²` texels at each level l.
fn cube_map_bytes(size: u32, levels: usize) -> u64 {
    (0..levels)
        .map(|level| {
            let side = u64::from(size.checked_shr(level as u32).unwrap_or(0).max(1));
            6 * side * side * EM_TEXEL_BYTES
        })
        .sum()
}

/// Maps one frame draws from that do not fit the device's budget for maps. Its message names the
/// options that shrink them: the EMs' face size (`em_size`, of projected EMs or of a bake) and
/// the light maps' texel budget (`light_map_max_texels`, which lowers every chart's density).
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("{}", self.worded(&LibraryWords))]
pub struct MapBudgetError {
    /// The frame's maps.
    pub maps: MapBytes,
    /// Bytes they may take: [`MAP_HEAP_SHARE`] of the largest device-local heap.
    pub budget: u64,
}

impl Worded for MapBudgetError {
    fn worded(&self, words: &dyn OptionWords) -> String {
        let maps = &self.maps;
        let light_maps = if maps.light_maps > 0 {
            format!(
                "; {} light map(s) of {} texels: {}",
                maps.light_maps,
                maps.light_map_texels,
                size(maps.light_map_bytes)
            )
        } else {
            String::new()
        };
        format!(
            "the frame's maps need {} of device memory ({} layered-EM cube maps of up to {}² texels a face with their mip chains: {}{light_maps}), past this device's budget for maps of {} ({:.0}% of its largest device-local heap); give a smaller {} (of the projected EMs, or bake with a smaller one) or a smaller {} (it lowers every light-map chart's density)",
            size(maps.total()),
            maps.cube_maps,
            maps.largest_em_size,
            size(maps.layered_em_bytes),
            size(self.budget),
            MAP_HEAP_SHARE * 100.0,
            words.option(names::EM_SIZE),
            words.option(names::LIGHT_MAP_MAX_TEXELS),
        )
    }
}

/// `bytes` for a message: KiB below a MiB, MiB below a GiB, else GiB.
fn size(bytes: u64) -> String {
    const KIB: f64 = 1024.0;
    let b = bytes as f64;
    if b < KIB * KIB {
        format!("{:.1} KiB", b / KIB)
    } else if b < KIB * KIB * KIB {
        format!("{:.1} MiB", b / (KIB * KIB))
    } else {
        format!("{:.2} GiB", b / (KIB * KIB * KIB))
    }
}

/// Checks `maps` against [`MAP_HEAP_SHARE`] of the device's largest device-local heap, before
/// any of them is uploaded.
pub(super) fn check_map_budget(gpu: &Gpu, maps: &MapBytes) -> Result<(), RenderError> {
    Ok(map_budget(maps, gpu.device_local_heap_bytes())?)
}

/// `maps` against [`MAP_HEAP_SHARE`] of `heap_bytes`.
fn map_budget(maps: &MapBytes, heap_bytes: u64) -> Result<(), MapBudgetError> {
    let budget = (heap_bytes as f64 * MAP_HEAP_SHARE) as u64;
    if maps.total() > budget {
        return Err(MapBudgetError {
            maps: *maps,
            budget,
        });
    }
    Ok(())
}

/// A framebuffer this device cannot hold. Its message names the options that size it (the
/// camera's `width`, `height`, `supersampling`, the frame's `format` and `blend`).
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error("{}", self.worded(&LibraryWords))]
pub enum FramebufferError {
    /// A side is longer than the device's `maxImageDimension2D`.
    TooLarge {
        /// Framebuffer width, subpixels.
        width: u32,
        /// Framebuffer height, subpixels.
        height: u32,
        /// The device's `maxImageDimension2D`.
        limit: u32,
    },
    /// The targets of every frame in flight need more device memory than
    /// [`FRAMEBUFFER_HEAP_SHARE`] of the largest device-local heap.
    OverBudget {
        /// Framebuffer width, subpixels.
        width: u32,
        /// Framebuffer height, subpixels.
        height: u32,
        /// The framebuffer's format.
        format: TargetFormat,
        /// Framebuffer-sized scratch images of a blending scheme, per frame (0: none).
        scratch: u32,
        /// Bytes the targets need.
        needed: u64,
        /// Bytes they may take.
        budget: u64,
        /// Frames in flight, each with its own targets.
        frames_in_flight: usize,
    },
}

impl Worded for FramebufferError {
    fn worded(&self, words: &dyn OptionWords) -> String {
        match *self {
            FramebufferError::TooLarge {
                width,
                height,
                limit,
            } => format!(
                "the framebuffer is {width}×{height} subpixels, past this device's limit of {limit} a side (maxImageDimension2D); give a smaller image or less supersampling ({}/{}/{})",
                words.option(names::WIDTH),
                words.option(names::HEIGHT),
                words.option(names::SUPERSAMPLING)
            ),
            FramebufferError::OverBudget {
                width,
                height,
                format,
                scratch,
                needed,
                budget,
                frames_in_flight,
            } => {
                let mib = |bytes: u64| bytes as f64 / (1u64 << 20) as f64;
                let (scratch_images, fewer_scratch) = if scratch > 0 {
                    (
                        format!(" and the blending scheme's {scratch} scratch images"),
                        format!(
                            " or {}",
                            words.setting(names::BLEND, super::BlendScheme::FrontToBack.name())
                        ),
                    )
                } else {
                    (String::new(), String::new())
                };
                format!(
                    "the framebuffer is {width}×{height} subpixels in {}: its targets{scratch_images} need {:.0} MiB of device memory ({frames_in_flight} frames in flight), past this device's budget of {:.0} MiB ({:.0}% of its largest device-local heap); give a smaller image, less supersampling, a smaller {}{fewer_scratch}",
                    format.name(),
                    mib(needed),
                    mib(budget),
                    FRAMEBUFFER_HEAP_SHARE * 100.0,
                    words.option(names::FORMAT),
                )
            }
        }
    }
}

/// Checks a framebuffer of `width × height` subpixels in `format` against the device, before any
/// work: each side against `maxImageDimension2D`, and the colour, depth and readback targets of
/// every frame in flight against [`FRAMEBUFFER_HEAP_SHARE`] of the largest device-local heap.
pub fn check_framebuffer(
    gpu: &Gpu,
    width: u32,
    height: u32,
    format: TargetFormat,
) -> Result<(), RenderError> {
    check_dimensions(gpu, width, height)?;
    Ok(framebuffer_budget(
        width,
        height,
        format,
        0,
        gpu.device_local_heap_bytes(),
    )?)
}

/// [`check_framebuffer`]'s budget with `scratch` more framebuffer-sized colour images per frame
/// (a blending scheme's, [`Scratch`]), checked before they are made.
pub(super) fn check_scratch_budget(
    gpu: &Gpu,
    width: u32,
    height: u32,
    format: TargetFormat,
    scratch: usize,
) -> Result<(), RenderError> {
    Ok(framebuffer_budget(
        width,
        height,
        format,
        Scratch::layers_for(scratch),
        gpu.device_local_heap_bytes(),
    )?)
}

/// Each side of a `width × height` framebuffer against the device's `maxImageDimension2D`.
pub(super) fn check_dimensions(gpu: &Gpu, width: u32, height: u32) -> Result<(), RenderError> {
    let limit = gpu.properties().limits.max_image_dimension2_d;
    if width > limit || height > limit {
        return Err(FramebufferError::TooLarge {
            width,
            height,
            limit,
        }
        .into());
    }
    Ok(())
}

/// The device memory the targets of [`FRAMES_IN_FLIGHT`] frames of `width × height` subpixels in
/// `format` take (colour, 32-bit depth, readback, and `scratch` colour images of a blending
/// scheme), against [`FRAMEBUFFER_HEAP_SHARE`] of `heap_bytes`.
fn framebuffer_budget(
    width: u32,
    height: u32,
    format: TargetFormat,
    scratch: u32,
    heap_bytes: u64,
) -> Result<(), FramebufferError> {
    let colour = u64::from(crate::gpu::format_bytes(super::vulkan::vk_format(
        format.graph_format(),
    )));
    let per_frame = u64::from(width) * u64::from(height) * ((2 + u64::from(scratch)) * colour + 4);
    let needed = per_frame * FRAMES_IN_FLIGHT as u64;
    let budget = (heap_bytes as f64 * FRAMEBUFFER_HEAP_SHARE) as u64;
    if needed > budget {
        return Err(FramebufferError::OverBudget {
            width,
            height,
            format,
            scratch,
            needed,
            budget,
            frames_in_flight: FRAMES_IN_FLIGHT,
        });
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::{FRAMEBUFFER_HEAP_SHARE, FramebufferError, framebuffer_budget};
    use super::{MAP_HEAP_SHARE, MapBytes, cube_map_bytes, map_budget};
    use crate::options::Worded;
    use crate::render::{FRAMES_IN_FLIGHT, TargetFormat, tests::Flags};

    /// The budget is the targets' bytes, counted independently here: RGBA32F colour (16 bytes),
    /// its readback (16) and 32-bit depth (4) per subpixel, for every frame in flight.
    #[test]
    fn the_framebuffer_budget_counts_every_target_of_every_frame_in_flight() {
        let (width, height) = (4000u32, 3000u32);
        let needed = u64::from(width) * u64::from(height) * 36 * FRAMES_IN_FLIGHT as u64;
        let heap_fitting = (needed as f64 / FRAMEBUFFER_HEAP_SHARE).ceil() as u64 + 1;
        assert!(framebuffer_budget(width, height, TargetFormat::Rgba32f, 0, heap_fitting).is_ok());
        let error =
            framebuffer_budget(width, height, TargetFormat::Rgba32f, 0, heap_fitting - 1024)
                .unwrap_err();
        let (library, flags) = (error.to_string(), error.worded(&Flags));
        assert!(
            library.contains("4000×3000") && library.contains("a smaller `FrameOptions.format`"),
            "{library}"
        );
        assert!(
            flags.contains("--format") && !library.contains("--"),
            "{flags}"
        );
        // RGBA8 needs 4 + 4 + 4 bytes a subpixel: a third of RGBA32F's, so it fits there.
        assert!(framebuffer_budget(width, height, TargetFormat::Rgba8, 0, needed / 2).is_ok());
        assert!(
            framebuffer_budget(1, 1, TargetFormat::Rgba8, 0, 0).is_err(),
            "no heap"
        );
        // A blending scheme's scratch images count too: four more RGBA32F images (64 bytes a
        // subpixel) take the frame past the heap that fits the targets alone, naming the blend.
        let error =
            framebuffer_budget(width, height, TargetFormat::Rgba32f, 4, heap_fitting).unwrap_err();
        let (library, flags) = (error.to_string(), error.worded(&Flags));
        assert!(
            library.contains("4 scratch images") && library.contains("`blend` = front-to-back"),
            "{library}"
        );
        assert!(flags.contains("--blend front-to-back"), "{flags}");
        let with_scratch = u64::from(width) * u64::from(height) * 100 * FRAMES_IN_FLIGHT as u64;
        let fitting = (with_scratch as f64 / FRAMEBUFFER_HEAP_SHARE).ceil() as u64 + 1;
        assert!(framebuffer_budget(width, height, TargetFormat::Rgba32f, 4, fitting).is_ok());
    }

    /// A side past the device's limit names the limit and, in each front end's words, the
    /// options that size the framebuffer.
    #[test]
    fn a_side_past_the_limit_names_the_sizing_options() {
        let error = FramebufferError::TooLarge {
            width: 20000,
            height: 10,
            limit: 16384,
        };
        assert_eq!(
            error.to_string(),
            "the framebuffer is 20000×10 subpixels, past this device's limit of 16384 a side (maxImageDimension2D); give a smaller image or less supersampling (`Camera.width`/`Camera.height`/`Camera.supersampling`)"
        );
        assert!(
            error
                .worded(&Flags)
                .ends_with("(--width/--height/--supersampling)")
        );
    }

    /// A cube map's bytes counted by hand: 16² texels a face, 5 levels (16, 8, 4, 2, 1): six
    /// faces of 256 + 64 + 16 + 4 + 1 = 341 texels of 16 bytes, 32736 bytes; a 1² map with one
    /// level, 96 bytes.
    #[test]
    fn a_cube_maps_bytes_are_every_face_of_every_level() {
        assert_eq!(cube_map_bytes(16, 5), 6 * 341 * 16);
        assert_eq!(cube_map_bytes(16, 5), 32736);
        assert_eq!(cube_map_bytes(1, 1), 96);
        // 128² with the full chain of 8 levels: 6·16·(128² + 64² + … + 1) = 6·16·21845.
        assert_eq!(cube_map_bytes(128, 8), 6 * 16 * 21845);
    }

    /// A frame's maps, counted by hand: two lens objects, the second sharing the first's
    /// viewpoint-0 array (counted once) and adding one of its own; two meshes with light maps,
    /// one of them listed twice (counted once), and one without (no map of its own).
    #[test]
    fn a_frames_maps_are_counted_once_each_against_the_budget() {
        use crate::cubemap::CubeMap;
        use crate::lightmap::LightMap;
        use crate::render::{EnvironmentMesh, FrameInput, LensFaces, LensObject, MeshLightMap};
        use glam::{Mat4, Vec2, Vec3};
        use std::sync::Arc;
        let cube = |size: u32| Arc::new(CubeMap::uniform(size, [0.5, 0.5, 0.5, 1.0]));
        let shared = vec![cube(16), cube(16)];
        let lens = |layers: Vec<Vec<Arc<CubeMap>>>| LensObject {
            name: format!("lens{}", layers.len()),
            positions: vec![Vec3::ZERO; 3],
            triangles: vec![[0, 1, 2]],
            faces: LensFaces::Front,
            hull_triangles: 0,
            terms: Vec::new(),
            layers,
            resident: None,
        };
        let mesh = |light_map: Option<(u32, u32)>| {
            Arc::new(EnvironmentMesh {
                positions: vec![Vec3::ZERO; 3],
                colours: vec![Vec3::ONE; 3],
                triangles: vec![[0, 1, 2]],
                light_map: light_map.map(|(w, h)| MeshLightMap {
                    uvs: vec![Vec2::ZERO; 3],
                    map: LightMap::uniform(w, h, [1.0; 4]),
                }),
            })
        };
        let lit = mesh(Some((64, 32)));
        let frame = FrameInput {
            width: 8,
            height: 8,
            view_proj: Mat4::IDENTITY,
            environment: vec![lit.clone(), lit, mesh(Some((10, 10))), mesh(None)],
            glossy: Vec::new(),
            lenses: vec![
                lens(vec![shared.clone()]),
                lens(vec![shared, vec![cube(32), cube(32)]]),
            ],
            viewpoint_weights: vec![0.5, 0.5],
        };
        let maps = MapBytes::of_frame(&frame);
        // Two arrays of two cube maps: 16² (5 levels) and 32² (6 levels: 1365 texels a face).
        let ems = 2 * 32736 + 2 * 6 * 1365 * 16;
        // 64·32 + 10·10 texels of 8 bytes.
        let light = (64 * 32 + 100) * 8;
        assert_eq!(
            maps,
            MapBytes {
                cube_maps: 4,
                largest_em_size: 32,
                layered_em_bytes: ems,
                light_maps: 2,
                light_map_texels: 64 * 32 + 100,
                light_map_bytes: light,
            }
        );
        assert_eq!(maps.total(), ems + light);
        // The budget is MAP_HEAP_SHARE of the heap: a heap just large enough passes, one a
        // KiB smaller is refused, naming the size, the budget and the options.
        let fitting = (maps.total() as f64 / MAP_HEAP_SHARE).ceil() as u64 + 8;
        assert!(map_budget(&maps, fitting).is_ok());
        let error = map_budget(&maps, fitting - 1024 * 5).unwrap_err();
        assert_eq!(
            error.budget,
            ((fitting - 5120) as f64 * MAP_HEAP_SHARE) as u64
        );
        let (library, flags) = (error.to_string(), error.worded(&Flags));
        assert_eq!(
            library,
            "the frame's maps need 336.7 KiB of device memory (4 layered-EM cube maps of up to 32² texels a face with their mip chains: 319.9 KiB; 2 light map(s) of 2148 texels: 16.8 KiB), past this device's budget for maps of 335.7 KiB (20% of its largest device-local heap); give a smaller `ProjectedOptions.size` (of the projected EMs, or bake with a smaller one) or a smaller `LightMapOptions.max_texels` (it lowers every light-map chart's density)"
        );
        assert!(
            flags.contains("a smaller --em-size") && flags.contains("--light-map-max-texels"),
            "{flags}"
        );
    }
}
