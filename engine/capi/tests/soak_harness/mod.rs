//! The soak through the C ABI, shared by the short soak that `cargo test` runs
//! (`tests/soak.rs`) and the full one (`examples/soak.rs`, run by `tools/scripts/soak.sh`).
//!
//! Two phases, both through the exported `extern "C"` functions, validation on:
//! - **frames**: one context renders frame after frame with a moving camera, alternating scenes,
//!   compositor variant, blending scheme, framebuffer format, size, supersampling, viewpoint
//!   blending, Fresnel model and tracer (a repeated camera now and then, which the scene's frame
//!   cache reuses). Every `sample_every` frames the process's resident memory (`VmRSS`), the
//!   heap (the C allocator's live bytes), the device memory lensmap's allocator holds and the
//!   validation messages are sampled.
//! - **cycles**: `lensmap_context_new`, `lensmap_scene_load`, one frame, `lensmap_scene_free`,
//!   `lensmap_context_free`, over and over, resident memory and the heap sampled between
//!   cycles.
//!
//! [`FramesReport::failures`] and [`CyclesReport::failures`] hold the figures against the
//! plan's [`Bounds`]; the bounds and why they are what they are live with the plans
//! ([`Plan::full`], [`Plan::short`]).

use std::ffi::{CStr, c_char};
use std::ptr::{null, null_mut};
use std::time::Instant;

use lensmap::gpu::DeviceMemory;
use lensmap_capi::*;

const MIB: f64 = 1024.0 * 1024.0;

/// The built-in scenes the soak alternates (both small; two, so that the renderer's upload
/// cache, which keeps the last two frames' meshes and maps, sees each scene's again).
pub const SCENES: [&CStr; 2] = [c"glass-sphere", c"mirror-teapot"];

/// The frame sizes alternated, pixels.
pub const SIZES: [(u32, u32); 2] = [(64, 48), (96, 72)];

/// How far memory may grow past its level once warm before the soak fails, bytes.
#[derive(Clone, Copy, Debug)]
pub struct Bounds {
    /// Resident memory in the frames phase, from the sample at `warm_frames` to any later one
    /// (plus `validation_layer_per_frame` for each frame in between when validation is on).
    pub frames_rss_growth: u64,
    /// Live allocations of the C allocator ([`heap_bytes`]) in the frames phase, from the
    /// sample at `warm_frames` to any later one (plus `validation_layer_per_frame` for each
    /// frame in between when validation is on, and any device block held above the warm
    /// sample's where the heap holds device memory: Mesa 22.3's lavapipe allocates it with
    /// malloc; 25.0 maps it itself, outside the heap, as any hardware driver does).
    pub frames_heap_growth: u64,
    /// What the Khronos validation layer may add to resident memory and the heap per frame,
    /// bytes: its state
    /// grows with every command buffer allocated (layer 1.3.239 leaks 3.1 KB a
    /// `vkAllocateCommandBuffers`, KhronosGroup/Vulkan-ValidationLayers#6033: 7 KB a frame
    /// before lensmap reused its one-off command buffers), which is not lensmap's.
    pub validation_layer_per_frame: u64,
    /// Device memory held through the allocator (its reserved blocks), from the sample at
    /// `warm_frames` to the last one, when the last one's live allocations exceed those of
    /// every sample in the run's first half (else it may hold a block more, as any sample may).
    pub frames_device_growth: u64,
    /// Device memory any sample past `warm_frames` may hold above it for a while: one more
    /// block of the allocator's (64 MiB host-visible) when fragmentation leaves no room, given
    /// back once emptied (measured: 256 MiB at frame 2,000 of the full soak, 192 MiB again by
    /// 2,500).
    pub frames_device_transient: u64,
    /// Resident memory in the cycles phase, from the sample at `warm_cycles` to any later one.
    pub cycles_rss_growth: u64,
    /// Live allocations of the C allocator in the cycles phase, from the sample at
    /// `warm_cycles` to any later one.
    pub cycles_heap_growth: u64,
}

/// What to run and what to hold it to.
#[derive(Clone, Copy, Debug)]
pub struct Plan {
    /// Frames rendered through one context.
    pub frames: u32,
    /// Frames between samples of memory and validation messages.
    pub sample_every: u32,
    /// The sample whose memory is the baseline: by then every option combination of the
    /// schedule has been rendered (its pipelines, targets and buffers made).
    pub warm_frames: u32,
    /// The frames at each end whose median frame times are compared (the drift).
    pub drift_window: u32,
    /// Context and scene cycles.
    pub cycles: u32,
    /// Cycles between samples of resident memory and the heap.
    pub cycle_sample_every: u32,
    /// The cycle sample whose memory is the baseline of the cycles.
    pub warm_cycles: u32,
    /// Face size of the projected layered EMs, texels.
    pub em_size: u32,
    /// Contexts with the Khronos validation layer on (its messages counted and held to zero);
    /// off only to tell the layer's own memory from lensmap's and the driver's.
    pub validation: bool,
    /// The limits on growth.
    pub bounds: Bounds,
}

