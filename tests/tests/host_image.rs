//! Frames rendered into a host's image: the frame's plan ends in the GPU box filter into an image
//! lensmap does not own, with no readback. Each is compared with the same frame read back and
//! box-filtered on the CPU by a fresh runner (a second path through the same framebuffer): bit for
//! bit in RGBA32F at k = 1, 2 and 3 and in RGBA8 at k = 1, and with the lens vertices traced on the
//! GPU at k = 2; a BGRA sRGB image holds the CPU frame's sRGB encoding with its channels swapped,
//! within the one 8-bit step the specification allows an sRGB conversion. The host's signal
//! semaphore is signalled, and a frame waits for the host's wait semaphore.

use lensmap::render::Compositing;
use lensmap::{
    gpu::{Buffer, BufferUsage, Gpu, Image, ImageDesc, copies, vk},
    hybrid::{HybridOptions, VertexTracer},
    render::{HostImage, TargetFormat},
    runner::{FrameOptions, FrameRunner, RunError},
    scene::Camera,
    trace::image::srgb_encode,
};
use lensmap_tests::{assert_clean, gpu, small_teapot_room};

fn options(format: TargetFormat) -> FrameOptions {
    traced(format, VertexTracer::Cpu)
}

/// [`options`] with the lens vertices traced by `tracer`.
fn traced(format: TargetFormat, tracer: VertexTracer) -> FrameOptions {
    FrameOptions {
        hybrid: HybridOptions {
            tracer,
            ..HybridOptions::with_t(3.0)
        },
        compositing: Compositing::SinglePass,
        format,
    }
}

/// An image a host could have made: the camera's size, usable as a colour attachment and a copy
/// source.
fn host_image(gpu: &Gpu, format: vk::Format, camera: &Camera) -> Image {
    Image::new(
        gpu,
        ImageDesc::colour_target("host", format, camera.width, camera.height),
    )
    .unwrap()
}

/// `image` as lent to a frame: from UNDEFINED to TRANSFER_SRC_OPTIMAL (read back below).
fn lent(image: &Image) -> HostImage {
    HostImage {
        image: image.handle,
        view: image.view,
        mip_level: 0,
        array_layer: 0,
        format: image.desc.format,
        width: image.desc.extent.width,
        height: image.desc.extent.height,
        current_layout: vk::ImageLayout::UNDEFINED,
        final_layout: vk::ImageLayout::TRANSFER_SRC_OPTIMAL,
        wait: Vec::new(),
        signal: Vec::new(),
    }
}

/// What the host does next: copies the image (in TRANSFER_SRC_OPTIMAL, after the frame on the
/// same queue) into a buffer and waits.
fn read_back(gpu: &Gpu, image: &Image) -> Vec<u8> {
    let extent = image.desc.extent;
    let bytes = u64::from(extent.width)
        * u64::from(extent.height)
        * u64::from(lensmap::gpu::format_bytes(image.desc.format));
    let buffer = Buffer::new(gpu, "host readback", bytes, BufferUsage::Readback).unwrap();
    gpu.submit_and_wait(|cb| {
        // SAFETY: recording; the frame left the image in TRANSFER_SRC_OPTIMAL, and its hand-back
        // barrier makes its writes available to every later command on the queue.
        unsafe {
            copies::copy_image_to_buffer(
                gpu.device(),
                cb,
                image.handle,
                buffer.handle,
                extent.width,
                extent.height,
            );
            copies::host_reads_transfers(gpu.device(), cb);
        }
        Ok(())
    })
    .unwrap();
    buffer.read().to_vec()
}

/// The frame read back and box-filtered on the CPU by a fresh runner: the expected pixels.
fn cpu_frame(
    hybrid: &lensmap::hybrid::HybridScene,
    camera: &Camera,
    options: &FrameOptions,
) -> Vec<[f32; 4]> {
    let mut alone = FrameRunner::new(gpu()).unwrap();
    let frame = alone.frame(hybrid, camera, options).unwrap();
    assert_clean(alone.gpu());
    frame.image.pixels
}

