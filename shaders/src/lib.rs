//! lensmap's shaders as SPIR-V: WGSL sources in `shaders/wgsl/`, compiled and validated by naga in
//! `build.rs` (a shader error fails the build naming file and line). One file per pass family:
//! `environment` (opaque meshes: vertex colour times a light map) and `lens` (the layered-EM
//! compositor, both variants).
//!
//! What Rust must agree on with the shaders is generated from them by `build.rs`: the push-constant
//! structs ([`LensConstants`], [`EnvironmentConstants`]) with compile-time checks of their layout,
//! the single pass's limits [`MAX_LAYERS`] and [`MAX_VIEWPOINTS`], and the table of specialized
//! entry points keyed by [`Overrides`].

include!(concat!(env!("OUT_DIR"), "/modules.rs"));

/// The WGSL `override` values a `*_specialized` entry point was compiled with (`build.rs` compiles
/// every combination). Field names are the override names in lower case: the generated table
/// spells them, so an override renamed in WGSL fails to compile here.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Overrides {
    /// `LAYER_COUNT`: layers composited, 1 ..= [`MAX_LAYERS`].
    pub layer_count: u32,
    /// `TERM_MASK`: bit 0 the refraction term, bit 1 the reflection term (1, 2 or 3).
    pub term_mask: u32,
    /// `VIEWPOINTS`: viewpoint samples blended, 1 ..= [`MAX_VIEWPOINTS`].
    pub viewpoints: u32,
}

/// A compiled entry point.
#[derive(Clone, Copy, Debug)]
pub struct Shader {
    /// Source file stem (`lens` for `shaders/wgsl/lens.wgsl`).
    pub file: &'static str,
    /// Entry point name, also the SPIR-V entry point.
    pub entry: &'static str,
    /// Override values baked in, `None` for an entry point without overrides.
    pub overrides: Option<Overrides>,
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

/// The compiled entry point `entry` of `file` (one without overrides), or `None` if there is none.
pub fn shader(file: &str, entry: &str) -> Option<Shader> {
    all().find(|s| s.file == file && s.entry == entry && s.overrides.is_none())
}

/// The entry point `entry` of `file` compiled with `overrides` (entry points named
/// `*_specialized` only), or `None` if `build.rs` did not compile that combination.
pub fn specialized(file: &str, entry: &str, overrides: Overrides) -> Option<Shader> {
    all().find(|s| s.file == file && s.entry == entry && s.overrides == Some(overrides))
}

/// Every compiled entry point.
pub fn all() -> impl Iterator<Item = Shader> {
    let plain = MODULES.iter().map(|&(file, entry, spirv)| Shader {
        file,
        entry,
        overrides: None,
        spirv,
    });
    let specialized = SPECIALIZED
        .iter()
        .map(|&(file, entry, overrides, spirv)| Shader {
            file,
            entry,
            overrides: Some(overrides),
            spirv,
        });
    plain.chain(specialized)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_entry_point_is_valid_spirv() {
        let names: Vec<_> = all().map(|s| (s.file, s.entry)).collect();
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
        for layer_count in 1..=MAX_LAYERS {
            for term_mask in 1..=3 {
                for viewpoints in 1..=MAX_VIEWPOINTS {
                    let overrides = Overrides {
                        layer_count,
                        term_mask,
                        viewpoints,
                    };
                    assert!(
                        specialized("lens", "fs_single_pass_specialized", overrides).is_some(),
                        "{overrides:?}"
                    );
                }
            }
        }
        assert_eq!(
            SPECIALIZED.len(),
            MAX_LAYERS as usize * 3 * MAX_VIEWPOINTS as usize
        );
        assert_eq!(
            MAX_VIEWPOINTS, 3,
            "the three samples of a spherical triangle"
        );
        for shader in all() {
            let words = shader.words();
            assert_eq!(words[0], 0x0723_0203, "{}: SPIR-V magic", shader.entry);
        }
    }

    #[test]
    fn push_constants_follow_the_wgsl_layout() {
        // The generated structs assert naga's offsets at compile time; here, the sizes the
        // pipeline layouts declare are the structs' sizes, multiples of 4 as Vulkan requires.
        assert_eq!(std::mem::size_of::<EnvironmentConstants>(), 64);
        assert_eq!(std::mem::size_of::<LensConstants>() % 4, 0);
        assert_eq!(std::mem::offset_of!(LensConstants, weight_a), 64);
    }
}
