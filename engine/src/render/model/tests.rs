//! The model checked against closed forms, hand-computed pixels and ray-plane intersections, and
//! its bounds against the values they must contain.

use super::bounds::{Interval, blend_front_to_back_bounds, light_map_bounds};
use super::*;
use crate::cubemap::CubeMap;
use crate::lightmap::LightMap;
use crate::render::frame_input::{EnvironmentMesh, LensFaces, LensObject, TermVertices};
use crate::trace::Term;
use glam::{DVec2, DVec3, Mat4, Vec3};
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64;

fn random_rgba(rng: &mut Pcg64) -> [f64; 4] {
    let alpha = rng.gen_range(0.0..1.0);
    [
        alpha * rng.gen_range(0.0..1.0),
        alpha * rng.gen_range(0.0..1.0),
        alpha * rng.gen_range(0.0..1.0),
        alpha,
    ]
}

#[test]
fn over_is_associative() {
    let mut rng = Pcg64::seed_from_u64(10);
    for _ in 0..1000 {
        let (a, b, c) = (
            random_rgba(&mut rng),
            random_rgba(&mut rng),
            random_rgba(&mut rng),
        );
        let left = over(over(a, b), c);
        let right = over(a, over(b, c));
        for k in 0..4 {
            assert!((left[k] - right[k]).abs() < 1e-14);
        }
    }
}

#[test]
fn blend_sequence_equals_the_closed_form() {
    let mut rng = Pcg64::seed_from_u64(11);
    for _ in 0..1000 {
        let groups: Vec<CompositeGroup> = (0..rng.gen_range(1..=4))
            .map(|_| CompositeGroup {
                weight: rng.gen_range(0.0..1.0),
                fg: std::array::from_fn(|_| rng.gen_range(0.0..1.0)),
                layers: (0..rng.gen_range(1..=4))
                    .map(|_| random_rgba(&mut rng))
                    .collect(),
            })
            .collect();
        let blended = composite_by_blending(&groups);
        let closed = composite_closed_form(&groups);
        for k in 0..4 {
            assert!(
                (blended[k] - closed[k]).abs() < 1e-14,
                "{blended:?} {closed:?}"
            );
        }
    }
}

/// An 8×8 frame with identity view-projection (framebuffer x = 4(x + 1), y = 4(y + 1)): an
/// environment triangle covering the screen at depth 0.9 whose colour is (x, y, 0.25), and a
/// lens rectangle over pixels 2..6 × 2..6 at depth 0.25, with a back-facing triangle in front of
/// part of it that culling must remove.
fn small_frame(weights: Vec<f32>, layers: Vec<Vec<CubeMap>>) -> FrameInput {
    let environment = EnvironmentMesh {
        positions: vec![
            Vec3::new(-1.0, -1.0, 0.9),
            Vec3::new(3.0, -1.0, 0.9),
            Vec3::new(-1.0, 3.0, 0.9),
        ],
        colours: vec![
            Vec3::new(-1.0, -1.0, 0.25),
            Vec3::new(3.0, -1.0, 0.25),
            Vec3::new(-1.0, 3.0, 0.25),
        ],
        triangles: vec![[0, 1, 2]],
        light_map: None,
    };
    let n = layers[0].len();
    // Front-facing order in framebuffer coordinates: (2,2) → (2,6) → (6,6) → (6,2).
    // The rectangle's corners are off the pixel grid so that no pixel centre lies on its
    // diagonal: framebuffer x ∈ [1.8, 6.0], y ∈ [2.0, 6.2] covers pixels 2..6 × 2..6.
    let positions = vec![
        Vec3::new(-0.55, -0.5, 0.25),
        Vec3::new(-0.55, 0.55, 0.25),
        Vec3::new(0.5, 0.55, 0.25),
        Vec3::new(0.5, -0.5, 0.25),
        // Back-facing triangle nearer the camera.
        Vec3::new(-0.5, -0.5, 0.1),
        Vec3::new(0.5, -0.5, 0.1),
        Vec3::new(0.5, 0.5, 0.1),
    ];
    let directions: Vec<Vec<Vec3>> = (0..n)
        .map(|l| {
            (0..positions.len())
                .map(|v| Vec3::new(0.1 * v as f32, 0.2 * l as f32 - 0.1, 1.0))
                .collect()
        })
        .collect();
    let lens = LensObject {
        name: "square".into(),
        positions,
        triangles: vec![[0, 1, 2], [0, 2, 3], [4, 5, 6]],
        faces: LensFaces::Front,
        hull_triangles: 0,
        terms: vec![TermVertices {
            term: Term::Reflection,
            fg: vec![Vec3::new(0.5, 0.75, 1.0); 7],
            directions,
        }],
        layers: layers
            .into_iter()
            .map(|v| v.into_iter().map(std::sync::Arc::new).collect())
            .collect(),
        resident: None,
    };
    FrameInput {
        width: 8,
        height: 8,
        view_proj: Mat4::IDENTITY,
        environment: vec![std::sync::Arc::new(environment)],
        glossy: Vec::new(),
        lenses: vec![lens],
        viewpoint_weights: weights,
    }
}

