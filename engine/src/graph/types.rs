//! What a graph is declared with: resource handles and descriptions, attachments with load and
//! store ops, fixed-function state, and passes.

use std::fmt;

/// Handle of an image declared in a graph.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct ImageId(pub u32);

/// Handle of a buffer declared in a graph.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct BufferId(pub u32);

/// Image formats the graph knows.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Format {
    /// 8-bit unsigned normalized RGBA (fixed-point blending).
    Rgba8Unorm,
    /// 16-bit float RGBA.
    Rgba16Float,
    /// 32-bit float RGBA (exact against the f64 model).
    Rgba32Float,
    /// 8-bit unsigned normalized BGRA (a host's swapchain image, typically).
    Bgra8Unorm,
    /// 8-bit RGBA, sRGB-encoded on write.
    Rgba8Srgb,
    /// 8-bit BGRA, sRGB-encoded on write.
    Bgra8Srgb,
    /// 32-bit float depth.
    Depth32Float,
}

impl Format {
    /// Whether this is a depth format.
    pub fn is_depth(self) -> bool {
        self == Format::Depth32Float
    }
}

impl fmt::Display for Format {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Format::Rgba8Unorm => "rgba8",
            Format::Rgba16Float => "rgba16f",
            Format::Rgba32Float => "rgba32f",
            Format::Bgra8Unorm => "bgra8",
            Format::Rgba8Srgb => "rgba8-srgb",
            Format::Bgra8Srgb => "bgra8-srgb",
            Format::Depth32Float => "d32f",
        })
    }
}

/// An image's description.
#[derive(Clone, Debug, PartialEq)]
pub struct ImageInfo {
    /// Debug name.
    pub name: String,
    /// Format.
    pub format: Format,
    /// Width × height of level 0.
    pub extent: (u32, u32),
    /// Where the image comes from.
    pub origin: Origin,
}

/// Where an image of a graph comes from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Origin {
    /// Created for the frame (a transient or the frame's own output); undefined before it.
    Frame,
    /// Exists before the frame (an uploaded texture), in [`Layout::ShaderRead`].
    Imported,
    /// Owned by the graph's user (a host's `VkImage`): in [`Layout::External`] before the frame,
    /// and handed back in it by a [`PassKind::Export`].
    External,
}

/// A buffer's description.
#[derive(Clone, Debug, PartialEq)]
pub struct BufferInfo {
    /// Debug name.
    pub name: String,
    /// Size in bytes.
    pub size: u64,
    /// Where its contents come from.
    pub origin: BufferOrigin,
}

/// Where a buffer of a graph comes from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BufferOrigin {
    /// Made for the frame, or its contents before the frame do not matter: its first use waits
    /// for nothing.
    Frame,
    /// Kept across submissions (a tessellation's shared buffers, a part's outputs): its first
    /// use in the frame waits for the work submitted before ([`Access::Earlier`]).
    Kept,
}

/// Image layouts, in the graph's words (render maps them to Vulkan's).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Layout {
    /// Contents undefined.
    Undefined,
    /// Colour attachment.
    ColourAttachment,
    /// Depth attachment.
    DepthAttachment,
    /// Sampled in shaders.
    ShaderRead,
    /// Source of a copy.
    TransferSrc,
    /// Whatever layout the owner of an [`Origin::External`] image has it in before the frame,
    /// or wants it in after (`render/` maps it to the layouts the host gave).
    External,
}

impl fmt::Display for Layout {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Layout::Undefined => "undefined",
            Layout::ColourAttachment => "colour",
            Layout::DepthAttachment => "depth",
            Layout::ShaderRead => "shader-read",
            Layout::TransferSrc => "transfer-src",
            Layout::External => "external",
        })
    }
}

/// How an access uses a resource (stage and access together), for barriers.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Access {
    /// Nothing yet.
    None,
    /// Colour attachment read (blend/load) and write.
    ColourAttachment,
    /// Depth test and/or write.
    DepthAttachment,
    /// Sampled by the fragment shader.
    FragmentSample,
    /// Read by the vertex stage: a storage buffer, indices or indirect draw arguments.
    VertexStorageRead,
    /// Read by a compute shader (storage buffer).
    ComputeRead,
    /// Written (and perhaps read, atomics included) by a compute shader (storage buffer).
    ComputeWrite,
    /// Read as a dispatch's indirect arguments.
    IndirectRead,
    /// Read by the host once the submission completed.
    HostRead,
    /// Whatever the work submitted before this submission did to a kept buffer.
    Earlier,
    /// Copy source.
    TransferRead,
    /// Copy destination.
    TransferWrite,
    /// Any use by the owner of an [`Origin::External`] image, before or after the frame.
    External,
}