impl Plan {
    /// The full soak: 10,000 frames, 200 cycles (`tools/scripts/soak.sh`).
    ///
    /// The bounds. The heap (the C allocator's live bytes) carries the leak check: it moves
    /// only when something is allocated and kept, and it sees what resident memory hides, a
    /// leak into memory the allocator had freed. Once warm its floor holds (390.4–390.7 MiB at
    /// the same device memory over two full runs on Mesa 22.3, 212.1–212.6 MiB on 25.0), and a
    /// transient of up to 14.5 MiB (22.3) and 11 MiB (25.0) is there at some samples and not
    /// others: at frame 100, 150 or 200 in different runs of the same schedule, so it follows
    /// the timing, not the schedule; it is still there 300 ms later, so it is kept until a
    /// later frame, not a thread still freeing. The bound is 24 MiB, the largest transient and
    /// 9.5 MiB more, plus the layer's share: over the 9,500 frames after the baseline, 2.6 KiB
    /// a frame beyond the layer's, less than one leaked Vulkan object per frame on lavapipe (an image view, a
    /// descriptor pool or a pipeline each hold more) and less than any of the frame's own
    /// buffers (the largest, its subpixel image read back, is 192 × 144 × 16 B = 432 KiB).
    ///
    /// Resident memory moves without a leak: freed pages stay with the process or go back as
    /// the allocator likes, and what the driver maps itself (its shaders' machine code; device
    /// memory on Mesa 25.0) comes and goes outside the heap. Over the
    /// full run at the same device memory it ranged over 485.6–549.3 MiB (Mesa 22.3; another
    /// run whose frame 500 sat 9.8 MiB under frame 1,000's broke an 8 MiB bound with its heap
    /// flat). Its bound is 128 MiB, twice that 64 MiB spread: 13.8 KiB a frame, which catches
    /// what bypasses the allocator (mapped memory, threads' stacks, JIT code) leaking a few
    /// pages a frame.
    ///
    /// Device memory: every buffer and image is either reused or cached per format, size and
    /// scene, so after the warm-up the allocator holds the same blocks; lens buffers grow only
    /// when a camera needs more vertices than any before. One allocator block (gpu-allocator's
    /// default, 256 MiB device-local, 64 MiB host-visible) would be a real step, so the bound
    /// is 1 MiB: the largest lens buffer of these frames grown once more.
    ///
    /// Cycles: each makes and drops an instance, a device, the validation layer's state, the
    /// pipelines and a scene. What may stay is the handle registry's tombstone per handle
    /// (16 B and a map entry: 2 × 200 × under 64 B = 25 KiB) and the allocator's arenas. The
    /// first ~20 cycles fill the driver's and the allocator's caches (Mesa 22.3, release:
    /// +26 MiB over cycles 0–10, +14.5 over 10–20, +0.2 over 20–30), so the baseline is cycle
    /// 30; 8 MiB over the 170 cycles after it is 48 KiB a cycle, less than one leaked device
    /// or scene. The heap's bound is the same 8 MiB: it moves 13 KiB a cycle with validation on
    /// (Mesa 22.3, +2.2 MiB over cycles 30–200; the layer's: with validation off, heaptrack
    /// finds 31 KB leaked at exit after 40 cycles, none of it per cycle), and a cycle's context
    /// and scene hold 80–120 MiB of it (the table's "held" figure).
    pub fn full() -> Plan {
        Plan {
            frames: 10_000,
            sample_every: 500,
            warm_frames: 500,
            drift_window: 1_000,
            cycles: 200,
            cycle_sample_every: 10,
            warm_cycles: 30,
            em_size: 8,
            validation: true,
            bounds: Bounds {
                frames_rss_growth: 128 << 20,
                frames_heap_growth: 24 << 20,
                // A third of the layer's 3.1 KB per allocated command buffer: with the heap's
                // 24 MiB, 33.3 MiB over 9,500 frames, which lensmap allocating its one-off
                // command buffers again (1.7 a frame: 48 MiB) breaks, and which holds the
                // layer's residual (resident memory in the full soak, 0.58 KB a frame over
                // frames 500 to 9,500 on Mesa 22.3, 0.80 KB to 10,000 on 25.0).
                validation_layer_per_frame: 1 << 10,
                frames_device_growth: 1 << 20,
                frames_device_transient: 64 << 20,
                cycles_rss_growth: 8 << 20,
                cycles_heap_growth: 8 << 20,
            },
        }
    }

