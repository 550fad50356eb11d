//! The compositor's shader programs as a type: each program knows the SPIR-V entry points
//! `shaders/build.rs` generated for it, and the single pass knows the combinations it was compiled
//! for and what a device allows ([`SinglePassLimits`]), so an unknown program or an unsupported
//! layer or viewpoint count is an error where the plan is built, never a silent fallback at
//! pipeline creation.

use ash::vk;
use lensmap_shaders::{LensConstants, Overrides, Shader};

use crate::{gpu::VertexInput, trace::Term};

/// What bounds one of the single pass's limits ([`SinglePassLimits`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum LimitSource {
    /// What the shader was compiled for (`const MAX_LAYERS` or `const MAX_VIEWPOINTS` in
    /// `shaders/wgsl/lens.wgsl`).
    Shader,
    /// A member of the device's `VkPhysicalDeviceLimits`, by its Vulkan name, and its value.
    Device {
        /// The member's name, e.g. `maxFragmentInputComponents`.
        limit: &'static str,
        /// Its value on the device.
        value: u32,
    },
}

impl std::fmt::Display for LimitSource {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            LimitSource::Shader => f.write_str("as its shader is compiled"),
            LimitSource::Device { limit, value } => {
                write!(f, "on this device ({limit} = {value})")
            }
        }
    }
}

/// The most layers and viewpoint samples the single pass composites per lens object on one
/// device: the smaller of what its shader is compiled for and what the device's
/// `VkPhysicalDeviceLimits` allow, each with what bounds it (for messages).
///
/// What the single pass takes from a device, and the spec's minimums that make the compiled
/// limits (6 layers, 3 viewpoints) fit on every conformant device:
/// - interpolated varyings: one `vec3` location per layer and term plus the two terms' F·G,
///   2n + 2 locations of 4 components, within `maxVertexOutputComponents` and
///   `maxFragmentInputComponents` (at least 64: 16 locations, so n ≤ 7). The viewpoints share
///   the directions (`TermVertices::directions`), so V does not count here. The single pass of
///   K path-class terms carries K·(n + 1) locations, a direction per layer and class and each
///   class's F·G, within the same limits and the shader's 16 slots (four classes at n ≤ 3);
/// - one cube-map array per viewpoint in the fragment stage: V sampled images within
///   `maxPerStageDescriptorSampledImages` (at least 16) and `maxDescriptorSetSampledImages` (at
///   least 96), and V + 1 resources with the colour attachment within `maxPerStageResources`
///   (at least 128);
/// - fixed whatever n and V: one sampler (`maxPerStageDescriptorSamplers`, at least 16), one
///   storage buffer in the vertex stage (`maxPerStageDescriptorStorageBuffers`, at least 4), two
///   sets for the programmable layer (`maxBoundDescriptorSets`, at least 4) and the 124 bytes of
///   `LensConstants` (`maxPushConstantsSize`, at least 128; asserted at compile time below).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct SinglePassLimits {
    /// Most layers n per lens object.
    pub max_layers: usize,
    /// What bounds [`Self::max_layers`].
    pub layers_bound: LimitSource,
    /// Most viewpoint samples V blended.
    pub max_viewpoints: usize,
    /// What bounds [`Self::max_viewpoints`].
    pub viewpoints_bound: LimitSource,
    /// Most varyings (locations) of the single pass of path classes: K classes of n layers
    /// take K·(n + 1).
    pub max_class_slots: usize,
    /// What bounds [`Self::max_class_slots`].
    pub class_slots_bound: LimitSource,
}

/// The spec's minimum `maxPushConstantsSize`: the lens programs' push constants fit every device.
const _: () = assert!(std::mem::size_of::<LensConstants>() <= 128);

impl SinglePassLimits {
    /// What the shader is compiled for, whatever the device: `lensmap passes` and the C ABI's
    /// plan text, which have no device, plan with these.
    pub const COMPILED: SinglePassLimits = SinglePassLimits {
        max_layers: lensmap_shaders::MAX_LAYERS as usize,
        layers_bound: LimitSource::Shader,
        max_viewpoints: lensmap_shaders::MAX_VIEWPOINTS as usize,
        viewpoints_bound: LimitSource::Shader,
        max_class_slots: lensmap_shaders::SINGLE_PASS_SLOTS as usize,
        class_slots_bound: LimitSource::Shader,
    };

