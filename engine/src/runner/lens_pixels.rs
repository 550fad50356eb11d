//! The error of a hybrid frame against the reference ray tracer over the lens pixels, or over the
//! environment pixels, as the reference's rule defines them ([`crate::trace::lens_pixels`]).

use crate::{
    metrics::{self, Channels, Encoding, ImageError, Mask, MetricsError},
    render::RenderedImage,
    trace::{LensSelection, ReferenceImage},
};

/// The error of a hybrid frame against the reference ray tracer over the lens pixels (each pixel
/// whose every subpixel the reference sees hit one lens object first), RGB, in `encoding`.
/// [`Encoding::DisplaySrgb`] is the figure the command line prints as "lens PSNR";
/// [`Encoding::Linear`] also counts errors in highlights above 1. An error when there is no lens
/// pixel.
pub fn lens_error(
    image: &RenderedImage,
    reference: &ReferenceImage,
    encoding: Encoding,
) -> Result<ImageError, MetricsError> {
    let mask = Mask::lens(&reference.lens_pixels, LensSelection::All);
    error_over(image, reference, &mask, encoding)
}

/// The error of a hybrid frame against the reference ray tracer over the environment pixels: those
/// in which no reference subpixel saw a lens object, so the opaque environment, light-mapped on
/// the GPU, and the background are all they show; RGB, in `encoding`. An error when every pixel
/// sees some lens.
pub fn non_lens_error(
    image: &RenderedImage,
    reference: &ReferenceImage,
    encoding: Encoding,
) -> Result<ImageError, MetricsError> {
    let mask = Mask::environment(&reference.lens_pixels);
    error_over(image, reference, &mask, encoding)
}

/// The RGB error of `image` against the reference's radiance over `mask`, in `encoding`.
fn error_over(
    image: &RenderedImage,
    reference: &ReferenceImage,
    mask: &Mask,
    encoding: Encoding,
) -> Result<ImageError, MetricsError> {
    metrics::compare(
        &image.pixels,
        &reference.radiance,
        mask,
        encoding,
        Channels::Rgb,
    )
}
