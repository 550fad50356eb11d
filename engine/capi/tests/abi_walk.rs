//! The numeric fields of the C ABI's versioned structs, each tried with 0, 1, 2³¹, 2³² − 1 and,
//! for floats, −1, NaN, ±∞ and f32::MAX, one field at a time from a good struct: every call
//! returns `LENSMAP_RESULT_OK` or a documented refusal with a one-line message, never a panic
//! or an internal error, and nothing is allocated for a size before it is checked (a huge frame
//! is refused, not attempted). Validation is on and must stay silent.

use std::ffi::CStr;
use std::ptr::{null, null_mut};

use lensmap_capi::*;

const UNSIGNED: [u64; 5] = [0, 1, 1 << 31, u32::MAX as u64, u32::MAX as u64 - 1];
const FLOATS: [f32; 8] = [
    0.0,
    1.0,
    -1.0,
    f32::NAN,
    f32::INFINITY,
    f32::NEG_INFINITY,
    f32::MAX,
    4_294_967_296.0,
];

/// A named field of struct `S` and how to set it to a value of type `V`.
type Field<S, V> = (&'static str, fn(&mut S, V));

fn last_error() -> String {
    // SAFETY: the library's message is a valid C string until the next call on this thread.
    unsafe { CStr::from_ptr(lensmap_last_error()) }
        .to_string_lossy()
        .into_owned()
}

/// `code` is a success or a refusal the ABI documents for bad input, with one line saying why.
fn judged(code: LensmapResult, what: &str, failures: &mut Vec<String>) {
    use LensmapResult::*;
    match code {
        Ok => {}
        InvalidArgument | BufferTooSmall | UnsupportedFormat | Scene | Bake | Device
            if !last_error().is_empty() && !last_error().contains('\n') => {}
        code => failures.push(format!("{what}: {code:?} ({})", last_error())),
    }
}

#[test]
fn every_numeric_field_of_the_versioned_structs_is_checked_before_use() {
    lensmap_tests::one_validated_test_at_a_time();
    let mut context = null_mut();
    let options = LensmapContextOptions {
        struct_size: size_of::<LensmapContextOptions>() as u32,
        validation: 1,
        device_name: null(),
    };
    // SAFETY: valid options and out-pointer.
    let code = unsafe { lensmap_context_new(&options, &mut context) };
    assert_eq!(code, LensmapResult::Ok, "{}", last_error());
    let mut failures = Vec::new();
    let mut tried = 0usize;

    // Scene options: the EM size and the light maps' texel budget.
    let good_scene = LensmapSceneOptions {
        struct_size: size_of::<LensmapSceneOptions>() as u32,
        scene: c"glass-sphere".as_ptr(),
        bake_dir: null(),
        em_size: 8,
        accept_any_bake: 0,
        light_map_max_texels: 0,
        radiance_dir: null(),
    };
    let scene_fields: [Field<LensmapSceneOptions, u64>; 3] = [
        ("em_size", |o, v| o.em_size = v as u32),
        ("accept_any_bake", |o, v| o.accept_any_bake = v as u32),
        ("light_map_max_texels", |o, v| o.light_map_max_texels = v),
    ];
    for (field, set) in scene_fields {
        for value in UNSIGNED.into_iter().chain([u64::MAX, 1 << 40]) {
            let mut options = good_scene;
            set(&mut options, value);
            let mut scene = null_mut();
            // SAFETY: valid options and out-pointer.
            let code = unsafe { lensmap_scene_load(&options, &mut scene) };
            judged(code, &format!("scene {field} = {value}"), &mut failures);
            if !scene.is_null() {
                // SAFETY: a scene this library made.
                unsafe { lensmap_scene_free(scene) };
            }
            tried += 1;
        }
    }

    // Frame options, one field at a time, on a small good frame.
    let mut scene = null_mut();
    // SAFETY: valid options and out-pointer.
    let code = unsafe { lensmap_scene_load(&good_scene, &mut scene) };
    assert_eq!(code, LensmapResult::Ok, "{}", last_error());
    let mut good = LensmapFrameOptions {
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
    // SAFETY: valid handles and out-pointer: the scene's own camera.
    let code = unsafe { lensmap_scene_frame_options(scene, &mut good) };
    assert_eq!(code, LensmapResult::Ok, "{}", last_error());
    (good.width, good.height, good.supersampling) = (16, 12, 1);
    let mut pixels = vec![0f32; 4 * 16 * 12];
    let mut render = |options: &LensmapFrameOptions| {
        // SAFETY: `pixels` is writable for its length; the handles are this library's.
        unsafe {
            lensmap_render_to_memory(
                context,
                scene,
                options,
                pixels.as_mut_ptr(),
                pixels.len(),
                null_mut(),
            )
        }
    };
    assert_eq!(render(&good), LensmapResult::Ok, "{}", last_error());
    let unsigned_fields: [Field<LensmapFrameOptions, u32>; 9] = [
        ("width", |o, v| o.width = v),
        ("height", |o, v| o.height = v),
        ("supersampling", |o, v| o.supersampling = v),
        ("variant", |o, v| o.variant = v),
        ("format", |o, v| o.format = v),
        ("blend", |o, v| o.blend = v),
        ("viewpoint_blending", |o, v| o.viewpoint_blending = v),
        ("fresnel_texels", |o, v| o.fresnel_texels = v),
        ("tracer", |o, v| o.tracer = v),
    ];
    for (field, set) in unsigned_fields {
        for value in UNSIGNED {
            let mut options = good;
            set(&mut options, value as u32);
            judged(
                render(&options),
                &format!("frame {field} = {value}"),
                &mut failures,
            );
            tried += 1;
        }
    }
    let float_fields: [Field<LensmapFrameOptions, f32>; 5] = [
        ("vfov_degrees", |o, v| o.vfov_degrees = v),
        ("t", |o, v| o.t = v),
        ("position[0]", |o, v| o.position[0] = v),
        ("look_at[1]", |o, v| o.look_at[1] = v),
        ("up[2]", |o, v| o.up[2] = v),
    ];
    for (field, set) in float_fields {
        for value in FLOATS {
            let mut options = good;
            set(&mut options, value);
            judged(
                render(&options),
                &format!("frame {field} = {value}"),
                &mut failures,
            );
            tried += 1;
        }
    }

    // Plan options: a size query of the plan's text.
    let good_plan = LensmapPlanOptions {
        struct_size: size_of::<LensmapPlanOptions>() as u32,
        layers: 2,
        viewpoints: 1,
        terms: 2,
        variant: LENSMAP_VARIANT_MULTIPASS,
        format: LENSMAP_FORMAT_RGBA16F,
        blend: LENSMAP_BLEND_FRONT_TO_BACK,
    };
    let plan_fields: [Field<LensmapPlanOptions, u32>; 6] = [
        ("layers", |o, v| o.layers = v),
        ("viewpoints", |o, v| o.viewpoints = v),
        ("terms", |o, v| o.terms = v),
        ("variant", |o, v| o.variant = v),
        ("format", |o, v| o.format = v),
        ("blend", |o, v| o.blend = v),
    ];
    for (field, set) in plan_fields {
        for value in UNSIGNED {
            let mut options = good_plan;
            set(&mut options, value as u32);
            let mut length = 0usize;
            // SAFETY: valid options; a size query (no buffer).
            let code = unsafe { lensmap_plan_text(&options, null_mut(), 0, &mut length) };
            judged(code, &format!("plan {field} = {value}"), &mut failures);
            tried += 1;
        }
    }

    let mut count = 0u64;
    // SAFETY: a live context and a writable count.
    let code = unsafe { lensmap_context_validation_messages(context, &mut count) };
    assert_eq!(
        (code, count),
        (LensmapResult::Ok, 0),
        "validation messages (see stderr)"
    );
    // SAFETY: handles this library made, freed once.
    unsafe {
        lensmap_scene_free(scene);
        lensmap_context_free(context);
    }
    println!("{tried} (struct, field, value) calls through the C ABI");
    assert!(
        failures.is_empty(),
        "{} failures:\n{}",
        failures.len(),
        failures.join("\n")
    );
}