    /// The limits on a device whose limits are `limits`: each the smaller of the compiled one
    /// and what the device allows (see the type's documentation).
    pub fn of_device(limits: &vk::PhysicalDeviceLimits) -> SinglePassLimits {
        // A location holds 4 components; two of them carry F·G, the rest a direction per
        // layer and term.
        let layers_for = |components: u32| ((components / 4).saturating_sub(2) / 2) as usize;
        let (max_layers, layers_bound) = smallest(
            Self::COMPILED.max_layers,
            &[
                (
                    "maxVertexOutputComponents",
                    limits.max_vertex_output_components,
                    layers_for(limits.max_vertex_output_components),
                ),
                (
                    "maxFragmentInputComponents",
                    limits.max_fragment_input_components,
                    layers_for(limits.max_fragment_input_components),
                ),
            ],
        );
        // The classes' single pass: every location a slot.
        let (max_class_slots, class_slots_bound) = smallest(
            Self::COMPILED.max_class_slots,
            &[
                (
                    "maxVertexOutputComponents",
                    limits.max_vertex_output_components,
                    (limits.max_vertex_output_components / 4) as usize,
                ),
                (
                    "maxFragmentInputComponents",
                    limits.max_fragment_input_components,
                    (limits.max_fragment_input_components / 4) as usize,
                ),
            ],
        );
        let (max_viewpoints, viewpoints_bound) = smallest(
            Self::COMPILED.max_viewpoints,
            &[
                (
                    "maxPerStageDescriptorSampledImages",
                    limits.max_per_stage_descriptor_sampled_images,
                    limits.max_per_stage_descriptor_sampled_images as usize,
                ),
                (
                    "maxDescriptorSetSampledImages",
                    limits.max_descriptor_set_sampled_images,
                    limits.max_descriptor_set_sampled_images as usize,
                ),
                (
                    // The fragment stage's resources: the cube-map arrays and the colour
                    // attachment (samplers do not count).
                    "maxPerStageResources",
                    limits.max_per_stage_resources,
                    limits.max_per_stage_resources.saturating_sub(1) as usize,
                ),
            ],
        );
        SinglePassLimits {
            max_layers,
            layers_bound,
            max_viewpoints,
            viewpoints_bound,
            max_class_slots,
            class_slots_bound,
        }
    }
}

/// The smallest of `compiled` (the shader's bound) and each device limit's `allows`, with what
/// bounds it: the shader where it is not larger than every device limit's.
fn smallest(compiled: usize, device: &[(&'static str, u32, usize)]) -> (usize, LimitSource) {
    device
        .iter()
        .filter(|&&(_, _, allows)| allows < compiled)
        .min_by_key(|&&(_, _, allows)| allows)
        .map_or(
            (compiled, LimitSource::Shader),
            |&(limit, value, allows)| (allows, LimitSource::Device { limit, value }),
        )
}

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
    /// the shader has varyings for, or the device interpolates, need the multipass variant.
    #[error(
        "lens \"{lens}\" has {layers} layers; the single-pass variant supports at most {max} {bound}: use the multipass variant"
    )]
    TooManyLayers {
        /// The lens object.
        lens: String,
        /// Its layer count.
        layers: usize,
        /// [`SinglePassLimits::max_layers`].
        max: usize,
        /// What bounds it.
        bound: LimitSource,
    },
    /// The single pass samples one cube-map array per viewpoint sample; more viewpoints than
    /// the shader binds, or the device allows, need the multipass variant.
    #[error(
        "lens \"{lens}\" blends {viewpoints} viewpoint samples; the single-pass variant samples at most {max} {bound}: use the multipass variant"
    )]
    TooManyViewpoints {
        /// The lens object.
        lens: String,
        /// Viewpoint samples asked for.
        viewpoints: usize,
        /// [`SinglePassLimits::max_viewpoints`].
        max: usize,
        /// What bounds it.
        bound: LimitSource,
    },
    /// The single pass of path classes carries K·(n + 1) varyings for K classes of n layers;
    /// more than the shader has, or the device interpolates, need the multipass variant.
    #[error(
        "lens \"{lens}\" sums {terms} path-class terms over {layers} layers: the single-pass variant carries {terms}·({layers} + 1) = {slots} varyings for them, at most {max} {bound}: use the multipass variant"
    )]
    TooManyClassSlots {
        /// The lens object.
        lens: String,
        /// Its class terms.
        terms: usize,
        /// Its layers.
        layers: usize,
        /// The varyings they take.
        slots: usize,
        /// [`SinglePassLimits::max_class_slots`].
        max: usize,
        /// What bounds it.
        bound: LimitSource,
    },
    /// A lens object with no layers, no terms, more than two terms or no viewpoint sample.
    #[error(
        "lens \"{lens}\": the single pass needs 1 to {max} layers, one or two terms and at least one viewpoint (got {layers}, {terms}, {viewpoints})"
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
        /// [`SinglePassLimits::max_layers`].
        max: usize,
    },
}

