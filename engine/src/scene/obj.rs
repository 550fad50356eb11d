//! Wavefront OBJ meshes: every polygon face triangulated by ear clipping, one index per vertex,
//! all groups merged into one mesh; normals from the file or generated smooth.
//!
//! Read here, not through `tobj` (which the project used before): tobj triangulates a polygon as
//! a fan, which covers the wrong area for a concave face (assimp's 66-gon test polygon: a fan
//! covers 7× its area), and its errors name no line. Here every record is read in one pass and
//! every error names its line and quotes its record. Faces of more than three corners go to
//! `earcut` (mapbox's ear clipping, georust's port) in the plane of the face's Newell normal.

use std::collections::HashMap;
use std::path::Path;

use glam::{DVec3, Vec2, Vec3};

use super::mesh::TriangleMesh;

/// A mesh read from an OBJ file and what was accepted with a fallback, one line each.
#[derive(Debug, Default)]
pub(crate) struct ObjMesh {
    /// The mesh in the file's space, not yet checked.
    pub mesh: TriangleMesh,
    /// The line of the face each triangle comes from (1-based), for messages about a triangle.
    pub lines: Vec<usize>,
    /// Records read with a fallback (an empty `usemtl`, a keyword lensmap does not know).
    pub warnings: Vec<String>,
}

/// The most corners a face may have: far above any modelling tool's output, and small enough
/// that ear clipping one face stays quick (it is quadratic in the worst case).
pub const MAX_FACE_CORNERS: usize = 65_536;

/// Relative difference between a face's triangles' area and its polygon's (shoelace) area above
/// which the polygon is refused as self-intersecting: ear clipping a simple polygon reproduces
/// its area to rounding (about 1e-15 relative in f64).
const AREA_TOLERANCE: f64 = 1e-7;

/// Records that describe free-form geometry (curves and surfaces), which lensmap cannot draw.
const FREE_FORM: &[&str] = &[
    "vp", "cstype", "deg", "bmat", "step", "curv", "curv2", "surf", "parm", "trim", "hole", "scrv",
    "sp", "end", "con",
];

/// Records with no effect on the mesh lensmap draws: groups, smoothing groups, objects, and
/// materials and render attributes (a scene file gives each object its material).
const NO_EFFECT: &[&str] = &[
    "g",
    "o",
    "s",
    "mg",
    "mtllib",
    "usemtl",
    "maplib",
    "usemap",
    "lod",
    "bevel",
    "c_interp",
    "d_interp",
    "shadow_obj",
    "trace_obj",
    "ctech",
    "stech",
];

/// Reads an OBJ file (UTF-8, or UTF-16 with a byte-order mark) into one mesh. Texture
/// coordinates are kept only if every face corner has one; a corner's normal is the file's
/// where it has one and `smooth_normals` is false, and zero otherwise (generated smooth later).
pub(crate) fn load_obj(path: &Path, smooth_normals: bool) -> Result<ObjMesh, String> {
    let bytes = std::fs::read(path).map_err(|e| e.to_string())?;
    parse_obj(&decode(&bytes)?, smooth_normals)
}

/// The text of an OBJ file's bytes: UTF-8 (a byte-order mark dropped), or UTF-16 in either
/// byte order where a byte-order mark says so.
fn decode(bytes: &[u8]) -> Result<String, String> {
    let utf16 = |big: bool| {
        let units: Vec<u16> = bytes[2..]
            .chunks(2)
            .map(|p| {
                let pair = [p[0], p.get(1).copied().unwrap_or(0)];
                if big {
                    u16::from_be_bytes(pair)
                } else {
                    u16::from_le_bytes(pair)
                }
            })
            .collect();
        String::from_utf16(&units)
            .map_err(|_| "not valid UTF-16 text after its byte-order mark".to_owned())
    };
    match bytes {
        [0xFE, 0xFF, ..] => utf16(true),
        [0xFF, 0xFE, ..] => utf16(false),
        [0xEF, 0xBB, 0xBF, rest @ ..] => Ok(text_of(rest)),
        _ => Ok(text_of(bytes)),
    }
}

