//! lensmap's shaders as SPIR-V: WGSL sources in `shaders/wgsl/`, compiled and validated by naga in
//! `build.rs` (a shader error fails the build naming file and line). One file per pass family:
//! `environment` (opaque meshes: vertex colour times a light map) and `lens` (the layered-EM
//! compositor, both variants).
//!
//! What Rust must agree on with the shaders is generated from them by `build.rs`: the push-constant
//! structs ([`LensConstants`], [`EnvironmentConstants`]) with compile-time checks of their layout,
//! the single pass's limits [`MAX_LAYERS`] and [`MAX_VIEWPOINTS`], the table of specialized
//! entry points keyed by [`Overrides`], and per shader file a module of its contracts
//! (`lensmap_shaders::tessellate`, …): its entry points as an enum implementing [`EntryPoint`]
//! (so that one that does not exist cannot be named), its resources' binding numbers
//! (`tessellate::binding::CONTROL`) and sets ([`Binding`]), its module-scope constants
//! (`tessellate::CONTROL_VERTICES`) and its structs' sizes (`tracer::VERTEX_RECORD_BYTES`).

include!(concat!(env!("OUT_DIR"), "/modules.rs"));

/// The WGSL `override` values a `*_specialized` entry point was compiled with (`build.rs` compiles
/// every combination). Field names are the override names in lower case: the generated table
/// spells them, so an override renamed in WGSL fails to compile here.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Overrides {
    /// `LAYER_COUNT`: layers composited, 1 ..= [`MAX_LAYERS`].
    pub layer_count: u32,
    /// `TERM_MASK`: bit 0 the refraction term, bit 1 the reflection term (1, 2 or 3); 0 for
    /// the single pass of path classes.
    pub term_mask: u32,
    /// `VIEWPOINTS`: viewpoint samples blended, 1 ..= [`MAX_VIEWPOINTS`].
    pub viewpoints: u32,
    /// `CLASS_COUNT`: the path-class terms K of the single pass of path classes, with
    /// K·(`layer_count` + 1) ≤ [`SINGLE_PASS_SLOTS`]; 0 for the greedy terms' single pass.
    pub class_count: u32,
}

/// An entry point of one shader file (each file's `Entry`, generated).
pub trait EntryPoint: Copy + 'static {
    /// Every entry point of the file, in its order: `ALL[e.index()] == e`.
    const ALL: &'static [Self];
    /// Its name, the SPIR-V entry point.
    fn name(self) -> &'static str;
    /// Its compiled SPIR-V.
    fn shader(self) -> Shader;
    /// `@workgroup_size` (compute; `[0, 0, 0]` for other stages).
    fn workgroup_size(self) -> [u32; 3];
    /// The resources it reads or writes (from naga's analysis of the entry point), in binding
    /// order.
    fn uses(self) -> &'static [Use];
    /// Its index in [`EntryPoint::ALL`].
    fn index(self) -> usize;
}

/// How an entry point uses a resource.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Access {
    /// It only reads it.
    Read,
    /// It only writes it.
    Write,
    /// It reads and writes it (atomics included).
    ReadWrite,
}

/// A resource an entry point uses.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Use {
    /// Its group.
    pub group: u32,
    /// Its binding number.
    pub binding: u32,
    /// How.
    pub access: Access,
}

/// [`Binding::stages`]: the vertex stage.
pub const STAGE_VERTEX: u32 = 1;
/// [`Binding::stages`]: the fragment stage.
pub const STAGE_FRAGMENT: u32 = 2;
/// [`Binding::stages`]: the compute stage.
pub const STAGE_COMPUTE: u32 = 4;

/// What a shader binds at one binding number.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BindingKind {
    /// A storage buffer the shader only reads.
    StorageRead,
    /// A storage buffer the shader writes.
    StorageReadWrite,
    /// A uniform buffer.
    Uniform,
    /// A sampled texture (2D, array or cube).
    SampledImage,
    /// A sampler.
    Sampler,
    /// A top-level acceleration structure (ray queries).
    AccelerationStructure,
}

/// One resource of a shader's set.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Binding {
    /// Its binding number.
    pub binding: u32,
    /// The WGSL variable.
    pub name: &'static str,
    /// What it is.
    pub kind: BindingKind,
    /// The stages whose entry points use it ([`STAGE_VERTEX`], [`STAGE_FRAGMENT`],
    /// [`STAGE_COMPUTE`] or'd).
    pub stages: u32,
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