#[test]
fn small_frame_matches_hand_computed_pixels() {
    let l1 = [0.1f32, 0.15, 0.05, 0.5];
    let l2 = [0.4f32, 0.6, 0.8, 1.0];
    let frame = small_frame(
        vec![1.0],
        vec![vec![CubeMap::uniform(4, l1), CubeMap::uniform(4, l2)]],
    );
    let image = render_model(&frame, &ModelOptions::default());
    let fg = [0.5, 0.75, 1.0];
    for y in 0..8u32 {
        for x in 0..8u32 {
            let i = image.index(x, y);
            assert_eq!(image.exclusion[i], None, "({x},{y})");
            let inside = (2..6).contains(&x) && (2..6).contains(&y);
            assert_eq!(image.lens_mask[i], inside);
            let expected = if inside {
                // L1 over L2, times F·G; one group so no alpha clear.
                let c: [f64; 4] =
                    std::array::from_fn(|k| f64::from(l1[k]) + 0.5 * f64::from(l2[k]));
                [c[0] * fg[0], c[1] * fg[1], c[2] * fg[2], c[3]]
            } else {
                // The environment's colour is the pixel centre's NDC position.
                let nx = (f64::from(x) + 0.5) / 4.0 - 1.0;
                let ny = (f64::from(y) + 0.5) / 4.0 - 1.0;
                [nx, ny, 0.25, 1.0]
            };
            for k in 0..4 {
                assert!(
                    (image.rgba[i][k] - expected[k]).abs() < 1e-7,
                    "({x},{y}) {:?} vs {expected:?}",
                    image.rgba[i]
                );
            }
            let depth = if inside { 0.25 } else { 0.9 };
            assert!((image.depth[i] - depth).abs() < 1e-7);
        }
    }
}

#[test]
fn two_viewpoints_sum_and_alpha_clear() {
    let a = [[0.1f32, 0.2, 0.3, 0.5], [0.2, 0.2, 0.2, 0.25]];
    let b = [[0.4f32, 0.1, 0.0, 0.5], [0.6, 0.3, 0.9, 1.0]];
    let cubes = |texels: [[f32; 4]; 2]| texels.map(|t| CubeMap::uniform(2, t)).to_vec();
    let weights = [0.25f32, 0.75];
    for scope in [AlphaClearScope::FullScreen, AlphaClearScope::LensCoverage] {
        let frame = small_frame(weights.to_vec(), vec![cubes(a), cubes(b)]);
        let options = ModelOptions {
            alpha_clear: scope,
            ..ModelOptions::default()
        };
        let image = render_model(&frame, &options);
        let composite =
            |t: [[f32; 4]; 2]| -> [f64; 4] { over(t[0].map(f64::from), t[1].map(f64::from)) };
        let (ca, cb) = (composite(a), composite(b));
        let fg = [0.5, 0.75, 1.0];
        let lens_pixel = image.rgba[image.index(3, 4)];
        for k in 0..3 {
            let expected = fg[k] * (0.25 * ca[k] + 0.75 * cb[k]);
            assert!((lens_pixel[k] - expected).abs() < 1e-7);
        }
        // α is the last group's composite α.
        assert!((lens_pixel[3] - cb[3]).abs() < 1e-7);
        let environment_alpha = image.rgba[image.index(0, 0)][3];
        let expected_alpha = match scope {
            AlphaClearScope::FullScreen => 0.0,
            AlphaClearScope::LensCoverage => 1.0,
        };
        assert_eq!(environment_alpha, expected_alpha);
    }
}

