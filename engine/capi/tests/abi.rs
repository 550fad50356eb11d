//! The C ABI as a host calls it (through the exported `extern "C"` functions): a frame through
//! the ABI equals the same frame through the Rust API bit for bit, on lensmap's own device and
//! on a device the host made itself; and a misuse corpus, each case returning its documented
//! code with a message naming the problem, out-pointers untouched, no crash. Validation is on
//! and must stay silent.

use std::ffi::{CStr, CString, c_char};
use std::ptr::{null, null_mut};

use lensmap::gpu::{Gpu, GpuOptions};
use lensmap::hybrid::HybridOptions;
use lensmap::layers::projected::ProjectedOptions;
use lensmap::render::{BlendScheme, Compositing, TargetFormat};
use lensmap::runner::{EmSource, FrameOptions, FrameRunner, load_hybrid_scene};
use lensmap::scene::{Camera, Scene};
use lensmap_capi::*;

fn last_error() -> String {
    // SAFETY: lensmap_last_error returns a NUL-terminated string valid until the next failure.
    unsafe { CStr::from_ptr(lensmap_last_error()) }
        .to_string_lossy()
        .into_owned()
}

/// `code` is `expected` and the message names `what`.
#[track_caller]
fn assert_failure(code: LensmapResult, expected: LensmapResult, what: &str) {
    let message = last_error();
    assert_eq!(code, expected, "message: {message}");
    assert!(
        message.contains(what),
        "the message should name {what:?}: {message}"
    );
}

fn context_options(device: Option<&CString>) -> LensmapContextOptions {
    lensmap_tests::one_validated_test_at_a_time();
    LensmapContextOptions {
        struct_size: size_of::<LensmapContextOptions>() as u32,
        validation: 1,
        device_name: device.map_or(null(), |d| d.as_ptr()),
    }
}

fn new_context() -> *mut LensmapContext {
    let mut context = null_mut();
    // SAFETY: valid options and out-pointer.
    let code = unsafe { lensmap_context_new(&context_options(None), &mut context) };
    assert_eq!(code, LensmapResult::Ok, "{}", last_error());
    context
}

const SCENE: &CStr = c"glass-sphere";

fn scene_options(scene: &CStr, bake: Option<&CStr>) -> LensmapSceneOptions {
    LensmapSceneOptions {
        struct_size: size_of::<LensmapSceneOptions>() as u32,
        scene: scene.as_ptr(),
        bake_dir: bake.map_or(null(), CStr::as_ptr),
        em_size: 8,
        accept_any_bake: 0,
        light_map_max_texels: 0,
        radiance_dir: null(),
    }
}

fn load_scene() -> *mut LensmapScene {
    let mut scene = null_mut();
    // SAFETY: valid options and out-pointer.
    let code = unsafe { lensmap_scene_load(&scene_options(SCENE, None), &mut scene) };
    assert_eq!(code, LensmapResult::Ok, "{}", last_error());
    scene
}

/// A small frame of glass-sphere from its scene camera.
fn frame_options(format: u32) -> LensmapFrameOptions {
    let camera = Scene::builtin("glass-sphere")
        .expect("built in")
        .expect("loads")
        .camera;
    LensmapFrameOptions {
        struct_size: size_of::<LensmapFrameOptions>() as u32,
        position: camera.position.to_array(),
        look_at: camera.look_at.to_array(),
        up: camera.up.to_array(),
        vfov_degrees: camera.vfov_radians.to_degrees(),
        width: 40,
        height: 30,
        supersampling: 2,
        t: 3.0,
        variant: LENSMAP_VARIANT_SINGLE_PASS,
        format,
        blend: LENSMAP_BLEND_FRONT_TO_BACK,
        viewpoint_blending: LENSMAP_VIEWPOINTS_VIEW_SPACE,
        fresnel_texels: 0,
        tracer: LENSMAP_TRACER_CPU,
    }
}

fn render(
    context: *mut LensmapContext,
    scene: *const LensmapScene,
    options: &LensmapFrameOptions,
    pixels: &mut [f32],
) -> LensmapResult {
    render_with_stats(context, scene, options, pixels).0
}

/// [`render`] with the frame's statistics, checked when it rendered.
fn render_with_stats(
    context: *mut LensmapContext,
    scene: *const LensmapScene,
    options: &LensmapFrameOptions,
    pixels: &mut [f32],
) -> (LensmapResult, LensmapFrameStats) {
    let mut stats = LensmapFrameStats {
        struct_size: size_of::<LensmapFrameStats>() as u32,
        ..LensmapFrameStats::default()
    };
    // SAFETY: `pixels` is writable for its length; the rest are valid or deliberately bad
    // handles, which the ABI refuses without dereferencing.
    let code = unsafe {
        lensmap_render_to_memory(
            context,
            scene,
            options,
            pixels.as_mut_ptr(),
            pixels.len(),
            &mut stats,
        )
    };
    if code == LensmapResult::Ok {
        assert!(stats.passes >= 2, "{stats:?}");
        // A still camera (the scene's previous frame) traces nothing.
        assert!(
            (stats.rays > 0 && stats.triangle_tests > 0) || stats.reused == 1,
            "{stats:?}"
        );
        assert!(
            stats.total_ms > 0.0 && stats.total_ms.is_finite(),
            "{stats:?}"
        );
        assert!((1..=3).contains(&stats.viewpoints), "{stats:?}");
        assert!(stats.outside_view_space <= 1, "{stats:?}");
        assert!(stats.traced_on_gpu <= 1, "{stats:?}");
    }
    (code, stats)
}

fn assert_no_validation_messages(context: *mut LensmapContext) {
    let mut count = u64::MAX;
    // SAFETY: a live context and a writable count.
    let code = unsafe { lensmap_context_validation_messages(context, &mut count) };
    assert_eq!(code, LensmapResult::Ok, "{}", last_error());
    assert_eq!(count, 0, "validation messages (see stderr)");
}

/// The Rust API's frame for the same scene, camera and options.
/// lensmap's Rust API on its own device, validation on: what ABI frames are compared with.
fn validated_runner() -> FrameRunner {
    lensmap_tests::one_validated_test_at_a_time();
    let gpu = Gpu::new(&GpuOptions {
        validation: true,
        ..GpuOptions::default()
    })
    .expect("a device");
    lensmap_tests::name_the_driver_on_failure(gpu.device_id());
    FrameRunner::new(gpu).expect("a runner")
}

fn rust_frame(runner: &mut FrameRunner, options: &LensmapFrameOptions) -> Vec<f32> {
    let scene = Scene::load_named("glass-sphere").expect("loads");
    let (hybrid, _) = load_hybrid_scene(
        scene,
        &EmSource::Projected(ProjectedOptions::with_size(8)).into(),
    )
    .expect("projected");
    let camera = Camera {
        position: options.position.into(),
        look_at: options.look_at.into(),
        up: options.up.into(),
        vfov_radians: options.vfov_degrees.to_radians(),
        width: options.width,
        height: options.height,
        supersampling: options.supersampling,
    };
    let frame = runner
        .frame(
            &hybrid,
            &camera,
            &FrameOptions {
                hybrid: HybridOptions::with_t(options.t),
                compositing: match options.variant {
                    LENSMAP_VARIANT_MULTIPASS => {
                        Compositing::Multipass(BlendScheme::ALL[options.blend as usize])
                    }
                    _ => Compositing::SinglePass,
                },
                format: TargetFormat::Rgba32f,
            },
        )
        .expect("renders");
    frame.image.pixels.iter().flatten().copied().collect()
}