/// UTF-8 text; bytes that are not (a Latin-1 group or material name, as old exporters write)
/// become U+FFFD. Records are ASCII: such bytes can stand only in names and comments, which carry
/// nothing lensmap reads, or in a number, which is then refused naming its line.
fn text_of(bytes: &[u8]) -> String {
    String::from_utf8_lossy(bytes).into_owned()
}

/// One face corner: its position, texture coordinate and normal indices (0-based).
type Corner = (u32, Option<u32>, Option<u32>);

/// The reader's state: the records read so far and the mesh being built.
#[derive(Default)]
struct Reader {
    positions: Vec<DVec3>,
    uvs: Vec<Vec2>,
    normals: Vec<Vec3>,
    /// Mesh vertex of each distinct corner.
    vertices: HashMap<Corner, u32>,
    corners: Vec<Corner>,
    triangles: Vec<[u32; 3]>,
    /// The line of each triangle's face.
    lines: Vec<usize>,
    warnings: Vec<String>,
    earcut: earcut::Earcut<f64>,
}

/// Parses OBJ text (see [`load_obj`]).
pub(crate) fn parse_obj(text: &str, smooth_normals: bool) -> Result<ObjMesh, String> {
    let mut reader = Reader::default();
    let mut unknown: Vec<String> = Vec::new();
    for (number, record) in records(text) {
        let at = |problem: String| format!("line {number} (`{}`): {problem}", quote(&record));
        let mut words = record.split_whitespace();
        let Some(keyword) = words.next() else {
            continue;
        };
        let words: Vec<&str> = words.collect();
        match keyword {
            "v" => {
                let p = numbers(&words, 3, 4, "x y z [w]")
                    .or_else(|e| numbers(&words, 6, 6, "x y z r g b").map_err(|_| e))
                    .map_err(at)?;
                reader.positions.push(DVec3::new(p[0], p[1], p[2]));
            }
            "vt" => {
                let t = numbers(&words, 1, 3, "u [v [w]]").map_err(at)?;
                reader
                    .uvs
                    .push(Vec2::new(t[0] as f32, t.get(1).copied().unwrap_or(0.0) as f32));
            }
            "vn" => {
                let n = numbers(&words, 3, 3, "x y z").map_err(at)?;
                reader
                    .normals
                    .push(Vec3::new(n[0] as f32, n[1] as f32, n[2] as f32));
            }
            "f" | "fo" => {
                reader.face(&words).map_err(at)?;
                reader.lines.resize(reader.triangles.len(), number);
            }
            "l" => {
                return Err(at(
                    "`l` (a polyline) is not a surface; lensmap reads faces (`f`) only, so remove the line or make it a face".into(),
                ));
            }
            "p" => {
                return Err(at(
                    "`p` (points) is not a surface; lensmap reads faces (`f`) only, so remove the line".into(),
                ));
            }
            "usemtl" if words.is_empty() => reader.warnings.push(format!(
                "line {number}: `usemtl` names no material; its faces take the object's material, as every face does (a scene file gives each object its material)"
            )),
            k if NO_EFFECT.contains(&k) => {}
            k if FREE_FORM.contains(&k) => {
                return Err(at(format!(
                    "`{k}` is free-form geometry (curves and surfaces), which lensmap cannot draw; export the mesh as polygons"
                )));
            }
            k => {
                if !unknown.iter().any(|u| u == k) {
                    unknown.push(k.to_owned());
                    reader.warnings.push(format!(
                        "line {number}: `{}` is not an OBJ record lensmap knows; lines starting with it are skipped",
                        quote(k)
                    ));
                }
            }
        }
    }
    Ok(reader.finish(smooth_normals))
}

