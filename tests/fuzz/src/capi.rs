//! The C ABI target: one context, made once per process (a Vulkan device per input would cost
//! more than the input), and per input a short program of calls whose values, struct sizes and
//! strings come from the input: `lensmap_scene_load`, `lensmap_scene_frame_options`,
//! `lensmap_render_to_memory`, `lensmap_plan_text`, `lensmap_scene_free`,
//! `lensmap_context_validation_messages`. Every pointer the harness passes is valid for what it
//! claims (a struct buffer is at least `struct_size` bytes, `rgba` holds `rgba_floats` floats,
//! a handle is NULL, live, freed or of the other kind, all of which the ABI must refuse
//! cleanly): raw bytes in pointer fields would be undefined behaviour, not findings.
//!
//! A finding is a panic here: `LENSMAP_RESULT_PANIC` (a bug caught at the boundary), a failure
//! whose `lensmap_last_error` is not one non-empty line, or a new validation message.
//! Frames are kept small: a width or height that fits the ABI's limits is folded to at most
//! [`MAX_RENDER_SIDE`] subpixels so that lavapipe renders it in milliseconds; values past the
//! limits are passed unchanged, to reach the refusals.

use std::ffi::{CStr, CString, c_char};
use std::path::PathBuf;

use lensmap_capi::*;

/// The widest or tallest frame the harness renders, in subpixels (width × supersampling).
pub const MAX_RENDER_SIDE: u32 = 24;

/// The largest dimension the ABI accepts, in subpixels; bigger values reach the refusal as is.
const SUBPIXEL_LIMIT: u64 = 16384;

/// The most calls one input makes.
const MAX_CALLS: usize = 6;

/// A small scene file the harness writes beside its scratch files: a glass ball over a floor
/// (loads and renders in milliseconds), the one the reader targets place their assets in.
const SMALL_SCENE: &str = include_str!("small-scene.toml");

/// The input, read front to back; past its end every read is zero.
struct Input<'a> {
    data: &'a [u8],
}

impl Input<'_> {
    fn bytes(&mut self, count: usize) -> &[u8] {
        let (taken, rest) = self.data.split_at(count.min(self.data.len()));
        self.data = rest;
        taken
    }

    fn u8(&mut self) -> u8 {
        self.bytes(1).first().copied().unwrap_or(0)
    }

    fn u32(&mut self) -> u32 {
        let mut word = [0; 4];
        let taken = self.bytes(4);
        word[..taken.len()].copy_from_slice(taken);
        u32::from_le_bytes(word)
    }

    fn u64(&mut self) -> u64 {
        u64::from(self.u32()) | (u64::from(self.u32()) << 32)
    }

    fn f32(&mut self) -> f32 {
        f32::from_bits(self.u32())
    }

    fn is_empty(&self) -> bool {
        self.data.is_empty()
    }

    /// A string of up to 255 bytes (its length first), cut at its first NUL.
    fn c_string(&mut self) -> CString {
        let length = usize::from(self.u8());
        let bytes = self.bytes(length);
        let end = bytes.iter().position(|&b| b == 0).unwrap_or(bytes.len());
        CString::new(&bytes[..end]).unwrap_or_default()
    }
}

/// The process's context and scratch folder, made by [`Harness::new`].
pub struct Harness {
    context: *mut LensmapContext,
    dir: PathBuf,
    small_scene: CString,
}

