//! The canonical encoding of a scene's content (see [`crate::identity`]): every value a bake
//! depends on, each enum variant under a fixed tag, each struct destructured whole so that a new
//! field cannot be left out unnoticed.

use crate::identity::{Canonical, Encoder};

use super::{
    Environment, ImageTexture, LatLongMap, LayerSpec, LensObject, Material, PointLight,
    SceneObject, Texture, TriangleMesh, ViewSpace,
};

impl Canonical for TriangleMesh {
    fn encode(&self, encoder: &mut Encoder) {
        let TriangleMesh {
            positions,
            normals,
            uvs,
            triangles,
        } = self;
        encoder
            .value(positions)
            .value(normals)
            .value(uvs)
            .value(triangles);
    }
}

impl Canonical for SceneObject {
    fn encode(&self, encoder: &mut Encoder) {
        let SceneObject {
            name,
            mesh,
            material,
        } = self;
        encoder.value(name).value(mesh).value(material);
    }
}

impl Canonical for ImageTexture {
    fn encode(&self, encoder: &mut Encoder) {
        let ImageTexture {
            width,
            height,
            texels,
        } = self;
        encoder.value(width).value(height).value(texels);
    }
}

impl Canonical for Texture {
    fn encode(&self, encoder: &mut Encoder) {
        match self {
            Texture::Checker { a, b, scale } => encoder.tag(0).value(a).value(b).value(scale),
            Texture::Image(image) => encoder.tag(1).value(image),
        };
    }
}

impl Canonical for Material {
    fn encode(&self, encoder: &mut Encoder) {
        match self {
            Material::Glass { ior, absorption } => encoder.tag(0).value(ior).value(absorption),
            Material::Mirror { reflectance } => encoder.tag(1).value(reflectance),
            Material::Diffuse { colour, texture } => encoder.tag(2).value(colour).value(texture),
            Material::Glossy(glossy) => {
                let encoder = encoder
                    .tag(3)
                    .value(&glossy.diffuse)
                    .value(&glossy.specular)
                    .value(&glossy.exponent);
                match &glossy.coat {
                    None => encoder.tag(0),
                    Some(coat) => encoder.tag(1).value(&coat.ior).value(&coat.exponent),
                }
            }
        };
    }
}

impl Canonical for PointLight {
    fn encode(&self, encoder: &mut Encoder) {
        let PointLight {
            position,
            intensity,
        } = self;
        encoder.value(position).value(intensity);
    }
}

impl Canonical for LatLongMap {
    fn encode(&self, encoder: &mut Encoder) {
        let LatLongMap {
            width,
            height,
            texels,
        } = self;
        encoder.value(width).value(height).value(texels);
    }
}

impl Canonical for Environment {
    fn encode(&self, encoder: &mut Encoder) {
        match self {
            Environment::Constant(colour) => encoder.tag(0).value(colour),
            Environment::LatLong(map) => encoder.tag(1).value(map),
        };
    }
}

impl Canonical for LayerSpec {
    fn encode(&self, encoder: &mut Encoder) {
        match self {
            LayerSpec::Sphere(radius) => encoder.tag(0).value(radius),
            LayerSpec::Cylinder(radius) => encoder.tag(1).value(radius),
            LayerSpec::Box(half_extents) => encoder.tag(2).value(half_extents),
            LayerSpec::Ellipsoid(radii) => encoder.tag(3).value(radii),
        };
    }
}

impl Canonical for LensObject {
    fn encode(&self, encoder: &mut Encoder) {
        let LensObject {
            name,
            objects,
            layers,
            layering,
            // How frames shade it, not what its maps hold: a bake's terms are its own option
            // (`bake --terms`, in the bake's identity), which the scene file's do not set.
            terms: _,
        } = self;
        encoder.value(name).value(objects).value(layers);
        // Came after identity version 1: by distance, what every earlier scene meant, writes
        // nothing, so their identities stand.
        if *layering == crate::layers::Layering::Bounce {
            encoder.tag(1);
        }
    }
}