    /// The short soak `cargo test` runs: 300 frames, 4 cycles, the same schedule and checks,
    /// and bounds for a run that is not warm yet.
    ///
    /// Frames: resident memory is not warm by then. lavapipe's device memory is the process's
    /// memory (in the heap on Mesa 22.3, mapped by the driver on 25.0), and the pages of the
    /// allocator's 192 MiB of blocks become resident as frames first use them, long after
    /// every option has come round; the allocator keeps or returns freed pages as it likes.
    /// From frame 150 to 300 in the test profile (Mesa 22.3, ten runs on one machine and one
    /// in CI) resident memory moved from −46 to +33 MiB; in the runs that sampled the heap it
    /// moved 1.5 MiB at most beyond its transient. So the heap carries the check: 24 MiB past
    /// frame 150 (plus the layer's 1 KiB a frame) catches a leak through the C allocator of
    /// 164 KiB a frame or more (any leaked readback buffer or frame image of these sizes: 96 ×
    /// 72 subpixels at 2 × 2 in RGBA32F is 432 KiB), and the device memory bound any leaked
    /// target or block at once. Resident memory's bound is the full soak's 128 MiB, twice the
    /// spread measured there: it catches what bypasses the allocator (mapped memory, threads'
    /// stacks, JIT code) at 874 KiB a frame; the full soak's 9,500 warm frames hold it to
    /// 13.8 KiB a frame.
    ///
    /// Cycles: the first cycles grow resident memory while the driver's and the allocator's
    /// caches fill (22.3: +26 MiB over cycles 0–10, +15 over 10–20, +0.2 over 20–30; 25.0:
    /// +8 MiB from cycle 2 to 4; from +2.8 to +23 MiB over cycles 2–4 in the runs of 22.3 here
    /// and in CI), while the heap moved +0.04 MiB. The heap's bound is the full soak's 8 MiB past cycle 2,
    /// less than one leaked context with its scene; resident memory's is 128 MiB. They also
    /// check validation and that a context holds the same device memory every time.
    pub fn short() -> Plan {
        let full = Plan::full();
        Plan {
            frames: 300,
            sample_every: 50,
            warm_frames: 150,
            drift_window: 100,
            cycles: 4,
            cycle_sample_every: 2,
            warm_cycles: 2,
            bounds: Bounds {
                cycles_rss_growth: 128 << 20,
                ..full.bounds
            },
            ..full
        }
    }
}

/// Bytes the C allocator holds for live allocations now: glibc's in-use chunks over all arenas
/// plus the chunks it mapped on its own (`mallinfo2`'s `uordblks + hblkhd`). lensmap (Rust's
/// system allocator), the driver and the validation layer all allocate through it. Unlike
/// resident memory it does not move when allocated pages are first touched (Mesa 22.3's
/// lavapipe mallocs device memory, which becomes resident only as frames use it) or when freed
/// pages stay with the process: it moves when something is allocated and kept.
pub fn heap_bytes() -> u64 {
    // SAFETY: mallinfo2 takes nothing and reads the allocator's statistics under its locks.
    let info = unsafe { libc::mallinfo2() };
    (info.uordblks + info.hblkhd) as u64
}

/// The process's resident memory now (`VmRSS` of `/proc/self/status`), bytes.
pub fn resident_bytes() -> Result<u64, String> {
    let status = std::fs::read_to_string("/proc/self/status")
        .map_err(|e| format!("/proc/self/status: {e}"))?;
    status
        .lines()
        .find_map(|line| line.strip_prefix("VmRSS:"))
        .and_then(|value| value.trim().strip_suffix("kB"))
        .and_then(|kib| kib.trim().parse::<u64>().ok())
        .map(|kib| kib * 1024)
        .ok_or_else(|| "/proc/self/status: no VmRSS line in kB".to_string())
}

fn last_error() -> String {
    // SAFETY: lensmap_last_error returns a NUL-terminated string valid until the next failure.
    unsafe { CStr::from_ptr(lensmap_last_error()) }
        .to_string_lossy()
        .into_owned()
}

/// `Ok` or the call's name, code and last error.
fn ok(call: &str, code: LensmapResult) -> Result<(), String> {
    if code == LensmapResult::Ok {
        Ok(())
    } else {
        Err(format!("{call}: {code:?}: {}", last_error()))
    }
}

fn new_context(validation: bool) -> Result<*mut LensmapContext, String> {
    let options = LensmapContextOptions {
        struct_size: size_of::<LensmapContextOptions>() as u32,
        validation: validation.into(),
        device_name: null(),
    };
    let mut context = null_mut();
    // SAFETY: valid options and out-pointer.
    ok("lensmap_context_new", unsafe {
        lensmap_context_new(&options, &mut context)
    })?;
    Ok(context)
}

fn load_scene(name: &CStr, em_size: u32) -> Result<*mut LensmapScene, String> {
    let options = LensmapSceneOptions {
        struct_size: size_of::<LensmapSceneOptions>() as u32,
        scene: name.as_ptr() as *const c_char,
        bake_dir: null(),
        em_size,
        accept_any_bake: 0,
        light_map_max_texels: 0,
        radiance_dir: null(),
    };
    let mut scene = null_mut();
    // SAFETY: valid options (NUL-terminated strings) and out-pointer.
    ok("lensmap_scene_load", unsafe {
        lensmap_scene_load(&options, &mut scene)
    })?;
    Ok(scene)
}

