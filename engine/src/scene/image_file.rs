//! Reading image assets (PNG, EXR, anything the `image` crate decodes) into linear RGB f32,
//! rejecting NaN, infinite and negative texels.

use std::path::Path;

use glam::Vec3;
use image::{DynamicImage, ImageDecoder};

/// The most texels an image asset may have: 2²⁴ (4096 × 4096, or 8192 × 2048 for a lat-long
/// sky). Reading one holds up to 28 bytes a texel at once (the decoded RGBA f32 image and its
/// RGB f32 copy, then that copy and the texels), about 450 MiB at the limit; the size is
/// checked from the file's header, before anything is decoded (the EXR decoder allocates
/// whatever the header claims).
pub(crate) const MAX_IMAGE_TEXELS: u64 = 1 << 24;

/// Bilinear filtering at continuous texel coordinates (`x`, `y`; texel centres at integers + ½),
/// with `texel` deciding how coordinates outside the image wrap or clamp.
pub(crate) fn bilinear(x: f32, y: f32, texel: impl Fn(i64, i64) -> Vec3) -> Vec3 {
    let (x, y) = (x - 0.5, y - 0.5);
    let (x0, y0) = (x.floor(), y.floor());
    let (fx, fy) = (x - x0, y - y0);
    let (x0, y0) = (x0 as i64, y0 as i64);
    let top = texel(x0, y0).lerp(texel(x0 + 1, y0), fx);
    let bottom = texel(x0, y0 + 1).lerp(texel(x0 + 1, y0 + 1), fx);
    top.lerp(bottom, fy)
}

/// A decoded image in linear RGB, row-major, row 0 at the top.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct LinearImage {
    /// Width in pixels, ≥ 1.
    pub width: u32,
    /// Height in pixels, ≥ 1.
    pub height: u32,
    /// `width × height` linear rgb texels, each finite and ≥ 0.
    pub texels: Vec<Vec3>,
}

/// Why an image could not be used, one line.
#[derive(Clone, Debug, PartialEq)]
pub(crate) enum ImageProblem {
    /// The file cannot be opened or decoded.
    Unreadable(String),
    /// The image has no pixels.
    Empty,
    /// The header claims more than [`MAX_IMAGE_TEXELS`] texels.
    TooLarge {
        /// Width in pixels, as the header says.
        width: u32,
        /// Height in pixels, as the header says.
        height: u32,
    },
    /// Texels that are NaN, infinite or negative.
    BadTexels {
        /// How many texels are bad.
        count: usize,
        /// Column of the first bad texel (0 on the left).
        x: u32,
        /// Row of the first bad texel (0 at the top).
        y: u32,
        /// The first bad texel's linear rgb value.
        value: Vec3,
    },
}

impl std::fmt::Display for ImageProblem {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            ImageProblem::Unreadable(why) => write!(f, "cannot read the image ({why})"),
            ImageProblem::Empty => write!(f, "the image has no pixels"),
            ImageProblem::TooLarge { width, height } => write!(
                f,
                "cannot read the image (it is {width}×{height} texels, over the limit of \
                 {MAX_IMAGE_TEXELS}: 4096×4096; downscale it)"
            ),
            ImageProblem::BadTexels { count, x, y, value } => write!(
                f,
                "{count} texel(s) are NaN, infinite or negative, the first at pixel ({x}, {y}) = \
                 ({}, {}, {})",
                value.x, value.y, value.z
            ),
        }
    }
}

/// The sRGB transfer function inverted: an encoded value in [0, 1] to linear.
pub(crate) fn srgb_to_linear(encoded: f32) -> f32 {
    if encoded <= 0.04045 {
        encoded / 12.92
    } else {
        ((encoded + 0.055) / 1.055).powf(2.4)
    }
}

/// Loads an image as linear RGB. Floating-point images (EXR, HDR) are taken as linear; 8- and
/// 16-bit images (PNG) as sRGB-encoded and linearized. Alpha is ignored.
pub(crate) fn load_linear_rgb(path: &Path) -> Result<LinearImage, ImageProblem> {
    let unreadable = |e: image::ImageError| ImageProblem::Unreadable(e.to_string());
    let decoder = image::ImageReader::open(path)
        .map_err(|e| ImageProblem::Unreadable(e.to_string()))?
        .with_guessed_format()
        .map_err(|e| ImageProblem::Unreadable(e.to_string()))?
        .into_decoder()
        .map_err(unreadable)?;
    let (width, height) = decoder.dimensions();
    if u64::from(width) * u64::from(height) > MAX_IMAGE_TEXELS {
        return Err(ImageProblem::TooLarge { width, height });
    }
    let image = DynamicImage::from_decoder(decoder).map_err(unreadable)?;
    let is_float = matches!(
        image,
        DynamicImage::ImageRgb32F(_) | DynamicImage::ImageRgba32F(_)
    );
    let rgb = image.into_rgb32f();
    let (width, height) = rgb.dimensions();
    if width == 0 || height == 0 {
        return Err(ImageProblem::Empty);
    }
    let texels: Vec<Vec3> = rgb
        .pixels()
        .map(|p| {
            let v = Vec3::from_array(p.0);
            if is_float { v } else { v.map(srgb_to_linear) }
        })
        .collect();
    check_texels(width, &texels)?;
    Ok(LinearImage {
        width,
        height,
        texels,
    })
}

/// Rejects NaN, infinite or negative texels, naming how many and the first.
pub(crate) fn check_texels(width: u32, texels: &[Vec3]) -> Result<(), ImageProblem> {
    let is_bad = |v: &Vec3| !v.is_finite() || v.min_element() < 0.0;
    let count = texels.iter().filter(|v| is_bad(v)).count();
    match texels.iter().position(is_bad) {
        Some(first) => Err(ImageProblem::BadTexels {
            count,
            x: (first % width.max(1) as usize) as u32,
            y: (first / width.max(1) as usize) as u32,
            value: texels[first],
        }),
        None => Ok(()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn srgb_round_trip_points() {
        assert_eq!(srgb_to_linear(0.0), 0.0);
        assert!((srgb_to_linear(1.0) - 1.0).abs() < 1e-6);
        // sRGB 0.5 ≈ 0.2140 linear (IEC 61966-2-1).
        assert!((srgb_to_linear(0.5) - 0.214_041).abs() < 1e-5);
    }

    #[test]
    fn bad_texels_are_named() {
        let texels = [
            Vec3::ONE,
            Vec3::new(0.0, f32::NAN, 0.0),
            Vec3::ONE,
            -Vec3::ONE,
        ];
        match check_texels(2, &texels) {
            Err(ImageProblem::BadTexels { count, x, y, .. }) => {
                assert_eq!((count, x, y), (2, 1, 0));
            }
            other => panic!("{other:?}"),
        }
    }
}
