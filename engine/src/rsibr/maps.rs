//! The glossy objects of a scene, the lobes their maps hold, and the maps of one view sample.

use std::sync::Arc;

use glam::DVec3;

use crate::cubemap::CubeMap;
use crate::scene::{Glossy, Material, Scene};
use crate::trace::radiance_map::{RadianceMap, RadianceMapRequest, Warp};
use crate::trace::{TraceCounters, TraceOptions, TraceScene};

/// The default face size of a radiance map, texels.
pub const DEFAULT_MAP_SIZE: u32 = 32;

/// The default directions sampled per texel.
pub const DEFAULT_MAP_SAMPLES: u32 = 256;

/// One lobe of a glossy BRDF, with a map of its own.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum MapLobe {
    /// The Lambertian base `kd/π`, warped by the normal.
    Diffuse,
    /// The base's Phong lobe, warped by the mirror direction.
    Specular,
    /// The coat's Phong lobe of reflectance 1, warped by the mirror direction; weighted by F at
    /// run time.
    Coat,
}

impl MapLobe {
    /// Every lobe, in map order.
    pub const ALL: [MapLobe; 3] = [MapLobe::Diffuse, MapLobe::Specular, MapLobe::Coat];

    /// The name files and reports use.
    pub fn name(self) -> &'static str {
        match self {
            MapLobe::Diffuse => "diffuse",
            MapLobe::Specular => "specular",
            MapLobe::Coat => "coat",
        }
    }

    /// The direction its map is indexed by.
    pub fn warp(self) -> Warp {
        match self {
            MapLobe::Diffuse => Warp::Normal,
            MapLobe::Specular | MapLobe::Coat => Warp::Mirror,
        }
    }

    /// The lobes of `brdf` that reflect anything, in map order.
    pub fn of(brdf: &Glossy) -> Vec<MapLobe> {
        let mut lobes = Vec::new();
        if brdf.diffuse.max_element() > 0.0 {
            lobes.push(MapLobe::Diffuse);
        }
        if brdf.specular.max_element() > 0.0 {
            lobes.push(MapLobe::Specular);
        }
        if brdf.coat.is_some() {
            lobes.push(MapLobe::Coat);
        }
        lobes
    }

    /// The BRDF of this lobe alone, without Fresnel: what its map integrates.
    pub fn brdf(self, brdf: &Glossy) -> Glossy {
        let alone = Glossy {
            diffuse: glam::Vec3::ZERO,
            specular: glam::Vec3::ZERO,
            exponent: brdf.exponent,
            coat: None,
        };
        match self {
            MapLobe::Diffuse => Glossy {
                diffuse: brdf.diffuse,
                ..alone
            },
            MapLobe::Specular => Glossy {
                specular: brdf.specular,
                ..alone
            },
            MapLobe::Coat => Glossy {
                specular: glam::Vec3::ONE,
                exponent: brdf.coat.map_or(1.0, |c| c.exponent),
                ..alone
            },
        }
    }

    /// The lobe's run-time weight where the pixel's view makes cosine `cos_view` with its
    /// normal: 1 − F for the base's lobes, F for the coat's (F the coat's exact dielectric
    /// reflectance; 0 without a coat).
    pub fn weight(self, brdf: &Glossy, cos_view: f64) -> f64 {
        let fresnel = brdf.coat.map_or(0.0, |coat| {
            crate::trace::fresnel::dielectric(cos_view.clamp(0.0, 1.0), 1.0, f64::from(coat.ior))
                .reflectance
        });
        match self {
            MapLobe::Coat => fresnel,
            _ => 1.0 - fresnel,
        }
    }
}

/// A glossy object of a scene, as its maps see it.
#[derive(Clone, Debug, PartialEq)]
pub struct GlossyObject {
    /// Index into [`Scene::objects`].
    pub object: usize,
    /// The object's name.
    pub name: String,
    /// Its BRDF.
    pub brdf: Glossy,
    /// The lobes its maps hold ([`MapLobe::of`]).
    pub lobes: Vec<MapLobe>,
    /// The centre of its bounding box: where the maps' surface elements are.
    pub centre: DVec3,
    /// The radius about `centre` holding every vertex: the rays of its maps start on this sphere,
    /// so the object never shadows or reflects itself in them.
    pub radius: f64,
}

