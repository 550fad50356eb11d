// The hybrid frame's per-vertex work on the GPU (hybrid-rendering paper §5): the eye ray and the
// two greedy ray paths at each lens vertex, by the rules of the CPU oracle
// (engine/src/hybrid/paths.rs, engine/src/trace/path.rs) run in `real`: the visibility query
// against every part of the scene, Fresnel (exact, or Schlick through the 1D table), total
// internal reflection, attenuation `absorption^distance`, the interface cap.
//
// Shared by the two traversals, which each define `closest_hit(part, ray, max_t, exclude,
// tests)` and `part_count()` and bind set 0's bindings 0 and 3: tracer.wgsl walks a binary BVH
// per part with a stack, tracer_rq.wgsl asks the driver's acceleration structures with ray
// queries. Both test triangles with `intersect` and pick the winner with `consider`, so they
// find the same hits.
//
// The file that includes this one also sets the precision: `alias real = f32;` or `f64`, with
// `BARYCENTRIC_SLACK`, `ORIGIN_OFFSET` (the CPU's values in that precision) and `word(x)`, the
// u32 a triangle's `w` holds. Records, vertices, materials and the Schlick table are f32 either
// way; f64 costs the device `shaderFloat64`.

struct TracerConstants {
    // World → Vulkan clip space, for the screen positions the tessellation measures edges in.
    view_proj: mat4x4<f32>,
    eye: vec3<f32>,
    // The part (0: the environment, 1 + l: lens object l) the vertices belong to.
    part: u32,
    // Framebuffer size in subpixels.
    subpixels: vec2<f32>,
    // The scene object a vertex's synthetic hit (an occluded vertex) is on.
    object: u32,
    // The vertices this dispatch evaluates: [first_vertex, first_vertex + vertex_count).
    first_vertex: u32,
    vertex_count: u32,
    // 1: paths stop at the first interface (a lens object layered by bounce).
    first_bounce_only: u32,
    // Most interfaces one path may meet (the CPU's GreedyOptions::max_interfaces).
    max_interfaces: u32,
    // Texels of the Schlick table; 0: Fresnel evaluated exactly.
    schlick_texels: u32,
}

var<immediate> constants: TracerConstants;

// Triangles, seven vec4 each: (v0, object), e1, e2, the unit face normal (oriented like the
// vertex normals), the three unit vertex normals.
@group(0) @binding(1) var<storage, read> triangles: array<vec4<real>>;
// Per scene object two vec4: (kind: 0 none, 1 glass, 2 mirror; index of refraction),
// (absorption per metre for glass, reflectance at normal incidence for a mirror).
@group(0) @binding(2) var<storage, read> materials: array<vec4<f32>>;
// Schlick's fifth-order term (1 − i/(N − 1))⁵ per texel (at least one texel bound).
@group(0) @binding(4) var<storage, read> schlick: array<f32>;
// The mesh's vertices, two vec4 each: (position, 1), (unit shading normal, 0).
@group(0) @binding(5) var<storage, read_write> vertices: array<vec4<f32>>;
// Per vertex its record: record_terms() TermRecords (the greedy refraction and reflection
// terms, or one per path class), then its screen position (record_screen below).
@group(0) @binding(6) var<storage, read_write> records: array<vec4<f32>>;
// Counters, written with atomics: see COUNTER_* (include/control.wgsl).
@group(0) @binding(7) var<storage, read_write> counters: array<atomic<u32>>;
// The tessellation's control words (include/control.wgsl): the range of vertices a level
// traces, and the path classes it follows (CONTROL_CLASSES); and per input vertex whether it
// is traced (1) or not (0).
@group(0) @binding(8) var<storage, read> control: array<u32>;
@group(0) @binding(9) var<storage, read> wanted: array<u32>;

const NO_PRIMITIVE: u32 = 0xffffffffu;

// One term's greedy path: F·G (w: interfaces met), the outgoing ray's origin (w: the greedy
// choices, bit i set for a reflection at interface i + 2) and direction (w: 1 when the term has
// a path, 0 when not).
struct TermRecord {
    fg: vec4<f32>,
    origin: vec4<f32>,
    direction: vec4<f32>,
}

// A vertex record: its terms (3 vec4 each) and then its screen position in subpixels, 1 when it
// has one (0: at or behind the eye's plane), 1 when the vertex is visible from the eye.
fn record_terms() -> u32 {
    return max(control[CONTROL_CLASSES], 2u);
}