impl Harness {
    /// Makes the context (lensmap's own device; validation on when `validation`) and writes
    /// the small scene file into a scratch folder. Panics when no device can be made: the
    /// harness cannot run at all then.
    pub fn new(validation: bool) -> Harness {
        let dir = std::env::temp_dir().join(format!("lensmap-fuzz-capi-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap_or_else(|e| panic!("harness: {}: {e}", dir.display()));
        let scene_path = dir.join("small.toml");
        std::fs::write(&scene_path, SMALL_SCENE)
            .unwrap_or_else(|e| panic!("harness: {}: {e}", scene_path.display()));
        let options = LensmapContextOptions {
            struct_size: size_of::<LensmapContextOptions>() as u32,
            validation: u32::from(validation),
            device_name: std::ptr::null(),
        };
        let mut context = std::ptr::null_mut();
        // SAFETY: valid options and out-pointer.
        let result = unsafe { lensmap_context_new(&options, &mut context) };
        assert_eq!(
            result,
            LensmapResult::Ok,
            "harness: no context: {}",
            last_error()
        );
        Harness {
            context,
            dir,
            small_scene: CString::new(scene_path.to_string_lossy().as_bytes())
                .expect("a temporary path without NUL"),
        }
    }

    /// Validation messages the context has seen.
    fn validation_messages(&self) -> u64 {
        let mut count = 0;
        // SAFETY: a live context and a writable count.
        let result = unsafe { lensmap_context_validation_messages(self.context, &mut count) };
        assert_eq!(result, LensmapResult::Ok, "{}", last_error());
        count
    }

    /// Runs one input's calls. Ok holds the results in order (for the tests to look at);
    /// a finding panics.
    pub fn run(&self, data: &[u8]) -> Vec<LensmapResult> {
        let before = self.validation_messages();
        let mut input = Input { data };
        let mut session = Session {
            harness: self,
            scene: std::ptr::null_mut(),
            freed: std::ptr::null_mut(),
            results: Vec::new(),
            newline_in_input: data.contains(&b'\n'),
        };
        for _ in 0..MAX_CALLS {
            if input.is_empty() {
                break;
            }
            session.call(&mut input);
        }
        session.free_all();
        let after = self.validation_messages();
        assert_eq!(after, before, "validation messages during this input");
        session.results
    }
}

impl Drop for Harness {
    fn drop(&mut self) {
        // SAFETY: the context this harness made, freed once.
        unsafe { lensmap_context_free(self.context) };
        let _ = std::fs::remove_dir_all(&self.dir);
    }
}

/// The last error's text.
fn last_error() -> String {
    // SAFETY: lensmap_last_error returns a NUL-terminated string valid until the next failure.
    unsafe { CStr::from_ptr(lensmap_last_error()) }
        .to_string_lossy()
        .into_owned()
}

/// Checks one call's result: no panic caught at the boundary, and a failure says one line
/// (more only when `newline_in_input`: messages quote the caller's paths and names as given,
/// and a path may hold a newline).
fn check(call: &str, result: LensmapResult, newline_in_input: bool) -> LensmapResult {
    assert_ne!(result, LensmapResult::Panic, "{call}: {}", last_error());
    if result != LensmapResult::Ok {
        let message = last_error();
        assert!(
            !message.is_empty() && (newline_in_input || !message.contains('\n')),
            "{call} returned {result:?} with the message {message:?}"
        );
    }
    result
}

/// A buffer of at least `size` and at least `size_of::<T>()` bytes, 8-byte aligned, holding
/// `value` then `tail` bytes from the input: what a caller of a struct of size `size` owns.
fn struct_buffer<T: Copy>(value: T, size: usize, input: &mut Input<'_>) -> Vec<u64> {
    let bytes = size.max(size_of::<T>());
    let mut buffer = vec![0u64; bytes.div_ceil(8)];
    // SAFETY: the buffer holds at least size_of::<T>() bytes and is 8-aligned (T's alignment
    // is at most 8); T is plain data.
    unsafe { std::ptr::write(buffer.as_mut_ptr() as *mut T, value) };
    // The bytes past T: input bytes (never read by the ABI unless it misjudges a size).
    let tail = input.bytes(bytes - size_of::<T>()).to_vec();
    // SAFETY: within the buffer's bytes.
    let raw =
        unsafe { std::slice::from_raw_parts_mut(buffer.as_mut_ptr() as *mut u8, buffer.len() * 8) };
    raw[size_of::<T>()..size_of::<T>() + tail.len()].copy_from_slice(&tail);
    buffer
}

/// A struct size from the input: mostly this ABI's or an earlier one's, sometimes anything
/// up to 64 KiB.
fn struct_size(input: &mut Input<'_>, current: usize, older: &[usize]) -> usize {
    let choice = input.u8();
    match choice % 4 {
        0 | 1 => current,
        2 => older
            .get(usize::from(choice / 4) % older.len().max(1))
            .copied()
            .unwrap_or(current),
        _ => usize::from(input.u32() as u16),
    }
}

/// A width or height: past the ABI's limit (with `supersampling`), unchanged; else folded into
/// 1..=MAX_RENDER_SIDE subpixels (0 stays 0, to reach its refusal).
fn frame_side(value: u32, supersampling: u32) -> u32 {
    let subpixels = u64::from(value) * u64::from(supersampling.max(1));
    if value == 0 || subpixels > SUBPIXEL_LIMIT {
        value
    } else {
        let most = (MAX_RENDER_SIDE / supersampling.clamp(1, MAX_RENDER_SIDE)).max(1);
        1 + (value - 1) % most
    }
}

/// One input's state: the scene loaded last and one freed.
struct Session<'a> {
    harness: &'a Harness,
    scene: *mut LensmapScene,
    freed: *mut LensmapScene,
    results: Vec<LensmapResult>,
    /// Whether the input holds a newline (which a string the harness passes may then hold).
    newline_in_input: bool,
}

impl Session<'_> {
    /// A scene handle from the input: the live one, NULL, a freed one or the context.
    fn scene_handle(&self, input: &mut Input<'_>) -> *const LensmapScene {
        match input.u8() % 8 {
            0 => std::ptr::null(),
            1 => self.freed,
            2 => self.harness.context as *const LensmapScene,
            _ => self.scene,
        }
    }