/// Three viewpoint samples (a camera inside a spherical triangle): the lens pixel's colour is
/// the weighted sum of the six groups' composites, computed by hand, its α the last group's, for
/// every blending scheme.
#[test]
fn three_viewpoints_sum_and_alpha_clear() {
    let texels = [
        [[0.1f32, 0.2, 0.3, 0.5], [0.2, 0.2, 0.2, 0.25]],
        [[0.4, 0.1, 0.0, 0.5], [0.6, 0.3, 0.9, 1.0]],
        [[0.05, 0.3, 0.2, 0.75], [0.1, 0.1, 0.4, 0.5]],
    ];
    let cubes = |texels: [[f32; 4]; 2]| texels.map(|t| CubeMap::uniform(2, t)).to_vec();
    let weights = [0.2f32, 0.3, 0.5];
    let frame = small_frame(weights.to_vec(), texels.map(cubes).to_vec());
    // L1 over L2 per viewpoint, by hand: rgb = L1 + (1 − α1)·L2.
    let composites = texels.map(|[front, back]| {
        let front = front.map(f64::from);
        let back = back.map(f64::from);
        std::array::from_fn::<f64, 4, _>(|c| front[c] + (1.0 - front[3]) * back[c])
    });
    let fg = [0.5, 0.75, 1.0];
    for blend in BlendScheme::ALL {
        let image = render_model(
            &frame,
            &ModelOptions {
                blend,
                ..ModelOptions::default()
            },
        );
        let lens_pixel = image.rgba[image.index(3, 4)];
        for k in 0..3 {
            let expected: f64 = (0..3)
                .map(|v| fg[k] * f64::from(weights[v]) * composites[v][k])
                .sum();
            assert!(
                (lens_pixel[k] - expected).abs() < 1e-7,
                "{blend:?} channel {k}: {} vs {expected}",
                lens_pixel[k]
            );
        }
        assert!((lens_pixel[3] - composites[2][3]).abs() < 1e-7, "{blend:?}");
    }
}

/// The tests' perspective projection: right-handed view space looking down −z to Vulkan clip
/// space (y down, depth 0 at the near plane 0.1, 1 at the far plane 100), focal length 1.5,
/// written out by hand.
fn test_projection() -> Mat4 {
    let (near, far, focal) = (0.1f32, 100.0f32, 1.5f32);
    Mat4::from_cols_array(&[
        focal,
        0.0,
        0.0,
        0.0, //
        0.0,
        -focal,
        0.0,
        0.0, //
        0.0,
        0.0,
        far / (near - far),
        -1.0, //
        0.0,
        0.0,
        near * far / (near - far),
        0.0,
    ])
}

#[test]
fn perspective_interpolation_matches_ray_plane_intersection() {
    // A tilted environment triangle seen in perspective; its colour is its world position,
    // so at every pixel the model's colour must be where the pixel's ray meets the plane.
    let projection = test_projection();
    let view = Mat4::from_rotation_y(0.15)
        * Mat4::from_rotation_x(-0.1)
        * Mat4::from_translation(Vec3::new(-0.3, -0.2, -3.0));
    let view_proj = projection * view;
    let corners = vec![
        Vec3::new(-2.0, -2.0, -1.0),
        Vec3::new(2.0, -1.5, 0.5),
        Vec3::new(-1.0, 2.5, 0.0),
    ];
    let frame = FrameInput {
        width: 32,
        height: 32,
        view_proj,
        environment: vec![std::sync::Arc::new(EnvironmentMesh {
            positions: corners.clone(),
            colours: corners.clone(),
            triangles: vec![[0, 1, 2]],
            light_map: None,
        })],
        glossy: Vec::new(),
        lenses: vec![],
        viewpoint_weights: vec![1.0],
    };
    let image = render_model(&frame, &ModelOptions::default());
    let inverse = view_proj.as_dmat4().inverse();
    let p: Vec<DVec3> = corners.iter().map(|c| c.as_dvec3()).collect();
    let normal = (p[1] - p[0]).cross(p[2] - p[0]);
    let mut drawn = 0;
    for y in 0..32u32 {
        for x in 0..32u32 {
            let i = image.index(x, y);
            if image.depth[i] == 1.0 || image.exclusion[i].is_some() {
                continue;
            }
            drawn += 1;
            let ndc = DVec2::new(
                (f64::from(x) + 0.5) / 16.0 - 1.0,
                (f64::from(y) + 0.5) / 16.0 - 1.0,
            );
            let near = inverse.project_point3(ndc.extend(0.0));
            let far = inverse.project_point3(ndc.extend(1.0));
            let t = normal.dot(p[0] - near) / normal.dot(far - near);
            let hit = near + t * (far - near);
            let rgb = image.rgba[i];
            let got = DVec3::new(rgb[0], rgb[1], rgb[2]);
            assert!((got - hit).length() < 1e-9, "({x},{y}) {got} vs {hit}");
        }
    }
    assert!(drawn > 100);
}