/// The glossy objects of `scene`, in object order (those whose BRDF reflects nothing left out).
pub fn glossy_objects(scene: &Scene) -> Vec<GlossyObject> {
    scene
        .objects
        .iter()
        .enumerate()
        .filter_map(|(object, o)| {
            let Material::Glossy(brdf) = scene.materials[o.material] else {
                return None;
            };
            let (lo, hi) = o.mesh.bounds()?;
            let centre = ((lo + hi) * 0.5).as_dvec3();
            let radius = o
                .mesh
                .positions
                .iter()
                .map(|p| p.as_dvec3().distance(centre))
                .fold(0.0, f64::max);
            let lobes = MapLobe::of(&brdf);
            (!lobes.is_empty()).then(|| GlossyObject {
                object,
                name: o.name.clone(),
                brdf,
                lobes,
                centre,
                // A hair outside the outermost vertex, relative to the coordinates' magnitude.
                radius: radius + 1e-6 * centre.abs().max_element().max(radius).max(1.0),
            })
        })
        .collect()
}

/// How radiance maps are computed.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct RadianceMapOptions {
    /// Face size, texels (rounded up to a power of two).
    pub size: u32,
    /// Directions sampled per texel (≥ 2).
    pub samples: u32,
    /// Seed of the samples; each map's is this mixed with its object, sample and lobe.
    pub seed: u64,
    /// View samples: one of [`super::views::GEODESIC_COUNTS`].
    pub views: usize,
}

impl Default for RadianceMapOptions {
    fn default() -> Self {
        RadianceMapOptions {
            size: DEFAULT_MAP_SIZE,
            samples: DEFAULT_MAP_SAMPLES,
            seed: 0,
            views: super::views::DEFAULT_VIEW_COUNT,
        }
    }
}

/// One glossy object's radiance maps: `maps[sample][lobe]`, lobes as [`GlossyObject::lobes`].
#[derive(Clone, Debug, PartialEq)]
pub struct GlossyMaps {
    /// The object.
    pub object: GlossyObject,
    /// The maps, by view sample, then lobe.
    pub maps: Vec<Vec<Arc<CubeMap>>>,
}

/// The maps of `object` at view sample `sample` (unit direction `view`), one per lobe, with the
/// largest texel standard error over them and the rays traced.
pub fn sample_maps(
    trace: &TraceScene,
    object: &GlossyObject,
    sample: usize,
    view: DVec3,
    options: &RadianceMapOptions,
) -> (Vec<RadianceMap>, TraceCounters) {
    let trace_options = TraceOptions::default();
    let mut counters = TraceCounters::default();
    let maps = object
        .lobes
        .iter()
        .enumerate()
        .map(|(k, lobe)| {
            let map = trace.radiance_map(
                &RadianceMapRequest {
                    centre: object.centre,
                    radius: object.radius,
                    view,
                    brdf: lobe.brdf(&object.brdf),
                    warp: lobe.warp(),
                    size: options.size,
                    samples: options.samples,
                    seed: map_seed(options.seed, object.object, sample, k),
                },
                &trace_options,
            );
            counters += map.counters;
            map
        })
        .collect();
    (maps, counters)
}

/// The seed of one map: `seed`, the object, the sample and the lobe hashed together, so that
/// every map (and every `seed`) draws its own stream.
fn map_seed(seed: u64, object: usize, sample: usize, lobe: usize) -> u64 {
    use std::hash::Hasher;
    let mut hasher = rustc_hash::FxHasher::default();
    for value in [seed, object as u64, sample as u64, lobe as u64] {
        hasher.write_u64(value);
    }
    hasher.finish()
}

/// Every map of `object` at every sample of `views`.
pub fn all_maps(
    trace: &TraceScene,
    object: &GlossyObject,
    views: &super::GlossyViews,
    options: &RadianceMapOptions,
) -> (GlossyMaps, TraceCounters) {
    let mut counters = TraceCounters::default();
    let maps = views
        .directions()
        .iter()
        .enumerate()
        .map(|(sample, &view)| {
            let (maps, c) = sample_maps(trace, object, sample, view, options);
            counters += c;
            maps.into_iter().map(|m| Arc::new(m.map)).collect()
        })
        .collect();
    (
        GlossyMaps {
            object: object.clone(),
            maps,
        },
        counters,
    )
}
