//! Geometric invariants of an adaptive tessellation, checked independently of the tessellator's
//! bookkeeping (for the CPU tessellator's tests and the GPU's alike): watertight (interior edges
//! shared by exactly two oppositely wound triangles; the output's boundary covers exactly the
//! input's boundary), no vertex strictly inside an edge, area preserved to 1e-5 relative,
//! triangles on and wound like their source triangles.

use std::collections::{HashMap, HashSet};

use glam::{DVec3, Vec3};
use lensmap::hybrid::tessellate::{Tessellation, VertexOrigin};
use lensmap::scene::TriangleMesh;

/// `p` in f64.
pub fn to_f64(p: Vec3) -> DVec3 {
    p.as_dvec3()
}

/// Twice the vector area of triangle `tri` of `mesh`.
pub fn area2(mesh: &TriangleMesh, tri: [u32; 3]) -> DVec3 {
    let [a, b, c] = tri.map(|i| to_f64(mesh.positions[i as usize]));
    (b - a).cross(c - a)
}

/// The summed area of `mesh`'s triangles.
pub fn total_area(mesh: &TriangleMesh) -> f64 {
    mesh.triangles
        .iter()
        .map(|&t| 0.5 * area2(mesh, t).length())
        .sum()
}

/// Undirected edge → (uses, directed uses a→b with a < b).
pub fn edge_uses(triangles: &[[u32; 3]]) -> HashMap<(u32, u32), (u32, u32)> {
    let mut edges: HashMap<(u32, u32), (u32, u32)> = HashMap::new();
    for tri in triangles {
        for i in 0..3 {
            let (a, b) = (tri[i], tri[(i + 1) % 3]);
            let entry = edges.entry((a.min(b), a.max(b))).or_default();
            entry.0 += 1;
            entry.1 += u32::from(a < b);
        }
    }
    edges
}

/// Connected components of the input (vertices joined by triangles), as a component per vertex.
pub fn components(mesh: &TriangleMesh) -> Vec<u32> {
    let mut parent: Vec<u32> = (0..mesh.positions.len() as u32).collect();
    fn find(parent: &mut [u32], mut x: u32) -> u32 {
        while parent[x as usize] != x {
            parent[x as usize] = parent[parent[x as usize] as usize];
            x = parent[x as usize];
        }
        x
    }
    for tri in &mesh.triangles {
        for i in 1..3 {
            let (a, b) = (find(&mut parent, tri[0]), find(&mut parent, tri[i]));
            parent[a as usize] = b;
        }
    }
    (0..mesh.positions.len() as u32)
        .map(|v| find(&mut parent, v))
        .collect()
}

/// Pairs (vertex, edge) of the same component where the vertex lies strictly inside the edge
/// (closer than 1e-5 of the edge's length to it, away from its ends). A uniform grid over the
/// vertices keeps this near-linear.
pub fn t_junctions(mesh: &TriangleMesh, component: &[u32]) -> Vec<(u32, (u32, u32))> {
    let used: HashSet<u32> = mesh.triangles.iter().flatten().copied().collect();
    let Some((lo, hi)) = mesh.bounds() else {
        return Vec::new();
    };
    let cells = 64.0;
    let size = ((hi - lo).max_element() / cells).max(1e-6);
    let key = |p: Vec3| ((p - lo) / size).floor().as_ivec3();
    let mut grid: HashMap<glam::IVec3, Vec<u32>> = HashMap::new();
    for &v in &used {
        grid.entry(key(mesh.positions[v as usize]))
            .or_default()
            .push(v);
    }
    let mut found = Vec::new();
    for &(a, b) in edge_uses(&mesh.triangles).keys() {
        let (p, q) = (mesh.positions[a as usize], mesh.positions[b as usize]);
        let (klo, khi) = (key(p.min(q)), key(p.max(q)));
        let (pd, qd) = (to_f64(p), to_f64(q));
        let length = (qd - pd).length();
        for x in klo.x..=khi.x {
            for y in klo.y..=khi.y {
                for z in klo.z..=khi.z {
                    for &v in grid.get(&glam::IVec3::new(x, y, z)).into_iter().flatten() {
                        if v == a || v == b || component[v as usize] != component[a as usize] {
                            continue;
                        }
                        let r = to_f64(mesh.positions[v as usize]);
                        let s = (r - pd).dot(qd - pd) / (length * length);
                        let distance = (r - (pd + (qd - pd) * s)).length();
                        if s > 1e-6 && s < 1.0 - 1e-6 && distance < 1e-5 * length {
                            found.push((v, (a, b)));
                        }
                    }
                }
            }
        }
    }
    found
}

