//! A host's image as a frame's destination: what a host lends ([`HostImage`]), checked against
//! the frame before anything is recorded.

use ash::vk;

use super::{RenderError, plan::Output, vulkan};
use crate::graph::Format;

/// A host's `VkImage` to render a frame into, on the host's own device and queue
/// ([`super::Renderer::submit`] with [`super::RenderOptions::host`]). Lensmap renders the frame
/// into its own framebuffer as always, then box-filters it into this image with a full-screen draw (the supersampling filter
/// on the GPU: no readback), with the barriers that take the image from `current_layout` to a
/// colour attachment and on to `final_layout`. The submission waits for `wait` and signals
/// `signal`; it is on the queue lensmap was given, so the host's later work on that queue is
/// ordered after it as well.
#[derive(Clone, Debug, PartialEq)]
pub struct HostImage {
    /// The image: 2D, `COLOR_ATTACHMENT` usage.
    pub image: vk::Image,
    /// A 2D view of it: the one level `mip_level` and the one layer `array_layer`.
    pub view: vk::ImageView,
    /// The level the view shows (the barriers cover it alone).
    pub mip_level: u32,
    /// The array layer the view shows (the barriers cover it alone).
    pub array_layer: u32,
    /// Its format: one of [`HostImage::FORMATS`].
    pub format: vk::Format,
    /// Its width: the frame's pixels, not its subpixels.
    pub width: u32,
    /// Its height.
    pub height: u32,
    /// The layout the image is in when the submission begins (after `wait`).
    pub current_layout: vk::ImageLayout,
    /// The layout the frame leaves it in (`COLOR_ATTACHMENT_OPTIMAL`, `TRANSFER_SRC_OPTIMAL`,
    /// `SHADER_READ_ONLY_OPTIMAL`, `PRESENT_SRC_KHR`, …; not `UNDEFINED` or `PREINITIALIZED`).
    pub final_layout: vk::ImageLayout,
    /// Semaphores the submission waits for before it writes any colour attachment, with the
    /// value to wait for (timeline semaphores; ignored for binary ones).
    pub wait: Vec<(vk::Semaphore, u64)>,
    /// Semaphores the submission signals when all its work is done, with the value to signal
    /// (timeline semaphores; ignored for binary ones).
    pub signal: Vec<(vk::Semaphore, u64)>,
}

impl HostImage {
    /// The formats a host image may have: those every Vulkan device can render to (colour
    /// attachment support is mandatory for them). The `_SRGB` ones encode on write.
    pub const FORMATS: [vk::Format; 6] = [
        vk::Format::R8G8B8A8_UNORM,
        vk::Format::R16G16B16A16_SFLOAT,
        vk::Format::R32G32B32A32_SFLOAT,
        vk::Format::B8G8R8A8_UNORM,
        vk::Format::R8G8B8A8_SRGB,
        vk::Format::B8G8R8A8_SRGB,
    ];

    /// Whether lensmap can render into an image of `format`.
    pub fn supports(format: vk::Format) -> bool {
        vulkan::graph_format_of(format).is_some()
    }

    /// The layouts a colour image may be in before a frame (`UNDEFINED` and `PREINITIALIZED`
    /// too) and, but for those two, after it.
    pub const LAYOUTS: [vk::ImageLayout; 11] = [
        vk::ImageLayout::UNDEFINED,
        vk::ImageLayout::PREINITIALIZED,
        vk::ImageLayout::GENERAL,
        vk::ImageLayout::COLOR_ATTACHMENT_OPTIMAL,
        vk::ImageLayout::SHADER_READ_ONLY_OPTIMAL,
        vk::ImageLayout::TRANSFER_SRC_OPTIMAL,
        vk::ImageLayout::TRANSFER_DST_OPTIMAL,
        vk::ImageLayout::ATTACHMENT_OPTIMAL,
        vk::ImageLayout::READ_ONLY_OPTIMAL,
        vk::ImageLayout::PRESENT_SRC_KHR,
        vk::ImageLayout::SHARED_PRESENT_KHR,
    ];

    /// The graph output of a frame of `width × height` subpixels into this image: its format and
    /// the supersampling factor k (the frame's sides are k times the image's). An error names
    /// what does not fit.
    pub(crate) fn output(&self, width: u32, height: u32) -> Result<Output, RenderError> {
        let format: Format = vulkan::graph_format_of(self.format).ok_or_else(|| {
            RenderError::BadInput(format!(
                "host image format {:?}: lensmap renders into {}",
                self.format,
                Self::FORMATS.map(|f| format!("{f:?}")).join(", ")
            ))
        })?;
        if self.image == vk::Image::null() || self.view == vk::ImageView::null() {
            return Err(RenderError::BadInput(
                "host image: image and view must be live handles, not VK_NULL_HANDLE".into(),
            ));
        }
        if !Self::LAYOUTS.contains(&self.current_layout) {
            return Err(RenderError::BadInput(format!(
                "host image current layout {:?}: not a layout of a colour image (give UNDEFINED if its contents do not matter)",
                self.current_layout
            )));
        }
        if !Self::LAYOUTS[2..].contains(&self.final_layout) {
            return Err(RenderError::BadInput(format!(
                "host image final layout {:?}: give the colour-image layout the host uses next (a frame cannot end in UNDEFINED or PREINITIALIZED)",
                self.final_layout
            )));
        }
        let fits = self.width > 0
            && self.height > 0
            && width.is_multiple_of(self.width)
            && height.is_multiple_of(self.height)
            && width / self.width == height / self.height;
        if !fits {
            return Err(RenderError::BadInput(format!(
                "host image is {}×{}; the frame's framebuffer is {width}×{height} subpixels: the image must be the camera's width × height",
                self.width, self.height
            )));
        }
        let supersampling = width / self.width;
        Ok(Output::External {
            format,
            supersampling,
        })
    }
}