#[test]
fn lod_uses_the_quads_coarse_derivatives() {
    // Directions on the +Z face varying linearly in screen space (w = 1): s grows by
    // 2^k/size per pixel along x, so every lens pixel samples at λ = k. A cube map whose
    // levels hold different uniform values reveals the level mix.
    let size = 64u32;
    let levels = CubeMap::full_chain_levels(size) as usize;
    let mut cube = CubeMap::uniform(size, [0.0; 4]);
    for (l, level) in cube.levels.iter_mut().enumerate() {
        for face in level.iter_mut() {
            face.fill([l as f32 / 8.0, 0.0, 0.0, 1.0]);
        }
    }
    for k in [0.0f64, 1.0, 1.5, 2.25] {
        let mut frame = small_frame(vec![1.0], vec![vec![cube.clone()]]);
        // Framebuffer x = 4(x_ndc + 1); s = ½(rx + 1) on +Z with rz = 1, so ∂s/∂x_fb =
        // ½·∂rx/∂x_fb = 2^k/size needs rx = 2·2^k/size·x_fb + c = 8·2^k/size·x_ndc + c.
        let slope = 8.0 * 2f64.powf(k) / f64::from(size);
        let lens = &mut frame.lenses[0];
        lens.terms[0].directions[0] = lens
            .positions
            .iter()
            .map(|p| Vec3::new((slope * f64::from(p.x)) as f32, 0.0, 1.0))
            .collect();
        let image = render_model(&frame, &ModelOptions::default());
        let expected = k / 8.0;
        assert!(expected <= (levels - 1) as f64 / 8.0);
        for y in 2..6 {
            for x in 2..6 {
                let i = image.index(x, y);
                assert!(image.lens_mask[i]);
                // F·G red = 0.5.
                let got = image.rgba[i][0] / 0.5;
                assert!((got - expected).abs() < 1e-6, "λ={k} ({x},{y}) {got}");
            }
        }
    }
}

#[test]
fn edge_pixels_and_ties_are_excluded() {
    // Move the lens square so its left edge passes exactly through pixel centres x = 2.5.
    let mut frame = small_frame(vec![1.0], vec![vec![CubeMap::uniform(1, [0.5; 4])]]);
    for p in frame.lenses[0].positions.iter_mut().take(4) {
        if p.x < 0.0 {
            // Framebuffer x = 2.5: through the centres of column 2.
            p.x = -0.375;
        }
    }
    let image = render_model(&frame, &ModelOptions::default());
    for y in 2..6 {
        assert_eq!(
            image.exclusion[image.index(2, y)],
            Some(Exclusion::NearTriangleEdge)
        );
        assert_eq!(image.exclusion[image.index(4, y)], None);
    }
    // A lens at the environment's depth is a z-fight.
    let mut frame = small_frame(vec![1.0], vec![vec![CubeMap::uniform(1, [0.5; 4])]]);
    for p in frame.lenses[0].positions.iter_mut().take(4) {
        p.z = 0.9;
    }
    let image = render_model(&frame, &ModelOptions::default());
    assert_eq!(
        image.exclusion[image.index(3, 3)],
        Some(Exclusion::DepthTie)
    );
    // A lens vertex behind the camera: its triangles are clipped and their pixels excluded.
    let mut frame = small_frame(vec![1.0], vec![vec![CubeMap::uniform(1, [0.5; 4])]]);
    frame.lenses[0].positions[0].z = -0.5;
    let image = render_model(&frame, &ModelOptions::default());
    assert_eq!(
        image.exclusion[image.index(3, 3)],
        Some(Exclusion::ClippedTriangle)
    );
    let counts = image.exclusion_counts();
    assert!(
        counts
            .iter()
            .any(|&(r, n)| r == Exclusion::ClippedTriangle && n > 0)
    );
}

