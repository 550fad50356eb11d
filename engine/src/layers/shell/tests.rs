//! Shell intersections against closed forms, and random rays checked against each shell's
//! implicit surface equation written out here independently of the intersection code.

use glam::{DVec2, DVec3};
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64;

use super::*;

/// Relative tolerance of "on the surface" and "along the ray".
const RELATIVE: f64 = 1e-9;

fn close(a: f64, b: f64, scale: f64) -> bool {
    (a - b).abs() <= RELATIVE * scale.max(1.0)
}

fn assert_point(actual: DVec3, expected: DVec3, scale: f64) {
    assert!(
        (actual - expected).length() <= RELATIVE * scale.max(1.0),
        "{actual} != {expected}"
    );
}

fn hit(shell: &LayerShell, origin: DVec3, direction: DVec3) -> ShellHit {
    shell
        .intersect(origin, direction)
        .unwrap_or_else(|| panic!("{shell:?} missed from {origin} along {direction}"))
}

fn sphere() -> LayerShell {
    LayerShell::Sphere {
        centre: DVec3::new(1.0, -2.0, 0.5),
        radius: 3.0,
    }
}

fn unit_direction(rng: &mut Pcg64) -> DVec3 {
    loop {
        let v = DVec3::new(
            rng.gen_range(-1.0..1.0),
            rng.gen_range(-1.0..1.0),
            rng.gen_range(-1.0..1.0),
        );
        if (0.01..=1.0).contains(&v.length_squared()) {
            return v.normalize();
        }
    }
}

// ---------------------------------------------------------------- sphere

#[test]
fn sphere_from_inside_returns_the_exit() {
    let s = sphere();
    let c = s.centre();
    // From the centre: t = r along a unit direction, t = r/|d| along any.
    let d = DVec3::new(0.3, -0.4, 0.5);
    let h = hit(&s, c, d);
    assert!(close(h.t, 3.0 / d.length(), 3.0));
    assert_point(h.point, c + 3.0 * d.normalize(), 3.0);
    assert!(!h.forced);
    // Off centre by 0.9 along x: 2.1 forward, 3.9 backward, √(9 − 0.81) sideways.
    let o = c + DVec3::new(0.9, 0.0, 0.0);
    assert!(close(hit(&s, o, DVec3::X).t, 2.1, 3.0));
    assert!(close(hit(&s, o, DVec3::NEG_X).t, 3.9, 3.0));
    assert!(close(hit(&s, o, DVec3::Y).t, (9.0f64 - 0.81).sqrt(), 3.0));
}

#[test]
fn sphere_from_outside_returns_the_first_hit_in_front() {
    let s = sphere();
    let c = s.centre();
    let o = c + DVec3::new(-10.0, 0.0, 0.0);
    let h = hit(&s, o, DVec3::X);
    assert!(close(h.t, 7.0, 10.0));
    assert_point(h.point, c - DVec3::new(3.0, 0.0, 0.0), 10.0);
    // Offset by 1.8 in y: enters at x = −√(9 − 3.24).
    let h = hit(&s, o + DVec3::new(0.0, 1.8, 0.0), DVec3::X);
    assert!(close(h.t, 10.0 - (9.0f64 - 3.24).sqrt(), 10.0));
    // Pointing away, or passing by.
    assert_eq!(s.intersect(o, DVec3::NEG_X), None);
    assert_eq!(s.intersect(o + DVec3::new(0.0, 3.01, 0.0), DVec3::X), None);
}

