//! The exported functions, in the order `lensmap.h` lists them (cbindgen writes them in the
//! order it reads them): the ABI version and last error; contexts (lensmap's own device, or the
//! host's); scenes; rendering into memory or into a host's image; a scene's default frame
//! options; and the compositor's plan as text. Each runs inside the panic boundary.

use std::ffi::c_char;

use lensmap::gpu::{Gpu, GpuOptions, HostDevice, HostFeatures, vk};
use lensmap::layers::projected::{DEFAULT_EM_SIZE, ProjectedOptions};
use lensmap::lightmap::{DEFAULT_MAX_TEXELS, LightMapOptions};
use lensmap::options::Worded;
use lensmap::render::{
    FrameShape, MAX_VIEWPOINTS, SinglePassLimits,
    plan::{Output, PlanOptions, frame_graph},
};
use lensmap::runner::{EmSource, FrameRunner, LoadOptions, load_hybrid_scene};
use lensmap::scene::Scene;

use crate::failure::{Failure, LAST_ERROR, StructFields, boundary, null};
use crate::handles::{
    Kind, LensmapContext, LensmapScene, free_handle, hand_out_context, lock_context, register,
    scene_ref,
};
use crate::structs::{
    FRAME_OPTIONS_OLDER, PLAN_OPTIONS_ABI2, SCENE_OPTIONS_ABI3, SCENE_OPTIONS_ABI6, compositing,
    degrees_of, format, frame_settings, frame_stats, read_struct, read_text, read_versioned,
    semaphores, stats_size, struct_size_failure, write_stats,
};
use crate::types::*;

/// The ABI version of the loaded library ([`LENSMAP_ABI_VERSION`] of its header).
#[unsafe(no_mangle)]
pub extern "C" fn lensmap_abi_version() -> u32 {
    LENSMAP_ABI_VERSION
}

/// The message of the last failure on the calling thread, NUL-terminated UTF-8; an empty string
/// before any failure. Successful calls leave it as it is. The pointer stays valid until the
/// next failing call on this thread; copy the text to keep it.
#[unsafe(no_mangle)]
pub extern "C" fn lensmap_last_error() -> *const c_char {
    LAST_ERROR.with(|last| last.borrow().as_ptr())
}

/// Creates a context on lensmap's own Vulkan instance and device (headless). `options` may be
/// NULL for the defaults (best device, no validation). On success `*out` is a new context to
/// free with [`lensmap_context_free`].
///
/// # Safety
/// `options` must be NULL or point to a `LensmapContextOptions`; `out` must be writable.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn lensmap_context_new(
    options: *const LensmapContextOptions,
    out: *mut *mut LensmapContext,
) -> LensmapResult {
    boundary(|| {
        if out.is_null() {
            return Err(null("out"));
        }
        let mut gpu_options = GpuOptions::default();
        if !options.is_null() {
            // SAFETY: the caller's promise.
            let options = unsafe { read_struct(options, "options") }?;
            gpu_options.validation = options.validation != 0;
            // SAFETY: the caller's promise.
            if let Some(name) = unsafe { read_text(options.device_name, "options->device_name") }? {
                gpu_options.device = lensmap::gpu::DeviceChoice::NameContains(name);
            }
        }
        let runner = FrameRunner::new(Gpu::new(&gpu_options)?)?;
        // SAFETY: checked non-null; writable by the caller's promise.
        unsafe { hand_out_context(runner, false, out) };
        Ok(())
    })
}