/// The file's records with the number of the line each starts on: comments (from `#`) removed
/// and lines ending in `\` joined to the next, as the OBJ format says.
fn records(text: &str) -> Vec<(usize, String)> {
    let mut out = Vec::new();
    let mut pending: Option<(usize, String)> = None;
    for (i, line) in text.lines().enumerate() {
        let line = line.split('#').next().unwrap_or("");
        let (body, continues) = match line.trim_end().strip_suffix('\\') {
            Some(body) => (body, true),
            None => (line, false),
        };
        let (number, mut record) = pending.take().unwrap_or((i + 1, String::new()));
        record.push(' ');
        record.push_str(body);
        if continues {
            pending = Some((number, record));
        } else {
            out.push((number, record));
        }
    }
    out.extend(pending);
    out
}

/// A record as an error quotes it: trimmed, and cut short past 80 characters.
fn quote(record: &str) -> String {
    let record = record.trim();
    match record.char_indices().nth(80) {
        Some((at, _)) => format!("{}…", &record[..at]),
        None => record.to_owned(),
    }
}

/// `min` to `max` numbers, as the record's `form` says.
fn numbers(words: &[&str], min: usize, max: usize, form: &str) -> Result<Vec<f64>, String> {
    if words.len() < min || words.len() > max {
        return Err(format!("has {} values; give {form}", words.len()));
    }
    words
        .iter()
        .map(|w| match w.parse::<f64>() {
            Ok(x) if x.is_finite() && x.abs() <= f64::from(f32::MAX) => Ok(x),
            Ok(_) => Err(format!(
                "`{}` is not a finite number (NaN, infinite, or beyond f32); give finite values",
                quote(w)
            )),
            Err(_) => Err(format!("`{}` is not a number", quote(w))),
        })
        .collect()
}

impl Reader {
    /// Reads a face's corners and adds its triangles.
    fn face(&mut self, words: &[&str]) -> Result<(), String> {
        if words.len() < 3 {
            return Err(format!(
                "a face has {} corner(s); give at least 3",
                words.len()
            ));
        }
        if words.len() > MAX_FACE_CORNERS {
            return Err(format!(
                "a face has {} corners, more than the {MAX_FACE_CORNERS} lensmap reads; split it",
                words.len()
            ));
        }
        let mut corners = words
            .iter()
            .map(|w| self.corner(w))
            .collect::<Result<Vec<Corner>, String>>()?;
        if let [a, b, c] = corners[..] {
            // A triangle as written, a repeated corner too: the mesh check calls it degenerate,
            // naming its line (and `drop_degenerate` drops it).
            let [a, b, c] = [a, b, c].map(|corner| self.vertex(corner));
            self.triangles.push([a, b, c]);
            return Ok(());
        }
        // A corner repeated at once (an exporter's zero-length edge) is one corner. A position
        // may recur (a polygon with a hole, bridged to it by an edge walked there and back, as
        // LightWave writes one), but an edge walked twice the same way means the polygon winds
        // over itself, which no triangulation keeps.
        corners.dedup_by_key(|c| c.0);
        while corners.len() > 1 && corners.first().map(|c| c.0) == corners.last().map(|c| c.0) {
            corners.pop();
        }
        let mut edges = std::collections::HashSet::new();
        let n = corners.len();
        if let Some(i) = (0..n).find(|&i| !edges.insert((corners[i].0, corners[(i + 1) % n].0))) {
            return Err(format!(
                "a face of {} corners walks its edge from position {} to {} twice, so it winds over itself; split it into faces that do not overlap",
                words.len(),
                corners[i].0 + 1,
                corners[(i + 1) % n].0 + 1
            ));
        }
        if corners.len() < 3 {
            return Err(format!(
                "a face has {} distinct corner(s); give at least 3",
                corners.len()
            ));
        }
        let vertices: Vec<u32> = corners.iter().map(|c| self.vertex(*c)).collect();
        if let [a, b, c] = vertices[..] {
            self.triangles.push([a, b, c]);
            return Ok(());
        }
        let points: Vec<DVec3> = corners
            .iter()
            .map(|c| self.positions[c.0 as usize])
            .collect();
        for [a, b, c] in self.ear_clip(&points)? {
            self.triangles.push([vertices[a], vertices[b], vertices[c]]);
        }
        Ok(())
    }