fn write_term(index: u32, slot: u32, term: TermRecord) {
    let base = (3u * record_terms() + 1u) * index + 3u * slot;
    records[base] = term.fg;
    records[base + 1u] = term.origin;
    records[base + 2u] = term.direction;
}

struct Ray {
    origin: vec3<real>,
    direction: vec3<real>,
}

struct Hit {
    t: real,
    primitive: u32,
    u: real,
    v: real,
}

struct Surface {
    t: real,
    position: vec3<real>,
    geometric_normal: vec3<real>,
    shading_normal: vec3<real>,
    object: u32,
    primitive: u32,
}

// Hits this close (relative distance) are one hit, won by the lowest CPU triangle id (e1.w):
// the CPU's rule (bvh.rs `TIE`), so that a ray through a shared vertex starts on the same
// triangle on both.
const TIE: real = 1e-5;
// |cos| between a vertex's normal and its eye ray below which it is on the silhouette and its
// paths start at the vertex itself (paths.rs `GRAZING`).
const GRAZING: real = 0.02;

// Möller–Trumbore as the CPU's test in the same precision: (t, u, v) with t in (0, best), or t = -1.
fn intersect(primitive: u32, ray: Ray, best: real) -> vec3<real> {
    let base = primitive * 7u;
    let v0 = triangles[base].xyz;
    let e1 = triangles[base + 1u].xyz;
    let e2 = triangles[base + 2u].xyz;
    let p = cross(ray.direction, e2);
    let determinant = dot(e1, p);
    if determinant == 0.0 {
        return vec3<real>(-1.0);
    }
    let inverse = 1.0 / determinant;
    let s = ray.origin - v0;
    let u = dot(s, p) * inverse;
    if !(u >= -BARYCENTRIC_SLACK && u <= 1.0 + BARYCENTRIC_SLACK) {
        return vec3<real>(-1.0);
    }
    let q = cross(s, e1);
    let v = dot(ray.direction, q) * inverse;
    if v < -BARYCENTRIC_SLACK || u + v > 1.0 + BARYCENTRIC_SLACK {
        return vec3<real>(-1.0);
    }
    let t = dot(e2, q) * inverse;
    if t > 0.0 && t < best {
        return vec3<real>(t, u, v);
    }
    return vec3<real>(-1.0);
}

// The search for a ray's closest hit: the nearest hit so far, and the winner among the hits
// within TIE of it, the lowest CPU id (the CPU's rule; the window only shrinks, so the order
// hits are found in does not matter).
struct Closest {
    best: Hit,
    best_id: u32,
    nearest: real,
    // Hits up to here may still win: the nearest hit so far plus the tie margin.
    reach: real,
    max_t: real,
}

fn no_hit_yet(max_t: real) -> Closest {
    return Closest(Hit(max_t, NO_PRIMITIVE, 0.0, 0.0), 0u, max_t, max_t, max_t);
}

// Tests triangle `primitive` against `ray`; keeps it where it wins.
fn consider(closest: ptr<function, Closest>, primitive: u32, ray: Ray) {
    let found = intersect(primitive, ray, (*closest).reach);
    if found.x <= 0.0 {
        return;
    }
    let id = word(triangles[primitive * 7u + 1u].w);
    if found.x < (*closest).nearest {
        (*closest).nearest = found.x;
        (*closest).reach = min(found.x * (1.0 + TIE), (*closest).max_t);
    }
    let best = (*closest).best;
    if best.primitive == NO_PRIMITIVE || best.t > (*closest).reach || id < (*closest).best_id {
        (*closest).best = Hit(found.x, primitive, found.y, found.z);
        (*closest).best_id = id;
    }
}


// The surface at a hit: position and normals interpolated as the CPU's path does.
fn surface_at(hit: Hit) -> Surface {
    let base = hit.primitive * 7u;
    let w = 1.0 - hit.u - hit.v;
    let v0 = triangles[base];
    let position = v0.xyz + triangles[base + 1u].xyz * hit.u + triangles[base + 2u].xyz * hit.v;
    let geometric = triangles[base + 3u].xyz;
    let interpolated = triangles[base + 4u].xyz * w + triangles[base + 5u].xyz * hit.u
        + triangles[base + 6u].xyz * hit.v;
    var shading = geometric;
    if dot(interpolated, interpolated) > 1e-24 {
        let n = normalize(interpolated);
        if dot(n, geometric) > 0.0 {
            shading = n;
        }
    }
    return Surface(hit.t, position, geometric, shading, word(v0.w), hit.primitive);
}