#[test]
fn sphere_tangent_and_on_surface_rays() {
    let s = sphere();
    let c = s.centre();
    // Exactly tangent from outside: touches at c + 3y.
    let h = hit(&s, c + DVec3::new(-7.0, 3.0, 0.0), DVec3::X);
    assert_point(h.point, c + DVec3::new(0.0, 3.0, 0.0), 7.0);
    assert!(close(h.t, 7.0, 7.0));
    // On the surface heading out (t = 0), along it (t = 0), and in (exits opposite).
    let top = c + DVec3::new(0.0, 3.0, 0.0);
    assert_eq!(hit(&s, top, DVec3::Y).t, 0.0);
    assert_eq!(hit(&s, top, DVec3::X).t, 0.0);
    let h = hit(&s, top, DVec3::NEG_Y);
    assert!(close(h.t, 6.0, 3.0));
    assert_point(h.point, c - DVec3::new(0.0, 3.0, 0.0), 3.0);
    // Grazing just outside and just inside the tangent: no NaN, a miss or two close hits.
    for offset in [3.0 - 1e-12, 3.0, 3.0 + 1e-12, 3.0 + 1e-300] {
        if let Some(h) = s.intersect(c + DVec3::new(-7.0, offset, 0.0), DVec3::X) {
            assert!(h.point.is_finite() && h.t.is_finite());
            assert!((h.point - (c + DVec3::new(0.0, 3.0, 0.0))).length() < 1e-5);
        }
    }
}

#[test]
fn degenerate_rays_return_none() {
    let s = sphere();
    assert_eq!(s.intersect(DVec3::ZERO, DVec3::ZERO), None);
    assert_eq!(s.intersect(DVec3::NAN, DVec3::X), None);
    assert_eq!(
        s.intersect(DVec3::ZERO, DVec3::new(f64::INFINITY, 0.0, 0.0)),
        None
    );
}

// ---------------------------------------------------------------- cylinder

fn cylinder(half_height: Option<f64>) -> LayerShell {
    LayerShell::Cylinder {
        centre: DVec3::new(0.5, 1.0, -1.0),
        axis: DVec3::new(1.0, 2.0, 2.0) / 3.0,
        radius: 2.0,
        half_height,
    }
}

/// `(axis, two unit vectors orthogonal to it)` of [`cylinder`].
fn cylinder_frame() -> (DVec3, DVec3, DVec3) {
    let axis = DVec3::new(1.0, 2.0, 2.0) / 3.0;
    let (p, q) = axis.any_orthonormal_pair();
    (axis, p, q)
}

#[test]
fn infinite_cylinder_closed_forms() {
    let s = cylinder(None);
    let c = s.centre();
    let (axis, p, q) = cylinder_frame();
    // From the axis along (0.6 p + 0.8 axis): radial speed 0.6 → t = 2/0.6.
    let d = 0.6 * p + 0.8 * axis;
    let h = hit(&s, c, d);
    assert!(close(h.t, 2.0 / 0.6, 4.0));
    assert_point(h.point, c + (2.0 / 0.6) * d, 4.0);
    // Off axis by 1 along q, heading along p: exits after √(4 − 1).
    assert!(close(hit(&s, c + q, p).t, 3.0f64.sqrt(), 2.0));
    // From outside at 5 along p heading back: enters at radius 2 → t = 3.
    let h = hit(&s, c + 5.0 * p + 7.0 * axis, -p);
    assert!(close(h.t, 3.0, 10.0));
    // Tangent from outside (tilted axis: rounding decides touch or miss, never NaN).
    if let Some(h) = s.intersect(c + 2.0 * q - 6.0 * p, p) {
        assert!((h.point - (c + 2.0 * q)).length() < 1e-6);
    }
    // Tangent, exactly representable (axis y): touches at x = 2.
    let upright = LayerShell::Cylinder {
        centre: DVec3::new(1.0, 0.0, 0.0),
        axis: DVec3::Y,
        radius: 2.0,
        half_height: None,
    };
    let h = hit(&upright, DVec3::new(3.0, 5.0, -6.0), DVec3::Z);
    assert_point(h.point, DVec3::new(3.0, 5.0, 0.0), 6.0);
    assert!(close(h.t, 6.0, 6.0));
    // Along the axis, inside: never leaves → None, and the texture direction is the ray's.
    assert_eq!(s.intersect(c + 0.5 * p, axis), None);
    assert_eq!(s.texture_direction_for_ray(c, c + 0.5 * p, axis), axis);
    // Parallel to the axis outside: misses.
    assert_eq!(s.intersect(c + 3.0 * p, axis), None);
}

