//! Wavefront OBJ meshes through `tobj`: triangulated, one index per vertex, all groups merged into
//! one mesh; normals from the file or generated smooth.

use std::path::Path;

use glam::{Vec2, Vec3};

use super::mesh::TriangleMesh;

/// Reads every model of an OBJ file into one mesh (local space, not yet checked). Texture
/// coordinates are kept only if every model has them; normals are taken from the file where a
/// model has them and `smooth_normals` is false, and generated (angle-weighted smooth) otherwise.
pub(crate) fn load_obj(path: &Path, smooth_normals: bool) -> Result<TriangleMesh, String> {
    let options = tobj::LoadOptions {
        triangulate: true,
        single_index: true,
        ignore_points: true,
        ignore_lines: true,
    };
    // tobj reads `l a b c` (a polyline) as a triangle; a line element is no surface, so it is
    // refused here with its line number rather than turned into geometry.
    let text = std::fs::read_to_string(path).map_err(|e| e.to_string())?;
    if let Some(number) = text
        .lines()
        .position(|line| line.trim_start().starts_with("l ") || line.trim() == "l")
    {
        return Err(format!(
            "line {}: `l` (a polyline) is not a surface; lensmap reads faces (`f`) only, so remove the line or make it a face",
            number + 1
        ));
    }
    let (models, _materials) = tobj::load_obj(path, &options).map_err(|e| e.to_string())?;
    let mut mesh = TriangleMesh::default();
    let all_have_uvs = models
        .iter()
        .all(|m| !m.mesh.texcoords.is_empty() && !m.mesh.positions.is_empty());
    for model in &models {
        let source = &model.mesh;
        let positions: Vec<Vec3> = source
            .positions
            .chunks_exact(3)
            .map(Vec3::from_slice)
            .collect();
        let mut part = TriangleMesh {
            normals: if source.normals.len() == source.positions.len() && !smooth_normals {
                source
                    .normals
                    .chunks_exact(3)
                    .map(Vec3::from_slice)
                    .collect()
            } else {
                Vec::new()
            },
            uvs: if all_have_uvs {
                source
                    .texcoords
                    .chunks_exact(2)
                    .map(Vec2::from_slice)
                    .collect()
            } else {
                Vec::new()
            },
            triangles: source
                .indices
                .chunks_exact(3)
                .map(|t| [t[0], t[1], t[2]])
                .collect(),
            positions,
        };
        if part.normals.is_empty() {
            part.normals = vec![Vec3::ZERO; part.positions.len()];
        }
        mesh.append(&part);
        if !all_have_uvs {
            mesh.uvs.clear();
        }
    }
    Ok(mesh)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_polyline_is_refused_with_its_line() {
        let dir = std::env::temp_dir().join(format!("lensmap-obj-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("line.obj");
        std::fs::write(&path, "v 0 0 0\nv 1 0 0\nv 0 1 0\nl 1 2 3\n").unwrap();
        let error = load_obj(&path, false).unwrap_err();
        assert!(
            error.contains("line 4") && error.contains("polyline"),
            "{error}"
        );
        std::fs::write(&path, "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n").unwrap();
        assert_eq!(load_obj(&path, false).unwrap().triangles.len(), 1);
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
