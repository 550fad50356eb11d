//! The pass graph's vocabulary in Vulkan's words: formats, layouts, accesses (pipeline stages and
//! access flags), compare ops and blend states. The one place where `graph/` types meet `vk`.

use ash::vk;

use crate::graph::{self, Access, Blend, CompareOp, Format, Layout};

/// The Vulkan format of a graph format.
pub(super) fn vk_format(format: Format) -> vk::Format {
    match format {
        Format::Rgba8Unorm => vk::Format::R8G8B8A8_UNORM,
        Format::Rgba16Float => vk::Format::R16G16B16A16_SFLOAT,
        Format::Rgba32Float => vk::Format::R32G32B32A32_SFLOAT,
        Format::Bgra8Unorm => vk::Format::B8G8R8A8_UNORM,
        Format::Rgba8Srgb => vk::Format::R8G8B8A8_SRGB,
        Format::Bgra8Srgb => vk::Format::B8G8R8A8_SRGB,
        Format::Depth32Float => vk::Format::D32_SFLOAT,
    }
}

/// The graph format of a host image's Vulkan format: the colour formats every Vulkan device can
/// render to (their colour-attachment support is mandatory), `None` for any other.
pub(super) fn graph_format_of(format: vk::Format) -> Option<Format> {
    [
        Format::Rgba8Unorm,
        Format::Rgba16Float,
        Format::Rgba32Float,
        Format::Bgra8Unorm,
        Format::Rgba8Srgb,
        Format::Bgra8Srgb,
    ]
    .into_iter()
    .find(|f| vk_format(*f) == format)
}

/// The Vulkan image layout of a graph layout.
pub(super) fn vk_layout(layout: Layout) -> vk::ImageLayout {
    match layout {
        Layout::Undefined => vk::ImageLayout::UNDEFINED,
        Layout::ColourAttachment => vk::ImageLayout::COLOR_ATTACHMENT_OPTIMAL,
        // Valid for depth-only formats without the separateDepthStencilLayouts feature.
        Layout::DepthAttachment => vk::ImageLayout::DEPTH_STENCIL_ATTACHMENT_OPTIMAL,
        Layout::ShaderRead => vk::ImageLayout::SHADER_READ_ONLY_OPTIMAL,
        Layout::TransferSrc => vk::ImageLayout::TRANSFER_SRC_OPTIMAL,
        // The recorder puts the host's own layouts in place of this one (Recorder::record); a
        // plan with an external image is only ever recorded with the host's image.
        Layout::External => vk::ImageLayout::GENERAL,
    }
}

