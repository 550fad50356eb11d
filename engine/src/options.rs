//! Options out of range, and how messages name options. Every option of the library is an
//! [`OptionName`]: the field of the library's options struct that holds it, and each front end's
//! word for it (the command line's flag, the C ABI's struct field). Every option check returns an
//! [`OptionError`] naming the option by its [`OptionName`], the value and what to give instead. A
//! message that names options (an option error, or advice such as "set `accept_any_bake`") is
//! written through [`OptionWords`], so each front end says it in its own terms: the library's
//! [`Display`](std::fmt::Display) names the fields, the command line its flags, the C ABI its
//! struct fields. No front end derives one word from another: each reads its own from the
//! [`OptionName`].

use std::borrow::Cow;

/// One option of the library, with each front end's word for it: a handle to its
/// [`OptionInfo`] (one pointer, so that errors carrying it stay small).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct OptionName(pub &'static OptionInfo);

impl std::ops::Deref for OptionName {
    type Target = OptionInfo;

    fn deref(&self) -> &OptionInfo {
        self.0
    }
}

/// What an [`OptionName`] names: the library's field and each front end's word for it.
#[derive(Debug, PartialEq, Eq, Hash)]
pub struct OptionInfo {
    /// The struct that holds the field (`LightMapOptions`), or the function whose parameter it
    /// is (`Compositing::new`).
    pub owner: &'static str,
    /// The field (or parameter) in the library: `min_texels_per_metre`.
    pub field: &'static str,
    /// What the library's words append to a value: the unit of a value shown in other units
    /// than the field holds (`°` where the field holds radians and every front end takes
    /// degrees); empty for none.
    pub shown_in: &'static str,
    /// The command line's flag, without its dashes (`light-map-density`); `None` where no flag
    /// sets the option.
    pub flag: Option<&'static str>,
    /// The C ABI's struct field (`light_map_max_texels`); `None` where the C ABI has none.
    pub c_field: Option<&'static str>,
    /// For an option whose values are named, the prefix of the C ABI's constants for them
    /// (`LENSMAP_BLEND_`, followed by the name in capitals with `_` for `-`).
    pub c_constants: Option<&'static str>,
}

impl OptionInfo {
    /// An option held by `owner.field`, with no front-end words yet.
    pub const fn field(owner: &'static str, field: &'static str) -> OptionInfo {
        OptionInfo {
            owner,
            field,
            shown_in: "",
            flag: None,
            c_field: None,
            c_constants: None,
        }
    }

    /// This option, set on the command line by `--flag`.
    pub const fn flag(self, flag: &'static str) -> OptionInfo {
        OptionInfo {
            flag: Some(flag),
            ..self
        }
    }

    /// This option, set through the C ABI by the struct field `field`.
    pub const fn c_field(self, field: &'static str) -> OptionInfo {
        OptionInfo {
            c_field: Some(field),
            ..self
        }
    }

    /// This option's named values, as the C ABI's constants `prefix` + NAME.
    pub const fn c_constants(self, prefix: &'static str) -> OptionInfo {
        OptionInfo {
            c_constants: Some(prefix),
            ..self
        }
    }

    /// This option's values, shown with `unit` (the front ends' unit where the field holds
    /// another).
    pub const fn shown_in(self, unit: &'static str) -> OptionInfo {
        OptionInfo {
            shown_in: unit,
            ..self
        }
    }
}

/// The library's options, each with its front ends' words. The baker's are in
/// `lensmap_baker::bake::names`.
pub mod names {
    use super::{OptionInfo, OptionName};

