//! The scene file's serde schema, exactly as written in TOML: one struct per table, one field per
//! key, each documented with its meaning, unit, range and default. `tools/scenes/README.md` is the
//! user's documentation of the same schema; a change to a field here changes it there. Values
//! are checked and turned into a [`super::Scene`] by [`super::load`]; nothing here validates
//! beyond types, so the ranges below are the loader's checks, not serde's.
//!
//! Every struct is `deny_unknown_fields`: a misspelt key is an error, not a silent default. Units
//! are metres and degrees (the key says which), colours linear rgb, the world right-handed with
//! y up; relative paths start at the scene file's folder.

use serde::Deserialize;

/// The whole file: the top-level keys and tables. Only `[camera]` is required, unless the file
/// `extends` a built-in scene.
#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct SceneFile {
    /// `extends = "teapot-room"`: a built-in scene this file starts from. Each top-level key or
    /// table the file gives replaces the built-in's whole (`[view_space]` for another view
    /// space); `name` is not inherited (it defaults to the file stem).
    pub extends: Option<String>,
    /// `name`: the scene's name, not blank. `None`: the file stem (`scene` for a path without
    /// one).
    pub name: Option<String>,
    /// `[camera]`, required (unless inherited through `extends`): the default camera; every
    /// viewpoint sample of the view space shares its look-at point, up, field of view and
    /// resolution.
    pub camera: Option<CameraSpec>,
    /// `[environment]`: the radiance at infinity. `None`: constant black.
    pub environment: Option<EnvironmentSpec>,
    /// `[[lights]]`: point lights. Default: none.
    #[serde(default)]
    pub lights: Vec<LightSpec>,
    /// `[[materials]]`: named materials, which objects refer to by name. Default: none.
    #[serde(default)]
    pub materials: Vec<MaterialSpec>,
    /// `[[objects]]`: meshes with a material and a transform, in file order. Default: none.
    #[serde(default)]
    pub objects: Vec<ObjectSpec>,
    /// `[[lenses]]`: which objects form each lens object. Default: none. Every glass or mirror
    /// object that no entry names becomes a lens of its own, named after it.
    #[serde(default)]
    pub lenses: Vec<LensSpec>,
    /// `[view_space]`: the viewpoint samples for baking. `None`: the camera position alone.
    pub view_space: Option<ViewSpaceSpec>,
}

/// `camera.up` when absent: the world's up, +y.
fn default_up() -> [f32; 3] {
    [0.0, 1.0, 0.0]
}

/// Default of `camera.supersampling` and `plane.subdivisions`.
fn one() -> u32 {
    1
}

/// Default of `environment.latlong.scale`: the radiance as stored.
fn one_f32() -> f32 {
    1.0
}

/// Default of `cylinder.caps`: a closed cylinder.
fn yes() -> bool {
    true
}

/// `[camera]`: the default pinhole camera. Primary rays go through pixel (x, y) in pixel units,
/// (0, 0) the top-left corner of the image, pixel centres at +0.5; the top row of the image is
/// the camera's up side.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct CameraSpec {
    /// `position = [x, y, z]`, required: the eye position in metres, finite.
    pub position: [f32; 3],
    /// `look_at = [x, y, z]`, required: the point looked at, in metres; must differ from
    /// `position`.
    pub look_at: [f32; 3],
    /// `up = [x, y, z]`, default [0, 1, 0]: the up direction (any non-zero length, normalized on
    /// loading); must not be parallel to `look_at − position`.
    #[serde(default = "default_up")]
    pub up: [f32; 3],
    /// `vfov_degrees`, required: the vertical field of view in degrees, in (0, 180).
    pub vfov_degrees: f32,
    /// `width`, required: the image width in pixels, ≥ 1.
    pub width: u32,
    /// `height`, required: the image height in pixels, ≥ 1.
    pub height: u32,
    /// `supersampling`, default 1: k, for k×k samples per pixel, box filtered; ≥ 1 (1 is one
    /// sample at the pixel centre).
    #[serde(default = "one")]
    pub supersampling: u32,
}

