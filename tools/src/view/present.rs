//! The window's surface and swapchain on lensmap's own device and queue, and the per-frame
//! submission that follows the frame: the overlay drawn over it, an optional copy of the image
//! for a screenshot, and the presentation. The frame itself is rendered into the swapchain image
//! by [`lensmap::runner::FrameRunner::frame_into`], the C ABI's host-image path: no readback.

use anyhow::{Context as _, bail};
use ash::vk;
use lensmap::{
    gpu::{Buffer, BufferUsage, Gpu, Timeline},
    render::HostImage,
};
use raw_window_handle::{HasDisplayHandle, HasWindowHandle};
use winit::window::Window;

use super::PresentArg;

/// Swapchain formats in order of preference: the `_SRGB` ones encode on write, as `lensmap
/// render`'s PNG does, so that the window shows what the PNG holds.
const FORMATS: [vk::Format; 4] = [
    vk::Format::B8G8R8A8_SRGB,
    vk::Format::R8G8B8A8_SRGB,
    vk::Format::B8G8R8A8_UNORM,
    vk::Format::R8G8B8A8_UNORM,
];

/// A window's surface, swapchain and the objects one frame in flight needs.
pub struct Presenter {
    device: ash::Device,
    surface_fn: ash::khr::surface::Instance,
    swapchain_fn: ash::khr::swapchain::Device,
    physical_device: vk::PhysicalDevice,
    queue: vk::Queue,
    surface: vk::SurfaceKHR,
    swapchain: vk::SwapchainKHR,
    images: Vec<vk::Image>,
    views: Vec<vk::ImageView>,
    /// Per image: signalled by the frame's last submission, waited for by its presentation.
    presentable: Vec<vk::Semaphore>,
    /// Signalled when the acquired image may be written.
    acquired: vk::Semaphore,
    /// Signalled when lensmap's frame is in the image.
    rendered: vk::Semaphore,
    /// Raised to [`Self::frames`] by lensmap's frame when it is done: the host's way to time
    /// the GPU's part of a frame without a readback.
    timeline: Timeline,
    /// Frames submitted into host images.
    frames: u64,
    /// Signalled when the frame's last submission is done.
    done: vk::Fence,
    pool: vk::CommandPool,
    command_buffer: vk::CommandBuffer,
    /// The surface format in use.
    pub format: vk::SurfaceFormatKHR,
    /// The swapchain's size.
    pub extent: vk::Extent2D,
    /// The present mode in use.
    pub mode: vk::PresentModeKHR,
    /// Whether the images can be copied from (screenshots).
    copyable: bool,
}

/// An acquired swapchain image.
pub enum Acquired {
    /// Image `index`: render into [`Presenter::host_image`], then [`Presenter::finish`].
    Image(u32),
    /// The swapchain no longer fits the surface: recreate it and try again.
    OutOfDate,
}

/// What the frame's last submission copies for a screenshot.
pub struct Copies {
    /// The frame as lensmap rendered it, before the overlay.
    pub frame: Buffer,
    /// The window as shown, overlay and all.
    pub window: Buffer,
}