#[test]
fn a_frame_through_the_abi_equals_the_rust_apis() {
    let context = new_context();
    let scene = load_scene();
    let options = frame_options(LENSMAP_FORMAT_RGBA32F);
    let mut pixels = vec![f32::NAN; 4 * 40 * 30];
    assert_eq!(
        render(context, scene, &options, &mut pixels),
        LensmapResult::Ok
    );
    assert!(pixels.iter().all(|p| p.is_finite()));
    assert!(pixels.iter().any(|&p| p > 0.0), "an image, not a blank");
    let mut runner = validated_runner();
    let expected = rust_frame(&mut runner, &options);
    assert_eq!(pixels, expected, "bit-identical to the Rust API's frame");
    assert!(runner.gpu().validation_report().messages.is_empty());
    assert_no_validation_messages(context);
    // SAFETY: live handles, freed once.
    unsafe {
        assert_eq!(lensmap_scene_free(scene), LensmapResult::Ok);
        assert_eq!(lensmap_context_free(context), LensmapResult::Ok);
    }
}

/// ABI 4's viewpoint blending: every value renders (the scene's projected EMs are shared by its
/// samples, so all three give the same frame), a value past the three is refused naming the
/// field, and an ABI 3 caller's struct (no such field) renders with the view space's rule.
#[test]
fn viewpoint_blending_through_the_abi_and_abi_3_structs() {
    let context = new_context();
    let scene = load_scene();
    let mut frames = Vec::new();
    for blending in [
        LENSMAP_VIEWPOINTS_VIEW_SPACE,
        LENSMAP_VIEWPOINTS_TWO_NEAREST,
        LENSMAP_VIEWPOINTS_NEAREST,
    ] {
        let mut options = frame_options(LENSMAP_FORMAT_RGBA32F);
        options.viewpoint_blending = blending;
        let mut pixels = vec![f32::NAN; 4 * 40 * 30];
        assert_eq!(
            render(context, scene, &options, &mut pixels),
            LensmapResult::Ok,
            "{}",
            last_error()
        );
        frames.push(pixels);
    }
    assert!(frames.iter().all(|f| *f == frames[0]));
    let mut bad = frame_options(LENSMAP_FORMAT_RGBA32F);
    bad.viewpoint_blending = 3;
    let mut pixels = vec![f32::NAN; 4 * 40 * 30];
    assert_eq!(
        render(context, scene, &bad, &mut pixels),
        LensmapResult::InvalidArgument
    );
    let error = last_error();
    assert!(
        error.contains("options->viewpoint_blending is 3") && !error.contains('\n'),
        "{error}"
    );
    // An ABI 3 struct: 72 bytes, ending before `viewpoint_blending` (not read).
    let mut old = frame_options(LENSMAP_FORMAT_RGBA32F);
    old.viewpoint_blending = 0xdead;
    old.struct_size = 72;
    let mut pixels = vec![f32::NAN; 4 * 40 * 30];
    assert_eq!(render(context, scene, &old, &mut pixels), LensmapResult::Ok);
    assert_eq!(
        pixels, frames[0],
        "an ABI 3 struct blends by the view space's rule"
    );
    // Neither 72 nor 68 nor the current size: refused, naming every size it knows.
    old.struct_size = 70;
    assert_eq!(
        render(context, scene, &old, &mut pixels),
        LensmapResult::StructSize
    );
    let error = last_error();
    assert!(error.contains("68 or 72"), "{error}");
    assert_no_validation_messages(context);
    // SAFETY: handles from this library, freed once.
    unsafe {
        lensmap_scene_free(scene);
        lensmap_context_free(context);
    }
}

/// ABI 5's Fresnel table: a table renders glass-sphere close to, but not as, exact Fresnel
/// (Schlick differs from exact dielectric Fresnel by a few hundredths of reflectance), a size
/// out of range is refused naming the field, and an ABI 4 caller's struct (no such field)
/// renders with exact Fresnel.
#[test]
fn fresnel_table_through_the_abi_and_abi_4_structs() {
    let context = new_context();
    let scene = load_scene();
    let mut frames = Vec::new();
    for texels in [0, 64] {
        let mut options = frame_options(LENSMAP_FORMAT_RGBA32F);
        options.fresnel_texels = texels;
        let mut pixels = vec![f32::NAN; 4 * 40 * 30];
        assert_eq!(
            render(context, scene, &options, &mut pixels),
            LensmapResult::Ok,
            "{}",
            last_error()
        );
        frames.push(pixels);
    }
    let largest = frames[0]
        .iter()
        .zip(&frames[1])
        .map(|(a, b)| (a - b).abs())
        .fold(0.0f32, f32::max);
    assert!(largest > 0.0, "the table changed nothing");
    assert!(largest < 0.5, "the table moved a channel by {largest}");
    for texels in [1, 4097] {
        let mut bad = frame_options(LENSMAP_FORMAT_RGBA32F);
        bad.fresnel_texels = texels;
        let mut pixels = vec![f32::NAN; 4 * 40 * 30];
        assert_eq!(
            render(context, scene, &bad, &mut pixels),
            LensmapResult::InvalidArgument
        );
        let error = last_error();
        assert!(
            error.contains(&format!("options->fresnel_texels is {texels}"))
                && error.contains("2 to 4096")
                && !error.contains('\n'),
            "{error}"
        );
    }
    // An ABI 4 struct: 76 bytes, ending before `fresnel_texels` (not read).
    let mut old = frame_options(LENSMAP_FORMAT_RGBA32F);
    old.fresnel_texels = 0xdead;
    old.struct_size = 76;
    let mut pixels = vec![f32::NAN; 4 * 40 * 30];
    assert_eq!(render(context, scene, &old, &mut pixels), LensmapResult::Ok);
    assert_eq!(
        pixels, frames[0],
        "an ABI 4 struct evaluates Fresnel exactly"
    );
    assert_no_validation_messages(context);
    // SAFETY: handles from this library, freed once.
    unsafe {
        lensmap_scene_free(scene);
        lensmap_context_free(context);
    }
}

/// ABI 6's tracer: the GPU traces the lens vertices (the stats say where) and its frame agrees
/// with the CPU-traced one but for the few vertices whose f32 paths part from f64; a value out
/// of range is refused naming the field; an ABI 5 caller's struct (no such field) traces on the
/// CPU.
#[test]
fn tracer_through_the_abi_and_abi_5_structs() {
    let context = new_context();
    let scene = load_scene();
    let frame = |options: &LensmapFrameOptions| {
        let mut pixels = vec![f32::NAN; 4 * 40 * 30];
        let (code, stats) = render_with_stats(context, scene, options, &mut pixels);
        (code, pixels, stats)
    };
    let on = |tracer| {
        let mut options = frame_options(LENSMAP_FORMAT_RGBA32F);
        options.tracer = tracer;
        let (code, pixels, stats) = frame(&options);
        assert_eq!(code, LensmapResult::Ok, "{}", last_error());
        // The same camera with the other tracer is another frame, not the previous one again.
        assert_eq!(stats.reused, 0, "{stats:?}");
        (pixels, stats)
    };
    let (cpu, cpu_stats) = on(LENSMAP_TRACER_CPU);
    let (gpu, gpu_stats) = on(LENSMAP_TRACER_GPU);
    assert_eq!((cpu_stats.traced_on_gpu, gpu_stats.traced_on_gpu), (0, 1));
    assert!(
        gpu_stats.rays > 0 && gpu_stats.vertices_traced > 0,
        "{gpu_stats:?}"
    );
    let mean = |p: &[f32]| p.iter().map(|v| f64::from(v.abs())).sum::<f64>() / p.len() as f64;
    let difference: Vec<f32> = cpu.iter().zip(&gpu).map(|(a, b)| a - b).collect();
    eprintln!(
        "CPU-traced frame: mean {:.4}; GPU-traced: mean {:.4}, mean |difference| {:.5}",
        mean(&cpu),
        mean(&gpu),
        mean(&difference)
    );
    assert!(gpu.iter().all(|v| v.is_finite()));
    assert!(
        mean(&difference) < 0.01 * mean(&cpu),
        "the GPU-traced frame differs from the CPU-traced one by {} on average",
        mean(&difference)
    );
    let mut bad = frame_options(LENSMAP_FORMAT_RGBA32F);
    bad.tracer = 3;
    let (code, _, _) = frame(&bad);
    assert_eq!(code, LensmapResult::InvalidArgument);
    let error = last_error();
    assert!(
        error.contains("options->tracer is 3") && !error.contains('\n'),
        "{error}"
    );
    // An ABI 5 struct: 80 bytes, ending before `tracer` (not read).
    let mut old = frame_options(LENSMAP_FORMAT_RGBA32F);
    old.tracer = 0xdead;
    old.struct_size = 80;
    old.position[1] += 0.01;
    let (code, _, stats) = frame(&old);
    assert_eq!(code, LensmapResult::Ok, "{}", last_error());
    assert_eq!(stats.traced_on_gpu, 0, "an ABI 5 struct traces on the CPU");
    assert_no_validation_messages(context);
    // SAFETY: handles from this library, freed once.
    unsafe {
        lensmap_scene_free(scene);
        lensmap_context_free(context);
    }
}