/// Creates a context on the host's Vulkan instance, device and queue: lensmap makes its own
/// allocator, command pool and resources on the host's device and destroys only those. The host
/// must have enabled `LENSMAP_FEATURES_REQUIRED` and say so in `enabled_features`; a missing
/// feature returns `LENSMAP_RESULT_DEVICE` naming it.
///
/// # Safety
/// `host` must point to a `LensmapHostDevice` whose handles are valid and belong together;
/// `out` must be writable.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn lensmap_context_new_on_host(
    host: *const LensmapHostDevice,
    out: *mut *mut LensmapContext,
) -> LensmapResult {
    boundary(|| {
        if out.is_null() {
            return Err(null("out"));
        }
        // SAFETY: the caller's promise.
        let host = unsafe { read_struct(host, "host") }?;
        let Some(get_instance_proc_addr) = host.get_instance_proc_addr else {
            return Err(null("host->get_instance_proc_addr"));
        };
        for (pointer, name) in [
            (host.instance, "host->instance"),
            (host.physical_device, "host->physical_device"),
            (host.device, "host->device"),
            (host.queue, "host->queue"),
        ] {
            if pointer.is_null() {
                return Err(null(name));
            }
        }
        let bits = host.enabled_features;
        let enabled = HostFeatures {
            dynamic_rendering: bits & LENSMAP_FEATURE_DYNAMIC_RENDERING != 0,
            synchronization2: bits & LENSMAP_FEATURE_SYNCHRONIZATION2 != 0,
            timeline_semaphore: bits & LENSMAP_FEATURE_TIMELINE_SEMAPHORE != 0,
            image_cube_array: bits & LENSMAP_FEATURE_IMAGE_CUBE_ARRAY != 0,
        };
        use vk::Handle as _;
        let lent = HostDevice {
            // SAFETY: the C and Rust signatures of vkGetInstanceProcAddr are the same ABI.
            get_instance_proc_addr: unsafe {
                std::mem::transmute::<
                    unsafe extern "system" fn(
                        VkInstance,
                        *const c_char,
                    )
                        -> Option<unsafe extern "system" fn()>,
                    vk::PFN_vkGetInstanceProcAddr,
                >(get_instance_proc_addr)
            },
            instance: vk::Instance::from_raw(host.instance as u64),
            physical_device: vk::PhysicalDevice::from_raw(host.physical_device as u64),
            device: vk::Device::from_raw(host.device as u64),
            queue_family: host.queue_family,
            queue: vk::Queue::from_raw(host.queue as u64),
            enabled,
        };
        // SAFETY: the caller promises valid handles that belong together.
        let gpu = unsafe { Gpu::from_host(&lent) }?;
        let runner = FrameRunner::new(gpu)?;
        // SAFETY: checked non-null; writable by the caller's promise.
        unsafe { hand_out_context(runner, true, out) };
        Ok(())
    })
}

/// Frees a context (waiting for its device to be idle). NULL is a no-op; a pointer that is not
/// a live context (a second free) returns `LENSMAP_RESULT_INVALID_HANDLE` and frees nothing.
///
/// # Safety
/// No other thread may be using `context`.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn lensmap_context_free(context: *mut LensmapContext) -> LensmapResult {
    boundary(|| {
        // SAFETY: a context is only ever registered as Kind::Context.
        unsafe {
            free_handle(
                context,
                Kind::Context,
                "lensmap_context_free: not a live LensmapContext",
            )
        }
    })
}

/// Writes into `*count` the number of Vulkan validation messages the context has seen (0 when
/// validation is off, or on a host's device, whose messages go to the host's messenger).
///
/// # Safety
/// `context` must be a handle from this library (or NULL); `count` must be writable.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn lensmap_context_validation_messages(
    context: *mut LensmapContext,
    count: *mut u64,
) -> LensmapResult {
    boundary(|| {
        if count.is_null() {
            return Err(null("count"));
        }
        // SAFETY: the caller's promise.
        let runner = unsafe { lock_context(context) }?;
        let messages = runner.gpu().validation_report().messages.len() as u64;
        // SAFETY: checked non-null; writable by the caller's promise.
        unsafe { *count = messages };
        Ok(())
    })
}