/// The scene's default frame, as `lensmap_scene_frame_options` fills it.
fn default_frame(scene: *const LensmapScene) -> Result<LensmapFrameOptions, String> {
    let mut options = LensmapFrameOptions {
        struct_size: size_of::<LensmapFrameOptions>() as u32,
        position: [0.0; 3],
        look_at: [0.0; 3],
        up: [0.0; 3],
        vfov_degrees: 0.0,
        width: 0,
        height: 0,
        supersampling: 0,
        t: 0.0,
        variant: 0,
        format: 0,
        blend: 0,
        viewpoint_blending: 0,
        fresnel_texels: 0,
        tracer: 0,
    };
    // SAFETY: a live scene; `options` is writable for its struct_size.
    ok("lensmap_scene_frame_options", unsafe {
        lensmap_scene_frame_options(scene, &mut options)
    })?;
    Ok(options)
}

fn validation_messages(context: *mut LensmapContext) -> Result<u64, String> {
    let mut count = 0;
    // SAFETY: a live context and a writable count.
    ok("lensmap_context_validation_messages", unsafe {
        lensmap_context_validation_messages(context, &mut count)
    })?;
    Ok(count)
}

fn device_memory(context: *mut LensmapContext) -> Result<DeviceMemory, String> {
    // SAFETY: a live context this thread made and no other thread uses.
    unsafe { &*context }
        .device_memory()
        .ok_or_else(|| "the context is busy".to_string())
}

/// Renders `options` into `pixels` (resized to fit), checking the result and the stats.
fn render(
    context: *mut LensmapContext,
    scene: *const LensmapScene,
    options: &LensmapFrameOptions,
    pixels: &mut Vec<f32>,
) -> Result<LensmapFrameStats, String> {
    pixels.resize(4 * options.width as usize * options.height as usize, 0.0);
    let mut stats = LensmapFrameStats {
        struct_size: size_of::<LensmapFrameStats>() as u32,
        ..LensmapFrameStats::default()
    };
    // SAFETY: live handles; `pixels` is writable for its length; `stats` writable.
    ok("lensmap_render_to_memory", unsafe {
        lensmap_render_to_memory(
            context,
            scene,
            options,
            pixels.as_mut_ptr(),
            pixels.len(),
            &mut stats,
        )
    })?;
    if stats.passes == 0 || !stats.total_ms.is_finite() {
        return Err(format!("a frame with implausible stats: {stats:?}"));
    }
    Ok(stats)
}

/// Frame `step` of the schedule, from its scene's default frame `base`: the camera orbits the
/// look-at point (1.3° a frame, bobbing up and down) and the options cycle with coprime
/// periods, so that every combination comes round within the first few hundred frames.
pub fn frame_options(base: &LensmapFrameOptions, step: u32) -> LensmapFrameOptions {
    let angle = (step as f32 * 1.3).to_radians();
    let look = glam::Vec3::from(base.look_at);
    let offset = glam::Vec3::from(base.position) - look;
    let rotated = glam::Quat::from_rotation_y(angle) * offset;
    let bob = glam::Vec3::Y * offset.length() * 0.15 * (step as f32 * 0.05).sin();
    let multipass = step % 2 == 1;
    let (width, height) = SIZES[(step / 4) as usize % SIZES.len()];
    LensmapFrameOptions {
        position: (look + rotated + bob).to_array(),
        width,
        height,
        supersampling: 1 + (step / 8) % 2,
        t: 3.0,
        variant: if multipass {
            LENSMAP_VARIANT_MULTIPASS
        } else {
            LENSMAP_VARIANT_SINGLE_PASS
        },
        blend: if multipass {
            (step / 2) % 4
        } else {
            LENSMAP_BLEND_FRONT_TO_BACK
        },
        format: (step / 3) % 3,
        viewpoint_blending: (step / 16) % 3,
        fresnel_texels: if (step / 32) % 2 == 1 { 64 } else { 0 },
        tracer: if step % 7 == 3 {
            LENSMAP_TRACER_GPU
        } else {
            LENSMAP_TRACER_CPU
        },
        ..*base
    }
}

/// The frames or cycles a growth is measured over.
struct Span {
    /// "frame" or "cycle".
    unit: &'static str,
    from: u32,
    to: u32,
}

/// The failure line when `what` grew from `then` to `now` bytes by more than `bound` over
/// `span`.
fn grew_past(what: &str, now: u64, then: u64, bound: u64, span: Span) -> Option<String> {
    let Span { unit, from, to } = span;
    (now > then + bound).then(|| {
        format!(
            "{what} grew {:.2} MiB from {unit} {from} to {unit} {to} (bound {:.2} MiB)",
            (now - then) as f64 / MIB,
            bound as f64 / MIB
        )
    })
}

