//! `Gpu::device_memory` counts what lensmap's allocator holds: a buffer's memory requirements
//! appear in it while the buffer lives and are gone once it is dropped, and the blocks reserved
//! from the driver cover every allocation (what the C ABI's soak samples for growth).

use lensmap::gpu::{Buffer, BufferUsage, DeviceMemory, Image, ImageDesc, vk};
use lensmap_tests::gpu;

#[test]
fn device_memory_counts_live_buffers_and_images_and_returns_when_they_drop() {
    let gpu = gpu();
    let before = gpu.device_memory();
    assert!(
        before.reserved_bytes >= before.allocated_bytes,
        "{before:?}"
    );
    // A buffer of 3 MiB + 4 B and a 64×32 RGBA32F image (32 KiB of texels at least).
    let size = (3 << 20) + 4;
    let buffer = Buffer::new(&gpu, "soak probe", size, BufferUsage::Storage).expect("a buffer");
    let image = Image::new(
        &gpu,
        ImageDesc::texture_2d("soak probe", vk::Format::R32G32B32A32_SFLOAT, 64, 32),
    )
    .expect("an image");
    let during = gpu.device_memory();
    assert_eq!(during.allocations, before.allocations + 2, "{during:?}");
    // Each allocation is its memory requirements' size: at least the bytes asked for, and
    // under a page of alignment more.
    let grown = during.allocated_bytes - before.allocated_bytes;
    let least = size + 64 * 32 * 16;
    assert!(
        (least..least + 2 * 65_536).contains(&grown),
        "grew by {grown} B for {least} B asked"
    );
    assert!(
        during.reserved_bytes >= during.allocated_bytes,
        "{during:?}"
    );
    assert!(during.blocks >= 1, "{during:?}");
    drop((buffer, image));
    let after = gpu.device_memory();
    assert_eq!(
        DeviceMemory {
            reserved_bytes: before.reserved_bytes,
            blocks: before.blocks,
            ..after
        },
        before,
        "every allocation returned"
    );
    assert!(gpu.validation_report().messages.is_empty());
}