/// Loads a scene and its layered EMs (a bake directory, or projected from the scene) and its
/// light maps. On success `*out` is a new scene to free with [`lensmap_scene_free`].
///
/// # Safety
/// `options` must point to a `LensmapSceneOptions` whose strings are NUL-terminated or NULL;
/// `out` must be writable.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn lensmap_scene_load(
    options: *const LensmapSceneOptions,
    out: *mut *mut LensmapScene,
) -> LensmapResult {
    boundary(|| {
        if out.is_null() {
            return Err(null("out"));
        }
        // SAFETY: the caller's promise (LensmapSceneOptions is integers and pointers).
        let options = unsafe {
            read_versioned(
                options,
                "options",
                &[SCENE_OPTIONS_ABI3, SCENE_OPTIONS_ABI6],
            )
        }?;
        // SAFETY: the caller's promise.
        let Some(name) = (unsafe { read_text(options.scene, "options->scene") })? else {
            return Err(null("options->scene"));
        };
        // SAFETY: the caller's promise.
        let bake = unsafe { read_text(options.bake_dir, "options->bake_dir") }?;
        let scene = Scene::load_named(&name)?;
        let ems = match bake {
            Some(dir) if options.accept_any_bake != 0 => EmSource::AnyBake(dir.into()),
            Some(dir) => EmSource::Bake(dir.into()),
            None => {
                let size = if options.em_size == 0 {
                    DEFAULT_EM_SIZE
                } else {
                    options.em_size
                };
                let projected = ProjectedOptions::with_size(size);
                projected.validate().map_err(|error| {
                    Failure::new(LensmapResult::InvalidArgument, error.worded(&StructFields))
                })?;
                EmSource::Projected(projected)
            }
        };
        let light_maps = LightMapOptions {
            max_texels: match options.light_map_max_texels {
                0 => DEFAULT_MAX_TEXELS,
                texels => texels,
            },
            ..LightMapOptions::default()
        };
        // SAFETY: the caller's promise.
        let radiance = unsafe { read_text(options.radiance_dir, "options->radiance_dir") }?;
        let (mut hybrid, _) = load_hybrid_scene(scene, &LoadOptions { ems, light_maps })?;
        if let Some(dir) = radiance {
            hybrid
                .use_radiance_bake(
                    std::path::Path::new(&dir),
                    lensmap::rsibr::Reconstruction::Warped,
                )
                .map_err(|error| {
                    Failure::new(
                        LensmapResult::Bake,
                        format!("options->radiance_dir: {error}"),
                    )
                })?;
        }
        let handle = register(
            Box::new(LensmapScene {
                hybrid: Box::new(hybrid),
            }),
            Kind::Scene,
        );
        // SAFETY: checked non-null; writable by the caller's promise.
        unsafe { *out = handle };
        Ok(())
    })
}

/// Frees a scene. NULL is a no-op; a pointer that is not a live scene (a second free) returns
/// `LENSMAP_RESULT_INVALID_HANDLE` and frees nothing.
///
/// # Safety
/// No other thread may be using `scene`.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn lensmap_scene_free(scene: *mut LensmapScene) -> LensmapResult {
    boundary(|| {
        // SAFETY: a scene is only ever registered as Kind::Scene.
        unsafe {
            free_handle(
                scene,
                Kind::Scene,
                "lensmap_scene_free: not a live LensmapScene",
            )
        }
    })
}