fn offset_origin(position: vec3<real>, side: vec3<real>) -> vec3<real> {
    let a = abs(position);
    let magnitude = max(max(max(a.x, a.y), a.z), 1.0);
    return position + side * (ORIGIN_OFFSET * magnitude);
}

// (1 − c)⁵ for c clamped to [0, 1]: evaluated, or through the Schlick table as a linear sampler
// with clamp-to-edge addressing reads it (SchlickTable::sample).
fn fifth_power(cos_theta: real) -> real {
    var c = clamp(cos_theta, 0.0, 1.0);
    if cos_theta != cos_theta {
        c = 0.0;
    }
    let n = constants.schlick_texels;
    if n == 0u {
        let m = 1.0 - c;
        return m * m * m * m * m;
    }
    let size = real(n);
    let u = (c * (size - 1.0) + 0.5) / size;
    let x = u * size - 0.5;
    let i = floor(x);
    let alpha = x - i;
    let last = i32(n) - 1;
    let a = real(schlick[u32(clamp(i32(i), 0, last))]);
    let b = real(schlick[u32(clamp(i32(i) + 1, 0, last))]);
    return (1.0 - alpha) * a + alpha * b;
}

fn amplitude_squared(numerator: real, denominator: real) -> real {
    if denominator == 0.0 {
        return 1.0;
    }
    let r = numerator / denominator;
    return r * r;
}

// The children at one interface: the reflected ray and its Fresnel coefficient, the refracted
// ray and its coefficient (transmittance < 0: none).
struct Scattering {
    reflected: Ray,
    reflectance: vec3<real>,
    refracted: Ray,
    transmittance: real,
}

fn scatter_about(
    material: u32,
    direction: vec3<real>,
    surface: Surface,
    face: vec3<real>,
    normal: vec3<real>,
    entering: bool,
) -> Scattering {
    let kind = materials[2u * material];
    let colour = vec3<real>(materials[2u * material + 1u].xyz);
    let cos_incident = -dot(direction, normal);
    let reflected = Ray(
        offset_origin(surface.position, face),
        normalize(direction - normal * (2.0 * dot(direction, normal))),
    );
    var out = Scattering(reflected, vec3<real>(0.0), reflected, -1.0);
    if kind.x != 1.0 {
        // A mirror (or, as the CPU's fallback, anything else): Schlick per channel.
        out.reflectance = colour + (vec3<real>(1.0) - colour) * fifth_power(cos_incident);
        return out;
    }
    let ior = real(kind.y);
    let eta_incident = select(ior, 1.0, entering);
    let eta_transmitted = select(1.0, ior, entering);
    var cos_i = clamp(cos_incident, 0.0, 1.0);
    if cos_incident != cos_incident {
        cos_i = 0.0;
    }
    let eta = eta_incident / eta_transmitted;
    let sin2_t = eta * eta * max(1.0 - cos_i * cos_i, 0.0);
    if sin2_t >= 1.0 {
        out.reflectance = vec3<real>(1.0);
        return out;
    }
    let cos_t = sqrt(1.0 - sin2_t);
    var reflectance: real = 0.0;
    if constants.schlick_texels == 0u {
        let n1 = eta_incident;
        let n2 = eta_transmitted;
        let rs = amplitude_squared(n1 * cos_i - n2 * cos_t, n1 * cos_i + n2 * cos_t);
        let rp = amplitude_squared(n2 * cos_i - n1 * cos_t, n2 * cos_i + n1 * cos_t);
        reflectance = clamp(0.5 * (rs + rp), 0.0, 1.0);
    } else {
        // Schlick with the cosine on the optically thinner side.
        let thinner = select(cos_i, cos_t, eta_incident > eta_transmitted);
        let r0 = amplitude_squared(eta_incident - eta_transmitted, eta_incident + eta_transmitted);
        reflectance = clamp(r0 + (1.0 - r0) * fifth_power(thinner), 0.0, 1.0);
    }
    out.reflectance = vec3<real>(reflectance);
    out.transmittance = 1.0 - reflectance;
    out.refracted = Ray(
        offset_origin(surface.position, -face),
        normalize(direction * eta + normal * (eta * cos_i - cos_t)),
    );
    return out;
}