/// ABI 3's blend field: each scheme of the multipass compositor through the ABI is bit-identical
/// to the Rust API's frame with the same scheme; the schemes agree within 1e-5; and an ABI 2
/// caller's smaller struct (no blend field) still renders, as front-to-back.
#[test]
fn blending_schemes_through_the_abi_equal_the_rust_apis_and_abi_2_structs_still_work() {
    let context = new_context();
    let scene = load_scene();
    let mut runner = validated_runner();
    let mut frames = Vec::new();
    for blend in [
        LENSMAP_BLEND_FRONT_TO_BACK,
        LENSMAP_BLEND_BACK_TO_FRONT,
        LENSMAP_BLEND_GROUP_TARGETS,
        LENSMAP_BLEND_PROGRAMMABLE,
    ] {
        let mut options = frame_options(LENSMAP_FORMAT_RGBA32F);
        options.variant = LENSMAP_VARIANT_MULTIPASS;
        options.blend = blend;
        let mut pixels = vec![f32::NAN; 4 * 40 * 30];
        assert_eq!(
            render(context, scene, &options, &mut pixels),
            LensmapResult::Ok
        );
        assert_eq!(
            pixels,
            rust_frame(&mut runner, &options),
            "blend {blend}: bit-identical to the Rust API's frame"
        );
        frames.push(pixels);
    }
    for (blend, pixels) in frames.iter().enumerate().skip(1) {
        let largest = pixels
            .iter()
            .zip(&frames[0])
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f32::max);
        assert!(largest <= 1e-5, "blend {blend}: {largest}");
    }
    // An ABI 2 struct: its size ends before `blend` (whatever lies past it is not read).
    let mut old = frame_options(LENSMAP_FORMAT_RGBA32F);
    old.variant = LENSMAP_VARIANT_MULTIPASS;
    old.blend = 0xdead;
    old.struct_size = 68;
    let mut pixels = vec![f32::NAN; 4 * 40 * 30];
    assert_eq!(render(context, scene, &old, &mut pixels), LensmapResult::Ok);
    assert_eq!(pixels, frames[0], "an ABI 2 struct renders front-to-back");
    // lensmap_scene_frame_options fills an ABI 2 struct without writing past it: 17 aligned
    // words of a struct's 19, the rest markers.
    let mut filled = [0xabab_abab_u32; size_of::<LensmapFrameOptions>() / 4];
    filled[0] = 68;
    // SAFETY: `filled` is 4-aligned and as large as the struct, so any write is in bounds.
    let code = unsafe {
        lensmap_scene_frame_options(scene, filled.as_mut_ptr() as *mut LensmapFrameOptions)
    };
    assert_eq!(code, LensmapResult::Ok);
    assert_eq!(filled[17], 0xabab_abab, "nothing written past ABI 2's size");
    assert_eq!(filled[0], 68, "struct_size stays the caller's");
    assert!(
        filled[1..17].iter().any(|&w| w != 0xabab_abab),
        "the camera and options were filled"
    );
    // lensmap_plan_text reads an ABI 2 plan struct (24 bytes) as front-to-back.
    let mut plan = LensmapPlanOptions {
        struct_size: 24,
        layers: 2,
        viewpoints: 2,
        terms: 2,
        variant: LENSMAP_VARIANT_MULTIPASS,
        format: LENSMAP_FORMAT_RGBA8,
        blend: 0xdead,
    };
    let mut length = 0usize;
    // SAFETY: valid pointers; a size query writes only `length`.
    assert_eq!(
        unsafe { lensmap_plan_text(&plan, null_mut(), 0, &mut length) },
        LensmapResult::Ok
    );
    plan.struct_size = size_of::<LensmapPlanOptions>() as u32;
    plan.blend = LENSMAP_BLEND_FRONT_TO_BACK;
    let mut current = 0usize;
    // SAFETY: as above.
    assert_eq!(
        unsafe { lensmap_plan_text(&plan, null_mut(), 0, &mut current) },
        LensmapResult::Ok
    );
    assert_eq!(length, current, "the ABI 2 plan is the front-to-back plan");
    assert!(runner.gpu().validation_report().messages.is_empty());
    assert_no_validation_messages(context);
    // SAFETY: live handles, freed once.
    unsafe {
        assert_eq!(lensmap_scene_free(scene), LensmapResult::Ok);
        assert_eq!(lensmap_context_free(context), LensmapResult::Ok);
    }
}

/// Validation messages the hosts' messengers received.
static HOST_MESSAGES: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);

unsafe extern "system" fn count_host_message(
    _severity: ash::vk::DebugUtilsMessageSeverityFlagsEXT,
    _types: ash::vk::DebugUtilsMessageTypeFlagsEXT,
    data: *const ash::vk::DebugUtilsMessengerCallbackDataEXT<'_>,
    _user: *mut std::ffi::c_void,
) -> ash::vk::Bool32 {
    // SAFETY: the layer passes valid callback data for the duration of the call.
    let message = unsafe { (*data).message_as_c_str() }
        .map(|m| m.to_string_lossy().into_owned())
        .unwrap_or_default();
    eprintln!("host validation: {message}");
    HOST_MESSAGES.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    ash::vk::FALSE
}

/// A host's own Vulkan instance and device (made here with ash, validation on, its messages
/// counted in [`HOST_MESSAGES`]), lent to lensmap.
struct HostVulkan {
    entry: ash::Entry,
    instance: ash::Instance,
    debug: ash::ext::debug_utils::Instance,
    messenger: ash::vk::DebugUtilsMessengerEXT,
    physical_device: ash::vk::PhysicalDevice,
    device: ash::Device,
    family: u32,
}

