//! Targets and confidence (hybrid-rendering paper §4.3): from the reference ray tracer's
//! intersection records at a camera, per layer and term, the image b the inferred EM must
//! reproduce and the confidence that weights each pixel's equation.
//!
//! A record's outgoing ray is split between the layers exactly as the projected EMs split the
//! rays from the EM origin ([`lensmap::layers::projected`]): with tᵢ the distance along the ray to
//! shell i, layer i holds the first front-facing hit at a distance in (½(tᵢ₋₁ + tᵢ), ½(tᵢ + tᵢ₊₁)]
//! (the records keep every hit, so an inner layer's surface does not hide what an outer layer
//! holds: the paper's ray continuation); the outermost layer also holds the environment at
//! infinity. b is premultiplied RGBA at display resolution: α = the fraction of the pixel's
//! supersamples whose outgoing ray has a hit in the layer, rgb = the sum of those hits' radiance
//! over the supersample count — incident radiance, without F·G (see [`crate::matrix`]).

use glam::DVec3;
use lensmap::{
    layers::{LayerShell, projected::layer_range},
    trace::{IntersectionRecord, LensRecords, Term},
};

/// The paper's confidence threshold θ_c, degrees.
pub const PAPER_CONFIDENCE_DEGREES: f64 = 5.0;

/// lensmap's default θ_c, degrees, chosen by measurement (`lensmap bench infer`, teapot-room
/// 640×480, targets 3×3, judged 6×6: lens PSNR over projection +4.6 dB at the paper's 5°,
/// +6.4 dB at 30°, +6.9 dB with no down-weighting). The paper's targets were filtered to display
/// resolution and matched by a display-resolution rendering, so a pixel whose rays diverge had no
/// texel combination to match; here the framebuffer is supersampled like the targets and the
/// rendering matrix follows every subsample's own direction, so divergence within a pixel is
/// largely modelled, and only wide spreads (near silhouettes, caustics) are down-weighted.
pub const DEFAULT_CONFIDENCE_DEGREES: f64 = 30.0;

/// Why targets cannot be made.
#[derive(Debug, thiserror::Error)]
pub enum TargetError {
    /// An input is inconsistent; names the field and the fix.
    #[error("targets: {0}")]
    BadInput(String),
}

/// The paper's per-pixel confidence `1 − min(θ_m², θ_c²)/θ_c²`: 1 when all of a pixel's outgoing
/// rays are parallel, falling to 0 at θ_m = θ_c and beyond. Angles in radians; θ_c > 0.
pub fn confidence(theta_m: f64, theta_c: f64) -> f64 {
    let c2 = theta_c * theta_c;
    1.0 - (theta_m * theta_m).min(c2) / c2
}

/// One term's targets of every layer at one camera.
#[derive(Clone, Debug)]
pub struct TermTargets {
    /// The term.
    pub term: Term,
    /// `layers[layer][pixel]`: premultiplied RGBA incident radiance, display resolution.
    pub layers: Vec<Vec<[f64; 4]>>,
    /// Per display pixel confidence in [0, 1] (0 where the lens is not seen).
    pub confidence: Vec<f64>,
    /// Display pixels with at least one record of this term.
    pub pixels_with_records: usize,
}

/// The image lens records were traced for: `width × height` display pixels, each supersampled
/// `k × k`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Display {
    /// Display pixels across.
    pub width: u32,
    /// Display pixels down.
    pub height: u32,
    /// Supersamples per pixel along each axis.
    pub k: u32,
}

/// Builds the targets of `term` for lens records `records` of image `display`, for layer shells `shells` (nearest first), with threshold `theta_c`
/// (radians). Only records where the lens object is what the camera sees count.
pub fn term_targets(
    records: &LensRecords,
    term: Term,
    shells: &[LayerShell],
    display: Display,
    theta_c: f64,
) -> Result<TermTargets, TargetError> {
    if shells.is_empty() {
        return Err(TargetError::BadInput(
            "no layer shells; give at least one".into(),
        ));
    }
    let n = shells.len();
    let mut sum = Accumulation::new(n, display, theta_c)?;
    for record in records
        .records
        .iter()
        .filter(|r| r.term == term && r.visible)
    {
        let pixel = sum.pixel(record)?;
        let ray = record.outgoing_ray;
        let distances: Vec<f64> = shells
            .iter()
            .map(|s| {
                s.intersect(ray.origin, ray.direction)
                    .map_or(f64::INFINITY, |h| h.t)
            })
            .collect();
        let hits = records.hits_of(record);
        for layer in 0..n {
            let (start, end) = layer_range(&distances, layer);
            let hit = hits
                .iter()
                .find(|h| h.distance > start && h.distance <= end)
                .map(|h| h.radiance);
            let radiance = match hit {
                Some(radiance) => radiance,
                None if layer + 1 == n => record.background,
                None => continue,
            };
            sum.add(layer, pixel, radiance);
        }
    }
    Ok(sum.finish(term))
}