// The children of a ray arriving along `direction` at `surface` (the CPU's scatter_with): about
// the shading normal, or the face normal where that would send a child to the wrong side.
fn scatter(material: u32, direction: vec3<real>, surface: Surface) -> Scattering {
    let entering = dot(direction, surface.geometric_normal) < 0.0;
    let face = select(-surface.geometric_normal, surface.geometric_normal, entering);
    let shading = select(-surface.shading_normal, surface.shading_normal, entering);
    let about_shading = scatter_about(material, direction, surface, face, shading, entering);
    let reflection_ok = dot(about_shading.reflected.direction, face) > 0.0;
    let refraction_ok = about_shading.transmittance < 0.0
        || dot(about_shading.refracted.direction, face) < 0.0;
    if reflection_ok && refraction_ok {
        return about_shading;
    }
    return scatter_about(material, direction, surface, face, face, entering);
}

fn greedy_reflects(s: Scattering) -> bool {
    return s.transmittance < 0.0 || s.transmittance < max(max(s.reflectance.x, s.reflectance.y), s.reflectance.z);
}

struct Path {
    fresnel: vec3<real>,
    attenuation: vec3<real>,
    ray: Ray,
    interfaces: u32,
    reflections: u32,
    truncated: bool,
}

// Follows the greedy child from the path's ray until it misses the lens object
// (propagate_greedy on the CPU). Counts secondary rays and triangle tests.
fn propagate(path_in: Path, first_exclude: u32, rays: ptr<function, u32>, tests: ptr<function, u32>) -> Path {
    var path = path_in;
    var exclude = first_exclude;
    let cap = max(constants.max_interfaces, 1u);
    loop {
        *rays += 1u;
        let hit = closest_hit(constants.part, path.ray, 3.4e38, exclude, tests);
        if hit.primitive == NO_PRIMITIVE {
            return path;
        }
        let surface = surface_at(hit);
        let kind = materials[2u * surface.object];
        if dot(path.ray.direction, surface.geometric_normal) >= 0.0 && kind.x == 1.0 {
            // Leaving the glass: the segment just travelled was inside it.
            // In f32: SPIR-V's pow has no f64 form (the CPU's f64 power differs by ~1e-7).
            let absorption = max(materials[2u * surface.object + 1u].xyz, vec3<f32>(0.0));
            let through = pow(absorption, vec3<f32>(f32(hit.t)));
            path.attenuation = path.attenuation * vec3<real>(through);
        }
        if path.interfaces >= cap {
            path.truncated = true;
            return path;
        }
        let s = scatter(surface.object, path.ray.direction, surface);
        let reflects = greedy_reflects(s);
        if reflects && path.interfaces <= 32u {
            path.reflections |= 1u << (path.interfaces - 1u);
        }
        path.interfaces += 1u;
        if reflects {
            path.fresnel = path.fresnel * s.reflectance;
            path.ray = s.reflected;
        } else {
            path.fresnel = path.fresnel * s.transmittance;
            path.ray = s.refracted;
        }
        exclude = surface.primitive;
    }
    return path;
}

fn term_record(path: Path) -> TermRecord {
    var fg = path.fresnel * path.attenuation;
    if path.truncated {
        fg = vec3<real>(0.0);
    }
    return TermRecord(
        vec4<f32>(vec3<f32>(fg), bitcast<f32>(path.interfaces)),
        vec4<f32>(vec3<f32>(path.ray.origin), bitcast<f32>(path.reflections)),
        vec4<f32>(vec3<f32>(path.ray.direction), 1.0),
    );
}

fn start_path(ray: Ray, coefficient: vec3<real>, exclude: u32, rays: ptr<function, u32>, tests: ptr<function, u32>) -> Path {
    var path = Path(coefficient, vec3<real>(1.0), ray, 1u, 0u, false);
    if constants.first_bounce_only == 0u {
        path = propagate(path, exclude, rays, tests);
    }
    return path;
}

// A term with no path: no F·G, and `direction.w` 0.
fn no_term() -> TermRecord {
    return TermRecord(vec4<f32>(0.0), vec4<f32>(0.0), vec4<f32>(0.0));
}

// The lens object's next interface along `ray` from the surface of `start`, past hits closer than
// CRACK (relative) that a seam vertex's rounding gives: a path class counts its events exactly
// (the CPU's next_interface in engine/src/trace/classes.rs). The hit's t is from `ray`'s origin.
const CRACK: real = 1.2e-6;