/// Renders one hybrid frame of `scene` and reads it back into `rgba`: `width × height` pixels,
/// rows top to bottom, 4 floats each (linear, premultiplied RGBA), `rgba_floats` ≥
/// `4 × width × height`. `stats` may be NULL; else set its `struct_size` and lensmap fills it.
///
/// # Safety
/// `context` and `scene` must be handles from this library (or NULL); `options` must point to a
/// `LensmapFrameOptions` readable for its `struct_size` bytes; `rgba` must be writable for `rgba_floats` floats; `stats` NULL or
/// writable.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn lensmap_render_to_memory(
    context: *mut LensmapContext,
    scene: *const LensmapScene,
    options: *const LensmapFrameOptions,
    rgba: *mut f32,
    rgba_floats: usize,
    stats: *mut LensmapFrameStats,
) -> LensmapResult {
    boundary(|| {
        // SAFETY: the caller's promise.
        let options = unsafe { read_versioned(options, "options", &FRAME_OPTIONS_OLDER) }?;
        if rgba.is_null() {
            return Err(null("rgba"));
        }
        // SAFETY: the caller's promise.
        let stats_size = unsafe { stats_size(stats) }?;
        let (camera, frame_options) = frame_settings(&options)?;
        let needed = 4 * camera.width as usize * camera.height as usize;
        if rgba_floats < needed {
            return Err(Failure::new(
                LensmapResult::BufferTooSmall,
                format!(
                    "rgba holds {rgba_floats} floats; a {}×{} frame needs {needed} (4 per pixel)",
                    camera.width, camera.height
                ),
            ));
        }
        // SAFETY: the caller's promise for both handles.
        let scene = unsafe { scene_ref(scene) }?;
        // SAFETY: as above.
        let mut runner = unsafe { lock_context(context) }?;
        runner.check_framebuffer(&camera, frame_options.format)?;
        let frame = runner.frame(&scene.hybrid, &camera, &frame_options)?;
        // SAFETY: writable for rgba_floats ≥ needed floats (the caller's promise, checked).
        let out = unsafe { std::slice::from_raw_parts_mut(rgba, needed) };
        for (chunk, pixel) in out.chunks_exact_mut(4).zip(&frame.image.pixels) {
            chunk.copy_from_slice(pixel);
        }
        if let Some(size) = stats_size {
            let filled = frame_stats(
                &frame.stats,
                frame.render.passes,
                frame.total_ms,
                frame.other_ms(),
            );
            // SAFETY: the caller set struct_size to what it can hold (checked above).
            unsafe { write_stats(stats, size, filled) };
        }
        Ok(())
    })
}

/// Renders one hybrid frame of `scene` into the host's image `image` and returns once it is
/// submitted on the host's queue: no readback, no wait. lensmap renders its framebuffer as
/// always and box-filters it (supersampling) into the image on the GPU, with the barriers from
/// `current_layout` to `final_layout`; the submission waits for `image`'s wait semaphores and
/// signals its signal semaphores when done, which is how the host learns the image is ready (or
/// from later work on the same queue). The context must have been made by
/// [`lensmap_context_new_on_host`] on the image's device. `stats` may be NULL; its GPU part is
/// the host's to time (`other_ms` covers upload, recording and submission).
///
/// On failure nothing was submitted: the wait semaphores were not waited on (a binary one stays
/// signalled) and the signal semaphores will not be signalled by this call. The call may wait
/// on the CPU for lensmap's own earlier work (a still camera for the previous frame, a moving
/// one for the frame two calls back, which reuse their buffers), never for this call's wait
/// semaphores; so a host must not make an earlier frame's wait semaphores depend on a later
/// lensmap call.
///
/// # Safety
/// `context` and `scene` must be handles from this library (or NULL); `options` must point to a
/// `LensmapFrameOptions` readable for its `struct_size` bytes and `image` to a `LensmapHostImage` whose handles are live objects of
/// the context's device, kept alive until the frame's signal semaphores are signalled; `stats`
/// NULL or writable.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn lensmap_render_to_image(
    context: *mut LensmapContext,
    scene: *const LensmapScene,
    options: *const LensmapFrameOptions,
    image: *const LensmapHostImage,
    stats: *mut LensmapFrameStats,
) -> LensmapResult {
    boundary(|| {
        // SAFETY: the caller's promise.
        let options = unsafe { read_versioned(options, "options", &FRAME_OPTIONS_OLDER) }?;
        // SAFETY: the caller's promise.
        let lent = unsafe { read_struct(image, "image") }?;
        // SAFETY: the caller's promise.
        let stats_size = unsafe { stats_size(stats) }?;
        let (camera, frame_options) = frame_settings(&options)?;
        let format = vk::Format::from_raw(lent.format);
        if !lensmap::render::HostImage::supports(format) {
            return Err(Failure::new(
                LensmapResult::UnsupportedFormat,
                format!(
                    "image->format is {format:?} ({}); lensmap renders into {}",
                    lent.format,
                    lensmap::render::HostImage::FORMATS
                        .map(|f| format!("VK_FORMAT_{f:?}"))
                        .join(", ")
                ),
            ));
        }
        for (pointer, name) in [(lent.image, "image->image"), (lent.view, "image->view")] {
            if pointer.is_null() {
                return Err(null(name));
            }
        }
        use vk::Handle as _;
        let host = lensmap::render::HostImage {
            image: vk::Image::from_raw(lent.image as u64),
            view: vk::ImageView::from_raw(lent.view as u64),
            mip_level: lent.mip_level,
            array_layer: lent.array_layer,
            format,
            width: camera.width,
            height: camera.height,
            current_layout: vk::ImageLayout::from_raw(lent.current_layout),
            final_layout: vk::ImageLayout::from_raw(lent.final_layout),
            // SAFETY: the caller's promise for both arrays.
            wait: unsafe {
                semaphores(
                    lent.wait_count,
                    lent.wait_semaphores,
                    lent.wait_values,
                    "wait",
                )
            }?,
            // SAFETY: as above.
            signal: unsafe {
                semaphores(
                    lent.signal_count,
                    lent.signal_semaphores,
                    lent.signal_values,
                    "signal",
                )
            }?,
        };
        // SAFETY: the caller's promise for both handles.
        let scene = unsafe { scene_ref(scene) }?;
        // SAFETY: as above.
        let mut runner = unsafe { lock_context(context) }?;
        // SAFETY: live (lock_context checked it) until freed, which the caller does not do now.
        if !unsafe { &*context }.on_host {
            return Err(Failure::new(
                LensmapResult::InvalidArgument,
                "context was made by lensmap_context_new on lensmap's own device: rendering into a host's image needs a context made by lensmap_context_new_on_host on the image's device",
            ));
        }
        runner.check_framebuffer(&camera, frame_options.format)?;
        let frame = runner.frame_into(&scene.hybrid, &camera, &frame_options, &host)?;
        if let Some(size) = stats_size {
            let counted = frame.counted_stats();
            let filled = frame_stats(&counted, frame.passes, frame.total_ms, frame.other_ms());
            // SAFETY: the caller set struct_size to what it can hold (checked above).
            unsafe { write_stats(stats, size, filled) };
        }
        Ok(())
    })
}

