//! How lens objects are composited: the variant, the multipass variant's blending schemes, and
//! [`Compositing`], the two together in a type that cannot hold the pair the single pass does
//! not take (it composites in registers and does not blend).

use super::FrameShape;
use crate::options::{LibraryWords, OptionWords, Worded, names};

/// How lens objects are composited.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Variant {
    /// The paper's scheme: one pass per (viewpoint, term, layer), alpha clears between groups
    /// (2·V·n layer passes for V viewpoint samples, n layers and both terms).
    Multipass,
    /// One draw per lens object sampling the 2·V (viewpoint, term) textures per layer at once.
    SinglePass,
}

impl Variant {
    /// Name on the command line.
    pub fn name(self) -> &'static str {
        match self {
            Variant::Multipass => "multipass",
            Variant::SinglePass => "single-pass",
        }
    }
}

/// How the multipass variant combines the layers of a (viewpoint, term) group and the groups of
/// a lens object (`--blend`). Every scheme computes the paper's closed form
/// `Σ_groups w·FG ⊙ (L1 over … over Ln).rgb`, α = the last group's `(L1 over … over Ln).α`; they
/// differ in the passes, attachments and barriers it takes, and in where rounding happens. (Where
/// two lens objects lie at exactly the same depth, the later one's prime fails its `<` test but
/// its layers pass `<=`, and each scheme then mixes the two objects its own way; the f64 model
/// marks such pixels as depth ties and leaves them out.)
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum BlendScheme {
    /// The paper's scheme: per group, layers nearest first with `src·(1 − dstα) + dst` straight
    /// into the framebuffer, an alpha clear between groups. One rendering instance, no barriers.
    #[default]
    FrontToBack,
    /// Layers farthest first with the classic `src + dst·(1 − srcα)`. "Over" from the back needs
    /// a clear destination, so each group composites into a cleared scratch image, and a
    /// full-screen pass adds it to the framebuffer (colour only, but α too for the last group):
    /// per group two more passes (the clear and the add) and two more rendering instances, with
    /// three or four barriers.
    BackToFront,
    /// Each group composited front to back into its own cleared image (no alpha clears), then one
    /// full-screen resolve adds the groups' colour and takes the last group's α.
    GroupTargets,
    /// Blending in the fragment shader: each layer pass reads the pixel's current value and
    /// writes `src·(1 − dstα) + dst` (and the alpha clear) with shader arithmetic, so the result
    /// does not depend on fixed-function blend precision. The current value comes from the
    /// previous pass's image (passes alternate between two scratch images and end in the
    /// framebuffer): a rendering instance and two barriers per pass, no device feature needed.
    Programmable,
}

impl BlendScheme {
    /// Every scheme, the default first.
    pub const ALL: [BlendScheme; 4] = [
        BlendScheme::FrontToBack,
        BlendScheme::BackToFront,
        BlendScheme::GroupTargets,
        BlendScheme::Programmable,
    ];

    /// Name on the command line.
    pub fn name(self) -> &'static str {
        match self {
            BlendScheme::FrontToBack => "front-to-back",
            BlendScheme::BackToFront => "back-to-front",
            BlendScheme::GroupTargets => "group-targets",
            BlendScheme::Programmable => "programmable",
        }
    }

    /// The scheme named `name` on the command line.
    pub fn from_name(name: &str) -> Option<BlendScheme> {
        Self::ALL.into_iter().find(|s| s.name() == name)
    }

    /// Scratch images (framebuffer-sized, the framebuffer's format) a frame of `shape` needs.
    pub fn scratch_images(self, shape: &FrameShape) -> usize {
        match self {
            BlendScheme::FrontToBack => 0,
            BlendScheme::BackToFront => 1,
            BlendScheme::Programmable => 2,
            BlendScheme::GroupTargets => shape
                .lenses
                .iter()
                .map(|lens| shape.active_viewpoints(lens).len() * lens.terms.len())
                .max()
                .unwrap_or(0),
        }
    }
}

/// How a frame's lens objects are composited: the single pass, or the paper's multipass scheme
/// with one of its blending schemes. The single pass does not blend, so "single pass with a
/// blending scheme" cannot be written; a front end that reads the variant and the scheme apart
/// (flags, C struct fields) makes this with [`Compositing::new`], the one place the pair is
/// checked.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum Compositing {
    /// One draw per lens object sampling every (viewpoint, term) texture per layer at once.
    #[default]
    SinglePass,
    /// One pass per (viewpoint, term, layer), combined by the blending scheme.
    Multipass(BlendScheme),
}

impl Compositing {
    /// The compositing of `variant` with `blend`: an error for the single pass with a scheme
    /// other than front-to-back, which it would not honour.
    pub fn new(variant: Variant, blend: BlendScheme) -> Result<Compositing, CompositingError> {
        match (variant, blend) {
            (Variant::Multipass, blend) => Ok(Compositing::Multipass(blend)),
            (Variant::SinglePass, BlendScheme::FrontToBack) => Ok(Compositing::SinglePass),
            (Variant::SinglePass, blend) => Err(CompositingError { blend }),
        }
    }

    /// The variant.
    pub fn variant(self) -> Variant {
        match self {
            Compositing::SinglePass => Variant::SinglePass,
            Compositing::Multipass(_) => Variant::Multipass,
        }
    }

    /// The blending scheme: the multipass variant's, front-to-back for the single pass (whose
    /// result is the front-to-back composite, made in registers).
    pub fn blend(self) -> BlendScheme {
        match self {
            Compositing::SinglePass => BlendScheme::FrontToBack,
            Compositing::Multipass(blend) => blend,
        }
    }
}

/// A blending scheme other than front-to-back asked of the single pass, which does not blend.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
#[error("{}", self.worded(&LibraryWords))]
pub struct CompositingError {
    /// The scheme asked for.
    pub blend: BlendScheme,
}

impl Worded for CompositingError {
    fn worded(&self, words: &dyn OptionWords) -> String {
        format!(
            "{} applies to the multipass variant; the single pass composites in registers and does not blend: use {}",
            words.setting(names::BLEND, self.blend.name()),
            words.setting(names::VARIANT, Variant::Multipass.name())
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every pair but the single pass with a blending scheme is a compositing, and gives its
    /// variant and scheme back.
    #[test]
    fn every_pair_but_a_blending_single_pass_is_a_compositing() {
        for blend in BlendScheme::ALL {
            let multipass = Compositing::new(Variant::Multipass, blend).unwrap();
            assert_eq!(
                (multipass.variant(), multipass.blend()),
                (Variant::Multipass, blend)
            );
            let single = Compositing::new(Variant::SinglePass, blend);
            if blend == BlendScheme::FrontToBack {
                assert_eq!(single, Ok(Compositing::SinglePass));
            } else {
                assert_eq!(single, Err(CompositingError { blend }));
            }
        }
        assert_eq!(Compositing::default().variant(), Variant::SinglePass);
    }

    /// The single pass asked to blend names the options by their field names; a front end
    /// words them its own way.
    #[test]
    fn a_blend_for_the_single_pass_names_the_options() {
        use crate::render::tests::Flags;
        let error = CompositingError {
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