impl Access {
    /// Whether the access writes (a read-write counts as a write).
    pub fn writes(self) -> bool {
        matches!(
            self,
            Access::ColourAttachment
                | Access::DepthAttachment
                | Access::ComputeWrite
                | Access::TransferWrite
                | Access::External
                | Access::Earlier
        )
    }

    /// Its name in a plan's barriers.
    pub fn name(self) -> &'static str {
        match self {
            Access::None => "none",
            Access::ColourAttachment => "colour",
            Access::DepthAttachment => "depth",
            Access::FragmentSample => "sampled",
            Access::VertexStorageRead => "vertex",
            Access::ComputeRead => "compute-read",
            Access::ComputeWrite => "compute",
            Access::IndirectRead => "indirect",
            Access::TransferRead => "transfer-read",
            Access::TransferWrite => "transfer",
            Access::HostRead => "host",
            Access::External => "external",
            Access::Earlier => "earlier",
        }
    }
}

/// What happens to an attachment when a pass begins.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum LoadOp {
    /// Keep the contents (blending onto them).
    Load,
    /// Clear to a colour (or depth in `[0]`).
    Clear([f32; 4]),
    /// Contents undefined.
    DontCare,
}

/// What happens to an attachment when a pass ends.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum StoreOp {
    /// Keep the results.
    Store,
    /// Discard them.
    DontCare,
}

/// Colour blending of one attachment.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Blend {
    /// No blending: the fragment replaces the pixel.
    Replace,
    /// Front-to-back "over" on colour and alpha: `src·(1 − dstα) + dst·1`.
    FrontToBackOver,
    /// Back-to-front "over" on colour and alpha: `src·1 + dst·(1 − srcα)`.
    BackToFrontOver,
    /// Addition on colour and alpha: `src·1 + dst·1`.
    Add,
}

impl fmt::Display for Blend {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Blend::Replace => "replace",
            Blend::FrontToBackOver => "src*(1-dstA)+dst",
            Blend::BackToFrontOver => "src+dst*(1-srcA)",
            Blend::Add => "src+dst",
        })
    }
}

/// Which colour channels a pass writes (bit 0 R … bit 3 A).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct ColourMask(pub u8);

impl ColourMask {
    /// All four channels.
    pub const RGBA: ColourMask = ColourMask(0b1111);
    /// Alpha only: with an output of 0 this is the paper's alpha clear (rgb×1, α×0).
    pub const A: ColourMask = ColourMask(0b1000);
    /// Colour only: α keeps what the pixel held.
    pub const RGB: ColourMask = ColourMask(0b0111);
}

impl fmt::Display for ColourMask {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        for (bit, c) in ['R', 'G', 'B', 'A'].iter().enumerate() {
            if self.0 & (1 << bit) != 0 {
                write!(f, "{c}")?;
            }
        }
        Ok(())
    }
}

/// Depth comparison.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum CompareOp {
    /// Pass when nearer.
    Less,
    /// Pass when nearer or equal (the passes after a lens prime).
    LessOrEqual,
}

/// Face culling.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Cull {
    /// Draw both faces.
    None,
    /// Drop back faces (counter-clockwise is front).
    Back,
}

/// A colour attachment of a draw pass.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ColourAttachment {
    /// The image.
    pub image: ImageId,
    /// Load op.
    pub load: LoadOp,
    /// Store op.
    pub store: StoreOp,
    /// Blending.
    pub blend: Blend,
    /// Channels written.
    pub write_mask: ColourMask,
}

/// The depth attachment of a draw pass.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DepthAttachment {
    /// The image.
    pub image: ImageId,
    /// Load op (`Clear([d, ..])` clears to depth d).
    pub load: LoadOp,
    /// Store op.
    pub store: StoreOp,
    /// Depth test, if any.
    pub test: Option<CompareOp>,
    /// Whether depth is written.
    pub write: bool,
}