/// The pipeline stages and access flags of a graph access.
pub(super) fn vk_access(access: Access) -> (vk::PipelineStageFlags2, vk::AccessFlags2) {
    match access {
        // Whatever ran before on the queue (earlier frames included) finishes first.
        Access::None => (
            vk::PipelineStageFlags2::ALL_COMMANDS,
            vk::AccessFlags2::NONE,
        ),
        Access::ColourAttachment => (
            vk::PipelineStageFlags2::COLOR_ATTACHMENT_OUTPUT,
            vk::AccessFlags2::COLOR_ATTACHMENT_READ | vk::AccessFlags2::COLOR_ATTACHMENT_WRITE,
        ),
        Access::DepthAttachment => (
            vk::PipelineStageFlags2::EARLY_FRAGMENT_TESTS
                | vk::PipelineStageFlags2::LATE_FRAGMENT_TESTS,
            vk::AccessFlags2::DEPTH_STENCIL_ATTACHMENT_READ
                | vk::AccessFlags2::DEPTH_STENCIL_ATTACHMENT_WRITE,
        ),
        Access::FragmentSample => (
            vk::PipelineStageFlags2::FRAGMENT_SHADER,
            vk::AccessFlags2::SHADER_SAMPLED_READ,
        ),
        Access::VertexStorageRead => (
            vk::PipelineStageFlags2::VERTEX_SHADER
                | vk::PipelineStageFlags2::INDEX_INPUT
                | vk::PipelineStageFlags2::DRAW_INDIRECT,
            vk::AccessFlags2::SHADER_STORAGE_READ
                | vk::AccessFlags2::INDEX_READ
                | vk::AccessFlags2::INDIRECT_COMMAND_READ,
        ),
        Access::ComputeRead => (
            vk::PipelineStageFlags2::COMPUTE_SHADER,
            vk::AccessFlags2::SHADER_STORAGE_READ,
        ),
        // Written, and perhaps read (read-modify-write, atomics): both.
        Access::ComputeWrite => (
            vk::PipelineStageFlags2::COMPUTE_SHADER,
            vk::AccessFlags2::SHADER_STORAGE_READ | vk::AccessFlags2::SHADER_STORAGE_WRITE,
        ),
        Access::IndirectRead => (
            vk::PipelineStageFlags2::DRAW_INDIRECT,
            vk::AccessFlags2::INDIRECT_COMMAND_READ,
        ),
        Access::HostRead => (vk::PipelineStageFlags2::HOST, vk::AccessFlags2::HOST_READ),
        // Every command submitted before (a kept buffer's last writer, in an earlier submission).
        Access::Earlier => (
            vk::PipelineStageFlags2::ALL_COMMANDS,
            vk::AccessFlags2::MEMORY_WRITE,
        ),
        // Copies, fills and updates: every transfer stage (sync2 puts buffer fills and updates
        // in CLEAR, copies in COPY).
        Access::TransferRead => (
            vk::PipelineStageFlags2::ALL_TRANSFER,
            vk::AccessFlags2::TRANSFER_READ,
        ),
        Access::TransferWrite => (
            vk::PipelineStageFlags2::ALL_TRANSFER,
            vk::AccessFlags2::TRANSFER_WRITE,
        ),
        // A host's work on its image, before the frame (it may have written it) or after it:
        // every stage, every memory access.
        Access::External => (
            vk::PipelineStageFlags2::ALL_COMMANDS,
            vk::AccessFlags2::MEMORY_READ | vk::AccessFlags2::MEMORY_WRITE,
        ),
    }
}

/// The Vulkan depth compare op.
pub(super) fn vk_compare(op: CompareOp) -> vk::CompareOp {
    match op {
        CompareOp::Less => vk::CompareOp::LESS,
        CompareOp::LessOrEqual => vk::CompareOp::LESS_OR_EQUAL,
    }
}

/// The colour attachment's blend state and write mask.
pub(super) fn blend_state(
    blend: Blend,
    mask: graph::ColourMask,
) -> vk::PipelineColorBlendAttachmentState {
    let state = vk::PipelineColorBlendAttachmentState::default()
        .color_write_mask(vk::ColorComponentFlags::from_raw(u32::from(mask.0)));
    // Every blend adds `src·source_factor + dst·destination_factor`, the same on colour and
    // alpha.
    let (source_factor, destination_factor) = match blend {
        Blend::Replace => return state.blend_enable(false),
        // Front-to-back "over": src·(1 − dstα) + dst·1.
        Blend::FrontToBackOver => (vk::BlendFactor::ONE_MINUS_DST_ALPHA, vk::BlendFactor::ONE),
        // Back-to-front "over": src·1 + dst·(1 − srcα).
        Blend::BackToFrontOver => (vk::BlendFactor::ONE, vk::BlendFactor::ONE_MINUS_SRC_ALPHA),
        // Sum: src·1 + dst·1.
        Blend::Add => (vk::BlendFactor::ONE, vk::BlendFactor::ONE),
    };
    state
        .blend_enable(true)
        .src_color_blend_factor(source_factor)
        .dst_color_blend_factor(destination_factor)
        .color_blend_op(vk::BlendOp::ADD)
        .src_alpha_blend_factor(source_factor)
        .dst_alpha_blend_factor(destination_factor)
        .alpha_blend_op(vk::BlendOp::ADD)
}
