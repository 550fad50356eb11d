//! The compositor's shader programs as a type: each program knows the SPIR-V entry points
//! `shaders/build.rs` generated for it, and the single pass knows the combinations it was compiled
//! for, so an unknown program or an unsupported layer count is an error where the plan is built,
//! never a silent fallback at pipeline creation.

use lensmap_shaders::{Overrides, Shader};

use super::{BlendScheme, Variant};
use crate::{
    gpu::VertexInput,
    options::{LibraryWords, OptionWords, Worded},
    trace::Term,
};

/// The single-pass fragment shader's specialization: what its constant loop bounds and branches
/// are compiled for. Built only through [`SinglePassProgram::new`], so every value names a blob
/// that `shaders/build.rs` compiled.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct SinglePassProgram {
    overrides: Overrides,
}

/// Why a program cannot be built.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum ProgramError {
    /// The single pass carries one interpolated direction per layer and term; more layers than
    /// the shader has varyings for need the multipass variant.
    #[error(
        "lens \"{lens}\" has {layers} layers; the single-pass variant supports at most {max}: use the multipass variant"
    )]
    TooManyLayers {
        /// The lens object.
        lens: String,
        /// Its layer count.
        layers: usize,
        /// [`SinglePassProgram::MAX_LAYERS`].
        max: usize,
    },
    /// A blending scheme other than front-to-back asked of the single pass, which does not blend.
    #[error("{}", single_pass_blend(*.blend, &LibraryWords))]
    SinglePassBlend {
        /// The scheme asked for.
        blend: BlendScheme,
    },
    /// A lens object with no layers, no terms, or not one or two viewpoint samples.
    #[error(
        "lens \"{lens}\": the single pass needs 1 to {max} layers, one or two terms and one or two viewpoints (got {layers}, {terms}, {viewpoints})"
    )]
    Unsupported {
        /// The lens object.
        lens: String,
        /// Layers asked for.
        layers: usize,
        /// Terms asked for.
        terms: usize,
        /// Viewpoint samples asked for.
        viewpoints: usize,
        /// [`SinglePassProgram::MAX_LAYERS`].
        max: usize,
    },
}

/// The message of [`ProgramError::SinglePassBlend`], naming the options by `words`.
fn single_pass_blend(blend: BlendScheme, words: &dyn OptionWords) -> String {
    format!(
        "{} applies to the multipass variant; the single pass composites in registers and does not blend: use {}",
        words.setting("blend", blend.name()),
        words.setting("variant", Variant::Multipass.name())
    )
}

impl Worded for ProgramError {
    fn worded(&self, words: &dyn OptionWords) -> String {
        match self {
            ProgramError::SinglePassBlend { blend } => single_pass_blend(*blend, words),
            ProgramError::TooManyLayers { .. } | ProgramError::Unsupported { .. } => {
                self.to_string()
            }
        }
    }
}

impl SinglePassProgram {
    /// The most layers per lens object the single-pass variant composites (`const MAX_LAYERS` in
    /// `shaders/wgsl/lens.wgsl`, the one place the limit is written). The multipass variant has
    /// no such limit.
    pub const MAX_LAYERS: usize = lensmap_shaders::MAX_LAYERS as usize;

    /// The program for a lens object named `lens` (for messages) with `layers` layers, the given
    /// terms and `viewpoints` blended viewpoint samples.
    pub fn new(
        lens: &str,
        layers: usize,
        terms: &[Term],
        viewpoints: usize,
    ) -> Result<SinglePassProgram, ProgramError> {
        if layers > Self::MAX_LAYERS {
            return Err(ProgramError::TooManyLayers {
                lens: lens.to_owned(),
                layers,
                max: Self::MAX_LAYERS,
            });
        }
        let term_mask = terms
            .iter()
            .map(|t| match t {
                Term::Refraction => 1,
                Term::Reflection => 2,
            })
            .fold(0u32, |mask, bit| mask | bit);
        if layers == 0 || term_mask == 0 || terms.len() > 2 || !(1..=2).contains(&viewpoints) {
            return Err(ProgramError::Unsupported {
                lens: lens.to_owned(),
                layers,
                terms: terms.len(),
                viewpoints,
                max: Self::MAX_LAYERS,
            });
        }
        Ok(SinglePassProgram {
            overrides: Overrides {
                layer_count: layers as u32,
                term_mask,
                viewpoints: viewpoints as u32,
            },
        })
    }
}

/// A shader program of the compositor: a vertex and a fragment entry point and the vertex input
/// they expect.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum ShaderProgram {
    /// Opaque vertex-coloured environment meshes (`environment.wgsl`).
    Environment,
    /// A lens object's triangles writing zero: the prime and, with write mask A, the alpha clear.
    LensZero,
    /// One layer of one (viewpoint, term) group of the multipass variant.
    LensLayer,
    /// One layer of the programmable blending scheme: the blend done in the shader, over the
    /// pixel's current value read from a scratch image.
    LensLayerProgrammable,
    /// The sum of scratch images into the framebuffer (`composite.wgsl`): back-to-front and
    /// group-targets blending.
    GroupSum,
    /// The single-pass variant, specialized.
    LensSinglePass(SinglePassProgram),
    /// The supersampling box filter into an external image (`resolve.wgsl`).
    BoxFilter,
}