/// The pipeline a draw pass needs, derived from its declaration: two passes with equal keys share
/// one pipeline. `P` is the shader program type of the graph's user (`render/` maps it to SPIR-V).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct PipelineKey<P> {
    /// The shader program.
    pub program: P,
    /// Colour format.
    pub colour_format: Format,
    /// Depth format, if a depth attachment is bound.
    pub depth_format: Option<Format>,
    /// Blending.
    pub blend: Blend,
    /// Write mask.
    pub write_mask: ColourMask,
    /// Depth test.
    pub depth_test: Option<CompareOp>,
    /// Depth write.
    pub depth_write: bool,
    /// Culling.
    pub cull: Cull,
}

/// What a pass does.
#[derive(Clone, Debug, PartialEq)]
pub enum PassKind<D, P> {
    /// Rasterize `draws` with `program` into the attachments.
    Draw {
        /// The shader program (a type of the graph's user: the graph only compares it).
        program: P,
        /// Colour attachment.
        colour: ColourAttachment,
        /// Depth attachment.
        depth: Option<DepthAttachment>,
        /// Face culling.
        cull: Cull,
        /// Images sampled by the fragment shader.
        sampled: Vec<ImageId>,
        /// Buffers read by the vertex stage: as storage, indices or indirect arguments.
        storage: Vec<BufferId>,
        /// The draws, as payloads `render/` understands.
        draws: Vec<D>,
    },
    /// Run `dispatches` (compute or transfer work, as payloads `render/` understands), outside
    /// any rendering instance, using `buffers` as each says: the graph places a barrier before
    /// a use that must wait for an earlier one (a read after a write, a write after a read or a
    /// write), and a later draw pass that reads a buffer it writes (its `storage`) waits for it
    /// and keeps it alive.
    Compute {
        /// The dispatches.
        dispatches: Vec<D>,
        /// The buffers they use and how: [`Access::ComputeRead`], [`Access::ComputeWrite`],
        /// [`Access::IndirectRead`], [`Access::TransferRead`] or [`Access::TransferWrite`].
        buffers: Vec<(BufferId, Access)>,
    },
    /// The host reads `buffers` once the submission completed (a side effect: it keeps the
    /// passes that wrote them alive). Records no command, only the barrier that makes the
    /// writes visible to the host.
    HostRead {
        /// The buffers read.
        buffers: Vec<BufferId>,
    },
    /// Copy an image into a host-readable buffer (a side effect: it keeps what it reads alive).
    Readback {
        /// Source image.
        image: ImageId,
        /// Destination buffer.
        buffer: BufferId,
    },
    /// Hand an [`Origin::External`] image back to its owner in [`Layout::External`] (a side
    /// effect: it keeps the passes that wrote the image alive).
    Export {
        /// The external image.
        image: ImageId,
    },
}

/// A declared pass. `D` (draw payloads), `P` (shader programs) and `C` (categories) are types of
/// the graph's user: the graph stores and compares them but never looks inside.
#[derive(Clone, Debug, PartialEq)]
pub struct Pass<D, P, C> {
    /// Unique name (debug label).
    pub name: String,
    /// What kind of pass this is in the user's words (the compositor's prime, layer, alpha
    /// clear, …), for counting with [`crate::graph::Plan::count`]. A type of the user's, like
    /// `D` and `P`, so the graph knows no compositor concept; a parameter of its own rather than
    /// derived from the draws, because passes without draws (a clear, a layer whose cube map is
    /// all zeros, a readback) have a category too.
    pub category: C,
    /// Kept even if nothing reads its outputs.
    pub side_effect: bool,
    /// What it does.
    pub kind: PassKind<D, P>,
}