#[test]
fn capped_cylinder_closed_forms() {
    let s = cylinder(Some(1.5));
    let c = s.centre();
    let (axis, p, q) = cylinder_frame();
    // Along the axis from the centre: the cap at t = 1.5.
    let h = hit(&s, c, axis);
    assert!(close(h.t, 1.5, 2.0));
    assert_point(h.point, c + 1.5 * axis, 2.0);
    // Mixed directions: t = min(r/|radial|, h/|along|), side or cap.
    for (radial, along) in [(0.6, 0.8), (0.8, 0.6), (0.8, -0.6), (0.96, 0.28)] {
        let d = radial * q + along * axis;
        let expected = f64::min(2.0 / radial, 1.5 / f64::abs(along));
        assert!(close(hit(&s, c, d).t, expected, 3.0), "{radial} {along}");
    }
    // From outside above the cap heading down: enters through the top cap.
    let h = hit(&s, c + 0.5 * p + 4.0 * axis, -axis);
    assert!(close(h.t, 2.5, 5.0));
    assert_point(h.point, c + 0.5 * p + 1.5 * axis, 5.0);
    // Outside beside it, parallel to the axis: misses; beyond the cap heading away: misses.
    assert_eq!(s.intersect(c + 2.5 * p, axis), None);
    assert_eq!(s.intersect(c + 2.0 * axis, axis), None);
    // Grazing the rim exactly (the side's tangent line at the cap height): touches.
    let capped = LayerShell::Cylinder {
        centre: DVec3::ZERO,
        axis: DVec3::Y,
        radius: 2.0,
        half_height: Some(1.5),
    };
    let h = hit(&capped, DVec3::new(2.0, 1.5, -5.0), DVec3::Z);
    assert_point(h.point, DVec3::new(2.0, 1.5, 0.0), 5.0);
    // Tilted: touch or miss by rounding, never NaN.
    let rim = c + 2.0 * q + 1.5 * axis;
    if let Some(h) = s.intersect(rim - 5.0 * p, p) {
        assert!((h.point - rim).length() < 1e-6);
    }
}

// ---------------------------------------------------------------- box

fn boxed() -> LayerShell {
    LayerShell::Box {
        centre: DVec3::new(-1.0, 0.5, 2.0),
        half_extents: DVec3::new(4.0, 2.5, 3.0),
    }
}

#[test]
fn box_closed_forms() {
    let s = boxed();
    let c = s.centre();
    let h_ = DVec3::new(4.0, 2.5, 3.0);
    // From the centre: t = min_i h_i / |d_i|.
    for d in [
        DVec3::new(1.0, 0.2, -0.3),
        DVec3::new(-0.1, 1.0, 0.5),
        DVec3::new(0.5, -0.5, -0.9),
    ] {
        let expected = (h_ / d.abs()).min_element();
        let h = hit(&s, c, d);
        assert!(close(h.t, expected, 5.0), "{d}");
    }
    // Off centre along an axis: 4 − 1 forward.
    assert!(close(hit(&s, c + DVec3::X, DVec3::X).t, 3.0, 4.0));
    // From outside: enters the −x face at t = 10 − 4.
    let h = hit(&s, c - DVec3::new(10.0, 0.5, 0.5), DVec3::X);
    assert!(close(h.t, 6.0, 10.0));
    assert_point(h.point, c - DVec3::new(4.0, 0.5, 0.5), 10.0);
    // Grazing along the top face (y = +h_y, parallel): enters its edge at x = −h_x.
    let h = hit(&s, c + DVec3::new(-10.0, 2.5, 0.0), DVec3::X);
    assert_point(h.point, c + DVec3::new(-4.0, 2.5, 0.0), 10.0);
    // Parallel just above the top face: misses. Towards a corner exactly: hits the corner.
    assert_eq!(
        s.intersect(c + DVec3::new(-10.0, 2.5 + 1e-9, 0.0), DVec3::X),
        None
    );
    let corner = c + h_;
    let h = hit(&s, corner + DVec3::splat(2.0), DVec3::splat(-1.0));
    assert_point(h.point, corner, 10.0);
    // On a face heading out: t = 0.
    assert_eq!(hit(&s, c + DVec3::new(4.0, 0.0, 0.0), DVec3::X).t, 0.0);
}

