//! The pixels of a lens object and the error of a hybrid frame over them: which framebuffer
//! pixels the compositor covers with a lens object, and the error against the reference ray
//! tracer over the pixels its coverage calls lens, or non-lens.

use super::FrameRunner;
use crate::{
    cubemap::CubeMap,
    metrics::{self, Channels, Coverage, Encoding, ImageError, Mask, MetricsError},
    render::{FrameInput, RenderError, RenderedImage, TargetFormat, Variant},
    trace::ReferenceImage,
};

impl FrameRunner {
    /// Which pixels of `frame` show a lens object, from its geometry, not from a frame's
    /// colours: the frame rendered twice in the multipass variant with every layered EM replaced
    /// by a uniform map, once of (0, 0, 0, 0) texels and once of opaque black (0, 0, 0, 1). A lens
    /// pixel (its prime passed the depth test) ends with α = 0 in the first render (the prime and
    /// the alpha clears write 0, and no layer adds any) and α = 1 in the second (each group's
    /// first layer blends 1 over 0); the environment writes α = 1 in both and the background
    /// keeps the clear's 0 in both. In RGBA8 these alphas are exact on any driver. The pixels are
    /// the framebuffer's (its subpixels, before any box filter).
    pub fn lens_coverage(&mut self, frame: &FrameInput) -> Result<Mask, RenderError> {
        let mut alpha = |texel: [f32; 4]| -> Result<Vec<f32>, RenderError> {
            let mut uniform = frame.clone();
            for lens in &mut uniform.lenses {
                for maps in &mut lens.layers {
                    for map in maps.iter_mut() {
                        *map = std::sync::Arc::new(CubeMap::uniform(map.size, texel));
                    }
                }
            }
            let image = self.render(&uniform, Variant::Multipass, TargetFormat::Rgba8)?;
            Ok(image.pixels.iter().map(|p| p[3]).collect())
        };
        let transparent = alpha([0.0; 4])?;
        let opaque = alpha([0.0, 0.0, 0.0, 1.0])?;
        Ok(Mask::from_flags(
            transparent
                .iter()
                .zip(&opaque)
                .map(|(&t, &o)| t == 0.0 && o == 1.0)
                .collect(),
        ))
    }
}

/// The error of a hybrid frame against the reference ray tracer over the lens pixels: those the
/// reference sees as entirely lens (coverage 1, no background mixed in), RGB, in `encoding`.
/// [`Encoding::DisplaySrgb`] is the figure the command line prints as "lens PSNR";
/// [`Encoding::Linear`] also counts errors in highlights above 1. An error when no pixel is all
/// lens.
pub fn lens_error(
    image: &RenderedImage,
    reference: &ReferenceImage,
    encoding: Encoding,
) -> Result<ImageError, MetricsError> {
    error_where(image, reference, Coverage::Full, encoding)
}

/// The error of a hybrid frame against the reference ray tracer over the non-lens pixels: those
/// in which no reference sub-sample saw a lens object (coverage 0), so the opaque environment,
/// light-mapped on the GPU, and the background are all they show; RGB, in `encoding`. An error
/// when every pixel sees some lens.
pub fn non_lens_error(
    image: &RenderedImage,
    reference: &ReferenceImage,
    encoding: Encoding,
) -> Result<ImageError, MetricsError> {
    error_where(image, reference, Coverage::None, encoding)
}

/// The RGB error of `image` against the reference over the pixels whose reference lens coverage
/// is `coverage`, in `encoding`.
fn error_where(
    image: &RenderedImage,
    reference: &ReferenceImage,
    coverage: Coverage,
    encoding: Encoding,
) -> Result<ImageError, MetricsError> {
    metrics::compare(
        &image.pixels,
        &reference.radiance,
        &Mask::from_coverage(&reference.lens_mask, coverage),
        encoding,
        Channels::Rgb,
    )
}
