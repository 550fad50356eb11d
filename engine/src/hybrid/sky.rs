//! The environment at infinity on the GPU: a sphere of directions around the eye whose vertices
//! carry the environment's radiance, drawn as the last opaque environment mesh, so that every
//! pixel whose camera ray leaves the scene shows the sky the reference tracer sees
//! ([`TraceScene::background_radiance`]).
//!
//! The dome is centred on the eye every frame (no parallax: a vertex's direction from the eye is
//! exactly the direction its radiance was taken in) and placed beyond everything in the scene, so
//! the depth test hides it wherever a surface is seen. Its vertices lie on a lat-long grid of
//! directions (the mapping of [`crate::scene::lat_long_to_direction`]):
//!
//! - a **constant** environment is reproduced exactly (every vertex has the same colour);
//! - a **lat-long map** is point-sampled (bilinearly, as the tracer samples it) at the grid's
//!   [`LAT_LONG_COLUMNS`] × [`LAT_LONG_ROWS`] directions and interpolated linearly across each
//!   triangle: exact at the grid directions, in between a low-pass of the map that loses detail
//!   finer than the grid's 2.8° spacing.

use std::sync::{Arc, Mutex};

use glam::{Vec2, Vec3};

use crate::{render::EnvironmentMesh, scene::Environment, trace::world::TraceScene};

/// Longitude steps of the dome for a lat-long map (2.8° apart).
pub const LAT_LONG_COLUMNS: u32 = 128;
/// Latitude steps of the dome for a lat-long map (2.8° apart).
pub const LAT_LONG_ROWS: u32 = 64;
/// Steps of the dome for a constant environment: its colour is the same everywhere, so the
/// dome only has to surround the eye.
const CONSTANT_STEPS: (u32, u32) = (16, 8);

/// The sky dome of a scene: unit directions and their radiance, made once per scene; the mesh of
/// the last frame's eye is kept so that frames from the same camera hand the renderer the same
/// mesh (uploaded once).
#[derive(Debug)]
pub struct SkyDome {
    /// Unit directions from the eye, one per vertex.
    directions: Vec<Vec3>,
    /// Radiance seen along each direction, linear rgb.
    colours: Vec<Vec3>,
    /// Triangles over the directions (the environment pass draws both faces).
    triangles: Vec<[u32; 3]>,
    /// The mesh of the last (eye, radius) asked for.
    last: Mutex<Option<(Vec3, f32, Arc<EnvironmentMesh>)>>,
}

impl SkyDome {
    /// The dome of `trace`'s environment at infinity, or `None` when that environment is black
    /// in every direction of the dome (the cleared framebuffer already shows it).
    pub fn new(trace: &TraceScene) -> Option<SkyDome> {
        let (columns, rows) = match trace.background {
            Environment::Constant(_) => CONSTANT_STEPS,
            Environment::LatLong(_) => (LAT_LONG_COLUMNS, LAT_LONG_ROWS),
        };
        let direction = |i: u32, j: u32| {
            crate::scene::lat_long_to_direction(Vec2::new(
                i as f32 / columns as f32,
                j as f32 / rows as f32,
            ))
        };
        // The zenith, the rings j = 1 … rows − 1 (vertex 1 + (j − 1)·columns + i), the nadir.
        let mut directions = vec![Vec3::Y];
        for j in 1..rows {
            directions.extend((0..columns).map(|i| direction(i, j)));
        }
        directions.push(Vec3::NEG_Y);
        let ring = |j: u32, i: u32| 1 + (j - 1) * columns + i % columns;
        let nadir = directions.len() as u32 - 1;
        let mut triangles = Vec::new();
        for i in 0..columns {
            triangles.push([0, ring(1, i), ring(1, i + 1)]);
            for j in 1..rows - 1 {
                let (a, b) = (ring(j, i), ring(j, i + 1));
                let (c, d) = (ring(j + 1, i), ring(j + 1, i + 1));
                triangles.push([a, c, d]);
                triangles.push([a, d, b]);
            }
            triangles.push([ring(rows - 1, i), nadir, ring(rows - 1, i + 1)]);
        }
        let colours: Vec<Vec3> = directions
            .iter()
            .map(|d| trace.background_radiance(d.as_dvec3()).as_vec3())
            .collect();
        if colours.iter().all(|c| *c == Vec3::ZERO) {
            return None;
        }
        Some(SkyDome {
            directions,
            colours,
            triangles,
            last: Mutex::new(None),
        })
    }

