//! The reader targets: a scene file, a scene's OBJ or image asset, and a bake directory, each
//! written to a scratch folder and read through the library's entry points ([`Scene::load`],
//! [`Bake::read`]) as the command line reads them. Each returns the library's error as text,
//! so a test can assert it is one clean line; a panic is the finding.

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};

use lensmap::layers::Bake;
use lensmap::scene::Scene;

/// The scene every asset input is placed into: one glass ball over a floor, under a constant sky.
pub const ASSET_SCENE: &str = include_str!("small-scene.toml");

/// The kinds of asset input: the first byte of an input picks one (modulo their number), the
/// rest is the file. (file name, text replaced in [`ASSET_SCENE`], its replacement.)
pub const ASSET_KINDS: [(&str, &str, &str); 4] = [
    // The floor from an OBJ file.
    (
        "asset.obj",
        "plane = { size = [4, 4] }",
        "obj = { path = \"asset.obj\" }",
    ),
    // The sky from a lat-long image (EXR or PNG: the format is guessed from the content).
    (
        "asset.exr",
        "constant = [0.1, 0.1, 0.1]",
        "latlong = { path = \"asset.exr\", scale = 1.0 }",
    ),
    // The floor's texture from a PNG (or EXR).
    (
        "asset.png",
        "diffuse = { colour = [0.5, 0.5, 0.5] }",
        "diffuse = { image = \"asset.png\" }",
    ),
    // The floor from an OBJ file, its normals smoothed and degenerate triangles dropped.
    (
        "asset.obj",
        "plane = { size = [4, 4] }",
        "obj = { path = \"asset.obj\", smooth_normals = true, drop_degenerate = true }",
    ),
];

/// A folder of its own under the system's temporary folder, emptied before each input and
/// removed when dropped.
pub struct Scratch {
    dir: PathBuf,
}

impl Scratch {
    /// A new folder named after `target`, this process and a counter.
    pub fn new(target: &str) -> Scratch {
        static COUNT: AtomicUsize = AtomicUsize::new(0);
        let dir = std::env::temp_dir().join(format!(
            "lensmap-fuzz-{target}-{}-{}",
            std::process::id(),
            COUNT.fetch_add(1, Ordering::Relaxed)
        ));
        Scratch { dir }
    }

    /// The folder, made if missing. Files of earlier inputs stay: each target writes every
    /// file its input's reading can reach, or empties a subfolder itself.
    fn folder(&self) -> &Path {
        std::fs::create_dir_all(&self.dir)
            .unwrap_or_else(|e| panic!("harness: {}: {e}", self.dir.display()));
        &self.dir
    }

    /// Writes `bytes` to `name` in the folder and returns its path.
    fn write(&self, name: &str, bytes: &[u8]) -> PathBuf {
        let path = self.dir.join(name);
        std::fs::write(&path, bytes).unwrap_or_else(|e| panic!("harness: {}: {e}", path.display()));
        path
    }
}

impl Drop for Scratch {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.dir);
    }
}

/// Valid assets placed beside every fuzzed scene file, so that the scene's paths can reach
/// a readable file: `mesh.obj` (a triangle), `sky.exr` (8×4, linear) and `wood.png` (4×4).
fn write_valid_assets(scratch: &Scratch) {
    if scratch.dir.join("wood.png").is_file() {
        return;
    }
    scratch.write(
        "mesh.obj",
        b"v 0 0 0\nv 1 0 0\nv 0 0 1\nvt 0 0\nvt 1 0\nvt 0 1\nvn 0 1 0\nf 1/1/1 3/3/1 2/2/1\n",
    );
    let sky = image::Rgb32FImage::from_fn(8, 4, |x, y| {
        image::Rgb([x as f32 * 0.1, y as f32 * 0.2, 0.5])
    });
    sky.save(scratch.dir.join("sky.exr"))
        .unwrap_or_else(|e| panic!("harness: sky.exr: {e}"));
    let wood = image::RgbImage::from_fn(4, 4, |x, y| {
        image::Rgb([(x * 60) as u8, (y * 60) as u8, 90])
    });
    wood.save(scratch.dir.join("wood.png"))
        .unwrap_or_else(|e| panic!("harness: wood.png: {e}"));
}

/// A scene file's bytes, loaded as `lensmap --scene FILE` loads it, with a valid OBJ, EXR and
/// PNG beside it (`mesh.obj`, `sky.exr`, `wood.png`). Ok holds the scene's content hash.
pub fn scene_file(scratch: &Scratch, data: &[u8]) -> Result<String, String> {
    scratch.folder();
    write_valid_assets(scratch);
    let path = scratch.write("scene.toml", data);
    Scene::load(&path)
        .map(|scene| scene.content_hash())
        .map_err(|error| error.to_string())
}