/// The targets of `term` for records of first-bounce paths ([`lensmap::trace::Bounces::First`]),
/// layered by bounce (the PEM paper §4): layer 0, the local layer, holds what a first bounce sees
/// of the lens objects (α = the fraction of the pixel's supersamples that see one); layer 1,
/// the distant one, the environment seen through them (the first environment hit, else the
/// environment at infinity: α = 1 wherever the term has records). Arguments as
/// [`term_targets`].
pub fn bounce_targets(
    records: &LensRecords,
    term: Term,
    display: Display,
    theta_c: f64,
) -> Result<TermTargets, TargetError> {
    let mut sum = Accumulation::new(2, display, theta_c)?;
    for record in records
        .records
        .iter()
        .filter(|r| r.term == term && r.visible)
    {
        let pixel = sum.pixel(record)?;
        let distant = records
            .hits_of(record)
            .first()
            .map_or(record.background, |h| h.radiance);
        if let Some(local) = record.local {
            sum.add(0, pixel, local.radiance);
        }
        sum.add(1, pixel, distant);
    }
    Ok(sum.finish(term))
}

/// One term's targets as they are summed: per layer the premultiplied images, per pixel its
/// records' outgoing directions (for the confidence).
struct Accumulation {
    layers: Vec<Vec<[f64; 4]>>,
    directions: Vec<Vec<DVec3>>,
    /// 1/k²: one supersample's share of its pixel.
    scale: f64,
    size: (u32, u32),
    theta_c: f64,
}

impl Accumulation {
    /// Empty images of `n` layers of `display`; θc checked.
    fn new(n: usize, display: Display, theta_c: f64) -> Result<Self, TargetError> {
        let Display { width, height, k } = display;
        let size = (width, height);
        if !(theta_c.is_finite() && theta_c > 0.0) {
            return Err(TargetError::BadInput(format!(
                "confidence angle {} degrees; give an angle > 0, e.g. 5",
                theta_c.to_degrees()
            )));
        }
        let pixels = (size.0 as usize) * (size.1 as usize);
        Ok(Accumulation {
            layers: vec![vec![[0.0f64; 4]; pixels]; n],
            directions: vec![Vec::new(); pixels],
            scale: 1.0 / f64::from(k.max(1) * k.max(1)),
            size,
            theta_c,
        })
    }

    /// The display pixel of `record`, whose outgoing direction it takes; an error for a record
    /// outside the image.
    fn pixel(&mut self, record: &IntersectionRecord) -> Result<usize, TargetError> {
        let (width, height) = self.size;
        let position = record.image_position;
        let (x, y) = (position.x.floor(), position.y.floor());
        if x < 0.0 || y < 0.0 || x >= width as f32 || y >= height as f32 {
            return Err(TargetError::BadInput(format!(
                "a record at image position {position} lies outside the {width}×{height} image; compile the records with the same camera"
            )));
        }
        let pixel = y as usize * width as usize + x as usize;
        self.directions[pixel].push(record.outgoing_ray.direction.normalize_or_zero());
        Ok(pixel)
    }

    /// One supersample's `radiance` into `layer` at `pixel` (α: its coverage).
    fn add(&mut self, layer: usize, pixel: usize, radiance: DVec3) {
        let target = &mut self.layers[layer][pixel];
        target[0] += radiance.x * self.scale;
        target[1] += radiance.y * self.scale;
        target[2] += radiance.z * self.scale;
        target[3] += self.scale;
    }

    /// The targets of `term`: each pixel's confidence from its widest pair of directions.
    fn finish(self, term: Term) -> TermTargets {
        let Accumulation {
            layers,
            directions,
            theta_c,
            ..
        } = self;
        let confidence: Vec<f64> = directions
            .iter()
            .map(|rays| {
                if rays.is_empty() {
                    return 0.0;
                }
                let mut widest = 0.0f64;
                for (i, a) in rays.iter().enumerate() {
                    for b in &rays[i + 1..] {
                        widest = widest.max(a.angle_between(*b));
                    }
                }
                confidence(widest, theta_c)
            })
            .collect();
        TermTargets {
            term,
            layers,
            pixels_with_records: directions.iter().filter(|d| !d.is_empty()).count(),
            confidence,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn confidence_closed_forms() {
        let c = 5f64.to_radians();
        assert_eq!(confidence(0.0, c), 1.0);
        assert!((confidence(0.5 * c, c) - 0.75).abs() < 1e-15);
        assert_eq!(confidence(c, c), 0.0);
        assert_eq!(confidence(3.0 * c, c), 0.0);
    }
}
