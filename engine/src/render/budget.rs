//! Whether a framebuffer fits the device, checked before any work: each side against
//! `maxImageDimension2D`, and the targets of every frame in flight (colour, depth, readback, a
//! blending scheme's scratch images) against a share of the largest device-local heap. A
//! refusal is a [`FramebufferError`] carrying the sizes and limits, worded by each front end.

use super::{FRAMES_IN_FLIGHT, RenderError, TargetFormat, targets::Scratch};
use crate::{
    gpu::Gpu,
    options::{LibraryWords, OptionWords, Worded},
};

/// The share of the largest device-local heap the framebuffer targets may take; the rest is
/// for layered EMs, light maps, meshes and the driver.
pub const FRAMEBUFFER_HEAP_SHARE: f64 = 0.75;

/// A framebuffer this device cannot hold. Its message names the options that size it (the
/// camera's `width`, `height`, `supersampling`, the frame's `format` and `blend`).
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error("{}", self.worded(&LibraryWords))]
pub enum FramebufferError {
    /// A side is longer than the device's `maxImageDimension2D`.
    TooLarge {
        /// Framebuffer width, subpixels.
        width: u32,
        /// Framebuffer height, subpixels.
        height: u32,
        /// The device's `maxImageDimension2D`.
        limit: u32,
    },
    /// The targets of every frame in flight need more device memory than
    /// [`FRAMEBUFFER_HEAP_SHARE`] of the largest device-local heap.
    OverBudget {
        /// Framebuffer width, subpixels.
        width: u32,
        /// Framebuffer height, subpixels.
        height: u32,
        /// The framebuffer's format.
        format: TargetFormat,
        /// Framebuffer-sized scratch images of a blending scheme, per frame (0: none).
        scratch: u32,
        /// Bytes the targets need.
        needed: u64,
        /// Bytes they may take.
        budget: u64,
        /// Frames in flight, each with its own targets.
        frames_in_flight: usize,
    },
}

impl Worded for FramebufferError {
    fn worded(&self, words: &dyn OptionWords) -> String {
        match *self {
            FramebufferError::TooLarge {
                width,
                height,
                limit,
            } => format!(
                "the framebuffer is {width}×{height} subpixels, past this device's limit of {limit} a side (maxImageDimension2D); give a smaller image or less supersampling ({}/{}/{})",
                words.option("width"),
                words.option("height"),
                words.option("supersampling")
            ),
            FramebufferError::OverBudget {
                width,
                height,
                format,
                scratch,
                needed,
                budget,
                frames_in_flight,
            } => {
                let mib = |bytes: u64| bytes as f64 / (1u64 << 20) as f64;
                let (scratch_images, fewer_scratch) = if scratch > 0 {
                    (
                        format!(" and the blending scheme's {scratch} scratch images"),
                        format!(
                            " or {}",
                            words.setting("blend", super::BlendScheme::FrontToBack.name())
                        ),
                    )
                } else {
                    (String::new(), String::new())
                };
                format!(
                    "the framebuffer is {width}×{height} subpixels in {}: its targets{scratch_images} need {:.0} MiB of device memory ({frames_in_flight} frames in flight), past this device's budget of {:.0} MiB ({:.0}% of its largest device-local heap); give a smaller image, less supersampling, a smaller {}{fewer_scratch}",
                    format.name(),
                    mib(needed),
                    mib(budget),
                    FRAMEBUFFER_HEAP_SHARE * 100.0,
                    words.option("format"),
                )
            }
        }
    }
}

/// Checks a framebuffer of `width × height` subpixels in `format` against the device, before any
/// work: each side against `maxImageDimension2D`, and the colour, depth and readback targets of
/// every frame in flight against [`FRAMEBUFFER_HEAP_SHARE`] of the largest device-local heap.
pub fn check_framebuffer(
    gpu: &Gpu,
    width: u32,
    height: u32,
    format: TargetFormat,
) -> Result<(), RenderError> {
    check_dimensions(gpu, width, height)?;
    Ok(framebuffer_budget(
        width,
        height,
        format,
        0,
        gpu.device_local_heap_bytes(),
    )?)
}

/// [`check_framebuffer`]'s budget with `scratch` more framebuffer-sized colour images per frame
/// (a blending scheme's, [`Scratch`]), checked before they are made.
pub(super) fn check_scratch_budget(
    gpu: &Gpu,
    (width, height): (u32, u32),
    format: TargetFormat,
    scratch: usize,
) -> Result<(), RenderError> {
    Ok(framebuffer_budget(
        width,
        height,
        format,
        Scratch::layers_for(scratch),
        gpu.device_local_heap_bytes(),
    )?)
}

