//! One function per way of compositing a lens object, each the list of passes its description in
//! [`super::BlendScheme`] names, declared through [`LensPasses`]. Every multipass scheme begins
//! with the prime and takes the groups in the order [`Group::all`] gives them (the last group's α
//! is the frame's).

use crate::graph::{Blend, ColourMask};
use crate::index::LayerIndex;
use crate::render::program::{ProgramError, SinglePassLimits, SinglePassProgram};

use super::lens::{Current, Group, LensPasses, Target};

/// The paper's scheme, 2·V·n layer passes for V viewpoints and both terms (4n for two): per group
/// its layers nearest first with front-to-back "over" straight into the framebuffer, an alpha
/// clear between groups.
pub(super) fn front_to_back(passes: &mut LensPasses, groups: &[Group]) {
    passes.prime();
    for (index, &group) in groups.iter().enumerate() {
        if index > 0 {
            passes.alpha_clear(group);
        }
        passes.layers(group, Target::Framebuffer, Blend::FrontToBackOver);
    }
}

/// Per group: scratch image 0 cleared, the layers farthest first with back-to-front "over" into
/// it, and its colour added into the framebuffer (its α too for the last group).
pub(super) fn back_to_front(passes: &mut LensPasses, groups: &[Group]) {
    passes.prime();
    for (index, &group) in groups.iter().enumerate() {
        passes.scratch_clear(group, 0);
        passes.layers(group, Target::Scratch(0), Blend::BackToFrontOver);
        let last = index + 1 == groups.len();
        let mask = if last {
            ColourMask::RGBA
        } else {
            ColourMask::RGB
        };
        passes.accumulate(group, mask);
    }
}

/// Each group front to back into its own cleared scratch image, then one sum of them all.
pub(super) fn group_targets(passes: &mut LensPasses, groups: &[Group]) {
    passes.prime();
    for (index, &group) in groups.iter().enumerate() {
        passes.scratch_clear(group, index);
        passes.layers(group, Target::Scratch(index), Blend::FrontToBackOver);
    }
    passes.group_sum(groups.len());
}

/// Every drawn layer blended in the shader over the previous pass's image: pass i writes scratch
/// image i mod 2 and reads the other, the last writes the framebuffer, so no pass reads what it
/// writes. Layers whose cube map is all zeros are left out (the identity).
pub(super) fn programmable(passes: &mut LensPasses, groups: &[Group]) {
    passes.prime();
    let lens = passes.lens();
    // The drawn layers in front-to-back order, each with its group's index.
    let drawn: Vec<(usize, Group, LayerIndex)> = groups
        .iter()
        .enumerate()
        .flat_map(|(index, &group)| {
            LayerIndex::all(lens.layer_count())
                .filter(move |&layer| !lens.empty[group.viewpoint][layer.index()])
                .map(move |layer| (index, group, layer))
        })
        .collect();
    for (i, &(index, group, layer)) in drawn.iter().enumerate() {
        let target = if i + 1 == drawn.len() {
            Target::Framebuffer
        } else {
            Target::Scratch(i % 2)
        };
        let current = match i.checked_sub(1) {
            None => Current::Prime,
            Some(previous) if drawn[previous].0 != index => {
                Current::ScratchAfterGroup((previous % 2) as u32)
            }
            Some(previous) => Current::Scratch((previous % 2) as u32),
        };
        passes.programmable_layer(group, layer, target, current);
    }
    // Groups after the last drawn layer (all of their layers zero) still clear α, as the
    // front-to-back scheme's alpha clears do. (With nothing drawn, the prime's α is 0 already.)
    if let Some(&(index, _, _)) = drawn.last()
        && let Some(&next) = groups.get(index + 1)
    {
        passes.alpha_clear(next);
    }
}

/// The single-pass variant: one draw sampling the `viewpoints` active viewpoints' layers at once,
/// within `limits`.
pub(super) fn single_pass(
    passes: &mut LensPasses,
    viewpoints: usize,
    limits: &SinglePassLimits,
) -> Result<(), ProgramError> {
    let lens = passes.lens();
    let program = SinglePassProgram::new(
        &lens.name,
        lens.layer_count(),
        &lens.terms,
        viewpoints,
        limits,
    )?;
    passes.single_pass(program);
    Ok(())
}
