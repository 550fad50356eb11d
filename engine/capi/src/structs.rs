//! The caller's structs: reading what it passes (option structs with their `struct_size` checked
//! against this ABI's and earlier ABIs' sizes, UTF-8 strings, the `LENSMAP_*` values, semaphore
//! arrays), checked and turned into the library's types, and writing statistics back into the
//! size it gave. A bad value is a failure naming the field and the fix.

use std::ffi::{CStr, c_char};

use lensmap::gpu::vk;
use lensmap::hybrid::{FresnelModel, HybridOptions, VertexTracer, ViewpointBlending};
use lensmap::options::Worded;
use lensmap::render::{BlendScheme, Compositing, TargetFormat, Variant};
use lensmap::runner::FrameOptions;
use lensmap::scene::Camera;
use lensmap::trace::schlick_table::{MAX_TEXELS, MIN_TEXELS};

use crate::failure::{Failure, StructFields, null};
use crate::types::*;

/// `*pointer`, or a NullArgument failure naming it.
///
/// # Safety
/// A non-null `pointer` must point to a readable `T`.
pub(crate) unsafe fn read_struct<T: Copy>(pointer: *const T, name: &str) -> Result<T, Failure> {
    if pointer.is_null() {
        return Err(Failure::new(
            LensmapResult::NullArgument,
            format!("{name} is NULL"),
        ));
    }
    // SAFETY: non-null, and readable by the caller's promise. Its first field is the size.
    let size = unsafe { *(pointer as *const u32) };
    if size as usize != std::mem::size_of::<T>() {
        return Err(Failure::new(
            LensmapResult::StructSize,
            format!(
                "{name}->struct_size is {size}, but this lensmap (ABI {LENSMAP_ABI_VERSION}) knows {} bytes; set it to sizeof the struct from the lensmap.h this library ships",
                std::mem::size_of::<T>()
            ),
        ));
    }
    // SAFETY: the caller says a whole T is there, and the size it wrote agrees.
    Ok(unsafe { *pointer })
}

/// `*pointer` of a struct that grew at its end: its `struct_size` may be this library's size or
/// one of `older`, earlier ABIs' (the struct up to the first field that version lacked); the
/// missing fields read as zero (each one's zero is the earlier behaviour).
///
/// # Safety
/// A non-null `pointer` must point to a readable struct of the size its first field says, and
/// `T` must be a `repr(C)` struct of integers, floats and raw pointers (all-zero bytes are a
/// valid `T`: a zero pointer is NULL).
pub(crate) unsafe fn read_versioned<T: Copy>(
    pointer: *const T,
    name: &str,
    older: &[usize],
) -> Result<T, Failure> {
    if pointer.is_null() {
        return Err(Failure::new(
            LensmapResult::NullArgument,
            format!("{name} is NULL"),
        ));
    }
    // SAFETY: non-null, and readable by the caller's promise. Its first field is the size.
    let size = unsafe { *(pointer as *const u32) } as usize;
    let current = std::mem::size_of::<T>();
    debug_assert!(
        older.iter().all(|&o| o < current),
        "an earlier ABI's struct is a prefix of this one"
    );
    if size != current && !older.contains(&size) {
        return Err(struct_size_failure(name, size, current, older));
    }
    // SAFETY: all-zero bytes are a valid T (the caller's promise); the caller's struct holds
    // `size` ≤ size_of::<T>() readable bytes, copied over the zeros.
    let mut value: T = unsafe { std::mem::zeroed() };
    unsafe {
        std::ptr::copy_nonoverlapping(pointer as *const u8, &mut value as *mut T as *mut u8, size)
    };
    Ok(value)
}

/// The refusal of a `struct_size` that is neither `current` nor one of `older`.
pub(crate) fn struct_size_failure(
    name: &str,
    size: usize,
    current: usize,
    older: &[usize],
) -> Failure {
    let older: Vec<String> = older.iter().map(usize::to_string).collect();
    Failure::new(
        LensmapResult::StructSize,
        format!(
            "{name}->struct_size is {size}, but this lensmap (ABI {LENSMAP_ABI_VERSION}) knows {current} bytes (or {} from an earlier ABI); set it to sizeof the struct from the lensmap.h this library ships",
            older.join(" or ")
        ),
    )
}

/// ABI 2's `sizeof(LensmapFrameOptions)`: everything before `blend` (ABI 2 had no trailing
/// padding, so its size is the new field's offset; pinned, so a reordering cannot move it).
pub(crate) const FRAME_OPTIONS_ABI2: usize = 68;

/// ABI 3's `sizeof(LensmapFrameOptions)`: everything before `viewpoint_blending`.
pub(crate) const FRAME_OPTIONS_ABI3: usize = 72;

