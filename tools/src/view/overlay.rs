//! The viewer's overlay: the paper's per-frame table, the experiment's settings, where the
//! camera is in the view space, the reference's progress and PSNR, the key list, the
//! tessellation wireframe and the reference image, drawn by egui over the frame with
//! egui-ash-renderer in the frame's last submission.

use ash::vk;
use egui::{Align2, Color32, Pos2, Rect, RichText, Stroke, TextureHandle, TextureOptions, Vec2};
use egui_ash_renderer::{DynamicRendering, Options, RenderMode, Renderer};
use lensmap::gpu::Gpu;

use super::keys::{self, ReferenceView};

/// Colours of subdivision depths 0, 1, 2, … (the last repeats for deeper levels): the
/// hybrid-rendering paper's Figure 5 colours the tessellation by depth the same way, coarse to
/// fine.
pub const DEPTH_COLOURS: [Color32; 8] = [
    Color32::from_rgb(90, 90, 255),
    Color32::from_rgb(0, 200, 255),
    Color32::from_rgb(0, 230, 120),
    Color32::from_rgb(160, 240, 0),
    Color32::from_rgb(255, 230, 0),
    Color32::from_rgb(255, 150, 0),
    Color32::from_rgb(255, 60, 40),
    Color32::from_rgb(255, 0, 200),
];

/// What the overlay shows this frame.
#[derive(Default)]
pub struct OverlayView {
    /// Lines of the top-left panel: the scene, device, EMs and the experiment's settings.
    pub settings: Vec<String>,
    /// The table: (stage, value) rows.
    pub table: Vec<(String, String)>,
    /// Where the camera is: the samples in use and their weights.
    pub viewpoints: String,
    /// The camera has left the view space: said in red.
    pub outside: Option<String>,
    /// Notes (a key's effect, a stopped move, shells the camera is inside), newest last.
    pub notes: Vec<String>,
    /// The reference's state line.
    pub reference: Option<String>,
    /// The key list.
    pub help: bool,
    /// Wireframe edges in window pixels, with their depth.
    pub wireframe: Vec<([Pos2; 2], u8)>,
    /// The reference image and how it is shown.
    pub image: Option<(ReferenceView, TextureHandle)>,
}

/// egui and its Vulkan renderer.
pub struct Overlay {
    ctx: egui::Context,
    renderer: Renderer<egui_ash_renderer::allocator::DefaultAllocator>,
    /// The command pool egui-ash-renderer uploads textures with.
    pool: vk::CommandPool,
    device: ash::Device,
    queue: vk::Queue,
    format: vk::Format,
    /// Textures egui freed in the last frame, freed once that frame is done.
    to_free: Vec<egui::TextureId>,
}

impl Overlay {
    /// The overlay for images of `format`.
    pub fn new(gpu: &Gpu, format: vk::Format) -> anyhow::Result<Overlay> {
        let vulkan = gpu.vulkan();
        let renderer = Renderer::with_default_allocator(
            vulkan.instance,
            vulkan.physical_device,
            vulkan.device.clone(),
            render_mode(format),
            options(format),
        )?;
        let pool_info = vk::CommandPoolCreateInfo::default()
            .queue_family_index(vulkan.queue_family)
            .flags(vk::CommandPoolCreateFlags::RESET_COMMAND_BUFFER);
        // SAFETY: a plain object on a live device, destroyed in Drop.
        let pool = unsafe { vulkan.device.create_command_pool(&pool_info, None) }?;
        let ctx = egui::Context::default();
        ctx.set_visuals(egui::Visuals::dark());
        Ok(Overlay {
            ctx,
            renderer,
            pool,
            device: vulkan.device.clone(),
            queue: vulkan.queue,
            format,
            to_free: Vec::new(),
        })
    }

    /// The egui context (for textures).
    pub fn context(&self) -> &egui::Context {
        &self.ctx
    }

    /// Follows a change of the swapchain's format.
    pub fn set_format(&mut self, format: vk::Format) -> anyhow::Result<()> {
        if format != self.format {
            self.renderer.set_render_mode(render_mode(format))?;
            self.format = format;
        }
        Ok(())
    }

    /// Lays out the overlay for a window of `size` pixels and uploads its textures; the
    /// primitives to draw come back.
    pub fn prepare(
        &mut self,
        size: vk::Extent2D,
        view: &OverlayView,
    ) -> anyhow::Result<Vec<egui::ClippedPrimitive>> {
        let input = egui::RawInput {
            screen_rect: Some(Rect::from_min_size(
                Pos2::ZERO,
                Vec2::new(size.width as f32, size.height as f32),
            )),
            ..Default::default()
        };
        let mut output = self.ctx.run_ui(input, |ui| draw(ui.ctx(), size, view));
        // Every delta is handled (egui checks that none is dropped): the new textures uploaded
        // now, the freed ones once the frame that may still use them is done.
        let delta = &mut output.textures_delta;
        for (id, deltas) in delta.set.drain() {
            for delta in deltas {
                self.renderer
                    .set_texture(self.queue, self.pool, id, &delta)?;
            }
        }
        self.to_free.extend(delta.free.drain());
        Ok(self.ctx.tessellate(output.shapes, output.pixels_per_point))
    }