impl SinglePassProgram {
    /// The most layers per lens object the single-pass variant is compiled for (`const
    /// MAX_LAYERS` in `shaders/wgsl/lens.wgsl`, the one place the limit is written); a device
    /// may allow fewer ([`SinglePassLimits::of_device`]). The multipass variant has no such
    /// limit.
    pub const MAX_LAYERS: usize = lensmap_shaders::MAX_LAYERS as usize;

    /// The program for a lens object named `lens` (for messages) with `layers` layers, the given
    /// terms and `viewpoints` blended viewpoint samples, within `limits`.
    pub fn new(
        lens: &str,
        layers: usize,
        terms: &[Term],
        viewpoints: usize,
        limits: &SinglePassLimits,
    ) -> Result<SinglePassProgram, ProgramError> {
        if layers > limits.max_layers {
            return Err(ProgramError::TooManyLayers {
                lens: lens.to_owned(),
                layers,
                max: limits.max_layers,
                bound: limits.layers_bound,
            });
        }
        if viewpoints > limits.max_viewpoints {
            return Err(ProgramError::TooManyViewpoints {
                lens: lens.to_owned(),
                viewpoints,
                max: limits.max_viewpoints,
                bound: limits.viewpoints_bound,
            });
        }
        // Path classes take the classes' program: every term a class (it reads them from one
        // run of slots), K·(n + 1) varyings within the limits.
        let classes = terms.iter().filter(|t| matches!(t, Term::Class(_))).count();
        let slots = SinglePassProgram::class_slots(classes, layers);
        if slots > limits.max_class_slots {
            return Err(ProgramError::TooManyClassSlots {
                lens: lens.to_owned(),
                terms: classes,
                layers,
                slots,
                max: limits.max_class_slots,
                bound: limits.class_slots_bound,
            });
        }
        let term_mask = terms
            .iter()
            .map(|t| match t {
                Term::Refraction => 1,
                Term::Reflection => 2,
                Term::Class(_) => 0,
            })
            .fold(0u32, |mask, bit| mask | bit);
        let terms_supported = if classes > 0 {
            classes == terms.len()
        } else {
            term_mask != 0 && terms.len() <= 2
        };
        if layers == 0 || viewpoints == 0 || !terms_supported {
            return Err(ProgramError::Unsupported {
                lens: lens.to_owned(),
                layers,
                terms: terms.len(),
                viewpoints,
                max: limits.max_layers,
            });
        }
        Ok(SinglePassProgram {
            overrides: Overrides {
                layer_count: layers as u32,
                term_mask,
                viewpoints: viewpoints as u32,
                class_count: classes as u32,
            },
        })
    }

    /// The varyings the single pass of `classes` path-class terms over `layers` layers carries:
    /// each class's F·G and a direction per layer, K·(n + 1); 0 without classes.
    pub fn class_slots(classes: usize, layers: usize) -> usize {
        classes * (layers + 1)
    }

    /// The path-class terms it composites; 0 for the greedy terms' single pass.
    pub fn class_terms(&self) -> usize {
        self.overrides.class_count as usize
    }
}