fn next_interface(ray_in: Ray, start: u32, rays: ptr<function, u32>, tests: ptr<function, u32>) -> Hit {
    let a = abs(ray_in.origin);
    let crack = CRACK * max(max(max(a.x, a.y), a.z), 1.0);
    var ray = ray_in;
    var exclude = start;
    var travelled: real = 0.0;
    for (var i = 0u; i < 5u; i++) {
        var next = closest_hit(constants.part, ray, 3.4e38, exclude, tests);
        if next.primitive == NO_PRIMITIVE || i == 4u || travelled + next.t >= crack {
            next.t += travelled;
            return next;
        }
        travelled += next.t;
        ray = Ray(surface_at(next).position, ray.direction);
        exclude = next.primitive;
        *rays += 1u;
    }
    return Hit(3.4e38, NO_PRIMITIVE, 0.0, 0.0);
}

// The most interfaces a class's greedy tail meets in all (the CPU's MAX_TAIL_INTERFACES).
const MAX_TAIL_INTERFACES: u32 = 16u;

// The path of class `k` of the control words from the first hit `first` of a ray along
// `direction` (trace_term on the CPU): its events, then for a prefix the greedy choice, until
// the ray leaves; no path where an event is impossible, the ray leaves before the events end or
// meets the object after them. Topology: (events, reflections), as the CPU's class records.
fn class_term(k: u32, direction_in: vec3<real>, first: Surface, rays: ptr<function, u32>, tests: ptr<function, u32>) -> TermRecord {
    let word = control[CONTROL_CLASS_WORDS + 2u * k];
    let events = word & 0xffu;
    let greedy_tail = (word & 0x100u) != 0u;
    let reflections = control[CONTROL_CLASS_WORDS + 2u * k + 1u];
    var cap = events;
    if greedy_tail {
        cap = MAX_TAIL_INTERFACES;
    }
    var fresnel = vec3<real>(1.0);
    var attenuation = vec3<real>(1.0);
    var direction = direction_in;
    var surface = first;
    var taken = 0u;
    var reflected = 0u;
    loop {
        let s = scatter(surface.object, direction, surface);
        var reflects = greedy_reflects(s);
        if taken < events {
            reflects = (reflections & (1u << taken)) != 0u;
        }
        if (!reflects && s.transmittance < 0.0) || taken >= 32u {
            return no_term();
        }
        var ray = s.refracted;
        if reflects {
            fresnel = fresnel * s.reflectance;
            ray = s.reflected;
            reflected += 1u;
        } else {
            fresnel = fresnel * s.transmittance;
        }
        taken += 1u;
        *rays += 1u;
        let hit = next_interface(ray, surface.primitive, rays, tests);
        if hit.primitive == NO_PRIMITIVE {
            if taken < events {
                return no_term();
            }
            let fg = fresnel * attenuation;
            return TermRecord(
                vec4<f32>(vec3<f32>(fg), bitcast<f32>(taken)),
                vec4<f32>(vec3<f32>(ray.origin), bitcast<f32>(reflected)),
                vec4<f32>(vec3<f32>(ray.direction), 1.0),
            );
        }
        if taken >= cap {
            return no_term();
        }
        let next = surface_at(hit);
        if dot(ray.direction, next.geometric_normal) >= 0.0 && materials[2u * next.object].x == 1.0 {
            // Leaving the glass: the segment was inside it (in f32, as `propagate`).
            let absorption = max(materials[2u * next.object + 1u].xyz, vec3<f32>(0.0));
            attenuation = attenuation * vec3<real>(pow(absorption, vec3<f32>(f32(hit.t))));
        }
        direction = ray.direction;
        surface = next;
    }
    return no_term();
}

// Screen position in subpixels (xy) and whether there is one (z), as ScreenCamera::project.
fn project(position: vec3<real>) -> vec3<f32> {
    let clip = constants.view_proj * vec4<f32>(vec3<f32>(position), 1.0);
    if clip.w <= 1e-6 {
        return vec3<f32>(0.0);
    }
    let ndc = clip.xy / clip.w;
    let screen = (ndc + vec2<f32>(1.0)) * 0.5 * constants.subpixels;
    if any(abs(screen) > vec2<f32>(3.0e38)) {
        return vec3<f32>(0.0);
    }
    return vec3<f32>(screen, 1.0);
}

