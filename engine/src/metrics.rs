//! Image error metrics, one set of rules for every figure lensmap prints or asserts: masked
//! PSNR, RMSE and largest difference between an image and a reference, either in **linear HDR**
//! (values as they are, nothing clamped: errors in highlights above 1 count in full) or in
//! **display sRGB** (each colour channel clamped to [0, 1] and sRGB-encoded, as a PNG shows it;
//! α only clamped). The mask is explicit, and a comparison over an empty mask is an error, never
//! a zero.
//!
//! PSNR is `10·log10(1 / MSE)` with a peak of 1 in both encodings (in linear HDR, values above 1
//! can make it negative), capped at 200 dB (MSE floored at 1e-20) so that identical images give a
//! finite figure every output (JSON included) can hold. A NaN or infinite value compared in
//! linear HDR is an error, not a figure; display sRGB shows NaN as 0, as a PNG does.

use glam::Vec3;

use crate::trace::image::srgb_encode;
use crate::trace::{LensPixels, LensSelection};

/// How values are compared.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
pub enum Encoding {
    /// Linear radiance as stored, nothing clamped.
    Linear,
    /// Colour channels clamped to [0, 1] and sRGB-encoded, α clamped to [0, 1]; NaN as 0.
    DisplaySrgb,
}

impl Encoding {
    /// How outputs name it.
    pub fn name(self) -> &'static str {
        match self {
            Encoding::Linear => "linear HDR",
            Encoding::DisplaySrgb => "display sRGB, clamped to [0, 1]",
        }
    }

    fn encode(self, channel: usize, value: f32) -> f32 {
        match (self, channel) {
            (Encoding::Linear, _) => value,
            (Encoding::DisplaySrgb, 0..=2) => srgb_encode(value),
            (Encoding::DisplaySrgb, _) if value.is_nan() => 0.0,
            (Encoding::DisplaySrgb, _) => value.clamp(0.0, 1.0),
        }
    }
}

/// Which channels are compared.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
pub enum Channels {
    /// Red, green and blue.
    Rgb,
    /// Red, green, blue and α (both images need α).
    Rgba,
}

impl Channels {
    fn count(self) -> usize {
        match self {
            Channels::Rgb => 3,
            Channels::Rgba => 4,
        }
    }
}

/// A pixel the metrics can read: RGB or RGBA in f32.
pub trait Pixel {
    /// Channel `c` (0 = R … 3 = A); α is 1 for pixels without one.
    fn channel(&self, c: usize) -> f32;
}

impl Pixel for [f32; 4] {
    fn channel(&self, c: usize) -> f32 {
        self[c]
    }
}

impl Pixel for [f32; 3] {
    fn channel(&self, c: usize) -> f32 {
        self.get(c).copied().unwrap_or(1.0)
    }
}

impl Pixel for Vec3 {
    fn channel(&self, c: usize) -> f32 {
        if c < 3 { self[c] } else { 1.0 }
    }
}

/// Which pixels a comparison covers.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Mask {
    pixels: Vec<bool>,
}

impl Mask {
    /// Every one of `len` pixels.
    pub fn all(len: usize) -> Mask {
        Mask {
            pixels: vec![true; len],
        }
    }

    /// The lens pixels of `selection` (every lens object, or one), by the rule every lens-error
    /// figure uses ([`crate::trace::lens_pixels`]).
    pub fn lens(pixels: &LensPixels, selection: LensSelection) -> Mask {
        Mask {
            pixels: pixels.flags(selection),
        }
    }

    /// The environment pixels: no subpixel sees a lens object ([`crate::trace::lens_pixels`]).
    pub fn environment(pixels: &LensPixels) -> Mask {
        Mask {
            pixels: pixels.environment_flags(),
        }
    }

    /// A mask from one flag per pixel.
    pub fn from_flags(pixels: Vec<bool>) -> Mask {
        Mask { pixels }
    }

    /// Pixels in either mask (the shorter mask's missing pixels count as out).
    pub fn union(&self, other: &Mask) -> Mask {
        let len = self.pixels.len().max(other.pixels.len());
        let at = |m: &Mask, i: usize| m.pixels.get(i).copied().unwrap_or(false);
        Mask {
            pixels: (0..len).map(|i| at(self, i) || at(other, i)).collect(),
        }
    }

    /// Whether pixel `i` is selected (false past the mask's end).
    pub fn contains(&self, i: usize) -> bool {
        self.pixels.get(i).copied().unwrap_or(false)
    }