/// The entry point `entry` of `file` compiled with `overrides`, or `None` if `build.rs` did not
/// compile that combination: what each file's generated `Specialized::shader` looks up.
fn specialized(file: &str, entry: &str, overrides: Overrides) -> Option<Shader> {
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
            ("lens", "vs_single_pass_classes"),
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
                        class_count: 0,
                    };
                    assert!(
                        lens::Specialized::FsSinglePassSpecialized
                            .shader(overrides)
                            .is_some(),
                        "{overrides:?}"
                    );
                }
            }
        }
        // The classes' single pass: every K classes of n layers within the slots, and no more.
        let mut class_programs = 0;
        for layer_count in 1..=MAX_LAYERS {
            for class_count in 1..=SINGLE_PASS_SLOTS + 1 {
                for viewpoints in 1..=MAX_VIEWPOINTS {
                    let overrides = Overrides {
                        layer_count,
                        term_mask: 0,
                        viewpoints,
                        class_count,
                    };
                    let fits = class_count * (layer_count + 1) <= SINGLE_PASS_SLOTS;
                    let shader =
                        lens::Specialized::FsSinglePassClassesSpecialized.shader(overrides);
                    assert_eq!(shader.is_some(), fits, "{overrides:?}");
                    class_programs += usize::from(fits);
                }
            }
        }
        // 16 slots: K ≤ 8, 5, 4, 3, 2, 2 at n = 1 … 6.
        assert_eq!(class_programs, 24 * MAX_VIEWPOINTS as usize);
        assert_eq!(
            SPECIALIZED.len(),
            MAX_LAYERS as usize * 3 * MAX_VIEWPOINTS as usize + class_programs
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

    /// Every file's entry enum lists its plain entry points, each naming its own blob, and its
    /// index is its place in the list.
    #[test]
    fn each_files_entries_are_its_blobs() {
        fn check<E: EntryPoint + std::fmt::Debug>(file: &str) {
            let plain: Vec<&str> = MODULES
                .iter()
                .filter(|(f, _, _)| *f == file)
                .map(|(_, entry, _)| *entry)
                .collect();
            let named: Vec<&str> = E::ALL.iter().map(|e| e.name()).collect();
            assert_eq!(named, plain, "{file}");
            for (i, entry) in E::ALL.iter().enumerate() {
                assert_eq!(entry.index(), i, "{entry:?}");
                let shader = entry.shader();
                assert_eq!((shader.file, shader.entry), (file, entry.name()));
                assert_eq!(shader.words()[0], 0x0723_0203, "{entry:?}: SPIR-V magic");
            }
        }
        check::<tessellate::Entry>("tessellate");
        check::<texgen::Entry>("texgen");
        check::<drawlist::Entry>("drawlist");
        check::<tracer::Entry>("tracer");
        check::<tracer_rq_f64::Entry>("tracer_rq_f64");
        check::<lens::Entry>("lens");
        assert_eq!(tessellate::Entry::CsBegin.workgroup_size(), [64, 1, 1]);
    }

    /// A set's bindings are numbered 0, 1, 2, … by the generated table, with the kinds the
    /// WGSL declares.
    #[test]
    fn sets_list_the_bindings_in_order() {
        assert_eq!(tessellate::SETS.len(), 1);
        assert_eq!(tessellate::SETS[0].len(), 13);
        assert_eq!(
            tessellate::SETS[0][tessellate::binding::CONTROL as usize].name,
            "control"
        );
        assert_eq!(
            tracer_rq::SETS[0][0].kind,
            BindingKind::AccelerationStructure
        );
        assert_eq!(tracer::SETS[0][0].kind, BindingKind::StorageRead);
        assert_eq!(lens::SETS.len(), 2, "the programmable scheme reads set 1");
        assert_eq!(lens::SETS[0][0].stages, STAGE_VERTEX, "the lens data");
        assert_eq!(lens::SETS[0][1].stages, STAGE_FRAGMENT, "layers_a");
        // cs_scan_top reads and writes the block sums, and nothing of the input mesh.
        let uses = tessellate::Entry::CsScanTop.uses();
        let block_sums = tessellate::binding::BLOCK_SUMS;
        assert!(
            uses.iter()
                .any(|u| u.binding == block_sums && u.access == Access::ReadWrite)
        );
        assert!(
            !uses
                .iter()
                .any(|u| u.binding == tessellate::binding::INPUT_VERTICES)
        );
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
