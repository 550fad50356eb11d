//! Which pixels show which lens object: the one rule behind every lens-error figure lensmap prints
//! (the baker's judge, `render --compare`, the benchmarks).
//!
//! **The rule.** A pixel counts for lens object L when the camera ray through each of its k×k
//! subpixel positions ([`subsample_position`], the reference ray tracer's own sample pattern) hits
//! L first: before any other lens object and any environment surface. The *lens pixels* of an
//! image are those that count for some lens object. A pixel on a lens object's silhouette (a
//! subpixel sees past it) or where two lens objects meet counts for none: an error over lens
//! pixels then measures how a lens object is shaded, not how its outline is rasterized, and a
//! pixel is never scored against a colour that mixes two objects. The *environment pixels* are
//! those where no subpixel hits any lens object.
//!
//! The rule is evaluated on the CPU from first hits alone, so the same scene and camera give the
//! same pixels on every Vulkan driver. The reference ray tracer records it while it renders
//! ([`super::ReferenceImage::lens_pixels`]); [`LensPixels::trace`] casts only the camera rays.

use rayon::prelude::*;

use super::image::{camera_ray, subsample_position};
use super::stats::TraceCounters;
use super::world::{Part, TraceScene};
use crate::scene::Camera;

/// What one pixel's subpixels see first.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum PixelCover {
    /// No subpixel hits a lens object first: an environment pixel.
    Environment,
    /// Every subpixel hits this lens object first (its index in the trace scene's lens objects).
    Lens(usize),
    /// Some subpixels hit a lens object first and the others something else (the environment,
    /// the background or another lens object): neither kind.
    Mixed,
}

impl PixelCover {
    /// The cover of a pixel whose subpixels' first lens hits are `first_hits` (`None`: the
    /// subpixel's camera ray hits no lens object first).
    pub fn of(first_hits: impl IntoIterator<Item = Option<usize>>) -> PixelCover {
        let mut hits = first_hits.into_iter();
        let Some(first) = hits.next() else {
            return PixelCover::Environment;
        };
        let mut cover = match first {
            Some(lens) => PixelCover::Lens(lens),
            None => PixelCover::Environment,
        };
        for hit in hits {
            let same = match (cover, hit) {
                (PixelCover::Lens(lens), Some(other)) => lens == other,
                (PixelCover::Environment, None) => true,
                _ => false,
            };
            if !same {
                cover = PixelCover::Mixed;
            }
        }
        cover
    }
}

/// Which lens pixels a mask selects.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum LensSelection {
    /// The pixels of every lens object.
    All,
    /// The pixels of one lens object (its index in the trace scene's lens objects).
    Object(usize),
}

/// The cover of every pixel of an image, row-major, by the rule of the module documentation.
#[derive(Clone, Debug, PartialEq)]
pub struct LensPixels {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// One cover per pixel, row-major, row 0 at the top.
    pub covers: Vec<PixelCover>,
}

impl LensPixels {
    /// The lens pixels of `scene` seen by `camera` (its size and supersampling), from the camera
    /// rays' first hits alone (no shading), on the current rayon pool.
    pub fn trace(scene: &TraceScene, camera: &Camera) -> LensPixels {
        let k = camera.supersampling.max(1);
        let covers = (0..camera.width * camera.height)
            .into_par_iter()
            .map(|pixel| {
                let (x, y) = (pixel % camera.width, pixel / camera.width);
                let mut counters = TraceCounters::default();
                PixelCover::of((0..k * k).map(|s| {
                    let (sx, sy) = subsample_position(x, y, s % k, s / k, k);
                    let hit =
                        scene.closest_hit(&camera_ray(camera, sx, sy), None, None, &mut counters);
                    match hit?.part {
                        Part::Lens(lens) => Some(lens),
                        Part::Environment => None,
                    }
                }))
            })
            .collect();
        LensPixels {
            width: camera.width,
            height: camera.height,
            covers,
        }
    }

    /// One flag per pixel: whether it is a pixel of `selection`.
    pub fn flags(&self, selection: LensSelection) -> Vec<bool> {
        self.covers
            .iter()
            .map(|cover| match (cover, selection) {
                (PixelCover::Lens(_), LensSelection::All) => true,
                (PixelCover::Lens(lens), LensSelection::Object(object)) => *lens == object,
                _ => false,
            })
            .collect()
    }

    /// One flag per pixel: whether it is an environment pixel (no subpixel hits a lens object).
    pub fn environment_flags(&self) -> Vec<bool> {
        self.covers
            .iter()
            .map(|cover| *cover == PixelCover::Environment)
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_pixel_counts_for_a_lens_object_only_when_every_subpixel_hits_it_first() {
        assert_eq!(PixelCover::of([Some(1); 9]), PixelCover::Lens(1));
        assert_eq!(PixelCover::of([None; 4]), PixelCover::Environment);
        // A silhouette pixel, and a pixel where two lens objects meet.
        assert_eq!(PixelCover::of([Some(0), None]), PixelCover::Mixed);
        assert_eq!(PixelCover::of([None, Some(0)]), PixelCover::Mixed);
        assert_eq!(PixelCover::of([Some(0), Some(1)]), PixelCover::Mixed);
    }

    /// The reference ray tracer's record of the rule and a second evaluation from the camera rays
    /// alone agree, on a scene with two lens objects; the lens pixels are the fully covered pixels
    /// of the reference's coverage less those where two lens objects meet.
    #[test]
    fn the_reference_and_the_camera_rays_give_the_same_pixels() {
        let mut scene = crate::scene::Scene::load_named("teapot-room").expect("built in");
        scene.camera = scene.camera.with_resolution(40, 30, 2);
        let trace = TraceScene::new(&scene).expect("traceable");
        let reference = crate::trace::render_reference(
            &trace,
            &scene.camera,
            &crate::trace::TraceOptions::default(),
            &|_| {},
        )
        .expect("renders");
        let traced = LensPixels::trace(&trace, &scene.camera);
        assert_eq!(reference.lens_pixels, traced);
        for lens in 0..trace.lenses.len() {
            let count = traced
                .flags(LensSelection::Object(lens))
                .iter()
                .filter(|&&f| f)
                .count();
            assert!(count > 0, "lens object {lens} has no pixel");
        }
        for (i, cover) in traced.covers.iter().enumerate() {
            let coverage = reference.lens_mask[i];
            match cover {
                PixelCover::Lens(_) => assert_eq!(coverage, 1.0),
                PixelCover::Environment => assert_eq!(coverage, 0.0),
                PixelCover::Mixed => assert!(coverage > 0.0),
            }
        }
    }

    #[test]
    fn selections_pick_their_pixels() {
        let pixels = LensPixels {
            width: 4,
            height: 1,
            covers: vec![
                PixelCover::Lens(0),
                PixelCover::Mixed,
                PixelCover::Lens(1),
                PixelCover::Environment,
            ],
        };
        assert_eq!(pixels.flags(LensSelection::All), [true, false, true, false]);
        assert_eq!(
            pixels.flags(LensSelection::Object(1)),
            [false, false, true, false]
        );
        assert_eq!(pixels.environment_flags(), [false, false, false, true]);
    }
}
