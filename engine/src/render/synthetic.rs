//! The built-in synthetic compositor scene: a glass sphere lens with analytic per-vertex ray
//! paths (exact dielectric Fresnel, absorption along the chord) over a vertex-coloured room, with
//! procedurally made layered cube maps for up to three viewpoint samples. It exercises every pass
//! of the frame without the ray tracer or the baker, so `lensmap demo` and the benches have a
//! scene.

use std::f64::consts::PI;

use glam::{DVec3, Mat4, Vec3};

use super::{EnvironmentMesh, FrameInput, LensFaces, LensObject, TermVertices};
use crate::cubemap::CubeMap;
use crate::{
    scene::Camera,
    trace::Term,
    trace::classes::{ClassTerm, Event},
    trace::fresnel::{dielectric, reflect, refract},
};

/// Knobs of the synthetic scene.
#[derive(Clone, Debug)]
pub struct SyntheticOptions {
    /// Framebuffer width in pixels.
    pub width: u32,
    /// Framebuffer height in pixels.
    pub height: u32,
    /// Layers n per viewpoint (1 ..= [`super::SinglePassProgram::MAX_LAYERS`] for the
    /// single-pass variant).
    pub layers: usize,
    /// Viewpoint samples blended (1 to [`super::MAX_VIEWPOINTS`]; more are clamped).
    pub viewpoints: usize,
    /// Terms: both for glass, reflection only for a mirror.
    pub terms: Vec<Term>,
    /// Cube-map face size (power of two).
    pub cube_size: u32,
    /// Sphere tessellation: stacks (slices = 2 × stacks).
    pub stacks: u32,
    /// Index of refraction of the glass.
    pub ior: f64,
    /// The sphere's last this many triangles (the southern ones) drawn without layer 0, as the
    /// convex-hull split draws a lens object's hull triangles ([`LensObject::hull_triangles`];
    /// at most every triangle).
    pub hull_triangles: usize,
}

impl Default for SyntheticOptions {
    fn default() -> Self {
        SyntheticOptions {
            width: 640,
            height: 480,
            layers: 3,
            viewpoints: 2,
            terms: vec![Term::Refraction, Term::Reflection],
            cube_size: 64,
            stacks: 48,
            ior: 1.5,
            hull_triangles: 0,
        }
    }
}

/// Radius of layer shell `layer` of `layers` (nearest first), centred on the EM origin.
fn shell_radius(layer: usize) -> f64 {
    2.0 * 2.2f64.powi(layer as i32)
}

/// The demo's camera.
pub fn camera(width: u32, height: u32) -> Camera {
    Camera {
        position: Vec3::new(0.0, 0.9, 4.2),
        look_at: Vec3::new(0.0, 0.1, 0.0),
        up: Vec3::Y,
        vfov_radians: 40f32.to_radians(),
        width,
        height,
        supersampling: 1,
    }
}

/// Where the ray `origin + s·direction` (unit direction) leaves the sphere of `radius` at the
/// origin, for an origin inside it.
fn exit_distance(origin: DVec3, direction: DVec3, radius: f64) -> f64 {
    let b = origin.dot(direction);
    let c = origin.length_squared() - radius * radius;
    -b + (b * b - c).max(0.0).sqrt()
}

/// Builds the frame.
pub fn sphere_frame(options: &SyntheticOptions) -> FrameInput {
    let camera = camera(options.width, options.height);
    let eye = camera.position.as_dvec3();
    let (positions, triangles) = uv_sphere(1.0, options.stacks.max(3), 2 * options.stacks.max(3));
    let absorption = DVec3::new(0.82, 0.93, 0.97);

    let mut refraction = TermVertices {
        term: Term::Refraction,
        fg: Vec::new(),
        directions: vec![Vec::new(); options.layers],
    };
    let mut reflection = TermVertices {
        term: Term::Reflection,
        fg: Vec::new(),
        directions: vec![Vec::new(); options.layers],
    };
    for p in &positions {
        let p = p.as_dvec3();
        let normal = p.normalize();
        let view = (p - eye).normalize();
        let cos_in = -view.dot(normal);
        let entry = dielectric(cos_in, 1.0, options.ior);
        let reflected = reflect(view, normal);
        let (fg_t, exit_point, exit_dir) = if cos_in > 0.0 && !entry.total_internal_reflection {
            let inside = refract(view, normal, 1.0 / options.ior, entry.cos_transmitted);
            let chord = exit_distance(p, inside, 1.0);
            let exit = p + chord * inside;
            let exit_normal = exit.normalize();
            let out = dielectric(inside.dot(exit_normal), options.ior, 1.0);
            // A sphere is symmetric: the exit angle equals the entry angle, so no TIR at the exit.
            let outgoing = refract(inside, -exit_normal, options.ior, out.cos_transmitted);
            let g = DVec3::new(
                absorption.x.powf(chord),
                absorption.y.powf(chord),
                absorption.z.powf(chord),
            );
            (g * entry.transmittance * out.transmittance, exit, outgoing)
        } else {
            (DVec3::ZERO, p, reflected)
        };
        refraction.fg.push(fg_t.as_vec3());
        reflection.fg.push(Vec3::splat(entry.reflectance as f32));
        for layer in 0..options.layers {
            let radius = shell_radius(layer);
            refraction.directions[layer].push(
                (exit_point + exit_distance(exit_point, exit_dir, radius) * exit_dir).as_vec3(),
            );
            reflection.directions[layer]
                .push((p + exit_distance(p, reflected, radius) * reflected).as_vec3());
        }
    }
    let terms = options
        .terms
        .iter()
        .map(|&t| match t {
            Term::Refraction => refraction.clone(),
            Term::Reflection => reflection.clone(),
            Term::Class(class) => sphere_class(&positions, eye, options, absorption, class),
        })
        .collect();
    let viewpoints = options.viewpoints.clamp(1, super::MAX_VIEWPOINTS);
    let weights = match viewpoints {
        1 => vec![1.0],
        2 => vec![0.6, 0.4],
        _ => vec![0.5, 0.3, 0.2],
    };
    let layers = (0..viewpoints)
        .map(|v| {
            (0..options.layers)
                .map(|l| std::sync::Arc::new(layer_map(options.cube_size, l, options.layers, v)))
                .collect()
        })
        .collect();

    FrameInput {
        width: options.width,
        height: options.height,
        view_proj: camera.view_proj(0.1, 100.0),
        environment: room(),
        glossy: Vec::new(),
        lenses: vec![LensObject {
            name: "sphere".into(),
            positions,
            hull_triangles: options.hull_triangles.min(triangles.len()),
            triangles,
            faces: LensFaces::Front,
            terms,
            layers,
            resident: None,
        }],
        viewpoint_weights: weights,
    }
}

