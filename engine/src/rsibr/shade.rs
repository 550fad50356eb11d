//! The run time's shading of one glossy surface point, in f64 on the CPU: what the glossy pass
//! computes per fragment (`shaders/wgsl/glossy.wgsl`), and its independent model in the tests.
//!
//! For each lobe, each slot's map is read (bilinear, level 0, seamless) along the lobe's central
//! direction turned by the slot's rotation, and the slots are blended by their weights and the
//! texels' confidences: `Σ wᵢ·rgbᵢ / Σ wᵢ·αᵢ` (0 where no slot has confidence). The lobes are
//! summed with their Fresnel weights ([`MapLobe::weight`]).

use std::sync::Arc;

use glam::{DMat3, DVec3};

use super::maps::MapLobe;
use crate::cubemap::CubeMap;
use crate::cubemap::sampling::sample_cube_trilinear;
use crate::scene::Glossy;

/// What shading a glossy object in one frame needs.
#[derive(Clone, Debug)]
pub struct GlossyShading {
    /// The object's BRDF.
    pub brdf: Glossy,
    /// The lobes, in map order.
    pub lobes: Vec<MapLobe>,
    /// Per slot: its weight, its rotation ([`super::ViewSlot::rotation`]) and its maps by lobe.
    pub slots: Vec<(f64, DMat3, Vec<Arc<CubeMap>>)>,
}

/// The radiance leaving a point with unit shading normal `normal` towards the viewer along unit
/// `toward_viewer` (the normal is turned to the viewer's side first, as the tracer does).
pub fn shade(shading: &GlossyShading, normal: DVec3, toward_viewer: DVec3) -> DVec3 {
    // A zero normal (opposite vertex normals interpolated) faces the viewer.
    let normal = if normal == DVec3::ZERO {
        toward_viewer
    } else {
        normal
    };
    let normal = if normal.dot(toward_viewer) < 0.0 {
        -normal
    } else {
        normal
    };
    let cos_view = normal.dot(toward_viewer);
    let mirror = (normal * (2.0 * cos_view) - toward_viewer).normalize_or_zero();
    let mut radiance = DVec3::ZERO;
    for (k, lobe) in shading.lobes.iter().enumerate() {
        let direction = match lobe {
            MapLobe::Diffuse => normal,
            _ => mirror,
        };
        let (mut colour, mut confidence) = (DVec3::ZERO, 0.0);
        for (weight, rotation, maps) in &shading.slots {
            let [r, g, b, a] = sample_cube_trilinear(&maps[k], *rotation * direction, 0.0);
            colour += DVec3::new(r, g, b) * *weight;
            confidence += a * weight;
        }
        if confidence > 0.0 {
            radiance += colour / confidence * lobe.weight(&shading.brdf, cos_view);
        }
    }
    radiance
}
