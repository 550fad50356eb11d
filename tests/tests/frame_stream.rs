//! A stream of hybrid frames: frames in flight, reused uploads, a still camera and lens objects
//! outside the view change no image. Each frame of a stream is compared bit for bit (RGBA32F) with
//! the same frame rendered alone by a fresh runner, which builds everything from scratch: a second,
//! independent path through the same stages.

use lensmap::render::BlendScheme;
use lensmap::render::Compositing;
use lensmap::{
    hybrid::{HybridOptions, HybridScene},
    render::{TargetFormat, Variant},
    runner::{FrameOptions, FrameRunner, HybridFrame},
    scene::Camera,
};
use lensmap_tests::{assert_clean, gpu, small_teapot_room};

fn options(variant: Variant) -> FrameOptions {
    FrameOptions {
        hybrid: HybridOptions::with_t(3.0),
        compositing: Compositing::new(variant, BlendScheme::FrontToBack).unwrap(),
        format: TargetFormat::Rgba32f,
    }
}

/// `camera`'s single-pass frame of `hybrid` ([`options`]).
fn single_pass(runner: &mut FrameRunner, hybrid: &HybridScene, camera: &Camera) -> HybridFrame {
    runner
        .frame(hybrid, camera, &options(Variant::SinglePass))
        .unwrap()
}

/// Frames in flight over a moving camera (with a repeated camera in the middle: a still frame)
/// equal the frames rendered one at a time, each by a fresh runner from a fresh scene cache.
#[test]
fn frames_in_flight_equal_frames_rendered_alone() {
    let hybrid = small_teapot_room(48, 36);
    let base = hybrid.scene().camera;
    let cameras = [
        base.orbited(0.0),
        base.orbited(4.0),
        base.orbited(4.0),
        base.orbited(8.0),
        base.orbited(0.0),
    ];
    for variant in [Variant::SinglePass, Variant::Multipass] {
        let mut stream = FrameRunner::new(gpu()).unwrap();
        let (frames, wall_ms) = stream
            .frames_in_flight(&hybrid, &cameras, &options(variant))
            .unwrap();
        assert_eq!(frames.len(), cameras.len());
        assert!(wall_ms > 0.0);
        // The repeated camera is the only reused frame.
        let reused: Vec<bool> = frames.iter().map(|f| f.stats.reused).collect();
        assert_eq!(reused, [false, false, true, false, false], "{variant:?}");
        assert_eq!(frames[2].stats.vertices_traced, 0);
        assert!(frames[1].stats.vertices_traced > 0);
        for (i, (frame, camera)) in frames.iter().zip(&cameras).enumerate() {
            let mut alone = FrameRunner::new(gpu()).unwrap();
            let expected = alone.frame(&hybrid, camera, &options(variant)).unwrap();
            assert!(!expected.stats.reused);
            assert!(
                frame.image == expected.image,
                "{variant:?}: frame {i} of the stream differs from the frame rendered alone"
            );
            assert!(frame.image.pixels.iter().flatten().all(|c| c.is_finite()));
            assert_clean(alone.gpu());
        }
        assert_clean(stream.gpu());
    }
}

/// A still camera: the second frame reuses the first's tessellation, texture coordinates and
/// upload (nothing traced), and its image is the first's, bit for bit.
#[test]
fn a_still_camera_renders_the_same_frame_without_cpu_work() {
    let hybrid = small_teapot_room(48, 36);
    let camera = hybrid.scene().camera;
    let mut runner = FrameRunner::new(gpu()).unwrap();
    let first = single_pass(&mut runner, &hybrid, &camera);
    let second = single_pass(&mut runner, &hybrid, &camera);
    assert!(!first.stats.reused && second.stats.reused);
    assert!(first.stats.vertices_traced > 0);
    assert_eq!(second.stats.vertices_traced, 0);
    assert_eq!(second.stats.counters.all_rays(), 0);
    assert_eq!(second.stats.triangles_out, first.stats.triangles_out);
    assert!(first.image == second.image);
    // Other options are another frame.
    let coarser = FrameOptions {
        hybrid: HybridOptions::with_t(6.0),
        ..options(Variant::SinglePass)
    };
    let third = runner.frame(&hybrid, &camera, &coarser).unwrap();
    assert!(!third.stats.reused && third.stats.vertices_traced > 0);
    assert_clean(runner.gpu());
}