/// Fills `options` (whose `struct_size` the caller set; the other fields are not read) with what
/// `lensmap render --scene`
/// renders by default: the scene's camera (position, look-at, up, vertical field of view,
/// width, height, supersampling), t = 3, the single-pass compositor (front-to-back) and an
/// RGBA16F framebuffer. Change what differs, then render. An ABI 2 caller's smaller struct is
/// filled up to its own size.
///
/// # Safety
/// `scene` must be a handle from this library (or NULL); `options` must point to a
/// `LensmapFrameOptions` writable for its `struct_size` bytes.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn lensmap_scene_frame_options(
    scene: *const LensmapScene,
    options: *mut LensmapFrameOptions,
) -> LensmapResult {
    boundary(|| {
        if options.is_null() {
            return Err(null("options"));
        }
        // SAFETY: non-null and points to a LensmapFrameOptions (the caller's promise); only its
        // first field, the size, is read: the rest may be unset.
        let size = unsafe { *(options as *const u32) } as usize;
        let current = std::mem::size_of::<LensmapFrameOptions>();
        if size != current && !FRAME_OPTIONS_OLDER.contains(&size) {
            return Err(struct_size_failure(
                "options",
                size,
                current,
                &FRAME_OPTIONS_OLDER,
            ));
        }
        // SAFETY: the caller's promise.
        let scene = unsafe { scene_ref(scene) }?;
        let camera = scene.hybrid.scene().camera;
        let filled = LensmapFrameOptions {
            struct_size: size as u32,
            position: camera.position.to_array(),
            look_at: camera.look_at.to_array(),
            up: camera.up.to_array(),
            vfov_degrees: degrees_of(camera.vfov_radians),
            width: camera.width,
            height: camera.height,
            supersampling: camera.supersampling,
            t: lensmap::hybrid::tessellate::DEFAULT_T,
            variant: LENSMAP_VARIANT_SINGLE_PASS,
            format: LENSMAP_FORMAT_RGBA16F,
            blend: LENSMAP_BLEND_FRONT_TO_BACK,
            viewpoint_blending: LENSMAP_VIEWPOINTS_VIEW_SPACE,
            fresnel_texels: 0,
            tracer: LENSMAP_TRACER_AUTO,
        };
        // SAFETY: writable for `size` bytes by the caller's promise (a struct of that ABI's
        // size, checked above): only those are written.
        unsafe {
            std::ptr::copy_nonoverlapping(
                &filled as *const LensmapFrameOptions as *const u8,
                options as *mut u8,
                size,
            )
        };
        Ok(())
    })
}

