//! The lens pixels of a compositor frame, by the rule every lens-error figure uses
//! ([`crate::trace::lens_pixels`]), evaluated on the frame's own geometry: for a frame that no
//! scene stands behind (the synthetic frames of `bench passes`), or to compare compositor
//! variants of one frame with each other. A framebuffer pixel is one subpixel: its camera ray
//! passes through the pixel's centre, through the frame's view-projection, and it counts for lens
//! object L when the first surface it meets inside the depth range is a triangle of L that the
//! compositor draws (a back face of a lens object drawn with [`LensFaces::Front`] is culled, so the
//! ray passes it). Evaluated on the CPU, so the pixels are the same on every Vulkan driver.

use glam::{DMat4, DVec4, Vec2, Vec3};
use rayon::prelude::*;

use super::{FrameInput, LensFaces};
use crate::trace::{
    LensPixels, PixelCover, Ray,
    bvh::{MeshBvh, SourceTriangle},
};

/// The object index of the environment's triangles in the frame's BVH; lens object `L` is `L + 1`.
const ENVIRONMENT: u32 = 0;

/// The lens pixels of `frame`, one per framebuffer pixel (see the module documentation).
pub fn frame_lens_pixels(frame: &FrameInput) -> LensPixels {
    let bvh = MeshBvh::build(&frame_triangles(frame));
    let inverse = frame.view_proj.as_dmat4().inverse();
    let (width, height) = (frame.width, frame.height);
    let covers = (0..width * height)
        .into_par_iter()
        .map(|pixel| {
            let (x, y) = (pixel % width, pixel / width);
            let first = pixel_ray(&inverse, x, y, width, height)
                .and_then(|(ray, length)| first_drawn_lens(frame, &bvh, &ray, length));
            PixelCover::of([first])
        })
        .collect();
    LensPixels {
        width,
        height,
        covers,
    }
}

/// Every triangle the frame draws, the environment's as object [`ENVIRONMENT`] and lens object
/// L's as object L + 1.
fn frame_triangles(frame: &FrameInput) -> Vec<SourceTriangle> {
    let triangle = |positions: &[Vec3], indices: &[u32; 3], object: u32| {
        let at = |i: u32| positions.get(i as usize).copied().unwrap_or(Vec3::NAN);
        SourceTriangle {
            positions: indices.map(at),
            normals: [Vec3::ZERO; 3],
            uvs: [Vec2::ZERO; 3],
            object,
        }
    };
    let environment = frame.environment.iter().flat_map(|mesh| {
        mesh.triangles
            .iter()
            .map(|t| triangle(&mesh.positions, t, ENVIRONMENT))
    });
    let lenses = frame.lenses.iter().enumerate().flat_map(|(lens, object)| {
        object
            .triangles
            .iter()
            .map(move |t| triangle(&object.positions, t, lens as u32 + 1))
    });
    environment.chain(lenses).collect()
}

/// The ray through the centre of framebuffer pixel `(x, y)` from the near plane (depth 0) towards
/// the far plane (depth 1), and the distance between them; `None` where the view-projection
/// cannot be inverted there.
fn pixel_ray(inverse: &DMat4, x: u32, y: u32, width: u32, height: u32) -> Option<(Ray, f64)> {
    let ndc_x = 2.0 * (f64::from(x) + 0.5) / f64::from(width) - 1.0;
    let ndc_y = 2.0 * (f64::from(y) + 0.5) / f64::from(height) - 1.0;
    let unproject = |depth: f64| {
        let p = *inverse * DVec4::new(ndc_x, ndc_y, depth, 1.0);
        (p.w != 0.0).then(|| p.truncate() / p.w)
    };
    let (near, far) = (unproject(0.0)?, unproject(1.0)?);
    let length = (far - near).length();
    (length.is_finite() && length > 0.0).then(|| (Ray::new(near, far - near), length))
}

/// The lens object whose drawn triangle the ray meets first within `length`, if that first
/// surface is a lens object's.
fn first_drawn_lens(frame: &FrameInput, bvh: &MeshBvh, ray: &Ray, length: f64) -> Option<usize> {
    let mut tests = 0;
    bvh.all_hits(ray, 0.0, length, None, &mut tests)
        .iter()
        .find(|hit| match hit_lens(hit.object) {
            None => true,
            Some(lens) => {
                let culls_back = frame
                    .lenses
                    .get(lens)
                    .is_some_and(|object| object.faces == LensFaces::Front);
                !culls_back || hit.is_front_facing(ray.direction)
            }
        })
        .and_then(|hit| hit_lens(hit.object))
}

/// The lens object of BVH object `object`, `None` for the environment.
fn hit_lens(object: usize) -> Option<usize> {
    object.checked_sub(ENVIRONMENT as usize + 1)
}