impl<D, P, C> Pass<D, P, C> {
    /// The pipeline this pass needs (draw passes only).
    pub fn pipeline_key(&self, images: &[ImageInfo]) -> Option<PipelineKey<P>>
    where
        P: Copy,
    {
        match &self.kind {
            PassKind::Draw {
                program,
                colour,
                depth,
                cull,
                ..
            } => Some(PipelineKey {
                program: *program,
                colour_format: images.get(colour.image.0 as usize)?.format,
                depth_format: match depth {
                    Some(d) => Some(images.get(d.image.0 as usize)?.format),
                    None => None,
                },
                blend: colour.blend,
                write_mask: colour.write_mask,
                depth_test: depth.and_then(|d| d.test),
                depth_write: depth.is_some_and(|d| d.write),
                cull: *cull,
            }),
            PassKind::Compute { .. }
            | PassKind::HostRead { .. }
            | PassKind::Readback { .. }
            | PassKind::Export { .. } => None,
        }
    }

    /// Number of draws, or dispatches of a compute pass (0 for a readback or an export).
    pub fn draw_count(&self) -> usize {
        match &self.kind {
            PassKind::Draw { draws, .. } => draws.len(),
            PassKind::Compute { dispatches, .. } => dispatches.len(),
            PassKind::HostRead { .. } | PassKind::Readback { .. } | PassKind::Export { .. } => 0,
        }
    }
}

/// A graph being declared (its type parameters are [`Pass`]'s). Passes run in declaration order.
#[derive(Clone, Debug)]
pub struct Graph<D, P, C> {
    pub(crate) images: Vec<ImageInfo>,
    pub(crate) buffers: Vec<BufferInfo>,
    pub(crate) passes: Vec<Pass<D, P, C>>,
}

impl<D, P, C> Default for Graph<D, P, C> {
    fn default() -> Self {
        Graph {
            images: Vec::new(),
            buffers: Vec::new(),
            passes: Vec::new(),
        }
    }
}

impl<D, P, C> Graph<D, P, C> {
    /// An empty graph.
    pub fn new() -> Self {
        Self::default()
    }

    /// Declares an image the frame creates (transient or an output).
    pub fn image(&mut self, name: &str, format: Format, width: u32, height: u32) -> ImageId {
        self.push_image(name, format, width, height, Origin::Frame)
    }

    /// Declares an image that exists before the frame, already in [`Layout::ShaderRead`].
    pub fn import_image(&mut self, name: &str, format: Format, width: u32, height: u32) -> ImageId {
        self.push_image(name, format, width, height, Origin::Imported)
    }

    /// Declares an image the graph's user owns (a host's `VkImage`): in [`Layout::External`]
    /// before the frame; a [`PassKind::Export`] hands it back.
    pub fn external_image(
        &mut self,
        name: &str,
        format: Format,
        width: u32,
        height: u32,
    ) -> ImageId {
        self.push_image(name, format, width, height, Origin::External)
    }

    fn push_image(
        &mut self,
        name: &str,
        format: Format,
        width: u32,
        height: u32,
        origin: Origin,
    ) -> ImageId {
        self.images.push(ImageInfo {
            name: name.into(),
            format,
            extent: (width, height),
            origin,
        });
        ImageId(self.images.len() as u32 - 1)
    }

    /// Declares a buffer the frame makes (vertex data, storage or readback).
    pub fn buffer(&mut self, name: &str, size: u64) -> BufferId {
        self.push_buffer(name, size, BufferOrigin::Frame)
    }

    /// Declares a buffer kept across submissions: its first use waits for earlier work.
    pub fn kept_buffer(&mut self, name: &str, size: u64) -> BufferId {
        self.push_buffer(name, size, BufferOrigin::Kept)
    }

    fn push_buffer(&mut self, name: &str, size: u64, origin: BufferOrigin) -> BufferId {
        self.buffers.push(BufferInfo {
            name: name.into(),
            size,
            origin,
        });
        BufferId(self.buffers.len() as u32 - 1)
    }

    /// The buffer named `name`, if one is declared.
    pub fn find_buffer(&self, name: &str) -> Option<BufferId> {
        self.buffers
            .iter()
            .position(|b| b.name == name)
            .map(|i| BufferId(i as u32))
    }

    /// Adds a pass after the others.
    pub fn add_pass(&mut self, pass: Pass<D, P, C>) {
        self.passes.push(pass);
    }

    /// The declared passes.
    pub fn passes(&self) -> &[Pass<D, P, C>] {
        &self.passes
    }

    /// The declared images.
    pub fn images(&self) -> &[ImageInfo] {
        &self.images
    }
}