impl ShaderProgram {
    /// The vertex and fragment shaders; `None` only if `shaders/build.rs` did not compile them,
    /// which the unit test over every program rules out.
    pub fn shaders(self) -> Option<(Shader, Shader)> {
        let plain = |file, vertex, fragment| {
            Some((
                lensmap_shaders::shader(file, vertex)?,
                lensmap_shaders::shader(file, fragment)?,
            ))
        };
        match self {
            ShaderProgram::Environment => plain("environment", "vs_environment", "fs_environment"),
            ShaderProgram::LensZero => plain("lens", "vs_position", "fs_zero"),
            ShaderProgram::LensLayer => plain("lens", "vs_layer", "fs_layer"),
            ShaderProgram::BoxFilter => plain("resolve", "vs_full_screen", "fs_box_filter"),
            ShaderProgram::LensLayerProgrammable => {
                plain("lens", "vs_layer", "fs_layer_programmable")
            }
            ShaderProgram::GroupSum => plain("composite", "vs_full_screen", "fs_group_sum"),
            ShaderProgram::LensSinglePass(program) => Some((
                lensmap_shaders::shader("lens", "vs_single_pass")?,
                lensmap_shaders::specialized(
                    "lens",
                    "fs_single_pass_specialized",
                    program.overrides,
                )?,
            )),
        }
    }

    /// The vertex buffers the program reads (lens programs read a storage buffer instead).
    pub fn vertex_input(self) -> VertexInput {
        match self {
            ShaderProgram::Environment => VertexInput::PositionColourUv,
            ShaderProgram::LensZero
            | ShaderProgram::LensLayer
            | ShaderProgram::LensSinglePass(_)
            | ShaderProgram::LensLayerProgrammable
            | ShaderProgram::GroupSum
            | ShaderProgram::BoxFilter => VertexInput::None,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_program_has_its_spirv() {
        let mut programs = vec![
            ShaderProgram::Environment,
            ShaderProgram::LensZero,
            ShaderProgram::LensLayer,
            ShaderProgram::BoxFilter,
            ShaderProgram::LensLayerProgrammable,
            ShaderProgram::GroupSum,
        ];
        let term_sets: [&[Term]; 3] = [
            &[Term::Refraction],
            &[Term::Reflection],
            &[Term::Refraction, Term::Reflection],
        ];
        for layers in 1..=SinglePassProgram::MAX_LAYERS {
            for terms in term_sets {
                for viewpoints in 1..=2 {
                    let program = SinglePassProgram::new("lens", layers, terms, viewpoints)
                        .expect("a supported combination");
                    programs.push(ShaderProgram::LensSinglePass(program));
                }
            }
        }
        assert_eq!(programs.len(), 6 + 6 * SinglePassProgram::MAX_LAYERS);
        for program in programs {
            let (vertex, fragment) = program.shaders().expect("compiled by shaders/build.rs");
            assert_ne!(vertex.entry, fragment.entry, "{program:?}");
        }
    }

    #[test]
    fn unsupported_single_passes_are_errors_naming_the_fix() {
        let both = [Term::Refraction, Term::Reflection];
        let too_many =
            SinglePassProgram::new("teapot", SinglePassProgram::MAX_LAYERS + 1, &both, 2)
                .expect_err("over the limit");
        assert!(
            matches!(
                too_many,
                ProgramError::TooManyLayers {
                    layers: 7,
                    max: 6,
                    ..
                }
            ),
            "{too_many}"
        );
        assert!(too_many.to_string().contains("multipass"), "{too_many}");
        for (layers, terms, viewpoints) in [(0, &both[..], 1), (2, &[][..], 1), (2, &both[..], 3)] {
            assert!(
                matches!(
                    SinglePassProgram::new("lens", layers, terms, viewpoints),
                    Err(ProgramError::Unsupported { .. })
                ),
                "{layers} {terms:?} {viewpoints}"
            );
        }
    }

    /// The single pass asked to blend names the options by their field names; a front end
    /// words them its own way.
    #[test]
    fn a_blend_for_the_single_pass_names_the_options() {
        use crate::render::tests::Flags;
        let error = ProgramError::SinglePassBlend {
            blend: BlendScheme::Programmable,
        };
        assert_eq!(
            error.to_string(),
            "`blend` = programmable applies to the multipass variant; the single pass composites in registers and does not blend: use `variant` = multipass"
        );
        assert_eq!(
            error.worded(&Flags),
            "--blend programmable applies to the multipass variant; the single pass composites in registers and does not blend: use --variant multipass"
        );
    }
}
