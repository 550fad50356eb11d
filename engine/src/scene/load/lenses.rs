//! Loading the lens objects: the glass and mirror objects each `[[lenses]]` entry names, its
//! layer shells, and a lens object of its own for every glass or mirror object no entry names.

use std::collections::HashMap;

use glam::Vec3;

use super::{Loader, Result, sorted_list};
use crate::layers::Layering;
use crate::scene::file::{LensSpec, SceneFile, TermsSpec};
use crate::scene::material::Material;
use crate::scene::{LayerSpec, LensObject, SceneObject};
use crate::trace::classes::ClassSet;

impl Loader<'_> {
    pub(super) fn lenses(
        &self,
        file: &SceneFile,
        objects: &[SceneObject],
        materials: &[Material],
    ) -> Result<Vec<LensObject>> {
        let object_index: HashMap<&str, usize> = objects
            .iter()
            .enumerate()
            .map(|(i, o)| (o.name.as_str(), i))
            .collect();
        let mut owner: Vec<Option<usize>> = vec![None; objects.len()];
        let mut lenses: Vec<LensObject> = Vec::new();
        for (l, spec) in file.lenses.iter().enumerate() {
            let field = format!("lenses[{l}]");
            let used = lenses.iter().any(|lens| lens.name == spec.name);
            self.check_name(&field, &spec.name, used, "lens object")?;
            if spec.objects.is_empty() {
                return Err(self.error(
                    format!("{field}.objects"),
                    "the lens has no objects",
                    "name the glass or mirror [[objects]] that form it",
                ));
            }
            let mut members = Vec::with_capacity(spec.objects.len());
            for (k, name) in spec.objects.iter().enumerate() {
                let member_field = format!("{field}.objects[{k}]");
                let Some(&object) = object_index.get(name.as_str()) else {
                    return Err(self.error(
                        member_field,
                        format!("no object is named \"{name}\""),
                        format!(
                            "name one of the [[objects]]: {}",
                            sorted_list(object_index.keys().copied().collect())
                        ),
                    ));
                };
                let material = &materials[objects[object].material];
                if !material.is_lens() {
                    return Err(self.error(member_field, format!("object \"{name}\" is {}, but a lens is made of glass or mirror objects", material.kind()), "give the object a glass or mirror material, or leave it out of the lens"));
                }
                if let Some(other) = owner[object] {
                    return Err(self.error(
                        member_field,
                        format!(
                            "object \"{name}\" is already part of lens \"{}\"",
                            file.lenses[other].name
                        ),
                        "put each object in one lens only",
                    ));
                }
                owner[object] = Some(l);
                members.push(object);
            }
            let mut layers = Vec::with_capacity(spec.layers.len());
            for (k, layer) in spec.layers.iter().enumerate() {
                let layer_field = format!("{field}.layers[{k}]");
                let positive = |v: f32| v.is_finite() && v > 0.0;
                let parsed = match (
                    layer.sphere,
                    layer.cylinder,
                    layer.box_half_extents,
                    layer.ellipsoid,
                ) {
                    (Some(r), None, None, None) if positive(r) => LayerSpec::Sphere(r),
                    (None, Some(r), None, None) if positive(r) => LayerSpec::Cylinder(r),
                    (None, None, Some(h), None) if h.iter().all(|v| positive(*v)) => {
                        LayerSpec::Box(Vec3::from(h))
                    }
                    (None, None, None, Some(r)) if r.iter().all(|v| positive(*v)) => {
                        LayerSpec::Ellipsoid(Vec3::from(r))
                    }
                    _ => {
                        return Err(self.error(
                            layer_field,
                            "a layer needs exactly one of sphere, cylinder, box, ellipsoid with positive finite sizes",
                            "write e.g. { sphere = 3.0 }, { cylinder = 6.0 }, { box = [8, 4, 8] } or { ellipsoid = [2, 1, 2] } (metres)",
                        ));
                    }
                };
                layers.push(parsed);
            }
            let layering = self.layering(&field, spec, &members, objects, materials)?;
            let terms = self.terms(&field, spec)?;
            if terms.is_some() && layering == Layering::Bounce {
                return Err(self.error(
                    format!("{field}.terms"),
                    "path classes follow a path until it leaves, but a lens layered by bounce stops at the first bounce",
                    "leave terms out (greedy), or layering out (by distance)",
                ));
            }
            let glass =
                |o: &usize| matches!(materials[objects[*o].material], Material::Glass { .. });
            if matches!(terms, Some(ClassSet::First(_)))
                && members.iter().any(glass)
                && !members.iter().all(glass)
            {
                return Err(self.error(
                    format!("{field}.terms"),
                    "a count takes the first classes of glass (R, TT, TRT, …) or of a mirror (R, RR, …), but this lens joins glass and mirrors",
                    "list the classes instead, e.g. [\"R\", \"TT\", \"TRT\", \"RR\"]",
                ));
            }
            lenses.push(LensObject {
                name: spec.name.clone(),
                objects: members,
                layers,
                layering,
                terms,
            });
        }
        // Glass and mirror objects that no lens names become lenses of their own.
        for (i, object) in objects.iter().enumerate() {
            if owner[i].is_none() && materials[object.material].is_lens() {
                if lenses.iter().any(|lens| lens.name == object.name) {
                    return Err(self.error(format!("objects[{i}]"), format!("glass/mirror object \"{}\" is in no lens, and a lens with its name already exists", object.name), "add the object to a [[lenses]] entry"));
                }
                lenses.push(LensObject {
                    name: object.name.clone(),
                    objects: vec![i],
                    layers: Vec::new(),
                    layering: Layering::Distance,
                    terms: None,
                });
            }
        }
        Ok(lenses)
    }

    /// A lens entry's `terms`: "greedy" (the default), a count of path classes (`4` or "4"), a
    /// list ("R,TT,TRT" or `["R", "TT", "TRT"]`) or "greedy:D" ([`ClassSet::parse`]).
    fn terms(&self, field: &str, spec: &LensSpec) -> Result<Option<ClassSet>> {
        let text = match &spec.terms {
            None => return Ok(None),
            Some(TermsSpec::Count(n)) => n.to_string(),
            Some(TermsSpec::Text(text)) if text.trim() == "greedy" => return Ok(None),
            Some(TermsSpec::Text(text)) => text.clone(),
            Some(TermsSpec::List(list)) => list.join(","),
        };
        ClassSet::parse(&text).map(Some).map_err(|problem| {
            self.error(
                format!("{field}.terms"),
                problem,
                "write \"greedy\", a count such as 4, or a list such as [\"R\", \"TT\", \"TRT\", \"TRRT\"]",
            )
        })
    }

    /// A lens entry's `layering`: "distance" (the default) or "bounce", which is for reflectors
    /// (the local layer holds what a mirror reflects of itself) and fits its own shells.
    fn layering(
        &self,
        field: &str,
        spec: &LensSpec,
        members: &[usize],
        objects: &[SceneObject],
        materials: &[Material],
    ) -> Result<Layering> {
        let field = format!("{field}.layering");
        let layering = match spec.layering.as_deref() {
            None | Some("distance") => return Ok(Layering::Distance),
            Some("bounce") => Layering::Bounce,
            Some(other) => {
                return Err(self.error(
                    field,
                    format!("\"{other}\" is not a layering"),
                    "write \"distance\" (layers by hit distance, the default) or \"bounce\" (the PEM paper's local and distant layers, for mirrors)",
                ));
            }
        };
        if let Some(&glass) = members
            .iter()
            .find(|&&o| !matches!(materials[objects[o].material], Material::Mirror { .. }))
        {
            return Err(self.error(
                field,
                format!(
                    "layers by bounce are for reflectors, but object \"{}\" is {}",
                    objects[glass].name,
                    materials[objects[glass].material].kind()
                ),
                "leave layering out (by distance) for a lens with glass",
            ));
        }
        if !spec.layers.is_empty() {
            return Err(self.error(
                field,
                "a lens layered by bounce gets its shells fitted by the baker, but it also lists layers",
                "remove either `layers` or `layering = \"bounce\"`",
            ));
        }
        Ok(layering)
    }
}
