//! A compositor frame on the CPU: the read-back texels converted to f32 RGBA
//! ([`RenderedImage`]), box-filtered from the supersampled framebuffer to pixels, written as PNG
//! and EXR, and put beside a reference for a side-by-side picture.

use std::path::Path;

use glam::Vec3;
use rayon::prelude::*;

use super::TargetFormat;
use crate::{
    metrics::{self, Channels, Encoding, Mask, MetricsError},
    trace::{TraceError, image},
};

/// A frame read back from the GPU, converted to f32 RGBA (rows top to bottom).
#[derive(Clone, Debug, PartialEq)]
pub struct RenderedImage {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Linear RGBA per pixel, exactly as stored in the target (RGBA8 as n/255).
    pub pixels: Vec<[f32; 4]>,
}

impl RenderedImage {
    /// The image box-filtered by k×k (k ≥ 1 dividing both sides): supersampled frames to pixels.
    /// Takes the image by value so that k = 1, every frame without supersampling, costs no copy.
    pub fn box_downsample(self, k: u32) -> RenderedImage {
        let k = k.max(1);
        if k == 1 || !self.width.is_multiple_of(k) || !self.height.is_multiple_of(k) {
            return self;
        }
        let (width, height) = (self.width / k, self.height / k);
        let scale = 1.0 / (k * k) as f32;
        // Every output pixel is independent: in parallel, in order (the same sums in the same
        // order as one thread, so the result does not depend on the thread count).
        let pixels = (0..width * height)
            .into_par_iter()
            .map(|i| {
                let (x, y) = (i % width, i / width);
                let mut sum = [0.0f32; 4];
                for dy in 0..k {
                    for dx in 0..k {
                        let p = self.pixels[((y * k + dy) * self.width + x * k + dx) as usize];
                        for c in 0..4 {
                            sum[c] += p[c];
                        }
                    }
                }
                sum.map(|v| v * scale)
            })
            .collect();
        RenderedImage {
            width,
            height,
            pixels,
        }
    }
    /// The colour of every pixel, α dropped.
    pub fn rgb(&self) -> Vec<Vec3> {
        self.pixels
            .iter()
            .map(|p| Vec3::new(p[0], p[1], p[2]))
            .collect()
    }

    /// Writes the image as an 8-bit sRGB PNG at `path` (extension made `.png`) and a linear f32
    /// EXR beside it (`.exr`), creating the folder if needed.
    pub fn write_png_and_exr(&self, path: &Path) -> Result<(), TraceError> {
        self.write_files(&path.with_extension("png"), &path.with_extension("exr"))
    }

    /// Writes the image as an 8-bit sRGB PNG at `png` and a linear f32 EXR at `exr`, creating
    /// their folders if needed: both are staged before either is put in place, so a failure (a
    /// full disk) leaves the earlier pair as it was, never a new PNG beside an old EXR.
    pub fn write_files(&self, png: &Path, exr: &Path) -> Result<(), TraceError> {
        let rgb = self.rgb();
        let png = image::stage_png(png, self.width, self.height, &rgb)?;
        let exr = image::stage_exr(exr, self.width, self.height, &rgb)?;
        png.commit()?;
        exr.commit()
    }

    /// The largest difference of one channel value (RGBA, linear) between this image and
    /// `other` over every pixel: how far two variants or formats of one frame disagree.
    pub fn max_abs_difference(&self, other: &RenderedImage) -> Result<f64, MetricsError> {
        let all = Mask::all(self.pixels.len());
        metrics::compare(
            &self.pixels,
            &other.pixels,
            &all,
            Encoding::Linear,
            Channels::Rgba,
        )
        .map(|error| error.max_abs)
    }

    /// This image on the left and `right` (RGB, the same size, rows top to bottom) on the right.
    pub fn side_by_side(&self, right: &[Vec3]) -> Result<RenderedImage, TraceError> {
        let (w, h) = (self.width as usize, self.height as usize);
        if right.len() != w * h || self.pixels.len() != w * h {
            return Err(TraceError::InvalidImage(format!(
                "side by side: {} and {} pixels for two {w}×{h} images",
                self.pixels.len(),
                right.len()
            )));
        }
        let mut pixels = Vec::with_capacity(2 * w * h);
        for y in 0..h {
            pixels.extend_from_slice(&self.pixels[y * w..(y + 1) * w]);
            pixels.extend(
                right[y * w..(y + 1) * w]
                    .iter()
                    .map(|p| [p.x, p.y, p.z, 1.0]),
            );
        }
        Ok(RenderedImage {
            width: 2 * self.width,
            height: self.height,
            pixels,
        })
    }
}

/// The largest finite RGBA16F value: an overflowed texel is clamped to it.
pub const HALF_MAX: f32 = 65504.0;

/// Converts read-back texels to f32 RGBA, and counts the channel values that overflowed: an
/// RGBA16F framebuffer holds ±Inf where blending passed ±65504 (or a driver rounded a value past
/// it to nearest; Vulkan leaves the rounding mode open), and those are clamped to ±[`HALF_MAX`]
/// here, so no frame carries an Inf.
pub(super) fn decode(bytes: &[u8], format: TargetFormat, pixels: usize) -> (Vec<[f32; 4]>, usize) {
    let mut texels = decode_texels(bytes, format, pixels);
    let saturated = if format == TargetFormat::Rgba16f {
        texels
            .par_iter_mut()
            .map(|pixel| {
                let mut count = 0;
                for value in pixel.iter_mut().filter(|v| v.is_infinite()) {
                    *value = HALF_MAX.copysign(*value);
                    count += 1;
                }
                count
            })
            .sum()
    } else {
        0
    };
    (texels, saturated)
}