/// One sample of the frames phase.
#[derive(Clone, Copy, Debug)]
pub struct Sample {
    /// Frames rendered before it.
    pub frame: u32,
    /// Resident memory, bytes.
    pub rss: u64,
    /// Live allocations of the C allocator ([`heap_bytes`]), bytes.
    pub heap: u64,
    /// Device memory held through lensmap's allocator.
    pub device: DeviceMemory,
    /// Validation messages the context has seen.
    pub validation: u64,
}

/// What the frames phase measured.
#[derive(Clone, Debug)]
pub struct FramesReport {
    /// The plan it ran.
    pub plan: Plan,
    /// Samples at frame 0 and every `sample_every` frames.
    pub samples: Vec<Sample>,
    /// Each frame's time as the host sees it (the `lensmap_render_to_memory` call), ms.
    pub frame_ms: Vec<f64>,
    /// Frames the scene's frame cache reused (a repeated camera).
    pub reused: u32,
    /// Frames traced on the device.
    pub traced_on_gpu: u32,
}

/// Runs the frames phase of `plan`.
pub fn run_frames(plan: &Plan) -> Result<FramesReport, String> {
    let context = new_context(plan.validation)?;
    let scenes = SCENES
        .iter()
        .map(|name| load_scene(name, plan.em_size))
        .collect::<Result<Vec<_>, _>>()?;
    let bases = scenes
        .iter()
        .map(|&scene| default_frame(scene))
        .collect::<Result<Vec<_>, _>>()?;
    let sample = |frame| -> Result<Sample, String> {
        Ok(Sample {
            frame,
            rss: resident_bytes()?,
            heap: heap_bytes(),
            device: device_memory(context)?,
            validation: validation_messages(context)?,
        })
    };
    let mut report = FramesReport {
        plan: *plan,
        samples: vec![sample(0)?],
        frame_ms: Vec::with_capacity(plan.frames as usize),
        reused: 0,
        traced_on_gpu: 0,
    };
    let mut pixels = Vec::new();
    for frame in 0..plan.frames {
        // Every 25th frame repeats the one before: a still camera.
        let step = if frame % 25 == 24 { frame - 1 } else { frame };
        let which = (step / 5) as usize % scenes.len();
        let options = frame_options(&bases[which], step);
        let start = Instant::now();
        let stats = render(context, scenes[which], &options, &mut pixels)
            .map_err(|e| format!("frame {frame} ({options:?}): {e}"))?;
        report.frame_ms.push(start.elapsed().as_secs_f64() * 1e3);
        report.reused += stats.reused;
        report.traced_on_gpu += stats.traced_on_gpu;
        if (frame + 1) % plan.sample_every == 0 {
            report.samples.push(sample(frame + 1)?);
        }
    }
    for scene in scenes {
        // SAFETY: a live scene, freed once.
        ok("lensmap_scene_free", unsafe { lensmap_scene_free(scene) })?;
    }
    // SAFETY: a live context, freed once.
    ok("lensmap_context_free", unsafe {
        lensmap_context_free(context)
    })?;
    Ok(report)
}

/// The median of `values` (NaN for none).
fn median(values: &[f64]) -> f64 {
    let mut sorted = values.to_vec();
    sorted.sort_by(f64::total_cmp);
    match sorted.len() {
        0 => f64::NAN,
        n if n % 2 == 1 => sorted[n / 2],
        n => 0.5 * (sorted[n / 2 - 1] + sorted[n / 2]),
    }
}

/// The least-squares slope of `y` against `x`.
fn slope(points: &[(f64, f64)]) -> f64 {
    let n = points.len() as f64;
    let (mx, my) = points
        .iter()
        .fold((0.0, 0.0), |(sx, sy), (x, y)| (sx + x / n, sy + y / n));
    let (sxy, sxx) = points.iter().fold((0.0, 0.0), |(sxy, sxx), (x, y)| {
        (sxy + (x - mx) * (y - my), sxx + (x - mx) * (x - mx))
    });
    sxy / sxx
}

/// Frame-time drift over the frames phase.
#[derive(Clone, Copy, Debug)]
pub struct Drift {
    /// Median frame time of the first `drift_window` frames, ms.
    pub first_ms: f64,
    /// Median frame time of the last `drift_window` frames, ms.
    pub last_ms: f64,
    /// The least-squares slope of the per-sample-interval medians against the frame number,
    /// ms per 1,000 frames.
    pub slope_ms_per_1000: f64,
}

impl FramesReport {
    /// The sample whose memory is the baseline (at `warm_frames`).
    fn warm(&self) -> Option<&Sample> {
        self.samples
            .iter()
            .find(|s| s.frame == self.plan.warm_frames)
    }

    /// Whether the heap holds the device memory (lavapipe of Mesa 22.3 mallocs it): the heap
    /// grew by at least the reserved device memory from frame 0 to the warm sample. Decides
    /// whether a device block held above the warm sample's counts toward the heap's bound.
    pub fn device_memory_in_heap(&self) -> bool {
        match (self.samples.first(), self.warm()) {
            (Some(first), Some(warm)) => {
                warm.heap.saturating_sub(first.heap) >= warm.device.reserved_bytes
                    && warm.device.reserved_bytes > 0
            }
            _ => false,
        }
    }