impl HostVulkan {
    fn new() -> HostVulkan {
        use ash::vk;
        // SAFETY: loading the system's libvulkan.
        let entry = unsafe { ash::Entry::load() }.expect("libvulkan");
        let app = vk::ApplicationInfo::default().api_version(vk::API_VERSION_1_3);
        let layers = [c"VK_LAYER_KHRONOS_validation".as_ptr()];
        let extensions = [ash::ext::debug_utils::NAME.as_ptr()];
        let info = vk::InstanceCreateInfo::default()
            .application_info(&app)
            .enabled_layer_names(&layers)
            .enabled_extension_names(&extensions);
        // SAFETY: valid create info.
        let instance = unsafe { entry.create_instance(&info, None) }.expect("an instance");
        let debug = ash::ext::debug_utils::Instance::new(&entry, &instance);
        let messenger_info = vk::DebugUtilsMessengerCreateInfoEXT::default()
            .message_severity(
                vk::DebugUtilsMessageSeverityFlagsEXT::WARNING
                    | vk::DebugUtilsMessageSeverityFlagsEXT::ERROR,
            )
            .message_type(
                vk::DebugUtilsMessageTypeFlagsEXT::GENERAL
                    | vk::DebugUtilsMessageTypeFlagsEXT::VALIDATION,
            )
            .pfn_user_callback(Some(count_host_message));
        // SAFETY: a static callback without user data.
        let messenger = unsafe { debug.create_debug_utils_messenger(&messenger_info, None) }
            .expect("a messenger");
        // SAFETY: a live instance.
        let physical_device = unsafe { instance.enumerate_physical_devices() }.expect("devices")[0];
        // SAFETY: as above.
        let family =
            unsafe { instance.get_physical_device_queue_family_properties(physical_device) }
                .iter()
                .position(|f| f.queue_flags.contains(vk::QueueFlags::GRAPHICS))
                .expect("a graphics family") as u32;
        let priorities = [1.0];
        let queues = [vk::DeviceQueueCreateInfo::default()
            .queue_family_index(family)
            .queue_priorities(&priorities)];
        let features = vk::PhysicalDeviceFeatures::default().image_cube_array(true);
        let mut features12 = vk::PhysicalDeviceVulkan12Features::default().timeline_semaphore(true);
        let mut features13 = vk::PhysicalDeviceVulkan13Features::default()
            .dynamic_rendering(true)
            .synchronization2(true);
        let info = vk::DeviceCreateInfo::default()
            .queue_create_infos(&queues)
            .enabled_features(&features)
            .push_next(&mut features12)
            .push_next(&mut features13);
        // SAFETY: valid create info for a device of this instance.
        let device =
            unsafe { instance.create_device(physical_device, &info, None) }.expect("a device");
        HostVulkan {
            entry,
            instance,
            debug,
            messenger,
            physical_device,
            device,
            family,
        }
    }

    fn lent(&self, enabled_features: u32) -> LensmapHostDevice {
        use ash::vk::Handle as _;
        // SAFETY: a queue of the family the device was made with.
        let queue = unsafe { self.device.get_device_queue(self.family, 0) };
        LensmapHostDevice {
            struct_size: size_of::<LensmapHostDevice>() as u32,
            // SAFETY: the loader's vkGetInstanceProcAddr has this C signature.
            get_instance_proc_addr: Some(unsafe {
                std::mem::transmute::<
                    ash::vk::PFN_vkGetInstanceProcAddr,
                    unsafe extern "system" fn(
                        VkInstance,
                        *const c_char,
                    )
                        -> Option<unsafe extern "system" fn()>,
                >(self.entry.static_fn().get_instance_proc_addr)
            }),
            instance: self.instance.handle().as_raw() as VkInstance,
            physical_device: self.physical_device.as_raw() as VkPhysicalDevice,
            device: self.device.handle().as_raw() as VkDevice,
            queue_family: self.family,
            queue: queue.as_raw() as VkQueue,
            enabled_features,
        }
    }
}

impl Drop for HostVulkan {
    fn drop(&mut self) {
        // SAFETY: lensmap's context on this device was freed first; nothing else uses it.
        unsafe {
            self.device.destroy_device(None);
            self.debug
                .destroy_debug_utils_messenger(self.messenger, None);
            self.instance.destroy_instance(None);
        }
    }
}

/// ABI 4: plans of three viewpoint samples (2·3·n layer passes, five alpha clears), four
/// refused naming the range; the scene options' `light_map_max_texels`, out of range refused in
/// the ABI's words, and an ABI 3 struct (which ends before it) loading the scene with the
/// default, whose frame equals the current struct's with 0 there.
#[test]
fn three_viewpoint_plans_and_abi_3_scene_options() {
    let mut plan = LensmapPlanOptions {
        struct_size: size_of::<LensmapPlanOptions>() as u32,
        layers: 3,
        viewpoints: 3,
        terms: 2,
        variant: LENSMAP_VARIANT_MULTIPASS,
        format: LENSMAP_FORMAT_RGBA8,
        blend: LENSMAP_BLEND_FRONT_TO_BACK,
    };
    let mut length = 0usize;
    // SAFETY: valid pointers; a size query writes only `length`.
    let code = unsafe { lensmap_plan_text(&plan, null_mut(), 0, &mut length) };
    assert_eq!(code, LensmapResult::Ok, "{}", last_error());
    let mut text = vec![1 as c_char; length + 1];
    // SAFETY: writable for length + 1 bytes.
    let code = unsafe { lensmap_plan_text(&plan, text.as_mut_ptr(), text.len(), &mut length) };
    assert_eq!(code, LensmapResult::Ok, "{}", last_error());
    // SAFETY: NUL-terminated by lensmap_plan_text.
    let printed = unsafe { CStr::from_ptr(text.as_ptr()) }.to_string_lossy();
    assert_eq!(printed.matches("alpha-clear").count(), 5, "{printed}");
    assert_eq!(printed.matches("/layer").count(), 18, "{printed}");
    assert!(printed.contains("lens/v2/R/layer2"), "{printed}");
    plan.viewpoints = 4;
    // SAFETY: as above.
    assert_failure(
        unsafe { lensmap_plan_text(&plan, null_mut(), 0, &mut length) },
        LensmapResult::InvalidArgument,
        "options->viewpoints is 4; give 1 to 3",
    );

    let mut bad = scene_options(SCENE, None);
    bad.light_map_max_texels = 5;
    let mut scene = null_mut();
    // SAFETY: valid options and out-pointer.
    assert_failure(
        unsafe { lensmap_scene_load(&bad, &mut scene) },
        LensmapResult::InvalidArgument,
        "options->light_map_max_texels 5",
    );
    assert!(scene.is_null(), "out untouched on failure");
    // An ABI 3 struct: its size ends before `light_map_max_texels`, whatever lies past it.
    let mut old = scene_options(SCENE, None);
    old.struct_size = 32;
    old.light_map_max_texels = 5;
    // SAFETY: valid options and out-pointer.
    let code = unsafe { lensmap_scene_load(&old, &mut scene) };
    assert_eq!(code, LensmapResult::Ok, "{}", last_error());
    let current = load_scene();
    let context = new_context();
    let options = frame_options(LENSMAP_FORMAT_RGBA32F);
    let mut frames = [vec![0f32; 4 * 40 * 30], vec![0f32; 4 * 40 * 30]];
    for (scene, pixels) in [scene, current].into_iter().zip(&mut frames) {
        assert_eq!(
            render(context, scene, &options, pixels),
            LensmapResult::Ok,
            "{}",
            last_error()
        );
    }
    assert_eq!(
        frames[0], frames[1],
        "an ABI 3 struct loads default light maps"
    );
    assert_no_validation_messages(context);
    // SAFETY: live handles, freed once.
    unsafe {
        assert_eq!(lensmap_scene_free(scene), LensmapResult::Ok);
        assert_eq!(lensmap_scene_free(current), LensmapResult::Ok);
        assert_eq!(lensmap_context_free(context), LensmapResult::Ok);
    }
}

#[test]
fn a_frame_on_the_hosts_own_device_equals_one_on_lensmaps() {
    let host = HostVulkan::new();
    let mut context = null_mut();
    // SAFETY: the host's live handles, which belong together.
    let code =
        unsafe { lensmap_context_new_on_host(&host.lent(LENSMAP_FEATURES_REQUIRED), &mut context) };
    assert_eq!(code, LensmapResult::Ok, "{}", last_error());
    let scene = load_scene();
    let options = frame_options(LENSMAP_FORMAT_RGBA32F);
    let mut on_host = vec![0.0f32; 4 * 40 * 30];
    assert_eq!(
        render(context, scene, &options, &mut on_host),
        LensmapResult::Ok
    );
    let own = new_context();
    let mut on_own = vec![0.0f32; 4 * 40 * 30];
    assert_eq!(render(own, scene, &options, &mut on_own), LensmapResult::Ok);
    assert_eq!(
        on_host, on_own,
        "the same device kind renders the same frame"
    );
    assert_no_validation_messages(own);
    // SAFETY: live handles, freed once, lensmap's context before the host's device.
    unsafe {
        assert_eq!(lensmap_context_free(context), LensmapResult::Ok);
        assert_eq!(lensmap_context_free(own), LensmapResult::Ok);
        assert_eq!(lensmap_scene_free(scene), LensmapResult::Ok);
    }
    drop(host);
    assert_eq!(
        HOST_MESSAGES.load(std::sync::atomic::Ordering::Relaxed),
        0,
        "the host's validation layer reported messages (see stderr)"
    );
}