/// Distance from `r` to segment pq.
pub fn segment_distance(r: DVec3, p: DVec3, q: DVec3) -> f64 {
    let s = ((r - p).dot(q - p) / (q - p).length_squared()).clamp(0.0, 1.0);
    (r - (p + (q - p) * s)).length()
}

/// Checks the invariants of `out`, the tessellation of `input`, and returns each output vertex's
/// connected part of the input (a vertex's component).
pub fn check_surface<S>(case: &str, input: &TriangleMesh, out: &Tessellation<S>) -> Vec<u32> {
    let mesh = &out.mesh;
    // Watertight: interior edges shared by exactly two oppositely wound triangles; boundary
    // edges (used once) lie on the input's boundary, wound the same way, and cover it exactly.
    let input_edges = edge_uses(&input.triangles);
    assert!(
        input_edges
            .values()
            .all(|&(uses, forward)| uses == 1 || (uses == 2 && forward == 1)),
        "{case}: the test needs an oriented manifold input"
    );
    let input_boundary: Vec<(u32, u32)> = input
        .triangles
        .iter()
        .flat_map(|tri| (0..3).map(move |i| (tri[i], tri[(i + 1) % 3])))
        .filter(|&(a, b)| input_edges[&(a.min(b), a.max(b))].0 == 1)
        .collect();
    let mut boundary_length = 0.0;
    for (&(a, b), &(uses, forward)) in &edge_uses(&mesh.triangles) {
        assert!(
            uses == 1 || uses == 2,
            "{case}: edge {a}-{b} used {uses} times"
        );
        if uses == 2 {
            assert_eq!(forward, 1, "{case}: edge {a}-{b} wound the same way twice");
            continue;
        }
        let (from, to) = if forward == 1 { (a, b) } else { (b, a) };
        let (p, q) = (
            to_f64(mesh.positions[from as usize]),
            to_f64(mesh.positions[to as usize]),
        );
        let on_input_boundary = input_boundary.iter().any(|&(ia, ib)| {
            let (ip, iq) = (
                to_f64(input.positions[ia as usize]),
                to_f64(input.positions[ib as usize]),
            );
            let tolerance = 1e-6 * (iq - ip).length();
            segment_distance(p, ip, iq) < tolerance
                && segment_distance(q, ip, iq) < tolerance
                && (q - p).dot(iq - ip) > 0.0
        });
        assert!(
            on_input_boundary,
            "{case}: open edge {from}-{to} inside the mesh"
        );
        boundary_length += (q - p).length();
    }
    let input_boundary_length: f64 = input_boundary
        .iter()
        .map(|&(a, b)| {
            (to_f64(input.positions[a as usize]) - to_f64(input.positions[b as usize])).length()
        })
        .sum();
    assert!(
        (boundary_length - input_boundary_length).abs() <= 1e-5 * input_boundary_length.max(1.0),
        "{case}: boundary length {boundary_length} vs the input's {input_boundary_length}"
    );

    // No T-junctions (within each connected part of the input).
    let input_component = components(input);
    let component: Vec<u32> = out
        .origins
        .iter()
        .scan(Vec::<u32>::new(), |so_far, origin| {
            let c = match *origin {
                VertexOrigin::Input(i) => input_component[i as usize],
                VertexOrigin::Midpoint([u, _]) => so_far[u as usize],
            };
            so_far.push(c);
            Some(c)
        })
        .collect();
    let junctions = t_junctions(mesh, &component);
    assert!(
        junctions.is_empty(),
        "{case}: T-junctions {:?}",
        &junctions[..junctions.len().min(5)]
    );

    // Area preserved, and every triangle lies on its source triangle, wound the same way and
    // not degenerate.
    let (input_area, output_area) = (total_area(input), total_area(mesh));
    assert!(
        (output_area - input_area).abs() <= 1e-5 * input_area,
        "{case}: area {output_area} vs {input_area}"
    );
    for (tri, record) in mesh.triangles.iter().zip(&out.triangles) {
        let source = input.triangles[record.source as usize];
        let source_normal = area2(input, source);
        let normal = area2(mesh, *tri);
        assert!(
            normal.dot(source_normal) > 0.0,
            "{case}: triangle {tri:?} flipped or flat"
        );
        let origin = to_f64(input.positions[source[0] as usize]);
        let unit = source_normal.normalize();
        for v in tri {
            let off = (to_f64(mesh.positions[*v as usize]) - origin)
                .dot(unit)
                .abs();
            assert!(
                off < 1e-5,
                "{case}: vertex {v} is {off} off its source plane"
            );
        }
    }

    component
}

