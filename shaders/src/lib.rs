//! lensmap's shaders as SPIR-V: WGSL sources in `shaders/wgsl/`, compiled and validated by naga in
//! `build.rs` (a shader error fails the build naming file and line). One file per pass family:
//! `environment` (opaque vertex-coloured meshes) and `lens` (the layered-EM compositor, both
//! variants).

include!(concat!(env!("OUT_DIR"), "/modules.rs"));

/// A compiled entry point.
#[derive(Clone, Copy, Debug)]
pub struct Shader {
    /// Source file stem (`lens` for `shaders/wgsl/lens.wgsl`).
    pub file: &'static str,
    /// Entry point name, also the SPIR-V entry point.
    pub entry: &'static str,
    /// SPIR-V bytes (little-endian words).
    pub spirv: &'static [u8],
}

impl Shader {
    /// SPIR-V as 32-bit words.
    pub fn words(&self) -> Vec<u32> {
        self.spirv
            .chunks_exact(4)
            .map(|c| u32::from_le_bytes([c[0], c[1], c[2], c[3]]))
            .collect()
    }
}

/// The compiled entry point `entry` of `file`, or `None` if there is no such shader.
pub fn shader(file: &str, entry: &str) -> Option<Shader> {
    MODULES
        .iter()
        .find(|(f, e, _)| *f == file && *e == entry)
        .map(|&(file, entry, spirv)| Shader { file, entry, spirv })
}

/// Every compiled entry point.
pub fn all() -> impl Iterator<Item = Shader> {
    MODULES
        .iter()
        .map(|&(file, entry, spirv)| Shader { file, entry, spirv })
}

#[cfg(test)]
mod tests {
    #[test]
    fn every_entry_point_is_valid_spirv() {
        let names: Vec<_> = super::all().map(|s| (s.file, s.entry)).collect();
        for expected in [
            ("environment", "vs_environment"),
            ("environment", "fs_environment"),
            ("lens", "vs_position"),
            ("lens", "fs_zero"),
            ("lens", "vs_layer"),
            ("lens", "fs_layer"),
            ("lens", "vs_single_pass"),
            ("lens", "fs_single_pass"),
        ] {
            assert!(names.contains(&expected), "missing {expected:?} in {names:?}");
        }
        for shader in super::all() {
            let words = shader.words();
            assert_eq!(words[0], 0x0723_0203, "{}: SPIR-V magic", shader.entry);
        }
    }
}