/// Each side of a `width × height` framebuffer against the device's `maxImageDimension2D`.
pub(super) fn check_dimensions(gpu: &Gpu, width: u32, height: u32) -> Result<(), RenderError> {
    let limit = gpu.properties().limits.max_image_dimension2_d;
    if width > limit || height > limit {
        return Err(FramebufferError::TooLarge {
            width,
            height,
            limit,
        }
        .into());
    }
    Ok(())
}

/// The device memory the targets of [`FRAMES_IN_FLIGHT`] frames of `width × height` subpixels in
/// `format` take (colour, 32-bit depth, readback, and `scratch` colour images of a blending
/// scheme), against [`FRAMEBUFFER_HEAP_SHARE`] of `heap_bytes`.
fn framebuffer_budget(
    width: u32,
    height: u32,
    format: TargetFormat,
    scratch: u32,
    heap_bytes: u64,
) -> Result<(), FramebufferError> {
    let colour = u64::from(crate::gpu::format_bytes(super::vulkan::vk_format(
        format.graph_format(),
    )));
    let per_frame = u64::from(width) * u64::from(height) * ((2 + u64::from(scratch)) * colour + 4);
    let needed = per_frame * FRAMES_IN_FLIGHT as u64;
    let budget = (heap_bytes as f64 * FRAMEBUFFER_HEAP_SHARE) as u64;
    if needed > budget {
        return Err(FramebufferError::OverBudget {
            width,
            height,
            format,
            scratch,
            needed,
            budget,
            frames_in_flight: FRAMES_IN_FLIGHT,
        });
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::{FRAMEBUFFER_HEAP_SHARE, FramebufferError, framebuffer_budget};
    use crate::options::Worded;
    use crate::render::{FRAMES_IN_FLIGHT, TargetFormat, tests::Flags};

    /// The budget is the targets' bytes, counted independently here: RGBA32F colour (16 bytes),
    /// its readback (16) and 32-bit depth (4) per subpixel, for every frame in flight.
    #[test]
    fn the_framebuffer_budget_counts_every_target_of_every_frame_in_flight() {
        let (width, height) = (4000u32, 3000u32);
        let needed = u64::from(width) * u64::from(height) * 36 * FRAMES_IN_FLIGHT as u64;
        let heap_fitting = (needed as f64 / FRAMEBUFFER_HEAP_SHARE).ceil() as u64 + 1;
        assert!(framebuffer_budget(width, height, TargetFormat::Rgba32f, 0, heap_fitting).is_ok());
        let error =
            framebuffer_budget(width, height, TargetFormat::Rgba32f, 0, heap_fitting - 1024)
                .unwrap_err();
        let (library, flags) = (error.to_string(), error.worded(&Flags));
        assert!(
            library.contains("4000×3000") && library.contains("a smaller `format`"),
            "{library}"
        );
        assert!(
            flags.contains("--format") && !library.contains("--"),
            "{flags}"
        );
        // RGBA8 needs 4 + 4 + 4 bytes a subpixel: a third of RGBA32F's, so it fits there.
        assert!(framebuffer_budget(width, height, TargetFormat::Rgba8, 0, needed / 2).is_ok());
        assert!(
            framebuffer_budget(1, 1, TargetFormat::Rgba8, 0, 0).is_err(),
            "no heap"
        );
        // A blending scheme's scratch images count too: four more RGBA32F images (64 bytes a
        // subpixel) take the frame past the heap that fits the targets alone, naming the blend.
        let error =
            framebuffer_budget(width, height, TargetFormat::Rgba32f, 4, heap_fitting).unwrap_err();
        let (library, flags) = (error.to_string(), error.worded(&Flags));
        assert!(
            library.contains("4 scratch images") && library.contains("`blend` = front-to-back"),
            "{library}"
        );
        assert!(flags.contains("--blend front-to-back"), "{flags}");
        let with_scratch = u64::from(width) * u64::from(height) * 100 * FRAMES_IN_FLIGHT as u64;
        let fitting = (with_scratch as f64 / FRAMEBUFFER_HEAP_SHARE).ceil() as u64 + 1;
        assert!(framebuffer_budget(width, height, TargetFormat::Rgba32f, 4, fitting).is_ok());
    }

    /// A side past the device's limit names the limit and, in each front end's words, the
    /// options that size the framebuffer.
    #[test]
    fn a_side_past_the_limit_names_the_sizing_options() {
        let error = FramebufferError::TooLarge {
            width: 20000,
            height: 10,
            limit: 16384,
        };
        assert_eq!(
            error.to_string(),
            "the framebuffer is 20000×10 subpixels, past this device's limit of 16384 a side (maxImageDimension2D); give a smaller image or less supersampling (`width`/`height`/`supersampling`)"
        );
        assert!(
            error
                .worded(&Flags)
                .ends_with("(--width/--height/--supersampling)")
        );
    }
}