    /// A corner `v`, `v/t`, `v//n` or `v/t/n`, its indices 1-based or, negative, relative to the
    /// records read so far.
    fn corner(&self, word: &str) -> Result<Corner, String> {
        if word.split('/').count() > 3 {
            return Err(format!(
                "corner `{}` has more than three indices; give v, v/vt, v//vn or v/vt/vn",
                quote(word)
            ));
        }
        let mut parts = word.split('/');
        let index = |part: Option<&str>, what: &str, count: usize| -> Result<Option<u32>, String> {
            let Some(part) = part.filter(|p| !p.is_empty()) else {
                return Ok(None);
            };
            let bad = || {
                format!(
                    "corner `{}`: its {what} index {part} is not one of the {count} defined before it (1 to {count}, or -1 to -{count} counting back)",
                    quote(word)
                )
            };
            let i: i64 = part.parse().map_err(|_| bad())?;
            let count = count as i64;
            let resolved = match i {
                1.. if i <= count => i - 1,
                ..=-1 if -i <= count => count + i,
                _ => return Err(bad()),
            };
            Ok(Some(resolved as u32))
        };
        let position = index(parts.next(), "position (v)", self.positions.len())?
            .ok_or_else(|| format!("corner `{}` has no position index", quote(word)))?;
        let uv = index(parts.next(), "texture coordinate (vt)", self.uvs.len())?;
        let normal = index(parts.next(), "normal (vn)", self.normals.len())?;
        Ok((position, uv, normal))
    }

    /// The mesh vertex of `corner`, made at its first use.
    fn vertex(&mut self, corner: Corner) -> u32 {
        let next = self.corners.len() as u32;
        *self.vertices.entry(corner).or_insert_with(|| {
            self.corners.push(corner);
            next
        })
    }

    /// Triangles (corner indices) covering the polygon `points`, wound as it is. A polygon that
    /// is not planar is triangulated in the plane perpendicular to its Newell normal (the normal
    /// of its vector area, which a least-squares plane would share for a planar polygon); its
    /// triangles keep the corners' positions, so they meet its edges exactly.
    fn ear_clip(&mut self, points: &[DVec3]) -> Result<Vec<[usize; 3]>, String> {
        let newell: DVec3 = (0..points.len())
            .map(|i| points[i].cross(points[(i + 1) % points.len()]))
            .sum();
        let extent = points
            .iter()
            .map(|p| (*p - points[0]).length_squared())
            .fold(0.0, f64::max);
        if newell.length() <= 1e-12 * extent {
            return Err(format!(
                "a face of {} corners encloses no area (its corners lie on a line or it folds onto itself); remove it",
                points.len()
            ));
        }
        let normal = newell.normalize();
        let u = normal.any_orthonormal_vector();
        let v = normal.cross(u);
        let flat: Vec<[f64; 2]> = points.iter().map(|p| [p.dot(u), p.dot(v)]).collect();
        let mut indices: Vec<u32> = Vec::new();
        self.earcut.earcut(flat.iter().copied(), &[], &mut indices);
        let area = |a: [f64; 2], b: [f64; 2], c: [f64; 2]| {
            0.5 * ((b[0] - a[0]) * (c[1] - a[1]) - (c[0] - a[0]) * (b[1] - a[1]))
        };
        // The polygon's signed area in (u, v), positive: u × v is its normal.
        let polygon: f64 = (0..flat.len())
            .map(|i| {
                let (a, b) = (flat[i], flat[(i + 1) % flat.len()]);
                0.5 * (a[0] * b[1] - b[0] * a[1])
            })
            .sum();
        let mut covered = 0.0;
        let triangles: Vec<[usize; 3]> = indices
            .chunks_exact(3)
            .map(|t| {
                let [a, b, c] = [t[0] as usize, t[1] as usize, t[2] as usize];
                let signed = area(flat[a], flat[b], flat[c]);
                covered += signed.abs();
                // Wound as the polygon is (its normal is u × v).
                if signed < 0.0 { [a, c, b] } else { [a, b, c] }
            })
            .collect();
        if (covered - polygon).abs() > AREA_TOLERANCE * polygon {
            return Err(format!(
                "a face of {} corners crosses itself (its triangles cover {covered:.6e} of its {polygon:.6e} area in its plane); split it into simple polygons",
                points.len()
            ));
        }
        Ok(triangles)
    }

