// Glossy objects by reflection-space IBR (Cabral, Olano & Nemec 1999), drawn opaque after the
// environment with depth test and write (engine/src/rsibr and render/plan's glossy pass).
//
// The maps of the (up to three) view samples a frame blends are one cube-map array: layer
// slot·lobe_count + lobe. Each holds one lobe's radiance premultiplied by its confidence n·v_s,
// indexed by the world-space central direction: the normal (lobe kind 0, the Lambertian base)
// or the mirror direction of the view (1, the base's Phong lobe; 2, the coat's). Per fragment
// and lobe the slots are read along that direction turned by the slot's rotation (the identity
// when warped) and blended Σ wᵢ·rgbᵢ / Σ wᵢ·αᵢ; the lobes are summed, the base's times 1 − F and
// the coat's times F, F the exact dielectric Fresnel reflectance at the pixel's view angle. The
// same arithmetic as rsibr::shade, in f32.

struct GlossyData {
    view_proj: mat4x4<f32>,
    // xyz: the camera position; w: the number of slots (1 to 3).
    eye: vec4<f32>,
    // xyz: the slots' weights; w: the coat's index of refraction (0: no coat).
    weights: vec4<f32>,
    // xyz: the kind of lobe k (0 diffuse, 1 specular, 2 coat); w: the number of lobes.
    lobes: vec4<u32>,
    // Per slot, the rotation of lookup directions (columns 0..2).
    rotations: array<mat4x4<f32>, 3>,
}

@group(0) @binding(0) var<storage, read> data: GlossyData;
@group(0) @binding(1) var maps: texture_cube_array<f32>;
@group(0) @binding(2) var maps_sampler: sampler;

struct VertexOut {
    @builtin(position) @invariant clip: vec4<f32>,
    @location(0) position: vec3<f32>,
    @location(1) normal: vec3<f32>,
}

@vertex
fn vs_glossy(@location(0) position: vec3<f32>, @location(1) normal: vec3<f32>) -> VertexOut {
    var out: VertexOut;
    out.clip = data.view_proj * vec4<f32>(position, 1.0);
    out.position = position;
    out.normal = normal;
    return out;
}

// Unpolarized reflectance of light arriving at cosine `cos_i` from air onto a dielectric of
// index `eta` (trace::fresnel::dielectric with n₁ = 1, n₂ = eta).
fn dielectric_reflectance(cos_i: f32, eta: f32) -> f32 {
    let c = clamp(cos_i, 0.0, 1.0);
    let sin_t2 = (1.0 - c * c) / (eta * eta);
    let cos_t = sqrt(max(1.0 - sin_t2, 0.0));
    let rs = (c - eta * cos_t) / (c + eta * cos_t);
    let rp = (eta * c - cos_t) / (eta * c + cos_t);
    return 0.5 * (rs * rs + rp * rp);
}

@fragment
fn fs_glossy(in: VertexOut) -> @location(0) vec4<f32> {
    let toward_viewer = normalize(data.eye.xyz - in.position);
    // Opposite vertex normals can interpolate to zero: face the viewer there (as rsibr::shade).
    var normal = toward_viewer;
    if dot(in.normal, in.normal) > 0.0 {
        normal = normalize(in.normal);
    }
    if dot(normal, toward_viewer) < 0.0 {
        normal = -normal;
    }
    let cos_view = dot(normal, toward_viewer);
    let mirror = normalize(normal * (2.0 * cos_view) - toward_viewer);
    var fresnel = 0.0;
    if data.weights.w > 0.0 {
        fresnel = dielectric_reflectance(cos_view, data.weights.w);
    }
    let slots = u32(data.eye.w);
    let lobe_count = data.lobes.w;
    var radiance = vec3<f32>(0.0);
    for (var k = 0u; k < lobe_count; k++) {
        let kind = data.lobes[k];
        var direction = mirror;
        if kind == 0u {
            direction = normal;
        }
        var colour = vec3<f32>(0.0);
        var confidence = 0.0;
        for (var s = 0u; s < slots; s++) {
            let turned = (data.rotations[s] * vec4<f32>(direction, 0.0)).xyz;
            let texel = textureSampleLevel(maps, maps_sampler, turned, s * lobe_count + k, 0.0);
            colour += texel.rgb * data.weights[s];
            confidence += texel.a * data.weights[s];
        }
        if confidence > 0.0 {
            var weight = 1.0 - fresnel;
            if kind == 2u {
                weight = fresnel;
            }
            radiance += colour / confidence * weight;
        }
    }
    return vec4<f32>(radiance, 1.0);
}