// Traces vertex `index`: the eye ray (the visibility query, and the first hit when the vertex is
// visible), then both greedy paths or one path per class; writes its record.
fn trace_vertex(index: u32) {
    let position = vec3<real>(vertices[2u * index].xyz);
    let eye = vec3<real>(constants.eye);
    let to_vertex = position - eye;
    let distance = length(to_vertex);
    var direction = vec3<real>(0.0, 0.0, -1.0);
    if distance > 0.0 {
        direction = to_vertex / distance;
    }
    let eye_ray = Ray(eye, direction);
    var rays = 0u;
    var tests = 0u;
    // Only what lies up to the vertex matters: the vertex itself, or an occluder.
    let tolerance = 1e-4 * max(distance, 1.0);
    var first = Hit(distance + tolerance, NO_PRIMITIVE, 0.0, 0.0);
    var first_part = 0u;
    for (var part = 0u; part < part_count(); part++) {
        let hit = closest_hit(part, eye_ray, first.t, NO_PRIMITIVE, &tests);
        if hit.primitive != NO_PRIMITIVE {
            first = hit;
            first_part = part;
        }
    }
    // Visible: nothing hit before the vertex (the CPU oracle's rule). Whether the eye ray meets
    // the vertex's own surface or slips past it at a silhouette is up to rounding; an occluder
    // stands clear of it.
    let visible = first.primitive == NO_PRIMITIVE || first.t >= distance - tolerance;
    let normal_in = vec3<real>(vertices[2u * index + 1u].xyz);
    var cos_view: real = 0.0;
    if dot(normal_in, normal_in) > 0.0 {
        cos_view = abs(dot(normalize(normal_in), direction));
    }
    let on_vertex = cos_view >= GRAZING && first.primitive != NO_PRIMITIVE
        && first_part == constants.part && abs(first.t - distance) <= tolerance;
    var surface: Surface;
    if on_vertex {
        surface = surface_at(first);
    } else {
        // Occluded, or a silhouette the eye ray slips past: the paths start at the vertex with
        // its normal, turned to face the eye so the first interface is an entry.
        var normal = vec3<real>(vertices[2u * index + 1u].xyz);
        if dot(normal, normal) > 0.0 {
            normal = normalize(normal);
        } else {
            normal = -direction;
        }
        let facing = dot(direction, normal);
        if facing >= -1e-3 {
            let turned = normal - (facing + 1e-3) * direction;
            normal = select(-direction, normalize(turned), dot(turned, turned) > 0.0);
        }
        surface = Surface(distance, position, normal, normal, constants.object, NO_PRIMITIVE);
    }
    let classes = control[CONTROL_CLASSES];
    if classes > 0u {
        for (var k = 0u; k < classes; k++) {
            write_term(index, k, class_term(k, direction, surface, &rays, &tests));
        }
    } else {
        let s = scatter(surface.object, direction, surface);
        let reflection = term_record(
            start_path(s.reflected, s.reflectance, surface.primitive, &rays, &tests),
        );
        var refraction = reflection;
        refraction.direction.w = 0.0;
        if s.transmittance >= 0.0 {
            refraction = term_record(start_path(
                s.refracted, vec3<real>(s.transmittance), surface.primitive, &rays, &tests,
            ));
        }
        write_term(index, 0u, refraction);
        write_term(index, 1u, reflection);
    }
    let screen = project(position);
    records[(3u * record_terms() + 1u) * (index + 1u) - 1u] =
        vec4<f32>(screen.xy, screen.z, select(0.0, 1.0, visible));
    atomicAdd(&counters[COUNTER_PRIMARY_RAYS], 1u);
    atomicAdd(&counters[COUNTER_SECONDARY_RAYS], rays);
    atomicAdd(&counters[COUNTER_TRIANGLE_TESTS], tests);
}

// The vertices [first_vertex, first_vertex + vertex_count).
@compute @workgroup_size(64)
fn cs_vertex_paths(@builtin(global_invocation_id) id: vec3<u32>) {
    if id.x >= constants.vertex_count {
        return;
    }
    trace_vertex(constants.first_vertex + id.x);
}

// A tessellation level's new vertices [control VERTEX_LO, VERTEX_HI): of the input vertices only
// the wanted ones (corners of triangles that are subdivided).
@compute @workgroup_size(64)
fn cs_level_paths(@builtin(global_invocation_id) id: vec3<u32>) {
    let index = control[CONTROL_VERTEX_LO] + id.x;
    if index >= control[CONTROL_VERTEX_HI] {
        return;
    }
    if index < control[CONTROL_INPUT_VERTICES] && wanted[index] == 0u {
        return;
    }
    trace_vertex(index);
}