    /// The frame times' drift.
    pub fn drift(&self) -> Drift {
        let window = (self.plan.drift_window as usize).min(self.frame_ms.len());
        let every = self.plan.sample_every as usize;
        let points = self
            .frame_ms
            .chunks(every)
            .enumerate()
            .map(|(i, chunk)| ((i * every + chunk.len() / 2) as f64, median(chunk)))
            .collect::<Vec<_>>();
        Drift {
            first_ms: median(&self.frame_ms[..window]),
            last_ms: median(&self.frame_ms[self.frame_ms.len() - window..]),
            slope_ms_per_1000: slope(&points) * 1000.0,
        }
    }

    /// Largest resident, heap and device memory growth past the warm sample (the warm sample
    /// itself counts, so never below 0), bytes.
    pub fn growth(&self) -> [i64; 3] {
        let Some(warm) = self.warm() else {
            return [0; 3];
        };
        let later = self.samples.iter().filter(|s| s.frame >= warm.frame);
        later.fold([i64::MIN; 3], |[rss, heap, device], s| {
            [
                rss.max(s.rss as i64 - warm.rss as i64),
                heap.max(s.heap as i64 - warm.heap as i64),
                device.max(s.device.reserved_bytes as i64 - warm.device.reserved_bytes as i64),
            ]
        })
    }

    /// How far memory bounded by `growth` (resident or heap) may grow over `frames` frames
    /// past the warm sample, bytes: `growth` plus the validation layer's share.
    pub fn bound(&self, growth: u64, frames: u32) -> u64 {
        let layer = if self.plan.validation {
            self.plan.bounds.validation_layer_per_frame * u64::from(frames)
        } else {
            0
        };
        growth + layer
    }

    /// What broke the plan's bounds, one line each; empty when the soak held.
    pub fn failures(&self) -> Vec<String> {
        let mut failures = Vec::new();
        let Some(warm) = self.warm() else {
            return vec![format!(
                "no sample at the warm frame {} (samples every {})",
                self.plan.warm_frames, self.plan.sample_every
            )];
        };
        for s in &self.samples {
            if s.validation != 0 {
                failures.push(format!(
                    "{} validation messages by frame {} (see stderr)",
                    s.validation, s.frame
                ));
                break;
            }
        }
        let bounds = self.plan.bounds;
        let device_memory_in_heap = self.device_memory_in_heap();
        for s in self.samples.iter().filter(|s| s.frame > warm.frame) {
            // Device memory is checked on its own below; on lavapipe its blocks are also
            // resident (and on Mesa 22.3 in the heap), so a block held for a while is not
            // counted twice.
            let blocks = s
                .device
                .reserved_bytes
                .saturating_sub(warm.device.reserved_bytes);
            let heap_blocks = if device_memory_in_heap { blocks } else { 0 };
            let measures = [
                (
                    "resident memory",
                    s.rss,
                    warm.rss,
                    bounds.frames_rss_growth,
                    blocks,
                ),
                (
                    "the heap",
                    s.heap,
                    warm.heap,
                    bounds.frames_heap_growth,
                    heap_blocks,
                ),
            ];
            for (what, now, then, growth, blocks) in measures {
                let bound = self.bound(growth, s.frame - warm.frame) + blocks;
                let span = Span {
                    unit: "frame",
                    from: warm.frame,
                    to: s.frame,
                };
                failures.extend(grew_past(what, now, then, bound, span));
            }
            let last = self.samples.last().is_some_and(|l| l.frame == s.frame);
            // The last sample may also fall while fragmentation holds a block, which tells
            // nothing of a leak when lensmap's live allocations (bytes and count) are no more
            // than at the samples of the run's first half past frame 0 (the schedule repeats,
            // so those samples saw the same states, and a slow leak had not yet accumulated);
            // otherwise it is held to `frames_device_growth`. The first half starts at frame 0,
            // not at the warm sample: in the short soak that would leave one sample, frame 200,
            // whose state held 104 allocations where frame 300's held 108 and frame 50's 110
            // (a CI run on Mesa 25.0 whose allocator took a second host-visible block at frame
            // 200 failed so, every live figure within those of frame 50).
            let first_half = self
                .samples
                .iter()
                .filter(|e| e.frame > 0 && e.frame <= self.plan.frames / 2);
            let fragmented = first_half
                .fold(None, |most: Option<(u64, u64)>, e| {
                    let (bytes, count) = most.unwrap_or_default();
                    Some((
                        bytes.max(e.device.allocated_bytes),
                        count.max(e.device.allocations),
                    ))
                })
                .is_some_and(|(bytes, count)| {
                    s.device.allocated_bytes <= bytes && s.device.allocations <= count
                });
            let device_bound = if last && !fragmented {
                bounds.frames_device_growth
            } else {
                bounds.frames_device_transient
            };
            if s.device.reserved_bytes > warm.device.reserved_bytes + device_bound {
                failures.push(format!(
                    "device memory grew {:.2} MiB from frame {} to frame {} (bound {:.2} MiB)",
                    (s.device.reserved_bytes - warm.device.reserved_bytes) as f64 / MIB,
                    warm.frame,
                    s.frame,
                    device_bound as f64 / MIB
                ));
            }
        }
        failures
    }