/// `[environment]`: the radiance arriving from infinitely far away along rays that leave the
/// scene. Exactly one of `constant`, `latlong` and `studio`.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct EnvironmentSpec {
    /// `constant = [r, g, b]`: the same radiance in every direction, linear rgb, each finite and
    /// ≥ 0.
    pub constant: Option<[f32; 3]>,
    /// `latlong = { path, scale }`: an equirectangular HDR image.
    pub latlong: Option<LatLongSpec>,
    /// `studio = { width, scale }`: lensmap's procedural studio ([`super::environment::studio`]),
    /// a lat-long map `width` texels wide (default 512) made at load time.
    pub studio: Option<StudioSpec>,
}

/// `studio = { width = 512, scale = 1.0 }`.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct StudioSpec {
    /// `width`, default 512: texels around; the map is half as tall. In [8, 8192].
    #[serde(default = "studio_width")]
    pub width: u32,
    /// `scale`, default 1: a multiplier on the radiance, finite and ≥ 0.
    #[serde(default = "one_f32")]
    pub scale: f32,
}

fn studio_width() -> u32 {
    512
}

/// `latlong = { path = "sky.exr", scale = 1.0 }`: an equirectangular (latitude-longitude) map of
/// the radiance at infinity. A unit direction d = (x, y, z) maps to u = ½ + atan2(x, −z) / 2π
/// ∈ [0, 1) and v = acos(y) / π ∈ [0, 1] (see [`super::direction_to_lat_long`]): −z at u = ½,
/// +x at u = ¾, +z at the seam, the zenith +y on the top row. Pixel (i, j) of a W×H map has its
/// centre at ((i + ½)/W, (j + ½)/H); sampling is bilinear, wrapping in u and clamping in v.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct LatLongSpec {
    /// `path`, required: the image file, relative to the scene file's folder. EXR is linear;
    /// 8/16-bit files (PNG) are taken as sRGB. NaN, infinite or negative texels are rejected.
    pub path: String,
    /// `scale`, default 1: a multiplier on every texel's radiance, finite and ≥ 0 (1 is the
    /// radiance as stored, 0 a black environment).
    #[serde(default = "one_f32")]
    pub scale: f32,
}

/// One `[[lights]]` entry: an isotropic point light. Both keys are required.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct LightSpec {
    /// `position = [x, y, z]`: the light's position in metres, finite.
    pub position: [f32; 3],
    /// `intensity = [r, g, b]`: radiant intensity per channel in W/sr, linear rgb, each finite
    /// and ≥ 0: the irradiance at distance d facing the light is intensity / d².
    pub intensity: [f32; 3],
}

/// One `[[materials]]` entry: a `name` and exactly one of `glass`, `mirror`, `diffuse` and
/// `glossy`. Glass and mirror materials make lens objects; diffuse and glossy ones make the
/// environment.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct MaterialSpec {
    /// `name`, required: unique among the materials and not blank; an object's `material`
    /// names it.
    pub name: String,
    /// `glass = { ior, absorption }`: a dielectric that refracts and reflects.
    pub glass: Option<GlassSpec>,
    /// `mirror = { reflectance }`: a reflector.
    pub mirror: Option<MirrorSpec>,
    /// `diffuse = { colour, checker, image }`: a Lambertian surface lit by the point lights.
    pub diffuse: Option<DiffuseSpec>,
    /// `glossy = { diffuse, specular, exponent, coat }`: a glossy surface.
    pub glossy: Option<GlossySpec>,
}