    /// The mesh: one vertex per distinct corner.
    fn finish(self, smooth_normals: bool) -> ObjMesh {
        let every_corner_has_uv = self.corners.iter().all(|c| c.1.is_some());
        let mesh = TriangleMesh {
            positions: self
                .corners
                .iter()
                .map(|c| self.positions[c.0 as usize].as_vec3())
                .collect(),
            normals: self
                .corners
                .iter()
                .map(|c| match c.2 {
                    Some(n) if !smooth_normals => self.normals[n as usize],
                    _ => Vec3::ZERO,
                })
                .collect(),
            uvs: if every_corner_has_uv && !self.corners.is_empty() {
                self.corners
                    .iter()
                    .map(|c| self.uvs[c.1.unwrap_or(0) as usize])
                    .collect()
            } else {
                Vec::new()
            },
            triangles: self.triangles,
        };
        ObjMesh {
            mesh,
            lines: self.lines,
            warnings: self.warnings,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(text: &str) -> Result<ObjMesh, String> {
        parse_obj(text, false)
    }

    #[test]
    fn polylines_and_points_are_refused_with_their_line_whatever_the_whitespace() {
        for record in ["l 1 2 3", "l\t1 3 4", "l", "p 1", "  p\t2"] {
            let error = parse(&format!("v 0 0 0\nv 1 0 0\nv 0 1 0\n\n{record}\n")).unwrap_err();
            assert!(error.starts_with("line 5 (`"), "{record}: {error}");
            assert!(error.contains("not a surface"), "{record}: {error}");
        }
        let mesh = parse("v 0 0 0\nv 1 0 0\nv 0 1 0\nf\t1\t2 3\n")
            .unwrap()
            .mesh;
        assert_eq!(mesh.triangles, vec![[0, 1, 2]]);
        // Repeated corners in a row, and the last equal to the first, are one corner.
        let obj = parse("v 0 0 0\nv 1 0 0\nv 0 1 0\n#\nf 1 2 2 3 1\n").unwrap();
        assert_eq!((obj.mesh.triangles.len(), obj.lines), (1, vec![5]));
    }

    #[test]
    fn corners_share_a_vertex_only_with_the_same_indices_and_count_back_when_negative() {
        let text = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvt 0 0\nvt 1 1\nvn 0 0 1\n\
                    f 1/1/1 2/1/1 3/2/1\nf -4/1/1 -2/2/1 -1/2/1\n";
        let obj = parse(text).unwrap();
        // Corners (1,1,1) and (3,2,1) recur; (4,2,1) is new.
        assert_eq!(obj.mesh.triangles, vec![[0, 1, 2], [0, 2, 3]]);
        assert_eq!(obj.mesh.positions.len(), 4);
        assert_eq!(obj.mesh.uvs.len(), 4);
        assert_eq!(obj.mesh.normals[3], Vec3::Z);
    }

    #[test]
    fn every_error_names_its_line_and_record() {
        let cases = [
            ("v 1 2\n", "line 1 (`v 1 2`): has 2 values"),
            ("v 1 2 3.1+e2\n", "`3.1+e2` is not a number"),
            ("v 0 0 0\nf 1 2 3\n", "line 2 (`f 1 2 3`): corner `2`"),
            (
                "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1/1 2 3\n",
                "texture coordinate (vt) index 1",
            ),
            ("v 0 0 0\nv 1 0 0\nf 1 2\n", "a face has 2 corner(s)"),
            (
                "v 0 0 0\nv 1 0 0\nv 2 0 0\nv 3 0 0\nf 1 2 3 4\n",
                "encloses no area",
            ),
            ("curv 0 1 1 2\n", "free-form geometry"),
            ("v 0 0 0\nf 1/2/3/4 1 1\n", "more than three indices"),
            ("v 0 0 nan\n", "`nan` is not a finite number"),
            ("v 0 0 1e39\n", "beyond f32"),
            (
                "v 0 0 0\nv 1 0 0\nv 1 1 0\nf 1 2 3 1 2 3\n",
                "from position 1 to 2 twice",
            ),
            ("v 0 0 0\nv 1 0 0\nf 1 2 2 1\n", "2 distinct corner(s)"),
            (
                "v 0 0 0\nv 1 0 0\nf 1 2 1 2\n",
                "from position 1 to 2 twice",
            ),
        ];
        for (text, wanted) in cases {
            let error = parse(text).unwrap_err();
            assert!(error.contains(wanted), "{text:?}: {error}");
            assert!(error.starts_with("line "), "{text:?}: {error}");
        }
    }

    #[test]
    fn a_self_intersecting_face_is_refused() {
        // A pentagram: a regular pentagon's corners taken two apart.
        let mut text: String = (0..5)
            .map(|k| {
                let a = std::f64::consts::TAU * f64::from(k) / 5.0;
                format!("v {} {} 0\n", a.cos(), a.sin())
            })
            .collect();
        text.push_str("f 1 3 5 2 4\n");
        let error = parse(&text).unwrap_err();
        assert!(
            error.contains("line 6") && error.contains("crosses itself"),
            "{error}"
        );
        // A bow tie's halves cancel: it encloses no net area.
        let text = "v 0 0 0\nv 1 1 0\nv 1 0 0\nv 0 1 0\nf 1 2 3 4\n";
        assert!(parse(text).unwrap_err().contains("encloses no area"));
    }

    /// An L-shaped hexagon, concave at one corner: a fan from its first corner would cover the
    /// notch; ear clipping covers exactly its area, wound as the face.
    #[test]
    fn a_concave_face_keeps_its_shape_and_winding() {
        let text = "v 0 0 0\nv 2 0 0\nv 2 1 0\nv 1 1 0\nv 1 2 0\nv 0 2 0\nf 4 5 6 1 2 3\n";
        let mesh = parse(text).unwrap().mesh;
        assert_eq!(mesh.triangles.len(), 4);
        let mut area = 0.0;
        for t in &mesh.triangles {
            let [a, b, c] = t.map(|i| mesh.positions[i as usize]);
            let n = (b - a).cross(c - a);
            assert!(n.z > 0.0, "triangle {t:?} is wound against the face");
            area += 0.5 * n.length();
        }
        assert!((area - 3.0).abs() < 1e-6, "area {area}");
    }

    #[test]
    fn an_empty_usemtl_and_an_unknown_keyword_are_warnings_and_continuations_join() {
        let text = "v 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl\nusemtl   \nxyz 1\nxyz 2\nf 1 2 \\\n 3\n";
        let obj = parse(text).unwrap();
        assert_eq!(obj.mesh.triangles.len(), 1);
        assert_eq!(obj.warnings.len(), 3, "{:?}", obj.warnings);
        assert!(obj.warnings[0].starts_with("line 4: `usemtl` names no material"));
        assert!(obj.warnings[2].contains("`xyz`"));
    }

    #[test]
    fn utf16_with_a_byte_order_mark_reads_as_utf8_does() {
        let text = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";
        let mut big = vec![0xFE, 0xFF];
        big.extend(text.encode_utf16().flat_map(u16::to_be_bytes));
        let mut little = vec![0xFF, 0xFE];
        little.extend(text.encode_utf16().flat_map(u16::to_le_bytes));
        for bytes in [big, little, text.as_bytes().to_vec()] {
            let mesh = parse_obj(&decode(&bytes).unwrap(), false).unwrap().mesh;
            assert_eq!(mesh.triangles.len(), 1);
        }
        // A Latin-1 name reads; a Latin-1 byte in a number is refused.
        assert!(
            parse(&decode(b"g caf\xe9\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n").unwrap()).is_ok()
        );
        let error = parse(&decode(b"v 0 0 0\xb0\n").unwrap()).unwrap_err();
        assert!(
            error.starts_with("line 1") && error.contains("not a number"),
            "{error}"
        );
    }
}