/// ABI 4's `sizeof(LensmapFrameOptions)`: everything before `fresnel_texels`.
pub(crate) const FRAME_OPTIONS_ABI4: usize = 76;

/// ABI 5's `sizeof(LensmapFrameOptions)`: everything before `tracer`.
pub(crate) const FRAME_OPTIONS_ABI5: usize = 80;

/// The sizes of `LensmapFrameOptions` earlier ABIs had, all accepted.
pub(crate) const FRAME_OPTIONS_OLDER: [usize; 4] = [
    FRAME_OPTIONS_ABI2,
    FRAME_OPTIONS_ABI3,
    FRAME_OPTIONS_ABI4,
    FRAME_OPTIONS_ABI5,
];

/// ABI 2's `sizeof(LensmapPlanOptions)`: everything before `blend`.
pub(crate) const PLAN_OPTIONS_ABI2: usize = 24;

/// ABI 3's `sizeof(LensmapSceneOptions)`: everything before `light_map_max_texels` (ABI 3's
/// struct ended on two `uint32_t` after two pointers, without trailing padding).
pub(crate) const SCENE_OPTIONS_ABI3: usize = 32;

/// ABI 6's `sizeof(LensmapSceneOptions)`: everything before `radiance_dir`.
pub(crate) const SCENE_OPTIONS_ABI6: usize = 40;

const _: () = assert!(
    SCENE_OPTIONS_ABI6 == std::mem::offset_of!(LensmapSceneOptions, radiance_dir),
    "ABI 6's scene options end where `radiance_dir` begins"
);
const _: () = assert!(
    FRAME_OPTIONS_ABI2 == std::mem::offset_of!(LensmapFrameOptions, blend)
        && PLAN_OPTIONS_ABI2 == std::mem::offset_of!(LensmapPlanOptions, blend),
    "ABI 2's structs end where `blend` begins"
);
const _: () = assert!(
    FRAME_OPTIONS_ABI3 == std::mem::offset_of!(LensmapFrameOptions, viewpoint_blending),
    "ABI 3's frame options end where `viewpoint_blending` begins"
);
const _: () = assert!(
    FRAME_OPTIONS_ABI4 == std::mem::offset_of!(LensmapFrameOptions, fresnel_texels),
    "ABI 4's frame options end where `fresnel_texels` begins"
);
const _: () = assert!(
    FRAME_OPTIONS_ABI5 == std::mem::offset_of!(LensmapFrameOptions, tracer),
    "ABI 5's frame options end where `tracer` begins"
);
const _: () = assert!(
    SCENE_OPTIONS_ABI3 == std::mem::offset_of!(LensmapSceneOptions, light_map_max_texels),
    "ABI 3's scene options end where `light_map_max_texels` begins"
);

/// A UTF-8 C string, or a failure naming the field.
///
/// # Safety
/// A non-null `text` must be NUL-terminated and readable.
pub(crate) unsafe fn read_text(text: *const c_char, name: &str) -> Result<Option<String>, Failure> {
    if text.is_null() {
        return Ok(None);
    }
    // SAFETY: the caller's promise.
    let text = unsafe { CStr::from_ptr(text) };
    text.to_str().map(|s| Some(s.to_owned())).map_err(|_| {
        Failure::new(
            LensmapResult::InvalidArgument,
            format!("{name} is not UTF-8"),
        )
    })
}

pub(crate) fn variant(value: u32, field: &str) -> Result<Variant, Failure> {
    match value {
        LENSMAP_VARIANT_SINGLE_PASS => Ok(Variant::SinglePass),
        LENSMAP_VARIANT_MULTIPASS => Ok(Variant::Multipass),
        other => Err(Failure::new(
            LensmapResult::InvalidArgument,
            format!(
                "{field} is {other}; give LENSMAP_VARIANT_SINGLE_PASS (0) or LENSMAP_VARIANT_MULTIPASS (1)"
            ),
        )),
    }
}

pub(crate) fn blend(value: u32, field: &str) -> Result<BlendScheme, Failure> {
    match value {
        LENSMAP_BLEND_FRONT_TO_BACK => Ok(BlendScheme::FrontToBack),
        LENSMAP_BLEND_BACK_TO_FRONT => Ok(BlendScheme::BackToFront),
        LENSMAP_BLEND_GROUP_TARGETS => Ok(BlendScheme::GroupTargets),
        LENSMAP_BLEND_PROGRAMMABLE => Ok(BlendScheme::Programmable),
        other => Err(Failure::new(
            LensmapResult::InvalidArgument,
            format!(
                "{field} is {other}; give LENSMAP_BLEND_FRONT_TO_BACK (0), _BACK_TO_FRONT (1), _GROUP_TARGETS (2) or _PROGRAMMABLE (3)"
            ),
        )),
    }
}