/// `glossy = { diffuse = [0.5, 0.1, 0.1], specular = [0.3, 0.3, 0.3], exponent = 40, coat = {
/// ior = 1.5, exponent = 1000 } }`: a Lambertian base and a normalized Phong lobe, optionally
/// under a Fresnel clear coat (the reflection-space IBR paper's car paint).
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct GlossySpec {
    /// `diffuse`, default [0, 0, 0]: the Lambertian albedo kd per channel, each in [0, 1].
    #[serde(default)]
    pub diffuse: [f32; 3],
    /// `specular`, default [0, 0, 0]: the Phong lobe's reflectance ks per channel, each in
    /// [0, 1], with diffuse + specular ≤ 1 per channel.
    #[serde(default)]
    pub specular: [f32; 3],
    /// `exponent`, required with a specular lobe: the Phong exponent, in [1, 100000].
    pub exponent: Option<f32>,
    /// `coat = { ior, exponent }`: a clear coat over the base. `None`: none.
    pub coat: Option<CoatSpec>,
}

/// `coat = { ior = 1.5, exponent = 1000 }`: both keys required.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct CoatSpec {
    /// `ior`: the coat's index of refraction, in (1, 3].
    pub ior: f32,
    /// `exponent`: the coat lobe's Phong exponent, in [1, 100000].
    pub exponent: f32,
}

/// `glass = { ior = 1.5, absorption = [0.82, 0.9, 0.95] }`: a dielectric lens material.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct GlassSpec {
    /// `ior`, required: the index of refraction relative to air, finite and > 0 (e.g. 1.5).
    pub ior: f32,
    /// `absorption`, default [1, 1, 1] (clear glass): the transmittance per metre per channel,
    /// each in (0, 1]: light travelling d metres inside is multiplied by G = absorption^d.
    #[serde(default = "clear")]
    pub absorption: [f32; 3],
}

/// Default of `glass.absorption`: clear glass, no attenuation.
fn clear() -> [f32; 3] {
    [1.0; 3]
}

/// `mirror = { reflectance = [0.95, 0.95, 0.95] }`: a reflective lens material.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct MirrorSpec {
    /// `reflectance`, required: the reflectance at normal incidence R₀ per channel, each in
    /// [0, 1]; the tracer applies Schlick's approximation F = R₀ + (1 − R₀)(1 − cos θ)⁵.
    pub reflectance: [f32; 3],
}

/// `diffuse = { colour, checker, image }`: a Lambertian material whose albedo is
/// `colour × texture(uv)`. It needs a `colour` or a texture, and at most one texture (`checker`
/// or `image`).
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct DiffuseSpec {
    /// `colour = [r, g, b]`: the Lambertian albedo per channel, linear rgb, each in [0, 1].
    /// `None`: [1, 1, 1] when there is a texture, else an error.
    pub colour: Option<[f32; 3]>,
    /// `checker = { a, b, scale }`: a procedural checkerboard texture. `None`: none.
    pub checker: Option<CheckerSpec>,
    /// `image`: a PNG (sRGB) or EXR (linear) texture file, relative to the scene file's folder;
    /// bilinear, repeating, v = 0 on the bottom row (as in OBJ). NaN, infinite or negative texels
    /// are rejected. `None`: none.
    pub image: Option<String>,
}

/// `checker = { a = [0.8, 0.8, 0.8], b = [0.1, 0.1, 0.1], scale = 20 }`: the square with
/// floor(u·scale) + floor(v·scale) even is `a`, odd is `b`. All three keys are required.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct CheckerSpec {
    /// `a`: the colour of the even squares (the one just above and right of uv = (0, 0)),
    /// linear rgb, each in [0, 1].
    pub a: [f32; 3],
    /// `b`: the colour of the odd squares, linear rgb, each in [0, 1].
    pub b: [f32; 3],
    /// `scale`: squares per uv unit along u and along v, finite and > 0 (a 20 m plane, whose uvs
    /// span [0, 1], gets 1 m squares from scale = 20).
    pub scale: f32,
}