    /// `TessellationOptions::t`, the tessellation threshold in subpixels.
    pub const T: OptionName = OptionName(
        &OptionInfo::field("TessellationOptions", "t")
            .flag("t")
            .c_field("t"),
    );
    /// `TessellationOptions::max_vertices`, the frame's vertex budget.
    pub const MAX_VERTICES: OptionName =
        OptionName(&OptionInfo::field("TessellationOptions", "max_vertices").flag("max-vertices"));
    /// `TessellationOptions::max_depth`, the deepest subdivision.
    pub const MAX_DEPTH: OptionName =
        OptionName(&OptionInfo::field("TessellationOptions", "max_depth"));
    /// `HybridOptions::angle_radians`, the paper's angle threshold (front ends take degrees).
    pub const ANGLE: OptionName = OptionName(
        &OptionInfo::field("HybridOptions", "angle_radians")
            .shown_in("°")
            .flag("angle-degrees"),
    );
    /// `HybridOptions::footprint_subpixels`, footprint coarsening.
    pub const FOOTPRINT: OptionName =
        OptionName(&OptionInfo::field("HybridOptions", "footprint_subpixels").flag("footprint"));
    /// `HybridOptions::fresnel`, how the vertex paths evaluate Fresnel.
    pub const FRESNEL: OptionName = OptionName(
        &OptionInfo::field("HybridOptions", "fresnel")
            .flag("fresnel")
            .c_field("fresnel_texels"),
    );
    /// `HybridOptions::tracer`, where the lens vertices are traced.
    pub const TRACER: OptionName = OptionName(
        &OptionInfo::field("HybridOptions", "tracer")
            .flag("tracer")
            .c_field("tracer")
            .c_constants("LENSMAP_TRACER_"),
    );
    /// `HybridOptions::terms`, the shading terms of a frame's lens objects (the scene's, the
    /// two greedy terms, or path classes).
    pub const TERMS: OptionName =
        OptionName(&OptionInfo::field("HybridOptions", "terms").flag("terms"));
    /// The compositor variant, `Compositing::new`'s `variant`.
    pub const VARIANT: OptionName = OptionName(
        &OptionInfo::field("Compositing::new", "variant")
            .flag("variant")
            .c_field("variant")
            .c_constants("LENSMAP_VARIANT_"),
    );
    /// The multipass variant's blending scheme, `Compositing::new`'s `blend`.
    pub const BLEND: OptionName = OptionName(
        &OptionInfo::field("Compositing::new", "blend")
            .flag("blend")
            .c_field("blend")
            .c_constants("LENSMAP_BLEND_"),
    );
    /// `FrameOptions::format`, the framebuffer's format.
    pub const FORMAT: OptionName = OptionName(
        &OptionInfo::field("FrameOptions", "format")
            .flag("format")
            .c_field("format")
            .c_constants("LENSMAP_FORMAT_"),
    );
    /// `Camera::width`, pixels.
    pub const WIDTH: OptionName = OptionName(
        &OptionInfo::field("Camera", "width")
            .flag("width")
            .c_field("width"),
    );
    /// `Camera::height`, pixels.
    pub const HEIGHT: OptionName = OptionName(
        &OptionInfo::field("Camera", "height")
            .flag("height")
            .c_field("height"),
    );
    /// `Camera::supersampling`, subpixels a pixel side.
    pub const SUPERSAMPLING: OptionName = OptionName(
        &OptionInfo::field("Camera", "supersampling")
            .flag("supersampling")
            .c_field("supersampling"),
    );
    /// `ProjectedOptions::size`, the projected EMs' cube-map face size.
    pub const EM_SIZE: OptionName = OptionName(
        &OptionInfo::field("ProjectedOptions", "size")
            .flag("em-size")
            .c_field("em_size"),
    );
    /// `ProjectedOptions::supersampling`, rays a texel side.
    pub const EM_SUPERSAMPLING: OptionName =
        OptionName(&OptionInfo::field("ProjectedOptions", "supersampling"));
    /// `LightMapOptions::min_texels_per_metre`.
    pub const LIGHT_MAP_DENSITY: OptionName = OptionName(
        &OptionInfo::field("LightMapOptions", "min_texels_per_metre").flag("light-map-density"),
    );
    /// `LightMapOptions::max_texels_per_metre`.
    pub const LIGHT_MAP_MAX_DENSITY: OptionName = OptionName(
        &OptionInfo::field("LightMapOptions", "max_texels_per_metre").flag("light-map-max-density"),
    );
    /// `LightMapOptions::pixels_per_texel`.
    pub const LIGHT_MAP_PIXELS_PER_TEXEL: OptionName = OptionName(
        &OptionInfo::field("LightMapOptions", "pixels_per_texel")
            .flag("light-map-pixels-per-texel"),
    );
    /// `LightMapOptions::max_atlas_size`.
    pub const LIGHT_MAP_MAX_SIZE: OptionName =
        OptionName(&OptionInfo::field("LightMapOptions", "max_atlas_size"));
    /// `LightMapOptions::max_texels`, the atlases' texel budget.
    pub const LIGHT_MAP_MAX_TEXELS: OptionName = OptionName(
        &OptionInfo::field("LightMapOptions", "max_texels")
            .flag("light-map-max-texels")
            .c_field("light_map_max_texels"),
    );
    /// `LightMapOptions::supersampling`.
    pub const LIGHT_MAP_SUPERSAMPLING: OptionName =
        OptionName(&OptionInfo::field("LightMapOptions", "supersampling"));
    /// `EmSource::AnyBake`: a bake used whatever scene it was made for.
    pub const ACCEPT_ANY_BAKE: OptionName = OptionName(
        &OptionInfo::field("EmSource", "AnyBake")
            .flag("accept-any-bake")
            .c_field("accept_any_bake"),
    );