/// A camera that looks away from every lens object traces and tessellates none of them (the
/// frustum test itself is checked against sampled points in `hybrid::frame`'s unit tests).
#[test]
fn lens_objects_outside_the_view_are_skipped() {
    let hybrid = small_teapot_room(48, 36);
    let base = hybrid.scene().camera;
    // Look from the scene camera straight away from the lens objects.
    let away = Camera {
        look_at: base.position + (base.position - base.look_at),
        ..base
    };
    let mut runner = FrameRunner::new(gpu()).unwrap();
    let frame = single_pass(&mut runner, &hybrid, &away);
    assert_eq!(frame.stats.lenses_outside_view, hybrid.trace().lenses.len());
    assert_eq!(frame.stats.vertices_traced, 0);
    assert_eq!(frame.stats.triangles_out, 0);
    // A camera that sees them skips none.
    let seen = single_pass(&mut runner, &hybrid, &base);
    assert_eq!(seen.stats.lenses_outside_view, 0);
    assert!(seen.stats.vertices_traced > 0);

    assert_clean(runner.gpu());
}

/// The frame is the same at every thread count: tessellation, tracing and texture coordinates
/// run in parallel but gather their results in order.
#[test]
fn frames_do_not_depend_on_the_thread_count() {
    let hybrid = small_teapot_room(48, 36);
    let camera = hybrid.scene().camera.orbited(2.0);
    let mut runner = FrameRunner::new(gpu()).unwrap();
    let mut render = |threads: usize| {
        runner.forget_frame();
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| single_pass(&mut runner, &hybrid, &camera))
    };
    let one = render(1);
    for threads in [2, 5] {
        let other = render(threads);
        assert_eq!(one.stats.triangles_out, other.stats.triangles_out);
        assert_eq!(one.stats.counters, other.stats.counters);
        assert!(one.image == other.image, "{threads} threads");
    }
    assert_clean(runner.gpu());
}

/// Footprint coarsening: off by default; on, a lens object far from the camera (few subpixels
/// on screen) gets a coarser t, fewer triangles and the count in the stats; a negative footprint
/// is refused.
#[test]
fn small_footprints_get_a_coarser_t_only_when_asked() {
    let hybrid = small_teapot_room(48, 36);
    let base = hybrid.scene().camera;
    // Farther away: the lens objects cover part of the 48×36 frame, all below 1000 subpixels.
    let far = Camera {
        position: base.look_at + 1.5 * (base.position - base.look_at),
        ..base
    };
    let mut runner = FrameRunner::new(gpu()).unwrap();
    let exact = single_pass(&mut runner, &hybrid, &far);
    assert_eq!(exact.stats.lenses_coarsened, 0);
    let coarse_options = FrameOptions {
        hybrid: HybridOptions {
            footprint_subpixels: 1000.0,
            ..HybridOptions::with_t(3.0)
        },
        ..options(Variant::SinglePass)
    };
    let coarse = runner.frame(&hybrid, &far, &coarse_options).unwrap();
    assert!(coarse.stats.lenses_coarsened > 0, "{:?}", coarse.stats);
    assert!(
        coarse.stats.vertices_traced < exact.stats.vertices_traced,
        "{} vs {}",
        coarse.stats.vertices_traced,
        exact.stats.vertices_traced
    );
    assert!(coarse.image.pixels.iter().flatten().all(|c| c.is_finite()));
    let negative = HybridOptions {
        footprint_subpixels: -1.0,
        ..HybridOptions::with_t(3.0)
    };
    assert!(negative.validate().is_err());
    assert_clean(runner.gpu());
}

/// The still-camera cache is keyed by the scene's version: every setter (other maps, even the
/// same maps again; other viewpoint samples; another sky) makes the next frame a new one, and a
/// frame of an unchanged scene is reused.
#[test]
fn changing_the_scene_is_not_a_still_frame() {
    let mut hybrid = small_teapot_room(48, 36);
    let camera = hybrid.scene().camera;
    let options = options(Variant::SinglePass);
    let mut runner = FrameRunner::new(gpu()).unwrap();
    let mut reused = |hybrid: &lensmap::hybrid::HybridScene| {
        runner
            .frame(hybrid, &camera, &options)
            .unwrap()
            .stats
            .reused
    };
    assert!(!reused(&hybrid));
    assert!(reused(&hybrid));
    // The same maps set again: a new version.
    let lens = lensmap::index::LensIndex::new(0);
    let maps = hybrid.lenses()[0].maps.clone();
    hybrid.set_lens_maps(lens, maps);
    assert!(!reused(&hybrid));
    assert!(reused(&hybrid));
    let reversed = hybrid.viewpoints().iter().rev().copied().collect();
    hybrid.set_viewpoints(reversed);
    assert!(!reused(&hybrid));
    assert!(hybrid.sky().is_some(), "teapot-room has a sky");
    hybrid.set_sky(None);
    assert!(!reused(&hybrid));
    assert!(reused(&hybrid));
    let version = hybrid.version();
    hybrid.set_sky(None);
    assert_ne!(hybrid.version(), version);
    assert_eq!(hybrid.version().id, version.id, "the same scene");
    assert_clean(runner.gpu());
}