/// One `[[objects]]` entry: a mesh with a material and a transform. Exactly one of the mesh keys
/// (`obj`, `plane`, `box`, `sphere`, `cylinder`, `torus`, `teapot`) is given; the mesh is built
/// in its local frame, turned inside out if asked, then moved to world space by `transform` at
/// load time. Positions, normals and uvs must be finite.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct ObjectSpec {
    /// `name`, required: unique among the objects and not blank; `[[lenses]]` entries name it.
    pub name: String,
    /// `material`, required: the `name` of one of the `[[materials]]`. A glass or mirror
    /// material makes the object part of a lens object.
    pub material: String,
    /// `transform = { translate, rotate_degrees, scale }`. Default: the identity.
    #[serde(default)]
    pub transform: TransformSpec,
    /// `inside_out`, default false: true reverses every triangle and negates every normal (a
    /// room seen from inside).
    #[serde(default)]
    pub inside_out: bool,
    /// `obj = { path, smooth_normals, drop_degenerate }`: a Wavefront OBJ file.
    pub obj: Option<ObjSpec>,
    /// `plane = { size, subdivisions }`: a rectangle in the xz plane.
    pub plane: Option<PlaneSpec>,
    /// `box = { size }`: an axis-aligned box. Renamed because `box` is a Rust keyword.
    #[serde(rename = "box")]
    pub cuboid: Option<BoxSpec>,
    /// `sphere = { radius, segments, rings }`: a UV sphere.
    pub sphere: Option<SphereSpec>,
    /// `cylinder = { radius, height, segments, caps }`: a cylinder about the y axis.
    pub cylinder: Option<CylinderSpec>,
    /// `torus = { major_radius, minor_radius, major_segments, minor_segments }`: a torus about
    /// the y axis.
    pub torus: Option<TorusSpec>,
    /// `teapot = { tessellation, parts }`: the Newell teapot.
    pub teapot: Option<TeapotSpec>,
}

/// `obj = { path = "bunny.obj" }`: a Wavefront OBJ, triangulated, all groups merged into one
/// mesh. Its positions, normals and uvs must be finite.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct ObjSpec {
    /// `path`, required: the OBJ file, relative to the scene file's folder.
    pub path: String,
    /// `smooth_normals`, default false: true ignores the file's normals and generates
    /// angle-weighted smooth ones, as is done anyway where the file has none.
    #[serde(default)]
    pub smooth_normals: bool,
    /// `drop_degenerate`, default false: true drops zero-area triangles; false makes them an
    /// error naming how many there are and the first.
    #[serde(default)]
    pub drop_degenerate: bool,
}

/// `plane = { size = [sx, sz] }`: a rectangle in the xz plane centred on the origin, normal +y;
/// uv = (x/sx + ½, ½ − z/sz).
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct PlaneSpec {
    /// `size = [sx, sz]`, required: the extents along x and z in metres, each > 0.
    pub size: [f32; 2],
    /// `subdivisions`, default 1: quads along each side (subdivisions² quads of two triangles),
    /// in [1, 4096].
    #[serde(default = "one")]
    pub subdivisions: u32,
}

/// `box = { size = [sx, sy, sz] }`: an axis-aligned box centred on the origin, flat faces,
/// uv [0, 1]² per face.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct BoxSpec {
    /// `size = [sx, sy, sz]`, required: the full edge lengths in metres along x, y and z, each
    /// greater than 0 (full sizes, not half extents as in a layer shell's `box`).
    pub size: [f32; 3],
}

/// Default segment count around the round shapes' main axis.
fn segments() -> u32 {
    64
}

/// Default count of a sphere's rings and of a torus's segments around its tube.
fn rings() -> u32 {
    32
}

/// `sphere = { radius = 1.0 }`: a UV sphere centred on the origin; uv = (φ/2π, 1 − θ/π) with φ
/// the angle about +y from +z and θ the polar angle from +y.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct SphereSpec {
    /// `radius`, required: in metres, > 0.
    pub radius: f32,
    /// `segments`, default 64: divisions around the y axis, in [3, 4096].
    #[serde(default = "segments")]
    pub segments: u32,
    /// `rings`, default 32: divisions from pole to pole, in [2, 4096].
    #[serde(default = "rings")]
    pub rings: u32,
}