// ---------------------------------------------------------------- ellipsoid

fn ellipsoid() -> LayerShell {
    LayerShell::Ellipsoid {
        centre: DVec3::new(0.0, 1.0, 0.0),
        radii: DVec3::new(5.0, 2.0, 3.0),
    }
}

#[test]
fn ellipsoid_closed_forms() {
    let s = ellipsoid();
    let c = s.centre();
    let r = DVec3::new(5.0, 2.0, 3.0);
    // From the centre: t = 1 / |d / r|.
    for d in [DVec3::X, DVec3::NEG_Y, DVec3::Z, DVec3::new(0.3, 0.4, -0.5)] {
        let expected = 1.0 / (d / r).length();
        let h = hit(&s, c, d);
        assert!(close(h.t, expected, 5.0), "{d}");
        assert!(close(((h.point - c) / r).length(), 1.0, 1.0));
    }
    // From outside along x: enters at x = −5.
    let h = hit(&s, c - DVec3::new(12.0, 0.0, 0.0), DVec3::X);
    assert!(close(h.t, 7.0, 12.0));
    // Tangent at the top (y = +2): touches.
    let h = hit(&s, c + DVec3::new(-9.0, 2.0, 0.0), DVec3::X);
    assert_point(h.point, c + DVec3::new(0.0, 2.0, 0.0), 9.0);
    // Just above the top: misses.
    assert_eq!(
        s.intersect(c + DVec3::new(-9.0, 2.0 + 1e-9, 0.0), DVec3::X),
        None
    );
    // A sphere-shaped ellipsoid agrees with the sphere.
    let round = LayerShell::Ellipsoid {
        centre: DVec3::ZERO,
        radii: DVec3::splat(3.0),
    };
    let ball = LayerShell::Sphere {
        centre: DVec3::ZERO,
        radius: 3.0,
    };
    let (o, d) = (DVec3::new(0.4, -0.2, 1.0), DVec3::new(-0.3, 0.9, 0.2));
    assert_point(hit(&round, o, d).point, hit(&ball, o, d).point, 3.0);
}

// ---------------------------------------------------------------- quad

fn quad() -> LayerShell {
    LayerShell::Quad {
        centre: DVec3::new(0.0, 0.0, -4.0),
        normal: DVec3::Z,
        u_axis: DVec3::X,
        v_axis: DVec3::Y,
        half_extents: DVec2::new(2.0, 1.0),
    }
}

fn far_distance() -> f64 {
    QUAD_FORCED_DISTANCE_FACTOR * DVec2::new(2.0, 1.0).length()
}

#[test]
fn quad_hits_its_plane_where_the_ray_meets_it() {
    let s = quad();
    let o = DVec3::new(0.3, 0.2, 0.0);
    // Towards the plane z = −4: t = 4 / |d_z|, inside or outside the rectangle alike.
    for d in [
        DVec3::new(0.1, 0.05, -1.0),
        DVec3::new(2.0, -1.0, -0.5),
        DVec3::new(0.0, 0.0, -2.0),
    ] {
        let h = hit(&s, o, d);
        assert!(!h.forced);
        assert!(close(h.t, 4.0 / -d.z, 10.0));
        assert_point(h.point, o + (4.0 / -d.z) * d, 10.0);
    }
    // The normal's sign does not matter.
    let flipped = LayerShell::Quad {
        centre: DVec3::new(0.0, 0.0, -4.0),
        normal: DVec3::NEG_Z,
        u_axis: DVec3::X,
        v_axis: DVec3::NEG_Y,
        half_extents: DVec2::new(2.0, 1.0),
    };
    let d = DVec3::new(0.2, 0.3, -1.0);
    assert_eq!(hit(&flipped, o, d), hit(&s, o, d));
    // From the far side of the plane, towards it.
    let h = hit(&s, DVec3::new(1.0, 1.0, -6.0), DVec3::new(0.0, 0.0, 1.0));
    assert_point(h.point, DVec3::new(1.0, 1.0, -4.0), 6.0);
}