    fn record(&mut self, call: &str, result: LensmapResult) -> LensmapResult {
        let result = check(call, result, self.newline_in_input);
        self.results.push(result);
        result
    }

    fn call(&mut self, input: &mut Input<'_>) {
        match input.u8() % 8 {
            0 | 1 => self.scene_load(input),
            2 => self.frame_options(input),
            3 | 4 => self.render(input),
            5 => self.plan_text(input),
            6 => self.free_scene(),
            _ => {
                let mut count = 0;
                // SAFETY: a live context and a writable count.
                let result = unsafe {
                    lensmap_context_validation_messages(self.harness.context, &mut count)
                };
                self.record("lensmap_context_validation_messages", result);
            }
        }
    }

    fn scene_load(&mut self, input: &mut Input<'_>) {
        let scene_file = self.harness.dir.join("input.toml");
        let scene = match input.u8() % 4 {
            0 | 1 => self.harness.small_scene.clone(),
            2 => {
                // A scene file from the input.
                let length = usize::from(input.u32() as u16);
                std::fs::write(&scene_file, input.bytes(length))
                    .unwrap_or_else(|e| panic!("harness: {}: {e}", scene_file.display()));
                CString::new(scene_file.to_string_lossy().as_bytes()).expect("no NUL")
            }
            _ => input.c_string(),
        };
        let bake_dir = match input.u8() % 4 {
            0 | 1 => None,
            2 => Some(CString::new(self.harness.dir.to_string_lossy().as_bytes()).expect("no NUL")),
            _ => Some(input.c_string()),
        };
        let radiance_dir = match input.u8() % 4 {
            0..=2 => None,
            _ => Some(input.c_string()),
        };
        let em_size = match input.u8() % 4 {
            0 | 1 => 8,
            2 => 0,
            _ => input.u32(),
        };
        let light_map_max_texels = match input.u8() % 4 {
            0 | 1 => 65_536,
            _ => input.u64(),
        };
        let options = LensmapSceneOptions {
            struct_size: 0,
            scene: if matches!(input.u8() % 16, 0) {
                std::ptr::null()
            } else {
                scene.as_ptr()
            },
            bake_dir: bake_dir.as_ref().map_or(std::ptr::null(), |s| s.as_ptr()),
            em_size,
            accept_any_bake: u32::from(input.u8()),
            light_map_max_texels,
            radiance_dir: radiance_dir
                .as_ref()
                .map_or(std::ptr::null(), |s| s.as_ptr()),
        };
        let size = struct_size(input, size_of::<LensmapSceneOptions>(), &[32]);
        let mut buffer = struct_buffer(options, size, input);
        // SAFETY: the buffer starts with the struct; its size field is the first u32.
        unsafe { *(buffer.as_mut_ptr() as *mut u32) = size as u32 };
        let mut out = std::ptr::null_mut();
        // SAFETY: the buffer holds at least `size` bytes; its strings live until after the call.
        let result =
            unsafe { lensmap_scene_load(buffer.as_ptr() as *const LensmapSceneOptions, &mut out) };
        if self.record("lensmap_scene_load", result) == LensmapResult::Ok {
            self.replace_scene(out);
        }
    }