    /// Distance from the eye at which a dome must sit to lie beyond every scene point that is at
    /// most `farthest` metres from the eye: the dome's flat triangles come as close as
    /// cos(half their angular size) of the radius (≥ 0.92 for the coarsest dome), so twice
    /// the distance, plus a metre, leaves room.
    pub fn radius_beyond(farthest: f32) -> f32 {
        2.0 * farthest + 1.0
    }

    /// The dome centred on `eye` with vertices `radius` metres away.
    pub fn mesh(&self, eye: Vec3, radius: f32) -> Arc<EnvironmentMesh> {
        let mut last = self
            .last
            .lock()
            .unwrap_or_else(|poisoned| poisoned.into_inner());
        if let Some((e, r, mesh)) = last.as_ref()
            && *e == eye
            && *r == radius
        {
            return mesh.clone();
        }
        let mesh = Arc::new(EnvironmentMesh {
            positions: self.directions.iter().map(|d| eye + radius * *d).collect(),
            colours: self.colours.clone(),
            light_map: None,
            triangles: self.triangles.clone(),
        });
        *last = Some((eye, radius, mesh.clone()));
        mesh
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scene(environment: Environment) -> TraceScene {
        let mut scene = crate::scene::Scene::load_named("glass-sphere").unwrap();
        scene.environment = environment;
        TraceScene::new(&scene).unwrap()
    }

    /// Every direction from the eye crosses the dome exactly once: it is a closed surface around
    /// the eye (each edge shared by two triangles in opposite directions) that encloses it.
    #[test]
    fn the_dome_is_closed_and_surrounds_the_eye() {
        let sky = SkyDome::new(&scene(Environment::Constant(Vec3::new(0.2, 0.3, 0.4)))).unwrap();
        let eye = Vec3::new(1.0, -2.0, 3.0);
        let mesh = sky.mesh(eye, 10.0);
        let closed = crate::scene::TriangleMesh {
            positions: mesh.positions.clone(),
            normals: Vec::new(),
            uvs: Vec::new(),
            triangles: mesh.triangles.clone(),
        };
        assert!(closed.is_closed());
        // Consistently wound and enclosing the eye: the solid angle it subtends is 4π (signed
        // volume of the tetrahedra to the eye, all one sign).
        let volume: f64 = mesh
            .triangles
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(|i| (mesh.positions[i as usize] - eye).as_dvec3());
                a.dot(b.cross(c)) / 6.0
            })
            .sum();
        let inscribed = (4.0 / 3.0) * std::f64::consts::PI * 1000.0;
        assert!(
            volume.abs() > 0.9 * inscribed && volume.abs() < inscribed,
            "{volume}"
        );
        assert!(mesh.colours.iter().all(|c| *c == Vec3::new(0.2, 0.3, 0.4)));
        // The same eye and radius: the same mesh, so the renderer uploads it once.
        assert!(Arc::ptr_eq(&mesh, &sky.mesh(eye, 10.0)));
        assert!(!Arc::ptr_eq(&mesh, &sky.mesh(eye + Vec3::X, 10.0)));
    }

    #[test]
    fn a_black_environment_has_no_dome() {
        assert!(SkyDome::new(&scene(Environment::Constant(Vec3::ZERO))).is_none());
    }

    #[test]
    fn lat_long_vertices_carry_the_maps_radiance_in_their_direction() {
        let (width, height) = (16u32, 8u32);
        let texels = (0..width * height)
            .map(|k| Vec3::new((k % width) as f32, (k / width) as f32, 1.0))
            .collect();
        let map = crate::scene::LatLongMap {
            width,
            height,
            texels,
        };
        let trace = scene(Environment::LatLong(map.clone()));
        let sky = SkyDome::new(&trace).unwrap();
        let mesh = sky.mesh(Vec3::ZERO, 5.0);
        assert_eq!(
            mesh.positions.len() as u32,
            2 + (LAT_LONG_ROWS - 1) * LAT_LONG_COLUMNS
        );
        for (p, c) in mesh.positions.iter().zip(&mesh.colours) {
            assert!((p.length() - 5.0).abs() < 1e-4);
            // The map's own bilinear sample in that direction (up to the rounding of a
            // direction scaled by 5 and renormalized).
            assert!(
                (*c - map.radiance(*p)).abs().max_element() < 1e-3,
                "{p} {c}"
            );
        }
    }
}
