//! Reflection-space image-based rendering of glossy objects (Cabral, Olano & Nemec 1999).
//!
//! Offline, each glossy object gets radiance environment maps: at each view sample of a 2D view
//! space ([`views`]), the lighting integral of its BRDF under everything around it, computed by
//! the reference tracer's integrator ([`crate::trace::radiance_map`]). At run time a frame takes
//! the three samples around its view direction, warps each into the view's reflection space and
//! blends them with spherical barycentric weights ([`shade`]).
//!
//! **One map per lobe.** A glossy material is a Lambertian base, a Phong lobe and an optional
//! Fresnel clear coat ([`crate::trace::glossy`]). Lambert and Phong are radially symmetric about
//! one axis (the normal, the mirror direction), as the paper's warps assume; the coat is not,
//! since its Fresnel weight varies with the view angle and its lobes have different axes. So each
//! lobe has a map of its own ([`MapLobe`]): the diffuse base warped by the normal, the Phong lobe
//! and the coat's by the mirror direction, each without Fresnel; the run time weights them by the
//! exact dielectric Fresnel reflectance at the pixel's view angle, `(1 − F)·(D + S) + F·C`. This
//! is exact in the coat's Fresnel (the product separates), at the price of up to three maps per
//! sample instead of one.
//!
//! **Maps** are cube maps over world-space directions, premultiplied by their confidence n·v
//! ([`crate::trace::radiance_map`]). With the central direction in world space, the paper's warp
//! `g_d⁻¹·T_d⁻¹·T_s·g_s` becomes the lookup itself: the warped map of sample s at the current
//! view is map_s read at the current pixel's normal (normal warp) or mirror direction (mirror
//! warp). The singularity of the mirror warp (r = −v_s) and the normals a sample never saw carry
//! confidence 0 and drop out of the blend `Σ wᵢ·rgbᵢ / Σ wᵢ·αᵢ`.

pub mod bake;
pub mod maps;
pub mod shade;
pub mod views;

pub use maps::{GlossyMaps, GlossyObject, MapLobe, RadianceMapOptions, glossy_objects};
pub use shade::{GlossyShading, shade};
pub use views::{GlossyViews, Reconstruction, ViewSlot};