    /// Every option above.
    pub const ALL: &[OptionName] = &[
        T,
        MAX_VERTICES,
        MAX_DEPTH,
        ANGLE,
        FOOTPRINT,
        FRESNEL,
        TRACER,
        TERMS,
        VARIANT,
        BLEND,
        FORMAT,
        WIDTH,
        HEIGHT,
        SUPERSAMPLING,
        EM_SIZE,
        EM_SUPERSAMPLING,
        LIGHT_MAP_DENSITY,
        LIGHT_MAP_MAX_DENSITY,
        LIGHT_MAP_PIXELS_PER_TEXEL,
        LIGHT_MAP_MAX_SIZE,
        LIGHT_MAP_MAX_TEXELS,
        LIGHT_MAP_SUPERSAMPLING,
        ACCEPT_ANY_BAKE,
    ];
}

/// How a front end names the library's options in messages.
pub trait OptionWords {
    /// The option `name`, in this front end's word.
    fn option(&self, name: OptionName) -> String;

    /// The option `name` given `value` (the value as the front ends write it).
    fn setting(&self, name: OptionName, value: &str) -> String {
        format!("{} = {value}{}", self.option(name), name.shown_in)
    }

    /// The library's entry point `call` (a function such as `bake`), for messages that say
    /// what to run: by default the function's name in backquotes; the command line names its
    /// command.
    fn call(&self, call: &str) -> String {
        format!("`{call}`")
    }

    /// Advice to turn on the switch `name` (`accept_any_bake`): "set `accept_any_bake`".
    fn switch_on(&self, name: OptionName) -> String {
        format!("set {}", self.option(name))
    }

    /// The command that bakes scene `scene` (`None`: the scene being loaded, unnamed) where this
    /// front end has one (the command line's); `None` where baking is a call of the library.
    fn bake_command(&self, scene: Option<&str>) -> Option<String> {
        let _ = scene;
        None
    }
}

/// The library's own words: options by their struct and field, in backquotes
/// (`` `ProjectedOptions.size` ``); a function's parameter by its name (`` `blend` ``).
#[derive(Clone, Copy, Debug, Default)]
pub struct LibraryWords;

impl OptionWords for LibraryWords {
    fn option(&self, name: OptionName) -> String {
        if name.owner.contains("::") || name.owner.starts_with(char::is_lowercase) {
            format!("`{}`", name.field)
        } else {
            format!("`{}.{}`", name.owner, name.field)
        }
    }
}

/// An error whose message names options: [`Worded::worded`] says it in a front end's terms, and
/// its `Display` is the same message in [`LibraryWords`].
pub trait Worded: std::error::Error {
    /// The message, with options named by `words`.
    fn worded(&self, words: &dyn OptionWords) -> String;
}