impl Presenter {
    /// A surface on `window` and a swapchain of its size, on `gpu`'s device and queue.
    pub fn new(gpu: &Gpu, window: &Window, mode: PresentArg) -> anyhow::Result<Presenter> {
        let vulkan = gpu.vulkan();
        let display = window.display_handle().context("the window's display")?;
        let handle = window.window_handle().context("the window's handle")?;
        // SAFETY: the instance has the window system's extensions (GpuOptions::surface_extensions)
        // and the window outlives the surface (the viewer drops the Presenter first).
        let surface = unsafe {
            ash_window::create_surface(
                vulkan.entry,
                vulkan.instance,
                display.as_raw(),
                handle.as_raw(),
                None,
            )
        }
        .context("vkCreate*SurfaceKHR")?;
        let surface_fn = ash::khr::surface::Instance::new(vulkan.entry, vulkan.instance);
        // SAFETY: a live surface of this instance.
        let supported = unsafe {
            surface_fn.get_physical_device_surface_support(
                vulkan.physical_device,
                vulkan.queue_family,
                surface,
            )
        }
        .unwrap_or(false);
        if !supported {
            // SAFETY: nothing uses the surface yet.
            unsafe { surface_fn.destroy_surface(surface, None) };
            bail!(
                "{} cannot present to this window from its graphics queue; choose another device with LENSMAP_DEVICE",
                gpu.device_name()
            );
        }
        let device = vulkan.device.clone();
        let semaphore = || {
            // SAFETY: a plain object on a live device, destroyed in Drop.
            unsafe { device.create_semaphore(&vk::SemaphoreCreateInfo::default(), None) }
        };
        let pool_info = vk::CommandPoolCreateInfo::default()
            .queue_family_index(vulkan.queue_family)
            .flags(vk::CommandPoolCreateFlags::RESET_COMMAND_BUFFER);
        // SAFETY: plain objects on a live device, destroyed in Drop.
        let (acquired, rendered, done, pool) = unsafe {
            (
                semaphore()?,
                semaphore()?,
                device.create_fence(
                    &vk::FenceCreateInfo::default().flags(vk::FenceCreateFlags::SIGNALED),
                    None,
                )?,
                device.create_command_pool(&pool_info, None)?,
            )
        };
        // SAFETY: the pool is live.
        let command_buffer = unsafe {
            device.allocate_command_buffers(
                &vk::CommandBufferAllocateInfo::default()
                    .command_pool(pool)
                    .command_buffer_count(1),
            )
        }?[0];
        let mut presenter = Presenter {
            swapchain_fn: ash::khr::swapchain::Device::new(vulkan.instance, vulkan.device),
            device,
            surface_fn,
            physical_device: vulkan.physical_device,
            queue: vulkan.queue,
            surface,
            swapchain: vk::SwapchainKHR::null(),
            images: Vec::new(),
            views: Vec::new(),
            presentable: Vec::new(),
            acquired,
            rendered,
            timeline: Timeline::new(gpu)?,
            frames: 0,
            done,
            pool,
            command_buffer,
            format: vk::SurfaceFormatKHR::default(),
            extent: vk::Extent2D::default(),
            mode: vk::PresentModeKHR::FIFO,
            copyable: false,
        };
        presenter.mode = presenter.choose_mode(mode)?;
        let size = window.inner_size();
        presenter.recreate(size.width, size.height)?;
        Ok(presenter)
    }

    /// The present mode asked for, or FIFO (which every surface has) saying why.
    fn choose_mode(&self, asked: PresentArg) -> anyhow::Result<vk::PresentModeKHR> {
        let wanted = match asked {
            PresentArg::Fifo => return Ok(vk::PresentModeKHR::FIFO),
            PresentArg::Mailbox => vk::PresentModeKHR::MAILBOX,
            PresentArg::Immediate => vk::PresentModeKHR::IMMEDIATE,
        };
        // SAFETY: a live surface.
        let modes = unsafe {
            self.surface_fn
                .get_physical_device_surface_present_modes(self.physical_device, self.surface)
        }
        .context("vkGetPhysicalDeviceSurfacePresentModesKHR")?;
        if modes.contains(&wanted) {
            Ok(wanted)
        } else {
            warn!("the surface has no {wanted:?} present mode (it has {modes:?}); presenting FIFO");
            Ok(vk::PresentModeKHR::FIFO)
        }
    }