/// `cylinder = { radius = 0.2, height = 3.0 }`: a cylinder about the y axis, y ∈ [−height/2,
/// height/2], smooth side normals.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct CylinderSpec {
    /// `radius`, required: in metres, > 0.
    pub radius: f32,
    /// `height`, required: the full length along y in metres, > 0.
    pub height: f32,
    /// `segments`, default 64: divisions around the y axis, in [3, 4096].
    #[serde(default = "segments")]
    pub segments: u32,
    /// `caps`, default true: flat discs close both ends; false leaves an open tube.
    #[serde(default = "yes")]
    pub caps: bool,
}

/// `torus = { major_radius = 1.0, minor_radius = 0.25 }`: a tube swept around a circle about the
/// y axis in the xz plane, centred on the origin.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct TorusSpec {
    /// `major_radius`, required: the radius in metres of the circle that the tube's centre
    /// follows, > 0.
    pub major_radius: f32,
    /// `minor_radius`, required: the tube's radius in metres, > 0 and < `major_radius` (else the
    /// tube intersects itself).
    pub minor_radius: f32,
    /// `major_segments`, default 64: divisions around the y axis, in [3, 4096].
    #[serde(default = "segments")]
    pub major_segments: u32,
    /// `minor_segments`, default 32: divisions around the tube, in [3, 4096].
    #[serde(default = "rings")]
    pub minor_segments: u32,
}

/// Default of `teapot.tessellation`: about 4k triangles for the whole teapot.
fn tessellation() -> u32 {
    8
}

/// `teapot = { tessellation = 8 }`: the Newell teapot from its 32 Bézier patches, y up, base at
/// y = 0, in metres before `transform`: x ∈ [−3, 3.43] (handle to spout), y ∈ [0, 3.15],
/// z ∈ [−2, 2]. It has no texture coordinates.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct TeapotSpec {
    /// `tessellation`, default 8: each patch is split into tessellation² quads (8 gives about 4k
    /// triangles for the whole teapot), in [1, 64].
    #[serde(default = "tessellation")]
    pub tessellation: u32,
    /// `parts`: the patch groups to build, a non-empty list of `rim`, `body`, `handle`, `spout`,
    /// `lid`, `bottom`. `None`: all of them.
    pub parts: Option<Vec<String>>,
}

/// `transform = { translate = [x, y, z], rotate_degrees = [rx, ry, rz], scale = s }`: the
/// object-to-world matrix M = T · Rz · Ry · Rx · S, applied at load time: scale, then rotate
/// about x, then y, then z (right-handed: counter-clockwise seen from the positive end of the
/// axis), then translate. Positions are transformed by M and normals by its inverse transpose.
/// Every key is optional; the default is the identity.
#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct TransformSpec {
    /// `translate = [x, y, z]`, default [0, 0, 0]: the offset in metres, applied last; finite.
    #[serde(default)]
    pub translate: [f32; 3],
    /// `rotate_degrees = [rx, ry, rz]`, default [0, 0, 0]: the angles about x, y and z in
    /// degrees, applied in that order after scaling; finite.
    #[serde(default)]
    pub rotate_degrees: [f32; 3],
    /// `scale = s` or `[sx, sy, sz]`, default 1: applied first.
    #[serde(default)]
    pub scale: ScaleSpec,
}

/// `scale = 2.0` or `scale = [1.0, 2.0, 1.0]`: factors along the local x, y and z axes, each
/// finite and non-zero. An odd number of negative factors mirrors the mesh; its winding is then
/// reversed so that triangles stay counter-clockwise seen from outside.
#[derive(Debug)]
pub(crate) enum ScaleSpec {
    /// `scale = s`: the same factor along every axis.
    Uniform(f32),
    /// `scale = [sx, sy, sz]`: one factor per axis.
    PerAxis([f32; 3]),
}

impl<'de> Deserialize<'de> for ScaleSpec {
    fn deserialize<D: serde::Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        /// Accepts a number or a sequence of exactly three numbers, with serde's usual messages
        /// ("invalid type: …, expected a number or an array of three numbers").
        struct ScaleVisitor;

