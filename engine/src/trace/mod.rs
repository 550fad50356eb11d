//! The CPU reference ray tracer (paper §3–4.1): obvhs BVHs, the two-term greedy ray paths and the
//! full ray tree, exact Fresnel, transparency attenuation, reference images and intersection
//! records.
//!
//! Laid out like pbrt: [`fresnel`] (interface physics), [`schlick_table`] (Schlick's fifth-order
//! term through a 1D texture, and its error), [`bvh`] (acceleration and f64
//! intersection), [`world`] (the scene flattened into lens objects and environment), [`path`]
//! (ray-path models), [`classes`] (fixed path classes beyond the two greedy terms), [`shade`]
//! (environment shading and the camera-ray integrator), [`image`] (film, render loop, EXR/PNG),
//! [`records`] (the baker's intersection records) and [`stats`] (work counters). All geometry
//! after the BVH traversal is f64.
//!
//! ```no_run
//! use lensmap::scene::Scene;
//! use lensmap::trace::{TraceScene, TraceOptions, render_reference};
//! let scene = Scene::load_named("glass-sphere")?;
//! let world = TraceScene::new(&scene)?;
//! let image = render_reference(&world, &scene.camera, &TraceOptions::default(), &|_| {})?;
//! image.write(std::path::Path::new("out"))?;
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

pub mod bvh;
pub mod bvh_gpu;
pub mod classes;
pub mod fresnel;
pub mod glossy;
pub mod image;
pub mod lens_pixels;
pub mod path;
pub mod radiance_map;
pub mod records;
pub mod schlick_table;
pub mod shade;
pub mod stats;
pub mod world;

use std::path::PathBuf;

use glam::DVec3;

pub use self::classes::{ClassSet, PathClass};
pub use self::image::{ReferenceImage, render_reference};
pub use self::lens_pixels::{LensPixels, LensSelection, PixelCover};
pub use self::path::{Bounces, GreedyOptions, GreedyRayPath, Interface, RayTreeOptions, Term};
pub use self::records::{
    EnvironmentHit, IntersectionRecord, LensRecords, LocalHit, RecordSet, compile_records,
};
pub use self::shade::{CameraSample, ClassShare, PathModel, TraceOptions};
pub use self::stats::{RenderStats, TraceCounters};
pub use self::world::TraceScene;

/// A ray in world space, f64: `origin + t · direction` for t ≥ 0, `direction` a unit vector.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct Ray {
    /// Start point in metres.
    pub origin: DVec3,
    /// Unit direction.
    pub direction: DVec3,
}

impl Ray {
    /// A ray from `origin` along `direction` (normalized here; must be non-zero and finite).
    pub fn new(origin: DVec3, direction: DVec3) -> Ray {
        Ray {
            origin,
            direction: direction.normalize(),
        }
    }

    /// The point at distance `t` along the ray.
    pub fn at(&self, t: f64) -> DVec3 {
        self.origin + t * self.direction
    }
}

/// What can go wrong in the tracer.
#[derive(Debug, thiserror::Error)]
pub enum TraceError {
    /// The scene's cross references are inconsistent (the scene loader normally rules this out).
    #[error("the scene cannot be traced: {0}")]
    InvalidScene(String),
    /// The camera cannot generate rays.
    #[error("the camera cannot generate rays: {0}")]
    InvalidCamera(String),
    /// Pixel data do not match the image size.
    #[error("invalid image: {0}")]
    InvalidImage(String),
    /// A file or directory could not be written.
    #[error("cannot write {}", path.display())]
    Io {
        /// The path concerned.
        path: PathBuf,
        /// The underlying error.
        source: std::io::Error,
    },
    /// An image could not be encoded or written.
    #[error("cannot write the image {}", path.display())]
    Image {
        /// The path concerned.
        path: PathBuf,
        /// The underlying error.
        source: ::image::ImageError,
    },
}