    /// A swapchain of the surface's size (the window's `width × height` where the surface
    /// leaves it open) replacing the current one; `false` while the surface has no area (a
    /// minimized window): nothing is drawn until it has.
    pub fn recreate(&mut self, width: u32, height: u32) -> anyhow::Result<bool> {
        // SAFETY: a live surface.
        let capabilities = unsafe {
            self.surface_fn
                .get_physical_device_surface_capabilities(self.physical_device, self.surface)
        }
        .context("vkGetPhysicalDeviceSurfaceCapabilitiesKHR")?;
        let extent = if capabilities.current_extent.width == u32::MAX {
            vk::Extent2D {
                width: width.clamp(
                    capabilities.min_image_extent.width,
                    capabilities.max_image_extent.width,
                ),
                height: height.clamp(
                    capabilities.min_image_extent.height,
                    capabilities.max_image_extent.height,
                ),
            }
        } else {
            capabilities.current_extent
        };
        if extent.width == 0 || extent.height == 0 {
            return Ok(false);
        }
        // SAFETY: a live surface.
        let formats = unsafe {
            self.surface_fn
                .get_physical_device_surface_formats(self.physical_device, self.surface)
        }
        .context("vkGetPhysicalDeviceSurfaceFormatsKHR")?;
        let format = FORMATS
            .iter()
            .find_map(|f| {
                formats
                    .iter()
                    .find(|s| s.format == *f && s.color_space == vk::ColorSpaceKHR::SRGB_NONLINEAR)
            })
            .copied()
            .with_context(|| {
                format!("the surface offers none of the formats lensmap renders to ({formats:?})")
            })?;
        self.copyable = capabilities
            .supported_usage_flags
            .contains(vk::ImageUsageFlags::TRANSFER_SRC);
        let usage = if self.copyable {
            vk::ImageUsageFlags::COLOR_ATTACHMENT | vk::ImageUsageFlags::TRANSFER_SRC
        } else {
            vk::ImageUsageFlags::COLOR_ATTACHMENT
        };
        let mut count = capabilities.min_image_count + 1;
        if capabilities.max_image_count > 0 {
            count = count.min(capabilities.max_image_count);
        }
        let old = self.swapchain;
        let info = vk::SwapchainCreateInfoKHR::default()
            .surface(self.surface)
            .min_image_count(count)
            .image_format(format.format)
            .image_color_space(format.color_space)
            .image_extent(extent)
            .image_array_layers(1)
            .image_usage(usage)
            .image_sharing_mode(vk::SharingMode::EXCLUSIVE)
            .pre_transform(capabilities.current_transform)
            .composite_alpha(vk::CompositeAlphaFlagsKHR::OPAQUE)
            .present_mode(self.mode)
            .clipped(true)
            .old_swapchain(old);
        // SAFETY: nothing is in flight (the fence was waited for after the last frame).
        unsafe {
            self.device.device_wait_idle()?;
            self.destroy_views();
            self.swapchain = self
                .swapchain_fn
                .create_swapchain(&info, None)
                .context("vkCreateSwapchainKHR")?;
            if old != vk::SwapchainKHR::null() {
                self.swapchain_fn.destroy_swapchain(old, None);
            }
            self.images = self.swapchain_fn.get_swapchain_images(self.swapchain)?;
        }
        self.format = format;
        self.extent = extent;
        for &image in &self.images {
            let view_info = vk::ImageViewCreateInfo::default()
                .image(image)
                .view_type(vk::ImageViewType::TYPE_2D)
                .format(format.format)
                .subresource_range(colour_range());
            // SAFETY: a live image of this device; destroyed with the swapchain.
            self.views
                .push(unsafe { self.device.create_image_view(&view_info, None) }?);
            // SAFETY: a plain object; destroyed with the swapchain.
            self.presentable.push(unsafe {
                self.device
                    .create_semaphore(&vk::SemaphoreCreateInfo::default(), None)
            }?);
        }
        Ok(true)
    }

    /// Destroys the image views and per-image semaphores (not the swapchain).
    ///
    /// # Safety
    /// Nothing in flight uses them.
    unsafe fn destroy_views(&mut self) {
        for view in self.views.drain(..) {
            // SAFETY: the caller's promise.
            unsafe { self.device.destroy_image_view(view, None) };
        }
        for semaphore in self.presentable.drain(..) {
            // SAFETY: the caller's promise.
            unsafe { self.device.destroy_semaphore(semaphore, None) };
        }
    }

    /// The next image to draw, once the previous frame is done.
    pub fn acquire(&mut self) -> anyhow::Result<Acquired> {
        // SAFETY: live objects; the fence belongs to the previous frame's last submission.
        unsafe {
            self.device.wait_for_fences(&[self.done], true, u64::MAX)?;
            match self.swapchain_fn.acquire_next_image(
                self.swapchain,
                u64::MAX,
                self.acquired,
                vk::Fence::null(),
            ) {
                Ok((index, _suboptimal)) => Ok(Acquired::Image(index)),
                Err(vk::Result::ERROR_OUT_OF_DATE_KHR) => Ok(Acquired::OutOfDate),
                Err(e) => Err(e).context("vkAcquireNextImageKHR"),
            }
        }
    }

    /// Image `index` as a host image for lensmap's frame: written after the acquisition, left
    /// as a colour attachment for the overlay, signalling [`Self::finish`]'s wait and the
    /// timeline [`Self::wait_for_frame`] waits on.
    pub fn host_image(&mut self, index: u32) -> HostImage {
        self.frames += 1;
        HostImage {
            image: self.images[index as usize],
            view: self.views[index as usize],
            mip_level: 0,
            array_layer: 0,
            format: self.format.format,
            width: self.extent.width,
            height: self.extent.height,
            current_layout: vk::ImageLayout::UNDEFINED,
            final_layout: vk::ImageLayout::COLOR_ATTACHMENT_OPTIMAL,
            wait: vec![(self.acquired, 0)],
            signal: vec![(self.rendered, 0), (self.timeline.handle(), self.frames)],
        }
    }

    /// Waits until the frame of the last [`Self::host_image`] is rendered.
    pub fn wait_for_frame(&self) -> anyhow::Result<()> {
        self.timeline.wait(self.frames)?;
        Ok(())
    }