#[test]
fn quad_forces_rays_that_miss_far_along_their_tangential_direction() {
    let s = quad();
    let c = s.centre();
    let far = far_distance();
    let o = DVec3::new(0.3, 0.2, 0.0);
    // Pointing away (+z) and parallel: the point is on the plane at distance R from the centre,
    // in the direction of the ray's tangential component.
    for d in [
        DVec3::new(1.0, 0.5, 0.3),
        DVec3::new(-0.2, 1.0, 2.0),
        DVec3::new(1.0, -1.0, 0.0),
    ] {
        let h = hit(&s, o, d);
        assert!(h.forced, "{d}");
        assert!(h.point.is_finite() && h.t.is_finite() && h.t > 0.0);
        assert!(close(h.point.z, -4.0, far));
        assert!(close((h.point - c).length(), far, far));
        let tangential = DVec3::new(d.x, d.y, 0.0).normalize();
        assert_point(h.point, c + far * tangential, far);
        assert!(close(h.t, (h.point - o).length() / d.length(), far));
    }
    // Straight away along the normal: no tangential direction → centre + R·u_axis.
    let h = hit(&s, o, DVec3::Z);
    assert!(h.forced);
    assert_point(h.point, c + far * DVec3::X, far);
    // Meeting the plane beyond R: pulled back to distance R, flagged.
    let d = DVec3::new(1.0, 0.0, -1e-5);
    let h = hit(&s, o, d);
    assert!(h.forced);
    assert!(close((h.point - c).length(), far, far));
    assert!(close(h.point.z, -4.0, far));
}

#[test]
fn quad_enforcement_is_continuous_across_the_horizon() {
    let s = quad();
    let c = s.centre();
    let far = far_distance();
    let o = DVec3::new(0.3, 0.2, 0.0);
    let em_origin = DVec3::new(0.0, 0.0, 0.5);
    let tangential = DVec3::new(0.6, 0.8, 0.0);
    // Just towards the plane and just away from it: both land near centre + R·û.
    let toward = hit(&s, o, tangential - 1e-12 * DVec3::Z);
    let away = hit(&s, o, tangential + 1e-12 * DVec3::Z);
    assert!(toward.forced && away.forced);
    assert!((toward.point - away.point).length() <= 1e-6 * far);
    assert!((away.point - (c + far * tangential)).length() <= 1e-9 * far);
    // Sweep the elevation through the horizon in steps of 1e-6 rad: the cube-map direction seen
    // from the EM origin never jumps by more than 1e-3 rad (it moves through ≈ 0.2 rad in all).
    let mut previous: Option<DVec3> = None;
    let mut forced_count = 0;
    let mut max_step = 0.0f64;
    for i in -2000..=2000 {
        let elevation = f64::from(i) * 1e-6 - 1e-4;
        let d = elevation.cos() * tangential + elevation.sin() * DVec3::Z;
        let h = hit(&s, o, d);
        forced_count += usize::from(h.forced);
        let direction = s.texture_direction(em_origin, h.point);
        if let Some(p) = previous {
            max_step = max_step.max(p.angle_between(direction));
        }
        previous = Some(direction);
    }
    assert!(forced_count > 2000 && forced_count < 4001, "{forced_count}");
    assert!(max_step < 1e-3, "largest step {max_step} rad");
}

// ---------------------------------------------------------------- random rays, every shell

/// The implicit surface residual of each closed shell, written from its definition, in metres-ish
/// units of the shell's size: 0 on the surface, < 0 inside, > 0 outside.
fn residual(shell: &LayerShell, p: DVec3) -> f64 {
    match *shell {
        LayerShell::Sphere { centre, radius } => (p - centre).length() / radius - 1.0,
        LayerShell::Ellipsoid { centre, radii } => ((p - centre) / radii).length() - 1.0,
        LayerShell::Box {
            centre,
            half_extents,
        } => ((p - centre).abs() / half_extents).max_element() - 1.0,
        LayerShell::Cylinder {
            centre,
            axis,
            radius,
            half_height,
        } => {
            let v = p - centre;
            let along = v.dot(axis);
            let radial = (v - along * axis).length() / radius - 1.0;
            match half_height {
                None => radial,
                Some(h) => radial.max(along.abs() / h - 1.0),
            }
        }
        LayerShell::Quad { centre, normal, .. } => (p - centre).dot(normal),
    }
}

