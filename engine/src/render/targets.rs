//! The images a frame renders into, per framebuffer format: the colour and depth attachments,
//! the readback buffer, the box filter's set reading the colour, and the blending schemes'
//! scratch images with the sets that read them, made when a plan first needs them.

use std::sync::Arc;

use ash::vk;

use super::{
    TargetFormat,
    descriptors::{DescriptorPool, Resource, SAMPLED_IMAGE_SET},
    pipelines::Pipelines,
};
use crate::gpu::{
    Buffer, BufferUsage, Gpu, GpuError, Image, ImageDesc, VkContext, context::Shared,
};

/// The attachments and readback buffer of one framebuffer format, and the box filter's
/// descriptor set of the colour target (for frames rendered into a host's image).
pub(super) struct Targets {
    pub(super) colour: Image,
    pub(super) depth: Image,
    pub(super) readback: Buffer,
    /// Set 0 of the box filter: `colour`, sampled (a set may outlive the view it names as long as
    /// it is not used after).
    pub(super) box_filter_set: vk::DescriptorSet,
    _box_filter_pool: DescriptorPool,
    /// The blending schemes' scratch images, made when a plan first needs them.
    pub(super) scratch: Option<Scratch>,
}

/// Framebuffer-sized scratch images (layers of one 2D-array image, in the framebuffer's format)
/// and the sets that sample them. Each set's view covers exactly the layers a pass reads, so no
/// view a draw samples overlaps an attachment or a layer the frame never wrote.
pub(super) struct Scratch {
    pub(super) image: Image,
    /// `layer_sets[k]`: layer k alone (2D; the programmable layer's set 1).
    pub(super) layer_sets: Vec<vk::DescriptorSet>,
    /// `prefix_sets[c − 1]`: layers 0..c (2D array; the group sum's set 0 for c groups).
    pub(super) prefix_sets: Vec<vk::DescriptorSet>,
    /// The prefix views, destroyed with the scratch images.
    prefix_views: Vec<vk::ImageView>,
    pool: DescriptorPool,
    shared: Arc<Shared>,
}

impl Drop for Scratch {
    fn drop(&mut self) {
        // SAFETY: the owning frame waited for its last submission; the views are this image's.
        unsafe {
            for view in &self.prefix_views {
                self.shared.device.destroy_image_view(*view, None);
            }
        }
    }
}

impl Scratch {
    /// The layers made for `needed` scratch images: at least two, so the image is an array with
    /// a 2D view per layer.
    pub(super) fn layers_for(needed: usize) -> u32 {
        if needed == 0 { 0 } else { needed.max(2) as u32 }
    }

    fn new(
        gpu: &Gpu,
        pipelines: &Pipelines,
        format: vk::Format,
        width: u32,
        height: u32,
        layers: u32,
    ) -> Result<Scratch, GpuError> {
        let layers = Self::layers_for(layers as usize);
        let image = Image::new(
            gpu,
            ImageDesc::scratch_targets("scratch", format, width, height, layers),
        )?;
        let mut scratch = Scratch {
            layer_sets: Vec::new(),
            prefix_sets: Vec::new(),
            prefix_views: Vec::new(),
            image,
            pool: DescriptorPool::new(gpu, SAMPLED_IMAGE_SET, 2 * layers)?,
            shared: gpu.shared.clone(),
        };
        for count in 1..=layers {
            let range = vk::ImageSubresourceRange {
                layer_count: count,
                ..scratch.image.full_range()
            };
            let info = vk::ImageViewCreateInfo::default()
                .image(scratch.image.handle)
                .view_type(vk::ImageViewType::TYPE_2D_ARRAY)
                .format(format)
                .subresource_range(range);
            // SAFETY: the view covers the image's own layers; destroyed in Drop.
            let view =
                unsafe { gpu.device().create_image_view(&info, None) }.vk("vkCreateImageView")?;
            scratch.prefix_views.push(view);
        }
        let layout = &pipelines.sampled_image_set_layout;
        for k in 0..layers as usize {
            let view = Resource::Image(scratch.image.layer_views[k]);
            let set = scratch.pool.allocate_one(gpu, layout, &[view])?;
            scratch.layer_sets.push(set.0);
            let prefix = Resource::Image(scratch.prefix_views[k]);
            let set = scratch.pool.allocate_one(gpu, layout, &[prefix])?;
            scratch.prefix_sets.push(set.0);
        }
        Ok(scratch)
    }
}

impl Targets {
    /// Colour and depth attachments of `width × height`, a readback buffer for the colour and
    /// the box filter's set reading it.
    pub(super) fn new(
        gpu: &Gpu,
        pipelines: &Pipelines,
        format: TargetFormat,
        width: u32,
        height: u32,
    ) -> Result<Targets, GpuError> {
        let colour_format = super::vulkan::vk_format(format.graph_format());
        let colour = Image::new(
            gpu,
            ImageDesc::colour_target("colour", colour_format, width, height),
        )?;
        let pool = DescriptorPool::new(gpu, SAMPLED_IMAGE_SET, 1)?;
        let set = pool.allocate_one(
            gpu,
            &pipelines.sampled_image_set_layout,
            &[Resource::Image(colour.view)],
        )?;
        Ok(Targets {
            colour,
            box_filter_set: set.0,
            _box_filter_pool: pool,
            scratch: None,
            depth: Image::new(gpu, ImageDesc::depth_target("depth", width, height))?,
            readback: Buffer::new(
                gpu,
                "readback",
                u64::from(width)
                    * u64::from(height)
                    * u64::from(crate::gpu::format_bytes(colour_format)),
                BufferUsage::Readback,
            )?,
        })
    }

    /// Makes sure the targets hold at least `layers` scratch images (none needed: nothing made).
    /// No submission using the previous scratch images may be pending.
    pub(super) fn ensure_scratch(
        &mut self,
        gpu: &Gpu,
        pipelines: &Pipelines,
        layers: usize,
    ) -> Result<(), GpuError> {
        let have = self
            .scratch
            .as_ref()
            .map_or(0, |s| s.image.desc.array_layers as usize);
        if layers > have {
            let extent = self.colour.desc.extent;
            self.scratch = Some(Scratch::new(
                gpu,
                pipelines,
                self.colour.desc.format,
                extent.width,
                extent.height,
                layers as u32,
            )?);
        }
        Ok(())
    }
}
