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
    /// Override values baked in (`LAYER_COUNT=3,TERM_MASK=3,VIEWPOINTS=2`), empty if none.
    pub specialization: &'static str,
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
    specialized(file, entry, "")
}

/// The entry point `entry` of `file` compiled with the override values `specialization`
/// (`LAYER_COUNT=3,TERM_MASK=3,VIEWPOINTS=2`; entry points named `*_specialized` only).
pub fn specialized(file: &str, entry: &str, specialization: &str) -> Option<Shader> {
    all().find(|s| s.file == file && s.entry == entry && s.specialization == specialization)
}

/// Every compiled entry point.
pub fn all() -> impl Iterator<Item = Shader> {
    MODULES
        .iter()
        .map(|&(file, entry, specialization, spirv)| Shader {
            file,
            entry,
            specialization,
            spirv,
        })
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
        ] {
            assert!(
                names.contains(&expected),
                "missing {expected:?} in {names:?}"
            );
        }
        for layers in 1..=6 {
            for terms in 1..=3 {
                for viewpoints in 1..=2 {
                    let key =
                        format!("LAYER_COUNT={layers},TERM_MASK={terms},VIEWPOINTS={viewpoints}");
                    assert!(
                        super::specialized("lens", "fs_single_pass_specialized", &key).is_some(),
                        "{key}"
                    );
                }
            }
        }
        for shader in super::all() {
            let words = shader.words();
            assert_eq!(words[0], 0x0723_0203, "{}: SPIR-V magic", shader.entry);
        }
    }
}
