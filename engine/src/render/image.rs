//! A compositor frame on the CPU: the read-back texels converted to f32 RGBA
//! ([`RenderedImage`]), box-filtered from the supersampled framebuffer to pixels.

use super::TargetFormat;

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
    pub fn box_downsample(&self, k: u32) -> RenderedImage {
        let k = k.max(1);
        if k == 1 || !self.width.is_multiple_of(k) || !self.height.is_multiple_of(k) {
            return self.clone();
        }
        let (width, height) = (self.width / k, self.height / k);
        let scale = 1.0 / (k * k) as f32;
        let pixels = (0..width * height)
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
}

/// Converts read-back texels to f32 RGBA.
pub(super) fn decode(bytes: &[u8], format: TargetFormat, pixels: usize) -> Vec<[f32; 4]> {
    match format {
        TargetFormat::Rgba8 => bytes
            .chunks_exact(4)
            .take(pixels)
            .map(|c| [0, 1, 2, 3].map(|i| f32::from(c[i]) / 255.0))
            .collect(),
        TargetFormat::Rgba16f => bytes
            .chunks_exact(8)
            .take(pixels)
            .map(|c| {
                [0, 1, 2, 3].map(|i| half::f16::from_le_bytes([c[2 * i], c[2 * i + 1]]).to_f32())
            })
            .collect(),
        TargetFormat::Rgba32f => bytes
            .chunks_exact(16)
            .take(pixels)
            .map(|c| {
                [0, 1, 2, 3].map(|i| {
                    f32::from_le_bytes([c[4 * i], c[4 * i + 1], c[4 * i + 2], c[4 * i + 3]])
                })
            })
            .collect(),
    }
}