    /// The frame's last submission into image `index`: after lensmap's frame (`rendered`: it
    /// is in the image) or, when the frame failed, after the acquisition alone (the image is
    /// cleared), `draw` records the overlay into a dynamic rendering of the image; `copies`
    /// (when given) receive the frame before the overlay and the window after it; then the
    /// image goes to presentation. Returns `false` when the swapchain must be recreated.
    pub fn finish(
        &mut self,
        gpu: &Gpu,
        index: u32,
        rendered: bool,
        copies: Option<&Copies>,
        draw: impl FnOnce(vk::CommandBuffer, vk::Extent2D) -> anyhow::Result<()>,
    ) -> anyhow::Result<bool> {
        let image = self.images[index as usize];
        let cb = self.command_buffer;
        let device = &self.device;
        // SAFETY: the command buffer's previous submission is done (the fence was waited for in
        // acquire); every handle is live; the barriers name the image's real layouts.
        unsafe {
            device.reset_command_buffer(cb, vk::CommandBufferResetFlags::empty())?;
            device.begin_command_buffer(
                cb,
                &vk::CommandBufferBeginInfo::default()
                    .flags(vk::CommandBufferUsageFlags::ONE_TIME_SUBMIT),
            )?;
            gpu.begin_label(cb, "viewer overlay");
            let mut layout = if rendered {
                vk::ImageLayout::COLOR_ATTACHMENT_OPTIMAL
            } else {
                vk::ImageLayout::UNDEFINED
            };
            if let (Some(copies), true) = (copies, rendered) {
                self.copy(cb, image, &mut layout, &copies.frame);
            }
            barrier(
                device,
                cb,
                image,
                &mut layout,
                vk::ImageLayout::COLOR_ATTACHMENT_OPTIMAL,
            );
            let attachment = [vk::RenderingAttachmentInfo::default()
                .image_view(self.views[index as usize])
                .image_layout(vk::ImageLayout::COLOR_ATTACHMENT_OPTIMAL)
                .load_op(if rendered {
                    vk::AttachmentLoadOp::LOAD
                } else {
                    vk::AttachmentLoadOp::CLEAR
                })
                .store_op(vk::AttachmentStoreOp::STORE)
                .clear_value(vk::ClearValue::default())];
            let area = vk::Rect2D {
                offset: vk::Offset2D::default(),
                extent: self.extent,
            };
            device.cmd_begin_rendering(
                cb,
                &vk::RenderingInfo::default()
                    .render_area(area)
                    .layer_count(1)
                    .color_attachments(&attachment),
            );
            draw(cb, self.extent)?;
            device.cmd_end_rendering(cb);
            if let Some(copies) = copies {
                self.copy(cb, image, &mut layout, &copies.window);
            }
            barrier(
                device,
                cb,
                image,
                &mut layout,
                vk::ImageLayout::PRESENT_SRC_KHR,
            );
            gpu.end_label(cb);
            device.end_command_buffer(cb)?;
            let wait = [vk::SemaphoreSubmitInfo::default()
                .semaphore(if rendered {
                    self.rendered
                } else {
                    self.acquired
                })
                .stage_mask(
                    vk::PipelineStageFlags2::COLOR_ATTACHMENT_OUTPUT
                        | vk::PipelineStageFlags2::TRANSFER,
                )];
            let signal = [vk::SemaphoreSubmitInfo::default()
                .semaphore(self.presentable[index as usize])
                .stage_mask(vk::PipelineStageFlags2::ALL_COMMANDS)];
            let buffers = [vk::CommandBufferSubmitInfo::default().command_buffer(cb)];
            let submit = [vk::SubmitInfo2::default()
                .wait_semaphore_infos(&wait)
                .command_buffer_infos(&buffers)
                .signal_semaphore_infos(&signal)];
            device.reset_fences(&[self.done])?;
            device.queue_submit2(self.queue, &submit, self.done)?;
            let swapchains = [self.swapchain];
            let indices = [index];
            let waits = [self.presentable[index as usize]];
            let present = vk::PresentInfoKHR::default()
                .wait_semaphores(&waits)
                .swapchains(&swapchains)
                .image_indices(&indices);
            match self.swapchain_fn.queue_present(self.queue, &present) {
                Ok(false) => Ok(true),
                Ok(true) | Err(vk::Result::ERROR_OUT_OF_DATE_KHR) => Ok(false),
                Err(e) => Err(e).context("vkQueuePresentKHR"),
            }
        }
    }

    /// Waits until the frame's last submission is done (its copies readable).
    pub fn wait(&self) -> anyhow::Result<()> {
        // SAFETY: a live fence.
        unsafe { self.device.wait_for_fences(&[self.done], true, u64::MAX) }?;
        Ok(())
    }