/// A shader program of the compositor: a vertex and a fragment entry point and the vertex input
/// they expect.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum ShaderProgram {
    /// Opaque vertex-coloured environment meshes (`environment.wgsl`).
    Environment,
    /// Glossy objects by reflection-space IBR (`glossy.wgsl`).
    Glossy,
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
    /// The vertex and fragment shaders; `None` only for a single pass whose combination
    /// `shaders/build.rs` did not compile, which [`SinglePassProgram::new`] rules out.
    pub fn shaders(self) -> Option<(Shader, Shader)> {
        use lensmap_shaders::{EntryPoint, composite, environment, glossy, lens, resolve};
        let pair = |vertex: Shader, fragment: Shader| Some((vertex, fragment));
        match self {
            ShaderProgram::Environment => pair(
                environment::Entry::VsEnvironment.shader(),
                environment::Entry::FsEnvironment.shader(),
            ),
            ShaderProgram::Glossy => pair(
                glossy::Entry::VsGlossy.shader(),
                glossy::Entry::FsGlossy.shader(),
            ),
            ShaderProgram::LensZero => pair(
                lens::Entry::VsPosition.shader(),
                lens::Entry::FsZero.shader(),
            ),
            ShaderProgram::LensLayer => {
                pair(lens::Entry::VsLayer.shader(), lens::Entry::FsLayer.shader())
            }
            ShaderProgram::BoxFilter => pair(
                resolve::Entry::VsFullScreen.shader(),
                resolve::Entry::FsBoxFilter.shader(),
            ),
            ShaderProgram::LensLayerProgrammable => pair(
                lens::Entry::VsLayer.shader(),
                lens::Entry::FsLayerProgrammable.shader(),
            ),
            ShaderProgram::GroupSum => pair(
                composite::Entry::VsFullScreen.shader(),
                composite::Entry::FsGroupSum.shader(),
            ),
            ShaderProgram::LensSinglePass(program) if program.class_terms() > 0 => pair(
                lens::Entry::VsSinglePassClasses.shader(),
                lens::Specialized::FsSinglePassClassesSpecialized.shader(program.overrides)?,
            ),
            ShaderProgram::LensSinglePass(program) => pair(
                lens::Entry::VsSinglePass.shader(),
                lens::Specialized::FsSinglePassSpecialized.shader(program.overrides)?,
            ),
        }
    }

    /// The vertex buffers the program reads (lens programs read a storage buffer instead).
    pub fn vertex_input(self) -> VertexInput {
        match self {
            ShaderProgram::Environment => VertexInput::PositionColourUv,
            ShaderProgram::Glossy => VertexInput::PositionNormal,
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
        let limits = SinglePassLimits::COMPILED;
        for layers in 1..=limits.max_layers {
            for terms in term_sets {
                for viewpoints in 1..=limits.max_viewpoints {
                    let program =
                        SinglePassProgram::new("lens", layers, terms, viewpoints, &limits)
                            .expect("a supported combination");
                    programs.push(ShaderProgram::LensSinglePass(program));
                }
            }
        }
        assert_eq!(programs.len(), 6 + 9 * SinglePassProgram::MAX_LAYERS);
        for program in programs {
            let (vertex, fragment) = program.shaders().expect("compiled by shaders/build.rs");
            assert_ne!(vertex.entry, fragment.entry, "{program:?}");
        }
    }

    #[test]
    fn unsupported_single_passes_are_errors_naming_the_fix() {
        let both = [Term::Refraction, Term::Reflection];
        let limits = SinglePassLimits::COMPILED;
        let too_many = SinglePassProgram::new(
            "teapot",
            SinglePassProgram::MAX_LAYERS + 1,
            &both,
            2,
            &limits,
        )
        .expect_err("over the limit");
        assert!(
            matches!(
                too_many,
                ProgramError::TooManyLayers {
                    layers: 7,
                    max: 6,
                    bound: LimitSource::Shader,
                    ..
                }
            ),
            "{too_many}"
        );
        assert!(too_many.to_string().contains("multipass"), "{too_many}");
        let four = SinglePassProgram::new("teapot", 2, &both, 4, &limits).expect_err("4 > 3");
        assert_eq!(
            four.to_string(),
            "lens \"teapot\" blends 4 viewpoint samples; the single-pass variant samples at most 3 as its shader is compiled: use the multipass variant"
        );
        for (layers, terms, viewpoints) in [(0, &both[..], 1), (2, &[][..], 1), (2, &both[..], 0)] {
            assert!(
                matches!(
                    SinglePassProgram::new("lens", layers, terms, viewpoints, &limits),
                    Err(ProgramError::Unsupported { .. })
                ),
                "{layers} {terms:?} {viewpoints}"
            );
        }
    }

    /// The spec's minimum limits allow everything the shader is compiled for; a device below
    /// them (fewer interpolated components, fewer sampled images) lowers the limits, and the
    /// refusal names the device limit that did it.
    #[test]
    fn the_single_pass_limits_follow_the_device() {
        let minimum = vk::PhysicalDeviceLimits {
            max_vertex_output_components: 64,
            max_fragment_input_components: 64,
            max_per_stage_descriptor_sampled_images: 16,
            max_descriptor_set_sampled_images: 96,
            max_per_stage_resources: 128,
            ..Default::default()
        };
        assert_eq!(
            SinglePassLimits::of_device(&minimum),
            SinglePassLimits::COMPILED
        );
        // 48 components: 12 locations, two for F·G, five layers of two terms.
        let narrow = vk::PhysicalDeviceLimits {
            max_fragment_input_components: 48,
            max_per_stage_resources: 3,
            ..minimum
        };
        let limits = SinglePassLimits::of_device(&narrow);
        assert_eq!((limits.max_layers, limits.max_viewpoints), (5, 2));
        let both = [Term::Refraction, Term::Reflection];
        let error = SinglePassProgram::new("glass", 6, &both, 1, &limits).unwrap_err();
        assert_eq!(
            error.to_string(),
            "lens \"glass\" has 6 layers; the single-pass variant supports at most 5 on this device (maxFragmentInputComponents = 48): use the multipass variant"
        );
        let error = SinglePassProgram::new("glass", 5, &both, 3, &limits).unwrap_err();
        assert!(
            error
                .to_string()
                .contains("at most 2 on this device (maxPerStageResources = 3)"),
            "{error}"
        );
        assert!(SinglePassProgram::new("glass", 5, &both, 2, &limits).is_ok());
    }
}