impl Canonical for ViewSpace {
    fn encode(&self, encoder: &mut Encoder) {
        match self {
            ViewSpace::Circle {
                centre,
                radius,
                height,
                start_radians,
                step_radians,
                count,
            } => encoder
                .tag(0)
                .value(centre)
                .value(radius)
                .value(height)
                .value(start_radians)
                .value(step_radians)
                .value(count),
            ViewSpace::List(positions) => encoder.tag(1).value(positions),
            ViewSpace::Patch {
                centre,
                radius,
                azimuth_radians,
                azimuth_count,
                elevation_radians,
                elevation_count,
            } => encoder
                .tag(2)
                .value(centre)
                .value(radius)
                .value(azimuth_radians)
                .value(azimuth_count)
                .value(elevation_radians)
                .value(elevation_count),
            ViewSpace::Cap {
                centre,
                radius,
                axis,
                half_angle_radians,
                count,
            } => encoder
                .tag(3)
                .value(centre)
                .value(radius)
                .value(axis)
                .value(half_angle_radians)
                .value(count),
        };
    }
}

#[cfg(test)]
mod tests {
    use std::path::Path;

    use crate::scene::Scene;

    /// A small scene with every kind of value the identity encodes: a glass and a mirror lens
    /// object, a textured diffuse floor, a light, a constant sky, named layer shells and a circle
    /// of viewpoint samples.
    const PINNED_SCENE: &str = r#"
name = "pinned"

[camera]
position = [0.0, 1.0, 4.0]
look_at = [0.0, 0.5, 0.0]
vfov_degrees = 40.0
width = 32
height = 24

[environment]
constant = [0.25, 0.5, 1.0]

[[lights]]
position = [1.0, 3.0, 2.0]
intensity = [5.0, 5.0, 5.0]

[[materials]]
name = "glass"
glass = { ior = 1.5, absorption = [0.9, 0.95, 1.0] }

[[materials]]
name = "silver"
mirror = { reflectance = [0.9, 0.9, 0.9] }

[[materials]]
name = "floor"
diffuse = { checker = { a = [0.8, 0.8, 0.8], b = [0.1, 0.1, 0.1], scale = 4 } }

[[objects]]
name = "ball"
material = "glass"
sphere = { radius = 0.5, segments = 12, rings = 6 }
transform = { translate = [0.0, 0.5, 0.0] }

[[objects]]
name = "plate"
material = "silver"
plane = { size = [0.5, 0.5] }
transform = { translate = [1.0, 0.2, 0.0] }

[[objects]]
name = "floor"
material = "floor"
plane = { size = [4.0, 4.0], subdivisions = 2 }

[[lenses]]
name = "ball"
objects = ["ball"]
layers = [{ sphere = 2.0 }, { box = [3.0, 3.0, 3.0] }]

[view_space]
circle = { centre = [0.0, 0.5, 0.0], radius = 4.0, height = 0.5, start_degrees = 0.0, step_degrees = 10.0, count = 4 }
"#;

    fn pinned() -> Scene {
        Scene::from_toml_str(PINNED_SCENE, Path::new("pinned.toml")).expect("the scene loads")
    }

    /// The identity of a fixed scene, pinned: a change here means every bake's scene identity
    /// moved, which needs a new [`crate::identity::IDENTITY_VERSION`].
    #[test]
    fn the_identity_of_a_fixed_scene_is_pinned() {
        assert_eq!(
            pinned().content_hash(),
            "2494a0c9fe014bbc4cef8b41ae389b471c86d1e4e56daab2a725447063293439"
        );
    }

    /// What the identity covers: the content a bake depends on, not where the camera stands or
    /// how large the image is.
    #[test]
    fn the_identity_covers_what_a_bake_depends_on() {
        let base = pinned().content_hash();
        let mut moved = pinned();
        moved.camera.position.x += 1.0;
        moved.camera.width = 64;
        moved.name = "renamed".into();
        assert_eq!(moved.content_hash(), base);
        let mut changed = pinned();
        changed.lights[0].intensity.x = 5.5;
        assert_ne!(changed.content_hash(), base);
        let mut aimed = pinned();
        aimed.camera.look_at.y = 0.75;
        assert_ne!(aimed.content_hash(), base);
    }
}