#[test]
fn a_frame_into_a_host_image_equals_the_frame_read_back() {
    let hybrid = small_teapot_room(24, 18);
    let mut runner = FrameRunner::new(gpu()).unwrap();
    let (cpu, on_gpu) = (VertexTracer::Cpu, VertexTracer::Gpu);
    let cases = [
        (
            TargetFormat::Rgba32f,
            vk::Format::R32G32B32A32_SFLOAT,
            1,
            cpu,
        ),
        (
            TargetFormat::Rgba32f,
            vk::Format::R32G32B32A32_SFLOAT,
            2,
            cpu,
        ),
        (
            TargetFormat::Rgba32f,
            vk::Format::R32G32B32A32_SFLOAT,
            3,
            cpu,
        ),
        (TargetFormat::Rgba8, vk::Format::R8G8B8A8_UNORM, 1, cpu),
        // A host's frame with no lens vertex traced on the CPU.
        (
            TargetFormat::Rgba32f,
            vk::Format::R32G32B32A32_SFLOAT,
            2,
            on_gpu,
        ),
    ];
    for (format, image_format, k, tracer) in cases {
        let camera = Camera {
            supersampling: k,
            ..hybrid.scene().camera
        };
        let image = host_image(runner.gpu(), image_format, &camera);
        runner.forget_frame();
        let frame = runner
            .frame_into(&hybrid, &camera, &traced(format, tracer), &lent(&image))
            .unwrap();
        assert!(frame.passes >= 4, "environment, lens, box filter, export");
        assert_eq!(frame.stats.traced_on_gpu, tracer == on_gpu);
        // A frame drawn from the device's buffers has its counts read with the next frame.
        assert_eq!(frame.stats.counted_on_device, tracer == on_gpu);
        assert_eq!(frame.stats.vertices_traced > 0, tracer == cpu);
        let bytes = read_back(runner.gpu(), &image);
        if tracer == on_gpu {
            // The read-back above waited for the frame: the next one reports its counts.
            runner.forget_frame();
            let next = runner
                .frame_into(&hybrid, &camera, &traced(format, tracer), &lent(&image))
                .unwrap();
            // Waits for the frame before the image goes.
            read_back(runner.gpu(), &image);
            let counted = next.previous.expect("the frame before is done and counted");
            assert!(counted.vertices_traced > 0 && counted.triangles_out > 0);
            assert!(counted.counters.primary_rays > 0);
        }
        let expected = cpu_frame(&hybrid, &camera, &traced(format, tracer));
        assert_eq!(expected.len(), (camera.width * camera.height) as usize);
        let mut distinct: Vec<[u32; 4]> = expected.iter().map(|p| p.map(f32::to_bits)).collect();
        distinct.sort_unstable();
        distinct.dedup();
        assert!(
            distinct.len() > 50,
            "a frame with a picture in it, not a flat one"
        );
        for (i, pixel) in expected.iter().enumerate() {
            for c in 0..4 {
                let got = match format {
                    TargetFormat::Rgba8 => f32::from(bytes[4 * i + c]) / 255.0,
                    _ => f32::from_le_bytes(
                        bytes[16 * i + 4 * c..16 * i + 4 * c + 4]
                            .try_into()
                            .unwrap(),
                    ),
                };
                assert_eq!(
                    got.to_bits(),
                    pixel[c].to_bits(),
                    "{format:?} k = {k}: pixel {i} channel {c}: host image {got}, read back {}",
                    pixel[c]
                );
            }
        }
    }
    assert_clean(runner.gpu());
}