    fn replace_scene(&mut self, scene: *mut LensmapScene) {
        self.free_scene();
        self.scene = scene;
    }

    fn free_scene(&mut self) {
        let scene = std::mem::replace(&mut self.scene, std::ptr::null_mut());
        // SAFETY: NULL, or a live scene of this session (freed once; a second free of the
        // freed one is refused by the registry).
        let result = unsafe { lensmap_scene_free(scene) };
        self.record("lensmap_scene_free", result);
        if !scene.is_null() {
            self.freed = scene;
        }
    }

    fn frame_options(&mut self, input: &mut Input<'_>) {
        let scene = self.scene_handle(input);
        let size = struct_size(input, size_of::<LensmapFrameOptions>(), &[68, 72, 76, 80]);
        let mut buffer = struct_buffer(
            LensmapFrameOptions {
                struct_size: size as u32,
                ..blank_frame_options()
            },
            size,
            input,
        );
        // SAFETY: the buffer is writable for at least `size` bytes.
        let result = unsafe {
            lensmap_scene_frame_options(scene, buffer.as_mut_ptr() as *mut LensmapFrameOptions)
        };
        self.record("lensmap_scene_frame_options", result);
    }

    fn render(&mut self, input: &mut Input<'_>) {
        // The scene's own options first, then fields from the input.
        let mut options = blank_frame_options();
        if !self.scene.is_null() {
            options.struct_size = size_of::<LensmapFrameOptions>() as u32;
            // SAFETY: a live scene and a writable struct of the current size.
            let result = unsafe { lensmap_scene_frame_options(self.scene, &mut options) };
            self.record("lensmap_scene_frame_options", result);
        }
        let fields = input.u32();
        let field = |bit: u32| fields & (1 << bit) != 0;
        if field(0) {
            options.position = [input.f32(), input.f32(), input.f32()];
        }
        if field(1) {
            options.look_at = [input.f32(), input.f32(), input.f32()];
        }
        if field(2) {
            options.up = [input.f32(), input.f32(), input.f32()];
        }
        if field(3) {
            options.vfov_degrees = input.f32();
        }
        if field(4) {
            options.supersampling = input.u32();
        }
        if field(5) {
            options.width = input.u32();
        }
        if field(6) {
            options.height = input.u32();
        }
        if field(7) {
            options.t = input.f32();
        }
        if field(8) {
            options.variant = input.u32();
        }
        if field(9) {
            options.format = input.u32();
        }
        if field(10) {
            options.blend = input.u32();
        }
        if field(11) {
            options.viewpoint_blending = input.u32();
        }
        if field(12) {
            options.fresnel_texels = input.u32();
        }
        if field(13) {
            options.tracer = input.u32();
        }
        // Small frames only (see the module documentation); t ≥ 1 subpixel keeps the lens's
        // tessellation small unless t is past its limits.
        options.supersampling = match options.supersampling {
            s @ 0..=4 => s,
            s if u64::from(s) > SUBPIXEL_LIMIT => s,
            s => 1 + s % 4,
        };
        options.width = frame_side(options.width, options.supersampling);
        options.height = frame_side(options.height, options.supersampling);
        if options.t.is_finite() && options.t > 0.0 && options.t < 1.0 {
            options.t += 1.0;
        }
        let scene = self.scene_handle(input);
        let size = struct_size(input, size_of::<LensmapFrameOptions>(), &[68, 72, 76, 80]);
        options.struct_size = size as u32;
        let buffer = struct_buffer(options, size, input);
        let pixels = u64::from(options.width) * u64::from(options.height);
        let floats = if pixels <= u64::from(MAX_RENDER_SIDE * MAX_RENDER_SIDE) {
            4 * pixels as usize
        } else {
            16
        };
        let mut rgba = vec![0f32; floats];
        let claimed =
            floats - usize::from(matches!(input.u8() % 4, 0)) * usize::from(input.u8()).min(floats);
        let stats_size = match input.u8() % 4 {
            0 => None,
            1 => Some(usize::from(input.u32() as u16)),
            _ => Some(size_of::<LensmapFrameStats>()),
        };
        let mut stats = stats_size.map(|size| {
            let mut buffer = vec![0u64; size.max(size_of::<LensmapFrameStats>()).div_ceil(8)];
            // SAFETY: the buffer starts with the struct's size field.
            unsafe { *(buffer.as_mut_ptr() as *mut u32) = size as u32 };
            buffer
        });
        let stats_pointer = stats.as_mut().map_or(std::ptr::null_mut(), |b| {
            b.as_mut_ptr() as *mut LensmapFrameStats
        });
        // SAFETY: the options buffer holds `size` bytes, rgba `claimed` floats, stats NULL or
        // its struct_size bytes; the handles are NULL, live, freed or of the other kind.
        let result = unsafe {
            lensmap_render_to_memory(
                self.harness.context,
                scene,
                buffer.as_ptr() as *const LensmapFrameOptions,
                rgba.as_mut_ptr(),
                claimed,
                stats_pointer,
            )
        };
        if self.record("lensmap_render_to_memory", result) == LensmapResult::Ok {
            assert!(
                rgba.iter().all(|v| v.is_finite()),
                "lensmap_render_to_memory wrote a NaN or infinite value"
            );
        }
    }