/// `options->variant` and `options->blend` as the library's [`Compositing`], whose one check
/// refuses the single pass with a blending scheme.
pub(crate) fn compositing(variant_value: u32, blend_value: u32) -> Result<Compositing, Failure> {
    Compositing::new(
        variant(variant_value, "options->variant")?,
        blend(blend_value, "options->blend")?,
    )
    .map_err(|error| Failure::new(LensmapResult::InvalidArgument, error.worded(&StructFields)))
}

pub(crate) fn format(value: u32, field: &str) -> Result<TargetFormat, Failure> {
    match value {
        LENSMAP_FORMAT_RGBA8 => Ok(TargetFormat::Rgba8),
        LENSMAP_FORMAT_RGBA16F => Ok(TargetFormat::Rgba16f),
        LENSMAP_FORMAT_RGBA32F => Ok(TargetFormat::Rgba32f),
        other => Err(Failure::new(
            LensmapResult::UnsupportedFormat,
            format!(
                "{field} is {other}; lensmap renders to LENSMAP_FORMAT_RGBA8 (0), LENSMAP_FORMAT_RGBA16F (1) or LENSMAP_FORMAT_RGBA32F (2)"
            ),
        )),
    }
}

/// The camera and frame options of a `LensmapFrameOptions`, validated.
pub(crate) fn frame_settings(
    options: &LensmapFrameOptions,
) -> Result<(Camera, FrameOptions), Failure> {
    let camera = Camera {
        position: glam::Vec3::from_array(options.position),
        look_at: glam::Vec3::from_array(options.look_at),
        up: glam::Vec3::from_array(options.up),
        vfov_radians: options.vfov_degrees.to_radians(),
        width: options.width,
        height: options.height,
        supersampling: options.supersampling,
    };
    lensmap::trace::image::validate_camera(&camera).map_err(|error| {
        Failure::new(
            LensmapResult::InvalidArgument,
            format!(
                "options (position, look_at, up, vfov_degrees, width, height, supersampling): {error}"
            ),
        )
    })?;
    let t = if options.t == 0.0 {
        lensmap::hybrid::tessellate::DEFAULT_T
    } else {
        options.t
    };
    let compositing = compositing(options.variant, options.blend)?;
    let viewpoint_blending = match options.viewpoint_blending {
        LENSMAP_VIEWPOINTS_VIEW_SPACE => ViewpointBlending::ViewSpace,
        LENSMAP_VIEWPOINTS_TWO_NEAREST => ViewpointBlending::TwoNearest,
        LENSMAP_VIEWPOINTS_NEAREST => ViewpointBlending::Nearest,
        other => {
            return Err(Failure::new(
                LensmapResult::InvalidArgument,
                format!(
                    "options->viewpoint_blending is {other}; give LENSMAP_VIEWPOINTS_VIEW_SPACE (0), LENSMAP_VIEWPOINTS_TWO_NEAREST (1) or LENSMAP_VIEWPOINTS_NEAREST (2)"
                ),
            ));
        }
    };
    let fresnel = match options.fresnel_texels {
        0 => FresnelModel::Exact,
        texels if (MIN_TEXELS..=MAX_TEXELS).contains(&texels) => FresnelModel::Table { texels },
        other => {
            return Err(Failure::new(
                LensmapResult::InvalidArgument,
                format!(
                    "options->fresnel_texels is {other}; give 0 (exact Fresnel) or a table of {MIN_TEXELS} to {MAX_TEXELS} texels, e.g. 64"
                ),
            ));
        }
    };
    let tracer = match options.tracer {
        LENSMAP_TRACER_CPU => VertexTracer::Cpu,
        LENSMAP_TRACER_GPU => VertexTracer::Gpu,
        LENSMAP_TRACER_AUTO => VertexTracer::Auto,
        other => {
            return Err(Failure::new(
                LensmapResult::InvalidArgument,
                format!(
                    "options->tracer is {other}; give LENSMAP_TRACER_CPU (0), LENSMAP_TRACER_GPU (1) or LENSMAP_TRACER_AUTO (2)"
                ),
            ));
        }
    };
    let frame_options = FrameOptions {
        hybrid: HybridOptions {
            viewpoint_blending,
            fresnel,
            tracer,
            ..HybridOptions::with_t(t)
        },
        compositing,
        format: format(options.format, "options->format")?,
    };
    frame_options.validate().map_err(|error| {
        Failure::new(LensmapResult::InvalidArgument, error.worded(&StructFields))
    })?;
    Ok((camera, frame_options))
}