/// An asset: `data[0]` picks one of [`ASSET_KINDS`], the rest is the file, loaded through a
/// scene that uses it. An empty input is no input (`Ok`).
pub fn asset(scratch: &Scratch, data: &[u8]) -> Result<String, String> {
    let Some((&kind, bytes)) = data.split_first() else {
        return Ok(String::new());
    };
    let (name, from, to) = ASSET_KINDS[usize::from(kind) % ASSET_KINDS.len()];
    scratch.folder();
    scratch.write(name, bytes);
    let scene = scratch.write("scene.toml", ASSET_SCENE.replacen(from, to, 1).as_bytes());
    Scene::load(&scene)
        .map(|scene| scene.content_hash())
        .map_err(|error| error.to_string())
}

/// The longest file name a bake archive may hold (longer ones are skipped).
const MAX_NAME: usize = 64;

/// Whether `name` is a plain file name the harness may create: 1 to [`MAX_NAME`] characters of
/// `[A-Za-z0-9._-]`, not `.` or `..`. (The manifest may still name anything; the library must
/// refuse names that leave the bake directory.)
fn plain_name(name: &[u8]) -> bool {
    !name.is_empty()
        && name.len() <= MAX_NAME
        && name != b"."
        && name != b".."
        && name
            .iter()
            .all(|&b| b.is_ascii_alphanumeric() || b == b'.' || b == b'_' || b == b'-')
}

/// Splits a bake archive into its files: a sequence of `[name length: u8][name][data length:
/// u32 LE][data]`, the last data cut short if the input ends first. Entries whose name is not
/// [`plain_name`] are skipped; a later entry of the same name replaces an earlier one.
pub fn unpack(mut data: &[u8]) -> Vec<(String, &[u8])> {
    let mut files: Vec<(String, &[u8])> = Vec::new();
    while let Some((&name_length, rest)) = data.split_first() {
        let name_length = usize::from(name_length);
        if rest.len() < name_length + 4 {
            break;
        }
        let (name, rest) = rest.split_at(name_length);
        let (length, rest) = rest.split_at(4);
        let length = u32::from_le_bytes([length[0], length[1], length[2], length[3]]) as usize;
        let (file, rest) = rest.split_at(length.min(rest.len()));
        data = rest;
        if plain_name(name) {
            let name = String::from_utf8_lossy(name).into_owned();
            files.retain(|(other, _)| *other != name);
            files.push((name, file));
        }
    }
    files
}

/// Packs files into a bake archive ([`unpack`]'s format), in the given order.
pub fn pack<'a>(files: impl IntoIterator<Item = (&'a str, &'a [u8])>) -> Vec<u8> {
    let mut archive = Vec::new();
    for (name, data) in files {
        let name_length = u8::try_from(name.len()).expect("a name under 256 bytes");
        archive.push(name_length);
        archive.extend_from_slice(name.as_bytes());
        let length = u32::try_from(data.len()).expect("a file under 4 GiB");
        archive.extend_from_slice(&length.to_le_bytes());
        archive.extend_from_slice(data);
    }
    archive
}

/// A bake archive ([`unpack`]) written out as a bake directory and read as `render --bake`
/// reads it: the manifest parsed and validated, every map it lists read and checked
/// (EXR or compressed). Ok says how many lens objects and viewpoints it holds.
pub fn bake_directory(scratch: &Scratch, data: &[u8]) -> Result<String, String> {
    let dir = scratch.folder().join("bake");
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir(&dir).unwrap_or_else(|e| panic!("harness: {}: {e}", dir.display()));
    for (name, bytes) in unpack(data) {
        let path = dir.join(&name);
        std::fs::write(&path, bytes).unwrap_or_else(|e| panic!("harness: {}: {e}", path.display()));
    }
    Bake::read(&dir)
        .map(|bake| {
            format!(
                "{} lenses, {} viewpoints",
                bake.lenses.len(),
                bake.viewpoints.len()
            )
        })
        .map_err(|error| error.to_string())
}

/// A reader target: an input in, the outcome (what was read, or the error line) out.
pub type Target = fn(&Scratch, &[u8]) -> Result<String, String>;

/// The targets of this module by name, for the tests that replay corpus folders.
pub fn by_name(target: &str) -> Option<Target> {
    match target {
        "scene" => Some(scene_file),
        "asset" => Some(asset),
        "bake" => Some(bake_directory),
        _ => None,
    }
}