/// The most events a synthetic class path follows (a greedy tail stops there, weightless).
const MAX_SPHERE_EVENTS: usize = 16;

/// One path class's term on the unit glass sphere at `positions`, seen from `eye`: per vertex
/// the class's events in closed form (reflect, or refract by Snell's law, with exact dielectric
/// Fresnel and absorption along each chord), then the greedy choice after a prefix with a
/// greedy tail. A vertex whose path has another sequence (total internal reflection where the
/// class refracts, a ray outside the ball before the class ends, or still inside after it)
/// carries nothing in this class.
fn sphere_class(
    positions: &[Vec3],
    eye: DVec3,
    options: &SyntheticOptions,
    absorption: DVec3,
    class: ClassTerm,
) -> TermVertices {
    let events: Vec<Event> = class.class.events().collect();
    let mut term = TermVertices {
        term: Term::Class(class),
        fg: Vec::with_capacity(positions.len()),
        directions: vec![Vec::with_capacity(positions.len()); options.layers],
    };
    for p in positions {
        let p = p.as_dvec3();
        let view = (p - eye).normalize();
        let (mut point, mut direction, mut inside) = (p, view, false);
        let mut fg = DVec3::ONE;
        let mut carried = true;
        for i in 0..MAX_SPHERE_EVENTS {
            let event = match events.get(i) {
                Some(&event) => Some(event),
                None if class.greedy_tail && inside => None,
                None => break,
            };
            let outward = point.normalize();
            let (normal, n1, n2) = if inside {
                (-outward, options.ior, 1.0)
            } else {
                (outward, 1.0, options.ior)
            };
            let cos_in = -direction.dot(normal);
            if cos_in <= 0.0 {
                carried = false;
                break;
            }
            let fresnel = dielectric(cos_in, n1, n2);
            let reflects = match event {
                Some(event) => event == Event::Reflect,
                None => fresnel.reflectance >= fresnel.transmittance,
            };
            if reflects {
                fg *= fresnel.reflectance;
                direction = reflect(direction, normal);
            } else if fresnel.total_internal_reflection {
                carried = false;
                break;
            } else {
                fg *= fresnel.transmittance;
                direction = refract(direction, normal, n1 / n2, fresnel.cos_transmitted);
                inside = !inside;
            }
            if !inside {
                // Outside a convex ball the ray leaves: the class must end here.
                carried = i + 1 >= events.len();
                break;
            }
            let chord = exit_distance(point, direction, 1.0);
            fg *= DVec3::new(
                absorption.x.powf(chord),
                absorption.y.powf(chord),
                absorption.z.powf(chord),
            );
            point += chord * direction;
        }
        if inside || !carried {
            // Another sequence: nothing in this class (the direction is the mirror one, finite).
            (point, direction, fg) = (p, reflect(view, p.normalize()), DVec3::ZERO);
        }
        term.fg.push(fg.as_vec3());
        for (layer, directions) in term.directions.iter_mut().enumerate() {
            let radius = shell_radius(layer);
            directions
                .push((point + exit_distance(point, direction, radius) * direction).as_vec3());
        }
    }
    term
}