        impl<'de> serde::de::Visitor<'de> for ScaleVisitor {
            type Value = ScaleSpec;

            fn expecting(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
                f.write_str("a number or an array of three numbers")
            }

            fn visit_f64<E: serde::de::Error>(self, v: f64) -> Result<ScaleSpec, E> {
                Ok(ScaleSpec::Uniform(v as f32))
            }

            fn visit_i64<E: serde::de::Error>(self, v: i64) -> Result<ScaleSpec, E> {
                Ok(ScaleSpec::Uniform(v as f32))
            }

            fn visit_u64<E: serde::de::Error>(self, v: u64) -> Result<ScaleSpec, E> {
                Ok(ScaleSpec::Uniform(v as f32))
            }

            fn visit_seq<A: serde::de::SeqAccess<'de>>(
                self,
                mut seq: A,
            ) -> Result<ScaleSpec, A::Error> {
                let mut factors = [0f32; 3];
                for (i, factor) in factors.iter_mut().enumerate() {
                    *factor = seq
                        .next_element()?
                        .ok_or_else(|| serde::de::Error::invalid_length(i, &self))?;
                }
                if seq.next_element::<serde::de::IgnoredAny>()?.is_some() {
                    return Err(serde::de::Error::invalid_length(4, &self));
                }
                Ok(ScaleSpec::PerAxis(factors))
            }
        }

        deserializer.deserialize_any(ScaleVisitor)
    }
}

impl Default for ScaleSpec {
    fn default() -> Self {
        ScaleSpec::Uniform(1.0)
    }
}

/// One `[[lenses]]` entry: a lens object, the glass or mirror objects ray traced together as one
/// local system at run time, with its own layered environment maps.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct LensSpec {
    /// `name`, required: not blank, and unique among the lens objects, including the lenses made
    /// for glass or mirror objects that no entry lists (those take the object's name).
    pub name: String,
    /// `objects`, required: the `name`s of the `[[objects]]` forming it, at least one; each must
    /// exist, be glass or mirror, and belong to this lens only.
    pub objects: Vec<String>,
    /// `layers`: the shells of its layered environment map, nearest first, each centred on the
    /// lens object's centroid (its EM origin). Empty (the default): the runtime's projected EMs
    /// use one sphere at the mean distance of the environment seen from the EM origin.
    #[serde(default)]
    pub layers: Vec<LayerSpecFile>,
    /// `layering`: "distance" (the default: layers by hit distance) or "bounce" (the PEM
    /// paper's local and distant layers: for a lens of mirror objects without `layers`).
    #[serde(default)]
    pub layering: Option<String>,
    /// `terms`: the path classes a hybrid frame shades it with: "greedy" (the default, the
    /// papers' two terms), a count (`4`: the first four of R, TT, TRT, … for glass), a list
    /// (`["R", "TT", "TRT"]` or "R,TT,TRT") or "greedy:D"; a frame's options may override it.
    #[serde(default)]
    pub terms: Option<TermsSpec>,
}

/// A lens entry's `terms`, as TOML writes it: a count, a string, or a list of classes.
#[derive(Debug, Deserialize)]
#[serde(untagged)]
pub(crate) enum TermsSpec {
    /// `terms = 4`.
    Count(u32),
    /// `terms = "greedy"`, `"4"`, `"R,TT,TRT"` or `"greedy:2"`.
    Text(String),
    /// `terms = ["R", "TT", "TRT"]`.
    List(Vec<String>),
}

/// One layer shell of a lens object, centred on its EM origin, e.g. `{ sphere = 1.4 }`: exactly
/// one key, with finite sizes > 0 in metres.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct LayerSpecFile {
    /// `sphere = r`: a sphere of radius r.
    pub sphere: Option<f32>,
    /// `cylinder = r`: an infinite vertical (y-axis) cylinder of radius r.
    pub cylinder: Option<f32>,
    /// `box = [hx, hy, hz]`: an axis-aligned box with these half extents (not full sizes, unlike
    /// an object's `box`). Renamed because `box` is a Rust keyword.
    #[serde(rename = "box")]
    pub box_half_extents: Option<[f32; 3]>,
    /// `ellipsoid = [rx, ry, rz]`: an axis-aligned ellipsoid with these radii.
    pub ellipsoid: Option<[f32; 3]>,
}