/// `count` semaphores and their values (NULL values: zeros) from a host's arrays.
///
/// # Safety
/// Non-null arrays must be readable for `count` elements.
pub(crate) unsafe fn semaphores(
    count: u32,
    handles: *const VkSemaphore,
    values: *const u64,
    name: &str,
) -> Result<Vec<(vk::Semaphore, u64)>, Failure> {
    if count == 0 {
        return Ok(Vec::new());
    }
    if handles.is_null() {
        return Err(null(&format!(
            "image->{name}_semaphores (with {name}_count {count})"
        )));
    }
    use vk::Handle as _;
    (0..count as usize)
        .map(|i| {
            // SAFETY: readable for `count` elements by the caller's promise.
            let handle = unsafe { *handles.add(i) };
            if handle.is_null() {
                return Err(null(&format!("image->{name}_semaphores[{i}]")));
            }
            let value = if values.is_null() {
                0
            } else {
                // SAFETY: as above.
                unsafe { *values.add(i) }
            };
            Ok((vk::Semaphore::from_raw(handle as u64), value))
        })
        .collect()
}

/// The size a caller gave its `LensmapFrameStats` (NULL: none wanted), checked: at least the
/// first two fields, at most the whole struct this library knows.
///
/// # Safety
/// A non-null `stats` must be readable for its first field.
pub(crate) unsafe fn stats_size(stats: *mut LensmapFrameStats) -> Result<Option<usize>, Failure> {
    if stats.is_null() {
        return Ok(None);
    }
    // SAFETY: non-null and readable by the caller's promise; its first field is the size.
    let size = unsafe { *(stats as *const u32) } as usize;
    if size < 8 || size > std::mem::size_of::<LensmapFrameStats>() {
        return Err(Failure::new(
            LensmapResult::StructSize,
            format!(
                "stats->struct_size is {size}; set it to sizeof(LensmapFrameStats) ({})",
                std::mem::size_of::<LensmapFrameStats>()
            ),
        ));
    }
    Ok(Some(size))
}

/// Copies the fields of `filled` that fit in the caller's `size` bytes into `stats`.
///
/// # Safety
/// `stats` must be writable for `size` ≤ `sizeof(LensmapFrameStats)` bytes.
pub(crate) unsafe fn write_stats(
    stats: *mut LensmapFrameStats,
    size: usize,
    filled: LensmapFrameStats,
) {
    let filled = LensmapFrameStats {
        struct_size: size as u32,
        ..filled
    };
    // SAFETY: the caller's promise; `size` ≤ sizeof(LensmapFrameStats), so only the fields that
    // fit are copied.
    unsafe {
        std::ptr::copy_nonoverlapping(
            &filled as *const LensmapFrameStats as *const u8,
            stats as *mut u8,
            size,
        );
    }
}

/// The paper's table of a frame: its CPU stages and counters, with the passes, the total and
/// "other" (everything but the three CPU stages).
pub(crate) fn frame_stats(
    stats: &lensmap::hybrid::HybridStats,
    passes: usize,
    total_ms: f64,
    other_ms: f64,
) -> LensmapFrameStats {
    let counters = stats.counters;
    LensmapFrameStats {
        struct_size: 0,
        passes: passes as u32,
        reused: u32::from(stats.reused),
        trace_ms: stats.trace_ms,
        texgen_ms: stats.texgen_ms,
        tessellation_ms: stats.tessellation_ms,
        other_ms,
        total_ms,
        rays: counters.all_rays(),
        triangle_tests: counters.triangle_tests,
        lens_triangles: stats.triangles_out as u64,
        vertices_traced: stats.vertices_traced as u64,
        viewpoints: stats.viewpoints_blended as u32,
        outside_view_space: u32::from(stats.outside_view_space),
        traced_on_gpu: u32::from(stats.traced_on_gpu),
        glossy_maps: stats.glossy_maps as u32,
    }
}

/// The f32 degrees that [`frame_settings`] turns back into exactly `radians`: `to_degrees` and
/// `to_radians` are not inverses in f32, and a camera one ulp off is another frame. The nearest
/// value within a few ulps of `radians.to_degrees()` that converts back exactly.
pub(crate) fn degrees_of(radians: f32) -> f32 {
    let first = radians.to_degrees();
    // Fields of view are positive and finite: their neighbours are one bit pattern apart.
    let bits = first.to_bits();
    (0..=8u32)
        .flat_map(|step| [bits.saturating_add(step), bits.saturating_sub(step)])
        .map(f32::from_bits)
        .find(|d| d.to_radians() == radians)
        .unwrap_or(first)
}