/// Converts read-back texels to f32 RGBA as they are.
fn decode_texels(bytes: &[u8], format: TargetFormat, pixels: usize) -> Vec<[f32; 4]> {
    match format {
        TargetFormat::Rgba8 => bytes
            .par_chunks_exact(4)
            .take(pixels)
            .map(|c| [0, 1, 2, 3].map(|i| f32::from(c[i]) / 255.0))
            .collect(),
        TargetFormat::Rgba16f => decode_half(&bytes[..(8 * pixels).min(bytes.len())]),
        TargetFormat::Rgba32f => bytes
            .par_chunks_exact(16)
            .take(pixels)
            .map(|c| {
                [0, 1, 2, 3].map(|i| {
                    f32::from_le_bytes([c[4 * i], c[4 * i + 1], c[4 * i + 2], c[4 * i + 3]])
                })
            })
            .collect(),
    }
}

/// RGBA16F texels to f32 RGBA, in parallel chunks through half's slice conversion (which uses the
/// CPU's F16C instructions where it has them: a scalar conversion of every value cost ~20 ms for a
/// 1920×1440 frame).
fn decode_half(bytes: &[u8]) -> Vec<[f32; 4]> {
    use half::slice::{HalfBitsSliceExt, HalfFloatSliceExt};
    /// Pixels per parallel task.
    const CHUNK: usize = 16384;
    let scalar = |c: &[u8]| {
        [0, 1, 2, 3].map(|i| half::f16::from_le_bytes([c[2 * i], c[2 * i + 1]]).to_f32())
    };
    // The mapped buffer is aligned far beyond 2 bytes and little-endian on every host Vulkan
    // runs on here; anything else takes the scalar path.
    let Ok(bits) = bytemuck::try_cast_slice::<u8, u16>(bytes) else {
        return bytes.par_chunks_exact(8).map(scalar).collect();
    };
    if cfg!(target_endian = "big") {
        return bytes.par_chunks_exact(8).map(scalar).collect();
    }
    let mut pixels = vec![[0.0f32; 4]; bits.len() / 4];
    pixels
        .par_chunks_mut(CHUNK)
        .zip(bits.par_chunks(4 * CHUNK))
        .for_each(|(out, bits)| {
            let out: &mut [f32] = bytemuck::cast_slice_mut(out);
            bits[..out.len()]
                .reinterpret_cast::<half::f16>()
                .convert_to_f32_slice(out);
        });
    pixels
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    /// Overflowed RGBA16F texels (±Inf) come back clamped to ±65504 and counted; finite values
    /// and the other formats are untouched.
    #[test]
    fn overflowed_half_texels_are_clamped_and_counted() {
        let texel = |values: [f32; 4]| values.map(|v| half::f16::from_f32(v).to_le_bytes());
        let bytes: Vec<u8> = [
            texel([1.0, f32::INFINITY, -f32::INFINITY, 0.5]),
            texel([65504.0, -2.0, 0.0, 1.0]),
        ]
        .iter()
        .flatten()
        .flatten()
        .copied()
        .collect();
        let (pixels, saturated) = decode(&bytes, TargetFormat::Rgba16f, 2);
        assert_eq!(saturated, 2);
        assert_eq!(pixels[0], [1.0, HALF_MAX, -HALF_MAX, 0.5]);
        assert_eq!(pixels[1], [65504.0, -2.0, 0.0, 1.0]);
        let floats: Vec<u8> = [f32::INFINITY, 1.0, 2.0, 3.0]
            .iter()
            .flat_map(|v| v.to_le_bytes())
            .collect();
        let (pixels, saturated) = decode(&floats, TargetFormat::Rgba32f, 1);
        assert_eq!((pixels[0][0], saturated), (f32::INFINITY, 0));
    }

    /// The chunked F16C-capable conversion equals the scalar one bit for bit on random texels
    /// (every finite half, infinities included; NaNs excluded, whose payloads may be quieted),
    /// over a length that is not a multiple of the chunk.
    #[test]
    fn half_decoding_matches_the_scalar_conversion() {
        let mut rng = rand_pcg::Pcg64::seed_from_u64(16);
        let pixels = 40_000 + 3;
        let bytes: Vec<u8> = (0..4 * pixels)
            .flat_map(|_| {
                loop {
                    let h = half::f16::from_bits(rng.r#gen::<u16>());
                    if !h.is_nan() {
                        break h.to_le_bytes();
                    }
                }
            })
            .collect();
        let fast = decode_texels(&bytes, TargetFormat::Rgba16f, pixels);
        assert_eq!(fast.len(), pixels);
        for (i, (pixel, c)) in fast.iter().zip(bytes.chunks_exact(8)).enumerate() {
            for k in 0..4 {
                let scalar = half::f16::from_le_bytes([c[2 * k], c[2 * k + 1]]).to_f32();
                assert_eq!(
                    pixel[k].to_bits(),
                    scalar.to_bits(),
                    "pixel {i} channel {k}"
                );
            }
        }
    }
}