/// A bake that says nothing of its scene, or was made from another scene, is refused with
/// `LENSMAP_RESULT_BAKE` and a message that names the option as this ABI's struct field, never a
/// command-line flag or command; `accept_any_bake` takes a bake that says nothing of its scene.
#[test]
fn bakes_of_other_or_unnamed_scenes_are_refused_in_the_abis_words() {
    use LensmapResult as R;
    let ems = EmSource::Projected(ProjectedOptions::with_size(8));
    let (hybrid, _) = load_hybrid_scene(Scene::load_named("glass-sphere").unwrap(), &ems.into())
        .expect("projected");
    let root = std::env::temp_dir().join(format!("lensmap-capi-bakes-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&root);
    let (made, unnamed) = (root.join("made"), root.join("unnamed"));
    let bake = hybrid.to_bake();
    bake.write(&made).unwrap();
    let no_provenance = lensmap::layers::Bake {
        provenance: None,
        ..bake
    };
    no_provenance.write(&unnamed).unwrap();
    let c_path = |path: &std::path::Path| CString::new(path.to_str().unwrap()).unwrap();
    let (made, unnamed) = (c_path(&made), c_path(&unnamed));
    let in_the_abis_words = || {
        let message = last_error();
        assert!(
            !message.contains("--") && !message.contains("lensmap bake"),
            "a command line in the C ABI's message: {message}"
        );
    };
    let mut out = null_mut();
    // SAFETY: valid options, strings and out-pointers.
    unsafe {
        assert_failure(
            lensmap_scene_load(&scene_options(c"mirror-teapot", Some(&made)), &mut out),
            R::Bake,
            "provenance.scene_hash",
        );
        in_the_abis_words();
        assert_failure(
            lensmap_scene_load(&scene_options(SCENE, Some(&unnamed)), &mut out),
            R::Bake,
            "set options->accept_any_bake",
        );
        in_the_abis_words();
        let mut accepting = scene_options(SCENE, Some(&unnamed));
        accepting.accept_any_bake = 1;
        assert_eq!(
            lensmap_scene_load(&accepting, &mut out),
            R::Ok,
            "{}",
            last_error()
        );
        assert_eq!(lensmap_scene_free(out), R::Ok);
    }
    std::fs::remove_dir_all(&root).unwrap();
}

/// The misuse corpus: every case returns its documented code, names the problem in
/// `lensmap_last_error()`, leaves out-pointers as they were, and crashes nothing.
#[test]
fn misuse_returns_documented_codes_and_useful_messages() {
    use LensmapResult as R;
    let untouched = 0x5a5a_usize as *mut LensmapContext;
    // SAFETY (the whole test): every pointer is valid, NULL, or a deliberately stale or foreign
    // handle, which the ABI must refuse without dereferencing.
    unsafe {
        // 1–2. Freeing NULL is a no-op.
        assert_eq!(lensmap_context_free(null_mut()), R::Ok);
        assert_eq!(lensmap_scene_free(null_mut()), R::Ok);
        // 3. A NULL out-pointer.
        assert_failure(
            lensmap_context_new(&context_options(None), null_mut()),
            R::NullArgument,
            "out",
        );
        // 4. A struct size from another version: refused, the out-pointer untouched.
        let mut out = untouched;
        let mut bad = context_options(None);
        bad.struct_size = 4;
        assert_failure(
            lensmap_context_new(&bad, &mut out),
            R::StructSize,
            "struct_size",
        );
        assert_eq!(out, untouched);
        // 5. A device no system has.
        let nowhere = CString::new("no-such-gpu-anywhere").unwrap();
        assert_failure(
            lensmap_context_new(&context_options(Some(&nowhere)), &mut out),
            R::Device,
            "no-such-gpu-anywhere",
        );
        assert_eq!(out, untouched);

        let context = new_context();
        let scene = load_scene();
        // 6. An unknown scene.
        let mut scene_out = 0x77usize as *mut LensmapScene;
        assert_failure(
            lensmap_scene_load(&scene_options(c"glass-spere", None), &mut scene_out),
            R::Scene,
            "glass-spere",
        );
        assert_eq!(scene_out, 0x77usize as *mut LensmapScene);
        // 7. No scene named.
        let mut nameless = scene_options(SCENE, None);
        nameless.scene = null();
        assert_failure(
            lensmap_scene_load(&nameless, &mut scene_out),
            R::NullArgument,
            "options->scene",
        );
        // 8. A bake directory that does not exist.
        let missing = CString::new(
            std::env::temp_dir()
                .join("lensmap-capi-no-such-bake")
                .to_str()
                .unwrap(),
        )
        .unwrap();
        assert_failure(
            lensmap_scene_load(&scene_options(SCENE, Some(&missing)), &mut scene_out),
            R::Bake,
            "lensmap-capi-no-such-bake",
        );
        // 9. A directory that is not a bake (no manifest).
        let not_a_bake =
            std::env::temp_dir().join(format!("lensmap-capi-empty-{}", std::process::id()));
        std::fs::create_dir_all(&not_a_bake).unwrap();
        std::fs::write(not_a_bake.join("manifest.json"), b"{ not json").unwrap();
        let not_a_bake_c = CString::new(not_a_bake.to_str().unwrap()).unwrap();
        assert_failure(
            lensmap_scene_load(&scene_options(SCENE, Some(&not_a_bake_c)), &mut scene_out),
            R::Bake,
            "manifest.json",
        );
        std::fs::remove_dir_all(&not_a_bake).unwrap();
        // 10. A projected EM size that is not a power of two.
        let mut odd = scene_options(SCENE, None);
        odd.em_size = 12;
        assert_failure(
            lensmap_scene_load(&odd, &mut scene_out),
            R::InvalidArgument,
            "em_size",
        );
        assert_eq!(scene_out, 0x77usize as *mut LensmapScene);

        let mut pixels = vec![0.0f32; 4 * 40 * 30];
        // 11. A zero-size image.
        let mut empty = frame_options(LENSMAP_FORMAT_RGBA32F);
        empty.width = 0;
        assert_failure(
            render(context, scene, &empty, &mut pixels),
            R::InvalidArgument,
            "empty",
        );
        // 12. A format lensmap cannot render to.
        assert_failure(
            render(context, scene, &frame_options(7), &mut pixels),
            R::UnsupportedFormat,
            "options->format is 7",
        );
        // 13. An unknown variant.
        let mut variant = frame_options(LENSMAP_FORMAT_RGBA8);
        variant.variant = 9;
        assert_failure(
            render(context, scene, &variant, &mut pixels),
            R::InvalidArgument,
            "options->variant is 9",
        );
        // 13a. An unknown blending scheme, and one the single pass cannot take.
        let mut blend = frame_options(LENSMAP_FORMAT_RGBA8);
        blend.variant = LENSMAP_VARIANT_MULTIPASS;
        blend.blend = 9;
        assert_failure(
            render(context, scene, &blend, &mut pixels),
            R::InvalidArgument,
            "options->blend is 9",
        );
        blend.variant = LENSMAP_VARIANT_SINGLE_PASS;
        blend.blend = LENSMAP_BLEND_PROGRAMMABLE;
        assert_failure(
            render(context, scene, &blend, &mut pixels),
            R::InvalidArgument,
            "options->blend LENSMAP_BLEND_PROGRAMMABLE",
        );
        // 13b. Options struct sizes of no ABI, on a render and on a plan: refused.
        for size in [0, 64, 78, 82, 88, u32::MAX] {
            let mut sized = frame_options(LENSMAP_FORMAT_RGBA8);
            sized.struct_size = size;
            assert_failure(
                render(context, scene, &sized, &mut pixels),
                R::StructSize,
                "options->struct_size",
            );
        }
        let mut sized_plan = LensmapPlanOptions {
            struct_size: 20,
            layers: 2,
            viewpoints: 1,
            terms: 1,
            variant: LENSMAP_VARIANT_MULTIPASS,
            format: LENSMAP_FORMAT_RGBA8,
            blend: LENSMAP_BLEND_FRONT_TO_BACK,
        };
        let mut plan_length = 0usize;
        for size in [20, 32, u32::MAX] {
            sized_plan.struct_size = size;
            assert_failure(
                lensmap_plan_text(&sized_plan, null_mut(), 0, &mut plan_length),
                R::StructSize,
                "options->struct_size",
            );
        }
        // 13c. The single pass with another blending scheme, in a plan: the C names.
        sized_plan.struct_size = size_of::<LensmapPlanOptions>() as u32;
        sized_plan.variant = LENSMAP_VARIANT_SINGLE_PASS;
        sized_plan.blend = LENSMAP_BLEND_GROUP_TARGETS;
        assert_failure(
            lensmap_plan_text(&sized_plan, null_mut(), 0, &mut plan_length),
            R::InvalidArgument,
            "LENSMAP_VARIANT_MULTIPASS",
        );
        // 14. A negative tessellation threshold.
        let mut negative = frame_options(LENSMAP_FORMAT_RGBA8);
        negative.t = -1.0;
        assert_failure(
            render(context, scene, &negative, &mut pixels),
            R::InvalidArgument,
            "t -1",
        );
        // 15. A buffer too small for the frame: refused before any work, nothing written.
        let mut small = vec![-7.0f32; 100];
        assert_failure(
            render(
                context,
                scene,
                &frame_options(LENSMAP_FORMAT_RGBA8),
                &mut small,
            ),
            R::BufferTooSmall,
            "4800",
        );
        assert!(small.iter().all(|&v| v == -7.0));
        // 16. NULL handles.
        assert_failure(
            render(
                null_mut(),
                scene,
                &frame_options(LENSMAP_FORMAT_RGBA8),
                &mut pixels,
            ),
            R::NullArgument,
            "context",
        );
        assert_failure(
            render(
                context,
                null(),
                &frame_options(LENSMAP_FORMAT_RGBA8),
                &mut pixels,
            ),
            R::NullArgument,
            "scene",
        );
        // 17. A scene handle passed as a context (a type confusion): refused, not dereferenced.
        assert_failure(
            render(
                scene as *mut LensmapContext,
                scene,
                &frame_options(LENSMAP_FORMAT_RGBA8),
                &mut pixels,
            ),
            R::InvalidHandle,
            "not a live LensmapContext",
        );
        // 18. A stats struct of a size lensmap never had.
        let mut stats = LensmapFrameStats {
            struct_size: 3,
            ..LensmapFrameStats::default()
        };
        assert_failure(
            lensmap_render_to_memory(
                context,
                scene,
                &frame_options(LENSMAP_FORMAT_RGBA8),
                pixels.as_mut_ptr(),
                pixels.len(),
                &mut stats,
            ),
            R::StructSize,
            "stats->struct_size",
        );
        // 19. The plan: a size query, then a buffer one byte short.
        let plan = LensmapPlanOptions {
            struct_size: size_of::<LensmapPlanOptions>() as u32,
            layers: 3,
            viewpoints: 2,
            terms: 2,
            variant: LENSMAP_VARIANT_MULTIPASS,
            format: LENSMAP_FORMAT_RGBA8,
            blend: LENSMAP_BLEND_FRONT_TO_BACK,
        };
        let mut length = 0usize;
        assert_eq!(lensmap_plan_text(&plan, null_mut(), 0, &mut length), R::Ok);
        let mut text = vec![1 as c_char; length];
        let mut unchanged = 12345usize;
        assert_failure(
            lensmap_plan_text(&plan, text.as_mut_ptr(), text.len(), &mut unchanged),
            R::BufferTooSmall,
            "buffer holds",
        );
        assert_eq!(unchanged, 12345);
        let mut text = vec![1 as c_char; length + 1];
        assert_eq!(
            lensmap_plan_text(&plan, text.as_mut_ptr(), text.len(), &mut unchanged),
            R::Ok
        );
        let printed = CStr::from_ptr(text.as_ptr()).to_string_lossy();
        assert_eq!(printed.len(), length);
        assert_eq!(printed.matches("alpha-clear").count(), 3, "{printed}");
        // 20. A plan of 0 layers.
        let mut none = plan;
        none.layers = 0;
        assert_failure(
            lensmap_plan_text(&none, null_mut(), 0, &mut length),
            R::InvalidArgument,
            "options->layers is 0",
        );
        // 21. A host's device that lacks a feature lensmap needs (imageCubeArray not enabled).
        let host = HostVulkan::new();
        let mut out = untouched;
        assert_failure(
            lensmap_context_new_on_host(
                &host.lent(LENSMAP_FEATURES_REQUIRED & !LENSMAP_FEATURE_IMAGE_CUBE_ARRAY),
                &mut out,
            ),
            R::Device,
            "imageCubeArray",
        );
        // 22. A host without a device.
        let mut deviceless = host.lent(LENSMAP_FEATURES_REQUIRED);
        deviceless.device = null_mut();
        assert_failure(
            lensmap_context_new_on_host(&deviceless, &mut out),
            R::NullArgument,
            "host->device",
        );
        // 23. A queue family without graphics (one past the last family).
        let mut familyless = host.lent(LENSMAP_FEATURES_REQUIRED);
        familyless.queue_family = 1000;
        assert_failure(
            lensmap_context_new_on_host(&familyless, &mut out),
            R::Device,
            "queue family 1000",
        );
        assert_eq!(out, untouched);
        drop(host);

        assert_no_validation_messages(context);
        // 24–25. Double frees are detected and free nothing.
        assert_eq!(lensmap_scene_free(scene), R::Ok);
        assert_failure(lensmap_scene_free(scene), R::InvalidHandle, "freed twice");
        // 26. A freed scene is refused by render.
        assert_failure(
            render(
                context,
                scene,
                &frame_options(LENSMAP_FORMAT_RGBA8),
                &mut pixels,
            ),
            R::InvalidHandle,
            "not a live LensmapScene",
        );
        assert_eq!(lensmap_context_free(context), R::Ok);
        assert_failure(
            lensmap_context_free(context),
            R::InvalidHandle,
            "freed twice",
        );
    }
    // 27. The last error is per thread: a fresh thread has none.
    let fresh = std::thread::spawn(last_error).join().unwrap();
    assert_eq!(fresh, "");
}

/// Calls on one context from two threads at once: one of them is refused with BUSY (the
/// documented contract: one thread at a time), none crashes, and both go on working after.
#[test]
fn two_threads_on_one_context_get_busy_not_a_crash() {
    struct Shared(*mut LensmapContext, *mut LensmapScene);
    // SAFETY: the ABI's handles may be passed between threads; the test frees them at the end.
    unsafe impl Send for Shared {}
    unsafe impl Sync for Shared {}
    let shared = std::sync::Arc::new(Shared(new_context(), load_scene()));
    let stop = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
    let worker = {
        let (shared, stop) = (shared.clone(), stop.clone());
        std::thread::spawn(move || {
            let mut options = frame_options(LENSMAP_FORMAT_RGBA32F);
            (options.width, options.height) = (200, 150);
            let mut pixels = vec![0.0f32; 4 * 200 * 150];
            let mut busy = 0;
            while !stop.load(std::sync::atomic::Ordering::Relaxed) {
                match render(shared.0, shared.1, &options, &mut pixels) {
                    LensmapResult::Ok => {}
                    LensmapResult::Busy => busy += 1,
                    other => panic!("{other:?}: {}", last_error()),
                }
            }
            busy
        })
    };
    let mut pixels = vec![0.0f32; 4 * 40 * 30];
    let options = frame_options(LENSMAP_FORMAT_RGBA8);
    let mut busy = false;
    for _ in 0..2000 {
        match render(shared.0, shared.1, &options, &mut pixels) {
            LensmapResult::Ok => {}
            LensmapResult::Busy => {
                assert!(last_error().contains("another thread"), "{}", last_error());
                busy = true;
                break;
            }
            other => panic!("{other:?}: {}", last_error()),
        }
        std::thread::sleep(std::time::Duration::from_millis(1));
    }
    stop.store(true, std::sync::atomic::Ordering::Relaxed);
    let worker_busy = worker.join().expect("the worker never failed");
    assert!(
        busy || worker_busy > 0,
        "a call while another thread rendered was never refused"
    );
    assert_eq!(
        render(shared.0, shared.1, &options, &mut pixels),
        LensmapResult::Ok
    );
    // SAFETY: live handles, freed once, no thread uses them any more.
    unsafe {
        assert_eq!(lensmap_scene_free(shared.1), LensmapResult::Ok);
        assert_eq!(lensmap_context_free(shared.0), LensmapResult::Ok);
    }
}

/// An image of the host's device to render into: `width × height` RGBA32F, device-local, bound,
/// with a view; and what it takes to free it.
struct HostTarget<'a> {
    device: &'a ash::Device,
    image: ash::vk::Image,
    view: ash::vk::ImageView,
    memory: ash::vk::DeviceMemory,
}

impl<'a> HostTarget<'a> {
    fn new(host: &'a HostVulkan, width: u32, height: u32) -> HostTarget<'a> {
        use ash::vk;
        let device = &host.device;
        let format = vk::Format::R32G32B32A32_SFLOAT;
        let info = vk::ImageCreateInfo::default()
            .image_type(vk::ImageType::TYPE_2D)
            .format(format)
            .extent(vk::Extent3D {
                width,
                height,
                depth: 1,
            })
            .mip_levels(1)
            .array_layers(1)
            .samples(vk::SampleCountFlags::TYPE_1)
            .usage(vk::ImageUsageFlags::COLOR_ATTACHMENT | vk::ImageUsageFlags::TRANSFER_SRC);
        // SAFETY (all calls): valid create infos on the host's live device; freed by Drop.
        unsafe {
            let image = device.create_image(&info, None).expect("an image");
            let needs = device.get_image_memory_requirements(image);
            let types = host
                .instance
                .get_physical_device_memory_properties(host.physical_device);
            let index = (0..types.memory_type_count)
                .find(|&i| {
                    needs.memory_type_bits & (1 << i) != 0
                        && types.memory_types[i as usize]
                            .property_flags
                            .contains(vk::MemoryPropertyFlags::DEVICE_LOCAL)
                })
                .expect("device-local memory");
            let memory = device
                .allocate_memory(
                    &vk::MemoryAllocateInfo::default()
                        .allocation_size(needs.size)
                        .memory_type_index(index),
                    None,
                )
                .expect("memory");
            device.bind_image_memory(image, memory, 0).expect("bound");
            let view = device
                .create_image_view(
                    &vk::ImageViewCreateInfo::default()
                        .image(image)
                        .view_type(vk::ImageViewType::TYPE_2D)
                        .format(format)
                        .subresource_range(vk::ImageSubresourceRange {
                            aspect_mask: vk::ImageAspectFlags::COLOR,
                            base_mip_level: 0,
                            level_count: 1,
                            base_array_layer: 0,
                            layer_count: 1,
                        }),
                    None,
                )
                .expect("a view");
            HostTarget {
                device,
                image,
                view,
                memory,
            }
        }
    }

    /// The image as lent to `lensmap_render_to_image`, signalling nothing.
    fn lent(&self) -> LensmapHostImage {
        use ash::vk::Handle as _;
        LensmapHostImage {
            struct_size: size_of::<LensmapHostImage>() as u32,
            image: self.image.as_raw() as VkImage,
            view: self.view.as_raw() as VkImageView,
            mip_level: 0,
            array_layer: 0,
            format: ash::vk::Format::R32G32B32A32_SFLOAT.as_raw(),
            current_layout: ash::vk::ImageLayout::UNDEFINED.as_raw(),
            final_layout: ash::vk::ImageLayout::TRANSFER_SRC_OPTIMAL.as_raw(),
            wait_count: 0,
            wait_semaphores: null(),
            wait_values: null(),
            signal_count: 0,
            signal_semaphores: null(),
            signal_values: null(),
        }
    }
}

impl Drop for HostTarget<'_> {
    fn drop(&mut self) {
        // SAFETY: the device is idle (waited below); these objects are the host's own.
        unsafe {
            let _ = self.device.device_wait_idle();
            self.device.destroy_image_view(self.view, None);
            self.device.destroy_image(self.image, None);
            self.device.free_memory(self.memory, None);
        }
    }
}

/// `lensmap_render_to_image` and `lensmap_scene_frame_options`: a frame rendered into the host's
/// image signals the host's timeline semaphore with its value, with no validation message on the
/// host's device; and the misuse cases of the image path (continuing the corpus's numbering)
/// return their documented codes and leave the semaphore unsignalled.
#[test]
fn a_frame_into_a_hosts_image_signals_its_semaphore_and_misuse_is_refused() {
    use LensmapResult as R;
    use ash::vk::{self, Handle as _};
    let host = HostVulkan::new();
    let mut context = null_mut();
    // SAFETY (the whole test): live handles of the host's device, NULL, or deliberately wrong
    // values the ABI must refuse without using them.
    unsafe {
        assert_eq!(
            lensmap_context_new_on_host(&host.lent(LENSMAP_FEATURES_REQUIRED), &mut context),
            R::Ok,
            "{}",
            last_error()
        );
        let scene = load_scene();
        // The scene's own camera, as `lensmap render` would use it.
        let mut options = frame_options(LENSMAP_FORMAT_RGBA32F);
        let mut too_small = options;
        too_small.struct_size = 8;
        assert_failure(
            lensmap_scene_frame_options(scene, &mut too_small),
            R::StructSize,
            "struct_size",
        );
        assert_eq!(lensmap_scene_frame_options(scene, &mut options), R::Ok);
        let camera = Scene::builtin("glass-sphere").unwrap().unwrap().camera;
        assert_eq!(
            options.vfov_degrees.to_radians(),
            camera.vfov_radians,
            "the degrees given back convert to the scene's very field of view"
        );
        assert_eq!(
            (options.width, options.height, options.format),
            (camera.width, camera.height, LENSMAP_FORMAT_RGBA16F)
        );
        options.format = LENSMAP_FORMAT_RGBA32F;
        (options.width, options.height, options.supersampling) = (40, 30, 2);
        let target = HostTarget::new(&host, 40, 30);
        let mut kind =
            vk::SemaphoreTypeCreateInfo::default().semaphore_type(vk::SemaphoreType::TIMELINE);
        let done = host
            .device
            .create_semaphore(
                &vk::SemaphoreCreateInfo::default().push_next(&mut kind),
                None,
            )
            .expect("a timeline");
        let done_raw = done.as_raw() as VkSemaphore;
        let value = 5u64;
        let mut image = target.lent();
        image.signal_count = 1;
        image.signal_semaphores = &done_raw;
        image.signal_values = &value;

        // 28. A context on lensmap's own device cannot render into the host's image.
        let own = new_context();
        assert_failure(
            lensmap_render_to_image(own, scene, &options, &image, null_mut()),
            R::InvalidArgument,
            "lensmap_context_new_on_host",
        );
        // 29. A format lensmap cannot render to.
        let mut packed = image;
        packed.format = vk::Format::R5G6B5_UNORM_PACK16.as_raw();
        assert_failure(
            lensmap_render_to_image(context, scene, &options, &packed, null_mut()),
            R::UnsupportedFormat,
            "R8G8B8A8_UNORM",
        );
        // 30. No image.
        assert_failure(
            lensmap_render_to_image(context, scene, &options, null(), null_mut()),
            R::NullArgument,
            "image",
        );
        // 31. An image struct of another size.
        let mut other_size = image;
        other_size.struct_size -= 8;
        assert_failure(
            lensmap_render_to_image(context, scene, &options, &other_size, null_mut()),
            R::StructSize,
            "sizeof",
        );
        // 32. A semaphore count with no array.
        let mut no_array = image;
        no_array.signal_semaphores = null();
        assert_failure(
            lensmap_render_to_image(context, scene, &options, &no_array, null_mut()),
            R::NullArgument,
            "signal_semaphores",
        );
        // 33. A final layout a frame cannot end in.
        let mut undefined = image;
        undefined.final_layout = vk::ImageLayout::UNDEFINED.as_raw();
        assert_failure(
            lensmap_render_to_image(context, scene, &options, &undefined, null_mut()),
            R::InvalidArgument,
            "final layout",
        );
        // 34. No view.
        let mut viewless = image;
        viewless.view = null_mut();
        assert_failure(
            lensmap_render_to_image(context, scene, &options, &viewless, null_mut()),
            R::NullArgument,
            "image->view",
        );
        assert_eq!(
            host.device.get_semaphore_counter_value(done).unwrap(),
            0,
            "no refused call signalled"
        );

        let mut stats = LensmapFrameStats {
            struct_size: size_of::<LensmapFrameStats>() as u32,
            ..Default::default()
        };
        assert_eq!(
            lensmap_render_to_image(context, scene, &options, &image, &mut stats),
            R::Ok,
            "{}",
            last_error()
        );
        let semaphores = [done];
        let values = [value];
        host.device
            .wait_semaphores(
                &vk::SemaphoreWaitInfo::default()
                    .semaphores(&semaphores)
                    .values(&values),
                30_000_000_000,
            )
            .expect("the frame signals the host's semaphore");
        assert!(
            stats.passes >= 4 && stats.rays > 0 && stats.total_ms > 0.0,
            "{stats:?}"
        );

        assert_eq!(lensmap_context_free(own), R::Ok);
        assert_eq!(lensmap_context_free(context), R::Ok);
        assert_eq!(lensmap_scene_free(scene), R::Ok);
        host.device.destroy_semaphore(done, None);
    }
    drop(host);
    assert_eq!(
        HOST_MESSAGES.load(std::sync::atomic::Ordering::Relaxed),
        0,
        "the host's validation layer reported messages (see stderr)"
    );
}

/// A radiance-map bake of glossy-studio at `dir`: 4² maps, 4 directions a texel, all twelve
/// samples (written with the library's own staging, as `lensmap bake --radiance-maps` does).
fn tiny_radiance_bake(dir: &std::path::Path) {
    use lensmap::rsibr::bake::{RadianceManifest, RadianceStaging, SampleRecord};
    use lensmap::rsibr::{GlossyViews, RadianceMapOptions, glossy_objects, maps::sample_maps};
    let scene = Scene::builtin("glossy-studio")
        .expect("built in")
        .expect("loads");
    let options = RadianceMapOptions {
        size: 4,
        samples: 4,
        seed: 0,
        views: 12,
    };
    let template = RadianceManifest::template(&scene, &options);
    let staging = RadianceStaging::open(dir, template.identity.clone(), false).expect("staging");
    let trace = lensmap::trace::TraceScene::new(&scene).expect("a trace scene");
    let objects = glossy_objects(&scene);
    let views = GlossyViews::geodesic(12).expect("12");
    for (sample, &view) in views.directions().iter().enumerate() {
        let maps: Vec<Vec<std::sync::Arc<lensmap::cubemap::CubeMap>>> = objects
            .iter()
            .map(|o| {
                let (maps, _) = sample_maps(&trace, o, sample, view, &options);
                maps.into_iter()
                    .map(|m| std::sync::Arc::new(m.map))
                    .collect()
            })
            .collect();
        let record = SampleRecord {
            sample,
            max_standard_error: vec![0.0; objects.len()],
            rms_standard_error: vec![0.0; objects.len()],
            rays: 0,
            seconds: 0.0,
            device: None,
        };
        staging
            .write_sample(&objects, &maps, &record)
            .expect("a sample");
    }
    staging.commit(&template).expect("the bake");
}

/// Glossy objects through the ABI: a scene loaded with `radiance_dir` draws them by the glossy
/// pass (the stats count the maps it read, the pixels differ from the light-mapped frame), an
/// ABI 6 struct (without the field) loads them light-mapped, and a directory that is not a bake
/// is a bake failure naming the field.
#[test]
fn glossy_objects_are_drawn_from_a_radiance_map_bake() {
    let dir = std::env::temp_dir().join(format!("lensmap-abi-radiance-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    tiny_radiance_bake(&dir);
    let dir_text = CString::new(dir.to_str().expect("UTF-8")).expect("no NUL");
    let context = new_context();
    let camera = Scene::builtin("glossy-studio")
        .expect("built in")
        .expect("loads")
        .camera;
    let options = LensmapFrameOptions {
        position: camera.position.to_array(),
        look_at: camera.look_at.to_array(),
        up: camera.up.to_array(),
        vfov_degrees: camera.vfov_radians.to_degrees(),
        supersampling: 1,
        ..frame_options(LENSMAP_FORMAT_RGBA32F)
    };
    let frame = |radiance: Option<&CStr>, struct_size: usize| {
        let mut scene_options = scene_options(c"glossy-studio", None);
        scene_options.radiance_dir = radiance.map_or(null(), CStr::as_ptr);
        scene_options.struct_size = struct_size as u32;
        let mut scene = null_mut();
        // SAFETY: valid options and out-pointer.
        let code = unsafe { lensmap_scene_load(&scene_options, &mut scene) };
        assert_eq!(code, LensmapResult::Ok, "{}", last_error());
        let mut pixels = vec![0.0f32; 40 * 30 * 4];
        let mut stats = LensmapFrameStats {
            struct_size: size_of::<LensmapFrameStats>() as u32,
            ..LensmapFrameStats::default()
        };
        // SAFETY: live handles, writable pixels and stats.
        let code = unsafe {
            lensmap_render_to_memory(
                context,
                scene,
                &options,
                pixels.as_mut_ptr(),
                pixels.len(),
                &mut stats,
            )
        };
        assert_eq!(code, LensmapResult::Ok, "{}", last_error());
        // SAFETY: a live scene.
        unsafe { lensmap_scene_free(scene) };
        (pixels, stats)
    };
    let full = size_of::<LensmapSceneOptions>();
    let (glossy, stats) = frame(Some(&dir_text), full);
    // Both objects inside a triangle or on an edge: 2 or 3 samples × (2 + 3) lobes.
    assert!((10..=15).contains(&stats.glossy_maps), "{stats:?}");
    let (light_mapped, stats) = frame(None, full);
    assert_eq!(stats.glossy_maps, 0);
    let (older, stats) = frame(
        Some(&dir_text),
        std::mem::offset_of!(LensmapSceneOptions, radiance_dir),
    );
    assert_eq!(stats.glossy_maps, 0, "an ABI 6 struct has no radiance_dir");
    assert!(older == light_mapped);
    let differing = glossy
        .chunks(4)
        .zip(light_mapped.chunks(4))
        .filter(|(a, b)| a != b)
        .count();
    assert!(differing > 100, "{differing} pixels differ");

    let mut scene_options = scene_options(c"glossy-studio", None);
    let missing = CString::new(dir.join("missing").to_str().unwrap()).unwrap();
    scene_options.radiance_dir = missing.as_ptr();
    let mut scene = null_mut();
    // SAFETY: valid options and out-pointer.
    let code = unsafe { lensmap_scene_load(&scene_options, &mut scene) };
    assert_failure(code, LensmapResult::Bake, "options->radiance_dir");
    assert_no_validation_messages(context);
    // SAFETY: a live context.
    unsafe { lensmap_context_free(context) };
    let _ = std::fs::remove_dir_all(&dir);
}