    /// Number of pixels the mask selects.
    pub fn selected(&self) -> usize {
        self.pixels.iter().filter(|&&p| p).count()
    }

    /// Number of pixels the mask describes, selected or not (the image size it fits).
    pub fn pixel_count(&self) -> usize {
        self.pixels.len()
    }
}

/// Why a comparison has no value.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum MetricsError {
    /// The mask selects no pixel: the error over an empty set is undefined, not zero.
    #[error("the comparison mask selects no pixel, so there is no error to report")]
    EmptyMask,
    /// The image, the reference and the mask differ in size.
    #[error("image has {image} pixels, reference {reference}, mask {mask}: they must agree")]
    SizeMismatch {
        /// Pixels of the image.
        image: usize,
        /// Pixels of the reference.
        reference: usize,
        /// Pixels the mask describes.
        mask: usize,
    },
    /// A value compared in linear HDR is NaN or infinite, so no error figure means anything.
    #[error("pixel {pixel} channel {channel} of the {which} is {value}; it must be finite")]
    NonFinite {
        /// "image" or "reference".
        which: &'static str,
        /// Pixel index (row-major).
        pixel: usize,
        /// Channel (0 = R … 3 = A).
        channel: usize,
        /// The value.
        value: f32,
    },
}

/// The MSE below which PSNR stops growing: 200 dB.
const MSE_FLOOR: f64 = 1e-20;

/// The difference between an image and its reference over a mask.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct ImageError {
    /// The values compared.
    pub encoding: Encoding,
    /// The channels compared.
    pub channels: Channels,
    /// Pixels compared (> 0).
    pub pixels: usize,
    /// Mean squared difference over every compared channel value.
    pub mse: f64,
    /// Its square root.
    pub rmse: f64,
    /// `10·log10(1 / max(mse, 1e-20))`, dB: at most 200.
    pub psnr_db: f64,
    /// Largest absolute difference of one channel value.
    pub max_abs: f64,
}