    /// Records a copy of `image` (in `layout`) into `buffer`, leaving it in TRANSFER_SRC.
    ///
    /// # Safety
    /// `cb` is recording; `buffer` holds the image's bytes.
    unsafe fn copy(
        &self,
        cb: vk::CommandBuffer,
        image: vk::Image,
        layout: &mut vk::ImageLayout,
        buffer: &Buffer,
    ) {
        barrier(
            &self.device,
            cb,
            image,
            layout,
            vk::ImageLayout::TRANSFER_SRC_OPTIMAL,
        );
        // SAFETY: the caller's promise; the image is in TRANSFER_SRC now.
        unsafe {
            lensmap::gpu::copies::copy_image_to_buffer(
                &self.device,
                cb,
                image,
                buffer.handle,
                self.extent.width,
                self.extent.height,
            )
        };
    }

    /// Two readback buffers of the swapchain's size for a screenshot.
    pub fn copies(&self, gpu: &Gpu) -> anyhow::Result<Copies> {
        if !self.copyable {
            bail!(
                "the surface's images cannot be copied from (no TRANSFER_SRC usage): no screenshot"
            );
        }
        let bytes = u64::from(self.extent.width) * u64::from(self.extent.height) * 4;
        Ok(Copies {
            frame: Buffer::new(gpu, "screenshot frame", bytes, BufferUsage::Readback)?,
            window: Buffer::new(gpu, "screenshot window", bytes, BufferUsage::Readback)?,
        })
    }

    /// A copied image as RGB8 rows (the swapchain's BGRA or RGBA bytes reordered).
    pub fn rgb8(&self, buffer: &Buffer) -> Vec<u8> {
        let bgra = matches!(
            self.format.format,
            vk::Format::B8G8R8A8_SRGB | vk::Format::B8G8R8A8_UNORM
        );
        buffer
            .read()
            .chunks_exact(4)
            .flat_map(|p| {
                if bgra {
                    [p[2], p[1], p[0]]
                } else {
                    [p[0], p[1], p[2]]
                }
            })
            .collect()
    }
}

impl Drop for Presenter {
    fn drop(&mut self) {
        // SAFETY: the device is idle after the wait; every object was made here.
        unsafe {
            let _ = self.device.device_wait_idle();
            self.destroy_views();
            self.swapchain_fn.destroy_swapchain(self.swapchain, None);
            self.surface_fn.destroy_surface(self.surface, None);
            self.device.destroy_command_pool(self.pool, None);
            self.device.destroy_fence(self.done, None);
            self.device.destroy_semaphore(self.acquired, None);
            self.device.destroy_semaphore(self.rendered, None);
        }
    }
}

/// The one mip level and layer of a swapchain image.
fn colour_range() -> vk::ImageSubresourceRange {
    vk::ImageSubresourceRange {
        aspect_mask: vk::ImageAspectFlags::COLOR,
        base_mip_level: 0,
        level_count: 1,
        base_array_layer: 0,
        layer_count: 1,
    }
}

/// Records a full barrier of `image` from `*layout` to `to` (all prior writes and transfers
/// made visible to all later colour and transfer work), and notes the new layout.
fn barrier(
    device: &ash::Device,
    cb: vk::CommandBuffer,
    image: vk::Image,
    layout: &mut vk::ImageLayout,
    to: vk::ImageLayout,
) {
    if *layout == to {
        return;
    }
    let stages =
        vk::PipelineStageFlags2::COLOR_ATTACHMENT_OUTPUT | vk::PipelineStageFlags2::TRANSFER;
    let accesses = vk::AccessFlags2::COLOR_ATTACHMENT_WRITE
        | vk::AccessFlags2::COLOR_ATTACHMENT_READ
        | vk::AccessFlags2::TRANSFER_READ;
    let barrier = [vk::ImageMemoryBarrier2::default()
        .src_stage_mask(stages)
        .src_access_mask(vk::AccessFlags2::COLOR_ATTACHMENT_WRITE)
        .dst_stage_mask(stages)
        .dst_access_mask(if to == vk::ImageLayout::PRESENT_SRC_KHR {
            vk::AccessFlags2::NONE
        } else {
            accesses
        })
        .old_layout(*layout)
        .new_layout(to)
        .image(image)
        .subresource_range(colour_range())];
    // SAFETY: `cb` is recording (the caller's), the image is live.
    unsafe {
        device.cmd_pipeline_barrier2(
            cb,
            &vk::DependencyInfo::default().image_memory_barriers(&barrier),
        )
    };
    *layout = to;
}
