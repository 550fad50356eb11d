//! Loading the environment at infinity and the materials: radiance (constant or a lat-long
//! EXR), glass, mirror and diffuse materials with their checker or image textures.

use std::collections::HashMap;

use glam::Vec3;

use super::{Loader, MAX_RADIANCE, Result};
use crate::scene::environment::{Environment, LatLongMap};
use crate::scene::file::{DiffuseSpec, EnvironmentSpec, GlossySpec, MaterialSpec};
use crate::scene::image_file::load_linear_rgb;
use crate::scene::material::{Coat, Glossy, ImageTexture, Material, Texture};

impl Loader<'_> {
    pub(super) fn environment(&self, spec: &EnvironmentSpec) -> Result<Environment> {
        if let Some(studio) = &spec.studio {
            if spec.constant.is_some() || spec.latlong.is_some() {
                return Err(self.error(
                    "environment",
                    "names studio and another environment",
                    "keep one of constant, latlong and studio",
                ));
            }
            if !(8..=8192).contains(&studio.width) {
                return Err(self.error(
                    "environment.studio.width",
                    format!("{} texels is out of range", studio.width),
                    "give a width in [8, 8192], e.g. 512",
                ));
            }
            let scale = spec_scale(self, "environment.studio.scale", studio.scale)?;
            let mut map = crate::scene::environment::studio(studio.width);
            map.texels.iter_mut().for_each(|t| *t *= scale);
            return Ok(Environment::LatLong(map));
        }
        match (&spec.constant, &spec.latlong) {
            (Some(colour), None) => Ok(Environment::Constant(self.colour(
                "environment.constant",
                *colour,
                None,
            )?)),
            (None, Some(latlong)) => {
                let scale = spec_scale(self, "environment.latlong.scale", latlong.scale)?;
                let path = self.resolve(&latlong.path);
                let image = load_linear_rgb(&path).map_err(|problem| {
                    self.error("environment.latlong.path", format!("{}: {problem}", path.display()), "give a readable lat-long EXR with finite, non-negative radiance (relative paths start at the scene file's folder)")
                })?;
                let brightest = image
                    .texels
                    .iter()
                    .map(|t| t.max_element())
                    .fold(0.0, f32::max);
                if brightest * scale > MAX_RADIANCE {
                    let field = if brightest > MAX_RADIANCE {
                        "environment.latlong.path"
                    } else {
                        "environment.latlong.scale"
                    };
                    return Err(self.error(
                        field,
                        format!(
                            "{}: the brightest texel {brightest:e} times scale {scale} is beyond the {MAX_RADIANCE:e} a radiance may be",
                            path.display()
                        ),
                        "give a smaller scale, or divide the image's texels",
                    ));
                }
                Ok(Environment::LatLong(LatLongMap {
                    width: image.width,
                    height: image.height,
                    texels: image.texels.into_iter().map(|t| t * scale).collect(),
                }))
            }
            _ => Err(self.error(
                "environment",
                "needs exactly one of constant, latlong and studio",
                "write constant = [r, g, b], latlong = { path = \"sky.exr\" } or studio = {}",
            )),
        }
    }

    pub(super) fn materials(
        &self,
        specs: &[MaterialSpec],
    ) -> Result<(Vec<Material>, HashMap<String, usize>)> {
        let mut index = HashMap::new();
        let mut materials = Vec::with_capacity(specs.len());
        for (i, spec) in specs.iter().enumerate() {
            let field = format!("materials[{i}]");
            let used = index.insert(spec.name.clone(), i).is_some();
            self.check_name(&field, &spec.name, used, "material")?;
            let kinds = [
                spec.glass.is_some(),
                spec.mirror.is_some(),
                spec.diffuse.is_some(),
                spec.glossy.is_some(),
            ];
            let not_one = || {
                self.error(
                    &field,
                    format!(
                        "material \"{}\" needs exactly one of glass, mirror, diffuse or glossy",
                        spec.name
                    ),
                    "keep one of glass = { ... }, mirror = { ... }, diffuse = { ... }, glossy = { ... }",
                )
            };
            let material = match (&spec.glass, &spec.mirror, &spec.diffuse, &spec.glossy) {
                _ if kinds.iter().filter(|&&k| k).count() != 1 => return Err(not_one()),
                (Some(glass), ..) => {
                    let ior = glass.ior;
                    if !(ior.is_finite() && ior > 0.0) {
                        return Err(self.error(
                            format!("{field}.glass.ior"),
                            format!("index of refraction {ior} is not > 0"),
                            "give the glass's index of refraction, e.g. 1.5",
                        ));
                    }
                    let absorption = Vec3::from_array(glass.absorption);
                    if !(absorption.is_finite()
                        && absorption.min_element() > 0.0
                        && absorption.max_element() <= 1.0)
                    {
                        return Err(self.error(format!("{field}.glass.absorption"), format!("{:?} is outside (0, 1]", glass.absorption), "give the transmittance per metre per channel in (0, 1] (1 = clear glass)"));
                    }
                    Material::Glass { ior, absorption }
                }
                (_, Some(mirror), ..) => Material::Mirror {
                    reflectance: self.colour(
                        &format!("{field}.mirror.reflectance"),
                        mirror.reflectance,
                        Some(1.0),
                    )?,
                },
                (_, _, Some(diffuse), _) => self.diffuse(&format!("{field}.diffuse"), diffuse)?,
                (.., Some(glossy)) => self.glossy(&format!("{field}.glossy"), glossy)?,
                (None, None, None, None) => return Err(not_one()),
            };
            materials.push(material);
        }
        Ok((materials, index))
    }

    pub(super) fn glossy(&self, field: &str, spec: &GlossySpec) -> Result<Material> {
        let diffuse = self.colour(&format!("{field}.diffuse"), spec.diffuse, Some(1.0))?;
        let specular = self.colour(&format!("{field}.specular"), spec.specular, Some(1.0))?;
        // With room for the f32 rounding of two decimals that sum to 1.
        if (diffuse + specular).max_element() > 1.0 + 1e-6 {
            return Err(self.error(
                field,
                format!("diffuse + specular is {:?}, above 1 in a channel", (diffuse + specular).to_array()),
                "lower diffuse or specular so that their sum is at most 1 per channel (the light a surface reflects)",
            ));
        }
        let exponent_in = |name: &str, exponent: f32| {
            if (1.0..=MAX_EXPONENT).contains(&exponent) {
                Ok(exponent)
            } else {
                Err(self.error(
                    format!("{field}.{name}"),
                    format!("{exponent} is outside [1, {MAX_EXPONENT}]"),
                    "give a Phong exponent of at least 1 (broad) and at most 100000 (near a mirror)",
                ))
            }
        };
        let exponent = match spec.exponent {
            Some(exponent) => exponent_in("exponent", exponent)?,
            None if specular == Vec3::ZERO => 1.0,
            None => {
                return Err(self.error(
                    field,
                    "has a specular lobe but no exponent",
                    "add exponent = N (the Phong exponent, e.g. 40)",
                ));
            }
        };
        let coat = match &spec.coat {
            None => None,
            Some(coat) => {
                if !(coat.ior > 1.0 && coat.ior <= 3.0) {
                    return Err(self.error(
                        format!("{field}.coat.ior"),
                        format!("index of refraction {} is outside (1, 3]", coat.ior),
                        "give the clear coat's index of refraction, e.g. 1.5",
                    ));
                }
                Some(Coat {
                    ior: coat.ior,
                    exponent: exponent_in("coat.exponent", coat.exponent)?,
                })
            }
        };
        Ok(Material::Glossy(Glossy {
            diffuse,
            specular,
            exponent,
            coat,
        }))
    }

    pub(super) fn diffuse(&self, field: &str, spec: &DiffuseSpec) -> Result<Material> {
        let texture = match (&spec.checker, &spec.image) {
            (Some(checker), None) => Some(Texture::Checker {
                a: self.colour(&format!("{field}.checker.a"), checker.a, Some(1.0))?,
                b: self.colour(&format!("{field}.checker.b"), checker.b, Some(1.0))?,
                scale: self.positive(
                    &format!("{field}.checker.scale"),
                    checker.scale,
                    "squares per uv unit",
                )?,
            }),
            (None, Some(image)) => {
                let path = self.resolve(image);
                let image = load_linear_rgb(&path).map_err(|problem| {
                    self.error(format!("{field}.image"), format!("{}: {problem}", path.display()), "give a readable PNG or EXR with finite, non-negative texels (relative paths start at the scene file's folder)")
                })?;
                Some(Texture::Image(ImageTexture {
                    width: image.width,
                    height: image.height,
                    texels: image.texels,
                }))
            }
            (None, None) => None,
            (Some(_), Some(_)) => {
                return Err(self.error(field, "has both checker and image", "keep one texture"));
            }
        };
        let colour = match spec.colour {
            Some(colour) => self.colour(&format!("{field}.colour"), colour, Some(1.0))?,
            None if texture.is_some() => Vec3::ONE,
            None => {
                return Err(self.error(field, "has neither colour nor a texture", "add colour = [r, g, b] (albedo in [0, 1]), checker = { ... } or image = \"file.png\""));
            }
        };
        Ok(Material::Diffuse { colour, texture })
    }
}

/// The largest Phong exponent a glossy material may have (a lobe about 0.3° wide).
const MAX_EXPONENT: f32 = 100_000.0;

/// Checks a lat-long scale factor.
fn spec_scale(loader: &Loader<'_>, field: &str, scale: f32) -> Result<f32> {
    if scale.is_finite() && scale >= 0.0 {
        Ok(scale)
    } else {
        Err(loader.error(
            field,
            format!("{scale} is not a finite number ≥ 0"),
            "give a radiance multiplier ≥ 0 (1 = as stored)",
        ))
    }
}