/// What to give instead of a value: a text that may name other options, each written `{N}` for
/// entry N of `names` and said in the front end's words.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Fix {
    /// The advice.
    pub text: Cow<'static, str>,
    /// The options `{0}`, `{1}`, … in `text` name.
    pub names: &'static [OptionName],
}

impl Fix {
    /// Advice that names `names` (written `{0}`, `{1}`, … in `text`).
    pub fn naming(text: impl Into<Cow<'static, str>>, names: &'static [OptionName]) -> Fix {
        Fix {
            text: text.into(),
            names,
        }
    }

    /// The advice with its options named by `words`.
    pub fn worded(&self, words: &dyn OptionWords) -> String {
        let mut text = self.text.to_string();
        for (index, name) in self.names.iter().enumerate() {
            text = text.replace(&format!("{{{index}}}"), &words.option(*name));
        }
        text
    }
}

impl From<&'static str> for Fix {
    fn from(text: &'static str) -> Fix {
        Fix::naming(text, &[])
    }
}

impl From<String> for Fix {
    fn from(text: String) -> Fix {
        Fix::naming(text, &[])
    }
}

/// An option value the library cannot use.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("{}", self.worded(&LibraryWords))]
pub struct OptionError {
    /// The option.
    pub option: OptionName,
    /// The value given, as text (in the unit the front ends write it).
    pub value: String,
    /// What to give instead (the valid range, with an example).
    pub fix: Fix,
}

impl OptionError {
    /// The error for `option` = `value`, with `fix` saying what to give instead.
    pub fn new(option: OptionName, value: impl ToString, fix: impl Into<Fix>) -> OptionError {
        OptionError {
            option,
            value: value.to_string(),
            fix: fix.into(),
        }
    }

    /// `Ok` when `valid`, else the error for `option` = `value` with `fix`: the shape of every
    /// option check.
    pub fn require(
        valid: bool,
        option: OptionName,
        value: impl ToString,
        fix: impl Into<Fix>,
    ) -> Result<(), OptionError> {
        if valid {
            Ok(())
        } else {
            Err(OptionError::new(option, value, fix))
        }
    }
}

impl Worded for OptionError {
    fn worded(&self, words: &dyn OptionWords) -> String {
        format!(
            "{}: {}",
            words.setting(self.option, &self.value),
            self.fix.worded(words)
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Flags as the command line writes them: each option's own flag.
    struct Flags;
    impl OptionWords for Flags {
        fn option(&self, name: OptionName) -> String {
            format!("--{}", name.flag.unwrap_or(name.field))
        }
        fn setting(&self, name: OptionName, value: &str) -> String {
            format!("{} {value}", self.option(name))
        }
    }

    #[test]
    fn an_option_error_is_worded_by_each_front_end() {
        let error = OptionError::new(names::EM_SIZE, 7, "give a power of two, e.g. 128");
        assert_eq!(
            error.to_string(),
            "`ProjectedOptions.size` = 7: give a power of two, e.g. 128"
        );
        assert_eq!(
            error.worded(&Flags),
            "--em-size 7: give a power of two, e.g. 128"
        );
    }

    /// A fix that names another option names it in each front end's words; a value shown in
    /// another unit than its field's says so in the library's words.
    #[test]
    fn a_fix_names_other_options_and_a_value_its_unit() {
        let error = OptionError::new(
            names::LIGHT_MAP_MAX_DENSITY,
            2,
            Fix::naming("give a density ≥ {0}", &[names::LIGHT_MAP_DENSITY]),
        );
        assert_eq!(
            error.to_string(),
            "`LightMapOptions.max_texels_per_metre` = 2: give a density ≥ `LightMapOptions.min_texels_per_metre`"
        );
        assert_eq!(
            error.worded(&Flags),
            "--light-map-max-density 2: give a density ≥ --light-map-density"
        );
        let angle = OptionError::new(names::ANGLE, -3, "give an angle in (0, 180), e.g. 3");
        assert_eq!(
            angle.to_string(),
            "`HybridOptions.angle_radians` = -3°: give an angle in (0, 180), e.g. 3"
        );
    }
}