/// Layer `layer` of `count` as seen from viewpoint sample `viewpoint`: inner layers are sparse
/// (coloured bands and columns with transparent gaps), the outermost is an opaque sky and ground.
fn layer_map(size: u32, layer: usize, count: usize, viewpoint: usize) -> CubeMap {
    // Each viewpoint sample sees the world turned slightly, so blending them is visible.
    let turn = 0.06 * viewpoint as f64;
    CubeMap::from_fn(size, |d| {
        let d = d.normalize();
        let azimuth = d.z.atan2(d.x) + turn;
        let elevation = d.y.asin();
        if layer + 1 == count {
            let sky = [
                0.35 + 0.3 * elevation.max(0.0),
                0.55 + 0.25 * elevation.max(0.0),
                0.9,
            ];
            let ground_checker = ((azimuth * 8.0 / PI).floor() as i64
                + (elevation * 10.0).floor() as i64)
                .rem_euclid(2);
            let ground = if ground_checker == 0 {
                [0.55, 0.5, 0.42]
            } else {
                [0.25, 0.22, 0.2]
            };
            let c = if elevation > 0.0 { sky } else { ground };
            [c[0] as f32, c[1] as f32, c[2] as f32, 1.0]
        } else if layer.is_multiple_of(2) {
            // Columns: opaque vertical bars at regular azimuths.
            let bars = 6.0 + 4.0 * layer as f64;
            let phase = (azimuth * bars / (2.0 * PI)).rem_euclid(1.0);
            if phase < 0.22 && elevation.abs() < 0.7 {
                let hue = (azimuth / (2.0 * PI) + 0.5).rem_euclid(1.0);
                [(0.9 * hue) as f32, 0.35, (0.9 * (1.0 - hue)) as f32, 1.0]
            } else {
                [0.0; 4]
            }
        } else {
            // A half-transparent band around the horizon (premultiplied).
            let alpha = (1.0 - (elevation / 0.25).powi(2)).max(0.0) * 0.6;
            [
                (0.9 * alpha) as f32,
                (0.75 * alpha) as f32,
                (0.2 * alpha) as f32,
                alpha as f32,
            ]
        }
    })
}

/// A UV sphere with outward, counter-clockwise triangles.
pub fn uv_sphere(radius: f32, stacks: u32, slices: u32) -> (Vec<Vec3>, Vec<[u32; 3]>) {
    let mut positions = Vec::new();
    for i in 0..=stacks {
        let polar = std::f32::consts::PI * i as f32 / stacks as f32;
        for j in 0..=slices {
            let azimuth = 2.0 * std::f32::consts::PI * j as f32 / slices as f32;
            positions.push(
                radius
                    * Vec3::new(
                        polar.sin() * azimuth.cos(),
                        polar.cos(),
                        -polar.sin() * azimuth.sin(),
                    ),
            );
        }
    }
    let row = slices + 1;
    let mut triangles = Vec::new();
    for i in 0..stacks {
        for j in 0..slices {
            let (a, b, c, d) = (
                i * row + j,
                (i + 1) * row + j,
                (i + 1) * row + j + 1,
                i * row + j + 1,
            );
            if i != 0 {
                triangles.push([a, b, d]);
            }
            if i + 1 != stacks {
                triangles.push([b, c, d]);
            }
        }
    }
    (positions, triangles)
}

/// A floor checkerboard and a back wall, as flat-coloured quads.
fn room() -> Vec<std::sync::Arc<EnvironmentMesh>> {
    let mut mesh = EnvironmentMesh {
        positions: Vec::new(),
        colours: Vec::new(),
        triangles: Vec::new(),
        light_map: None,
    };
    let mut quad = |corners: [Vec3; 4], colour: Vec3| {
        let base = mesh.positions.len() as u32;
        mesh.positions.extend(corners);
        mesh.colours.extend([colour; 4]);
        mesh.triangles.push([base, base + 1, base + 2]);
        mesh.triangles.push([base, base + 2, base + 3]);
    };
    let cells = 12;
    let cell = 1.0;
    for i in 0..cells {
        for j in 0..cells {
            let x = (i as f32 - cells as f32 / 2.0) * cell;
            let z = (j as f32 - cells as f32 / 2.0) * cell;
            let colour = if (i + j) % 2 == 0 {
                Vec3::new(0.8, 0.78, 0.7)
            } else {
                Vec3::new(0.2, 0.25, 0.35)
            };
            let y = -1.0;
            quad(
                [
                    Vec3::new(x, y, z),
                    Vec3::new(x, y, z + cell),
                    Vec3::new(x + cell, y, z + cell),
                    Vec3::new(x + cell, y, z),
                ],
                colour,
            );
        }
    }
    let wall = Vec3::new(0.45, 0.3, 0.3);
    quad(
        [
            Vec3::new(-6.0, -1.0, -6.0),
            Vec3::new(6.0, -1.0, -6.0),
            Vec3::new(6.0, 5.0, -6.0),
            Vec3::new(-6.0, 5.0, -6.0),
        ],
        wall,
    );
    vec![std::sync::Arc::new(mesh)]
}

/// The demo camera's view-projection (for callers that build their own frames).
pub fn view_proj(width: u32, height: u32) -> Mat4 {
    camera(width, height).view_proj(0.1, 100.0)
}