    /// Records the primitives into the command buffer (inside the frame's rendering).
    pub fn record(
        &mut self,
        cb: vk::CommandBuffer,
        extent: vk::Extent2D,
        primitives: &[egui::ClippedPrimitive],
    ) -> anyhow::Result<()> {
        self.renderer.cmd_draw(cb, extent, 1.0, primitives)?;
        Ok(())
    }

    /// Frees what egui let go of, once the frame that last used it is done.
    pub fn frame_done(&mut self) -> anyhow::Result<()> {
        for id in std::mem::take(&mut self.to_free) {
            self.renderer.free_texture(id)?;
        }
        Ok(())
    }
}

impl Drop for Overlay {
    fn drop(&mut self) {
        // SAFETY: the device is idle after the wait; the pool was made here.
        unsafe {
            let _ = self.device.device_wait_idle();
            self.device.destroy_command_pool(self.pool, None);
        }
    }
}

fn render_mode(format: vk::Format) -> RenderMode {
    RenderMode::DynamicRendering(DynamicRendering {
        color_attachment_format: format,
        depth_attachment_format: None,
        stencil_attachment_format: None,
    })
}

fn options(format: vk::Format) -> Options {
    Options {
        in_flight_frames: 1,
        srgb_framebuffer: matches!(
            format,
            vk::Format::B8G8R8A8_SRGB | vk::Format::R8G8B8A8_SRGB
        ),
        ..Options::default()
    }
}

/// The overlay's layout.
fn draw(ctx: &egui::Context, size: vk::Extent2D, view: &OverlayView) {
    let (w, h) = (size.width as f32, size.height as f32);
    let painter = ctx.layer_painter(egui::LayerId::new(
        egui::Order::Background,
        egui::Id::new("lensmap images"),
    ));
    if let Some((mode, texture)) = &view.image {
        let full = Rect::from_min_size(Pos2::ZERO, Vec2::new(w, h));
        match mode {
            ReferenceView::SideBySide => {
                // The right half of the reference over the right half of the frame, pixel for
                // pixel, with a line at the seam.
                let half = Rect::from_min_max(Pos2::new(w * 0.5, 0.0), Pos2::new(w, h));
                let uv = Rect::from_min_max(Pos2::new(0.5, 0.0), Pos2::new(1.0, 1.0));
                painter.image(texture.id(), half, uv, Color32::WHITE);
                painter.line_segment(
                    [Pos2::new(w * 0.5, 0.0), Pos2::new(w * 0.5, h)],
                    Stroke::new(1.0, Color32::WHITE),
                );
            }
            ReferenceView::Difference => {
                let uv = Rect::from_min_max(Pos2::ZERO, Pos2::new(1.0, 1.0));
                painter.image(texture.id(), full, uv, Color32::WHITE);
            }
            ReferenceView::Off => {}
        }
    }
    for (edge, depth) in &view.wireframe {
        let colour = DEPTH_COLOURS[usize::from(*depth).min(DEPTH_COLOURS.len() - 1)];
        painter.line_segment(*edge, Stroke::new(1.0, colour));
    }
    let frame = egui::Frame::new()
        .fill(Color32::from_black_alpha(170))
        .inner_margin(6.0)
        .corner_radius(4.0);
    let small = |text: &str| {
        RichText::new(text)
            .monospace()
            .size(11.0)
            .color(Color32::WHITE)
    };
    egui::Area::new(egui::Id::new("settings"))
        .anchor(Align2::LEFT_TOP, Vec2::new(6.0, 6.0))
        .show(ctx, |ui| {
            frame.show(ui, |ui| {
                ui.set_max_width(w - 24.0);
                for line in &view.settings {
                    ui.label(small(line));
                }
                ui.label(small(&view.viewpoints));
                if let Some(outside) = &view.outside {
                    ui.label(
                        RichText::new(outside)
                            .monospace()
                            .size(11.0)
                            .strong()
                            .color(Color32::from_rgb(255, 80, 60)),
                    );
                }
                if let Some(reference) = &view.reference {
                    ui.label(small(reference));
                }
                for note in &view.notes {
                    ui.label(
                        RichText::new(note)
                            .monospace()
                            .size(11.0)
                            .color(Color32::from_rgb(255, 220, 120)),
                    );
                }
            });
        });
    egui::Area::new(egui::Id::new("table"))
        .anchor(Align2::RIGHT_BOTTOM, Vec2::new(-6.0, -6.0))
        .show(ctx, |ui| {
            frame.show(ui, |ui| {
                egui::Grid::new("stats")
                    .spacing([10.0, 0.0])
                    .show(ui, |ui| {
                        for (stage, value) in &view.table {
                            ui.label(small(stage));
                            ui.label(small(value));
                            ui.end_row();
                        }
                    });
            });
        });
    if view.help {
        egui::Area::new(egui::Id::new("help"))
            .anchor(Align2::LEFT_BOTTOM, Vec2::new(6.0, -6.0))
            .show(ctx, |ui| {
                frame.show(ui, |ui| {
                    ui.label(small(&keys::help_text()));
                });
            });
    }
}

/// An RGB8 image as an egui texture.
pub fn texture(
    ctx: &egui::Context,
    name: &str,
    width: u32,
    height: u32,
    rgb: &[u8],
) -> TextureHandle {
    let image = egui::ColorImage::from_rgb([width as usize, height as usize], rgb);
    ctx.load_texture(name, image, TextureOptions::NEAREST)
}