    fn plan_text(&mut self, input: &mut Input<'_>) {
        let options = LensmapPlanOptions {
            struct_size: 0,
            layers: input.u32() % 64,
            viewpoints: input.u32() % 8,
            terms: input.u32() % 8,
            variant: input.u32() % 4,
            format: input.u32() % 4,
            blend: input.u32() % 8,
        };
        // A raw value for one field, past the folded ranges.
        let mut options = options;
        match input.u8() % 8 {
            0 => options.layers = input.u32(),
            1 => options.viewpoints = input.u32(),
            2 => options.terms = input.u32(),
            3 => options.variant = input.u32(),
            4 => options.format = input.u32(),
            5 => options.blend = input.u32(),
            _ => {}
        }
        let size = struct_size(input, size_of::<LensmapPlanOptions>(), &[]);
        options.struct_size = size as u32;
        let buffer = struct_buffer(options, size, input);
        let options = buffer.as_ptr() as *const LensmapPlanOptions;
        let mut length = 0usize;
        // SAFETY: the options buffer holds `size` bytes; a size query writes only `length`.
        let result = unsafe { lensmap_plan_text(options, std::ptr::null_mut(), 0, &mut length) };
        if self.record("lensmap_plan_text", result) != LensmapResult::Ok {
            return;
        }
        let capacity = match input.u8() % 4 {
            0 => length,
            _ => length + 1,
        };
        let mut text = vec![0 as c_char; capacity.max(1)];
        // SAFETY: the buffer is writable for `capacity` bytes.
        let result =
            unsafe { lensmap_plan_text(options, text.as_mut_ptr(), capacity, &mut length) };
        if self.record("lensmap_plan_text", result) == LensmapResult::Ok {
            assert_eq!(
                text[length], 0,
                "lensmap_plan_text: the text is not NUL-terminated"
            );
        }
    }

    fn free_all(&mut self) {
        self.free_scene();
    }
}

/// Frame options of zeros (a struct the input fills).
fn blank_frame_options() -> LensmapFrameOptions {
    LensmapFrameOptions {
        struct_size: 0,
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
    }
}
