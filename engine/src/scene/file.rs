//! The scene file's serde schema, exactly as written in TOML (see the module documentation of
//! [`super`] for the meaning of every field). Values are checked and turned into a
//! [`super::Scene`] by [`super::load`]; nothing here validates beyond types.

use serde::Deserialize;

/// The whole file.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct SceneFile {
    pub name: Option<String>,
    pub camera: CameraSpec,
    pub environment: Option<EnvironmentSpec>,
    #[serde(default)]
    pub lights: Vec<LightSpec>,
    #[serde(default)]
    pub materials: Vec<MaterialSpec>,
    #[serde(default)]
    pub objects: Vec<ObjectSpec>,
    #[serde(default)]
    pub lenses: Vec<LensSpec>,
    pub view_space: Option<ViewSpaceSpec>,
}

fn default_up() -> [f32; 3] {
    [0.0, 1.0, 0.0]
}

fn one() -> u32 {
    1
}

fn one_f32() -> f32 {
    1.0
}

fn yes() -> bool {
    true
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct CameraSpec {
    pub position: [f32; 3],
    pub look_at: [f32; 3],
    #[serde(default = "default_up")]
    pub up: [f32; 3],
    pub vfov_degrees: f32,
    pub width: u32,
    pub height: u32,
    #[serde(default = "one")]
    pub supersampling: u32,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct EnvironmentSpec {
    pub constant: Option<[f32; 3]>,
    pub latlong: Option<LatLongSpec>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct LatLongSpec {
    pub path: String,
    #[serde(default = "one_f32")]
    pub scale: f32,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct LightSpec {
    pub position: [f32; 3],
    pub intensity: [f32; 3],
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct MaterialSpec {
    pub name: String,
    pub glass: Option<GlassSpec>,
    pub mirror: Option<MirrorSpec>,
    pub diffuse: Option<DiffuseSpec>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct GlassSpec {
    pub ior: f32,
    #[serde(default = "clear")]
    pub absorption: [f32; 3],
}

fn clear() -> [f32; 3] {
    [1.0; 3]
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct MirrorSpec {
    pub reflectance: [f32; 3],
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct DiffuseSpec {
    pub colour: Option<[f32; 3]>,
    pub checker: Option<CheckerSpec>,
    pub image: Option<String>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct CheckerSpec {
    pub a: [f32; 3],
    pub b: [f32; 3],
    pub scale: f32,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct ObjectSpec {
    pub name: String,
    pub material: String,
    #[serde(default)]
    pub transform: TransformSpec,
    #[serde(default)]
    pub inside_out: bool,
    pub obj: Option<ObjSpec>,
    pub plane: Option<PlaneSpec>,
    #[serde(rename = "box")]
    pub cuboid: Option<BoxSpec>,
    pub sphere: Option<SphereSpec>,
    pub cylinder: Option<CylinderSpec>,
    pub torus: Option<TorusSpec>,
    pub teapot: Option<TeapotSpec>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct ObjSpec {
    pub path: String,
    #[serde(default)]
    pub smooth_normals: bool,
    #[serde(default)]
    pub drop_degenerate: bool,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct PlaneSpec {
    pub size: [f32; 2],
    #[serde(default = "one")]
    pub subdivisions: u32,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct BoxSpec {
    pub size: [f32; 3],
}

fn segments() -> u32 {
    64
}

fn rings() -> u32 {
    32
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct SphereSpec {
    pub radius: f32,
    #[serde(default = "segments")]
    pub segments: u32,
    #[serde(default = "rings")]
    pub rings: u32,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct CylinderSpec {
    pub radius: f32,
    pub height: f32,
    #[serde(default = "segments")]
    pub segments: u32,
    #[serde(default = "yes")]
    pub caps: bool,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct TorusSpec {
    pub major_radius: f32,
    pub minor_radius: f32,
    #[serde(default = "segments")]
    pub major_segments: u32,
    #[serde(default = "rings")]
    pub minor_segments: u32,
}

fn tessellation() -> u32 {
    8
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct TeapotSpec {
    #[serde(default = "tessellation")]
    pub tessellation: u32,
    pub parts: Option<Vec<String>>,
}

#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct TransformSpec {
    #[serde(default)]
    pub translate: [f32; 3],
    #[serde(default)]
    pub rotate_degrees: [f32; 3],
    #[serde(default)]
    pub scale: ScaleSpec,
}

/// `scale = 2.0` or `scale = [1.0, 2.0, 1.0]`.
#[derive(Debug)]
pub(crate) enum ScaleSpec {
    Uniform(f32),
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

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct LensSpec {
    pub name: String,
    pub objects: Vec<String>,
    #[serde(default)]
    pub layers: Vec<LayerSpecFile>,
}

/// One layer shell of a lens object, centred on its EM origin: exactly one key.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct LayerSpecFile {
    pub sphere: Option<f32>,
    pub cylinder: Option<f32>,
    #[serde(rename = "box")]
    pub box_half_extents: Option<[f32; 3]>,
    pub ellipsoid: Option<[f32; 3]>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct ViewSpaceSpec {
    pub circle: Option<CircleSpec>,
    pub list: Option<Vec<[f32; 3]>>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct CircleSpec {
    pub centre: [f32; 3],
    pub radius: f32,
    #[serde(default)]
    pub height: f32,
    #[serde(default)]
    pub start_degrees: f32,
    pub step_degrees: f32,
    pub count: u32,
}