/// Writes the compositor's plan for a frame of this shape as text (the table `lensmap passes`
/// prints) into `buffer`, NUL-terminated, and its length without the NUL into `*length`. With
/// `buffer` NULL only `*length` is written (a size query: allocate `*length + 1` bytes). A
/// `capacity` of `*length` or less returns `LENSMAP_RESULT_BUFFER_TOO_SMALL` and writes nothing.
///
/// # Safety
/// `options` must point to a `LensmapPlanOptions` readable for its `struct_size` bytes; `buffer`
/// NULL or writable for `capacity`
/// bytes; `length` writable.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn lensmap_plan_text(
    options: *const LensmapPlanOptions,
    buffer: *mut c_char,
    capacity: usize,
    length: *mut usize,
) -> LensmapResult {
    boundary(|| {
        // SAFETY: the caller's promise.
        let options = unsafe { read_versioned(options, "options", &[PLAN_OPTIONS_ABI2]) }?;
        if length.is_null() {
            return Err(null("length"));
        }
        let most = FrameShape::MAX_EXPERIMENT_LAYERS;
        if !(1..=most).contains(&(options.layers as usize)) {
            return Err(Failure::new(
                LensmapResult::InvalidArgument,
                format!("options->layers is {}; give 1 to {most}", options.layers),
            ));
        }
        let terms: &[lensmap::trace::Term] = match options.terms {
            2 => &[
                lensmap::trace::Term::Refraction,
                lensmap::trace::Term::Reflection,
            ],
            1 => &[lensmap::trace::Term::Reflection],
            other => {
                return Err(Failure::new(
                    LensmapResult::InvalidArgument,
                    format!("options->terms is {other}; give 2 (glass) or 1 (mirror)"),
                ));
            }
        };
        if !(1..=MAX_VIEWPOINTS).contains(&(options.viewpoints as usize)) {
            return Err(Failure::new(
                LensmapResult::InvalidArgument,
                format!(
                    "options->viewpoints is {}; give 1 to {MAX_VIEWPOINTS}",
                    options.viewpoints
                ),
            ));
        }
        let shape = FrameShape::synthetic(
            640,
            480,
            options.layers as usize,
            options.viewpoints as usize,
            terms,
        );
        let plan_options = PlanOptions {
            compositing: compositing(options.variant, options.blend)?,
            format: format(options.format, "options->format")?,
            output: Output::Readback,
            single_pass: SinglePassLimits::COMPILED,
        };
        let (graph, _) = frame_graph(&shape, &plan_options)
            .map_err(|error| Failure::new(LensmapResult::InvalidArgument, error.to_string()))?;
        let plan = graph
            .compile()
            .map_err(|error| Failure::new(LensmapResult::Render, error.to_string()))?;
        let text = plan.to_string();
        if buffer.is_null() {
            // SAFETY: checked non-null; writable by the caller's promise.
            unsafe { *length = text.len() };
            return Ok(());
        }
        if capacity <= text.len() {
            return Err(Failure::new(
                LensmapResult::BufferTooSmall,
                format!(
                    "the plan is {} bytes and its NUL; the buffer holds {capacity}",
                    text.len()
                ),
            ));
        }
        // SAFETY: writable for capacity > text.len() bytes (the caller's promise, checked).
        unsafe {
            std::ptr::copy_nonoverlapping(text.as_ptr(), buffer as *mut u8, text.len());
            *buffer.add(text.len()) = 0;
            *length = text.len();
        }
        Ok(())
    })
}