/// Where an output vertex lies on the input mesh, combinatorially.
#[derive(Clone, Copy, PartialEq)]
enum Carrier {
    /// The input vertex.
    Vertex(u32),
    /// Inside the input edge (smaller index first).
    Edge(u32, u32),
    /// Inside an input triangle.
    Face,
}

/// The input edge both carriers lie on, if any.
fn common_edge(
    a: Carrier,
    b: Carrier,
    input_edges: &HashMap<(u32, u32), (u32, u32)>,
) -> Option<(u32, u32)> {
    let edge = |u: u32, w: u32| {
        let key = (u.min(w), u.max(w));
        input_edges.contains_key(&key).then_some(key)
    };
    match (a, b) {
        (Carrier::Vertex(u), Carrier::Vertex(w)) => edge(u, w),
        (Carrier::Edge(u, w), Carrier::Vertex(v)) | (Carrier::Vertex(v), Carrier::Edge(u, w)) => {
            (v == u || v == w).then_some((u, w))
        }
        (Carrier::Edge(u, w), Carrier::Edge(x, y)) => ((u, w) == (x, y)).then_some((u, w)),
        _ => None,
    }
}

/// The combinatorial form of [`check_surface`]'s watertightness, exact and valid for meshes with
/// seams (coincident vertices under different indices, where the geometric T-junction check
/// cannot tell a seam from a crack): every output edge is used by one triangle or by two wound
/// oppositely; one used once lies on an input edge used once (the input's boundary or seam);
/// no output edge has a midpoint (the T-junction a finer neighbour would leave); and the area is
/// preserved to 1e-5 relative.
pub fn check_topology<S>(case: &str, input: &TriangleMesh, out: &Tessellation<S>) {
    let input_edges = edge_uses(&input.triangles);
    let mut carriers: Vec<Carrier> = Vec::with_capacity(out.origins.len());
    let mut midpoints = HashSet::new();
    for origin in &out.origins {
        let carrier = match *origin {
            VertexOrigin::Input(i) => Carrier::Vertex(i),
            VertexOrigin::Midpoint([u, w]) => {
                midpoints.insert((u.min(w), u.max(w)));
                match common_edge(carriers[u as usize], carriers[w as usize], &input_edges) {
                    Some((x, y)) => Carrier::Edge(x, y),
                    None => Carrier::Face,
                }
            }
        };
        carriers.push(carrier);
    }
    for (&(a, b), &(uses, forward)) in &edge_uses(&out.mesh.triangles) {
        assert!(
            uses == 1 || (uses == 2 && forward == 1),
            "{case}: edge {a}-{b} used {uses} times, {forward} of them from the lower index"
        );
        assert!(
            !midpoints.contains(&(a, b)),
            "{case}: edge {a}-{b} has a midpoint: a T-junction"
        );
        if uses == 1 {
            let on = common_edge(carriers[a as usize], carriers[b as usize], &input_edges);
            assert!(
                on.is_some_and(|e| input_edges[&e].0 == 1),
                "{case}: open edge {a}-{b} inside the mesh"
            );
        }
    }
    let (input_area, output_area) = (total_area(input), total_area(&out.mesh));
    assert!(
        (output_area - input_area).abs() <= 1e-5 * input_area,
        "{case}: area {output_area} vs {input_area}"
    );
}