/// Compares `image` with `reference` over the pixels of `mask`, in `encoding`, on `channels`.
/// Differences are taken in f32 after encoding and accumulated in f64, pixel by pixel and
/// channel by channel in order, so the figure does not depend on threads.
pub fn compare<A: Pixel, B: Pixel>(
    image: &[A],
    reference: &[B],
    mask: &Mask,
    encoding: Encoding,
    channels: Channels,
) -> Result<ImageError, MetricsError> {
    if image.len() != reference.len() || image.len() != mask.pixel_count() {
        return Err(MetricsError::SizeMismatch {
            image: image.len(),
            reference: reference.len(),
            mask: mask.pixel_count(),
        });
    }
    let mut sum = 0.0f64;
    let mut max_abs = 0.0f64;
    let mut pixels = 0usize;
    for (index, ((p, r), _)) in image
        .iter()
        .zip(reference)
        .zip(&mask.pixels)
        .enumerate()
        .filter(|(_, (_, inside))| **inside)
    {
        for channel in 0..channels.count() {
            let (a, b) = (
                encoding.encode(channel, p.channel(channel)),
                encoding.encode(channel, r.channel(channel)),
            );
            for (which, value) in [("image", a), ("reference", b)] {
                if !value.is_finite() {
                    return Err(MetricsError::NonFinite {
                        which,
                        pixel: index,
                        channel,
                        value,
                    });
                }
            }
            let d = f64::from(a - b);
            sum += d * d;
            max_abs = max_abs.max(d.abs());
        }
        pixels += 1;
    }
    if pixels == 0 {
        return Err(MetricsError::EmptyMask);
    }
    let mse = sum / (channels.count() * pixels) as f64;
    Ok(ImageError {
        encoding,
        channels,
        pixels,
        mse,
        rmse: mse.sqrt(),
        psnr_db: 10.0 * (1.0 / mse.max(MSE_FLOOR)).log10(),
        max_abs,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::trace::PixelCover;

    #[test]
    fn linear_error_against_a_hand_computation() {
        let image = [[0.5f32, 0.25, 2.0, 1.0], [0.0, 0.0, 0.0, 0.5]];
        let reference = [Vec3::new(0.25, 0.25, 1.0), Vec3::new(9.0, 9.0, 9.0)];
        let mask = Mask::from_flags(vec![true, false]);
        let e = compare(&image, &reference, &mask, Encoding::Linear, Channels::Rgb).unwrap();
        // Differences 0.25, 0, 1 over three values: MSE = (1/16 + 1) / 3.
        let mse = (1.0 / 16.0 + 1.0) / 3.0;
        assert_eq!(e.pixels, 1);
        assert!((e.mse - mse).abs() < 1e-15, "{e:?}");
        assert!((e.psnr_db - 10.0 * (1.0 / mse).log10()).abs() < 1e-12);
        assert_eq!(e.max_abs, 1.0, "linear HDR counts the highlight in full");
    }

    #[test]
    fn display_srgb_clamps_highlights_and_encodes() {
        let image = [Vec3::new(2.0, 0.5, 0.0)];
        let reference = [Vec3::new(1.0, 0.5, 0.0)];
        let all = Mask::all(1);
        let display = compare(
            &image,
            &reference,
            &all,
            Encoding::DisplaySrgb,
            Channels::Rgb,
        )
        .unwrap();
        assert_eq!(display.mse, 0.0, "2 and 1 both show as white");
        assert_eq!(display.psnr_db, 200.0, "identical: the cap");
        let linear = compare(&image, &reference, &all, Encoding::Linear, Channels::Rgb).unwrap();
        assert!((linear.mse - 1.0 / 3.0).abs() < 1e-15);
        // sRGB(0.5) = 0.7353569…: against black that is the whole difference.
        let grey = compare(
            &[Vec3::splat(0.5)],
            &[Vec3::ZERO],
            &all,
            Encoding::DisplaySrgb,
            Channels::Rgb,
        )
        .unwrap();
        assert!((grey.max_abs - 0.735_356_9).abs() < 1e-6, "{grey:?}");
    }

    #[test]
    fn rgba_compares_alpha_and_an_empty_mask_is_an_error() {
        let a = [[0.0f32, 0.0, 0.0, 0.25]];
        let b = [[0.0f32, 0.0, 0.0, 1.0]];
        let e = compare(&a, &b, &Mask::all(1), Encoding::Linear, Channels::Rgba).unwrap();
        assert_eq!(e.max_abs, 0.75);
        assert_eq!(
            compare(
                &a,
                &b,
                &Mask::from_flags(vec![false]),
                Encoding::Linear,
                Channels::Rgb
            ),
            Err(MetricsError::EmptyMask)
        );
        assert!(matches!(
            compare(&a, &b, &Mask::all(2), Encoding::Linear, Channels::Rgb),
            Err(MetricsError::SizeMismatch { .. })
        ));
    }

    #[test]
    fn non_finite_values_are_errors_in_linear_and_zero_on_display() {
        let nan = [[f32::NAN, 0.0, 0.0, 1.0]];
        let black = [[0.0f32, 0.0, 0.0, 1.0]];
        let all = Mask::all(1);
        assert!(matches!(
            compare(&nan, &black, &all, Encoding::Linear, Channels::Rgb),
            Err(MetricsError::NonFinite {
                which: "image",
                pixel: 0,
                channel: 0,
                ..
            })
        ));
        let infinite = [Vec3::new(0.0, f32::INFINITY, 0.0)];
        assert!(matches!(
            compare(&black, &infinite, &all, Encoding::Linear, Channels::Rgb),
            Err(MetricsError::NonFinite {
                which: "reference",
                channel: 1,
                ..
            })
        ));
        let shown = compare(&nan, &black, &all, Encoding::DisplaySrgb, Channels::Rgba).unwrap();
        assert_eq!(shown.mse, 0.0, "a PNG shows NaN as 0");
    }

    #[test]
    fn lens_and_environment_masks_and_union() {
        let pixels = LensPixels {
            width: 3,
            height: 1,
            covers: vec![
                PixelCover::Environment,
                PixelCover::Mixed,
                PixelCover::Lens(0),
            ],
        };
        let lens = Mask::lens(&pixels, LensSelection::All);
        let environment = Mask::environment(&pixels);
        assert_eq!((lens.selected(), environment.selected()), (1, 1));
        assert!(lens.contains(2) && environment.contains(0));
        assert_eq!(Mask::lens(&pixels, LensSelection::Object(1)).selected(), 0);
        let other = Mask::from_flags(vec![true, false, false]);
        assert_eq!(lens.union(&other).selected(), 2);
        assert_eq!(lens.pixel_count(), 3);
    }
}