/// `[view_space]`: the viewpoint samples at which layered environment maps are baked. Exactly one
/// of `circle`, `list`, `patch` and `cap`. Each sample is a camera at that position with the `[camera]`'s
/// look-at point, up, field of view and resolution; a sample may not sit on the look-at point.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct ViewSpaceSpec {
    /// `[view_space.circle]`: samples evenly spaced in angle on a horizontal circle.
    pub circle: Option<CircleSpec>,
    /// `list = [[x, y, z], …]`: explicit sample positions in metres, finite, at least one.
    pub list: Option<Vec<[f32; 3]>>,
    /// `[view_space.patch]`: an azimuth × elevation grid on a sphere.
    pub patch: Option<PatchSpec>,
    /// `[view_space.cap]`: a Fibonacci set within a cone about an axis.
    pub cap: Option<CapSpec>,
}

/// `[view_space.patch]`: rows of elevation × columns of azimuth on the sphere of `radius` about
/// `centre`; azimuth about +y from +z towards +x, elevation above the horizontal: position =
/// centre + radius·(cos e·sin a, sin e, cos e·cos a). Row-major, sample 0 at the first azimuth
/// and elevation.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct PatchSpec {
    /// `centre = [x, y, z]`, default the camera's `look_at`: the sphere's centre, metres.
    pub centre: Option<[f32; 3]>,
    /// `radius`, required: metres, > 0.
    pub radius: f32,
    /// `azimuth_degrees = [first, last]`, required: first < last, last − first ≤ 360.
    pub azimuth_degrees: [f32; 2],
    /// `azimuth_count`, required: columns, ≥ 2.
    pub azimuth_count: u32,
    /// `elevation_degrees = [first, last]`, required: in [−90, 90], first < last.
    pub elevation_degrees: [f32; 2],
    /// `elevation_count`, required: rows, ≥ 2.
    pub elevation_count: u32,
}

/// `[view_space.cap]`: `count` samples of a Fibonacci spiral within `half_angle_degrees` of
/// `axis`, on the sphere of `radius` about `centre`.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct CapSpec {
    /// `centre = [x, y, z]`, default the camera's `look_at`: the sphere's centre, metres.
    pub centre: Option<[f32; 3]>,
    /// `radius`, required: metres, > 0.
    pub radius: f32,
    /// `axis = [x, y, z]`, default from the centre towards the camera: the cap's middle.
    pub axis: Option<[f32; 3]>,
    /// `half_angle_degrees`, required: the cap's angular radius, in (0, 180] (180: the sphere).
    pub half_angle_degrees: f32,
    /// `count`, required: samples, ≥ 3.
    pub count: u32,
}

/// `[view_space.circle]`: sample i is at angle a = start + i·step about +y, measured from +z
/// towards +x: position = centre + (radius·sin a, height, radius·cos a).
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct CircleSpec {
    /// `centre = [x, y, z]`, required: a point on the circle's vertical axis, in metres.
    pub centre: [f32; 3],
    /// `radius`, required: in metres, > 0.
    pub radius: f32,
    /// `height`, default 0: the circle's height above `centre.y`, in metres.
    #[serde(default)]
    pub height: f32,
    /// `start_degrees`, default 0: the angle of sample 0, in degrees (0 is +z from the centre).
    #[serde(default)]
    pub start_degrees: f32,
    /// `step_degrees`, required: the angle between consecutive samples, in degrees; non-zero
    /// when `count` > 1 (45 samples 8° apart close the circle).
    pub step_degrees: f32,
    /// `count`, required: the number of samples, ≥ 1.
    pub count: u32,
}