    /// The figures as text: one line per sample, then the drift.
    pub fn table(&self) -> String {
        let mut text = String::from(
            "frame   resident MiB   heap MiB   device allocated MiB   device reserved MiB   allocations   validation   median ms (since last sample)\n",
        );
        let every = self.plan.sample_every as usize;
        for s in &self.samples {
            // No frame before the first sample: its cell is empty, not a median of nothing.
            let end = (s.frame as usize).min(self.frame_ms.len());
            let before = &self.frame_ms[end.saturating_sub(every)..end];
            let since = if before.is_empty() {
                String::new()
            } else {
                format!("{:.2}", median(before))
            };
            text += &format!(
                "{:>6}   {:>12.2}   {:>8.2}   {:>20.2}   {:>19.2}   {:>11}   {:>10}   {:>8}\n",
                s.frame,
                s.rss as f64 / MIB,
                s.heap as f64 / MIB,
                s.device.allocated_bytes as f64 / MIB,
                s.device.reserved_bytes as f64 / MIB,
                s.device.allocations,
                s.validation,
                since
            );
        }
        let drift = self.drift();
        let [rss, heap, device] = self.growth();
        let warm_frames = self.plan.frames.saturating_sub(self.plan.warm_frames);
        text += &format!(
            "largest growth past frame {}: resident {:+.2} MiB, heap {:+.2} MiB (bounds {:.2} and {:.2} at the end, plus any device block held above the warm sample's, for the heap {}; validation {}), device reserved {:+.2} MiB (bound {:.2} at the end when its live allocations exceed those of every sample in the run's first half, else {:.2})\n",
            self.plan.warm_frames,
            rss as f64 / MIB,
            heap as f64 / MIB,
            self.bound(self.plan.bounds.frames_rss_growth, warm_frames) as f64 / MIB,
            self.bound(self.plan.bounds.frames_heap_growth, warm_frames) as f64 / MIB,
            if self.device_memory_in_heap() {
                "too (it holds the device memory)"
            } else {
                "not (device memory is outside it)"
            },
            if self.plan.validation { "on" } else { "off" },
            device as f64 / MIB,
            self.plan.bounds.frames_device_growth as f64 / MIB,
            self.plan.bounds.frames_device_transient as f64 / MIB
        );
        text += &format!(
            "frame time: median of the first {w} frames {:.2} ms, of the last {w} {:.2} ms ({:+.1} %); slope {:+.3} ms per 1,000 frames\n",
            drift.first_ms,
            drift.last_ms,
            (drift.last_ms / drift.first_ms - 1.0) * 100.0,
            drift.slope_ms_per_1000,
            w = self.plan.drift_window,
        );
        text += &format!(
            "frames: {} ({} reused by the frame cache, {} traced on the device)\n",
            self.frame_ms.len(),
            self.reused,
            self.traced_on_gpu
        );
        text
    }
}

/// One sample of the cycles phase.
#[derive(Clone, Copy, Debug)]
pub struct CycleSample {
    /// Cycles done before it.
    pub cycle: u32,
    /// Resident memory, bytes.
    pub rss: u64,
    /// Live allocations of the C allocator ([`heap_bytes`]), bytes.
    pub heap: u64,
}

impl CycleSample {
    fn now(cycle: u32) -> Result<CycleSample, String> {
        Ok(CycleSample {
            cycle,
            rss: resident_bytes()?,
            heap: heap_bytes(),
        })
    }
}

/// What the cycles phase measured.
#[derive(Clone, Debug)]
pub struct CyclesReport {
    /// The plan it ran.
    pub plan: Plan,
    /// Samples at 0 and every `cycle_sample_every` cycles.
    pub samples: Vec<CycleSample>,
    /// Validation messages over every cycle's context.
    pub validation: u64,
    /// Device memory held during each cycle's frame, before its scene was freed.
    pub device: Vec<DeviceMemory>,
    /// The heap during each cycle's frame less the sample before the cycle: what one leaked
    /// cycle would leave (with the transients of a frame), bytes.
    pub held: Vec<i64>,
    /// Each cycle's time, ms.
    pub cycle_ms: Vec<f64>,
}