/// A perspective frame like the GPU comparison uses: a tessellated sphere lens with both
/// terms, random F·G, smooth directions, random texels in every level of every cube map,
/// `viewpoints` samples with random weights summing to 1, in front of a coloured environment quad.
fn random_sphere_frame(
    rng: &mut Pcg64,
    size: u32,
    cube_size: u32,
    layer_count: usize,
    viewpoints: usize,
) -> FrameInput {
    let projection = test_projection();
    let view_proj = projection * Mat4::from_translation(Vec3::new(0.05, -0.03, -3.0));
    let environment = EnvironmentMesh {
        positions: vec![
            Vec3::new(-6.0, -6.0, -4.0),
            Vec3::new(6.0, -6.0, -4.0),
            Vec3::new(6.0, 6.0, -4.0),
            Vec3::new(-6.0, 6.0, -4.0),
        ],
        colours: (0..4)
            .map(|_| Vec3::new(rng.r#gen(), rng.r#gen(), rng.r#gen()))
            .collect(),
        triangles: vec![[0, 1, 2], [0, 2, 3]],
        light_map: None,
    };
    let (rings, segments) = (12usize, 24usize);
    let mut positions = Vec::new();
    for i in 0..=rings {
        let theta = std::f32::consts::PI * i as f32 / rings as f32;
        for j in 0..segments {
            let phi = std::f32::consts::TAU * j as f32 / segments as f32;
            positions.push(
                0.8 * Vec3::new(
                    theta.sin() * phi.cos(),
                    theta.cos(),
                    theta.sin() * phi.sin(),
                ),
            );
        }
    }
    let index = |i: usize, j: usize| (i * segments + j % segments) as u32;
    let mut triangles = Vec::new();
    for i in 0..rings {
        for j in 0..segments {
            let quad = [
                index(i, j),
                index(i + 1, j),
                index(i + 1, j + 1),
                index(i, j + 1),
            ];
            for mut t in [[quad[0], quad[1], quad[2]], [quad[0], quad[2], quad[3]]] {
                let p = t.map(|v| positions[v as usize]);
                let normal = (p[1] - p[0]).cross(p[2] - p[0]);
                if normal.length_squared() < 1e-12 {
                    continue; // the poles' degenerate triangles
                }
                // Counter-clockwise seen from outside.
                if normal.dot(p[0] + p[1] + p[2]) < 0.0 {
                    t.swap(1, 2);
                }
                triangles.push(t);
            }
        }
    }
    let eye = Vec3::new(-0.05, 0.03, 3.0);
    let terms = [Term::Refraction, Term::Reflection]
        .into_iter()
        .map(|term| TermVertices {
            term,
            fg: positions
                .iter()
                .map(|_| Vec3::new(rng.r#gen(), rng.r#gen(), rng.r#gen()))
                .collect(),
            directions: (0..layer_count)
                .map(|layer| {
                    positions
                        .iter()
                        .map(|&p| {
                            let normal = p.normalize();
                            let view = (p - eye).normalize();
                            let outgoing = match term {
                                Term::Reflection => view - 2.0 * view.dot(normal) * normal,
                                Term::Refraction | Term::Class(_) => {
                                    (view - 0.3 * normal).normalize()
                                }
                            };
                            p + (1.5 + layer as f32) * outgoing
                        })
                        .collect()
                })
                .collect(),
        })
        .collect();
    let layers = (0..viewpoints)
        .map(|_| {
            (0..layer_count)
                .map(|_| {
                    let levels = (0..CubeMap::full_chain_levels(cube_size))
                        .map(|l| {
                            let n = ((cube_size >> l).max(1) as usize).pow(2);
                            std::array::from_fn(|_| {
                                (0..n)
                                    .map(|_| {
                                        let alpha: f32 = rng.gen_range(0.0..1.0);
                                        [
                                            alpha * rng.r#gen::<f32>(),
                                            alpha * rng.r#gen::<f32>(),
                                            alpha * rng.r#gen::<f32>(),
                                            alpha,
                                        ]
                                    })
                                    .collect()
                            })
                        })
                        .collect();
                    std::sync::Arc::new(CubeMap {
                        size: cube_size,
                        levels,
                    })
                })
                .collect()
        })
        .collect();
    // Random positive weights summing to 1 (a point of a segment or a spherical triangle).
    let raw: Vec<f32> = (0..viewpoints).map(|_| rng.gen_range(0.05..1.0)).collect();
    let total: f32 = raw.iter().sum();
    let viewpoint_weights = raw.iter().map(|w| w / total).collect();
    FrameInput {
        width: size,
        height: size,
        view_proj,
        environment: vec![std::sync::Arc::new(environment)],
        glossy: Vec::new(),
        lenses: vec![LensObject {
            name: "sphere".into(),
            positions,
            triangles,
            faces: LensFaces::Front,
            hull_triangles: 0,
            terms,
            layers,
            resident: None,
        }],
        viewpoint_weights,
    }
}

#[test]
fn bounds_are_points_without_precision_and_hold_the_nominal_value_with_it() {
    let mut rng = Pcg64::seed_from_u64(13);
    let frame = random_sphere_frame(&mut rng, 64, 16, 3, 3);
    // The exact logarithm lies in the bounds at any precision; lavapipe's (≤ 0.043 low) where
    // the mip precision is as coarse as lavapipe reports (4 bits).
    let precise = FilterPrecision {
        sub_texel_bits: 8,
        mipmap_bits: 8,
    };
    let lavapipe_like = FilterPrecision {
        sub_texel_bits: 8,
        mipmap_bits: 4,
    };
    for (options, precisions) in [
        (
            ModelOptions::default(),
            [FilterPrecision::SPEC_MINIMUM, precise],
        ),
        (
            ModelOptions::lavapipe(),
            [FilterPrecision::SPEC_MINIMUM, lavapipe_like],
        ),
    ] {
        let nominal = render_model(&frame, &options);
        for (rgba, bounds) in nominal.rgba.iter().zip(&nominal.bounds) {
            assert_eq!(*bounds, rgba.map(|v| [v, v]));
        }
        for precision in precisions {
            let image = render_model(
                &frame,
                &ModelOptions {
                    precision: Some(precision),
                    ..options
                },
            );
            // The same frame, the same nominal values; bounds around them.
            assert_eq!(image.rgba, nominal.rgba);
            let mut widths = Vec::new();
            for i in 0..image.rgba.len() {
                if image.exclusion[i].is_some() {
                    continue;
                }
                // Up to the f64 rounding of two evaluation orders.
                assert!(image.distance_outside_bounds(i, image.rgba[i]) < 1e-12);
                let width = image.bounds[i]
                    .iter()
                    .map(|[lo, hi]| hi - lo)
                    .fold(0.0, f64::max);
                if image.lens_mask[i] {
                    widths.push(width);
                } else {
                    assert_eq!(width, 0.0, "environment pixels are exact");
                }
            }
            widths.sort_by(f64::total_cmp);
            let median = widths[widths.len() / 2];
            eprintln!(
                "{:?} {precision:?}: lens interval width median {median:.2e}, largest {:.2e}",
                options.lod_log2,
                widths.last().unwrap()
            );
            assert!(median > 0.0);
            // α stays a coverage: its bounds lie in [0, 1].
            for bounds in &image.bounds {
                assert!(0.0 <= bounds[3][0] && bounds[3][1] <= 1.0 + 1e-12);
            }
        }
    }
    // A 1 is exact in any order of arithmetic: the helper reports distances, 0 inside.
    let image = render_model(&frame, &ModelOptions::default());
    let i = image.index(32, 32);
    let mut outside = image.rgba[i];
    outside[2] += 0.25;
    assert!((image.distance_outside_bounds(i, outside) - 0.25).abs() < 1e-12);
    assert_eq!(image.distance_outside_bounds(i, image.rgba[i]), 0.0);
    assert_eq!(
        image.distance_outside_bounds(i, [f64::NAN; 4]),
        f64::INFINITY
    );
}

#[test]
fn light_map_bounds_hold_the_bilinear_sample() {
    let mut rng = Pcg64::seed_from_u64(15);
    let map = LightMap {
        width: 5,
        height: 3,
        texels: (0..15)
            .map(|_| {
                [
                    rng.gen_range(0.0f32..4.0),
                    0.5,
                    rng.gen_range(0.0f32..1.0),
                    1.0,
                ]
            })
            .map(|t| t.map(half::f16::from_f32))
            .collect(),
    };
    for _ in 0..500 {
        let uv = DVec2::new(rng.gen_range(-0.2..1.2), rng.gen_range(-0.2..1.2));
        let nominal = map.sample_bilinear(uv);
        let bounds = light_map_bounds(&map, uv, FilterPrecision::SPEC_MINIMUM);
        for c in 0..3 {
            assert!(bounds[c][0] - 1e-12 <= nominal[c] && nominal[c] <= bounds[c][1] + 1e-12);
        }
        // A uniform channel stays a point.
        assert!((bounds[1][0] - 0.5).abs() < 1e-12 && (bounds[1][1] - 0.5).abs() < 1e-12);
    }
}

#[test]
fn interval_blend_contains_every_blend_of_its_members() {
    let mut rng = Pcg64::seed_from_u64(14);
    let interval = |rng: &mut Pcg64, lo: f64, hi: f64| {
        let (a, b) = (rng.gen_range(lo..hi), rng.gen_range(lo..hi));
        [a.min(b), a.max(b)]
    };
    for _ in 0..2000 {
        // Mostly premultiplied values in [0, 1]; sometimes beyond, for the general product.
        let (lo, hi) = if rng.gen_bool(0.7) {
            (0.0, 1.0)
        } else {
            (-0.5, 1.5)
        };
        let dst: [Interval; 4] = std::array::from_fn(|_| interval(&mut rng, lo, hi));
        let src: [Interval; 4] = std::array::from_fn(|_| interval(&mut rng, lo, hi));
        let out = blend_front_to_back_bounds(dst, src);
        for _ in 0..20 {
            let pick = |i: Interval, rng: &mut Pcg64| i[0] + (i[1] - i[0]) * rng.r#gen::<f64>();
            let d: [f64; 4] = std::array::from_fn(|c| pick(dst[c], &mut rng));
            let s: [f64; 4] = std::array::from_fn(|c| pick(src[c], &mut rng));
            let blended = blend_front_to_back(d, s);
            for c in 0..4 {
                assert!(out[c][0] - 1e-12 <= blended[c] && blended[c] <= out[c][1] + 1e-12);
            }
        }
    }
}

#[test]
fn random_sphere_frame_keeps_most_lens_pixels_comparable() {
    let mut rng = Pcg64::seed_from_u64(12);
    for (layer_count, viewpoints) in [(1, 1), (4, 2), (2, 3)] {
        let frame = random_sphere_frame(&mut rng, 128, 16, layer_count, viewpoints);
        for options in [ModelOptions::default(), ModelOptions::lavapipe()] {
            let image = render_model(&frame, &options);
            let lens = image.lens_mask.iter().filter(|&&m| m).count();
            let comparable = image.comparable_lens_pixels();
            eprintln!(
                "n={layer_count} viewpoints={viewpoints} {:?}: {comparable}/{lens} lens \
                 pixels comparable; excluded {:?}",
                options.lod_log2,
                image.exclusion_counts()
            );
            assert!(lens > 1500, "{lens}");
            assert!(comparable as f64 > 0.9 * lens as f64);
            // Lens pixels hold finite premultiplied values: α ∈ [0, 1].
            for (rgba, _) in image.rgba.iter().zip(&image.lens_mask).filter(|(_, m)| **m) {
                assert!(rgba.iter().all(|v| v.is_finite()));
                assert!((0.0..=1.0).contains(&rgba[3]));
            }
            // Deterministic.
            assert_eq!(render_model(&frame, &options), image);
        }
    }
}