fn every_closed_shell() -> Vec<LayerShell> {
    vec![
        sphere(),
        cylinder(None),
        cylinder(Some(1.5)),
        boxed(),
        ellipsoid(),
    ]
}

#[test]
fn random_rays_from_inside_exit_on_the_surface_along_the_ray() {
    let mut rng = Pcg64::seed_from_u64(41);
    for shell in every_closed_shell() {
        let c = shell.centre();
        let mut tested = 0;
        while tested < 2000 {
            let origin = c + 5.0 * DVec3::new(rng.r#gen(), rng.r#gen(), rng.r#gen()) - 2.5;
            if residual(&shell, origin) >= -1e-6 {
                continue;
            }
            tested += 1;
            let d = unit_direction(&mut rng) * rng.gen_range(0.1..10.0);
            let Some(h) = shell.intersect(origin, d) else {
                // Only a ray along an infinite cylinder's axis never leaves.
                assert!(matches!(
                    shell,
                    LayerShell::Cylinder {
                        half_height: None,
                        ..
                    }
                ));
                continue;
            };
            let scale = (h.point - c).length().max(1.0);
            assert!(!h.forced && h.t >= 0.0);
            assert!(residual(&shell, h.point).abs() <= RELATIVE, "{shell:?}");
            assert_point(h.point, origin + h.t * d, scale);
            // The exit: just before inside, just after outside.
            let step = 1e-6 / d.length();
            assert!(residual(&shell, origin + (h.t - step) * d) < 0.0);
            assert!(residual(&shell, origin + (h.t + step) * d) > 0.0);
        }
    }
}

#[test]
fn random_rays_from_outside_enter_at_the_first_hit_or_miss() {
    let mut rng = Pcg64::seed_from_u64(42);
    for shell in every_closed_shell() {
        let c = shell.centre();
        let (mut hits, mut misses) = (0, 0);
        while hits + misses < 2000 {
            let origin = c + 24.0 * DVec3::new(rng.r#gen(), rng.r#gen(), rng.r#gen()) - 12.0;
            if residual(&shell, origin) <= 1e-6 {
                continue;
            }
            // Aim near the shell so that about half the rays hit.
            let target = c + 14.0 * DVec3::new(rng.r#gen(), rng.r#gen(), rng.r#gen()) - 7.0;
            let d = (target - origin) * rng.gen_range(0.1..3.0);
            match shell.intersect(origin, d) {
                Some(h) => {
                    hits += 1;
                    let scale = (h.point - c).length().max(1.0);
                    assert!(!h.forced && h.t > 0.0);
                    assert!(residual(&shell, h.point).abs() <= RELATIVE, "{shell:?}");
                    assert_point(h.point, origin + h.t * d, scale);
                    // The first hit: every earlier point of the ray is outside.
                    for k in 0..64 {
                        let t = h.t * f64::from(k) / 64.0;
                        assert!(residual(&shell, origin + t * d) > -1e-12);
                    }
                }
                None => {
                    misses += 1;
                    for k in 0..256 {
                        let t = f64::from(k) * 0.25 / d.length();
                        assert!(residual(&shell, origin + t * d) > -1e-9, "{shell:?}");
                    }
                }
            }
        }
        assert!(hits > 200 && misses > 200, "{shell:?}: {hits} hits");
    }
}

#[test]
fn random_rays_meet_the_quad_on_its_plane() {
    let mut rng = Pcg64::seed_from_u64(43);
    let s = LayerShell::quad_facing(
        DVec3::new(1.0, 2.0, -3.0),
        DVec3::new(0.2, -0.3, 1.0),
        DVec2::new(1.5, 0.5),
    );
    s.validate().unwrap();
    let c = s.centre();
    let far = QUAD_FORCED_DISTANCE_FACTOR * DVec2::new(1.5, 0.5).length();
    let mut forced = 0;
    for _ in 0..4000 {
        let origin = c + 10.0 * DVec3::new(rng.r#gen(), rng.r#gen(), rng.r#gen()) - 5.0;
        let d = unit_direction(&mut rng) * rng.gen_range(0.1..10.0);
        let h = hit(&s, origin, d);
        assert!(h.point.is_finite() && h.t.is_finite() && h.t >= 0.0);
        let scale = (h.point - origin).length().max(1.0);
        assert!(residual(&s, h.point).abs() <= RELATIVE * scale);
        assert!((h.point - c).length() <= far * (1.0 + RELATIVE));
        if h.forced {
            forced += 1;
            assert!(close((h.point - c).length(), far, far));
        } else {
            assert_point(h.point, origin + h.t * d, scale);
        }
    }
    assert!(forced > 1000 && forced < 3000, "{forced}");
}

// ---------------------------------------------------------------- the rest

#[test]
fn texture_direction_is_hit_minus_em_origin() {
    let em_origin = DVec3::new(0.1, 0.2, 0.3);
    for shell in every_closed_shell().into_iter().chain([quad()]) {
        let h = hit(&shell, em_origin, DVec3::new(0.3, -0.2, -1.0));
        assert_eq!(
            shell.texture_direction(em_origin, h.point),
            h.point - em_origin
        );
        assert_eq!(
            shell.texture_direction_for_ray(em_origin, em_origin, DVec3::new(0.3, -0.2, -1.0)),
            h.point - em_origin
        );
    }
}

#[test]
fn validate_rejects_impossible_shells() {
    for shell in every_closed_shell().into_iter().chain([quad()]) {
        shell.validate().unwrap();
    }
    let bad = [
        (
            LayerShell::Sphere {
                centre: DVec3::ZERO,
                radius: 0.0,
            },
            "radius",
        ),
        (
            LayerShell::Sphere {
                centre: DVec3::new(f64::NAN, 0.0, 0.0),
                radius: 1.0,
            },
            "centre",
        ),
        (
            LayerShell::Cylinder {
                centre: DVec3::ZERO,
                axis: DVec3::new(0.0, 2.0, 0.0),
                radius: 1.0,
                half_height: None,
            },
            "axis",
        ),
        (
            LayerShell::Cylinder {
                centre: DVec3::ZERO,
                axis: DVec3::Y,
                radius: 1.0,
                half_height: Some(-1.0),
            },
            "half_height",
        ),
        (
            LayerShell::Box {
                centre: DVec3::ZERO,
                half_extents: DVec3::new(1.0, 0.0, 1.0),
            },
            "half_extents",
        ),
        (
            LayerShell::Ellipsoid {
                centre: DVec3::ZERO,
                radii: DVec3::new(1.0, 1.0, f64::INFINITY),
            },
            "radii",
        ),
        (
            LayerShell::Quad {
                centre: DVec3::ZERO,
                normal: DVec3::Z,
                u_axis: DVec3::X,
                v_axis: DVec3::new(0.6, 0.8, 0.0),
                half_extents: DVec2::ONE,
            },
            "v_axis",
        ),
    ];
    for (shell, field) in bad {
        let error = shell.validate().expect_err(field);
        assert_eq!(error.field, field, "{error}");
    }
}

#[test]
fn shells_serialize_tagged_by_kind() {
    let json = serde_json::to_string(&cylinder(None)).unwrap();
    assert!(
        json.starts_with(r#"{"kind":"cylinder","centre":[0.5,1.0,-1.0]"#),
        "{json}"
    );
    assert!(!json.contains("half_height"));
    for shell in every_closed_shell().into_iter().chain([quad()]) {
        let json = serde_json::to_string(&shell).unwrap();
        let back: LayerShell = serde_json::from_str(&json).unwrap();
        assert_eq!(back, shell);
    }
    let unknown = r#"{"kind":"sphere","centre":[0,0,0],"radius":1,"colour":2}"#;
    assert!(serde_json::from_str::<LayerShell>(unknown).is_err());
}