#[test]
fn an_srgb_bgra_image_holds_the_encoded_frame_and_the_semaphores_are_honoured() {
    let hybrid = small_teapot_room(24, 18);
    let mut runner = FrameRunner::new(gpu()).unwrap();
    let camera = Camera {
        supersampling: 2,
        ..hybrid.scene().camera
    };
    let image = host_image(runner.gpu(), vk::Format::B8G8R8A8_SRGB, &camera);
    let device = runner.gpu().device().clone();
    let timeline = |initial: u64| {
        let mut kind = vk::SemaphoreTypeCreateInfo::default()
            .semaphore_type(vk::SemaphoreType::TIMELINE)
            .initial_value(initial);
        // SAFETY: a valid create info; destroyed at the end of the test.
        unsafe {
            device.create_semaphore(
                &vk::SemaphoreCreateInfo::default().push_next(&mut kind),
                None,
            )
        }
        .unwrap()
    };
    // The host's semaphores: the frame waits for `ready` to reach 1 (the host signals it from
    // the CPU after submitting) and signals `done` with 7.
    let (ready, done) = (timeline(0), timeline(0));
    let mut host = lent(&image);
    host.wait = vec![(ready, 1)];
    host.signal = vec![(done, 7)];
    runner
        .frame_into(&hybrid, &camera, &options(TargetFormat::Rgba32f), &host)
        .unwrap();
    // SAFETY: live semaphores of this device; ready's value only grows.
    unsafe {
        assert_eq!(
            device.get_semaphore_counter_value(done).unwrap(),
            0,
            "waits for ready"
        );
        device
            .signal_semaphore(&vk::SemaphoreSignalInfo::default().semaphore(ready).value(1))
            .unwrap();
        let semaphores = [done];
        let values = [7];
        device
            .wait_semaphores(
                &vk::SemaphoreWaitInfo::default()
                    .semaphores(&semaphores)
                    .values(&values),
                10_000_000_000,
            )
            .unwrap();
    }
    let bytes = read_back(runner.gpu(), &image);
    let expected = cpu_frame(&hybrid, &camera, &options(TargetFormat::Rgba32f));
    let mut worst = 0;
    for (i, pixel) in expected.iter().enumerate() {
        // BGRA: blue first. Alpha is linear in sRGB formats.
        let want = [
            srgb_encode(pixel[2]),
            srgb_encode(pixel[1]),
            srgb_encode(pixel[0]),
            pixel[3].clamp(0.0, 1.0),
        ]
        .map(|v| (v * 255.0).round() as i32);
        for c in 0..4 {
            let step = (i32::from(bytes[4 * i + c]) - want[c]).abs();
            worst = worst.max(step);
        }
    }
    assert!(
        worst <= 1,
        "an sRGB channel is {worst} steps off the CPU's encoding"
    );
    // SAFETY: the frame completed (done reached 7); nothing uses them any more.
    unsafe {
        device.destroy_semaphore(ready, None);
        device.destroy_semaphore(done, None);
    }
    assert_clean(runner.gpu());
}

#[test]
fn host_images_that_do_not_fit_the_frame_are_refused_naming_the_fix() {
    let hybrid = small_teapot_room(24, 18);
    let mut runner = FrameRunner::new(gpu()).unwrap();
    let camera = hybrid.scene().camera;
    let image = host_image(runner.gpu(), vk::Format::R8G8B8A8_UNORM, &camera);
    let mut refusal = |host: HostImage| -> String {
        match runner.frame_into(&hybrid, &camera, &options(TargetFormat::Rgba8), &host) {
            Err(error @ RunError::Render(_)) => error.to_string(),
            other => panic!("expected a refusal, got {other:?}"),
        }
    };
    let mut half = lent(&image);
    half.width /= 2;
    assert!(refusal(half).contains("camera's size"));
    let mut depth = lent(&image);
    depth.format = vk::Format::D32_SFLOAT;
    assert!(refusal(depth).contains("R8G8B8A8_UNORM"));
    let mut undefined = lent(&image);
    undefined.final_layout = vk::ImageLayout::UNDEFINED;
    assert!(refusal(undefined).contains("final layout"));
    let mut null = lent(&image);
    null.view = vk::ImageView::null();
    assert!(refusal(null).contains("VK_NULL_HANDLE"));
    let mut depth_layout = lent(&image);
    depth_layout.current_layout = vk::ImageLayout::DEPTH_STENCIL_ATTACHMENT_OPTIMAL;
    assert!(refusal(depth_layout).contains("current layout"));
    assert!(HostImage::supports(vk::Format::B8G8R8A8_SRGB));
    assert!(!HostImage::supports(vk::Format::R8G8B8_UNORM));
    assert_clean(runner.gpu());
}
