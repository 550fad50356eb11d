//! Commands every reader of an image records the same way: the whole of a 2D colour image copied
//! into a buffer, and the barrier that makes transfers' writes visible to the host. The
//! renderer's readback, the viewer's screenshots and the host-image tests record these.

use ash::vk;

/// Records the copy of mip 0, layer 0 of colour image `image` (`width` × `height`, in
/// TRANSFER_SRC_OPTIMAL) into `buffer`, tightly packed.
///
/// # Safety
/// `cb` is recording on `device`, outside a rendering instance; `image` is in
/// TRANSFER_SRC_OPTIMAL by then and `buffer` holds its bytes; both live until the submission
/// completes.
pub unsafe fn copy_image_to_buffer(
    device: &ash::Device,
    cb: vk::CommandBuffer,
    image: vk::Image,
    buffer: vk::Buffer,
    width: u32,
    height: u32,
) {
    let region = vk::BufferImageCopy::default()
        .image_subresource(vk::ImageSubresourceLayers {
            aspect_mask: vk::ImageAspectFlags::COLOR,
            mip_level: 0,
            base_array_layer: 0,
            layer_count: 1,
        })
        .image_extent(vk::Extent3D {
            width,
            height,
            depth: 1,
        });
    // SAFETY: the caller's promise.
    unsafe {
        device.cmd_copy_image_to_buffer(
            cb,
            image,
            vk::ImageLayout::TRANSFER_SRC_OPTIMAL,
            buffer,
            &[region],
        )
    };
}

/// Records the barrier after which the host may read what earlier copies wrote (once the
/// submission completed).
///
/// # Safety
/// `cb` is recording on `device`.
pub unsafe fn host_reads_transfers(device: &ash::Device, cb: vk::CommandBuffer) {
    let to_host = [vk::MemoryBarrier2::default()
        .src_stage_mask(vk::PipelineStageFlags2::COPY)
        .src_access_mask(vk::AccessFlags2::TRANSFER_WRITE)
        .dst_stage_mask(vk::PipelineStageFlags2::HOST)
        .dst_access_mask(vk::AccessFlags2::HOST_READ)];
    // SAFETY: the caller's promise.
    unsafe {
        device.cmd_pipeline_barrier2(cb, &vk::DependencyInfo::default().memory_barriers(&to_host))
    };
}