/// Runs the cycles phase of `plan`: context, scene, one frame, free, `plan.cycles` times.
pub fn run_cycles(plan: &Plan) -> Result<CyclesReport, String> {
    let mut report = CyclesReport {
        plan: *plan,
        samples: vec![CycleSample::now(0)?],
        validation: 0,
        device: Vec::new(),
        held: Vec::new(),
        cycle_ms: Vec::new(),
    };
    let mut pixels = Vec::new();
    for cycle in 0..plan.cycles {
        let start = Instant::now();
        let before = heap_bytes();
        let context = new_context(plan.validation)?;
        let scene = load_scene(SCENES[cycle as usize % SCENES.len()], plan.em_size)?;
        // The same scene and options every other cycle: their device memory must be the same.
        let options = frame_options(&default_frame(scene)?, cycle % SCENES.len() as u32);
        render(context, scene, &options, &mut pixels).map_err(|e| format!("cycle {cycle}: {e}"))?;
        report.device.push(device_memory(context)?);
        report.held.push(heap_bytes() as i64 - before as i64);
        report.validation += validation_messages(context)?;
        // SAFETY: live handles, each freed once.
        unsafe {
            ok("lensmap_scene_free", lensmap_scene_free(scene))?;
            ok("lensmap_context_free", lensmap_context_free(context))?;
        }
        report.cycle_ms.push(start.elapsed().as_secs_f64() * 1e3);
        if (cycle + 1) % plan.cycle_sample_every == 0 {
            report.samples.push(CycleSample::now(cycle + 1)?);
        }
    }
    Ok(report)
}

impl CyclesReport {
    /// The sample at `cycle`, if there is one.
    pub fn at(&self, cycle: u32) -> Option<&CycleSample> {
        self.samples.iter().find(|s| s.cycle == cycle)
    }

    /// Largest resident and heap growth past the warm sample, bytes.
    pub fn growth(&self) -> [i64; 2] {
        let Some(warm) = self.at(self.plan.warm_cycles) else {
            return [0; 2];
        };
        let later = self.samples.iter().filter(|s| s.cycle >= warm.cycle);
        later.fold([i64::MIN; 2], |[rss, heap], s| {
            [
                rss.max(s.rss as i64 - warm.rss as i64),
                heap.max(s.heap as i64 - warm.heap as i64),
            ]
        })
    }

    /// What broke the plan's bounds, one line each; empty when the cycles held.
    pub fn failures(&self) -> Vec<String> {
        let mut failures = Vec::new();
        if self.validation != 0 {
            failures.push(format!(
                "{} validation messages over the cycles (see stderr)",
                self.validation
            ));
        }
        let Some(warm) = self.at(self.plan.warm_cycles) else {
            failures.push(format!(
                "no sample at the warm cycle {}",
                self.plan.warm_cycles
            ));
            return failures;
        };
        let bounds = self.plan.bounds;
        for s in self.samples.iter().filter(|s| s.cycle > warm.cycle) {
            let measures = [
                ("resident memory", s.rss, warm.rss, bounds.cycles_rss_growth),
                ("the heap", s.heap, warm.heap, bounds.cycles_heap_growth),
            ];
            for (what, now, then, bound) in measures {
                let span = Span {
                    unit: "cycle",
                    from: warm.cycle,
                    to: s.cycle,
                };
                failures.extend(grew_past(what, now, then, bound, span));
            }
        }
        // The same scene and frame in a fresh context hold the same device memory.
        for (cycle, device) in self.device.iter().enumerate().skip(SCENES.len()) {
            let first = &self.device[cycle % SCENES.len()];
            if device.reserved_bytes != first.reserved_bytes {
                failures.push(format!(
                    "cycle {cycle} held {} B of device memory, cycle {} of the same scene {} B",
                    device.reserved_bytes,
                    cycle % SCENES.len(),
                    first.reserved_bytes
                ));
            }
        }
        failures
    }

    /// The figures as text.
    pub fn table(&self) -> String {
        let mut text = String::from("cycle   resident MiB   heap MiB\n");
        for s in &self.samples {
            text += &format!(
                "{:>5}   {:>12.2}   {:>8.2}\n",
                s.cycle,
                s.rss as f64 / MIB,
                s.heap as f64 / MIB
            );
        }
        let [rss, heap] = self.growth();
        text += &format!(
            "growth from cycle {}: resident {:+.2} MiB, heap {:+.2} MiB (bounds {:.2} and {:.2}); heap held by a cycle's context and scene: {:.2} MiB at least; validation messages {}; median cycle {:.0} ms\n",
            self.plan.warm_cycles,
            rss as f64 / MIB,
            heap as f64 / MIB,
            self.plan.bounds.cycles_rss_growth as f64 / MIB,
            self.plan.bounds.cycles_heap_growth as f64 / MIB,
            self.held.iter().min().copied().unwrap_or(0) as f64 / MIB,
            self.validation,
            median(&self.cycle_ms)
        );
        text
    }
}

/// The device and driver lensmap picks (as `lensmap_context_new` with no device name does),
/// from a probe without validation that is dropped at once.
pub fn device_named() -> String {
    match lensmap::gpu::Gpu::new(&lensmap::gpu::GpuOptions::default()) {
        Ok(gpu) => gpu.device_id().to_string(),
        Err(error) => format!("(no device: {error})"),
    }
}
